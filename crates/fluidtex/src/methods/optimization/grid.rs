//! The paper's texture transport on a grid (Sec. VI, Eqs. 3 and 4),
//! selected by `transport = "grid"`.
//!
//! The paper carries the texture between two surfaces through the
//! simulation's volumetric grid: the coordinate field φ(x) = x is advected
//! one frame by a first-order upwind scheme (Eq. 3), so that each new point
//! reads, at φ, where it came from, and takes the previous colour at the
//! closest previous surface point. The orientation is extended off the
//! previous surface onto the grid and advected by Eq. 4, the scalar
//! advection of its components alternated with the stretching term
//! (I − ddᵀ)(d·∇)u, then interpolated at the new points.
//!
//! fluidtex's inputs are meshes with per-vertex velocity, so the grid is
//! built here: a **narrow band** of nodes at spacing `h` (the finest point
//! spacing, so no texture detail is lost in the interpolation) around the
//! new surface, wide enough to hold a frame's displacement (at most
//! [`MAX_BAND_CELLS`] cells each side), with the velocity at each node taken
//! from the closest point of each frame's mesh and blended linearly in time,
//! as the back-tracking transport reads it. Characteristics that start
//! outside the band keep the band edge's own coordinates; the paper notes
//! that such wrong back-tracked positions are pasted over by the synthesis.
//!
//! Written here rather than taken from a crate: the sparse-grid crates of
//! the ecosystem (VDB ports) hold values but have no upwind advection, and
//! the band is a sorted key list, a few dozen lines.

use glam::Vec3;
use rayon::prelude::*;

use super::tangent::{reference, tangent};
use super::transport::Previous;
use crate::surface::velocity::FlowFrame;

/// Band half-width limit, in cells: what a frame's displacement may span
/// and still be carried on the grid (violent frames beyond it lose the
/// upstream part of their characteristics, see the module doc).
pub const MAX_BAND_CELLS: i32 = 12;
/// Node limit (about 110 bytes a node): dilation stops at the layer that
/// would pass it.
pub const MAX_NODES: usize = 6_000_000;
/// Upwind steps at most per frame (the CFL number is kept at 0.5).
pub const MAX_STEPS: u32 = 256;

/// Bits per axis in a packed cell key.
const BITS: u32 = 21;
const OFFSET: i64 = 1 << (BITS - 1);
const NONE: u32 = u32::MAX;

/// A narrow band of grid nodes at `origin + h·(i, j, k)`.
pub struct Band {
    pub h: f32,
    origin: Vec3,
    /// Packed (i, j, k) of every node, sorted.
    keys: Vec<u64>,
    /// Per node: −x, +x, −y, +y, −z, +z neighbours (or [`NONE`]).
    nb: Vec<[u32; 6]>,
    /// Whether the dilation stopped at [`MAX_NODES`] before its width.
    pub capped: bool,
}

fn pack(c: [i64; 3]) -> Option<u64> {
    let mut key = 0u64;
    for v in c {
        let u = v + OFFSET;
        if !(0..(1i64 << BITS)).contains(&u) {
            return None;
        }
        key = (key << BITS) | u as u64;
    }
    Some(key)
}

fn unpack(key: u64) -> [i64; 3] {
    let mask = (1u64 << BITS) - 1;
    [
        ((key >> (2 * BITS)) & mask) as i64 - OFFSET,
        ((key >> BITS) & mask) as i64 - OFFSET,
        (key & mask) as i64 - OFFSET,
    ]
}

/// Sorted `b` minus sorted `a` (both deduplicated).
fn difference(b: &[u64], a: &[u64]) -> Vec<u64> {
    let mut out = Vec::with_capacity(b.len());
    let mut j = 0;
    for &k in b {
        while j < a.len() && a[j] < k {
            j += 1;
        }
        if j >= a.len() || a[j] != k {
            out.push(k);
        }
    }
    out
}

impl Band {
    /// The nodes of every cell holding one of `points`, dilated by `cells`
    /// layers (26-neighbourhood, so the band holds every node within
    /// `cells·h` of a point).
    pub fn around(points: &[Vec3], h: f32, cells: i32) -> Band {
        let lo = points
            .iter()
            .fold(Vec3::splat(f32::INFINITY), |m, &p| m.min(p));
        let origin = if lo.is_finite() { lo } else { Vec3::ZERO };
        let mut band = Band {
            h,
            origin,
            keys: Vec::new(),
            nb: Vec::new(),
            capped: false,
        };
        let mut seeds: Vec<u64> = points
            .par_iter()
            .flat_map_iter(|&p| {
                let c = band.cell(p);
                (0..8).filter_map(move |corner| {
                    pack([
                        c[0] + (corner & 1) as i64,
                        c[1] + ((corner >> 1) & 1) as i64,
                        c[2] + ((corner >> 2) & 1) as i64,
                    ])
                })
            })
            .collect();
        seeds.par_sort_unstable();
        seeds.dedup();
        let mut all = seeds.clone();
        let mut frontier = seeds;
        for _ in 0..cells.max(0) {
            let mut next: Vec<u64> = frontier
                .par_iter()
                .flat_map_iter(|&k| {
                    let c = unpack(k);
                    (0..27).filter(|&n| n != 13).filter_map(move |n| {
                        pack([
                            c[0] + (n % 3) as i64 - 1,
                            c[1] + ((n / 3) % 3) as i64 - 1,
                            c[2] + (n / 9) as i64 - 1,
                        ])
                    })
                })
                .collect();
            next.par_sort_unstable();
            next.dedup();
            let new = difference(&next, &all);
            if all.len() + new.len() > MAX_NODES {
                band.capped = true;
                break;
            }
            let mut merged = Vec::with_capacity(all.len() + new.len());
            merged.extend_from_slice(&all);
            merged.extend_from_slice(&new);
            merged.par_sort_unstable();
            all = merged;
            frontier = new;
            if frontier.is_empty() {
                break;
            }
        }
        band.nb = all
            .par_iter()
            .map(|&k| {
                let c = unpack(k);
                let mut out = [NONE; 6];
                for (axis, pair) in out.chunks_exact_mut(2).enumerate() {
                    for (side, slot) in pair.iter_mut().enumerate() {
                        let mut n = c;
                        n[axis] += if side == 0 { -1 } else { 1 };
                        if let Some(found) = pack(n).and_then(|key| all.binary_search(&key).ok()) {
                            *slot = found as u32;
                        }
                    }
                }
                out
            })
            .collect();
        band.keys = all;
        band
    }

    /// Nodes in the band.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// Whether the band has no node.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    fn cell(&self, p: Vec3) -> [i64; 3] {
        let q = (p - self.origin) / self.h;
        [q.x.floor() as i64, q.y.floor() as i64, q.z.floor() as i64]
    }

    /// World position of node `i`.
    pub fn position(&self, i: usize) -> Vec3 {
        let c = unpack(self.keys[i]);
        self.origin + Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) * self.h
    }

    fn node(&self, c: [i64; 3]) -> Option<usize> {
        pack(c).and_then(|k| self.keys.binary_search(&k).ok())
    }

    /// Trilinear interpolation of `field` at `p` over the cell's nodes in
    /// the band (weights renormalised over those present); `None` where
    /// none is.
    pub fn interpolate(&self, field: &[Vec3], p: Vec3) -> Option<Vec3> {
        let c = self.cell(p);
        let f = (p - self.origin) / self.h - Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32);
        let mut sum = Vec3::ZERO;
        let mut weight = 0.0f32;
        for corner in 0..8usize {
            let bit = |b: usize| (corner >> b) & 1;
            let Some(i) = self.node([
                c[0] + bit(0) as i64,
                c[1] + bit(1) as i64,
                c[2] + bit(2) as i64,
            ]) else {
                continue;
            };
            let w = (0..3)
                .map(|a| if bit(a) == 1 { f[a] } else { 1.0 - f[a] })
                .product::<f32>();
            sum += field[i] * w;
            weight += w;
        }
        (weight > 1e-6).then(|| sum / weight)
    }

    /// One first-order upwind step of ∂f/∂t = −u·∇f over `dt` (Eq. 3, each
    /// component of `f` a scalar field). A missing upwind neighbour counts
    /// as no gradient: the band's edge keeps its value.
    fn upwind(&self, f: &[Vec3], u: &[Vec3], dt: f32) -> Vec<Vec3> {
        let inv = 1.0 / self.h;
        (0..f.len())
            .into_par_iter()
            .map(|i| {
                let mut change = Vec3::ZERO;
                for (axis, ua) in u[i].to_array().into_iter().enumerate() {
                    let (n, sign) = if ua > 0.0 {
                        (self.nb[i][2 * axis], 1.0)
                    } else {
                        (self.nb[i][2 * axis + 1], -1.0)
                    };
                    if n != NONE {
                        change += (f[i] - f[n as usize]) * (sign * inv * ua);
                    }
                }
                f[i] - change * dt
            })
            .collect()
    }

    /// (d·∇)u at node `i` by central differences (one-sided at the band's
    /// edge).
    fn directional_derivative(&self, u: &[Vec3], d: Vec3, i: usize) -> Vec3 {
        let mut g = Vec3::ZERO;
        for axis in 0..3 {
            let lo = self.nb[i][2 * axis];
            let hi = self.nb[i][2 * axis + 1];
            let du = match (lo != NONE, hi != NONE) {
                (true, true) => (u[hi as usize] - u[lo as usize]) / (2.0 * self.h),
                (true, false) => (u[i] - u[lo as usize]) / self.h,
                (false, true) => (u[hi as usize] - u[i]) / self.h,
                (false, false) => Vec3::ZERO,
            };
            g += du * d[axis];
        }
        g
    }
}

/// What one grid transport did, for the frame's statistics.
#[derive(Clone, Copy, Debug, Default)]
pub struct GridStats {
    pub nodes: usize,
    pub cells: i32,
    pub steps: u32,
    pub capped: bool,
}

impl GridStats {
    /// As the frame's statistics report it (`transport_grid`).
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "nodes": self.nodes,
            "band_cells": self.cells,
            "steps": self.steps,
            "capped": self.capped,
        })
    }
}

/// The two frames' flow on the band: velocities at the previous frame
/// (`old`) and the current one (`cur`), blended linearly in time.
pub struct BandFlow {
    u0: Vec<Vec3>,
    u1: Vec<Vec3>,
}

impl BandFlow {
    pub fn sample(band: &Band, old: &FlowFrame<'_>, cur: &FlowFrame<'_>, hint: f32) -> BandFlow {
        let (u0, u1) = (0..band.len())
            .into_par_iter()
            .map(|i| {
                let x = band.position(i);
                let a = old.sample(x, hint);
                let b = cur.sample(x, hint);
                (a.or(b).unwrap_or(Vec3::ZERO), b.or(a).unwrap_or(Vec3::ZERO))
            })
            .unzip();
        BandFlow { u0, u1 }
    }

    fn at(&self, s: f32) -> Vec<Vec3> {
        self.u0
            .par_iter()
            .zip(self.u1.par_iter())
            .map(|(&a, &b)| a * (1.0 - s) + b * s)
            .collect()
    }
}

/// Steps for a frame of `dt` seconds at top speed `speed` on spacing `h`
/// (CFL number 0.5).
pub fn steps_for(speed: f32, dt: f32, h: f32) -> u32 {
    let cfl = (speed * dt.abs() / (0.5 * h)).ceil();
    if cfl.is_finite() {
        (cfl as u32).clamp(1, MAX_STEPS)
    } else {
        MAX_STEPS
    }
}

/// The grid transport of one frame: each of `points` gets the previous
/// values at its back-tracked position (the returned colours, `channels`
/// each, and how many found none), and each of `coarse` (with unit
/// `coarse_normals`) the orientation advected by Eq. 4.
#[allow(clippy::too_many_arguments)]
pub fn transport(
    points: &[Vec3],
    coarse: &[Vec3],
    coarse_normals: &[Vec3],
    old: &FlowFrame<'_>,
    cur: &FlowFrame<'_>,
    dt: f32,
    h: f32,
    hint: f32,
    prev: &Previous<'_>,
) -> (Vec<f32>, usize, Vec<Vec3>, GridStats) {
    let speed = old
        .velocity
        .iter()
        .chain(cur.velocity)
        .map(|v| v.length())
        .filter(|s| s.is_finite())
        .fold(0.0f32, f32::max);
    let reach = (speed * dt.abs() / h).ceil();
    let cells = if reach.is_finite() {
        (reach as i32 + 2).min(MAX_BAND_CELLS)
    } else {
        MAX_BAND_CELLS
    };
    let band = Band::around(points, h, cells);
    let flow = BandFlow::sample(&band, old, cur, hint);
    let steps = steps_for(speed, dt, h);
    let step = dt.abs() / steps as f32;
    // Eq. 3: the coordinate field, φ = x at the previous frame.
    let mut phi: Vec<Vec3> = (0..band.len()).map(|i| band.position(i)).collect();
    // Eq. 4: the previous orientation, extended off the surface (constant
    // along the normal: the closest surface point's).
    let mut d: Vec<Vec3> = (0..band.len())
        .into_par_iter()
        .map(|i| {
            prev.orientation_at(band.position(i), hint)
                .map_or(Vec3::ZERO, |(_, d)| d)
        })
        .collect();
    for k in 0..steps {
        let u = flow.at((k as f32 + 0.5) / steps as f32);
        phi = band.upwind(&phi, &u, step);
        d = band.upwind(&d, &u, step);
        // The stretching term, alternated with the advection, its length
        // change projected out: a rotation only.
        d = (0..d.len())
            .into_par_iter()
            .map(|i| {
                let di = d[i];
                if di.length_squared() < 1e-12 {
                    return di;
                }
                let g = band.directional_derivative(&u, di, i);
                (di + (g - di * di.dot(g)) * step).normalize_or_zero()
            })
            .collect();
    }
    let k = prev.channels;
    let mut colours = vec![0.0f32; points.len() * k];
    let missing: usize = colours
        .par_chunks_mut(k)
        .zip(points.par_iter())
        .map(|(o, &p)| {
            let x = band.interpolate(&phi, p).unwrap_or(p);
            usize::from(!prev.values_at(x, hint, o))
        })
        .sum();
    let orientation = coarse
        .par_iter()
        .zip(coarse_normals.par_iter())
        .map(|(&p, &n)| match band.interpolate(&d, p) {
            Some(v) if v.length_squared() > 1e-12 => tangent(v, n),
            _ => reference(n),
        })
        .collect();
    let stats = GridStats {
        nodes: band.len(),
        cells,
        steps,
        capped: band.capped,
    };
    (colours, missing, orientation, stats)
}
