//! Dynamic lapped textures with trackers (Gagnon, Dagenais, Paquette 2016),
//! `--method lapped-rigid`: the erosion method's direct ancestor and the
//! baseline the 2021 paper compares against. Per frame:
//!
//! 1. [`trackers`]: advect every tracker P and its tangent tracker T (RK4),
//!    project P onto the new surface, rebuild the rigid local frame; a
//!    tracker that left the surface is deleted (Sec. 3.1.1–3.1.2). On the
//!    first frame, Poisson-disk trackers instead.
//! 2. [`distribution::apply_sink`]: patches whose frame corners all move
//!    inward fade out and are deleted at 0 (Sec. 3.1.3).
//! 3. [`receivers`]: each patch's receiver triangles, connected to the
//!    triangle closest to P and within φ_max of its normal (Sec. 3.2.1).
//! 4. [`composite`]: Algorithm 1, the over operator in layer order, older
//!    patches on top, α = falloff × mask × fade (Sec. 3.3); the falloff of
//!    [`falloff`] is read at each texel's interpolated normal.
//! 5. [`distribution::cover`]: uncovered texels seed new trackers below the
//!    others until every texel is covered; patches nothing showed are
//!    deleted (Sec. 3.1.3).
//!
//! Unlike erosion, a patch never deforms: its uv are an orthographic
//! projection onto its frame, recomputed on each frame's mesh. Where
//! patches overlap with partial α the texture blends (the ghosting the 2021
//! paper removes); the per-texel layer count reports it.
//!
//! Several exemplars per surface (the paper's Sec. 4 extension): each
//! tracker carries the index of its exemplar, chosen at creation by the
//! run's [`ExemplarSet`] strategy ([`crate::exemplar::set`]); its layer
//! reads that exemplar's channels, feature map (for the derived mask) and
//! mip level. With one exemplar none of this runs and the saved state is
//! unchanged; with several the ids follow the tracker state ([`MultiState`]).

pub mod composite;
pub mod distribution;
pub mod falloff;
mod params;
pub mod receivers;
pub mod trackers;

#[cfg(test)]
mod behaviour_tests;
#[cfg(test)]
mod tests;

use std::sync::Arc;

use rand::SeedableRng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use self::composite::{CompositeBuffers, CompositeContext, Layer, MultiComposite};
use self::distribution::{CoverInputs, SinkRule};
use self::falloff::PatchMask;
pub use self::params::LappedRigidParams;
use self::receivers::{ReceiverContext, Receivers};
use self::trackers::Tracker;
pub use super::erosion::SeedTexel;
use super::lapped::state;
use super::{ChannelSpec, FrameContext, FrameResult, Method, MethodError, Selection, StageClock};
use crate::exemplar::set::{Chooser, Coverage, RegionBox, SelectBy};
use crate::exemplar::{Exemplar, ExemplarFilter, ExemplarSelect, ExemplarSet};
use crate::surface::SurfacePoint;
use crate::surface::poisson::sample_mesh;
use crate::surface::velocity::FlowFrame;
use crate::texture::Texture;

/// Tracker state carried from frame to frame (saved for `--resume`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LappedRigidState {
    /// Trackers ordered by id: oldest first (top layer).
    pub trackers: Vec<Tracker>,
    pub next_id: u32,
    /// r and S once resolved from the first non-empty frame.
    pub radius: Option<f32>,
    pub exemplar_size: Option<f32>,
}

impl LappedRigidState {
    /// Whether a loaded state is one this method could have saved (a
    /// state file with a valid checksum can still be crafted): trackers in
    /// id order below `next_id`, finite positions, fades in [0, 1], a
    /// positive radius and exemplar size.
    pub fn check(&self) -> Result<(), String> {
        super::check_scale(self.radius, self.exemplar_size)?;
        let mut last = None;
        for (k, t) in self.trackers.iter().enumerate() {
            super::check_id(k, t.id, &mut last, self.next_id, "tracker")?;
            let finite = [t.position, t.tangent_tracker, t.normal]
                .iter()
                .all(|v| v.is_finite());
            if !finite || !(0.0..=1.0).contains(&t.fade) {
                return Err(format!(
                    "tracker {k} (id {}): a non-finite frame or fade",
                    t.id
                ));
            }
        }
        Ok(())
    }
}

/// The 2016 method.
pub struct LappedRigid {
    params: LappedRigidParams,
    exemplar: Arc<Exemplar>,
    /// The user's mask; `None`: derived once r/S is known.
    mask_image: Option<Texture>,
    seed: u64,
    state: LappedRigidState,
    /// Several exemplars per surface; `None`: one (`exemplar`).
    multi: Option<Multi>,
}

/// The exemplars of a multi-exemplar run.
struct Multi {
    set: Arc<ExemplarSet>,
    /// Where the region image lies, resolved on the first non-empty frame.
    region: Option<RegionBox>,
}

/// The part of the state only a multi-exemplar run has, saved after the
/// tracker state.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MultiState {
    /// Exemplar index of each tracker, in tracker order.
    pub exemplars: Vec<u32>,
    pub region: Option<RegionBox>,
}

impl LappedRigid {
    /// Validates `params` and reads the mask image if one is named (the
    /// error names the file).
    pub fn new(
        params: LappedRigidParams,
        exemplar: Arc<Exemplar>,
        seed: u64,
    ) -> Result<LappedRigid, MethodError> {
        params.validate()?;
        let mask_image = match &params.mask {
            Some(path) => match PatchMask::from_file(path) {
                Ok(PatchMask::Image(t)) => Some(t),
                Ok(_) => None,
                Err(reason) => {
                    return Err(MethodError::InvalidParameter {
                        name: "lapped_rigid.mask",
                        value: reason,
                        allowed: "a readable PNG, JPEG or EXR image",
                    });
                }
            },
            None => None,
        };
        Ok(LappedRigid {
            params,
            exemplar,
            mask_image,
            seed,
            state: LappedRigidState::default(),
            multi: None,
        })
    }

    /// The method over the exemplars of `set`, each patch showing the one
    /// its strategy chose. One exemplar is exactly [`LappedRigid::new`].
    pub fn with_exemplars(
        params: LappedRigidParams,
        set: Arc<ExemplarSet>,
        seed: u64,
    ) -> Result<LappedRigid, MethodError> {
        let mut m = LappedRigid::new(params, Arc::clone(set.primary()), seed)?;
        if set.len() > 1 || set.is_animated() {
            m.multi = Some(Multi { set, region: None });
        }
        Ok(m)
    }

    /// The tracker state (for tests and statistics).
    pub fn state(&self) -> &LappedRigidState {
        &self.state
    }

    /// Replaces the tracker state (tests build hand-made layer stacks).
    pub fn set_state(&mut self, state: LappedRigidState) {
        self.state = state;
    }

    fn mask(&self, radius: f32, exemplar_size: f32) -> PatchMask {
        match &self.mask_image {
            Some(t) => PatchMask::Image(t.clone()),
            None => PatchMask::Derived {
                reach: (radius / exemplar_size).max(1e-6),
                feature_weight: self.params.mask_feature_weight,
                softness: self.params.mask_softness,
            },
        }
    }

    /// The seeded tangent angle of a tracker keyed by `key`.
    fn rotation(seed: u64, random: bool, key: u64) -> f32 {
        if random {
            let bits = super::erosion::mix(seed, 1, key);
            (bits >> 40) as f32 / (1u64 << 24) as f32 * std::f32::consts::TAU
        } else {
            0.0
        }
    }
}

/// A key of a surface location: its triangle and barycentric bits, so a
/// fluid at rest that keeps asking for a tracker at one texel gets the same.
fn location_key(at: SurfacePoint) -> u64 {
    let [a, b, _] = at.bary.map(f32::to_bits);
    super::erosion::mix(at.triangle as u64, a as u64, b as u64)
}

/// What a frame did, for `stats.F.json`.
#[derive(Default, Serialize, Deserialize)]
struct FrameCounts {
    deleted_left: usize,
    deleted_sink: usize,
    sinking: usize,
    created: usize,
    forced: usize,
    unused: usize,
    /// (triangle, patch) receiver pairs.
    pairs: usize,
    /// How r was chosen, on the frame that chose it.
    radius_rule: Option<String>,
}

impl LappedRigid {
    /// Stages 1–2 of the module doc and the first frame's trackers, on a
    /// frame with a surface: what the frame's selection holds. Returns r and
    /// the exemplar size S.
    fn prepare_surface(
        &mut self,
        ctx: &FrameContext<'_>,
        counts: &mut FrameCounts,
        clock: &mut StageClock,
    ) -> Result<(f32, f32), MethodError> {
        let mesh = ctx.mesh;
        let velocity = mesh.velocity().ok_or(MethodError::MissingVelocity {
            frame: ctx.number,
            method: self.name(),
        })?;
        let scale = self.params.scale().resolve(
            mesh,
            &mut self.state.radius,
            &mut self.state.exemplar_size,
        );
        counts.radius_rule = scale.radius_rule;
        let (radius, exemplar_size) = (scale.radius, scale.exemplar_size);
        if let Some(m) = &mut self.multi {
            m.set
                .check_mesh(mesh, ctx.number)
                .map_err(MethodError::Input)?;
            if m.region.is_none() {
                m.region = RegionBox::of(mesh);
            }
        }
        let here = FlowFrame {
            mesh,
            index: ctx.index,
            velocity,
        };
        counts.deleted_left = self.advect(ctx, radius)?;
        clock.lap("advection");
        self.fade_mismatched(ctx, radius);
        (counts.sinking, counts.deleted_sink) = self.sinks(&here, radius, ctx.dt);
        clock.lap("sinks");
        if self.state.trackers.is_empty() {
            counts.created += self.initial_distribution(ctx, radius);
        }
        clock.lap("creation");
        Ok((radius, exemplar_size))
    }

    /// The stages before the composite: on a frame without a surface the
    /// trackers all go; returns r and S where there is one.
    fn prepare(
        &mut self,
        ctx: &FrameContext<'_>,
        counts: &mut FrameCounts,
        clock: &mut StageClock,
    ) -> Result<Option<(f32, f32)>, MethodError> {
        if ctx.mesh.is_empty() {
            counts.deleted_left = self.state.trackers.len();
            self.state.trackers.clear();
            clock.lap("advection");
            return Ok(None);
        }
        self.prepare_surface(ctx, counts, clock).map(Some)
    }

    /// The composite and the coverage update (stages 3–5) from the
    /// prepared trackers, and the deletion of the unused ones: what the
    /// next frame's trackers are. The same in a step, a selection and a
    /// resampled selection.
    fn composite_frame(
        &mut self,
        ctx: &FrameContext<'_>,
        scale: Option<(f32, f32)>,
        counts: &mut FrameCounts,
        clock: &mut StageClock,
    ) -> Result<CompositeBuffers, MethodError> {
        let atlas = ctx.atlas;
        let channels = self.exemplar.total_channels();
        let mut out = CompositeBuffers::new(atlas.width, atlas.height, channels).with_layers();
        let used_ids = match scale {
            Some(scale) => self.composite_and_cover(ctx, scale, &mut out, counts, clock)?,
            None => Vec::new(),
        };
        counts.unused = self.delete_unused(used_ids);
        clock.lap("delete");
        Ok(out)
    }

    /// [`LappedRigid::composite_frame`] and the frame's result: the same in
    /// a one-pass step and in a resampled selection.
    fn finish_frame(
        &mut self,
        ctx: &FrameContext<'_>,
        scale: Option<(f32, f32)>,
        mut counts: FrameCounts,
        mut clock: StageClock,
    ) -> Result<FrameResult, MethodError> {
        let out = self.composite_frame(ctx, scale, &mut counts, &mut clock)?;
        let mut result = self.frame_result(out, &counts);
        self.record_state_agreement(ctx, &mut result);
        result.timings = clock.stages;
        Ok(result)
    }

    /// Stage 1 (Sec. 3.1.1–3.1.2): carries the trackers to this frame and
    /// deletes those that left the surface; returns how many did. A fresh
    /// surface (first frame, or after an empty one) drops them all.
    fn advect(&mut self, ctx: &FrameContext<'_>, radius: f32) -> Result<usize, MethodError> {
        let before = self.state.trackers.len();
        if let Some(prev) = ctx.previous
            && !self.state.trackers.is_empty()
            && !prev.mesh.is_empty()
        {
            if prev.mesh.velocity().is_none() {
                return Err(MethodError::MissingVelocity {
                    frame: ctx.number - 1,
                    method: self.name(),
                });
            }
            if let Some(flow) = ctx.flow(self.params.substeps, 0.25 * radius) {
                let far = if self.params.far_fraction == 0.0 {
                    f32::MAX
                } else {
                    self.params.far_fraction * radius
                };
                let (mesh, index, normals) = (ctx.mesh, ctx.index, ctx.normals);
                let keep: Vec<bool> = self
                    .state
                    .trackers
                    .par_iter_mut()
                    .map(|t| t.advect(&flow, mesh, index, normals, radius, far))
                    .collect();
                let mut k = 0;
                self.state.trackers.retain(|_| {
                    k += 1;
                    keep[k - 1]
                });
            }
        } else if ctx.previous.is_none() || ctx.previous.is_some_and(|p| p.mesh.is_empty()) {
            // A fresh start of the surface: trackers of an older surface cannot be carried.
            self.state.trackers.clear();
        }
        Ok(before - self.state.trackers.len())
    }

    /// With selection by attribute, a patch whose exemplar no longer
    /// matches the attribute at its centre fades at the mismatch rate, as
    /// a sink fades, and goes with the sinks at `keep_weight`: the patches
    /// of the other exemplar, placed where the atlas opens, take over.
    fn fade_mismatched(&mut self, ctx: &FrameContext<'_>, radius: f32) {
        let Some(by) = self.multi.as_ref().and_then(|m| m.set.by.as_ref()) else {
            return;
        };
        let Some(values) = by.values(ctx.mesh) else {
            return;
        };
        let (mesh, index, dt) = (ctx.mesh, ctx.index, ctx.dt);
        let everywhere = by.matching_everywhere(values);
        self.state.trackers.par_iter_mut().for_each(|t| {
            if everywhere.get(t.exemplar as usize) == Some(&true) {
                return;
            }
            // As erosion's weights: the farther the state is past the
            // exemplar's range, the faster the fade.
            let drop = index.closest(t.position, radius).and_then(|h| {
                by.mismatch_drop(t.exemplar, SelectBy::value_at(values, mesh, h.location), dt)
            });
            if let Some(drop) = drop {
                t.fade = (t.fade - drop).max(0.0);
            }
        });
    }

    /// Stage 2 (Sec. 3.1.3): fades the sinks and deletes the invisible
    /// ones; returns (sinking, deleted).
    fn sinks(&mut self, here: &FlowFrame<'_>, radius: f32, dt: f32) -> (usize, usize) {
        let rule = SinkRule {
            radius,
            min_speed: self.params.sink_speed * radius,
            fade_rate: self.params.sink_fade_rate,
            dt,
        };
        let sinking = self
            .state
            .trackers
            .par_iter_mut()
            .map(|t| distribution::apply_sink(t, here, &rule) as usize)
            .sum();
        let alive = self.state.trackers.len();
        // Below keep_weight a patch can no longer count as used: it is gone.
        let keep = self.params.keep_weight.max(f32::MIN_POSITIVE);
        self.state.trackers.retain(|t| t.fade >= keep);
        (sinking, alive - self.state.trackers.len())
    }

    /// Poisson-disk trackers over the whole surface (frame 0, or a surface
    /// that reappears); returns how many.
    fn initial_distribution(&mut self, ctx: &FrameContext<'_>, radius: f32) -> usize {
        let mesh = ctx.mesh;
        let mut rng =
            rand_pcg::Pcg64::seed_from_u64(super::erosion::mix(self.seed, 2, ctx.number as u64));
        let samples = sample_mesh(mesh, radius, self.params.normal_dot, 30.0, &mut rng);
        let first = self.state.next_id;
        let (seed, random) = (self.seed, self.params.random_rotation);
        let normals = ctx.normals;
        let mut new: Vec<Tracker> = samples
            .par_iter()
            .enumerate()
            .map(|(k, s)| {
                let id = first + k as u32;
                let angle = LappedRigid::rotation(seed, random, id as u64);
                Tracker::create(id, mesh, normals, s.location, radius, angle)
            })
            .collect();
        if let Some(m) = &self.multi {
            // In id order, each an equal share for histogram steering.
            let mut c = Chooser::new(&m.set, seed, mesh, m.region, radius);
            for (t, s) in new.iter_mut().zip(&samples) {
                t.exemplar = c.choose(s.location, t.id as u64);
                c.coverage.push(t.position, t.exemplar, 1.0);
            }
        }
        self.state.next_id += new.len() as u32;
        let created = new.len();
        self.state.trackers.extend(new);
        created
    }

    /// Stages 3–5: receivers (Sec. 3.2), Algorithm 1, and the distribution
    /// update (Sec. 3.1.3); returns the ids of the patches shown.
    /// One compositing layer per tracker, oldest first, each with the
    /// exemplar slot it shows on frame `number` (pyramids of animated
    /// exemplars prepared).
    fn layers(&self, number: i32, exemplar_size: f32) -> Vec<Layer> {
        let slot = |t: &Tracker| match &self.multi {
            Some(m) => m.set.slot(t.exemplar, self.seed, u64::from(t.id), number),
            None => t.exemplar,
        };
        let feature_slot = |t: &Tracker| match &self.multi {
            Some(m) => m.set.feature_slot(t.exemplar, self.seed, u64::from(t.id)),
            None => t.exemplar,
        };
        let layers: Vec<Layer> = self
            .state
            .trackers
            .iter()
            .map(|t| Layer {
                id: t.id,
                frame: t.frame(exemplar_size),
                fade: t.fade,
                exemplar: slot(t),
                feature: feature_slot(t),
            })
            .collect();
        if let Some(m) = &self.multi
            && m.set.is_animated()
        {
            m.set.prepare(layers.iter().map(|l| l.exemplar));
        }
        layers
    }

    fn composite_and_cover(
        &mut self,
        ctx: &FrameContext<'_>,
        (radius, exemplar_size): (f32, f32),
        out: &mut CompositeBuffers,
        counts: &mut FrameCounts,
        clock: &mut StageClock,
    ) -> Result<Vec<u32>, MethodError> {
        let mesh = ctx.mesh;
        let rc = ReceiverContext {
            mesh,
            topology: ctx.topology,
            index: ctx.index,
            vertex_normals: ctx.normals,
            radius,
            phi_max: self.params.phi_max.to_radians(),
        };
        let layers = self.layers(ctx.number, exemplar_size);
        let receivers: Vec<Receivers> = layers.par_iter().map(|l| rc.receivers(&l.frame)).collect();
        // The receivers grow with the trackers and the radius: counted
        // against the frame's memory budget (a pair held twice at the
        // peak, 8 bytes each, with spare capacity).
        let held: usize = receivers.iter().map(|r| r.triangles.len()).sum();
        if !ctx.arena.memory().grow("receivers", held * 32) {
            ctx.arena.memory().check()?;
        }
        let lists = composite::layer_lists(&receivers, mesh.triangle_count());
        counts.pairs = lists.len();
        drop(receivers);
        clock.lap("receivers");

        let mask = self.mask(radius, exemplar_size);
        let base_lod_of = |e: &Exemplar| base_lod(e, ctx.atlas, exemplar_size);
        // Held here, so the update below may change the tracker state.
        let exemplar = Arc::clone(&self.exemplar);
        let set = self.multi.as_ref().map(|m| Arc::clone(&m.set));
        let multi_composite = set.as_ref().map(|set| MultiComposite {
            exemplars: set.exemplars(),
            set,
            seed: self.seed,
            frame: ctx.number,
            features: set
                .exemplars()
                .iter()
                .map(|e| e.feature.sampler())
                .collect(),
            base_lods: set.exemplars().iter().map(|e| base_lod_of(e)).collect(),
        });
        let composite = CompositeContext {
            mesh,
            vertex_normals: ctx.normals,
            opaque: self.params.alpha_opaque.to_radians(),
            transparent: self.params.alpha_transparent.to_radians(),
            falloff_at: self.params.falloff_at,
            composite: self.params.composite,
            layers: &layers,
            exemplar: &exemplar,
            mask: &mask,
            feature: exemplar.feature.sampler(),
            base_lod: base_lod_of(&exemplar),
            coverage: self.params.coverage,
            keep_weight: self.params.keep_weight,
            multi: multi_composite.as_ref(),
        };
        let outcome = composite::fill(&composite, ctx.atlas, &lists, out);
        let mut used_ids: Vec<u32> = outcome
            .used
            .iter()
            .map(|&i| layers[i as usize].id)
            .collect();
        drop(lists);
        clock.lap("fill");

        let first_new = self.state.next_id;
        let stats = self.cover(
            &composite,
            &rc,
            (exemplar_size, ctx.number),
            outcome.uncovered,
            out,
        );
        counts.created += stats.created;
        counts.forced = stats.forced;
        // Trackers of the update were created for a texel they now cover.
        used_ids.extend(first_new..self.state.next_id);
        clock.lap("update");
        Ok(used_ids)
    }

    /// Stage 5 (Sec. 3.1.3): new trackers below the others until every
    /// texel is covered.
    fn cover(
        &mut self,
        composite: &CompositeContext<'_>,
        rc: &ReceiverContext<'_>,
        (exemplar_size, frame): (f32, i32),
        uncovered: Vec<composite::Uncovered>,
        out: &mut CompositeBuffers,
    ) -> distribution::CoverStats {
        let (seed, random) = (self.seed, self.params.random_rotation);
        let rotation =
            move |at: SurfacePoint| LappedRigid::rotation(seed, random, location_key(at));
        let inputs = CoverInputs {
            receivers: rc,
            exemplar_size,
            rotation: &rotation,
            placement: match self.params.placement {
                distribution::Placement::First => None,
                distribution::Placement::Random => Some(rand_pcg::Pcg64::seed_from_u64(
                    super::erosion::mix(seed, 6, frame as u64),
                )),
            },
            force_seed: self.params.seed_texel == SeedTexel::Forced,
        };
        let mut chooser = self.multi.as_ref().map(|m| {
            let mut c = Chooser::new(&m.set, seed, rc.mesh, m.region, rc.radius);
            if m.set.select == ExemplarSelect::Histogram {
                c.coverage = coverage(&self.state.trackers, &out.source);
            }
            c
        });
        distribution::cover(
            composite,
            inputs,
            &mut self.state.trackers,
            &mut self.state.next_id,
            uncovered,
            out,
            chooser.as_mut(),
        )
    }

    /// Deletes the patches no texel showed (Sec. 3.1.3); returns how many.
    fn delete_unused(&mut self, mut used_ids: Vec<u32>) -> usize {
        used_ids.sort_unstable();
        used_ids.dedup();
        let alive_before = self.state.trackers.len();
        self.state
            .trackers
            .retain(|t| used_ids.binary_search(&t.id).is_ok());
        alive_before - self.state.trackers.len()
    }

    /// The frame's textures, provenance and statistics.
    fn frame_result(&self, out: CompositeBuffers, counts: &FrameCounts) -> FrameResult {
        let stats = self.frame_stats(&out, counts);
        let filtered = self.exemplar.filter == ExemplarFilter::Trilinear;
        let CompositeBuffers {
            width,
            height,
            values,
            source,
            uv,
            layers,
            lod,
            ..
        } = out;
        FrameResult {
            channels: crate::exemplar::channels::split_interleaved(
                width,
                height,
                values,
                &self.exemplar,
            ),
            exemplar_lod: filtered.then_some(lod),
            stats,
            source: Some(source),
            uv: Some(uv),
            layers: Some(layers),
            ..Default::default()
        }
    }

    fn frame_stats(&self, out: &CompositeBuffers, counts: &FrameCounts) -> super::MethodStats {
        let count = |keep: &dyn Fn(u32) -> bool| out.source.iter().filter(|&&s| keep(s)).count();
        let texels_in_charts = count(&|s| s != super::SOURCE_OUTSIDE);
        let uncovered_after = count(&|s| s == super::SOURCE_UNCOVERED);
        let blended = out.layers.iter().filter(|&&l| l >= 2).count();
        let deleted = counts.deleted_left + counts.deleted_sink + counts.unused;
        let mut stats = super::MethodStats::new();
        stats.insert("patches_alive".into(), self.state.trackers.len().into());
        stats.insert("patches_created".into(), counts.created.into());
        stats.insert("patches_deleted".into(), deleted.into());
        stats.insert("patches_deleted_unused".into(), counts.unused.into());
        stats.insert(
            "patches_deleted_advection".into(),
            counts.deleted_left.into(),
        );
        stats.insert("patches_deleted_sink".into(), counts.deleted_sink.into());
        stats.insert("patches_sinking".into(), counts.sinking.into());
        stats.insert("texels_in_charts".into(), texels_in_charts.into());
        stats.insert("uncovered_texels".into(), uncovered_after.into());
        stats.insert("forced_texels".into(), counts.forced.into());
        stats.insert("blended_texels".into(), blended.into());
        stats.insert("receiver_pairs".into(), counts.pairs.into());
        if let Some(r) = self.state.radius {
            stats.insert("radius".into(), serde_json::json!(r));
        }
        if let Some(rule) = &counts.radius_rule {
            stats.insert("radius_rule".into(), serde_json::json!(rule));
        }
        if let Some(s) = self.state.exemplar_size {
            stats.insert("exemplar_size".into(), serde_json::json!(s));
        }
        if let Some(m) = &self.multi {
            let by_id = self.exemplar_by_id();
            let texels =
                state::texels_per_exemplar(&out.source, m.set.len(), |id| by_id.get(&id).copied());
            stats.insert("exemplar_texels".into(), texels.into());
        }
        stats
    }

    /// Exemplar of each tracker, by id.
    fn exemplar_by_id(&self) -> std::collections::HashMap<u32, u32> {
        self.state
            .trackers
            .iter()
            .map(|t| (t.id, t.exemplar))
            .collect()
    }

    /// With selection by attribute, the frame's state agreement
    /// ([`state::state_agreement`]) in its statistics.
    fn record_state_agreement(&self, ctx: &FrameContext<'_>, result: &mut FrameResult) {
        let Some(by) = self.multi.as_ref().and_then(|m| m.set.by.as_ref()) else {
            return;
        };
        let by_id = self.exemplar_by_id();
        state::record_agreement(ctx, by, result, |id| by_id.get(&id).copied());
    }
}

/// Mip level of an atlas texel seen head-on (log2 of exemplar texels per
/// atlas texel) for exemplar `e` shown at world size `exemplar_size`;
/// `None` when the exemplar is read at level 0.
fn base_lod(e: &Exemplar, atlas: &crate::atlas::Atlas, exemplar_size: f32) -> Option<f32> {
    (e.filter == ExemplarFilter::Trilinear && atlas.scale > 0.0).then(|| {
        let (ew, eh) = e.size();
        let texels_per_world = ew.max(eh) as f32 / exemplar_size;
        (texels_per_world / atlas.scale as f32).log2()
    })
}

impl Method for LappedRigid {
    fn name(&self) -> &'static str {
        "lapped-rigid"
    }

    fn memory_model(
        &self,
        _: &crate::atlas::AtlasParams,
        _: Option<&crate::mesh::TriMesh>,
    ) -> super::MemoryModel {
        let exemplars = (self.multi.as_ref())
            .map_or_else(|| self.exemplar.memory_bytes(), |m| m.set.memory_bytes());
        // Rigid trackers are few and small, but their receiver sets follow
        // the surface: measured, 0.8 kB per triangle with the frames'
        // geometry on 14k–85k triangles from scratch, 2.4 kB over a
        // 48-frame Mantaflow splash. Per texel: the blend's accumulated
        // colour and weight, and the heaviest layer's uv.
        super::MemoryModel {
            fixed: 2 * exemplars,
            per_triangle: 1000,
            per_texel: 24,
            per_thread: 0,
        }
    }

    fn channel_specs(&self) -> Vec<ChannelSpec> {
        crate::exemplar::channels::exemplar_channels(&self.exemplar)
    }

    fn step(&mut self, ctx: &FrameContext<'_>) -> Result<FrameResult, MethodError> {
        let mut clock = StageClock::default();
        let mut counts = FrameCounts::default();
        let scale = self.prepare(ctx, &mut counts, &mut clock)?;
        self.finish_frame(ctx, scale, counts, clock)
    }

    /// The trackers as the frame's composite reads them, carried, faded
    /// and seeded: resampling composites and covers from them, with the
    /// frame's geometry alone.
    fn select(&mut self, ctx: &FrameContext<'_>) -> Result<Selection, MethodError> {
        let mut clock = StageClock::default();
        let mut counts = FrameCounts::default();
        let scale = self.prepare(ctx, &mut counts, &mut clock)?;
        let selected = Selected {
            tag: *SELECTION_TAG,
            scale,
            state: self.save_state()?,
            counts,
        };
        let selection = Selection::encode(self.name(), &selected)?;
        // The composite decides which trackers are made and kept, the
        // state of the next frame; the frame's channels are phase 2's.
        let mut counts = selected.counts;
        self.composite_frame(ctx, scale, &mut counts, &mut clock)?;
        Ok(selection)
    }

    fn resample(
        &mut self,
        ctx: &FrameContext<'_>,
        selection: &Selection,
    ) -> Result<FrameResult, MethodError> {
        let selected: Selected = selection.decode(self.name())?;
        if selected.tag != *SELECTION_TAG {
            return Err(MethodError::selection(self.name(), "another method's"));
        }
        let has_surface = !ctx.mesh.is_empty();
        if selected.scale.is_some() != has_surface {
            let made = if has_surface { "without" } else { "with" };
            return Err(MethodError::selection(
                self.name(),
                format!("frame {}: made for a frame {made} a surface", ctx.number),
            ));
        }
        self.load_state(&selected.state)
            .map_err(|e| MethodError::selection(self.name(), e))?;
        let mut clock = StageClock::default();
        clock.lap("selection");
        self.finish_frame(ctx, selected.scale, selected.counts, clock)
    }

    fn save_state(&self) -> Result<Vec<u8>, MethodError> {
        let state_err = |e: postcard::Error| MethodError::State(e.to_string());
        let mut bytes = postcard::to_allocvec(&self.state).map_err(state_err)?;
        // Several exemplars: their ids follow the tracker state.
        if let Some(m) = &self.multi {
            let multi = MultiState {
                exemplars: self.state.trackers.iter().map(|t| t.exemplar).collect(),
                region: m.region,
            };
            bytes.extend(postcard::to_allocvec(&multi).map_err(state_err)?);
        }
        Ok(bytes)
    }

    fn load_state(&mut self, bytes: &[u8]) -> Result<(), MethodError> {
        let state_err = |e: postcard::Error| MethodError::State(e.to_string());
        let (state, rest) =
            postcard::take_from_bytes::<LappedRigidState>(bytes).map_err(state_err)?;
        state.check().map_err(MethodError::State)?;
        self.state = state;
        if let Some(m) = &mut self.multi {
            let multi: MultiState = if rest.is_empty() {
                MultiState::default()
            } else {
                postcard::from_bytes(rest).map_err(state_err)?
            };
            if multi.exemplars.len() != self.state.trackers.len() {
                return Err(MethodError::State(format!(
                    "{} exemplar ids for {} trackers (a state saved with one exemplar cannot \
                     continue with several)",
                    multi.exemplars.len(),
                    self.state.trackers.len()
                )));
            }
            let n = m.set.len();
            for (t, &e) in self.state.trackers.iter_mut().zip(&multi.exemplars) {
                if e as usize >= n {
                    return Err(MethodError::State(format!(
                        "tracker {} shows exemplar {e}, but {n} exemplars are given",
                        t.id
                    )));
                }
                t.exemplar = e;
            }
            m.region = multi.region;
        }
        Ok(())
    }
}

/// Marks a lapped-rigid selection (another method's bytes are refused).
const SELECTION_TAG: &[u8; 4] = b"LRS1";

/// A frame's selection: the trackers before the composite, and what the
/// stages before it did.
#[derive(Serialize, Deserialize)]
struct Selected {
    tag: [u8; 4],
    /// r and S; `None` on a frame without a surface.
    scale: Option<(f32, f32)>,
    /// [`Method::save_state`]'s bytes.
    state: Vec<u8>,
    counts: FrameCounts,
}

/// The exemplar histogram of the composite: every tracker at P, weighted by
/// the texels whose heaviest layer it is (`source` holds id + 1).
fn coverage(trackers: &[Tracker], source: &[u32]) -> Coverage {
    let mut texels = std::collections::HashMap::<u32, u32>::new();
    for &s in source {
        if s != super::SOURCE_OUTSIDE && s != super::SOURCE_UNCOVERED && s > 0 {
            *texels.entry(s - 1).or_default() += 1;
        }
    }
    let mut c = Coverage::default();
    for t in trackers {
        if let Some(&k) = texels.get(&t.id) {
            c.push(t.position, t.exemplar, k as f32);
        }
    }
    c
}
