//! Distortion: how far the exemplar is stretched or squashed on the surface
//! relative to its scale when the patch was created.
//!
//! At each chart texel the Jacobian J = d(exemplar uv, in exemplar texels) /
//! d(surface tangent coordinates) is estimated by finite differences with
//! its right and lower neighbours (left or upper where those are missing)
//! that have the same source, and the same chart where charts are given.
//! With P = [dp/dx dp/dy] (3×2, surface point per atlas texel step) and
//! U = [du/dx du/dy] (2×2, exemplar texels per atlas texel step), an
//! orthonormal tangent frame e₁ = dp/dx/|dp/dx|, e₂ = n̂ × e₁ (n = dp/dx ×
//! dp/dy) gives P = E T with T upper triangular, and J = U T⁻¹. The singular
//! values σ₁ ≥ σ₂ of the 2×2 J come in closed form (via the conformal and
//! anti-conformal parts of J), and its weight is the surface area it
//! covers, |dp/dx × dp/dy|.
//!
//! **The metric** is the distortion the primary method bounds
//! (docs/design.md, *Triangle distortion*):
//! Sorkine et al. 2002's δ = max(σ₁/s₀, s₀/σ₂), where s₀ is the texel
//! scale at the patch's creation (exemplar texels per world unit: the
//! exemplar's width over the world size S it covers), so a patch is
//! undistorted when it shows the exemplar at the scale it was made with.
//! δ is infinite where σ₂ vanishes (the map folds or collapses a
//! direction). The pass threshold is δ_max on the area-weighted p95.
//!
//! **Anisotropy** σ₁/σ₂ is reported beside it for information. It is
//! scale-free, so it misses a uniformly magnified or shrunk exemplar, and
//! under an area-preserving shear (σ₁ σ₂ = s₀²) it is δ², not δ: judging
//! it against δ_max would fail textures the method rightly keeps.
//!
//! Texels without a usable neighbour pair (single-texel slivers), and texels
//! whose surface samples are degenerate (dp/dx ∥ dp/dy, which is an atlas
//! fault and not the method's), are skipped and not counted.

use glam::{DVec2, DVec3, Vec2, Vec3};
use rayon::prelude::*;

use super::{MetricsError, SOURCE_OUTSIDE, SOURCE_UNCOVERED, check_len, wrap_delta};

/// Per-texel inputs of the distortion metric (an atlas, or a render's
/// G-buffer: the same arrays per pixel).
#[derive(Clone, Copy, Debug)]
pub struct SurfaceSamples<'a> {
    pub width: u32,
    pub height: u32,
    /// Provenance per texel (see the module doc of [`super`]).
    pub source: &'a [u32],
    /// Exemplar uv of the source, normalised, NaN where none.
    pub uv: &'a [Vec2],
    /// The surface point of each texel, NaN outside charts.
    pub points: &'a [Vec3],
    /// Chart id per texel. Texels of different charts are never
    /// differenced; `None` is safe when charts are separated by at least
    /// one texel of [`SOURCE_OUTSIDE`] (a gutter), as in packed atlases.
    pub chart: Option<&'a [u32]>,
}

impl SurfaceSamples<'_> {
    fn validate(&self) -> Result<(), MetricsError> {
        check_len("source", self.source, self.width, self.height)?;
        check_len("uv", self.uv, self.width, self.height)?;
        check_len("points", self.points, self.width, self.height)?;
        if let Some(c) = self.chart {
            check_len("chart ids", c, self.width, self.height)?;
        }
        Ok(())
    }

    fn usable(&self, i: usize) -> bool {
        let s = self.source[i];
        s != SOURCE_OUTSIDE
            && s != SOURCE_UNCOVERED
            && self.uv[i].is_finite()
            && self.points[i].is_finite()
    }

    fn same_group(&self, i: usize, j: usize) -> bool {
        self.source[i] == self.source[j] && self.chart.is_none_or(|c| c[i] == c[j])
    }
}

/// The distortion of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Distortion {
    /// Texels with a Jacobian.
    pub texels: usize,
    /// Their total surface area (world units²).
    pub area: f64,
    /// Texels whose map collapses a direction (σ₂ ≈ 0): infinite δ and
    /// anisotropy.
    pub folded: usize,
    /// The rest scale s₀ it was measured against (exemplar texels per
    /// world unit).
    pub rest_scale: f64,
    /// The metric: area-weighted quantile of δ = max(σ₁/s₀, s₀/σ₂) (NaN
    /// without texels).
    pub delta: f64,
    /// Area-weighted median of δ.
    pub median_delta: f64,
    /// For information: area-weighted quantile of σ₁/σ₂.
    pub anisotropy: f64,
    /// Area-weighted median of σ₁/σ₂.
    pub median_anisotropy: f64,
    /// Median of sqrt(σ₁σ₂): exemplar texels per world unit on the surface.
    pub exemplar_texels_per_unit: f64,
    /// Median of sqrt(|det U|): exemplar texels per atlas texel (the
    /// factor by which [`super::rescale`] brings the exemplar to the
    /// output's texel scale for [`super::exemplar_fidelity`]).
    pub exemplar_texels_per_texel: f64,
}

#[derive(Clone, Copy)]
struct Local {
    s1: f64,
    s2: f64,
    anisotropy: f64,
    area: f64,
    scale: f64,
    texel_scale: f64,
}

/// Per texel σ₁/σ₂ (NaN where not measured), for heat-map images.
pub fn anisotropy_map(
    samples: &SurfaceSamples,
    exemplar_size: (u32, u32),
) -> Result<Vec<f32>, MetricsError> {
    Ok(locals(samples, exemplar_size)?
        .into_iter()
        .map(|l| l.map_or(f32::NAN, |l| l.anisotropy as f32))
        .collect())
}

/// Sorkine's δ of singular values `s1 ≥ s2` against the rest scale `s0`:
/// infinite where the map collapses a direction.
fn delta_of(s1: f64, s2: f64, s0: f64) -> f64 {
    if s2 <= 1e-6 * s1 || s1 == 0.0 {
        f64::INFINITY
    } else {
        (s1 / s0).max(s0 / s2)
    }
}

/// The distortion metric of one frame; `rest_scale` is s₀ (exemplar texels
/// per world unit at the patches' creation: exemplar width / S), `quantile`
/// is `thresholds.distortion.quantile` (0.95).
pub fn distortion(
    samples: &SurfaceSamples,
    exemplar_size: (u32, u32),
    rest_scale: f64,
    quantile: f32,
) -> Result<Distortion, MetricsError> {
    if !(quantile > 0.0 && quantile <= 1.0) {
        return Err(MetricsError::Invalid {
            name: "distortion quantile",
            value: quantile as f64,
            allowed: "(0, 1]",
        });
    }
    if !(rest_scale.is_finite() && rest_scale > 0.0) {
        return Err(MetricsError::Invalid {
            name: "distortion rest scale s0",
            value: rest_scale,
            allowed: "(0, inf) exemplar texels per world unit",
        });
    }
    let l: Vec<Local> = locals(samples, exemplar_size)?
        .into_iter()
        .flatten()
        .collect();
    let texels = l.len();
    let folded = l.iter().filter(|l| l.anisotropy.is_infinite()).count();
    let area: f64 = l.iter().map(|l| l.area).sum();
    let median_of = |v: &mut Vec<f64>| -> f64 {
        v.sort_unstable_by(f64::total_cmp);
        v.get(v.len().saturating_sub(1) / 2)
            .copied()
            .unwrap_or(f64::NAN)
    };
    let exemplar_texels_per_unit = median_of(&mut l.iter().map(|l| l.scale).collect());
    let exemplar_texels_per_texel = median_of(&mut l.iter().map(|l| l.texel_scale).collect());
    // Area-weighted quantiles of a per-texel value.
    let weighted = |value: &dyn Fn(&Local) -> f64, qs: [f64; 2]| -> [f64; 2] {
        let mut v: Vec<(f64, f64)> = l.iter().map(|x| (value(x), x.area)).collect();
        v.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        qs.map(|q| {
            let target = q * area;
            let mut acc = 0.0;
            for &(x, a) in &v {
                acc += a;
                if acc >= target {
                    return x;
                }
            }
            v.last().map_or(f64::NAN, |x| x.0)
        })
    };
    let q = quantile as f64;
    let [delta, median_delta] = weighted(&|x| delta_of(x.s1, x.s2, rest_scale), [q, 0.5]);
    let [anisotropy, median_anisotropy] = weighted(&|x| x.anisotropy, [q, 0.5]);
    Ok(Distortion {
        texels,
        area,
        folded,
        rest_scale,
        delta,
        median_delta,
        anisotropy,
        median_anisotropy,
        exemplar_texels_per_unit,
        exemplar_texels_per_texel,
    })
}

fn locals(
    s: &SurfaceSamples,
    exemplar_size: (u32, u32),
) -> Result<Vec<Option<Local>>, MetricsError> {
    s.validate()?;
    if exemplar_size.0 == 0 || exemplar_size.1 == 0 {
        return Err(MetricsError::TooSmall {
            what: "exemplar",
            width: exemplar_size.0,
            height: exemplar_size.1,
            min: 1,
        });
    }
    let ex = DVec2::new(exemplar_size.0 as f64, exemplar_size.1 as f64);
    let (w, h) = (s.width as usize, s.height as usize);
    let rows: Vec<Vec<Option<Local>>> = (0..h)
        .into_par_iter()
        .map(|y| (0..w).map(|x| local(s, x, y, ex)).collect())
        .collect();
    Ok(rows.into_iter().flatten().collect())
}

/// Forward difference towards `j`, or backward from `k`, within the group.
fn difference(
    s: &SurfaceSamples,
    i: usize,
    forward: Option<usize>,
    backward: Option<usize>,
    ex: DVec2,
) -> Option<(DVec3, DVec2)> {
    let d = |a: usize, b: usize| {
        let dp = (s.points[b] - s.points[a]).as_dvec3();
        let du = wrap_delta(s.uv[b] - s.uv[a]).as_dvec2() * ex;
        (dp, du)
    };
    let ok = |j: usize| s.usable(j) && s.same_group(i, j);
    match (forward.filter(|&j| ok(j)), backward.filter(|&j| ok(j))) {
        (Some(j), _) => Some(d(i, j)),
        (None, Some(k)) => Some(d(k, i)),
        (None, None) => None,
    }
}

fn local(s: &SurfaceSamples, x: usize, y: usize, ex: DVec2) -> Option<Local> {
    let (w, h) = (s.width as usize, s.height as usize);
    let i = y * w + x;
    if !s.usable(i) {
        return None;
    }
    let (px, ux) = difference(
        s,
        i,
        (x + 1 < w).then_some(i + 1),
        x.checked_sub(1).map(|_| i - 1),
        ex,
    )?;
    let (py, uy) = difference(
        s,
        i,
        (y + 1 < h).then_some(i + w),
        y.checked_sub(1).map(|_| i - w),
        ex,
    )?;
    // Tangent frame and T = E^T P (upper triangular).
    let a = px.length();
    let n = px.cross(py);
    let area = n.length();
    if a == 0.0 || area <= 1e-9 * a * py.length() {
        return None;
    }
    let e1 = px / a;
    let e2 = (n / area).cross(e1);
    let b = py.dot(e1);
    let c = py.dot(e2);
    // J = U T^-1, T^-1 = [[1/a, -b/(a c)], [0, 1/c]]; columns of J:
    let j0 = ux / a;
    let j1 = (uy - ux * (b / a)) / c;
    let (m00, m10, m01, m11) = (j0.x, j0.y, j1.x, j1.y);
    // Singular values of a 2x2 matrix from its conformal (q) and
    // anti-conformal (r) parts: sigma = q +- r.
    let q = DVec2::new((m00 + m11) / 2.0, (m10 - m01) / 2.0).length();
    let r = DVec2::new((m00 - m11) / 2.0, (m10 + m01) / 2.0).length();
    let (s1, s2) = (q + r, (q - r).abs());
    let anisotropy = if s2 <= 1e-6 * s1 || s1 == 0.0 {
        f64::INFINITY
    } else {
        s1 / s2
    };
    Some(Local {
        s1,
        s2,
        anisotropy,
        area,
        scale: (s1 * s2).sqrt(),
        texel_scale: (ux.perp_dot(uy)).abs().sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// A `w`×`h` atlas on the plane through `origin` spanned by `ax`, `ay`
    /// per texel, one source, uv = `map` of the texel centre.
    pub(crate) fn planar(
        w: u32,
        h: u32,
        origin: Vec3,
        ax: Vec3,
        ay: Vec3,
        map: impl Fn(Vec2) -> Vec2,
    ) -> (Vec<u32>, Vec<Vec2>, Vec<Vec3>) {
        let mut source = Vec::new();
        let mut uv = Vec::new();
        let mut points = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let c = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                source.push(1);
                points.push(origin + ax * c.x + ay * c.y);
                uv.push(map(c));
            }
        }
        (source, uv, points)
    }

    fn measure(
        w: u32,
        h: u32,
        data: &(Vec<u32>, Vec<Vec2>, Vec<Vec3>),
        ex: u32,
        s0: f64,
    ) -> Distortion {
        let s = SurfaceSamples {
            width: w,
            height: h,
            source: &data.0,
            uv: &data.1,
            points: &data.2,
            chart: None,
        };
        distortion(&s, (ex, ex), s0, 0.95).expect("valid input")
    }

    #[test]
    fn affine_maps_on_skewed_planes_give_their_anisotropy() {
        // The atlas axes are skewed and scaled on the surface; uv is a
        // known linear map of *surface tangent* coordinates, so the metric
        // must undo the atlas's own skew.
        let mut rng = Pcg64::seed_from_u64(7);
        for case in 0..20 {
            let ax = Vec3::new(0.01, 0.002, 0.0) * rng.random_range(0.5..2.0f32);
            let ay = Vec3::new(0.003, 0.012, 0.004) * rng.random_range(0.5..2.0f32);
            // Orthonormal tangent coordinates of the plane.
            let e1 = ax.normalize();
            let e2 = ax.cross(ay).normalize().cross(e1);
            let stretch = rng.random_range(1.0..6.0f32);
            let angle = rng.random_range(0.0..std::f32::consts::TAU);
            let scale = rng.random_range(0.5..3.0f32);
            let rot = glam::Mat2::from_angle(angle);
            let m = rot * glam::Mat2::from_diagonal(Vec2::new(stretch, 1.0)) * scale;
            let data = planar(16, 12, Vec3::ZERO, ax, ay, |c| {
                let p = ax * c.x + ay * c.y;
                // uv in exemplar texels / 256, plus an offset.
                Vec2::splat(0.3) + m * Vec2::new(p.dot(e1), p.dot(e2)) * 40.0 / 256.0
            });
            // s0 = 40 exemplar texels per unit: the map is s0 * m.
            let d = measure(16, 12, &data, 256, 40.0);
            assert_eq!(d.texels, 16 * 12, "case {case}");
            assert_eq!(d.folded, 0);
            let rel = (d.anisotropy - stretch as f64).abs() / stretch as f64;
            assert!(rel < 1e-3, "case {case}: {} vs {stretch}", d.anisotropy);
            // sigma / s0 = stretch * scale and scale: delta is the larger
            // of stretch * scale and 1 / scale.
            let want = (stretch * scale).max(1.0 / scale) as f64;
            let rel = (d.delta - want).abs() / want;
            assert!(rel < 1e-3, "case {case}: delta {} vs {want}", d.delta);
            let expected_scale = (stretch * scale * scale).sqrt() as f64 * 40.0;
            let rel = (d.exemplar_texels_per_unit - expected_scale).abs() / expected_scale;
            assert!(
                rel < 1e-3,
                "case {case}: scale {}",
                d.exemplar_texels_per_unit
            );
        }
    }

    #[test]
    fn quantile_is_weighted_by_surface_area() {
        // Left half: isometric, small texels. Right half: 5x stretch, texels
        // 4x larger in area. Area share of the right half: 4/5 > 5%.
        let (w, h) = (20u32, 10u32);
        let mut source = Vec::new();
        let mut uv = Vec::new();
        let mut points = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let right = x >= w / 2;
                source.push(if right { 2 } else { 1 });
                let k = if right { 2.0 } else { 1.0 };
                let p = Vec3::new(x as f32 * k, y as f32 * k, 0.0);
                points.push(p + Vec3::new(if right { 100.0 } else { 0.0 }, 0.0, 0.0));
                uv.push(if right {
                    Vec2::new(p.x * 5.0, p.y) / 1024.0
                } else {
                    Vec2::new(p.x, p.y) / 1024.0
                });
            }
        }
        let s = SurfaceSamples {
            width: w,
            height: h,
            source: &source,
            uv: &uv,
            points: &points,
            chart: None,
        };
        let d = distortion(&s, (1024, 1024), 1.0, 0.95).expect("valid");
        assert!((d.anisotropy - 5.0).abs() < 1e-3, "{}", d.anisotropy);
        assert!((d.delta - 5.0).abs() < 1e-3, "{}", d.delta);
        assert!((d.median_anisotropy - 5.0).abs() < 1e-3);
        // At the 10% quantile the isometric fifth of the area decides.
        let d = distortion(&s, (1024, 1024), 1.0, 0.1).expect("valid");
        assert!((d.anisotropy - 1.0).abs() < 1e-3, "{}", d.anisotropy);
        assert!((d.delta - 1.0).abs() < 1e-3, "{}", d.delta);
        assert!((d.area - (100.0 + 400.0)).abs() < 1e-6 * 500.0);
    }

    #[test]
    fn sources_and_charts_are_never_differenced() {
        // Alternate sources per column with wildly different uv: if
        // neighbours of different sources were differenced, anisotropy
        // would explode. Each column then has no horizontal partner.
        let (w, h) = (8u32, 8u32);
        let mut data = planar(w, h, Vec3::ZERO, Vec3::X, Vec3::Y, |c| c / 64.0);
        for (i, s) in data.0.iter_mut().enumerate() {
            *s = 1 + (i as u32 % 2);
        }
        let s = SurfaceSamples {
            width: w,
            height: h,
            source: &data.0,
            uv: &data.1,
            points: &data.2,
            chart: None,
        };
        assert_eq!(
            distortion(&s, (64, 64), 1.0, 0.95).expect("valid").texels,
            0
        );
        // Same with one source but two charts.
        let one = vec![1u32; 64];
        let charts: Vec<u32> = (0..64).map(|i| (i % 8 >= 4) as u32).collect();
        let mut uv = data.1.clone();
        for (i, t) in uv.iter_mut().enumerate() {
            if i % 8 >= 4 {
                *t += Vec2::new(0.3, 0.1);
            }
        }
        let s = SurfaceSamples {
            source: &one,
            uv: &uv,
            chart: Some(&charts),
            ..s
        };
        let d = distortion(&s, (64, 64), 1.0, 1.0).expect("valid");
        assert_eq!(d.texels, 64);
        assert!((d.anisotropy - 1.0).abs() < 1e-4, "{}", d.anisotropy);
        assert!((d.delta - 1.0).abs() < 1e-4, "{}", d.delta);
    }

    #[test]
    fn wrapped_uv_and_folds() {
        // uv wrapped into [0, 1) across the tile edge is not a jump.
        let data = planar(16, 4, Vec3::ZERO, Vec3::X, Vec3::Y, |c| {
            Vec2::new((c.x / 8.0).fract(), c.y / 8.0)
        });
        let d = measure(16, 4, &data, 32, 4.0);
        assert!((d.anisotropy - 1.0).abs() < 1e-4, "{}", d.anisotropy);
        assert!((d.delta - 1.0).abs() < 1e-4, "{}", d.delta);
        // The same map judged against half its scale is magnified 2x.
        let d = measure(16, 4, &data, 32, 2.0);
        assert!((d.delta - 2.0).abs() < 1e-4, "{}", d.delta);
        assert_eq!(d.exemplar_texels_per_texel, 4.0);
        // A map that ignores y collapses a direction: infinite anisotropy.
        let data = planar(8, 8, Vec3::ZERO, Vec3::X, Vec3::Y, |c| {
            Vec2::new(c.x / 8.0, 0.5)
        });
        let d = measure(8, 8, &data, 32, 4.0);
        assert_eq!(d.folded, 64);
        assert_eq!(d.anisotropy, f64::INFINITY);
        assert_eq!(d.delta, f64::INFINITY);
    }

    #[test]
    fn mismatched_lengths_are_named() {
        let data = planar(4, 4, Vec3::ZERO, Vec3::X, Vec3::Y, |c| c);
        let s = SurfaceSamples {
            width: 4,
            height: 4,
            source: &data.0,
            uv: &data.1[..15],
            points: &data.2,
            chart: None,
        };
        assert_eq!(
            distortion(&s, (8, 8), 1.0, 0.95),
            Err(MetricsError::Length {
                what: "uv",
                expected: 16,
                got: 15
            })
        );
        let s = SurfaceSamples { uv: &data.1, ..s };
        assert!(matches!(
            distortion(&s, (8, 8), 0.0, 0.95),
            Err(MetricsError::Invalid { .. })
        ));
    }
}
