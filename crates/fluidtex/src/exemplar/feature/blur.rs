//! Separable Gaussian blur on a torus (the exemplar tiles, so its derived
//! feature map must tile too).

/// Blurs a `width × height` scalar image with standard deviation `sigma`
/// texels, wrapping around both edges. `sigma <= 0` returns a copy.
pub fn gaussian_wrap(values: &[f32], width: usize, height: usize, sigma: f32) -> Vec<f32> {
    if sigma <= 0.0 || !sigma.is_finite() || values.len() != width * height {
        return values.to_vec();
    }
    let radius = (3.0 * sigma).ceil() as usize;
    let kernel: Vec<f32> = (0..=2 * radius)
        .map(|i| {
            let d = i as f32 - radius as f32;
            (-0.5 * d * d / (sigma * sigma)).exp()
        })
        .collect();
    let norm: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / norm).collect();

    let mut rows = vec![0.0; values.len()];
    for y in 0..height {
        let row = &values[y * width..(y + 1) * width];
        for (x, out) in rows[y * width..(y + 1) * width].iter_mut().enumerate() {
            *out = kernel
                .iter()
                .enumerate()
                .map(|(k, w)| w * row[(x + width * (radius / width + 1) + k - radius) % width])
                .sum();
        }
    }
    let mut out = vec![0.0; values.len()];
    for y in 0..height {
        for x in 0..width {
            out[y * width + x] = kernel
                .iter()
                .enumerate()
                .map(|(k, w)| {
                    let yy = (y + height * (radius / height + 1) + k - radius) % height;
                    w * rows[yy * width + x]
                })
                .sum();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preserves_mean_and_wraps() {
        // A single bright texel in the corner spreads to the opposite corner.
        let (w, h) = (7, 5);
        let mut v = vec![0.0; w * h];
        v[0] = 1.0;
        let b = gaussian_wrap(&v, w, h, 1.0);
        let sum: f32 = b.iter().sum();
        assert!((sum - 1.0).abs() < 1e-5);
        assert!(b[w * h - 1] > 0.01, "no wrap-around: {}", b[w * h - 1]);
        assert_eq!(b[1], b[w - 1], "blur must be symmetric across the seam");
    }
}
