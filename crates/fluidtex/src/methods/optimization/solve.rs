//! Surface texture optimisation on one level (paper Sec. V-B).
//!
//! E(s) = E_t(s; {z_p}) + E_c(s; c) with
//! E_t = Σ_{p ∈ S†} Σ_{v ∈ N_p} ‖s(v) − z_p(v)‖² (Eq. 1) and
//! E_c = Σ_k λ_k ‖s(k) − c(k)‖² (Eq. 2), colour channels. Per pass (one
//! window size), repeated until no centre changes its match or
//! `iterations` is reached:
//! 1. for every centre p of S†: its vertex and pixel neighbourhoods
//!    ([`super::neighbourhood`]) from the current s;
//! 2. the nearest exemplar neighbourhood to the pixel neighbourhood
//!    ([`super::search`]), read at the members' real-valued texel
//!    coordinates by bilinear interpolation: z_p;
//! 3. the exact minimiser of E for fixed z: per point, the average of every
//!    z_p(v) that covers it and of c weighted by λ (all exemplar channels
//!    with the same weights, so extra channels follow the colour).
//!
//! S† is one point per cell of a 3-D grid of side `spacing` × w texels
//! (the point nearest the cell centre; a separate cell per dominant normal
//! direction so both sides of a thin sheet get centres): neighbourhoods of
//! width w overlap about (1/spacing)² times, the quarter-width overlap of
//! Kwatra et al. 2005.
//!
//! 4. with [`super::Histogram::Matched`] (the default, not the paper's):
//!    every channel of s remapped onto the working exemplar's histogram
//!    ([`super::histogram`]) before the next search.
//!
//! λ_k (Eq. 2's gradient weighting): `coherence` × (number of
//! neighbourhoods covering k) × min(g_k / ḡ, 3), g_k the mean colour
//! difference between the transported c at k and at its neighbours and ḡ
//! its mean over the level: the transported texture wins where it has
//! structure and is re-synthesised where transport has blurred it.

use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::histogram::Quantiles;
use super::lattice::Level;
use super::neighbourhood::{CellSample, Scratch, Window, build, fill_query};
use super::search::{SearchIndex, WorkingExemplar};

/// What a level needs besides its current values.
pub struct LevelInput<'a> {
    pub level: &'a Level,
    /// Orientation per level vertex.
    pub orientation: &'a [Vec3],
    pub exemplar: &'a WorkingExemplar,
    /// One search index per pass, in order (largest window first).
    pub passes: &'a [SearchIndex],
    /// Transported values per level vertex (all channels), if any.
    pub transported: Option<&'a [f32]>,
    pub coherence: f32,
    /// Centre spacing as a fraction of the window width.
    pub spacing: f32,
    pub iterations: u32,
    /// A pass also stops once an iteration lowered the energy by less than
    /// this share of it (0: only once no match changed).
    pub convergence: f32,
    /// Robust exponent r of Kwatra et al. 2005: each neighbourhood's terms
    /// are weighted by (mean ‖s_p − z_p‖²)^((r − 2)/2), fixed during an
    /// averaging step; r = 2 is Eq. 1 unweighted.
    pub robust: f32,
    /// Gauss–Newton steps of the sub-texel registration of each match
    /// ([`refine_shift`]); 0: the paper's integer matches.
    pub refine: u32,
    /// Target histograms the values are remapped onto after every
    /// averaging step ([`super::histogram`]); `None`: the paper's average.
    pub histogram: Option<&'a Quantiles>,
}

/// Gauss–Newton steps of the sub-texel registration run by the method
/// ([`refine_shift`]): 0, the paper's integer matches. Why off: on the flat
/// square (one level, passes 33/17/9 from random texels, 4 iterations) it
/// lowers the luminance contrast kept when the members fall on whole
/// exemplar texels (0.66 with 0 steps, 0.51 with 2) and raises it only a
/// little when they do not (texel = 0.77 spacing: 0.46 → 0.53), though E
/// ends lower in the second case (1.72e4 → 1.43e4). Registered
/// predictions agree better, and their average drifts to the smoother
/// sub-texel reads of the bilinear exemplar. Kept, tested, for surfaces
/// whose points are far from texel-aligned.
pub const REFINE_STEPS: u32 = 0;

/// Energies of one pass.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct PassReport {
    pub width: u32,
    pub centres: usize,
    pub iterations: u32,
    /// (E before the averaging step, E after it) per iteration, with that
    /// iteration's matches.
    pub energies: Vec<(f64, f64)>,
    /// Matches that changed in the last search (0: converged).
    pub changed: usize,
    /// Luminance contrast of the last predictions z_p over every member,
    /// relative to the working exemplar's: below 1 where the matches
    /// favour the exemplar's smooth regions.
    pub prediction_contrast: f64,
}

impl PassReport {
    /// E at the start of the pass (before the first averaging).
    pub fn start(&self) -> f64 {
        self.energies.first().map_or(0.0, |e| e.0)
    }
    /// E at the end of the pass (after the last averaging).
    pub fn end(&self) -> f64 {
        self.energies.last().map_or(0.0, |e| e.1)
    }
}

/// Seconds spent per part.
#[derive(Clone, Copy, Debug, Default)]
pub struct SolveTimes {
    /// Building the pixel search vectors and the nearest-neighbour search.
    pub search: f64,
    /// Building the neighbourhoods (flattening and rasterising), once per pass.
    pub neighbourhoods: f64,
    pub solve: f64,
}

/// The centres S† of a window of `width` texels of size `texel`.
pub fn centres(level: &Level, cell: f32) -> Vec<u32> {
    let inv = 1.0 / cell.max(1e-12);
    let mut keyed: Vec<([i32; 4], u32, u32)> = (0..level.len())
        .into_par_iter()
        .map(|v| {
            let p = level.positions[v] * inv;
            let c = p.floor();
            let d = (p - c - Vec3::splat(0.5)).length_squared();
            let n = level.normals[v];
            let a = n.abs();
            let axis = if a.x >= a.y && a.x >= a.z {
                0
            } else if a.y >= a.z {
                1
            } else {
                2
            };
            let sign = (n[axis] < 0.0) as i32;
            let axis = axis as i32;
            (
                [c.x as i32, c.y as i32, c.z as i32, axis * 2 + sign],
                d.to_bits(),
                v as u32,
            )
        })
        .collect();
    keyed.par_sort_unstable();
    let mut out: Vec<u32> = Vec::new();
    let mut last: Option<[i32; 4]> = None;
    for (k, _, v) in keyed {
        if last != Some(k) {
            out.push(v);
            last = Some(k);
        }
    }
    out.sort_unstable();
    out
}

/// The λ_k of Eq. 2 before the coverage factor (`coherence` × min(g/ḡ, 3)).
fn gradient_weights(level: &Level, c: &[f32], k: usize, kc: usize, coherence: f32) -> Vec<f32> {
    let g: Vec<f32> = (0..level.len())
        .into_par_iter()
        .map(|v| {
            let nb = level.neighbours(v as u32);
            if nb.is_empty() {
                return 0.0;
            }
            let mut s = 0.0f32;
            for &u in nb {
                let mut d = 0.0;
                for ch in 0..kc {
                    let x = c[v * k + ch] - c[u as usize * k + ch];
                    d += x * x;
                }
                s += d.sqrt();
            }
            s / nb.len() as f32
        })
        .collect();
    let mean = g.iter().map(|&x| x as f64).sum::<f64>() / g.len().max(1) as f64;
    g.iter()
        .map(|&x| {
            if mean > 1e-12 {
                coherence * ((x as f64 / mean) as f32).min(3.0)
            } else {
                coherence
            }
        })
        .collect()
}

/// The neighbourhoods of one pass, built once: they depend on the level's
/// geometry and orientation only, so every iteration of the pass re-reads
/// colours through them instead of flattening the surface again.
struct PassGeometry {
    /// Members of centre i: `members[offsets[i]..offsets[i + 1]]`.
    offsets: Vec<usize>,
    /// (level vertex, texel coordinates) of every member, centre by centre.
    members: Vec<(u32, Vec2)>,
    /// Search-grid samples, g² per centre.
    cells: Vec<CellSample>,
    /// The centre of each member.
    owner: Vec<u32>,
    /// Members covering vertex v: `by_vertex[vertex_offsets[v]..vertex_offsets[v + 1]]`,
    /// member indices ascending (= centre order, the order of the sums).
    vertex_offsets: Vec<usize>,
    by_vertex: Vec<u32>,
}

/// One parallel chunk's part of a [`PassGeometry`]: members per centre,
/// the members (vertex, neighbourhood coordinates), the grid cells.
type ChunkGeometry = (Vec<usize>, Vec<(u32, Vec2)>, Vec<CellSample>);

impl PassGeometry {
    fn build(input: &LevelInput<'_>, window: Window, centres: &[u32]) -> PassGeometry {
        let level = input.level;
        let g2 = (window.grid * window.grid) as usize;
        let chunk = (centres.len() / 64).max(8);
        let parts: Vec<ChunkGeometry> = centres
            .par_chunks(chunk)
            .map(|part| {
                let mut scratch = Scratch::new(level);
                let mut counts = Vec::with_capacity(part.len());
                let mut members = Vec::new();
                let mut cells = vec![CellSample::UNCOVERED; part.len() * g2];
                for (i, &c) in part.iter().enumerate() {
                    let before = members.len();
                    build(
                        level,
                        c,
                        input.orientation[c as usize],
                        window,
                        &mut scratch,
                        &mut members,
                        &mut cells[i * g2..(i + 1) * g2],
                    );
                    counts.push(members.len() - before);
                }
                (counts, members, cells)
            })
            .collect();
        let total: usize = parts.iter().map(|p| p.1.len()).sum();
        let mut offsets = Vec::with_capacity(centres.len() + 1);
        offsets.push(0usize);
        let mut members = Vec::with_capacity(total);
        let mut cells = Vec::with_capacity(centres.len() * g2);
        for (counts, m, c) in parts {
            for n in counts {
                offsets.push(offsets[offsets.len() - 1] + n);
            }
            members.extend(m);
            cells.extend(c);
        }
        let mut owner = vec![0u32; total];
        for i in 0..centres.len() {
            owner[offsets[i]..offsets[i + 1]].fill(i as u32);
        }
        // Counting sort of the members by vertex (stable: centre order kept).
        let n = level.len();
        let mut vertex_offsets = vec![0usize; n + 1];
        for &(v, _) in &members {
            vertex_offsets[v as usize + 1] += 1;
        }
        for v in 0..n {
            vertex_offsets[v + 1] += vertex_offsets[v];
        }
        let mut fill = vertex_offsets.clone();
        let mut by_vertex = vec![0u32; total];
        for (j, &(v, _)) in members.iter().enumerate() {
            by_vertex[fill[v as usize]] = j as u32;
            fill[v as usize] += 1;
        }
        PassGeometry {
            offsets,
            members,
            cells,
            owner,
            vertex_offsets,
            by_vertex,
        }
    }

    fn centre_members(&self, i: usize) -> &[(u32, Vec2)] {
        &self.members[self.offsets[i]..self.offsets[i + 1]]
    }
}

/// The sub-texel shift δ (|δ| ≤ ½ texel per axis) of the matched exemplar
/// neighbourhood at `origin` that minimises ‖s_p − z_p(δ)‖² over the
/// members (colour channels), by `steps` Gauss–Newton steps on the
/// bilinear reads; a step that does not lower the SSD is not taken.
///
/// Why: matches are integer exemplar texels but the members sit at
/// real-valued coordinates, so two overlapping neighbourhoods that agree
/// on the texture can still disagree by a sub-texel offset, and their
/// average blurs. Registering each z_p to the current s makes overlapping
/// predictions agree; it only lowers E_t for the current s, like the
/// search it refines (see [`REFINE_STEPS`] for why the method leaves it off).
pub fn refine_shift(
    ex: &WorkingExemplar,
    origin: Vec2,
    members: &[(u32, Vec2)],
    s: &[f32],
    k: usize,
    kc: usize,
    steps: u32,
) -> Vec2 {
    if steps == 0 || members.is_empty() {
        return Vec2::ZERO;
    }
    let mut z = [0.0f32; 4];
    let mut gx = [0.0f32; 4];
    let mut gy = [0.0f32; 4];
    let kc = kc.min(4);
    let ssd_at = |d: Vec2, z: &mut [f32; 4]| -> f64 {
        let mut e = 0.0f64;
        for &(v, x) in members {
            let p = origin + d + x;
            ex.bilinear_grad(
                p.x,
                p.y,
                &mut z[..kc],
                &mut [0.0; 4][..kc],
                &mut [0.0; 4][..kc],
            );
            for ch in 0..kc {
                let r = (s[v as usize * k + ch] - z[ch]) as f64;
                e += r * r;
            }
        }
        e
    };
    let mut shift = Vec2::ZERO;
    let mut best = f64::INFINITY;
    for _ in 0..steps {
        let (mut a11, mut a12, mut a22, mut b1, mut b2, mut e) = (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
        for &(v, x) in members {
            let p = origin + shift + x;
            ex.bilinear_grad(p.x, p.y, &mut z[..kc], &mut gx[..kc], &mut gy[..kc]);
            for ch in 0..kc {
                let r = (s[v as usize * k + ch] - z[ch]) as f64;
                let (u, w) = (gx[ch] as f64, gy[ch] as f64);
                a11 += u * u;
                a12 += u * w;
                a22 += w * w;
                b1 += u * r;
                b2 += w * r;
                e += r * r;
            }
        }
        if !best.is_finite() {
            best = e;
        }
        let det = a11 * a22 - a12 * a12;
        // A flat patch (no gradient along some direction) or NaN: no step.
        if det.is_nan() || det <= 1e-12 * (a11 * a22).max(1e-30) {
            break;
        }
        let d = Vec2::new(
            ((a22 * b1 - a12 * b2) / det) as f32,
            ((a11 * b2 - a12 * b1) / det) as f32,
        );
        let next = (shift + d).clamp(Vec2::splat(-0.5), Vec2::splat(0.5));
        let e_next = ssd_at(next, &mut z);
        if e_next < best {
            best = e_next;
            shift = next;
        } else {
            break;
        }
    }
    shift
}

/// Σ over centres of w_p ‖s_p − z_p‖² (colour channels), each centre's
/// term computed in parallel and summed in centre order (deterministic).
fn texture_energy(
    geo: &PassGeometry,
    z: &[f32],
    s: &[f32],
    weights: &[f64],
    k: usize,
    kc: usize,
) -> f64 {
    let terms: Vec<f64> = (0..weights.len())
        .into_par_iter()
        .map(|i| {
            let mut e = 0.0f64;
            for j in geo.offsets[i]..geo.offsets[i + 1] {
                let v = geo.members[j].0 as usize;
                for ch in 0..kc {
                    let d = (s[v * k + ch] - z[j * k + ch]) as f64;
                    e += d * d;
                }
            }
            weights[i] * e
        })
        .collect();
    terms.iter().sum()
}

/// Optimises `s` (per level vertex, `exemplar.channels` floats each) in
/// place over every pass. Returns the pass reports.
pub fn optimise(input: &LevelInput<'_>, s: &mut [f32], times: &mut SolveTimes) -> Vec<PassReport> {
    let level = input.level;
    let ex = input.exemplar;
    let k = ex.channels;
    let kc = ex.colour;
    let n = level.len();
    let lambda0 = input
        .transported
        .map(|c| gradient_weights(level, c, k, kc, input.coherence));
    let sigma_ex = super::luminance_sigma(&ex.data, k, kc);
    let mut reports = Vec::new();
    for index in input.passes {
        let window: Window = index.window;
        let cell = input.spacing * window.width as f32 * window.texel;
        let t_geo = Instant::now();
        let cs = centres(level, cell);
        let geo = PassGeometry::build(input, window, &cs);
        times.neighbourhoods += t_geo.elapsed().as_secs_f64();
        let mut report = PassReport {
            width: window.width,
            centres: cs.len(),
            ..Default::default()
        };
        let mut previous: Vec<u32> = Vec::new();
        let mut z = vec![0.0f32; geo.members.len() * k];
        for _ in 0..input.iterations.max(1) {
            let t0 = Instant::now();
            let matches = search_matches(index, ex, &geo, s, cs.len());
            times.search += t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            report.changed = if previous.is_empty() {
                matches.len()
            } else {
                matches
                    .iter()
                    .zip(&previous)
                    .filter(|(a, b)| a != b)
                    .count()
            };
            if !previous.is_empty() && report.changed == 0 {
                times.solve += t1.elapsed().as_secs_f64();
                break;
            }
            report.iterations += 1;
            // z_p at every member: the matched exemplar neighbourhood read
            // at the member's real-valued coordinates, shifted by the
            // sub-texel offset that best registers it to the current s.
            predict(input, &geo, &matches, s, &mut z);
            previous = matches;
            let weights = robust_weights(input, &geo, &z, s, cs.len());
            let (sum, weight, count) = accumulate(&geo, &z, &weights, n, k);
            let e_t = texture_energy(&geo, &z, s, &weights, k, kc);
            // λ_k relative to the (weighted) neighbourhoods covering k.
            let lambda: Option<Vec<f32>> =
                lambda0.as_ref().map(|l| covered_lambda(l, &weight, &count));
            let e_c = |values: &[f32]| -> f64 {
                match (&lambda, input.transported) {
                    (Some(l), Some(c)) => coherence_energy(values, c, l, k, kc),
                    _ => 0.0,
                }
            };
            let before = e_t + e_c(s);
            // The minimiser for fixed z.
            s.par_chunks_mut(k).enumerate().for_each(|(v, out)| {
                let cnt = weight[v];
                let l = lambda.as_ref().map_or(0.0, |l| l[v] as f64);
                if cnt + l <= 0.0 {
                    return;
                }
                for ch in 0..k {
                    let c = input.transported.map_or(0.0, |c| c[v * k + ch] as f64);
                    out[ch] = ((sum[v * k + ch] + l * c) / (cnt + l)) as f32;
                }
            });
            let after = texture_energy(&geo, &z, s, &weights, k, kc) + e_c(s);
            report.energies.push((before, after));
            // Converged: the last iteration lowered the energy by less than
            // `convergence` of it (also when it rose: an approximate search
            // can trade a match for a slightly worse one).
            if let [.., (_, last), (_, now)] = report.energies[..]
                && input.convergence > 0.0
                && last - now < input.convergence as f64 * last
            {
                if let Some(q) = input.histogram {
                    q.apply(s);
                }
                times.solve += t1.elapsed().as_secs_f64();
                break;
            }
            if let Some(q) = input.histogram {
                q.apply(s);
            }
            times.solve += t1.elapsed().as_secs_f64();
        }
        report.prediction_contrast = super::luminance_sigma(&z, k, kc) / sigma_ex.max(1e-12);
        reports.push(report);
    }
    reports
}

/// λ_k relative to the (robust-weighted) neighbourhoods covering k: the
/// gradient weight times their number, scaled by their mean weight.
fn covered_lambda(lambda0: &[f32], weight: &[f64], count: &[u32]) -> Vec<f32> {
    lambda0
        .iter()
        .zip(weight)
        .zip(count)
        .map(|((&l, &w), &c)| {
            let cover = if c > 0 { w / c as f64 } else { 1.0 };
            l * (c.max(1) as f64 * cover) as f32
        })
        .collect()
}

/// E_c (Eq. 2): Σ_k λ_k ‖s(k) − c(k)‖² over the colour channels.
fn coherence_energy(values: &[f32], c: &[f32], lambda: &[f32], k: usize, kc: usize) -> f64 {
    (0..lambda.len())
        .map(|v| {
            let mut e = 0.0f64;
            for ch in 0..kc {
                let d = (values[v * k + ch] - c[v * k + ch]) as f64;
                e += d * d;
            }
            e * lambda[v] as f64
        })
        .sum()
}

/// The exemplar neighbourhood nearest to each centre's current pixel
/// neighbourhood (the search half of the alternation).
fn search_matches(
    index: &SearchIndex,
    ex: &WorkingExemplar,
    geo: &PassGeometry,
    s: &[f32],
    centres: usize,
) -> Vec<u32> {
    let (k, kc) = (ex.channels, ex.colour);
    let g2 = (index.window.grid * index.window.grid) as usize;
    let chunk = (centres / 64).max(16);
    (0..centres)
        .into_par_iter()
        .with_min_len(chunk)
        .map_init(
            || {
                (
                    vec![0.0f32; index.dims],
                    vec![0.0f32; index.dims],
                    vec![0.0f32; kc],
                )
            },
            |(q, buf, mean), i| {
                fill_query(
                    &geo.cells[i * g2..(i + 1) * g2],
                    geo.centre_members(i),
                    s,
                    k,
                    kc,
                    q,
                    mean,
                );
                index.nearest(ex, q, buf).0
            },
        )
        .collect()
}

/// z_p at every member: the matched exemplar neighbourhood read at the
/// member's real-valued coordinates, shifted by the sub-texel offset that
/// best registers it to the current `s`.
fn predict(input: &LevelInput<'_>, geo: &PassGeometry, matches: &[u32], s: &[f32], z: &mut [f32]) {
    let ex = input.exemplar;
    let (k, kc) = (ex.channels, ex.colour);
    let mut slices: Vec<&mut [f32]> = Vec::with_capacity(matches.len());
    let mut rest: &mut [f32] = z;
    for i in 0..matches.len() {
        let (head, tail) = rest.split_at_mut((geo.offsets[i + 1] - geo.offsets[i]) * k);
        slices.push(head);
        rest = tail;
    }
    slices
        .into_par_iter()
        .enumerate()
        .with_min_len(16)
        .for_each(|(i, out)| {
            let (mx, my) = ex.position(matches[i]);
            let members = geo.centre_members(i);
            let shift = refine_shift(
                ex,
                Vec2::new(mx as f32, my as f32),
                members,
                s,
                k,
                kc,
                input.refine,
            );
            let origin = Vec2::new(mx as f32, my as f32) + shift;
            for (o, &(_, x)) in out.chunks_exact_mut(k).zip(members) {
                ex.bilinear(origin.x + x.x, origin.y + x.y, o);
            }
        });
}

/// Robust weight of each neighbourhood, fixed for one minimisation step.
fn robust_weights(
    input: &LevelInput<'_>,
    geo: &PassGeometry,
    z: &[f32],
    s: &[f32],
    centres: usize,
) -> Vec<f64> {
    let (k, kc) = (input.exemplar.channels, input.exemplar.colour);
    (0..centres)
        .into_par_iter()
        .map(|i| {
            let (a, b) = (geo.offsets[i], geo.offsets[i + 1]);
            if input.robust >= 2.0 || a == b {
                return 1.0;
            }
            let mut e = 0.0f64;
            for j in a..b {
                let v = geo.members[j].0 as usize;
                for ch in 0..kc {
                    let d = (s[v * k + ch] - z[j * k + ch]) as f64;
                    e += d * d;
                }
            }
            let mean = e / (b - a) as f64;
            (mean + 1e-6).powf((input.robust as f64 - 2.0) / 2.0)
        })
        .collect()
}

/// Per vertex: Σ w z, Σ w and the number of neighbourhoods covering it,
/// members in centre order.
fn accumulate(
    geo: &PassGeometry,
    z: &[f32],
    weights: &[f64],
    n: usize,
    k: usize,
) -> (Vec<f64>, Vec<f64>, Vec<u32>) {
    let mut sum = vec![0.0f64; n * k];
    let mut weight = vec![0.0f64; n];
    let mut count = vec![0u32; n];
    sum.par_chunks_mut(k)
        .zip(weight.par_iter_mut())
        .zip(count.par_iter_mut())
        .enumerate()
        .with_min_len(256)
        .for_each(|(v, ((acc, wsum), cnt))| {
            let list = &geo.by_vertex[geo.vertex_offsets[v]..geo.vertex_offsets[v + 1]];
            for &j in list {
                let j = j as usize;
                let w = weights[geo.owner[j] as usize];
                *wsum += w;
                for ch in 0..k {
                    acc[ch] += w * z[j * k + ch] as f64;
                }
            }
            *cnt = list.len() as u32;
        });
    (sum, weight, count)
}
