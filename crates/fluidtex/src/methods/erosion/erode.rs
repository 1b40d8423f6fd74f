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

use glam::Vec2;

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

    /// Whether the test can erode anything ([`ErosionTest::never`] cannot):
    /// a weight below 1 erodes texels only where it can.
    pub fn can_erode(&self) -> bool {
        self.epsilon.is_finite()
    }

    /// Left-hand side of the test: normalised sqrt(F_m + D) − ε.
    #[inline]
    pub fn lhs(&self, feature: f32, u: f32, v: f32) -> f32 {
        self.lhs_of_sum(feature + falloff_with_reach(u, v, self.inv_reach))
    }

    /// The left-hand side for F_m + D = `sum`.
    #[inline]
    fn lhs_of_sum(&self, sum: f32) -> f32 {
        sum.max(0.0).sqrt() * self.inv_max_norm - self.epsilon
    }

    /// True when the texel is eroded (rejected) for weight `w`.
    #[inline]
    pub fn eroded(&self, feature: f32, u: f32, v: f32, w: f32) -> bool {
        ErosionTest::eroded_lhs(self.lhs(feature, u, v), w)
    }

    /// [`ErosionTest::eroded`] once the left-hand side `lhs` is known: the
    /// test at several weights of one point computes it once.
    #[inline]
    pub fn eroded_lhs(lhs: f32, w: f32) -> bool {
        lhs < 1.0 - w
    }
}

/// What the erosion test says of every point of one patch triangle,
/// whatever the feature value there ([`ErosionTest::triangle_verdict`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Some points may be kept and others eroded: test each.
    Test,
    /// Every point is kept.
    Kept,
    /// Every point is eroded.
    Eroded,
}

/// Slack, in units of the test's left-hand side, between a verdict's bound
/// and the per-texel test: far above the float error of that test (≈ 1e-6),
/// so a verdict never disagrees with it.
const VERDICT_MARGIN: f32 = 1e-4;

impl ErosionTest {
    /// The verdict for a patch triangle with rest uvs `uv` and vertex
    /// weights `w`, for any point of it (its uv and w are convex
    /// combinations of the corners') and any feature value in \[0, 1\] (the
    /// map's range, kept by every mip level). The left-hand side grows with
    /// F_m + D, and D is concave where positive: over the triangle D is
    /// least at a corner and greatest at the point nearest the centre. So
    /// the test holds everywhere when it holds for F_m = 0, the least D and
    /// the least w, and fails everywhere when it fails for F_m = 1, the
    /// greatest D and the greatest w. A non-finite corner gives
    /// [`Verdict::Test`].
    pub fn triangle_verdict(&self, uv: [Vec2; 3], w: [f32; 3]) -> Verdict {
        if !uv.iter().all(|p| p.is_finite()) || !w.iter().all(|v| v.is_finite()) {
            return Verdict::Test;
        }
        let d_least = uv
            .iter()
            .map(|p| falloff_with_reach(p.x, p.y, self.inv_reach))
            .fold(f32::INFINITY, f32::min);
        let nearest = distance_to_triangle(Vec2::splat(0.5), uv);
        let d_greatest = (1.0 - nearest * self.inv_reach).max(0.0);
        let w_least = w[0].min(w[1]).min(w[2]);
        let w_greatest = w[0].max(w[1]).max(w[2]);
        if self.lhs_of_sum(d_least) - VERDICT_MARGIN >= 1.0 - w_least {
            Verdict::Kept
        } else if self.lhs_of_sum(1.0 + d_greatest) + VERDICT_MARGIN < 1.0 - w_greatest {
            Verdict::Eroded
        } else {
            Verdict::Test
        }
    }
}

/// Distance from `p` to the triangle `t` in the plane (0 inside; a
/// collapsed triangle is its longest edge).
fn distance_to_triangle(p: Vec2, t: [Vec2; 3]) -> f32 {
    let side = |a: Vec2, b: Vec2| (b - a).perp_dot(p - a);
    let s = [side(t[0], t[1]), side(t[1], t[2]), side(t[2], t[0])];
    if s.iter().all(|&v| v > 0.0) || s.iter().all(|&v| v < 0.0) {
        return 0.0;
    }
    let to_segment = |a: Vec2, b: Vec2| {
        let e = b - a;
        let len2 = e.length_squared();
        let k = if len2 > 0.0 {
            ((p - a).dot(e) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (a + e * k - p).length()
    };
    to_segment(t[0], t[1])
        .min(to_segment(t[1], t[2]))
        .min(to_segment(t[2], t[0]))
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;
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

    /// A point of triangle `t` at random barycentrics, as the fill forms it.
    fn point_in(rng: &mut Pcg64, t: [Vec2; 3], w: [f32; 3]) -> (Vec2, f32) {
        let b: [f32; 3] = std::array::from_fn(|_| rng.random::<f32>());
        let s = b[0] + b[1] + b[2];
        let b = b.map(|v| v / s);
        (
            t[0] * b[0] + t[1] * b[1] + t[2] * b[2],
            w[0] * b[0] + w[1] * b[1] + w[2] * b[2],
        )
    }

    #[test]
    fn a_triangle_verdict_agrees_with_the_test_at_every_point() {
        let mut rng = Pcg64::seed_from_u64(11);
        let mut seen = [0usize; 3];
        for case in 0..3000 {
            let test = ErosionTest {
                inv_max_norm: 1.0 / rng.random_range(0.8f32..1.6),
                epsilon: rng.random_range(0.0f32..0.3),
                inv_reach: 1.0 / rng.random_range(0.2f32..0.6),
            };
            // Small triangles anywhere in the patch, weights from 0 to 1.
            let centre = Vec2::new(rng.random(), rng.random());
            let size = rng.random_range(0.005f32..0.2);
            let t: [Vec2; 3] = std::array::from_fn(|_| {
                centre + Vec2::new(rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5) * size
            });
            let base = rng.random::<f32>();
            let w: [f32; 3] =
                std::array::from_fn(|_| (base + rng.random_range(-0.1f32..0.1)).clamp(0.0, 1.0));
            let verdict = test.triangle_verdict(t, w);
            seen[verdict as usize] += 1;
            if verdict == Verdict::Test {
                continue;
            }
            for _ in 0..200 {
                let (uv, wp) = point_in(&mut rng, t, w);
                // The extremes of F_m as well as values between.
                let f = match rng.random_range(0..4) {
                    0 => 0.0,
                    1 => 1.0,
                    _ => rng.random::<f32>(),
                };
                let eroded = test.eroded(f, uv.x, uv.y, wp);
                assert_eq!(
                    eroded,
                    verdict == Verdict::Eroded,
                    "case {case}: {t:?} {w:?}"
                );
            }
        }
        // Every verdict occurs, so the agreement above is tested on each.
        assert!(seen.iter().all(|&n| n > 200), "{seen:?}");
    }

    #[test]
    fn verdicts_of_known_triangles() {
        let test = ErosionTest::new(2f32.sqrt(), 0.1);
        let near_centre = [
            Vec2::new(0.45, 0.45),
            Vec2::new(0.55, 0.45),
            Vec2::new(0.5, 0.55),
        ];
        assert_eq!(test.triangle_verdict(near_centre, [1.0; 3]), Verdict::Kept);
        assert_eq!(
            test.triangle_verdict(near_centre, [0.0; 3]),
            Verdict::Eroded
        );
        // At w = 0.3 a texel with F_m = 1 survives and one with F_m = 0 does not.
        assert!(!test.eroded(1.0, 0.5, 0.5, 0.3) && test.eroded(0.0, 0.5, 0.5, 0.3));
        assert_eq!(test.triangle_verdict(near_centre, [0.3; 3]), Verdict::Test);
        // The centre lies inside this triangle though no corner is near it:
        // D reaches 1 there, which a bound from the corners alone would miss.
        let around = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.5, 1.0),
        ];
        assert_eq!(test.triangle_verdict(around, [0.2; 3]), Verdict::Test);
        assert!(!test.eroded(1.0, 0.5, 0.5, 0.2) && test.eroded(1.0, 0.0, 0.0, 0.2));
        // Non-finite corners are always tested; the disabled test keeps all.
        let nan = [Vec2::NAN, Vec2::ZERO, Vec2::ONE];
        assert_eq!(test.triangle_verdict(nan, [1.0; 3]), Verdict::Test);
        assert!(!ErosionTest::never().can_erode() && test.can_erode());
        assert_eq!(
            ErosionTest::never().triangle_verdict(near_centre, [0.0; 3]),
            Verdict::Kept
        );
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
