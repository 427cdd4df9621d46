//! IK benchmarks: one warm-started solve per target along the lab circle, for chains of 5, 10
//! and 30 joints, with FABRIK and CCD; and a whole 40-character text bake (solve + glTF write).
//!
//! Run with `cargo bench --bench ik`. Before timing, the mean iterations per frame over the
//! circle are printed for each solver and chain length. The Fox group solves the rig
//! chain (b_Spine01_02..b_Head_05 of meshes/Fox.glb) along its default heart. The constrained
//! group solves a 3-joint arm writing a cursive word on a board, free and then with a pole, an
//! elbow hinge and a shoulder cone, then adding a shoulder twist limit and a tip axis, printing
//! mean iterations for each before timing. The humanoid group solves the robot's right arm
//! (UpperArmR..Palm2R of meshes/humanoid/RobotExpressive.glb, rest frames) on the targets of the
//! `robot_writing` demo, free and with that demo's pole, limits and tip axis.

use std::f64::consts::TAU;
use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use scenebake::bake::{bake_ik, IkJob};
use scenebake::glam::DVec3;
use scenebake::ik::{Ccd, Chain, Constraints, Fabrik, IkSolver, TipAxis};
use scenebake::io::rig::RigDocument;

fn circle() -> Vec<DVec3> {
    (0..150)
        .map(|k| {
            let t = TAU * k as f64 / 150.0;
            DVec3::new(0.6 * t.cos(), 0.0, 0.6 * t.sin())
        })
        .collect()
}

fn chain(n: usize) -> Chain {
    if n == 5 {
        Chain::lab_arm()
    } else {
        Chain::straight(n, 2.6).unwrap()
    }
}

fn solvers() -> Vec<(&'static str, Box<dyn IkSolver>)> {
    vec![
        ("fabrik", Box::new(Fabrik::default())),
        ("ccd", Box::new(Ccd::default())),
    ]
}

fn solve(c: &mut Criterion) {
    let targets = circle();
    for (name, solver) in solvers() {
        for n in [5, 10, 30] {
            let ch = chain(n);
            let mut pose = ch.rest_pose();
            let (mut total, mut reached) = (0, 0);
            for t in &targets {
                let r = solver.solve(&ch, &mut pose, *t).unwrap();
                total += r.iterations;
                reached += usize::from(r.reached);
            }
            eprintln!(
                "{name:>6} n={n:>2}: mean iterations {:.2}, reached {reached}/150",
                total as f64 / 150.0
            );
        }
    }
    let mut group = c.benchmark_group("solve_per_target");
    group
        .sample_size(20)
        .measurement_time(std::time::Duration::from_secs(2))
        .warm_up_time(std::time::Duration::from_millis(500));
    for (name, solver) in solvers() {
        for n in [5, 10, 30] {
            let ch = chain(n);
            group.bench_with_input(BenchmarkId::new(name, n), &n, |b, _| {
                let mut pose = ch.rest_pose();
                let mut k = 0;
                b.iter(|| {
                    k = (k + 1) % targets.len();
                    black_box(solver.solve(&ch, &mut pose, targets[k]).unwrap())
                })
            });
        }
    }
    group.finish();
}

/// The Fox chain (b_Spine01_02..b_Head_05, 4 joints in the rig's real frames) on the
/// heart targets its bake uses.
fn fox(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let rig = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/Fox.glb");
    let job = IkJob {
        rig: Some(rig.clone()),
        chain: Some("b_Spine01_02..b_Head_05".into()),
        curve: Some(scenebake::path::CurveKind::Heart),
        output: dir.path().join("fox.glb"),
        ..Default::default()
    };
    let report = bake_ik(&job, &mut |_, _| {}).unwrap();
    let targets: Vec<DVec3> = report
        .targets
        .iter()
        .map(|t| DVec3::from_array(*t))
        .collect();
    let rc = scenebake::io::rig::RigDocument::load(&rig)
        .unwrap()
        .chain("b_Spine01_02..b_Head_05")
        .unwrap();
    let mut group = c.benchmark_group("fox_spine_heart");
    group
        .sample_size(20)
        .measurement_time(std::time::Duration::from_secs(2))
        .warm_up_time(std::time::Duration::from_millis(500));
    for (name, solver) in solvers() {
        let mut pose = rc.chain.rest_pose();
        let total: usize = targets
            .iter()
            .map(|t| solver.solve(&rc.chain, &mut pose, *t).unwrap().iterations)
            .sum();
        eprintln!(
            "fox {name}: mean iterations {:.2} over {} targets",
            total as f64 / targets.len() as f64,
            targets.len()
        );
        group.bench_function(name, |b| {
            let mut pose = rc.chain.rest_pose();
            let mut k = 0;
            b.iter(|| {
                k = (k + 1) % targets.len();
                black_box(solver.solve(&rc.chain, &mut pose, targets[k]).unwrap())
            })
        });
    }
    group.finish();
}

fn text_bake(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let text = "THE QUICK BROWN FOX JUMPS OVER 12 DOGS!?";
    assert_eq!(text.len(), 40);
    let job = IkJob {
        preset: Some(scenebake::bake::ik::IkPreset::LabArm),
        text: Some(text.into()),
        output: dir.path().join("text.glb"),
        ..Default::default()
    };
    let r = bake_ik(&job, &mut |_, _| {}).unwrap();
    eprintln!(
        "text bake: {} frames, mean iterations {:.2}, reached {}/{}, {:.1} ms total",
        r.frames,
        r.mean_iterations,
        r.reached,
        r.frames,
        r.seconds_total * 1e3
    );
    let mut group = c.benchmark_group("bake");
    group
        .sample_size(10)
        .measurement_time(std::time::Duration::from_secs(3));
    group.bench_function("text_40_chars_fabrik", |b| {
        b.iter(|| black_box(bake_ik(&job, &mut |_, _| {}).unwrap().frames))
    });
    group.finish();
}

/// A shoulder-elbow-hand arm (two 0.6 bones) writing "hello" in the cursive font on a board in
/// front of it: unconstrained, then with `--pole 0.6,-0.5,0 --limit joint_1:hinge:0..150
/// --limit joint_0:cone:100`.
fn constrained(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        joints: Some(3),
        length: Some(1.2),
        text: Some("hello".into()),
        font: Some("cursive".into()),
        size: Some(0.08),
        center: Some(DVec3::new(0.15, 0.45, 0.45)),
        normal: Some(DVec3::new(0.0, 0.0, -1.0)),
        spacing: Some(0.002),
        output: dir.path().join("arm.glb"),
        ..Default::default()
    };
    let targets: Vec<DVec3> = bake_ik(&job, &mut |_, _| {})
        .unwrap()
        .targets
        .iter()
        .map(|t| DVec3::from_array(*t))
        .collect();
    let arm = Chain::straight(3, 1.2).unwrap();
    let limited = Constraints::from_specs(
        &arm,
        Some(DVec3::new(0.6, -0.5, 0.0)),
        &["joint_1:hinge:0..150".into(), "joint_0:cone:100".into()],
    )
    .unwrap();
    let mut twisted = Constraints::from_specs(
        &arm,
        Some(DVec3::new(0.6, -0.5, 0.0)),
        &[
            "joint_1:hinge:0..150".into(),
            "joint_0:cone:100".into(),
            "joint_0:twist:-20..20".into(),
        ],
    )
    .unwrap();
    twisted.tip_axis = Some(TipAxis::new(DVec3::Z, TipAxis::continuing(&arm)).unwrap());
    let free = Constraints::default();
    let mut group = c.benchmark_group("arm_writing");
    group
        .sample_size(20)
        .measurement_time(std::time::Duration::from_secs(2))
        .warm_up_time(std::time::Duration::from_millis(500));
    for (name, solver) in solvers() {
        for (label, cons) in [
            ("free", &free),
            ("limited", &limited),
            ("twist_tip", &twisted),
        ] {
            let mut pose = arm.rest_pose();
            let (mut total, mut reached) = (0, 0);
            for t in &targets {
                let r = solver.solve_with(&arm, &mut pose, *t, cons).unwrap();
                total += r.iterations;
                reached += usize::from(r.reached);
            }
            eprintln!(
                "arm {name} {label}: mean iterations {:.2}, reached {reached}/{}",
                total as f64 / targets.len() as f64,
                targets.len()
            );
            group.bench_function(format!("{name}_{label}"), |b| {
                let mut pose = arm.rest_pose();
                let mut k = 0;
                b.iter(|| {
                    k = (k + 1) % targets.len();
                    black_box(
                        solver
                            .solve_with(&arm, &mut pose, targets[k], cons)
                            .unwrap(),
                    )
                })
            });
        }
    }
    group.finish();
}

/// The robot's right arm (rest frames) on the `robot_writing` demo's targets: free, then with
/// the demo's pole, elbow hinge, shoulder cone and twist, and tip axis.
fn humanoid(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let rig = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("meshes/humanoid/RobotExpressive.glb");
    let pole = DVec3::new(-2.0, 0.5, 0.0);
    let limits: Vec<String> = vec![
        "LowerArmR:hinge:-120..0".into(),
        "UpperArmR:cone:100".into(),
        "UpperArmR:twist:0..75".into(),
    ];
    let job = IkJob {
        rig: Some(rig.clone()),
        chain: Some("UpperArmR..Palm2R".into()),
        text: Some("hello".into()),
        font: Some("script".into()),
        size: Some(0.2),
        center: Some(DVec3::new(-0.45, 1.85, 1.2)),
        normal: Some(DVec3::new(0.0, 0.0, -1.0)),
        pen_speed: Some(0.5),
        output: dir.path().join("robot.glb"),
        ..Default::default()
    };
    let targets: Vec<DVec3> = bake_ik(&job, &mut |_, _| {})
        .unwrap()
        .targets
        .iter()
        .map(|t| DVec3::from_array(*t))
        .collect();
    let doc = RigDocument::load(&rig).unwrap();
    let arm = doc.chain("UpperArmR..Palm2R").unwrap().chain;
    let mut limited = Constraints::from_specs(&arm, Some(pole), &limits).unwrap();
    // The hand's pen: towards its first child (Middle1R), +Y in the hand's frame.
    limited.tip_axis = Some(TipAxis::new(DVec3::Z, DVec3::Y).unwrap());
    let free = Constraints::default();
    let mut group = c.benchmark_group("humanoid_writing");
    group
        .sample_size(20)
        .measurement_time(std::time::Duration::from_secs(2))
        .warm_up_time(std::time::Duration::from_millis(500));
    for (name, solver) in solvers() {
        for (label, cons) in [("free", &free), ("limited", &limited)] {
            let mut pose = arm.rest_pose();
            let (mut total, mut reached) = (0, 0);
            for t in &targets {
                let r = solver.solve_with(&arm, &mut pose, *t, cons).unwrap();
                total += r.iterations;
                reached += usize::from(r.reached);
            }
            eprintln!(
                "robot {name} {label}: mean iterations {:.2}, reached {reached}/{}",
                total as f64 / targets.len() as f64,
                targets.len()
            );
            group.bench_function(format!("{name}_{label}"), |b| {
                let mut pose = arm.rest_pose();
                let mut k = 0;
                b.iter(|| {
                    k = (k + 1) % targets.len();
                    black_box(
                        solver
                            .solve_with(&arm, &mut pose, targets[k], cons)
                            .unwrap(),
                    )
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, solve, fox, text_bake, constrained, humanoid);
criterion_main!(benches);
