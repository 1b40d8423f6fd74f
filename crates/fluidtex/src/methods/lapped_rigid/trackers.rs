//! Trackers and their local frames (Gagnon, Dagenais, Paquette 2016,
//! Sec. 3.1.1–3.1.2).
//!
//! A patch is a point P on the surface plus a *tangent tracker* T at
//! distance r/2 along the patch's tangent. Both ride the flow (RK4, the
//! same [`FlowInterval`] erosion uses). P is projected back onto the new
//! surface; T is not, so it keeps the flow's rotation of the tangent plane.
//! The frame is then rebuilt from the surface normal n at P and the
//! direction to T: b = n × (T − P), t = b × n, and T is put back at
//! P + (r/2) t. A patch so turns with the flow but keeps its shape: its
//! texture coordinates are an orthographic projection onto the plane
//! (P, t, b), the same for every frame of its life.
//!
//! Why store T rather than an angle: the flow rotates vectors, not angles,
//! and advecting a second point is exactly how the flow's rotation (and
//! only its rotation, after re-orthonormalisation) reaches the frame.

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::mesh::TriMesh;
use crate::surface::velocity::FlowInterval;
use crate::surface::{SurfaceIndex, SurfacePoint};

/// One patch of the 2016 method.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Tracker {
    /// Creation order: lower ids are older and lie on top.
    pub id: u32,
    /// P, on the current surface.
    pub position: Vec3,
    /// T, at distance r/2 from P along the tangent t, perpendicular to n.
    pub tangent_tracker: Vec3,
    /// The frame's normal n: the surface normal at P.
    pub normal: Vec3,
    /// Opacity multiplier: 1, falling towards 0 while the patch is a sink.
    pub fade: f32,
    /// Set once the patch is found to be a sink; it then fades until deleted.
    pub sinking: bool,
    /// Index of the exemplar the patch shows (several exemplars per
    /// surface; 0 with one). Saved after the tracker state
    /// ([`super::MultiState`]), so a one-exemplar state is unchanged.
    #[serde(skip)]
    pub exemplar: u32,
}

/// The orthonormal frame of a tracker this frame, with the exemplar scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub origin: Vec3,
    pub tangent: Vec3,
    pub binormal: Vec3,
    pub normal: Vec3,
    /// World size S covered by the exemplar's \[0, 1]².
    pub exemplar_size: f32,
}

impl Frame {
    /// Patch (exemplar) uv of a world point: its orthographic projection
    /// onto the frame plane, scaled by 1/S, with P at (0.5, 0.5). v points
    /// down (the texture convention of [`crate::texture`]), so seen from
    /// the side n points to, t → +u and b → −v: the exemplar is not mirrored.
    #[inline]
    pub fn uv(&self, x: Vec3) -> Vec2 {
        let d = x - self.origin;
        Vec2::new(
            0.5 + d.dot(self.tangent) / self.exemplar_size,
            0.5 - d.dot(self.binormal) / self.exemplar_size,
        )
    }
}

/// The unit surface normal at a surface point: interpolated vertex
/// normals, or the triangle's own where those cancel.
pub fn surface_normal(mesh: &TriMesh, vertex_normals: &[Vec3], at: SurfacePoint) -> Vec3 {
    let n = at
        .interpolate(&mesh.triangles, vertex_normals)
        .normalize_or_zero();
    if n == Vec3::ZERO {
        mesh.triangle_normal(at.triangle as usize)
    } else {
        n
    }
}

impl Tracker {
    /// A new tracker at `at` whose tangent makes angle `rotation` with a
    /// fixed basis of the tangent plane (seeded per patch by the caller).
    pub fn create(
        id: u32,
        mesh: &TriMesh,
        vertex_normals: &[Vec3],
        at: SurfacePoint,
        radius: f32,
        rotation: f32,
    ) -> Tracker {
        let p = at.position(mesh);
        let n = surface_normal(mesh, vertex_normals, at);
        let (a, b) = n.any_orthonormal_pair();
        let (sin, cos) = rotation.sin_cos();
        let t = a * cos + b * sin;
        Tracker {
            id,
            position: p,
            tangent_tracker: p + t * (0.5 * radius),
            normal: n,
            fade: 1.0,
            sinking: false,
            exemplar: 0,
        }
    }

    /// The unit tangent t (towards T).
    #[inline]
    pub fn tangent(&self) -> Vec3 {
        (self.tangent_tracker - self.position).normalize_or_zero()
    }

    /// This frame's orthonormal frame.
    pub fn frame(&self, exemplar_size: f32) -> Frame {
        let t = self.tangent();
        Frame {
            origin: self.position,
            tangent: t,
            binormal: self.normal.cross(t),
            normal: self.normal,
            exemplar_size,
        }
    }

    /// Advects P and T through `flow`, projects P onto the next surface
    /// (`next`, whose vertex normals are `next_normals`) and rebuilds the
    /// frame. Returns false when P ends farther than `far` from the next
    /// surface: the tracker left it and is deleted.
    ///
    /// A tracker the flow leaves exactly in place (both points unmoved, P
    /// already on the surface) is left bit for bit as it is, so a fluid at
    /// rest gives identical frames: closest-point projection and the
    /// re-orthonormalisation are not idempotent to the last bit.
    pub fn advect(
        &mut self,
        flow: &FlowInterval<'_>,
        next_mesh: &TriMesh,
        next: &SurfaceIndex,
        next_normals: &[Vec3],
        radius: f32,
        far: f32,
    ) -> bool {
        let moved_p = flow.advect(self.position);
        let moved_t = flow.advect(self.tangent_tracker);
        let Some(hit) = next.closest(moved_p, far) else {
            return false;
        };
        if moved_p == self.position
            && moved_t == self.tangent_tracker
            && hit.distance <= 1e-5 * radius
        {
            return true;
        }
        let p = hit.point;
        let n = surface_normal(next_mesh, next_normals, hit.location);
        self.rebuild(p, moved_t, n, radius);
        true
    }

    /// Rebuilds the frame at P = `p` with normal `n` from the advected
    /// tangent tracker `t_moved`: b = n × (T' − P), t = b × n, T = P + r/2 t.
    /// Where T' − P is (nearly) parallel to n, the previous tangent,
    /// projected onto the new tangent plane, stands in.
    pub fn rebuild(&mut self, p: Vec3, t_moved: Vec3, n: Vec3, radius: f32) {
        let mut b = n.cross(t_moved - p);
        if b.length_squared() <= (1e-6 * radius).powi(2) {
            b = n.cross(self.tangent());
        }
        let b = b.normalize_or_zero();
        let t = if b == Vec3::ZERO {
            // Both fallbacks are parallel to n: any tangent will do.
            n.any_orthonormal_vector()
        } else {
            b.cross(n).normalize_or_zero()
        };
        self.position = p;
        self.normal = n;
        self.tangent_tracker = p + t * (0.5 * radius);
    }

    /// World positions of the frame's four corners, P + (r/2)(±t ± b),
    /// where the sink test samples the flow.
    pub fn corners(&self, radius: f32) -> [Vec3; 4] {
        let t = self.tangent() * (0.5 * radius);
        let b = self.normal.cross(self.tangent()) * (0.5 * radius);
        let p = self.position;
        [p + t + b, p - t + b, p - t - b, p + t - b]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uv_is_an_unmirrored_orthographic_projection_scaled_by_s() {
        let f = Frame {
            origin: Vec3::new(1.0, 2.0, 3.0),
            tangent: Vec3::X,
            binormal: Vec3::Y,
            normal: Vec3::Z,
            exemplar_size: 2.0,
        };
        assert_eq!(f.uv(f.origin), Vec2::splat(0.5));
        // The normal component is dropped (orthographic).
        assert_eq!(
            f.uv(f.origin + Vec3::new(0.5, 0.0, 7.0)),
            Vec2::new(0.75, 0.5)
        );
        assert_eq!(
            f.uv(f.origin + Vec3::new(0.0, 0.5, 0.0)),
            Vec2::new(0.5, 0.25)
        );
        // +x then +y, seen from +z, turns clockwise in (u, v down).
        let (a, b, c) = (
            f.uv(f.origin),
            f.uv(f.origin + Vec3::X),
            f.uv(f.origin + Vec3::Y),
        );
        assert!((b - a).perp_dot(c - a) < 0.0);
    }

    #[test]
    fn rebuild_keeps_t_at_half_r_perpendicular_to_n() {
        let mut tr = Tracker {
            id: 0,
            position: Vec3::ZERO,
            tangent_tracker: Vec3::X * 0.5,
            normal: Vec3::Z,
            fade: 1.0,
            sinking: false,
            exemplar: 0,
        };
        let n = Vec3::new(0.1, 0.2, 1.0).normalize();
        tr.rebuild(Vec3::ONE, Vec3::ONE + Vec3::new(0.3, 0.4, 0.9), n, 1.0);
        let d = tr.tangent_tracker - tr.position;
        assert!((d.length() - 0.5).abs() < 1e-6);
        assert!(d.dot(n).abs() < 1e-6);
        // T' straight above P: the old tangent, projected, stands in.
        let before = tr.tangent();
        tr.rebuild(Vec3::ONE, Vec3::ONE + n, n, 1.0);
        assert!(tr.tangent().dot(before) > 0.999);
    }
}
