//! Linear algebra for the cloth solvers: sparse Cholesky factors laid out for their triangular
//! sweeps ([`factor`]), the fill-reducing orders they are computed in ([`ordering`]), the
//! right-hand-side lanes the sweeps run over ([`lanes`]), the factor in two halves on two threads
//! ([`split`]), the hand-off between those threads ([`handoff`]), algebraic multigrid
//! ([`multigrid`]), and the conjugate gradients every solver's iterative solves run (`cg`).

pub(crate) mod cg;
pub mod factor;
pub(crate) mod handoff;
pub mod lanes;
pub mod multigrid;
pub mod ordering;
pub(crate) mod split;

pub use factor::{analyse_upper_with, upper_from_triplets, Cholesky};
pub use lanes::{Lanes4, Lanes4f};
pub use ordering::fill_reducing_order;
