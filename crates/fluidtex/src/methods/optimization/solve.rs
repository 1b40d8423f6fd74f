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
//! λ_k (Eq. 2's gradient weighting): `coherence` × (number of
//! neighbourhoods covering k) × min(g_k / ḡ, 3), g_k the mean colour
//! difference between the transported c at k and at its neighbours and ḡ
//! its mean over the level: the transported texture wins where it has
//! structure and is re-synthesised where transport has blurred it.

use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::lattice::Level;
use super::neighbourhood::{Scratch, Window, build};
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
    /// Robust exponent r of Kwatra et al. 2005: each neighbourhood's terms
    /// are weighted by (mean ‖s_p − z_p‖²)^((r − 2)/2), fixed during an
    /// averaging step; r = 2 is Eq. 1 unweighted.
    pub robust: f32,
}

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
    pub search: f64,
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

/// One centre's result.
struct Matched {
    best: u32,
    members: Vec<(u32, Vec2)>,
    /// z_p at each member, all channels.
    z: Vec<f32>,
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
    let mut reports = Vec::new();
    for index in input.passes {
        let window: Window = index.window;
        let cell = input.spacing * window.width as f32 * window.texel;
        let cs = centres(level, cell);
        let mut report = PassReport {
            width: window.width,
            centres: cs.len(),
            ..Default::default()
        };
        let mut previous: Vec<u32> = Vec::new();
        let chunk = (cs.len() / 32).max(16);
        for _ in 0..input.iterations.max(1) {
            let t0 = Instant::now();
            let snapshot: &[f32] = s;
            let matched: Vec<Matched> = cs
                .par_chunks(chunk)
                .flat_map_iter(|part| {
                    let mut scratch = Scratch::new(level);
                    let mut q = vec![0.0f32; index.dims];
                    let mut buf = vec![0.0f32; index.dims];
                    let mut z = vec![0.0f32; k];
                    part.iter()
                        .map(|&c| {
                            let nb = build(
                                level,
                                c,
                                input.orientation[c as usize],
                                window,
                                snapshot,
                                k,
                                kc,
                                &mut scratch,
                                &mut q,
                            );
                            let (best, _) = index.nearest(ex, &q, &mut buf);
                            let (mx, my) = ex.position(best);
                            let mut zs = Vec::with_capacity(nb.members.len() * k);
                            for &(_, x) in &nb.members {
                                ex.bilinear(mx as f32 + x.x, my as f32 + x.y, &mut z);
                                zs.extend_from_slice(&z);
                            }
                            Matched {
                                best,
                                members: nb.members,
                                z: zs,
                            }
                        })
                        .collect::<Vec<_>>()
                })
                .collect();
            times.search += t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            let matches: Vec<u32> = matched.iter().map(|m| m.best).collect();
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
            previous = matches;
            // Accumulate Σ z and coverage, in centre order.
            let mut sum = vec![0.0f64; n * k];
            let mut count = vec![0u32; n];
            let mut weight = vec![0.0f64; n];
            let mut e_t = 0.0f64;
            let weights: Vec<f64> = matched
                .iter()
                .map(|m| {
                    if input.robust >= 2.0 || m.members.is_empty() {
                        return 1.0;
                    }
                    let mut e = 0.0f64;
                    for (j, &(v, _)) in m.members.iter().enumerate() {
                        for ch in 0..kc {
                            let d = (s[v as usize * k + ch] - m.z[j * k + ch]) as f64;
                            e += d * d;
                        }
                    }
                    let mean = e / m.members.len() as f64;
                    (mean + 1e-6).powf((input.robust as f64 - 2.0) / 2.0)
                })
                .collect();
            for (m, &w) in matched.iter().zip(&weights) {
                for (j, &(v, _)) in m.members.iter().enumerate() {
                    let v = v as usize;
                    count[v] += 1;
                    weight[v] += w;
                    let z = &m.z[j * k..j * k + k];
                    for ch in 0..k {
                        sum[v * k + ch] += w * z[ch] as f64;
                    }
                    for ch in 0..kc {
                        let d = (s[v * k + ch] - z[ch]) as f64;
                        e_t += w * d * d;
                    }
                }
            }
            // λ_k relative to the (weighted) neighbourhoods covering k.
            let lambda: Option<Vec<f32>> = lambda0.as_ref().map(|l| {
                l.iter()
                    .zip(&weight)
                    .zip(&count)
                    .map(|((&l, &w), &c)| {
                        let cover = if c > 0 { w / c as f64 } else { 1.0 };
                        l * (c.max(1) as f64 * cover) as f32
                    })
                    .collect()
            });
            let e_c = |values: &[f32]| -> f64 {
                match (&lambda, input.transported) {
                    (Some(l), Some(c)) => (0..n)
                        .map(|v| {
                            let mut e = 0.0f64;
                            for ch in 0..kc {
                                let d = (values[v * k + ch] - c[v * k + ch]) as f64;
                                e += d * d;
                            }
                            e * l[v] as f64
                        })
                        .sum(),
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
            let mut e_t_after = 0.0f64;
            for (m, &w) in matched.iter().zip(&weights) {
                for (j, &(v, _)) in m.members.iter().enumerate() {
                    let v = v as usize;
                    for ch in 0..kc {
                        let d = (s[v * k + ch] - m.z[j * k + ch]) as f64;
                        e_t_after += w * d * d;
                    }
                }
            }
            let after = e_t_after + e_c(s);
            report.energies.push((before, after));
            times.solve += t1.elapsed().as_secs_f64();
        }
        reports.push(report);
    }
    reports
}
