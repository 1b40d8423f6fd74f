//! Triangle distortion δ_t (Sorkine, Cohen-Or, Goldenthal, Lischinski 2002,
//! "Bounded-distortion piecewise mesh parameterization", Sec. 3) and the
//! triangle quality Q_T of Gagnon et al. 2021, Eq. 1.
//!
//! The map goes from a triangle's rest shape (its flattened coordinates in
//! world units, fixed at patch creation) to its current 3-D position. Its
//! Jacobian's singular values Γ ≥ γ measure the largest stretch and the
//! largest compression; δ_t = max(Γ, 1/γ) is 1 exactly for an isometry and
//! grows with either. Computed in f64: the expressions subtract nearly equal
//! quantities for near-isometric triangles, which is the common case.

use glam::{DVec2, DVec3, Vec2, Vec3};

/// Singular values and distortion of one triangle's rest→current map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Distortion {
    /// Largest singular value Γ (maximal stretch).
    pub gamma_max: f64,
    /// Smallest singular value γ (maximal compression).
    pub gamma_min: f64,
    /// δ_t = max(Γ, 1/γ) ≥ 1; +∞ for a collapsed or degenerate triangle.
    pub delta: f64,
}

/// Distortion of the map from rest coordinates `(s_i, t_i)` to 3-D points `q_i`.
pub fn distortion(rest: [Vec2; 3], q: [Vec3; 3]) -> Distortion {
    let r = rest.map(|p| p.as_dvec2());
    let q = q.map(|p| p.as_dvec3());
    distortion_f64(r, q)
}

/// [`distortion`] on f64 input (used by the tests against the f64 vectors).
pub fn distortion_f64(r: [DVec2; 3], q: [DVec3; 3]) -> Distortion {
    let (s1, t1) = (r[0].x, r[0].y);
    let (s2, t2) = (r[1].x, r[1].y);
    let (s3, t3) = (r[2].x, r[2].y);
    let area = ((s2 - s1) * (t3 - t1) - (s3 - s1) * (t2 - t1)) / 2.0;
    if area.abs() < f64::MIN_POSITIVE || !area.is_finite() {
        return Distortion {
            gamma_max: f64::INFINITY,
            gamma_min: 0.0,
            delta: f64::INFINITY,
        };
    }
    let ss = (q[0] * (t2 - t3) + q[1] * (t3 - t1) + q[2] * (t1 - t2)) / (2.0 * area);
    let st = (q[0] * (s3 - s2) + q[1] * (s1 - s3) + q[2] * (s2 - s1)) / (2.0 * area);
    let a = ss.dot(ss);
    let b = ss.dot(st);
    let c = st.dot(st);
    let root = ((a - c) * (a - c) + 4.0 * b * b).sqrt();
    let gamma_max = (0.5 * (a + c + root)).sqrt();
    // a + c − root can round to a tiny negative number for a collapsed triangle.
    let gamma_min = (0.5 * (a + c - root)).max(0.0).sqrt();
    let delta = if gamma_min > 0.0 {
        gamma_max.max(1.0 / gamma_min)
    } else {
        f64::INFINITY
    };
    Distortion {
        gamma_max,
        gamma_min,
        delta,
    }
}

/// Eq. 1 of Gagnon et al. 2021: Q_T = max((δ_max − δ_t)/(δ_max − 1), 0).
/// 1 for an undistorted triangle, 0 at or beyond δ_max.
#[inline]
pub fn triangle_quality(delta: f64, delta_max: f64) -> f64 {
    triangle_quality_from(delta, 1.0, delta_max)
}

/// Eq. 1 with the fall starting at δ_onset instead of 1:
/// Q_T = clamp((δ_max − δ_t)/(δ_max − δ_onset), 0, 1). δ_onset = 1 is the
/// paper's Eq. 1 exactly.
#[inline]
pub fn triangle_quality_from(delta: f64, delta_onset: f64, delta_max: f64) -> f64 {
    ((delta_max - delta) / (delta_max - delta_onset)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use serde::Deserialize;

    use super::*;

    #[derive(Deserialize)]
    struct Case {
        name: String,
        rest_st: [[f64; 2]; 3],
        q: [[f64; 3]; 3],
        #[serde(rename = "Gamma")]
        gamma_max: f64,
        #[serde(rename = "gamma")]
        gamma_min: f64,
        delta: f64,
        #[serde(rename = "Q_T_delta_max_3")]
        q_t: f64,
    }

    #[derive(Deserialize)]
    struct Vectors {
        distortion: Vec<Case>,
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * (1.0 + b.abs())
    }

    #[test]
    fn matches_the_independent_vectors() {
        let v: Vectors = serde_json::from_str(include_str!(
            "../../../tests/data/vectors/erosion-vectors.json"
        ))
        .expect("vectors parse");
        assert!(v.distortion.len() >= 10);
        for c in &v.distortion {
            let r = c.rest_st.map(|p| DVec2::new(p[0], p[1]));
            let q = c.q.map(|p| DVec3::new(p[0], p[1], p[2]));
            let d = distortion_f64(r, q);
            assert!(
                close(d.gamma_max, c.gamma_max),
                "{}: Γ {} vs {}",
                c.name,
                d.gamma_max,
                c.gamma_max
            );
            assert!(
                close(d.gamma_min, c.gamma_min),
                "{}: γ {} vs {}",
                c.name,
                d.gamma_min,
                c.gamma_min
            );
            assert!(
                close(d.delta, c.delta),
                "{}: δ {} vs {}",
                c.name,
                d.delta,
                c.delta
            );
            assert!(
                close(triangle_quality(d.delta, 3.0), c.q_t),
                "{}: Q_T",
                c.name
            );
        }
    }

    #[test]
    fn rigid_motions_of_random_triangles_have_unit_distortion() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        for _ in 0..500 {
            let rest: [Vec2; 3] = std::array::from_fn(|_| Vec2::new(rng.random(), rng.random()));
            let e0 = rest[1] - rest[0];
            let e1 = rest[2] - rest[0];
            if e0.perp_dot(e1).abs() < 0.05 {
                continue; // skip slivers: f32 input makes them ill-conditioned
            }
            let axis = Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
            let rot = glam::Quat::from_axis_angle(axis.normalize(), rng.random::<f32>() * 6.0);
            let shift = Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
            let q = rest.map(|p| rot * p.extend(0.0) + shift);
            let d = distortion(rest, q);
            assert!((d.delta - 1.0).abs() < 1e-4, "δ = {}", d.delta);
            assert!((triangle_quality(d.delta, 3.0) - 1.0).abs() < 1e-4);
        }
    }

    #[test]
    fn known_stretch_has_its_analytic_value() {
        // Stretch by a along s and compress by b along t: Γ = a, γ = b,
        // δ = max(a, 1/b).
        let rest = [Vec2::ZERO, Vec2::new(0.3, 0.0), Vec2::new(0.1, 0.2)];
        for (a, b) in [(1.5f32, 1.0f32), (1.0, 0.4), (2.5, 0.8), (1.2, 0.5)] {
            let q = rest.map(|p| Vec3::new(a * p.x, b * p.y, 0.0));
            let d = distortion(rest, q);
            assert!((d.gamma_max - a as f64).abs() < 1e-5);
            assert!((d.gamma_min - b as f64).abs() < 1e-5);
            let want = (a as f64).max(1.0 / b as f64);
            assert!((d.delta - want).abs() < 1e-5, "{} vs {want}", d.delta);
        }
    }

    #[test]
    fn collapsed_triangles_are_infinitely_distorted() {
        let rest = [Vec2::ZERO, Vec2::X, Vec2::Y];
        let flat = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        assert_eq!(distortion(rest, flat).delta, f64::INFINITY);
        let degenerate_rest = [Vec2::ZERO, Vec2::X, Vec2::X * 2.0];
        assert_eq!(
            distortion(degenerate_rest, [Vec3::ZERO, Vec3::X, Vec3::Y]).delta,
            f64::INFINITY
        );
        assert_eq!(triangle_quality(f64::INFINITY, 3.0), 0.0);
    }

    #[test]
    fn quality_onset_holds_one_then_falls_linearly_to_delta_max() {
        // δ_onset = 1 is the paper's Eq. 1 at every δ.
        for i in 0..=40 {
            let d = 1.0 + i as f64 * 0.1;
            assert_eq!(triangle_quality_from(d, 1.0, 3.0), triangle_quality(d, 3.0));
        }
        // δ_onset = 1.5: 1 up to the onset, 0 from δ_max, linear between.
        assert_eq!(triangle_quality_from(1.0, 1.5, 3.0), 1.0);
        assert_eq!(triangle_quality_from(1.5, 1.5, 3.0), 1.0);
        assert!((triangle_quality_from(2.25, 1.5, 3.0) - 0.5).abs() < 1e-12);
        assert!((triangle_quality_from(2.7, 1.5, 3.0) - 0.2).abs() < 1e-12);
        assert_eq!(triangle_quality_from(3.0, 1.5, 3.0), 0.0);
        assert_eq!(triangle_quality_from(f64::INFINITY, 1.5, 3.0), 0.0);
        // Below the onset a distorted triangle loses nothing; the paper's
        // Eq. 1 already lowers it.
        assert!(triangle_quality(1.4, 3.0) < 1.0);
    }
}
