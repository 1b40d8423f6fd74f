//! Feature maps: what the erosion of the 2021 method removes first.
//!
//! Gagnon et al. 2021, Sec. 5.2: a feature map `F_m` in `[0, 1]`, the same
//! size as the exemplar, drives the erosion test; low values are eroded
//! first. The paper uses height maps and leaves automatic feature maps as
//! future work. Here a map is either given by the user (any grey image; a
//! colour image is reduced to its Rec. 709 luminance `0.2126 R + 0.7152 G +
//! 0.0722 B` of the stored values, alpha ignored), built in (the procedural
//! pebbles' own height), or derived from the exemplar ([`FeatureMethod`]):
//!
//! - **Luminance**: the exemplar's luminance, contrast-stretched so its 1st
//!   and 99th percentiles map to 0 and 1 (the erosion test normalises
//!   `sqrt(F_m + D)`, so an unstretched dull map would barely shape it).
//! - **DistanceTransform**: for textures of separate objects (stones,
//!   bricks, tiles). Luminance is smoothed (toroidal Gaussian) and split in
//!   two classes by Otsu's threshold. Which class holds the objects is
//!   decided by topology, not brightness: crevices and mortar form one
//!   network spanning the image, objects are separate pieces, so the class
//!   whose largest connected component holds the smaller share of it is the
//!   objects; when the shares are within 0.15 of each other, the *thicker*
//!   class (larger mean distance to the other) is. The
//!   exact Euclidean distance to the crevices (toroidal, so the map tiles) is
//!   divided per object by the object's own peak ([`objects`]), so every
//!   object's centre is 1 and every crevice 0: crevices erode first, then
//!   object rims, and whole objects survive longest.
//! - **Auto**: DistanceTransform when the smoothed luminance is clearly
//!   two-class — Otsu separability η ≥ [`DistanceParams::auto_separability`]
//!   (a uniform histogram gives 0.75, a Gaussian 0.64) and the objects are on
//!   average at least [`DistanceParams::auto_min_thickness`] texels thick —
//!   otherwise Luminance. [`FeatureOrigin::Derived`] records the method that
//!   was actually used.

pub mod blur;
pub mod edt;
pub mod objects;
pub mod otsu;

use std::path::PathBuf;

use super::ExemplarError;
use super::sampling::{Lattice, blend};
use crate::io::image_read::ImageError;
use crate::texture::Texture;

/// How a feature map is derived when none is given.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum FeatureMethod {
    /// Contrast-stretched luminance.
    Luminance,
    /// Per-object normalised distance to the crevices.
    DistanceTransform,
    /// DistanceTransform for two-class images, Luminance otherwise.
    #[default]
    Auto,
}

crate::named!(FeatureMethod {
    Auto => "auto",
    Luminance => "luminance",
    DistanceTransform => "distance",
});

/// Where a feature map came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FeatureOrigin {
    /// Read from this file.
    Given(PathBuf),
    /// Derived from the exemplar with this method (never `Auto`: the method
    /// `Auto` chose).
    Derived(FeatureMethod),
    /// The procedural exemplar's own height map.
    Builtin,
}

/// A one-channel feature map `F_m ∈ [0, 1]` (2021 paper, Sec. 5.2), the same
/// size as the exemplar it belongs to.
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureMap {
    /// One channel, values in `[0, 1]`.
    pub map: Texture,
    pub origin: FeatureOrigin,
}

/// [`FeatureMap::sample`] with its set-up hoisted out of the loop.
#[derive(Clone, Copy, Debug)]
pub struct FeatureSampler<'a> {
    lattice: Lattice,
    data: &'a [f32],
    stride: usize,
}

impl FeatureSampler<'_> {
    /// `F_m(u, v)`: bilinear, repeating.
    #[inline]
    pub fn sample(&self, u: f32, v: f32) -> f32 {
        let mut out = [0.0];
        blend(
            self.data,
            self.stride,
            &self.lattice.footprint(u, v),
            &mut out,
        );
        out[0]
    }
}

impl FeatureMap {
    /// Checks the map: non-empty, finite, one channel, values in `[0, 1]`.
    /// `what` names it in errors (a file name, or a description).
    pub fn new(
        map: Texture,
        origin: FeatureOrigin,
        what: &str,
    ) -> Result<FeatureMap, ExemplarError> {
        check_map(&map, what)?;
        Ok(FeatureMap { map, origin })
    }

    /// `F_m(u, v)`: bilinear, repeating ([`crate::texture::Wrap::Repeat`]).
    #[inline]
    pub fn sample(&self, u: f32, v: f32) -> f32 {
        self.sampler().sample(u, v)
    }

    /// A sampler with the lattice arithmetic set up once, for loops that
    /// sample the map per texel (the lapped fill).
    pub fn sampler(&self) -> FeatureSampler<'_> {
        FeatureSampler {
            lattice: Lattice::new(self.map.width, self.map.height),
            data: &self.map.data,
            stride: self.map.channels.max(1),
        }
    }

    /// The normaliser of the erosion test (2021 paper, Sec. 5.2):
    /// `max over texel centres (s, t) of sqrt(F_m(s, t) + D(s, t))`, with
    /// `D(s, t) = max(0, 1 − ‖(0.5, 0.5) − (s, t)‖ / 0.5)`. A constant of the
    /// map: compute it once per exemplar.
    pub fn erosion_normaliser(&self) -> f32 {
        self.erosion_normaliser_with_reach(0.5)
    }

    /// [`FeatureMap::erosion_normaliser`] for a D that reaches 0 at uv
    /// distance `reach` from the centre instead of 0.5 (the erosion
    /// method's footprint falloff).
    pub fn erosion_normaliser_with_reach(&self, reach: f32) -> f32 {
        let (w, h) = (self.map.width as usize, self.map.height as usize);
        let c = self.map.channels.max(1);
        let inv_reach = 1.0 / reach;
        let mut best = 0.0f32;
        for y in 0..h {
            let t = (y as f32 + 0.5) / h as f32;
            for x in 0..w {
                let s = (x as f32 + 0.5) / w as f32;
                let d = (1.0 - ((s - 0.5).powi(2) + (t - 0.5).powi(2)).sqrt() * inv_reach).max(0.0);
                let f = self.map.data.get((y * w + x) * c).copied().unwrap_or(0.0);
                best = best.max((f + d).sqrt());
            }
        }
        best
    }
}

/// Checks a feature map texture: one channel, non-empty, values in `[0, 1]`.
pub(crate) fn check_map(map: &Texture, what: &str) -> Result<(), ExemplarError> {
    if map.channels != 1 {
        return Err(ExemplarError::FeatureChannels {
            what: what.to_owned(),
            channels: map.channels,
        });
    }
    if map.data.len() != map.texel_count() {
        return Err(ExemplarError::Layout {
            what: what.to_owned(),
            reason: format!(
                "{}x{} with 1 channel holds {} values",
                map.width,
                map.height,
                map.data.len()
            ),
        });
    }
    crate::io::image_read::check(map, what)?;
    if let Some(i) = map.data.iter().position(|v| !(0.0..=1.0).contains(v)) {
        let w = map.width as usize;
        return Err(ExemplarError::FeatureRange {
            what: what.to_owned(),
            x: (i % w) as u32,
            y: (i / w) as u32,
            value: map.data[i],
        });
    }
    Ok(())
}

/// Parameters of the derived feature maps. Defaults suit exemplars whose
/// objects are 10–100 texels across.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistanceParams {
    /// Standard deviation of the Gaussian applied to the luminance before
    /// thresholding, texels. Removes texture inside objects so they do not
    /// break into pieces. Default 1.5; range `[0, 64]`.
    pub blur_sigma: f32,
    /// A distance peak is an object of its own only if it rises above the
    /// neck joining it to a higher peak by more than
    /// `max(min_prominence, relative_prominence · peak)`. Texels; default 1.5.
    pub min_prominence: f32,
    /// See `min_prominence`. Default 0.3; range `[0, 1]`.
    pub relative_prominence: f32,
    /// Auto: smallest Otsu separability η that counts as two-class.
    /// Default 0.8 (above a uniform histogram's 0.75); range `[0, 1]`.
    pub auto_separability: f32,
    /// Auto: smallest mean distance (texels) from an object texel to the
    /// crevices for the objects to count as objects. Default 2.
    pub auto_min_thickness: f32,
}

impl Default for DistanceParams {
    fn default() -> Self {
        DistanceParams {
            blur_sigma: 1.5,
            min_prominence: 1.5,
            relative_prominence: 0.3,
            auto_separability: 0.8,
            auto_min_thickness: 2.0,
        }
    }
}

impl DistanceParams {
    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), ExemplarError> {
        let fields = [
            ("blur_sigma", self.blur_sigma, 0.0, 64.0),
            ("min_prominence", self.min_prominence, 0.0, 1e6),
            ("relative_prominence", self.relative_prominence, 0.0, 1.0),
            ("auto_separability", self.auto_separability, 0.0, 1.0),
            ("auto_min_thickness", self.auto_min_thickness, 0.0, 1e6),
        ];
        for (name, value, min, max) in fields {
            if !(min..=max).contains(&value) {
                return Err(ExemplarError::InvalidParameter {
                    name,
                    value,
                    min,
                    max,
                });
            }
        }
        Ok(())
    }
}

/// Rec. 709 luminance of the stored values (alpha ignored); a 1-channel
/// texture is returned as is.
pub fn luminance(t: &Texture) -> Vec<f32> {
    match t.channels {
        0 => Vec::new(),
        1 => t.data.clone(),
        2 => t.data.chunks_exact(2).map(|p| p[0]).collect(),
        c => t
            .data
            .chunks_exact(c)
            .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
            .collect(),
    }
}

/// What a derivation produced, with the statistics that chose it.
#[derive(Clone, Debug, PartialEq)]
pub struct Derived {
    pub map: FeatureMap,
    /// Otsu separability η of the smoothed luminance (0 when constant).
    pub separability: f32,
    /// Mean distance from an object texel to the crevices, texels (0 when
    /// the distance transform was not computed or found no objects).
    pub thickness: f32,
}

/// Derives a feature map from an exemplar's colour texture.
pub fn derive(
    colour: &Texture,
    method: FeatureMethod,
    params: &DistanceParams,
) -> Result<Derived, ExemplarError> {
    params.validate()?;
    crate::io::image_read::check(colour, "colour texture")?;
    let (w, h) = (colour.width as usize, colour.height as usize);
    let lum = luminance(colour);
    let stretched = || stretch(&lum);
    let make = |data: Vec<f32>, m: FeatureMethod| {
        Texture::from_data(colour.width, colour.height, 1, data)
            .map(|map| FeatureMap {
                map,
                origin: FeatureOrigin::Derived(m),
            })
            .map_err(|e| {
                ExemplarError::Image(ImageError::Decode {
                    what: "derived feature map".into(),
                    reason: e.to_string(),
                })
            })
    };
    if method == FeatureMethod::Luminance {
        return Ok(Derived {
            map: make(stretched(), FeatureMethod::Luminance)?,
            separability: 0.0,
            thickness: 0.0,
        });
    }
    let smooth = blur::gaussian_wrap(&lum, w, h, params.blur_sigma);
    let split = otsu::otsu(&smooth);
    let dt = split.and_then(|o| distance_objects(&smooth, w, h, o.threshold));
    let separability = split.map_or(0.0, |o| o.separability);
    let thickness = dt.as_ref().map_or(0.0, |d| d.thickness);
    let use_dt = match method {
        FeatureMethod::DistanceTransform => dt.is_some(),
        _ => {
            dt.is_some()
                && separability >= params.auto_separability
                && thickness >= params.auto_min_thickness
        }
    };
    let map = match dt {
        Some(d) if use_dt => {
            let prominence = objects::Prominence {
                min: params.min_prominence,
                relative: params.relative_prominence,
            };
            let f = objects::normalise_per_object(&d.distance, w, h, prominence);
            make(f, FeatureMethod::DistanceTransform)?
        }
        // A constant image or one class only: nothing to measure distances
        // to, so luminance is the only honest answer.
        _ => make(stretched(), FeatureMethod::Luminance)?,
    };
    Ok(Derived {
        map,
        separability,
        thickness,
    })
}

/// The distance from object texels to the crevices and the objects' mean
/// thickness; `None` when one class is empty.
struct Objects {
    distance: Vec<f32>,
    thickness: f32,
}

/// Shares of the largest component closer than this are no evidence of
/// which class is the network; thickness decides then.
const NETWORK_MARGIN: f32 = 0.15;

fn distance_objects(smooth: &[f32], w: usize, h: usize, threshold: f32) -> Option<Objects> {
    let upper: Vec<bool> = smooth.iter().map(|&v| v > threshold).collect();
    let lower: Vec<bool> = upper.iter().map(|&b| !b).collect();
    // Distance of upper-class texels to the lower class, and vice versa.
    let d_upper = edt::squared_distance_wrap(&lower, w, h);
    let d_lower = edt::squared_distance_wrap(&upper, w, h);
    let mean = |d: &[f64], class: &[bool]| {
        let (sum, n) = d
            .iter()
            .zip(class)
            .filter(|(_, c)| **c)
            .fold((0.0f64, 0usize), |(s, n), (d, _)| (s + d.sqrt(), n + 1));
        (n > 0).then(|| sum / n as f64)
    };
    let (mu, ml) = (mean(&d_upper, &upper)?, mean(&d_lower, &lower)?);
    if !(mu.is_finite() && ml.is_finite()) {
        return None;
    }
    // The crevices are the class that forms one spanning network; when
    // both or neither do, the objects are the thicker class.
    let share_upper = objects::largest_component_share(&upper, w, h);
    let share_lower = objects::largest_component_share(&lower, w, h);
    let upper_are_objects = if (share_upper - share_lower).abs() > NETWORK_MARGIN {
        share_upper < share_lower
    } else {
        mu >= ml
    };
    let (d, thickness) = if upper_are_objects {
        (d_upper, mu)
    } else {
        (d_lower, ml)
    };
    Some(Objects {
        distance: d.iter().map(|&x| x.sqrt() as f32).collect(),
        thickness: thickness as f32,
    })
}

/// Maps the 1st and 99th percentiles to 0 and 1, clamping outside.
fn stretch(values: &[f32]) -> Vec<f32> {
    let mut sorted = values.to_vec();
    sorted.sort_by(f32::total_cmp);
    let at = |q: f32| {
        let i = ((sorted.len().saturating_sub(1)) as f32 * q).round() as usize;
        sorted.get(i).copied().unwrap_or(0.0)
    };
    let (lo, hi) = (at(0.01), at(0.99));
    if hi > lo {
        values
            .iter()
            .map(|&v| ((v - lo) / (hi - lo)).clamp(0.0, 1.0))
            .collect()
    } else {
        values.iter().map(|&v| v.clamp(0.0, 1.0)).collect()
    }
}
