//! Nearest-neighbour search in the exemplar (paper Sec. V-B step 2).
//!
//! **The working exemplar.** Synthesis runs at the points' resolution: one
//! exemplar texel per point spacing. [`WorkingExemplar`] resamples every
//! exemplar channel (colour and extras together) to that size through the
//! exemplar's mip pyramid (trilinear), repeating at the borders as every
//! method does.
//!
//! **The search.** Every texel of the working exemplar is a candidate
//! neighbourhood centre. A neighbourhood is compared as its g × g subsample
//! (colour channels only): 9 × 9 × 3 = 243 numbers. These vectors are
//! reduced by PCA (faer's symmetric eigendecomposition of their covariance,
//! estimated on an evenly strided subset of at most 4096 candidates) to
//! [`PCA_DIMS`] = 8 dimensions and put in a kiddo k-d tree (kiddo is built
//! for low dimensions, < ~10). A query takes the `rerank` nearest
//! candidates in the reduced space (exact k-d tree search there) and
//! returns the one with the smallest full 243-dimensional SSD. Why not the
//! paper's hierarchical clustering: PCA + k-d tree is the standard,
//! maintained route (Hertzmann et al., Lefebvre–Hoppe), the tree is exact
//! in the reduced space, and re-ranking in the full space recovers most of
//! what the reduction loses; [`SearchIndex::brute_force`] is the reference
//! the tests compare with.
//!
//! **The paper's search** (`search = "exact"`, [`SearchIndex::exact`]):
//! the whole w × w neighbourhood (33² × 3 = 3 267 numbers for the widest
//! pass), compared with every candidate by SSD, no reduction. The paper
//! accelerates this search by hierarchical clustering, an approximation of
//! it; the exact scan is what that clustering approximates, and slow: a
//! query costs w² × 3 × (exemplar texels) operations, about 50 M for the
//! widest pass over a 128² working exemplar.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use std::num::NonZeroUsize;

use super::cluster::ClusterTree;
use super::neighbourhood::Window;
use crate::exemplar::Exemplar;

/// Dimensions kept by the PCA.
pub const PCA_DIMS: usize = 8;

/// Largest number of candidates the covariance is estimated on.
const PCA_SAMPLES: usize = 4096;

/// The exemplar resampled to the synthesis resolution, all channels.
pub struct WorkingExemplar {
    pub width: u32,
    pub height: u32,
    /// Floats per texel (colour channels, then extras).
    pub channels: usize,
    /// Colour channels (compared by the search).
    pub colour: usize,
    pub data: Vec<f32>,
}

impl WorkingExemplar {
    /// The exemplar at `width` texels across (height in proportion).
    pub fn new(exemplar: &Exemplar, width: u32) -> WorkingExemplar {
        let (ew, eh) = exemplar.size();
        let width = width.max(4);
        let height = ((width as f64 * eh as f64 / ew.max(1) as f64).round() as u32).max(4);
        let channels = exemplar.total_channels();
        let lod = (ew as f32 / width as f32).log2().max(0.0);
        let mut data = vec![0.0f32; (width * height) as usize * channels];
        use rayon::prelude::*;
        data.par_chunks_mut(width as usize * channels)
            .enumerate()
            .for_each(|(y, row)| {
                for x in 0..width as usize {
                    let (u, v) = (
                        (x as f32 + 0.5) / width as f32,
                        (y as f32 + 0.5) / height as f32,
                    );
                    exemplar.sample_all_lod(u, v, lod, &mut row[x * channels..(x + 1) * channels]);
                }
            });
        WorkingExemplar {
            width,
            height,
            channels,
            colour: exemplar.colour.channels,
            data,
        }
    }

    /// Texel (x, y), repeating.
    #[inline]
    pub fn texel(&self, x: i32, y: i32) -> &[f32] {
        let x = x.rem_euclid(self.width as i32) as usize;
        let y = y.rem_euclid(self.height as i32) as usize;
        let i = (y * self.width as usize + x) * self.channels;
        &self.data[i..i + self.channels]
    }

    /// Bilinear read between texel centres at integer (x, y), repeating;
    /// writes every channel.
    #[inline]
    pub fn bilinear(&self, x: f32, y: f32, out: &mut [f32]) {
        let (fx, fy) = (x.floor(), y.floor());
        let (tx, ty) = (x - fx, y - fy);
        let (ix, iy) = (fx as i32, fy as i32);
        let w = [
            (1.0 - tx) * (1.0 - ty),
            tx * (1.0 - ty),
            (1.0 - tx) * ty,
            tx * ty,
        ];
        let t = [
            self.texel(ix, iy),
            self.texel(ix + 1, iy),
            self.texel(ix, iy + 1),
            self.texel(ix + 1, iy + 1),
        ];
        for c in 0..self.channels {
            out[c] = w[0] * t[0][c] + w[1] * t[1][c] + w[2] * t[2][c] + w[3] * t[3][c];
        }
    }

    /// Bilinear read of the first `out.len()` channels and their x and y
    /// derivatives at (x, y) (texel units, repeating).
    #[inline]
    pub fn bilinear_grad(&self, x: f32, y: f32, out: &mut [f32], gx: &mut [f32], gy: &mut [f32]) {
        let (fx, fy) = (x.floor(), y.floor());
        let (tx, ty) = (x - fx, y - fy);
        let (ix, iy) = (fx as i32, fy as i32);
        let t = [
            self.texel(ix, iy),
            self.texel(ix + 1, iy),
            self.texel(ix, iy + 1),
            self.texel(ix + 1, iy + 1),
        ];
        for c in 0..out.len() {
            let (a, b, d, e) = (t[0][c], t[1][c], t[2][c], t[3][c]);
            let top = a + tx * (b - a);
            let bottom = d + tx * (e - d);
            out[c] = top + ty * (bottom - top);
            gx[c] = (1.0 - ty) * (b - a) + ty * (e - d);
            gy[c] = bottom - top;
        }
    }

    /// Candidate count (one per texel).
    pub fn candidates(&self) -> usize {
        (self.width * self.height) as usize
    }

    /// (x, y) of candidate `i`.
    #[inline]
    pub fn position(&self, i: u32) -> (i32, i32) {
        ((i % self.width) as i32, (i / self.width) as i32)
    }
}

/// The search structure for one window over one working exemplar.
pub struct SearchIndex {
    pub window: Window,
    /// Length of a full search vector (g² × colour channels).
    pub dims: usize,
    mean: Vec<f32>,
    /// PCA_DIMS rows of `dims` values.
    basis: Vec<f32>,
    tree: Option<ImmutableKdTree<f32, PCA_DIMS>>,
    reduced: Vec<[f32; PCA_DIMS]>,
    /// Every candidate's full search vector (`dims` floats each), kept
    /// when it fits in [`FULL_VECTORS_LIMIT`] floats so re-ranking reads
    /// contiguous memory instead of gathering g² texels per candidate.
    full: Vec<f32>,
    rerank: usize,
    /// The paper's hierarchical clustering (`search = "clustered"`).
    cluster: Option<ClusterTree>,
}

/// Most floats kept for the candidates' full search vectors (256 MiB).
const FULL_VECTORS_LIMIT: usize = 64 << 20;

impl SearchIndex {
    pub fn new(ex: &WorkingExemplar, window: Window, rerank: usize) -> SearchIndex {
        use rayon::prelude::*;
        let side = window.grid as usize;
        let dims = side * side * ex.colour;
        let n = ex.candidates();
        let step = n.div_ceil(PCA_SAMPLES).max(1);
        let sample: Vec<u32> = (0..n).step_by(step).map(|i| i as u32).collect();
        let mut vectors = vec![0.0f32; sample.len() * dims];
        vectors
            .par_chunks_mut(dims)
            .zip(&sample)
            .for_each(|(v, &i)| candidate_vector(ex, window, i, v));
        let mut mean = vec![0.0f64; dims];
        for v in vectors.chunks_exact(dims) {
            for (m, &x) in mean.iter_mut().zip(v) {
                *m += x as f64;
            }
        }
        for m in &mut mean {
            *m /= sample.len().max(1) as f64;
        }
        // Covariance (dims × dims), rows in parallel: deterministic (each
        // entry is one sequential sum).
        let cov_rows: Vec<Vec<f64>> = (0..dims)
            .into_par_iter()
            .map(|a| {
                let mut row = vec![0.0f64; dims];
                for v in vectors.chunks_exact(dims) {
                    let xa = v[a] as f64 - mean[a];
                    for (b, r) in row.iter_mut().enumerate().skip(a) {
                        *r += xa * (v[b] as f64 - mean[b]);
                    }
                }
                row
            })
            .collect();
        let cov = faer::Mat::<f64>::from_fn(dims, dims, |a, b| {
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            cov_rows[lo][hi]
        });
        let basis = principal_axes(&cov, dims);
        let mean: Vec<f32> = mean.iter().map(|&m| m as f32).collect();
        let mut index = SearchIndex {
            window,
            dims,
            mean,
            basis,
            tree: None,
            reduced: Vec::new(),
            full: Vec::new(),
            rerank: rerank.max(1),
            cluster: None,
        };
        let reduced: Vec<[f32; PCA_DIMS]> = if n * dims <= FULL_VECTORS_LIMIT {
            let mut full = vec![0.0f32; n * dims];
            full.par_chunks_mut(dims)
                .enumerate()
                .for_each(|(i, v)| candidate_vector(ex, window, i as u32, v));
            let reduced = full.par_chunks(dims).map(|v| index.project(v)).collect();
            index.full = full;
            reduced
        } else {
            (0..n as u32)
                .into_par_iter()
                .map_init(
                    || vec![0.0f32; dims],
                    |buf, i| {
                        candidate_vector(ex, window, i, buf);
                        index.project(buf)
                    },
                )
                .collect()
        };
        index.tree = ImmutableKdTree::new_from_slice(&reduced).ok();
        index.reduced = reduced;
        index
    }

    /// The index of the paper's search (`search = "exact"`): no reduction
    /// and no tree, every query scans every candidate's full vector
    /// (`window.grid` should then be `window.width`: the whole w × w
    /// neighbourhood). The vectors are kept when they fit in
    /// `FULL_VECTORS_LIMIT` (64 M) floats (33 × 33 × 3 over a 128² exemplar:
    /// 53 M), gathered per query otherwise.
    pub fn exact(ex: &WorkingExemplar, window: Window) -> SearchIndex {
        use rayon::prelude::*;
        let side = window.grid as usize;
        let dims = side * side * ex.colour;
        let n = ex.candidates();
        let mut full = Vec::new();
        if n * dims <= FULL_VECTORS_LIMIT {
            full = vec![0.0f32; n * dims];
            full.par_chunks_mut(dims)
                .enumerate()
                .for_each(|(i, v)| candidate_vector(ex, window, i as u32, v));
        }
        SearchIndex {
            window,
            dims,
            mean: Vec::new(),
            basis: Vec::new(),
            tree: None,
            reduced: Vec::new(),
            full,
            rerank: 1,
            cluster: None,
        }
    }

    /// The index of the paper's accelerated search (`search =
    /// "clustered"`): the exact index's whole-window vectors in a k-means
    /// tree ([`cluster`](super::cluster)), a query comparing at least
    /// `checks` candidates.
    pub fn clustered(ex: &WorkingExemplar, window: Window, checks: usize) -> SearchIndex {
        let mut index = SearchIndex::exact(ex, window);
        let full = &index.full;
        let dims = index.dims;
        let tree = ClusterTree::build(ex.candidates(), dims, checks, |i, out| {
            if full.is_empty() {
                candidate_vector(ex, window, i, out);
            } else {
                out.copy_from_slice(&full[i as usize * dims..(i as usize + 1) * dims]);
            }
        });
        index.cluster = Some(tree);
        index
    }

    /// The clustering of a clustered index.
    pub fn cluster(&self) -> Option<&ClusterTree> {
        self.cluster.as_ref()
    }

    /// The reduced coordinates of a full search vector (zeros for an
    /// [`SearchIndex::exact`] index, which has no reduction).
    pub fn project(&self, v: &[f32]) -> [f32; PCA_DIMS] {
        let mut out = [0.0f32; PCA_DIMS];
        if self.basis.is_empty() {
            return out;
        }
        for (k, o) in out.iter_mut().enumerate() {
            let row = &self.basis[k * self.dims..(k + 1) * self.dims];
            let mut s = 0.0f32;
            for ((&x, &m), &b) in v.iter().zip(&self.mean).zip(row) {
                s += (x - m) * b;
            }
            *o = s;
        }
        out
    }

    /// The best candidate for `query` (full vector): PCA k-d tree, then
    /// re-ranking by full SSD; every candidate by full SSD for an exact
    /// index. Returns (candidate, full SSD); ties go to the lower index.
    pub fn nearest(&self, ex: &WorkingExemplar, query: &[f32], buf: &mut [f32]) -> (u32, f32) {
        if let Some(cluster) = &self.cluster {
            let window = self.window;
            return cluster.nearest(query, &self.full, buf, |i, out| {
                candidate_vector(ex, window, i, out)
            });
        }
        let Some(tree) = &self.tree else {
            return self.scan(ex, query, buf);
        };
        let q = self.project(query);
        let k = NonZeroUsize::new(self.rerank.min(self.reduced.len().max(1)))
            .unwrap_or(NonZeroUsize::MIN);
        let found = tree
            .query(&q)
            .nearest_n::<SquaredEuclidean<f32>>(k)
            .execute();
        let mut best = (u32::MAX, f32::INFINITY);
        for item in found {
            let d = if self.full.is_empty() {
                candidate_vector(ex, self.window, item.item, buf);
                ssd(query, buf)
            } else {
                let i = item.item as usize * self.dims;
                ssd(query, &self.full[i..i + self.dims])
            };
            if d < best.1 || (d == best.1 && item.item < best.0) {
                best = (item.item, d);
            }
        }
        if best.0 == u32::MAX {
            best = (0, f32::INFINITY);
        }
        best
    }

    /// Every candidate by full SSD, from the kept vectors when there are
    /// any; ties go to the lower index.
    fn scan(&self, ex: &WorkingExemplar, query: &[f32], buf: &mut [f32]) -> (u32, f32) {
        let mut best = (0u32, f32::INFINITY);
        if self.full.is_empty() {
            for i in 0..ex.candidates() as u32 {
                candidate_vector(ex, self.window, i, buf);
                let d = ssd(query, buf);
                if d < best.1 {
                    best = (i, d);
                }
            }
        } else {
            for (i, v) in self.full.chunks_exact(self.dims).enumerate() {
                let d = ssd(query, v);
                if d < best.1 {
                    best = (i as u32, d);
                }
            }
        }
        best
    }

    /// The k-d tree's nearest candidate in the reduced space (no re-ranking).
    pub fn nearest_reduced(&self, query: &[f32]) -> Option<(u32, f32)> {
        let q = self.project(query);
        let found = self
            .tree
            .as_ref()?
            .query(&q)
            .nearest_one::<SquaredEuclidean<f32>>()
            .execute();
        Some((found.item, found.distance))
    }

    /// Exact nearest candidate in the reduced space by linear scan.
    pub fn brute_force_reduced(&self, query: &[f32]) -> (u32, f32) {
        let q = self.project(query);
        let mut best = (0u32, f32::INFINITY);
        for (i, r) in self.reduced.iter().enumerate() {
            let d: f32 = r.iter().zip(&q).map(|(a, b)| (a - b) * (a - b)).sum();
            if d < best.1 {
                best = (i as u32, d);
            }
        }
        best
    }

    /// Distance in the reduced space from `query` to candidate `i`.
    pub fn reduced_distance(&self, query: &[f32], i: u32) -> f32 {
        let q = self.project(query);
        self.reduced[i as usize]
            .iter()
            .zip(&q)
            .map(|(a, b)| (a - b) * (a - b))
            .sum()
    }

    /// Exact nearest candidate by full SSD (linear scan; the reference).
    pub fn brute_force(&self, ex: &WorkingExemplar, query: &[f32]) -> (u32, f32) {
        let mut buf = vec![0.0f32; self.dims];
        let mut best = (0u32, f32::INFINITY);
        for i in 0..ex.candidates() as u32 {
            candidate_vector(ex, self.window, i, &mut buf);
            let d = ssd(query, &buf);
            if d < best.1 {
                best = (i, d);
            }
        }
        best
    }
}

/// Sum of squared differences.
#[inline]
pub fn ssd(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The g × g search vector of candidate `i` (colour channels).
pub fn candidate_vector(ex: &WorkingExemplar, window: Window, i: u32, out: &mut [f32]) {
    let (cx, cy) = ex.position(i);
    let hg = window.half_grid();
    let s = window.stride() as i32;
    let side = window.grid as usize;
    let k = ex.colour;
    for b in -hg..=hg {
        for a in -hg..=hg {
            let cell = (b + hg) as usize * side + (a + hg) as usize;
            let t = ex.texel(cx + a * s, cy + b * s);
            out[cell * k..cell * k + k].copy_from_slice(&t[..k]);
        }
    }
}

/// The PCA_DIMS eigenvectors of the largest eigenvalues of `cov`, as rows.
fn principal_axes(cov: &faer::Mat<f64>, dims: usize) -> Vec<f32> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::evd;
    let mut basis = vec![0.0f32; PCA_DIMS * dims];
    let mut u = faer::Mat::<f64>::zeros(dims, dims);
    let mut s = faer::diag::Diag::<f64>::zeros(dims);
    let par = faer::Par::Seq;
    let scratch = evd::self_adjoint_evd_scratch::<f64>(
        dims,
        evd::ComputeEigenvectors::Yes,
        par,
        Default::default(),
    );
    let ok = evd::self_adjoint_evd(
        cov.as_ref(),
        s.as_mut(),
        Some(u.as_mut()),
        par,
        MemStack::new(&mut MemBuffer::new(scratch)),
        Default::default(),
    )
    .is_ok();
    if !ok {
        // Fall back to the first coordinate axes.
        for k in 0..PCA_DIMS.min(dims) {
            basis[k * dims + k] = 1.0;
        }
        return basis;
    }
    // Eigenvalues ascend: the last columns are the principal axes.
    for k in 0..PCA_DIMS.min(dims) {
        let col = dims - 1 - k;
        for r in 0..dims {
            basis[k * dims + r] = u[(r, col)] as f32;
        }
    }
    basis
}
