//! Triangle quality of a mesh as the distribution of per-triangle minimum
//! angles: slivers (small min angle) are what hurt texture patches, which
//! distort and erode on elongated triangles.

use serde::Serialize;

use crate::mesh::TriMesh;

/// Min-angle statistics in degrees (over non-degenerate triangles;
/// percentiles by nearest rank).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct QualityStats {
    pub triangles: usize,
    /// 1st percentile of the min angle.
    pub p1: f32,
    /// 5th percentile of the min angle.
    pub p5: f32,
    pub median: f32,
    /// Share of triangles whose min angle is below 10°.
    pub below_10: f32,
    /// Share of triangles whose min angle is below 20°.
    pub below_20: f32,
    /// Triangles with a repeated corner or zero (or non-finite) area.
    pub degenerate: usize,
}

/// Smallest interior angle of a triangle (degrees), `None` if degenerate.
pub fn min_angle_degrees(p: [glam::Vec3; 3]) -> Option<f32> {
    let mut best = f32::INFINITY;
    for k in 0..3 {
        let u = p[(k + 1) % 3] - p[k];
        let v = p[(k + 2) % 3] - p[k];
        if u.length_squared() == 0.0 || v.length_squared() == 0.0 {
            return None;
        }
        // atan2 of |u×v| and u·v is accurate for small angles, unlike acos.
        let angle = u.cross(v).length().atan2(u.dot(v));
        best = best.min(angle);
    }
    (best.is_finite() && best > 0.0).then(|| best.to_degrees())
}

/// Min-angle distribution of `mesh` (see [`QualityStats`]).
pub fn triangle_quality(mesh: &TriMesh) -> QualityStats {
    let mut angles = Vec::with_capacity(mesh.triangles.len());
    let mut degenerate = 0;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let in_range = tri.iter().all(|&i| (i as usize) < mesh.positions.len());
        let distinct = tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2];
        match (in_range && distinct)
            .then(|| min_angle_degrees(mesh.corners(t)))
            .flatten()
        {
            Some(a) => angles.push(a),
            None => degenerate += 1,
        }
    }
    if angles.is_empty() {
        return QualityStats {
            triangles: mesh.triangles.len(),
            degenerate,
            ..QualityStats::default()
        };
    }
    angles.sort_by(f32::total_cmp);
    let rank = |q: f64| {
        let i = ((q * angles.len() as f64).ceil() as usize).clamp(1, angles.len()) - 1;
        angles[i]
    };
    let share = |limit: f32| angles.partition_point(|&a| a < limit) as f32 / angles.len() as f32;
    QualityStats {
        triangles: mesh.triangles.len(),
        p1: rank(0.01),
        p5: rank(0.05),
        median: rank(0.5),
        below_10: share(10.0),
        below_20: share(20.0),
        degenerate,
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    #[test]
    fn equilateral_right_and_degenerate_triangles() {
        let h = 3f32.sqrt() / 2.0;
        let mesh = TriMesh::new(
            vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::new(0.5, h, 0.0),
                Vec3::Y,
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(1.0, 0.1, 0.0),
            ],
            // equilateral, right isosceles, collinear, repeated corner, thin
            vec![[0, 1, 2], [0, 1, 3], [0, 1, 4], [0, 0, 1], [0, 4, 5]],
        );
        let q = triangle_quality(&mesh);
        assert_eq!(q.triangles, 5);
        assert_eq!(q.degenerate, 2);
        // Sorted min angles: thin (≈5.71°), 45°, 60°.
        let thin = (0.1f32).atan2(1.0).to_degrees();
        assert!((q.p1 - thin).abs() < 1e-3, "{q:?}");
        assert!((q.median - 45.0).abs() < 1e-3, "{q:?}");
        assert!((q.below_10 - 1.0 / 3.0).abs() < 1e-6);
        assert!((q.below_20 - 1.0 / 3.0).abs() < 1e-6);
        assert!((min_angle_degrees(mesh.corners(0)).unwrap_or(0.0) - 60.0).abs() < 1e-4);
    }
}
