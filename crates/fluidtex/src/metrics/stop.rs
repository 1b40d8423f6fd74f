//! Static stop and exemplar-size cost: the two sequence-level numbers.
//!
//! Once the fluid stops, the output must stop changing: every frame after
//! the first still frame must be bit-identical to it (`f32` bit patterns,
//! so `-0.0` differs from `0.0` and a NaN equals only the same NaN; a
//! change of size or channel count is a difference). [`StaticStop`] takes
//! the frames one at a time, so a streamed sequence needs one reference
//! frame of memory.

use super::MetricsError;
use crate::texture::Texture;

/// Whether two textures are bit for bit the same.
pub fn bit_identical(a: &Texture, b: &Texture) -> bool {
    a.width == b.width
        && a.height == b.height
        && a.channels == b.channels
        && a.data.len() == b.data.len()
        && a.data
            .iter()
            .zip(&b.data)
            .all(|(x, y)| x.to_bits() == y.to_bits())
}

/// Counts the frames after the stop that differ from the first still
/// frame.
#[derive(Clone, Debug, Default)]
pub struct StaticStop {
    reference: Option<Texture>,
    after: usize,
    changed: usize,
}

impl StaticStop {
    pub fn new() -> StaticStop {
        StaticStop::default()
    }

    /// Feeds the next frame; the first one fed is the reference. Returns
    /// whether this frame differs from it.
    pub fn push(&mut self, frame: &Texture) -> bool {
        match &self.reference {
            None => {
                self.reference = Some(frame.clone());
                false
            }
            Some(r) => {
                self.after += 1;
                let differs = !bit_identical(r, frame);
                self.changed += usize::from(differs);
                differs
            }
        }
    }

    /// The metric: frames after the reference that differ from it.
    pub fn changed(&self) -> usize {
        self.changed
    }

    /// Frames fed after the reference.
    pub fn frames_after(&self) -> usize {
        self.after
    }
}

/// time(2048² exemplar) / time(256² exemplar), from the harness's timings
/// (seconds per frame, same scene and settings otherwise).
pub fn size_cost_ratio(seconds_large: f64, seconds_small: f64) -> Result<f64, MetricsError> {
    for (name, v) in [
        ("time with the 2048² exemplar", seconds_large),
        ("time with the 256² exemplar", seconds_small),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(MetricsError::Invalid {
                name,
                value: v,
                allowed: "(0, inf) seconds",
            });
        }
    }
    Ok(seconds_large / seconds_small)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_identity_is_strict() {
        let a = Texture::filled(2, 2, 1, 0.0);
        let mut b = a.clone();
        assert!(bit_identical(&a, &b));
        b.data[3] = -0.0;
        assert!(!bit_identical(&a, &b));
        let n = Texture::filled(2, 2, 1, f32::NAN);
        assert!(bit_identical(&n, &n.clone()));
        assert!(!bit_identical(&a, &Texture::filled(2, 2, 2, 0.0)));
        assert!(!bit_identical(&a, &Texture::filled(4, 1, 1, 0.0)));
    }

    #[test]
    fn size_cost() {
        assert_eq!(size_cost_ratio(1.1, 1.0), Ok(1.1));
        assert!(size_cost_ratio(1.0, 0.0).is_err());
        assert!(size_cost_ratio(f64::NAN, 1.0).is_err());
    }
}
