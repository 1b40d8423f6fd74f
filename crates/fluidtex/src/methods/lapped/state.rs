//! What the lapped methods measure of a texture that follows the fluid's
//! state ([`crate::exemplar::SelectBy`]): per exemplar, the atlas texels it
//! shows, and the *state agreement*, the share of covered texels whose
//! shown exemplar matches the selecting attribute at the texel's surface
//! point. Both read the per-texel source (patch id + 1) that erosion and
//! lapped-rigid write alike, so the two methods count the same way.

use crate::atlas::Atlas;
use crate::exemplar::SelectBy;
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
    let values = by.values(mesh)?;
    let width = atlas.width as usize;
    let (mut covered, mut agree) = (0u64, 0u64);
    for span in atlas.bands().iter().flat_map(|b| &b.spans) {
        let row = span.y as usize * width;
        for (x, bary) in atlas.span_barycentrics(span) {
            let Some(id) = source.get(row + x as usize).and_then(|&s| patch_of(s)) else {
                continue;
            };
            covered += 1;
            let at = SurfacePoint::new(span.triangle, bary);
            let value = SelectBy::value_at(values, mesh, at);
            if by.matches(exemplar_of(id).unwrap_or(0), value) {
                agree += 1;
            }
        }
    }
    (covered > 0).then(|| agree as f64 / covered as f64)
}

/// Records the frame's state agreement under `by` in `result`'s
/// statistics ([`Stat::StateAgreement`]), from the sources it carries.
pub fn record_agreement(
    ctx: &FrameContext<'_>,
    by: &SelectBy,
    result: &mut FrameResult,
    exemplar_of: impl Fn(u32) -> Option<u32>,
) {
    let Some(source) = result.source.as_deref() else {
        return;
    };
    if let Some(share) = state_agreement(ctx.atlas, ctx.mesh, by, source, exemplar_of) {
        result.stats.set(Stat::StateAgreement, share);
    }
}
