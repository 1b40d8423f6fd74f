//! Feature-aware erosion test (Gagnon et al. 2021, Sec. 5.2).
//!
//! A patch texel at patch uv (u, v) with interpolated weight w is eroded when
//!
//! ```text
//! sqrt(F_m(u,v) + D(u,v)) / max_{s,t} sqrt(F_m(s,t) + D(s,t)) − ε  <  1 − w
//! ```
//!
//! with D(u, v) = max(0, 1 − ‖(0.5, 0.5) − (u, v)‖ / 0.5): texels with low
//! feature values, far from the patch centre or on distorted parts of the
//! patch go first. The denominator is a constant of the feature map, computed
//! once per exemplar by [`FeatureMap::erosion_normaliser_with_reach`]. The equation is implemented as
//! written (the authors' public code replaced it by a pre-baked image
//! sequence), with one documented choice: by default D reaches 0 at the
//! patch's own footprint, uv distance r/S, rather than at the exemplar
//! square's edge (0.5), so that every patch is eroded along the features
//! from its creation on (`Falloff` in the method's parameters; the paper's
//! reach stays selectable).

use crate::exemplar::FeatureMap;

/// The uv distance at which the paper's D(u, v) reaches 0: the edge of the
/// exemplar square.
pub const PAPER_REACH: f32 = 0.5;

/// D(u, v) of Sec. 5.2: 1 at the patch centre, falling linearly to 0 at
/// distance 0.5 in uv.
#[inline]
pub fn centre_falloff(u: f32, v: f32) -> f32 {
    falloff_with_reach(u, v, 1.0 / PAPER_REACH)
}

/// D(u, v) falling linearly from 1 at the centre to 0 at uv distance
/// 1 / `inv_reach`.
#[inline]
fn falloff_with_reach(u: f32, v: f32, inv_reach: f32) -> f32 {
    let (du, dv) = (u - 0.5, v - 0.5);
    (1.0 - (du * du + dv * dv).sqrt() * inv_reach).max(0.0)
}

/// The erosion decision with its constants bound.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErosionTest {
    /// 1 / max_{s,t} sqrt(F_m + D).
    inv_max_norm: f32,
    /// ε of Sec. 5.2.
    epsilon: f32,
    /// 1 / the uv distance where D reaches 0 (2 for the paper's D).
    inv_reach: f32,
}

impl ErosionTest {
    /// `max_norm` from [`crate::exemplar::FeatureMap::erosion_normaliser`] (must be > 0), ε ∈ (0, 1) by default 0.1.
    pub fn new(max_norm: f32, epsilon: f32) -> ErosionTest {
        ErosionTest {
            inv_max_norm: if max_norm > 0.0 { 1.0 / max_norm } else { 0.0 },
            epsilon,
            inv_reach: 1.0 / PAPER_REACH,
        }
    }

    /// The test with D reaching 0 at uv distance `reach` from the centre
    /// (the patch footprint r/S instead of the paper's 0.5), normalised over
    /// the feature map `map` for that D.
    pub fn with_reach(feature: &FeatureMap, epsilon: f32, reach: f32) -> ErosionTest {
        let reach = reach.max(1e-3);
        ErosionTest {
            inv_reach: 1.0 / reach,
            ..ErosionTest::new(feature.erosion_normaliser_with_reach(reach), epsilon)
        }
    }

    /// A test that never erodes (the baselines that carry patches without
    /// erosion): ε = −∞ makes the left-hand side +∞, never below 1 − w.
    pub fn never() -> ErosionTest {
        ErosionTest {
            inv_max_norm: 0.0,
            epsilon: f32::NEG_INFINITY,
            inv_reach: 1.0 / PAPER_REACH,
        }
    }

    /// Left-hand side of the test: normalised sqrt(F_m + D) − ε.
    #[inline]
    pub fn lhs(&self, feature: f32, u: f32, v: f32) -> f32 {
        (feature + falloff_with_reach(u, v, self.inv_reach))
            .max(0.0)
            .sqrt()
            * self.inv_max_norm
            - self.epsilon
    }

    /// True when the texel is eroded (rejected) for weight `w`.
    #[inline]
    pub fn eroded(&self, feature: f32, u: f32, v: f32, w: f32) -> bool {
        self.lhs(feature, u, v) < 1.0 - w
    }
}

#[cfg(test)]
mod tests {
    use serde::Deserialize;

    use super::*;

    #[derive(Deserialize)]
    struct Case {
        u: f32,
        v: f32,
        #[serde(rename = "F_m")]
        f: f32,
        max_norm: f32,
        epsilon: f32,
        w: f32,
        #[serde(rename = "D")]
        d: f32,
        lhs: f32,
        eroded: bool,
    }

    #[derive(Deserialize)]
    struct Vectors {
        erosion: Vec<Case>,
    }

    #[test]
    fn the_disabled_test_keeps_every_texel() {
        let t = ErosionTest::never();
        for (f, u, v, w) in [
            (0.0, 0.0, 0.0, 0.0),
            (1.0, 0.5, 0.5, 0.0),
            (0.3, 0.9, 0.1, 1.0),
        ] {
            assert!(!t.eroded(f, u, v, w));
        }
        // Control: the real test erodes the first case.
        assert!(ErosionTest::new(1.0, 0.1).eroded(0.0, 0.0, 0.0, 0.0));
    }

    #[test]
    fn matches_the_independent_vectors() {
        let v: Vectors = serde_json::from_str(include_str!(
            "../../../tests/data/vectors/erosion-vectors.json"
        ))
        .expect("vectors parse");
        assert!(v.erosion.len() >= 10);
        for (i, c) in v.erosion.iter().enumerate() {
            assert!((centre_falloff(c.u, c.v) - c.d).abs() < 1e-6, "case {i}: D");
            let test = ErosionTest::new(c.max_norm, c.epsilon);
            assert!(
                (test.lhs(c.f, c.u, c.v) - c.lhs).abs() < 1e-6,
                "case {i}: lhs"
            );
            assert_eq!(test.eroded(c.f, c.u, c.v, c.w), c.eroded, "case {i}");
        }
    }

    #[test]
    fn centre_is_kept_at_full_weight_and_eroded_at_zero() {
        let t = ErosionTest::new(2f32.sqrt(), 0.1);
        // At the centre D = 1: lhs ≥ 1/√2 − ε > 0 = 1 − w.
        for f in [0.0, 0.5, 1.0] {
            assert!(!t.eroded(f, 0.5, 0.5, 1.0));
            assert!(t.eroded(f, 0.5, 0.5, 0.0));
        }
    }

    #[test]
    fn threshold_weight_is_exact() {
        // Hand computation: F = 0.44, (u,v) = (0.8, 0.5) → D = 0.4,
        // sqrt(0.84)/√2 − 0.1 = 0.548074...; eroded iff w < 1 − 0.548074 =
        // 0.451926 (checked on either side of that weight).
        let t = ErosionTest::new(2f32.sqrt(), 0.1);
        let lhs = (0.84f64).sqrt() / 2f64.sqrt() - 0.1;
        let w_star = (1.0 - lhs) as f32;
        assert!((t.lhs(0.44, 0.8, 0.5) as f64 - lhs).abs() < 1e-6);
        assert!(t.eroded(0.44, 0.8, 0.5, w_star - 1e-4));
        assert!(!t.eroded(0.44, 0.8, 0.5, w_star + 1e-4));
    }
}
