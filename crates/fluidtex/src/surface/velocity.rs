//! The flow between two frames, sampled at arbitrary points, and RK4
//! advection through it (docs/design.md, *Time*).
//!
//! Velocity at a point x near M_t is the barycentric interpolation of the
//! per-vertex velocity at the closest point of M_t. Advection from frame t to
//! t+1 integrates with classical RK4 over dt = 1/fps (split into `substeps`);
//! within the step the field is blended linearly in time between the
//! velocity sampled on M_t and on M_{t+1}:
//! v(x, s) = (1 − s) v_t(x) + s v_{t+1}(x), s ∈ [0, 1] the fraction of the
//! frame interval. The fluid mesh is a different mesh each frame, so this
//! blend is the only way the intermediate RK stages see the motion of the
//! next frame. Without a next frame (the last input frame) v_t alone is used.

use glam::Vec3;

use super::SurfaceIndex;
use crate::mesh::TriMesh;

/// One frame of the flow: mesh, its BVH and per-vertex velocity.
#[derive(Clone, Copy)]
pub struct FlowFrame<'a> {
    pub mesh: &'a TriMesh,
    pub index: &'a SurfaceIndex,
    pub velocity: &'a [Vec3],
}

impl<'a> FlowFrame<'a> {
    /// The velocity at the closest point of the mesh to `p`, `None` when the
    /// mesh is empty or `p` is not finite. `hint` bounds the first search
    /// (points are usually close to the surface); the search is repeated
    /// unbounded when nothing lies within it.
    pub fn sample(&self, p: Vec3, hint: f32) -> Option<Vec3> {
        let hit = self
            .index
            .closest(p, hint)
            .or_else(|| self.index.closest_unbounded(p))?;
        Some(
            hit.location
                .interpolate(&self.mesh.triangles, self.velocity),
        )
    }
}

/// The flow over one frame interval [t, t + dt].
#[derive(Clone, Copy)]
pub struct FlowInterval<'a> {
    pub from: FlowFrame<'a>,
    /// The next frame, when there is one.
    pub to: Option<FlowFrame<'a>>,
    /// Seconds per frame (1 / fps).
    pub dt: f32,
    /// RK4 steps per frame interval (≥ 1).
    pub substeps: u32,
    /// Distance bound for the first closest-point search (see [`FlowFrame::sample`]).
    pub search_hint: f32,
}

impl FlowInterval<'_> {
    /// Velocity at `p` and fraction `s` ∈ [0, 1] of the interval.
    pub fn velocity(&self, p: Vec3, s: f32) -> Option<Vec3> {
        let Some(to) = &self.to else {
            return self.from.sample(p, self.search_hint);
        };
        // At the ends of the interval one mesh has weight 0: skip its
        // closest-point query (RK4's first and last stages; 2 of the 8
        // queries of a step). The result is the blend's, exactly.
        if s <= 0.0 {
            return self
                .from
                .sample(p, self.search_hint)
                .or_else(|| to.sample(p, self.search_hint));
        }
        if s >= 1.0 {
            return to
                .sample(p, self.search_hint)
                .or_else(|| self.from.sample(p, self.search_hint));
        }
        match self.from.sample(p, self.search_hint) {
            Some(v0) => match to.sample(p, self.search_hint) {
                Some(v1) => Some(v0 * (1.0 - s) + v1 * s),
                None => Some(v0),
            },
            None => to.sample(p, self.search_hint),
        }
    }

    /// Advects `p` over the whole interval with RK4. Points where no velocity
    /// can be sampled (both meshes empty) stay where they are.
    pub fn advect(&self, p: Vec3) -> Vec3 {
        let n = self.substeps.max(1);
        let h = self.dt / n as f32;
        let ds = 1.0 / n as f32;
        let mut x = p;
        for i in 0..n {
            let s = i as f32 * ds;
            let v = |q: Vec3, s: f32| self.velocity(q, s).unwrap_or(Vec3::ZERO);
            let k1 = v(x, s);
            let k2 = v(x + k1 * (0.5 * h), s + 0.5 * ds);
            let k3 = v(x + k2 * (0.5 * h), s + 0.5 * ds);
            let k4 = v(x + k3 * h, s + ds);
            x += (k1 + 2.0 * k2 + 2.0 * k3 + k4) * (h / 6.0);
        }
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat square grid in z = 0, n×n quads.
    fn plane(n: usize, velocity: impl Fn(Vec3) -> Vec3) -> TriMesh {
        let mut positions = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                positions
                    .push(Vec3::new(i as f32 / n as f32, j as f32 / n as f32, 0.0) * 4.0 - 2.0);
            }
        }
        let mut triangles = Vec::new();
        let w = (n + 1) as u32;
        for j in 0..n as u32 {
            for i in 0..n as u32 {
                let a = j * w + i;
                triangles.push([a, a + 1, a + w + 1]);
                triangles.push([a, a + w + 1, a + w]);
            }
        }
        let v = positions.iter().map(|&p| velocity(p)).collect();
        TriMesh::new(positions, triangles).with_velocity(v)
    }

    #[test]
    fn linear_field_is_interpolated_exactly() {
        // A linear field is reproduced exactly by barycentric interpolation.
        let f = |p: Vec3| Vec3::new(0.3 * p.y + 0.1, -0.2 * p.x, 0.0);
        let mesh = plane(8, f);
        let index = SurfaceIndex::new(&mesh);
        let frame = FlowFrame {
            mesh: &mesh,
            index: &index,
            velocity: mesh.velocity().expect("has velocity"),
        };
        for p in [Vec3::new(0.31, -0.7, 0.0), Vec3::new(-1.2, 1.9, 0.05)] {
            let got = frame.sample(p, 0.1).expect("non-empty");
            let want = f(Vec3::new(p.x, p.y, 0.0));
            assert!((got - want).length() < 1e-5, "{got} vs {want}");
        }
    }

    #[test]
    fn rk4_follows_a_rotation_along_its_circle() {
        // Rigid rotation about z with ω = 1 rad/s: after dt the point has
        // turned by dt radians. The field is linear, so the only error is
        // RK4's (tiny at this step size).
        let omega = 1.0f32;
        let f = move |p: Vec3| Vec3::new(-omega * p.y, omega * p.x, 0.0);
        let mesh = plane(16, f);
        let index = SurfaceIndex::new(&mesh);
        let frame = FlowFrame {
            mesh: &mesh,
            index: &index,
            velocity: mesh.velocity().expect("has velocity"),
        };
        let flow = FlowInterval {
            from: frame,
            to: Some(frame),
            dt: 0.25,
            substeps: 2,
            search_hint: 0.1,
        };
        let p = Vec3::new(1.0, 0.0, 0.0);
        let q = flow.advect(p);
        let want = Vec3::new(0.25f32.cos(), 0.25f32.sin(), 0.0);
        assert!((q - want).length() < 1e-5, "{q} vs {want}");
        // Euler would be off by ~dt²/2 = 0.03: make sure we are far better.
        let euler = p + f(p) * 0.25;
        assert!((euler - want).length() > 1e-2);
    }

    #[test]
    fn blends_towards_the_next_frame() {
        let a = plane(2, |_| Vec3::X);
        let b = plane(2, |_| Vec3::Y);
        let (ia, ib) = (SurfaceIndex::new(&a), SurfaceIndex::new(&b));
        let flow = FlowInterval {
            from: FlowFrame {
                mesh: &a,
                index: &ia,
                velocity: a.velocity().expect("v"),
            },
            to: Some(FlowFrame {
                mesh: &b,
                index: &ib,
                velocity: b.velocity().expect("v"),
            }),
            dt: 1.0,
            substeps: 1,
            search_hint: 1.0,
        };
        assert_eq!(
            flow.velocity(Vec3::ZERO, 0.25),
            Some(Vec3::new(0.75, 0.25, 0.0))
        );
        // The ends of the interval are each frame's own field.
        assert_eq!(flow.velocity(Vec3::ZERO, 0.0), Some(Vec3::X));
        assert_eq!(flow.velocity(Vec3::ZERO, 1.0), Some(Vec3::Y));
        // With one mesh empty, the other one's field at both ends.
        let empty = TriMesh::new(Vec::new(), Vec::new()).with_velocity(Vec::new());
        let ie = SurfaceIndex::new(&empty);
        let half = FlowInterval {
            to: Some(FlowFrame {
                mesh: &empty,
                index: &ie,
                velocity: &[],
            }),
            ..flow
        };
        assert_eq!(half.velocity(Vec3::ZERO, 0.0), Some(Vec3::X));
        assert_eq!(half.velocity(Vec3::ZERO, 1.0), Some(Vec3::X));
        // Constant-in-space, linear-in-time field: RK4 integrates it exactly.
        let q = flow.advect(Vec3::ZERO);
        assert!((q - Vec3::new(0.5, 0.5, 0.0)).length() < 1e-6, "{q}");
    }
}
