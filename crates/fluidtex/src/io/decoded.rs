//! What the image decoders ([`super::image_read`] for PNG and JPEG,
//! `exr_read` for EXR) share: the decoded image and how its samples were
//! stored, their errors, and the check of a header's size against the
//! file's length. Kept apart from both so that neither decoder imports the
//! other's file for them.

use thiserror::Error;

use crate::texture::Texture;

/// A decoded image and how its samples were stored.
#[derive(Clone, Debug, PartialEq)]
pub struct Decoded {
    pub texture: Texture,
    pub format: SampleFormat,
}

/// How a channel's samples were stored, and so how its atlas is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SampleFormat {
    /// 8-bit integer (PNG 8-bit).
    U8,
    /// 16-bit integer (PNG 16-bit).
    U16,
    /// Float (EXR).
    F32,
}

/// Errors reading one image. `what` names the file (or the in-memory
/// texture) at fault.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ImageError {
    #[error("{what}: file not found")]
    NotFound { what: String },
    #[error("{what}: cannot read: {reason}")]
    Io { what: String, reason: String },
    #[error("{what}: cannot decode image: {reason}")]
    Decode { what: String, reason: String },
    #[error("{what}: image has zero size ({width}x{height})")]
    ZeroSize {
        what: String,
        width: u32,
        height: u32,
    },
    #[error(
        "{what}: texel ({x}, {y}) channel {channel} is {value}; images must hold finite values"
    )]
    NotFinite {
        what: String,
        x: u32,
        y: u32,
        channel: usize,
        value: f32,
    },
}

/// The most samples a file of `len` bytes can describe. Deflate (PNG, EXR
/// ZIP) expands at most 1032:1 and a 1-bit PNG packs 8 pixels a byte, so
/// no real file exceeds 8300 samples per byte; a million is always
/// allowed. JPEG and EXR's other codecs compress less than deflate.
pub fn max_samples_for(len: usize) -> u64 {
    (len as u64).saturating_mul(8300).saturating_add(1 << 20)
}

/// Refuses a header whose size (`channels` samples per pixel; 1 where the
/// format's decoder does not say) the data cannot hold, before any pixel
/// memory is reserved.
pub fn check_size_against_data(
    width: u64,
    height: u64,
    channels: u64,
    len: usize,
    what: &str,
) -> Result<(), ImageError> {
    let samples = width.saturating_mul(height).saturating_mul(channels.max(1));
    if samples > max_samples_for(len) {
        let of = if channels > 1 {
            format!(" of {channels} channels")
        } else {
            String::new()
        };
        return Err(ImageError::Decode {
            what: what.to_owned(),
            reason: format!(
                "the header says {width}x{height} pixels{of}, more than {len} bytes can hold \
                 (damaged file?)"
            ),
        });
    }
    Ok(())
}
