//! Otsu's threshold (Otsu 1979, "A threshold selection method from
//! gray-level histograms"): the cut of a 256-bin histogram that maximises the
//! between-class variance σ_B². The ratio η = σ_B² / σ_T² (Otsu's
//! "separability", in `[0, 1]`) says how well two classes explain the image:
//! near 1 for a clean two-level image, lower for unimodal ones.

/// Result of Otsu's method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Otsu {
    /// Values `> threshold` form the upper class.
    pub threshold: f32,
    /// η = σ_B² / σ_T² at the chosen threshold; 0 for a constant image.
    pub separability: f32,
}

const BINS: usize = 256;

/// Otsu's threshold of `values`; `None` when they hold fewer than two
/// distinct values (nothing to separate).
pub fn otsu(values: &[f32]) -> Option<Otsu> {
    let (lo, hi) = values
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if !matches!(hi.partial_cmp(&lo), Some(std::cmp::Ordering::Greater)) {
        return None;
    }
    let bin = |v: f32| (((v - lo) / (hi - lo) * BINS as f32) as usize).min(BINS - 1);
    let mut hist = [0u64; BINS];
    for &v in values {
        hist[bin(v)] += 1;
    }
    let n = values.len() as f64;
    let centre = |b: usize| (b as f64 + 0.5) / BINS as f64;
    let total_mean: f64 = hist
        .iter()
        .enumerate()
        .map(|(b, &c)| c as f64 * centre(b))
        .sum::<f64>()
        / n;
    let total_var: f64 = hist
        .iter()
        .enumerate()
        .map(|(b, &c)| c as f64 * (centre(b) - total_mean).powi(2))
        .sum::<f64>()
        / n;
    let (mut best, mut best_b) = (-1.0f64, 0usize);
    let (mut w0, mut sum0) = (0.0f64, 0.0f64);
    for (b, &c) in hist.iter().enumerate().take(BINS - 1) {
        w0 += c as f64;
        sum0 += c as f64 * centre(b);
        let w1 = n - w0;
        if w0 == 0.0 || w1 == 0.0 {
            continue;
        }
        let m0 = sum0 / w0;
        let m1 = (total_mean * n - sum0) / w1;
        let between = w0 * w1 / (n * n) * (m0 - m1).powi(2);
        if between > best {
            best = between;
            best_b = b;
        }
    }
    let threshold = lo + (hi - lo) * (best_b + 1) as f32 / BINS as f32;
    let separability = if total_var > 0.0 {
        (best / total_var).clamp(0.0, 1.0) as f32
    } else {
        0.0
    };
    Some(Otsu {
        threshold,
        separability,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separates_two_levels() {
        let mut v = vec![0.2f32; 300];
        v.extend(vec![0.7f32; 100]);
        let o = otsu(&v).expect("two levels");
        assert!(o.threshold > 0.2 && o.threshold < 0.7, "{o:?}");
        assert!(o.separability > 0.99, "{o:?}");
        let above = v.iter().filter(|&&x| x > o.threshold).count();
        assert_eq!(above, 100);
    }

    #[test]
    fn uniform_noise_is_less_separable() {
        let v: Vec<f32> = (0..1000).map(|i| i as f32 / 999.0).collect();
        let o = otsu(&v).expect("many values");
        // A uniform distribution split in half: η = 3/4.
        assert!((o.separability - 0.75).abs() < 0.01, "{o:?}");
        assert!(otsu(&[0.5; 10]).is_none());
    }
}
