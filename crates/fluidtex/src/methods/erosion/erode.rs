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
//! once per exemplar by [`max_norm`]. The equation is implemented as written
//! (the authors' public code replaced it by a pre-baked image sequence).

use crate::texture::{Texture, Wrap};

/// D(u, v) of Sec. 5.2: 1 at the patch centre, falling linearly to 0 at
/// distance 0.5 in uv.
#[inline]
pub fn centre_falloff(u: f32, v: f32) -> f32 {
    let (du, dv) = (u - 0.5, v - 0.5);
    (1.0 - (du * du + dv * dv).sqrt() / 0.5).max(0.0)
}

/// max over the feature map of sqrt(F_m(s,t) + D(s,t)), taken at texel
/// centres of the feature map over one tile [0,1]² (where D is defined).
/// The maximum of a bilinear interpolant of texel values lies at texel
/// centres for F_m, and D peaks at the centre: evaluating at texel centres
/// and at (0.5, 0.5) itself gives the exact maximum of the continuous map
/// up to the sub-texel variation of D.
pub fn max_norm(feature: &Texture) -> f32 {
    let (w, h) = (feature.width, feature.height);
    let mut best = 0.0f32;
    let mut probe = [0.0f32];
    feature.sample_bilinear(0.5, 0.5, Wrap::Repeat, &mut probe);
    best = best.max((probe[0] + 1.0).max(0.0).sqrt());
    for y in 0..h {
        for x in 0..w {
            let (u, v) = ((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let f = feature.texel(x, y)[0];
            best = best.max((f + centre_falloff(u, v)).max(0.0).sqrt());
        }
    }
    best
}

/// The erosion decision with its constants bound.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErosionTest {
    /// 1 / max_{s,t} sqrt(F_m + D).
    inv_max_norm: f32,
    /// ε of Sec. 5.2.
    epsilon: f32,
}

impl ErosionTest {
    /// `max_norm` from [`max_norm`] (must be > 0), ε ∈ (0, 1) by default 0.1.
    pub fn new(max_norm: f32, epsilon: f32) -> ErosionTest {
        ErosionTest {
            inv_max_norm: if max_norm > 0.0 { 1.0 / max_norm } else { 0.0 },
            epsilon,
        }
    }

    /// Left-hand side of the test: normalised sqrt(F_m + D) − ε.
    #[inline]
    pub fn lhs(&self, feature: f32, u: f32, v: f32) -> f32 {
        (feature + centre_falloff(u, v)).max(0.0).sqrt() * self.inv_max_norm - self.epsilon
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

    #[test]
    fn max_norm_of_constant_and_peaked_maps() {
        // Constant F = c: the maximum is at the centre, sqrt(c + 1).
        let flat = Texture::filled(16, 16, 1, 0.3);
        assert!((max_norm(&flat) - 1.3f32.sqrt()).abs() < 1e-6);
        // A single bright texel in a corner, where D = 0: sqrt(1) vs centre
        // sqrt(0 + 1): equal; make it exceed with F = 1 near the centre.
        let mut peak = Texture::filled(16, 16, 1, 0.0);
        peak.texel_mut(8, 8)[0] = 1.0; // centre (8.5/16, 8.5/16), D ≈ 0.94
        let d = centre_falloff(8.5 / 16.0, 8.5 / 16.0);
        assert!((max_norm(&peak) - (1.0 + d).sqrt()).abs() < 1e-6);
    }
}
