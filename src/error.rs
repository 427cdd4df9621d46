//! The library's error type.
//!
//! Every variant carries what a user needs to fix the input: the file, the line or element, the
//! option, and what was wrong. Messages are lowercase with no trailing period; the binary prints
//! them behind `error:`.
//!
//! Only the job layer ([`crate::bake`], [`crate::scene`], the binary) knows which job parameter
//! a value came from. Lower layers (loaders, models, solvers, writers) report a bad value as an
//! [`Error::Value`], or a problem of their own kind ([`Error::Basis`], [`Error::HingeAxis`]...),
//! and the job layer names the parameter: [`Error::for_param`] (or [`ForParam::for_param`] on a
//! result) makes a value error an [`Error::Param`].

use std::fmt;
use std::path::PathBuf;

use crate::param::{scene_key, Param, Text, Vocabulary};

/// Result alias used throughout the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong while loading, simulating or writing.
///
/// Variants that concern a job parameter carry it as a [`Param`]; [`Error::render`] names it in
/// the caller's vocabulary (the binary's `--flag`), `Display` as its scene key.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be opened, read or written.
    Io {
        /// The file involved.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A file's content could not be understood.
    Parse {
        /// The file involved.
        path: PathBuf,
        /// One-based line number, when the format is line-oriented.
        line: Option<usize>,
        /// What was wrong.
        message: Text,
    },
    /// The input is readable but unusable (no faces, index out of range, non-finite value...).
    InvalidInput {
        /// The file (or preset name) involved.
        path: PathBuf,
        /// What was wrong, naming the element.
        message: Text,
    },
    /// A triangle mesh given as a collider is unusable.
    ColliderMesh {
        /// The mesh file, when the mesh came from one.
        path: Option<PathBuf>,
        /// What is wrong, naming the element.
        problem: ColliderMeshProblem,
    },
    /// A character of the text that the font has no glyph for.
    UnknownGlyph {
        /// The font's name (built-in name or file path).
        font: String,
        /// The character.
        glyph: char,
    },
    /// A value is invalid, reported by a layer that does not know which job parameter it came
    /// from; the job layer makes it an [`Error::Param`] ([`Error::for_param`]).
    Value {
        /// What was wrong with the value, and the expected form.
        message: Text,
    },
    /// A job parameter has an invalid value, or does not go with the others given.
    Param {
        /// The parameter.
        param: Param,
        /// What was wrong with the value, and the expected form.
        message: Text,
    },
    /// A pin specification selected no particle.
    EmptyPin {
        /// The pin specification as given.
        spec: String,
        /// Extra help (for example the mesh bounds), starting with "; ".
        hint: String,
    },
    /// The simulation produced non-finite or exploding positions.
    Diverged {
        /// The first frame whose state was unusable (1-based, frame 0 is the input pose).
        frame: usize,
        /// What was detected (for example "non-finite position at particle 12").
        reason: String,
        /// The options that could help, for the solver that diverged (see [`advise`]).
        advice: Vec<Param>,
    },
    /// The sparse Cholesky factorisation failed (matrix not positive definite).
    Factorisation(String),
    /// A glTF document could not be loaded.
    Gltf {
        /// The file involved.
        path: PathBuf,
        /// The `gltf` crate's error.
        source: gltf::Error,
    },
    /// A glTF document could not be serialised.
    Json {
        /// The output file.
        path: PathBuf,
        /// The serialiser's error.
        source: serde_json::Error,
    },
    /// An inverse-kinematics chain could not be built.
    Chain(String),
    /// A chain end names no node of the rig.
    UnknownJoint {
        /// The rig file.
        path: PathBuf,
        /// The joint as given.
        joint: String,
    },
    /// The chain's tip is not a descendant of the chain root.
    JointNotBelow {
        /// The rig file.
        path: PathBuf,
        /// The chain root as given.
        root: String,
        /// The chain tip as given.
        tip: String,
    },
    /// An export could not be written because its data is inconsistent or too large.
    Export {
        /// The output file.
        path: PathBuf,
        /// What was wrong.
        message: Text,
    },
    /// A morph basis cannot be written as asked for this bake.
    Basis {
        /// The output file.
        path: PathBuf,
        /// What stands in the way.
        problem: BasisProblem,
    },
    /// A glTF given as a mesh sequence has no mesh animated by morph-target weights.
    NoMorphAnimation {
        /// The glTF file.
        path: PathBuf,
        /// The node or mesh asked for, when one was.
        part: Option<String>,
    },
    /// The frame rate of a glTF mesh sequence is unknown: its keys are not evenly spaced and the
    /// file records none, so the caller must give one.
    UnknownRate {
        /// The glTF file.
        path: PathBuf,
    },
    /// A hinge limit without an axis on a joint that is straight in the rest pose, with no pole
    /// to tell its bend.
    HingeAxis {
        /// The limit specification as given.
        spec: String,
        /// The joint.
        joint: String,
    },
    /// A scene file is malformed: unknown keys, wrong types, no jobs.
    Scene {
        /// The scene file.
        path: PathBuf,
        /// The job (`[[cloth]]` number or name), when the problem is inside one.
        job: Option<String>,
        /// What was wrong.
        message: String,
    },
}

impl Error {
    /// The message with every parameter named by `vocabulary` (the binary passes its `--flag`
    /// spellings); causes are included.
    pub fn render(&self, vocabulary: Vocabulary<'_>) -> String {
        let v = vocabulary;
        match self {
            Error::Io { path, source } => format!("{}: {source}", path.display()),
            Error::Parse {
                path,
                line,
                message,
            } => format!(
                "{}{}: {}",
                path.display(),
                location_suffix(*line),
                message.render(v)
            ),
            Error::InvalidInput { path, message } | Error::Export { path, message } => {
                format!("{}: {}", path.display(), message.render(v))
            }
            Error::ColliderMesh { path, problem } => {
                format!("collider mesh{}: {problem}", path_suffix(path.as_deref()))
            }
            Error::UnknownGlyph { font, glyph } => format!(
                "{}: font `{font}` has no glyph for {glyph:?} (U+{:04X})",
                v(Param::Text),
                u32::from(*glyph)
            ),
            Error::Value { message } => format!("invalid value: {}", message.render(v)),
            Error::Param { param, message } => {
                format!("invalid value for {}: {}", v(*param), message.render(v))
            }
            Error::EmptyPin { spec, hint } => {
                format!("{} {spec}: selects no particle{hint}", v(Param::Pin))
            }
            Error::Diverged {
                frame,
                reason,
                advice,
            } => {
                let mut m = format!("simulation diverged at frame {frame} ({reason})");
                for (k, p) in advice.iter().enumerate() {
                    m.push_str(match k {
                        0 => "; try ",
                        _ if k + 1 == advice.len() => " or ",
                        _ => ", ",
                    });
                    m.push_str(&advise(*p, v));
                }
                m
            }
            Error::Factorisation(m) => format!("sparse factorisation failed: {m}"),
            Error::Gltf { path, source } => {
                format!("{}: {}", path.display(), describe_gltf(source))
            }
            Error::Json { path, source } => {
                format!("{}: cannot serialise glTF JSON: {source}", path.display())
            }
            Error::Chain(m) => m.clone(),
            Error::UnknownJoint { path, joint } => format!(
                "{}: {}: no node named `{joint}` (use a node name, `#N` for node N, quoted in a \
                 shell as in '#13..#15', or Blender's `Node_N`; `scenebake inspect {}` lists \
                 them)",
                path.display(),
                v(Param::Chain),
                path.display()
            ),
            Error::JointNotBelow { path, root, tip } => format!(
                "{}: {} {root}..{tip}: `{tip}` is not below `{root}` in the node hierarchy",
                path.display(),
                v(Param::Chain)
            ),
            Error::Basis { path, problem } => format!("{}: {problem}", path.display()),
            Error::NoMorphAnimation { path, part } => format!(
                "`{}`: no mesh{} animated by morph-target weights (a skinned character is a \
                 rig, not a mesh sequence)",
                path.display(),
                part.as_ref()
                    .map_or_else(String::new, |p| format!(" named `{p}`"))
            ),
            Error::UnknownRate { path } => format!(
                "`{}`: the keys are not evenly spaced and the file records no frame rate; give \
                 the rate to sample at",
                path.display()
            ),
            Error::HingeAxis { spec, joint } => format!(
                "limit `{spec}`: cannot tell the bend axis of `{joint}`: it is straight in the \
                 rest pose; give a pole or the axis as JOINT:hinge:MIN..MAX:X,Y,Z"
            ),
            Error::Scene { path, job, message } => match job {
                Some(job) => format!("{}: {job}: {message}", path.display()),
                None => format!("{}: {message}", path.display()),
            },
        }
    }

    /// What is wrong, without the "invalid value for …" lead of a [`Error::Param`] or
    /// [`Error::Value`] (for front ends that name the option themselves); parameters named by
    /// their scene keys.
    pub fn detail(&self) -> String {
        match self {
            Error::Param { message, .. } | Error::Value { message } => message.to_string(),
            other => other.to_string(),
        }
    }

    /// The parameter the error is about, when it is about one.
    pub fn param(&self) -> Option<Param> {
        match self {
            Error::Param { param, .. } => Some(*param),
            Error::EmptyPin { .. } => Some(Param::Pin),
            Error::UnknownGlyph { .. } => Some(Param::Text),
            Error::UnknownJoint { .. } | Error::JointNotBelow { .. } => Some(Param::Chain),
            _ => None,
        }
    }
}

impl fmt::Display for Error {
    /// The message with parameters named by their scene keys.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.render(&scene_key))
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            Error::Gltf { source, .. } => Some(source),
            Error::Json { source, .. } => Some(source),
            Error::ColliderMesh { problem, .. } => Some(problem),
            Error::Basis { problem, .. } => Some(problem),
            _ => None,
        }
    }
}

/// The `gltf` crate's errors in words a user can act on.
fn describe_gltf(e: &gltf::Error) -> String {
    match e {
        gltf::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "the file ends early: truncated or corrupt glTF binary".into()
        }
        gltf::Error::Binary(b) => format!("not a valid GLB container ({b})"),
        gltf::Error::Deserialize(d) => format!("invalid glTF JSON ({d})"),
        gltf::Error::Validation(v) => {
            let first: Vec<String> = v
                .iter()
                .take(3)
                .map(|(path, err)| format!("{}: {err}", path.as_str()))
                .collect();
            format!(
                "invalid glTF ({}{})",
                first.join("; "),
                if v.len() > 3 {
                    format!("; and {} more", v.len() - 3)
                } else {
                    String::new()
                }
            )
        }
        other => other.to_string(),
    }
}

/// Why a collider mesh was refused (see [`Error::ColliderMesh`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ColliderMeshProblem {
    /// A position has a NaN or infinite coordinate.
    #[error("position {index} is not finite")]
    NonFinitePosition {
        /// Zero-based index of the position.
        index: usize,
    },
    /// A triangle refers to a position that does not exist.
    #[error("triangle {triangle} refers to position {index}, but there are {positions} positions")]
    IndexOutOfRange {
        /// Zero-based index of the triangle.
        triangle: usize,
        /// The offending zero-based position index.
        index: u32,
        /// How many positions there are.
        positions: usize,
    },
    /// Every triangle is degenerate (repeated corner or zero area), or there are none.
    #[error("no triangle of non-zero area ({dropped} degenerate triangles dropped)")]
    NoTriangles {
        /// How many degenerate triangles were dropped.
        dropped: usize,
    },
}

/// Why a morph basis cannot be written (see [`Error::Basis`]).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BasisProblem {
    /// A fixed number of targets larger than the frames after frame 0.
    #[error("{targets} targets: the bake has only {available} frames after frame 0")]
    TooFewFrames {
        /// The targets asked for.
        targets: usize,
        /// The frames after frame 0.
        available: usize,
    },
    /// No basis within the target cap keeps every frame within the tolerance.
    #[error(
        "a tolerance of {tolerance} m cannot be met with at most {cap} targets (best: {best} \
         targets, {best_error:.3e} m); raise it, or allow more targets"
    )]
    ToleranceUnmet {
        /// The tolerance, m.
        tolerance: f64,
        /// The most targets tried.
        cap: usize,
        /// The target count that came closest.
        best: usize,
        /// Its largest error, m.
        best_error: f64,
        /// The allowed maximum, when it (not the frame count) set the cap.
        max_targets: Option<usize>,
    },
    /// The basis needs more targets than allowed.
    #[error("the basis needs {needed} targets, more than allowed")]
    TooManyTargets {
        /// The targets the basis needs.
        needed: usize,
    },
}

/// How option `p` helps a diverging simulation, for [`Error::Diverged`]'s advice, named by `v`.
fn advise(p: Param, v: Vocabulary<'_>) -> String {
    match p {
        Param::Substeps | Param::Splits => format!("more {}", v(p)),
        Param::Fps | Param::Iterations => format!("a higher {}", v(p)),
        _ => v(p),
    }
}

fn path_suffix(path: Option<&std::path::Path>) -> String {
    path.map(|p| format!(" {}", p.display()))
        .unwrap_or_default()
}

fn location_suffix(line: Option<usize>) -> String {
    line.map(|l| format!(":{l}")).unwrap_or_default()
}

impl Error {
    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// Shorthand for [`Error::InvalidInput`].
    pub fn invalid(path: impl Into<PathBuf>, message: impl Into<Text>) -> Self {
        Error::InvalidInput {
            path: path.into(),
            message: message.into(),
        }
    }

    /// Shorthand for [`Error::Param`].
    pub fn param_value(param: Param, message: impl Into<Text>) -> Self {
        Error::Param {
            param,
            message: message.into(),
        }
    }

    /// Shorthand for [`Error::Value`].
    pub fn value(message: impl Into<Text>) -> Self {
        Error::Value {
            message: message.into(),
        }
    }

    /// The error with the parameter the value came from: an [`Error::Value`] becomes an
    /// [`Error::Param`] naming `param`; every other error is returned as it is.
    pub fn for_param(self, param: Param) -> Self {
        match self {
            Error::Value { message } => Error::Param { param, message },
            other => other,
        }
    }
}

/// [`Error::for_param`] on a result's error.
pub trait ForParam<T> {
    /// The result, a value error naming `param`.
    ///
    /// # Errors
    /// The result's error, an [`Error::Value`] made an [`Error::Param`].
    fn for_param(self, param: Param) -> Result<T>;
}

impl<T> ForParam<T> for Result<T> {
    fn for_param(self, param: Param) -> Result<T> {
        self.map_err(|e| e.for_param(param))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_errors_take_the_parameter_the_job_names() {
        let flag = |p: Param| format!("--{}", p.key().replace('_', "-"));
        let e = Error::value("`x`: expected a number");
        assert_eq!(e.param(), None);
        assert_eq!(e.to_string(), "invalid value: `x`: expected a number");
        assert_eq!(e.detail(), "`x`: expected a number");
        let e = e.for_param(Param::Pin);
        assert_eq!(e.param(), Some(Param::Pin));
        assert_eq!(
            e.render(&flag),
            "invalid value for --pin: `x`: expected a number"
        );
        // Only value errors take a parameter: others keep their own.
        let r: Result<()> = Err(Error::param_value(Param::Frames, "0: must be at least 1"));
        assert_eq!(
            r.for_param(Param::Pin).unwrap_err().param(),
            Some(Param::Frames)
        );
        let io = Error::io("a.obj", std::io::Error::other("gone")).for_param(Param::Pin);
        assert!(matches!(io, Error::Io { .. }), "{io}");
    }
}
