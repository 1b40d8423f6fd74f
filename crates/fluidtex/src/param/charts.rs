//! Chart segmentation: cutting a triangle mesh into disc-like charts that
//! LSCM can flatten with little distortion.
//!
//! **Method.** Region growing with a normal-cone bound, in the family of
//! Sander et al. 2003 ("Multi-chart geometry images": grow charts from seeds
//! with a priority queue, relocate the seeds to chart centres, regrow) and
//! of the segmentation of Lévy et al. 2002 (charts grown in parallel from
//! seeds restarted at their centroids, small charts merged):
//!
//! 1. **Greedy pass.** The lowest-index unassigned triangle seeds a chart,
//!    which grows through a priority queue of edge-adjacent candidates until
//!    none can join; repeat until every triangle has a chart.
//! 2. **Relaxation** ([`ChartParams::relax_iterations`]). Each chart's seed
//!    moves to its triangle nearest the chart's area-weighted centroid, all
//!    charts are cleared and regrow *simultaneously* from one shared queue,
//!    which makes them compact (Voronoi-like) instead of the crescents a
//!    sequential pass leaves; leftovers get new seeds as in step 1.
//! 3. **Merging.** Charts with fewer than
//!    [`ChartParams::min_chart_triangles`] triangles join the neighbour they
//!    share the longest boundary with, when the union is still a disc and
//!    still within the cone: every chart costs a gutter in the atlas, so
//!    slivers waste texels.
//!
//! **Cost** of candidate t for chart c: `(1 − n_t·N_c) + λ (d / L)²`, with
//! n_t the triangle normal, N_c the chart's area-weighted mean normal, d the
//! distance from t's centroid to the chart seed's, L the diameter of a
//! full-size chart (`√(mean triangle area × max_chart_triangles)`) and λ =
//! [`ChartParams::compactness`]. The normal term grows charts along flat
//! directions first; the distance term keeps flat regions round.
//!
//! **Acceptance.** t joins c only if
//! - `n_t·N_c ≥ cos θ_max` with the mean normal at that moment (the mean
//!   drifts a little as the chart grows on, so the final spread can exceed
//!   θ_max slightly; a chart within 90° of one direction is a height field
//!   over a plane, which LSCM rarely folds, and [`super::flatten`] catches
//!   the folds that remain),
//! - the chart is below its size cap, and
//! - the chart stays a topological disc: t must share one or two edges with
//!   c, each a boundary edge of c (one chart triangle on it), and when it
//!   shares one edge its third vertex must not already be in c.
//!
//! Adding an ear or filling a notch keeps a disc a disc; anything else would
//! close a loop (an annulus, a handle, or a closed sphere), which no planar
//! map can flatten without a cut. A sphere therefore always yields several charts, and fluid meshes
//! with non-manifold edges still give manifold charts.
//!
//! Degenerate triangles ([`crate::param::is_degenerate`]) never join a chart:
//! each becomes a chart of its own (LSCM has no solution for them).
//!
//! Everything is sequential and keyed by (cost, triangle, chart), so the
//! result depends only on the input. Charts are numbered by their lowest
//! triangle index.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::{DVec3, Vec3};

use crate::mesh::Topology;
use crate::param::is_degenerate;

const NONE: u32 = u32::MAX;

/// Parameters of chart segmentation.
#[derive(Clone, Debug, PartialEq)]
pub struct ChartParams {
    /// Largest angle between a triangle's normal and its chart's mean normal
    /// (θ_max, degrees, in (0, 90]). Default: 60. Smaller gives flatter charts (less
    /// area distortion) but more of them (more gutter waste).
    pub max_cone_angle_deg: f32,
    /// Size cap of a chart, in triangles (≥ 1). Default: 4096. Bounds the LSCM
    /// solve per chart and its area distortion on gently curved surfaces.
    pub max_chart_triangles: u32,
    /// Charts with fewer triangles are merged into a neighbour when the
    /// union stays a disc within the cone. Default: 64. 0 disables merging.
    pub min_chart_triangles: u32,
    /// Seed relocation + simultaneous regrowth passes (step 2). Default: 1.
    pub relax_iterations: u32,
    /// Weight λ of the squared seed distance in the growth cost
    /// (dimensionless, ≥ 0). Default: 0.5.
    pub compactness: f32,
}

impl Default for ChartParams {
    fn default() -> Self {
        ChartParams {
            max_cone_angle_deg: 60.0,
            max_chart_triangles: 4096,
            min_chart_triangles: 64,
            relax_iterations: 1,
            compactness: 0.5,
        }
    }
}

/// A partition of a mesh's triangles into charts.
#[derive(Clone, Debug, PartialEq)]
pub struct Segmentation {
    /// Chart index per triangle.
    pub chart_of_triangle: Vec<u32>,
    /// Triangles of each chart, ascending; charts ordered by first triangle.
    pub charts: Vec<Vec<u32>>,
}

/// Segments the mesh `(positions, triangles)` into disc-like charts.
/// `topology` must be built from the same triangles. Indices must be valid
/// (checked by the caller); degenerate triangles become single-triangle charts.
pub fn segment(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    topology: &Topology,
    params: &ChartParams,
) -> Segmentation {
    let mut g = Grower::new(positions, triangles, topology, params);
    g.fill_unassigned();
    for _ in 0..params.relax_iterations {
        let seeds = g.relocated_seeds();
        g.reset();
        for s in seeds {
            g.start_chart(s);
        }
        g.grow();
        g.fill_unassigned();
    }
    if params.min_chart_triangles > 1 {
        g.merge_small(params.min_chart_triangles);
    }
    g.finish()
}

/// Splits one chart (given as its own small mesh) into disc-like pieces by
/// growing from the two triangles farthest apart along the longest axis of
/// its bounding box; used when a chart's LSCM map folds. Returns charts of
/// local triangle indices. Always at least two pieces for two or more
/// usable triangles, so repeated splitting terminates.
pub fn split(positions: &[Vec3], triangles: &[[u32; 3]], params: &ChartParams) -> Segmentation {
    let topology = Topology::new(positions.len(), triangles);
    let mut g = Grower::new(positions, triangles, &topology, params);
    // A split piece must be smaller than its parent.
    g.max_tris = g.max_tris.min((triangles.len() as u32).div_ceil(2).max(1));
    if let Some((lo, hi)) = g.extreme_pair() {
        g.start_chart(lo);
        if hi != lo {
            g.start_chart(hi);
        }
        g.grow();
    }
    g.fill_unassigned();
    g.finish()
}

#[derive(Clone, Copy, Debug)]
struct ChartState {
    normal_sum: DVec3,
    /// `normal_sum` normalised, kept up to date by `assign`.
    mean_normal: Vec3,
    count: u32,
    seed_point: Vec3,
}

struct Grower<'a> {
    tris: &'a [[u32; 3]],
    topo: &'a Topology,
    normal: Vec<Vec3>,
    area: Vec<f32>,
    centroid: Vec<Vec3>,
    usable: Vec<bool>,
    cos_max: f32,
    max_tris: u32,
    inv_length_sq: f32,
    compactness: f32,
    chart_of: Vec<u32>,
    charts: Vec<ChartState>,
    heap: BinaryHeap<Reverse<(u32, u32, u32)>>,
    next_unassigned: usize,
}

impl<'a> Grower<'a> {
    fn new(
        positions: &[Vec3],
        tris: &'a [[u32; 3]],
        topo: &'a Topology,
        params: &ChartParams,
    ) -> Grower<'a> {
        let n = tris.len();
        let mut normal = Vec::with_capacity(n);
        let mut area = Vec::with_capacity(n);
        let mut centroid = Vec::with_capacity(n);
        let mut usable = Vec::with_capacity(n);
        let mut total_area = 0.0f64;
        for tri in tris {
            let [a, b, c] = tri.map(|v| positions[v as usize]);
            let cross = (b - a).cross(c - a);
            normal.push(cross.normalize_or_zero());
            area.push(0.5 * cross.length());
            centroid.push((a + b + c) / 3.0);
            let ok =
                tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2] && !is_degenerate(a, b, c);
            usable.push(ok);
            total_area += 0.5 * cross.length() as f64;
        }
        let max_tris = params.max_chart_triangles.max(1);
        let length_sq = (total_area / n.max(1) as f64) * max_tris as f64;
        let inv_length_sq = if length_sq > 0.0 {
            (1.0 / length_sq) as f32
        } else {
            0.0
        };
        Grower {
            tris,
            topo,
            normal,
            area,
            centroid,
            usable,
            cos_max: params.max_cone_angle_deg.to_radians().cos(),
            max_tris,
            inv_length_sq,
            compactness: params.compactness,
            chart_of: vec![NONE; n],
            charts: Vec::new(),
            heap: BinaryHeap::new(),
            next_unassigned: 0,
        }
    }

    fn reset(&mut self) {
        self.chart_of.fill(NONE);
        self.charts.clear();
        self.heap.clear();
        self.next_unassigned = 0;
    }

    #[inline]
    fn mean_normal(&self, c: u32) -> Vec3 {
        self.charts[c as usize].mean_normal
    }

    fn cost(&self, t: u32, c: u32) -> f32 {
        let s = &self.charts[c as usize];
        let dev = (1.0 - self.normal[t as usize].dot(self.mean_normal(c))).max(0.0);
        let d2 = self.centroid[t as usize].distance_squared(s.seed_point) * self.inv_length_sq;
        dev + self.compactness * d2
    }

    fn start_chart(&mut self, seed: u32) {
        let c = self.charts.len() as u32;
        self.charts.push(ChartState {
            normal_sum: DVec3::ZERO,
            mean_normal: Vec3::ZERO,
            count: 0,
            seed_point: self.centroid[seed as usize],
        });
        self.assign(seed, c);
    }

    fn assign(&mut self, t: u32, c: u32) {
        self.chart_of[t as usize] = c;
        let s = &mut self.charts[c as usize];
        s.normal_sum += (self.normal[t as usize] * self.area[t as usize]).as_dvec3();
        s.mean_normal = s.normal_sum.normalize_or_zero().as_vec3();
        s.count += 1;
        for k in 0..3 {
            for &nb in self.topo.edge_neighbours(t, k) {
                if self.chart_of[nb as usize] == NONE && self.usable[nb as usize] {
                    let key = self.cost(nb, c).max(0.0).to_bits();
                    self.heap.push(Reverse((key, nb, c)));
                }
            }
        }
    }

    fn vertex_in_chart(&self, v: u32, c: u32) -> bool {
        self.topo
            .vertex_triangles(v)
            .iter()
            .any(|&t| self.chart_of[t as usize] == c)
    }

    /// The disc-preserving acceptance test of the module doc.
    fn can_join(&self, t: u32, c: u32) -> bool {
        if self.chart_of[t as usize] != NONE || !self.usable[t as usize] {
            return false;
        }
        let s = &self.charts[c as usize];
        if s.count >= self.max_tris
            || self.normal[t as usize].dot(self.mean_normal(c)) < self.cos_max
        {
            return false;
        }
        let mut shared = 0;
        let mut last_shared = 0;
        for k in 0..3 {
            let on_edge = self
                .topo
                .edge_neighbours(t, k)
                .iter()
                .filter(|&&nb| self.chart_of[nb as usize] == c)
                .count();
            match on_edge {
                0 => {}
                1 => {
                    shared += 1;
                    last_shared = k;
                }
                _ => return false,
            }
        }
        match shared {
            1 => !self.vertex_in_chart(self.tris[t as usize][(last_shared + 2) % 3], c),
            2 => true,
            _ => false,
        }
    }

    fn grow(&mut self) {
        while let Some(Reverse((_, t, c))) = self.heap.pop() {
            if self.can_join(t, c) {
                self.assign(t, c);
            }
        }
    }

    /// Step 1: seeds every unassigned triangle in index order.
    fn fill_unassigned(&mut self) {
        while self.next_unassigned < self.tris.len() {
            let t = self.next_unassigned;
            self.next_unassigned += 1;
            if self.chart_of[t] != NONE {
                continue;
            }
            if self.usable[t] {
                self.start_chart(t as u32);
                self.grow();
            }
        }
    }

    /// Per chart, its triangle nearest its area-weighted centroid.
    fn relocated_seeds(&self) -> Vec<u32> {
        let nc = self.charts.len();
        let mut sum = vec![(DVec3::ZERO, 0.0f64); nc];
        for (t, &c) in self.chart_of.iter().enumerate() {
            if c != NONE {
                let a = self.area[t] as f64;
                sum[c as usize].0 += self.centroid[t].as_dvec3() * a;
                sum[c as usize].1 += a;
            }
        }
        let centre: Vec<Vec3> = sum
            .iter()
            .map(|(p, a)| {
                if *a > 0.0 {
                    (*p / *a).as_vec3()
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        let mut best = vec![(f32::INFINITY, NONE); nc];
        for (t, &c) in self.chart_of.iter().enumerate() {
            if c != NONE {
                let d = self.centroid[t].distance_squared(centre[c as usize]);
                if d < best[c as usize].0 {
                    best[c as usize] = (d, t as u32);
                }
            }
        }
        best.into_iter()
            .map(|(_, t)| t)
            .filter(|&t| t != NONE)
            .collect()
    }

    /// The usable triangles with extreme centroids along the bounding box's
    /// longest axis (lowest index on ties).
    fn extreme_pair(&self) -> Option<(u32, u32)> {
        let usable: Vec<usize> = (0..self.tris.len()).filter(|&t| self.usable[t]).collect();
        let &first = usable.first()?;
        let (mut lo, mut hi) = (self.centroid[first], self.centroid[first]);
        for &t in &usable {
            lo = lo.min(self.centroid[t]);
            hi = hi.max(self.centroid[t]);
        }
        let ext = hi - lo;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let (mut a, mut b) = (first, first);
        for &t in &usable {
            if self.centroid[t][axis] < self.centroid[a][axis] {
                a = t;
            }
            if self.centroid[t][axis] > self.centroid[b][axis] {
                b = t;
            }
        }
        Some((a as u32, b as u32))
    }

    /// Step 3: merges charts below `min_tris` triangles into a neighbour.
    fn merge_small(&mut self, min_tris: u32) {
        let nc = self.charts.len();
        let mut members: Vec<Vec<u32>> = vec![Vec::new(); nc];
        for (t, &c) in self.chart_of.iter().enumerate() {
            if c != NONE {
                members[c as usize].push(t as u32);
            }
        }
        let mut order: Vec<u32> = (0..nc as u32)
            .filter(|&c| self.charts[c as usize].count < min_tris)
            .collect();
        order.sort_by_key(|&c| (self.charts[c as usize].count, c));
        for a in order {
            let count = self.charts[a as usize].count;
            if count == 0 || count >= min_tris {
                continue;
            }
            // Neighbour charts by number of shared edge incidences.
            let mut tally: Vec<(u32, u32)> = Vec::new();
            for &t in &members[a as usize] {
                for nb in self.topo.triangle_neighbours(t) {
                    let b = self.chart_of[nb as usize];
                    if b != a && b != NONE {
                        match tally.iter_mut().find(|(c, _)| *c == b) {
                            Some(entry) => entry.1 += 1,
                            None => tally.push((b, 1)),
                        }
                    }
                }
            }
            tally.sort_by_key(|&(b, n)| (Reverse(n), b));
            for (b, _) in tally {
                if self.can_merge(a, b, &members) {
                    let moved = std::mem::take(&mut members[a as usize]);
                    for &t in &moved {
                        self.chart_of[t as usize] = b;
                    }
                    members[b as usize].extend(moved);
                    let sa = self.charts[a as usize];
                    let sb = &mut self.charts[b as usize];
                    sb.normal_sum += sa.normal_sum;
                    sb.mean_normal = sb.normal_sum.normalize_or_zero().as_vec3();
                    sb.count += sa.count;
                    self.charts[a as usize].count = 0;
                    self.charts[a as usize].normal_sum = DVec3::ZERO;
                    break;
                }
            }
        }
    }

    /// True when chart `a` can join chart `b`: size cap, cone, and the union
    /// of the two discs is a disc (they meet along one simple path of edges
    /// and touch nowhere else).
    fn can_merge(&self, a: u32, b: u32, members: &[Vec<u32>]) -> bool {
        let (sa, sb) = (&self.charts[a as usize], &self.charts[b as usize]);
        if sa.count + sb.count > self.max_tris {
            return false;
        }
        let mean = (sa.normal_sum + sb.normal_sum)
            .normalize_or_zero()
            .as_vec3();
        let within = |t: &u32| self.normal[*t as usize].dot(mean) >= self.cos_max;
        if !members[a as usize].iter().all(within) || !members[b as usize].iter().all(within) {
            return false;
        }
        let mut edges: Vec<(u32, u32)> = Vec::new();
        let mut verts: Vec<u32> = Vec::new();
        for &t in &members[a as usize] {
            let tri = self.tris[t as usize];
            for k in 0..3 {
                let on_b = self
                    .topo
                    .edge_neighbours(t, k)
                    .iter()
                    .filter(|&&nb| self.chart_of[nb as usize] == b)
                    .count();
                if on_b > 1 {
                    return false;
                }
                if on_b == 1 {
                    let (u, v) = (tri[k], tri[(k + 1) % 3]);
                    edges.push((u.min(v), u.max(v)));
                }
                verts.push(tri[k]);
            }
        }
        if edges.is_empty() {
            return false;
        }
        let n_edges = edges.len();
        edges.sort_unstable();
        edges.dedup();
        if edges.len() != n_edges {
            // An edge interior to `a` also touches `b`: non-manifold union.
            return false;
        }
        verts.sort_unstable();
        verts.dedup();
        let shared_verts: Vec<u32> = verts
            .into_iter()
            .filter(|&v| self.vertex_in_chart(v, b))
            .collect();
        is_simple_path(&edges, &shared_verts)
    }

    fn finish(self) -> Segmentation {
        let Grower {
            tris,
            chart_of,
            charts,
            ..
        } = self;
        // Renumber: charts (including degenerate singletons) by first triangle.
        let mut new_id = vec![NONE; charts.len()];
        let mut out_charts: Vec<Vec<u32>> = Vec::new();
        let mut chart_of_triangle = vec![NONE; tris.len()];
        for (t, &c) in chart_of.iter().enumerate() {
            let id = if c == NONE {
                // Unusable (degenerate) triangle: a chart of its own.
                out_charts.push(Vec::new());
                (out_charts.len() - 1) as u32
            } else {
                if new_id[c as usize] == NONE {
                    out_charts.push(Vec::new());
                    new_id[c as usize] = (out_charts.len() - 1) as u32;
                }
                new_id[c as usize]
            };
            chart_of_triangle[t] = id;
            out_charts[id as usize].push(t as u32);
        }
        Segmentation {
            chart_of_triangle,
            charts: out_charts,
        }
    }
}

/// True when `edges` (sorted, unique vertex pairs) form one simple open path
/// whose vertex set is exactly `verts` (sorted, unique).
fn is_simple_path(edges: &[(u32, u32)], verts: &[u32]) -> bool {
    let mut ends: Vec<u32> = edges.iter().flat_map(|&(u, v)| [u, v]).collect();
    ends.sort_unstable();
    let mut path_verts = ends.clone();
    path_verts.dedup();
    if path_verts != verts || path_verts.len() != edges.len() + 1 {
        return false;
    }
    let mut degree_one = Vec::new();
    let mut i = 0;
    while i < ends.len() {
        let mut j = i;
        while j < ends.len() && ends[j] == ends[i] {
            j += 1;
        }
        match j - i {
            1 => degree_one.push(ends[i]),
            2 => {}
            _ => return false,
        }
        i = j;
    }
    if degree_one.len() != 2 {
        return false;
    }
    // Walk from one end; a path plus a disjoint cycle would stop early.
    let mut visited = 1;
    let (mut prev, mut cur) = (u32::MAX, degree_one[0]);
    loop {
        let next = edges.iter().find_map(|&(u, v)| {
            if u == cur && v != prev {
                Some(v)
            } else if v == cur && u != prev {
                Some(u)
            } else {
                None
            }
        });
        match next {
            Some(n) => {
                prev = cur;
                cur = n;
                visited += 1;
                if visited > path_verts.len() {
                    return false;
                }
            }
            None => break,
        }
    }
    visited == path_verts.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::fixtures::icosphere;
    use crate::mesh::TriMesh;

    fn grid(n: u32) -> TriMesh {
        let mut pos = Vec::new();
        for j in 0..n {
            for i in 0..n {
                pos.push(Vec3::new(i as f32, j as f32, 0.0));
            }
        }
        let mut tris = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = j * n + i;
                tris.push([a, a + 1, a + n + 1]);
                tris.push([a, a + n + 1, a + n]);
            }
        }
        TriMesh::new(pos, tris)
    }

    fn run(mesh: &TriMesh, params: &ChartParams) -> Segmentation {
        let topo = Topology::new(mesh.positions.len(), &mesh.triangles);
        segment(&mesh.positions, &mesh.triangles, &topo, params)
    }

    /// Partition, disc topology (connected, χ = 1, a boundary) and manifold
    /// edges of every chart.
    fn assert_disc_partition(mesh: &TriMesh, seg: &Segmentation) {
        let mut seen = vec![false; mesh.triangles.len()];
        for (c, tris) in seg.charts.iter().enumerate() {
            assert!(
                tris.windows(2).all(|w| w[0] < w[1]),
                "chart {c} not ascending"
            );
            for &t in tris {
                assert!(!seen[t as usize], "triangle {t} in two charts");
                seen[t as usize] = true;
                assert_eq!(seg.chart_of_triangle[t as usize], c as u32);
            }
            let (local, src) = mesh.submesh(tris);
            let topo = Topology::new(src.len(), &local.triangles);
            assert_eq!(topo.components().1, 1, "chart {c} not connected");
            let mut edges: Vec<(u32, u32)> = local
                .triangles
                .iter()
                .flat_map(|t| {
                    (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3])))
                })
                .collect();
            edges.sort_unstable();
            let all = edges.len();
            edges.dedup();
            assert!(all <= 2 * edges.len(), "chart {c} has a non-manifold edge");
            let chi = src.len() as i64 - edges.len() as i64 + tris.len() as i64;
            assert_eq!(chi, 1, "chart {c} is not a disc");
            assert!(topo.boundary_edge_count() >= 3);
        }
        assert!(seen.iter().all(|&s| s), "a triangle has no chart");
        // Charts are numbered by first triangle.
        assert!(seg.charts.windows(2).all(|w| w[0][0] < w[1][0]));
    }

    #[test]
    fn a_flat_square_is_one_chart() {
        let mesh = grid(12);
        let seg = run(&mesh, &ChartParams::default());
        assert_eq!(seg.charts.len(), 1);
        assert_disc_partition(&mesh, &seg);
    }

    #[test]
    fn the_size_cap_holds_with_and_without_merging() {
        let mesh = grid(31); // 1800 triangles
        for min in [0, 64] {
            let params = ChartParams {
                max_chart_triangles: 100,
                min_chart_triangles: min,
                ..ChartParams::default()
            };
            let seg = run(&mesh, &params);
            assert!(seg.charts.len() >= 18);
            assert!(
                seg.charts.iter().all(|c| c.len() <= 100),
                "{:?}",
                seg.charts.iter().map(Vec::len).collect::<Vec<_>>()
            );
            assert_disc_partition(&mesh, &seg);
        }
    }

    #[test]
    fn sphere_charts_are_discs_within_the_cone() {
        let mesh = icosphere(10);
        for angle in [30.0f32, 60.0, 89.0] {
            let params = ChartParams {
                max_cone_angle_deg: angle,
                ..ChartParams::default()
            };
            let seg = run(&mesh, &params);
            assert!(seg.charts.len() >= 2);
            assert_disc_partition(&mesh, &seg);
            // The cone is tested against the mean normal when a triangle
            // joins; the mean then drifts slightly (0.2° here), hence 1°.
            let cos = (angle + 1.0).to_radians().cos();
            for (c, tris) in seg.charts.iter().enumerate() {
                let mean: Vec3 = tris
                    .iter()
                    .map(|&t| mesh.triangle_cross(t as usize))
                    .sum::<Vec3>()
                    .normalize();
                for &t in tris {
                    let n = mesh.triangle_normal(t as usize);
                    assert!(
                        n.dot(mean) >= cos,
                        "chart {c} triangle {t} outside the {angle}° cone"
                    );
                }
            }
        }
    }

    #[test]
    fn non_manifold_fins_give_manifold_charts() {
        // Three quads (six triangles) sharing the edge 0-1.
        let mut pos = vec![Vec3::ZERO, Vec3::Z];
        let mut tris = Vec::new();
        for k in 0..3 {
            let a = k as f32 * std::f32::consts::TAU / 3.0;
            let d = Vec3::new(a.cos(), a.sin(), 0.0);
            let b = pos.len() as u32;
            pos.push(d);
            pos.push(d + Vec3::Z);
            tris.push([0, b, b + 1]);
            tris.push([0, b + 1, 1]);
        }
        let mesh = TriMesh::new(pos, tris);
        let params = ChartParams {
            max_cone_angle_deg: 90.0,
            ..ChartParams::default()
        };
        let seg = run(&mesh, &params);
        assert!(seg.charts.len() >= 2);
        assert_disc_partition(&mesh, &seg);
    }

    #[test]
    fn merging_removes_small_charts_on_a_bumpy_sphere() {
        let mesh = crate::atlas::fixtures::liquid_blob(4000, 5);
        let without = run(
            &mesh,
            &ChartParams {
                min_chart_triangles: 0,
                ..ChartParams::default()
            },
        );
        let with = run(&mesh, &ChartParams::default());
        assert_disc_partition(&mesh, &with);
        let small = |s: &Segmentation| s.charts.iter().filter(|c| c.len() < 64).count();
        assert!(with.charts.len() < without.charts.len());
        assert!(small(&with) < small(&without));
    }

    #[test]
    fn simple_paths_are_told_from_other_edge_sets() {
        let v = |x: &[u32]| x.to_vec();
        assert!(is_simple_path(&[(0, 1), (1, 2), (2, 3)], &v(&[0, 1, 2, 3])));
        assert!(is_simple_path(&[(4, 7)], &v(&[4, 7])));
        // Touching elsewhere (vertex 9 shared but not on the path).
        assert!(!is_simple_path(&[(0, 1), (1, 2)], &v(&[0, 1, 2, 9])));
        // A cycle, a fork, a path plus a separate cycle, two paths.
        assert!(!is_simple_path(&[(0, 1), (0, 2), (1, 2)], &v(&[0, 1, 2])));
        assert!(!is_simple_path(
            &[(0, 1), (0, 2), (0, 3)],
            &v(&[0, 1, 2, 3])
        ));
        assert!(!is_simple_path(
            &[(0, 1), (1, 2), (5, 6), (5, 7), (6, 7)],
            &v(&[0, 1, 2, 5, 6, 7])
        ));
        assert!(!is_simple_path(&[(0, 1), (2, 3)], &v(&[0, 1, 2, 3])));
    }

    #[test]
    fn split_halves_a_chart_into_discs() {
        let mesh = grid(10);
        let seg = split(&mesh.positions, &mesh.triangles, &ChartParams::default());
        assert!(seg.charts.len() >= 2);
        assert!(
            seg.charts
                .iter()
                .all(|c| c.len() <= mesh.triangles.len().div_ceil(2))
        );
        assert_disc_partition(&mesh, &seg);
    }
}
