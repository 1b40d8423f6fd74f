//! Lapped-patch machinery shared by the methods that lay patches over the
//! surface and resolve every atlas texel against them: erosion and its
//! baselines (advect, blend-deformable, dual-rest) in [`super::erosion`],
//! and the 2016 rigid patches of [`super::lapped_rigid`].
//!
//! Why one module: the methods differ in *how a texel combines the patches
//! it meets* (the topmost surviving one, a weight-normalised blend, or the
//! over operator in layer order), not in how the texels are visited or how
//! per-band results come together. Both halves used to be written once per
//! fill; a change to either (band size, texel order, the candidate layout)
//! now happens once, and a new patch method composes these pieces instead
//! of borrowing them from inside another method's folder.
//!
//! - [`lists`]: per-fluid-triangle lists in patch (= age) order, the
//!   layout of erosion's candidate patch triangles and of the rigid
//!   patches' receivers.
//! - [`bands`]: the per-texel outputs every lapped fill writes
//!   ([`TexelBuffers`]) and the parallel walk over the atlas's bands of
//!   rows: per span the fluid triangle, its normal and its texels' surface
//!   points; per band its rows of every buffer; and the deterministic merge
//!   of the bands' uncovered texels and used patches.
//! - [`pending`]: the uncovered texels the coverage-driven insertion still
//!   has to close, grouped by fluid triangle, handed out in texel order.
//! - [`scale`]: the patch radius r and exemplar size S, their checks and
//!   their one-time resolution on the first frame with a surface.
//! - [`state`]: texels per exemplar and the state agreement of a texture
//!   chosen by a simulation attribute.
//!
//! Everything here is deterministic whatever the thread count: each band
//! writes only its own rows and the merge sorts by texel and patch index.

pub mod bands;
pub mod lists;
pub mod pending;
pub mod scale;
pub mod state;

pub use bands::{BandResult, BandTexel, SpanTexels, TexelBuffers, TexelRows, fill_bands};
pub use lists::TriangleLists;
pub use pending::Pending;
pub use scale::{PatchScale, ScaleKeys};

/// Layers below this share of a texel's result are not counted as visible
/// layers (the ghost-fraction rule of docs/evaluation.md); they still
/// contribute. The blended erosion baseline and the rigid patches count
/// with the same rule, so their ghost metrics compare.
pub const VISIBLE_LAYER_WEIGHT: f32 = 0.05;

/// A chart texel: its row-major index and the surface point it shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChartTexel {
    /// Row-major texel index.
    pub texel: u32,
    pub triangle: u32,
    pub bary: [f32; 3],
}

/// Something attached to one chart texel (an uncovered texel, possibly
/// with a partial result): the band merge orders them by texel.
pub trait AtTexel {
    fn texel(&self) -> u32;
}

impl AtTexel for ChartTexel {
    fn texel(&self) -> u32 {
        self.texel
    }
}
