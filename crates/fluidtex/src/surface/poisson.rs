//! Poisson-disk sampling on surfaces (the initial patch distribution and the
//! global placement of new patches; docs/design.md, *Initial distribution*).
//!
//! Dart throwing over a dense pool of candidates (the surface variant of
//! Bridson 2007 / Cook 1986): candidates are drawn uniformly by area with a
//! seeded RNG and accepted in that order when no accepted point lies closer
//! than the spacing. Two points whose normals disagree (dot below a
//! threshold, 0.9 in the 2021 method) never block each other, so both sides
//! of a thin sheet receive samples. With about 30 candidates per final
//! sample, the result is close to maximal: no gap larger than the spacing
//! remains, which is what the patch distribution needs.
//!
//! Neighbour lookups use a uniform hash grid with the spacing as cell size;
//! it is written here rather than borrowed from a k-d tree crate because
//! points are inserted one at a time between queries.

use std::collections::HashMap;

use glam::Vec3;
use rand::Rng;

use super::SurfacePoint;
use crate::mesh::TriMesh;

/// One accepted sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceSample {
    pub location: SurfacePoint,
    pub position: Vec3,
    /// Unit normal of the sample's triangle.
    pub normal: Vec3,
}

/// Incremental Poisson-disk set: accepts a point when no accepted point
/// with an agreeing normal lies within `spacing`.
pub struct DiskSet {
    spacing: f32,
    normal_dot: f32,
    cells: HashMap<(i32, i32, i32), Vec<u32>>,
    points: Vec<(Vec3, Vec3)>,
}

impl DiskSet {
    /// `spacing` in world units; `normal_dot`: points whose normals have a
    /// smaller dot product do not block each other.
    pub fn new(spacing: f32, normal_dot: f32) -> DiskSet {
        DiskSet {
            spacing,
            normal_dot,
            cells: HashMap::new(),
            points: Vec::new(),
        }
    }

    fn cell(&self, p: Vec3) -> (i32, i32, i32) {
        let c = (p / self.spacing).floor();
        (c.x as i32, c.y as i32, c.z as i32)
    }

    /// True when `p` with normal `n` would be accepted.
    pub fn is_free(&self, p: Vec3, n: Vec3) -> bool {
        let (cx, cy, cz) = self.cell(p);
        let r2 = self.spacing * self.spacing;
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(list) = self.cells.get(&(cx + dx, cy + dy, cz + dz)) {
                        for &i in list {
                            let (q, m) = self.points[i as usize];
                            if q.distance_squared(p) < r2 && m.dot(n) >= self.normal_dot {
                                return false;
                            }
                        }
                    }
                }
            }
        }
        true
    }

    /// Inserts `p` if free; returns whether it was inserted.
    pub fn try_insert(&mut self, p: Vec3, n: Vec3) -> bool {
        if !p.is_finite() || !self.is_free(p, n) {
            return false;
        }
        let key = self.cell(p);
        self.cells
            .entry(key)
            .or_default()
            .push(self.points.len() as u32);
        self.points.push((p, n));
        true
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// Uniform random points on a mesh, by area: cumulative triangle areas
/// pick the triangle, Osada et al. 2002's square-root rule the point in it.
pub struct AreaDraw {
    cdf: Vec<f64>,
}

impl AreaDraw {
    pub fn new(mesh: &TriMesh) -> AreaDraw {
        let mut total = 0.0f64;
        let cdf = (0..mesh.triangles.len())
            .map(|t| {
                total += mesh.triangle_area(t) as f64;
                total
            })
            .collect();
        AreaDraw { cdf }
    }

    /// The mesh's area.
    pub fn total(&self) -> f64 {
        self.cdf.last().copied().unwrap_or(0.0)
    }

    /// A point drawn uniformly by area (the mesh must have a triangle; of
    /// zero total area, the last triangle).
    pub fn point<R: Rng>(&self, rng: &mut R) -> SurfacePoint {
        let x = rng.random::<f64>() * self.total();
        let t = (self.cdf.partition_point(|&c| c <= x)).min(self.cdf.len().saturating_sub(1));
        let (r1, r2): (f32, f32) = (rng.random(), rng.random());
        let s = r1.sqrt();
        SurfacePoint::new(t as u32, [1.0 - s, s * (1.0 - r2), s * r2])
    }
}

/// Poisson-disk samples on `mesh` with the given spacing. `candidates_per_sample`
/// \[30] controls how close to maximal the set gets. Deterministic for a given RNG state.
pub fn sample_mesh<R: Rng>(
    mesh: &TriMesh,
    spacing: f32,
    normal_dot: f32,
    candidates_per_sample: f32,
    rng: &mut R,
) -> Vec<SurfaceSample> {
    if mesh.triangles.is_empty() || spacing <= 0.0 || !spacing.is_finite() {
        return Vec::new();
    }
    let draw = AreaDraw::new(mesh);
    let total = draw.total();
    if total <= 0.0 {
        return Vec::new();
    }
    // Hexagonal packing bound: about 1.15 A / s² samples at most.
    let expected = (1.155 * total / (spacing as f64 * spacing as f64)).max(1.0);
    let count = ((expected * candidates_per_sample as f64).ceil() as usize).clamp(16, 4_000_000);
    let mut set = DiskSet::new(spacing, normal_dot);
    let mut out = Vec::new();
    for _ in 0..count {
        let location = draw.point(rng);
        let t = location.triangle as usize;
        let position = location.position(mesh);
        let normal = mesh.triangle_normal(t);
        if set.try_insert(position, normal) {
            out.push(SurfaceSample {
                location,
                position,
                normal,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    use super::*;

    fn sheet(z: f32, flip: bool, n: u32) -> TriMesh {
        crate::atlas::fixtures::square_sheet(n, 0.0, 1.0, z, flip)
    }

    #[test]
    fn spacing_is_respected_and_set_is_nearly_maximal() {
        let mesh = sheet(0.0, false, 10);
        let mut rng = Pcg64::seed_from_u64(7);
        let s = 0.1;
        let pts = sample_mesh(&mesh, s, 0.9, 30.0, &mut rng);
        for (i, a) in pts.iter().enumerate() {
            for b in &pts[i + 1..] {
                assert!(a.position.distance(b.position) >= s);
            }
        }
        // Maximality: every point of a fine grid is within s of a sample.
        for j in 0..=50 {
            for i in 0..=50 {
                let q = Vec3::new(i as f32 / 50.0, j as f32 / 50.0, 0.0);
                let d = pts
                    .iter()
                    .map(|p| p.position.distance(q))
                    .fold(f32::MAX, f32::min);
                assert!(d < 1.15 * s, "gap of {d} at {q}");
            }
        }
    }

    #[test]
    fn opposite_sheets_do_not_block_each_other() {
        // Two coincident-ish sheets 0.01 apart, facing opposite ways: each
        // gets its own full set of samples.
        let mut a = sheet(0.0, false, 8);
        let b = sheet(0.01, true, 8);
        let off = a.positions.len() as u32;
        a.positions.extend_from_slice(&b.positions);
        a.triangles
            .extend(b.triangles.iter().map(|t| t.map(|v| v + off)));
        let mut rng = Pcg64::seed_from_u64(3);
        let pts = sample_mesh(&a, 0.2, 0.9, 30.0, &mut rng);
        let up = pts.iter().filter(|p| p.normal.z > 0.0).count();
        let down = pts.len() - up;
        assert!(up >= 15 && down >= 15, "up {up} down {down}");
        // Same-side control: a single sheet gets about half as many.
        let mut rng = Pcg64::seed_from_u64(3);
        let single = sample_mesh(&sheet(0.0, false, 8), 0.2, 0.9, 30.0, &mut rng).len();
        assert!(pts.len() > single * 3 / 2, "{} vs {single}", pts.len());
    }

    #[test]
    fn same_seed_same_samples() {
        let mesh = sheet(0.0, false, 6);
        let a = sample_mesh(&mesh, 0.15, 0.9, 30.0, &mut Pcg64::seed_from_u64(11));
        let b = sample_mesh(&mesh, 0.15, 0.9, 30.0, &mut Pcg64::seed_from_u64(11));
        let c = sample_mesh(&mesh, 0.15, 0.9, 30.0, &mut Pcg64::seed_from_u64(12));
        assert_eq!(a, b);
        assert_ne!(a, c);
    }
}
