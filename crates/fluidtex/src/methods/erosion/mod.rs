//! Eroded deformable lapped textures (Gagnon, Guzmán, Mould, Paquette 2021),
//! the primary method. Per frame:
//!
//! 1. [`patch`]: advect every patch vertex (RK4) to the new frame, project
//!    it onto the new surface, drop vertices farther than r/4 (Sec. 4); on
//!    the first frame, place patches on a Poisson-disk set instead.
//! 2. [`distortion`], [`patch::Patch::update_weights`]: δ_t, Q_T, Q_V, B_V,
//!    w_V (Eqs. 1–3).
//! 3. [`fill`]: the lapped fill, oldest patch on top, one source per texel,
//!    with the erosion test of [`erode`] (Sec. 5.1–5.2).
//! 4. [`update`]: new patches below the others until no chart texel is
//!    uncovered; patches no texel used are deleted.
//!
//! Every exemplar channel is driven by the same per-texel selection. With
//! several exemplars each patch shows its own ([`exemplars`]).

pub mod blend;
pub mod distortion;
pub mod erode;
pub mod exemplars;
pub mod feature_levels;
pub mod fill;
mod lifecycle;
mod params;
pub mod patch;
mod radius;
mod resample;
mod selection;
mod stats;
pub mod transition;
pub mod update;

#[cfg(test)]
mod behaviour_tests;
#[cfg(test)]
mod tests;

use std::sync::Arc;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use self::erode::ErosionTest;
use self::fill::{Candidates, FillBuffers, FillContext, LocateTolerance};
pub use self::params::{
    Bound, ErodedTriangles, ErosionParams, Falloff, FeatureFilter, Orientation, PatchRegion,
    SeedCorners, SeedTexel, WeightMode,
};
use self::patch::{FrameSurface, Patch, PatchShape};
pub use self::radius::{default_radius, median_edge_length};
use self::stats::{Blended, StepCounts};
pub use self::update::Placement;
use super::{ChannelSpec, FrameContext, FrameResult, Method, MethodError, StageClock};
use crate::exemplar::Exemplar;
use crate::exemplar::tone::ExemplarTone;

/// Patch state carried from frame to frame (saved for `--resume`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ErosionState {
    /// Patches ordered by id: oldest first (top of the lapped stack).
    pub patches: Vec<Patch>,
    pub next_id: u32,
    /// r and S once resolved from the first non-empty frame.
    pub radius: Option<f32>,
    pub exemplar_size: Option<f32>,
}

impl ErosionState {
    /// Whether a loaded state is one this method could have saved (a
    /// state file with a valid checksum can still be crafted): patches in
    /// id order below `next_id`, each with as many rest coordinates, pins
    /// and weights (or none yet) as vertices, finite, and triangles that
    /// name its own vertices; a positive radius and exemplar size.
    pub fn check(&self) -> Result<(), String> {
        super::check_scale(self.radius, self.exemplar_size)?;
        let mut last = None;
        for (k, p) in self.patches.iter().enumerate() {
            super::check_id(k, p.id, &mut last, self.next_id, "patch")?;
            p.check()
                .map_err(|e| format!("patch {k} (id {}): {e}", p.id))?;
        }
        Ok(())
    }
}

/// What the patch machinery does with its patches: the 2021 method
/// ([`EROSION`]), or a baseline built from the same parts, which declares
/// its own rules in its folder (`methods::advect`,
/// `methods::blend_deformable`; docs/design.md, *Baselines*).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rules {
    /// The method's name (`--method`, state files, reports).
    pub name: &'static str,
    /// Eqs. 1–3 erode the patches in the lapped fill (Sec. 5), with the
    /// erosion method's own refinements: progressive weights, tone
    /// matching, pruning of hidden and eroded triangles, the whole centre.
    /// Without it no texel is ever eroded.
    pub erodes: bool,
    /// Patches are alpha-blended by weight ([`blend`]) instead of lapped
    /// (one source per texel).
    pub blends: bool,
    /// Patches are renewed after the first frame: new ones where texels are
    /// uncovered, unused ones deleted, a mismatching exemplar fading.
    /// Without it the first frame's patches are carried for ever.
    pub renews: bool,
}

/// The 2021 method: erosion, lapped fill, new patches, deletion.
pub const EROSION: Rules = Rules {
    name: "erosion",
    erodes: true,
    blends: false,
    renews: true,
};

/// The erosion method (and the baselines sharing its patches).
pub struct Erosion {
    rules: Rules,
    params: ErosionParams,
    exemplar: Arc<Exemplar>,
    /// Built once r and S are known (the footprint falloff needs r/S).
    test: Option<ErosionTest>,
    /// The feature map filtered to the atlas texel's footprint.
    feature_levels: feature_levels::FeatureLevels,
    seed: u64,
    state: ErosionState,
    /// Patches dropped by [`Erosion::reset`] since the last step (counted
    /// as deleted by the next step).
    dropped_by_reset: usize,
    /// Several exemplars per surface; `None`: one (`exemplar`).
    multi: Option<exemplars::Multi>,
    /// Each exemplar's statistics, measured on the first frame that
    /// matches its tone.
    tones: Option<Vec<ExemplarTone>>,
    /// Whether wholly eroded and hidden triangles are dropped
    /// ([`Erosion::prune`], [`Erosion::prune_hidden`]):
    /// `eroded_triangles = "dropped"`.
    prune_eroded: bool,
    /// [`patch::KEPT_SPLIT_DISTORTION`]; a test's unbounded control sets
    /// it to infinity.
    kept_split_distortion: f32,
}

pub(crate) use crate::seed::mix;

/// The seeded random rotation (radians) for `key`, or 0 when disabled.
/// Patches of the initial distribution are keyed by id; patches the update
/// creates by where they are created ([`location_key`]), so that a fluid at
/// rest that keeps asking for a patch at the same texel gets the same one.
fn rotation_for(seed: u64, random: bool, key: u64) -> f32 {
    if random {
        let bits = mix(seed, 1, key);
        (bits >> 40) as f32 / (1u64 << 24) as f32 * std::f32::consts::TAU
    } else {
        0.0
    }
}

/// A key of a surface location: its triangle and barycentric bits.
fn location_key(at: crate::surface::SurfacePoint) -> u64 {
    let [a, b, _] = at.bary.map(f32::to_bits);
    mix(at.triangle as u64, a as u64, b as u64)
}

impl Erosion {
    pub fn new(
        params: ErosionParams,
        exemplar: Arc<Exemplar>,
        seed: u64,
    ) -> Result<Erosion, MethodError> {
        Erosion::with_rules(EROSION, params, exemplar, seed)
    }

    /// The method or baseline of `rules` with the erosion method's parameters.
    pub fn with_rules(
        rules: Rules,
        params: ErosionParams,
        exemplar: Arc<Exemplar>,
        seed: u64,
    ) -> Result<Erosion, MethodError> {
        params.validate()?;
        let prune_eroded = params.eroded_triangles == ErodedTriangles::Dropped;
        Ok(Erosion {
            rules,
            params,
            feature_levels: feature_levels::FeatureLevels::new(&exemplar.feature),
            exemplar,
            test: None,
            seed,
            state: ErosionState::default(),
            dropped_by_reset: 0,
            multi: None,
            tones: None,
            prune_eroded,
            kept_split_distortion: patch::KEPT_SPLIT_DISTORTION,
        })
    }

    /// The method with every distorted triangle split as before the bound
    /// ([`patch::KEPT_SPLIT_DISTORTION`]): the tests' unbounded control.
    #[cfg(test)]
    pub(crate) fn splitting_without_bound(mut self) -> Erosion {
        self.kept_split_distortion = f32::INFINITY;
        self
    }

    /// The method or baseline of `rules` over the exemplars of `set`, each
    /// patch showing the one its strategy chose ([`exemplars`]). One
    /// exemplar is exactly [`Erosion::with_rules`].
    pub fn with_exemplars(
        rules: Rules,
        params: ErosionParams,
        set: Arc<crate::exemplar::ExemplarSet>,
        seed: u64,
    ) -> Result<Erosion, MethodError> {
        let mut e = Erosion::with_rules(rules, params, Arc::clone(set.primary()), seed)?;
        if set.len() > 1 || set.is_animated() {
            e.multi = Some(exemplars::Multi::new(set, seed));
        }
        Ok(e)
    }

    /// The fluid frame being textured: which frame of an animated exemplar
    /// each patch shows.
    fn show_frame(&mut self, number: i32) {
        if let Some(m) = &mut self.multi {
            m.frame = number;
        }
    }

    /// The patch state (for tests and statistics).
    pub fn state(&self) -> &ErosionState {
        &self.state
    }

    /// Drops every patch: the next frame starts a fresh distribution (as on
    /// the first frame). Ids keep increasing, so new patches get new
    /// rotations and colours.
    pub fn reset(&mut self) {
        self.dropped_by_reset += self.state.patches.len();
        self.state.patches.clear();
    }

    /// The erosion test for patches of uv radius `footprint` = r/S over
    /// `feature` (the exemplar's feature map).
    fn erosion_test(&self, footprint: f32, feature: &crate::exemplar::FeatureMap) -> ErosionTest {
        if !self.rules.erodes {
            return ErosionTest::never();
        }
        let reach = match self.params.falloff {
            Falloff::Paper => erode::PAPER_REACH,
            // Patches larger than the exemplar square cannot reach further than it.
            Falloff::Footprint => footprint.clamp(1e-3, erode::PAPER_REACH),
        };
        ErosionTest::with_reach(feature, self.params.epsilon, reach)
    }

    /// Whether the triangles past δ_max go ([`Erosion::prune`]): the
    /// eroding method with `eroded_triangles = "dropped"`.
    fn pruned(&self) -> bool {
        self.rules.erodes && self.prune_eroded
    }

    fn shape(
        &self,
        radius: f32,
        exemplar_size: f32,
        mesh: &crate::mesh::TriMesh,
        atlas: &crate::atlas::Atlas,
    ) -> PatchShape {
        PatchShape {
            split_length: if self.params.split_edges > 0.0 {
                self.params.split_edges * median_edge_length(mesh)
            } else {
                0.0
            },
            // Only where the triangles past δ_max are pruned (see
            // [`Erosion::prune`]).
            split_stretch: if self.pruned() {
                self.params.delta_max * exemplar_size
            } else {
                f32::INFINITY
            },
            // Where every triangle is kept, a triangle distorted past a
            // multiple of δ_max is split no more
            // ([`patch::Patch::refine_within`]).
            split_distortion: if self.pruned() {
                f32::INFINITY
            } else {
                self.kept_split_distortion * self.params.delta_max
            },
            // The paper's F_m is read at full resolution: no footprint.
            texel_size: if atlas.scale > 0.0 && self.params.feature_filter == FeatureFilter::Mip {
                (1.0 / atlas.scale) as f32
            } else {
                0.0
            },
            feature_width: self.feature_levels.width() as f32,
            radius,
            exemplar_size,
            delta_max: self.params.delta_max,
            delta_onset: self.params.delta_onset,
            far_distance: self.params.far_fraction * radius,
            centre_radius: self.params.centre_fraction * radius,
            // Only where progressive weights carry it over the next frames.
            whole_centre: self.rules.erodes && self.params.weights == WeightMode::Progressive,
            whole_region: self.params.patch_region == PatchRegion::Paper,
            pin_seed_corners: self.params.seed_corners == SeedCorners::Pinned,
        }
    }
}

/// What the stages of one frame on a non-empty surface share.
#[derive(Clone, Copy)]
struct FrameSetup {
    radius: f32,
    shape: PatchShape,
    align: Option<glam::Vec3>,
    test: ErosionTest,
    /// `advect` carried its patches: none are created.
    carried: bool,
}

/// A frame's selection per texel, before any channel is sampled.
struct Texels {
    out: FillBuffers,
    blended: Blended,
}

impl Method for Erosion {
    fn name(&self) -> &'static str {
        self.rules.name
    }

    fn channel_specs(&self) -> Vec<ChannelSpec> {
        crate::exemplar::channels::exemplar_channels(&self.exemplar)
    }

    fn step(&mut self, ctx: &FrameContext<'_>) -> Result<FrameResult, MethodError> {
        let mut clock = StageClock::default();
        let mut counts = StepCounts::default();
        let setup = self.carry(ctx, &mut counts, &mut clock)?;
        let wants = ctx.arena.wants();
        let texels = self.select_texels(ctx, setup, wants.renewal, &mut counts, &mut clock);
        ctx.arena.memory().check()?;
        let mut result = self.resample_texels(texels, counts, clock, wants);
        self.record_state_agreement(ctx, &mut result);
        Ok(result)
    }

    /// The patches as this frame's fill reads them are the selection
    /// (`erosion/selection.rs`); the fill and the update run here too, for the
    /// state of the next frame, but nothing is resampled.
    fn select(&mut self, ctx: &FrameContext<'_>) -> Result<super::Selection, MethodError> {
        let mut clock = StageClock::default();
        let mut counts = StepCounts::default();
        let setup = self.carry(ctx, &mut counts, &mut clock)?;
        let bytes = self.snapshot(setup.as_ref().map(|s| s.carried), &counts)?;
        // The selection reports the patches a reset dropped (a resampled
        // frame's statistics take them), so the next frame must not.
        self.dropped_by_reset = 0;
        // Only a resampled frame's switches are measured.
        let texels = self.select_texels(ctx, setup, false, &mut counts, &mut clock);
        ctx.arena.memory().check()?;
        self.keep_spare(ctx.arena, texels);
        Ok(super::Selection::Own(bytes))
    }

    fn resample(
        &mut self,
        ctx: &FrameContext<'_>,
        selection: &super::Selection,
    ) -> Result<FrameResult, MethodError> {
        let bytes = selection.own(self.name())?;
        let mut clock = StageClock::default();
        self.show_frame(ctx.number);
        let (mut counts, carried) = self.restore(bytes)?;
        let setup = match carried {
            Some(carried) if !ctx.mesh.is_empty() => Some(FrameSetup {
                carried,
                ..self.setup(ctx, &mut counts)?
            }),
            _ => None,
        };
        clock.lap("selection");
        let wants = ctx.arena.wants();
        let texels = self.select_texels(ctx, setup, wants.renewal, &mut counts, &mut clock);
        ctx.arena.memory().check()?;
        let mut result = self.resample_texels(texels, counts, clock, wants);
        self.record_state_agreement(ctx, &mut result);
        Ok(result)
    }

    fn save_state(&self) -> Result<Vec<u8>, MethodError> {
        let mut bytes =
            postcard::to_allocvec(&self.state).map_err(|e| MethodError::State(e.to_string()))?;
        // A transition's weights of the frames before, then several
        // exemplars' ids, follow the patch state.
        if self.transition_frames() > 0 {
            bytes.extend(transition::save_history(&self.state.patches)?);
        }
        if let Some(m) = &self.multi {
            bytes.extend(m.save(&self.state.patches)?);
        }
        Ok(bytes)
    }

    fn memory_model(
        &self,
        _: &crate::atlas::AtlasParams,
        largest: Option<&crate::mesh::TriMesh>,
    ) -> super::MemoryModel {
        let exemplars = (self.multi.as_ref())
            .map_or_else(|| self.exemplar.memory_bytes(), |m| m.set.memory_bytes());
        // Per texel besides channels and ids: uv (8), exemplar level (4)
        // and renewal flags (1); a blend adds its accumulated channels and
        // weights, a transition the second source's uv and weight.
        let blend = if self.rules.blends { 24 } else { 0 };
        let transition = if self.transition_frames() > 0 { 16 } else { 0 };
        // A radius above the default makes larger patches that stretch
        // further before they erode, so more of their triangles are split
        // and kept: measured on a Mantaflow splash, 4 times the default
        // radius holds about twice the patch triangles and candidate pairs
        // per surface triangle (13–18 and 100–136 against 7–8 and 47–55).
        let radius_ratio = match (self.params.radius, largest) {
            (Some(r), Some(mesh)) if !mesh.triangles.is_empty() => {
                f64::from(r) / f64::from(default_radius(mesh, &self.params).0).max(1e-12)
            }
            _ => 1.0,
        };
        // The blend never erodes a triangle away, so its patches keep what
        // they gathered: measured, 4 patch triangles per surface triangle
        // on the first frame of a Mantaflow splash, 48 at frame 31 and 63
        // at frame 48 (910 MiB at 85k triangles). Three times the erosion
        // figure covers a run of about two seconds; the memory guard stops
        // a longer one that outgrows it.
        let history = if self.rules.blends { 3.0 } else { 1.0 };
        let per_triangle =
            super::PATCH_BYTES_PER_TRIANGLE as f64 * history * radius_ratio.clamp(1.0, 64.0).sqrt();
        super::MemoryModel {
            // The feature levels and tone statistics are built from each
            // exemplar and are no larger than it.
            fixed: 2 * exemplars,
            per_triangle: per_triangle as u64,
            per_texel: 13 + blend + transition,
            per_thread: 0,
        }
    }

    fn memory_report(&self) -> Option<String> {
        let patches = &self.state.patches;
        let triangles: usize = patches.iter().map(|p| p.triangles.len()).sum();
        let bytes: usize = patches.iter().map(Patch::geometry_bytes).sum();
        let triangles = if triangles >= 1_000_000 {
            format!("{:.1} M", triangles as f64 / 1e6)
        } else {
            triangles.to_string()
        };
        let mib = bytes as f64 / f64::from(1u32 << 20);
        let geometry = if mib >= 1024.0 {
            format!("{:.1} GiB", mib / 1024.0)
        } else {
            format!("{mib:.0} MiB")
        };
        Some(format!(
            "{} patches, {triangles} patch triangles, {geometry} of patch geometry",
            patches.len()
        ))
    }

    fn load_state(&mut self, bytes: &[u8]) -> Result<(), MethodError> {
        let (state, rest) = postcard::take_from_bytes::<ErosionState>(bytes)
            .map_err(|e| MethodError::State(e.to_string()))?;
        state.check().map_err(MethodError::State)?;
        self.state = state;
        let rest = if self.transition_frames() > 0 {
            transition::load_history(rest, &mut self.state.patches)?
        } else {
            rest
        };
        if let Some(m) = &mut self.multi {
            m.load(rest, &mut self.state.patches)?;
        }
        Ok(())
    }
}

impl Erosion {
    /// r and S, resolved on the first non-empty frame and kept.
    fn resolve_scale(
        &mut self,
        mesh: &crate::mesh::TriMesh,
        counts: &mut StepCounts,
    ) -> (f32, f32) {
        let radius = match self.state.radius {
            Some(r) => r,
            None => {
                let (r, rule) = match self.params.radius {
                    Some(r) => (r, "given".to_string()),
                    None => default_radius(mesh, &self.params),
                };
                counts.radius_rule = Some(rule);
                self.state.radius = Some(r);
                r
            }
        };
        let exemplar_size = *self.state.exemplar_size.get_or_insert(
            self.params
                .exemplar_size
                .unwrap_or(self.params.exemplar_scale * radius),
        );
        (radius, exemplar_size)
    }

    /// This frame's fill buffers, refilling the spent ones `arena` lends
    /// where they fit; with the renewal of each texel where `renewal`.
    fn fill_buffers(
        &mut self,
        atlas: &crate::atlas::Atlas,
        arena: &super::FrameArena,
        renewal: bool,
    ) -> FillBuffers {
        // The footprint pass samples every covered texel (blends excepted).
        let defer_values = !self.rules.blends
            && self.exemplar.filter == crate::exemplar::ExemplarFilter::Trilinear;
        // Deferred values are first written by the footprint pass, late in
        // the frame: fresh zero pages until then, instead of the last
        // frame's values held idle (453 MB at 6144²) through the
        // advection, the update and the fill.
        let spare = arena.take();
        let spare_values = spare.values.filter(|_| !defer_values);
        let mut out = FillBuffers::reusing(
            atlas.width,
            atlas.height,
            self.exemplar.total_channels(),
            spare.uv,
            spare_values,
            // Where the caller kept levels (an evaluation) and handed them
            // back, they hold this frame's patch ids: a fresh id buffer
            // goes to the caller every frame, and levels kept aside until
            // the footprint pass would sit idle through the fill (151 MB
            // at 6144²). A run keeps no levels: its ids are fresh pages.
            spare
                .exemplar_lod
                .and_then(|lods| bytemuck::allocation::try_cast_vec(lods).ok()),
        );
        out.defer_values = defer_values;
        // The lapped fill records what became of each texel's previous
        // holder (the forced / unforced split of the switches); the blended
        // fill shows every layer and has no single holder.
        if !self.rules.blends && renewal {
            out = out.with_renewal();
        }
        out
    }

    /// What the stages of a frame on a non-empty surface share.
    fn setup(
        &mut self,
        ctx: &FrameContext<'_>,
        counts: &mut StepCounts,
    ) -> Result<FrameSetup, MethodError> {
        self.require_velocity(ctx)?;
        let (radius, exemplar_size) = self.resolve_scale(ctx.mesh, counts);
        Ok(FrameSetup {
            radius,
            shape: self.shape(radius, exemplar_size, ctx.mesh, ctx.atlas),
            align: self.align_axis(),
            test: self.prepare_tests(ctx, radius / exemplar_size)?,
            carried: false,
        })
    }

    /// The stages before the fill: advection, creation, weights (or, where
    /// the fluid vanished, every patch dropped: `None`).
    fn carry(
        &mut self,
        ctx: &FrameContext<'_>,
        counts: &mut StepCounts,
        clock: &mut StageClock,
    ) -> Result<Option<FrameSetup>, MethodError> {
        self.show_frame(ctx.number);
        if ctx.mesh.is_empty() {
            // Nothing to project onto: every patch goes.
            counts.deleted_before = self.state.patches.len();
            self.state.patches.clear();
            clock.lap("advection");
            return Ok(None);
        }
        let mut setup = self.setup(ctx, counts)?;
        let (shape, radius) = (setup.shape, setup.radius);
        // 1. Advection and projection (Sec. 4).
        setup.carried = self.advect(ctx, &shape, radius, counts)?;
        clock.lap("advection");
        // Initial distribution (frame 0, or a surface that reappears).
        let first_new_id = self.state.next_id;
        if self.state.patches.is_empty() {
            let surface = FrameSurface::of(ctx);
            counts.created += self.seed_distribution(ctx, &surface, &shape, radius, setup.align);
        }
        clock.lap("creation");
        // 2. Weights (Eqs. 1-3), then the triangles they erode for good.
        self.update_weights(ctx, &shape, first_new_id);
        counts.pruned = self.prune(&shape, setup.test);
        clock.lap("weights");
        Ok(Some(setup))
    }

    /// Which patch shows at each texel: the fill, the update (new patches
    /// where none did) and the deletion of patches no texel used.
    /// `renewal`: whether the fill records what became of each texel's
    /// previous holder.
    fn select_texels(
        &mut self,
        ctx: &FrameContext<'_>,
        setup: Option<FrameSetup>,
        renewal: bool,
        counts: &mut StepCounts,
        clock: &mut StageClock,
    ) -> Texels {
        let mut out = self.fill_buffers(ctx.atlas, ctx.arena, renewal);
        let shape = setup.as_ref().map(|s| s.shape);
        let mut blended = match setup {
            Some(setup) => self.fill_and_cover(ctx, &setup, &mut out, counts, clock),
            None => Blended::default(),
        };
        let mut kept = blended.used.take();
        if !blended.transitions.is_empty() {
            let ids = kept.get_or_insert_with(Vec::new);
            ids.extend(blended.transitions.iter().map(|e| e.patch_id));
        }
        counts.unused = self.delete_unused(&out, kept.as_deref());
        if let Some(shape) = shape {
            counts.pruned += self.prune_hidden(&out, &blended, &shape);
        }
        clock.lap("delete");
        Texels { out, blended }
    }

    /// The fill and the update on a non-empty surface.
    fn fill_and_cover(
        &mut self,
        ctx: &FrameContext<'_>,
        setup: &FrameSetup,
        out: &mut FillBuffers,
        counts: &mut StepCounts,
        clock: &mut StageClock,
    ) -> Blended {
        let mesh = ctx.mesh;
        let FrameSetup {
            radius,
            shape,
            align,
            test,
            carried,
        } = *setup;
        let surface = FrameSurface::of(ctx);

        // 3. Lapped (or blended) fill.
        let tolerance = LocateTolerance::for_radius(radius);
        let feature = self.feature_levels.samplers();
        let multi_fill =
            (self.multi.as_ref()).map(|m| m.fill(&self.state.patches, self.state.next_id));
        let mut blended = Blended::default();
        let exemplar = Arc::clone(&self.exemplar);
        let fluid = fill::FluidTriangles::new(mesh);
        // What the fill and the update share; the fill adds the patches.
        let template = FillContext {
            mesh,
            fluid: &fluid,
            patches: &[],
            frames: &[],
            exemplar: &exemplar,
            feature: &feature,
            test,
            tolerance,
            multi: multi_fill.as_ref(),
            verdicts: &[],
            verdicts_before: &[],
            verdicts_older: &[],
            transition: 0,
            hard_bound: self.rules.erodes && self.params.bound == Bound::Hard,
        };
        let frames = fill::patch_frames(&self.state.patches);
        let unjudged = FillContext {
            patches: &self.state.patches,
            frames: &frames,
            transition: self.transition_frames(),
            ..template
        };
        let tables = fill::VerdictTables::of(&unjudged, !out.renewal.is_empty());
        let uncovered = self.fill(ctx, &tables.judge(unjudged), out, counts, &mut blended);
        clock.lap("fill");

        // 4. Distribution update: new patches see the fill's settings.
        let (seed, random) = (self.seed, self.params.random_rotation);
        let rotation = move |at| rotation_for(seed, random, location_key(at));
        let inputs = update::UpdateInputs {
            surface: &surface,
            index: ctx.index,
            shape,
            placement: self.params.placement,
            normal_dot: self.params.normal_dot,
            rotation: &rotation,
            align,
            force_seed: self.params.seed_texel == SeedTexel::Forced,
        };
        if !carried {
            let mut chooser = self
                .multi
                .as_ref()
                .map(|m| m.chooser(seed, mesh, radius, &self.state.patches, &out.source));
            let stats = update::cover(
                &template,
                &inputs,
                &mut self.state.patches,
                &mut self.state.next_id,
                &uncovered,
                out,
                chooser.as_mut(),
            );
            counts.created += stats.created;
            counts.forced = stats.forced;
        }
        blended.count_update(&out.source);
        clock.lap("update");
        blended
    }

    /// Erosion carries patches with the mesh velocity: a frame without it is an input error.
    fn require_velocity(&self, ctx: &FrameContext<'_>) -> Result<(), MethodError> {
        match ctx.mesh.velocity() {
            Some(_) => Ok(()),
            None => Err(MethodError::MissingVelocity {
                frame: ctx.number,
                method: self.name(),
            }),
        }
    }

    /// The world axis the exemplar's up follows on new patches, with
    /// aligned orientation.
    fn align_axis(&self) -> Option<glam::Vec3> {
        (self.params.orientation == Orientation::Aligned)
            .then(|| glam::Vec3::from(self.params.up_axis).normalize_or_zero())
    }

    /// w_V of every patch (Eqs. 1-3), progressive (at most
    /// `erosion_rate` · dt lower than the last frame's) when eroding with
    /// progressive weights.
    /// Patches from `first_new_id` on were placed this frame: they showed
    /// nothing the frame before.
    /// With selection by attribute, a vertex whose exemplar no longer
    /// matches falls too, the faster the farther the state is past its
    /// range ([`crate::exemplar::SelectBy::mismatch_drop`]); not on
    /// `advect`, which never lowers a weight.
    fn update_weights(&mut self, ctx: &FrameContext<'_>, shape: &PatchShape, first_new_id: u32) {
        let dt = ctx.dt;
        let max_drop = match (self.rules.erodes, self.params.weights) {
            (true, WeightMode::Progressive) => Some(self.params.erosion_rate * dt),
            _ => None,
        };
        let mismatch = match (&self.multi, self.rules.renews) {
            (Some(m), true) => m.set.by.as_ref().map(|by| {
                let everywhere =
                    (by.values(ctx.mesh)).map_or_else(Vec::new, |v| by.matching_everywhere(v));
                (m, everywhere)
            }),
            _ => None,
        };
        let older = self.transition_frames().saturating_sub(1) as usize;
        self.state.patches.par_iter_mut().for_each(|p| {
            p.remember_weights(older);
            p.update_weights(shape, max_drop);
            if let Some((m, everywhere)) = &mismatch {
                let drops = m.mismatched(p, ctx.mesh, ctx.index, shape.radius, everywhere, dt);
                p.lower_mismatched(&drops);
            }
            if p.id >= first_new_id {
                p.weight_before.clear();
                p.weight_older.clear();
            }
        });
    }

    /// With selection by attribute, the frame's state agreement
    /// ([`crate::methods::lapped::state::state_agreement`]) in its
    /// statistics.
    fn record_state_agreement(&self, ctx: &FrameContext<'_>, result: &mut FrameResult) {
        let Some(by) = self.multi.as_ref().and_then(|m| m.set.by.as_ref()) else {
            return;
        };
        let by_id = exemplars::by_id(&self.state.patches, self.state.next_id);
        crate::methods::lapped::state::record_agreement(ctx, by, result, |id| {
            by_id.get(id as usize).copied()
        });
    }

    /// The erosion tests of this run, built on the first frame with a
    /// surface (they need r/S), and the exemplar set's checks of this mesh.
    fn prepare_tests(
        &mut self,
        ctx: &FrameContext<'_>,
        footprint: f32,
    ) -> Result<ErosionTest, MethodError> {
        if self.test.is_none() {
            self.test = Some(self.erosion_test(footprint, &self.exemplar.feature));
        }
        if let Some(m) = &self.multi {
            m.set
                .check_mesh(ctx.mesh, ctx.number)
                .map_err(MethodError::Input)?;
        }
        if let Some(mut m) = self.multi.take() {
            if m.tests.is_empty() {
                m.tests = (m.set.exemplars().iter())
                    .map(|e| self.erosion_test(footprint, &e.feature))
                    .collect();
            }
            if m.region.is_none() {
                m.region = crate::exemplar::set::RegionBox::of(ctx.mesh);
            }
            self.multi = Some(m);
        }
        Ok(self.test.unwrap_or_else(ErosionTest::never))
    }

    /// The lapped fill (or the blended one), over the candidate pairs of
    /// every patch; returns the texels no patch covered.
    fn fill(
        &self,
        ctx: &FrameContext<'_>,
        fill_ctx: &FillContext<'_>,
        out: &mut FillBuffers,
        counts: &mut StepCounts,
        blended: &mut Blended,
    ) -> Vec<fill::Uncovered> {
        let budget = ctx.arena.memory();
        let candidates = Candidates::build_within(
            fill_ctx.fluid,
            ctx.index,
            fill_ctx.patches,
            fill_ctx.frames,
            fill_ctx.tolerance,
            &|bytes| budget.grow("candidates", bytes),
        );
        counts.candidate_pairs = candidates.len();
        if budget.tripped().is_some() {
            // The list is incomplete and the frame ends on the budget's
            // error ([`Erosion::step`]): no fill to waste time on.
            return Vec::new();
        }
        if self.rules.blends {
            let outcome = blend::fill(fill_ctx, ctx.atlas, &candidates, out);
            blended.layers = Some(outcome.layers);
            blended.used = Some(outcome.used);
            outcome.uncovered
        } else {
            // Looking for each texel's previous holder keeps the triangles
            // that erode this frame.
            // (and those that eroded within the transition).
            let candidates = if out.renewal.is_empty() && fill_ctx.transition == 0 {
                candidates.without_eroded(fill_ctx.verdicts)
            } else {
                let earlier: Vec<&[Vec<erode::Verdict>]> =
                    std::iter::once(fill_ctx.verdicts_before)
                        .chain(fill_ctx.verdicts_older.iter().map(Vec::as_slice))
                        .collect();
                let dead = fill::eroded_at_every_frame(fill_ctx.verdicts, &earlier);
                candidates.without_eroded(&dead)
            };
            let (uncovered, transitions) =
                fill::fill_with_transitions(fill_ctx, ctx.atlas, &candidates, out);
            blended.transitions = transitions;
            uncovered
        }
    }
}
