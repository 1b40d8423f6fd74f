//! Random points spread by repulsion and connected by re-tiling: the 2007
//! paper's point placement (Sec. IV-A), selected by
//! `optimization.placement = "repulsion"` (the default is the subdivision
//! [`lattice`](super::lattice); `docs/departures.md` compares the two).
//!
//! **Points.** The levels are built coarse to fine and nested, as in Turk's
//! surface texture synthesis, whose procedure the paper follows: the
//! coarsest level's points are drawn at random over the fluid surface (by
//! area) and spread by surface-restricted point repulsion (Turk 1991); each
//! finer level keeps every coarser point where it is and adds new random
//! points, which alone move, repelled by all. So level ℓ is the first
//! `counts[ℓ]` points and copying values up a level is exact at the shared
//! points, as it is on the lattice. Each level holds about 2A / (√3 d²)
//! points for spacing d = h·2^ℓ: the density of a hexagonal packing, the
//! lattice's too.
//!
//! **Repulsion.** Each point is pushed by every point within
//! r = [`RADIUS`]·d whose normal agrees (the other side of a thin sheet
//! does not push), with a force falling linearly from 1 at distance 0 to 0
//! at r (Turk 1991's radius, 2·√(A/n), is 1.86 hexagonal spacings). The
//! push is taken in the tangent plane, capped at half a spacing, and the
//! moved point is projected back onto the fluid surface. All points move
//! at once from the previous positions, so the result does not depend on
//! the order (or the thread count) in which they are visited.
//!
//! **Re-tiling.** The paper re-tiles the surface with the new points by
//! Turk 1992's mutual tessellation, triangulated with the Triangle
//! library. Here each level's points are connected by the dual of their
//! Voronoi partition restricted to the surface: samples at about a third
//! of the level's spacing (the same steps on every fluid edge, so that
//! neighbouring triangles agree along their edge) label each sample with its nearest point
//! facing the same way, and every sample triangle whose three corners carry
//! three different labels gives the level a triangle, in the fluid's
//! orientation (a triangle found once each way cancels). Edges then join
//! points that are neighbours along the surface, not only in space. This
//! step departs from the paper's procedure (the ledger says so); the
//! synthesis needs only a mesh whose edges join surface neighbours.
//!
//! Own code: no maintained crate places points by repulsion on a surface
//! or re-tiles one (Triangle is C and planar); kiddo's k-d trees find the
//! neighbours and parry's BVH ([`SurfaceIndex`]) projects onto the surface.

use std::num::NonZeroUsize;

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::level::Level;
use crate::mesh::TriMesh;
use crate::surface::poisson::AreaDraw;
use crate::surface::{SurfaceIndex, SurfacePoint};

/// Repulsion iterations per level \[20]: the paper names no count; after
/// 20 the spread of nearest-neighbour distances on a plane no longer falls
/// (tested by `repulsion_evens_the_spacing`).
pub const REPULSION_ITERATIONS: u32 = 20;

/// Repulsion radius in spacings (Turk 1991's 2·√(A/n) for a hexagonal packing).
pub const RADIUS: f32 = 1.86;

/// Move per unit of force, in spacings.
const STEP: f32 = 0.2;

/// Spacing of the re-tiling samples, in the level's spacings.
const TILE_SAMPLES: f32 = 1.0 / 3.0;

/// Points of every level, each level's mesh, and what locating a surface
/// point among them needs.
pub struct Scatter {
    /// Level ℓ's points are the first `counts[ℓ]` points.
    pub counts: Vec<usize>,
    /// Level ℓ (its vertex i is point i).
    pub levels: Vec<Level>,
    trees: Vec<Option<ImmutableKdTree<f32, 3>>>,
    fluid_positions: Vec<Vec3>,
    fluid_normals: Vec<Vec3>,
}

/// The fluid surface as the placement reads it.
struct Surface<'a> {
    mesh: &'a TriMesh,
    index: SurfaceIndex,
    normals: Vec<Vec3>,
    draw: AreaDraw,
}

impl<'a> Surface<'a> {
    fn new(mesh: &'a TriMesh) -> Surface<'a> {
        Surface {
            mesh,
            index: SurfaceIndex::new(mesh),
            normals: mesh.vertex_normals(),
            draw: AreaDraw::new(mesh),
        }
    }

    /// Position and unit normal at `at` (the triangle's normal where the
    /// vertex normals cancel).
    fn point(&self, at: SurfacePoint) -> (Vec3, Vec3) {
        let n = at.interpolate(&self.mesh.triangles, &self.normals);
        let n = n.try_normalize().unwrap_or_else(|| {
            (self.mesh.triangle_normal(at.triangle as usize)).normalize_or(Vec3::Z)
        });
        (at.position(self.mesh), n)
    }

    /// A point drawn uniformly by area.
    fn random(&self, rng: &mut Pcg64) -> (Vec3, Vec3) {
        self.point(self.draw.point(rng))
    }

    /// The surface point closest to `x` within `reach`.
    fn project(&self, x: Vec3, reach: f32) -> Option<(Vec3, Vec3)> {
        let hit = self.index.closest(x, reach)?;
        Some(self.point(hit.location))
    }
}

fn tree_of(points: &[Vec3]) -> Option<ImmutableKdTree<f32, 3>> {
    let flat: Vec<[f32; 3]> = points.iter().map(|p| p.to_array()).collect();
    ImmutableKdTree::new_from_slice(&flat).ok()
}

impl Scatter {
    /// `levels` nested levels of points at spacing h·2^ℓ on `mesh`
    /// (non-empty), drawn from `seed`.
    pub fn new(mesh: &TriMesh, h: f32, levels: usize, seed: u64) -> Scatter {
        Scatter::with_iterations(mesh, h, levels, seed, REPULSION_ITERATIONS)
    }

    /// [`Scatter::new`] with `iterations` rounds of repulsion per level.
    fn with_iterations(
        mesh: &TriMesh,
        h: f32,
        levels: usize,
        seed: u64,
        iterations: u32,
    ) -> Scatter {
        let levels = levels.max(1);
        let surface = Surface::new(mesh);
        let area = mesh.area();
        let mut positions: Vec<Vec3> = Vec::new();
        let mut normals: Vec<Vec3> = Vec::new();
        let mut counts = vec![0usize; levels];
        for l in (0..levels).rev() {
            let d = h * (1u32 << l) as f32;
            let target = (2.0 * area / (3f64.sqrt() * (d as f64).powi(2))).round() as usize;
            let fixed = positions.len();
            // Drawn from the level's spacing, not its index: a level is the
            // same whatever the number of finer ones below it.
            let mut rng =
                Pcg64::seed_from_u64(crate::seed::mix(seed, 0x5ca7, u64::from(d.to_bits())));
            for _ in fixed..target.max(fixed).max(3) {
                let (p, n) = surface.random(&mut rng);
                positions.push(p);
                normals.push(n);
            }
            sort_block(&mut positions, &mut normals, fixed);
            repel(&surface, &mut positions, &mut normals, fixed, d, iterations);
            sort_block(&mut positions, &mut normals, fixed);
            counts[l] = positions.len();
        }
        let mut trees = Vec::with_capacity(levels);
        let mut meshes = Vec::with_capacity(levels);
        for (l, &c) in counts.iter().enumerate() {
            let d = h * (1u32 << l) as f32;
            let tree = tree_of(&positions[..c]);
            let triangles = match &tree {
                Some(t) => retile(&surface, &normals[..c], t, d),
                None => Vec::new(),
            };
            let mut local = vec![u32::MAX; positions.len()];
            for (i, x) in local.iter_mut().take(c).enumerate() {
                *x = i as u32;
            }
            meshes.push(Level::new(
                1 << l,
                positions[..c].to_vec(),
                normals[..c].to_vec(),
                (0..c as u32).collect(),
                local,
                triangles,
            ));
            trees.push(tree);
        }
        Scatter {
            counts,
            levels: meshes,
            trees,
            fluid_positions: mesh.positions.clone(),
            fluid_normals: surface.normals,
        }
    }

    /// The finest level's points.
    pub fn positions(&self) -> &[Vec3] {
        &self.levels[0].positions
    }

    pub fn normals(&self) -> &[Vec3] {
        &self.levels[0].normals
    }

    /// The level of stride `stride` (clamped to the levels built).
    pub fn level_index(&self, stride: u32) -> usize {
        (stride.max(1).trailing_zeros() as usize).min(self.levels.len() - 1)
    }

    /// Position and normal of fluid triangle `corners` at `bary`.
    pub fn fluid_point(&self, corners: [u32; 3], bary: [f32; 3]) -> (Vec3, Vec3) {
        let mut x = Vec3::ZERO;
        let mut n = Vec3::ZERO;
        for (v, w) in corners.into_iter().zip(bary) {
            x += self.fluid_positions[v as usize] * w;
            n += self.fluid_normals[v as usize] * w;
        }
        (x, n.normalize_or_zero())
    }

    /// [`Lattice::prolong`](super::lattice::Lattice::prolong) on scattered points: a point of `to` that
    /// `from` holds keeps its value (the levels are nested), any other
    /// takes the interpolation at its position in `from`'s mesh.
    pub fn prolong(&self, from: &Level, values: &[f32], k: usize, to: &Level, out: &mut [f32]) {
        let lf = self.level_index(from.stride);
        (out[..to.len() * k].par_chunks_mut(k))
            .enumerate()
            .for_each(|(i, o)| {
                let at = from.local[to.ids[i] as usize];
                if at != u32::MAX {
                    o.copy_from_slice(&values[at as usize * k..at as usize * k + k]);
                    return;
                }
                o.fill(0.0);
                for (p, w) in self.locate(lf, to.positions[i], to.normals[i]) {
                    let src = from.local[p as usize] as usize * k;
                    for (c, x) in o.iter_mut().enumerate() {
                        *x += w * values[src + c];
                    }
                }
            });
    }

    /// Three points of level `l` and their weights at `x` (normal `n`):
    /// the barycentric weights of `x` projected into the level triangle
    /// that holds it best, among the triangles around the nearest points
    /// facing the same way; outside every one of them by more than half a
    /// triangle (a hole of the re-tiling), the nearest point alone.
    pub fn locate(&self, l: usize, x: Vec3, n: Vec3) -> [(u32, f32); 3] {
        let l = l.min(self.levels.len() - 1);
        let Some(tree) = &self.trees[l] else {
            return [(0, 1.0), (0, 0.0), (0, 0.0)];
        };
        let level = &self.levels[l];
        let near = nearest_four(tree, x);
        let facing: Vec<u32> = (near.iter().copied())
            .filter(|&c| level.normals[c as usize].dot(n) > 0.0)
            .collect();
        let nearest = facing.first().or(near.first()).copied().unwrap_or(0);
        let mut best: Option<(f32, [u32; 3], [f32; 3])> = None;
        for &c in &facing {
            for &t in level.vertex_triangles(c) {
                let tri = level.triangles[t as usize];
                let Some(w) = projected_bary(x, tri.map(|v| level.positions[v as usize])) else {
                    continue;
                };
                let score = w[0].min(w[1]).min(w[2]);
                if best.is_none_or(|b| score > b.0) {
                    best = Some((score, tri, w));
                }
            }
        }
        match best {
            Some((score, tri, w)) if score > -0.5 => {
                let w = w.map(|w| w.max(0.0));
                let s = w[0] + w[1] + w[2];
                [0, 1, 2].map(|k| (tri[k], w[k] / s))
            }
            _ => [(nearest, 1.0), (nearest, 0.0), (nearest, 0.0)],
        }
    }
}

/// Orders the points from `fixed` on along a space-filling curve: nearby
/// points get nearby ids, so the repulsion's and the synthesis's walks
/// from a point to its neighbours stay in cache (in the drawing order
/// every step was a miss; the synthesis's neighbourhoods took 3.7× the
/// lattice's time).
fn sort_block(positions: &mut Vec<Vec3>, normals: &mut Vec<Vec3>, fixed: usize) {
    let order = crate::surface::query_order(&positions[fixed..]);
    let (p, n): (Vec<Vec3>, Vec<Vec3>) = (order.iter())
        .map(|&i| (positions[fixed + i as usize], normals[fixed + i as usize]))
        .unzip();
    positions.truncate(fixed);
    positions.extend(p);
    normals.truncate(fixed);
    normals.extend(n);
}

/// Barycentric weights of `x` projected into the plane of `p`, `None` for
/// a degenerate triangle.
fn projected_bary(x: Vec3, p: [Vec3; 3]) -> Option<[f32; 3]> {
    let (e0, e1, e2) = (p[1] - p[0], p[2] - p[0], x - p[0]);
    let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let (d20, d21) = (e2.dot(e0), e2.dot(e1));
    let det = d00 * d11 - d01 * d01;
    if det.is_nan() || det <= 1e-12 * d00 * d11 {
        return None;
    }
    let v = (d11 * d20 - d01 * d21) / det;
    let w = (d00 * d21 - d01 * d20) / det;
    Some([1.0 - v - w, v, w])
}

/// Moves the points from `fixed` on by `iterations` rounds of
/// repulsion at spacing `d`, each projected back onto the surface.
fn repel(
    surface: &Surface<'_>,
    positions: &mut [Vec3],
    normals: &mut [Vec3],
    fixed: usize,
    d: f32,
    iterations: u32,
) {
    let r = RADIUS * d;
    for _ in 0..iterations {
        if positions.len() <= fixed {
            return;
        }
        let Some(tree) = tree_of(positions) else {
            return;
        };
        let (pos, nor) = (&*positions, &*normals);
        let moved: Vec<(Vec3, Vec3)> = (fixed..pos.len())
            .into_par_iter()
            .map(|i| {
                let (p, n) = (pos[i], nor[i]);
                let mut near = tree
                    .query(&p.to_array())
                    .within::<SquaredEuclidean<f32>>(r * r)
                    .execute();
                near.sort_unstable_by_key(|c| c.item);
                let mut f = Vec3::ZERO;
                for c in near {
                    let j = c.item as usize;
                    let e = p - pos[j];
                    let dist = e.length();
                    if j == i || nor[j].dot(n) <= 0.0 || dist <= 1e-6 * d {
                        continue;
                    }
                    f += e / dist * (1.0 - dist / r);
                }
                let step = (f - n * n.dot(f)) * (STEP * d);
                let step = step.clamp_length_max(0.5 * d);
                surface.project(p + step, 2.0 * d).unwrap_or((p, n))
            })
            .collect();
        for (k, (p, n)) in moved.into_iter().enumerate() {
            positions[fixed + k] = p;
            normals[fixed + k] = n;
        }
    }
}

/// The nearest of `points` to `x` whose normal agrees with `n` (among the
/// four nearest; the nearest of all when none agrees).
fn nearest_facing(tree: &ImmutableKdTree<f32, 3>, normals: &[Vec3], x: Vec3, n: Vec3) -> u32 {
    let near = nearest_four(tree, x);
    (near.iter())
        .find(|&&c| normals[c as usize].dot(n) > 0.0)
        .or(near.first())
        .copied()
        .unwrap_or(0)
}

/// The four points of `tree` nearest to `x`, nearest first (ties by id,
/// so the order does not depend on how the tree was built).
fn nearest_four(tree: &ImmutableKdTree<f32, 3>, x: Vec3) -> Vec<u32> {
    let mut near = tree
        .query(&x.to_array())
        .nearest_n::<SquaredEuclidean<f32>>(NonZeroUsize::new(4).unwrap_or(NonZeroUsize::MIN))
        .execute();
    near.sort_unstable_by(|a, b| a.distance.total_cmp(&b.distance).then(a.item.cmp(&b.item)));
    near.into_iter().map(|c| c.item).collect()
}

/// The triangles connecting the points of `tree` (normals `normals`,
/// spacing `d`): the dual of their Voronoi partition restricted to the
/// surface, read off samples at about a third of `d` (every fluid triangle
/// split into the same number of steps per edge).
fn retile(
    surface: &Surface<'_>,
    normals: &[Vec3],
    tree: &ImmutableKdTree<f32, 3>,
    d: f32,
) -> Vec<[u32; 3]> {
    let mesh = surface.mesh;
    // One step count for every triangle, so that two triangles sample
    // their shared edge at the same points: per-triangle counts left
    // Voronoi vertices on edges between counts undetected or doubled
    // (on a sphere of 2,265 points, χ = −12 instead of 2).
    let n = ((mesh.mean_edge_length() / (d * TILE_SAMPLES)).ceil() as u32).clamp(1, 128);
    // (sorted corners, +1 when the triangle runs in their cyclic order).
    let mut found: Vec<([u32; 3], i32)> = (0..mesh.triangles.len())
        .into_par_iter()
        .flat_map_iter(|t| {
            // Samples (i, j), i + j ≤ n, row by row in i; weights
            // ((n − i − j)/n, i/n, j/n) on the corners.
            let mut labels = Vec::with_capacity(((n + 1) * (n + 2) / 2) as usize);
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let (wb, wc) = (i as f32 / n as f32, j as f32 / n as f32);
                    let at = SurfacePoint::new(t as u32, [1.0 - wb - wc, wb, wc]);
                    let (x, normal) = surface.point(at);
                    labels.push(nearest_facing(tree, normals, x, normal));
                }
            }
            let id = |i: u32, j: u32| (i * (n + 1) - i * i.saturating_sub(1) / 2 + j) as usize;
            let mut out = Vec::new();
            let mut add = |a: usize, b: usize, c: usize| {
                let l = [labels[a], labels[b], labels[c]];
                if l[0] != l[1] && l[1] != l[2] && l[0] != l[2] {
                    out.push(oriented(l));
                }
            };
            for i in 0..n {
                for j in 0..(n - i) {
                    add(id(i, j), id(i + 1, j), id(i, j + 1));
                    if i + j + 1 < n {
                        add(id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                    }
                }
            }
            out
        })
        .collect();
    found.sort_unstable();
    let mut out = Vec::new();
    let mut k = 0;
    while k < found.len() {
        let key = found[k].0;
        let mut net = 0;
        while k < found.len() && found[k].0 == key {
            net += found[k].1;
            k += 1;
        }
        match net.signum() {
            1 => out.push(key),
            -1 => out.push([key[0], key[2], key[1]]),
            _ => {}
        }
    }
    out
}

/// The corners sorted, and +1 when `t` runs in their cyclic order, −1 when
/// against it.
fn oriented(t: [u32; 3]) -> ([u32; 3], i32) {
    let r = t
        .iter()
        .position(|&v| v == t.iter().copied().min().unwrap_or(v));
    let [x, p, q] = match r {
        Some(1) => [t[1], t[2], t[0]],
        Some(2) => [t[2], t[0], t[1]],
        _ => t,
    };
    if p < q {
        ([x, p, q], 1)
    } else {
        ([x, q, p], -1)
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;

    /// A flat square \[-1, 1]² at height `z`, n × n quads, facing +z (or −z
    /// when `flip`).
    fn square(n: u32, z: f32, flip: bool) -> TriMesh {
        crate::atlas::fixtures::square_sheet(n, -1.0, 1.0, z, flip)
    }

    /// Distance from each point to its nearest other point, for the points
    /// inside |x|, |y| < 0.8 (away from the square's rim).
    fn nearest_distances(points: &[Vec3]) -> Vec<f32> {
        let inner = |p: &Vec3| p.x.abs() < 0.8 && p.y.abs() < 0.8;
        (points.iter().enumerate())
            .filter(|(_, p)| inner(p))
            .map(|(i, p)| {
                (points.iter().enumerate())
                    .filter(|&(j, _)| j != i)
                    .map(|(_, q)| p.distance(*q))
                    .fold(f32::INFINITY, f32::min)
            })
            .collect()
    }

    /// (smallest, coefficient of variation).
    fn spread(d: &[f32]) -> (f32, f32) {
        let n = d.len() as f32;
        let mean = d.iter().sum::<f32>() / n;
        let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / n;
        (
            d.iter().copied().fold(f32::INFINITY, f32::min),
            var.sqrt() / mean,
        )
    }

    #[test]
    fn repulsion_evens_the_spacing() {
        let mesh = square(16, 0.0, false);
        let h = 0.05;
        let spread_after = |iterations| {
            let s = Scatter::with_iterations(&mesh, h, 1, 7, iterations);
            // Area 4: about 2·4 / (√3 h²) points.
            let expected = 8.0 / (3f32.sqrt() * h * h);
            assert!(
                (s.counts[0] as f32 - expected).abs() < 1.0,
                "{}",
                s.counts[0]
            );
            assert!(s.positions().iter().all(|p| p.z == 0.0 && p.x.abs() <= 1.0));
            spread(&nearest_distances(s.positions()))
        };
        let (random_min, random_cv) = spread_after(0);
        let (min, cv) = spread_after(REPULSION_ITERATIONS);
        let (_, cv_more) = spread_after(2 * REPULSION_ITERATIONS);
        // Random points clump (the control); repelled ones keep apart.
        assert!(random_min < 0.1 * h && random_cv > 0.4);
        assert!(min > 0.6 * h && cv < 0.1, "{min} {cv}");
        // Twice the iterations do not spread them much more evenly.
        assert!(cv_more > 0.7 * cv, "{cv} {cv_more}");
    }

    #[test]
    fn levels_are_nested_and_the_same_seed_gives_the_same_points() {
        let mesh = square(8, 0.0, false);
        let a = Scatter::new(&mesh, 0.06, 3, 3);
        let expected = |l: i32| 8.0 / (3f32.sqrt() * (0.06 * 2f32.powi(l)).powi(2));
        for l in 0..3 {
            assert!((a.counts[l] as f32 - expected(l as i32)).abs() < 1.0);
            let level = &a.levels[l];
            assert_eq!(level.len(), a.counts[l]);
            assert_eq!(level.positions[..], a.positions()[..a.counts[l]]);
            assert_eq!(level.stride, 1 << l);
        }
        let b = Scatter::new(&mesh, 0.06, 3, 3);
        assert_eq!(a.positions(), b.positions());
        assert_eq!(a.levels[0].triangles, b.levels[0].triangles);
        let c = Scatter::new(&mesh, 0.06, 3, 4);
        assert_ne!(a.positions(), c.positions());
        // The coarse levels do not depend on how many finer ones follow.
        let two = Scatter::new(&mesh, 0.12, 2, 3);
        assert_eq!(
            two.positions()[..two.counts[1]],
            a.positions()[..a.counts[2]]
        );
    }

    /// Edge → number of triangles holding it, and χ = V − E + F.
    fn edges_and_euler(level: &Level) -> (HashMap<(u32, u32), u32>, i64) {
        let mut edges = HashMap::new();
        for t in &level.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        let used: std::collections::HashSet<u32> =
            level.triangles.iter().flatten().copied().collect();
        let chi = used.len() as i64 - edges.len() as i64 + level.triangles.len() as i64;
        (edges, chi)
    }

    #[test]
    fn retiling_a_sphere_gives_a_closed_oriented_mesh() {
        let mesh = crate::atlas::fixtures::icosphere(16);
        let h = 0.08;
        for (seed, l) in [(5, 0), (5, 1), (6, 0), (7, 0)] {
            let s = Scatter::new(&mesh, h, l + 1, seed);
            let level = &s.levels[l];
            let (edges, chi) = edges_and_euler(level);
            let manifold = edges.values().filter(|&&c| c == 2).count();
            // Every point is connected; the sphere is closed (χ = 2) with
            // every edge between two triangles, all facing outwards.
            assert!((0..level.len() as u32).all(|v| level.vertex_triangles(v).len() >= 3));
            assert_eq!(chi, 2);
            assert_eq!(manifold, edges.len());
            for t in &level.triangles {
                let p = t.map(|v| level.positions[v as usize]);
                let n = (p[1] - p[0]).cross(p[2] - p[0]);
                assert!(n.dot(p[0] + p[1] + p[2]) > 0.0);
                // Edges join neighbours: none longer than twice the
                // repulsion radius (spacing h·2^l).
                for k in 0..3 {
                    assert!(p[k].distance(p[(k + 1) % 3]) < 2.0 * RADIUS * h * (1 << l) as f32);
                }
            }
        }
    }

    #[test]
    fn the_two_sides_of_a_thin_sheet_stay_apart() {
        // Two squares 0.02 apart facing away from each other, spacing 0.05:
        // closer in space than their points' spacing, never connected.
        let (top, bottom) = (square(10, 0.01, false), square(10, -0.01, true));
        let offset = top.positions.len() as u32;
        let mut positions = top.positions.clone();
        positions.extend_from_slice(&bottom.positions);
        let mut triangles = top.triangles.clone();
        triangles.extend(bottom.triangles.iter().map(|t| t.map(|v| v + offset)));
        let sheet = TriMesh::new(positions, triangles);
        let s = Scatter::new(&sheet, 0.05, 1, 9);
        let level = &s.levels[0];
        let side = |v: u32| level.positions[v as usize].z > 0.0;
        let top_count = (0..level.len() as u32).filter(|&v| side(v)).count();
        assert!(top_count > level.len() / 3 && top_count < 2 * level.len() / 3);
        assert!(level.triangles.len() > level.len());
        for t in &level.triangles {
            assert!(t.iter().all(|&v| side(v) == side(t[0])), "{t:?}");
        }
        // Each side's points face their side.
        for v in 0..level.len() as u32 {
            assert_eq!(level.normals[v as usize].z > 0.0, side(v));
        }
    }

    #[test]
    fn locating_reproduces_a_linear_function() {
        let mesh = square(8, 0.0, false);
        let s = Scatter::new(&mesh, 0.05, 2, 1);
        let f = |p: Vec3| 2.0 * p.x - p.y + 0.5;
        let mut rng = Pcg64::seed_from_u64(4);
        for l in 0..2 {
            let level = &s.levels[l];
            let values: Vec<f32> = level.positions.iter().map(|&p| f(p)).collect();
            let mut worst = 0.0f32;
            for _ in 0..500 {
                let x = Vec3::new(
                    rng.random_range(-0.8..0.8),
                    rng.random_range(-0.8..0.8),
                    0.0,
                );
                let w = s.locate(l, x, Vec3::Z);
                assert!(w.iter().all(|&(_, w)| (0.0..=1.0).contains(&w)));
                assert!((w.iter().map(|&(_, w)| w).sum::<f32>() - 1.0).abs() < 1e-5);
                let got: f32 = w.iter().map(|&(v, w)| w * values[v as usize]).sum();
                worst = worst.max((got - f(x)).abs());
            }
            // Linear interpolation inside a containing triangle is exact.
            assert!(worst < 1e-4, "level {l}: {worst}");
            // At a point itself, all the weight is on it.
            let w = s.locate(l, level.positions[5], Vec3::Z);
            let on_it: f32 = w.iter().filter(|&&(v, _)| v == 5).map(|&(_, w)| w).sum();
            assert!(on_it > 0.999, "{w:?}");
        }
    }
}
