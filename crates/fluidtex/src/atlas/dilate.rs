//! Dilation: copying chart texels outward into the gutter, so that bilinear
//! filtering and mipmapping near a chart's border read the chart's own
//! colours instead of the background or a neighbouring chart.
//!
//! Every texel outside the charts within Euclidean distance `radius` of a
//! chart texel takes the value of the nearest chart texel (ties: smaller
//! row, then smaller column). Exact nearest neighbours are found per row
//! pair: within row y + dy the nearest chart texel to column x is at one end
//! of the chart run containing or adjacent to x, so a cursor per row walks
//! the runs once while x increases, and a texel costs one lookup per row
//! up to its nearest chart texel's row distance (rows are tried nearest
//! first), at most 2·radius + 1. Only texels within `radius` columns of a
//! run in a nearby row are visited.
//!
//! Sources are chart texels, which dilation never writes, so the result
//! does not depend on order. Work is split by bands: nearest sources are
//! found in parallel once per atlas (`DilationMap`, 8 bytes per gutter
//! texel), then each image's values are written band by band through
//! `par_chunks_mut` (groups of bands bound the memory of the staged
//! values).

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
    /// Marks each band's span texels in a bit mask (one row of `W/64` words
    /// per texel row) and reads the runs back from it, band by band in
    /// parallel: linear in spans and texel rows, no sorting.
    pub(crate) fn new(bands: &[Band], width: u32, height: u32) -> RowRuns {
        let words = (width as usize).div_ceil(64);
        let per_band: Vec<Vec<(u32, [u32; 2])>> = bands
            .par_iter()
            .map(|b| {
                let mut bits = vec![0u64; words * (b.y1 - b.y0) as usize];
                for s in &b.spans {
                    let row = &mut bits[(s.y - b.y0) as usize * words..][..words];
                    set_bits(row, s.x0 as usize, s.x1 as usize);
                }
                let mut runs = Vec::new();
                for (r, row) in bits.chunks_exact(words).enumerate() {
                    let y = b.y0 + r as u32;
                    let mut x = 0usize;
                    while let Some(start) = next_bit(row, x, true) {
                        let end = next_bit(row, start, false).unwrap_or(width as usize);
                        runs.push((y, [start as u32, end as u32]));
                        x = end;
                    }
                }
                runs
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

/// Where every gutter texel within `radius` of a chart takes its value
/// from: per band, (texel index within the band, global index of the
/// nearest chart texel). Found once per atlas and radius and reused by
/// every image dilated on that atlas (a frame's channels, its debug
/// colours and patch ids), since only the values differ.
#[derive(Clone)]
pub(crate) struct DilationMap {
    pub(crate) radius: u32,
    per_band: Vec<Vec<(u32, u32)>>,
}

impl std::fmt::Debug for DilationMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let texels: usize = self.per_band.iter().map(Vec::len).sum();
        write!(
            f,
            "DilationMap {{ radius: {}, texels: {texels} }}",
            self.radius
        )
    }
}

impl DilationMap {
    /// The map of `bands` (an atlas of `width × height`, at most
    /// 16384², so a texel index fits `u32`).
    pub(crate) fn new(bands: &[Band], width: u32, height: u32, radius: u32) -> DilationMap {
        if radius == 0 || bands.is_empty() {
            return DilationMap {
                radius,
                per_band: Vec::new(),
            };
        }
        let rows = RowRuns::new(bands, width, height);
        let per_band = bands
            .par_iter()
            .map(|b| sources_in_band(&rows, b.y0, b.y1, width, height, radius))
            .collect();
        DilationMap { radius, per_band }
    }
}

/// See the module doc. `texture` has the atlas's size (checked by the caller).
pub(crate) fn dilate(map: &DilationMap, width: u32, texture: &mut Texture) {
    let channels = texture.channels;
    dilate_values(map, width, &mut texture.data, channels);
}

/// [`dilate`] over any per-texel values, `channels` interleaved per texel
/// (patch ids dilate as `u32`, without a float copy). `data` holds
/// `width × height × channels` values (checked by the caller).
pub(crate) fn dilate_values<T: Copy + Send + Sync>(
    map: &DilationMap,
    width: u32,
    data: &mut [T],
    channels: usize,
) {
    let band_len = BAND_HEIGHT as usize * width as usize * channels;
    for (g, staged) in map.per_band.chunks(GROUP).enumerate() {
        let src_data = &*data;
        let values: Vec<Vec<T>> = staged
            .par_iter()
            .map(|entries| {
                let mut v = Vec::with_capacity(entries.len() * channels);
                for &(_, src) in entries {
                    let src = src as usize;
                    v.extend_from_slice(&src_data[src * channels..(src + 1) * channels]);
                }
                v
            })
            .collect();
        let first = g * GROUP * band_len;
        let last = (first + staged.len() * band_len).min(data.len());
        data[first..last]
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

/// Sets bits `x0..x1` of a row mask.
fn set_bits(row: &mut [u64], x0: usize, x1: usize) {
    let mut x = x0;
    while x < x1 {
        let (w, b) = (x / 64, x % 64);
        let n = (64 - b).min(x1 - x);
        let mask = if n == 64 {
            u64::MAX
        } else {
            ((1u64 << n) - 1) << b
        };
        row[w] |= mask;
        x += n;
    }
}

/// First position ≥ `from` whose bit equals `value`, if any.
fn next_bit(row: &[u64], from: usize, value: bool) -> Option<usize> {
    let mut w = from / 64;
    if w >= row.len() {
        return None;
    }
    let flip = if value { 0 } else { u64::MAX };
    let mut word = (row[w] ^ flip) & (u64::MAX << (from % 64));
    loop {
        if word != 0 {
            return Some(w * 64 + word.trailing_zeros() as usize);
        }
        w += 1;
        if w >= row.len() {
            return None;
        }
        word = row[w] ^ flip;
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
) -> Vec<(u32, u32)> {
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
                // Rows nearest first (dy = 0, −1, +1, −2, ...): once dy²
                // exceeds the best squared distance no farther row can
                // beat or tie it, and its cursor catches up when next read.
                for step in 0..=2 * r {
                    let dy = if step % 2 == 1 {
                        -(step + 1) / 2
                    } else {
                        step / 2
                    };
                    if best.is_some_and(|b| dy * dy > b.0) {
                        break;
                    }
                    let yy = y as i64 + dy;
                    if yy < ya || yy > yb {
                        continue;
                    }
                    let runs = rows.row(yy as u32);
                    let cur = &mut cursor[(yy - ya) as usize];
                    while *cur < runs.len() && (runs[*cur][1] as i64) <= x {
                        *cur += 1;
                    }
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
                        (sy * width as i64 + sx) as u32,
                    ));
                }
            }
            x_done = x_done.max(c1);
        }
    }
    out
}
