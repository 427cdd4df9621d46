//! Compact morph caches: a morph basis (`--basis K|auto`) and quantised attributes
//! (`--quantize`, KHR_mesh_quantization).
//!
//! **The basis.** One target per frame stores F deltas of V vertices. The motion of a cloth is
//! far more regular than that: the frame deltas `d_f = p_f - p_0` (stacked as the columns of a
//! 3V × (F-1) matrix D) are well approximated by a few directions. A thin SVD of D (faer) gives
//! orthonormal directions `u_1, u_2, ...` ordered by singular value; the first K span the best
//! rank-K subspace in the least-squares sense (Eckart–Young). Each frame is then
//! `p_f ≈ p_0 + Σ_k c_fk u_k`.
//!
//! **Weights in [0, 1].** glTF weights may be any float, but Blender clamps a shape key's value
//! to its slider range, and its importer widens that range only from the first key and the
//! default weight. So every coefficient range `[lo_k, hi_k]` (padded by 1 %) is mapped onto
//! [0, 1]: the written base is `b = p_0 + Σ lo_k u_k`, target k is `(hi_k - lo_k) u_k`, and the
//! weights `w_fk = (c_fk - lo_k) / (hi_k - lo_k)` lie in [0, 1]. The mesh's default weights are
//! frame 0's, so a player without animation shows frame 0.
//!
//! **Refit and measurement.** After the base and targets are rounded to what the file stores
//! (`f32`, or `int16` when quantised), each frame's weights are refitted by least squares against
//! the baked frame (a K × K normal system) and clamped to [0, 1]. The error is then *measured*:
//! every baked frame is played back as a player computes it (`f32`, base plus weighted targets,
//! then the node transform; dropped frames with their interpolated weights) and compared with
//! the bake; the largest vertex distance is reported. `auto` takes the smallest K whose measured
//! error is within the tolerance (the f64 projection error picks the first candidate; the
//! measurement decides).
//!
//! **Normals.** The base NORMAL `n_b` is the stored base shape's own smooth normal (corner-angle
//! weighted, as Blender computes it), with the vertices that would make a face import flat leaned
//! by [`super::shading::LEAN_DEGREES`]. Blender's importer keeps the base NORMAL as custom normals
//! relative to the imported base shape and carries that offset into every shape-key frame; the
//! base shape is far from any baked frame (it sits at the lowest coefficients), so any other base
//! NORMAL (such as the best fit to the baked normals) shades every frame off by its offset, and
//! normals equal to the face normals import flat. glTF morphs normals with the same weights as
//! positions. In the *shared* layout each target's NORMAL delta `m_k` is fitted by least
//! squares given the position weights: per vertex,
//! `min Σ_f |n_b + o + Σ_k w_fk m_k - n_f|²`, where `o` is the NORMAL of one more target,
//! `normal_offset` (zero POSITION: a sparse accessor listing one zero; weight 1 in every frame): the offset from the base shape's
//! normals to the best constant term, which Blender ignores (it drops NORMAL deltas) and engines
//! that morph normals add. That target is written when `--max-targets` leaves room for it,
//! unless the file with the deltas fitted to `n_b` alone (`o = 0`) is smaller and its measured
//! normal error is within 2° (largest) and 0.1° (mean) of the one with the offset.
//! A normal that never changes gets zero deltas (kept sparse). Players renormalise after
//! blending; the largest and mean angle between the played normal and the baked one are
//! reported.
//!
//! **Normal targets.** Shared weights have a cost: a quantised target is stored normalised
//! (its weights carry its amplitude), so small-amplitude targets have tiny weights (0.001 on
//! the lab grid) and their fitted NORMAL deltas run to ±100, far outside what a normalised
//! integer holds, so they stay f32 (about 40 % of the lab file). The alternative layout gives
//! the normals targets of their own: the position targets get zero NORMAL deltas (a one-entry
//! sparse accessor; three.js would use the base normals as the deltas of a target without
//! one), and J *normal targets* (zero POSITION; NORMAL the first J directions of a thin SVD of
//! the residual normals `n_f − n_b − o`, each scaled to a largest component of 1 and stored as
//! int8, or with the leading third int16, or int16, sparse where smaller; weights of their
//! own, refitted by least squares per frame, any sign: they move no position, so Blender's
//! slider range does not matter) carry them, after `normal_offset`. J is the smallest whose
//! measured normal error is within [`CLAMP_MAX_DEGREES`] / [`CLAMP_MEAN_DEGREES`] of the shared
//! f32 fit's (with the offset), at the coarsest of those precisions that meets it, and at most
//! K, within `--max-targets` (64 targets in all without it). Of the three layouts (shared
//! deltas without and with the
//! offset, normal targets), the file written is the smallest whose normal error is within
//! those margins of the shared layout with the offset (that one when none is), within
//! `--max-targets` (which counts every target). The report's `normal_targets` gives J.
//!
//! **Keyframes.** With `--keyframe-tolerance T`, the weight animation keeps only the frames
//! needed so that every dropped frame, played back with interpolated weights, is within
//! `max(T, M)` of the bake (M the basis tolerance): the same greedy forward scan as
//! [`super::compact`], measured against the baked frames.
//!
//! **Quantisation** (KHR_mesh_quantization). Positions are stored as normalised `int16` in a
//! local frame: `world = t + s · local`, with the uniform scale `s` and translation `t` on the
//! cloth's node (uniform, so normals need no correction), chosen so that the base and every
//! target fit in [-1, 1]. Each target is stored normalised to fill [-1, 1] (the refitted weights
//! then carry its amplitude, still within [0, 1]; the node transform scales targets with the
//! base), as `int16`, or as `int8` for the targets of smallest amplitude: their rounding bounds
//! (amplitude · s · √3 / 254 each) are added up to a budget, the tolerance left over by the
//! `int16` file, doubled while the measured error stays within the tolerance. The base normals
//! are `int16` (int8's step, about 0.45°, would round the lean away), shortened so that none is
//! longer than 1 (Blender tests the stored normal unnormalised), and so is the normal offset
//! when every component fits in [-1, 1]. In the shared layout each target's NORMAL deltas are
//! `int8` when every component fits in [-1, 1]; the others are `int8` clamped to [-1, 1] when that raises the measured normal error by at
//! most 2° (largest) and 0.1° (mean) over the unclamped file (always with `--quantize on`),
//! else `f32` (sparse where smaller). A target whose weights leave room gets a gain
//! g = max |normal delta| (weights × g ≤ 1, stored positions ÷ g) that brings its normal
//! deltas into `int8`; that encoding is measured too and written when within the tolerance and
//! smaller. Vertex attributes keep 4-byte aligned elements (stride 8
//! for `int16` VEC3, 4 for `int8` VEC3). `auto` quantises when the measured error stays within
//! the tolerance: it tries K from the fewest that fit up to half as many again and keeps the K
//! whose target positions and weight keys take the fewest bytes (more targets lower the
//! projection error and leave more of the tolerance to int8 rounding); `on` always quantises
//! with the K of the f32 file (the error is reported); `off` never. Texture coordinates within
//! [0, 1] are normalised u16 in a quantised file.
//!
//! Sparse targets: `f32` targets go through [`super::compact::delta_accessor`] (vertices whose
//! delta is zero in every frame, such as pins, are exactly zero in every basis vector);
//! quantised POSITION deltas are always dense, quantised NORMAL deltas sparse (no buffer view,
//! the non-zero elements packed) where that is smaller.

use std::path::Path;

use faer::Mat;
use glam::{DVec3, Vec3};
use gltf_json as json;
use json::validation::Checked::Valid;

use super::character::CharacterHost;
use super::compact::{delta_accessor, DeltaEncoding, SparseMode, SPARSE_JSON_OVERHEAD};
use super::frames::RenderFrames;
use super::gltf_doc::{primitive, GltfBuilder};
use super::morph::{
    cloth_material, flip_v, push_weights_animation, CacheStats, EncodedMorph, Interpolation,
    MorphOptions,
};
use super::statics::push_scene;
use crate::error::BasisProblem;
use crate::error::{Error, Result};
use crate::mesh::Mesh;

pub use crate::data::KHR_MESH_QUANTIZATION;

/// `--basis`: how many basis targets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BasisSize {
    /// Exactly this many targets (at most the number of baked frames after frame 0).
    Fixed(usize),
    /// The fewest targets that keep every baked frame within the tolerance (measured).
    Auto,
}

impl std::str::FromStr for BasisSize {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        if s.eq_ignore_ascii_case("auto") {
            return Ok(BasisSize::Auto);
        }
        match s.trim().parse::<usize>() {
            Ok(k) if k >= 1 => Ok(BasisSize::Fixed(k)),
            _ => Err(Error::value(format!(
                "`{s}`: expected a number of targets (1 or more) or `auto`"
            ))),
        }
    }
}

impl<'de> serde::Deserialize<'de> for BasisSize {
    /// A number of targets, or `"auto"`.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(serde::Deserialize)]
        #[serde(untagged)]
        enum Repr {
            Count(u64),
            Word(String),
        }
        let text = match Repr::deserialize(d)? {
            Repr::Count(n) => n.to_string(),
            Repr::Word(w) => w,
        };
        text.parse()
            .map_err(|e: Error| serde::de::Error::custom(e.detail()))
    }
}

/// `--quantize`: KHR_mesh_quantization for the basis cache.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum QuantizeMode {
    /// Quantise when the measured error stays within the tolerance and the file gets smaller.
    #[default]
    Auto,
    /// Always quantise.
    On,
    /// Never quantise.
    Off,
}

/// Options of the basis encoding.
#[derive(Debug, Clone, PartialEq)]
pub struct BasisOptions {
    /// `--basis`.
    pub size: BasisSize,
    /// `--basis-tolerance` M (scene units): the largest vertex distance allowed between a played
    /// frame and the bake (for `auto`, and for `--quantize auto`); finite and not negative (the
    /// job checks it).
    pub tolerance: f64,
    /// `--max-targets N`: most targets written (the job refuses 0).
    pub max_targets: Option<usize>,
    /// `--quantize`.
    pub quantize: QuantizeMode,
}

/// How the positions and normals are stored.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Quantization {
    /// Component type of the base POSITION: `float` or `int16` (normalised).
    pub positions: String,
    /// Targets whose POSITION deltas are normalised int16.
    pub int16_targets: usize,
    /// Targets whose POSITION deltas are normalised int8.
    pub int8_targets: usize,
    /// Component type of the base NORMAL: `float` or `int16` (normalised); `none` without normals.
    pub normals: String,
    /// Targets whose NORMAL deltas are normalised int8.
    pub int8_normal_targets: usize,
    /// Targets whose NORMAL deltas are normalised int16. Both counts include the normal targets;
    /// the other targets' NORMAL is float, or zero.
    pub int16_normal_targets: usize,
    /// The node's uniform scale s (world = t + s · stored), 1 unquantised.
    pub node_scale: f64,
    /// The node's translation t, m.
    pub node_translation: [f64; 3],
}

/// Bytes of each part of the file.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct PartBytes {
    /// Base POSITION, NORMAL and TEXCOORD_0.
    pub base: u64,
    /// Triangle indices.
    pub indices: u64,
    /// Target POSITION deltas.
    pub target_positions: u64,
    /// Target NORMAL deltas.
    pub target_normals: u64,
    /// Weight animation (key times and weights).
    pub animation: u64,
    /// Static meshes (colliders).
    pub statics: u64,
    /// The JSON (and GLB headers), i.e. everything else.
    pub json: u64,
}

/// What the basis encoding wrote and how close it is to the bake.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BasisStats {
    /// `--basis` as asked.
    pub requested: BasisSize,
    /// Basis targets written (K).
    pub targets: usize,
    /// `--basis-tolerance`, scene units.
    pub tolerance: f64,
    /// Largest vertex distance between a played frame and the bake, over every baked frame
    /// (measured in `f32` as a player computes it), scene units.
    pub max_error: f64,
    /// The frame where it occurs.
    pub worst_frame: usize,
    /// The same with the basis alone in `f64` (before rounding and keyframe reduction).
    pub projection_error: f64,
    /// Largest angle between a played normal and the baked one, degrees (0 without normals).
    pub max_normal_error_degrees: f64,
    /// Mean of that angle over every vertex and frame, degrees.
    pub mean_normal_error_degrees: f64,
    /// The first singular values of the frame deltas (up to K + 8), m.
    pub singular_values: Vec<f64>,
    /// Whether one more target, `normal_offset` (zero POSITION, weight 1 in every frame), carries
    /// the NORMAL offset from the base shape's own normals to the fitted ones (see
    /// [`super::basis`]); then `targets + 1 + normal_targets` targets are written.
    pub normal_offset_target: bool,
    /// Normal targets (zero POSITION, NORMAL of their own, own weights; counted in the file's
    /// targets, not in `targets`): 0 unless their file was smaller.
    pub normal_targets: usize,
    /// Storage of the attributes.
    pub quantization: Quantization,
    /// Bytes per part.
    pub bytes: PartBytes,
}

/// A basis cache encoded in memory.
#[derive(Debug, Clone)]
pub struct EncodedBasis {
    /// The files and the common cache figures (targets, kept frames, accessors).
    pub morph: EncodedMorph,
    /// Basis figures.
    pub basis: BasisStats,
}

/// Padding of each coefficient range before it is mapped onto [0, 1], so that refitted weights
/// rarely need clamping.
const RANGE_PAD: f64 = 0.01;
/// `--quantize auto` clamps normal deltas to int8 when the largest normal error grows by at
/// most this (degrees)...
const CLAMP_MAX_DEGREES: f64 = 2.0;
/// ...and the mean normal error by at most this (degrees).
const CLAMP_MEAN_DEGREES: f64 = 0.1;
/// Without `--max-targets`, normal targets are added only while the file keeps at most this
/// many targets in all: the count engines handle comfortably (three.js keeps one influence and
/// one morph-texture layer per target; the glTF cache of one target per frame that prompted the
/// basis had 240).
const NORMAL_TARGET_BUDGET: usize = 64;
/// Headroom of a normal gain, so that normal deltas refitted after the gain still fit.
const GAIN_MARGIN: f64 = 1.02;
/// Largest value of a normalised int16.
const I16: f64 = 32767.0;
/// Largest value of a normalised int8.
const I8: f64 = 127.0;

/// The SVD of the frame deltas: orthonormal directions (3V each) and singular values.
struct Svd {
    directions: Vec<Vec<f64>>,
    singular: Vec<f64>,
}

/// A candidate encoding: what the file stores, dequantised, and the weights of every frame.
#[derive(Debug, Clone)]
struct Candidate {
    k: usize,
    quantized: bool,
    scale: f64,
    translation: DVec3,
    /// Stored base positions (local units), as the player reads them.
    base: Vec<Vec3>,
    base_q: Vec<[i16; 3]>,
    /// Stored target deltas (local units).
    deltas: Vec<Vec<Vec3>>,
    /// Quantised target deltas, normalised to fill [-1, 1] (the weights carry the amplitude).
    deltas_q: Vec<StoredDelta>,
    /// Weights of every frame (F × K), in [0, 1].
    weights: Vec<Vec<f32>>,
}

/// A candidate with its weight keys, measured error and worst frame.
type Pick = (Candidate, Vec<usize>, f64, usize);

/// A quantised target's values.
#[derive(Debug, Clone)]
enum StoredDelta {
    I16(Vec<[i16; 3]>),
    I8(Vec<[i8; 3]>),
}

impl StoredDelta {
    /// The values a player reads (normalised to [-1, 1]).
    fn dequantized(&self) -> Vec<Vec3> {
        match self {
            StoredDelta::I16(q) => q.iter().map(|x| dequantize_i16(*x)).collect(),
            StoredDelta::I8(q) => q.iter().map(|x| dequantize_i8(*x)).collect(),
        }
    }
}

/// Encodes `frames` as a basis cache for `path` (see the module documentation).
///
/// # Errors
/// [`Error::Basis`] for more fixed targets than frames, a tolerance that cannot be met within
/// the targets allowed, or a basis that needs more targets than allowed; [`Error::Export`] for
/// too few frames or a bad static mesh; [`Error::Json`]. The tolerances and the target cap are
/// the caller's to check (finite, not negative; at least 1).
pub fn encode_basis_gltf(
    path: &Path,
    mesh: &Mesh,
    frames: &RenderFrames,
    options: &MorphOptions,
    basis: &BasisOptions,
) -> Result<EncodedBasis> {
    encode_basis_on(path, mesh, frames, options, basis, None)
}

/// As [`encode_basis_gltf`], the garment added to a character's document when `host` is given
/// (as [`super::character::encode_character_gltf`] adds a per-frame cache).
///
/// # Errors
/// As [`encode_basis_gltf`].
pub fn encode_basis_on(
    path: &Path,
    mesh: &Mesh,
    frames: &RenderFrames,
    options: &MorphOptions,
    basis: &BasisOptions,
    host: Option<&CharacterHost<'_>>,
) -> Result<EncodedBasis> {
    let f = frames.frame_count();
    if f < 2 || frames.vertex_count() != mesh.render_vertices.len() {
        return Err(Error::Export {
            path: path.into(),
            message: format!(
                "{f} frames of {} vertices: need at least 2 frames of the mesh's {} render vertices",
                frames.vertex_count(),
                mesh.render_vertices.len()
            ).into(),
        });
    }
    if let Some((name, problem)) = options
        .static_meshes
        .iter()
        .find_map(|s| s.problem().map(|p| (&s.name, p)))
    {
        return Err(Error::Export {
            path: path.into(),
            message: format!("static mesh `{name}` {problem}").into(),
        });
    }
    let keyframe_tolerance = options.keyframe_tolerance;
    let available = f - 1;
    let cap = basis.max_targets.unwrap_or(usize::MAX).min(available);
    let refuse = |problem: BasisProblem| Error::Basis {
        path: path.into(),
        problem,
    };
    if let BasisSize::Fixed(k) = basis.size {
        if k > available {
            return Err(refuse(BasisProblem::TooFewFrames {
                targets: k,
                available,
            }));
        }
        // More than `max_targets` allowed is refused below (`TooManyTargets`).
    }

    let svd = frame_svd(frames).ok_or_else(|| Error::Export {
        path: path.into(),
        message: "the SVD of the frame deltas did not converge (non-finite positions?)".into(),
    })?;
    let projection = match basis.size {
        BasisSize::Fixed(k) => projection_errors(frames, &svd, k, f64::NEG_INFINITY),
        BasisSize::Auto => projection_errors(frames, &svd, cap, basis.tolerance),
    };
    let m = basis.tolerance;
    // The bound every played frame must meet: M at keyed frames, max(T, M) at dropped ones.
    let bound = keyframe_tolerance.map_or(m, |t| t.max(m));
    let ks: Vec<usize> = match basis.size {
        BasisSize::Fixed(k) => vec![k],
        BasisSize::Auto => {
            let first = projection
                .iter()
                .position(|&e| e <= m)
                .map_or(cap, |i| i + 1);
            (first.max(1)..=cap).collect()
        }
    };
    let try_quantized = basis.quantize != QuantizeMode::Off;
    let mut best: Option<Pick> = None;
    let mut float_pick: Option<Pick> = None;
    for &k in &ks {
        let float = build(frames, &svd, k, false, &[], &[]);
        let keys = select_keys(frames, &float, keyframe_tolerance.map(|_| bound), options);
        let (err, worst) = measure(frames, &float, &keys, options.interpolation);
        let fits = err <= bound || basis.size != BasisSize::Auto;
        if fits {
            float_pick = Some((float, keys, err, worst));
            break;
        }
        if best.as_ref().is_none_or(|b| err < b.2) {
            best = Some((float, keys, err, worst));
        }
    }
    let Some(float_pick) = float_pick else {
        let (k, err) = best.map_or((cap, f64::INFINITY), |b| (b.0.k, b.2));
        return Err(refuse(BasisProblem::ToleranceUnmet {
            tolerance: m,
            cap,
            best: k,
            best_error: err,
            max_targets: basis.max_targets.filter(|&n| n < available),
        }));
    };
    let mut pick = float_pick;
    if try_quantized {
        // Quantised targets are two thirds of the size of f32 ones: try as many extra targets as
        // still make the file smaller.
        let k0 = pick.0.k;
        // With normals, leave `--max-targets` room for the offset target when K0 did.
        let room = if options.normals && k0 < cap {
            cap - 1
        } else {
            cap
        };
        let limit = if basis.quantize == QuantizeMode::On || basis.size != BasisSize::Auto {
            k0
        } else {
            (k0 * 3 / 2).min(room)
        };
        // Each K from the fewest that fits: the targets of small amplitude as int8 (see
        // `with_int8_targets`); the K whose targets take the fewest bytes, stopping after two
        // K in a row that do not improve on it.
        let mut best: Option<(Pick, usize)> = None;
        let mut worse = 0;
        for k in k0..=limit {
            let q = build(frames, &svd, k, true, &[], &[]);
            let keys = select_keys(frames, &q, keyframe_tolerance.map(|_| bound), options);
            let (err, worst) = measure(frames, &q, &keys, options.interpolation);
            if err > bound && basis.quantize != QuantizeMode::On {
                continue;
            }
            let mut p = (q, keys, err, worst);
            if p.2 < bound {
                p = with_int8_targets(frames, &svd, p, bound, keyframe_tolerance, options);
            }
            let bytes = target_bytes(&p);
            if best.as_ref().is_none_or(|b| bytes < b.1) {
                best = Some((p, bytes));
                worse = 0;
            } else {
                worse += 1;
                if worse == 2 {
                    break;
                }
            }
        }
        if let Some((p, _)) = best {
            pick = p;
        }
    }
    let mut gained: Option<Pick> = None;
    if pick.0.quantized && options.normals {
        // Targets whose fitted normal deltas exceed [-1, 1] but whose weights leave room: a
        // gain g = max |normal delta| (weights × g stay ≤ 1) brings the normals into int8 at
        // the cost of g× coarser positions; an alternative when the measured error stays within
        // the tolerance (first with the int8 targets as chosen, then with the gained ones
        // int16), written instead when its file is smaller.
        let c = &pick.0;
        let nb = stored_base_normals(&base_shape_normals(mesh, frames, c), true).0;
        let nd = fit_normals(frames, c, &nb, c.k);
        let gains: Vec<f64> = (0..c.k)
            .map(|t| {
                let m = nd[t]
                    .iter()
                    .map(|x| x.abs().max_element())
                    .fold(0.0f32, f32::max) as f64
                    * GAIN_MARGIN;
                let a = c.weights.iter().map(|w| w[t] as f64).fold(0.0, f64::max);
                if m > 1.0 && a * m <= 1.0 {
                    m
                } else {
                    1.0
                }
            })
            .collect();
        if gains.iter().any(|g| *g > 1.0) {
            let int8: Vec<bool> = c
                .deltas_q
                .iter()
                .map(|d| matches!(d, StoredDelta::I8(_)))
                .collect();
            let int16_gained: Vec<bool> = int8
                .iter()
                .zip(&gains)
                .map(|(i, g)| *i && *g == 1.0)
                .collect();
            let k = c.k;
            for flags in [int8, int16_gained] {
                let q = build(frames, &svd, k, true, &flags, &gains);
                let keys = select_keys(frames, &q, keyframe_tolerance.map(|_| bound), options);
                let (err, worst) = measure(frames, &q, &keys, options.interpolation);
                if err <= bound {
                    gained = Some((q, keys, err, worst));
                    break;
                }
            }
        }
    }
    let k = pick.0.k;
    let projection_error = match projection.get(k - 1) {
        Some(e) => *e,
        None => projection_errors(frames, &svd, k, f64::NEG_INFINITY)[k - 1],
    };
    let size = |e: &EncodedBasis| e.morph.files.iter().map(|(_, b)| b.len()).sum::<usize>();
    let targets_allowed = |n: usize| basis.max_targets.is_none_or(|m| n <= m);
    // Writes `pick` with `normals`; `None` when that needs more targets than allowed.
    let encode = |pick: &Pick, normals: Option<WrittenNormals>| -> Result<Option<EncodedBasis>> {
        let (c, keys, max_error, worst_frame) = pick;
        let extra = normals.as_ref().map_or(0, |n| {
            usize::from(n.offset.is_some()) + n.basis.as_ref().map_or(0, |b| b.stored.len())
        });
        if !targets_allowed(c.k + extra) {
            return Ok(None);
        }
        write(
            path,
            mesh,
            frames,
            options,
            basis,
            c.clone(),
            keys.clone(),
            (*max_error, *worst_frame),
            projection_error,
            svd.singular.iter().take(k + 8).copied().collect(),
            normals,
            host,
        )
        .map(Some)
    };
    // The normal layouts (module documentation): shared deltas without and with the offset
    // target, and normal targets of their own, the last two from one fit. The smallest file
    // whose played normals (what engines show) are about as close to the bake as the shared
    // deltas with the offset (within the margins used for clamping normal deltas); that one when
    // no other is.
    let encode = |pick: Pick| -> Result<EncodedBasis> {
        let (c, keys) = (&pick.0, &pick.1);
        // The shared layout applies whenever K is within `--max-targets`, as every pick's is.
        let too_many = || refuse(BasisProblem::TooManyTargets { needed: c.k });
        if !options.normals {
            return encode(&pick, None)?.ok_or_else(too_many);
        }
        let base = stored_base_normals(&base_shape_normals(mesh, frames, c), c.quantized);
        let shared = |fit: &WrittenNormals| shared_normals(fit, frames, c, keys, options, basis);
        let plain = encode(
            &pick,
            Some(shared(&fitted_normals(frames, c, &base, false))),
        )?
        .ok_or_else(too_many)?;
        let fit = fitted_normals(frames, c, &base, true);
        let Some(with) = encode(&pick, Some(shared(&fit)))? else {
            return Ok(plain);
        };
        let reference = (
            with.basis.max_normal_error_degrees,
            with.basis.mean_normal_error_degrees,
        );
        let close = |e: &EncodedBasis| {
            e.basis.max_normal_error_degrees <= reference.0 + CLAMP_MAX_DEGREES
                && e.basis.mean_normal_error_degrees <= reference.1 + CLAMP_MEAN_DEGREES
        };
        let own = match with_normal_targets(fit, frames, c, keys, options, basis) {
            Some(n) => encode(&pick, Some(n))?,
            None => None,
        };
        Ok([Some(plain), own]
            .into_iter()
            .flatten()
            .filter(|e| close(e))
            .fold(
                with,
                |best, e| if size(&e) < size(&best) { e } else { best },
            ))
    };
    let first = encode(pick)?;
    // Keep the normal-gained encoding only when its file is smaller. Gains serve normal deltas
    // shared with the position targets: not tried when the normals went to normal targets
    // (whose file beat the shared layouts of the same pick; the gained pick's int16 positions
    // only add bytes).
    match gained.filter(|_| first.basis.normal_targets == 0) {
        Some(alt) => {
            let second = encode(alt)?;
            Ok(if size(&second) < size(&first) {
                second
            } else {
                first
            })
        }
        None => Ok(first),
    }
}

/// Binary bytes of a quantised pick's target positions and weight keys.
fn target_bytes((c, keys, _, _): &Pick) -> usize {
    let v = c.base.len();
    let positions: usize = c
        .deltas_q
        .iter()
        .map(|d| match d {
            StoredDelta::I16(_) => 8 * v,
            StoredDelta::I8(_) => 4 * v,
        })
        .sum();
    positions + 4 * keys.len() * c.k
}

/// `pick` (quantised, its measured error below `bound`) with its targets of small amplitude as
/// int8 (half the bytes of int16): the rounding bound of each is amplitude · s · √3 / 254; the
/// smallest ones are taken while their bounds add up to a budget (the tolerance the int16 file
/// leaves), doubled while the measured error stays within `bound`.
fn with_int8_targets(
    frames: &RenderFrames,
    svd: &Svd,
    mut pick: Pick,
    bound: f64,
    keyframe_tolerance: Option<f64>,
    options: &MorphOptions,
) -> Pick {
    let (c, k) = (&pick.0, pick.0.k);
    let step: Vec<f64> = (0..c.k)
        .map(|t| {
            let amplitude = c.weights.iter().map(|w| w[t] as f64).fold(0.0, f64::max);
            amplitude * c.scale * 3f64.sqrt() / 254.0
        })
        .collect();
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|a, b| step[*a].total_cmp(&step[*b]));
    let mut budget = bound - pick.2;
    let mut chosen = 0;
    for _ in 0..6 {
        let mut int8 = vec![false; k];
        let mut sum = 0.0;
        let mut n = 0;
        for &t in &order {
            if sum + step[t] > budget {
                break;
            }
            sum += step[t];
            int8[t] = true;
            n += 1;
        }
        if n > chosen {
            let q = build(frames, svd, k, true, &int8, &[]);
            let keys = select_keys(frames, &q, keyframe_tolerance.map(|_| bound), options);
            let (err, worst) = measure(frames, &q, &keys, options.interpolation);
            if err > bound {
                break;
            }
            chosen = n;
            pick = (q, keys, err, worst);
        }
        budget *= 2.0;
    }
    pick
}

/// The thin SVD of the frame deltas from frame 0 (rows: vertex coordinates; columns: frames
/// 1..F). Rows that are zero in every frame (vertices that never move) are exactly zero in every
/// direction. A cache that never moves gets one zero direction (one target of zeros). `None`
/// when the SVD does not converge.
fn frame_svd(frames: &RenderFrames) -> Option<Svd> {
    let (f, v) = (frames.frame_count(), frames.vertex_count());
    let p0 = frames.positions(0);
    let d = Mat::<f64>::from_fn(3 * v, f - 1, |i, j| {
        (frames.positions(j + 1)[i / 3][i % 3] - p0[i / 3][i % 3]) as f64
    });
    let still: Vec<bool> = (0..3 * v)
        .map(|i| (0..f - 1).all(|j| d[(i, j)] == 0.0))
        .collect();
    let svd = d.thin_svd().ok()?;
    let (u, s) = (svd.U(), svd.S().column_vector());
    let r = s.nrows();
    let scale = s[0].max(f64::MIN_POSITIVE);
    let mut directions = Vec::new();
    let mut singular = Vec::new();
    for k in 0..r {
        // Directions of a (numerically) zero singular value carry no motion.
        if s[k] <= scale * 1e-12 {
            break;
        }
        directions.push(
            (0..3 * v)
                .map(|i| if still[i] { 0.0 } else { u[(i, k)] })
                .collect(),
        );
        singular.push(s[k]);
    }
    if directions.is_empty() {
        directions.push(vec![0.0; 3 * v]);
        singular.push(0.0);
    }
    Some(Svd {
        directions,
        singular,
    })
}

/// For K = 1..=cap, the largest vertex distance between each frame and its orthogonal
/// projection onto the first K directions (f64), m; stops after the first K whose error is at
/// most `stop` (so the last entry is the first K within `stop`, when there is one).
fn projection_errors(frames: &RenderFrames, svd: &Svd, cap: usize, stop: f64) -> Vec<f64> {
    let (f, v) = (frames.frame_count(), frames.vertex_count());
    let p0 = frames.positions(0);
    let mut residual: Vec<Vec<f64>> = (1..f)
        .map(|j| {
            (0..3 * v)
                .map(|i| (frames.positions(j)[i / 3][i % 3] - p0[i / 3][i % 3]) as f64)
                .collect()
        })
        .collect();
    let mut errors = Vec::new();
    for u in svd.directions.iter().take(cap) {
        let mut worst = 0.0f64;
        for r in residual.iter_mut() {
            let c: f64 = r.iter().zip(u).map(|(a, b)| a * b).sum();
            for (a, b) in r.iter_mut().zip(u) {
                *a -= c * b;
            }
            for x in r.chunks_exact(3) {
                worst = worst.max((x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt());
            }
        }
        errors.push(worst);
        if worst <= stop {
            return errors;
        }
    }
    // With fewer directions than the cap, the remaining K reproduce the motion exactly.
    while errors.len() < cap {
        errors.push(0.0);
    }
    errors
}

/// Builds the K-target candidate: base and targets from the first K directions mapped so that
/// weights lie in [0, 1], rounded to what the file stores (quantised or not), weights refitted.
/// `int8[t]` stores target t as int8 (quantised candidates only).
/// `gain[t]` (default 1) shrinks target t's stored values below [-1, 1] (its weights grow by
/// as much), so that its normal deltas fit in int8 too.
fn build(
    frames: &RenderFrames,
    svd: &Svd,
    k: usize,
    quantized: bool,
    int8: &[bool],
    gain: &[f64],
) -> Candidate {
    let (f, v) = (frames.frame_count(), frames.vertex_count());
    let k = k.min(svd.directions.len());
    let p0 = frames.positions(0);
    let dirs = &svd.directions[..k];
    // Coefficient ranges over every frame (frame 0 has coefficients 0).
    let mut lo = vec![0.0f64; k];
    let mut hi = vec![0.0f64; k];
    for j in 1..f {
        let p = frames.positions(j);
        for (kk, u) in dirs.iter().enumerate() {
            let c: f64 = (0..v)
                .map(|i| {
                    let d = (p[i] - p0[i]).as_dvec3();
                    d.x * u[3 * i] + d.y * u[3 * i + 1] + d.z * u[3 * i + 2]
                })
                .sum();
            lo[kk] = lo[kk].min(c);
            hi[kk] = hi[kk].max(c);
        }
    }
    for kk in 0..k {
        let pad = RANGE_PAD * (hi[kk] - lo[kk]).max(f64::MIN_POSITIVE);
        lo[kk] -= pad;
        hi[kk] += pad;
    }
    let base: Vec<DVec3> = (0..v)
        .map(|i| {
            let mut b = p0[i].as_dvec3();
            for (kk, u) in dirs.iter().enumerate() {
                b += lo[kk] * DVec3::new(u[3 * i], u[3 * i + 1], u[3 * i + 2]);
            }
            b
        })
        .collect();
    let deltas: Vec<Vec<DVec3>> = dirs
        .iter()
        .enumerate()
        .map(|(kk, u)| {
            let r = hi[kk] - lo[kk];
            (0..v)
                .map(|i| r * DVec3::new(u[3 * i], u[3 * i + 1], u[3 * i + 2]))
                .collect()
        })
        .collect();
    let (scale, translation) = if quantized {
        local_frame(&base, &deltas)
    } else {
        (1.0, DVec3::ZERO)
    };
    let to_local = |p: DVec3| (p - translation) / scale;
    let (base_s, base_q): (Vec<Vec3>, Vec<[i16; 3]>) = if quantized {
        let q: Vec<[i16; 3]> = base.iter().map(|p| quantize_i16(to_local(*p))).collect();
        (q.iter().map(|x| dequantize_i16(*x)).collect(), q)
    } else {
        (base.iter().map(|p| p.as_vec3()).collect(), Vec::new())
    };
    let mut deltas_s = Vec::with_capacity(k);
    let mut deltas_q = Vec::new();
    for (t, d) in deltas.iter().enumerate() {
        if quantized {
            // Fill [-1, 1]: the refitted weights then carry the amplitude (and stay in [0, 1]).
            let amplitude = d
                .iter()
                .map(|x| x.abs().max_element())
                .fold(0.0f64, f64::max)
                / scale;
            let unit =
                scale * amplitude.max(f64::MIN_POSITIVE) * gain.get(t).copied().unwrap_or(1.0);
            if int8.get(t).copied().unwrap_or(false) {
                let q: Vec<[i8; 3]> = d
                    .iter()
                    .map(|x| quantize_i8((*x / unit).as_vec3()))
                    .collect();
                deltas_s.push(q.iter().map(|x| dequantize_i8(*x)).collect());
                deltas_q.push(StoredDelta::I8(q));
            } else {
                let q: Vec<[i16; 3]> = d.iter().map(|x| quantize_i16(*x / unit)).collect();
                deltas_s.push(q.iter().map(|x| dequantize_i16(*x)).collect());
                deltas_q.push(StoredDelta::I16(q));
            }
        } else {
            deltas_s.push(d.iter().map(|x| x.as_vec3()).collect());
        }
    }
    let mut c = Candidate {
        k,
        quantized,
        scale,
        translation,
        base: base_s,
        base_q,
        deltas: deltas_s,
        deltas_q,
        weights: Vec::new(),
    };
    c.weights = refit_weights(frames, &c);
    c
}

/// The uniform scale and translation that put the base and every target in [-1, 1].
fn local_frame(base: &[DVec3], deltas: &[Vec<DVec3>]) -> (f64, DVec3) {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in base {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let centre = (lo + hi) * 0.5;
    let mut s = ((hi - lo) * 0.5).max_element();
    for d in deltas.iter().flatten() {
        s = s.max(d.abs().max_element());
    }
    (if s > 0.0 { s } else { 1.0 }, centre)
}

fn quantize_i16(x: DVec3) -> [i16; 3] {
    x.to_array()
        .map(|c| (c.clamp(-1.0, 1.0) * I16).round() as i16)
}

/// What a player reads from a normalised int16 (max(c / 32767, -1)), as f32.
fn dequantize_i16(q: [i16; 3]) -> Vec3 {
    Vec3::from_array(q.map(|c| (c as f32 / I16 as f32).max(-1.0)))
}

/// Least-squares weights of every frame for the stored base and targets, clamped to [0, 1].
fn refit_weights(frames: &RenderFrames, c: &Candidate) -> Vec<Vec<f32>> {
    let (f, v, k) = (frames.frame_count(), frames.vertex_count(), c.k);
    let d: Vec<Vec<DVec3>> = c
        .deltas
        .iter()
        .map(|t| t.iter().map(|x| x.as_dvec3()).collect())
        .collect();
    let mut gram = vec![0.0f64; k * k];
    for a in 0..k {
        for b in 0..=a {
            let g: f64 = (0..v).map(|i| d[a][i].dot(d[b][i])).sum();
            gram[a * k + b] = g;
            gram[b * k + a] = g;
        }
    }
    let chol = cholesky(&gram, k);
    (0..f)
        .map(|j| {
            let p = frames.positions(j);
            let target: Vec<DVec3> = (0..v)
                .map(|i| (p[i].as_dvec3() - c.translation) / c.scale - c.base[i].as_dvec3())
                .collect();
            let rhs: Vec<f64> = (0..k)
                .map(|a| (0..v).map(|i| d[a][i].dot(target[i])).sum())
                .collect();
            cholesky_solve(&chol, k, rhs)
                .into_iter()
                .map(|w| (w.clamp(0.0, 1.0)) as f32)
                .collect()
        })
        .collect()
}

/// Lower Cholesky factor of the symmetric positive semi-definite n × n matrix `a` (row-major),
/// with a tiny ridge so that a rank-deficient system still solves.
fn cholesky(a: &[f64], n: usize) -> Vec<f64> {
    let trace: f64 = (0..n).map(|i| a[i * n + i]).sum();
    let ridge = 1e-14 * trace.max(f64::MIN_POSITIVE);
    let mut l = vec![0.0f64; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[i * n + j] - (0..j).map(|m| l[i * n + m] * l[j * n + m]).sum::<f64>();
            if i == j {
                s += ridge;
                l[i * n + i] = s.max(ridge).sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    l
}

/// Solves L Lᵀ x = b.
fn cholesky_solve(l: &[f64], n: usize, mut b: Vec<f64>) -> Vec<f64> {
    for i in 0..n {
        let s: f64 = (0..i).map(|m| l[i * n + m] * b[m]).sum();
        b[i] = (b[i] - s) / l[i * n + i];
    }
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|m| l[m * n + i] * b[m]).sum();
        b[i] = (b[i] - s) / l[i * n + i];
    }
    b
}

/// The weights a player evaluates at frame `j` from the keys `keys` (sorted, first 0, last F-1).
fn played_weights(
    c: &Candidate,
    keys: &[usize],
    j: usize,
    interpolation: Interpolation,
) -> Vec<f32> {
    interpolated_weights(&c.weights, keys, j, interpolation)
}

/// Row `j` of `weights` (one row per frame) as a player evaluates it from the keys `keys`.
fn interpolated_weights(
    weights: &[Vec<f32>],
    keys: &[usize],
    j: usize,
    interpolation: Interpolation,
) -> Vec<f32> {
    let at = keys.partition_point(|&key| key <= j) - 1;
    let a = keys[at];
    if a == j || at + 1 == keys.len() {
        return weights[a].clone();
    }
    match interpolation {
        Interpolation::Step => weights[a].clone(),
        Interpolation::Linear => {
            let b = keys[at + 1];
            let t = (j - a) as f32 / (b - a) as f32;
            weights[a]
                .iter()
                .zip(&weights[b])
                .map(|(x, y)| x + t * (y - x))
                .collect()
        }
    }
}

/// Vertex `i` as a player computes it with weights `w`: base plus weighted targets in f32, then
/// the node transform.
fn played_position(c: &Candidate, w: &[f32], i: usize) -> Vec3 {
    let mut p = c.base[i];
    for (d, wk) in c.deltas.iter().zip(w) {
        p += *wk * d[i];
    }
    p * c.scale as f32 + c.translation.as_vec3()
}

/// Largest distance between a played frame and the bake over every frame, and its frame.
fn measure(
    frames: &RenderFrames,
    c: &Candidate,
    keys: &[usize],
    interpolation: Interpolation,
) -> (f64, usize) {
    let mut worst = (0.0f64, 0usize);
    for j in 0..frames.frame_count() {
        let w = played_weights(c, keys, j, interpolation);
        let e = frame_error(frames, c, &w, j, f64::INFINITY).unwrap_or(f64::INFINITY);
        if e > worst.0 {
            worst = (e, j);
        }
    }
    worst
}

/// The largest vertex distance of frame `j` played with weights `w`, or `None` past `limit`.
fn frame_error(
    frames: &RenderFrames,
    c: &Candidate,
    w: &[f32],
    j: usize,
    limit: f64,
) -> Option<f64> {
    let mut worst = 0.0f64;
    for (i, want) in frames.positions(j).iter().enumerate() {
        let e = played_position(c, w, i)
            .as_dvec3()
            .distance(want.as_dvec3());
        if e > limit {
            return None;
        }
        worst = worst.max(e);
    }
    Some(worst)
}

/// The frames that get a weight key: all of them, or with a bound, the greedy forward scan that
/// drops a frame when its played-back positions stay within the bound of the bake.
fn select_keys(
    frames: &RenderFrames,
    c: &Candidate,
    bound: Option<f64>,
    options: &MorphOptions,
) -> Vec<usize> {
    let last = frames.frame_count() - 1;
    let Some(bound) = bound else {
        return (0..=last).collect();
    };
    let mut kept = vec![0];
    let mut a = 0;
    while a < last {
        let mut b = a + 1;
        'extend: for candidate in a + 2..=last {
            let keys = [a, candidate];
            for j in a + 1..candidate {
                let w = played_weights(c, &keys, j, options.interpolation);
                if frame_error(frames, c, &w, j, bound).is_none() {
                    break 'extend;
                }
            }
            b = candidate;
        }
        kept.push(b);
        a = b;
    }
    kept
}

/// The base NORMAL: the stored base shape's own smooth normals, as Blender computes them
/// (corner-angle weighted, from the positions a player reads), with the vertices that would make
/// their faces import flat leaned by [`super::shading::LEAN_DEGREES`] towards where the baked
/// normal turns. Unit vectors.
///
/// Blender's importer keeps the base NORMAL as custom split normals, stored relative to the
/// imported (base) shape's own normals, and shades every shape-key frame with that offset carried
/// along; a base NORMAL equal to the base shape's normals leaves no offset, so Blender shades each
/// frame with the normals of the shape it plays (as the full cache, whose base is frame 0, does).
fn base_shape_normals(mesh: &Mesh, frames: &RenderFrames, c: &Candidate) -> Vec<Vec3> {
    let positions: Vec<DVec3> = c.base.iter().map(|p| p.as_dvec3()).collect();
    let mut normals = Vec::new();
    super::shading::angle_weighted_normals(&positions, &mesh.render_triangles, &mut normals);
    let normals: Vec<Vec3> = normals.iter().map(|n| n.as_vec3()).collect();
    let mut turns = vec![DVec3::ZERO; frames.vertex_count()];
    for j in 0..frames.frame_count() {
        for (t, n) in turns.iter_mut().zip(frames.normals(j)) {
            *t += n.as_dvec3();
        }
    }
    super::shading::lean_flat_normals(
        &mesh.render_triangles,
        &c.base,
        &normals,
        &turns,
        frames.frame_count(),
    )
}

/// Per-target normal deltas fitted by least squares to the baked normals given the weights and
/// the fixed `base` normals (as stored). Only the first `j` targets get normal deltas; the
/// others' are zero.
fn fit_normals(frames: &RenderFrames, c: &Candidate, base: &[Vec3], j: usize) -> Vec<Vec<Vec3>> {
    fit_normal_deltas(frames, c, base, j, false).1
}

/// The least squares of [`fit_normals`] (regressors: the first `j` weights) and, with
/// `intercept`, with one more unknown per vertex: a constant offset added to `base` (the NORMAL
/// of a target whose weight is 1 in every frame; regressors [1, weights]: the offsets come
/// first; a normal that never changes then gets its offset alone and exactly zero deltas, so
/// they stay sparse). The normal matrix is shared by every vertex. Returns the offsets (zero
/// without `intercept`) and the deltas.
fn fit_normal_deltas(
    frames: &RenderFrames,
    c: &Candidate,
    base: &[Vec3],
    j: usize,
    intercept: bool,
) -> (Vec<Vec3>, Vec<Vec<Vec3>>) {
    let (v, k) = (frames.vertex_count(), j.min(c.k));
    let w: Vec<Vec<f64>> = c
        .weights
        .iter()
        .map(|r| r[..k].iter().map(|x| *x as f64).collect())
        .collect();
    let first = usize::from(intercept);
    let n1 = k + first;
    let row = |j: usize, a: usize| if a < first { 1.0 } else { w[j][a - first] };
    let mut xtx = vec![0.0f64; n1 * n1];
    for j in 0..w.len() {
        for a in 0..n1 {
            for b in 0..n1 {
                xtx[a * n1 + b] += row(j, a) * row(j, b);
            }
        }
    }
    let chol = cholesky(&xtx, n1);
    let mut offsets = vec![Vec3::ZERO; v];
    let mut deltas = vec![vec![Vec3::ZERO; v]; c.k];
    for i in 0..v {
        let nb = base[i].as_dvec3();
        let n0 = frames.normals(0)[i];
        if intercept && (1..w.len()).all(|j| frames.normals(j)[i] == n0) {
            offsets[i] = (n0.as_dvec3() - nb).as_vec3();
            continue;
        }
        let mut rhs = vec![DVec3::ZERO; n1];
        for j in 0..w.len() {
            let r = frames.normals(j)[i].as_dvec3() - nb;
            for (a, x) in rhs.iter_mut().enumerate() {
                *x += row(j, a) * r;
            }
        }
        for axis in 0..3 {
            let m = cholesky_solve(&chol, n1, rhs.iter().map(|r| r[axis]).collect());
            for (a, x) in m.into_iter().enumerate() {
                if a < first {
                    offsets[i][axis] = x as f32;
                } else {
                    deltas[a - first][i][axis] = x as f32;
                }
            }
        }
    }
    (offsets, deltas)
}

/// The base normals as stored: normalised int16 when `quantized` (fine enough to keep the lean
/// of [`super::shading::LEAN_DEGREES`]; int8's step, about 0.45°, is not), with what a player
/// reads back; else f32.
fn stored_base_normals(normals: &[Vec3], quantized: bool) -> (Vec<Vec3>, Option<Vec<[i16; 3]>>) {
    if !quantized {
        return (normals.to_vec(), None);
    }
    // Shortened by more than the rounding can lengthen them (√3 · 0.5 / 32767), so a stored
    // normal is never longer than 1: Blender's importer tests the stored (unnormalised) normal's
    // dot product with the face normal, and a lean's dominant component rounded up to exactly 1
    // would read as flat.
    let shorten = 1.0 - 1.0 / I16;
    let q: Vec<[i16; 3]> = normals
        .iter()
        .map(|n| quantize_i16(n.as_dvec3() * shorten))
        .collect();
    (q.iter().map(|x| dequantize_i16(*x)).collect(), Some(q))
}

fn quantize_i8(x: Vec3) -> [i8; 3] {
    x.to_array()
        .map(|c| (c.clamp(-1.0, 1.0) * I8 as f32).round() as i8)
}

fn dequantize_i8(q: [i8; 3]) -> Vec3 {
    Vec3::from_array(q.map(|c| (c as f32 / I8 as f32).max(-1.0)))
}

/// Targets' NORMAL deltas and their weights (one row per frame).
type NormalLayer<'a> = (&'a [Vec<Vec3>], &'a [Vec<f32>]);

/// The `normal_offset` target's NORMAL as read, and its int16 values when quantised.
type StoredOffset = (Vec<Vec3>, Option<Vec<[i16; 3]>>);

/// Largest and mean angle (degrees) between the played normals and the baked ones: `base`
/// plus every layer's deltas times its weights (F × targets, interpolated at dropped frames
/// as a player does), renormalised.
fn normal_errors(
    frames: &RenderFrames,
    keys: &[usize],
    interpolation: Interpolation,
    base: &[Vec3],
    layers: &[NormalLayer<'_>],
) -> (f64, f64) {
    let (mut worst, mut sum, mut n) = (0.0f64, 0.0f64, 0usize);
    for j in 0..frames.frame_count() {
        let w: Vec<Vec<f32>> = layers
            .iter()
            .map(|(_, weights)| interpolated_weights(weights, keys, j, interpolation))
            .collect();
        for (i, want) in frames.normals(j).iter().enumerate() {
            let mut m = base[i];
            for ((deltas, _), w) in layers.iter().zip(&w) {
                for (d, wk) in deltas.iter().zip(w) {
                    m += *wk * d[i];
                }
            }
            let cos = m.normalize_or_zero().as_dvec3().dot(want.as_dvec3());
            let angle = cos.clamp(-1.0, 1.0).acos().to_degrees();
            worst = worst.max(angle);
            sum += angle;
            n += 1;
        }
    }
    (worst, sum / n.max(1) as f64)
}

/// The normals as written: the base NORMAL, each target's NORMAL deltas, the `normal_offset`
/// target's NORMAL and the normal targets, each as a player reads it, with the stored integers
/// when quantised.
struct WrittenNormals {
    base: Vec<Vec3>,
    base_q: Option<Vec<[i16; 3]>>,
    deltas: Vec<Vec<Vec3>>,
    /// Per target: its normalised integers, or `None` for f32.
    deltas_q: Vec<Option<StoredDelta>>,
    /// The offset target's NORMAL as read, and its int16 values when quantised.
    offset: Option<StoredOffset>,
    /// What a player adds up before the deltas: the base, plus the offset at weight 1.
    played_base: Vec<Vec3>,
    /// The normal targets (see [`with_normal_targets`]).
    basis: Option<NormalBasis>,
}

impl WrittenNormals {
    /// Largest and mean angle (degrees) between the played normals and the baked ones.
    fn errors(
        &self,
        frames: &RenderFrames,
        c: &Candidate,
        keys: &[usize],
        interpolation: Interpolation,
    ) -> (f64, f64) {
        let mut layers = vec![(&self.deltas[..], &c.weights[..])];
        if let Some(n) = &self.basis {
            layers.push((&n.read[..], &n.weights[..]));
        }
        normal_errors(frames, keys, interpolation, &self.played_base, &layers)
    }
}

/// Normal targets: directions of their own for the normals, with free weights.
struct NormalBasis {
    /// Each target's normalised integers (its largest component is ±1 before rounding).
    stored: Vec<StoredDelta>,
    /// As a player reads them.
    read: Vec<Vec<Vec3>>,
    /// Weights of every frame (F × J), any sign.
    weights: Vec<Vec<f32>>,
}

/// The base normals as stored (see [`stored_base_normals`]) with the deltas of candidate `c`
/// fitted to the baked normals in f32 (see [`fit_normal_deltas`]) and, with `offset`, the
/// `normal_offset` target's NORMAL (int16 when quantised and every component fits: int8's step
/// would show in every frame's normal).
fn fitted_normals(
    frames: &RenderFrames,
    c: &Candidate,
    (base, base_q): &(Vec<Vec3>, Option<Vec<[i16; 3]>>),
    offset: bool,
) -> WrittenNormals {
    let (o, deltas) = fit_normal_deltas(frames, c, base, c.k, offset);
    let (o, o_q) = if c.quantized && o.iter().all(|x| x.abs().max_element() <= 1.0) {
        let q: Vec<[i16; 3]> = o.iter().map(|x| quantize_i16(x.as_dvec3())).collect();
        (q.iter().map(|x| dequantize_i16(*x)).collect(), Some(q))
    } else {
        (o, None)
    };
    let played_base = if offset {
        base.iter().zip(&o).map(|(b, o)| *b + *o).collect()
    } else {
        base.clone()
    };
    WrittenNormals {
        base: base.clone(),
        base_q: base_q.clone(),
        deltas,
        deltas_q: vec![None; c.k],
        offset: offset.then_some((o, o_q)),
        played_base,
        basis: None,
    }
}

/// The *shared* layout: the `fitted` deltas as written, each position target carrying its own.
/// Quantised, a target's deltas are int8 when every component fits in [-1, 1], and the others
/// are int8 clamped when that raises
/// the measured normal error by at most [`CLAMP_MAX_DEGREES`] / [`CLAMP_MEAN_DEGREES`] (always
/// with `--quantize on`), else f32.
fn shared_normals(
    fitted: &WrittenNormals,
    frames: &RenderFrames,
    c: &Candidate,
    keys: &[usize],
    options: &MorphOptions,
    basis: &BasisOptions,
) -> WrittenNormals {
    let fits: Vec<bool> = fitted
        .deltas
        .iter()
        .map(|t| t.iter().all(|x| x.abs().max_element() <= 1.0))
        .collect();
    let encode = |clamp: bool| {
        let (mut read, mut stored) = (Vec::new(), Vec::new());
        for (t, fit) in fitted.deltas.iter().zip(&fits) {
            if fitted.base_q.is_some() && (*fit || clamp) {
                let q = StoredDelta::I8(t.iter().map(|x| quantize_i8(*x)).collect());
                read.push(q.dequantized());
                stored.push(Some(q));
            } else {
                read.push(t.clone());
                stored.push(None);
            }
        }
        WrittenNormals {
            base: fitted.base.clone(),
            base_q: fitted.base_q.clone(),
            deltas: read,
            deltas_q: stored,
            offset: fitted.offset.clone(),
            played_base: fitted.played_base.clone(),
            basis: None,
        }
    };
    let unclamped = encode(false);
    if fitted.base_q.is_none() || fits.iter().all(|f| *f) {
        return unclamped;
    }
    let clamped = encode(true);
    let (e, ec) = (
        unclamped.errors(frames, c, keys, options.interpolation),
        clamped.errors(frames, c, keys, options.interpolation),
    );
    if basis.quantize == QuantizeMode::On
        || (ec.0 <= e.0 + CLAMP_MAX_DEGREES && ec.1 <= e.1 + CLAMP_MEAN_DEGREES)
    {
        clamped
    } else {
        unclamped
    }
}

/// The layout with *normal targets*, from `fitted` (fitted with the offset): zero deltas on the
/// position targets, and normal targets (see [`normal_basis`]) whose normal error is within
/// [`CLAMP_MAX_DEGREES`] / [`CLAMP_MEAN_DEGREES`] of `fitted`'s, at most as many as position
/// targets, within `--max-targets` (else [`NORMAL_TARGET_BUDGET`] targets in all). `None` when
/// `c` is not quantised, with `--sparse off` (the zero accessors are sparse), or when no such
/// normal targets exist.
fn with_normal_targets(
    fitted: WrittenNormals,
    frames: &RenderFrames,
    c: &Candidate,
    keys: &[usize],
    options: &MorphOptions,
    basis: &BasisOptions,
) -> Option<WrittenNormals> {
    if fitted.base_q.is_none() || options.sparse == SparseMode::Off {
        return None;
    }
    let (max, mean) = fitted.errors(frames, c, keys, options.interpolation);
    let accept = |e: (f64, f64)| e.0 <= max + CLAMP_MAX_DEGREES && e.1 <= mean + CLAMP_MEAN_DEGREES;
    let cap = basis
        .max_targets
        .unwrap_or(NORMAL_TARGET_BUDGET)
        .saturating_sub(c.k + 1)
        .min(c.k);
    let nb = normal_basis(
        frames,
        &fitted.played_base,
        keys,
        options.interpolation,
        cap,
        accept,
    )?;
    Some(WrittenNormals {
        deltas: vec![vec![Vec3::ZERO; frames.vertex_count()]; c.k],
        basis: Some(nb),
        ..fitted
    })
}

/// A basis for the normals alone: the residual normals `n_f − (n_b + o)` of every frame (a
/// 3V × F matrix) get a thin SVD, and the first J directions become *normal targets*: POSITION
/// zero (Blender, which drops NORMAL deltas, shows nothing for them), NORMAL the direction
/// scaled so that its largest component is 1, as normalised int8, the leading third int16, or
/// all int16, and weights of
/// their own, refitted per frame by least squares against the stored values (free in sign and
/// size: they move no position, so Blender's slider range does not matter). J is the smallest,
/// up to `cap`, whose played normals (interpolated weights at dropped frames, renormalised)
/// are accepted by `accept` (largest and mean angle to the baked normals, degrees), at the
/// coarsest of the three precisions that is accepted. Shared
/// weights tie the normals to the position motion, whose small-amplitude targets have tiny
/// weights and so need normal deltas far outside what a normalised integer holds; normal
/// targets of their own need neither f32 nor one target per position target.
fn normal_basis(
    frames: &RenderFrames,
    played_base: &[Vec3],
    keys: &[usize],
    interpolation: Interpolation,
    cap: usize,
    accept: impl Fn((f64, f64)) -> bool,
) -> Option<NormalBasis> {
    if cap == 0 {
        return None;
    }
    let (f, v) = (frames.frame_count(), frames.vertex_count());
    let residual = |i: usize, j: usize| -> f64 {
        (frames.normals(j)[i / 3][i % 3] - played_base[i / 3][i % 3]) as f64
    };
    let r = Mat::<f64>::from_fn(3 * v, f, residual);
    let svd = r.thin_svd().ok()?;
    let (u, s) = (svd.U(), svd.S().column_vector());
    let scale = s[0].max(f64::MIN_POSITIVE);
    let rank = (0..s.nrows()).take_while(|&k| s[k] > scale * 1e-12).count();
    let cap = cap.min(rank);
    // Three precisions: every direction as int8; the leading third (largest singular values,
    // so largest weights and rounding) as int16 and the rest int8; all int16. Each with its
    // stored directions, their Gram matrix and right-hand sides against every frame.
    let mut splits = vec![0, cap.div_ceil(3), cap];
    splits.dedup();
    let stages: Vec<_> = splits
        .into_iter()
        .map(|int16_first| {
            let stored: Vec<StoredDelta> = (0..cap)
                .map(|k| {
                    let largest = (0..3 * v).map(|i| u[(i, k)].abs()).fold(0.0, f64::max);
                    let d = (0..v).map(|i| {
                        DVec3::new(u[(3 * i, k)], u[(3 * i + 1, k)], u[(3 * i + 2, k)]) / largest
                    });
                    if k >= int16_first {
                        StoredDelta::I8(d.map(|x| quantize_i8(x.as_vec3())).collect())
                    } else {
                        StoredDelta::I16(d.map(quantize_i16).collect())
                    }
                })
                .collect();
            let read: Vec<Vec<Vec3>> = stored.iter().map(StoredDelta::dequantized).collect();
            let mut gram = vec![0.0f64; cap * cap];
            for a in 0..cap {
                for b in 0..=a {
                    let g: f64 = read[a]
                        .iter()
                        .zip(&read[b])
                        .map(|(x, y)| x.as_dvec3().dot(y.as_dvec3()))
                        .sum();
                    gram[a * cap + b] = g;
                    gram[b * cap + a] = g;
                }
            }
            let rhs: Vec<Vec<f64>> = (0..f)
                .map(|j| {
                    (0..cap)
                        .map(|a| {
                            read[a]
                                .iter()
                                .enumerate()
                                .map(|(i, x)| {
                                    let n = frames.normals(j)[i] - played_base[i];
                                    x.as_dvec3().dot(n.as_dvec3())
                                })
                                .sum()
                        })
                        .collect()
                })
                .collect();
            (stored, read, gram, rhs)
        })
        .collect();
    // The fewest normal targets first (engines pay per target), then the coarsest precision.
    for n in 1..=cap {
        for (stored, read, gram, rhs) in &stages {
            let g: Vec<f64> = (0..n * n).map(|x| gram[(x / n) * cap + x % n]).collect();
            let l = cholesky(&g, n);
            let weights: Vec<Vec<f32>> = rhs
                .iter()
                .map(|b| {
                    cholesky_solve(&l, n, b[..n].to_vec())
                        .into_iter()
                        .map(|x| x as f32)
                        .collect()
                })
                .collect();
            let e = normal_errors(
                frames,
                keys,
                interpolation,
                played_base,
                &[(&read[..n], &weights)],
            );
            if accept(e) {
                return Some(NormalBasis {
                    stored: stored[..n].to_vec(),
                    read: read[..n].to_vec(),
                    weights,
                });
            }
        }
    }
    None
}

/// Writes one quantised morph-target delta accessor (normalised int8 or int16 VEC3), sparse
/// (no buffer view, the non-zero elements packed) when `mode` allows it and that is smaller
/// than the dense attribute (elements padded to 4 bytes).
fn quantized_delta_accessor(
    b: &mut GltfBuilder,
    q: &StoredDelta,
    mode: SparseMode,
) -> (json::Index<json::Accessor>, DeltaEncoding) {
    let (count, mut changed, size) = match q {
        StoredDelta::I8(q) => (q.len(), nonzero(q, [0; 3]), 1),
        StoredDelta::I16(q) => (q.len(), nonzero(q, [0; 3]), 2),
    };
    if changed.is_empty() {
        changed.push(0);
    }
    let index = if count <= 1 << 16 { 2 } else { 4 };
    let sparse = (changed.len() * index).next_multiple_of(4)
        + (changed.len() * 3 * size).next_multiple_of(4)
        + SPARSE_JSON_OVERHEAD;
    let dense = count * (3 * size).next_multiple_of(4);
    if mode == SparseMode::Off || sparse >= dense {
        let a = match q {
            StoredDelta::I8(q) => i8_vec3(b, q, false),
            StoredDelta::I16(q) => i16_vec3(b, q, Some(json::buffer::Target::ArrayBuffer), false),
        };
        return (a, DeltaEncoding::Dense);
    }
    let (values, component): (Vec<u8>, _) = match q {
        StoredDelta::I8(q) => (
            changed
                .iter()
                .flat_map(|&i| q[i as usize].map(|c| c as u8))
                .collect(),
            json::accessor::ComponentType::I8,
        ),
        StoredDelta::I16(q) => (
            changed
                .iter()
                .flat_map(|&i| {
                    q[i as usize]
                        .iter()
                        .flat_map(|c| c.to_le_bytes())
                        .collect::<Vec<_>>()
                })
                .collect(),
            json::accessor::ComponentType::I16,
        ),
    };
    let a = b.sparse_accessor(
        count,
        &changed,
        &values,
        json::accessor::Type::Vec3,
        component,
        true,
        (None, None),
    );
    (a, DeltaEncoding::Sparse)
}

/// Indices of the elements of `q` other than `zero`, increasing.
fn nonzero<T: PartialEq + Copy>(q: &[T], zero: T) -> Vec<u32> {
    q.iter()
        .enumerate()
        .filter(|(_, x)| **x != zero)
        .map(|(i, _)| i as u32)
        .collect()
}

/// Writes the chosen candidate.
#[allow(
    clippy::too_many_arguments,
    reason = "the figures gathered while choosing"
)]
fn write(
    path: &Path,
    mesh: &Mesh,
    frames: &RenderFrames,
    options: &MorphOptions,
    basis: &BasisOptions,
    c: Candidate,
    keys: Vec<usize>,
    (max_error, worst_frame): (f64, usize),
    projection_error: f64,
    singular_values: Vec<f64>,
    normals: Option<WrittenNormals>,
    host: Option<&CharacterHost<'_>>,
) -> Result<EncodedBasis> {
    let mut b = host.map_or_else(GltfBuilder::new, CharacterHost::document);
    let mut bytes = PartBytes::default();
    let array = Some(json::buffer::Target::ArrayBuffer);
    let mut stats = CacheStats {
        targets: c.k,
        frames: frames.frame_count(),
        kept_frames: keys.clone(),
        max_interpolation_error: max_error,
        sparse_accessors: 0,
        dense_accessors: 0,
        target_bytes: 0,
    };

    // Normals (see `fitted_normals`, `shared_normals` and `with_normal_targets`).
    let normals_q = normals.as_ref().is_some_and(|n| n.base_q.is_some());
    let count_normal_targets = |want: fn(&StoredDelta) -> bool| {
        normals.as_ref().map_or(0, |n| {
            n.deltas_q
                .iter()
                .flatten()
                .chain(n.basis.iter().flat_map(|nb| &nb.stored))
                .filter(|q| want(q))
                .count()
        })
    };
    let int8_normal_targets = count_normal_targets(|q| matches!(q, StoredDelta::I8(_)));
    let int16_normal_targets = count_normal_targets(|q| matches!(q, StoredDelta::I16(_)));
    let (max_normal, mean_normal) = normals.as_ref().map_or((0.0, 0.0), |n| {
        n.errors(frames, &c, &keys, options.interpolation)
    });

    // Base primitive.
    let start = b.buffer_len();
    let mut attributes = std::collections::BTreeMap::new();
    let positions = if c.quantized {
        i16_vec3(&mut b, &c.base_q, array, true)
    } else {
        b.vec3(&c.base, array, true)
    };
    attributes.insert(Valid(json::mesh::Semantic::Positions), positions);
    if let Some(n) = &normals {
        let n = match &n.base_q {
            Some(nb_q) => i16_vec3(&mut b, nb_q, array, false),
            None => b.vec3(&n.base, array, false),
        };
        attributes.insert(Valid(json::mesh::Semantic::Normals), n);
    }
    if mesh.has_uvs() {
        let uvs: Vec<[f32; 2]> = mesh
            .render_vertices
            .iter()
            .map(|v| flip_v(v.uv.unwrap_or_default()))
            .collect();
        // Quantised, texture coordinates within [0, 1] as normalised u16 (KHR_mesh_quantization;
        // a step of 1/65535, under 0.07 texel of an 8K texture): half the bytes of f32.
        let in_unit = uvs.iter().flatten().all(|x| (0.0..=1.0).contains(x));
        let uv = if c.quantized && in_unit {
            let bytes: Vec<u8> = uvs
                .iter()
                .flatten()
                .flat_map(|x| ((x * 65535.0).round() as u16).to_le_bytes())
                .collect();
            b.accessor(
                &bytes,
                uvs.len(),
                json::accessor::Type::Vec2,
                json::accessor::ComponentType::U16,
                array,
                None,
                true,
            )
        } else {
            b.vec2(&uvs)
        };
        attributes.insert(Valid(json::mesh::Semantic::TexCoords(0)), uv);
    }
    bytes.base = (b.buffer_len() - start) as u64;
    let start = b.buffer_len();
    let indices: Vec<u32> = mesh.render_triangles.iter().flatten().copied().collect();
    let indices = b.indices(&indices);
    bytes.indices = (b.buffer_len() - start) as u64;

    // Targets.
    let mut targets = Vec::with_capacity(c.k);
    for t in 0..c.k {
        let start = b.buffer_len();
        let positions = if c.quantized {
            stats.dense_accessors += 1;
            match &c.deltas_q[t] {
                StoredDelta::I16(q) => i16_vec3(&mut b, q, array, true),
                StoredDelta::I8(q) => i8_vec3(&mut b, q, true),
            }
        } else {
            let (a, e) = delta_accessor(&mut b, &c.deltas[t], options.sparse, true);
            count(&mut stats, e);
            a
        };
        bytes.target_positions += (b.buffer_len() - start) as u64;
        let start = b.buffer_len();
        let normals = normals.as_ref().map(|n| match &n.deltas_q[t] {
            // Zero: a one-entry sparse accessor (every target has a NORMAL: three.js uses
            // the base normals as the deltas of a target without one).
            None if n.basis.is_some() => {
                stats.sparse_accessors += 1;
                zero_vec3(&mut b, frames.vertex_count())
            }
            Some(q) => {
                let (a, e) = quantized_delta_accessor(&mut b, q, options.sparse);
                count(&mut stats, e);
                a
            }
            None => {
                let (a, e) = delta_accessor(&mut b, &n.deltas[t], options.sparse, false);
                count(&mut stats, e);
                a
            }
        });
        bytes.target_normals += (b.buffer_len() - start) as u64;
        targets.push(json::mesh::MorphTarget {
            positions: Some(positions),
            normals,
            tangents: None,
        });
    }
    let mut names: Vec<String> = (1..=c.k).map(|t| format!("basis_{t:02}")).collect();
    let offset_target = normals.as_ref().and_then(|n| n.offset.as_ref());
    // Targets that move nothing: zero POSITION, then their NORMAL written by `normal`.
    let vertices = frames.vertex_count();
    let mut normal_only = |b: &mut GltfBuilder,
                           stats: &mut CacheStats,
                           name: String,
                           normal: &dyn Fn(
        &mut GltfBuilder,
        &mut CacheStats,
    ) -> json::Index<json::Accessor>| {
        let start = b.buffer_len();
        let zero = zero_vec3(b, vertices);
        stats.sparse_accessors += 1;
        bytes.target_positions += (b.buffer_len() - start) as u64;
        let start = b.buffer_len();
        let n = normal(b, stats);
        bytes.target_normals += (b.buffer_len() - start) as u64;
        targets.push(json::mesh::MorphTarget {
            positions: Some(zero),
            normals: Some(n),
            tangents: None,
        });
        names.push(name);
        stats.targets += 1;
    };
    if let Some((o, o_q)) = offset_target {
        normal_only(
            &mut b,
            &mut stats,
            "normal_offset".into(),
            &|b, stats| match o_q {
                Some(q) => {
                    stats.dense_accessors += 1;
                    i16_vec3(b, q, array, false)
                }
                None => {
                    let (a, e) = delta_accessor(b, o, options.sparse, false);
                    count(stats, e);
                    a
                }
            },
        );
    }
    let normal_basis = normals.as_ref().and_then(|n| n.basis.as_ref());
    for (j, q) in normal_basis.iter().flat_map(|n| &n.stored).enumerate() {
        normal_only(
            &mut b,
            &mut stats,
            format!("normal_{:02}", j + 1),
            &|b, stats| {
                let (a, e) = quantized_delta_accessor(b, q, options.sparse);
                count(stats, e);
                a
            },
        );
    }
    let offset_weight = offset_target.map(|_| 1.0f32);
    // Every key's weights: the position targets', the offset's, the normal targets'.
    let frame_weights = |k: usize| {
        c.weights[k].iter().copied().chain(offset_weight).chain(
            normal_basis
                .iter()
                .flat_map(move |n| n.weights[k].iter().copied()),
        )
    };
    stats.target_bytes = bytes.target_positions + bytes.target_normals;
    let material = cloth_material(&mut b);
    let to_raw = |value: serde_json::Value| {
        serde_json::value::to_raw_value(&value).map_err(|error| Error::Json {
            path: path.into(),
            source: error,
        })
    };
    let gmesh = b.root.push(json::Mesh {
        name: Some(options.name.clone()),
        primitives: vec![json::mesh::Primitive {
            targets: Some(targets),
            ..primitive(
                attributes,
                Some(indices),
                material,
                json::mesh::Mode::Triangles,
            )
        }],
        weights: Some(frame_weights(0).collect()),
        extensions: None,
        extras: Some(to_raw(serde_json::json!({ "targetNames": names }))?),
    });
    let node = b.root.push(json::Node {
        name: Some(options.name.clone()),
        mesh: Some(gmesh),
        translation: c.quantized.then(|| c.translation.as_vec3().to_array()),
        scale: c.quantized.then_some([c.scale as f32; 3]),
        ..Default::default()
    });
    if host.is_none() {
        bytes.statics = push_scene(&mut b, node, &options.static_meshes);
    }

    // Weights: one key per kept frame at its true time.
    let start = b.buffer_len();
    let weights: Vec<f32> = keys.iter().flat_map(|&k| frame_weights(k)).collect();
    push_weights_animation(&mut b, node, &keys, &weights, options);
    bytes.animation = (b.buffer_len() - start) as u64;
    if let Some(host) = host {
        host.dress(&mut b, node, &options.name);
    }
    super::playback::stamp(
        &mut b.root,
        &super::playback::Playback::frames(options.fps, frames.frame_count(), &options.name),
    );
    if c.quantized || normals_q {
        b.root.extensions_used.push(KHR_MESH_QUANTIZATION.into());
        b.root
            .extensions_required
            .push(KHR_MESH_QUANTIZATION.into());
    }
    let bin = b.buffer_len().next_multiple_of(4) as u64;
    let files = b.encode(path)?;
    let total: u64 = files.iter().map(|(_, f)| f.len() as u64).sum();
    bytes.json = total - bin;
    let quantization = Quantization {
        positions: if c.quantized { "int16" } else { "float" }.into(),
        normals: match (&normals, normals_q) {
            (None, _) => "none",
            (Some(_), true) => "int16",
            (Some(_), false) => "float",
        }
        .into(),
        int16_targets: c
            .deltas_q
            .iter()
            .filter(|d| matches!(d, StoredDelta::I16(_)))
            .count(),
        int8_targets: c
            .deltas_q
            .iter()
            .filter(|d| matches!(d, StoredDelta::I8(_)))
            .count(),
        int8_normal_targets,
        int16_normal_targets,
        node_scale: c.scale,
        node_translation: c.translation.to_array(),
    };
    Ok(EncodedBasis {
        morph: EncodedMorph { files, stats },
        basis: BasisStats {
            requested: basis.size,
            targets: c.k,
            tolerance: basis.tolerance,
            max_error,
            worst_frame,
            projection_error,
            max_normal_error_degrees: max_normal,
            mean_normal_error_degrees: mean_normal,
            normal_offset_target: offset_weight.is_some(),
            normal_targets: normal_basis.map_or(0, |n| n.stored.len()),
            singular_values,
            quantization,
            bytes,
        },
    })
}

/// Zero VEC3 deltas for `count` vertices: a sparse accessor without a buffer view (all zeros)
/// listing vertex 0's zero (the gltf crate wants a buffer view or sparse values), bounds 0.
fn zero_vec3(b: &mut GltfBuilder, count: usize) -> json::Index<json::Accessor> {
    b.sparse_vec3(&vec![Vec3::ZERO; count], &[0], true)
}

fn count(stats: &mut CacheStats, e: DeltaEncoding) {
    match e {
        DeltaEncoding::Sparse => stats.sparse_accessors += 1,
        DeltaEncoding::Dense => stats.dense_accessors += 1,
    }
}

/// Normalised int16 VEC3 vertex attribute, each element padded to 8 bytes (stride 8); `min_max`
/// writes bounds in the stored integer values.
fn i16_vec3(
    b: &mut GltfBuilder,
    data: &[[i16; 3]],
    target: Option<json::buffer::Target>,
    min_max: bool,
) -> json::Index<json::Accessor> {
    let bytes: Vec<u8> = data
        .iter()
        .flat_map(|v| {
            let mut e = [0u8; 8];
            for (c, x) in v.iter().enumerate() {
                e[2 * c..2 * c + 2].copy_from_slice(&x.to_le_bytes());
            }
            e
        })
        .collect();
    let bounds =
        min_max.then(|| super::gltf_doc::bounds_f32(data.iter().map(|v| v.map(|c| c as f32))));
    strided(
        b,
        &bytes,
        data.len(),
        8,
        json::accessor::ComponentType::I16,
        target,
        bounds,
    )
}

/// Normalised int8 VEC3 vertex attribute, each element padded to 4 bytes (stride 4); `min_max`
/// writes bounds in the stored integer values.
fn i8_vec3(b: &mut GltfBuilder, data: &[[i8; 3]], min_max: bool) -> json::Index<json::Accessor> {
    let bytes: Vec<u8> = data
        .iter()
        .flat_map(|v| [v[0] as u8, v[1] as u8, v[2] as u8, 0])
        .collect();
    strided(
        b,
        &bytes,
        data.len(),
        4,
        json::accessor::ComponentType::I8,
        Some(json::buffer::Target::ArrayBuffer),
        min_max.then(|| super::gltf_doc::bounds_f32(data.iter().map(|v| v.map(|c| c as f32)))),
    )
}

/// A normalised VEC3 accessor over a view with `stride`.
fn strided(
    b: &mut GltfBuilder,
    bytes: &[u8],
    count: usize,
    stride: usize,
    component: json::accessor::ComponentType,
    target: Option<json::buffer::Target>,
    bounds: Option<(Vec<f32>, Vec<f32>)>,
) -> json::Index<json::Accessor> {
    let index = b.accessor(
        bytes,
        count,
        json::accessor::Type::Vec3,
        component,
        target,
        bounds,
        true,
    );
    let accessor = &b.root.accessors[index.value()];
    let view = accessor.buffer_view.expect("a dense accessor has a view");
    b.root.buffer_views[view.value()].byte_stride = Some(json::buffer::Stride(stride));
    index
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_size_parses() {
        assert_eq!("auto".parse::<BasisSize>().unwrap(), BasisSize::Auto);
        assert_eq!("12".parse::<BasisSize>().unwrap(), BasisSize::Fixed(12));
        let e = "0".parse::<BasisSize>().unwrap_err();
        assert!(matches!(e, Error::Value { .. }), "{e}");
        assert_eq!(
            e.detail(),
            "`0`: expected a number of targets (1 or more) or `auto`"
        );
        assert!("x".parse::<BasisSize>().is_err());
    }

    #[test]
    fn cholesky_solves_a_small_system() {
        let a = [4.0, 2.0, 2.0, 3.0];
        let l = cholesky(&a, 2);
        let x = cholesky_solve(&l, 2, vec![2.0, 5.0]);
        // 4x + 2y = 2, 2x + 3y = 5 → x = -0.5, y = 2.
        assert!(
            (x[0] + 0.5).abs() < 1e-9 && (x[1] - 2.0).abs() < 1e-9,
            "{x:?}"
        );
    }

    #[test]
    fn int16_round_trip_is_within_half_a_step() {
        for x in [-1.0, -0.3, 0.0, 0.123456, 1.0] {
            let q = quantize_i16(DVec3::splat(x));
            let back = dequantize_i16(q).x as f64;
            assert!((back - x).abs() <= 0.5 / I16 + 1e-7, "{x} -> {back}");
        }
    }
}
