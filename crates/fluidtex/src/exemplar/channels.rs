//! The output channels of an exemplar and how each atlas is written: the
//! colour first, then every extra channel (displacement, roughness, ...)
//! under its own name, each in the sample format it was read in.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{Exemplar, SampleFormat};
use crate::texture::Texture;

/// How an atlas channel is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ChannelFormat {
    /// 8-bit PNG.
    Png8,
    /// 16-bit PNG.
    Png16,
    /// 32-bit float EXR.
    Exr,
}

impl ChannelFormat {
    pub fn extension(self) -> &'static str {
        match self {
            ChannelFormat::Png8 | ChannelFormat::Png16 => "png",
            ChannelFormat::Exr => "exr",
        }
    }
}

/// Name and format of one output channel (`color`, `displacement`, ...).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ChannelSpec {
    pub name: String,
    pub format: ChannelFormat,
}

impl From<SampleFormat> for ChannelFormat {
    fn from(f: SampleFormat) -> ChannelFormat {
        match f {
            SampleFormat::U8 => ChannelFormat::Png8,
            SampleFormat::U16 => ChannelFormat::Png16,
            SampleFormat::F32 => ChannelFormat::Exr,
        }
    }
}

/// The output channels of an exemplar: `color`, then its extra channels by
/// name, each written in the format it was read in.
pub fn exemplar_channels(e: &Exemplar) -> Vec<ChannelSpec> {
    let mut specs = vec![ChannelSpec {
        name: "color".into(),
        format: e.colour_format.into(),
    }];
    specs.extend(e.channels.iter().map(|c| ChannelSpec {
        name: c.name.clone(),
        format: c.format.into(),
    }));
    specs
}

/// Splits a `width` × `height` atlas of interleaved values (every channel
/// of `exemplar` per texel, colour first, as [`Exemplar::sample_all`]
/// writes them) into one texture per exemplar texture. An exemplar with
/// colour only hands its buffer over as it is: at 6144² that saves a copy
/// of 450 MB per frame.
pub fn split_interleaved(
    width: u32,
    height: u32,
    values: Vec<f32>,
    exemplar: &Exemplar,
) -> Vec<Texture> {
    let mut layout = vec![exemplar.colour.channels];
    layout.extend(exemplar.channels.iter().map(|c| c.texture.channels));
    let total = layout.iter().sum::<usize>().max(1);
    if layout.len() == 1 {
        let channels = layout[0];
        return vec![Texture {
            width,
            height,
            channels,
            data: values,
        }];
    }
    let texels = values.len() / total;
    let mut offset = 0;
    layout
        .into_iter()
        .map(|k| {
            let mut data = vec![0.0f32; texels * k];
            data.par_chunks_mut(k.max(1))
                .zip(values.par_chunks(total))
                .with_min_len(1 << 12)
                .for_each(|(o, texel)| o.copy_from_slice(&texel[offset..offset + k]));
            offset += k;
            Texture {
                width,
                height,
                channels: k,
                data,
            }
        })
        .collect()
}
