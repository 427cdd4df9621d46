//! Mesh-collider query benchmarks: 10,000 particles near a 5,120-triangle closed icosphere
//! (unit radius), and near `meshes/tableCloth.obj` used as an open 27,848-triangle shell.
//!
//! ```text
//! cargo bench --bench collide
//! ```
//!
//! - `build`: `MeshCollider::new` (validation, topology and pseudo-normals, BVH);
//! - `near_reach`: 10,000 `contact` queries at 0.95–1.05 m from the centre with a 2 cm reach
//!   (about 40 % answer), one step's motion of 1 % of the radius as `from`;
//! - `within_reach`: the same at 0.985–1.015 m (all within reach);
//! - `deep_inside`: at 0.9–0.95 m, inside beyond reach (the rare case that needs an unbounded
//!   search for the depth);
//! - `far`: 10,000 queries 2–3 m away (all pruned by the root box);
//! - tableCloth `near_reach`: particles up to 2 cm above and below the sheet, moving 3 mm.
//!
//! Divide the per-iteration time by 10,000 for the cost of one query.

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use glam::DVec3;
use scenebake::cloth::collide::mesh::{icosphere, MeshCollider};
use scenebake::io::obj::{load_obj, ObjOptions};

/// xorshift64*, uniform in [0, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn direction(&mut self) -> DVec3 {
        DVec3::new(
            2.0 * self.next() - 1.0,
            2.0 * self.next() - 1.0,
            2.0 * self.next() - 1.0,
        )
        .normalize()
    }
}

fn queries(c: &mut Criterion) {
    let (v, f) = icosphere(4);
    let mut group = c.benchmark_group("sphere5k");
    group.bench_function("build", |b| {
        b.iter(|| MeshCollider::new(black_box(v.clone()), black_box(f.clone())).unwrap())
    });
    let sphere = MeshCollider::new(v, f).unwrap();
    let mut rng = Rng(12345);
    let mut shell = |lo: f64, hi: f64| -> Vec<(DVec3, DVec3)> {
        (0..10_000)
            .map(|_| {
                let p = rng.direction() * (lo + (hi - lo) * rng.next());
                (p, p * 1.01)
            })
            .collect()
    };
    let near = shell(0.95, 1.05);
    let within = shell(0.985, 1.015);
    let deep = shell(0.9, 0.95);
    let far: Vec<(DVec3, DVec3)> = (0..10_000)
        .map(|_| {
            let p = rng.direction() * (2.0 + rng.next());
            (p, p)
        })
        .collect();
    for (name, set) in [
        ("near_reach", &near),
        ("within_reach", &within),
        ("deep_inside", &deep),
        ("far", &far),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                set.iter()
                    .filter_map(|&(p, from)| sphere.contact(p, from, 0.02))
                    .map(|s| s.distance)
                    .sum::<f64>()
            })
        });
    }
    group.finish();

    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/tableCloth.obj");
    let mesh = load_obj(&path, &ObjOptions::default()).unwrap();
    let sheet = MeshCollider::new(mesh.positions.clone(), mesh.triangles.clone()).unwrap();
    let mut group = c.benchmark_group("tableCloth");
    let sample: Vec<(DVec3, DVec3)> = (0..10_000)
        .map(|_| {
            let base = mesh.positions[(rng.next() * mesh.positions.len() as f64) as usize];
            let p = base + DVec3::new(0.0, 0.04 * rng.next() - 0.02, 0.0);
            (p, p + rng.direction() * 0.003)
        })
        .collect();
    group.bench_function("near_reach", |b| {
        b.iter(|| {
            sample
                .iter()
                .filter_map(|&(p, from)| sheet.contact(p, from, 0.02))
                .map(|s| s.distance)
                .sum::<f64>()
        })
    });
    group.finish();
}

criterion_group!(benches, queries);
criterion_main!(benches);
