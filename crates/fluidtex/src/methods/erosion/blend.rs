//! The blended fill of the `blend-deformable` baseline (DESIGN §4): the
//! deformable patches of the erosion method, but every patch covering a
//! texel contributes, alpha-blended by its interpolated weight w_V (Eqs.
//! 1–3), instead of the topmost surviving one alone. This is the look of
//! the 2019 deformable-patch predecessor: no hard seams, but ghosts and a
//! loss of contrast wherever patches overlap (docs/evaluation.md: blending n layers
//! with weights w_i leaves ρ² = Σ w_i² of the exemplar's contrast).
//!
//! Patches are located exactly as in [`super::fill`] (same candidates, same
//! tolerance), so the two fills differ only in how the located layers are
//! combined.

use glam::Vec2;
use rayon::prelude::*;

use super::fill::{
    Candidates, FillBuffers, FillContext, UNCOVERED, Uncovered, patch_groups, walk_band,
};
use crate::atlas::Atlas;

/// Layers below this normalised weight are not counted as visible layers
/// (the ghost-fraction rule of docs/evaluation.md); they still contribute.
pub const VISIBLE_LAYER_WEIGHT: f32 = 0.05;

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
    let w = atlas.width as usize;
    let c = out.channels;
    let mut layers = vec![0u8; out.source.len()];
    let bands = atlas.bands();
    let Some(first) = bands.first() else {
        return BlendOutcome {
            uncovered: Vec::new(),
            layers,
            used: Vec::new(),
        };
    };
    let band_rows = (first.y1 - first.y0) as usize;
    let results: Vec<(Vec<Uncovered>, Vec<u32>)> = out
        .values
        .par_chunks_mut(band_rows * w * c)
        .zip(out.source.par_chunks_mut(band_rows * w))
        .zip(out.uv.par_chunks_mut(band_rows * w))
        .zip(layers.par_chunks_mut(band_rows * w))
        .zip(bands.par_iter())
        .map(|((((values, source), uvs), layers), band)| {
            let mut missing = Vec::new();
            let mut used = Vec::new();
            let mut found: Vec<(u32, Vec2, f32)> = Vec::new();
            let mut sample = vec![0.0f32; c];
            let base = band.y0 as usize * w;
            walk_band(ctx, atlas, candidates, band, |texel, cands| {
                let t = texel.t;
                found.clear();
                for (i, tris) in patch_groups(cands, texel.k) {
                    if let Some((uv, weight, _)) = ctx.locate(i, tris, texel.p, texel.n)
                        && weight > 0.0
                    {
                        found.push((i, uv, weight));
                    }
                }
                let total: f32 = found.iter().map(|l| l.2).sum();
                if found.is_empty() || total <= 0.0 {
                    source[t] = UNCOVERED;
                    missing.push(Uncovered {
                        texel: (base + t) as u32,
                        triangle: texel.triangle,
                        bary: texel.bary,
                    });
                    return;
                }
                let out = &mut values[t * c..(t + 1) * c];
                out.fill(0.0);
                let mut heaviest = found[0];
                let mut visible = 0u8;
                for &(i, uv, weight) in &found {
                    let share = weight / total;
                    ctx.exemplar_of(i).sample_all(uv.x, uv.y, &mut sample);
                    for (o, s) in out.iter_mut().zip(&sample) {
                        *o += share * s;
                    }
                    if share >= VISIBLE_LAYER_WEIGHT {
                        visible = visible.saturating_add(1);
                        used.push(ctx.patches[i as usize].id);
                    }
                    if weight > heaviest.2 {
                        heaviest = (i, uv, weight);
                    }
                }
                source[t] = ctx.patches[heaviest.0 as usize].id + 1;
                uvs[t] = heaviest.1;
                layers[t] = visible;
            });
            used.sort_unstable();
            used.dedup();
            (missing, used)
        })
        .collect();
    let mut uncovered = Vec::new();
    let mut used = Vec::new();
    for (m, u) in results {
        uncovered.extend(m);
        used.extend(u);
    }
    uncovered.sort_unstable_by_key(|u| u.texel);
    used.sort_unstable();
    used.dedup();
    BlendOutcome {
        uncovered,
        layers,
        used,
    }
}
