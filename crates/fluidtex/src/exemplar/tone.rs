//! The exemplar's per-channel statistics as the methods' sampler shows
//! them: the mean of every channel and its variance at each mip level.
//!
//! These are the reference of tone matching ([`crate::methods::tone`]): an
//! honest mosaic of exemplar samples, each read at its texel's level at an
//! unrelated position, has the exemplar's mean (every level keeps it) and
//! the texel-weighted mean of the per-level variances (the same argument as
//! the contrast metric's reference, [`crate::metrics::shown_sigma`]).
//!
//! The variances are measured with the lookup the methods make,
//! [`Exemplar::sample_all_lod`], at [`TONE_SAMPLES`] fixed, evenly spread
//! positions ([`r2_points`]: deterministic, no RNG), in steps of
//! [`TONE_LOD_STEP`] levels. Bilinear reads between texel centres smooth a
//! little of the texel-scale variance away even at level 0, and a mosaic
//! read the same way shows exactly that, so the table is not rescaled to
//! the texels' own variance.

use super::Exemplar;

/// Levels between two entries of [`ExemplarTone::variance_by_lod`].
pub const TONE_LOD_STEP: f32 = 0.25;
/// Positions at which each level is read.
pub const TONE_SAMPLES: usize = 16_384;

/// `n` points of the R2 sequence (the plastic number's powers), evenly
/// spread in \[0, 1)² at every scale, so their sub-texel offsets are evenly
/// spread at every mip level.
pub fn r2_points(n: usize) -> Vec<(f32, f32)> {
    let g = 1.324_717_957_244_746f64;
    let (a1, a2) = (1.0 / g, 1.0 / (g * g));
    (0..n)
        .map(|i| {
            let i = i as f64;
            ((0.5 + a1 * i).fract() as f32, (0.5 + a2 * i).fract() as f32)
        })
        .collect()
}

/// Per-channel statistics of an exemplar (module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct ExemplarTone {
    /// Mean of each channel over the level-0 texels.
    pub mean: Vec<f64>,
    /// `variance_by_lod[k][c]`: variance of channel `c` read at level
    /// `k · TONE_LOD_STEP` (the last entry at [`Exemplar::max_lod`]).
    pub variance_by_lod: Vec<Vec<f64>>,
}

impl ExemplarTone {
    /// Measures `exemplar` (a few hundred thousand lookups: once per
    /// exemplar, not per frame).
    pub fn of(exemplar: &Exemplar) -> ExemplarTone {
        let c = exemplar.total_channels();
        let mean = ExemplarTone::means_of(exemplar).mean;
        let points = r2_points(TONE_SAMPLES);
        let top = exemplar.max_lod();
        let steps = (top / TONE_LOD_STEP).ceil() as usize;
        let mut value = vec![0.0f32; c];
        let variance_by_lod = (0..=steps)
            .map(|k| {
                let lod = (k as f32 * TONE_LOD_STEP).min(top);
                let (mut sum, mut sum_sq) = (vec![0.0f64; c], vec![0.0f64; c]);
                for &(u, v) in &points {
                    exemplar.sample_all_lod(u, v, lod, &mut value);
                    for ch in 0..c {
                        let x = f64::from(value[ch]);
                        sum[ch] += x;
                        sum_sq[ch] += x * x;
                    }
                }
                let n = points.len() as f64;
                (0..c)
                    .map(|ch| {
                        let m = sum[ch] / n;
                        (sum_sq[ch] / n - m * m).max(0.0)
                    })
                    .collect()
            })
            .collect();
        ExemplarTone {
            mean,
            variance_by_lod,
        }
    }

    /// The means alone, from level 0 (no variance table, so no mip
    /// pyramid is read): all that mean matching and transitions use.
    pub fn means_of(exemplar: &Exemplar) -> ExemplarTone {
        let c = exemplar.total_channels();
        let data = &exemplar.packed.data;
        let texels = (data.len() / c.max(1)).max(1) as f64;
        let mut mean = vec![0.0f64; c];
        for texel in data.chunks_exact(c.max(1)) {
            for (m, &v) in mean.iter_mut().zip(texel) {
                *m += f64::from(v);
            }
        }
        mean.iter_mut().for_each(|m| *m /= texels);
        ExemplarTone {
            mean,
            variance_by_lod: Vec::new(),
        }
    }

    /// Channel count.
    pub fn channels(&self) -> usize {
        self.mean.len()
    }

    /// Adds the variance of every channel at level `lod` to `out`
    /// (linear between table entries; NaN or ≤ 0 is level 0, beyond the
    /// table its last entry).
    #[inline]
    pub fn add_variance_at(&self, lod: f32, out: &mut [f64]) {
        let last = self.variance_by_lod.len().saturating_sub(1);
        let x = if lod > 0.0 {
            (lod / TONE_LOD_STEP).min(last as f32)
        } else {
            0.0
        };
        // `x` is in [0, last]: the cast floors.
        let k = x as usize;
        let t = f64::from(x - k as f32);
        let (Some(a), b) = (self.variance_by_lod.get(k), self.variance_by_lod.get(k + 1)) else {
            return;
        };
        match b {
            Some(b) if t > 0.0 => {
                for ((o, &a), &b) in out.iter_mut().zip(a).zip(b) {
                    *o += a + (b - a) * t;
                }
            }
            _ => {
                for (o, &a) in out.iter_mut().zip(a) {
                    *o += a;
                }
            }
        }
    }
}
