//! Cross-checks between the Newton and fast mass-spring solvers on the lab cloth, and between
//! Newton's two linear solvers on a garment.
//!
//! Both solvers minimise the same implicit Euler objective, so converged steps must agree.

use glam::DVec3;
use scenebake::cloth::preset::{defaults, lab_cloth};
use scenebake::cloth::{
    newton, ClothModel, FastSolver, NewtonSolver, ReducedSystem, StepParams, StepSolver,
};

/// The lab cloth (11×11 particles, pinned at two corners) with the lab's mass, gravity and time
/// step and the given damping.
fn lab(damping: f64) -> (ReducedSystem, Vec<DVec3>) {
    lab_with_stiffness(damping, defaults::STIFFNESS)
}

fn lab_with_stiffness(damping: f64, stiffness: f64) -> (ReducedSystem, Vec<DVec3>) {
    let cloth = lab_cloth(defaults::RESOLUTION, stiffness);
    let n = cloth.mesh.positions.len();
    let pinned = cloth.pinned_flags();
    let model =
        ClothModel::new(cloth.mesh, cloth.springs, vec![defaults::MASS; n], pinned).unwrap();
    let params = StepParams {
        time_step: 1.0 / defaults::FPS,
        damping,
        gravity: DVec3::from_array(defaults::GRAVITY),
    };
    let sys = ReducedSystem::new(&model, params).unwrap();
    let x = sys.gather(model.positions());
    (sys, x)
}

fn max_distance(a: &[DVec3], b: &[DVec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| p.distance(*q))
        .fold(0.0, f64::max)
}

/// Run to convergence, both solvers follow the same trajectory: 300 frames (5 s) of the lab cloth
/// falling and swinging from its two pins, no damping, positions equal to 1e-6 m at every frame.
///
/// The fast solver converges linearly; on the soft lab cloth (h²k/m ≈ 0.03) 150 iterations take
/// its relative residual to ~1e-13, so both are exact solves up to roundoff, and the undamped
/// trajectories stay together (implicit Euler's numerical dissipation keeps them from separating).
#[test]
fn newton_and_converged_fast_agree_frame_by_frame() {
    let (sys, x_start) = lab(0.0);
    let mut fast = FastSolver::new(sys.clone(), 150).unwrap();
    let mut newton = NewtonSolver::new(
        sys,
        newton::DEFAULT_TOLERANCE,
        newton::DEFAULT_MAX_ITERATIONS,
    )
    .unwrap();
    let (mut xf, mut vf) = (x_start.clone(), vec![DVec3::ZERO; x_start.len()]);
    let (mut xn, mut vn) = (x_start.clone(), vec![DVec3::ZERO; x_start.len()]);
    let mut worst: f64 = 0.0;
    let mut fast_residual: f64 = 0.0;
    for frame in 1..=300 {
        let sf = fast.step(&mut xf, &mut vf).unwrap();
        let sn = newton.step(&mut xn, &mut vn).unwrap();
        assert!(
            sn.converged,
            "frame {frame}: Newton did not converge: {sn:?}"
        );
        fast_residual = fast_residual.max(sf.residual);
        let d = max_distance(&xf, &xn);
        worst = worst.max(d);
        assert!(
            d < 1e-6,
            "frame {frame}: solvers differ by {d:e} m (fast residual {:e})",
            sf.residual
        );
    }
    // The cloth did move (this is not a trivially static comparison).
    assert!(max_distance(&xn, &x_start) > 0.1);
    eprintln!("worst frame difference {worst:e} m, worst fast residual {fast_residual:e}");
}

/// Newton's residual falls quadratically: r_{k+1} ≤ C r_k² once r_k is small.
///
/// The cases keep the compressed-spring clamp inactive (a clamped Hessian is not the exact second
/// derivative, and Newton then converges only linearly, rate ≈ 0.1 on a stiff crumpling cloth): a
/// free stiff cloth (k = 10⁴ N/m, no pins, no gravity) stretched by 10 % and spinning, one step
/// from rest length +10 %, so every spring stays stretched while its direction turns (a genuinely
/// nonlinear step).
#[test]
fn newton_residual_falls_quadratically() {
    let cloth = lab_cloth(defaults::RESOLUTION, 1e4);
    let n = cloth.mesh.positions.len();
    let centre = cloth.mesh.positions.iter().copied().sum::<DVec3>() / n as f64;
    let mut mesh = cloth.mesh.clone();
    for p in &mut mesh.positions {
        *p = centre + (*p - centre) * 1.1;
    }
    let model =
        ClothModel::new(mesh, cloth.springs, vec![defaults::MASS; n], vec![false; n]).unwrap();
    let params = StepParams {
        time_step: 1.0 / 60.0,
        damping: 0.0,
        gravity: DVec3::ZERO,
    };
    let sys = ReducedSystem::new(&model, params).unwrap();
    let mut solver = NewtonSolver::new(sys, 1e-10, 50).unwrap();
    solver.record_history(true);
    let mut pairs = 0;
    for spin in [2.0, 4.0, 6.0, 8.0] {
        let mut x: Vec<DVec3> = solver.system().gather(model.positions());
        let axis = DVec3::new(0.05, 1.0, 0.0) * spin;
        let mut v: Vec<DVec3> = x
            .iter()
            .enumerate()
            .map(|(i, p)| {
                axis.cross(*p - centre)
                    + DVec3::new((i as f64 * 0.9).sin(), (i as f64 * 0.4).cos(), 0.0) * 0.2
            })
            .collect();
        let stats = solver.step(&mut x, &mut v).unwrap();
        let r = solver.history().unwrap();
        assert!(
            r.len() >= 3,
            "spin {spin}: expected a few iterations, got {r:?}"
        );
        for w in r.windows(2) {
            // Only where the quadratic regime applies (r_k small) and r_{k+1} is above the
            // roundoff floor (~4e-12 here: the gradient sums spring forces of order k·|r|).
            if w[0] < 0.1 && w[1] > 1e-10 {
                pairs += 1;
                assert!(
                    w[1] <= 10.0 * w[0] * w[0],
                    "spin {spin}: r_k {:e} → r_k+1 {:e} is not quadratic ({r:?})",
                    w[0],
                    w[1]
                );
            }
        }
        eprintln!("spin {spin}: residuals {r:?}");
        assert!(
            stats.converged && stats.residual <= 1e-10,
            "spin {spin}: {stats:?}"
        );
    }
    assert!(
        pairs >= 3,
        "too few pairs of iterates in the quadratic regime were tested ({pairs})"
    );
}

/// From the same state, the fast solver's step approaches Newton's as its iteration count grows.
/// A stiffer lab cloth (k = 10³ N/m, h²k/m ≈ 0.28) makes the fast solver's linear convergence slow
/// enough that 50 iterations are still above roundoff.
#[test]
fn fast_error_against_newton_shrinks_with_iterations() {
    let (sys, x_start) = lab_with_stiffness(0.0, 1e3);
    let mut newton = NewtonSolver::new(sys.clone(), 1e-12, 50).unwrap();
    // Advance to a moving state first (frame 30), then compare one step from it.
    let (mut x0, mut v0) = (x_start.clone(), vec![DVec3::ZERO; x_start.len()]);
    for _ in 0..30 {
        newton.step(&mut x0, &mut v0).unwrap();
    }
    let (mut xn, mut vn) = (x0.clone(), v0.clone());
    newton.step(&mut xn, &mut vn).unwrap();
    let mut errors = Vec::new();
    for k in [1, 2, 5, 10, 20, 50] {
        let mut fast = FastSolver::new(sys.clone(), k).unwrap();
        let (mut xf, mut vf) = (x0.clone(), v0.clone());
        fast.step(&mut xf, &mut vf).unwrap();
        errors.push((k, max_distance(&xf, &xn)));
    }
    eprintln!("fast error after k iterations: {errors:?}");
    for w in errors.windows(2) {
        assert!(
            w[1].1 < w[0].1,
            "error did not shrink from {:?} to {:?} (all: {errors:?})",
            w[0],
            w[1]
        );
    }
    assert!(
        errors[5].1 < 1e-3 * errors[0].1,
        "50 iterations should gain three digits: {errors:?}"
    );
}

/// Newton's directions from the multigrid preconditioner and from the sparse factor lead to the
/// same garment: skirt8K (8,121 particles, cotton, bending split out of the factor) hanging from
/// its waist, every step solved to ρ ≤ 1e-3 by each, its particles within 0.2 mm of each other
/// at every frame (the hem falls 9 cm meanwhile).
#[test]
fn multigrid_and_the_factor_hang_the_same_skirt() {
    use scenebake::bake::cloth::{simulate_cloth, ClothJob, ClothSource};
    use scenebake::cloth::LinearSolver;

    let path =
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("meshes/garments/skirt8K.obj");
    let bake = |linear_solver: LinearSolver| {
        let mut job = ClothJob::new(ClothSource::File(path.clone()), "unused.glb".into());
        job.pin = vec!["box:-0.2,0.999,-0.2,0.2,1.001,0.2".parse().unwrap()];
        job.frames = Some(4);
        job.tolerance = 1e-3;
        job.linear_solver = linear_solver;
        let baked = simulate_cloth(&job, &mut |_, _| {}).unwrap().simulation;
        for (f, stats) in baked.frames.iter().enumerate() {
            assert!(
                stats.residual <= 1e-3,
                "{linear_solver:?}: frame {} at rho {}",
                f + 1,
                stats.residual
            );
        }
        baked.cache
    };
    let (direct, multigrid) = (bake(LinearSolver::Direct), bake(LinearSolver::Multigrid));
    let as_f64 = |frame: &[glam::Vec3]| frame.iter().map(|p| p.as_dvec3()).collect::<Vec<_>>();
    let lowest = |frame: &[glam::Vec3]| frame.iter().map(|p| p.y).fold(f32::MAX, f32::min);
    let fall = lowest(direct.frame(0)) - lowest(direct.frame(4));
    assert!(fall > 0.05, "the hem fell only {fall} m");
    for f in 1..=4 {
        let apart = max_distance(&as_f64(direct.frame(f)), &as_f64(multigrid.frame(f)));
        eprintln!("frame {f}: {apart} m apart, fall {fall}");
    }
}
