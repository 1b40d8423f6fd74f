//! The exemplar searches side by side (`fluidtex bench --exemplar-search`):
//! for each pass of a level, each search's build time, time per query and
//! agreement with the exact scan on the same queries.
//!
//! Queries stand in for what synthesis asks: a candidate's neighbourhood
//! averaged with another's (up to 40 % of it, the blur the averaging step
//! leaves) plus noise, seeded, so every search answers the same ones.

use std::time::Instant;

use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use super::neighbourhood::Window;
use super::search::{SearchIndex, WorkingExemplar, candidate_vector, ssd};
use crate::exemplar::Exemplar;

/// One search on one pass.
#[derive(Clone, Debug, PartialEq)]
pub struct SearchRow {
    /// Window width w of the pass.
    pub window: u32,
    /// `pca`, `clustered` or `exact`.
    pub search: &'static str,
    /// Seconds to build the index.
    pub build_s: f64,
    /// Microseconds per query (all threads, wall clock / queries).
    pub query_us: f64,
    /// Share of queries answered by the exact optimum.
    pub exact_share: f64,
    /// Share of queries whose answer's SSD over the whole window is within
    /// 10 % of the optimum's.
    pub within_10: f64,
    /// Mean of answer SSD / optimum SSD over the queries.
    pub mean_ratio: f64,
}

/// Seeded synthesis-like queries (module doc) over `window`.
pub fn queries(ex: &WorkingExemplar, window: Window, n: usize, seed: u64) -> Vec<Vec<f32>> {
    let dims = (window.grid * window.grid) as usize * ex.colour;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let (mut a, mut b) = (vec![0.0f32; dims], vec![0.0f32; dims]);
    let n_cand = ex.candidates() as u32;
    (0..n)
        .map(|_| {
            candidate_vector(ex, window, rng.random_range(0..n_cand), &mut a);
            candidate_vector(ex, window, rng.random_range(0..n_cand), &mut b);
            let mix = rng.random::<f32>() * 0.4;
            a.iter()
                .zip(&b)
                .map(|(x, y)| x * (1.0 - mix) + y * mix + 0.1 * (rng.random::<f32>() - 0.5))
                .collect()
        })
        .collect()
}

/// Every search on the passes `sizes` of a working exemplar `texels`
/// wide, `queries` queries each; `checks` for the clustered search (in
/// the widest pass, scaled as the method scales it) and
/// `rerank`, `grid` for the PCA one.
pub fn measure(
    exemplar: &Exemplar,
    texels: u32,
    sizes: &[u32],
    checks: usize,
    (rerank, grid): (usize, u32),
    queries_per_pass: usize,
) -> Vec<SearchRow> {
    let ex = WorkingExemplar::new(exemplar, texels);
    let mut rows = Vec::new();
    for &w in sizes {
        let limit = (ex.width.min(ex.height) - 1) | 1;
        let full = Window {
            width: w.min(limit).max(3),
            grid: w.min(limit).max(3),
            texel: 1.0,
            relaxation: 0,
        };
        let qs = queries(&ex, full, queries_per_pass, 2007 + w as u64);
        // The optimum of each query: the exact scan, timed as the exact row.
        let t = Instant::now();
        let exact = SearchIndex::exact(&ex, full);
        let build = t.elapsed().as_secs_f64();
        let (best, secs) = answer(&exact, &ex, &qs, |q| q.to_vec());
        let optimum: Vec<f32> = best.iter().map(|&(_, d)| d).collect();
        rows.push(row(
            w, "exact", build, secs, &best, &optimum, &ex, full, &qs,
        ));
        let t = Instant::now();
        let widest = sizes.iter().max().copied().unwrap_or(w);
        let checks = super::cluster::checks_for(checks as u32, widest, full.width);
        let clustered = SearchIndex::clustered(&ex, full, checks);
        let build = t.elapsed().as_secs_f64();
        let (found, secs) = answer(&clustered, &ex, &qs, |q| q.to_vec());
        rows.push(row(
            w,
            "clustered",
            build,
            secs,
            &found,
            &optimum,
            &ex,
            full,
            &qs,
        ));
        // The PCA search sees each query as its g × g subsample.
        let sub = Window {
            grid: grid.min(full.width),
            ..full
        };
        let t = Instant::now();
        let pca = SearchIndex::new(&ex, sub, rerank);
        let build = t.elapsed().as_secs_f64();
        let (found, secs) = answer(&pca, &ex, &qs, |q| subsample(q, full, sub, ex.colour));
        rows.push(row(w, "pca", build, secs, &found, &optimum, &ex, full, &qs));
    }
    rows
}

/// Each query's answer, and the wall-clock seconds for all of them.
fn answer(
    index: &SearchIndex,
    ex: &WorkingExemplar,
    qs: &[Vec<f32>],
    view: impl Fn(&[f32]) -> Vec<f32> + Sync,
) -> (Vec<(u32, f32)>, f64) {
    let t = Instant::now();
    let found = qs
        .par_iter()
        .map_init(
            || vec![0.0f32; index.dims],
            |buf, q| index.nearest(ex, &view(q), buf),
        )
        .collect();
    (found, t.elapsed().as_secs_f64())
}

/// The row of one search: its answers judged by SSD over the whole window.
#[allow(clippy::too_many_arguments)]
fn row(
    w: u32,
    search: &'static str,
    build_s: f64,
    secs: f64,
    found: &[(u32, f32)],
    optimum: &[f32],
    ex: &WorkingExemplar,
    full: Window,
    qs: &[Vec<f32>],
) -> SearchRow {
    let mut buf = vec![0.0f32; qs.first().map_or(0, Vec::len)];
    let (mut same, mut close, mut ratio) = (0usize, 0usize, 0.0f64);
    for ((&(i, _), &d_best), q) in found.iter().zip(optimum).zip(qs) {
        candidate_vector(ex, full, i, &mut buf);
        let d = ssd(q, &buf);
        same += usize::from(d <= d_best);
        close += usize::from(d <= 1.1 * d_best);
        ratio += (d / d_best.max(1e-12)) as f64;
    }
    let n = qs.len().max(1) as f64;
    SearchRow {
        window: w,
        search,
        build_s,
        query_us: secs * 1e6 / n,
        exact_share: same as f64 / n,
        within_10: close as f64 / n,
        mean_ratio: ratio / n,
    }
}

/// The g × g subsample of a whole-window vector.
fn subsample(q: &[f32], full: Window, sub: Window, k: usize) -> Vec<f32> {
    let (side, g) = (full.width as usize, sub.grid as usize);
    let stride = sub.stride() as usize;
    let h = (side - 1) / 2 - (g - 1) / 2 * stride;
    let mut out = Vec::with_capacity(g * g * k);
    for b in 0..g {
        for a in 0..g {
            let at = (h + b * stride) * side + h + a * stride;
            out.extend_from_slice(&q[at * k..at * k + k]);
        }
    }
    out
}
