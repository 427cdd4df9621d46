//! Closed-form physics checks, run against both solvers through `make_solver`.

use glam::DVec3;
use scenebake::cloth::springs::{Spring, SpringKind, SpringSet};
use scenebake::cloth::{make_solver, newton, BakeParams, ClothModel, SolverKind, StepSolver};
use scenebake::mesh::Mesh;

const SOLVERS: [SolverKind; 2] = [SolverKind::Fast, SolverKind::Newton];

fn params(solver: SolverKind, damping: f64, gravity: DVec3) -> BakeParams {
    BakeParams {
        frames: 1,
        fps: 60.0,
        substeps: 1,
        splits: 0,
        damping,
        gravity,
        solver,
        iterations: 200,
        tolerance: 1e-12,
        max_newton: newton::DEFAULT_MAX_ITERATIONS,
        sweeps: newton::DEFAULT_SWEEPS,
        threads: 1.into(),
        linear_solver: Default::default(),
        colliders: Default::default(),
        self_contact: None,
        measure_from: 0,
        loop_closure: None,
        wind: None,
    }
}

fn model(
    positions: Vec<DVec3>,
    springs: Vec<Spring>,
    mass: Vec<f64>,
    pinned: Vec<bool>,
) -> ClothModel {
    let mesh = Mesh::from_triangles("physics fixture".into(), positions, Vec::new());
    ClothModel::new(
        mesh,
        SpringSet {
            springs,
            ..SpringSet::default()
        },
        mass,
        pinned,
    )
    .unwrap()
}

/// Steps `solver` from the model's rest state, returning (x, v) of the free particles.
fn run(
    solver: &mut dyn StepSolver,
    start: &[DVec3],
    v0: DVec3,
    steps: usize,
) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut x = solver.system().gather(start);
    let mut v = vec![v0; x.len()];
    for _ in 0..steps {
        let stats = solver.step(&mut x, &mut v).unwrap();
        assert!(stats.residual.is_finite(), "{stats:?}");
    }
    (x, v)
}

/// A free particle (no springs) follows implicit Euler with mass-proportional damping exactly:
/// v₁ = (v₀ + h g)/(1 + h c), x₁ = x₀ + h v₁.
#[test]
fn free_particle_follows_damped_implicit_euler() {
    let gravity = DVec3::new(0.5, -9.81, 0.25);
    let (x_start, v_start) = (DVec3::new(0.0, 2.0, 1.0), DVec3::new(1.0, 3.0, -2.0));
    for solver_kind in SOLVERS {
        for damping in [0.0, 0.7, 5.0] {
            let p = params(solver_kind, damping, gravity);
            let body = model(vec![x_start], Vec::new(), vec![0.3], vec![false]);
            let mut solver = make_solver(&body, &p).unwrap();
            let steps = 120;
            let (x, v) = run(solver.as_mut(), body.positions(), v_start, steps);
            let h = p.time_step();
            let (mut xe, mut ve) = (x_start, v_start);
            for _ in 0..steps {
                ve = (ve + gravity * h) / (1.0 + h * damping);
                xe += ve * h;
            }
            assert!(
                x[0].distance(xe) < 1e-10,
                "{solver_kind:?} c={damping}: x {} vs {xe}",
                x[0]
            );
            assert!(
                v[0].distance(ve) < 1e-9,
                "{solver_kind:?} c={damping}: v {} vs {ve}",
                v[0]
            );
        }
    }
}

/// A mass hanging from a pinned point by one spring comes to rest where k·stretch = m·g.
#[test]
fn hanging_spring_settles_at_the_static_stretch() {
    let (k, m, g, rest) = (40.0, 0.5, 9.81, 1.0);
    for solver_kind in SOLVERS {
        let p = params(solver_kind, 4.0, DVec3::new(0.0, -g, 0.0));
        let spring = Spring {
            a: 0,
            b: 1,
            rest,
            stiffness: k,
            compression: k,
            kind: SpringKind::Stretch,
        };
        let body = model(
            vec![DVec3::new(0.0, 1.0, 0.0), DVec3::ZERO],
            vec![spring],
            vec![1.0, m],
            vec![true, false],
        );
        let mut solver = make_solver(&body, &p).unwrap();
        let (x, v) = run(solver.as_mut(), body.positions(), DVec3::ZERO, 1500);
        let stretch = (1.0 - x[0].y) - rest;
        assert!(
            v[0].length() < 1e-8,
            "{solver_kind:?}: still moving at {}",
            v[0]
        );
        assert!(
            (k * stretch - m * g).abs() < 1e-6 * m * g,
            "{solver_kind:?}: k·stretch {} vs m·g {}",
            k * stretch,
            m * g
        );
        assert!(
            x[0].x.abs() < 1e-12 && x[0].z.abs() < 1e-12,
            "{solver_kind:?}: drifted sideways to {}",
            x[0]
        );
    }
}

/// Two free particles joined by a spring, released stretched with no gravity and no damping:
/// momentum is conserved (the centre of mass stays put) and implicit Euler only loses energy.
#[test]
fn free_spring_conserves_momentum_and_dissipates_energy() {
    let (k, rest) = (50.0, 1.0);
    for solver_kind in SOLVERS {
        let p = params(solver_kind, 0.0, DVec3::ZERO);
        let spring = Spring {
            a: 0,
            b: 1,
            rest,
            stiffness: k,
            compression: k,
            kind: SpringKind::Stretch,
        };
        let start = vec![DVec3::new(-0.75, 0.0, 0.0), DVec3::new(0.75, 0.0, 0.0)];
        let mass = vec![1.0, 3.0];
        let body = model(
            start.clone(),
            vec![spring],
            mass.clone(),
            vec![false, false],
        );
        let mut solver = make_solver(&body, &p).unwrap();
        let energy0 = 0.5 * k * (1.5f64 - rest).powi(2);
        let mut x = solver.system().gather(&start);
        let mut v = vec![DVec3::ZERO; 2];
        let centre0 = (start[0] * mass[0] + start[1] * mass[1]) / 4.0;
        let mut last = energy0;
        for _ in 0..200 {
            solver.step(&mut x, &mut v).unwrap();
            let sys = solver.system();
            let m: Vec<f64> = sys.mass.clone();
            let centre = (x[0] * m[0] + x[1] * m[1]) / 4.0;
            let momentum = v[0] * m[0] + v[1] * m[1];
            assert!(
                centre.distance(centre0) < 1e-9,
                "{solver_kind:?}: centre moved to {centre}"
            );
            assert!(
                momentum.length() < 1e-9,
                "{solver_kind:?}: momentum {momentum}"
            );
            let energy = 0.5 * (m[0] * v[0].length_squared() + m[1] * v[1].length_squared())
                + 0.5 * k * (x[0].distance(x[1]) - rest).powi(2);
            assert!(
                energy <= last + 1e-9,
                "{solver_kind:?}: energy grew {last} → {energy}"
            );
            last = energy;
        }
        assert!(
            last < energy0,
            "{solver_kind:?}: implicit Euler should dissipate"
        );
    }
}
