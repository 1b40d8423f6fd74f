//! The paper's accelerated search: a hierarchical clustering of the
//! exemplar's neighbourhoods (2007 Sec. VII, after the tree-structured
//! vector quantisation of Wei and Levoy 2000, its ref. \[6]).
//!
//! **What the tree is.** Every candidate's whole w × w neighbourhood
//! (colour channels, no subsample, no reduction) is a vector. The root
//! holds all of them; a node with more than [`LEAF`] members is split by
//! k-means into [`BRANCHING`] children, recursively, and each child keeps
//! its members' mean as its code vector. This is a k-means tree: Wei and
//! Levoy's TSVQ is the case k = 2 with a greedy descent; a wider split and
//! a descent that may come back to the next-best branches (Muja and Lowe's
//! best-bin-first over a hierarchical k-means tree) buys back most of what
//! the greedy descent misses for the same number of distances.
//!
//! **A query** descends to the nearest code vector at each node, queueing
//! the other children by their distance, compares the leaf's members by
//! full SSD, and then opens the queued branches nearest first until
//! `checks` candidates have been compared. The answer is the best
//! candidate compared; `checks` ≥ the candidate count makes it the exact
//! scan's answer.
//!
//! **Why our own.** The crates that build k-means trees over dense float
//! vectors (FLANN bindings, `hnsw`-style graphs) need C++ or answer by an
//! insertion-order-dependent graph; ours is small, deterministic (fixed
//! seeds, parallel steps that each write their own slot) and works on the
//! candidate vectors the other searches already gather.
//!
//! **Cost.** The tree is built once per working exemplar and pass (the
//! method caches it per level): the k-means steps of a node run on at most
//! `KMEANS_SAMPLE` (4096) of its members, then every member is assigned once,
//! so building costs about (members × BRANCHING × dims) per tree level.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// Children of a split node. Eight keeps the tree shallow (a 128² working
/// exemplar is five levels deep) while each descent step costs only eight
/// distances.
pub const BRANCHING: usize = 8;

/// Most members of a leaf.
pub const LEAF: usize = 16;

/// Lloyd iterations of a split.
const KMEANS_ITERATIONS: usize = 6;

/// Most members a split's k-means steps run on (every member is assigned
/// to the resulting centres once afterwards).
const KMEANS_SAMPLE: usize = 4096;

/// Seed of the k-means initialisation (the tree depends on the exemplar
/// alone, never on the run's seed, so every run of an exemplar shares it).
const SEED: u64 = 2000;

/// Candidates a query compares in a pass of width `width` when `checks`
/// is the widest pass's count: (widest / width)² times as many, so every
/// pass compares about as many numbers per query (a narrow window's
/// vectors are short, and a greedy descent misses more of its optima).
pub fn checks_for(checks: u32, widest: u32, width: u32) -> usize {
    let scale = (widest as f64 / width.max(1) as f64).powi(2).max(1.0);
    (checks as f64 * scale).round() as usize
}

/// One node: a leaf owns `order[start..end]`; a split node's children are
/// `nodes[first..first + count]`.
#[derive(Clone, Copy, Debug)]
struct Node {
    start: u32,
    end: u32,
    first: u32,
    count: u32,
}

/// A k-means tree over candidate vectors `0..n`.
pub struct ClusterTree {
    dims: usize,
    nodes: Vec<Node>,
    /// Code vector of node i at `centres[i * dims..]` (the root's is unused).
    centres: Vec<f32>,
    /// Candidates, permuted so that every node's members are contiguous.
    order: Vec<u32>,
    checks: usize,
}

/// Sum of squared differences over eight lanes, summed in a fixed order:
/// deterministic and vectorisable, unlike a sequential f32 sum.
#[inline]
pub fn ssd_lanes(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            let d = x[l] - y[l];
            acc[l] += d * d;
        }
    }
    let mut tail = 0.0f32;
    for (x, y) in ra.iter().zip(rb) {
        tail += (x - y) * (x - y);
    }
    ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7])) + tail
}

/// [`ssd_lanes`], or any value above `bound` as soon as the partial sum
/// passes it (checked every 64 floats): a leaf's candidates are compared
/// against the best so far, and most of them lose within the first rows
/// of the window.
#[inline]
pub fn ssd_lanes_bounded(a: &[f32], b: &[f32], bound: f32) -> f32 {
    const BLOCK: usize = 64;
    let mut acc = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(BLOCK), b.chunks_exact(BLOCK));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for (xs, ys) in x.chunks_exact(8).zip(y.chunks_exact(8)) {
            for l in 0..8 {
                let d = xs[l] - ys[l];
                acc[l] += d * d;
            }
        }
        let partial =
            ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
        if partial > bound {
            return partial;
        }
    }
    let rest = ssd_lanes(ra, rb);
    ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7])) + rest
}

/// A queued branch, nearest first; ties to the lower node.
#[derive(PartialEq)]
struct Branch(f32, u32);

impl Eq for Branch {}

impl Ord for Branch {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

impl PartialOrd for Branch {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl ClusterTree {
    /// The tree over `n` vectors of `dims` floats, `vector(i, buf)` writing
    /// vector i into `buf`; a query compares at least `checks` candidates.
    pub fn build<F>(n: usize, dims: usize, checks: usize, vector: F) -> ClusterTree
    where
        F: Fn(u32, &mut [f32]) + Sync,
    {
        let mut tree = ClusterTree {
            dims,
            nodes: vec![Node {
                start: 0,
                end: n as u32,
                first: 0,
                count: 0,
            }],
            centres: vec![0.0; dims],
            order: (0..n as u32).collect(),
            checks: checks.max(1),
        };
        // Breadth first, so node numbers (and the seeds drawn from them)
        // do not depend on the thread count.
        let mut next = 0;
        while next < tree.nodes.len() {
            let node = tree.nodes[next];
            let members = (node.end - node.start) as usize;
            if members > LEAF {
                tree.split(next, &vector);
            }
            next += 1;
        }
        tree
    }

    /// Splits node `at` by k-means; leaves it a leaf when its members
    /// cannot be separated (all equal).
    fn split<F>(&mut self, at: usize, vector: &F)
    where
        F: Fn(u32, &mut [f32]) + Sync,
    {
        let dims = self.dims;
        let node = self.nodes[at];
        let members: Vec<u32> = self.order[node.start as usize..node.end as usize].to_vec();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(SEED ^ (at as u64).wrapping_mul(0x9E37_79B9));
        // The members the k-means steps run on: an even stride.
        let step = members.len().div_ceil(KMEANS_SAMPLE).max(1);
        let sample: Vec<u32> = members.iter().step_by(step).copied().collect();
        let data: Vec<f32> = gather(&sample, dims, vector);
        let mut centres = seed_centres(&data, dims, BRANCHING, &mut rng);
        let k = centres.len() / dims;
        if k < 2 {
            return;
        }
        for _ in 0..KMEANS_ITERATIONS {
            let labels = assign(&data, dims, &centres);
            let moved = recentre(&data, dims, &labels, &mut centres);
            if !moved {
                break;
            }
        }
        // Every member to its nearest centre, in chunks so a large node
        // never holds all its vectors at once.
        let mut labels = Vec::with_capacity(members.len());
        for chunk in members.chunks(KMEANS_SAMPLE) {
            let data = gather(chunk, dims, vector);
            labels.extend(assign(&data, dims, &centres));
        }
        let mut groups: Vec<Vec<u32>> = vec![Vec::new(); k];
        for (&m, &l) in members.iter().zip(&labels) {
            groups[l as usize].push(m);
        }
        groups.retain(|g| !g.is_empty());
        if groups.len() < 2 {
            return;
        }
        // The code vectors are the groups' means over all members.
        let first = self.nodes.len() as u32;
        let mut start = node.start;
        for g in &groups {
            let end = start + g.len() as u32;
            self.order[start as usize..end as usize].copy_from_slice(g);
            self.nodes.push(Node {
                start,
                end,
                first: 0,
                count: 0,
            });
            self.centres.extend(mean(g, dims, vector));
            start = end;
        }
        self.nodes[at].first = first;
        self.nodes[at].count = groups.len() as u32;
    }

    /// The candidate nearest to `query` among those the descent compares,
    /// with its SSD (eight-lane sum). Candidate vectors are read from
    /// `full` (`dims` floats each) when it is not empty, else written into
    /// `buf` by `vector`. Ties go to the lower candidate.
    pub fn nearest<F>(&self, query: &[f32], full: &[f32], buf: &mut [f32], vector: F) -> (u32, f32)
    where
        F: Fn(u32, &mut [f32]),
    {
        let dims = self.dims;
        let mut best = (u32::MAX, f32::INFINITY);
        let mut checked = 0usize;
        let mut queue = BinaryHeap::new();
        queue.push(Branch(0.0, 0));
        while let Some(Branch(_, mut at)) = queue.pop() {
            if checked >= self.checks {
                break;
            }
            // Down to a leaf, queueing the branches not taken.
            loop {
                let node = self.nodes[at as usize];
                if node.count == 0 {
                    break;
                }
                let mut near = (u32::MAX, f32::INFINITY);
                for c in node.first..node.first + node.count {
                    let centre = &self.centres[c as usize * dims..(c as usize + 1) * dims];
                    let d = ssd_lanes(query, centre);
                    if d < near.1 {
                        if near.0 != u32::MAX {
                            queue.push(Branch(near.1, near.0));
                        }
                        near = (c, d);
                    } else {
                        queue.push(Branch(d, c));
                    }
                }
                if near.0 == u32::MAX {
                    break;
                }
                at = near.0;
            }
            let node = self.nodes[at as usize];
            for &i in &self.order[node.start as usize..node.end as usize] {
                let d = if full.is_empty() {
                    vector(i, buf);
                    ssd_lanes_bounded(query, buf, best.1)
                } else {
                    let v = &full[i as usize * dims..(i as usize + 1) * dims];
                    ssd_lanes_bounded(query, v, best.1)
                };
                if d < best.1 || (d == best.1 && i < best.0) {
                    best = (i, d);
                }
                checked += 1;
            }
        }
        if best.0 == u32::MAX {
            best = (0, f32::INFINITY);
        }
        best
    }

    /// Nodes in the tree (for tests and the build report).
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Members of every leaf, in tree order (each candidate exactly once).
    pub fn leaves(&self) -> Vec<&[u32]> {
        self.nodes
            .iter()
            .filter(|n| n.count == 0)
            .map(|n| &self.order[n.start as usize..n.end as usize])
            .collect()
    }
}

/// Vectors of `ids`, concatenated.
fn gather<F>(ids: &[u32], dims: usize, vector: &F) -> Vec<f32>
where
    F: Fn(u32, &mut [f32]) + Sync,
{
    let mut data = vec![0.0f32; ids.len() * dims];
    data.par_chunks_mut(dims)
        .zip(ids)
        .for_each(|(v, &i)| vector(i, v));
    data
}

/// Mean of the vectors of `ids`, summed in f64 in member order.
fn mean<F>(ids: &[u32], dims: usize, vector: &F) -> Vec<f32>
where
    F: Fn(u32, &mut [f32]) + Sync,
{
    let mut sum = vec![0.0f64; dims];
    let mut buf = vec![0.0f32; dims];
    for &i in ids {
        vector(i, &mut buf);
        for (s, &x) in sum.iter_mut().zip(&buf) {
            *s += x as f64;
        }
    }
    let n = ids.len().max(1) as f64;
    sum.iter().map(|&s| (s / n) as f32).collect()
}

/// k-means++ seeding: the first centre drawn uniformly, each next one with
/// probability proportional to its squared distance to the nearest centre
/// so far. Stops early when every vector coincides with a centre.
fn seed_centres(data: &[f32], dims: usize, k: usize, rng: &mut impl Rng) -> Vec<f32> {
    let n = data.len() / dims;
    let mut centres = Vec::with_capacity(k * dims);
    let first = rng.random_range(0..n);
    centres.extend_from_slice(&data[first * dims..(first + 1) * dims]);
    let mut near: Vec<f32> = data
        .par_chunks(dims)
        .map(|v| ssd_lanes(v, &centres[..dims]))
        .collect();
    while centres.len() / dims < k {
        let total: f64 = near.iter().map(|&d| d as f64).sum();
        if total <= 0.0 {
            break;
        }
        let mut pick = rng.random::<f64>() * total;
        let mut chosen = n - 1;
        for (i, &d) in near.iter().enumerate() {
            pick -= d as f64;
            if pick < 0.0 {
                chosen = i;
                break;
            }
        }
        let c = data[chosen * dims..(chosen + 1) * dims].to_vec();
        near.par_iter_mut()
            .zip(data.par_chunks(dims))
            .for_each(|(d, v)| *d = d.min(ssd_lanes(v, &c)));
        centres.extend(c);
    }
    centres
}

/// The nearest centre of each vector (ties to the lower centre).
fn assign(data: &[f32], dims: usize, centres: &[f32]) -> Vec<u32> {
    data.par_chunks(dims)
        .map(|v| nearest_centre(v, centres, dims).0)
        .collect()
}

/// (index, SSD) of the centre nearest to `v`.
fn nearest_centre(v: &[f32], centres: &[f32], dims: usize) -> (u32, f32) {
    let mut best = (0u32, f32::INFINITY);
    for (c, centre) in centres.chunks_exact(dims).enumerate() {
        let d = ssd_lanes(v, centre);
        if d < best.1 {
            best = (c as u32, d);
        }
    }
    best
}

/// Moves each centre to the mean of its vectors (an empty cluster keeps
/// its centre). Returns whether any label set changed a centre.
fn recentre(data: &[f32], dims: usize, labels: &[u32], centres: &mut [f32]) -> bool {
    let k = centres.len() / dims;
    let mut sums = vec![0.0f64; k * dims];
    let mut counts = vec![0usize; k];
    for (v, &l) in data.chunks_exact(dims).zip(labels) {
        let l = l as usize;
        counts[l] += 1;
        for (s, &x) in sums[l * dims..(l + 1) * dims].iter_mut().zip(v) {
            *s += x as f64;
        }
    }
    let mut moved = false;
    for c in 0..k {
        if counts[c] == 0 {
            continue;
        }
        for d in 0..dims {
            let m = (sums[c * dims + d] / counts[c] as f64) as f32;
            if m != centres[c * dims + d] {
                moved = true;
                centres[c * dims + d] = m;
            }
        }
    }
    moved
}
