//! Per-pixel provenance of a render: which patch and which exemplar point
//! each pixel shows, read from the atlas texels around the pixel's atlas uv.
//!
//! The flow metric fits the exemplar uv as a smooth function of pixel
//! position, so a nearest-texel lookup (uv constant over each texel's
//! footprint, a staircase when a texel covers several pixels) would bias
//! it. Instead the source is that of the nearest chart texel, and the uv is
//! the bilinear blend of the four surrounding texels that share that
//! source, each taken at the periodic image nearest the nearest texel's uv
//! (methods may wrap uv into [0, 1)).

use glam::Vec2;
use rayon::prelude::*;

use crate::atlas::Atlas;
use crate::metrics::{SOURCE_OUTSIDE, SOURCE_UNCOVERED};
use crate::render::{BACKGROUND, GBuffer};

/// Source and exemplar uv per pixel ([`SOURCE_OUTSIDE`] and NaN on the
/// background and where no chart texel is near).
pub fn pixel_provenance(
    gbuffer: &GBuffer,
    atlas: &Atlas,
    source: &[u32],
    uv: &[Vec2],
) -> (Vec<u32>, Vec<Vec2>) {
    let (aw, ah) = (atlas.width as i64, atlas.height as i64);
    let mesh = &atlas.uv_mesh;
    let at = |x: i64, y: i64| -> Option<usize> {
        (x >= 0 && y >= 0 && x < aw && y < ah).then(|| (y * aw + x) as usize)
    };
    (0..gbuffer.triangle.len())
        .into_par_iter()
        .map(|i| {
            let none = (SOURCE_OUTSIDE, Vec2::NAN);
            let t = gbuffer.triangle[i] as usize;
            if gbuffer.triangle[i] == BACKGROUND || t >= mesh.triangles.len() {
                return none;
            }
            let b = gbuffer.bary[i];
            let [c0, c1, c2] = mesh.triangles[t].map(|v| mesh.uvs.get(v as usize).copied());
            let (Some(c0), Some(c1), Some(c2)) = (c0, c1, c2) else {
                return none;
            };
            let a = c0 * b[0] + c1 * b[1] + c2 * b[2];
            let x = a.x * aw as f32 - 0.5;
            let y = a.y * ah as f32 - 0.5;
            let (x0, y0) = (x.floor() as i64, y.floor() as i64);
            let (fx, fy) = (x - x0 as f32, y - y0 as f32);
            let taps = [
                (x0, y0, (1.0 - fx) * (1.0 - fy)),
                (x0 + 1, y0, fx * (1.0 - fy)),
                (x0, y0 + 1, (1.0 - fx) * fy),
                (x0 + 1, y0 + 1, fx * fy),
            ];
            // The nearest tap with a source decides; an uncovered texel
            // is a source too (a hole the coverage metric reports).
            let mut best: Option<(f32, usize)> = None;
            for &(tx, ty, _) in &taps {
                if let Some(j) = at(tx, ty)
                    && source.get(j).is_some_and(|&s| s != SOURCE_OUTSIDE)
                {
                    let d = (tx as f32 - x).powi(2) + (ty as f32 - y).powi(2);
                    if best.is_none_or(|(bd, _)| d < bd) {
                        best = Some((d, j));
                    }
                }
            }
            let Some((_, j)) = best else {
                return none;
            };
            let s = source[j];
            let base = uv.get(j).copied().unwrap_or(Vec2::NAN);
            if s == SOURCE_UNCOVERED || !base.is_finite() {
                return (s, Vec2::NAN);
            }
            let mut sum = Vec2::ZERO;
            let mut weight = 0.0f32;
            for &(tx, ty, w) in &taps {
                if let Some(k) = at(tx, ty)
                    && source.get(k) == Some(&s)
                    && let Some(u) = uv.get(k).filter(|u| u.is_finite())
                {
                    let d = *u - base;
                    sum += (base + d - d.round()) * w;
                    weight += w;
                }
            }
            if weight > 0.0 {
                (s, sum / weight)
            } else {
                (s, base)
            }
        })
        .unzip()
}
