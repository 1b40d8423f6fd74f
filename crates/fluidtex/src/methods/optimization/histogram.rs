//! Histogram matching of the point values to the working exemplar
//! ([`super::Histogram::Matched`]), a departure from the paper.
//!
//! **Why.** Averaging overlapping predictions that do not agree to the
//! texel (members sit at real-valued exemplar coordinates on a surface)
//! lowers the contrast of s a little; the next search then matches the
//! softened pixel neighbourhoods best to the exemplar's *smooth* regions
//! (a blurred query is closer to a flat patch than to a sharp one of the
//! same mean), whose predictions are softer still. Measured on the `vortex`
//! scene (atlas 512): the predictions of the last 9² pass kept 0.62–0.70 of
//! the exemplar's luminance contrast and the texture lost a few percent
//! more every frame through transport (0.69 → 0.56 in five frames).
//! Remapping each channel rank by rank onto the exemplar's values after
//! every averaging step (the histogram step of Kopf et al. 2007's solid
//! texture optimisation) keeps the queries as contrasted as the exemplar,
//! so the search keeps choosing textured neighbourhoods: predictions keep
//! 0.95–0.97, and the atlas's SWD fidelity ratio on that scene falls from
//! 3.8 to 1.5.
//!
//! Written here rather than taken from a crate: it is a sort and a table
//! lookup per channel.

use rayon::prelude::*;

use super::search::WorkingExemplar;

/// Every channel of a working exemplar, sorted: the target histograms.
pub struct Quantiles {
    /// Floats per texel.
    channels: usize,
    /// `sorted[ch]`: channel ch's values over every texel, ascending.
    sorted: Vec<Vec<f32>>,
}

impl Quantiles {
    pub fn new(ex: &WorkingExemplar) -> Quantiles {
        let k = ex.channels;
        let sorted = (0..k)
            .map(|ch| {
                let mut v: Vec<f32> = ex.data.chunks_exact(k).map(|t| t[ch]).collect();
                v.sort_unstable_by(f32::total_cmp);
                v
            })
            .collect();
        Quantiles {
            channels: k,
            sorted,
        }
    }

    /// Replaces each channel of `values` (`channels` floats per point) by
    /// the exemplar value of the same rank: the point of rank r among n
    /// takes the exemplar's quantile (r + ½)/n. Ties are ranked by point
    /// index, so the result does not depend on the thread count.
    pub fn apply(&self, values: &mut [f32]) {
        let k = self.channels;
        let n = values.len() / k.max(1);
        if n == 0 {
            return;
        }
        let mut order: Vec<(f32, u32)> = Vec::with_capacity(n);
        for (ch, target) in self.sorted.iter().enumerate() {
            let m = target.len();
            if m == 0 {
                continue;
            }
            order.clear();
            order.extend(
                values
                    .chunks_exact(k)
                    .enumerate()
                    .map(|(i, t)| (t[ch], i as u32)),
            );
            order.par_sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            for (rank, &(_, i)) in order.iter().enumerate() {
                let q = ((rank as f64 + 0.5) * m as f64 / n as f64) as usize;
                values[i as usize * k + ch] = target[q.min(m - 1)];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn exemplar(rng: &mut impl Rng, w: u32, h: u32, k: usize) -> WorkingExemplar {
        WorkingExemplar {
            width: w,
            height: h,
            channels: k,
            colour: k,
            data: (0..(w * h) as usize * k)
                .map(|_| rng.random::<f32>().powi(2))
                .collect(),
        }
    }

    #[test]
    fn values_take_the_exemplar_histogram_and_keep_their_order() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        for case in 0..20 {
            let k = 1 + case % 4;
            let (w, h) = (rng.random_range(2..20), rng.random_range(2..20));
            let ex = exemplar(&mut rng, w, h, k);
            let q = Quantiles::new(&ex);
            let n = rng.random_range(1..500);
            // A blurred, shifted input: every value in [0.4, 0.6].
            let before: Vec<f32> = (0..n * k)
                .map(|_| 0.4 + 0.2 * rng.random::<f32>())
                .collect();
            let mut after = before.clone();
            q.apply(&mut after);
            for ch in 0..k {
                let col = |v: &[f32]| -> Vec<f32> { v.chunks_exact(k).map(|t| t[ch]).collect() };
                let (b, a) = (col(&before), col(&after));
                // Order kept: a point below another stays at or below it.
                for i in 0..n {
                    for j in 0..n {
                        if b[i] < b[j] {
                            assert!(a[i] <= a[j], "case {case} ch {ch}: {i} {j}");
                        }
                    }
                }
                // Every output is an exemplar value, at its rank's quantile.
                let mut sorted = a.clone();
                sorted.sort_unstable_by(f32::total_cmp);
                let m = q.sorted[ch].len();
                for (r, v) in sorted.iter().enumerate() {
                    let at = (((r as f64 + 0.5) * m as f64 / n as f64) as usize).min(m - 1);
                    assert_eq!(*v, q.sorted[ch][at], "case {case} ch {ch} rank {r}");
                }
            }
        }
    }

    #[test]
    fn matching_restores_the_exemplar_spread_of_a_blurred_input() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let ex = exemplar(&mut rng, 64, 64, 1);
        let sd = |v: &[f32]| {
            let m = v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64;
            (v.iter().map(|&x| (x as f64 - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
        };
        // Same count as the exemplar: the exact same multiset comes back.
        let mut v: Vec<f32> = ex.data.iter().map(|&x| 0.5 + 0.1 * (x - 0.5)).collect();
        let blurred = sd(&v);
        Quantiles::new(&ex).apply(&mut v);
        assert!(blurred < 0.2 * sd(&ex.data));
        let mut a = v.clone();
        let mut b = ex.data.clone();
        a.sort_unstable_by(f32::total_cmp);
        b.sort_unstable_by(f32::total_cmp);
        assert_eq!(a, b);
    }
}
