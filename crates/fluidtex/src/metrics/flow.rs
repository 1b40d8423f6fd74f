//! Flow fidelity: does the texture move with the fluid?
//!
//! For two consecutive frames, the texture's motion at a pixel is compared
//! with the true motion of the surface point seen there, projected to the
//! image (px per frame). [`compare_motion`] gives the median end-point
//! error (EPE, px) and the share of pixels whose motion points the right
//! way (cos(angle) > `min_cos`), over the pixels that were measurable and
//! move faster than `min_speed_px`. A pixel whose texture could not be
//! found in the next frame is a failure: infinite EPE, not aligned.
//!
//! Texture motion comes from one of two estimators:
//! - [`provenance_motion`] (methods with per-pixel provenance): the pixel
//!   shows exemplar point uv₀ of source s at frame t. In frame t+1, within
//!   a square window of half-size R around the position the true motion
//!   predicts, the pixel of source s whose uv is nearest uv₀ is found; uv is
//!   fitted as a quadratic (affine at patch borders) function of pixel
//!   position over its 3×3 neighbours of the same source, and the fit is
//!   solved for the position where uv = uv₀, re-centred on the pixel that
//!   position falls in until it stays. That position minus the pixel's is
//!   the texture's motion, to a fraction of a pixel. Nothing about the
//!   true motion enters the measurement but the window's centre.
//! - [`super::image_motion`] (methods without provenance, e.g. a texture
//!   synthesised per frame): block matching on luminance, refined by
//!   Lucas–Kanade. It measures apparent motion, so it has an error floor of
//!   its own (see the controls) and cannot follow flat texture.
//!
//! The true motion the harness supplies is either docs/evaluation.md's projected
//! velocity times the frame time (first order: on a curved path it differs
//! from the real displacement by O(dt²), which is most of the ≈ 0.07 px an
//! ideal advection shows under the vortex) or the exact displacement of the
//! surface point over the frame; [`FlowStats`] does not care which, the
//! report must say.

use glam::{DVec2, Vec2};
use rayon::prelude::*;

use super::{MetricsError, SOURCE_OUTSIDE, SOURCE_UNCOVERED, check_len, lower_median, wrap_delta};

/// Per-pixel provenance of one rendered frame (or atlas).
#[derive(Clone, Copy, Debug)]
pub struct ProvenanceFrame<'a> {
    pub width: u32,
    pub height: u32,
    /// Source per pixel ([`SOURCE_OUTSIDE`] for background).
    pub source: &'a [u32],
    /// Exemplar uv per pixel, NaN where none.
    pub uv: &'a [Vec2],
}

impl ProvenanceFrame<'_> {
    fn validate(&self) -> Result<(), MetricsError> {
        check_len("source", self.source, self.width, self.height)?;
        check_len("uv", self.uv, self.width, self.height)
    }

    fn sourced(&self, i: usize) -> bool {
        let s = self.source[i];
        s != SOURCE_OUTSIDE && s != SOURCE_UNCOVERED && self.uv[i].is_finite()
    }
}

/// The texture's motion at one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Motion {
    /// Not measured (masked, no provenance, window off the image).
    Unmeasured,
    /// Measured, but the texture was not found in the next frame.
    Lost,
    /// Moved by this many pixels.
    Moved(Vec2),
}

/// Flow fidelity of one frame pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlowStats {
    /// Measured pixels faster than the speed floor.
    pub eligible: usize,
    /// Of those, the ones whose texture was found in the next frame.
    pub found: usize,
    /// Lower median of the end-point error (px; infinite for lost pixels;
    /// NaN without eligible pixels).
    pub median_epe_px: f64,
    /// Share of eligible pixels with cos(measured, true) > `min_cos`.
    pub aligned_share: f64,
}

/// The texture's motion per pixel from provenance.
///
/// `predicted` (px/frame) centres the search window, normally the true
/// motion. Pixels are measured where `measure` is `true` and the pixel has
/// a source and uv at frame t; candidates in frame t+1 must be `true` in
/// `usable_next` (the interior mask of that frame).
pub fn provenance_motion(
    prev: &ProvenanceFrame,
    next: &ProvenanceFrame,
    predicted: &[Vec2],
    measure: &[bool],
    usable_next: &[bool],
    search_radius_px: u32,
) -> Result<Vec<Motion>, MetricsError> {
    prev.validate()?;
    next.validate()?;
    if (next.width, next.height) != (prev.width, prev.height) {
        return Err(MetricsError::Size {
            what: "next frame",
            width: prev.width,
            height: prev.height,
            got_width: next.width,
            got_height: next.height,
        });
    }
    let (w, h) = (prev.width, prev.height);
    check_len("predicted motion", predicted, w, h)?;
    check_len("measure mask", measure, w, h)?;
    check_len("next frame's mask", usable_next, w, h)?;
    let (wu, hu) = (w as usize, h as usize);
    let rows: Vec<Vec<Motion>> = (0..hu)
        .into_par_iter()
        .map(|y| {
            (0..wu)
                .map(|x| {
                    let i = y * wu + x;
                    if !measure[i] || !prev.sourced(i) || !predicted[i].is_finite() {
                        return Motion::Unmeasured;
                    }
                    track(
                        prev,
                        next,
                        usable_next,
                        i,
                        predicted[i],
                        search_radius_px as i64,
                    )
                })
                .collect()
        })
        .collect();
    Ok(rows.into_iter().flatten().collect())
}

fn track(
    prev: &ProvenanceFrame,
    next: &ProvenanceFrame,
    usable_next: &[bool],
    i: usize,
    predicted: Vec2,
    r: i64,
) -> Motion {
    let (w, h) = (prev.width as i64, prev.height as i64);
    let (s, uv0) = (prev.source[i], prev.uv[i]);
    let here = Vec2::new((i as i64 % w) as f32 + 0.5, (i as i64 / w) as f32 + 0.5);
    let target = here + predicted;
    let (cx, cy) = (target.x.floor() as i64, target.y.floor() as i64);
    let same = |j: usize| next.source[j] == s && next.uv[j].is_finite();
    // The candidate closest to uv0 *in pixels*: the uv difference mapped
    // through the inverse of the local uv Jacobian (central differences).
    // Plain uv distance would be wrong where the texture is stretched: uv
    // changes slowly along the stretch, so a pixel several pixels away
    // along it can have the nearest uv.
    let mut best: Option<(f64, i64, i64)> = None;
    for y in (cy - r).max(0)..=(cy + r).min(h - 1) {
        for x in (cx - r).max(0)..=(cx + r).min(w - 1) {
            let j = (y * w + x) as usize;
            if !usable_next[j] || !same(j) {
                continue;
            }
            let Some(off) = affine_offset(next, s, uv0, x, y) else {
                continue;
            };
            let d = off.length_squared();
            if best.is_none_or(|(b, _, _)| d < b) {
                best = Some((d, x, y));
            }
        }
    }
    let Some((_, mut mx, mut my)) = best else {
        return Motion::Lost;
    };
    // Refine around the pixel the solution falls in until it stays within
    // a quarter pixel of the fitted pixel's square (the margin stops two
    // neighbours' fits, which differ by hundredths of a pixel, from
    // handing a point on their common edge back and forth).
    for _ in 0..4 {
        let off = match solve_near(next, s, uv0, mx, my) {
            Ok(off) => off,
            Err(lost) => return lost,
        };
        if off.x.abs() <= 0.75 && off.y.abs() <= 0.75 {
            let found = Vec2::new(mx as f32 + 0.5, my as f32 + 0.5) + off.as_vec2();
            return Motion::Moved(found - here);
        }
        let (nx, ny) = (mx + off.x.round() as i64, my + off.y.round() as i64);
        if nx < 0 || ny < 0 || nx >= w || ny >= h {
            return Motion::Lost;
        }
        let j = (ny * w + nx) as usize;
        if !usable_next[j] || !same(j) {
            return Motion::Lost;
        }
        (mx, my) = (nx, ny);
    }
    Motion::Lost
}

/// First-order offset (px) from pixel (x, y) to where uv = uv0, from the
/// central (one-sided at a source border) differences of uv there; `None`
/// where a direction has no neighbour of the same source or the Jacobian is
/// singular.
fn affine_offset(next: &ProvenanceFrame, s: u32, uv0: Vec2, x: i64, y: i64) -> Option<DVec2> {
    let (w, h) = (next.width as i64, next.height as i64);
    let at = |x: i64, y: i64| -> Option<Vec2> {
        if x < 0 || y < 0 || x >= w || y >= h {
            return None;
        }
        let j = (y * w + x) as usize;
        (next.source[j] == s && next.uv[j].is_finite()).then(|| next.uv[j])
    };
    let centre = at(x, y)?;
    let derivative = |a: Option<Vec2>, b: Option<Vec2>| -> Option<DVec2> {
        match (a, b) {
            (Some(a), Some(b)) => Some(wrap_delta(b - a).as_dvec2() / 2.0),
            (None, Some(b)) => Some(wrap_delta(b - centre).as_dvec2()),
            (Some(a), None) => Some(wrap_delta(centre - a).as_dvec2()),
            (None, None) => None,
        }
    };
    let ax = derivative(at(x - 1, y), at(x + 1, y))?;
    let ay = derivative(at(x, y - 1), at(x, y + 1))?;
    let det = ax.perp_dot(ay);
    let regular = det.abs() > 1e-9 * ax.length_squared().max(ay.length_squared());
    if !regular {
        return None;
    }
    let g = wrap_delta(uv0 - centre).as_dvec2();
    Some(DVec2::new(g.perp_dot(ay) / det, ax.perp_dot(g) / det))
}

/// Models uv around pixel m as a function of the offset d from m's centre
/// and solves it for uv = uv₀: a quadratic (least squares on [1, dx, dy,
/// dx², dx dy, dy²] over the full 3×3 neighbourhood, solved by Newton's
/// method) where all nine pixels share the source, else an affine fit over
/// those that do. The quadratic matters where ideal advection has
/// stretched the texture strongly: the uv field then curves noticeably
/// within a pixel, and since uv changes slowly along the stretched
/// direction, an affine model's curvature error becomes a position error
/// of several tenths of a pixel along it. Returns the offset, or `Lost`
/// where the neighbours do not determine the model, the map is singular or
/// the solution lies more than 1.5 px away (the texture there does not
/// continue frame t's).
fn solve_near(
    next: &ProvenanceFrame,
    s: u32,
    uv0: Vec2,
    mx: i64,
    my: i64,
) -> Result<DVec2, Motion> {
    let (w, h) = (next.width as i64, next.height as i64);
    let uv_m = next.uv[(my * w + mx) as usize];
    let mut samples: Vec<(DVec2, DVec2)> = Vec::with_capacity(9);
    for dy in -1..=1 {
        for dx in -1..=1 {
            let (x, y) = (mx + dx, my + dy);
            if x < 0 || y < 0 || x >= w || y >= h {
                continue;
            }
            let j = (y * w + x) as usize;
            if next.source[j] != s || !next.uv[j].is_finite() {
                continue;
            }
            let du = wrap_delta(next.uv[j] - uv_m).as_dvec2();
            samples.push((DVec2::new(dx as f64, dy as f64), du));
        }
    }
    let quadratic = samples.len() == 9;
    let terms = if quadratic { 6 } else { 3 };
    let basis = |d: DVec2| [1.0, d.x, d.y, d.x * d.x, d.x * d.y, d.y * d.y];
    let mut ata = [[0.0f64; 6]; 6];
    let mut atb = [[0.0f64; 2]; 6];
    for (d, du) in &samples {
        let b = basis(*d);
        for r in 0..terms {
            for c in 0..terms {
                ata[r][c] += b[r] * b[c];
            }
            atb[r][0] += b[r] * du.x;
            atb[r][1] += b[r] * du.y;
        }
    }
    let coef = solve(ata, atb, terms).ok_or(Motion::Lost)?;
    let c = |k: usize| DVec2::from(coef[k]);
    // The model's value and partial derivatives at offset d.
    let model = |d: DVec2| -> (DVec2, DVec2, DVec2) {
        let mut value = c(0) + d.x * c(1) + d.y * c(2);
        let (mut ddx, mut ddy) = (c(1), c(2));
        if quadratic {
            value += d.x * d.x * c(3) + d.x * d.y * c(4) + d.y * d.y * c(5);
            ddx += 2.0 * d.x * c(3) + d.y * c(4);
            ddy += d.x * c(4) + 2.0 * d.y * c(5);
        }
        (value, ddx, ddy)
    };
    let goal = wrap_delta(uv0 - uv_m).as_dvec2();
    let mut d = DVec2::ZERO;
    for _ in 0..8 {
        let (value, ax, ay) = model(d);
        let det = ax.perp_dot(ay);
        let scale = ax.length_squared().max(ay.length_squared());
        let regular = det.abs() > 1e-9 * scale;
        if !regular {
            return Err(Motion::Lost);
        }
        let r = goal - value;
        let step = DVec2::new(r.perp_dot(ay) / det, ax.perp_dot(r) / det);
        d += step;
        if d.x.abs() > 1.5 || d.y.abs() > 1.5 {
            return Err(Motion::Lost);
        }
        if step.length() < 1e-7 {
            break;
        }
    }
    Ok(d)
}

/// Solves the first `n` normal equations for two right-hand sides
/// (Gaussian elimination with partial pivoting; `None` when singular).
fn solve(mut a: [[f64; 6]; 6], mut b: [[f64; 2]; 6], n: usize) -> Option<[[f64; 2]; 6]> {
    for col in 0..n {
        let pivot = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() < 1e-9 {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let (pa, pb) = (a[col], b[col]);
        for row in col + 1..n {
            let f = a[row][col] / pa[col];
            for (x, p) in a[row][col..n].iter_mut().zip(&pa[col..n]) {
                *x -= f * p;
            }
            for (x, p) in b[row].iter_mut().zip(&pb) {
                *x -= f * p;
            }
        }
    }
    let mut x = [[0.0f64; 2]; 6];
    for row in (0..n).rev() {
        for k in 0..2 {
            let mut v = b[row][k];
            for c in row + 1..n {
                v -= a[row][c] * x[c][k];
            }
            x[row][k] = v / a[row][row];
        }
    }
    Some(x)
}

/// Compares measured motion with the true motion (px/frame).
///
/// Eligible: measured pixels (not [`Motion::Unmeasured`]) whose true speed
/// exceeds `min_speed_px`. Lost pixels count with infinite EPE and as not
/// aligned; a zero measured motion is not aligned.
pub fn compare_motion(
    motion: &[Motion],
    truth: &[Vec2],
    min_speed_px: f32,
    min_cos: f32,
) -> Result<FlowStats, MetricsError> {
    if motion.len() != truth.len() {
        return Err(MetricsError::Length {
            what: "true motion",
            expected: motion.len(),
            got: truth.len(),
        });
    }
    let mut epe = Vec::new();
    let mut aligned = 0usize;
    for (m, &v) in motion.iter().zip(truth) {
        if !(v.is_finite() && v.length() > min_speed_px) {
            continue;
        }
        match m {
            Motion::Unmeasured => {}
            Motion::Lost => epe.push(f32::INFINITY),
            Motion::Moved(d) => {
                epe.push((*d - v).length());
                let cos = d.dot(v) / (d.length() * v.length());
                aligned += usize::from(cos > min_cos);
            }
        }
    }
    let eligible = epe.len();
    let found = epe.iter().filter(|e| e.is_finite()).count();
    Ok(FlowStats {
        eligible,
        found,
        median_epe_px: lower_median(&mut epe) as f64,
        aligned_share: if eligible == 0 {
            f64::NAN
        } else {
            aligned as f64 / eligible as f64
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// Provenance of a plane whose uv field is `uv(p)` (p in pixels).
    fn frame(w: u32, h: u32, uv: impl Fn(Vec2) -> Vec2) -> (Vec<u32>, Vec<Vec2>) {
        let mut s = Vec::new();
        let mut u = Vec::new();
        for y in 0..h {
            for x in 0..w {
                s.push(1);
                u.push(uv(Vec2::new(x as f32 + 0.5, y as f32 + 0.5)));
            }
        }
        (s, u)
    }

    #[test]
    fn rigid_motions_are_recovered_to_a_thousandth_of_a_pixel() {
        let mut rng = Pcg64::seed_from_u64(11);
        let (w, h) = (40u32, 30u32);
        for case in 0..10 {
            let angle: f32 = rng.random_range(-0.05..0.05);
            let shift = Vec2::new(rng.random_range(-2.5..2.5), rng.random_range(-2.5..2.5));
            let centre = Vec2::new(20.0, 15.0);
            let rot = glam::Mat2::from_angle(angle);
            // uv at t: p / 64 (a tile of 64 px). At t+1 the texture is
            // rotated about `centre` and shifted: uv1(q) = uv0(M^-1 q).
            let uv0 = |p: Vec2| p / 64.0;
            let forward = |p: Vec2| rot * (p - centre) + centre + shift;
            let inverse = |q: Vec2| rot.inverse() * (q - centre - shift) + centre;
            let (s0, u0) = frame(w, h, uv0);
            let (s1, u1) = frame(w, h, |q| uv0(inverse(q)));
            let prev = ProvenanceFrame {
                width: w,
                height: h,
                source: &s0,
                uv: &u0,
            };
            let next = ProvenanceFrame {
                uv: &u1,
                source: &s1,
                ..prev
            };
            // Predicted motion off by up to 1.5 px: the window must still
            // find it.
            let truth: Vec<Vec2> = (0..w * h)
                .map(|i| {
                    let p = Vec2::new((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
                    forward(p) - p
                })
                .collect();
            let predicted: Vec<Vec2> = truth.iter().map(|t| *t + Vec2::new(1.5, -1.0)).collect();
            let measure: Vec<bool> = (0..w * h)
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    (5..w - 5).contains(&x) && (5..h - 5).contains(&y)
                })
                .collect();
            let all = vec![true; (w * h) as usize];
            let motion =
                provenance_motion(&prev, &next, &predicted, &measure, &all, 3).expect("valid");
            for (i, m) in motion.iter().enumerate() {
                match m {
                    Motion::Unmeasured => assert!(!measure[i]),
                    Motion::Lost => panic!("case {case}: pixel {i} lost"),
                    Motion::Moved(d) => {
                        assert!(
                            (*d - truth[i]).length() < 1e-3,
                            "case {case}: {d} vs {}",
                            truth[i]
                        )
                    }
                }
            }
            let stats = compare_motion(&motion, &truth, 0.3, 0.9).expect("lengths");
            assert!(stats.median_epe_px < 1e-3);
        }
    }

    #[test]
    fn other_sources_and_vanished_texture_are_lost() {
        let (w, h) = (12u32, 12u32);
        let (s0, u0) = frame(w, h, |p| p / 32.0);
        // Next frame: same uv field but a different source everywhere.
        let s1 = vec![2u32; (w * h) as usize];
        let prev = ProvenanceFrame {
            width: w,
            height: h,
            source: &s0,
            uv: &u0,
        };
        let next = ProvenanceFrame {
            source: &s1,
            ..prev
        };
        let zero = vec![Vec2::new(1.0, 0.0); (w * h) as usize];
        let all = vec![true; (w * h) as usize];
        let m = provenance_motion(&prev, &next, &zero, &all, &all, 2).expect("valid");
        assert!(m.iter().all(|m| *m == Motion::Lost));
        let stats = compare_motion(&m, &zero, 0.3, 0.9).expect("lengths");
        assert_eq!((stats.eligible, stats.found), (144, 0));
        assert_eq!(stats.median_epe_px, f64::INFINITY);
        assert_eq!(stats.aligned_share, 0.0);
        // Same source, but uv jumps far away (a new patch re-using the id).
        let (_, far) = frame(w, h, |p| p / 32.0 + Vec2::new(0.3, 0.2));
        let next = ProvenanceFrame { uv: &far, ..prev };
        let m = provenance_motion(&prev, &next, &zero, &all, &all, 2).expect("valid");
        assert!(m.iter().all(|m| *m == Motion::Lost));
    }

    #[test]
    fn compare_counts_speed_floor_and_direction() {
        let motion = [
            Motion::Moved(Vec2::new(1.0, 0.0)), // exact
            Motion::Moved(Vec2::new(0.0, 1.0)), // perpendicular
            Motion::Moved(Vec2::ZERO),          // stuck
            Motion::Lost,                       // lost
            Motion::Unmeasured,                 // not counted
            Motion::Moved(Vec2::new(0.2, 0.0)), // too slow to count
        ];
        let truth = [
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(0.3, 0.0),
        ];
        let s = compare_motion(&motion, &truth, 0.3, 0.9).expect("lengths");
        assert_eq!((s.eligible, s.found), (4, 3));
        // EPEs 0, sqrt 2, 1, inf: lower median 1.
        assert_eq!(s.median_epe_px, 1.0);
        assert_eq!(s.aligned_share, 0.25);
        assert!(compare_motion(&motion, &truth[..5], 0.3, 0.9).is_err());
    }
}
