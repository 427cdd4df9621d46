//! Cloth solver benchmarks: the lab grid at resolution 100 and 200 and `meshes/tableCloth.obj`.
//!
//! ```text
//! cargo bench --bench cloth                 # everything
//! cargo bench --bench cloth -- lab100       # one scene
//! ```
//!
//! Per scene:
//! - `fast/factor`: `FastSolver::new` (assembly, symbolic analysis, numeric factor of the n×n
//!   matrix);
//! - `fast/solve3`, `fast/solve4`: both triangular sweeps (three right-hand sides) with the
//!   exact f64 factor, on `DVec3` and on padded `Lanes4` (the solver's global step before the f32
//!   factor);
//! - `fast/solve4f`: the sweeps the solver's global step uses (f32 factor and f32 lanes when it
//!   picked them, see `FastSolver::new`); solve4 and solve4f copy a fresh right-hand side first
//!   (≈ 10 µs at 100×100), since repeated in-place solves decay towards zero;
//! - `fast/step_1`, `fast/step_10`: a whole time step with 1 and 10 local/global iterations; one
//!   iteration costs (step_10 − step_1)/9, and step_10 is the default frame;
//! - `newton/factor`: Hessian assembly plus numeric refactorisation of the 3n×3n matrix (what
//!   each Newton iteration pays besides the solve and the line search; in single precision
//!   where the factor is supernodal, as Newton factors by default);
//! - `newton/iteration`: one Newton iteration (assemblies, factorisation, solve, line search);
//! - `newton/step`: a whole time step to the default tolerance (skipped when that takes more
//!   than 10 iterations, as on tableCloth where the 50-iteration cap is hit: multiply instead).
//!
//! Steps start from the same moving state (10 frames after release) every time. The number of
//! Newton iterations that state needs is printed once per scene.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use glam::DVec3;
use scenebake::cloth::fast::GlobalFactor;
use scenebake::cloth::linalg::{Cholesky, Lanes4, Lanes4f};
use scenebake::cloth::model::masses_from_area;
use scenebake::cloth::pins::PinSpec;
use scenebake::cloth::preset::{defaults, lab_cloth};
use scenebake::cloth::springs::surface_springs;
use scenebake::cloth::{
    newton, ClothModel, FastSolver, NewtonSolver, ReducedSystem, StepParams, StepSolver,
};
use scenebake::io::obj::{load_obj, ObjOptions};

struct Scene {
    name: &'static str,
    sys: ReducedSystem,
    x: Vec<DVec3>,
    v: Vec<DVec3>,
}

fn settle(sys: &ReducedSystem, start: &[DVec3]) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut solver = FastSolver::new(sys.clone(), 10).unwrap();
    let mut x = sys.gather(start);
    let mut v = vec![DVec3::ZERO; x.len()];
    for _ in 0..10 {
        solver.step(&mut x, &mut v).unwrap();
    }
    (x, v)
}

fn lab(name: &'static str, resolution: u32) -> Scene {
    let cloth = lab_cloth(resolution, defaults::STIFFNESS);
    let n = cloth.mesh.positions.len();
    let pinned = cloth.pinned_flags();
    let model =
        ClothModel::new(cloth.mesh, cloth.springs, vec![defaults::MASS; n], pinned).unwrap();
    let params = StepParams {
        time_step: 1.0 / defaults::FPS,
        damping: defaults::DAMPING,
        gravity: DVec3::from_array(defaults::GRAVITY),
    };
    let sys = ReducedSystem::new(&model, params).unwrap();
    let (x, v) = settle(&sys, model.positions());
    Scene { name, sys, x, v }
}

/// tableCloth.obj (14,161 particles) with the CLI's file defaults (k = 1000 N/m, bending 2 N/m,
/// 0.2 kg/m², damping 0.5/s, 30 fps, g = 9.81 m/s²), pinned along its x = −0.48 m edge.
fn table_cloth() -> Option<Scene> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/tableCloth.obj");
    if !path.exists() {
        eprintln!("skipping tablecloth: {} not found", path.display());
        return None;
    }
    let mesh = load_obj(&path, &ObjOptions::default()).unwrap();
    let springs = surface_springs(&mesh, 1000.0, 2.0);
    let mass = masses_from_area(&mesh, 0.2);
    let pin: PinSpec = "box:-0.49,0.9,-0.4,-0.47,1.0,0.4".parse().unwrap();
    let mut pinned = vec![false; mesh.positions.len()];
    for i in pin.select(&mesh).unwrap() {
        pinned[i as usize] = true;
    }
    let model = ClothModel::new(mesh, springs, mass, pinned).unwrap();
    let params = StepParams {
        time_step: 1.0 / 30.0,
        damping: 0.5,
        gravity: DVec3::new(0.0, -9.81, 0.0),
    };
    let sys = ReducedSystem::new(&model, params).unwrap();
    let (x, v) = settle(&sys, model.positions());
    Some(Scene {
        name: "tablecloth",
        sys,
        x,
        v,
    })
}

fn bench_scene(c: &mut Criterion, scene: &Scene) {
    let Scene { name, sys, x, v } = scene;
    let mut newton = NewtonSolver::new(
        sys.clone(),
        newton::DEFAULT_TOLERANCE,
        newton::DEFAULT_MAX_ITERATIONS,
    )
    .unwrap();
    let fast = FastSolver::new(sys.clone(), 10).unwrap();
    let newton_iterations = {
        let (mut xs, mut vs) = (x.clone(), v.clone());
        let stats = newton.step(&mut xs, &mut vs).unwrap();
        let mut f = FastSolver::new(sys.clone(), 10).unwrap();
        let (mut xf, mut vf) = (x.clone(), v.clone());
        let fs = f.step(&mut xf, &mut vf).unwrap();
        eprintln!(
            "{name}: {} free particles, {} springs, {} anchors; fast factor nnz {} ({}, rate \
             {:.1e}); Newton Hessian nnz {}, factor nnz {} ({}); Newton step: {} iterations, \
             residual {:.1e}; fast 10 iterations: residual {:.1e}",
            sys.len(),
            sys.springs.a.len(),
            sys.anchors.a.len(),
            fast.factor().nnz(),
            if fast.factor().is_single() {
                "f32"
            } else {
                "f64"
            },
            fast.factor_rate(),
            newton.hessian_nnz(),
            newton.factor_nnz(),
            if newton.is_supernodal() {
                "supernodal"
            } else {
                "simplicial"
            },
            stats.iterations,
            stats.residual,
            fs.residual,
        );
        stats.iterations
    };

    let mut g = c.benchmark_group(*name);
    g.sample_size(10).warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(3));
    g.bench_function("fast/factor", |b| {
        b.iter(|| FastSolver::new(black_box(sys.clone()), 10).unwrap())
    });
    let exact = Cholesky::new(&FastSolver::matrix(sys)).unwrap();
    let mut rhs = x.clone();
    g.bench_function("fast/solve3", |b| {
        b.iter(|| {
            exact.solve3(black_box(&mut rhs));
        })
    });
    let src4: Vec<Lanes4> = x.iter().map(|p| Lanes4::from_vec3(*p)).collect();
    let mut rhs4 = src4.clone();
    g.bench_function("fast/solve4", |b| {
        b.iter(|| {
            rhs4.copy_from_slice(&src4);
            exact.solve4(black_box(&mut rhs4));
        })
    });
    match fast.factor() {
        GlobalFactor::Single(f) => {
            let src: Vec<Lanes4f> = src4.iter().map(|p| Lanes4f::from_lanes4(*p)).collect();
            let mut rhs = src.clone();
            g.bench_function("fast/solve4f", |b| {
                b.iter(|| {
                    rhs.copy_from_slice(&src);
                    f.solve4f(black_box(&mut rhs));
                })
            });
        }
        GlobalFactor::Double(_) => eprintln!("{name}: the solver keeps the f64 factor"),
    }
    for k in [1, 10] {
        let mut solver = FastSolver::new(sys.clone(), k).unwrap();
        let (mut xs, mut vs) = (x.clone(), v.clone());
        g.bench_function(format!("fast/step_{k}"), |b| {
            b.iter(|| {
                xs.copy_from_slice(x);
                vs.copy_from_slice(v);
                solver.step(&mut xs, &mut vs).unwrap()
            })
        });
    }
    g.bench_function("newton/factor", |b| {
        b.iter(|| newton.factorize_at(black_box(x)).unwrap())
    });
    // One Newton iteration: two assemblies, one factorisation, one solve, the line search.
    let mut one = NewtonSolver::new(sys.clone(), 0.0, 1).unwrap();
    let (mut xs, mut vs) = (x.clone(), v.clone());
    g.bench_function("newton/iteration", |b| {
        b.iter(|| {
            xs.copy_from_slice(x);
            vs.copy_from_slice(v);
            one.step(&mut xs, &mut vs).unwrap()
        })
    });
    if newton_iterations <= 10 {
        g.bench_function("newton/step", |b| {
            b.iter(|| {
                xs.copy_from_slice(x);
                vs.copy_from_slice(v);
                newton.step(&mut xs, &mut vs).unwrap()
            })
        });
    } else {
        eprintln!(
            "{name}: newton/step skipped ({newton_iterations} iterations; see newton/iteration)"
        );
    }
    g.finish();
}

fn benches(c: &mut Criterion) {
    bench_scene(c, &lab("lab100", 100));
    bench_scene(c, &lab("lab200", 200));
    if let Some(scene) = table_cloth() {
        bench_scene(c, &scene);
    }
}

criterion_group!(cloth, benches);
criterion_main!(cloth);
