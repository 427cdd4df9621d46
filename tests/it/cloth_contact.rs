//! Colliders, friction and wind, checked against closed forms and physical bounds, with both
//! solvers. Penetration is measured with distances computed here from each collider's
//! parameters (`common::geometry`), never with the library's own contact query.

use crate::common;

use std::path::PathBuf;

use common::geometry::{box_distance, plane_distance, sphere_distance, Triangles};
use common::mesh_path;
use common::strain::edge_strain_range;
use glam::{DVec3, Vec3};
use scenebake::bake::cloth::{simulate_cloth, ClothJob, ClothSource, SimulatedCloth};
use scenebake::cloth::collide::{
    Ball, Collider, ColliderSpec, Colliders, ContactModel, Cuboid, HalfSpace,
};
use scenebake::cloth::springs::SpringSet;
use scenebake::cloth::{
    make_solver, newton, simulate, BakeParams, ClothModel, FrameCache, SolverKind,
};
use scenebake::mesh::Mesh;

const SOLVERS: [SolverKind; 2] = [SolverKind::Fast, SolverKind::Newton];

/// Every solver with every contact model it has (the fast solver has one).
const MODELS: [(SolverKind, ContactModel); 3] = [
    (SolverKind::Fast, ContactModel::Constraint),
    (SolverKind::Newton, ContactModel::Constraint),
    (SolverKind::Newton, ContactModel::Barrier),
];

/// Where a particle with layer ℓ rests on a flat collider pressed by `load` times its weight
/// (m above the surface): at ℓ with the constraint; with the barrier where the documented
/// barrier's force, c·m·g₀·(2(u − 1) ln u + (u − 1)²/u) at depth u = (s − ℓ/2)/ℓ into its band,
/// c such that it is ten weights at u = ½, balances the load (found here by bisection).
fn resting_height(model: ContactModel, layer: f64, load: f64) -> f64 {
    match model {
        ContactModel::Constraint => layer,
        ContactModel::Barrier => {
            let force = |u: f64| 2.0 * (u - 1.0) * u.ln() + (u - 1.0) * (u - 1.0) / u;
            let c = 10.0 / force(0.5);
            let target = load * 9.81 / (c * 9.80665);
            let (mut lo, mut hi) = (1e-12, 1.0);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if force(mid) > target {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            0.5 * layer + 0.5 * (lo + hi) * layer
        }
    }
}

/// Bakes `job` with the library (no export) and returns the cache and the parameters used.
fn bake(job: &ClothJob) -> (FrameCache, BakeParams, ClothModel) {
    let SimulatedCloth {
        prepared,
        simulation,
    } = simulate_cloth(job, &mut |_, _| {}).unwrap();
    (simulation.cache, prepared.params, prepared.model)
}

fn job(input: &str, solver: SolverKind, frames: usize) -> ClothJob {
    let mut job = ClothJob::new(
        ClothSource::File(mesh_path(input)),
        PathBuf::from("unused.glb"),
    );
    job.solver = solver;
    job.frames = Some(frames);
    // These scenes use the default material (cotton) with a fixed effort per step: ten
    // local/global iterations, or Newton to 1e-8 (at most its default cap of iterations).
    job.iterations = 10;
    job.tolerance = 1e-8;
    job
}

/// The smallest signed distance (`distance`, positive outside the solid) of any particle over
/// every frame of `cache`.
fn closest_approach(cache: &FrameCache, distance: impl Fn(DVec3) -> f64) -> f64 {
    (0..cache.frame_count())
        .flat_map(|k| cache.frame(k).iter())
        .map(|p| distance(p.as_dvec3()))
        .fold(f64::INFINITY, f64::min)
}

fn centroid(frame: &[Vec3]) -> DVec3 {
    frame.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / frame.len() as f64
}

/// A lone particle on a slope of angle θ: with μ < tanθ it slides with a = g(sinθ − μcosθ)
/// (discretely, implicit Euler: s_N = a h² N(N+1)/2); with μ > tanθ it stays put.
#[test]
fn particle_on_a_slope_obeys_coulomb() {
    let theta = 20f64.to_radians();
    let g = 9.81;
    let normal = DVec3::new(-theta.sin(), theta.cos(), 0.0);
    let downhill = DVec3::new(-theta.cos(), -theta.sin(), 0.0);
    let thickness = 0.01;
    for (solver_kind, model) in MODELS {
        for (mu, sliding) in [(0.1, true), (0.5, false)] {
            let start = normal * thickness;
            let mesh = Mesh::from_triangles("particle".into(), vec![start], Vec::new());
            let body =
                ClothModel::new(mesh, SpringSet::default(), vec![0.01], vec![false]).unwrap();
            let params = BakeParams {
                frames: 60,
                fps: 60.0,
                substeps: 1,
                splits: 0,
                damping: 0.0,
                gravity: DVec3::new(0.0, -g, 0.0),
                solver: solver_kind,
                iterations: 10,
                tolerance: 1e-10,
                max_newton: newton::DEFAULT_MAX_ITERATIONS,
                sweeps: newton::DEFAULT_SWEEPS,
                threads: 1.into(),
                linear_solver: Default::default(),
                self_contact: None,
                measure_from: 0,
                loop_closure: None,
                colliders: Colliders {
                    shapes: vec![Collider::Plane(HalfSpace::new(normal, 0.0).unwrap())],
                    thickness,
                    friction: mu,
                    model,
                },
                wind: None,
            };
            let mut solver = make_solver(&body, &params).unwrap();
            let sim = simulate(&body, solver.as_mut(), &params, &mut |_| {}).unwrap();
            let h = params.time_step();
            let end = sim.cache.frame(60)[0].as_dvec3();
            let travelled = (end - start).dot(downhill);
            let lift = (end - start).dot(normal);
            // A barrier holds the particle where it balances the weight's normal part, within
            // its band (half a thickness either side of the thickness).
            let off = match model {
                ContactModel::Constraint => 1e-5,
                ContactModel::Barrier => 0.5 * thickness,
            };
            assert!(
                lift.abs() < off,
                "{solver_kind:?} {model:?} μ={mu}: off the slope by {lift}"
            );
            if sliding {
                let a = g * (theta.sin() - mu * theta.cos());
                let mut expected = a * h * h * 60.0 * 61.0 / 2.0;
                if solver_kind == SolverKind::Newton {
                    // Newton's friction is lagged one step: the first step slides freely, which
                    // adds h·μg·cosθ to the speed for the remaining 60 steps.
                    expected += 60.0 * h * h * mu * g * theta.cos();
                }
                assert!(
                    (travelled - expected).abs() < 0.01 * expected,
                    "{solver_kind:?} {model:?} μ={mu}: slid {travelled} m, Coulomb says {expected}"
                );
            } else {
                // The fast solver holds from the first step. Newton's friction is lagged: the
                // first step slides freely (h²g·sinθ ≈ 0.9 mm, reaching h·g·sinθ), then kinetic
                // friction stops it within a few steps (v²/2g(μcosθ − sinθ) ≈ 1.3 mm); after
                // that its smoothed static friction creeps at most ~1e-4 m/s · tanθ/μ.
                let (total, late) = match solver_kind {
                    SolverKind::Fast => (1e-7, 1e-7),
                    SolverKind::Newton => (3e-3, 1e-4),
                };
                let late_travel = (end - sim.cache.frame(30)[0].as_dvec3()).dot(downhill);
                assert!(
                    travelled.abs() < total && late_travel.abs() < late,
                    "{solver_kind:?} {model:?} μ={mu}: crept {travelled} m, {late_travel} m in the last 0.5 s"
                );
            }
        }
    }
}

/// A particle that starts closer to the ground than the thickness (a garment draped by another
/// tool with a smaller margin) is held by the ground at its starting distance under Newton: with
/// the constraint it stays exactly there, with the barrier that distance is its layer, and it
/// settles where the barrier carries its weight within that layer's band, never below half of
/// it; it is not pushed out to the thickness, nor let in. One that starts above the thickness
/// falls and rests on the thickness's layer.
#[test]
fn newton_keeps_a_particle_starting_inside_the_thickness_where_it_started() {
    let thickness = 0.01;
    for model in [ContactModel::Constraint, ContactModel::Barrier] {
        for (start, layer) in [(0.25 * thickness, 0.25 * thickness), (0.03, thickness)] {
            let p0 = DVec3::new(0.1, start, -0.2);
            let mesh = Mesh::from_triangles("particle".into(), vec![p0], Vec::new());
            let body =
                ClothModel::new(mesh, SpringSet::default(), vec![0.01], vec![false]).unwrap();
            let params = BakeParams {
                frames: 30,
                fps: 30.0,
                substeps: 1,
                splits: 0,
                damping: 0.0,
                gravity: DVec3::new(0.0, -9.81, 0.0),
                solver: SolverKind::Newton,
                iterations: 10,
                tolerance: 1e-10,
                max_newton: newton::DEFAULT_MAX_ITERATIONS,
                sweeps: newton::DEFAULT_SWEEPS,
                threads: 1.into(),
                linear_solver: Default::default(),
                self_contact: None,
                measure_from: 0,
                loop_closure: None,
                colliders: Colliders {
                    shapes: vec![Collider::Plane(HalfSpace::new(DVec3::Y, 0.0).unwrap())],
                    thickness,
                    friction: 0.5,
                    model,
                },
                wind: None,
            };
            let mut solver = make_solver(&body, &params).unwrap();
            let sim = simulate(&body, solver.as_mut(), &params, &mut |_| {}).unwrap();
            let lowest = match model {
                ContactModel::Constraint => layer,
                ContactModel::Barrier => 0.5 * layer,
            };
            for k in 1..=30 {
                let p = sim.cache.frame(k)[0].as_dvec3();
                assert!(
                    p.y > lowest - 1e-6,
                    "{model:?}, started at {start} m: at frame {k} it is at {} m, below {lowest} m",
                    p.y
                );
            }
            let rest = resting_height(model, layer, 1.0);
            let end = sim.cache.frame(30)[0].as_dvec3();
            assert!(
                (end.y - rest).abs() < 1e-6 && (end.x - p0.x).hypot(end.z - p0.z) < 1e-7,
                "{model:?}, started at {start} m: rests at {end}, expected height {rest} m"
            );
            assert!(sim.frames.iter().all(|f| f.converged), "{:?}", sim.frames);
        }
    }
}

/// A sheet dropped onto a tilted ground lands, comes to rest without penetrating and, with
/// μ > tanθ, does not drift down the slope.
#[test]
fn dropped_sheet_rests_on_a_tilted_ground_without_drifting() {
    let theta = 10f64.to_radians();
    let normal = DVec3::new(-theta.sin(), theta.cos(), 0.0);
    let offset = -0.15;
    for (solver_kind, model) in MODELS {
        let mut job = job("plane_30x30.obj", solver_kind, 150);
        job.collider = vec![ColliderSpec::Plane(normal, offset)];
        job.friction = 0.6;
        job.damping = Some(1.0);
        job.stiffness = Some(200.0);
        job.contact = (solver_kind == SolverKind::Newton).then_some(model);
        let (cache, params, _) = bake(&job);
        let above_ground = |p| plane_distance(normal, offset, p);
        let thickness = params.colliders.thickness;
        let approach = closest_approach(&cache, above_ground);
        assert!(
            approach > 0.0,
            "{solver_kind:?} {model:?}: a particle went {approach} m from the ground (inside)"
        );
        // Landed: the centroid lies where the ground carries the weight's normal part.
        let end = cache.frame(150);
        let lift = above_ground(centroid(end));
        let rest = resting_height(model, thickness, theta.cos());
        assert!(
            (lift - rest).abs() < 0.1 * thickness,
            "{solver_kind:?} {model:?}: centroid {lift} m above the ground, expected {rest} m \
             (thickness {thickness})"
        );
        // At rest and not drifting over the last second.
        let drift = centroid(end).distance(centroid(cache.frame(120)));
        assert!(
            drift < 2e-4,
            "{solver_kind:?} {model:?}: drifted {drift} m in 1 s"
        );
        let fastest = end
            .iter()
            .zip(cache.frame(149))
            .map(|(a, b)| a.distance(*b) as f64 * params.fps)
            .fold(0.0, f64::max);
        assert!(
            fastest < 1e-3,
            "{solver_kind:?}: a particle still moves at {fastest} m/s"
        );
    }
}

/// A sheet falling onto a ball never enters it, at any frame, and drapes around it.
#[test]
fn sheet_over_a_sphere_never_penetrates() {
    let ball = Ball {
        centre: DVec3::new(0.0, -0.35, 0.0),
        radius: 0.3,
    };
    for solver_kind in SOLVERS {
        let mut job = job("plane_30x30.obj", solver_kind, 60);
        job.collider = vec![ColliderSpec::Sphere(ball.centre, ball.radius)];
        if solver_kind == SolverKind::Fast {
            // Ten local/global iterations leave this cotton sheet far from converged (ρ ≈ 100,
            // edges compressed by 20–30 %), where how it drapes depends on where its edges jam:
            // at the default 6 % its centre stays 0.23 m above the ball after 60 frames. This
            // test is about contact, so the fast solver keeps the 8 % it was written with.
            job.jam_strain = Some(0.08);
        }
        let (cache, params, _) = bake(&job);
        // Newton's default is the barrier; the fast solver's filtered solve is a constraint, and
        // the parameters (which the report shows) say so.
        let model = match solver_kind {
            SolverKind::Fast => ContactModel::Constraint,
            SolverKind::Newton => ContactModel::Barrier,
        };
        assert_eq!(params.colliders.model, model);
        let approach = closest_approach(&cache, |p| sphere_distance(ball.centre, ball.radius, p));
        assert!(
            approach > 0.0,
            "{solver_kind:?}: a particle came {approach} m from the sphere (inside it)"
        );
        let end = cache.frame(60);
        // Draped: the top rests on the ball, the corners hang well below its equator.
        let top = end
            .iter()
            .map(|p| p.as_dvec3())
            .min_by(|a, b| (a.x.hypot(a.z)).total_cmp(&b.x.hypot(b.z)))
            .unwrap();
        let gap = top.distance(ball.centre) - ball.radius;
        assert!(
            gap < 2.0 * params.colliders.thickness,
            "{solver_kind:?}: the sheet's centre floats {gap} m above the ball"
        );
        let lowest_corner = end.iter().map(|p| p.y as f64).fold(f64::INFINITY, f64::min);
        assert!(
            lowest_corner < ball.centre.y - 0.1,
            "{solver_kind:?}: lowest point {lowest_corner} m, the ball's centre is at {}",
            ball.centre.y
        );
    }
}

/// Newton's two contact models drape the same sheet over a ball alike: with the barrier no
/// particle comes within half a thickness of the ball (distances computed here from the ball's
/// centre and radius), at least 95 % of the steps converge, and the sheet's centroid follows the constraint
/// model's within a thickness at every frame (the barrier rests the cloth up to half a
/// thickness higher, where it carries the weight).
#[test]
fn contact_models_drape_a_sheet_over_a_ball_alike() {
    let ball = Ball {
        centre: DVec3::new(0.0, -0.35, 0.0),
        radius: 0.3,
    };
    let bake_with = |model| {
        let mut job = job("plane_30x30.obj", SolverKind::Newton, 60);
        job.collider = vec![ColliderSpec::Sphere(ball.centre, ball.radius)];
        job.contact = Some(model);
        job.stiffness = Some(200.0);
        job.density = Some(0.5);
        job.tolerance = 0.1;
        let SimulatedCloth {
            prepared,
            simulation,
        } = simulate_cloth(&job, &mut |_, _| {}).unwrap();
        (simulation, prepared.params)
    };
    let (barrier, params) = bake_with(ContactModel::Barrier);
    let (constraint, _) = bake_with(ContactModel::Constraint);
    let t = params.colliders.thickness;
    assert_eq!(params.colliders.model, ContactModel::Barrier);
    let approach = closest_approach(&barrier.cache, |p| {
        sphere_distance(ball.centre, ball.radius, p)
    });
    assert!(
        approach > 0.5 * t,
        "came {approach} m from the ball, thickness {t} m"
    );
    // The bar for contact: at least 95 % of the steps within the tolerance.
    let unconverged: Vec<_> = barrier.frames.iter().filter(|f| !f.converged).collect();
    assert!(unconverged.len() <= 3, "{unconverged:?}");
    let mut worst: f64 = 0.0;
    for k in 0..=60 {
        let a = centroid(barrier.cache.frame(k));
        let b = centroid(constraint.cache.frame(k));
        worst = worst.max(a.distance(b));
    }
    assert!(worst < t, "centroids {worst} m apart, thickness {t} m");
    assert!(barrier.frames.iter().skip(20).all(|f| f.contacts > 0));
}

/// `tableCloth.obj` over a box table (fast solver; Newton drapes the coarser 30×30 sheet, since
/// on tableCloth it needs its iteration cap every step): the middle lies on the table top, the
/// overhang hangs, nothing enters the table.
#[test]
fn tablecloth_drapes_over_a_table() {
    let table = Cuboid {
        min: DVec3::new(-0.28, 0.0, -0.15),
        max: DVec3::new(0.02, 0.9, 0.15),
    };
    for (input, solver_kind, frames) in [
        ("tableCloth.obj", SolverKind::Fast, 45),
        ("plane_30x30.obj", SolverKind::Newton, 45),
    ] {
        let mut job = job(input, solver_kind, frames);
        // A heavier, softer cloth than the default light cotton, so it drapes within 1.5 s.
        job.stiffness = Some(100.0);
        job.density = Some(0.5);
        let table = if input == "plane_30x30.obj" {
            // The 1×1 m sheet at y = 0, centred on the origin: a 0.5 m table just below it.
            Cuboid {
                min: DVec3::new(-0.25, -1.0, -0.25),
                max: DVec3::new(0.25, -0.05, 0.25),
            }
        } else {
            table
        };
        job.collider = vec![ColliderSpec::Box(table.min, table.max)];
        let (cache, params, _) = bake(&job);
        let approach = closest_approach(&cache, |p| box_distance(table.min, table.max, p));
        assert!(
            approach > 0.0,
            "{input} {solver_kind:?}: entered the table ({approach} m)"
        );
        let end = cache.frame(frames);
        let middle = (table.min + table.max) * 0.5;
        let half = (table.max - table.min) * 0.5;
        for p in end.iter().map(|p| p.as_dvec3()) {
            let over_x = (p.x - middle.x).abs() - half.x;
            let over_z = (p.z - middle.z).abs() - half.z;
            if over_x < -0.05 && over_z < -0.05 {
                // Well inside the footprint: on the top.
                let above = p.y - table.max.y;
                assert!(
                    above > 0.0 && above < 3.0 * params.colliders.thickness,
                    "{input} {solver_kind:?}: {p} is {above} m above the top"
                );
            } else if over_x > 0.1 || over_z > 0.1 {
                // Overhang: hangs below the top.
                assert!(
                    p.y < table.max.y - 0.05,
                    "{input} {solver_kind:?}: overhang particle {p} does not hang"
                );
            }
        }
    }
}

/// A flag pinned along its pole in a gusty wind keeps flapping, and its energy stays bounded:
/// no particle outruns twice the wind speed, and the kinetic energy does not grow over time.
#[test]
fn flag_in_the_wind_keeps_moving_with_bounded_energy() {
    let wind = DVec3::new(6.0, 0.0, 0.0);
    for (solver_kind, frames) in [(SolverKind::Fast, 240), (SolverKind::Newton, 90)] {
        let mut job = job("square_dense.obj", solver_kind, frames);
        job.pin = vec!["box:-0.01,-1,-1,0.01,2,1".parse().unwrap()];
        job.wind = Some(wind);
        job.turbulence = 0.3;
        job.seed = 11;
        // A heavier, softer flag than the default cotton, two steps per frame: the fast solver's
        // ten iterations then converge well enough to flap instead of crumpling (h²k/m ≈ 50).
        job.stiffness = Some(200.0);
        job.density = Some(0.5);
        job.substeps = 2;
        if solver_kind == SolverKind::Newton {
            job.max_newton = 8;
        }
        let (cache, params, model) = bake(&job);
        let speeds: Vec<Vec<f64>> = (1..=frames)
            .map(|k| {
                cache
                    .frame(k)
                    .iter()
                    .zip(cache.frame(k - 1))
                    .map(|(a, b)| a.distance(*b) as f64 * params.fps)
                    .collect()
            })
            .collect();
        let kinetic: Vec<f64> = speeds
            .iter()
            .map(|s| {
                s.iter()
                    .zip(&model.mass)
                    .map(|(v, m)| 0.5 * m * v * v)
                    .sum()
            })
            .collect();
        let fastest = speeds.iter().flatten().copied().fold(0.0, f64::max);
        assert!(
            fastest < 2.0 * wind.length(),
            "{solver_kind:?}: a particle reached {fastest} m/s in a {} m/s wind",
            wind.length()
        );
        // Blown out: the free edge streams downwind of the pole.
        let end = cache.frame(frames);
        let reach = end
            .iter()
            .map(|p| p.x as f64)
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(
            reach > 0.7,
            "{solver_kind:?}: the flag reaches only x = {reach}"
        );
        // Keeps moving: every third of the second half has a clearly non-zero mean speed.
        let half = frames / 2;
        let third = (frames - half) / 3;
        for w in 0..3 {
            let window = &kinetic[half + w * third..half + (w + 1) * third];
            let mean_ke = window.iter().sum::<f64>() / window.len() as f64;
            let total_mass: f64 = model.mass.iter().sum();
            let rms_speed = (2.0 * mean_ke / total_mass).sqrt();
            assert!(
                rms_speed > 0.05,
                "{solver_kind:?}: window {w} rms speed {rms_speed} m/s: the flag froze"
            );
        }
        // Bounded: the late kinetic energy does not exceed the early peak by much.
        let early = kinetic[..half].iter().copied().fold(0.0, f64::max);
        let late = kinetic[half..].iter().copied().fold(0.0, f64::max);
        assert!(
            late < 2.0 * early,
            "{solver_kind:?}: kinetic energy grew from {early} J to {late} J"
        );
    }
}

/// The same seed gives the same bake; another seed gives another one.
#[test]
fn gusts_are_deterministic() {
    let run = |seed| {
        let mut job = job("square_dense.obj", SolverKind::Fast, 20);
        job.pin = vec!["box:-0.01,-1,-1,0.01,2,1".parse().unwrap()];
        job.wind = Some(DVec3::new(5.0, 0.0, 0.0));
        job.turbulence = 0.5;
        job.seed = seed;
        bake(&job).0
    };
    let (a, b, c) = (run(3), run(3), run(4));
    assert_eq!(a, b);
    assert_ne!(a.frame(20), c.frame(20));
}

/// A sheet dropped onto the table mesh (a 4 cm top on four legs) stays on its top with both
/// solvers: no particle ends a frame inside the table, and the middle rests on the top.
#[test]
fn sheet_rests_on_the_table_mesh() {
    // The table as tobj reads it, measured triangle by triangle.
    let table = Triangles::from_obj(&mesh_path("table.obj"));
    assert_eq!(table.triangles.len(), 60);
    for solver_kind in SOLVERS {
        let mut job = job("plane_30x30.obj", solver_kind, 20);
        job.scale = 1.6;
        job.translate = Some(DVec3::new(0.0, 0.9, 0.0));
        job.collider = vec![ColliderSpec::mesh(mesh_path("table.obj"))];
        job.stiffness = Some(200.0);
        job.density = Some(0.5);
        job.max_newton = 20;
        let (cache, params, _) = bake(&job);
        let approach = closest_approach(&cache, |p| table.signed_distance(p));
        assert!(
            approach > 0.0,
            "{solver_kind:?}: a particle entered the table ({approach} m)"
        );
        let middle = cache
            .frame(20)
            .iter()
            .map(|p| p.as_dvec3())
            .min_by(|a, b| a.x.hypot(a.z).total_cmp(&b.x.hypot(b.z)))
            .unwrap();
        let above = middle.y - 0.75;
        assert!(
            above > 0.0 && above < 2.0 * params.colliders.thickness,
            "{solver_kind:?}: the sheet's middle is {above} m above the table top"
        );
    }
}

/// An 8k-vertex skirt dropped with every default onto the table mesh: its hem ring lands on the
/// top and the skirt is crushed along its axis, the hardest steps a garment bake meets (springs
/// jam and buckle). At most one of its first 12 frames ends above the tolerance (the issue asks
/// for 95 % of steps; which crush frame is hardest moves with roundoff: with a double-precision
/// factor frame 7 takes 100 iterations, with the single-precision one 91), each flagged exactly
/// when its residual is above the tolerance, and some need more than 50 Newton iterations (the
/// default cap is a safety net, not a budget); no particle ends a frame inside the table, and
/// no edge stretches past 8 % or shortens past 10 %.
#[test]
fn a_skirt_crushed_on_the_table_converges_with_the_defaults() {
    let table = Triangles::from_obj(&mesh_path("table.obj"));
    let mut job = ClothJob::new(
        ClothSource::File(mesh_path("garments/skirt8K.obj")),
        PathBuf::from("unused.glb"),
    );
    job.frames = Some(12);
    job.collider = vec![ColliderSpec::mesh(mesh_path("table.obj"))];
    let SimulatedCloth {
        prepared,
        simulation,
    } = simulate_cloth(&job, &mut |_, _| {}).unwrap();
    let iterations: Vec<usize> = simulation.frames.iter().map(|f| f.iterations).collect();
    for (k, f) in simulation.frames.iter().enumerate() {
        assert_eq!(
            f.converged,
            f.residual <= prepared.params.tolerance,
            "frame {}: {f:?}",
            k + 1
        );
    }
    let above = simulation.frames.iter().filter(|f| !f.converged).count();
    assert!(
        above <= 1,
        "{above} of 12 frames above the tolerance (iterations per frame {iterations:?})"
    );
    assert!(
        iterations.iter().any(|&n| n > 50) && simulation.frames.iter().any(|f| f.contacts > 0),
        "the skirt must land and buckle: iterations per frame {iterations:?}"
    );
    let cache = &simulation.cache;
    let approach = closest_approach(cache, |p| table.signed_distance(p));
    assert!(
        approach > 0.0,
        "a particle entered the table ({approach} m)"
    );
    let (stretch, squash) = edge_strain_range(&prepared.model, cache);
    assert!(
        stretch < 0.08 && squash > -0.10,
        "edges stretched {:.1} %, shortened {:.1} %",
        100.0 * stretch,
        -100.0 * squash
    );
}

/// The two ways this file measures penetration agree: a box written as an OBJ and measured
/// triangle by triangle (with the winding number for inside) gives the box formula's distance.
#[test]
fn brute_force_mesh_distance_agrees_with_the_box_formula() {
    let (min, max) = (DVec3::new(-0.3, 0.7, -0.2), DVec3::new(0.5, 1.0, 0.4));
    let corner = |i: usize| {
        DVec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        )
    };
    // Corners 1..8 in OBJ order: (0,0,0) (1,0,0) (1,1,0) (0,1,0), then the same at z = 1.
    let order = [0, 1, 3, 2, 4, 5, 7, 6];
    let mut obj: String = order
        .iter()
        .map(|&i| {
            let c = corner(i);
            format!("v {} {} {}\n", c.x, c.y, c.z)
        })
        .collect();
    // Outward faces (counter-clockwise seen from outside).
    for f in [
        "1 4 3", "1 3 2", "5 6 7", "5 7 8", "1 2 6", "1 6 5", "4 8 7", "4 7 3", "1 5 8", "1 8 4",
        "2 3 7", "2 7 6",
    ] {
        obj.push_str(&format!("f {f}\n"));
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.obj");
    std::fs::write(&path, obj).unwrap();
    let mesh = Triangles::from_obj(&path);
    assert_eq!(mesh.triangles.len(), 12);
    let mut inside = 0;
    for i in 0..=12 {
        for j in 0..=12 {
            for k in 0..=12 {
                let t = DVec3::new(i as f64, j as f64, k as f64) / 12.0;
                let p = min - 0.2 + (max - min + 0.4) * t;
                let (got, want) = (mesh.signed_distance(p), box_distance(min, max, p));
                // tobj stores the corners as f32.
                assert!((got - want).abs() < 1e-6, "{p}: mesh {got}, box {want}");
                inside += usize::from(want < 0.0);
            }
        }
    }
    assert!(
        inside > 50,
        "the grid probes the inside too ({inside} points)"
    );
}
