//! Float images with an explicit texel convention, shared by exemplars,
//! atlases and renders.
//!
//! **Convention.** Texel `(x, y)` covers `[x, x+1) × [y, y+1)` in pixel
//! units; its centre is at `(x + 0.5, y + 0.5)`. Row 0 is the top row (image
//! order). Normalised coordinates are `u = px / width`, `v = py / height`,
//! so `v = 0` is the top edge; writers that need a bottom-left origin (OBJ)
//! flip `v` themselves. Bilinear sampling subtracts 0.5 before
//! interpolating, as pbrt does, so sampling at a texel centre returns that
//! texel exactly.

use thiserror::Error;

/// How coordinates outside `[0, 1)` are folded back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    /// Tile the image (exemplars).
    Repeat,
    /// Clamp to the edge texel (atlases).
    Clamp,
}

/// Errors building a texture from user data.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum TextureError {
    #[error("{width}x{height} texture with {channels} channels needs {expected} values, got {got}")]
    SizeMismatch {
        width: u32,
        height: u32,
        channels: usize,
        expected: usize,
        got: usize,
    },
    #[error("a texture needs 1 to 4 channels, got {0}")]
    Channels(usize),
}

/// An interleaved `f32` image with 1 to 4 channels.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub channels: usize,
    /// Row-major, interleaved: `data[(y * width + x) * channels + c]`.
    pub data: Vec<f32>,
}

impl Texture {
    /// A texture filled with `value`.
    pub fn filled(width: u32, height: u32, channels: usize, value: f32) -> Texture {
        Texture {
            width,
            height,
            channels,
            data: vec![value; width as usize * height as usize * channels],
        }
    }

    /// Wraps existing data, checking its length.
    pub fn from_data(
        width: u32,
        height: u32,
        channels: usize,
        data: Vec<f32>,
    ) -> Result<Texture, TextureError> {
        if !(1..=4).contains(&channels) {
            return Err(TextureError::Channels(channels));
        }
        let expected = width as usize * height as usize * channels;
        if data.len() != expected {
            return Err(TextureError::SizeMismatch {
                width,
                height,
                channels,
                expected,
                got: data.len(),
            });
        }
        Ok(Texture {
            width,
            height,
            channels,
            data,
        })
    }

    /// Number of texels.
    #[inline]
    pub fn texel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The channels of texel `(x, y)`.
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> &[f32] {
        let i = (y as usize * self.width as usize + x as usize) * self.channels;
        &self.data[i..i + self.channels]
    }

    /// Mutable channels of texel `(x, y)`.
    #[inline]
    pub fn texel_mut(&mut self, x: u32, y: u32) -> &mut [f32] {
        let i = (y as usize * self.width as usize + x as usize) * self.channels;
        &mut self.data[i..i + self.channels]
    }

    /// Bilinear sample at normalised `(u, v)`, written to `out[..channels]`.
    #[inline]
    pub fn sample_bilinear(&self, u: f32, v: f32, wrap: Wrap, out: &mut [f32]) {
        let (w, h) = (self.width as i64, self.height as i64);
        let px = u * self.width as f32 - 0.5;
        let py = v * self.height as f32 - 0.5;
        let (x0, y0) = (px.floor(), py.floor());
        let (fx, fy) = (px - x0, py - y0);
        let fold = |i: i64, n: i64| -> usize {
            match wrap {
                Wrap::Repeat => i.rem_euclid(n) as usize,
                Wrap::Clamp => i.clamp(0, n - 1) as usize,
            }
        };
        let (x0, y0) = (x0 as i64, y0 as i64);
        let (xa, xb) = (fold(x0, w), fold(x0 + 1, w));
        let (ya, yb) = (fold(y0, h), fold(y0 + 1, h));
        let c = self.channels;
        let row = self.width as usize;
        let at = |x: usize, y: usize| (y * row + x) * c;
        let (i00, i10, i01, i11) = (at(xa, ya), at(xb, ya), at(xa, yb), at(xb, yb));
        for (k, o) in out.iter_mut().enumerate().take(c) {
            let top = self.data[i00 + k] * (1.0 - fx) + self.data[i10 + k] * fx;
            let bottom = self.data[i01 + k] * (1.0 - fx) + self.data[i11 + k] * fx;
            *o = top * (1.0 - fy) + bottom * fy;
        }
    }

    /// Per-channel mean and standard deviation over all texels.
    pub fn mean_std(&self) -> Vec<(f64, f64)> {
        let n = self.texel_count().max(1) as f64;
        (0..self.channels)
            .map(|k| {
                let mean = self
                    .data
                    .iter()
                    .skip(k)
                    .step_by(self.channels)
                    .map(|&x| x as f64)
                    .sum::<f64>()
                    / n;
                let var = self
                    .data
                    .iter()
                    .skip(k)
                    .step_by(self.channels)
                    .map(|&x| (x as f64 - mean).powi(2))
                    .sum::<f64>()
                    / n;
                (mean, var.sqrt())
            })
            .collect()
    }
}

/// `⌊x⌋` as an integer, saturating (NaN gives 0), equal to
/// `x.floor() as i32` for every `x`: without SSE4.1 in the baseline,
/// `floor` is a libm call, so this truncates and corrects instead. Hot
/// per-texel paths (exemplar lookups, patch cells) use it.
#[inline(always)]
pub(crate) fn floor_i32(x: f32) -> i32 {
    let t = x as i32;
    if (t as f32) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;

    #[test]
    fn floor_i32_equals_floor_then_cast() {
        let mut cases = vec![
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            -1.0,
            1.0 - f32::EPSILON,
            -f32::MIN_POSITIVE,
            8_388_607.5,
            -8_388_607.5,
            2_147_483_520.0,
            -2_147_483_648.0,
            3e9,
            -3e9,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let mut rng = Pcg64::seed_from_u64(1);
        for _ in 0..100_000 {
            // Random bit patterns: every exponent, both signs.
            cases.push(f32::from_bits(rng.random()));
            // And small coordinates, where texel lookups live.
            cases.push(rng.random_range(-2048.0f32..2048.0));
        }
        for x in cases {
            assert_eq!(floor_i32(x), x.floor() as i32, "{x:e} ({:#x})", x.to_bits());
        }
    }

    fn ramp() -> Texture {
        // 4x2, one channel, value = x + 10 y.
        let data = (0..2)
            .flat_map(|y| (0..4).map(move |x| (x + 10 * y) as f32))
            .collect();
        Texture::from_data(4, 2, 1, data).expect("sizes match")
    }

    #[test]
    fn sampling_at_texel_centres_is_exact() {
        let t = ramp();
        let mut out = [0.0];
        for y in 0..2 {
            for x in 0..4 {
                let (u, v) = ((x as f32 + 0.5) / 4.0, (y as f32 + 0.5) / 2.0);
                t.sample_bilinear(u, v, Wrap::Clamp, &mut out);
                assert_eq!(out[0], t.texel(x, y)[0]);
            }
        }
    }

    #[test]
    fn bilinear_between_texels_and_wrap_modes() {
        let t = ramp();
        let mut out = [0.0];
        // Halfway between texel (1,0) and (2,0).
        t.sample_bilinear(0.5, 0.25, Wrap::Clamp, &mut out);
        assert_eq!(out[0], 1.5);
        // Left edge: clamp repeats texel 0, repeat blends with texel 3.
        t.sample_bilinear(0.0, 0.25, Wrap::Clamp, &mut out);
        assert_eq!(out[0], 0.0);
        t.sample_bilinear(0.0, 0.25, Wrap::Repeat, &mut out);
        assert_eq!(out[0], 1.5);
    }

    #[test]
    fn rejects_wrong_sizes() {
        assert!(matches!(
            Texture::from_data(2, 2, 3, vec![0.0; 11]),
            Err(TextureError::SizeMismatch {
                expected: 12,
                got: 11,
                ..
            })
        ));
        assert_eq!(
            Texture::from_data(1, 1, 5, vec![0.0; 5]),
            Err(TextureError::Channels(5))
        );
    }

    #[test]
    fn mean_and_std() {
        let t = Texture::from_data(2, 1, 1, vec![1.0, 3.0]).expect("sizes match");
        assert_eq!(t.mean_std(), vec![(2.0, 1.0)]);
    }
}
