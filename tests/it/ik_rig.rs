//! IK on chains inside real rigged glTF files: the document survives, the tip follows the path.

use crate::common;

use common::{load, mesh_path as mesh};
use glam::DVec3;
use scenebake::bake::{bake_ik, IkJob};
use scenebake::ik::SolverKind;
use scenebake::path::CurveKind;
use scenebake::Error;

#[test]
fn fox_spine_draws_a_heart_and_keeps_the_document() {
    let dir = tempfile::tempdir().unwrap();
    for solver in [SolverKind::Fabrik, SolverKind::Ccd] {
        let job = IkJob {
            rig: Some(mesh("Fox.glb")),
            chain: Some("b_Spine01_02..b_Head_05".into()),
            curve: Some(CurveKind::Heart),
            solver,
            output: dir.path().join(format!("fox_{}.glb", solver.as_str())),
            ..Default::default()
        };
        let r = bake_ik(&job, &mut |_, _| {}).unwrap();
        assert_eq!(r.joints, 4);
        assert_eq!(
            r.joint_names,
            ["b_Spine01_02", "b_Spine02_03", "b_Neck_04", "b_Head_05"]
        );
        assert_eq!(
            r.unreachable, 0,
            "{solver:?}: the default heart should be inside the reach"
        );

        let before = load(&mesh("Fox.glb"));
        let after = load(&job.output);
        // Added: the drawn trail, a `trail` node holding one mesh node per piece, and its material.
        let pieces = after
            .doc
            .nodes()
            .nth(after.node_by_name("trail"))
            .unwrap()
            .children()
            .count();
        assert!(pieces > 0);
        assert_eq!(
            after.doc.meshes().count(),
            before.doc.meshes().count() + pieces
        );
        assert_eq!(after.doc.skins().count(), before.doc.skins().count());
        assert_eq!(
            after.doc.nodes().count(),
            before.doc.nodes().count() + pieces + 1
        );
        assert_eq!(
            after.doc.materials().count(),
            before.doc.materials().count() + 1
        );
        assert_eq!(after.doc.textures().count(), before.doc.textures().count());
        assert_eq!(after.doc.images().count(), before.doc.images().count());
        assert_eq!(
            after.doc.animations().count(),
            before.doc.animations().count() + 1
        );
        assert_eq!(
            after.doc.buffers().count(),
            1,
            "GLB keeps a single BIN buffer"
        );
        // The original buffer's bytes are a prefix of the new one (data appended).
        assert!(after.buffers[0].len() > before.buffers[0].len());
        assert_eq!(
            &after.buffers[0][..before.doc.buffers().next().unwrap().length()],
            &before.buffers[0][..before.doc.buffers().next().unwrap().length()]
        );
        // The bake plays first; the original animations follow unchanged: every channel, read
        // back from both files, has the same node, times and values.
        assert_eq!(after.doc.animations().next().unwrap().name(), Some("ik"));
        for (a, b) in before.doc.animations().zip(after.doc.animations().skip(1)) {
            assert_eq!(a.name(), b.name());
            assert_eq!(a.channels().count(), b.channels().count());
            let name = a.name().unwrap();
            let (old, new) = (before.animation(name), after.animation(name));
            assert!(!old.rotation.is_empty(), "{name} has rotation keys");
            assert!(
                old == new,
                "{solver:?}: animation {name} changed in the bake"
            );
        }

        // Independent FK through the whole hierarchy (parents above the chain root included).
        let tracks = after.animation("ik");
        let head = after.node_by_name("b_Head_05");
        let spine = after.node_by_name("b_Spine01_02");
        let (times, _) = tracks.rotation.get(&spine).unwrap();
        assert_eq!(times.len(), r.frames);
        let empty = common::Tracks::default();
        let root_rest = after.world_pos(&empty, spine, 0.0);
        let bones: Vec<f64> = {
            let names = ["b_Spine01_02", "b_Spine02_03", "b_Neck_04", "b_Head_05"];
            let p: Vec<DVec3> = names
                .iter()
                .map(|n| after.world_pos(&empty, after.node_by_name(n), 0.0))
                .collect();
            p.windows(2).map(|w| w[0].distance(w[1])).collect()
        };
        let mut within = 0;
        for (k, &t) in times.iter().enumerate() {
            let tip = after.world_pos(&tracks, head, t);
            let target = DVec3::from_array(r.targets[k]);
            // f32 keys on a ~60-unit chain: allow for rounding on top of the solver tolerance.
            if tip.distance(target) <= 1e-4 + 2e-4 {
                within += 1;
            }
            if r.error[k] <= 1e-4 {
                assert!(
                    tip.distance(target) <= 1e-4 + 2e-4,
                    "{solver:?} frame {k}: reported reached but file tip is {} away",
                    tip.distance(target)
                );
            }
            assert!(
                after.world_pos(&tracks, spine, t).distance(root_rest) < 1e-3,
                "chain root moved"
            );
            let names = ["b_Spine01_02", "b_Spine02_03", "b_Neck_04", "b_Head_05"];
            let p: Vec<DVec3> = names
                .iter()
                .map(|n| after.world_pos(&tracks, after.node_by_name(n), t))
                .collect();
            for (i, w) in p.windows(2).enumerate() {
                assert!(
                    (w[0].distance(w[1]) - bones[i]).abs() < 1e-3,
                    "bone {i} length changed"
                );
            }
        }
        assert_eq!(within, r.reached, "{solver:?}");
        assert!(
            r.reached as f64 >= 0.95 * r.frames as f64,
            "{solver:?}: only {} of {} frames reached",
            r.reached,
            r.frames
        );
    }
}

#[test]
fn matrix_nodes_and_negative_w_rig_is_animated_in_its_real_frames() {
    // RiggedSimple: parents stored as matrices (a Z-up flip and a 90° turn), Bone as a matrix,
    // Bone.001 with w ≈ -1. A two-joint chain: only Bone rotates, so the tip can only reach the
    // sphere around Bone through its rest position; put a circle on that sphere.
    let dir = tempfile::tempdir().unwrap();
    let src = load(&mesh("RiggedSimple.gltf"));
    let empty = common::Tracks::default();
    let root = src.world_pos(&empty, src.node_by_name("Bone"), 0.0);
    let rest_tip = src.world_pos(&empty, src.node_by_name("Bone.001"), 0.0);
    let (axis, len) = ((rest_tip - root).normalize(), rest_tip.distance(root));
    let alpha: f64 = 0.3;
    let job = IkJob {
        rig: Some(mesh("RiggedSimple.gltf")),
        chain: Some("Bone..Bone.001".into()),
        curve: Some(CurveKind::Circle),
        center: Some(root + axis * len * alpha.cos()),
        radius: Some(len * alpha.sin()),
        output: dir.path().join("rs.gltf"),
        ..Default::default()
    };
    let r = bake_ik(&job, &mut |_, _| {}).unwrap();
    assert_eq!(r.reached, r.frames, "max error {}", r.max_error);
    let l = load(&job.output);
    let bone = l.node_by_name("Bone");
    assert!(
        matches!(
            l.doc.nodes().nth(bone).unwrap().transform(),
            gltf::scene::Transform::Decomposed { .. }
        ),
        "animated node must be TRS"
    );
    assert_eq!(l.doc.animations().count(), 2);
    let pieces = l
        .doc
        .nodes()
        .nth(l.node_by_name("trail"))
        .unwrap()
        .children()
        .count();
    assert_eq!(l.doc.meshes().count(), src.doc.meshes().count() + pieces);
    let tracks = l.animation("ik");
    let tip = l.node_by_name("Bone.001");
    let (times, keys) = tracks.rotation.get(&bone).unwrap();
    for (k, &t) in times.iter().enumerate() {
        let p = l.world_pos(&tracks, tip, t);
        assert!(
            p.distance(DVec3::from_array(r.targets[k])) < 1e-4 + 1e-5,
            "frame {k}: {}",
            p.distance(DVec3::from_array(r.targets[k]))
        );
        // The circle really is on the sphere the tip can reach, i.e. the frames are right.
        assert!((p.distance(root) - len).abs() < 1e-4);
    }
    for q in keys {
        let n: f32 = q.iter().map(|x| x * x).sum::<f32>().sqrt();
        assert!((n - 1.0).abs() < 1e-6);
    }
    for w in keys.windows(2) {
        assert!(
            w[0].iter().zip(&w[1]).map(|(a, b)| a * b).sum::<f32>() > 0.0,
            "sign flip between keys"
        );
    }
}

#[test]
fn simple_skin_loads_base64_buffers_but_its_zero_length_bone_is_refused() {
    // SimpleSkin's second joint sits exactly on the first: no bone to turn.
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        rig: Some(mesh("SimpleSkin.gltf")),
        chain: Some("#1..#2".into()),
        curve: Some(CurveKind::Square),
        output: dir.path().join("ss.glb"),
        ..Default::default()
    };
    let e = bake_ik(&job, &mut |_, _| {}).unwrap_err().to_string();
    assert!(
        e.contains("SimpleSkin.gltf") && e.contains("#2") && e.contains("length 0"),
        "{e}"
    );
}

#[test]
fn bad_chains_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let base = IkJob {
        rig: Some(mesh("Fox.glb")),
        curve: Some(CurveKind::Circle),
        output: dir.path().join("x.glb"),
        ..Default::default()
    };
    let e = bake_ik(
        &IkJob {
            chain: Some("b_Spine01_02..b_Nose".into()),
            ..base.clone()
        },
        &mut |_, _| {},
    )
    .unwrap_err();
    assert!(
        matches!(&e, Error::UnknownJoint { joint, .. } if joint == "b_Nose"),
        "{e}"
    );
    assert!(e.to_string().contains("Fox.glb") && e.to_string().contains("b_Nose"));
    let e = bake_ik(
        &IkJob {
            chain: Some("b_Head_05..b_Spine01_02".into()),
            ..base.clone()
        },
        &mut |_, _| {},
    )
    .unwrap_err();
    assert!(matches!(e, Error::JointNotBelow { .. }), "{e}");
    let e = bake_ik(
        &IkJob {
            chain: Some("b_Spine01_02..b_Tail03_014".into()),
            ..base.clone()
        },
        &mut |_, _| {},
    )
    .unwrap_err();
    assert!(matches!(e, Error::JointNotBelow { .. }), "{e}");
    let e = bake_ik(
        &IkJob {
            chain: Some("#999..#3".into()),
            ..base.clone()
        },
        &mut |_, _| {},
    )
    .unwrap_err();
    assert!(matches!(e, Error::UnknownJoint { .. }), "{e}");
    let e = bake_ik(
        &IkJob {
            chain: Some("b_Spine01_02".into()),
            ..base.clone()
        },
        &mut |_, _| {},
    )
    .unwrap_err();
    assert!(e.to_string().contains("`chain`"), "{e}");
    assert!(!dir.path().join("x.glb").exists());
}

/// What a viewer plays is the bake: it is animations[0], and it keys translation, rotation and
/// scale of every joint of the skin (constant ones at the input's own node transforms, read here
/// from the input file), so no bone keeps another action's pose when Blender switches actions.
/// The fps and frame range are in asset.extras.
#[test]
fn the_rig_bake_plays_first_and_poses_every_joint() {
    let dir = tempfile::tempdir().unwrap();
    for (rig, chain) in [
        ("Fox.glb", "b_Spine01_02..b_Head_05"),
        ("RiggedSimple.gltf", "Bone..Bone.001"),
    ] {
        let job = IkJob {
            rig: Some(mesh(rig)),
            chain: Some(chain.into()),
            curve: Some(CurveKind::Circle),
            fps: 24.0,
            output: dir.path().join(format!("{rig}.glb")),
            ..Default::default()
        };
        let r = bake_ik(&job, &mut |_, _| {}).unwrap();
        let before = load(&mesh(rig));
        let after = load(&job.output);
        let first = after.doc.animations().next().unwrap();
        assert_eq!(first.name(), Some("ik"), "{rig}");
        let mut keyed = std::collections::BTreeSet::new();
        for ch in first.channels() {
            let path = match ch.target().property() {
                gltf::animation::Property::Translation => "translation",
                gltf::animation::Property::Rotation => "rotation",
                gltf::animation::Property::Scale => "scale",
                gltf::animation::Property::MorphTargetWeights => "weights",
            };
            keyed.insert((ch.target().node().index(), path));
        }
        let ik = after.animation("ik");
        let end = (r.frames - 1) as f32 / 24.0;
        for skin in after.doc.skins() {
            for joint in skin.joints() {
                let j = joint.index();
                for path in ["translation", "rotation", "scale"] {
                    assert!(
                        keyed.contains(&(j, path)),
                        "{rig}: joint #{j} {path} not keyed"
                    );
                }
                // Constant keys hold the input's own transform over the whole bake.
                let (t, rot, s) = before.doc.nodes().nth(j).unwrap().transform().decomposed();
                if let Some((times, vals, _)) = ik.translation.get(&j) {
                    assert_eq!(times.first(), Some(&0.0));
                    assert!((times.last().unwrap() - end).abs() < 1e-6);
                    for v in vals {
                        for c in 0..3 {
                            assert!(
                                (v[c] - t[c]).abs() <= 1e-6 * (1.0 + t[c].abs()),
                                "{rig} #{j}"
                            );
                        }
                    }
                }
                if let Some((_, vals, _)) = ik.scale.get(&j) {
                    for v in vals {
                        for c in 0..3 {
                            assert!((v[c] - s[c]).abs() < 1e-5, "{rig} #{j} scale");
                        }
                    }
                }
                if let Some((times, vals)) = ik.rotation.get(&j) {
                    if times.len() == 2 {
                        for v in vals {
                            let dot: f32 = v.iter().zip(&rot).map(|(a, b)| a * b).sum();
                            assert!(dot.abs() > 1.0 - 1e-6, "{rig} #{j} rotation");
                        }
                    }
                }
            }
        }
        // Every joint another animation moves, the bake keys too (Blender keeps the pose of
        // bones the active action does not key).
        for other in after.doc.animations().skip(1) {
            for ch in other.channels() {
                let n = ch.target().node().index();
                let is_joint = after
                    .doc
                    .skins()
                    .any(|s| s.joints().any(|j| j.index() == n));
                if is_joint {
                    let path = ch.target().property();
                    assert!(
                        first.channels().any(
                            |c| c.target().node().index() == n && c.target().property() == path
                        ),
                        "{rig}: {:?} keys #{n} {path:?}, the bake does not",
                        other.name()
                    );
                }
            }
        }
        let extras: serde_json::Value =
            serde_json::from_str(after.doc.as_json().asset.extras.as_ref().unwrap().get()).unwrap();
        assert_eq!(
            extras["scenebake"],
            serde_json::json!({"fps": 24.0, "frame_start": 0, "frame_end": r.frames - 1, "animation": "ik"})
        );
    }
}

/// A rig whose weights do not sum to 1 (RiggedSimple with 40 vertices' weights halved): the
/// bake renormalises them, says so, and the output's weights sum to 1 (read back with the gltf
/// crate).
#[test]
fn unnormalised_weights_are_renormalised_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let src = mesh("RiggedSimple.gltf");
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&src).unwrap()).unwrap();
    let acc = &json["accessors"][json["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"]
        .as_u64()
        .unwrap() as usize];
    let view = &json["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
    let (offset, stride) = (
        view["byteOffset"].as_u64().unwrap() as usize
            + acc["byteOffset"].as_u64().unwrap_or(0) as usize,
        view["byteStride"].as_u64().unwrap_or(16) as usize,
    );
    let mut bin = std::fs::read(mesh("RiggedSimple0.bin")).unwrap();
    for v in 0..40 {
        for c in 0..4 {
            let at = offset + v * stride + c * 4;
            let w = f32::from_le_bytes(bin[at..at + 4].try_into().unwrap()) * 0.5;
            bin[at..at + 4].copy_from_slice(&w.to_le_bytes());
        }
    }
    std::fs::write(dir.path().join("RiggedSimple0.bin"), bin).unwrap();
    std::fs::copy(&src, dir.path().join("halved.gltf")).unwrap();
    let job = IkJob {
        rig: Some(dir.path().join("halved.gltf")),
        chain: Some("Bone..Bone.001".into()),
        curve: Some(CurveKind::Circle),
        output: dir.path().join("out.glb"),
        ..Default::default()
    };
    let r = bake_ik(&job, &mut |_, _| {}).unwrap();
    assert_eq!(r.warnings.len(), 1, "{:?}", r.warnings);
    assert!(
        r.warnings[0].to_string().contains(
            "halved.gltf: renormalised the skin weights of 40 vertices (they summed to 0.500–0.500"
        ),
        "{}",
        r.warnings[0]
    );
    let out = load(&job.output);
    let mesh0 = out.doc.meshes().next().unwrap();
    let prim = mesh0.primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&out.buffers[b.index()]));
    let sums: Vec<f64> = reader
        .read_weights(0)
        .unwrap()
        .into_f32()
        .map(|w| w.iter().map(|&x| f64::from(x)).sum())
        .collect();
    assert_eq!(sums.len(), 160);
    for (v, s) in sums.iter().enumerate() {
        assert!((s - 1.0).abs() < 1e-7, "vertex {v} sums to {s}");
    }
    // The unmodified rig needs no repair and gets no warning.
    let clean = bake_ik(
        &IkJob {
            rig: Some(mesh("RiggedSimple.gltf")),
            output: dir.path().join("clean.glb"),
            ..job
        },
        &mut |_, _| {},
    )
    .unwrap();
    assert!(clean.warnings.is_empty(), "{:?}", clean.warnings);
}
