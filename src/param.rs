//! Job parameters by name, and messages that mention them.
//!
//! A [`Param`] is one field of a job config ([`crate::bake::ClothJob`], [`crate::bake::IkJob`]).
//! Scene files spell it as its [`key`](Param::key) (`max_iterations = 50`); a front end may spell
//! it its own way (the `scenebake` binary writes `--max-iterations`). Library errors therefore
//! carry the parameter, not a spelling, and their words as a [`Text`] that the caller renders
//! with its own vocabulary ([`crate::Error::render`]).

use std::fmt;

macro_rules! params {
    ($($(#[doc = $doc:literal])* $variant:ident => $key:literal,)*) => {
        /// One parameter of a job config.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[non_exhaustive]
        pub enum Param {
            $($(#[doc = $doc])* $variant,)*
        }

        impl Param {
            /// Every parameter.
            pub const ALL: &'static [Param] = &[$(Param::$variant),*];

            /// The parameter's key in scene files and configs (the config field's serde name).
            pub const fn key(self) -> &'static str {
                match self {
                    $(Param::$variant => $key,)*
                }
            }
        }
    };
}

params! {
    /// The input file (a mesh, or a rig).
    Input => "input",
    /// A generated scene instead of an input file.
    Preset => "preset",
    /// Cells per side of a generated grid.
    Resolution => "resolution",
    /// The output file.
    Output => "output",
    /// Where the caller writes the job's JSON report.
    Report => "report",
    /// The name of the job and of what it writes.
    Name => "name",
    /// Frames baked.
    Frames => "frames",
    /// Frames per second.
    Fps => "fps",
    /// Solver steps per frame.
    Substeps => "substeps",
    /// How many times over a failed step may be halved.
    Splits => "splits",
    /// The solver.
    Solver => "solver",
    /// The stopping tolerance.
    Tolerance => "tolerance",
    /// The strain above which a frame is flagged.
    StrainLimit => "strain_limit",
    /// The iteration cap per step or frame.
    MaxIterations => "max_iterations",
    /// The fast cloth solver's iteration cap.
    Iterations => "iterations",
    /// Newton's iteration cap.
    MaxNewton => "max_newton",
    /// Newton's Gauss–Seidel sweeps per iteration.
    Sweeps => "sweeps",
    /// The threads a bake may use.
    Threads => "threads",
    /// How Newton solves for its directions (a factor or multigrid).
    LinearSolver => "linear_solver",
    /// A fabric preset.
    Material => "material",
    /// A fabric's stretch modulus.
    Stretch => "stretch",
    /// A fabric's bending rigidity.
    Bend => "bend",
    /// A fabric's compression stiffness.
    Compression => "compression",
    /// A fabric's jamming strain.
    JamStrain => "jam_strain",
    /// The rest shape of a fabric's bending.
    BendRest => "bend_rest",
    /// How a fabric resists stretch.
    Membrane => "membrane",
    /// The labs' spring stiffness.
    Stiffness => "stiffness",
    /// The labs' bending-spring stiffness.
    BendStiffness => "bend_stiffness",
    /// Mass-proportional damping.
    Damping => "damping",
    /// Mass per particle.
    Mass => "mass",
    /// Areal or volume density.
    Density => "density",
    /// Gravity.
    Gravity => "gravity",
    /// Pinned particles.
    Pin => "pin",
    /// One object or group of an OBJ input.
    Object => "object",
    /// One mesh of a glTF input.
    Mesh => "mesh",
    /// Weight interpolation between frames.
    Interpolation => "interpolation",
    /// Morph-target normals.
    Normals => "normals",
    /// A vertex-animation texture.
    Vat => "vat",
    /// What the vertex-animation texture stores.
    VatMode => "vat_mode",
    /// Most pixels per vertex-animation texture row.
    VatMaxWidth => "vat_max_width",
    /// A PC2 point cache.
    Pc2 => "pc2",
    /// An MDD point cache.
    Mdd => "mdd",
    /// A USD layer.
    Usd => "usd",
    /// Keyframe reduction tolerance.
    KeyframeTolerance => "keyframe_tolerance",
    /// Sparse morph targets.
    Sparse => "sparse",
    /// A morph basis.
    Basis => "basis",
    /// The morph basis tolerance.
    BasisTolerance => "basis_tolerance",
    /// Most morph targets.
    MaxTargets => "max_targets",
    /// Quantised attributes.
    Quantize => "quantize",
    /// Engine-side compression of the glTF.
    Compress => "compress",
    /// Scale of the input.
    Scale => "scale",
    /// Offset of the input.
    Translate => "translate",
    /// The input's up axis.
    Up => "up",
    /// A collider.
    Collider => "collider",
    /// Collision thickness.
    Thickness => "thickness",
    /// Coulomb friction.
    Friction => "friction",
    /// Newton's contact model.
    Contact => "contact",
    /// The cloth's contact with itself.
    SelfContact => "self_contact",
    /// The cloth's layer against itself.
    SelfThickness => "self_thickness",
    /// Wind velocity.
    Wind => "wind",
    /// Aerodynamic drag coefficient.
    Drag => "drag",
    /// Aerodynamic lift coefficient (cloth), or the pen's lift height (IK).
    Lift => "lift",
    /// Gust strength.
    Turbulence => "turbulence",
    /// Random seed.
    Seed => "seed",
    /// The animation of a rig that drives a cloth bake.
    Animation => "animation",
    /// Loops of the driving animation exported.
    Cycles => "cycles",
    /// Loops of the driving animation simulated and discarded first.
    WarmupCycles => "warmup_cycles",
    /// Seconds blending from the rig's rest pose into its animation.
    BlendIn => "blend_in",
    /// The joint the pins ride.
    PinTo => "pin_to",
    /// How far the pins' skin weights are averaged.
    PinSmooth => "pin_smooth",
    /// How long the end of a character's written loop is steered onto the loop before.
    LoopBlend => "loop_blend",
    /// Whether the character's body is a collider.
    BodyCollider => "body_collider",
    /// Body meshes the garment ignores.
    BodyExclude => "body_exclude",
    /// A body given as a mesh sequence (a file pattern with a frame number).
    Body => "body",
    /// Frames per second of a body sequence.
    BodyFps => "body_fps",
    /// The first frame number of a body sequence.
    BodyStart => "body_start",
    /// Write the garment alone.
    GarmentOnly => "garment_only",
    /// Metres per unit of the rig.
    RigScale => "rig_scale",
    /// Joints of a generated chain.
    Joints => "joints",
    /// Length of a generated chain.
    Length => "length",
    /// A rigged glTF.
    Rig => "rig",
    /// The chain of a rig.
    Chain => "chain",
    /// Largest joint rotation per frame.
    MaxAngle => "max_angle",
    /// The chain's pole point.
    Pole => "pole",
    /// Joint limits.
    Limit => "limit",
    /// A closed curve to follow.
    Curve => "curve",
    /// Text to write.
    Text => "text",
    /// The font of the text.
    Font => "font",
    /// An SVG drawing.
    Svg => "svg",
    /// A CSV of points.
    Points => "points",
    /// Curve radius.
    Radius => "radius",
    /// Centre of the drawing.
    Center => "center",
    /// The drawing board's normal.
    Normal => "normal",
    /// Letter or drawing height.
    Size => "size",
    /// Spacing of the targets.
    Spacing => "spacing",
    /// The pen's speed.
    PenSpeed => "pen_speed",
    /// The pen's easing time.
    Ease => "ease",
    /// The end effector's (pen's) world direction.
    TipAxis => "tip_axis",
    /// The rig animation the bake is layered on.
    BaseAnimation => "base_animation",
    /// The radius of the drawn trail's tubes.
    TrailRadius => "trail_radius",
}

impl fmt::Display for Param {
    /// The key in backticks, as scene files spell it.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}`", self.key())
    }
}

/// How a front end names parameters (`--max-iterations`, `` `max_iterations` ``...).
pub type Vocabulary<'a> = &'a dyn Fn(Param) -> String;

/// The library's own vocabulary: the scene key in backticks.
pub fn scene_key(param: Param) -> String {
    param.to_string()
}

/// Words that may name parameters; rendered with a [`Vocabulary`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Text(Vec<Piece>);

/// A piece of a [`Text`].
#[derive(Debug, Clone, PartialEq)]
pub enum Piece {
    /// Literal words.
    Words(String),
    /// A parameter, named by the reader's vocabulary.
    Param(Param),
}

impl From<&str> for Piece {
    fn from(s: &str) -> Self {
        Piece::Words(s.to_owned())
    }
}

impl From<String> for Piece {
    fn from(s: String) -> Self {
        Piece::Words(s)
    }
}

impl From<Param> for Piece {
    fn from(p: Param) -> Self {
        Piece::Param(p)
    }
}

impl From<&str> for Text {
    fn from(s: &str) -> Self {
        Text(vec![s.into()])
    }
}

impl From<String> for Text {
    fn from(s: String) -> Self {
        Text(vec![s.into()])
    }
}

impl Text {
    /// A text from its pieces (see the [`text!`](crate::text) macro).
    pub fn new(pieces: Vec<Piece>) -> Self {
        Text(pieces)
    }

    /// The pieces.
    pub fn pieces(&self) -> &[Piece] {
        &self.0
    }

    /// Every parameter the text names, in order.
    pub fn params(&self) -> impl Iterator<Item = Param> + '_ {
        self.0.iter().filter_map(|p| match p {
            Piece::Param(p) => Some(*p),
            Piece::Words(_) => None,
        })
    }

    /// The text with each parameter named by `vocabulary`.
    pub fn render(&self, vocabulary: Vocabulary<'_>) -> String {
        self.0
            .iter()
            .map(|p| match p {
                Piece::Words(w) => w.clone(),
                Piece::Param(p) => vocabulary(*p),
            })
            .collect()
    }
}

impl fmt::Display for Text {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.render(&scene_key))
    }
}

impl serde::Serialize for Text {
    /// As a string, parameters named by their scene keys.
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&self.to_string())
    }
}

/// Builds a [`Text`] from words and [`Param`]s: `text!("give ", Param::Wind, " too")`.
#[macro_export]
macro_rules! text {
    ($($piece:expr),* $(,)?) => {
        $crate::param::Text::new(vec![$($crate::param::Piece::from($piece)),*])
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_unique_snake_case() {
        let mut keys: Vec<&str> = Param::ALL.iter().map(|p| p.key()).collect();
        assert!(keys.iter().all(|k| k
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')));
        keys.sort_unstable();
        let n = keys.len();
        keys.dedup();
        assert_eq!(keys.len(), n, "duplicate keys");
    }

    #[test]
    fn texts_render_with_any_vocabulary() {
        let t = text!("give ", Param::Wind, " X,Y,Z too");
        assert_eq!(t.to_string(), "give `wind` X,Y,Z too");
        let flag = |p: Param| format!("--{}", p.key().replace('_', "-"));
        assert_eq!(t.render(&flag), "give --wind X,Y,Z too");
        assert_eq!(t.params().collect::<Vec<_>>(), vec![Param::Wind]);
    }
}
