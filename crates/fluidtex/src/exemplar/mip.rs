//! Mip pyramids of the exemplar, so that an exemplar shown minified (several
//! exemplar texels per atlas texel) is averaged over the texel's footprint
//! instead of point-sampled into per-texel noise that changes every frame.
//!
//! **Levels.** Level 0 is the exemplar. Level k + 1 halves each axis of
//! level k (rounding down, never below 1) and averages it with an
//! area-weighted box: coarse texel j of an axis of n fine texels shrunk to
//! m covers the fine interval `[j n/m, (j + 1) n/m)` and every fine texel
//! counts by its overlap. For even sizes this is the usual 2×2 box; for odd
//! sizes it still averages every fine texel with the same total weight, so
//! every level has exactly the exemplar's mean (up to float rounding), and
//! its texel centres stay aligned with the fine ones (the convention of
//! [`crate::texture`]: centres at +0.5 in each level's own texels). The
//! intervals partition the image, so no texel is read across a border:
//! every level tiles exactly as the exemplar does, and lookups into every
//! level wrap ([`crate::texture::Wrap::Repeat`]) like level 0.
//!
//! **Why not the `image` crate's resize.** `image::imageops::resize` clamps
//! at the borders (a tiling exemplar would get a seam at every coarse
//! level) and works on images of at most four channels, while the lookup
//! reads one interleaved buffer of every channel (colour and extras). The
//! box above is a few lines and exact for tiling.
//!
//! **Cost.** Built once per exemplar ([`super::Exemplar::new`]), in
//! parallel by output rows; ≈ 1/3 more memory than the packed exemplar.
//! The per-texel lookup [`super::Exemplar::sample_all_lod`] is two bilinear
//! lookups whatever the exemplar size, so the exemplar's resolution does
//! not change the cost per atlas texel.

use rayon::prelude::*;

use super::sampling::Lattice;
use crate::texture::Texture;

/// One coarse level of an interleaved pyramid.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Level {
    pub lattice: Lattice,
    pub width: u32,
    pub height: u32,
    pub data: Vec<f32>,
}

/// Per coarse texel of one axis, the fine texels it averages and their
/// weights (summing to 1).
fn box_taps(n: u32, m: u32) -> Vec<Vec<(usize, f32)>> {
    let scale = f64::from(n) / f64::from(m);
    (0..m)
        .map(|j| {
            let (lo, hi) = (f64::from(j) * scale, f64::from(j + 1) * scale);
            let first = lo.floor() as u32;
            (first..n)
                .take_while(|&i| f64::from(i) < hi)
                .filter_map(|i| {
                    let overlap = hi.min(f64::from(i) + 1.0) - lo.max(f64::from(i));
                    (overlap > 0.0).then_some((i as usize, (overlap / scale) as f32))
                })
                .collect()
        })
        .collect()
}

/// The next coarser level of a `width × height` image of `stride` values
/// per texel: each axis halved, rounding down, never below 1.
/// By rows in parallel, or (`parallel` false) on the calling thread: the
/// same values either way.
fn downsample_with(
    data: &[f32],
    stride: usize,
    width: u32,
    height: u32,
    parallel: bool,
) -> (Vec<f32>, u32, u32) {
    let (w2, h2) = ((width / 2).max(1), (height / 2).max(1));
    let (w, s) = (width as usize, stride);
    if s == 0 || data.len() < w * height as usize * s {
        return (vec![0.0; w2 as usize * h2 as usize * s], w2, h2);
    }
    let (tx, ty) = (box_taps(width, w2), box_taps(height, h2));
    let row2 = w2 as usize * s;
    // Horizontal pass into `height` rows of `w2` texels, then vertical.
    let mut across = vec![0.0f32; height as usize * row2];
    let horizontal = |(out, row): (&mut [f32], &[f32])| {
        for (j, taps) in tx.iter().enumerate() {
            let o = &mut out[j * s..(j + 1) * s];
            for &(i, wt) in taps {
                for (o, &v) in o.iter_mut().zip(&row[i * s..(i + 1) * s]) {
                    *o += wt * v;
                }
            }
        }
    };
    if parallel {
        (across.par_chunks_mut(row2).zip(data.par_chunks(w * s))).for_each(horizontal);
    } else {
        (across.chunks_mut(row2).zip(data.chunks(w * s))).for_each(horizontal);
    }
    let mut out = vec![0.0f32; h2 as usize * row2];
    let vertical = |(o, taps): (&mut [f32], &Vec<(usize, f32)>)| {
        for &(i, wt) in taps {
            for (o, &v) in o.iter_mut().zip(&across[i * row2..(i + 1) * row2]) {
                *o += wt * v;
            }
        }
    };
    if parallel {
        (out.par_chunks_mut(row2).zip(ty.par_iter())).for_each(vertical);
    } else {
        (out.chunks_mut(row2).zip(ty.iter())).for_each(vertical);
    }
    (out, w2, h2)
}

/// Every coarse level (1, 2, ... down to 1 × 1) of an interleaved image.
pub(crate) fn build(data: &[f32], stride: usize, width: u32, height: u32) -> Vec<Level> {
    build_with(data, stride, (width, height), true)
}

/// [`build`] on the calling thread: for a pyramid built lazily inside a
/// parallel loop, where waiting on a parallel build could deadlock.
pub(crate) fn build_serial(data: &[f32], stride: usize, size: (u32, u32)) -> Vec<Level> {
    build_with(data, stride, size, false)
}

fn build_with(
    data: &[f32],
    stride: usize,
    (width, height): (u32, u32),
    parallel: bool,
) -> Vec<Level> {
    let mut levels: Vec<Level> = Vec::new();
    let (mut w, mut h) = (width.max(1), height.max(1));
    while w > 1 || h > 1 {
        let fine = levels.last().map_or(data, |l| l.data.as_slice());
        let (next, w2, h2) = downsample_with(fine, stride, w, h, parallel);
        levels.push(Level {
            lattice: Lattice::new(w2, h2),
            width: w2,
            height: h2,
            data: next,
        });
        (w, h) = (w2, h2);
    }
    levels
}

/// The pyramid of a texture: level 0 (a copy of `texture`), then every
/// coarser level down to 1 × 1, with the box of the module doc. The levels
/// [`super::Exemplar::sample_all_lod`] reads are these, per channel.
pub fn mip_levels(texture: &Texture) -> Vec<Texture> {
    let mut out = vec![texture.clone()];
    out.extend(
        build(
            &texture.data,
            texture.channels,
            texture.width,
            texture.height,
        )
        .into_iter()
        .map(|l| Texture {
            width: l.width,
            height: l.height,
            channels: texture.channels,
            data: l.data,
        }),
    );
    out
}
