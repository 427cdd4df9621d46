//! Physical materials and converged steps: the tolerance is honoured (residuals recomputed here
//! from the positions, independently of the solvers), the same fabric on different meshes moves
//! alike, and the default bake agrees with a tightly converged Newton solve on a garment.

use crate::common;

use std::path::{Path, PathBuf};

use scenebake::bake::cloth::{prepare_cloth, ClothJob, ClothSource, PreparedCloth};
use scenebake::cloth::law::{JAM_RAMP, TOE_STRAIN};
use scenebake::cloth::material::DEFAULT_JAM_STRAIN;
use scenebake::cloth::membrane::MembraneModel;
use scenebake::cloth::pins::PinSpec;
use scenebake::cloth::{make_solver, simulate, StepSolver};
use scenebake::glam::DVec3;

/// ρ = ‖∇g‖ / ‖M·g‖ over the free particles for the step from (x₋₂, x₋₁) to x, evaluated from
/// the model's springs, bending stencils and masses with this file's own formulas:
/// ∇g = s·m/h²·(x − y) + Σ k(|r| − l)·r/|r| + Σ wᵢ(Σ wⱼxⱼ − target), y = x₋₁ + (h·v + h²·g)/s,
/// the bending target the rest mesh's curvature turned by each hinge's frame at x₋₁, springs
/// jamming around the compression strain `jam`: the tension stiffness adds back along a
/// smoothstep ramp from (1 − JAM_RAMP)·jam to (1 + JAM_RAMP)·jam; and with a toe in tension:
/// the stiffness rises linearly from kc to k over the first TOE_STRAIN of stretch. Also returns
/// how many springs are on or past their ramp.
fn recomputed_residual(
    p: &PreparedCloth,
    jam: f64,
    xm2: &[DVec3],
    xm1: &[DVec3],
    x: &[DVec3],
) -> (f64, usize) {
    let mut jammed = 0;
    let m = &p.model;
    let h = p.params.time_step();
    let s = 1.0 + h * p.params.damping;
    let g = p.params.gravity;
    let mut grad: Vec<DVec3> = (0..x.len())
        .map(|i| {
            let v = (xm1[i] - xm2[i]) / h;
            let y = xm1[i] + (v * h + g * h * h) / s;
            (x[i] - y) * (s * m.mass[i] / (h * h))
        })
        .collect();
    for sp in &m.springs {
        let (a, b) = (sp.a as usize, sp.b as usize);
        let r = x[a] - x[b];
        let len = r.length();
        let e = len - sp.rest;
        // Tension k·e, or with a toe t (kc < k) ∫₀ᵉ stiffness: kc·e + (k − kc)·e²/(2t) within
        // it and kc·t + (k − kc)·t/2 + k·(e − t) past it; compression kc·e, minus k·∫ramp once
        // jamming (kc < k): with the compression c = −e, the ramp [c0, c1] of width w and
        // σ = (c − c0)/w, ∫ (3σ² − 2σ³) dc = w·(σ³ − σ⁴/2) on the ramp and w/2 + (c − c1) past it.
        let (c0, c1) = (
            (1.0 - JAM_RAMP) * jam * sp.rest,
            (1.0 + JAM_RAMP) * jam * sp.rest,
        );
        let toe = TOE_STRAIN * sp.rest;
        let (k, kc) = (sp.stiffness, sp.compression);
        let tension = if e >= 0.0 && kc < k {
            if e < toe {
                kc * e + (k - kc) * e * e / (2.0 * toe)
            } else {
                kc * toe + (k - kc) * toe / 2.0 + k * (e - toe)
            }
        } else if e >= 0.0 {
            k * e
        } else if kc < k && -e > c0 {
            jammed += 1;
            let (c, w) = (-e, c1 - c0);
            let ramp = if c < c1 {
                let sigma = (c - c0) / w;
                w * (sigma.powi(3) - sigma.powi(4) / 2.0)
            } else {
                w / 2.0 + (c - c1)
            };
            kc * e - k * ramp
        } else {
            kc * e
        };
        let f = r * (tension / len);
        grad[a] += f;
        grad[b] -= f;
    }
    // The curved rest: Σ wᵢ xᵢ of the rest mesh in the hinge's frame (unit edge t, the normal
    // n ∝ t × (x_o0 − x_o1), t × n), turned by the frame at the step's start.
    let frame = |p: [DVec3; 4]| {
        let t = (p[1] - p[0]).normalize();
        let n = t.cross(p[2] - p[3]).normalize();
        [t, n, t.cross(n)]
    };
    let rest = &m.mesh.positions;
    for st in &m.bending {
        let corners = |x: &[DVec3]| st.vertices.map(|v| x[v as usize]);
        let at_rest: DVec3 = (0..4)
            .map(|i| rest[st.vertices[i] as usize] * st.weights[i])
            .sum();
        let [t0, n0, b0] = frame(corners(rest));
        let [t, n, b] = frame(corners(xm1));
        let target = t * at_rest.dot(t0) + n * at_rest.dot(n0) + b * at_rest.dot(b0);
        let sum: DVec3 = (0..4)
            .map(|i| x[st.vertices[i] as usize] * st.weights[i])
            .sum::<DVec3>()
            - target;
        for i in 0..4 {
            grad[st.vertices[i] as usize] += sum * st.weights[i];
        }
    }
    let (mut num, mut weight) = (0.0, 0.0);
    for ((g, pinned), mass) in grad.iter().zip(&m.pinned).zip(&m.mass) {
        if !pinned {
            num += g.length_squared();
            weight += mass * mass;
        }
    }
    (num.sqrt() / (weight.sqrt() * g.length().max(1.0)), jammed)
}

/// A 1 m sheet lying in the horizontal plane y = 1, `cells`² cells, every interior vertex
/// jittered by `jitter` cells in the plane.
fn sheet(dir: &Path, name: &str, cells: u32, jitter: f64) -> PathBuf {
    let n = cells + 1;
    let h = 1.0 / cells as f64;
    let mut obj = String::new();
    for i in 0..n {
        for j in 0..n {
            let interior = i > 0 && j > 0 && i < cells && j < cells;
            let t = (i * 7919 + j * 104_729) as f64;
            let (dx, dy) = if interior {
                (jitter * h * (t * 0.37).sin(), jitter * h * (t * 0.73).cos())
            } else {
                (0.0, 0.0)
            };
            obj += &format!("v {} 1 {}\n", j as f64 * h + dx, i as f64 * h + dy);
        }
    }
    for i in 0..cells {
        for j in 0..cells {
            let v = |a: u32, b: u32| a * n + b + 1;
            obj += &format!("f {} {} {}\n", v(i, j), v(i + 1, j), v(i + 1, j + 1));
            obj += &format!("f {} {} {}\n", v(i, j), v(i + 1, j + 1), v(i, j + 1));
        }
    }
    let path = dir.join(name);
    std::fs::write(&path, obj).unwrap();
    path
}

/// The centre of mass of the free particles (the pinned strip, a half cell wide, is 2.5 % of
/// the coarse sheet and 0.8 % of the fine one).
fn centroid(mass: &[f64], pinned: &[bool], frame: &[scenebake::glam::Vec3]) -> DVec3 {
    assert_eq!(mass.len(), frame.len());
    let free = || frame.iter().zip(mass).zip(pinned).filter(|(_, p)| !**p);
    let total: f64 = free().map(|((_, m), _)| *m).sum();
    free().map(|((x, m), _)| x.as_dvec3() * *m).sum::<DVec3>() / total
}

/// The same cotton sheet as a regular 21×21 grid and as a 61×61 grid with every interior vertex
/// jittered by up to 0.15 cells, lying level and pinned along one edge, swings down for 2 s: the
/// centroid paths agree within 3 cm (measured: 1.7 cm). An edge-spring network's stiffness
/// depends on its edges' directions: the triangle membrane's test below measures that.
#[test]
fn the_same_fabric_moves_alike_on_a_coarse_and_a_fine_irregular_mesh() {
    let worst = paths_apart([(20, 0.0), (60, 0.15)], MembraneModel::Springs);
    assert!(worst < 0.03, "centroid paths {worst} m apart");
}

/// The triangle membrane (`--membrane triangles`) makes the response independent of the
/// triangulation: the 61×61 sheet, regular and with every interior vertex jittered by 0.3
/// cells, moves alike: centroid paths at most 1 mm apart (measured: 0.05 mm), where the edge
/// springs' are more than 1 cm apart (measured: 2.1 cm).
#[test]
fn the_triangle_membrane_moves_alike_whatever_the_triangulation() {
    let springs = paths_apart([(60, 0.0), (60, 0.3)], MembraneModel::Springs);
    let triangles = paths_apart([(60, 0.0), (60, 0.3)], MembraneModel::Triangles);
    assert!(springs > 0.01, "edge springs {springs} m apart");
    assert!(triangles < 1e-3, "triangle membrane {triangles} m apart");
}

/// The largest distance between the centroid paths of the cotton sheet meshed as each of
/// `meshes` (a grid of that many cells a side, every interior vertex jittered by up to that
/// many cells), lying level and pinned along one edge, swinging down for 2 s.
fn paths_apart(meshes: [(u32, f64); 2], membrane: MembraneModel) -> f64 {
    let dir = tempfile::tempdir().unwrap();
    let mut paths = Vec::new();
    for (k, (cells, jitter)) in meshes.into_iter().enumerate() {
        let mesh = sheet(dir.path(), &format!("{k}.obj"), cells, jitter);
        let mut job = ClothJob::new(ClothSource::File(mesh), dir.path().join("x.glb"));
        job.frames = Some(60);
        job.membrane = Some(membrane);
        job.pin = vec!["box:-0.001,0.9,-1,0.001,1.1,2".parse::<PinSpec>().unwrap()];
        let p = prepare_cloth(&job).unwrap();
        let mut solver = make_solver(&p.model, &p.params).unwrap();
        let sim = simulate(&p.model, solver.as_mut(), &p.params, &mut |_| {}).unwrap();
        assert!(sim.frames.iter().all(|f| f.converged), "{membrane:?}");
        let path: Vec<DVec3> = (0..=60)
            .map(|k| centroid(&p.model.mass, &p.model.pinned, sim.cache.frame(k)))
            .collect();
        paths.push(path);
    }
    let travel = paths[0][0].distance(paths[0][60]);
    assert!(travel > 0.1, "the sheet moved {travel} m");
    let worst = paths[0]
        .iter()
        .zip(&paths[1])
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    eprintln!("{membrane:?}, {meshes:?}: centroid paths {worst} m apart");
    worst
}

/// Newton's split factor (the default, [`BendingFactor::Split`]: each bending stencil's
/// opposite pair left out of the factored matrix, the direction by conjugate gradients on the
/// whole Hessian) and the whole factor (a direct solve with the Hessian itself) end the same
/// steps within the tolerance, both within 1 cm of a solve to ρ ≤ 1e-3 with the whole factor
/// (RMS within 2 mm), on the robot's skirt (1,560 vertices) hanging from its waist, five steps,
/// each started from that tight solve, the split factor in at most 25 % (+ 2) more Newton
/// iterations than the whole one. The split directions take a handful of gradients each (about
/// six on the garments, at most 15 here).
#[test]
fn the_split_factor_takes_the_whole_factors_steps_on_a_garment() {
    use scenebake::cloth::newton::DEFAULT_SWEEPS;
    use scenebake::cloth::system::ReducedSystem;
    use scenebake::cloth::{BendingFactor, NewtonSolver};

    let mut job = ClothJob::new(
        ClothSource::File(common::crate_dir().join("meshes/garments/robot_skirt.obj")),
        PathBuf::from("unused.glb"),
    );
    job.pin = vec!["box:-1,0.559,-1,1,0.561,1.5".parse::<PinSpec>().unwrap()];
    let p = prepare_cloth(&job).unwrap();
    let sys = ReducedSystem::with_coupling(
        &p.model,
        p.params.step_params(),
        BendingFactor::Split.coupling(),
    )
    .unwrap();
    let tolerance = p.params.tolerance;
    let solver = |bending, tolerance, cap| {
        NewtonSolver::with_bending_factor(sys.clone(), tolerance, cap, bending)
            .unwrap()
            .with_sweeps(DEFAULT_SWEEPS)
    };
    let mut split = solver(BendingFactor::Split, tolerance, p.params.max_newton);
    let mut whole = solver(BendingFactor::Whole, tolerance, p.params.max_newton);
    let mut tight = solver(BendingFactor::Whole, 1e-3, 300);
    let [with_split, with_whole] = steps_beside_a_tight_solve(
        [("split factor", &mut split), ("whole factor", &mut whole)],
        &mut tight,
        sys.gather(p.model.positions()),
    );
    // Sweeps alone converge these steps even from a useless direction (a reversed one took
    // 283 iterations): the split directions must be as good as the whole factor's (23 and 23).
    assert!(
        4 * with_split <= 5 * with_whole + 8,
        "{with_split} Newton iterations with the split factor, {with_whole} with the whole"
    );
    let (on, gradients, directions) = split.conjugate_gradients();
    assert!(on && directions > 0, "{on} {directions}");
    assert!(
        gradients <= 15 * directions,
        "{gradients} gradients over {directions} directions"
    );
    assert!(!whole.conjugate_gradients().0);
}

/// Five steps from rest (`x`, solver order) of two solvers and a tight one, each of the two
/// started every step from the tight solver's state: all three must converge, and each of the
/// two must end within 1 cm of the tight step (RMS within 2 mm). Returns the two solvers'
/// Newton iterations.
fn steps_beside_a_tight_solve(
    solvers: [(&str, &mut dyn StepSolver); 2],
    tight: &mut dyn StepSolver,
    mut x: Vec<DVec3>,
) -> [usize; 2] {
    let mut v = vec![DVec3::ZERO; x.len()];
    let [(la, a), (lb, b)] = solvers;
    let mut iterations = [0; 2];
    for step in 1..=5 {
        let (mut xa, mut va) = (x.clone(), v.clone());
        let (mut xb, mut vb) = (x.clone(), v.clone());
        let sa = a.step(&mut xa, &mut va).unwrap();
        let sb = b.step(&mut xb, &mut vb).unwrap();
        let t = tight.step(&mut x, &mut v).unwrap();
        assert!(
            sa.converged && sb.converged && t.converged,
            "step {step}: {sa:?} {sb:?} {t:?}"
        );
        iterations[0] += sa.iterations;
        iterations[1] += sb.iterations;
        for (label, ours) in [(la, &xa), (lb, &xb)] {
            let worst = ours
                .iter()
                .zip(&x)
                .map(|(a, b)| a.distance(*b))
                .fold(0.0, f64::max);
            let sum: f64 = ours
                .iter()
                .zip(&x)
                .map(|(a, b)| a.distance_squared(*b))
                .sum();
            let rms = (sum / x.len() as f64).sqrt();
            assert!(
                worst < 1e-2 && rms < 2e-3,
                "step {step}, {label}: {worst} m from the tight solve, RMS {rms} m"
            );
        }
    }
    iterations
}

/// The circle skirt pinned at its waist, default cotton (nothing is written).
fn hanging_circle_skirt() -> ClothJob {
    let mut job = ClothJob::new(
        ClothSource::File(common::crate_dir().join("meshes/garments/circle_skirt.obj")),
        PathBuf::from("unused.glb"),
    );
    job.pin = vec!["box:-0.2,0.999,-0.2,0.2,1.001,0.2"
        .parse::<PinSpec>()
        .unwrap()];
    job
}

/// Steps of the default bake of a garment end at or below the tolerance, measured by this
/// file's own residual from the f64 positions, and steps above it are reported unconverged; the
/// same with a low `--jam-strain` (3 %), which this file's residual takes from the job: springs
/// must jam there, and the solver must have used that strain for its residual to agree (its
/// steps may stop at the iteration cap, but then flagged).
#[test]
fn the_tolerance_is_honoured_on_a_garment() {
    for jam in [None, Some(0.03)] {
        let mut job = hanging_circle_skirt();
        job.jam_strain = jam;
        let strain = jam.unwrap_or(DEFAULT_JAM_STRAIN);
        let p = prepare_cloth(&job).unwrap();
        let mut solver = make_solver(&p.model, &p.params).unwrap();
        let sys = solver.system().clone();
        let all0 = p.model.positions().to_vec();
        let mut x = sys.gather(&all0);
        let mut v = vec![DVec3::ZERO; x.len()];
        let (mut prev2, mut prev1) = (all0.clone(), all0.clone());
        let mut jammed = 0;
        for step in 1..=6 {
            let stats = solver.step(&mut x, &mut v).unwrap();
            let mut all = prev1.clone();
            sys.scatter(&x, &mut all);
            let (rho, j) = recomputed_residual(&p, strain, &prev2, &prev1, &all);
            jammed = jammed.max(j);
            assert!(
                (rho - stats.residual).abs() <= 1e-6 + 1e-6 * rho,
                "jam {strain}, step {step}: solver says {}, recomputed {rho}",
                stats.residual
            );
            assert_eq!(stats.converged, rho <= p.params.tolerance, "step {step}");
            // The default converges; at 3 % a jammed skirt may stop at the cap, flagged.
            assert!(jam.is_some() || stats.converged, "step {step}: {stats:?}");
            prev2 = std::mem::replace(&mut prev1, all);
        }
        if jam.is_some() {
            assert!(jammed > 0, "no spring compressed past {strain}");
        }
    }
}

/// `--jam-strain` outside (0, 1) is refused with an error naming the option.
#[test]
fn a_jam_strain_outside_zero_to_one_is_refused() {
    for bad in [0.0, 1.0, -0.1, f64::NAN] {
        let mut job = ClothJob::new(
            ClothSource::File(common::crate_dir().join("meshes/garments/circle_skirt.obj")),
            PathBuf::from("unused.glb"),
        );
        job.jam_strain = Some(bad);
        let message = match prepare_cloth(&job) {
            Ok(_) => panic!("jam strain {bad} accepted"),
            Err(e) => e.to_string(),
        };
        assert!(
            message.contains("jam_strain") && message.contains("between 0 and 1"),
            "{message}"
        );
    }
}

/// Gauss–Seidel sweeps between Newton iterations (`--sweeps`) change how many iterations a step
/// takes, not where it ends. On a cotton sheet (bending stencils, springs with a toe and a
/// jamming ramp) one step solved by Newton to ρ ≤ 1e-8 without sweeps is a fixed point of the
/// sweeps: a pass moves no particle by more than 1e-8 m, which holds only if each local step
/// uses the objective's own gradient; from that state disturbed by 1 mm a pass lowers the
/// objective ([`ReducedSystem::objective`]) by more than 90 % of its excess. On a garment
/// hanging from its waist, five steps, each started from a solve to ρ ≤ 1e-3 without sweeps,
/// end within the tolerance 0.1 with the default sweeps and without, both within 1 cm of that
/// solve (RMS within 2 mm; the step falling hardest, the third, is the worst: 7.7 and 5.7 mm),
/// the sweeps taking under half the Newton iterations (29 against 60).
#[test]
fn gauss_seidel_sweeps_shorten_newton_without_moving_its_solution() {
    use scenebake::cloth::newton::{NewtonSolver, DEFAULT_SWEEPS};
    use scenebake::cloth::smooth::{Smoother, SweepScratch};
    use scenebake::cloth::system::ReducedSystem;

    let dir = tempfile::tempdir().unwrap();
    let mesh = sheet(dir.path(), "sheet.obj", 20, 0.1);
    let mut job = ClothJob::new(ClothSource::File(mesh), dir.path().join("x.glb"));
    job.pin = vec!["box:-0.001,0.9,-1,0.001,1.1,2".parse::<PinSpec>().unwrap()];
    let p = prepare_cloth(&job).unwrap();
    let sys = ReducedSystem::new(&p.model, p.params.step_params()).unwrap();
    let x0 = sys.gather(p.model.positions());
    let v0 = vec![DVec3::ZERO; x0.len()];
    let mut y = vec![DVec3::ZERO; x0.len()];
    sys.predict(&x0, &v0, &mut y);
    let mut newton = NewtonSolver::new(sys.clone(), 1e-8, 50).unwrap();
    let (mut x, mut v) = (x0.clone(), v0.clone());
    let stats = newton.step(&mut x, &mut v).unwrap();
    assert!(stats.converged, "{stats:?}");
    let smoother = Smoother::new(&sys);
    let mut scratch = SweepScratch::default();
    let mut swept = x.clone();
    smoother.sweep(
        &sys,
        &mut swept,
        &y,
        DEFAULT_SWEEPS,
        None,
        &mut scratch,
        false,
    );
    let moved = swept
        .iter()
        .zip(&x)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    assert!(
        moved < 1e-8,
        "a pass moved a converged particle by {moved} m"
    );
    let fell = x0[0].y - x[0].y;
    assert!(fell > 1e-3, "the step moved the sheet by {fell} m only");
    let mut disturbed: Vec<DVec3> = x
        .iter()
        .enumerate()
        .map(|(i, p)| *p + DVec3::new((i as f64).sin(), (1.7 * i as f64).cos(), 0.5) * 1e-3)
        .collect();
    let before = sys.objective(&disturbed, &y);
    smoother.sweep(
        &sys,
        &mut disturbed,
        &y,
        DEFAULT_SWEEPS,
        None,
        &mut scratch,
        false,
    );
    let after = sys.objective(&disturbed, &y);
    let floor = sys.objective(&x, &y);
    assert!(
        after - floor < 0.1 * (before - floor),
        "objective {before} -> {after}, minimum {floor}"
    );

    let p = prepare_cloth(&hanging_circle_skirt()).unwrap();
    assert_eq!(p.params.sweeps, DEFAULT_SWEEPS);
    let mut with = make_solver(&p.model, &p.params).unwrap();
    let mut params = p.params.clone();
    params.sweeps = 0;
    let mut without = make_solver(&p.model, &params).unwrap();
    params.tolerance = 1e-3;
    params.max_newton = 300;
    let mut tight = make_solver(&p.model, &params).unwrap();
    let x = with.system().gather(p.model.positions());
    let [ia, ib] = steps_beside_a_tight_solve(
        [
            ("with sweeps", with.as_mut()),
            ("without sweeps", without.as_mut()),
        ],
        tight.as_mut(),
        x,
    );
    assert!(2 * ia < ib, "{ia} iterations with sweeps, {ib} without");
}

/// With two threads (`--threads 2`) Newton's sweeps move a garment's two halves at once, and
/// the bake is the same to the bit as on one thread: hanging from its waist, and dropped onto a
/// sphere (the sweeps' barrier planes), three frames each, and when a second thread comes free
/// after the first frame (a scene's share of the cores). The circle skirt is split: neither
/// half holds less than a third of its particles.
#[test]
fn two_threads_bake_the_same_garment_as_one() {
    use scenebake::cloth::collide::ColliderSpec;
    use scenebake::cloth::newton::{BendingFactor, NewtonSolver};
    use scenebake::cloth::smooth::Smoother;
    use scenebake::cloth::system::ReducedSystem;
    use scenebake::cores::{CoreShare, Threads};

    let hanging = hanging_circle_skirt();
    let mut dropped = hanging.clone();
    dropped.pin.clear();
    dropped.collider = vec!["sphere:0,0.55,0,0.3".parse::<ColliderSpec>().unwrap()];
    for (name, mut job) in [("hanging", hanging), ("dropped on a sphere", dropped)] {
        job.frames = Some(3);
        let p = prepare_cloth(&job).unwrap();
        let sys = ReducedSystem::new(&p.model, p.params.step_params()).unwrap();
        let (a, b) = Smoother::new(&sys).parts();
        assert!(
            3 * a.min(b) > sys.len(),
            "{name}: parts of {a} and {b} of {}",
            sys.len()
        );
        // Newton's factor splits too: its two halves are factored and solved at once.
        let ordered = ReducedSystem::with_coupling(
            &p.model,
            p.params.step_params(),
            BendingFactor::default().coupling(),
        )
        .unwrap();
        let newton = NewtonSolver::new(ordered, 0.1, 1).unwrap();
        let [top, ha, hb] = newton.factor_halves().expect("the factor splits");
        assert!(
            3 * ha.min(hb) > ha.max(hb) && 10 * top < ha + hb,
            "{name}: factor halves of {ha} and {hb} columns, a top of {top}"
        );
        let bake = |threads: Threads| {
            let mut params = p.params.clone();
            params.threads = threads.clone();
            let mut solver = make_solver(&p.model, &params).unwrap();
            simulate(&p.model, solver.as_mut(), &params, &mut |frame| {
                // A scene's other job ends after the first frame: this one takes its core.
                if let (1, Threads::Shared(share)) = (frame, &threads) {
                    share.leave();
                }
            })
            .unwrap()
        };
        let (one, two) = (bake(1.into()), bake(2.into()));
        let shared = bake(Threads::Shared(CoreShare::new(2, 2)));
        let last = one.cache.frame_count() - 1;
        let moved = one
            .cache
            .frame(0)
            .iter()
            .zip(one.cache.frame(last))
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f32::max);
        assert!(moved > 1e-3, "{name}: the skirt moved {moved} m only");
        let iterations = |s: &scenebake::cloth::Simulation| -> Vec<usize> {
            s.frames.iter().map(|f| f.iterations).collect()
        };
        assert_eq!(iterations(&one), iterations(&two), "{name}");
        assert_eq!(iterations(&one), iterations(&shared), "{name}");
        // Two threads measure each frame beside the next one's steps: the same figures, in order.
        assert_eq!(one.quality.len(), one.cache.frame_count(), "{name}");
        assert!(
            one.quality == two.quality && one.quality == shared.quality,
            "{name}"
        );
        for k in 0..one.cache.frame_count() {
            assert!(
                one.cache.frame(k) == two.cache.frame(k),
                "{name}: frame {k} differs between one thread and two"
            );
            assert!(
                one.cache.frame(k) == shared.cache.frame(k),
                "{name}: frame {k} differs between one thread and one then two"
            );
        }
    }
}
