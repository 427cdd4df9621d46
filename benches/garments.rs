//! Time to tolerance on real garments: each solver and model, how many iterations and how long
//! per frame it takes to bring every step below the tolerance, and what the garment does.
//!
//! ```text
//! cargo bench --bench garments                 # every case, 10 frames
//! cargo bench --bench garments -- skirt8K      # cases whose label contains "skirt8K"
//! cargo bench --bench garments -- "=dress on mannequin cotton newton 0.1"   # one case, exactly
//! FRAMES=30 cargo bench --bench garments -- dress
//! SWEEPS=0 cargo bench --bench garments        # every Newton case without Gauss–Seidel sweeps
//! THREADS=1 JAM=0.06 cargo bench --bench garments   # one thread; a 6 % jamming strain
//! ```
//!
//! Prints one markdown row per case: iterations per step (median, max), ms per frame, the share
//! of frames within the tolerance, the hem drop (lowest vertex, initial minus current height) at
//! frames 5 and 10, and the largest stretch and compression of any edge over the bake. Cases run
//! one after another in one process, so their ratios are measured side by side.

use std::path::PathBuf;

use scenebake::bake::cloth::{simulate_cloth, ClothJob, ClothSource, SimulatedCloth};
use scenebake::cloth::collide::{ColliderSpec, ContactModel};
use scenebake::cloth::pins::PinSpec;
use scenebake::cloth::SolverKind;

#[path = "../tests/it/common/strain.rs"]
mod strain;
use strain::edge_strain_range;

struct Case {
    label: String,
    job: ClothJob,
}

fn garment(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("meshes/garments")
        .join(name)
}

fn cases(frames: usize) -> Vec<Case> {
    let mut out = Vec::new();
    let skirts = [
        (
            "skirt8K",
            "skirt8K.obj",
            "box:-0.2,0.999,-0.2,0.2,1.001,0.2",
        ),
        (
            "circle_skirt",
            "circle_skirt.obj",
            "box:-0.2,0.999,-0.2,0.2,1.001,0.2",
        ),
    ];
    let mut add = |label: String, mut job: ClothJob| {
        job.frames = job.frames.or(Some(frames));
        out.push(Case { label, job });
    };
    for (name, file, pin) in skirts {
        let base = || {
            let mut job = ClothJob::new(ClothSource::File(garment(file)), "unused.glb".into());
            job.pin = vec![pin.parse::<PinSpec>().unwrap()];
            job
        };
        add(format!("{name} cotton newton 0.1 (default)"), base());
        let mut job = base();
        job.tolerance = 1e-3;
        add(format!("{name} cotton newton 1e-3 (reference)"), job);
        let mut job = base();
        job.solver = SolverKind::Fast;
        add(format!("{name} cotton fast 0.1 (cap 500)"), job);
        let mut job = base();
        job.stiffness = Some(1000.0);
        job.bend_stiffness = Some(2.0);
        job.density = Some(0.2);
        add(format!("{name} labs' springs 1000/2 newton 0.1"), job);
        // Dropped, unpinned, onto a sphere below its waist.
        let mut job = base();
        job.pin.clear();
        job.collider = vec!["sphere:0,0.55,0,0.3".parse::<ColliderSpec>().unwrap()];
        add(
            format!("{name} cotton newton 0.1 dropped on a sphere"),
            job.clone(),
        );
        job.contact = Some(ContactModel::Constraint);
        add(
            format!("{name} cotton newton 0.1 dropped on a sphere, constraint"),
            job,
        );
        // Dropped, unpinned, onto the table mesh (top at y = 0.75 m, 1.2 × 0.8 m): the hem ring
        // (y = 0.8 for skirt8K, 0.65 for circle_skirt, which is raised 0.15 m as in
        // docs/garments.md's Blender case) lands on the top and hangs over its long edges.
        let mut job = base();
        job.pin.clear();
        if name == "circle_skirt" {
            job.translate = Some(scenebake::glam::DVec3::new(0.0, 0.15, 0.0));
        }
        job.collider = vec![ColliderSpec::mesh(
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("meshes/table.obj"),
        )];
        add(
            format!("{name} cotton newton 0.1 dropped on a table"),
            job.clone(),
        );
        job.contact = Some(ContactModel::Constraint);
        add(
            format!("{name} cotton newton 0.1 dropped on a table, constraint"),
            job,
        );
    }
    let mut job = ClothJob::new(
        ClothSource::File(garment("dress_draped.obj")),
        "unused.glb".into(),
    );
    job.collider = vec![ColliderSpec::mesh(garment("mannequin.obj"))];
    // The dress is judged after 30 frames, whatever FRAMES says.
    job.frames = Some(frames.max(30));
    add("dress on mannequin cotton newton 0.1".into(), job.clone());
    job.contact = Some(ContactModel::Constraint);
    add(
        "dress on mannequin cotton newton 0.1, constraint".into(),
        job,
    );
    out
}

fn median(v: &mut [usize]) -> usize {
    v.sort_unstable();
    v[v.len() / 2]
}

fn main() {
    let frames: usize = std::env::var("FRAMES")
        .ok()
        .and_then(|f| f.parse().ok())
        .unwrap_or(10);
    let sweeps: Option<usize> = std::env::var("SWEEPS").ok().and_then(|s| s.parse().ok());
    // THREADS=1 for runs side by side, one per core (default: every core, as the CLI).
    let threads: Option<usize> = std::env::var("THREADS").ok().and_then(|s| s.parse().ok());
    // JAM=0.06: every material case with that jamming strain (`--jam-strain`).
    let jam: Option<f64> = std::env::var("JAM").ok().and_then(|s| s.parse().ok());
    let filters: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    println!(
        "| case | particles | iterations/step (median, max) | ms/frame | frames within tolerance | \
         hem drop f5 / f10 / last (mm) | max stretch / compression (%) |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: |");
    for case in cases(frames) {
        let matches = |f: &String| match f.strip_prefix('=') {
            Some(exact) => case.label == exact,
            None => case.label.contains(f.as_str()),
        };
        if !filters.is_empty() && !filters.iter().any(matches) {
            continue;
        }
        let mut job = case.job.clone();
        if let Some(sweeps) = sweeps {
            job.sweeps = Some(sweeps);
        }
        job.threads = threads.or(job.threads);
        if job.stiffness.is_none() {
            job.jam_strain = jam.or(job.jam_strain);
        }
        let result = simulate_cloth(&job, &mut |_, _| {});
        let SimulatedCloth {
            prepared,
            simulation,
        } = match result {
            Ok(s) => s,
            Err(e) => {
                println!("| {} | error: {e} |", case.label);
                continue;
            }
        };
        let model = &prepared.model;
        let cache = &simulation.cache;
        let min_y = |k: usize| {
            cache
                .frame(k.min(cache.frame_count() - 1))
                .iter()
                .map(|p| p.y)
                .fold(f32::INFINITY, f32::min)
        };
        let drop = |k: usize| 1e3 * (min_y(0) - min_y(k));
        let last = cache.frame_count() - 1;
        let (stretch, squash) = edge_strain_range(model, cache);
        let mut its: Vec<usize> = simulation.frames.iter().map(|f| f.iterations).collect();
        let max_its = its.iter().copied().max().unwrap_or(0);
        let within = simulation.frames.iter().filter(|f| f.converged).count();
        println!(
            "| {} | {} | {}, {} | {:.0} | {}/{} | {:.0} / {:.0} / {:.0} | {:.1} / {:.1} |",
            case.label,
            model.particle_count(),
            median(&mut its),
            max_its,
            1e3 * simulation.seconds / last as f64,
            within,
            last,
            drop(5),
            drop(10),
            drop(last),
            100.0 * stretch,
            100.0 * squash,
        );
    }
}
