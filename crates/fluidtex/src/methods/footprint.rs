//! Footprint filtering: a post-pass over a lapped fill that re-reads each
//! covered texel's exemplar channels at the mip level of its uv footprint
//! ([`Exemplar::sample_all_lod`]), so that an exemplar shown minified is
//! averaged over what the texel covers instead of point-sampled.
//!
//! **Footprint.** A texel's footprint is estimated from finite differences
//! of the patch uv to its atlas neighbours, like a GPU's quad derivatives,
//! but only to neighbours with the *same source*: across a patch border the
//! uv jumps to another patch's space and means nothing. Per axis the
//! forward and the backward neighbour are both tried and the shorter
//! difference is kept: two atlas neighbours in different charts can share
//! a patch yet lie far apart on the surface (a chart seam), and that jump
//! is always the longer one. An axis with no such neighbour takes the other
//! axis' length; a texel alone in its patch keeps level 0. Lengths are in
//! level-0 exemplar texels (u scaled by the width, v by the height) and
//! `lod = log2(max(|∂uv/∂x|, |∂uv/∂y|))`, the isotropic choice of GPU
//! trilinear filtering: under anisotropic stretch the short axis is
//! blurred more than it needs.
//!
//! Magnified texels (`lod` ≤ 0) keep the fill's bilinear value untouched,
//! so an exemplar shown at or above its resolution gives the same atlas as
//! without the pass. Bands of rows are processed in parallel, each writing
//! only its own rows from read-only uv and sources, tile by tile (for cache
//! reuse; a texel's result does not depend on the visiting order):
//! bit-identical for any thread count.

use glam::Vec2;
use rayon::prelude::*;

use super::erosion::fill::{FillBuffers, OUTSIDE, UNCOVERED};
use crate::exemplar::{Exemplar, ExemplarFilter};

/// Texels are visited in tiles of this many rows (a band per task) ...
const TILE_ROWS: usize = 16;
/// ... and this many columns: a tile's texels lie on a few fluid
/// triangles and read a few small regions of the exemplar, which stay in
/// cache while the tile's rows revisit them; a whole atlas row between two
/// visits of the same region would have evicted them.
const TILE_COLUMNS: usize = 64;

/// Re-samples every covered texel of `out` at the level of its uv
/// footprint when `exemplar.filter` is [`ExemplarFilter::Trilinear`], and
/// returns the level per texel (≥ 0; NaN where the texel has no source).
/// Leaves `out` as it is and returns `None` for
/// [`ExemplarFilter::Unfiltered`].
pub fn apply_footprint_filtering(out: &mut FillBuffers, exemplar: &Exemplar) -> Option<Vec<f32>> {
    apply_footprint_filtering_by(out, exemplar.filter, Levels::Keep, |_| exemplar)
}

/// Whether the footprint pass returns the level of every texel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Levels {
    /// An atlas-sized buffer of levels, for whoever reads them (an
    /// evaluation, contrast tone matching).
    Keep,
    /// Each tile's levels in scratch rows, used and dropped: a `run` reads
    /// no level, and the buffer (151 MB at 6144²) was held next to the
    /// values, the uv and the ids at the frame's peak of memory.
    Drop,
}

/// [`apply_footprint_filtering`] where texels show different exemplars
/// (several exemplars per surface): `exemplar_of(source)` is the exemplar
/// of a texel's source (patch id + 1, never outside or uncovered); its size
/// scales the footprint and its pyramid is read. `filter` applies to all.
/// With [`Levels::Drop`] the values are the same and `None` is returned.
pub fn apply_footprint_filtering_by<'e>(
    out: &mut FillBuffers,
    filter: ExemplarFilter,
    levels: Levels,
    exemplar_of: impl Fn(u32) -> &'e Exemplar + Sync,
) -> Option<Vec<f32>> {
    if filter == ExemplarFilter::Unfiltered {
        return None;
    }
    let FillBuffers {
        width,
        height,
        channels,
        values,
        source,
        uv,
        ..
    } = out;
    let (w, c) = (*width as usize, *channels);
    let n = w * *height as usize;
    if n == 0 || c == 0 || source.len() != n || uv.len() != n || values.len() != n * c {
        return (levels == Levels::Keep).then(|| vec![f32::NAN; n]);
    }
    // Zeroed pages the kernel maps on first touch: each tile writes every
    // level of its own texels below (NaN where there is none), on every
    // core and while they are in cache, instead of a serial pass over the
    // whole atlas first.
    let mut lods = match levels {
        Levels::Keep => vec![0.0f32; n],
        Levels::Drop => Vec::new(),
    };
    let bands: Vec<Option<&mut [f32]>> = match levels {
        Levels::Keep => lods.chunks_mut(TILE_ROWS * w).map(Some).collect(),
        Levels::Drop => (0..n.div_ceil(TILE_ROWS * w)).map(|_| None).collect(),
    };
    let (source, uv) = (source.as_slice(), uv.as_slice());
    let h = n / w;
    values
        .par_chunks_mut(TILE_ROWS * w * c)
        .zip(bands)
        .enumerate()
        .for_each(|(band, (values, band_lods))| {
            let rows = values.len() / (w * c);
            let mut steps = TileSteps::default();
            // Levels go to the band's rows of the atlas-sized buffer (row
            // stride the atlas width), or to one tile's scratch rows.
            let mut scratch = Vec::new();
            let (lods, stride, tiled) = match band_lods {
                Some(l) => (l, w, false),
                None => {
                    scratch.resize(rows * TILE_COLUMNS, 0.0f32);
                    (scratch.as_mut_slice(), TILE_COLUMNS, true)
                }
            };
            for x0 in (0..w).step_by(TILE_COLUMNS) {
                let x1 = (x0 + TILE_COLUMNS).min(w);
                let tile = Tile {
                    width: w,
                    height: h,
                    x0,
                    x1,
                    y0: band * TILE_ROWS,
                    rows,
                    stride,
                    x_base: if tiled { x0 } else { 0 },
                };
                tile_lods(source, uv, &tile, &exemplar_of, &mut steps, lods);
                let texels = TileTexels {
                    tile: &tile,
                    channels: c,
                    source,
                    uv,
                    lods,
                };
                match c {
                    1 => sample_tile::<1>(&texels, values, &exemplar_of),
                    2 => sample_tile::<2>(&texels, values, &exemplar_of),
                    3 => sample_tile::<3>(&texels, values, &exemplar_of),
                    4 => sample_tile::<4>(&texels, values, &exemplar_of),
                    _ => sample_tile::<0>(&texels, values, &exemplar_of),
                }
            }
        });
    (levels == Levels::Keep).then_some(lods)
}

/// What [`sample_tile`] reads: the tile, the values a texel, the atlas'
/// sources and uv, and the tile's levels as [`tile_lods`] wrote them.
struct TileTexels<'a> {
    tile: &'a Tile,
    channels: usize,
    source: &'a [u32],
    uv: &'a [Vec2],
    lods: &'a [f32],
}

/// Re-samples every covered texel of a tile into `values` (its band's
/// rows, `channels` values a texel) at the texel's level. Every covered texel:
/// the fill may have deferred its values to this pass; at lod 0 this is
/// the fill's own bilinear read, bit for bit.
///
/// `N` is the channel count (0: any) so that each count gets a loop with
/// the whole lookup inlined ([`Exemplar::sample_all_lod`] per texel was a
/// call that dispatched on the count every time); a texel whose exemplar
/// has another count takes the general lookup, with the same values.
fn sample_tile<'e, const N: usize>(
    texels: &TileTexels,
    values: &mut [f32],
    exemplar_of: &impl Fn(u32) -> &'e Exemplar,
) {
    let TileTexels {
        tile,
        channels: c,
        source,
        uv,
        lods,
    } = *texels;
    let w = tile.width;
    for r in 0..tile.rows {
        for x in tile.x0..tile.x1 {
            let lod = lods[r * tile.stride + x - tile.x_base];
            if lod.is_nan() {
                continue;
            }
            let t = r * w + x;
            let at = (tile.y0 + r) * w + x;
            let (e, p) = (exemplar_of(source[at]), uv[at]);
            let out = &mut values[t * c..(t + 1) * c];
            // No exemplar has 0 channels: N = 0 always takes the general
            // lookup.
            match e.sample_lod_fixed::<N>(p.x, p.y, lod) {
                Some(value) => {
                    for (o, v) in out.iter_mut().zip(value) {
                        *o = v;
                    }
                }
                None => e.sample_all_lod(p.x, p.y, lod, out),
            }
        }
    }
}

/// The mip level (≥ 0) of texel `(x, y)` of a `width`-wide atlas from its
/// uv differences to same-source neighbours (module doc), with uv scaled to
/// exemplar texels by `texels`. `None` for a texel without a source or a
/// finite uv. The pass computes the same levels tile by tile, sharing each
/// neighbour difference between the two texels it joins; this per-texel
/// form is the definition the tests hold it to.
pub fn texel_lod(
    source: &[u32],
    uv: &[Vec2],
    width: usize,
    x: usize,
    y: usize,
    texels: Vec2,
) -> Option<f32> {
    let t = y * width + x;
    let s = *source.get(t)?;
    let p = *uv.get(t)?;
    if s == OUTSIDE || s == UNCOVERED || !p.is_finite() {
        return None;
    }
    // Squared lengths until the one square root at the end: the square
    // root is monotone and correctly rounded, so the min and max below pick
    // the same lengths, bit for bit, at a quarter of the roots.
    let step = |q: Option<usize>| {
        let q = q?;
        let o = *uv.get(q)?;
        (source.get(q) == Some(&s) && o.is_finite()).then(|| ((o - p) * texels).length_squared())
    };
    let axis =
        |forward: Option<usize>, backward: Option<usize>| match (step(forward), step(backward)) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
    let across = axis((x + 1 < width).then(|| t + 1), (x > 0).then(|| t - 1));
    let down = axis(Some(t + width), y.checked_sub(1).map(|_| t - width));
    let longest = match (across, down) {
        (Some(a), Some(b)) => a.max(b),
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => return Some(0.0),
    };
    Some(level(longest))
}

/// The mip level of a footprint whose longest step is `squared` (squared
/// length in exemplar texels; NaN when there is none: level 0).
#[inline]
fn level(squared: f32) -> f32 {
    let longest = squared.sqrt();
    // Below one texel (and for zero-length steps, log2 = −inf) the
    // exemplar is magnified: level 0.
    if longest > 1.0 { longest.log2() } else { 0.0 }
}

/// The texels of one tile: columns `x0..x1` of rows `y0..y0 + rows` of a
/// `width × height` atlas.
struct Tile {
    width: usize,
    height: usize,
    x0: usize,
    x1: usize,
    y0: usize,
    rows: usize,
    /// Where the tile's levels go: row `r` at `r * stride`, column `x` at
    /// `x − x_base` in it.
    stride: usize,
    x_base: usize,
}

/// Scratch rows of [`tile_lods`], kept across the tiles of a band.
#[derive(Default)]
struct TileSteps {
    /// `right[i]`: the step between columns `x0 + i − 1` and `x0 + i` of the
    /// current row.
    right: Vec<f32>,
    /// `up[i]` / `down[i]`: the steps between column `x0 + i` of the current
    /// row and the row above / below.
    up: Vec<f32>,
    down: Vec<f32>,
}

/// [`texel_lod`] of every texel of `tile`, written into `lods` (rows from
/// `tile.y0` as the tile places them; NaN where
/// [`texel_lod`] is `None`), the
/// same values bit for bit. Each step between two neighbours is computed
/// once and read by both, where [`texel_lod`] computes it from either side
/// (the squared length of the negated difference is the same float): half
/// the neighbour reads and differences of the per-texel function, which
/// was a quarter of this pass's time.
fn tile_lods<'e>(
    source: &[u32],
    uv: &[Vec2],
    tile: &Tile,
    exemplar_of: &impl Fn(u32) -> &'e Exemplar,
    steps: &mut TileSteps,
    lods: &mut [f32],
) {
    let w = tile.width;
    let cols = tile.x1 - tile.x0;
    // The squared step from texel a to texel b in a's exemplar texels when
    // both show the same source at a finite uv; NaN otherwise (NaN is what
    // f32::min and f32::max pass over, as `texel_lod` passes over None).
    let step = |a: usize, b: usize| -> f32 {
        let (Some(&s), Some(&sb), Some(&p), Some(&q)) =
            (source.get(a), source.get(b), uv.get(a), uv.get(b))
        else {
            return f32::NAN;
        };
        if s != sb || s == OUTSIDE || s == UNCOVERED || !p.is_finite() || !q.is_finite() {
            return f32::NAN;
        }
        let (ew, eh) = exemplar_of(s).size();
        ((q - p) * Vec2::new(ew as f32, eh as f32)).length_squared()
    };
    let TileSteps { right, up, down } = steps;
    right.resize(cols + 1, f32::NAN);
    up.resize(cols, f32::NAN);
    down.resize(cols, f32::NAN);
    for r in 0..tile.rows {
        let y = tile.y0 + r;
        let row = y * w;
        if r == 0 {
            for (i, u) in up.iter_mut().enumerate() {
                let t = row + tile.x0 + i;
                *u = if y > 0 { step(t - w, t) } else { f32::NAN };
            }
        } else {
            std::mem::swap(up, down);
        }
        for (i, d) in down.iter_mut().enumerate() {
            let t = row + tile.x0 + i;
            *d = if y + 1 < tile.height {
                step(t, t + w)
            } else {
                f32::NAN
            };
        }
        for (i, s) in right.iter_mut().enumerate() {
            let x = tile.x0 + i;
            *s = if x > 0 && x < w {
                step(row + x - 1, row + x)
            } else {
                f32::NAN
            };
        }
        for i in 0..cols {
            let t = row + tile.x0 + i;
            let out = &mut lods[r * tile.stride + tile.x0 - tile.x_base + i];
            let (s, p) = (source.get(t).copied(), uv.get(t).copied());
            if s.is_none_or(|s| s == OUTSIDE || s == UNCOVERED) || p.is_none_or(|p| !p.is_finite())
            {
                *out = f32::NAN;
                continue;
            }
            // texel_lod's axis(forward, backward) and longest, in its order.
            let across = right[i + 1].min(right[i]);
            let along = down[i].min(up[i]);
            *out = level(across.max(along));
        }
    }
}

#[cfg(test)]
mod tests;
