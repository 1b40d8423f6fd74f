//! Reading OpenEXR images through the `exr` crate: the first flat layer, any of
//! these channel sets (names as OpenEXR spells them, case-sensitive):
//!
//! - `R`, `G`, `B` (and `A`): colour, 3 (4) channels;
//! - `Y` (and `A`): grey (grey + alpha → 4 channels, grey replicated);
//! - any other single channel (`Z`, `height`, ...): grey.
//!
//! Samples of every type (half, float, uint) become `f32`;
//! the exemplar records [`SampleFormat::F32`] so the atlas is written as EXR.

use std::io::Cursor;

use exr::prelude::{AnyChannels, FlatSamples, Image, Layer, ReadChannels, ReadLayers};

use super::decoded::{Decoded, ImageError, SampleFormat, check_size_against_data};
use crate::texture::Texture;

type FlatImage = Image<Layer<AnyChannels<FlatSamples>>>;

pub(crate) fn decode_exr(bytes: &[u8], what: &str) -> Result<Decoded, ImageError> {
    let what = || what.to_owned();
    let decode_err = |e: exr::error::Error| ImageError::Decode {
        what: what(),
        reason: e.to_string(),
    };
    // The headers alone first: no layer may claim more pixels than the
    // data can hold (see `decoded::check_size_against_data`).
    let meta =
        exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false).map_err(decode_err)?;
    for header in &meta.headers {
        let size = header.layer_size;
        let channels = header.channels.list.len().max(1) as u64;
        check_size_against_data(
            size.width() as u64,
            size.height() as u64,
            channels,
            bytes.len(),
            &what(),
        )?;
    }
    let image: FlatImage = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(decode_err)?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let channels = &layer.channel_data.list;
    let find = |name: &str| channels.iter().find(|c| c.name.eq(name));
    let values = |c: &exr::prelude::AnyChannel<FlatSamples>| -> Vec<f32> {
        c.sample_data.values_as_f32().collect()
    };
    let planes: Vec<Vec<f32>> = match (find("R"), find("G"), find("B"), find("Y"), find("A")) {
        (Some(r), Some(g), Some(b), _, a) => [Some(r), Some(g), Some(b), a]
            .into_iter()
            .flatten()
            .map(values)
            .collect(),
        (_, _, _, Some(y), Some(a)) => {
            let (y, a) = (values(y), values(a));
            vec![y.clone(), y.clone(), y, a]
        }
        (_, _, _, Some(y), None) => vec![values(y)],
        _ if channels.len() == 1 => channels.iter().map(values).collect(),
        _ => {
            let names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
            return Err(ImageError::Decode {
                what: what(),
                reason: format!(
                    "EXR channels [{}]: expected R,G,B(,A), Y(,A) or a single channel",
                    names.join(", ")
                ),
            });
        }
    };
    let n = w * h;
    if planes.iter().any(|p| p.len() != n) {
        return Err(ImageError::Decode {
            what: what(),
            reason: "EXR channels are subsampled; only full-resolution channels are supported"
                .into(),
        });
    }
    let mut data = Vec::with_capacity(n * planes.len());
    for i in 0..n {
        data.extend(planes.iter().map(|p| p[i]));
    }
    let texture = Texture::from_data(w as u32, h as u32, planes.len(), data).map_err(|e| {
        ImageError::Decode {
            what: what(),
            reason: e.to_string(),
        }
    })?;
    Ok(Decoded {
        texture,
        format: SampleFormat::F32,
    })
}
