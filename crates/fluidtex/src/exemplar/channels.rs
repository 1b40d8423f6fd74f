//! The output channels of an exemplar and how each atlas is written: the
//! colour first, then every extra channel (displacement, roughness, ...)
//! under its own name, each in the sample format it was read in.

use serde::{Deserialize, Serialize};

use super::{Exemplar, SampleFormat};

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
