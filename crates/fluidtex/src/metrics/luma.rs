//! Grey values for metrics that compare intensities (contrast, fidelity,
//! popping, image flow).

use crate::texture::Texture;

/// Rec. 709 luminance weights, applied to the stored channel values.
const REC709: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// One grey value per texel: channel 0 for 1- and 2-channel textures (grey,
/// grey + alpha), Rec. 709 luminance of RGB for 3- and 4-channel ones (alpha
/// ignored). Alpha is ignored because the exemplars' alpha, where any, is
/// coverage, not appearance.
pub fn luminance(texture: &Texture) -> Vec<f32> {
    let c = texture.channels.max(1);
    texture
        .data
        .chunks_exact(c)
        .map(|t| match t {
            [r, g, b, ..] => REC709[0] * r + REC709[1] * g + REC709[2] * b,
            [y, ..] => *y,
            [] => 0.0,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_alpha_and_colour() {
        let grey_alpha = Texture::from_data(2, 1, 2, vec![0.25, 1.0, 0.75, 0.0]).expect("sizes");
        assert_eq!(luminance(&grey_alpha), vec![0.25, 0.75]);
        let rgba = Texture::from_data(1, 1, 4, vec![1.0, 0.0, 0.0, 0.5]).expect("sizes");
        assert_eq!(luminance(&rgba), vec![0.2126]);
        let white = Texture::filled(2, 2, 3, 1.0);
        for y in luminance(&white) {
            assert!((y - 1.0).abs() < 1e-6);
        }
    }
}
