//! Analytic velocity fields, their flow maps, and the moving implicit
//! surfaces built from them.
//!
//! Every flow here is u(x, t) = a(t)·v(x) with a steady field v and a scalar
//! amplitude a(t). Such a field moves points along the paths of v, only at a
//! different speed: the position at time t of the point that started at x is
//! Φ_τ(x), the flow map of v run for τ(t) = ∫₀ᵗ a(s) ds. So the surface at
//! time t is {x : φ₀(Φ₋τ(t)(x)) = 0} for the initial signed distance φ₀, and
//! one backward trace per point gives it exactly (up to the integrator),
//! whatever the frame. The single-vortex and Enright fields are the standard
//! level-set tests (Enright, Fedkiw, Ferziger & Mitchell 2002, sec. 4;
//! LeVeque 1996 for the vortex), with a(t) = cos(πt/T) so that τ(T) = 0 and
//! the surface returns to its start.
//!
//! All of this is in f64: the map is composed many times per node and only
//! the final positions are rounded to f32.

use std::f64::consts::PI;

use glam::DVec3;
use serde_json::json;

/// The amplitude a(t) of a flow u = a(t)·v(x) and its integral τ(t).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Amplitude {
    /// a = 1, τ = t.
    Constant,
    /// a = s·cos(πt/T): forward for T/2, back for T/2; τ = s·(T/π)
    /// sin(πt/T), so τ(T) = 0. With s = T₀/T the path is that of period T₀
    /// taken T/T₀ times slower.
    Cosine { period: f64, speed: f64 },
    /// a = 1 until `hold`, then cos² down to exactly 0 at `hold + ramp`, and 0 after.
    Ramp { hold: f64, ramp: f64 },
}

impl Amplitude {
    /// a(t).
    pub fn a(&self, t: f64) -> f64 {
        match *self {
            Amplitude::Constant => 1.0,
            Amplitude::Cosine { period, speed } => speed * (PI * t / period).cos(),
            Amplitude::Ramp { hold, ramp } => {
                if t <= hold {
                    1.0
                } else if t >= hold + ramp {
                    0.0
                } else {
                    (0.5 * PI * (t - hold) / ramp).cos().powi(2)
                }
            }
        }
    }

    /// τ(t) = ∫₀ᵗ a(s) ds, in closed form. Constant (bit for bit) once a
    /// ramp has ended, which is what makes the `stop` scene's frames identical.
    pub fn tau(&self, t: f64) -> f64 {
        match *self {
            Amplitude::Constant => t,
            Amplitude::Cosine { period, speed } => speed * period / PI * (PI * t / period).sin(),
            Amplitude::Ramp { hold, ramp } => {
                if t <= hold {
                    t
                } else if t >= hold + ramp {
                    hold + 0.5 * ramp
                } else {
                    let s = t - hold;
                    hold + 0.5 * s + ramp / (2.0 * PI) * (PI * s / ramp).sin()
                }
            }
        }
    }

    pub fn to_json(self) -> serde_json::Value {
        match self {
            Amplitude::Constant => json!({"kind": "constant", "formula": "a(t) = 1"}),
            Amplitude::Cosine { period, speed: 1.0 } => {
                json!({"kind": "cosine", "formula": "a(t) = cos(pi t / T)", "T": period})
            }
            Amplitude::Cosine { period, speed } => json!({
                "kind": "cosine", "formula": "a(t) = s cos(pi t / T)", "T": period, "s": speed,
            }),
            Amplitude::Ramp { hold, ramp } => json!({
                "kind": "ramp",
                "formula": "a = 1 for t <= t1; cos^2(pi/2 (t - t1)/(t2 - t1)) on [t1, t2]; 0 after",
                "t1": hold, "t2": hold + ramp,
            }),
        }
    }
}

/// A steady velocity field v(x) (world units per second at a = 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Field {
    /// Enright et al. 2002, sec. 4 (3-D deformation): u = 2 sin²(πx) sin(2πy) sin(2πz),
    /// v = −sin(2πx) sin²(πy) sin(2πz), w = −sin(2πx) sin(2πy) sin²(πz).
    Enright,
    /// Single vortex in the xy plane: u = sin²(πx) sin(2πy), v = −sin²(πy) sin(2πx), w = 0.
    SingleVortex,
    /// Rigid rotation v = ω × (x − c), ω = (0, 0, omega) rad/s.
    RigidRotation { center: DVec3, omega: f64 },
    /// v = ω(ζ) ẑ × (x − c), ω(ζ) = ω₀ + ω₁ ζ with ζ = z − c_z (height above the centre).
    DifferentialRotation {
        center: DVec3,
        omega0: f64,
        omega1: f64,
    },
    /// Shear u = (γ (y − ½), 0, 0).
    Shear { gamma: f64 },
}

/// Largest step in τ that RK4 takes on the fields without a closed-form map
/// (seconds at a = 1). It only limits how exactly the surface is placed (the
/// velocity is evaluated in closed form): halving it moves a point traced
/// over the longest τ by less than 1% of a cell at the default resolutions
/// (checked in the tests), well below the marching-cubes error, while every
/// traced node costs 4 field evaluations per step. Enright: |∇v| ≈ 4π.
pub const ENRIGHT_MAX_STEP: f64 = 0.025;
/// Single vortex: |∇v| ≈ 2π, but τ reaches 8/π.
pub const VORTEX_MAX_STEP: f64 = 0.05;

impl Field {
    /// v(x).
    pub fn v(&self, p: DVec3) -> DVec3 {
        match *self {
            Field::Enright => {
                let (sx, cx) = (PI * p.x).sin_cos();
                let (sy, cy) = (PI * p.y).sin_cos();
                let (sz, cz) = (PI * p.z).sin_cos();
                // sin(2πs) = 2 sin(πs) cos(πs).
                let (s2x, s2y, s2z) = (2.0 * sx * cx, 2.0 * sy * cy, 2.0 * sz * cz);
                DVec3::new(
                    2.0 * sx * sx * s2y * s2z,
                    -s2x * sy * sy * s2z,
                    -s2x * s2y * sz * sz,
                )
            }
            Field::SingleVortex => {
                let (sx, cx) = (PI * p.x).sin_cos();
                let (sy, cy) = (PI * p.y).sin_cos();
                DVec3::new(sx * sx * (2.0 * sy * cy), -sy * sy * (2.0 * sx * cx), 0.0)
            }
            Field::RigidRotation { center, omega } => {
                let d = p - center;
                DVec3::new(-omega * d.y, omega * d.x, 0.0)
            }
            Field::DifferentialRotation {
                center,
                omega0,
                omega1,
            } => {
                let d = p - center;
                let w = omega0 + omega1 * d.z;
                DVec3::new(-w * d.y, w * d.x, 0.0)
            }
            Field::Shear { gamma } => DVec3::new(gamma * (p.y - 0.5), 0.0, 0.0),
        }
    }

    /// Φ_s(x): where the steady field carries x in time s (s may be
    /// negative). Closed form for the rotations and the shear, RK4 otherwise.
    pub fn map(&self, p: DVec3, s: f64) -> DVec3 {
        match *self {
            Field::RigidRotation { center, omega } => rotate_z(p, center, omega * s),
            Field::DifferentialRotation {
                center,
                omega0,
                omega1,
            } => rotate_z(p, center, (omega0 + omega1 * (p.z - center.z)) * s),
            Field::Shear { gamma } => DVec3::new(p.x + gamma * (p.y - 0.5) * s, p.y, p.z),
            Field::Enright => self.rk4(p, s, ENRIGHT_MAX_STEP),
            Field::SingleVortex => self.rk4(p, s, VORTEX_MAX_STEP),
        }
    }

    /// Classical RK4 on dx/ds = v(x) with n = ⌈|s|/max_step⌉ equal steps.
    pub fn rk4(&self, mut p: DVec3, s: f64, max_step: f64) -> DVec3 {
        if s == 0.0 {
            return p;
        }
        let n = (s.abs() / max_step).ceil().max(1.0) as usize;
        let h = s / n as f64;
        for _ in 0..n {
            let k1 = self.v(p);
            let k2 = self.v(p + 0.5 * h * k1);
            let k3 = self.v(p + 0.5 * h * k2);
            let k4 = self.v(p + h * k3);
            p += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        p
    }

    pub fn to_json(self) -> serde_json::Value {
        match self {
            Field::Enright => json!({
                "kind": "enright",
                "formula": "u = 2 sin^2(pi x) sin(2 pi y) sin(2 pi z), v = -sin(2 pi x) sin^2(pi y) sin(2 pi z), w = -sin(2 pi x) sin(2 pi y) sin^2(pi z)",
                "integrator": "RK4", "max_step_tau": ENRIGHT_MAX_STEP,
            }),
            Field::SingleVortex => json!({
                "kind": "single-vortex",
                "formula": "u = sin^2(pi x) sin(2 pi y), v = -sin^2(pi y) sin(2 pi x), w = 0",
                "integrator": "RK4", "max_step_tau": VORTEX_MAX_STEP,
            }),
            Field::RigidRotation { center, omega } => json!({
                "kind": "rigid-rotation", "formula": "v = omega x (x - c), omega = (0, 0, omega_z)",
                "c": center.to_array(), "omega_z": omega, "integrator": "closed form",
            }),
            Field::DifferentialRotation {
                center,
                omega0,
                omega1,
            } => json!({
                "kind": "differential-rotation",
                "formula": "v = (omega0 + omega1 (z - c_z)) e_z x (x - c)",
                "c": center.to_array(), "omega0": omega0, "omega1": omega1,
                "integrator": "closed form",
            }),
            Field::Shear { gamma } => json!({
                "kind": "shear", "formula": "u = (gamma (y - 1/2), 0, 0)", "gamma": gamma,
                "integrator": "closed form",
            }),
        }
    }
}

fn rotate_z(p: DVec3, c: DVec3, angle: f64) -> DVec3 {
    let (s, co) = angle.sin_cos();
    let d = p - c;
    DVec3::new(c.x + co * d.x - s * d.y, c.y + s * d.x + co * d.y, p.z)
}

/// Initial shapes as signed distances (negative inside, 1-Lipschitz, which
/// the narrow band of [`super::marching_cubes`] relies on).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    Sphere {
        center: DVec3,
        radius: f64,
    },
    /// A disc of `radius` in the xy plane extruded to half-thickness
    /// `half_height` about `center.z`, its rim rounded with radius `rounding`
    /// (so marching cubes sees no sharp edge).
    Puck {
        center: DVec3,
        radius: f64,
        half_height: f64,
        rounding: f64,
    },
    /// The plane z = height (inside below).
    Plane {
        height: f64,
    },
}

impl Shape {
    pub fn sdf(&self, p: DVec3) -> f64 {
        match *self {
            Shape::Sphere { center, radius } => (p - center).length() - radius,
            Shape::Puck {
                center,
                radius,
                half_height,
                rounding,
            } => {
                let disc = (p.x - center.x).hypot(p.y - center.y) - radius;
                let qx = disc + rounding;
                let qy = (p.z - center.z).abs() - half_height + rounding;
                qx.max(qy).min(0.0) + qx.max(0.0).hypot(qy.max(0.0)) - rounding
            }
            Shape::Plane { height } => p.z - height,
        }
    }

    /// A lower bound of |sdf| over the box [lo, hi] (0 when the surface may
    /// cross it): exact for the sphere and the plane; for the puck, exact
    /// outside and the 1-Lipschitz bound at the box centre inside.
    pub fn box_bound(&self, lo: DVec3, hi: DVec3) -> f64 {
        match *self {
            Shape::Sphere { center, radius } => {
                let near = (center.clamp(lo, hi) - center).length();
                let far = (lo - center).abs().max((hi - center).abs()).length();
                (near - radius).max(radius - far).max(0.0)
            }
            Shape::Plane { height } => (lo.z - height).max(height - hi.z).max(0.0),
            Shape::Puck {
                center,
                radius,
                half_height,
                ..
            } => {
                // The rounded puck's distance is at least the larger of the
                // disc's (in xy) and the slab's (in z): exact outside bound.
                let c2 = center.truncate();
                let near_xy = (c2.clamp(lo.truncate(), hi.truncate()) - c2).length();
                let near_z = (center.z.clamp(lo.z, hi.z) - center.z).abs();
                let outside = (near_xy - radius).max(near_z - half_height);
                // Elsewhere (inside), the 1-Lipschitz bound at the centre.
                let lipschitz = self.sdf(0.5 * (lo + hi)).abs() - 0.5 * (hi - lo).length();
                outside.max(lipschitz).max(0.0)
            }
        }
    }

    pub fn to_json(self) -> serde_json::Value {
        match self {
            Shape::Sphere { center, radius } => {
                json!({"kind": "sphere", "center": center.to_array(), "radius": radius})
            }
            Shape::Puck {
                center,
                radius,
                half_height,
                rounding,
            } => json!({
                "kind": "rounded puck (disc extruded along z, rim rounded)",
                "center": center.to_array(), "radius": radius,
                "half_height": half_height, "rounding": rounding,
            }),
            Shape::Plane { height } => json!({"kind": "plane z = height", "height": height}),
        }
    }
}

/// A moving implicit surface with its velocity field: what the mesher and
/// the scenes need from a motion.
pub trait Motion: Send + Sync {
    /// The surface function at time t (negative inside) and the point of the
    /// initial configuration it was evaluated at (x itself for a surface given
    /// directly in time).
    fn locate(&self, x: DVec3, t: f64) -> (f64, DVec3);
    /// A lower bound of |φ| over the points whose images (see [`Self::locate`])
    /// fill the box [lo, hi]; 0 when the surface may pass there. Used by the
    /// mesher's narrow band.
    fn box_bound(&self, lo: DVec3, hi: DVec3, t: f64) -> f64;
    /// The surface function at time t.
    fn phi(&self, x: DVec3, t: f64) -> f64 {
        self.locate(x, t).0
    }
    /// Exact velocity u(x, t).
    fn velocity(&self, x: DVec3, t: f64) -> DVec3;
    /// Everything that defines the motion, for [`super::SceneInfo`].
    fn to_json(&self) -> serde_json::Value;
}

/// An initial shape carried by u = a(t)·v(x): φ(x, t) = φ₀(Φ₋τ(t)(x)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PulledBack {
    pub shape: Shape,
    pub field: Field,
    pub amplitude: Amplitude,
}

impl Motion for PulledBack {
    fn locate(&self, x: DVec3, t: f64) -> (f64, DVec3) {
        let p = self.field.map(x, -self.amplitude.tau(t));
        (self.shape.sdf(p), p)
    }

    fn box_bound(&self, lo: DVec3, hi: DVec3, _t: f64) -> f64 {
        self.shape.box_bound(lo, hi)
    }

    fn velocity(&self, x: DVec3, t: f64) -> DVec3 {
        let a = self.amplitude.a(t);
        if a == 0.0 {
            // Exactly zero (not −0.0) once a flow has stopped.
            return DVec3::ZERO;
        }
        a * self.field.v(x)
    }

    fn to_json(&self) -> serde_json::Value {
        json!({
            "surface": "phi(x, t) = phi0(Phi_{-tau(t)}(x)), tau(t) = integral of a",
            "initial_shape": self.shape.to_json(),
            "field": self.field.to_json(),
            "amplitude": self.amplitude.to_json(),
        })
    }
}

/// Two spheres whose centres approach along x, overlap and part again,
/// blended by a quadratic smooth minimum so that they merge through a neck.
///
/// Surface: φ = smin_k(|x − c₁(t)| − R, |x − c₂(t)| − R) with
/// smin_k(a, b) = min(a, b) − h²k/4, h = max(k − |a − b|, 0)/k (a C¹ blend;
/// its gradient is the convex combination m_a ∇a + m_b ∇b, m = h/2 on the
/// larger argument, so φ stays 1-Lipschitz). Centres c₁,₂ = (½ ∓ d(t), ½, ½),
/// d(t) = d_far − (d_far − d_near) sin²(πt/P): the drops touch (through the
/// blend) when d < R + k/4.
///
/// Velocity: each drop's points move with their drop, blended with the same
/// weights, u₀ = m_a ċ₁ + m_b ċ₂, plus the normal correction that makes the
/// surface material: u = u₀ − (∂φ/∂t + u₀·∇φ) ∇φ/|∇φ|², so Dφ/Dt = 0 on
/// every level set. Outside the blend the correction vanishes (each drop
/// translates rigidly). At the saddle of the neck ∇φ → 0 and the correction
/// is singular, as the speed of a real pinch-off is; it is clamped to
/// `max_correction` (a multiple of the largest centre speed), which only
/// affects points within a sliver of the saddle at the instants of merging
/// and splitting.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplitMerge {
    /// Drop radius R (world units).
    pub radius: f64,
    /// Half distance of the centres at t = 0 and t = P.
    pub d_far: f64,
    /// Half distance of the centres at t = P/2.
    pub d_near: f64,
    /// Blend width k of the smooth minimum (world units).
    pub blend: f64,
    /// Period P (seconds).
    pub period: f64,
    /// Bound on the normal correction, in multiples of the largest centre speed.
    pub max_correction: f64,
}

impl SplitMerge {
    fn half_distance(&self, t: f64) -> (f64, f64) {
        let w = PI / self.period;
        let s = (w * t).sin();
        let amp = self.d_far - self.d_near;
        // d and its derivative d' = −amp·w·sin(2wt).
        (self.d_far - amp * s * s, -amp * w * (2.0 * w * t).sin())
    }

    /// φ, ∇φ, ∂φ/∂t and the blend weight m_b at (x, t).
    fn eval(&self, x: DVec3, t: f64) -> (f64, DVec3, f64, f64, DVec3, DVec3) {
        let (d, dd) = self.half_distance(t);
        let c1 = DVec3::new(0.5 - d, 0.5, 0.5);
        let c2 = DVec3::new(0.5 + d, 0.5, 0.5);
        let (v1, v2) = (DVec3::new(-dd, 0.0, 0.0), DVec3::new(dd, 0.0, 0.0));
        let (r1, r2) = (x - c1, x - c2);
        let (l1, l2) = (r1.length(), r2.length());
        let (a, b) = (l1 - self.radius, l2 - self.radius);
        let (ga, gb) = (r1.normalize_or_zero(), r2.normalize_or_zero());
        let k = self.blend;
        let h = (k - (a - b).abs()).max(0.0) / k;
        let phi = a.min(b) - h * h * k * 0.25;
        // Weight of b: 1 − h/2 where b is the smaller argument, h/2 otherwise.
        let mb = if b < a { 1.0 - 0.5 * h } else { 0.5 * h };
        let ma = 1.0 - mb;
        let grad = ma * ga + mb * gb;
        // ∂a/∂t = −∇a·ċ₁.
        let dphi_dt = -ma * ga.dot(v1) - mb * gb.dot(v2);
        (phi, grad, dphi_dt, mb, v1, v2)
    }

    fn max_center_speed(&self) -> f64 {
        (self.d_far - self.d_near) * PI / self.period
    }
}

impl Motion for SplitMerge {
    fn locate(&self, x: DVec3, t: f64) -> (f64, DVec3) {
        (self.eval(x, t).0, x)
    }

    fn box_bound(&self, lo: DVec3, hi: DVec3, t: f64) -> f64 {
        // φ is 1-Lipschitz (see the type's doc).
        (self.phi(0.5 * (lo + hi), t).abs() - 0.5 * (hi - lo).length()).max(0.0)
    }

    fn velocity(&self, x: DVec3, t: f64) -> DVec3 {
        let (_, grad, dphi_dt, mb, v1, v2) = self.eval(x, t);
        let u0 = (1.0 - mb) * v1 + mb * v2;
        let g2 = grad.length_squared();
        let residual = dphi_dt + u0.dot(grad);
        if residual == 0.0 || g2 == 0.0 {
            return u0;
        }
        let mut corr = -residual / g2 * grad;
        let cap = self.max_correction * self.max_center_speed();
        let len = corr.length();
        if len > cap {
            corr *= cap / len;
        }
        u0 + corr
    }

    fn to_json(&self) -> serde_json::Value {
        json!({
            "surface": "phi = smin_k(|x - c1| - R, |x - c2| - R), smin_k(a,b) = min(a,b) - h^2 k/4, h = max(k - |a-b|, 0)/k",
            "centres": "c1,2 = (1/2 -+ d(t), 1/2, 1/2), d(t) = d_far - (d_far - d_near) sin^2(pi t / P)",
            "velocity": "u0 = m_a c1' + m_b c2' (smin weights), u = u0 - (dphi/dt + u0.grad phi) grad phi/|grad phi|^2, correction clamped",
            "R": self.radius, "d_far": self.d_far, "d_near": self.d_near,
            "k": self.blend, "P": self.period,
            "max_correction_times_max_centre_speed": self.max_correction,
        })
    }
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;

    fn random_point(rng: &mut Pcg64) -> DVec3 {
        DVec3::new(rng.random(), rng.random(), rng.random())
    }

    #[test]
    fn tau_is_the_integral_of_a() {
        let amps = [
            Amplitude::Constant,
            Amplitude::Cosine {
                period: 3.0,
                speed: 1.0,
            },
            Amplitude::Ramp {
                hold: 1.0,
                ramp: 0.75,
            },
        ];
        for amp in amps {
            // Composite Simpson on a fine grid, independent of the closed form.
            let n = 4000;
            for &t in &[0.3, 1.2, 1.5, 2.9, 4.0] {
                let h = t / n as f64;
                let mut s = amp.a(0.0) + amp.a(t);
                for i in 1..n {
                    let w = if i % 2 == 1 { 4.0 } else { 2.0 };
                    s += w * amp.a(i as f64 * h);
                }
                let integral = s * h / 3.0;
                assert!(
                    (integral - amp.tau(t)).abs() < 1e-9,
                    "{amp:?} t={t}: {integral} vs {}",
                    amp.tau(t)
                );
            }
        }
    }

    #[test]
    fn cosine_flows_return_to_the_start() {
        let amp = Amplitude::Cosine {
            period: 3.0,
            speed: 1.0,
        };
        assert!(amp.tau(3.0).abs() < 1e-15);
        let mut rng = Pcg64::seed_from_u64(1);
        for _ in 0..20 {
            let p = random_point(&mut rng);
            assert!((Field::Enright.map(p, amp.tau(3.0)) - p).length() < 1e-13);
        }
    }

    #[test]
    fn ramp_tau_is_constant_after_the_stop() {
        let amp = Amplitude::Ramp {
            hold: 1.0,
            ramp: 1.0,
        };
        assert_eq!(amp.tau(2.0).to_bits(), amp.tau(3.7).to_bits());
        assert_eq!(amp.a(2.5), 0.0);
        assert!(amp.a(1.9) > 0.0);
    }

    #[test]
    fn backward_then_forward_trace_is_the_identity() {
        let mut rng = Pcg64::seed_from_u64(7);
        for field in [Field::Enright, Field::SingleVortex] {
            for _ in 0..20 {
                let p = random_point(&mut rng);
                let back = field.map(field.map(p, 0.8), -0.8);
                assert!((back - p).length() < 1e-4, "{field:?}: {p} -> {back}");
            }
        }
    }

    #[test]
    fn rk4_step_is_converged() {
        // Halving the step moves the traced point by less than 1% of a cell
        // (1/64 at the Enright default resolution, 1/96 for the vortex),
        // over the longest τ of each scene.
        let mut rng = Pcg64::seed_from_u64(3);
        for (field, step, tau, cells) in [
            (Field::Enright, ENRIGHT_MAX_STEP, 3.0 / PI, 64.0),
            (Field::SingleVortex, VORTEX_MAX_STEP, 8.0 / PI, 96.0),
        ] {
            for _ in 0..20 {
                let p = random_point(&mut rng);
                let a = field.rk4(p, -tau, step);
                let b = field.rk4(p, -tau, step / 2.0);
                let err = (a - b).length() * cells;
                assert!(err < 1e-2, "{field:?}: {err} cells");
            }
        }
    }

    #[test]
    fn closed_form_maps_agree_with_rk4() {
        let mut rng = Pcg64::seed_from_u64(5);
        let fields = [
            Field::RigidRotation {
                center: DVec3::splat(0.5),
                omega: 1.3,
            },
            Field::DifferentialRotation {
                center: DVec3::splat(0.5),
                omega0: 0.5,
                omega1: 3.0,
            },
            Field::Shear { gamma: 0.7 },
        ];
        for field in fields {
            for _ in 0..10 {
                let p = random_point(&mut rng);
                let exact = field.map(p, -1.7);
                let rk = field.rk4(p, -1.7, 0.005);
                assert!((exact - rk).length() < 1e-9, "{field:?}");
            }
        }
    }

    #[test]
    fn fields_match_the_written_formulas() {
        // Evaluated here straight from docs/evaluation.md, with sin(2πs) as is.
        let s = |v: f64| v.sin();
        let mut rng = Pcg64::seed_from_u64(11);
        for _ in 0..50 {
            let p = random_point(&mut rng);
            let (x, y, z) = (p.x, p.y, p.z);
            let e = DVec3::new(
                2.0 * s(PI * x).powi(2) * s(2.0 * PI * y) * s(2.0 * PI * z),
                -s(2.0 * PI * x) * s(PI * y).powi(2) * s(2.0 * PI * z),
                -s(2.0 * PI * x) * s(2.0 * PI * y) * s(PI * z).powi(2),
            );
            assert!((Field::Enright.v(p) - e).length() < 1e-12);
            let v = DVec3::new(
                s(PI * x).powi(2) * s(2.0 * PI * y),
                -s(PI * y).powi(2) * s(2.0 * PI * x),
                0.0,
            );
            assert!((Field::SingleVortex.v(p) - v).length() < 1e-12);
        }
    }

    #[test]
    fn box_bounds_are_lower_bounds() {
        let shapes = [
            Shape::Sphere {
                center: DVec3::new(0.4, 0.5, 0.6),
                radius: 0.2,
            },
            Shape::Plane { height: 0.45 },
            Shape::Puck {
                center: DVec3::new(0.5, 0.7, 0.5),
                radius: 0.15,
                half_height: 0.05,
                rounding: 0.02,
            },
        ];
        let mut rng = Pcg64::seed_from_u64(9);
        for shape in shapes {
            let mut positive = 0;
            for _ in 0..300 {
                let a = random_point(&mut rng);
                let b = a + random_point(&mut rng) * 0.3;
                let bound = shape.box_bound(a, b);
                positive += usize::from(bound > 0.0);
                for _ in 0..50 {
                    let u = random_point(&mut rng);
                    let p = a + (b - a) * u;
                    assert!(shape.sdf(p).abs() >= bound - 1e-12, "{shape:?}");
                }
            }
            // A bound that is always 0 would pass the above: it must be useful.
            assert!(positive > 100, "{shape:?}: {positive}");
        }
    }

    #[test]
    fn split_merge_velocity_is_material() {
        // Dφ/Dt = ∂φ/∂t + u·∇φ = 0 by finite differences, wherever the
        // correction is not clamped.
        let m = SplitMerge {
            radius: 0.15,
            d_far: 0.25,
            d_near: 0.12,
            blend: 0.08,
            period: 4.0,
            max_correction: 1e9,
        };
        let mut rng = Pcg64::seed_from_u64(2);
        let eps = 1e-6;
        let mut checked = 0;
        while checked < 200 {
            let x = DVec3::new(
                rng.random_range(0.05..0.95),
                rng.random_range(0.3..0.7),
                rng.random_range(0.3..0.7),
            );
            let t = rng.random_range(0.0..4.0);
            if m.phi(x, t).abs() > 0.05 {
                continue;
            }
            let u = m.velocity(x, t);
            let ahead = m.phi(x + eps * u, t + eps);
            let behind = m.phi(x - eps * u, t - eps);
            assert!(
                ((ahead - behind) / (2.0 * eps)).abs() < 1e-5,
                "x={x} t={t}: {}",
                (ahead - behind) / (2.0 * eps)
            );
            checked += 1;
        }
    }
}
