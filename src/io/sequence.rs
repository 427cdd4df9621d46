//! Reads a body given as a sequence of OBJ files (`--body kick/shell%d.obj`): one file per
//! frame, named by a printf-style pattern with one frame number (`%d`, `%04d`, `%4d`; `%%` is a
//! literal `%`).
//!
//! The frames are the pattern's files numbered from the first that exists (or from a given
//! start) up to the last, without gaps. Every file is read before anything is simulated, and
//! each must have the first frame's vertices and faces: only positions change.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::data::MeshSequence;
use crate::error::{Error, Result};
use crate::io::obj::{load_obj, ObjOptions};

/// A file-name pattern with one frame number.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FramePattern {
    dir: PathBuf,
    prefix: String,
    suffix: String,
    width: usize,
    zero_pad: bool,
}

impl FramePattern {
    /// Parses `pattern`: a path whose file name holds exactly one `%d`, `%0Nd` or `%Nd`.
    ///
    /// # Errors
    /// [`Error::Value`] when the file name has no frame number, more than one, or another
    /// conversion, or when the directory part holds one (the job names `--body`).
    pub fn parse(pattern: &Path) -> Result<Self> {
        let shown = pattern.display();
        let bad = |why: &str| {
            Error::value(format!(
                "`{shown}`: {why} (a file pattern with one frame number, such as \
                 `kick/shell%d.obj` or `frame_%04d.obj`)"
            ))
        };
        let name = pattern
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| bad("has no file name"))?;
        let dir = pattern.parent().map(Path::to_path_buf).unwrap_or_default();
        if dir.to_string_lossy().contains('%') {
            return Err(bad(
                "the frame number goes in the file name, not a directory",
            ));
        }
        let mut prefix = String::new();
        let mut suffix = String::new();
        let mut number: Option<(usize, bool)> = None;
        let mut chars = name.chars().peekable();
        while let Some(c) = chars.next() {
            let out = if number.is_some() {
                &mut suffix
            } else {
                &mut prefix
            };
            if c != '%' {
                out.push(c);
                continue;
            }
            if chars.peek() == Some(&'%') {
                chars.next();
                out.push('%');
                continue;
            }
            let mut spec = String::new();
            while let Some(&d) = chars.peek().filter(|d| d.is_ascii_digit()) {
                spec.push(d);
                chars.next();
            }
            if chars.next() != Some('d') {
                return Err(bad("a frame number is written %d, %0Nd or %Nd"));
            }
            if number.is_some() {
                return Err(bad("has more than one frame number"));
            }
            let zero_pad = spec.starts_with('0');
            let width = if spec.is_empty() {
                0
            } else {
                spec.parse()
                    .map_err(|_| bad("the frame number's width is too large"))?
            };
            if width > 20 {
                return Err(bad("the frame number's width is too large"));
            }
            number = Some((width, zero_pad));
        }
        let Some((width, zero_pad)) = number else {
            return Err(bad("has no frame number"));
        };
        Ok(FramePattern {
            dir,
            prefix,
            suffix,
            width,
            zero_pad,
        })
    }

    /// The file of frame number `n`.
    pub fn path(&self, n: u64) -> PathBuf {
        let w = self.width;
        let number = if self.zero_pad {
            format!("{n:0w$}")
        } else {
            format!("{n:w$}")
        };
        self.dir
            .join(format!("{}{number}{}", self.prefix, self.suffix))
    }

    /// The frame numbers of the files in the pattern's directory that it names.
    ///
    /// # Errors
    /// [`Error::Io`] when the directory cannot be read.
    pub fn existing(&self) -> Result<BTreeSet<u64>> {
        let dir = if self.dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            &self.dir
        };
        let mut found = BTreeSet::new();
        for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
            let entry = entry.map_err(|e| Error::io(dir, e))?;
            let name = entry.file_name();
            let Some(name) = name.to_str() else {
                continue;
            };
            let Some(middle) = name
                .strip_prefix(self.prefix.as_str())
                .and_then(|m| m.strip_suffix(self.suffix.as_str()))
            else {
                continue;
            };
            let digits = middle.trim_start_matches(' ');
            if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                continue;
            }
            let Ok(n) = digits.parse::<u64>() else {
                continue;
            };
            // Only the number's own spelling: `shell01.obj` is not frame 1 of `shell%d.obj`.
            if self.path(n).file_name() == Some(entry.file_name().as_os_str()) {
                found.insert(n);
            }
        }
        Ok(found)
    }
}

/// Reads the OBJ sequence `pattern` (see the module documentation) played at `fps`, from frame
/// number `start` (default: the first file that exists) to the last file, checking every frame.
///
/// # Errors
/// [`Error::Value`] for a bad pattern, no matching file, or a sequence of one frame (the job
/// names `--body`); [`Error::InvalidInput`] naming the file for a missing frame (a gap) or a frame whose
/// vertices or faces differ from the first's; the OBJ reader's errors (file and line).
pub fn load_obj_sequence(pattern: &Path, fps: f64, start: Option<u64>) -> Result<MeshSequence> {
    let p = FramePattern::parse(pattern)?;
    let numbers = p.existing()?;
    let first = match (start, numbers.first()) {
        (Some(s), _) => {
            if !numbers.contains(&s) {
                let path = p.path(s);
                return Err(Error::io(
                    &path,
                    std::io::Error::new(
                        std::io::ErrorKind::NotFound,
                        "the first frame of the body sequence does not exist",
                    ),
                ));
            }
            s
        }
        (None, Some(&f)) => f,
        (None, None) => {
            return Err(Error::value(format!(
                "`{}`: no file matches the pattern (frame 0 would be {})",
                pattern.display(),
                p.path(0).display()
            )))
        }
    };
    let last = *numbers.last().expect("the first frame exists");
    if let Some(gap) = (first..=last).find(|n| !numbers.contains(n)) {
        let next = numbers.range(gap..).next().expect("the last frame follows");
        return Err(Error::invalid(
            p.path(gap),
            format!(
                "frame {gap} of the body sequence is missing: frames {first}–{} exist, then {}–{last}",
                gap - 1,
                next
            ),
        ));
    }
    if last == first {
        return Err(Error::value(format!(
            "`{}`: only one frame ({}): a body sequence needs at least two",
            pattern.display(),
            p.path(first).display()
        )));
    }
    let files: Vec<PathBuf> = (first..=last).map(|n| p.path(n)).collect();
    let options = ObjOptions::default();
    let mesh = load_obj(&files[0], &options)?;
    let mut frames = Vec::with_capacity(files.len());
    frames.push(mesh.positions.clone());
    for file in &files[1..] {
        let m = load_obj(file, &options)?;
        let differs = |what: String| {
            Error::invalid(
                file,
                format!(
                    "{what}: every frame of a body sequence has the vertices and faces of its \
                     first frame, {}",
                    files[0].display()
                ),
            )
        };
        if m.file_index.len() != mesh.file_index.len() {
            return Err(differs(format!(
                "{} vertices used by faces, where the first frame has {}",
                m.file_index.len(),
                mesh.file_index.len()
            )));
        }
        if m.triangles.len() != mesh.triangles.len() {
            return Err(differs(format!(
                "{} triangles, where the first frame has {}",
                m.triangles.len(),
                mesh.triangles.len()
            )));
        }
        if let Some(v) = (0..m.file_index.len()).find(|&i| m.file_index[i] != mesh.file_index[i]) {
            return Err(differs(format!(
                "its faces use vertex {} where the first frame's use vertex {}",
                m.file_index[v] + 1,
                mesh.file_index[v] + 1
            )));
        }
        if let Some(t) = (0..m.triangles.len()).find(|&t| m.triangles[t] != mesh.triangles[t]) {
            let corners = |tri: [u32; 3], mesh: &crate::mesh::Mesh| {
                tri.map(|i| (mesh.file_index[i as usize] + 1).to_string())
                    .join(" ")
            };
            return Err(differs(format!(
                "triangle {} joins vertices {}, where the first frame's joins {}",
                t + 1,
                corners(m.triangles[t], &m),
                corners(mesh.triangles[t], &mesh)
            )));
        }
        frames.push(m.positions);
    }
    Ok(MeshSequence {
        mesh,
        frames,
        fps,
        files,
        first_number: first,
    })
}

/// Reads a body animated by morph targets from a glTF file (`--body FILE.glb[#NAME]`): the
/// first mesh node (named `part`, or whose mesh is) whose weights an animation drives (the first
/// such animation), its triangle primitives
/// merged and placed as [`super::gltf_mesh::load_gltf_mesh`] places a mesh, sampled every 1/fps
/// seconds from the animation's first key to its last. `fps` is `--body-fps`, else the rate a
/// scenebake export records, else the spacing of the keys when it is uniform.
///
/// # Errors
/// [`Error::NoMorphAnimation`] for a file without such a mesh; [`Error::Value`] for a
/// cubic-spline weights track (the job names `--body`); [`Error::UnknownRate`] when no rate is
/// given and none can be found; [`Error::InvalidInput`] for targets without
/// positions or weights of the wrong length; the glTF reader's errors.
pub fn load_gltf_sequence(
    path: &Path,
    part: Option<&str>,
    fps: Option<f64>,
) -> Result<MeshSequence> {
    let (doc, buffers) = super::gltf_import::import_gltf(path)?;
    let buffer = |b: gltf::Buffer<'_>| buffers.get(b.index()).map(|d| &d[..]);
    let driven = doc.animations().find_map(|a| {
        a.channels().find_map(|c| {
            let node = c.target().node();
            let morphs = node
                .mesh()
                .is_some_and(|m| m.primitives().any(|p| p.morph_targets().next().is_some()));
            let named = part.is_none_or(|p| {
                node.name() == Some(p) || node.mesh().and_then(|m| m.name()) == Some(p)
            });
            (c.target().property() == gltf::animation::Property::MorphTargetWeights
                && morphs
                && named
                && node.skin().is_none())
            .then_some(c)
        })
    });
    let Some(channel) = driven else {
        return Err(Error::NoMorphAnimation {
            path: path.to_path_buf(),
            part: part.map(str::to_owned),
        });
    };
    let gmesh = channel.target().node().mesh().expect("checked above");
    let sampler = channel.sampler();
    if sampler.interpolation() == gltf::animation::Interpolation::CubicSpline {
        return Err(Error::value(format!(
            "`{}`: the weights track is a cubic spline; linear or step weights are read",
            path.display()
        )));
    }
    let reader = channel.reader(buffer);
    let times: Vec<f64> = reader
        .read_inputs()
        .map(|t| t.map(f64::from).collect())
        .unwrap_or_default();
    let weights: Vec<f64> = match reader.read_outputs() {
        Some(gltf::animation::util::ReadOutputs::MorphTargetWeights(w)) => {
            w.into_f32().map(f64::from).collect()
        }
        _ => Vec::new(),
    };
    let transform = super::gltf_mesh::world_transform_of_mesh(&doc, gmesh.index());
    let mesh = super::gltf_mesh::read_mesh(path, &buffers, gmesh.clone(), transform)?;
    // Per render vertex (the primitives' vertices in order), its position and each target's
    // position delta, in the mesh's own frame.
    let mut base: Vec<DVec3> = Vec::new();
    let mut deltas: Vec<Vec<[f32; 3]>> = Vec::new();
    let mut vertices = 0;
    for prim in gmesh.primitives() {
        let r = prim.reader(buffer);
        if prim.mode() != gltf::mesh::Mode::Triangles {
            continue;
        }
        let Some(positions) = r.read_positions() else {
            continue;
        };
        let before = base.len();
        base.extend(positions.map(|p| DVec3::from(p.map(f64::from))));
        let count = base.len() - before;
        for (t, (positions, _, _)) in r.read_morph_targets().enumerate() {
            if deltas.len() <= t {
                deltas.push(vec![[0.0; 3]; vertices]);
            }
            match positions {
                Some(p) => deltas[t].extend(p),
                None => deltas[t].extend(std::iter::repeat_n([0.0; 3], count)),
            }
        }
        vertices += count;
        for d in &mut deltas {
            d.resize(vertices, [0.0; 3]);
        }
    }
    let targets = deltas.len();
    if targets == 0 || weights.len() != times.len() * targets || times.len() < 2 {
        return Err(Error::invalid(
            path,
            format!(
                "mesh {}: {targets} morph targets, {} weights for {} keys: expected one weight \
                 per target and key, and at least two keys",
                gmesh.index(),
                weights.len(),
                times.len()
            ),
        ));
    }
    let (start, end) = (times[0], times[times.len() - 1]);
    let recorded = (|| {
        let root: serde_json::Value =
            serde_json::from_str(doc.as_json().asset.extras.as_ref()?.get()).ok()?;
        root.get("scenebake")?.get("fps")?.as_f64()
    })();
    let spacing = (end - start) / (times.len() - 1) as f64;
    let uniform = times
        .windows(2)
        .all(|w| ((w[1] - w[0]) - spacing).abs() <= 1e-4 * spacing);
    let fps = match fps.or(recorded) {
        Some(f) => f,
        None if uniform && spacing > 0.0 => 1.0 / spacing,
        None => {
            return Err(Error::UnknownRate {
                path: path.to_path_buf(),
            })
        }
    };
    let count = ((end - start) * fps + 1e-6).floor() as usize + 1;
    let step = sampler.interpolation() == gltf::animation::Interpolation::Step;
    let weights_at = |t: f64| -> Vec<f64> {
        let row = |k: usize| &weights[k * targets..(k + 1) * targets];
        let k = times.partition_point(|&x| x <= t).clamp(1, times.len() - 1) - 1;
        let s = ((t - times[k]) / (times[k + 1] - times[k])).clamp(0.0, 1.0);
        if step {
            return row(if s >= 1.0 { k + 1 } else { k }).to_vec();
        }
        row(k)
            .iter()
            .zip(row(k + 1))
            .map(|(a, b)| a + (b - a) * s)
            .collect()
    };
    let frames: Vec<Vec<DVec3>> = (0..count)
        .map(|k| {
            let w = weights_at(start + k as f64 / fps);
            let mut positions = mesh.positions.clone();
            for (v, rv) in mesh.render_vertices.iter().enumerate().take(vertices) {
                let mut p = base[v];
                for (d, wt) in deltas.iter().zip(&w) {
                    p += DVec3::from(d[v].map(f64::from)) * *wt;
                }
                positions[rv.particle as usize] = transform.transform_point3(p);
            }
            positions
        })
        .collect();
    Ok(MeshSequence {
        mesh,
        frames,
        fps,
        files: vec![path.to_path_buf()],
        first_number: 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns_name_their_frames() {
        let p = FramePattern::parse(Path::new("kick/shell%d.obj")).unwrap();
        assert_eq!(p.path(12), Path::new("kick/shell12.obj"));
        let p = FramePattern::parse(Path::new("a/f_%04d.obj")).unwrap();
        assert_eq!(p.path(7), Path::new("a/f_0007.obj"));
        let p = FramePattern::parse(Path::new("100%%_%3d.obj")).unwrap();
        assert_eq!(p.path(7), Path::new("100%_  7.obj"));
        for bad in ["shell.obj", "s%d_%d.obj", "s%s.obj", "k%d/s%d.obj"] {
            let e = FramePattern::parse(Path::new(bad)).unwrap_err();
            assert!(matches!(e, Error::Value { .. }), "{bad}: {e}");
        }
    }

    #[test]
    fn only_the_numbers_own_spelling_matches() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["s0.obj", "s1.obj", "s01.obj", "s2.objx", "t3.obj", "s4.obj"] {
            std::fs::write(dir.path().join(name), "").unwrap();
        }
        let p = FramePattern::parse(&dir.path().join("s%d.obj")).unwrap();
        assert_eq!(
            p.existing().unwrap().into_iter().collect::<Vec<_>>(),
            [0, 1, 4]
        );
        let p = FramePattern::parse(&dir.path().join("s%02d.obj")).unwrap();
        assert_eq!(p.existing().unwrap().into_iter().collect::<Vec<_>>(), [1]);
    }
}
