//! Preview sheets: images placed side by side.

use super::shade::to_rgb;
use crate::texture::Texture;

/// Places images left to right, top-aligned, `gap` pixels apart, on
/// `background`; the result has 3 channels.
pub fn side_by_side(images: &[&Texture], gap: u32, background: [f32; 3]) -> Texture {
    let width =
        images.iter().map(|t| t.width).sum::<u32>() + gap * images.len().saturating_sub(1) as u32;
    let height = images.iter().map(|t| t.height).max().unwrap_or(0);
    let mut out = Texture::filled(width, height, 3, 0.0);
    for px in out.data.chunks_exact_mut(3) {
        px.copy_from_slice(&background);
    }
    let mut left = 0;
    for t in images {
        for y in 0..t.height {
            for x in 0..t.width {
                let rgb = to_rgb(t.texel(x, y));
                out.texel_mut(left + x, y).copy_from_slice(&rgb);
            }
        }
        left += t.width + gap;
    }
    out
}
