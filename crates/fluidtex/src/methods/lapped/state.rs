//! What the lapped methods measure of a texture that follows the fluid's
//! state ([`crate::exemplar::SelectBy`]): per exemplar, the atlas texels it
//! shows, and the *state agreement*, the share of covered texels whose
//! shown exemplar matches the selecting attribute at the texel's surface
//! point, over every covered texel and over the *decisive* ones (whose
//! value lies clear of every split between ranges). Both read the
//! per-texel source (patch id + 1) that erosion and lapped-rigid write
//! alike, so the two methods count the same way.

use crate::atlas::Atlas;
use crate::exemplar::SelectBy;
use crate::exemplar::select_by::DECISIVE_MARGIN;
use crate::mesh::TriMesh;
use crate::methods::{FrameContext, FrameResult, Stat, StatsExt};
use crate::provenance::{SOURCE_OUTSIDE, SOURCE_UNCOVERED};
use crate::surface::SurfacePoint;

/// The patch id a texel's `source` names, when it names one.
fn patch_of(source: u32) -> Option<u32> {
    (source != SOURCE_OUTSIDE && source != SOURCE_UNCOVERED && source > 0).then(|| source - 1)
}

/// Covered atlas texels per exemplar; `exemplar_of(id)` is the exemplar
/// of patch `id` (unknown ids count for exemplar 0).
pub fn texels_per_exemplar(
    source: &[u32],
    count: usize,
    exemplar_of: impl Fn(u32) -> Option<u32>,
) -> Vec<u64> {
    let mut out = vec![0u64; count];
    for id in source.iter().filter_map(|&s| patch_of(s)) {
        if let Some(slot) = out.get_mut(exemplar_of(id).unwrap_or(0) as usize) {
            *slot += 1;
        }
    }
    out
}

/// The state agreement of one frame: over every covered texel, and over
/// the decisive ones only ([`crate::exemplar::select_by::Decisive`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Agreement {
    /// `None` without covered texels.
    pub all: Option<f64>,
    /// `None` without covered decisive texels (a frame whose state lies
    /// within the margin of a split everywhere).
    pub decisive: Option<f64>,
}

/// The share of covered texels of `atlas` (on `mesh`) whose shown
/// exemplar matches `by` where the texel lies; `None` without covered
/// texels or without the attribute on the mesh.
pub fn state_agreement(
    atlas: &Atlas,
    mesh: &TriMesh,
    by: &SelectBy,
    source: &[u32],
    exemplar_of: impl Fn(u32) -> Option<u32>,
) -> Option<f64> {
    agreement(atlas, mesh, by, source, exemplar_of, DECISIVE_MARGIN).all
}

/// [`state_agreement`] over every covered texel, and over the texels
/// whose attribute is decisive with a margin of `margin` of the ranges'
/// span ([`SelectBy::decisive`]): there the state has been past the split
/// long enough that the texture must have followed, so a lagging texture
/// shows there and not in the band around the split, where any method
/// lags for a few frames by design.
pub fn agreement(
    atlas: &Atlas,
    mesh: &TriMesh,
    by: &SelectBy,
    source: &[u32],
    exemplar_of: impl Fn(u32) -> Option<u32>,
    margin: f32,
) -> Agreement {
    let Some(values) = by.values(mesh) else {
        return Agreement::default();
    };
    let decisive = by.decisive(margin);
    let width = atlas.width as usize;
    // (covered, agreeing), over all texels and over the decisive ones.
    let (mut all, mut sure) = ((0u64, 0u64), (0u64, 0u64));
    for span in atlas.bands().iter().flat_map(|b| &b.spans) {
        let row = span.y as usize * width;
        for (x, bary) in atlas.span_barycentrics(span) {
            let Some(id) = source.get(row + x as usize).and_then(|&s| patch_of(s)) else {
                continue;
            };
            let at = SurfacePoint::new(span.triangle, bary);
            let value = SelectBy::value_at(values, mesh, at);
            let agrees = u64::from(by.matches(exemplar_of(id).unwrap_or(0), value));
            all = (all.0 + 1, all.1 + agrees);
            if decisive.holds(value) {
                sure = (sure.0 + 1, sure.1 + agrees);
            }
        }
    }
    let share = |(n, k): (u64, u64)| (n > 0).then(|| k as f64 / n as f64);
    Agreement {
        all: share(all),
        decisive: share(sure),
    }
}

/// Records the frame's state agreement under `by` in `result`'s
/// statistics ([`Stat::StateAgreement`], and
/// [`Stat::StateAgreementDecisive`] at [`DECISIVE_MARGIN`]), from the
/// sources it carries.
pub fn record_agreement(
    ctx: &FrameContext<'_>,
    by: &SelectBy,
    result: &mut FrameResult,
    exemplar_of: impl Fn(u32) -> Option<u32>,
) {
    let Some(source) = result.source.as_deref() else {
        return;
    };
    let a = agreement(
        ctx.atlas,
        ctx.mesh,
        by,
        source,
        exemplar_of,
        DECISIVE_MARGIN,
    );
    if let Some(share) = a.all {
        result.stats.set(Stat::StateAgreement, share);
    }
    if let Some(share) = a.decisive {
        result.stats.set(Stat::StateAgreementDecisive, share);
    }
}
