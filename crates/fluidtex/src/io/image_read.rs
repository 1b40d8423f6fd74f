//! Reading images (PNG, JPEG, EXR) into float textures: exemplars, their
//! channels and feature maps, and our own outputs read back. Writing is
//! [`super::image`].
//!
//! Integer formats are scaled to `[0, 1]` (8-bit by 255, 16-bit by 65535)
//! and nothing else: no sRGB decoding, so an atlas written back in the same
//! format reproduces the exemplar's values. Channel layouts map as follows:
//! grey → 1 channel, grey + alpha → 4 channels (grey replicated into RGB,
//! because a texture here has 1, 3 or 4 channels), RGB → 3, RGBA → 4.
//!
//! PNG and JPEG go through the `image` crate. EXR is read with the `exr`
//! crate directly, because `image` only decodes EXR files that hold R, G and
//! B channels, and height or feature maps are usually a single `Y` (or other
//! single) channel.
//!
//! The size in an image's header is checked against the file's length
//! before any pixel memory is reserved ([`check_size_against_data`]), so a
//! damaged header claiming 60000² pixels is refused instead of reserving
//! gigabytes for data that is not there.

use std::io::Cursor;
use std::path::Path;

use image::DynamicImage;

pub use super::decoded::{
    Decoded, ImageError, SampleFormat, check_size_against_data, max_samples_for,
};
use crate::texture::Texture;

const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// Reads an image file, recognising the format from its contents.
pub fn read_image(path: &Path) -> Result<Decoded, ImageError> {
    let what = path.display().to_string();
    if !path.exists() {
        return Err(ImageError::NotFound { what });
    }
    let bytes = std::fs::read(path).map_err(|e| ImageError::Io {
        what: what.clone(),
        reason: e.to_string(),
    })?;
    decode_image(&bytes, &what)
}

/// Decodes image bytes (PNG, JPEG or EXR, recognised from the contents);
/// `what` names the image in messages.
pub fn decode_image(bytes: &[u8], what: &str) -> Result<Decoded, ImageError> {
    // Files shorter than 4 bytes fall through to the image crate's error.
    let decoded = if bytes.starts_with(&EXR_MAGIC) {
        super::exr_read::decode_exr(bytes, what)?
    } else {
        decode_with_image_crate(bytes, what)?
    };
    check(&decoded.texture, what)?;
    Ok(decoded)
}

/// Rejects empty images and non-finite samples.
pub(crate) fn check(texture: &Texture, what: &str) -> Result<(), ImageError> {
    if texture.width == 0 || texture.height == 0 {
        return Err(ImageError::ZeroSize {
            what: what.to_owned(),
            width: texture.width,
            height: texture.height,
        });
    }
    let channels = texture.channels.max(1);
    if let Some(i) = texture.data.iter().position(|x| !x.is_finite()) {
        let texel = i / channels;
        let w = texture.width as usize;
        return Err(ImageError::NotFinite {
            what: what.to_owned(),
            x: (texel % w) as u32,
            y: (texel / w) as u32,
            channel: i % channels,
            value: texture.data[i],
        });
    }
    Ok(())
}

fn decode_with_image_crate(bytes: &[u8], what: &str) -> Result<Decoded, ImageError> {
    let what = || what.to_owned();
    let reader = || {
        image::ImageReader::new(Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| ImageError::Io {
                what: what(),
                reason: e.to_string(),
            })
    };
    let decode_err = |e: image::ImageError| ImageError::Decode {
        what: what(),
        reason: e.to_string(),
    };
    // The header alone first: its size must fit the data (see above).
    let (w, h) = reader()?.into_dimensions().map_err(decode_err)?;
    check_size_against_data(u64::from(w), u64::from(h), 1, bytes.len(), &what())?;
    let image = reader()?.decode().map_err(decode_err)?;
    from_dynamic(image).map_err(|reason| ImageError::Decode {
        what: what(),
        reason,
    })
}

/// Converts any decoded layout to a 1, 3 or 4 channel float texture.
pub(crate) fn from_dynamic(image: DynamicImage) -> Result<Decoded, String> {
    // Divisors, not reciprocals: `51 / 255` must read back as exactly 0.2f32.
    const U8: f32 = 255.0;
    const U16: f32 = 65535.0;
    let (w, h) = (image.width(), image.height());
    let (channels, format, data): (usize, SampleFormat, Vec<f32>) = match image {
        DynamicImage::ImageLuma8(b) => (1, SampleFormat::U8, scale(b.as_raw(), U8)),
        DynamicImage::ImageLumaA8(b) => (4, SampleFormat::U8, grey_alpha(b.as_raw(), U8)),
        DynamicImage::ImageRgb8(b) => (3, SampleFormat::U8, scale(b.as_raw(), U8)),
        DynamicImage::ImageRgba8(b) => (4, SampleFormat::U8, scale(b.as_raw(), U8)),
        DynamicImage::ImageLuma16(b) => (1, SampleFormat::U16, scale(b.as_raw(), U16)),
        DynamicImage::ImageLumaA16(b) => (4, SampleFormat::U16, grey_alpha(b.as_raw(), U16)),
        DynamicImage::ImageRgb16(b) => (3, SampleFormat::U16, scale(b.as_raw(), U16)),
        DynamicImage::ImageRgba16(b) => (4, SampleFormat::U16, scale(b.as_raw(), U16)),
        DynamicImage::ImageRgb32F(b) => (3, SampleFormat::F32, b.into_raw()),
        DynamicImage::ImageRgba32F(b) => (4, SampleFormat::F32, b.into_raw()),
        other => return Err(format!("unsupported pixel layout {:?}", other.color())),
    };
    let texture = Texture::from_data(w, h, channels, data).map_err(|e| e.to_string())?;
    Ok(Decoded { texture, format })
}

fn scale<T: Copy + Into<f32>>(raw: &[T], max: f32) -> Vec<f32> {
    raw.iter().map(|&x| x.into() / max).collect()
}

fn grey_alpha<T: Copy + Into<f32>>(raw: &[T], max: f32) -> Vec<f32> {
    raw.chunks_exact(2)
        .flat_map(|la| {
            let (l, a) = (la[0].into() / max, la[1].into() / max);
            [l, l, l, a]
        })
        .collect()
}
