//! Contrast ratio ρ = σ(output)/σ_ex.
//!
//! Blending n independent layers with weights w_i (Σ w_i = 1) scales the
//! standard deviation by sqrt(Σ w_i²): a 50% cross-fade keeps ≈ 0.71 of the
//! contrast, which is the washed-out look of blended methods. Both σ are
//! population standard deviations of luminance ([`super::luminance`]),
//! accumulated in f64. Texels count equally (no surface-area weight): in an
//! atlas the charts' texel density is near uniform, in a render every
//! pixel is what a viewer sees.

use super::{MetricsError, check_len, check_texture, luminance};
use crate::texture::Texture;

/// σ_ex: the standard deviation of the exemplar's luminance over all its
/// texels.
pub fn exemplar_sigma(exemplar: &Texture) -> f32 {
    std_dev(&luminance(exemplar), None).unwrap_or(0.0) as f32
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
