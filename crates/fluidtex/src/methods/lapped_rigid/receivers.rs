//! Receiver polygons (Gagnon, Dagenais, Paquette 2016, Sec. 3.2.1): the
//! fluid triangles that take a patch's texture this frame.
//!
//! The candidates are the triangles within the patch size r of P. Of
//! those, only the ones edge-connected (through candidates) to the
//! triangle closest to P are kept, so a nearby but disjoint sheet of liquid
//! never receives the patch; then triangles whose normal turns more than
//! φ_max away from the frame's normal are dropped, because an orthographic
//! projection of a surface that folds back over itself overlaps in uv.
//!
//! Receivers are recomputed from the current fluid mesh every frame: the
//! patch itself is rigid (a frame), the mesh under it is new each frame.

use glam::Vec3;

use super::falloff::angle_between;
use super::trackers::Frame;
use crate::mesh::{Topology, TriMesh};
use crate::surface::{SurfaceIndex, closest_point_on_triangle};

/// The receivers of one patch.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Receivers {
    /// Fluid triangles, sorted.
    pub triangles: Vec<u32>,
}

/// What receiver selection reads besides the frame.
pub struct ReceiverContext<'a> {
    pub mesh: &'a TriMesh,
    pub topology: &'a Topology,
    pub index: &'a SurfaceIndex,
    pub vertex_normals: &'a [Vec3],
    /// Patch size r: the distance bound of the candidates.
    pub radius: f32,
    /// φ_max (radians).
    pub phi_max: f32,
}

impl ReceiverContext<'_> {
    /// The receivers of the patch with frame `frame` (module doc). Empty
    /// when no triangle lies within r of P.
    pub fn receivers(&self, frame: &Frame) -> Receivers {
        let p = frame.origin;
        let Some(hit) = self.index.closest(p, self.radius) else {
            return Receivers::default();
        };
        let mesh = self.mesh;
        let r2 = self.radius * self.radius;
        let mut taken = self.topology.grow_region(hit.location.triangle, |nb| {
            let [a, b, c] = mesh.corners(nb as usize);
            closest_point_on_triangle(p, a, b, c).distance_squared(p) <= r2
        });
        taken.retain(|&t| {
            let n = mesh.triangle_normal(t as usize);
            n != Vec3::ZERO && angle_between(n, frame.normal) <= self.phi_max
        });
        taken.sort_unstable();
        Receivers { triangles: taken }
    }
}
