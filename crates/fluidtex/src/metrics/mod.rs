//! The measurements of `docs/evaluation.md`, each a pure function on plain
//! per-texel or per-pixel arrays, and the committed pass thresholds.
//!
//! The evaluation harness feeds these from atlases (per-texel provenance and
//! surface points) or from software renders with a G-buffer (per-pixel
//! provenance, 3-D point, projected true velocity). Nothing here knows about
//! methods, atlases or renderers: a metric takes slices, dimensions and the
//! exemplar, and returns numbers. Every metric has a known-good and a
//! known-bad control in the tests (docs/evaluation.md, rule 2).
//!
//! | metric | function | value per frame | over frames | pass |
//! | --- | --- | --- | --- | --- |
//! | coverage | [`coverage()`] | share of chart texels with no source | worst | `= 0` |
//! | ghost fraction | [`ghosting()`] | share of chart texels with ≥ 2 layers of weight ≥ 0.05 | worst | `= 0` |
//! | contrast ratio ρ | [`contrast_ratio`] | σ(output)/σ_ex of luminance (σ_ex of the mip levels shown: [`shown_sigma`]) | min | `≥ 0.90` |
//! | distortion | [`distortion()`] | area-weighted p95 of δ = max(σ₁/s₀, s₀/σ₂), s₀ the texel scale at the patch's creation (σ₁/σ₂ beside it, for information) | worst | `≤ 3` |
//! | exemplar fidelity | [`FidelityReference::measure`] | mean over levels of SWD(output, exemplar)/SWD(half, half) | worst | `≤ 2.5` |
//! | flow fidelity | [`provenance_motion`] (or [`image_motion`]), then [`compare_motion`] | median EPE (px), share with cos > 0.9 | median | `≤ 0.25 px`, `≥ 90%` |
//! | popping | [`popping()`] | share with \|I₁ − warp(I₀)\| > 0.5 σ_ex | mean and worst | `≤ 2%`, `≤ 5%` |
//! | source switch share | [`source_switch()`] | share of points carried by the flow, with a patch at both ends, whose patch changed | every frame against the floor method's same frame | `≤ advect + 0.02` |
//! | colour follow ratio | [`colour_follow()`] | median \|c₁(carried) − c₀\| ÷ median \|c₁(unmoved) − c₀\| over points moving ≥ 3 texels | worst | `≤ 0.5` |
//! | static stop | [`StaticStop`] | frames after the stop that differ from the first still frame | — | `= 0` |
//! | exemplar-size cost | [`size_cost_ratio`] | time(2048²)/time(256²) | — | `≤ 1.15` |
//!
//! The thresholds and the settings each metric is measured with (search
//! window, patch counts, silhouette margin, ...) live in one committed file,
//! `metrics/thresholds.toml`, read by [`Thresholds::committed`]. They were
//! written before any method was run and are never tuned per method.
//!
//! **Conventions shared by all metrics.**
//! - Arrays are row-major, `index = y * width + x`, texel/pixel centres at
//!   `+0.5` (the [`crate::texture`] convention).
//! - Provenance: [`SOURCE_OUTSIDE`] (`u32::MAX`) is a texel outside every
//!   chart or a background pixel, [`SOURCE_UNCOVERED`] (`0`) a chart texel
//!   that no patch reached, `k + 1` patch `k`. These are the values
//!   `crate::methods` writes; they are repeated here so that metrics depend
//!   on no method code.
//! - Exemplar uv are normalised (`[0, 1)²` spans the exemplar once), NaN
//!   where there is no source. Differences of uv between neighbours are taken
//!   modulo 1 (the nearest of the periodic images), so a method may wrap uv
//!   into `[0, 1)` without creating false jumps; this assumes neighbouring
//!   texels are less than half an exemplar apart.
//! - Grey values: colour is reduced to Rec. 709 luminance
//!   `0.2126 R + 0.7152 G + 0.0722 B` of the stored values; one channel is
//!   itself; a second channel (grey + alpha) and a fourth (RGB + alpha) are
//!   ignored. See [`luminance`].
//! - A frame in which a metric has nothing to measure (an empty mask) gives
//!   NaN; [`Thresholds::summarize`] skips such frames and says so, and a
//!   summary of no frames at all is [`Verdict::NoData`], never a pass.
//!
//! **What the harness must supply** (details in each function's doc).
//! - Atlases: `source`, `uv`, per-texel surface `points` (NaN outside
//!   charts); chart ids where charts may touch without a gutter. For
//!   distortion, s₀: exemplar texels per world unit at the patches'
//!   creation (exemplar width / S for a method whose exemplar covers S
//!   world units).
//! - Renders (flow and popping are measured on renders only: the atlas is
//!   unwrapped anew every frame, so texel (x, y) of two frames are
//!   unrelated): a foreground mask and depth for [`interior_mask`]; per
//!   pixel the *true motion* over the frame in pixels. Prefer the exact
//!   displacement of the surface point seen at the pixel (trace it through
//!   the scene's velocity field over the frame and project both ends) to
//!   docs/evaluation.md's velocity × frame time: on curved paths the two differ by
//!   O(dt²), 0.12 px median in the vortex control, which is half the flow
//!   threshold and is charged to the method. Popping needs the same motion
//!   backwards (per pixel of frame t+1, from its position at frame t).
//! - Source switch and colour follow: per sample point of frame t, its
//!   source and grey value there, and at frame t+1 the source and grey
//!   value at the point carried by the flow and the grey value at the same
//!   point not moved, plus the distance moved in atlas texels. These are
//!   two-frame metrics on *points*, not texels (the atlas is unwrapped anew
//!   every frame); [`crate::coherence`] samples, carries and looks them up
//!   on atlases. The switch share's pass rule is relative: the report
//!   compares each frame with the floor method (`advect`) on the same
//!   scene and frames ([`Thresholds::summarize_against_floor`]).
//! - Fidelity: the output at the exemplar's texel scale. Where the output
//!   shows `s` exemplar texels per output texel
//!   ([`Distortion::exemplar_texels_per_texel`]), build the
//!   [`FidelityReference`] from `rescale(exemplar, 1/s)`, once per sequence.

mod colour_follow;
mod contrast;
mod coverage;
mod distortion;
mod fidelity;
mod flow;
mod image_flow;
mod luma;
mod mask;
mod popping;
mod source_switch;
mod stop;
mod thresholds;

#[cfg(test)]
mod controls;

use thiserror::Error;

pub use colour_follow::{ColourFollow, colour_follow};
pub use contrast::{contrast_ratio, exemplar_sigma, exemplar_sigma_by_lod, shown_sigma};
pub use coverage::{Coverage, Ghosting, coverage, ghosting, layers_from_weights};
pub use distortion::{Distortion, SurfaceSamples, anisotropy_map, distortion};
pub use fidelity::{
    Fidelity, FidelityReference, SwdSettings, exemplar_fidelity, rescale, sliced_wasserstein,
};
pub use flow::{FlowStats, Motion, ProvenanceFrame, compare_motion, provenance_motion};
pub use image_flow::image_motion;
pub use luma::luminance;
pub use mask::{chart_mask, interior_mask};
pub use popping::{Popping, popping};
pub use source_switch::{
    SourceSwitch, SwitchCauses, is_patch, source_switch, source_switch_same_points, switch_causes,
};
pub use stop::{StaticStop, bit_identical, size_cost_ratio};
pub use thresholds::{
    ColourFollowThresholds, ContrastThresholds, CoverageThresholds, DistortionThresholds,
    FidelityThresholds, FlowThresholds, GhostingThresholds, Metric, PoppingThresholds,
    SilhouetteSettings, SizeCostThresholds, SourceSwitchThresholds, StaticStopThresholds, Summary,
    Thresholds, Verdict, committed_text as committed_thresholds_text,
};

pub use crate::provenance::{SOURCE_OUTSIDE, SOURCE_UNCOVERED};

/// Errors of the metrics: inputs that do not fit together, and a thresholds
/// file that does not parse or holds a value out of range.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MetricsError {
    #[error("{what} holds {got} values, expected {expected}")]
    Length {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("{what} is {got_width}x{got_height}, expected {width}x{height}")]
    Size {
        what: &'static str,
        width: u32,
        height: u32,
        got_width: u32,
        got_height: u32,
    },
    #[error("{name} = {value} is outside {allowed}")]
    Invalid {
        name: &'static str,
        value: f64,
        allowed: &'static str,
    },
    #[error("{what} is too small: {width}x{height}, needs at least {min}x{min}")]
    TooSmall {
        what: &'static str,
        width: u32,
        height: u32,
        min: u32,
    },
    #[error("{what}: texel {index} is not a finite number")]
    NonFinite { what: &'static str, index: usize },
    #[error("no {0} to measure")]
    Empty(&'static str),
    #[error("thresholds file {file}: {message}")]
    Thresholds { file: &'static str, message: String },
}

/// Checks that a per-texel array has `width * height` entries.
pub(crate) fn check_len<T>(
    what: &'static str,
    values: &[T],
    width: u32,
    height: u32,
) -> Result<(), MetricsError> {
    let expected = width as usize * height as usize;
    if values.len() == expected {
        Ok(())
    } else {
        Err(MetricsError::Length {
            what,
            expected,
            got: values.len(),
        })
    }
}

/// Checks that a texture's data fits its size and channel count (its
/// fields are public, so a texture can be built without
/// [`crate::texture::Texture::from_data`]'s checks).
pub(crate) fn check_texture(
    what: &'static str,
    t: &crate::texture::Texture,
) -> Result<(), MetricsError> {
    if !(1..=4).contains(&t.channels) {
        return Err(MetricsError::Invalid {
            name: what,
            value: t.channels as f64,
            allowed: "1..=4 channels",
        });
    }
    let expected = t.texel_count() * t.channels;
    if t.data.len() == expected {
        Ok(())
    } else {
        Err(MetricsError::Length {
            what,
            expected,
            got: t.data.len(),
        })
    }
}

/// Checks a pair of consecutive frames with a per-pixel motion and a mask
/// for each (the inputs of the two-frame metrics); returns the size.
pub(crate) fn check_frame_pair<M>(
    prev: &crate::texture::Texture,
    next: &crate::texture::Texture,
    motion_name: &'static str,
    motion: &[M],
    usable_prev: &[bool],
    usable_next: &[bool],
) -> Result<(u32, u32), MetricsError> {
    if (next.width, next.height) != (prev.width, prev.height) {
        return Err(MetricsError::Size {
            what: "next frame",
            width: prev.width,
            height: prev.height,
            got_width: next.width,
            got_height: next.height,
        });
    }
    check_texture("previous frame", prev)?;
    check_texture("next frame", next)?;
    let (w, h) = (prev.width, prev.height);
    check_len(motion_name, motion, w, h)?;
    check_len("previous frame's mask", usable_prev, w, h)?;
    check_len("next frame's mask", usable_next, w, h)?;
    Ok((w, h))
}

/// The nearest periodic image of a uv difference (see the module doc).
#[inline]
pub(crate) fn wrap_delta(d: glam::Vec2) -> glam::Vec2 {
    d - d.round()
}

/// Lower median (the ⌈n/2⌉-th smallest), NaN for an empty slice. Sorts in
/// place with `total_cmp`, so infinities (failed matches) sort last.
pub(crate) fn lower_median(values: &mut [f32]) -> f32 {
    if values.is_empty() {
        return f32::NAN;
    }
    values.sort_unstable_by(f32::total_cmp);
    values[(values.len() - 1) / 2]
}
