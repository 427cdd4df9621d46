//! Self-contact: a curtain dropped on its edge onto the floor folds onto itself. With
//! self-contact (`--self-contact on`) no written frame has a crossing triangle pair, by an exact
//! test of every pair on the positions a player computes from the glTF; without it, the same
//! drop passes through itself (so the test can fail).

use crate::common;

use std::io::Write;
use std::path::{Path, PathBuf};

use common::cli::scenebake;
use common::crossing::{brute_between, brute_self, cloth_triangles, obj_soup, weld};
use common::morph::load_morph;

/// A 1 m square curtain of `n`×`n` cells standing on its lower edge 2 cm above the ground
/// (x across, y up), bowed 1 cm out of its plane so it folds the same way every run.
fn curtain(dir: &Path, n: usize) -> PathBuf {
    let path = dir.join("curtain.obj");
    let mut f = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
            let z =
                0.01 * (std::f64::consts::PI * u).sin() * (2.0 * std::f64::consts::PI * v).sin();
            writeln!(f, "v {:.6} {:.6} {:.6}", u - 0.5, 0.02 + v, z).unwrap();
        }
    }
    let id = |i: usize, j: usize| j * (n + 1) + i + 1;
    for j in 0..n {
        for i in 0..n {
            writeln!(f, "f {} {} {}", id(i, j), id(i + 1, j), id(i + 1, j + 1)).unwrap();
            writeln!(f, "f {} {} {}", id(i, j), id(i + 1, j + 1), id(i, j + 1)).unwrap();
        }
    }
    drop(f);
    path
}

/// Bakes `input` with the options `extra` to `NAME.glb` in `dir` (`NAME` the input's stem plus
/// `tag`) with its report; returns the glTF's path and the report.
fn bake(dir: &Path, input: &Path, tag: &str, extra: &[&str]) -> (PathBuf, serde_json::Value) {
    let stem = input.file_stem().unwrap().to_string_lossy();
    let out = dir.join(format!("{stem}{tag}.glb"));
    let report = dir.join(format!("{stem}{tag}.json"));
    let mut args = vec!["cloth", input.to_str().unwrap()];
    args.extend_from_slice(extra);
    args.extend([
        "-o",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    let (code, err) = scenebake(&args);
    assert_eq!(code, 0, "{err}");
    (out, common::read_json(&report))
}

/// The cloth of the bake written to `out` (its report `r`) as played: its welded triangles and
/// its positions at each written frame `0..=frames`, read back from the file.
fn played(
    out: &std::path::Path,
    r: &serde_json::Value,
    frames: usize,
) -> (Vec<[u32; 3]>, Vec<Vec<scenebake::glam::Vec3>>) {
    let fps = r["fps"].as_f64().unwrap() as f32;
    let morph = load_morph(out);
    let tris = weld(&morph.base, &cloth_triangles(out));
    let at = (0..=frames)
        .map(|k| morph.positions_at(k as f32 / fps))
        .collect();
    (tris, at)
}

/// Bakes the curtain's drop; returns the crossing pairs of every written frame (exact test on
/// the file) and the report's own counts.
fn drop_curtain(self_contact: &str) -> (Vec<usize>, Vec<usize>, f32, serde_json::Value) {
    const FRAMES: usize = 36;
    let dir = tempfile::tempdir().unwrap();
    let input = curtain(dir.path(), 24);
    let frames = FRAMES.to_string();
    let (out, r) = bake(
        dir.path(),
        &input,
        "",
        &[
            "--collider",
            "plane:0,1,0,0",
            "--frames",
            &frames,
            "--self-contact",
            self_contact,
        ],
    );
    let (tris, at) = played(&out, &r, FRAMES);
    let file: Vec<usize> = at.iter().map(|p| brute_self(p, &tris)).collect();
    let top = at[FRAMES].iter().map(|p| p.y).fold(f32::MIN, f32::max);
    let reported = common::counts_of(&r["quality"]["self_crossings"]);
    (file, reported, top, r)
}

#[test]
fn a_curtain_dropped_onto_the_floor_never_passes_through_itself() {
    let (file, reported, top, r) = drop_curtain("on");
    assert_eq!(file, reported, "the report counts what the file holds");
    assert!(
        file.iter().all(|&n| n == 0),
        "crossing pairs per frame: {file:?}"
    );
    // It did fold onto itself: the 1 m curtain lies in a pile under 15 % of its height, its
    // layers in contact (hundreds of pairs inside their bands).
    assert!(top < 0.15, "highest point {top} m at the last frame");
    let pairs = common::counts_of(&r["self_contact"]["pairs"]);
    assert!(pairs.iter().max().is_some_and(|&n| n > 100), "{pairs:?}");
    let unconverged = r["unconverged_frames"].as_array().unwrap();
    assert!(unconverged.is_empty(), "{unconverged:?}");
}

#[test]
fn without_self_contact_the_same_curtain_passes_through_itself() {
    let (file, reported, _, _) = drop_curtain("off");
    // The report measures the solver's positions rounded to single precision, a player base +
    // delta: a pair of the pile's thousands touching within that rounding may count in one only.
    for (a, b) in file.iter().zip(&reported) {
        assert!(
            a.abs_diff(*b) <= a / 100 + 1,
            "file {file:?}, report {reported:?}"
        );
    }
    assert!(file.iter().any(|&n| n > 0), "{file:?}");
}

/// The draped dress on its still mannequin (15k particles; the published input crosses itself
/// in 132 triangle pairs): with self-contact every step converges and no written frame has more
/// crossing pairs than the input (the exact count on the file). Newton's Gauss–Seidel sweeps,
/// which do not see the cloth's pairs, are off by default with self-contact: with them this
/// bake stalls at the iteration cap.
#[test]
fn the_draped_dress_with_self_contact_converges_and_adds_no_crossing() {
    let dir = tempfile::tempdir().unwrap();
    let dress = common::mesh_path("garments/dress_draped.obj");
    let body = format!(
        "mesh:{}",
        common::mesh_path("garments/mannequin.obj").display()
    );
    let (out, r) = bake(
        dir.path(),
        &dress,
        "",
        &["--collider", &body, "--self-contact", "on", "--frames", "2"],
    );
    let unconverged = r["unconverged_frames"].as_array().unwrap();
    assert!(unconverged.is_empty(), "{unconverged:?} {}", r["residuals"]);
    let (tris, at) = played(&out, &r, 2);
    let file: Vec<usize> = at.iter().map(|p| brute_self(p, &tris)).collect();
    assert!(file[0] > 100, "the input crosses itself: {file:?}");
    assert!(file[1..].iter().all(|&n| n <= file[0]), "{file:?}");
}

/// A coarse sheet (20 cm cells) dropped across a thin ridge (a 2 cm prism along z, between two
/// columns of particles). Kept off by its particles alone, the sheet lets the ridge's edge pass
/// between them, through its triangles; with self-contact the ridge's edges and vertices are
/// pairs too, and no written frame crosses it (the exact count of the file against the ridge).
fn drop_on_ridge(self_contact: &str) -> Vec<usize> {
    const FRAMES: usize = 20;
    let dir = tempfile::tempdir().unwrap();
    let n = 5;
    let sheet = dir.path().join("sheet.obj");
    let mut f = std::io::BufWriter::new(std::fs::File::create(&sheet).unwrap());
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
            writeln!(f, "v {:.6} 0.25 {:.6}", u - 0.5, v - 0.5).unwrap();
        }
    }
    let id = |i: usize, j: usize| j * (n + 1) + i + 1;
    for j in 0..n {
        for i in 0..n {
            writeln!(f, "f {} {} {}", id(i, j), id(i + 1, j + 1), id(i + 1, j)).unwrap();
            writeln!(f, "f {} {} {}", id(i, j), id(i, j + 1), id(i + 1, j + 1)).unwrap();
        }
    }
    drop(f);
    // The ridge: a closed triangular prism along z, its apex at y = 0.2 and x = 0, midway
    // between the particle columns x = -0.1 and x = 0.1.
    let ridge = dir.path().join("ridge.obj");
    let (x, w, top, z) = (0.0, 0.01, 0.2, 0.7);
    let corners = [
        [x - w, 0.0, -z],
        [x + w, 0.0, -z],
        [x, top, -z],
        [x - w, 0.0, z],
        [x + w, 0.0, z],
        [x, top, z],
    ];
    let faces = [
        [1, 3, 2],
        [4, 5, 6],
        [1, 2, 5],
        [1, 5, 4],
        [2, 3, 6],
        [2, 6, 5],
        [3, 1, 4],
        [3, 4, 6],
    ];
    let mut f = std::io::BufWriter::new(std::fs::File::create(&ridge).unwrap());
    for c in corners {
        writeln!(f, "v {} {} {}", c[0], c[1], c[2]).unwrap();
    }
    for t in faces {
        writeln!(f, "f {} {} {}", t[0], t[1], t[2]).unwrap();
    }
    drop(f);
    drop_over(&sheet, &[], &ridge, FRAMES, self_contact).with_body
}

#[test]
fn with_self_contact_a_ridge_between_particles_does_not_cut_through_the_sheet() {
    let file = drop_on_ridge("on");
    assert!(file.iter().all(|&n| n == 0), "{file:?}");
}

#[test]
fn kept_off_by_its_particles_alone_the_sheet_falls_through_the_ridge() {
    let file = drop_on_ridge("off");
    assert!(file.iter().any(|&n| n > 0), "{file:?}");
}

/// Self-contact's broad and narrow phases split over two threads on a large cloth (a 40×40
/// curtain: 1,681 vertices and 4,920 edges) and give the same pairs in the same order, so a bake
/// on two threads writes the same file as on one, to the byte.
#[test]
fn self_contact_on_two_threads_bakes_the_same_file_as_on_one() {
    let dir = tempfile::tempdir().unwrap();
    let input = curtain(dir.path(), 40);
    let run = |threads: &str| {
        let (out, r) = bake(
            dir.path(),
            &input,
            threads,
            &[
                "--collider",
                "plane:0,1,0,0",
                "--frames",
                "5",
                "--self-contact",
                "on",
                "--threads",
                threads,
            ],
        );
        (
            std::fs::read(&out).unwrap(),
            common::counts_of(&r["self_contact"]["pairs"]),
        )
    };
    let (one, pairs) = run("1");
    let (two, _) = run("2");
    assert!(pairs.iter().any(|&n| n > 0), "pairs in contact: {pairs:?}");
    assert!(one == two, "the files differ between one thread and two");
}

/// A move between steps (a character loop's steering, `--loop-blend`) goes only as far as the
/// cloth can go without passing through itself: two sheets 1 cm apart, the upper one moved
/// 2 cm straight down through the lower. With self-contact the solver allows less than half of
/// the move and the state there crosses nowhere (an exact test of every pair); without it, the
/// whole move, which crosses.
#[test]
fn a_move_between_steps_stops_where_the_cloth_would_cross_itself() {
    use scenebake::bake::cloth::{prepare_cloth, Switch};
    use scenebake::cloth::make_solver;
    use scenebake::glam::{DVec3, Vec3};

    let dir = tempfile::tempdir().unwrap();
    // The lower sheet's grid is offset from the upper's, so that crossings are not along edges.
    let input = common::write_layers(
        dir.path(),
        "two",
        &[(0.0, [0.013, 0.0208]), (0.01, [0.0, 0.0])],
    );
    let moved = |on: Switch| {
        let job = scenebake::ClothJob {
            input: Some(input.clone()),
            output: dir.path().join("x.glb"),
            self_contact: on,
            self_thickness: Some(0.004),
            ..scenebake::ClothJob::default()
        };
        let p = prepare_cloth(&job).unwrap();
        let mut solver = make_solver(&p.model, &p.params).unwrap();
        let sys = solver.system().clone();
        let from = sys.gather(p.model.positions());
        let mid = from.iter().map(|x| x.x).fold(f64::MIN, f64::max) * 0.5
            + from.iter().map(|x| x.x).fold(f64::MAX, f64::min) * 0.5;
        let to: Vec<DVec3> = from
            .iter()
            .map(|&x| {
                if x.y > 0.005 && x.x < mid {
                    x - DVec3::new(0.0, 0.02, 0.0)
                } else {
                    x
                }
            })
            .collect();
        let t = solver.free_path(&from, &to);
        let at: Vec<DVec3> = from
            .iter()
            .zip(&to)
            .map(|(a, b)| *a + (*b - *a) * t)
            .collect();
        let mut all = p.model.positions().to_vec();
        sys.scatter(&at, &mut all);
        let points: Vec<Vec3> = all.iter().map(|p| p.as_vec3()).collect();
        (t, brute_self(&points, &p.model.mesh.triangles))
    };
    let (t, crossing) = moved(Switch::On);
    assert!(t < 0.5 && crossing == 0, "{t}, {crossing} pairs crossing");
    let (t, crossing) = moved(Switch::Off);
    assert!(t == 1.0 && crossing > 0, "{t}, {crossing} pairs crossing");
}

/// A sheet dropped over a closed mesh collider (an OBJ of `v` and `f` lines) on the ground.
struct Dropped {
    /// The crossing pairs of every written frame of the sheet with itself and with the
    /// collider, by an exact test on the file (the collider read from its OBJ); the report's
    /// counts are checked to be these.
    with_itself: Vec<usize>,
    with_body: Vec<usize>,
    report: serde_json::Value,
}

/// Bakes `sheet` (placed by `place`, e.g. `--translate`) dropped over the collider `body` and
/// the ground for `frames` frames; see [`Dropped`].
fn drop_over(
    sheet: &Path,
    place: &[&str],
    body: &Path,
    frames: usize,
    self_contact: &str,
) -> Dropped {
    let dir = tempfile::tempdir().unwrap();
    let (collider, count) = (format!("mesh:{}", body.display()), frames.to_string());
    let mut args = place.to_vec();
    args.extend([
        "--collider",
        &collider,
        "--collider",
        "plane:0,1,0,0",
        "--frames",
        &count,
        "--self-contact",
        self_contact,
    ]);
    let (out, r) = bake(dir.path(), sheet, "", &args);
    let (tris, at) = played(&out, &r, frames);
    let (points, body_tris) = obj_soup(body);
    let with_body: Vec<usize> = at
        .iter()
        .map(|p| brute_between(p, &tris, &points, &body_tris))
        .collect();
    let with_itself: Vec<usize> = at.iter().map(|p| brute_self(p, &tris)).collect();
    for (file, key) in [
        (&with_body, "body_crossings"),
        (&with_itself, "self_crossings"),
    ] {
        assert_eq!(
            *file,
            common::counts_of(&r["quality"][key]),
            "the report counts what the file holds"
        );
    }
    Dropped {
        with_itself,
        with_body,
        report: r,
    }
}

/// The shipped 1 m sheet (3.3 cm cells) dropped over the shipped thin ring (a closed torus
/// standing on the ground, its tube 16 mm across), 20 frames.
fn drop_over_ring(self_contact: &str) -> Dropped {
    drop_over(
        &common::mesh_path("plane_30x30.obj"),
        &["--translate", "0,0.5,0"],
        &common::mesh_path("ring.obj"),
        20,
        self_contact,
    )
}

#[test]
fn with_self_contact_a_sheet_over_a_thin_ring_crosses_neither_itself_nor_the_ring() {
    let Dropped {
        with_itself,
        with_body: with_ring,
        report: r,
    } = drop_over_ring("on");
    assert!(
        with_itself.iter().chain(&with_ring).all(|&n| n == 0),
        "with itself {with_itself:?}, with the ring {with_ring:?}"
    );
    let unconverged = r["unconverged_frames"].as_array().unwrap();
    assert!(unconverged.is_empty(), "{unconverged:?}");
}

#[test]
fn kept_off_by_its_particles_alone_the_sheet_falls_through_the_ring_and_itself() {
    let Dropped {
        with_itself,
        with_body: with_ring,
        ..
    } = drop_over_ring("off");
    assert!(
        with_itself.iter().any(|&n| n > 0) && with_ring.iter().any(|&n| n > 0),
        "with itself {with_itself:?}, with the ring {with_ring:?}"
    );
}
