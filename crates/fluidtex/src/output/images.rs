//! Atlases to files: the channels as the writer receives them (8-bit
//! channels as their PNG samples), PNG/EXR encoding of a channel, and the
//! debug images made from the per-texel patch ids (`source.F.exr`,
//! `patches.F.png`).

use std::io::Write;
use std::path::Path;

use rayon::prelude::*;

use crate::atlas::AtlasError;
use crate::exemplar::channels::ChannelFormat;
use crate::io::Staging;
use crate::io::image::{ExrOptions, ExrSample, PngDepth, PngOptions};
use crate::methods::{SOURCE_OUTSIDE, SOURCE_UNCOVERED};
use crate::texture::Texture;

use super::error::PipelineError;

/// One channel atlas on its way to the writer.
pub(crate) enum OutChannel {
    /// As the method made it.
    Float(Texture),
    /// The 8-bit samples of a [`ChannelFormat::Png8`] channel, quantized as
    /// the PNG encoder quantizes ([`crate::io::image::quantize_8`]): what
    /// the file and the coherence numbers read of it, a quarter of the
    /// floats' memory while the frame is written.
    Eight {
        width: u32,
        height: u32,
        channels: usize,
        samples: Vec<u8>,
    },
}

impl OutChannel {
    /// The float atlas, where the channel still has it.
    pub(super) fn float(&self) -> Option<&Texture> {
        match self {
            OutChannel::Float(t) => Some(t),
            OutChannel::Eight { .. } => None,
        }
    }

    /// Components per texel.
    pub(super) fn channels(&self) -> usize {
        match self {
            OutChannel::Float(t) => t.channels,
            OutChannel::Eight { channels, .. } => *channels,
        }
    }

    /// Texels held (values ÷ components).
    pub(super) fn texels(&self) -> usize {
        match self {
            OutChannel::Float(t) => t.data.len() / t.channels.max(1),
            OutChannel::Eight {
                channels, samples, ..
            } => samples.len() / (*channels).max(1),
        }
    }
}

/// The channels as the writer takes them: with `eight`, each 8-bit PNG
/// channel that the encoder can take becomes its samples (in parallel,
/// on the computing thread), and the first such channel's floats come back
/// for the method to fill again (with a colour-only exemplar they are the
/// fill's own values buffer); the others stay floats.
pub(super) fn written_channels(
    channels: Vec<Texture>,
    formats: &[ChannelFormat],
    eight: bool,
) -> (Vec<OutChannel>, Option<Vec<f32>>) {
    let mut spent = None;
    let out = channels
        .into_iter()
        .enumerate()
        .map(|(k, t)| {
            let quantizable = eight
                && formats.get(k) == Some(&ChannelFormat::Png8)
                && crate::io::image::encodable(&t);
            if !quantizable {
                return OutChannel::Float(t);
            }
            let channel = OutChannel::Eight {
                width: t.width,
                height: t.height,
                channels: t.channels,
                samples: crate::io::image::quantize_8_all(&t.data),
            };
            if spent.is_none() {
                spent = Some(t.data);
            }
            channel
        })
        .collect();
    (out, spent)
}

pub(super) fn write_file(
    files: &mut Staging<'_>,
    path: &Path,
    bytes: &[u8],
) -> Result<(), PipelineError> {
    files.write(path, |w| w.write_all(bytes))?;
    Ok(())
}

/// The patch colours of every texel, dilated into the gutter.
pub(super) fn patch_colours(
    atlas: &crate::atlas::Atlas,
    source: &[u32],
    radius: u32,
) -> Result<Texture, AtlasError> {
    let mut colours = Texture::filled(atlas.width, atlas.height, 3, 0.0);
    colours
        .data
        .par_chunks_mut(3)
        .zip(source.par_iter())
        .with_min_len(1 << 14)
        .for_each(|(c, &s)| c.copy_from_slice(&patch_colour(s)));
    atlas.dilate(&mut colours, radius)?;
    Ok(colours)
}

/// `patches.F.png` without a float colour atlas: the ids are dilated as
/// ids (dilation copies the nearest chart texel's value, so dilating ids
/// and then colouring them is dilating the colours) and each strip of the
/// PNG encoder colours its own rows straight to 8 bits. The same bytes as
/// encoding [`patch_colours`], holding one id per texel instead of twelve
/// bytes of colour. The ids are dilated where they are (the frame's last
/// use of them), not in a copy: 151 MB of fresh pages at 6144².
pub(super) fn patch_png(
    atlas: &crate::atlas::Atlas,
    mut ids: Vec<u32>,
    radius: u32,
) -> Result<Vec<u8>, String> {
    atlas
        .dilate_ids(&mut ids, radius)
        .map_err(|e| e.to_string())?;
    let width = atlas.width as usize;
    let compression = PngOptions::default().compression;
    crate::io::image::encode_png_8_rows(atlas.width, atlas.height, 3, compression, |y, rgb| {
        // Ids come in runs along a row: one hash per run.
        let mut last: Option<(u32, [u8; 3])> = None;
        for (out, &id) in rgb.chunks_exact_mut(3).zip(&ids[y * width..][..width]) {
            let colour = match last {
                Some((l, c)) if l == id => c,
                _ => {
                    let c = patch_colour(id).map(crate::io::image::quantize_8);
                    last = Some((id, c));
                    c
                }
            };
            out.copy_from_slice(&colour);
        }
    })
}

/// A colour per patch id for `patches.F.png` (the paper's Fig. 1, left):
/// outside charts black, uncovered magenta, patches hashed to bright colours.
pub fn patch_colour(source: u32) -> [f32; 3] {
    match source {
        SOURCE_OUTSIDE => [0.0, 0.0, 0.0],
        SOURCE_UNCOVERED => [1.0, 0.0, 1.0],
        s => {
            let h = crate::seed::mix(0x5eed, 3, s as u64);
            let c = |k: u32| 0.25 + 0.7 * (((h >> (k * 16)) & 0xffff) as f32 / 65535.0);
            [c(0), c(1), c(2)]
        }
    }
}

/// `source.F.exr`: each texel's source patch id as a float, -1 outside
/// the charts; hands the ids back.
///
/// The ids become floats in their own buffer and turn back into the same
/// ids once the file is written: every id below 2^24 is an integer an f32
/// holds exactly. That saves a second atlas-sized buffer at the frame's
/// peak of memory (151 MB at 6144²). Ids from 2^24 up (16.7 million
/// patches: never met) take a float copy instead.
pub(super) fn write_source_ids(
    files: &mut Staging<'_>,
    path: &Path,
    atlas: &crate::atlas::Atlas,
    source: Vec<u32>,
) -> Result<Vec<u32>, PipelineError> {
    const EXACT: u32 = 1 << 24;
    let as_float = |s: u32| if s == SOURCE_OUTSIDE { -1.0 } else { s as f32 };
    let texture = |data| Texture {
        width: atlas.width,
        height: atlas.height,
        channels: 1,
        data,
    };
    // Ids are constant over each patch's piece of a row, which zlib after
    // EXR's byte split and delta takes better than PIZ's wavelets: at
    // 6144² (a splash frame, 1,200 charts) 5.1 MB where PIZ took 9.4 MB,
    // for about the same CPU (1.1–1.5 s of one core either way, measured
    // alone and in a whole run).
    let options = ExrOptions {
        compression: crate::io::image::ExrCompression::Zip16,
        ..exr_channel_options()
    };
    let exact = source
        .par_iter()
        .with_min_len(1 << 16)
        .all(|&s| s < EXACT || s == SOURCE_OUTSIDE);
    if !exact {
        let ids = source
            .par_iter()
            .with_min_len(1 << 16)
            .map(|&s| as_float(s))
            .collect();
        crate::io::image::stage_exr_owned(files, path, texture(ids), &options)?;
        return Ok(source);
    }
    let mut ids: Vec<f32> = bytemuck::cast_vec(source);
    ids.par_iter_mut()
        .with_min_len(1 << 16)
        .for_each(|x| *x = as_float(x.to_bits()));
    let mut ids = crate::io::image::stage_exr_owned(files, path, texture(ids), &options)?.data;
    ids.par_iter_mut().with_min_len(1 << 16).for_each(|x| {
        let s = if *x < 0.0 { SOURCE_OUTSIDE } else { *x as u32 };
        *x = f32::from_bits(s);
    });
    Ok(bytemuck::cast_vec(ids))
}

/// How a channel in [`ChannelFormat::Exr`] is written: 32-bit floats.
fn exr_channel_options() -> ExrOptions {
    ExrOptions {
        sample: ExrSample::F32,
        ..Default::default()
    }
}

/// An encoder's message as the error of writing `path`.
pub(super) fn output_error(path: &Path) -> impl Fn(String) -> PipelineError + '_ {
    move |message| PipelineError::Output {
        path: path.to_path_buf(),
        message,
    }
}

/// [`write_channel`] of a channel as the writer receives it.
pub(super) fn write_out_channel(
    files: &mut Staging<'_>,
    path: &Path,
    channel: &OutChannel,
    format: ChannelFormat,
) -> Result<Option<Vec<u8>>, PipelineError> {
    match channel {
        OutChannel::Float(t) => write_channel(files, path, t, format),
        OutChannel::Eight {
            width,
            height,
            channels,
            samples,
        } => {
            // The same bytes as encoding the floats they were quantized from.
            let row = *width as usize * channels;
            let compression = PngOptions::default().compression;
            let bytes = crate::io::image::encode_png_8_rows(
                *width,
                *height,
                *channels,
                compression,
                |y, out| out.copy_from_slice(&samples[y * row..(y + 1) * row]),
            )
            .map_err(output_error(path))?;
            write_file(files, path, &bytes)?;
            Ok(Some(bytes))
        }
    }
}

/// Writes one channel atlas; returns the PNG bytes for PNG formats (the
/// glb embeds the colour atlas without encoding it twice).
pub(super) fn write_channel(
    files: &mut Staging<'_>,
    path: &Path,
    texture: &Texture,
    format: ChannelFormat,
) -> Result<Option<Vec<u8>>, PipelineError> {
    let depth = match format {
        ChannelFormat::Png8 => PngDepth::Eight,
        ChannelFormat::Png16 => PngDepth::Sixteen,
        ChannelFormat::Exr => {
            crate::io::image::stage_exr(files, path, texture, &exr_channel_options())?;
            return Ok(None);
        }
    };
    let options = PngOptions {
        depth,
        ..Default::default()
    };
    let bytes = crate::io::image::encode_png(texture, &options).map_err(output_error(path))?;
    write_file(files, path, &bytes)?;
    Ok(Some(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::{Atlas, AtlasParams, fixtures::icosphere};
    use rand::{Rng, SeedableRng};

    /// An 8-bit channel handed to the writer as its samples writes the
    /// bytes its floats would (values outside [0, 1] and NaN included), and
    /// its floats come back for the method; previews, other formats and
    /// textures no encoder takes stay floats.
    #[test]
    fn eight_bit_channels_write_the_bytes_of_their_floats() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let sizes = [(1, 1, 1), (7, 3, 3), (33, 17, 4), (64, 9, 2), (5, 40, 3)];
        for (k, &(width, height, channels)) in sizes.iter().enumerate() {
            let data = (0..width as usize * height as usize * channels)
                .map(|i| match i % 11 {
                    0 => f32::NAN,
                    1 => -0.3,
                    2 => 1.7,
                    _ => rng.random::<f32>(),
                })
                .collect();
            let t = Texture {
                width,
                height,
                channels,
                data,
            };
            let (handed, spent) = written_channels(vec![t.clone()], &[ChannelFormat::Png8], true);
            assert_eq!(spent.as_deref().map(bits), Some(bits(&t.data)), "{k}");
            let OutChannel::Eight { samples, .. } = &handed[0] else {
                panic!("{k}: an 8-bit channel is handed over as samples");
            };
            let want: Vec<u8> = t
                .data
                .iter()
                .map(|&x| crate::io::image::quantize_8(x))
                .collect();
            assert_eq!(samples, &want, "{k}");
            let mut files = Staging::new(None, None);
            let eight = dir.path().join(format!("eight{k}.png"));
            let float = dir.path().join(format!("float{k}.png"));
            let a = write_out_channel(&mut files, &eight, &handed[0], ChannelFormat::Png8)
                .expect("write");
            let b = write_channel(&mut files, &float, &t, ChannelFormat::Png8).expect("write");
            files.commit().expect("commit");
            assert!(a.is_some() && a == b, "{k}: same PNG bytes");
            assert_eq!(std::fs::read(&eight).ok(), b, "{k}: the file holds them");
        }
        let t = Texture {
            width: 4,
            height: 4,
            channels: 3,
            data: vec![0.5; 48],
        };
        let floats = |c: &[OutChannel]| c.iter().map(|c| c.float().is_some()).collect::<Vec<_>>();
        let (handed, spent) = written_channels(vec![t.clone()], &[ChannelFormat::Png8], false);
        assert_eq!(
            (floats(&handed), spent),
            (vec![true], None),
            "a preview frame"
        );
        let formats = [
            ChannelFormat::Png16,
            ChannelFormat::Exr,
            ChannelFormat::Png8,
        ];
        let (handed, spent) = written_channels(vec![t.clone(); 4], &formats, true);
        assert_eq!(floats(&handed), vec![true, true, false, true]);
        assert_eq!(spent.map(|v| v.len()), Some(48));
        let bad = Texture {
            channels: 5,
            data: vec![0.5; 80],
            ..t
        };
        let (handed, spent) = written_channels(vec![bad], &[ChannelFormat::Png8], true);
        assert_eq!((floats(&handed), spent), (vec![true], None), "5 channels");
    }

    /// `source.F.exr` holds each id as a float (-1 outside) and the ids come
    /// back unchanged, whether they went through the file in their own
    /// buffer or, with an id past 2^24, through a copy.
    #[test]
    fn source_ids_come_back_from_their_file() {
        let atlas = Atlas::build(&icosphere(2), &AtlasParams::square(16)).expect("atlas");
        let n = (atlas.width * atlas.height) as usize;
        let dir = tempfile::tempdir().expect("tempdir");
        let mut rng = rand_pcg::Pcg64::seed_from_u64(12);
        for big in [false, true] {
            let mut ids: Vec<u32> = (0..n).map(|_| rng.random_range(0..5000)).collect();
            ids[0] = SOURCE_OUTSIDE;
            ids[1] = SOURCE_UNCOVERED;
            ids[2] = (1 << 24) - 1;
            if big {
                ids[3] = (1 << 24) + 1;
            }
            let path = dir.path().join(format!("source{big}.exr"));
            let mut files = Staging::new(None, None);
            let back = write_source_ids(&mut files, &path, &atlas, ids.clone()).expect("write");
            files.commit().expect("commit");
            assert_eq!(back, ids, "big ids: {big}");
            let read = crate::io::image_read::read_image(&path).expect("read");
            assert_eq!(read.texture.data.len(), n);
            for (i, (&v, &id)) in read.texture.data.iter().zip(&ids).enumerate() {
                let want = if id == SOURCE_OUTSIDE {
                    -1.0
                } else {
                    id as f32
                };
                assert_eq!(v.to_bits(), want.to_bits(), "texel {i}, big ids: {big}");
            }
        }
    }

    /// `patches.F.png` made in 8 bits from the dilated ids is byte for byte
    /// the float colour atlas encoded as before (ids dilate as colours do),
    /// with outside, uncovered and large ids.
    #[test]
    fn patch_png_from_ids_is_the_colour_atlas_encoded() {
        let atlas = Atlas::build(&icosphere(2), &AtlasParams::square(96)).expect("atlas");
        let n = (atlas.width * atlas.height) as usize;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        let mut source: Vec<u32> = (0..n).map(|_| rng.random_range(0..500)).collect();
        // The chart texels keep their ids; the rest are outside.
        let inside = atlas.triangle_map();
        for (s, &t) in source.iter_mut().zip(&inside) {
            if t == u32::MAX {
                *s = SOURCE_OUTSIDE;
            }
        }
        let chart: Vec<usize> = (0..n).filter(|&i| inside[i] != u32::MAX).collect();
        assert!(chart.len() > 100, "{} chart texels", chart.len());
        source[chart[0]] = SOURCE_UNCOVERED;
        source[chart[1]] = (1 << 24) - 1;
        for radius in [1, 4] {
            let want = crate::io::image::encode_png(
                &patch_colours(&atlas, &source, radius).expect("dilate"),
                &PngOptions::default(),
            )
            .expect("encode");
            let got = patch_png(&atlas, source.clone(), radius).expect("encode");
            assert!(got == want, "radius {radius}: the bytes differ");
        }
        // Ids past 2^24 (not exact as floats) are coloured as themselves.
        source[chart[2]] = 1 << 24;
        source[chart[3]] = u32::MAX - 1;
        let want = crate::io::image::encode_png(
            &patch_colours(&atlas, &source, 3).expect("dilate"),
            &PngOptions::default(),
        )
        .expect("encode");
        assert!(patch_png(&atlas, source.clone(), 3).expect("encode") == want);
        assert!(
            patch_png(&atlas, source[1..].to_vec(), 3).is_err(),
            "one id short"
        );
    }
}
