//! The blended fill of the `blend-deformable` baseline (docs/design.md,
//! *Baselines*): the deformable patches of the erosion method, but every
//! patch covering a texel contributes, alpha-blended by its interpolated
//! weight w_V (Eqs. 1–3), instead of the topmost surviving one alone. This
//! is the look of the 2019 deformable-patch predecessor: no hard seams, but
//! ghosts and a loss of contrast wherever patches overlap
//! (docs/evaluation.md: blending n layers with weights w_i leaves
//! ρ² = Σ w_i² of the exemplar's contrast).
//!
//! Patches are located exactly as in [`super::fill`] (same candidates, same
//! tolerance), so the two fills differ only in how the located layers are
//! combined.

use glam::Vec2;

use super::fill::{
    Candidates, FillBuffers, FillContext, UNCOVERED, Uncovered, patch_groups, walk_band,
};
use crate::atlas::Atlas;
use crate::methods::lapped::{BandResult, BandTexel, TexelRows, fill_bands};

pub use crate::methods::lapped::VISIBLE_LAYER_WEIGHT;

/// What the blended fill produced besides the buffers.
pub struct BlendOutcome {
    /// Texels no patch reached with a positive weight, in texel order.
    pub uncovered: Vec<Uncovered>,
    /// Per texel, the number of layers of normalised weight ≥
    /// [`VISIBLE_LAYER_WEIGHT`] (0 outside charts and where uncovered).
    pub layers: Vec<u8>,
    /// Ids of the patches that contributed a visible layer somewhere,
    /// sorted, without repeats.
    pub used: Vec<u32>,
}

/// Fills every chart texel of `atlas` with the weight-normalised blend of
/// every patch that covers it. `out.source` and `out.uv` get the heaviest
/// layer (for the patch view and the provenance metrics).
pub fn fill(
    ctx: &FillContext<'_>,
    atlas: &Atlas,
    candidates: &Candidates,
    out: &mut FillBuffers,
) -> BlendOutcome {
    let mut layers = vec![0u8; out.source.len()];
    let buffers = TexelRows {
        layers: &mut layers,
        ..out.rows()
    };
    let merged = fill_bands(atlas, buffers, |band, mut rows| {
        let mut result = BandResult::default();
        let mut found: Vec<(u32, Vec2, f32)> = Vec::new();
        let mut sample = vec![0.0f32; rows.channels];
        walk_band(ctx, atlas, candidates, band, |texel, cands| {
            found.clear();
            for (i, tris) in patch_groups(cands, texel.k) {
                if let Some((uv, weight, _)) = ctx.locate(i, tris, texel.p, texel.n)
                    && weight > 0.0
                {
                    found.push((i, uv, weight));
                }
            }
            blend_texel(ctx, texel, &found, &mut rows, &mut sample, &mut result);
        });
        result.used.sort_unstable();
        result.used.dedup();
        result
    });
    BlendOutcome {
        uncovered: merged.uncovered,
        layers,
        used: merged.used,
    }
}

/// Writes the weight-normalised blend of the `found` layers (patch index,
/// uv, weight) at `texel`, or records it as uncovered when none weighs.
fn blend_texel(
    ctx: &FillContext<'_>,
    texel: &BandTexel,
    found: &[(u32, Vec2, f32)],
    rows: &mut TexelRows<'_>,
    sample: &mut [f32],
    result: &mut BandResult<Uncovered>,
) {
    let t = texel.t;
    let total: f32 = found.iter().map(|l| l.2).sum();
    if found.is_empty() || total <= 0.0 {
        rows.source[t] = UNCOVERED;
        result.uncovered.push(Uncovered {
            texel: (rows.base + t) as u32,
            triangle: texel.triangle,
            bary: texel.bary,
        });
        return;
    }
    let out = rows.values_of(t);
    out.fill(0.0);
    let mut heaviest = found[0];
    let mut visible = 0u8;
    for &(i, uv, weight) in found {
        let share = weight / total;
        ctx.exemplar_of(i).sample_all(uv.x, uv.y, sample);
        for (o, s) in out.iter_mut().zip(sample.iter()) {
            *o += share * s;
        }
        if share >= VISIBLE_LAYER_WEIGHT {
            visible = visible.saturating_add(1);
            result.used.push(ctx.patches[i as usize].id);
        }
        if weight > heaviest.2 {
            heaviest = (i, uv, weight);
        }
    }
    rows.source[t] = ctx.patches[heaviest.0 as usize].id + 1;
    rows.uv[t] = heaviest.1;
    rows.layers[t] = visible;
}
