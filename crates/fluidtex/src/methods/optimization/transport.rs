//! Texture transport from the previous frame (paper Sec. VI).
//!
//! **Colour** (Eq. 3): each new point is back-tracked through the flow to
//! where it was one frame earlier and takes the colour of the previous
//! points interpolated at the closest point of the previous surface. The
//! paper advects the coordinate field on the simulation grid; our inputs
//! are meshes with per-vertex velocity, so the back-tracking is the RK4
//! integration through the mesh velocities that every method here uses
//! ([`crate::surface::velocity`]), run backwards in time. The closest
//! point is looked up on the previous fluid mesh and its lattice cell read
//! exactly ([`Lattice::locate`]), so no BVH over the points is needed.
//!
//! **Orientation** (Eq. 4): the paper's own construction, head and tail.
//! The previous orientation d at the back-tracked point x is carried by
//! advecting x and x + εd forward through the flow; the new orientation is
//! the normalised difference, projected on the new tangent plane. As ε → 0
//! this is Eq. 4 (translation plus rotation by the velocity gradient, with
//! the length change projected out); ε is a quarter of the level's point
//! spacing, below the scale at which the velocity gradient varies.

use glam::Vec3;
use rayon::prelude::*;

use super::lattice::Lattice;
use super::tangent::tangent;
use crate::mesh::TriMesh;
use crate::surface::SurfaceIndex;
use crate::surface::velocity::FlowInterval;

/// The previous frame's texture.
pub struct Previous<'a> {
    pub mesh: &'a TriMesh,
    pub index: &'a SurfaceIndex,
    pub lattice: &'a Lattice,
    /// Values per previous point (`channels` floats each).
    pub values: &'a [f32],
    pub channels: usize,
    /// Orientation per previous point.
    pub orientation: &'a [Vec3],
}

impl Previous<'_> {
    /// The previous surface location closest to `x`: (triangle, bary).
    fn locate(&self, x: Vec3, hint: f32) -> Option<(usize, [f32; 3])> {
        let hit = self
            .index
            .closest(x, hint)
            .or_else(|| self.index.closest_unbounded(x))?;
        Some((hit.location.triangle as usize, hit.location.bary))
    }

    /// Interpolated values at the previous surface point closest to `x`.
    pub fn values_at(&self, x: Vec3, hint: f32, out: &mut [f32]) -> bool {
        match self.locate(x, hint) {
            Some((t, b)) => {
                self.lattice
                    .interpolate(self.values, self.channels, t, b, out);
                true
            }
            None => false,
        }
    }

    /// Orientation (tangent to the previous surface) at the closest point to `x`.
    pub fn orientation_at(&self, x: Vec3, hint: f32) -> Option<(Vec3, Vec3)> {
        let (t, b) = self.locate(x, hint)?;
        let mut d = Vec3::ZERO;
        let mut n = Vec3::ZERO;
        let mut p = Vec3::ZERO;
        for (id, w) in self.lattice.locate(t, b) {
            d += self.orientation[id as usize] * w;
            n += self.lattice.normals[id as usize] * w;
            p += self.lattice.positions[id as usize] * w;
        }
        Some((p, tangent(d, n.normalize_or(Vec3::Z))))
    }
}

/// Back-tracks every point through `back` (current → previous frame) and
/// reads the previous values there. Returns the values and how many points
/// found none (the previous mesh was empty).
pub fn colours(points: &[Vec3], back: &FlowInterval<'_>, prev: &Previous<'_>) -> (Vec<f32>, usize) {
    let k = prev.channels;
    let hint = back.search_hint;
    let mut out = vec![0.0f32; points.len() * k];
    let missing: usize = out
        .par_chunks_mut(k)
        .zip(points.par_iter())
        .map(|(o, &p)| {
            let x = back.advect(p);
            usize::from(!prev.values_at(x, hint, o))
        })
        .sum();
    (out, missing)
}

/// Transports the previous orientation field to `points` (with unit
/// `normals`): back-track, read d, advect tail and head forward through
/// `forward` (previous → current frame).
pub fn orientations(
    points: &[Vec3],
    normals: &[Vec3],
    back: &FlowInterval<'_>,
    forward: &FlowInterval<'_>,
    prev: &Previous<'_>,
    epsilon: f32,
) -> Vec<Vec3> {
    let hint = back.search_hint;
    points
        .par_iter()
        .zip(normals.par_iter())
        .map(|(&p, &n)| {
            let x = back.advect(p);
            match prev.orientation_at(x, hint) {
                Some((on_surface, d)) => {
                    let tail = forward.advect(on_surface);
                    let head = forward.advect(on_surface + d * epsilon);
                    tangent(head - tail, n)
                }
                None => super::tangent::reference(n),
            }
        })
        .collect()
}
