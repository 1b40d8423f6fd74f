//! The orientation field: one unit tangent vector d per point, the first
//! axis of the local frame in which neighbourhoods are laid out (the
//! second is d × n, so image rows run down the frame as in the exemplar).
//!
//! **Smoothing** (paper Sec. IV-B): iterated averaging of each point's
//! orientation with those of its edge neighbours, coarsest level first,
//! then copied up the hierarchy ([`smooth_hierarchy`]) and averaged again.
//! The paper averages polar angles (Zhang et al.'s polar map, which scales
//! angles by 2π/Θ around each vertex); here a neighbour's vector is carried
//! into the point's tangent plane by projection and the vectors are
//! averaged. Both make two neighbours' orientations agree relative to
//! their common edge; projection skips the polar map's angle-defect
//! rescaling, which only matters at strongly curved vertices and needs
//! ordered one-rings the non-manifold fluid meshes do not always have.
//!
//! **Transport** (Eq. 4): see [`super::transport`]; the result is
//! re-smoothed here.

use glam::Vec3;
use rayon::prelude::*;

use super::lattice::{Lattice, Level};

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

/// `iterations` Jacobi steps of neighbour averaging on `level`.
pub fn diffuse(level: &Level, d: &mut Vec<Vec3>, iterations: u32) {
    for _ in 0..iterations {
        let next: Vec<Vec3> = (0..level.len())
            .into_par_iter()
            .map(|v| {
                let n = level.normals[v];
                let mut sum = d[v];
                for &u in level.neighbours(v as u32) {
                    sum += tangent(d[u as usize], n);
                }
                tangent(sum, n)
            })
            .collect();
        *d = next;
    }
}

/// Smooths an orientation field given on the coarsest of `levels` (the
/// last), then copies it up level by level (interpolation on the lattice)
/// and smooths again at each level. Returns the field on `levels\[0]`.
pub fn smooth_hierarchy(
    lattice: &Lattice,
    levels: &[Level],
    coarse: Vec<Vec3>,
    iterations: u32,
) -> Vec<Vec3> {
    let Some(last) = levels.len().checked_sub(1) else {
        return coarse;
    };
    let mut d = coarse;
    diffuse(&levels[last], &mut d, iterations);
    for l in (0..last).rev() {
        let (from, to) = (&levels[l + 1], &levels[l]);
        let flat: Vec<f32> = d.iter().flat_map(|v| v.to_array()).collect();
        let mut out = vec![0.0f32; to.len() * 3];
        lattice.prolong(from, &flat, 3, to, &mut out);
        d = out
            .chunks_exact(3)
            .zip(&to.normals)
            .map(|(c, &n)| tangent(Vec3::new(c[0], c[1], c[2]), n))
            .collect();
        diffuse(to, &mut d, iterations);
    }
    d
}
