//! Contrast ratio ρ = σ(output)/σ_ex.
//!
//! Blending n independent layers with weights w_i (Σ w_i = 1) scales the
//! standard deviation by sqrt(Σ w_i²): a 50% cross-fade keeps ≈ 0.71 of the
//! contrast, which is the washed-out look of blended methods. Both σ are
//! population standard deviations of luminance ([`super::luminance`]),
//! accumulated in f64. Texels count equally (no surface-area weight): in an
//! atlas the charts' texel density is near uniform, in a render every
//! pixel is what a viewer sees.
//!
//! **Filtered outputs.** A method that reads a minified exemplar through
//! its mip pyramid ([`crate::methods::footprint`]) shows it averaged over
//! each texel's footprint, which lowers σ honestly: the output is compared
//! with the exemplar *as shown*, not with level 0. [`shown_sigma`] gives
//! that reference from the per-texel levels the method reports: the square
//! root of the mean, over the measured texels, of σ²(lod) of the texel's
//! level. Why the mean of variances: a lapped output is a mosaic of
//! exemplar samples, each read at its texel's level at an unrelated
//! position, and every level keeps the exemplar's mean, so the mosaic's
//! variance is the texel-weighted mean of the per-level variances with no
//! between-level term.
//!
//! σ(lod) ([`exemplar_sigma_by_lod`]) is measured with the sampler the
//! methods use: the luminance pyramid ([`mip_levels`]) read trilinearly at
//! that level at [`SIGMA_SAMPLES`] fixed, evenly spread positions (an R2
//! low-discrepancy sequence: deterministic, no RNG), in steps of
//! [`LOD_STEP`] and interpolated linearly between. Measuring the sampler
//! rather than the levels' texels matters: a coarse level has more of its
//! variance at the texel scale, which bilinear reads between texel centres
//! smooth away, and the trilinear mix of two levels loses more (on the
//! built-in pebbles read at level 3, the texel σ of level 3 overstates what
//! the sampler shows by ≈ 10 %). The table is scaled so that lod 0 gives
//! exactly σ_ex (the texels' σ), so an unfiltered output is judged exactly
//! as before. A method that reports no levels (unfiltered or blended) is
//! compared with σ_ex.

use super::{MetricsError, check_len, check_texture, luminance};
use crate::exemplar::mip_levels;
use crate::exemplar::tone::r2_points;
use crate::texture::{Texture, Wrap};

/// Levels between two entries of [`exemplar_sigma_by_lod`].
pub const LOD_STEP: f32 = 0.25;
/// Positions at which [`exemplar_sigma_by_lod`] reads each level.
pub const SIGMA_SAMPLES: usize = 16_384;

/// σ_ex: the standard deviation of the exemplar's luminance over all its
/// texels.
pub fn exemplar_sigma(exemplar: &Texture) -> f32 {
    std_dev(&luminance(exemplar), None).unwrap_or(0.0) as f32
}

/// σ of the exemplar's luminance as the trilinear mip sampler shows it, at
/// lod 0, `LOD_STEP`, 2 `LOD_STEP`, ... up to the 1 × 1 level (module
/// doc); the first entry is [`exemplar_sigma`].
pub fn exemplar_sigma_by_lod(exemplar: &Texture) -> Vec<f32> {
    let grey = Texture {
        width: exemplar.width,
        height: exemplar.height,
        channels: 1,
        data: luminance(exemplar),
    };
    // Luminance is linear in the channels, so the pyramid of the luminance
    // is the luminance of the colour pyramid.
    let levels = mip_levels(&grey);
    let top = (levels.len() - 1) as f32;
    let positions = r2_points(SIGMA_SAMPLES);
    let sampled = |lod: f32| {
        let k = lod as usize;
        let t = lod - k as f32;
        let values: Vec<f32> = positions
            .iter()
            .map(|&(u, v)| {
                let (mut a, mut b) = ([0.0f32], [0.0f32]);
                levels[k].sample_bilinear(u, v, Wrap::Repeat, &mut a);
                match levels.get(k + 1) {
                    Some(l) if t > 0.0 => {
                        l.sample_bilinear(u, v, Wrap::Repeat, &mut b);
                        a[0] + (b[0] - a[0]) * t
                    }
                    _ => a[0],
                }
            })
            .collect();
        std_dev(&values, None).unwrap_or(0.0)
    };
    let base = std_dev(&grey.data, None).unwrap_or(0.0);
    let steps = (top / LOD_STEP).round() as usize;
    let at: Vec<f64> = (0..=steps)
        .map(|i| sampled((i as f32 * LOD_STEP).min(top)))
        .collect();
    let scale = if at[0] > 0.0 { base / at[0] } else { 0.0 };
    at.iter().map(|s| (s * scale) as f32).collect()
}

/// The σ_ex an output read at per-texel mip levels `lod` is compared with
/// (module doc): sqrt of the mean of σ²(lod) over the texels where `mask`
/// is `true` (all if `None`), from `by_lod` of [`exemplar_sigma_by_lod`]
/// (σ² interpolated linearly between its entries). NaN or negative levels
/// count as level 0; levels beyond the table as its last entry.
pub fn shown_sigma(
    by_lod: &[f32],
    lod: &[f32],
    mask: Option<&[bool]>,
) -> Result<f32, MetricsError> {
    let Some(&base) = by_lod.first() else {
        return Err(MetricsError::Empty("exemplar levels"));
    };
    if let Some(m) = mask
        && m.len() != lod.len()
    {
        return Err(MetricsError::Length {
            what: "contrast mask",
            expected: lod.len(),
            got: m.len(),
        });
    }
    let var = |i: usize| {
        let s = f64::from(by_lod.get(i).copied().unwrap_or(0.0));
        s * s
    };
    let top = (by_lod.len() - 1) as f32;
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (i, &l) in lod.iter().enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        let x = if l > 0.0 {
            (l / LOD_STEP).min(top)
        } else {
            0.0
        };
        // `x` is in [0, top]: the cast floors.
        let k = x as usize;
        let t = f64::from(x - k as f32);
        sum += if t > 0.0 {
            var(k) + (var(k + 1) - var(k)) * t
        } else {
            var(k)
        };
        n += 1;
    }
    if n == 0 {
        return Ok(base);
    }
    Ok((sum / n as f64).sqrt() as f32)
}

/// ρ over the texels where `mask` is `true` (all texels if `None`).
pub fn contrast_ratio(
    output: &Texture,
    mask: Option<&[bool]>,
    sigma_ex: f32,
) -> Result<f64, MetricsError> {
    if !(sigma_ex.is_finite() && sigma_ex > 0.0) {
        return Err(MetricsError::Invalid {
            name: "sigma_ex",
            value: sigma_ex as f64,
            allowed: "(0, inf): a flat exemplar has no contrast to keep",
        });
    }
    check_texture("output", output)?;
    if let Some(m) = mask {
        check_len("contrast mask", m, output.width, output.height)?;
    }
    let sigma = std_dev(&luminance(output), mask).ok_or(MetricsError::Empty("masked texels"))?;
    Ok(sigma / sigma_ex as f64)
}

/// Two-pass population standard deviation; `None` for no values.
fn std_dev(values: &[f32], mask: Option<&[bool]>) -> Option<f64> {
    let selected = || {
        values
            .iter()
            .enumerate()
            .filter(move |(i, _)| mask.is_none_or(|m| m.get(*i).copied().unwrap_or(false)))
            .map(|(_, &v)| v as f64)
    };
    let n = selected().count();
    if n == 0 {
        return None;
    }
    let mean = selected().sum::<f64>() / n as f64;
    let var = selected().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
    Some(var.sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ratio_of_known_images() {
        // Exemplar 0/1 checker: sigma 0.5. Output 0.25/0.75: sigma 0.25.
        let ex = Texture::from_data(2, 2, 1, vec![0.0, 1.0, 1.0, 0.0]).expect("sizes");
        assert_eq!(exemplar_sigma(&ex), 0.5);
        let out = Texture::from_data(2, 2, 1, vec![0.25, 0.75, 0.75, 0.25]).expect("sizes");
        assert_eq!(contrast_ratio(&out, None, 0.5), Ok(0.5));
        // Masking out the two 0.25 texels leaves no contrast.
        let mask = [false, true, true, false];
        assert_eq!(contrast_ratio(&out, Some(&mask), 0.5), Ok(0.0));
    }

    #[test]
    fn shown_sigma_follows_the_levels_texels_are_read_at() {
        // A 4x4 0/1 checker of single texels: every level from 1 on is
        // flat grey, so trilinear reads at lod l in [0, 1] are
        // (1 - l) x (a bilinear read of level 0) + l x 0.5, whose sigma is
        // (1 - l) times that at lod 0; the table is scaled to sigma_ex = 0.5.
        let data = (0..16).map(|i| ((i % 4 + i / 4) % 2) as f32).collect();
        let ex = Texture::from_data(4, 4, 1, data).expect("sizes");
        let table = exemplar_sigma_by_lod(&ex);
        assert_eq!(table.len(), 9, "lods 0 to 2 in quarters");
        assert_eq!(table[0], 0.5);
        for (i, want) in [0.375, 0.25, 0.125, 0.0, 0.0, 0.0, 0.0, 0.0]
            .iter()
            .enumerate()
        {
            assert!((table[i + 1] - want).abs() < 1e-6, "{table:?}");
        }
        assert_eq!(shown_sigma(&table, &[0.0, f32::NAN, -2.0], None), Ok(0.5));
        assert_eq!(shown_sigma(&table, &[1.0, 7.0], None), Ok(0.0));
        // Half the texels at lod 0, half at lod 1: sqrt(0.25 / 2).
        let s = shown_sigma(&table, &[0.0, 1.0], None).expect("valid");
        assert!((s - 0.125f32.sqrt()).abs() < 1e-6, "{s}");
        // Between two entries the variance is interpolated.
        let s = shown_sigma(&table, &[0.125], None).expect("valid");
        assert!((s * s - (0.25 + 0.140625) / 2.0).abs() < 1e-6, "{s}");
        // The mask selects the texels; nothing selected keeps lod 0.
        assert_eq!(
            shown_sigma(&table, &[1.0, 0.0], Some(&[false, true])),
            Ok(0.5)
        );
        assert_eq!(shown_sigma(&table, &[1.0], Some(&[false])), Ok(0.5));
        assert!(shown_sigma(&table, &[1.0], Some(&[false, true])).is_err());
    }

    #[test]
    fn bad_inputs_are_errors() {
        let out = Texture::filled(2, 2, 1, 0.5);
        assert!(matches!(
            contrast_ratio(&out, None, 0.0),
            Err(MetricsError::Invalid {
                name: "sigma_ex",
                ..
            })
        ));
        assert_eq!(
            contrast_ratio(&out, Some(&[false; 4]), 0.5),
            Err(MetricsError::Empty("masked texels"))
        );
        assert!(matches!(
            contrast_ratio(&out, Some(&[true; 3]), 0.5),
            Err(MetricsError::Length { got: 3, .. })
        ));
    }
}
