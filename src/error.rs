//! The library's error type.
//!
//! Every variant carries what a user needs to fix the input: the file, the line or element, the
//! option, and what was wrong. Messages are lowercase with no trailing period; the binary prints
//! them behind `error:`.

use std::path::PathBuf;

/// Result alias used throughout the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong while loading, simulating or writing.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be opened, read or written.
    #[error("{path}: {error}")]
    Io {
        /// The file involved.
        path: PathBuf,
        /// The operating system's error (already part of the message).
        error: std::io::Error,
    },
    /// A file's content could not be understood.
    #[error("{path}{}: {message}", location_suffix(*.line))]
    Parse {
        /// The file involved.
        path: PathBuf,
        /// One-based line number, when the format is line-oriented.
        line: Option<usize>,
        /// What was wrong.
        message: String,
    },
    /// The input is readable but unusable (no faces, index out of range, non-finite value...).
    #[error("{path}: {message}")]
    InvalidInput {
        /// The file (or preset name) involved.
        path: PathBuf,
        /// What was wrong, naming the element.
        message: String,
    },
    /// A triangle mesh given as a collider is unusable.
    #[error("collider mesh{}: {problem}", path_suffix(path.as_deref()))]
    ColliderMesh {
        /// The mesh file, when the mesh came from one.
        path: Option<PathBuf>,
        /// What is wrong, naming the element.
        problem: ColliderMeshProblem,
    },
    /// A character of `--text` that the font has no glyph for.
    #[error("--text: font `{font}` has no glyph for {glyph:?} (U+{:04X})", u32::from(*glyph))]
    UnknownGlyph {
        /// The font's name (built-in name or file path).
        font: String,
        /// The character.
        glyph: char,
    },
    /// A command-line option or scene-file key has an invalid value.
    #[error("invalid value for {option}: {message}")]
    InvalidOption {
        /// The option, as the user spelled it (`--pin`, `--frames`...).
        option: String,
        /// What was wrong with the value, and the expected form.
        message: String,
    },
    /// A pin specification selected no particle.
    #[error("--pin {spec}: selects no particle{hint}")]
    EmptyPin {
        /// The pin specification as given.
        spec: String,
        /// Extra help (for example the mesh bounds), starting with "; ".
        hint: String,
    },
    /// The simulation produced non-finite or exploding positions.
    #[error(
        "simulation diverged at frame {frame} ({reason}); try a smaller time step \
         (more --substeps or a higher --fps), lower --stiffness, or more --iterations"
    )]
    Diverged {
        /// The first frame whose state was unusable (1-based, frame 0 is the input pose).
        frame: usize,
        /// What was detected (for example "non-finite position at particle 12").
        reason: String,
    },
    /// The sparse Cholesky factorisation failed (matrix not positive definite).
    #[error("sparse factorisation failed: {0}")]
    Factorisation(String),
    /// A glTF document could not be loaded.
    #[error("{path}: {}", describe_gltf(error))]
    Gltf {
        /// The file involved.
        path: PathBuf,
        /// The `gltf` crate's error (already part of the message).
        error: gltf::Error,
    },
    /// A glTF document could not be serialised.
    #[error("{path}: cannot serialise glTF JSON: {error}")]
    Json {
        /// The output file.
        path: PathBuf,
        /// The serialiser's error (already part of the message).
        error: serde_json::Error,
    },
    /// An inverse-kinematics chain could not be built.
    #[error("{0}")]
    Chain(String),
    /// A `--chain` end names no node of the rig.
    #[error("{path}: --chain: no node named `{joint}` (use a node name, `#N` for node N, quoted in a shell as in '#13..#15', or Blender's `Node_N`; `scenebake inspect {}` lists them)", .path.display())]
    UnknownJoint {
        /// The rig file.
        path: PathBuf,
        /// The joint as given.
        joint: String,
    },
    /// The `--chain` tip is not a descendant of the chain root.
    #[error("{path}: --chain {root}..{tip}: `{tip}` is not below `{root}` in the node hierarchy")]
    JointNotBelow {
        /// The rig file.
        path: PathBuf,
        /// The chain root as given.
        root: String,
        /// The chain tip as given.
        tip: String,
    },
    /// An export could not be written because its data is inconsistent or too large.
    #[error("{path}: {message}")]
    Export {
        /// The output file.
        path: PathBuf,
        /// What was wrong.
        message: String,
    },
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
            error: source,
        }
    }

    /// Shorthand for [`Error::InvalidInput`].
    pub fn invalid(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::InvalidInput {
            path: path.into(),
            message: message.into(),
        }
    }

    /// Shorthand for [`Error::InvalidOption`].
    pub fn option(option: impl Into<String>, message: impl Into<String>) -> Self {
        Error::InvalidOption {
            option: option.into(),
            message: message.into(),
        }
    }
}
