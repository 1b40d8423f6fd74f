//! Dilation: copying chart texels outward into the gutter, so that bilinear
//! filtering and mipmapping near a chart's border read the chart's own
//! colours instead of the background or a neighbouring chart.
//!
//! Every texel outside the charts within Euclidean distance `radius` of a
//! chart texel takes the value of the nearest chart texel (ties: smaller
//! row, then smaller column). Exact nearest neighbours are found per row
//! pair: within row y + dy the nearest chart texel to column x is at one end
//! of the chart run containing or adjacent to x, so a cursor per row walks
//! the runs once while x increases, and a texel costs 2·radius + 1 lookups.
//! Only texels within `radius` columns of a run in a nearby row are visited.
//!
//! Sources are chart texels, which dilation never writes, so the result
//! does not depend on order. Work is split by bands: nearest sources are
//! found in parallel with the texture borrowed immutably, then the values
//! are written band by band through `par_chunks_mut` (groups of bands bound
//! the memory of the staged values).

use rayon::prelude::*;

use super::{BAND_HEIGHT, Band};
use crate::texture::Texture;

/// Bands processed per group (staged values ≈ gutter texels of
/// `GROUP × BAND_HEIGHT` rows).
const GROUP: usize = 32;

/// Chart runs `[x0, x1)` per row, merged from the spans (compressed rows).
pub(crate) struct RowRuns {
    start: Vec<u32>,
    runs: Vec<[u32; 2]>,
}

impl RowRuns {
    pub(crate) fn new(bands: &[Band], height: u32) -> RowRuns {
        let per_band: Vec<Vec<(u32, [u32; 2])>> = bands
            .par_iter()
            .map(|b| {
                let mut s: Vec<(u32, [u32; 2])> =
                    b.spans.iter().map(|s| (s.y, [s.x0, s.x1])).collect();
                s.sort_unstable();
                let mut merged: Vec<(u32, [u32; 2])> = Vec::with_capacity(s.len());
                for (y, r) in s {
                    match merged.last_mut() {
                        Some((ly, lr)) if *ly == y && lr[1] >= r[0] => lr[1] = lr[1].max(r[1]),
                        _ => merged.push((y, r)),
                    }
                }
                merged
            })
            .collect();
        let mut start = vec![0u32; height as usize + 1];
        let mut runs = Vec::new();
        for (y, r) in per_band.into_iter().flatten() {
            start[y as usize + 1] += 1;
            runs.push(r);
        }
        for y in 0..height as usize {
            start[y + 1] += start[y];
        }
        RowRuns { start, runs }
    }

    #[inline]
    pub(crate) fn row(&self, y: u32) -> &[[u32; 2]] {
        &self.runs[self.start[y as usize] as usize..self.start[y as usize + 1] as usize]
    }
}

/// See the module doc. `texture` has the atlas's size (checked by the caller).
pub(crate) fn dilate(bands: &[Band], width: u32, height: u32, texture: &mut Texture, radius: u32) {
    if radius == 0 || bands.is_empty() {
        return;
    }
    let rows = RowRuns::new(bands, height);
    let channels = texture.channels;
    let band_len = BAND_HEIGHT as usize * width as usize * channels;
    for (g, group) in bands.chunks(GROUP).enumerate() {
        let staged: Vec<Vec<(u32, usize)>> = group
            .par_iter()
            .map(|b| sources_in_band(&rows, b.y0, b.y1, width, height, radius))
            .collect();
        let src_data = &texture.data;
        let values: Vec<Vec<f32>> = staged
            .par_iter()
            .map(|entries| {
                let mut v = Vec::with_capacity(entries.len() * channels);
                for &(_, src) in entries {
                    v.extend_from_slice(&src_data[src * channels..(src + 1) * channels]);
                }
                v
            })
            .collect();
        let first = g * GROUP * band_len;
        let last = (first + group.len() * band_len).min(texture.data.len());
        texture.data[first..last]
            .par_chunks_mut(band_len)
            .zip(staged.par_iter().zip(values.par_iter()))
            .for_each(|(chunk, (entries, vals))| {
                for (k, &(dst, _)) in entries.iter().enumerate() {
                    let d = dst as usize * channels;
                    chunk[d..d + channels].copy_from_slice(&vals[k * channels..(k + 1) * channels]);
                }
            });
    }
}

/// For rows `y0..y1`: (texel index within the band, global source texel
/// index) of every texel to fill.
fn sources_in_band(
    rows: &RowRuns,
    y0: u32,
    y1: u32,
    width: u32,
    height: u32,
    radius: u32,
) -> Vec<(u32, usize)> {
    let r = radius as i64;
    let r2 = r * r;
    let mut out = Vec::new();
    let mut candidates: Vec<(i64, i64)> = Vec::new();
    for y in y0..y1 {
        let ya = (y as i64 - r).max(0);
        let yb = (y as i64 + r).min(height as i64 - 1);
        candidates.clear();
        for yy in ya..=yb {
            for run in rows.row(yy as u32) {
                candidates.push((
                    (run[0] as i64 - r).max(0),
                    (run[1] as i64 + r).min(width as i64),
                ));
            }
        }
        if candidates.is_empty() {
            continue;
        }
        candidates.sort_unstable();
        // Cursor per neighbouring row: first run with x1 > x.
        let mut cursor = vec![0usize; (yb - ya + 1) as usize];
        let own = rows.row(y);
        let mut own_i = 0;
        let mut x_done = 0i64;
        for &(c0, c1) in &candidates {
            for x in c0.max(x_done)..c1 {
                while own_i < own.len() && (own[own_i][1] as i64) <= x {
                    own_i += 1;
                }
                if own_i < own.len() && own[own_i][0] as i64 <= x {
                    continue; // a chart texel
                }
                let mut best: Option<(i64, i64, i64)> = None;
                for yy in ya..=yb {
                    let runs = rows.row(yy as u32);
                    let cur = &mut cursor[(yy - ya) as usize];
                    while *cur < runs.len() && (runs[*cur][1] as i64) <= x {
                        *cur += 1;
                    }
                    let dy = yy - y as i64;
                    let mut consider = |xs: i64| {
                        let key = ((xs - x) * (xs - x) + dy * dy, yy, xs);
                        if key.0 <= r2 && best.is_none_or(|b| key < b) {
                            best = Some(key);
                        }
                    };
                    if *cur < runs.len() {
                        consider((runs[*cur][0] as i64).max(x));
                    }
                    if *cur > 0 {
                        consider(runs[*cur - 1][1] as i64 - 1);
                    }
                }
                if let Some((_, sy, sx)) = best {
                    out.push((
                        ((y - y0) as i64 * width as i64 + x) as u32,
                        (sy * width as i64 + sx) as usize,
                    ));
                }
            }
            x_done = x_done.max(c1);
        }
    }
    out
}
