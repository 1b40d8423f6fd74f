//! The orientation field: one unit tangent vector d per point, the first
//! axis of the local frame in which neighbourhoods are laid out (the
//! second is d × n, so image rows run down the frame as in the exemplar).
//!
//! **Smoothing** (paper Sec. IV-B): iterated averaging of each point's
//! orientation with those of its edge neighbours, coarsest level first,
//! then copied up the hierarchy ([`smooth_hierarchy`]) and averaged again.
//! Two ways of comparing a neighbour's orientation with the point's
//! ([`Smoothing`]):
//! - `projected` (default): the neighbour's vector is carried into the
//!   point's tangent plane by projection and the vectors are averaged; a
//!   fresh surface starts from world X projected on each tangent plane.
//! - `polar` (the paper's): polar angles are averaged through Zhang et
//!   al.'s polar maps, which rescale the angles around each vertex by
//!   2π/Θ ([`super::polar`]); a fresh surface starts from polar angle 0.
//!
//! Both make two neighbours' orientations agree relative to their common
//! edge and coincide on a flat surface; projection skips the angle-defect
//! rescaling, which matters only at strongly curved vertices, and needs no
//! ordered one-rings, which the non-manifold fluid meshes do not always
//! have (the polar maps fall back to projection at such vertices).
//!
//! **Transport** (Eq. 4): see [`super::transport`]; the result is
//! re-smoothed here.

use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::lattice::{Lattice, Level};
use super::polar::{self, PolarMaps};
use super::tangent::{reference, tangent};

/// How the orientation field is smoothed (Sec. IV-B).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Smoothing {
    /// Neighbours' vectors projected into the point's tangent plane and
    /// averaged; fresh surfaces start from world X.
    #[default]
    Projected,
    /// The paper's: polar angles diffused through each vertex's polar map;
    /// fresh surfaces start from polar angle 0.
    Polar,
}

crate::named!(Smoothing {
    Projected => "projected",
    Polar => "polar",
});

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
/// last; `None` on a fresh surface, which starts from `mode`'s reference
/// field), then copies it up level by level (interpolation on the
/// lattice) and smooths again at each level. Returns the field on
/// `levels\[0]`.
pub fn smooth_hierarchy(
    lattice: &Lattice,
    levels: &[Level],
    coarse: Option<Vec<Vec3>>,
    iterations: u32,
    mode: Smoothing,
) -> Vec<Vec3> {
    let Some(last) = levels.len().checked_sub(1) else {
        return coarse.unwrap_or_default();
    };
    let smooth = |level: &Level, d: Option<Vec<Vec3>>| -> Vec<Vec3> {
        match mode {
            Smoothing::Projected => {
                let mut d =
                    d.unwrap_or_else(|| level.normals.iter().map(|&n| reference(n)).collect());
                diffuse(level, &mut d, iterations);
                d
            }
            Smoothing::Polar => {
                let maps = PolarMaps::new(level);
                let mut d = d.unwrap_or_else(|| polar::zero_angle(level, &maps));
                polar::diffuse(level, &maps, &mut d, iterations);
                d
            }
        }
    };
    let mut d = smooth(&levels[last], coarse);
    for l in (0..last).rev() {
        let (from, to) = (&levels[l + 1], &levels[l]);
        let flat: Vec<f32> = d.iter().flat_map(|v| v.to_array()).collect();
        let mut out = vec![0.0f32; to.len() * 3];
        lattice.prolong(from, &flat, 3, to, &mut out);
        let up = out
            .chunks_exact(3)
            .zip(&to.normals)
            .map(|(c, &n)| tangent(Vec3::new(c[0], c[1], c[2]), n))
            .collect();
        d = smooth(to, Some(up));
    }
    d
}
