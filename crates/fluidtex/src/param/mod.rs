//! Surface parameterization: flattening triangle meshes to the plane.
//!
//! - [`mod@lscm`] — least-squares conformal maps (Lévy et al. 2002), the one
//!   solver used both for patch flattening (docs/design.md, *Flattening*)
//!   and for atlas charts.
//! - [`charts`] — segmentation of a mesh into disc-like charts.
//! - [`flatten`] — LSCM per chart, injectivity check, splitting of folds.
//! - [`cut`] — cutting charts too long for the atlas into pieces.
//! - [`pack`] — packing flattened charts into a texel rectangle.
//!
//! All solves run in `f64`; inputs and outputs are `f32` geometry.

pub mod charts;
pub mod cut;
pub mod flatten;
pub mod lscm;
pub mod pack;

pub use lscm::{DEGENERATE_RATIO, is_degenerate, lscm};

use thiserror::Error;

/// Why a mesh could not be parameterized. Indices refer to the caller's
/// arrays (zero-based).
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ParamError {
    #[error("cannot parameterize a mesh without triangles")]
    Empty,
    #[error("triangle {triangle} refers to vertex {index}, but there are {vertex_count} vertices")]
    IndexOutOfRange {
        triangle: usize,
        index: u32,
        vertex_count: usize,
    },
    #[error("vertex {vertex} has a non-finite position")]
    NonFinitePosition { vertex: usize },
    #[error("triangle {triangle} is degenerate (zero area or a repeated corner)")]
    DegenerateTriangle { triangle: usize },
    #[error(
        "the mesh has {components} edge-connected components (triangle {triangle} is not connected to triangle 0)"
    )]
    Disconnected { components: usize, triangle: usize },
    #[error("the {unknowns}-unknown least-squares system could not be factorized: {reason}")]
    Factorization { unknowns: usize, reason: String },
}
