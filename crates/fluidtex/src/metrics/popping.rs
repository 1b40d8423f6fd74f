//! Popping: the share of pixels that change more than the true motion
//! explains (the warping error of Lai et al. 2018, "Learning blind video
//! temporal consistency", thresholded).
//!
//! Frame t is warped to frame t+1 with the true motion, backwards: pixel q
//! of frame t+1 takes frame t's luminance at q − m(q), bilinearly, where
//! m(q) is the motion (px/frame) over the frame of the surface point seen
//! at q in frame t+1. q pops when |I_{t+1}(q) − warp(I_t)(q)| > k σ_ex
//! (k = `sigma_factor`, 0.5). Pixels are counted where `usable_next` holds
//! at q and the four bilinear taps at q − m(q) are inside frame t's
//! `usable_prev`: the harness removes silhouettes and the pixels whose
//! point was hidden at frame t (disoccluded) through these masks.
//!
//! Bilinear warping blurs a little, so a texture with detail at the pixel
//! scale shows some warping error even when it moves perfectly; the
//! smoothly translated control measures that floor.

use glam::Vec2;

use super::{MetricsError, check_frame_pair, luminance};
use crate::texture::Texture;

/// Popping in one frame pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Popping {
    /// Pixels compared.
    pub compared: usize,
    /// Pixels whose change exceeds the threshold.
    pub popped: usize,
}

impl Popping {
    /// The metric: popped / compared (NaN when nothing was compared).
    pub fn share(&self) -> f64 {
        if self.compared == 0 {
            f64::NAN
        } else {
            self.popped as f64 / self.compared as f64
        }
    }
}

/// Counts popped pixels of `next` against `prev` warped by `motion_back`
/// (per pixel of `next`, px/frame).
pub fn popping(
    prev: &Texture,
    next: &Texture,
    motion_back: &[Vec2],
    usable_prev: &[bool],
    usable_next: &[bool],
    sigma_ex: f32,
    sigma_factor: f32,
) -> Result<Popping, MetricsError> {
    let (w, h) = check_frame_pair(prev, next, "motion", motion_back, usable_prev, usable_next)?;
    let limit = sigma_factor * sigma_ex;
    if !(limit.is_finite() && limit > 0.0) {
        return Err(MetricsError::Invalid {
            name: "sigma_factor * sigma_ex",
            value: limit as f64,
            allowed: "(0, inf)",
        });
    }
    let a = luminance(prev);
    let b = luminance(next);
    let (wi, hi) = (w as i64, h as i64);
    let mut out = Popping {
        compared: 0,
        popped: 0,
    };
    for (i, (&ok, &m)) in usable_next.iter().zip(motion_back).enumerate() {
        if !ok || !m.is_finite() {
            continue;
        }
        let i = i as i64;
        // Pixel-centre coordinates of the source point in frame t, minus
        // the half-texel offset of bilinear interpolation.
        let sx = (i % wi) as f32 - m.x;
        let sy = (i / wi) as f32 - m.y;
        let (x0, y0) = (sx.floor(), sy.floor());
        let (fx, fy) = (sx - x0, sy - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        if x0 < 0 || y0 < 0 || x0 + 1 >= wi || y0 + 1 >= hi {
            continue;
        }
        let taps = [
            (y0 * wi + x0) as usize,
            (y0 * wi + x0 + 1) as usize,
            ((y0 + 1) * wi + x0) as usize,
            ((y0 + 1) * wi + x0 + 1) as usize,
        ];
        if !taps.iter().all(|&t| usable_prev[t]) {
            continue;
        }
        let top = a[taps[0]] * (1.0 - fx) + a[taps[1]] * fx;
        let bottom = a[taps[2]] * (1.0 - fx) + a[taps[3]] * fx;
        let warped = top * (1.0 - fy) + bottom * fy;
        out.compared += 1;
        out.popped += usize::from((b[i as usize] - warped).abs() > limit);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integer_shift_is_exact_and_changes_are_counted() {
        // A random image shifted by (2, -1) px: warping undoes it exactly.
        let (w, h) = (16u32, 12u32);
        let value = |x: i64, y: i64| ((x * 7 + y * 13) % 11) as f32 / 10.0;
        let mk = |dx: i64, dy: i64| {
            let data = (0..h as i64)
                .flat_map(|y| (0..w as i64).map(move |x| value(x - dx, y - dy)))
                .collect();
            Texture::from_data(w, h, 1, data).expect("sizes")
        };
        let a = mk(0, 0);
        let mut b = mk(2, -1);
        let motion = vec![Vec2::new(2.0, -1.0); (w * h) as usize];
        let all = vec![true; (w * h) as usize];
        let p = popping(&a, &b, &motion, &all, &all, 0.2, 0.5).expect("valid");
        // Pixels whose four taps lie inside frame t: x in 2..16, y in 0..10.
        assert_eq!(
            p,
            Popping {
                compared: 14 * 10,
                popped: 0
            }
        );
        // Three changed pixels, one below the threshold 0.5 * 0.2.
        b.data[5 * 16 + 5] += 0.5;
        b.data[6 * 16 + 7] -= 0.3;
        b.data[7 * 16 + 9] += 0.05;
        let p = popping(&a, &b, &motion, &all, &all, 0.2, 0.5).expect("valid");
        assert_eq!(p.popped, 2);
        // A masked-out pixel of frame t removes the four pixels of frame
        // t+1 whose bilinear taps read it: x in {4, 5}, y in {3, 4}.
        let mut prev_mask = all.clone();
        prev_mask[5 * 16 + 3] = false;
        let p = popping(&a, &b, &motion, &prev_mask, &all, 0.2, 0.5).expect("valid");
        assert_eq!((p.compared, p.popped), (14 * 10 - 4, 2));
    }

    #[test]
    fn bad_inputs_are_errors() {
        let t = Texture::filled(4, 4, 1, 0.0);
        let m = vec![Vec2::ZERO; 16];
        let all = vec![true; 16];
        assert!(popping(&t, &t, &m, &all, &all, 0.0, 0.5).is_err());
        assert!(popping(&t, &t, &m[..3], &all, &all, 0.1, 0.5).is_err());
        let mut short = t.clone();
        short.data.pop();
        assert_eq!(
            popping(&short, &t, &m, &all, &all, 0.1, 0.5),
            Err(MetricsError::Length {
                what: "previous frame",
                expected: 16,
                got: 15
            })
        );
        let other = Texture::filled(4, 5, 1, 0.0);
        assert!(matches!(
            popping(&t, &other, &m, &all, &all, 0.1, 0.5),
            Err(MetricsError::Size { .. })
        ));
    }
}
