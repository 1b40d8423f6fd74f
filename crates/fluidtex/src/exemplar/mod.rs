//! Texture exemplars: the colour image, extra channels driven by the same
//! patch selection (displacement, roughness, ...), and the feature map that
//! decides what the erosion removes first (Gagnon et al. 2021, Sec. 5.2).
//!
//! - [`Exemplar::load`] reads PNG, JPEG or EXR files ([`crate::io::image_read`]),
//!   grey or colour, 8/16-bit or float, any size; values are the stored ones
//!   scaled to `[0, 1]` for integer formats (no colour-space conversion, so
//!   an atlas written back in [`SampleFormat`] reproduces them).
//! - [`feature`] holds feature maps `F_m`, given or derived automatically
//!   ([`FeatureMethod`]), with [`FeatureMap::sample`] and the erosion test's
//!   normaliser [`FeatureMap::erosion_normaliser`].
//! - [`builtin_pebbles`] is a procedural, tileable pebble exemplar with its
//!   own height as feature map, for demos and tests without files.
//! - [`Exemplar::sample_all`] is the lookup of the lapped fill: every
//!   channel at one `(u, v)`, tiled ([`crate::texture::Wrap::Repeat`]), with
//!   the texel convention of [`crate::texture`].
//! - [`Exemplar::sample_all_lod`] reads the same channels through a mip
//!   pyramid ([`mip`], built once with the exemplar), trilinear, for atlas
//!   texels that show the exemplar minified; [`Exemplar::filter`] says
//!   whether methods use it ([`ExemplarFilter`]).
//! - [`set`]: several exemplars on one surface, with the patch's choice
//!   among them ([`ExemplarSet`], [`ExemplarSelect`]).
//! - [`sequence`]: animated exemplars, an image sequence whose frame each
//!   patch shows by its own phase ([`ExemplarClock`]), loaded within a
//!   memory budget stated up front, their pyramids built when first shown;
//!   [`bubbles`] is a procedural one.
//! - [`tone`]: the per-channel mean and per-level variance the sampler
//!   shows, the reference of the methods' tone matching.

pub mod bubbles;
pub mod channels;
pub mod feature;
pub mod lava;
pub mod mip;
pub mod pebbles;
mod sampling;
pub mod select_by;
pub mod sequence;
pub mod set;
pub mod tone;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use thiserror::Error;

pub use bubbles::builtin_bubbles;
pub use feature::{DistanceParams, FeatureMap, FeatureMethod, FeatureOrigin};
pub use lava::{LavaState, builtin_lava};
pub use mip::mip_levels;
pub use pebbles::builtin_pebbles;
pub use select_by::{AttributeRange, SelectBy};
pub use sequence::{ExemplarClock, SequenceBudget, SequenceFiles, is_sequence, load_sequence};
pub use set::{ExemplarSelect, ExemplarSet, RegionImage};

use crate::io::image_read::{self, ImageError};
pub use crate::io::image_read::{Decoded, SampleFormat};
use crate::texture::Texture;
use sampling::{Lattice, bilinear, blend, blend_levels, lerp};

/// How methods read the exemplar at an atlas texel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ExemplarFilter {
    /// Trilinear through the mip pyramid, at the level of the texel's uv
    /// footprint ([`crate::methods::footprint`]); bilinear where the
    /// exemplar is magnified. The default: a minified exemplar read at one
    /// point per texel aliases into noise that changes every frame.
    #[default]
    Trilinear,
    /// Bilinear at level 0 whatever the footprint (the lapped fill's own
    /// lookup, left as it is): sharper, and aliased where minified.
    Unfiltered,
}

crate::named!(ExemplarFilter {
    Trilinear => "trilinear",
    Unfiltered => "none",
});

/// An extra channel (displacement, roughness, ...) synthesised with the same
/// patch selection as the colour.
#[derive(Clone, Debug, PartialEq)]
pub struct ExtraChannel {
    pub name: String,
    /// Same width and height as the colour.
    pub texture: Texture,
    pub format: SampleFormat,
}

/// Errors reading or assembling an exemplar. `what` names the file (or the
/// in-memory texture) at fault.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ExemplarError {
    /// The image itself could not be read (see [`ImageError`]).
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error(
        "{what} is {width}x{height} but the colour exemplar {colour} is {colour_width}x{colour_height}; they must match"
    )]
    SizeMismatch {
        what: String,
        width: u32,
        height: u32,
        colour: String,
        colour_width: u32,
        colour_height: u32,
    },
    #[error("{what}: feature value {value} at texel ({x}, {y}) is outside [0, 1]")]
    FeatureRange {
        what: String,
        x: u32,
        y: u32,
        value: f32,
    },
    #[error("{what}: a feature map has 1 channel, got {channels}")]
    FeatureChannels { what: String, channels: usize },
    #[error("{what}: a texture has 1 to 4 channels and width*height*channels values: {reason}")]
    Layout { what: String, reason: String },
    #[error("extra channel name '{name}' is used twice")]
    DuplicateChannel { name: String },
    #[error("{what}: exemplar weight {value} must be a positive number")]
    Weight { what: String, value: f32 },
    #[error("{what} and {other} cannot share a surface: {reason}")]
    Mismatch {
        what: String,
        other: String,
        reason: String,
    },
    /// An animated exemplar's frame is missing or its pattern is wrong.
    #[error("{what}: {reason}")]
    Sequence { what: String, reason: String },
    #[error(
        "{what}: {frames} frames take {} (mip pyramids included){}, over the {} budget for \
         animated exemplars; use fewer or smaller frames, or raise --exemplar-memory",
        mib(*needed), if *used > 0 { format!(" besides {} for the sequences before it", mib(*used)) } else { String::new() },
        mib(*budget)
    )]
    Budget {
        what: String,
        frames: usize,
        needed: u64,
        used: u64,
        budget: u64,
    },
    #[error("{name} = {value} is outside [{min}, {max}]")]
    InvalidParameter {
        name: &'static str,
        value: f32,
        min: f32,
        max: f32,
    },
}

/// A texture exemplar with its extra channels and feature map.
///
/// The fields are public for reading. [`Exemplar::sample_all`] reads a
/// packed copy of all channels made by [`Exemplar::new`]; code that changes
/// a field afterwards must call [`Exemplar::repack`].
#[derive(Clone, Debug, PartialEq)]
pub struct Exemplar {
    /// Colour, 1 (grey), 3 or 4 channels; integer formats scaled to `[0, 1]`,
    /// no colour-space conversion.
    pub colour: Texture,
    /// How the colour was stored: how its atlas channel is written.
    pub colour_format: SampleFormat,
    /// Extra channels, in order; same size as `colour`.
    pub channels: Vec<ExtraChannel>,
    pub feature: FeatureMap,
    /// Whether methods filter minified lookups \[trilinear]. Chosen by the
    /// user at load (`--exemplar-filter`); it changes no texel of the
    /// exemplar, only which lookup the methods' post-pass makes.
    pub filter: ExemplarFilter,
    packed: Packed,
}

/// One level of the pyramid as a lookup reads it: its texels and lattice.
type LevelRef<'a> = (&'a [f32], Lattice);

/// All channels of a texel side by side (colour, then extras in order), so a
/// lookup reads four contiguous runs instead of four per texture.
#[derive(Clone, Debug, PartialEq)]
struct Packed {
    lattice: Lattice,
    stride: usize,
    data: Vec<f32>,
    /// Levels 1, 2, ... of the mip pyramid of `data` ([`mip`]): built with
    /// the exemplar, or on first use for the frames of an animated one
    /// ([`Exemplar::deferring_pyramid`]).
    mips: OnceLock<Vec<mip::Level>>,
    /// Number of coarse levels (known before they are built).
    levels: usize,
    /// Width and height of level 0.
    size: (u32, u32),
}

impl Packed {
    /// The pyramid, built here (one thread) if nobody built it yet: a
    /// lookup inside a parallel loop must not wait on a parallel build.
    #[inline(always)]
    fn mips(&self) -> &[mip::Level] {
        self.mips
            .get_or_init(|| mip::build_serial(&self.data, self.stride, self.size))
    }
}

impl Exemplar {
    /// Bytes the exemplar holds: its textures, the packed copy the lookups
    /// read and its mip pyramid (for the memory estimate).
    pub fn memory_bytes(&self) -> u64 {
        let floats = self.colour.data.len()
            + self
                .channels
                .iter()
                .map(|c| c.texture.data.len())
                .sum::<usize>()
            + self.feature.map.data.len()
            + self.packed.data.len();
        4 * floats as u64 + self.pyramid_bytes()
    }

    /// Bytes of the mip pyramid, built or not (about a third of the
    /// packed copy): what it holds once shown.
    pub fn pyramid_bytes(&self) -> u64 {
        let (mut w, mut h) = self.packed.size;
        let mut floats = 0u64;
        while w > 1 || h > 1 {
            (w, h) = ((w / 2).max(1), (h / 2).max(1));
            floats += u64::from(w) * u64::from(h) * self.packed.stride as u64;
        }
        4 * floats
    }

    /// Whether the mip pyramid is built (always, except for an exemplar
    /// made by [`Exemplar::deferring_pyramid`] and not yet read filtered).
    pub fn pyramid_built(&self) -> bool {
        self.packed.mips.get().is_some()
    }

    /// Builds the mip pyramid now if it is not built, in parallel. Call it
    /// outside parallel loops (the lookups build a missing one on one
    /// thread, as a fallback).
    pub fn build_pyramid(&self) {
        let p = &self.packed;
        p.mips
            .get_or_init(|| mip::build(&p.data, p.stride, p.size.0, p.size.1));
    }

    /// The same exemplar with its mip pyramid dropped, to be built when it
    /// is first read filtered ([`Exemplar::build_pyramid`]): the frames of
    /// an animated exemplar, most of which a short run never shows.
    pub fn deferring_pyramid(mut self) -> Exemplar {
        self.packed.mips = OnceLock::new();
        self
    }

    /// Assembles an exemplar, checking that every texture is non-empty,
    /// finite, well formed and the size of `colour`, that channel names are
    /// unique, and that the feature map is valid.
    pub fn new(
        colour: Texture,
        colour_format: SampleFormat,
        channels: Vec<ExtraChannel>,
        feature: FeatureMap,
    ) -> Result<Exemplar, ExemplarError> {
        let mut e = Exemplar::assemble(colour, colour_format, channels, feature);
        e.repack()?;
        Ok(e)
    }

    /// Packs without validating: for generators whose output is valid by
    /// construction. Texels missing from a malformed texture read as 0.
    pub(crate) fn assemble(
        colour: Texture,
        colour_format: SampleFormat,
        channels: Vec<ExtraChannel>,
        feature: FeatureMap,
    ) -> Exemplar {
        let mut e = Exemplar {
            colour,
            colour_format,
            channels,
            feature,
            filter: ExemplarFilter::default(),
            packed: Packed {
                lattice: Lattice::new(1, 1),
                stride: 0,
                data: Vec::new(),
                mips: OnceLock::new(),
                levels: 0,
                size: (1, 1),
            },
        };
        e.pack();
        e
    }

    /// Re-validates the fields and rebuilds the packed copy that
    /// [`Exemplar::sample_all`] reads.
    pub fn repack(&mut self) -> Result<(), ExemplarError> {
        let colour_name = "colour texture";
        well_formed(&self.colour, colour_name)?;
        image_read::check(&self.colour, colour_name)?;
        let (w, h) = (self.colour.width, self.colour.height);
        let mismatch = |what: String, t: &Texture| ExemplarError::SizeMismatch {
            what,
            width: t.width,
            height: t.height,
            colour: colour_name.to_owned(),
            colour_width: w,
            colour_height: h,
        };
        for (i, c) in self.channels.iter().enumerate() {
            let what = format!("extra channel '{}'", c.name);
            well_formed(&c.texture, &what)?;
            image_read::check(&c.texture, &what)?;
            if (c.texture.width, c.texture.height) != (w, h) {
                return Err(mismatch(what, &c.texture));
            }
            if self.channels[..i].iter().any(|o| o.name == c.name) {
                return Err(ExemplarError::DuplicateChannel {
                    name: c.name.clone(),
                });
            }
        }
        feature::check_map(&self.feature.map, "feature map")?;
        if (self.feature.map.width, self.feature.map.height) != (w, h) {
            return Err(mismatch("feature map".into(), &self.feature.map));
        }
        self.pack();
        Ok(())
    }

    fn pack(&mut self) {
        let textures: Vec<&Texture> = std::iter::once(&self.colour)
            .chain(self.channels.iter().map(|c| &c.texture))
            .collect();
        let stride: usize = textures.iter().map(|t| t.channels).sum();
        let mut data = Vec::with_capacity(stride * self.colour.texel_count());
        for i in 0..self.colour.texel_count() {
            for t in &textures {
                match t.data.get(i * t.channels..(i + 1) * t.channels) {
                    Some(texel) => data.extend_from_slice(texel),
                    None => data.extend(std::iter::repeat_n(0.0, t.channels)),
                }
            }
        }
        let (w, h) = (self.colour.width, self.colour.height);
        let mips = mip::build(&data, stride, w, h);
        self.packed = Packed {
            lattice: Lattice::new(w, h),
            stride,
            levels: mips.len(),
            size: (w, h),
            mips: OnceLock::from(mips),
            data,
        };
    }

    /// Loads an exemplar: the colour image, extra channels `(name, path)` in
    /// order, and a feature map read from `feature` or, when `None`, derived
    /// from the colour with `derive` (default [`DistanceParams`];
    /// [`feature::derive`] takes others). A feature map file with
    /// more than one channel is reduced to its Rec. 709 luminance; its values
    /// must lie in `[0, 1]`. Errors name the file at fault.
    pub fn load(
        colour: &Path,
        channels: &[(String, PathBuf)],
        feature: Option<&Path>,
        derive: FeatureMethod,
    ) -> Result<Exemplar, ExemplarError> {
        let main = image_read::read_image(colour)?;
        let (w, h) = (main.texture.width, main.texture.height);
        let check_size = |path: &Path, t: &Texture| {
            if (t.width, t.height) == (w, h) {
                Ok(())
            } else {
                Err(ExemplarError::SizeMismatch {
                    what: path.display().to_string(),
                    width: t.width,
                    height: t.height,
                    colour: colour.display().to_string(),
                    colour_width: w,
                    colour_height: h,
                })
            }
        };
        let mut extras = Vec::with_capacity(channels.len());
        for (name, path) in channels {
            let d = image_read::read_image(path)?;
            check_size(path, &d.texture)?;
            extras.push(ExtraChannel {
                name: name.clone(),
                texture: d.texture,
                format: d.format,
            });
        }
        let feature = match feature {
            Some(path) => {
                let d = image_read::read_image(path)?;
                check_size(path, &d.texture)?;
                let grey = Texture {
                    width: d.texture.width,
                    height: d.texture.height,
                    channels: 1,
                    data: feature::luminance(&d.texture),
                };
                FeatureMap::new(
                    grey,
                    FeatureOrigin::Given(path.to_path_buf()),
                    &path.display().to_string(),
                )?
            }
            None => feature::derive(&main.texture, derive, &DistanceParams::default())?.map,
        };
        Exemplar::new(main.texture, main.format, extras, feature)
    }

    /// Every channel (colour, then extras in order) at `(u, v)`: bilinear,
    /// repeating. Writes `min(out.len(), total_channels())` values; pass a
    /// buffer of [`Exemplar::total_channels`].
    #[inline]
    pub fn sample_all(&self, u: f32, v: f32, out: &mut [f32]) {
        let p = &self.packed;
        blend(&p.data, p.stride, &p.lattice.footprint(u, v), out);
    }

    /// Every channel at `(u, v)` filtered to mip level `lod` (0: the
    /// exemplar; each level halves the resolution): trilinear between the
    /// two levels around `lod`, bilinear and repeating within each.
    /// `lod` ≤ 0 (or NaN) is exactly [`Exemplar::sample_all`]; `lod` above
    /// [`Exemplar::max_lod`] reads the 1 × 1 level, the exemplar's mean.
    #[inline]
    pub fn sample_all_lod(&self, u: f32, v: f32, lod: f32, out: &mut [f32]) {
        let stride = self.packed.stride;
        let ((fine, fine_lattice), coarse) = self.levels_at(lod);
        let f = fine_lattice.footprint(u, v);
        match coarse {
            None => blend(fine, stride, &f, out),
            Some(((coarse, coarse_lattice), t)) => {
                let c = coarse_lattice.footprint(u, v);
                blend_levels((fine, &f), (coarse, &c), stride, t, out);
            }
        }
    }

    /// [`Exemplar::sample_all_lod`] of an exemplar of exactly `N` channels
    /// ([`Exemplar::total_channels`]; `None` for any other count), returned
    /// by value. The values are the same bit for bit; with the channel
    /// count known at compile time a caller's loop over texels inlines the
    /// whole lookup instead of calling a function that dispatches on the
    /// count for every texel.
    #[inline(always)]
    pub(crate) fn sample_lod_fixed<const N: usize>(
        &self,
        u: f32,
        v: f32,
        lod: f32,
    ) -> Option<[f32; N]> {
        if self.packed.stride != N {
            return None;
        }
        let ((fine, fine_lattice), coarse) = self.levels_at(lod);
        let a = bilinear::<N>(fine, &fine_lattice.footprint(u, v));
        Some(match coarse {
            None => a,
            Some(((coarse, coarse_lattice), t)) => {
                lerp(a, bilinear::<N>(coarse, &coarse_lattice.footprint(u, v)), t)
            }
        })
    }

    /// Where a lookup at `lod` reads: the level at or below it, and the
    /// level above with its weight unless `lod` is a whole level (level 0
    /// for `lod` ≤ 0 or NaN, the 1 × 1 level past [`Exemplar::max_lod`]).
    #[inline(always)]
    fn levels_at(&self, lod: f32) -> (LevelRef<'_>, Option<(LevelRef<'_>, f32)>) {
        let p = &self.packed;
        if lod.is_nan() || lod <= 0.0 || p.levels == 0 {
            return ((&p.data, p.lattice), None);
        }
        let mips = p.mips();
        let lod = lod.min(mips.len() as f32);
        // `lod` is positive and at most the level count: the cast floors.
        let k = lod as usize;
        let t = lod - k as f32;
        let level = |k: usize| match k.checked_sub(1).and_then(|i| mips.get(i)) {
            Some(l) => (l.data.as_slice(), l.lattice),
            None => (p.data.as_slice(), p.lattice),
        };
        let coarse = (t != 0.0 && k != mips.len()).then(|| (level(k + 1), t));
        (level(k), coarse)
    }

    /// The coarsest mip level (1 × 1): the largest useful `lod`.
    #[inline]
    pub fn max_lod(&self) -> f32 {
        self.packed.levels as f32
    }

    /// The exemplar with `filter` as its [`Exemplar::filter`].
    pub fn with_filter(mut self, filter: ExemplarFilter) -> Exemplar {
        self.filter = filter;
        self
    }

    /// Colour channels plus all extra channels.
    #[inline]
    pub fn total_channels(&self) -> usize {
        self.packed.stride
    }

    /// Width and height in texels.
    pub fn size(&self) -> (u32, u32) {
        (self.colour.width, self.colour.height)
    }
}

/// Bytes as MiB with one decimal, for messages.
fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / (1 << 20) as f64)
}

/// Texture invariants that [`Texture::from_data`] enforces but a struct
/// literal may not.
fn well_formed(t: &Texture, what: &str) -> Result<(), ExemplarError> {
    let expected = t.width as usize * t.height as usize * t.channels;
    if !(1..=4).contains(&t.channels) || t.data.len() != expected {
        return Err(ExemplarError::Layout {
            what: what.to_owned(),
            reason: format!(
                "{}x{} with {} channels holds {} values",
                t.width,
                t.height,
                t.channels,
                t.data.len()
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests;
