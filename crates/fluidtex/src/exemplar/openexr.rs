//! OpenEXR exemplars through the `exr` crate: the first flat layer, any of
//! these channel sets (names as OpenEXR spells them, case-sensitive):
//!
//! - `R`, `G`, `B` (and `A`): colour, 3 (4) channels;
//! - `Y` (and `A`): grey (grey + alpha → 4 channels, grey replicated);
//! - any other single channel (`Z`, `height`, ...): grey.
//!
//! Samples of every type (half, float, uint) become `f32`;
//! the exemplar records [`SampleFormat::F32`] so the atlas is written as EXR.

use std::path::Path;

use exr::prelude::{AnyChannels, FlatSamples, Image, Layer, ReadChannels, ReadLayers};

use super::decode::Decoded;
use super::{ExemplarError, SampleFormat};
use crate::texture::Texture;

type FlatImage = Image<Layer<AnyChannels<FlatSamples>>>;

pub(crate) fn read_exr(path: &Path) -> Result<Decoded, ExemplarError> {
    let what = || path.display().to_string();
    let image: FlatImage = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| ExemplarError::Decode {
            what: what(),
            reason: e.to_string(),
        })?;
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
            return Err(ExemplarError::Decode {
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
        return Err(ExemplarError::Decode {
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
        ExemplarError::Decode {
            what: what(),
            reason: e.to_string(),
        }
    })?;
    Ok(Decoded {
        texture,
        format: SampleFormat::F32,
    })
}
