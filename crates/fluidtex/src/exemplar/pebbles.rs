//! A procedural pebble exemplar: tileable colour plus its own height map as
//! feature map, so demos and tests need no files.
//!
//! Stones sit on a jittered grid wrapped on a torus (Worley 1996, "A
//! cellular texture basis function": one site per cell, nearest sites give
//! Voronoi cells). Each stone is the intersection of its Voronoi cell,
//! shrunk by a crevice of random width, with a randomly oriented ellipse
//! around its site; the distances to the cell's edges and to the ellipse are
//! combined with a smooth minimum (Quílez's polynomial `smin`) so corners
//! are rounded. `t`, the inward distance to the stone's outline, is divided
//! by its maximum over the stone, and the height is the parabolic profile
//! `1 − (1 − t/t_max)²`: 1 at the stone's centre, 0 at its rim and in the
//! crevices. Colour is a per-stone base (warm greys and
//! tans), modulated by tileable value noise and lit from the top left
//! through the normals of that height field, with crevices dark.
//! Everything is a function of texel coordinates and `seed` on the torus,
//! so the image tiles seamlessly and is bit-identical on any thread count.

use rayon::prelude::*;

use super::{Exemplar, FeatureMap, FeatureOrigin, SampleFormat};
use crate::texture::Texture;

/// Stones per side of the exemplar.
const CELLS: u32 = 8;
/// How far a site may move from its cell's centre, in cells (< 0.5 keeps it
/// inside its cell, so a 5×5 cell neighbourhood holds every relevant site).
const JITTER: f32 = 0.38;
/// Mean half width of the crevice between neighbouring stones, in cells.
const GAP: f32 = 0.03;
/// Radius of the smooth minimum that rounds the stones' corners, in cells.
const ROUNDING: f32 = 0.1;
/// Sizes accepted by [`builtin_pebbles`]; others are clamped into range.
const SIZE_RANGE: (u32, u32) = (8, 8192);
/// Sentinel for crevice texels in [`PebbleLayout::stone`].
pub const CREVICE: u32 = u32::MAX;

/// The built-in pebbles exemplar, `size × size` texels (clamped to
/// `[8, 8192]`), 3 colour channels stored as 8-bit, feature map = height.
/// Deterministic in `(size, seed)`; tiles seamlessly.
pub fn builtin_pebbles(size: u32, seed: u64) -> Exemplar {
    pebbles_with_masks(size, seed).exemplar
}

/// The built-in exemplar with the generator's own stone masks (ground truth
/// for tests of feature maps and erosion).
#[derive(Clone, Debug, PartialEq)]
pub struct PebbleLayout {
    pub exemplar: Exemplar,
    /// Per texel (row-major), the stone it belongs to, or [`CREVICE`].
    pub stone: Vec<u32>,
}

/// Random parameters of one stone.
#[derive(Clone, Copy)]
struct Stone {
    /// Site in cell units, relative to the cell's corner.
    site: [f32; 2],
    /// Ellipse semi-axes (cells) and orientation.
    radii: [f32; 2],
    cos: f32,
    sin: f32,
    /// Half width of the crevice around it, cells.
    gap: f32,
    colour: [f32; 3],
}

/// [`builtin_pebbles`] plus which stone each texel belongs to.
pub fn pebbles_with_masks(size: u32, seed: u64) -> PebbleLayout {
    let size = size.clamp(SIZE_RANGE.0, SIZE_RANGE.1);
    let stones: Vec<Stone> = (0..CELLS * CELLS).map(|c| stone(seed, c)).collect();
    let (id, inward) = stone_map(size, &stones);
    let height = heights(&id, &inward, stones.len());
    let colour = shade(size, seed, &stones, &id, &height);
    let colour = Texture {
        width: size,
        height: size,
        channels: 3,
        data: colour,
    };
    let feature = FeatureMap {
        map: Texture {
            width: size,
            height: size,
            channels: 1,
            data: height,
        },
        origin: FeatureOrigin::Builtin,
    };
    // Sizes match and values are finite and in range by construction.
    let exemplar = Exemplar::assemble(colour, SampleFormat::U8, Vec::new(), feature);
    PebbleLayout {
        exemplar,
        stone: id,
    }
}

/// Pass 1: the stone id ([`CREVICE`] between stones) and the inward
/// distance of every texel.
fn stone_map(size: u32, stones: &[Stone]) -> (Vec<u32>, Vec<f32>) {
    let n = size as usize;
    let geometry = Geometry::new(stones);
    let mut id = vec![CREVICE; n * n];
    let mut inward = vec![0.0f32; n * n];
    id.par_chunks_mut(n)
        .zip(inward.par_chunks_mut(n))
        .enumerate()
        .for_each(|(y, (ids, ts))| {
            for x in 0..n {
                let p = [
                    (x as f32 + 0.5) / size as f32 * CELLS as f32,
                    (y as f32 + 0.5) / size as f32 * CELLS as f32,
                ];
                let (k, t) = geometry.stone_at(stones, p);
                if t > 0.0 {
                    ids[x] = k;
                    ts[x] = t;
                }
            }
        });
    (id, inward)
}

/// A dome per stone: 1 − (1 − s)² of the inward distance relative to the
/// stone's deepest texel; 0 in the crevices.
fn heights(id: &[u32], inward: &[f32], stones: usize) -> Vec<f32> {
    let mut t_max = vec![0.0f32; stones];
    for (&k, &t) in id.iter().zip(inward) {
        if let Some(m) = t_max.get_mut(k as usize) {
            *m = m.max(t);
        }
    }
    id.iter()
        .zip(inward)
        .map(|(&k, &t)| match t_max.get(k as usize) {
            Some(&m) if m > 0.0 => {
                let s = (t / m).clamp(0.0, 1.0);
                1.0 - (1.0 - s) * (1.0 - s)
            }
            _ => 0.0,
        })
        .collect()
}

/// Pass 2: the colour, lit through the height field's normals, in 8-bit
/// levels.
fn shade(size: u32, seed: u64, stones: &[Stone], id: &[u32], height: &[f32]) -> Vec<f32> {
    let n = size as usize;
    let mut colour = vec![0.0f32; n * n * 3];
    let (coarse, fine) = (
        ValueNoise::new(seed ^ 0x9e37, 48),
        ValueNoise::new(seed ^ 0x7f4a, 160),
    );
    let relief = size as f32 / CELLS as f32 * 0.06;
    colour
        .par_chunks_mut(n * 3)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..n {
                let h = |dx: i32, dy: i32| {
                    let xx = wrap(x as i32 + dx, n as i32) as usize;
                    let yy = wrap(y as i32 + dy, n as i32) as usize;
                    height[yy * n + xx]
                };
                let i = y * n + x;
                let (u, v) = ((x as f32 + 0.5) / n as f32, (y as f32 + 0.5) / n as f32);
                let grain = 0.75 * coarse.at(u, v) + 0.25 * fine.at(u, v);
                let rgb = match stones.get(id[i] as usize) {
                    Some(s) => {
                        // Normal of the height field (y down in the image).
                        let gx = (h(1, 0) - h(-1, 0)) * 0.5 * relief;
                        let gy = (h(0, 1) - h(0, -1)) * 0.5 * relief;
                        let nrm = normalise([-gx, -gy, 1.0]);
                        let light = normalise([-0.5, -0.6, 0.65]);
                        let lambert = dot(nrm, light).max(0.0);
                        let mottled = 0.8 + 0.35 * grain;
                        let shade = (0.35 + 0.75 * lambert) * mottled;
                        // Darker towards the rim: contact shadow.
                        let rim = 0.6 + 0.4 * height[i];
                        s.colour.map(|c| c * shade * rim)
                    }
                    None => {
                        let d = 0.08 + 0.08 * grain;
                        [d * 1.1, d, d * 0.85]
                    }
                };
                for (o, c) in row[x * 3..x * 3 + 3].iter_mut().zip(rgb) {
                    // Stored as 8-bit levels, so writing it back is lossless.
                    *o = (c.clamp(0.0, 1.0) * 255.0).round() / 255.0;
                }
            }
        });

    colour
}

/// The 5×5 cell offsets, own cell first, then the inner ring, then the
/// outer ring, so the nearest-site search can stop after the first nine.
const RING_ORDER: [(i32, i32); 25] = {
    let mut out = [(0, 0); 25];
    let mut n = 0;
    let mut ring = 0;
    while ring <= 2 {
        let mut dy: i32 = -2;
        while dy <= 2 {
            let mut dx: i32 = -2;
            while dx <= 2 {
                let r = if dx.abs() > dy.abs() {
                    dx.abs()
                } else {
                    dy.abs()
                };
                if r == ring {
                    out[n] = (dx, dy);
                    n += 1;
                }
                dx += 1;
            }
            dy += 1;
        }
        ring += 1;
    }
    out
};

/// The sites around one grid cell, unwrapped, and for each site the
/// bisectors with its Voronoi candidates, precomputed so the per-texel work
/// is a few multiply-adds.
struct Geometry {
    /// Per cell, the 25 sites of its 5×5 neighbourhood: position (cell
    /// units, unwrapped around that cell) and stone index.
    around: Vec<[([f32; 2], u32); 25]>,
    /// Per stone, its 24 neighbours as (unit direction, half distance): the
    /// signed distance of a point at offset `d` from the site to the
    /// bisector is `half − unit · d`.
    bisectors: Vec<[([f32; 2], f32); 24]>,
}

impl Geometry {
    fn new(stones: &[Stone]) -> Geometry {
        let cells = CELLS as i32;
        let neighbourhood = |cx: i32, cy: i32| {
            let mut out = [([0.0f32; 2], 0u32); 25];
            for (j, (dx, dy)) in RING_ORDER.into_iter().enumerate() {
                let (gx, gy) = (cx + dx, cy + dy);
                let k = (wrap(gy, cells) * cells + wrap(gx, cells)) as u32;
                let s = stones[k as usize].site;
                out[j] = ([gx as f32 + s[0], gy as f32 + s[1]], k);
            }
            out
        };
        let around: Vec<_> = (0..cells * cells)
            .map(|c| neighbourhood(c % cells, c / cells))
            .collect();
        let bisectors = around
            .iter()
            .map(|sites| {
                // Entry 0 is the cell's own site.
                let centre = sites[0].0;
                let mut out = [([0.0f32; 2], f32::INFINITY); 24];
                for (o, &(s, _)) in out.iter_mut().zip(&sites[1..]) {
                    let axis = [s[0] - centre[0], s[1] - centre[1]];
                    let len = (axis[0] * axis[0] + axis[1] * axis[1]).sqrt();
                    if len > 0.0 {
                        *o = ([axis[0] / len, axis[1] / len], 0.5 * len);
                    }
                }
                out
            })
            .collect();
        Geometry { around, bisectors }
    }

    /// The stone whose Voronoi cell holds `p` (cell units, in
    /// `[0, CELLS)²`) and the inward distance to its outline (negative
    /// outside the stone).
    #[inline]
    fn stone_at(&self, stones: &[Stone], p: [f32; 2]) -> (u32, f32) {
        let last = CELLS as usize - 1;
        let (cx, cy) = (
            (p[0].max(0.0) as usize).min(last),
            (p[1].max(0.0) as usize).min(last),
        );
        let sites = &self.around[cy * CELLS as usize + cx];
        let search = |best: &mut (f32, usize), range: std::ops::Range<usize>| {
            for j in range {
                let s = sites[j].0;
                let d2 = (p[0] - s[0]).powi(2) + (p[1] - s[1]).powi(2);
                if d2 < best.0 {
                    *best = (d2, j);
                }
            }
        };
        let mut best = (f32::INFINITY, 0usize);
        search(&mut best, 0..9);
        // Sites of the outer ring are at least 1 + (0.5 − JITTER) cells away
        // from any point of the centre cell; skip them when one is nearer.
        let outer = 1.5 - JITTER;
        if best.0 >= outer * outer {
            search(&mut best, 9..25);
        }
        let (s1, k1) = sites[best.1];
        let st = &stones[k1 as usize];
        let d = [p[0] - s1[0], p[1] - s1[1]];
        // Distance to the Voronoi cell's boundary (the nearest bisector),
        // corners rounded by a smooth minimum. Bisectors farther than the
        // rounding radius leave the minimum unchanged and are skipped.
        let mut edge = f32::INFINITY;
        for &(unit, half) in &self.bisectors[k1 as usize] {
            let e = half - (unit[0] * d[0] + unit[1] * d[1]);
            if e < edge + ROUNDING {
                edge = if edge.is_finite() {
                    smooth_min(edge, e, ROUNDING)
                } else {
                    e
                };
            }
        }
        let local = [
            st.cos * d[0] + st.sin * d[1],
            -st.sin * d[0] + st.cos * d[1],
        ];
        let q = ((local[0] / st.radii[0]).powi(2) + (local[1] / st.radii[1]).powi(2)).sqrt();
        let ellipse = (1.0 - q) * st.radii[0].min(st.radii[1]);
        (k1, smooth_min(edge - st.gap, ellipse, ROUNDING))
    }
}

/// `i mod n` for `i` within a few periods of `[0, n)`, without the division
/// that `rem_euclid` costs in the inner loops.
#[inline(always)]
fn wrap(mut i: i32, n: i32) -> i32 {
    while i < 0 {
        i += n;
    }
    while i >= n {
        i -= n;
    }
    i
}

/// Polynomial smooth minimum (Quílez): equals `min(a, b)` when they differ
/// by more than `k`, and rounds the crease otherwise.
fn smooth_min(a: f32, b: f32, k: f32) -> f32 {
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b + (a - b) * h - k * h * (1.0 - h)
}

fn stone(seed: u64, cell: u32) -> Stone {
    let r = |i: u64| unit(hash(seed, cell as u64 * 16 + i));
    // Warm greys, tans and a few darker slate stones.
    let value = 0.42 + 0.4 * r(5);
    let warmth = r(6) - 0.35;
    let slate = if r(7) < 0.15 { 0.7 } else { 1.0 };
    Stone {
        site: [
            0.5 + JITTER * (2.0 * r(0) - 1.0),
            0.5 + JITTER * (2.0 * r(1) - 1.0),
        ],
        radii: [0.55 + 0.25 * r(2), 0.45 + 0.2 * r(3)],
        cos: (std::f32::consts::PI * r(4)).cos(),
        sin: (std::f32::consts::PI * r(4)).sin(),
        gap: GAP * (0.6 + 0.9 * r(8)),
        colour: [
            value * slate * (1.0 + 0.12 * warmth),
            value * slate * (1.0 + 0.02 * warmth),
            value * slate * (1.0 - 0.10 * warmth),
        ],
    }
}

/// Tileable value noise in `[0, 1]`: random values on a `period × period`
/// lattice (drawn once), smoothstep-interpolated, repeating with period 1 in
/// `(u, v)`.
struct ValueNoise {
    period: usize,
    lattice: Vec<f32>,
}

impl ValueNoise {
    fn new(seed: u64, period: usize) -> ValueNoise {
        let lattice = (0..period * period)
            .map(|k| unit(hash(seed, k as u64)))
            .collect();
        ValueNoise { period, lattice }
    }

    #[inline]
    fn at(&self, u: f32, v: f32) -> f32 {
        let p = self.period;
        let (x, y) = (u * p as f32, v * p as f32);
        // u, v ≥ 0 here, so truncation is the floor.
        let (i, j) = (x as usize, y as usize);
        let (fx, fy) = (x - i as f32, y - j as f32);
        let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
        let (i0, i1) = (i % p, (i + 1) % p);
        let (j0, j1) = ((j % p) * p, ((j + 1) % p) * p);
        let l = &self.lattice;
        let top = l[j0 + i0] + (l[j0 + i1] - l[j0 + i0]) * sx;
        let bottom = l[j1 + i0] + (l[j1 + i1] - l[j1 + i0]) * sx;
        top + (bottom - top) * sy
    }
}

/// SplitMix64 finaliser of `(seed, key)`: stateless, so any texel can draw
/// its own numbers in any order.
fn hash(seed: u64, key: u64) -> u64 {
    let mut z = seed
        .wrapping_add(key.wrapping_mul(0x9e37_79b9_7f4a_7c15))
        .wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Top 24 bits as a float in `[0, 1)`.
fn unit(h: u64) -> f32 {
    (h >> 40) as f32 / (1u64 << 24) as f32
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalise(a: [f32; 3]) -> [f32; 3] {
    let l = dot(a, a).sqrt();
    a.map(|x| x / l)
}
