//! Directions in a point's tangent plane: the projection every orientation
//! goes through, and the reference (zero-angle) direction of a point.

use glam::Vec3;

/// `d` projected on the plane of normal `n` and normalised; a stable
/// tangent of `n` when `d` is (nearly) normal to the plane.
#[inline]
pub fn tangent(d: Vec3, n: Vec3) -> Vec3 {
    let t = d - n * d.dot(n);
    if t.length_squared() > 1e-12 {
        t.normalize()
    } else {
        reference(n)
    }
}

/// The reference (zero-angle) tangent of a point: world X projected on
/// the tangent plane, or world Z near the poles of X.
#[inline]
pub fn reference(n: Vec3) -> Vec3 {
    let axis = if n.x.abs() < 0.9 { Vec3::X } else { Vec3::Z };
    let t = axis - n * axis.dot(n);
    t.normalize_or(Vec3::X)
}
