//! The evaluation harness: runs a texturing method over a scene's frames in
//! memory and measures it with [`crate::metrics`] (docs/evaluation.md).
//!
//! Two halves. [`prepare()`] does everything that does not depend on the
//! method, once per scene: the meshes, their atlases (the same
//! [`Atlas::build`](crate::atlas::Atlas::build) as `pipeline::run`), the
//! surface point of every atlas texel, one fixed camera framing every
//! frame ([`Camera::framing`](crate::render::Camera::framing) on the
//! window's bounding box), the G-buffers, the interior masks and the true
//! motion per pixel ([`truth`]). [`evaluate`] then drives one method frame
//! by frame exactly as `pipeline::run` does (same [`FrameContext`](crate::methods::FrameContext), previous
//! frame, dt = 1/fps, gutter dilation) and measures, per frame:
//!
//! - on the atlas (per-texel provenance): coverage, ghost fraction (from
//!   the method's layer counts; 0 by construction for methods that never
//!   blend), contrast ρ over chart texels (against the exemplar filtered
//!   to the mip levels the method reports, [`metrics::shown_sigma`]),
//!   distortion (Sorkine's δ of the exemplar uv against the texel's surface
//!   point, relative to s₀ = exemplar width / S, S the world size the
//!   method reports as `exemplar_size`; anisotropy σ₁/σ₂ beside it) and
//!   exemplar fidelity (SWD, reference built once per sequence from the
//!   exemplar rescaled to the output's texel scale, metrics/mod.rs);
//! - on unlit renders from the fixed camera (colour looked up through the
//!   mesh's atlas uv, supersampled and box-filtered so sub-pixel atlas
//!   detail does not alias; source and exemplar uv from the atlas texels,
//!   see [`pixels`]): flow fidelity against the true motion (provenance-based
//!   where the method gives uv, image-based otherwise) and popping
//!   (backward warp with the true motion, disoccluded pixels left out);
//! - on surface points (two frames): source switch share and colour follow
//!   ratio ([`crate::coherence`]), 20k points sampled on each frame and
//!   carried to the next by the scene's exact flow ([`prepare()`]), looked up
//!   in both frames' atlases. The switch share has no absolute threshold:
//!   [`judge_against_floor`] compares each method with the floor method
//!   (`advect`) on the same frames once every method has run;
//! - static stop: once every vertex velocity is exactly zero, the colour
//!   atlas of every later frame must be bit-identical to the first still
//!   frame's;
//! - wall time of the method's step (plus dilation) and its patch count.
//!
//! Exemplar-size cost is not measured here (it needs two extra runs per
//! method); the report marks it n/a.
//!
//! Everything is held in memory: meant for evaluation windows of tens of
//! frames, not whole shots.

mod causes;
mod judge;
pub mod pixels;
pub mod prepare;
pub mod report;
mod supersample;
pub mod truth;

/// Two consecutive renders, with the prepared frames they show.
struct RenderPair<'a> {
    before: &'a FrameView,
    after: &'a FrameView,
    prev: &'a PreparedFrame,
    frame: &'a PreparedFrame,
}

impl RenderPair<'_> {
    /// The measured screen motion between the renders: from the per-pixel
    /// exemplar uv where both have provenance, else by block matching on
    /// the colours.
    fn motion(
        &self,
        truth: &[Vec2],
        thresholds: &Thresholds,
    ) -> Result<Vec<metrics::Motion>, MetricsError> {
        let gb = &self.frame.gbuffer;
        let (p, frame) = (self.prev, self.frame);
        if self.before.has_provenance && self.after.has_provenance {
            fn frame_of<'v>(v: &'v FrameView, gb: &GBuffer) -> metrics::ProvenanceFrame<'v> {
                metrics::ProvenanceFrame {
                    width: gb.width,
                    height: gb.height,
                    source: &v.source,
                    uv: &v.uv,
                }
            }
            metrics::provenance_motion(
                &frame_of(self.before, gb),
                &frame_of(self.after, gb),
                truth,
                &p.interior,
                &frame.interior,
                thresholds.flow.search_radius_px,
            )
        } else {
            metrics::image_motion(
                &self.before.colour,
                &self.after.colour,
                truth,
                &p.interior,
                &frame.interior,
                thresholds.flow.search_radius_px,
                thresholds.flow.block_half_px,
            )
        }
    }
}

#[cfg(test)]
mod rulings_tests;
#[cfg(test)]
mod tests;

use std::sync::Arc;

use glam::{Vec2, Vec3};
use thiserror::Error;

use crate::atlas::AtlasError;
use crate::driver::{DrivenFrame, Driver, DriverError, FrameSink, PendingFrame};
use crate::frame::StageClock;
use crate::methods::{FrameResult, Method, MethodError, Stat, StatsExt};
use crate::metrics::{
    self, FidelityReference, Metric, MetricsError, StaticStop, Summary, SurfaceSamples,
    SwdSettings, Thresholds, chart_mask,
};
use crate::render::{self, GBuffer};
use crate::scenes::SceneError;
use crate::texture::Texture;

pub use causes::{CauseShares, renewal_floor_growth};
pub use judge::{FIRST_LIFETIME_FRAMES, judge_against_floor, judge_against_floor_on};
pub use pixels::pixel_provenance;
pub use prepare::{PreparedFrame, PreparedScene, prepare};
use supersample::{box_filter, fine_gbuffer, lit_render};
pub use truth::{TruthMotion, trace, true_motion};

/// Background of evaluation renders (mid grey: neither black nor white
/// texture merges with it).
pub const RENDER_BACKGROUND: [f32; 3] = [0.5, 0.5, 0.5];

/// Settings of the harness (not of the metrics: those are the committed
/// [`Thresholds`]).
#[derive(Clone, Debug, PartialEq)]
pub struct EvalSettings {
    /// Side of the square evaluation renders, px \[256], 32–4096.
    pub render_size: u32,
    /// Direction the camera looks along [see [`default_view`]].
    pub view_dir: Vec3,
    /// RK4 steps per frame when tracing the true motion \[4], 1–64.
    pub trace_substeps: u32,
    /// Frames whose lit renders are kept for pictures.
    pub keep_renders: Vec<i32>,
    /// Measure exemplar fidelity every this many frames (1: all) \[1]; it
    /// is the slowest metric.
    pub fidelity_every: u32,
    /// Gutter dilation radius, texels, as `pipeline::run` uses it
    /// (`2 · max(gutter, 1)`).
    pub dilate_radius: u32,
    /// Colour renders are drawn at this many samples per pixel side and
    /// box-filtered \[4], 1–8: what a viewer sees with antialiasing. Without
    /// it, atlas detail finer than a pixel aliases, and the aliasing
    /// changes under sub-pixel motion, which popping would charge to the
    /// method. Provenance (flow) is read at one sample per pixel.
    pub supersample: u32,
}

impl Default for EvalSettings {
    fn default() -> Self {
        EvalSettings {
            render_size: 256,
            view_dir: Vec3::new(-0.3, -1.0, -0.35),
            trace_substeps: 4,
            keep_renders: Vec::new(),
            fidelity_every: 1,
            dilate_radius: 8,
            supersample: 4,
        }
    }
}

impl EvalSettings {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), EvalError> {
        let bad = |name: &'static str, value: String, allowed: &'static str| {
            Err(EvalError::Setting {
                name,
                value,
                allowed,
            })
        };
        if !(32..=4096).contains(&self.render_size) {
            return bad("render size", self.render_size.to_string(), "32 to 4096");
        }
        if !(self.view_dir.is_finite() && self.view_dir.length() > 0.0) {
            return bad(
                "view direction",
                format!("{:?}", self.view_dir),
                "a finite non-zero vector",
            );
        }
        if !(1..=64).contains(&self.trace_substeps) {
            return bad("trace substeps", self.trace_substeps.to_string(), "1 to 64");
        }
        if !(1..=8).contains(&self.supersample) {
            return bad("supersample", self.supersample.to_string(), "1 to 8");
        }
        if self.fidelity_every == 0 {
            return bad("fidelity_every", "0".into(), "1 or more");
        }
        Ok(())
    }
}

/// The camera direction for a scene: from above for the flat flows in the
/// xy plane (the vortex puck's top face, the shear plane), an oblique side
/// view of the spheres (rotations about z move the equator, which a view
/// from above would see edge-on).
pub fn default_view(scene: &str) -> Vec3 {
    match scene {
        "vortex" | "vortex-16" | "stop" | "shear" => Vec3::new(0.05, 0.15, -1.0),
        _ => Vec3::new(-0.3, -1.0, -0.35),
    }
}

/// Errors of the harness.
#[derive(Debug, Error)]
pub enum EvalError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("frame {frame}: {message}")]
    Mesh { frame: i32, message: String },
    #[error("frame {frame}: {source}")]
    Atlas { frame: i32, source: AtlasError },
    #[error("{method}: {source}")]
    Method { method: String, source: MethodError },
    #[error("frame {frame}: {what}: {source}")]
    Metrics {
        frame: i32,
        what: &'static str,
        source: MetricsError,
    },
    #[error("method {method} returned no colour channel at frame {frame}")]
    NoColour { method: String, frame: i32 },
    #[error("{0}")]
    Frames(String),
    #[error("evaluation setting {name} = {value} is out of range (allowed: {allowed})")]
    Setting {
        name: &'static str,
        value: String,
        allowed: &'static str,
    },
}

/// The key of a metric in JSON and file names.
pub fn metric_key(m: Metric) -> &'static str {
    match m {
        Metric::Coverage => "coverage",
        Metric::Ghosting => "ghosting",
        Metric::Contrast => "contrast",
        Metric::Distortion => "distortion",
        Metric::Fidelity => "fidelity",
        Metric::FlowEpe => "flow_epe",
        Metric::FlowAligned => "flow_aligned",
        Metric::Popping => "popping",
        Metric::SourceSwitch => "source_switch",
        Metric::ColourFollow => "colour_follow",
        Metric::StaticStop => "static_stop",
        Metric::SizeCost => "size_cost",
    }
}

/// The metrics measured per frame (plotted over time).
/// Every metric but the two that are not per frame (static stop, exemplar
/// size cost), which [`Metric::ALL`] lists last.
pub const PER_FRAME: &[Metric] = Metric::ALL.split_at(10).0;
const _: () = assert!(PER_FRAME.len() == 10 && matches!(PER_FRAME[9], Metric::ColourFollow));

/// One frame's numbers. Metrics with nothing to measure are NaN (flow and
/// popping on the first frame: they need the frame before).
#[derive(Clone, Debug, PartialEq)]
pub struct FrameRecord {
    pub frame: i32,
    /// Wall time of the method's step and the gutter dilation (s).
    pub seconds: f64,
    /// The method's `patches_alive` statistic, where it has one.
    pub patches: Option<f64>,
    /// Per metric of [`PER_FRAME`], in that order.
    pub values: [f64; 10],
    /// Whether the fluid is still at this frame.
    pub still: bool,
    /// For information beside distortion: area-weighted p95 of σ₁/σ₂ (NaN
    /// without exemplar uv).
    pub anisotropy: f64,
    /// Each carried point's source at the previous frame and this one
    /// (empty when not measured): the same points for every method.
    pub point_sources: Vec<[u32; 2]>,
    /// For information beside the switch share: this run's and the floor
    /// method's share on the points both cover at both ends
    /// ([`metrics::source_switch_same_points`]), set by
    /// [`judge_against_floor`]; NaN where not measured.
    pub switch_same_points: [f64; 2],
    /// Beside the switch share: the switches by cause and the share of
    /// points whose previous patch is past δ_max (on advect, the renewal
    /// floor); NaN where the method records no renewal.
    pub switch_causes: CauseShares,
    /// For information: the method's state agreement (exemplars chosen by
    /// an attribute, [`Stat::StateAgreement`]); NaN where it has none.
    pub state_agreement: f64,
    /// The same on the decisive points only
    /// ([`Stat::StateAgreementDecisive`]); NaN where it has none.
    pub state_agreement_decisive: f64,
}

impl FrameRecord {
    /// The value of `m` (NaN for metrics not measured per frame).
    pub fn value(&self, m: Metric) -> f64 {
        PER_FRAME
            .iter()
            .position(|&p| p == m)
            .map_or(f64::NAN, |k| self.values[k])
    }
}

/// A method's evaluation on one scene.
#[derive(Clone, Debug)]
pub struct MethodRun {
    pub method: String,
    pub frames: Vec<FrameRecord>,
    /// One per [`Metric::ALL`], in that order.
    pub summaries: Vec<Summary>,
    /// What the reader must know to read the numbers (fallbacks taken).
    pub notes: Vec<String>,
    /// Lit renders of [`EvalSettings::keep_renders`], by frame.
    pub renders: Vec<(i32, Texture)>,
    /// Exemplar texels per atlas texel the fidelity reference was built at.
    pub fidelity_scale: f64,
    /// The method blends layers (it reported per-texel layer counts,
    /// [`FrameResult::layers`]): its switch share is that of its heaviest
    /// layer, information only ([`judge_against_floor_on`]).
    pub blends: bool,
}

impl MethodRun {
    /// The summary of `m`.
    pub fn summary(&self, m: Metric) -> Option<&Summary> {
        self.summaries.iter().find(|s| s.metric == m)
    }

    /// [`MethodRun::summary`], to rewrite its verdict.
    fn summary_mut(&mut self, m: Metric) -> Option<&mut Summary> {
        self.summaries.iter_mut().find(|s| s.metric == m)
    }
}

/// The antialiased unlit render and per-pixel provenance of one frame.
struct FrameView {
    colour: Texture,
    source: Vec<u32>,
    uv: Vec<Vec2>,
    has_provenance: bool,
}

/// Runs `method` (fresh: its first step is the window's first frame) over
/// `scene` and measures every frame. `exemplar` is the colour exemplar the
/// method was built with.
pub fn evaluate(
    scene: &PreparedScene,
    method: &mut dyn Method,
    exemplar: &Texture,
    settings: &EvalSettings,
    thresholds: &Thresholds,
) -> Result<MethodRun, EvalError> {
    settings.validate()?;
    let name = method.name().to_string();
    let first_frame = scene.frames.first().map_or(0, |f| f.number);
    let sigma_ex = metrics::exemplar_sigma(exemplar);
    if sigma_ex.is_nan() || sigma_ex <= 0.0 {
        return Err(EvalError::Metrics {
            frame: first_frame,
            what: "exemplar",
            source: MetricsError::Invalid {
                name: "sigma_ex",
                value: sigma_ex as f64,
                allowed: "(0, inf): a flat exemplar has no contrast to keep",
            },
        });
    }
    let mut sink = MetricsSink {
        scene,
        exemplar,
        settings,
        thresholds,
        name: name.clone(),
        sigma_ex,
        swd: SwdSettings {
            levels: thresholds.fidelity.levels,
            patch_size: thresholds.fidelity.patch_size,
            projections: thresholds.fidelity.projections,
            patches_per_level: thresholds.fidelity.patches_per_level,
            seed: thresholds.fidelity.seed,
        },
        notes: Vec::new(),
        sigma_by_lod: None,
        fidelity: None,
        fidelity_scale: f64::NAN,
        stop: StaticStop::new(),
        previous_still: None,
        changed_from_previous: Vec::new(),
        records: Vec::with_capacity(scene.frames.len()),
        renders: Vec::new(),
        previous_view: None,
        previous_texels: None,
        image_flow_noted: false,
        rest_scale: f64::NAN,
        blends: false,
    };
    let mut driver = Driver::new(method, scene.dt, settings.dilate_radius);
    for frame in &scene.frames {
        let pending = PendingFrame {
            geometry: Arc::clone(&frame.geometry),
            clock: StageClock::default(),
        };
        driver.step(pending, &mut sink).map_err(|e| match e {
            EvalError::Method { source, .. } => EvalError::Method {
                method: name.clone(),
                source,
            },
            e => e,
        })?;
    }
    Ok(sink.finish())
}

impl From<DriverError> for EvalError {
    fn from(e: DriverError) -> EvalError {
        match e {
            DriverError::Atlas { frame, source } => EvalError::Atlas { frame, source },
            // `evaluate` names the method.
            DriverError::Method(source) => EvalError::Method {
                method: String::new(),
                source,
            },
        }
    }
}

/// The sink of `evaluate`: every metric of every frame, in memory.
struct MetricsSink<'a> {
    scene: &'a PreparedScene,
    exemplar: &'a Texture,
    settings: &'a EvalSettings,
    thresholds: &'a Thresholds,
    name: String,
    sigma_ex: f32,
    swd: SwdSettings,
    notes: Vec<String>,
    sigma_by_lod: Option<Vec<f32>>,
    fidelity: Option<FidelityReference>,
    fidelity_scale: f64,
    stop: StaticStop,
    /// Still frames that differ from the still frame before them: tells a
    /// method that settles late (a few changes, then identical) from one
    /// that never settles.
    previous_still: Option<Texture>,
    changed_from_previous: Vec<i32>,
    records: Vec<FrameRecord>,
    renders: Vec<(i32, Texture)>,
    previous_view: Option<FrameView>,
    /// Sources and grey values of the frame before, for the coherence
    /// metrics.
    previous_texels: Option<(Vec<u32>, Vec<f32>)>,
    image_flow_noted: bool,
    /// s₀ of the distortion metric (exemplar texels per world unit at the
    /// patches' creation), fixed at the first frame that gives it.
    rest_scale: f64,
    /// A frame reported blended layers ([`MethodRun::blends`]).
    blends: bool,
}

/// What the atlas of one frame holds, as the metrics read it.
struct AtlasView<'r> {
    colour: &'r Texture,
    source: Option<&'r [u32]>,
    uv: Option<&'r [Vec2]>,
    /// The method's renewal bytes ([`crate::methods::FrameResult::renewal`]).
    renewal: Option<&'r [u8]>,
    /// Chart texels: from the method's provenance where it has one, else
    /// from the atlas itself.
    charts: Vec<bool>,
}

impl FrameSink for MetricsSink<'_> {
    type Error = EvalError;

    fn frame(&mut self, driven: DrivenFrame<'_>) -> Result<(), EvalError> {
        let k = self.records.len();
        let scene = self.scene;
        let frame = scene.frames.get(k).ok_or_else(|| {
            EvalError::Frames(format!("frame {} was not prepared", driven.geometry.number))
        })?;
        let prev = k.checked_sub(1).and_then(|j| scene.frames.get(j));
        let number = frame.number;
        let result = &driven.result;
        let seconds = driven.clock.total();
        let colour = result.channels.first().ok_or_else(|| EvalError::NoColour {
            method: self.name.clone(),
            frame: number,
        })?;
        let atlas = &frame.geometry.atlas;
        let n_texels = atlas.width as usize * atlas.height as usize;
        let source: Option<&[u32]> = result.source.as_deref().filter(|s| s.len() == n_texels);
        let view = AtlasView {
            colour,
            source,
            uv: result.uv.as_deref().filter(|u| u.len() == n_texels),
            renewal: result.renewal.as_deref().filter(|r| r.len() == n_texels),
            charts: match source {
                Some(s) => chart_mask(s),
                None => frame.chart.iter().map(|&c| c != u32::MAX).collect(),
            },
        };
        let mut values = [f64::NAN; 10];
        let mut set = |m: Metric, v: f64| {
            if let Some(k) = PER_FRAME.iter().position(|&p| p == m) {
                values[k] = v;
            }
        };
        let anisotropy = self.atlas_metrics(k, frame, result, &view, &mut set)?;
        let rendered = self.render_metrics(frame, prev, &view, &mut set)?;
        let (point_sources, switch_causes) =
            self.coherence_metrics(frame, prev, &view, &mut set)?;
        if frame.still {
            self.stop.push(colour);
            if let Some(p) = &self.previous_still
                && !metrics::bit_identical(p, colour)
            {
                self.changed_from_previous.push(number);
            }
            self.previous_still = Some(colour.clone());
        }
        if self.settings.keep_renders.contains(&number) {
            self.renders.push((
                number,
                lit_render(frame, &scene.camera, colour, self.settings.supersample),
            ));
        }
        self.blends |= result.layers.is_some();
        let patches = result.stats.number(Stat::PatchesAlive);
        self.records.push(FrameRecord {
            frame: number,
            seconds,
            patches,
            values,
            still: frame.still,
            anisotropy,
            point_sources,
            switch_same_points: [f64::NAN; 2],
            switch_causes,
            state_agreement: result
                .stats
                .number(Stat::StateAgreement)
                .unwrap_or(f64::NAN),
            state_agreement_decisive: result
                .stats
                .number(Stat::StateAgreementDecisive)
                .unwrap_or(f64::NAN),
        });
        self.previous_view = Some(rendered);
        Ok(())
    }
}

impl MetricsSink<'_> {
    fn metric_err(frame: i32, what: &'static str) -> impl Fn(MetricsError) -> EvalError {
        move |source: MetricsError| EvalError::Metrics {
            frame,
            what,
            source,
        }
    }

    /// Coverage, ghosting, contrast, distortion and fidelity of the atlas;
    /// returns the anisotropy shown beside distortion.
    fn atlas_metrics(
        &mut self,
        k: usize,
        frame: &PreparedFrame,
        result: &FrameResult,
        view: &AtlasView<'_>,
        set: &mut impl FnMut(Metric, f64),
    ) -> Result<f64, EvalError> {
        let number = frame.number;
        let err = |what| Self::metric_err(number, what);
        let n_texels = view.charts.len();
        if let Some(s) = view.source {
            set(Metric::Coverage, metrics::coverage(s).share());
            let ghost = match &result.layers {
                Some(layers) => metrics::ghosting(s, layers)
                    .map_err(err("ghost fraction"))?
                    .share(),
                None => 0.0,
            };
            set(Metric::Ghosting, ghost);
        }
        let charts = &view.charts;
        if charts.iter().any(|&c| c) {
            // A filtered output is compared with the exemplar filtered to
            // the levels it shows (metrics::contrast doc).
            let shown = match result.exemplar_lod.as_deref() {
                Some(lod) if lod.len() == n_texels => {
                    let exemplar = self.exemplar;
                    let table = self
                        .sigma_by_lod
                        .get_or_insert_with(|| metrics::exemplar_sigma_by_lod(exemplar));
                    metrics::shown_sigma(table, lod, Some(charts)).map_err(err("contrast"))?
                }
                _ => self.sigma_ex,
            };
            set(
                Metric::Contrast,
                metrics::contrast_ratio(view.colour, Some(charts), shown)
                    .map_err(err("contrast"))?,
            );
        }
        let (texel_scale, anisotropy) = self.distortion(frame, result, view, set)?;
        let shown = Shown {
            texel_scale,
            lod: result.exemplar_lod.as_deref(),
        };
        self.fidelity(k, frame, shown, view, set)?;
        Ok(anisotropy)
    }

    /// Distortion (set) and (exemplar texels per atlas texel, anisotropy).
    fn distortion(
        &mut self,
        frame: &PreparedFrame,
        result: &FrameResult,
        view: &AtlasView<'_>,
        set: &mut impl FnMut(Metric, f64),
    ) -> Result<(f64, f64), EvalError> {
        let number = frame.number;
        let exemplar = self.exemplar;
        if self.rest_scale.is_nan()
            && let Some(size) = result
                .stats
                .number(Stat::ExemplarSize)
                .filter(|s| s.is_finite() && *s > 0.0)
        {
            // The exemplar's [0, 1]² covers S world units at creation.
            self.rest_scale = f64::from(exemplar.width) / size;
        }
        let (Some(s), Some(u)) = (view.source, view.uv) else {
            return Ok((f64::NAN, f64::NAN));
        };
        let atlas = &frame.geometry.atlas;
        let samples = SurfaceSamples {
            width: atlas.width,
            height: atlas.height,
            source: s,
            uv: u,
            points: &frame.points,
            chart: Some(&frame.chart),
        };
        let quantile = self.thresholds.distortion.quantile;
        let measure = |s0: f64| {
            metrics::distortion(&samples, (exemplar.width, exemplar.height), s0, quantile)
                .map_err(Self::metric_err(number, "distortion"))
        };
        let d = if self.rest_scale.is_nan() {
            // No S from the method: take the scale the texture shows on
            // its first measured frame as the rest scale.
            let first = measure(1.0)?;
            self.rest_scale = first.exemplar_texels_per_unit;
            self.notes.push(format!(
                "distortion: the method reports no exemplar size S; s0 = {:.4} \
                 exemplar texels per world unit, the median scale of frame {number}",
                self.rest_scale
            ));
            measure(self.rest_scale)?
        } else {
            measure(self.rest_scale)?
        };
        set(Metric::Distortion, d.delta);
        Ok((d.exemplar_texels_per_texel, d.anisotropy))
    }

    /// Exemplar fidelity (SWD) against a reference built once, at the
    /// output's texel scale (exemplar texels per atlas texel).
    fn fidelity(
        &mut self,
        k: usize,
        frame: &PreparedFrame,
        shown: Shown<'_>,
        view: &AtlasView<'_>,
        set: &mut impl FnMut(Metric, f64),
    ) -> Result<(), EvalError> {
        let number = frame.number;
        let exemplar = self.exemplar;
        if self.fidelity_scale.is_nan() {
            let texel_scale = match shown.texel_scale {
                s if s.is_finite() => s,
                _ => shown_scale(shown.lod),
            };
            let s = if texel_scale.is_finite() && texel_scale > 0.0 {
                texel_scale
            } else {
                self.notes.push(
                    "fidelity: no exemplar uv or level, the exemplar is compared at its own scale"
                        .into(),
                );
                1.0
            };
            let reference = if (s - 1.0).abs() < 1e-3 {
                exemplar.clone()
            } else {
                metrics::rescale(exemplar, (1.0 / s) as f32)
                    .map_err(Self::metric_err(number, "fidelity reference"))?
            };
            match FidelityReference::new(&reference, &self.swd) {
                Ok(r) => self.fidelity = Some(r),
                Err(e) => self.notes.push(format!(
                    "fidelity not measured: the exemplar at {s:.2} exemplar texels per \
                     atlas texel is {}x{}: {e}",
                    reference.width, reference.height
                )),
            }
            self.fidelity_scale = s;
        }
        if let Some(reference) = &self.fidelity
            && (k as u32).is_multiple_of(self.settings.fidelity_every)
            && view.charts.iter().any(|&c| c)
        {
            // Too little chart area for the pyramid's patches is a frame
            // without a value, not a failed evaluation.
            match reference.measure(view.colour, Some(&view.charts)) {
                Ok(f) => set(Metric::Fidelity, f.ratio),
                Err(e @ (MetricsError::Empty(_) | MetricsError::TooSmall { .. })) => {
                    let note = format!("fidelity not measured on some frames: {e}");
                    if !self.notes.contains(&note) {
                        self.notes.push(note);
                    }
                }
                Err(e) => return Err(Self::metric_err(number, "fidelity")(e)),
            }
        }
        Ok(())
    }

    /// Renders the frame, measures flow fidelity and popping against the
    /// frame before; returns the frame's view for the next one.
    fn render_metrics(
        &mut self,
        frame: &PreparedFrame,
        prev: Option<&PreparedFrame>,
        atlas_view: &AtlasView<'_>,
        set: &mut impl FnMut(Metric, f64),
    ) -> Result<FrameView, EvalError> {
        let thresholds = self.thresholds;
        let err = |what| Self::metric_err(frame.number, what);
        let view = self.render_view(frame, atlas_view);
        let (Some(p), Some(pv)) = (prev, &self.previous_view) else {
            return Ok(view);
        };
        if let Some(truth) = p.forward.as_deref() {
            let pair = RenderPair {
                before: pv,
                after: &view,
                prev: p,
                frame,
            };
            let by_image = !(pv.has_provenance && view.has_provenance);
            if by_image && !self.image_flow_noted {
                self.notes.push(
                    "flow: no per-texel exemplar uv, motion measured by block matching \
                     on the renders (image_motion)"
                        .into(),
                );
                self.image_flow_noted = true;
            }
            let motion = pair.motion(truth, thresholds).map_err(err("flow"))?;
            let stats = metrics::compare_motion(
                &motion,
                truth,
                thresholds.flow.min_speed_px,
                thresholds.flow.min_cos,
            )
            .map_err(err("flow"))?;
            set(Metric::FlowEpe, stats.median_epe_px);
            set(Metric::FlowAligned, stats.aligned_share);
        }
        if let Some((back, visible)) = &frame.backward {
            let usable_next: Vec<bool> = frame
                .interior
                .iter()
                .zip(visible)
                .map(|(&a, &b)| a && b)
                .collect();
            let pop = metrics::popping(
                &pv.colour,
                &view.colour,
                back,
                &p.interior,
                &usable_next,
                self.sigma_ex,
                thresholds.popping.sigma_factor,
            )
            .map_err(err("popping"))?;
            set(Metric::Popping, pop.share());
        }
        Ok(view)
    }

    /// The frame rendered unlit (supersampled when asked) with the per-pixel
    /// provenance where the method has it.
    fn render_view(&self, frame: &PreparedFrame, atlas_view: &AtlasView<'_>) -> FrameView {
        let gb = &frame.gbuffer;
        let mesh = &frame.geometry.atlas.uv_mesh;
        let colour = atlas_view.colour;
        let unlit = if self.settings.supersample > 1 {
            let k = self.settings.supersample;
            let (fine, _) = fine_gbuffer(frame, &self.scene.camera, k);
            let image = render::shade_textured(
                &fine,
                &mesh.triangles,
                &mesh.uvs,
                colour,
                RENDER_BACKGROUND,
            );
            box_filter(&image, k)
        } else {
            render::shade_textured(gb, &mesh.triangles, &mesh.uvs, colour, RENDER_BACKGROUND)
        };
        let (px_source, px_uv) = match (atlas_view.source, atlas_view.uv) {
            (Some(s), Some(u)) => pixel_provenance(gb, &frame.geometry.atlas, s, u),
            _ => (Vec::new(), Vec::new()),
        };
        FrameView {
            colour: unlit,
            has_provenance: !px_source.is_empty(),
            source: px_source,
            uv: px_uv,
        }
    }

    /// Source switch share and colour follow ratio: the previous frame's
    /// points carried here. Without per-texel sources nothing is covered
    /// (no switch share) but the colour still says whether the texture
    /// follows. Returns each point's sources at both ends (empty on the
    /// first frame) and [`FrameRecord::switch_causes`].
    fn coherence_metrics(
        &mut self,
        frame: &PreparedFrame,
        prev: Option<&PreparedFrame>,
        view: &AtlasView<'_>,
        set: &mut impl FnMut(Metric, f64),
    ) -> Result<(Vec<[u32; 2]>, CauseShares), EvalError> {
        let n_texels = view.charts.len();
        let texels = (
            view.source
                .map_or_else(|| vec![metrics::SOURCE_OUTSIDE; n_texels], <[u32]>::to_vec),
            metrics::luminance(view.colour),
        );
        let mut points = Vec::new();
        let mut causes = CauseShares::NONE;
        if let (Some(p), Some((ps, pg))) = (prev, &self.previous_texels)
            && let Some(carried) = &p.carried
        {
            let (c, sources) = crate::coherence::measure_with_points(
                carried,
                &crate::coherence::TexelFrame {
                    atlas: &p.geometry.atlas,
                    source: ps,
                    grey: pg,
                    renewal: &[],
                },
                &crate::coherence::TexelFrame {
                    atlas: &frame.geometry.atlas,
                    source: &texels.0,
                    grey: &texels.1,
                    renewal: view.renewal.unwrap_or_default(),
                },
                &crate::coherence::CoherenceSettings::from_thresholds(self.thresholds),
            )
            .map_err(Self::metric_err(frame.number, "coherence"))?;
            set(Metric::SourceSwitch, c.switch_share());
            set(Metric::ColourFollow, c.follow_ratio());
            points = sources;
            let before = self
                .records
                .last()
                .map_or(f64::NAN, |r| r.switch_causes.holder_distorted);
            causes = CauseShares::of(&c.causes, before);
        }
        self.previous_texels = Some(texels);
        Ok((points, causes))
    }

    /// The run: per-frame records and their summaries.
    fn finish(mut self) -> MethodRun {
        let stop = &self.stop;
        if stop.frames_after() > 0 {
            self.notes.push(format!(
                "static stop: {} of {} frames after the first still frame differ from it; \
                 still frames that differ from the frame before: {:?}",
                stop.changed(),
                stop.frames_after(),
                self.changed_from_previous
            ));
        }
        let summaries = Metric::ALL
            .iter()
            .map(|&m| {
                let values: Vec<f64> = match m {
                    Metric::StaticStop if stop.frames_after() > 0 => {
                        vec![stop.changed() as f64]
                    }
                    Metric::StaticStop | Metric::SizeCost => Vec::new(),
                    _ => self.records.iter().map(|r| r.value(m)).collect(),
                };
                self.thresholds.summarize(m, &values)
            })
            .collect();
        MethodRun {
            method: self.name,
            frames: self.records,
            summaries,
            notes: self.notes,
            renders: self.renders,
            fidelity_scale: self.fidelity_scale,
            blends: self.blends,
        }
    }
}

/// The scale a frame shows the exemplar at: exemplar texels per atlas
/// texel from its exemplar uv (NaN without), else the mip levels it reports.
struct Shown<'a> {
    texel_scale: f64,
    lod: Option<&'a [f32]>,
}

/// Exemplar texels per atlas texel of an output without exemplar uv, from
/// the mip levels it reports it shows (the median over chart texels); NaN
/// without such levels.
fn shown_scale(lod: Option<&[f32]>) -> f64 {
    let mut levels: Vec<f32> = lod
        .unwrap_or(&[])
        .iter()
        .copied()
        .filter(|l| l.is_finite())
        .collect();
    if levels.is_empty() {
        return f64::NAN;
    }
    let mid = levels.len() / 2;
    let (_, median, _) = levels.select_nth_unstable_by(mid, f32::total_cmp);
    f64::from(median.max(0.0)).exp2()
}

/// Median, min and max over a method's frames of the wall time per frame (s).
pub fn seconds_per_frame(run: &MethodRun) -> (f64, f64, f64) {
    let mut s: Vec<f64> = run.frames.iter().map(|r| r.seconds).collect();
    s.sort_unstable_by(f64::total_cmp);
    match (s.first(), s.last()) {
        (Some(&lo), Some(&hi)) => (s[(s.len() - 1) / 2], lo, hi),
        _ => (f64::NAN, f64::NAN, f64::NAN),
    }
}

/// Median, min and max of the patch counts, where the method reports them.
pub fn patch_counts(run: &MethodRun) -> Option<(f64, f64, f64)> {
    let mut s: Vec<f64> = run.frames.iter().filter_map(|r| r.patches).collect();
    s.sort_unstable_by(f64::total_cmp);
    match (s.first(), s.last()) {
        (Some(&lo), Some(&hi)) => Some((s[(s.len() - 1) / 2], lo, hi)),
        _ => None,
    }
}
