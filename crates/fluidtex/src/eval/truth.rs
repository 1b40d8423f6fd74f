//! The true motion of the surface point seen at each pixel over one frame.
//!
//! metrics/mod.rs asks for the exact displacement rather than velocity ×
//! frame time: on a curved path (a rotation, a vortex) the straight step
//! v·dt misses the arc by O(dt²), which the flow metric would charge to
//! the method. So each pixel's surface point is traced through the
//! scene's exact velocity field over the frame with classical RK4 in
//! `substeps` steps, and both ends are projected with the evaluation
//! camera. Scenes without an exact field (the SPH dam break) fall back to
//! the mesh's per-vertex velocity at the point times the frame time
//! (first order), and the report says which was used.

use glam::{DVec3, Vec2, Vec3};
use serde::Serialize;

use crate::mesh::TriMesh;
use crate::render::{BACKGROUND, Camera, GBuffer};
use crate::scenes::Scene;
use crate::surface::SurfacePoint;

/// How the true motion is obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum TruthMotion {
    /// RK4 through the scene's exact velocity field, in this many steps
    /// per frame.
    Exact { substeps: u32 },
    /// The mesh's interpolated vertex velocity × frame time.
    MeshVelocity,
}

impl TruthMotion {
    /// Exact where the scene has an exact field (probed at its origin).
    pub fn of(scene: &dyn Scene, substeps: u32) -> TruthMotion {
        if scene.exact_velocity(Vec3::ZERO, 0.0).is_some() {
            TruthMotion::Exact {
                substeps: substeps.max(1),
            }
        } else {
            TruthMotion::MeshVelocity
        }
    }

    /// One line for the report.
    pub fn describe(self) -> String {
        match self {
            TruthMotion::Exact { substeps } => format!(
                "exact displacement: each pixel's surface point traced through the scene's \
                 velocity field over the frame (RK4, {substeps} steps), both ends projected"
            ),
            TruthMotion::MeshVelocity => "first order: interpolated vertex velocity × frame time, \
                 projected (the scene has no exact field)"
                .to_string(),
        }
    }
}

/// Moves `p` from time `t` by `step` seconds (negative: backwards).
pub fn trace(scene: &dyn Scene, p: Vec3, t: f64, step: f64, substeps: u32) -> Option<Vec3> {
    let n = substeps.max(1);
    let h = step / f64::from(n);
    let v = |x: DVec3, t: f64| scene.exact_velocity(x.as_vec3(), t).map(|v| v.as_dvec3());
    let mut x = p.as_dvec3();
    let mut t = t;
    for _ in 0..n {
        let k1 = v(x, t)?;
        let k2 = v(x + 0.5 * h * k1, t + 0.5 * h)?;
        let k3 = v(x + 0.5 * h * k2, t + 0.5 * h)?;
        let k4 = v(x + h * k3, t + h)?;
        x += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        t += h;
    }
    Some(x.as_vec3())
}

/// Per pixel of `gbuffer` (drawn from `mesh`, same triangle indices): the
/// image displacement (px) of its surface point moved from `t` by `step`
/// seconds, and the moved point's depth. NaN on background and where the
/// moved point is behind the camera.
pub fn true_motion(
    scene: &dyn Scene,
    truth: &TruthMotion,
    mesh: &TriMesh,
    gbuffer: &GBuffer,
    camera: &Camera,
    t: f64,
    step: f64,
) -> (Vec<Vec2>, Vec<f32>) {
    let velocity = mesh.velocity();
    // Sequential: `Scene` is `Send` but not `Sync`.
    (0..gbuffer.triangle.len())
        .map(|i| {
            let none = (Vec2::NAN, f32::NAN);
            let tri = gbuffer.triangle[i];
            if tri == BACKGROUND || tri as usize >= mesh.triangles.len() {
                return none;
            }
            let sp = SurfacePoint::new(tri, gbuffer.bary[i]);
            let p = sp.interpolate(&mesh.triangles, &mesh.positions);
            let moved = match truth {
                TruthMotion::Exact { substeps } => trace(scene, p, t, step, *substeps),
                TruthMotion::MeshVelocity => velocity
                    .filter(|v| v.len() == mesh.positions.len())
                    .map(|v| p + sp.interpolate(&mesh.triangles, v) * step as f32),
            };
            match (moved.and_then(|q| camera.project(q)), camera.project(p)) {
                (Some((q, d)), Some((p, _))) => (q - p, d),
                _ => none,
            }
        })
        .unzip()
}
