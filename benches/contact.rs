//! The cost of collisions: one time step of a cloth lying on a table, with and without the table.
//!
//! ```text
//! cargo bench --bench contact
//! ```
//!
//! Scenes (prepared through the library exactly as `scenebake cloth` does):
//! - `tablecloth`: `meshes/tableCloth.obj` (14,161 particles, k = 100 N/m, 0.5 kg/m², 30 fps,
//!   fast solver, 10 iterations) dropped onto a 0.30 × 0.30 m box table and settled for 30
//!   frames, so about 2,000 particles rest on the top;
//! - `sheet30`: `meshes/plane_30x30.obj` (961 particles, defaults) draped over a box for 30
//!   frames, both solvers.
//!
//! Per scene and solver: `free` steps from the settled state with no collider (the cloth just
//! falls), `box` with the box; the difference is what contact handling costs per step.

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use glam::{DVec3, Vec3};
use scenebake::bake::cloth::{
    simulate_cloth, ClothJob, ClothSource, PreparedCloth, SimulatedCloth,
};
use scenebake::cloth::collide::ColliderSpec;
use scenebake::cloth::{make_solver, BakeParams, SolverKind};

struct Scene {
    name: &'static str,
    prepared: PreparedCloth,
    /// Positions (m) and velocities (m/s) of every particle, in the model's order.
    x: Vec<DVec3>,
    v: Vec<DVec3>,
}

fn settled(name: &'static str, input: &str, solver: SolverKind, table: ColliderSpec) -> Scene {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("meshes")
        .join(input);
    let mut job = ClothJob::new(ClothSource::File(path), PathBuf::from("unused.glb"));
    job.solver = solver;
    job.frames = Some(30);
    job.collider = vec![table];
    if input == "tableCloth.obj" {
        job.stiffness = Some(100.0);
        job.density = Some(0.5);
    }
    let SimulatedCloth {
        prepared,
        simulation,
    } = simulate_cloth(&job, &mut |_, _| {}).unwrap();
    let x: Vec<DVec3> = simulation
        .cache
        .frame(30)
        .iter()
        .map(Vec3::as_dvec3)
        .collect();
    let v = x
        .iter()
        .zip(simulation.cache.frame(29))
        .map(|(a, b)| (*a - b.as_dvec3()) * prepared.params.fps)
        .collect();
    Scene {
        name,
        prepared,
        x,
        v,
    }
}

fn bench_scene(c: &mut Criterion, scene: &Scene) {
    let mut g = c.benchmark_group(scene.name);
    g.sample_size(10).warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(4));
    let with_table = &scene.prepared.params;
    let free = BakeParams {
        colliders: Default::default(),
        self_contact: None,
        ..with_table.clone()
    };
    for (label, params) in [("free", &free), ("box", with_table)] {
        let mut solver = make_solver(&scene.prepared.model, params).unwrap();
        let (x0, v0) = (
            solver.system().gather(&scene.x),
            solver.system().gather(&scene.v),
        );
        let (mut x, mut v) = (x0.clone(), v0.clone());
        let stats = solver.step(&mut x, &mut v).unwrap();
        eprintln!(
            "{} {label} {:?}: {} particles in contact, {} iterations",
            scene.name, params.solver, stats.contacts, stats.iterations
        );
        g.bench_function(format!("{:?}/{label}", params.solver).to_lowercase(), |b| {
            b.iter(|| {
                x.copy_from_slice(&x0);
                v.copy_from_slice(&v0);
                black_box(solver.step(&mut x, &mut v).unwrap())
            })
        });
    }
    g.finish();
}

fn benches(c: &mut Criterion) {
    let table = ColliderSpec::Box(DVec3::new(-0.28, 0.0, -0.15), DVec3::new(0.02, 0.9, 0.15));
    bench_scene(
        c,
        &settled("tablecloth", "tableCloth.obj", SolverKind::Fast, table),
    );
    let block = ColliderSpec::Box(
        DVec3::new(-0.25, -1.0, -0.25),
        DVec3::new(0.25, -0.05, 0.25),
    );
    for solver in [SolverKind::Fast, SolverKind::Newton] {
        bench_scene(
            c,
            &settled("sheet30", "plane_30x30.obj", solver, block.clone()),
        );
    }
}

criterion_group!(contact, benches);
criterion_main!(contact);
