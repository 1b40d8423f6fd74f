//! Colour follow ratio: does the colour move with the fluid, or stay where
//! it was?
//!
//! For points sampled on frame t and carried to frame t+1 by the flow (see
//! [`super::source_switch`] and [`crate::coherence`]), compare the grey
//! value at t with the grey value at t+1 (a) at the carried point and (b)
//! at the same point not moved (its closest point on the surface of t+1).
//! The ratio of the medians of |(a) − t| and |(b) − t|, over points that
//! move at least `min_move_texels` atlas texels, is ≈ 0.1–0.3 for a texture
//! that follows the flow (what remains is resampling and the texture's own
//! changes) and ≈ 1 for a texture glued in place: then the carried and the
//! unmoved point are equally unrelated to the colour at t.
//!
//! Points that move less than a few texels are left out because there (a)
//! and (b) look up almost the same texel and the ratio says nothing. The
//! median, not the mean, because a few switched patches should not hide
//! the bulk (the switch share reports those).

use super::{MetricsError, lower_median};

/// The colour follow ratio of one frame pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColourFollow {
    /// Points that moved far enough and have all three grey values.
    pub moving: usize,
    /// Median |grey(t+1, carried) − grey(t)| over those points.
    pub carried_median: f32,
    /// Median |grey(t+1, not moved) − grey(t)|.
    pub still_median: f32,
    /// Fewer moving points than this give no ratio (NaN).
    pub min_moving: usize,
}

impl ColourFollow {
    /// The metric: carried_median / still_median; NaN with fewer than
    /// `min_moving` moving points or when neither median is above zero (a
    /// flat texture: nothing to follow). A texture that stays exactly where
    /// it was (unmoved colour identical, carried colour not) is infinite.
    pub fn ratio(&self) -> f64 {
        if self.moving == 0 || self.moving < self.min_moving {
            return f64::NAN;
        }
        match (self.carried_median > 0.0, self.still_median > 0.0) {
            (_, true) => self.carried_median as f64 / self.still_median as f64,
            (true, false) => f64::INFINITY,
            (false, false) => f64::NAN,
        }
    }
}

/// Per sample: grey value at frame t (`before`), at frame t+1 at the
/// carried point (`carried`) and at the unmoved point (`still`), and how
/// far the point moved in atlas texels (`moved_texels`). NaN entries (no
/// lookup there) leave the sample out.
pub fn colour_follow(
    before: &[f32],
    carried: &[f32],
    still: &[f32],
    moved_texels: &[f32],
    min_move_texels: f32,
    min_moving: usize,
) -> Result<ColourFollow, MetricsError> {
    let n = before.len();
    for (what, len) in [
        ("colours at the carried points", carried.len()),
        ("colours at the unmoved points", still.len()),
        ("moved distances", moved_texels.len()),
    ] {
        if len != n {
            return Err(MetricsError::Length {
                what,
                expected: n,
                got: len,
            });
        }
    }
    if !(min_move_texels.is_finite() && min_move_texels >= 0.0) {
        return Err(MetricsError::Invalid {
            name: "min_move_texels",
            value: min_move_texels as f64,
            allowed: "[0, inf)",
        });
    }
    let mut a = Vec::new();
    let mut b = Vec::new();
    for i in 0..n {
        let (c0, c1, c2, m) = (before[i], carried[i], still[i], moved_texels[i]);
        // `m >= min` is false for NaN, so unlocated points drop out here.
        if m >= min_move_texels && c0.is_finite() && c1.is_finite() && c2.is_finite() {
            a.push((c1 - c0).abs());
            b.push((c2 - c0).abs());
        }
    }
    Ok(ColourFollow {
        moving: a.len(),
        carried_median: lower_median(&mut a),
        still_median: lower_median(&mut b),
        min_moving,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medians_over_moving_points_only() {
        let before = [0.5, 0.5, 0.5, 0.5, 0.5];
        let carried = [0.6, 0.5, 0.5, 0.9, f32::NAN];
        let still = [0.1, 0.9, 0.7, 0.5, 0.0];
        // The first point does not move far enough, the last has no
        // carried colour.
        let moved = [1.0, 4.0, 4.0, 5.0, 9.0];
        let f = colour_follow(&before, &carried, &still, &moved, 3.0, 1).expect("valid");
        assert_eq!(f.moving, 3);
        // |carried - before| = 0, 0, 0.4 -> 0; |still - before| = .4, .2, 0 -> .2
        assert_eq!(f.carried_median, 0.0);
        assert!((f.still_median - 0.2).abs() < 1e-6);
        assert_eq!(f.ratio(), 0.0);
        // Too few moving points: no ratio.
        let f = colour_follow(&before, &carried, &still, &moved, 3.0, 4).expect("valid");
        assert!(f.ratio().is_nan());
        assert!(colour_follow(&before, &carried[..2], &still, &moved, 3.0, 1).is_err());
        // Glued in place: the unmoved point keeps its colour exactly.
        let f = colour_follow(&[0.5, 0.2], &[0.1, 0.9], &[0.5, 0.2], &[4.0, 4.0], 3.0, 1)
            .expect("valid");
        assert_eq!(f.ratio(), f64::INFINITY);
        let f = colour_follow(&[0.5], &[0.5], &[0.5], &[4.0], 3.0, 1).expect("valid");
        assert!(f.ratio().is_nan());
        assert!(colour_follow(&before, &carried, &still, &moved, f32::NAN, 1).is_err());
    }
}
