//! Cloth on a body given as an OBJ sequence (`cloth --body PATTERN --body-fps F`): a box whose
//! top rises under a sheet pushes the sheet up, the written glTF holds the body's motion (read
//! back with the `gltf` crate), and bad sequences fail before anything is simulated.

use crate::common;

use std::path::{Path, PathBuf};

use glam::DVec3;
use scenebake::bake::{bake_cloth, ClothJob};
use scenebake::error::Error;
use scenebake::param::Param;

/// The box: x, z in [-0.5, 0.5], bottom at y = -0.5; its top starts at y = 0.
const HALF: f64 = 0.5;
const BOTTOM: f64 = -0.5;
/// The top's rise over the first RISE_FRAMES frames (then held), at BODY_FPS.
const RISE: f64 = 0.2;
const RISE_FRAMES: usize = 4;
const FRAMES: usize = 11;
const BODY_FPS: f64 = 10.0;
/// The sheet's distance from the top: the contact thickness.
const THICKNESS: f64 = 0.01;

/// The top's height at `t` seconds: rising linearly for RISE_FRAMES frames, then held.
fn top_at(t: f64) -> f64 {
    let rise_time = RISE_FRAMES as f64 / BODY_FPS;
    RISE * (t / rise_time).clamp(0.0, 1.0)
}

/// The box with its top at `top`: 8 corners, 12 outward triangles.
fn box_obj(top: f64, extra_vertex: bool) -> String {
    let mut s = String::new();
    for (x, y, z) in [
        (-HALF, BOTTOM, -HALF),
        (HALF, BOTTOM, -HALF),
        (HALF, BOTTOM, HALF),
        (-HALF, BOTTOM, HALF),
        (-HALF, top, -HALF),
        (HALF, top, -HALF),
        (HALF, top, HALF),
        (-HALF, top, HALF),
    ] {
        s += &format!("v {x} {y} {z}\n");
    }
    s += "f 1 2 3\nf 1 3 4\nf 5 7 6\nf 5 8 7\nf 1 5 6\nf 1 6 2\nf 2 6 7\nf 2 7 3\nf 3 7 8\nf 3 8 4\nf 4 8 5\nf 4 5 1\n";
    if extra_vertex {
        s += &format!("v 0 {} 0\nf 5 6 9\n", top + 0.1);
    }
    s
}

/// Writes frames `0..FRAMES` of the rising box as `dir/box%d.obj`; returns the pattern.
fn write_sequence(dir: &Path) -> PathBuf {
    for i in 0..FRAMES {
        let top = top_at(i as f64 / BODY_FPS);
        std::fs::write(dir.join(format!("box{i}.obj")), box_obj(top, false)).unwrap();
    }
    dir.join("box%d.obj")
}

/// A 0.4 m square sheet, 9 × 9 vertices, lying a thickness above the box's starting top.
fn write_sheet(dir: &Path) -> PathBuf {
    common::write_layers(dir, "sheet", &[(THICKNESS, [0.0; 2])])
}

fn job(dir: &Path, pattern: PathBuf, output: &Path) -> ClothJob {
    ClothJob {
        input: Some(write_sheet(dir)),
        output: output.into(),
        body: Some(pattern),
        body_fps: Some(BODY_FPS),
        // The bake's rate differs from the body's: steps fall between body frames.
        fps: Some(50.0),
        thickness: Some(THICKNESS),
        ..ClothJob::default()
    }
}

/// Asserts that `p` is a corner of the box at `t` seconds (frame `k`): at x, z = ±HALF, at the
/// top's height `top_at(t)` for a top corner, at the bottom otherwise.
#[track_caller]
fn assert_box_corner(p: DVec3, top: bool, t: f64, k: usize) {
    assert!((p.x.abs() - HALF).abs() < 1e-6 && (p.z.abs() - HALF).abs() < 1e-6);
    let want = if top { top_at(t) } else { BOTTOM };
    assert!(
        (p.y - want).abs() < 1e-5,
        "frame {k}: body vertex at y = {}, the sequence has {want}",
        p.y
    );
}

/// One node's mesh positions as played at key `k` of the first animation: base + Σ wᵢ·δᵢ.
struct Played {
    base: Vec<DVec3>,
    deltas: Vec<Vec<DVec3>>,
    times: Vec<f32>,
    weights: Vec<f32>,
}

impl Played {
    fn read(doc: &gltf::Document, buffers: &[common::gltf_read::Data], name: &str) -> Played {
        let node = doc.nodes().find(|n| n.name() == Some(name)).unwrap();
        let prim = node.mesh().unwrap().primitives().next().unwrap();
        let reader = prim.reader(|b| Some(&buffers[b.index()]));
        let v = |p: [f32; 3]| DVec3::new(p[0].into(), p[1].into(), p[2].into());
        let base = reader.read_positions().unwrap().map(v).collect();
        let deltas = reader
            .read_morph_targets()
            .map(|(p, _, _)| p.unwrap().map(v).collect())
            .collect();
        assert_eq!(doc.animations().count(), 1, "one animation plays both");
        let anim = doc.animations().next().unwrap();
        let channel = anim
            .channels()
            .find(|c| c.target().node().index() == node.index())
            .unwrap();
        let r = channel.reader(|b| Some(&buffers[b.index()]));
        let times = r.read_inputs().unwrap().collect();
        let weights = match r.read_outputs().unwrap() {
            gltf::animation::util::ReadOutputs::MorphTargetWeights(w) => w.into_f32().collect(),
            _ => panic!("a weights channel"),
        };
        Played {
            base,
            deltas,
            times,
            weights,
        }
    }

    fn at_key(&self, k: usize) -> Vec<DVec3> {
        let n = self.deltas.len();
        let w = &self.weights[k * n..(k + 1) * n];
        self.base
            .iter()
            .enumerate()
            .map(|(i, p)| {
                *p + self
                    .deltas
                    .iter()
                    .zip(w)
                    .map(|(d, &w)| d[i] * f64::from(w))
                    .sum::<DVec3>()
            })
            .collect()
    }
}

#[test]
fn a_rising_box_lifts_the_sheet_and_the_file_plays_the_box() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = write_sequence(dir.path());
    let out = dir.path().join("sheet.glb");
    let report = bake_cloth(&job(dir.path(), pattern, &out), &mut |_, _| {}).unwrap();

    // The bake lasts the sequence: 10 body frames at 10 fps = 1 s = 50 frames at 50 fps.
    assert_eq!(report.frames, 50);
    let body = report.body.as_ref().unwrap();
    assert_eq!(
        (body.frames, body.vertices, body.triangles),
        (FRAMES, 8, 12)
    );
    assert!(
        report.unconverged_frames.is_empty(),
        "{:?}",
        report.residuals
    );

    let (doc, buffers, _) = common::gltf_read::import(&out).unwrap();
    let sheet = Played::read(&doc, &buffers, "sheet");
    let boxed = Played::read(&doc, &buffers, "sheet_body");
    // Both keyed on the same written frames.
    assert_eq!(sheet.times.len(), 51);
    assert_eq!(sheet.times, boxed.times);

    // The box as played equals the sequence, interpolated, at every written frame: its top
    // corners at top_at(t), its bottom ones still.
    for (k, &t) in boxed.times.iter().enumerate() {
        let t = f64::from(t);
        assert!((t - k as f64 / 50.0).abs() < 1e-6);
        let played = boxed.at_key(k);
        for (p, base) in played.iter().zip(&boxed.base) {
            assert_box_corner(*p, base.y > BOTTOM + 1e-6, t, k);
        }
    }

    // The sheet, from the written file, rests on the risen top: every vertex above the box
    // (over its top) within the contact band — the barrier keeps particles more than half the
    // thickness off and rests them about a thickness off.
    let last = sheet.at_key(50);
    for p in &last {
        assert!(p.x.abs() < HALF && p.z.abs() < HALF, "{p} left the top");
        let gap = p.y - RISE;
        assert!(
            gap > 0.5 * THICKNESS && gap < 2.0 * THICKNESS,
            "sheet vertex {p} is {gap} m above the risen top (thickness {THICKNESS})"
        );
    }
    // And rode it up all the way: at every written frame every vertex is above the top as the
    // sequence has it then, and less than two thicknesses above (it does not lag behind). While
    // the top rises a thickness per step the barrier gives way to about a tenth of it.
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (k, &t) in sheet.times.iter().enumerate() {
        for p in &sheet.at_key(k) {
            let gap = p.y - top_at(f64::from(t));
            lo = lo.min(gap);
            hi = hi.max(gap);
        }
    }
    eprintln!("gap between the sheet and the top over the bake: {lo:.5}..{hi:.5} m");
    assert!(lo > 0.0 && hi < 2.0 * THICKNESS, "{lo}..{hi}");
}

#[test]
fn frames_shorten_the_bake_and_cannot_lengthen_it() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = write_sequence(dir.path());
    let out = dir.path().join("short.glb");
    let mut j = job(dir.path(), pattern, &out);
    j.frames = Some(51);
    let e = bake_cloth(&j, &mut |_, _| {}).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Param {
                param: Param::Frames,
                ..
            }
        ),
        "{e}"
    );
    assert!(!out.exists());
    j.frames = Some(5);
    let report = bake_cloth(&j, &mut |_, _| {}).unwrap();
    assert_eq!(report.frames, 5);
}

#[test]
fn a_missing_frame_is_named_before_the_bake() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = write_sequence(dir.path());
    std::fs::remove_file(dir.path().join("box3.obj")).unwrap();
    let out = dir.path().join("gap.glb");
    let mut steps = 0;
    let e = bake_cloth(&job(dir.path(), pattern, &out), &mut |_, _| steps += 1).unwrap_err();
    let message = e.to_string();
    assert!(message.contains("box3.obj"), "{message}");
    assert!(message.contains("missing"), "{message}");
    assert_eq!(steps, 0, "nothing is simulated");
    assert!(!out.exists());
}

#[test]
fn a_frame_with_other_vertices_is_named_before_the_bake() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = write_sequence(dir.path());
    std::fs::write(dir.path().join("box7.obj"), box_obj(RISE, true)).unwrap();
    let out = dir.path().join("odd.glb");
    let mut steps = 0;
    let e = bake_cloth(&job(dir.path(), pattern, &out), &mut |_, _| steps += 1).unwrap_err();
    let message = e.to_string();
    assert!(message.contains("box7.obj"), "{message}");
    assert!(message.contains("9 vertices"), "{message}");
    assert!(message.contains("box0.obj"), "{message}");
    assert_eq!(steps, 0, "nothing is simulated");
    assert!(!out.exists());
}

#[test]
fn a_malformed_frame_is_named_with_its_line_before_the_bake() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = write_sequence(dir.path());
    let text = box_obj(RISE, false).replacen("v 0.5", "v zero", 1);
    std::fs::write(dir.path().join("box9.obj"), text).unwrap();
    let out = dir.path().join("bad.glb");
    let mut steps = 0;
    let e = bake_cloth(&job(dir.path(), pattern, &out), &mut |_, _| steps += 1).unwrap_err();
    let message = e.to_string();
    assert!(message.contains("box9.obj"), "{message}");
    assert!(message.contains("box9.obj:2:"), "{message}");
    assert_eq!(steps, 0);
}

#[test]
fn the_body_rate_is_required_and_the_numbering_may_be_padded() {
    let dir = tempfile::tempdir().unwrap();
    // Frames numbered 1001.. with %04d.
    for i in 0..3 {
        let top = top_at(i as f64 / BODY_FPS);
        std::fs::write(
            dir.path().join(format!("pad_{:04}.obj", 1001 + i)),
            box_obj(top, false),
        )
        .unwrap();
    }
    let out = dir.path().join("pad.glb");
    let mut j = job(dir.path(), dir.path().join("pad_%04d.obj"), &out);
    j.body_fps = None;
    let e = bake_cloth(&j, &mut |_, _| {}).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Param {
                param: Param::BodyFps,
                ..
            }
        ),
        "{e}"
    );
    j.body_fps = Some(BODY_FPS);
    let report = bake_cloth(&j, &mut |_, _| {}).unwrap();
    let body = report.body.unwrap();
    assert_eq!(body.frames, 3);
    assert!(body.first_file.ends_with("pad_1001.obj"));
    assert_eq!(report.frames, 10);
    // Starting later leaves frames out.
    j.body_start = Some(1002);
    let report = bake_cloth(&j, &mut |_, _| {}).unwrap();
    assert_eq!(report.body.unwrap().frames, 2);
    assert_eq!(report.frames, 5);
}

#[test]
fn body_options_without_a_body_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("none.glb");
    let mut j = job(dir.path(), PathBuf::new(), &out);
    j.body = None;
    let e = bake_cloth(&j, &mut |_, _| {}).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Param {
                param: Param::BodyFps,
                ..
            }
        ),
        "{e}"
    );
    assert!(!out.exists());
}

/// A body given as a glTF animated by morph targets (`--body FILE.glb#NAME`) moves as the
/// sequence it was written from: the rising box, written by a first bake into its glTF as
/// `sheet_body`, read back at the rate the file records (50 fps), has its top at `top_at(t)` at
/// every frame; a second sheet baked on it rides the risen top as on the OBJ sequence. Without a
/// name the first animated mesh is taken (the first bake's sheet); a skinned character is
/// refused, pointing to `--rig`.
#[test]
fn a_body_from_a_morph_animated_gltf_moves_as_its_sequence() {
    use scenebake::io::sequence::load_gltf_sequence;
    let dir = tempfile::tempdir().unwrap();
    let pattern = write_sequence(dir.path());
    let first = dir.path().join("first.glb");
    bake_cloth(&job(dir.path(), pattern, &first), &mut |_, _| {}).unwrap();
    let named = PathBuf::from(format!("{}#sheet_body", first.display()));
    let body = load_gltf_sequence(&first, Some("sheet_body"), None).unwrap();
    assert_eq!((body.fps, body.frames.len()), (50.0, 51));
    assert_eq!(body.mesh.positions.len(), 8);
    for (k, frame) in body.frames.iter().enumerate() {
        let t = k as f64 / 50.0;
        for p in frame {
            assert_box_corner(*p, p.y > BOTTOM + 1e-3, t, k);
        }
    }
    let unnamed = load_gltf_sequence(&first, None, None).unwrap();
    assert!(unnamed.mesh.positions.len() > 8, "the sheet comes first");
    let err = load_gltf_sequence(&common::mesh_path("RiggedSimple.gltf"), None, None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("rig") && err.contains("morph-target"), "{err}");
    // A bake names the options: the body's, and the one a skinned character is given with.
    let rigged = ClothJob {
        body_fps: None,
        ..job(
            dir.path(),
            common::mesh_path("RiggedSimple.gltf"),
            &dir.path().join("rigged.glb"),
        )
    };
    let err = bake_cloth(&rigged, &mut |_, _| {}).unwrap_err().to_string();
    assert!(
        err.starts_with("invalid value for `body`: ")
            && err.contains("no mesh animated by morph-target weights (a skinned character is given with `rig`)"),
        "{err}"
    );

    let second = dir.path().join("second.glb");
    let job = ClothJob {
        body_fps: None,
        ..job(dir.path(), named, &second)
    };
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert_eq!(report.frames, 50);
    assert!(report.unconverged_frames.is_empty());
    let (doc, buffers, _) = common::gltf_read::import(&second).unwrap();
    let sheet = Played::read(&doc, &buffers, "sheet");
    for p in &sheet.at_key(50) {
        let gap = p.y - RISE;
        assert!(
            gap > 0.5 * THICKNESS && gap < 2.0 * THICKNESS,
            "sheet vertex {p} is {gap} m above the risen top"
        );
    }
}

/// Writes `dir/box%d.obj`, 5 frames of a box whose top rises 0.2 m in two body frames (1 m/s:
/// 2 cm, two thicknesses, per 50-fps step), then holds.
fn write_fast_box(dir: &Path) {
    let fast_top = |t: f64| RISE * (t * BODY_FPS / 2.0).clamp(0.0, 1.0);
    for i in 0..5 {
        let top = fast_top(i as f64 / BODY_FPS);
        std::fs::write(dir.join(format!("box{i}.obj")), box_obj(top, false)).unwrap();
    }
}

/// A body that moves a thickness or more in a step, under cloth lying on it in two layers with
/// self-contact: the body moves within each step, pushing the layers up together, while a static
/// mesh collider (a floor) stays put. Every step converges, and no frame has a crossing pair, of
/// the cloth with itself or with the box (the report's exact counts).
#[test]
fn a_fast_box_lifts_a_fold_with_self_contact_every_step_converged_and_nothing_crossing() {
    let dir = tempfile::tempdir().unwrap();
    write_fast_box(dir.path());
    // A static mesh collider beside the moving body (a floor under the box): it stays put.
    let floor = dir.path().join("floor.obj");
    std::fs::write(
        &floor,
        "v -1 -0.6 -1\nv 1 -0.6 -1\nv 1 -0.6 1\nv -1 -0.6 1\nf 1 3 2\nf 1 4 3\n",
    )
    .unwrap();
    let out = dir.path().join("fold.glb");
    let job = ClothJob {
        collider: vec![scenebake::cloth::collide::ColliderSpec::mesh(floor)],
        // A fold lying on the box: two sheets, a thickness and 2.2 thicknesses above its top.
        input: Some(common::write_layers(
            dir.path(),
            "fold",
            &[(THICKNESS, [0.0; 2]), (2.2 * THICKNESS, [0.0; 2])],
        )),
        self_contact: scenebake::bake::cloth::Switch::On,
        ..job(dir.path(), dir.path().join("box%d.obj"), &out)
    };
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert_eq!(report.frames, 20);
    assert!(
        report.unconverged_frames.is_empty(),
        "unconverged frames {:?}, residuals {:?}, iterations {:?}",
        report.unconverged_frames,
        report.residuals,
        report.iterations
    );
    let q = &report.quality;
    assert!(
        q.intersecting_frames.is_empty(),
        "crossing pairs with itself {:?}, with the box {:?}",
        q.self_crossings,
        q.body_crossings
    );
    // Both layers rode up, in order: the lower one above the risen top, the upper one above it.
    let (doc, buffers, _) = common::gltf_read::import(&out).unwrap();
    let last = Played::read(&doc, &buffers, "fold").at_key(20);
    let layer = |l: usize| &last[l * 81..(l + 1) * 81];
    let lowest = |ps: &[DVec3]| ps.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    let highest = |ps: &[DVec3]| ps.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max);
    assert!(
        lowest(layer(0)) > RISE + 0.4 * THICKNESS,
        "lower layer at {} over the top at {RISE}",
        lowest(layer(0))
    );
    assert!(
        lowest(layer(1)) > highest(layer(0)),
        "upper layer from {} over the lower one up to {}",
        lowest(layer(1)),
        highest(layer(0))
    );
}

/// A step split in two (`--splits`) is taken again from its start: the contacts' state, the
/// moving body and the pins are put back as they were, so a bake whose every step fails (one
/// Newton iteration a step, against a tolerance no step reaches) and is split once makes
/// exactly the bake of two substeps a frame, with self-contact on and the body moving within
/// each step. The failed attempts' iterations are counted.
#[test]
fn a_split_step_is_the_two_half_steps_taken_from_its_start() {
    let dir = tempfile::tempdir().unwrap();
    write_fast_box(dir.path());
    let bake = |name: &str, substeps: usize, splits: usize| {
        let out = dir.path().join(format!("{name}.glb"));
        let job = ClothJob {
            input: Some(common::write_layers(
                dir.path(),
                "fold",
                &[(THICKNESS, [0.0; 2]), (2.2 * THICKNESS, [0.0; 2])],
            )),
            self_contact: scenebake::bake::cloth::Switch::On,
            substeps,
            splits,
            max_newton: 3,
            tolerance: 1e-14,
            name: Some("fold".into()),
            ..job(dir.path(), dir.path().join("box%d.obj"), &out)
        };
        let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
        let (doc, buffers, _) = common::gltf_read::import(&out).unwrap();
        let played = Played::read(&doc, &buffers, "fold");
        let keys: Vec<Vec<DVec3>> = (0..=report.frames).map(|k| played.at_key(k)).collect();
        (report, keys)
    };
    let (halves, halves_keys) = bake("halves", 2, 0);
    let (split, split_keys) = bake("split", 1, 1);
    assert_eq!(split.frames, 20);
    assert_eq!(
        split.residuals, halves.residuals,
        "every frame's residual, exactly"
    );
    assert_eq!(split_keys, halves_keys, "every frame's positions");
    assert!(
        split.residuals.iter().all(|r| *r > 1e-14),
        "no step converged"
    );
    assert_eq!(split.steps, vec![2; 20]);
    assert_eq!(halves.steps, vec![2; 20]);
    // Each frame: the failed whole step's iterations, then the halves'.
    for (f, (s, h)) in split.iterations.iter().zip(&halves.iterations).enumerate() {
        assert!(
            *s > *h && *s <= *h + 3,
            "frame {f}: {s} iterations split, {h} in halves"
        );
    }
}

/// The lid's bottom at `t` seconds: from 0.1 m above the box's top down to 5 mm into it by
/// body frame 6 (0.6 s), then held: it closes in on the sheet lying on the box.
fn lid_at(t: f64) -> f64 {
    0.1 - 0.105 * (t / 0.6).clamp(0.0, 1.0)
}

/// The box and, above it, a lid of the same footprint whose bottom is at `bottom`: two closed
/// pieces in one OBJ.
fn box_and_lid_obj(bottom: f64) -> String {
    let lid: String = box_obj(bottom + 0.2, false)
        .lines()
        .map(|l| match l.split_whitespace().collect::<Vec<_>>()[..] {
            ["v", x, y, z] => {
                let y: f64 = y.parse().unwrap();
                let y = if y == BOTTOM { bottom } else { y };
                format!("v {x} {y} {z}\n")
            }
            ["f", a, b, c] => {
                let i = |s: &str| s.parse::<usize>().unwrap() + 8;
                format!("f {} {} {}\n", i(a), i(b), i(c))
            }
            _ => String::new(),
        })
        .collect();
    box_obj(0.0, false) + &lid
}

/// Asserts that no frame of the lid bakes (50 fps) released anything, `released` per frame,
/// while the gap between lid and box was wider than the sheet's two layers: frame f's steps end
/// by (f + 1)/fps, and the gap then is the lid's bottom over the box's top (the sheet's layers
/// need 2 × THICKNESS / 2 of it).
fn none_released_while_open(released: &[usize]) {
    for (f, &n) in released.iter().enumerate() {
        let gap = lid_at((f + 1) as f64 / 50.0);
        if gap > 1.5 * THICKNESS {
            assert_eq!(n, 0, "frame {}: released {n} with a {gap} m gap", f + 1);
        }
    }
}

/// Writes `dir/lid%d.obj`: the box and the lid closing on it, frames `0..FRAMES`.
fn write_lid_sequence(dir: &Path) {
    for i in 0..FRAMES {
        let bottom = lid_at(i as f64 / BODY_FPS);
        std::fs::write(dir.join(format!("lid{i}.obj")), box_and_lid_obj(bottom)).unwrap();
    }
}

/// A lid closing on a sheet that lies on a box, until the two overlap: a particle the lid
/// carries down behind the box's top has nowhere to be held. It is released from that surface
/// (counted in the report's `environment.pinched`) and the bake goes on, where it used to stop
/// with a divergence. While the gap between lid and box is wider than the sheet's two layers,
/// no particle is released.
#[test]
fn cloth_pinched_by_a_closing_body_is_released_counted_and_the_bake_finishes() {
    let dir = tempfile::tempdir().unwrap();
    write_lid_sequence(dir.path());
    let out = dir.path().join("pinched.glb");
    let job = job(dir.path(), dir.path().join("lid%d.obj"), &out);
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert!(out.exists());
    let pinched = &report.environment.as_ref().unwrap().pinched;
    none_released_while_open(pinched);
    assert!(
        pinched.iter().sum::<usize>() > 0,
        "the overlapping lid and box pinch the sheet: {pinched:?}"
    );
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.to_string().contains("pinched 81 particles")),
        "the terminal says so: {:?}",
        report.warnings
    );
}

/// The same lid closing on the sheet with self-contact on: the lid's and the box's vertices and
/// edges are held off the cloth's triangles and edges too, and as the two close in, each push
/// of the body pressed such a pair a tenth further into its layer until a step ended with forces
/// beyond any weight (a divergence). A push that stalls now releases the body's pairs pressed to
/// the bottom of their layer (counted in the report's `environment.pinched_pairs`, and said on
/// the terminal), and the bake finishes; while the gap is wider than the sheet's two layers, no
/// pair is released.
#[test]
fn a_body_closing_on_cloth_with_self_contact_releases_its_pinched_pairs() {
    let dir = tempfile::tempdir().unwrap();
    write_lid_sequence(dir.path());
    let out = dir.path().join("pinched.glb");
    let job = ClothJob {
        self_contact: scenebake::bake::cloth::Switch::On,
        threads: Some(1),
        ..job(dir.path(), dir.path().join("lid%d.obj"), &out)
    };
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert!(out.exists());
    let pairs = &report.environment.as_ref().unwrap().pinched_pairs;
    none_released_while_open(pairs);
    assert!(pairs.iter().sum::<usize>() > 0, "{pairs:?}");
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.to_string().contains("the body was let through the cloth")),
        "the terminal says so: {:?}",
        report.warnings
    );
}
