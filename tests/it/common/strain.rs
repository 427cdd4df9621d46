//! Edge strain of a baked cloth, measured from its frames (shared by the integration tests and
//! `benches/garments.rs`, which includes this file by path).

use scenebake::cloth::springs::SpringKind;
use scenebake::cloth::{ClothModel, FrameCache};

/// The largest stretch and the largest compression (negative) of any mesh edge (the model's
/// stretch springs) over frames 1.. of `cache`, as strains len/rest − 1.
pub fn edge_strain_range(model: &ClothModel, cache: &FrameCache) -> (f64, f64) {
    let (mut stretch, mut squash) = (0.0f64, 0.0f64);
    for k in 1..cache.frame_count() {
        let f = cache.frame(k);
        for s in model
            .springs
            .iter()
            .filter(|s| s.kind == SpringKind::Stretch)
        {
            let len = f[s.a as usize]
                .as_dvec3()
                .distance(f[s.b as usize].as_dvec3());
            let strain = len / s.rest - 1.0;
            stretch = stretch.max(strain);
            squash = squash.min(strain);
        }
    }
    (stretch, squash)
}
