//! Locations on a triangle mesh and the queries that produce them.
//!
//! Patch vertices, atlas texels and Poisson-disk samples all live "on the
//! surface": a [`SurfacePoint`] names the triangle and barycentric
//! coordinates, and every per-vertex attribute (position, velocity, normal)
//! is interpolated *at* it. [`SurfaceIndex`] answers closest-point queries
//! through a BVH; [`velocity`] samples the flow at arbitrary points.

pub mod bvh;
pub mod poisson;
pub mod velocity;

use glam::{Vec2, Vec3};

pub use bvh::{SurfaceHit, SurfaceIndex, map_in_query_order, query_order};

use crate::mesh::TriMesh;

/// A point on a triangle mesh: triangle index and barycentric coordinates
/// (non-negative, summing to 1, weight `bary[k]` on corner k).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    pub triangle: u32,
    pub bary: [f32; 3],
}

impl SurfacePoint {
    pub fn new(triangle: u32, bary: [f32; 3]) -> Self {
        SurfacePoint { triangle, bary }
    }

    /// Interpolates any per-vertex quantity at this location.
    #[inline]
    pub fn interpolate<T>(&self, triangles: &[[u32; 3]], values: &[T]) -> T
    where
        T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
    {
        let [a, b, c] = triangles[self.triangle as usize];
        values[a as usize] * self.bary[0]
            + values[b as usize] * self.bary[1]
            + values[c as usize] * self.bary[2]
    }

    /// The 3-D position of this location on `mesh`.
    #[inline]
    pub fn position(&self, mesh: &TriMesh) -> Vec3 {
        self.interpolate(&mesh.triangles, &mesh.positions)
    }
}

/// Barycentric coordinates of `p` with respect to the 2-D triangle `(a, b, c)`.
/// Returns `None` when the triangle is degenerate.
#[inline]
pub fn barycentric_2d(p: Vec2, a: Vec2, b: Vec2, c: Vec2) -> Option<[f32; 3]> {
    let (e0, e1, e2) = (b - a, c - a, p - a);
    let det = e0.perp_dot(e1);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let l1 = e2.perp_dot(e1) / det;
    let l2 = e0.perp_dot(e2) / det;
    Some([1.0 - l1 - l2, l1, l2])
}

/// Closest point to `p` on the triangle `(a, b, c)` (Ericson, *Real-Time
/// Collision Detection*, 5.1.5). Used where a single triangle is tested and a
/// BVH would be overkill; also the brute-force reference of the BVH tests.
pub fn closest_point_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_at_corners_and_centroid() {
        let mesh = TriMesh::new(
            vec![
                Vec3::ZERO,
                Vec3::new(3.0, 0.0, 0.0),
                Vec3::new(0.0, 3.0, 0.0),
            ],
            vec![[0, 1, 2]],
        );
        let c = SurfacePoint::new(0, [1.0 / 3.0; 3]);
        assert!((c.position(&mesh) - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-6);
        assert_eq!(
            SurfacePoint::new(0, [0.0, 1.0, 0.0]).position(&mesh),
            Vec3::new(3.0, 0.0, 0.0)
        );
    }

    #[test]
    fn barycentric_2d_round_trips() {
        let (a, b, c) = (
            Vec2::new(0.1, 0.2),
            Vec2::new(2.0, 0.5),
            Vec2::new(0.7, 1.9),
        );
        let w = [0.2f32, 0.5, 0.3];
        let p = a * w[0] + b * w[1] + c * w[2];
        let got = barycentric_2d(p, a, b, c).expect("non-degenerate");
        for k in 0..3 {
            assert!((got[k] - w[k]).abs() < 1e-5, "{got:?}");
        }
        assert_eq!(barycentric_2d(p, a, a, c), None);
    }
}
