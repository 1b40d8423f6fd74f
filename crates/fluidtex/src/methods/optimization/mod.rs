//! Texturing fluids by surface texture optimisation with texture
//! transport (Kwatra, Adalsteinsson, Kim, Kwatra, Carlson, Lin 2007;
//! docs/design.md, *The 2007 optimization method*): the optimisation-family
//! baseline. Per frame:
//!
//! 1. [`lattice`]: points over the whole surface at about the target
//!    spacing (the density follows the fluid mesh's triangles within about
//!    a factor of two), connected into a triangle mesh, at `levels` nested
//!    levels (Sec. IV-A; a departure, see `docs/departures.md`); or, with
//!    `placement = "repulsion"`, [`scatter`]: random points spread by
//!    repulsion and re-tiled, the paper's placement.
//! 2. [`transport`]: the previous frame's colours (all channels) and
//!    orientations carried to the new points through the flow (Sec. VI,
//!    Eqs. 3–4): back-tracked through the mesh velocities, or with
//!    `transport = "grid"` advected on a narrow-band grid as the paper
//!    does ([`grid`]).
//! 3. [`orientation`]: the orientation field smoothed coarse to fine
//!    (Sec. IV-B), from the transported field or, on a fresh surface, from
//!    a reference field; by projection, or through [`polar`] maps.
//! 4. [`solve`] with [`neighbourhood`] and [`search`]: E = E_t + E_c
//!    (Eqs. 1–2) minimised by alternating nearest-neighbour search and
//!    averaging, passes of 33², 17², 9² at each level, coarse to fine; the
//!    first frame starts from random exemplar texels over `levels` levels,
//!    later frames from the transported texture on the finest level only
//!    (the paper's footnote 5: one level after the first frame).
//! 5. [`output`]: the point values interpolated into the atlas.
//!
//! **Outputs.** Every exemplar channel is carried by the points and driven
//! by the same matches (the averaging step averages all channels with the
//! colour's weights), so displacement and other extras follow the colour.
//! There is no per-texel provenance: the texture is an average of many
//! exemplar neighbourhoods, not a copy of one, so [`FrameResult::source`]
//! and [`FrameResult::uv`] are `None` (metrics that need them — patch
//! switches, uv distortion — report nothing for this method; colour metrics
//! work as for every method).

pub mod cluster;
#[cfg(test)]
mod cluster_tests;
pub mod grid;
#[cfg(test)]
mod grid_tests;
pub mod histogram;
pub mod lattice;
pub mod level;
pub mod neighbourhood;
pub mod orientation;
pub mod output;
mod params;
pub mod polar;
pub mod scatter;
pub mod search;
pub mod search_bench;
mod selection;
pub mod solve;
pub mod tangent;
pub mod transport;

#[cfg(test)]
mod behaviour_tests;
#[cfg(test)]
mod tests;

use std::sync::Arc;

use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use self::lattice::{Lattice, Level};
use self::neighbourhood::Window;
pub use self::params::{Histogram, OptimizationParams, Placement, Search, Transport};
use self::search::{SearchIndex, WorkingExemplar};
use super::{ChannelSpec, FrameContext, FrameResult, Method, MethodError, StageClock};
use crate::exemplar::Exemplar;
use crate::surface::velocity::{FlowFrame, FlowInterval};
use crate::texture::Texture;

/// What is carried from frame to frame (saved for `--resume`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OptimizationState {
    /// Point spacing h (world units), fixed on the first non-empty frame.
    pub spacing: Option<f32>,
    /// Exemplar width in texels at the finest level, fixed with h.
    pub exemplar_texels: Option<u32>,
    /// Lattice steps per fluid edge of the last frame (0: no texture).
    pub m: u32,
    /// Values of the last frame's points, all channels.
    pub values: Vec<f32>,
    /// Orientation of the last frame's points.
    pub orientation: Vec<[f32; 3]>,
}

impl OptimizationState {
    /// Whether a loaded state is one this method could have saved: a
    /// state file with a valid checksum can still be crafted, and a huge
    /// lattice step or exemplar size would allocate without bound.
    pub fn check(&self) -> Result<(), String> {
        if let Some(h) = self.spacing
            && !(h.is_finite() && h > 0.0)
        {
            return Err(format!("point spacing {h} is not a positive number"));
        }
        if let Some(t) = self.exemplar_texels
            && !(8..=4096).contains(&t)
        {
            return Err(format!("exemplar width {t} texels is outside 8..=4096"));
        }
        if self.m != 0 && !(self.m.is_power_of_two() && self.m <= 128) {
            return Err(format!(
                "{} lattice steps per edge (a power of two up to 128, or 0)",
                self.m
            ));
        }
        if let Some(k) = self.values.iter().position(|v| !v.is_finite()) {
            return Err(format!("point value {k} is not finite"));
        }
        if let Some(k) = (self.orientation.iter()).position(|d| d.iter().any(|x| !x.is_finite())) {
            return Err(format!("point orientation {k} is not finite"));
        }
        Ok(())
    }
}

/// Search structures of one level (the exemplar does not change, so they
/// are built once).
struct LevelSearch {
    exemplar: WorkingExemplar,
    passes: Vec<SearchIndex>,
    quantiles: histogram::Quantiles,
}

/// The 2007 optimisation method.
pub struct Optimization {
    params: OptimizationParams,
    exemplar: Arc<Exemplar>,
    seed: u64,
    state: OptimizationState,
    /// Search structures per level (index = level), built lazily.
    search: Vec<Option<LevelSearch>>,
    /// The last frame's lattice (rebuilt from the previous mesh after a resume).
    last_lattice: Option<Lattice>,
    /// Selecting ([`selection`]): the frame's points are synthesised but
    /// not resampled into the atlas.
    selecting: bool,
    /// The exemplar level the last frame's atlas shows (see
    /// [`Optimization::atlas_output`]).
    last_lod: Option<f32>,
    /// An animated exemplar's frames (empty for a still one), the clock
    /// that picks the one shown and its index: the whole surface shows one
    /// frame (phase 0), since the optimization has no patches to offset.
    frames: Vec<Arc<Exemplar>>,
    clock: crate::exemplar::ExemplarClock,
    shown: usize,
}

impl Optimization {
    pub fn new(
        params: OptimizationParams,
        exemplar: Arc<Exemplar>,
        seed: u64,
    ) -> Result<Optimization, MethodError> {
        params.validate()?;
        Ok(Optimization {
            params,
            exemplar,
            seed,
            state: OptimizationState::default(),
            search: Vec::new(),
            last_lattice: None,
            selecting: false,
            last_lod: None,
            frames: Vec::new(),
            clock: crate::exemplar::ExemplarClock::default(),
            shown: 0,
        })
    }

    /// The method over the exemplar of `set`: its one entry, still
    /// ([`Optimization::new`]) or animated ([`Optimization::with_frames`]).
    pub fn with_set(
        params: OptimizationParams,
        set: &crate::exemplar::ExemplarSet,
        seed: u64,
    ) -> Result<Optimization, MethodError> {
        if !set.is_animated() {
            return Optimization::new(params, Arc::clone(set.primary()), seed);
        }
        let frames = set
            .slots_of(0)
            .filter_map(|s| set.exemplars().get(s).cloned())
            .collect();
        Optimization::with_frames(params, frames, set.clock, seed)
    }

    /// The method over an animated exemplar's `frames`: fluid frame t
    /// synthesises from exemplar frame ⌊t·rate⌋ mod n, starting from the
    /// texture carried from the frame before, so the surface's texture
    /// evolves toward each new frame's neighbourhoods (a dynamic texture,
    /// as in Kwatra et al.'s flow-guided synthesis, Sec. 6).
    pub fn with_frames(
        params: OptimizationParams,
        frames: Vec<Arc<Exemplar>>,
        clock: crate::exemplar::ExemplarClock,
        seed: u64,
    ) -> Result<Optimization, MethodError> {
        let first = frames
            .first()
            .cloned()
            .ok_or_else(|| MethodError::Input("an animated exemplar without frames".into()))?;
        first.build_pyramid();
        let mut m = Optimization::new(params, first, seed)?;
        if frames.len() > 1 {
            m.frames = frames;
            m.clock = clock;
        }
        Ok(m)
    }

    /// Shows the exemplar frame of fluid frame `t`; true when it changed
    /// (its search structures are then rebuilt as they are next needed).
    fn show_frame(&mut self, t: i32) -> bool {
        let n = self.frames.len() as u32;
        if n <= 1 {
            return false;
        }
        let k = self.clock.frame(t, 0.0, n) as usize;
        if k == self.shown {
            return false;
        }
        self.shown = k;
        self.exemplar = Arc::clone(&self.frames[k]);
        self.exemplar.build_pyramid();
        self.search.clear();
        true
    }

    /// The carried state (for tests).
    pub fn state(&self) -> &OptimizationState {
        &self.state
    }

    /// The search structures of `level` (built on first use).
    fn level_search(&mut self, level: usize, texel: f32) -> &LevelSearch {
        if self.search.len() <= level {
            self.search.resize_with(level + 1, || None);
        }
        let n0 = self
            .state
            .exemplar_texels
            .unwrap_or(self.params.exemplar_texels);
        let params = &self.params;
        let exemplar = &self.exemplar;
        self.search[level].get_or_insert_with(|| {
            let width = (n0 >> level).max(8);
            let ex = WorkingExemplar::new(exemplar, width);
            let passes = params
                .sizes
                .iter()
                .map(|&w| {
                    let width = window_width(w, ex.width, ex.height);
                    let grid = match params.search {
                        Search::Pca => params.search_grid.min(width),
                        Search::Exact | Search::Clustered => width,
                    };
                    let window = Window {
                        width,
                        grid,
                        texel,
                        relaxation: params.relaxation,
                    };
                    match params.search {
                        Search::Pca => SearchIndex::new(&ex, window, params.rerank as usize),
                        Search::Exact => SearchIndex::exact(&ex, window),
                        Search::Clustered => {
                            let widest = params.sizes.iter().max().copied().unwrap_or(width);
                            let checks = cluster::checks_for(params.checks, widest, width);
                            SearchIndex::clustered(&ex, window, checks)
                        }
                    }
                })
                .collect();
            LevelSearch {
                quantiles: histogram::Quantiles::new(&ex),
                exemplar: ex,
                passes,
            }
        })
    }

    /// The previous frame's lattice (the cached one when it matches), when
    /// the carried state fits it and its texture can be transported.
    fn previous_lattice(&mut self, ctx: &FrameContext<'_>) -> Option<Lattice> {
        let k = self.exemplar.total_channels();
        let cached = self.last_lattice.take();
        let p = ctx
            .previous
            .filter(|p| !p.mesh.is_empty() && self.state.m > 0)?;
        let l = match cached {
            Some(l) if l.triangles.len() == p.mesh.triangle_count() && l.m == self.state.m => l,
            _ => match self.params.placement {
                Placement::Lattice => Lattice::new(p.mesh, self.state.m),
                Placement::Repulsion => self.points(p.mesh, self.state.spacing?),
            },
        };
        (l.len() * k == self.state.values.len() && l.len() == self.state.orientation.len())
            .then_some(l)
    }

    /// Levels the points are built with: the first frame's or a later
    /// frame's, whichever is more.
    fn point_levels(&self) -> usize {
        (self.params.levels.max(self.params.levels_after_first)) as usize
    }

    /// The frame's points at spacing `h`: a lattice, or scattered points
    /// drawn from the seed and the mesh itself (so the previous frame's
    /// are rebuilt from its mesh alone, after a resume or in a farm's
    /// second phase).
    fn points(&self, mesh: &crate::mesh::TriMesh, h: f32) -> Lattice {
        match self.params.placement {
            Placement::Lattice => Lattice::new(mesh, steps_for(mesh, h)),
            Placement::Repulsion => Lattice::scattered(
                mesh,
                h,
                self.point_levels(),
                mix(self.seed, 0x5ca7, mesh_key(mesh)),
            ),
        }
    }

    /// Every channel resampled from the points into the atlas, and the
    /// exemplar level it shows: the finest working exemplar puts one of its
    /// texels on each point spacing `h`, so an atlas texel holds
    /// (exemplar width / working width) × (atlas texel / h) exemplar texels.
    fn atlas_output(
        &mut self,
        atlas: &crate::atlas::Atlas,
        lattice: &Lattice,
        s: &[f32],
        h: f32,
        result: &mut FrameResult,
    ) {
        self.last_lod = self.search.first().and_then(|s| s.as_ref()).map(|search| {
            let per_point = self.exemplar.size().0 as f32 / search.exemplar.width as f32;
            let points_per_texel = if atlas.scale > 0.0 && h > 0.0 {
                (1.0 / (atlas.scale * h as f64)) as f32
            } else {
                1.0
            };
            (per_point * points_per_texel).log2().max(0.0)
        });
        if !self.selecting {
            self.resample_points(atlas, lattice, s, self.last_lod, result);
        }
    }

    /// Every channel from the points' values, and the level `lod` shown.
    fn resample_points(
        &self,
        atlas: &crate::atlas::Atlas,
        lattice: &Lattice,
        s: &[f32],
        lod: Option<f32>,
        result: &mut FrameResult,
    ) {
        let k = self.exemplar.total_channels();
        result.channels = output::fill(atlas, lattice, s, k, &self.exemplar);
        result.exemplar_lod = lod.map(|lod| output::lod_map(atlas, lod));
    }

    /// A frame where nothing moved ([`is_still`]): the previous frame's
    /// point values as they are. Re-synthesising them would change them
    /// (the averaging and the histogram step are not idempotent), and a
    /// still liquid must keep a still texture, bit for bit.
    fn still_frame(
        &mut self,
        atlas: &crate::atlas::Atlas,
        lattice: Lattice,
        h: f32,
        mut clock: StageClock,
    ) -> FrameResult {
        let mut result = FrameResult::default();
        clock.lap("points");
        let values = std::mem::take(&mut self.state.values);
        self.atlas_output(atlas, &lattice, &values, h, &mut result);
        self.state.values = values;
        clock.lap("output");
        self.lattice_stats(&lattice, h, None, &mut result.stats);
        let stats = &mut result.stats;
        stats.insert("transported".into(), true.into());
        stats.insert("still".into(), true.into());
        self.last_lattice = Some(lattice);
        result.timings = clock.stages;
        result
    }

    /// A frame without surface: empty channels, and no state to carry.
    fn empty_frame(&mut self, atlas: &crate::atlas::Atlas, result: &mut FrameResult) {
        self.state.m = 0;
        self.state.values.clear();
        self.state.orientation.clear();
        self.last_lattice = None;
        result.channels = self.empty_channels(atlas);
        result.stats.insert("points".into(), 0.into());
    }

    /// Every channel of `atlas`, black.
    fn empty_channels(&self, atlas: &crate::atlas::Atlas) -> Vec<Texture> {
        let mut layout = vec![self.exemplar.colour.channels];
        layout.extend(self.exemplar.channels.iter().map(|c| c.texture.channels));
        layout
            .into_iter()
            .map(|c| Texture::filled(atlas.width, atlas.height, c, 0.0))
            .collect()
    }

    /// Point spacing h, fixed on the first frame with a surface: the finer
    /// of the user's point count over the area and one atlas texel; returns
    /// which rule set it on that frame.
    fn spacing(
        &mut self,
        mesh: &crate::mesh::TriMesh,
        atlas: &crate::atlas::Atlas,
    ) -> (f32, Option<&'static str>) {
        if let Some(h) = self.state.spacing {
            return (h, None);
        }
        let area = mesh.area() as f32;
        let by_points = (area * 2.0 / (3f32.sqrt() * self.params.points as f32)).sqrt();
        let by_atlas = if atlas.scale > 0.0 {
            (1.0 / atlas.scale) as f32
        } else {
            0.0
        };
        let (h, rule) = if by_atlas > by_points {
            (by_atlas, "atlas texel")
        } else {
            (by_points, "points")
        };
        self.state.spacing = Some(h);
        self.state.exemplar_texels = Some(match self.params.exemplar_size {
            Some(s) => ((s / h).round() as u32).clamp(8, 4096),
            None => self.params.exemplar_texels,
        });
        (h, Some(rule))
    }

    /// Carries the previous frame's point colours (back-tracked through
    /// the flow) and its coarsest orientations (vector advection) to this
    /// frame's lattice; `None` without a previous frame.
    fn transport(
        &self,
        ctx: &FrameContext<'_>,
        velocity: &[Vec3],
        lattice: &Lattice,
        prev_lattice: &Lattice,
        coarsest: &Level,
        match_distance: f32,
    ) -> Result<Option<Transported>, MethodError> {
        let Some(prev) = ctx.previous else {
            return Ok(None);
        };
        let pv = prev.mesh.velocity().ok_or(MethodError::MissingVelocity {
            frame: ctx.number - 1,
            method: "optimization",
        })?;
        let mesh = ctx.mesh;
        let cur = FlowFrame {
            mesh,
            index: ctx.index,
            velocity,
        };
        let old = FlowFrame {
            mesh: prev.mesh,
            index: prev.index,
            velocity: pv,
        };
        let h = self.state.spacing.unwrap_or(0.0);
        let hint = 4.0 * h.max(mesh.mean_edge_length());
        let back = FlowInterval {
            from: cur,
            to: Some(old),
            dt: -ctx.dt,
            substeps: self.params.substeps,
            search_hint: hint,
        };
        let forward = FlowInterval {
            from: old,
            to: Some(cur),
            dt: ctx.dt,
            substeps: self.params.substeps,
            search_hint: hint,
        };
        let orientation: Vec<Vec3> = (self.state.orientation.iter())
            .map(|&a| Vec3::from(a))
            .collect();
        let previous = transport::Previous {
            mesh: prev.mesh,
            index: prev.index,
            lattice: prev_lattice,
            values: &self.state.values,
            channels: self.exemplar.total_channels(),
            orientation: &orientation,
        };
        if self.params.transport == Transport::Grid && h > 0.0 {
            let (colours, missing, coarse_orientation, grid) = grid::transport(
                &lattice.positions,
                &coarsest.positions,
                &coarsest.normals,
                &old,
                &cur,
                ctx.dt,
                h,
                hint,
                &previous,
            );
            return Ok(Some(Transported {
                colours,
                coarse_orientation,
                missing,
                grid: Some(grid),
            }));
        }
        let (colours, missing) = transport::colours(&lattice.positions, &back, &previous);
        let coarse_orientation = transport::orientations(
            &coarsest.positions,
            &coarsest.normals,
            &back,
            &forward,
            &previous,
            match_distance,
        );
        Ok(Some(Transported {
            colours,
            coarse_orientation,
            missing,
            grid: None,
        }))
    }

    /// Synthesis over `levels`, coarse to fine: each level starts from the
    /// transported colours restricted to it (random exemplar texels on a
    /// first frame) and the values copied up from the coarser level.
    /// Returns the finest level's values and the per-level statistics.
    #[allow(clippy::too_many_arguments)]
    fn synthesise(
        &mut self,
        ctx: &FrameContext<'_>,
        lattice: &Lattice,
        levels: &[Level],
        restricted: Option<&[Vec<f32>]>,
        fine_orientation: &[Vec3],
        h: f32,
        times: &mut solve::SolveTimes,
    ) -> Result<(Vec<f32>, Vec<serde_json::Value>), MethodError> {
        let k = self.exemplar.total_channels();
        let synth_levels = levels.len();
        let mut level_stats = Vec::new();
        let top = synth_levels - 1;
        let mut s: Vec<f32> = match restricted {
            Some(r) => r[top].clone(),
            None => {
                let (seed, frame) = (self.seed, ctx.number as i64 as u64);
                // Building a level's search structures (once a run) counts
                // as search time.
                let t = std::time::Instant::now();
                let search = self.level_search(top, h * (1u32 << top) as f32);
                times.search += t.elapsed().as_secs_f64();
                let ex = &search.exemplar;
                let n = ex.candidates() as u64;
                let lv = &levels[top];
                let mut s = vec![0.0f32; lv.len() * k];
                s.par_chunks_mut(k)
                    .zip(lv.ids.par_iter())
                    .for_each(|(o, &id)| {
                        let pick = mix(seed, frame, id as u64) % n.max(1);
                        let (x, y) = ex.position(pick as u32);
                        o.copy_from_slice(ex.texel(x, y));
                    });
                s
            }
        };
        // A carried frame runs only the last passes (`passes_after_first`).
        let first_pass = match restricted {
            Some(_) => {
                (self.params.sizes.len()).saturating_sub(self.params.passes_after_first as usize)
            }
            None => 0,
        };
        for l in (0..synth_levels).rev() {
            let texel = h * (1u32 << l) as f32;
            let t = std::time::Instant::now();
            self.level_search(l, texel);
            times.search += t.elapsed().as_secs_f64();
            let search = self.search[l]
                .as_ref()
                .ok_or(MethodError::State("search structures missing".into()))?;
            let lv = &levels[l];
            let orient: Vec<Vec3> = lv
                .ids
                .iter()
                .map(|&id| fine_orientation[id as usize])
                .collect();
            let input = solve::LevelInput {
                level: lv,
                orientation: &orient,
                exemplar: &search.exemplar,
                passes: &search.passes[first_pass..],
                transported: restricted.map(|r| r[l].as_slice()),
                coherence: self.params.coherence,
                spacing: self.params.centre_spacing,
                iterations: self.params.iterations,
                convergence: self.params.convergence,
                robust: self.params.robust,
                refine: solve::REFINE_STEPS,
                histogram: (self.params.histogram == Histogram::Matched)
                    .then_some(&search.quantiles),
            };
            let reports = solve::optimise(&input, &mut s, times);
            level_stats.push(serde_json::json!({
                "level": l,
                "points": lv.len(),
                "exemplar_texels": search.exemplar.width,
                "passes": reports.iter().map(|r| serde_json::json!({
                    "width": r.width,
                    "centres": r.centres,
                    "iterations": r.iterations,
                    "energy_start": r.start(),
                    "energy_end": r.end(),
                    "unconverged_matches": r.changed,
                    "prediction_contrast": r.prediction_contrast,
                })).collect::<Vec<_>>(),
            }));
            if l > 0 {
                // Copy up: shared points keep their values, new points take
                // the interpolation of the coarser cell (and, with
                // `upsample_diffusion`, the paper's diffusion after it).
                s = lattice.upsample(lv, &s, k, &levels[l - 1], self.params.upsample_diffusion);
            }
        }
        Ok((s, level_stats))
    }

    /// The points, their spacing h and lattice steps, and the rule that
    /// set h.
    fn lattice_stats(
        &self,
        lattice: &Lattice,
        h: f32,
        spacing_rule: Option<&'static str>,
        stats: &mut std::collections::BTreeMap<String, serde_json::Value>,
    ) {
        stats.insert("points".into(), lattice.len().into());
        stats.insert("lattice_steps".into(), lattice.m.into());
        stats.insert("spacing".into(), serde_json::json!(h));
        if let Some(rule) = spacing_rule {
            stats.insert("spacing_rule".into(), serde_json::json!(rule));
        }
        let texels = self.state.exemplar_texels.unwrap_or(0);
        stats.insert("exemplar_texels".into(), texels.into());
    }

    /// Contrast of the point values (and of the transported texture)
    /// against the working exemplar, into `stats`.
    fn contrast_stats(
        &self,
        s: &[f32],
        transported: Option<&[f32]>,
        stats: &mut std::collections::BTreeMap<String, serde_json::Value>,
    ) {
        let k = self.exemplar.total_channels();
        // Contrast of the point values (and of the transported texture)
        // against the working exemplar: with the atlas contrast of the
        // report, says which stage loses it (synthesis, transport, output).
        let point_contrast = self.search.first().and_then(|x| x.as_ref()).map(|x| {
            let sigma_ex = luminance_sigma(&x.exemplar.data, k, self.exemplar.colour.channels);
            let of = |v: &[f32]| {
                luminance_sigma(v, k, self.exemplar.colour.channels) / sigma_ex.max(1e-12)
            };
            (of(s), transported.map(of))
        });
        if let Some((points, carried)) = point_contrast {
            stats.insert("point_contrast".into(), serde_json::json!(points));
            if let Some(c) = carried {
                stats.insert("transported_contrast".into(), serde_json::json!(c));
            }
        }
    }
}

/// The width of a `w`-wide pass over a `width` × `height` working
/// exemplar: never wider than the exemplar, and odd (so a 33² pass over
/// the 32-texel coarsest level of the default hierarchy is 31²); windows
/// centred near the exemplar's edge read across it, since the exemplar
/// repeats ([`WorkingExemplar::texel`]).
fn window_width(w: u32, width: u32, height: u32) -> u32 {
    let limit = (width.min(height).max(1) - 1) | 1;
    w.min(limit).max(3)
}

/// The hierarchy of a frame: (levels built, levels synthesised). Every
/// frame builds `levels` (with `placement = "repulsion"`, scattering and
/// re-tiling each), since the orientation field is smoothed and
/// transported over the whole hierarchy; only the synthesis of a carried
/// frame keeps to `levels_after_first` (the paper's footnote 5).
fn level_counts(params: &OptimizationParams, carried: bool) -> (usize, usize) {
    let synthesised = if carried {
        params.levels_after_first
    } else {
        params.levels
    } as usize;
    (synthesised.max(params.levels as usize), synthesised)
}

/// Where the orientation field is transported, for point spacing `h` and
/// `levels` built levels: (the level, the length ε of the advected vector).
/// Only the coarsest level is carried (its field is then copied up and
/// re-smoothed, [`orientation::smooth_hierarchy`]), and ε is a quarter of
/// that level's spacing: with three levels, 4 h apart, ε = h.
fn orientation_carry(h: f32, levels: usize) -> (usize, f32) {
    let top = levels.saturating_sub(1);
    (top, 0.25 * h * (1u32 << top) as f32)
}

/// Whether nothing moved since the previous frame: the same mesh, and a
/// velocity of exactly zero on both frames (so transport is the identity).
fn is_still(ctx: &FrameContext<'_>, velocity: &[Vec3]) -> bool {
    let Some(prev) = ctx.previous else {
        return false;
    };
    let zero = |v: &[Vec3]| v.iter().all(|&v| v == Vec3::ZERO);
    prev.mesh.positions == ctx.mesh.positions
        && prev.mesh.triangles == ctx.mesh.triangles
        && zero(velocity)
        && prev.mesh.velocity().is_some_and(zero)
}

/// The previous frame's texture carried to this frame's points.
struct Transported {
    /// Every channel at every lattice point.
    colours: Vec<f32>,
    /// Orientations at the coarsest level's points.
    coarse_orientation: Vec<Vec3>,
    /// Points whose back-tracked position found no previous surface.
    missing: usize,
    /// The grid transport's figures (`transport = "grid"`).
    grid: Option<grid::GridStats>,
}

/// Splits the clock's last stage (synthesis) into building the
/// neighbourhoods (once per pass), the search (query vectors + nearest
/// neighbours) and the solve (z reads, averaging, energies, copying up).
fn split_synthesis(clock: &mut StageClock, times: &solve::SolveTimes) {
    if let Some((_, total)) = clock.stages.pop() {
        let nb = times.neighbourhoods.min(total);
        let search = times.search.min(total - nb);
        clock.stages.push(("neighbourhoods", nb));
        clock.stages.push(("search", search));
        clock.stages.push(("solve", total - nb - search));
    }
}

/// A well-mixed 64-bit value from (seed, stream, index).
fn mix(seed: u64, stream: u64, index: u64) -> u64 {
    super::erosion::mix(seed, stream, index)
}

/// A 64-bit digest of `mesh` (positions and triangles), which seeds its
/// scattered points: the same mesh gets the same points.
fn mesh_key(mesh: &crate::mesh::TriMesh) -> u64 {
    let mut key = mesh.positions.len() as u64;
    for (i, p) in mesh.positions.iter().enumerate() {
        let bits = u64::from(p.x.to_bits()) | (u64::from(p.y.to_bits()) << 32);
        key = mix(key, bits, (i as u64) << 32 | u64::from(p.z.to_bits()));
    }
    for (i, t) in mesh.triangles.iter().enumerate() {
        let bits = u64::from(t[0]) | (u64::from(t[1]) << 32);
        key = mix(key, bits, (i as u64) << 32 | u64::from(t[2]));
    }
    key
}

/// Lattice steps per fluid edge for point spacing `h`: the power of two
/// bringing the mean edge length closest to h (in ratio), at most 128.
pub fn steps_for(mesh: &crate::mesh::TriMesh, h: f32) -> u32 {
    let e = mesh.mean_edge_length();
    if !(e > 0.0 && h > 0.0) {
        return 1;
    }
    let k = (e / h).log2().round().clamp(0.0, 7.0) as u32;
    1 << k
}

/// Standard deviation of the luminance of `k`-float values whose first
/// `colour` floats are the colour (Rec. 709 weights, as the metrics).
fn luminance_sigma(values: &[f32], k: usize, colour: usize) -> f64 {
    let lum = |t: &[f32]| -> f64 {
        if colour >= 3 {
            (0.2126 * t[0] + 0.7152 * t[1] + 0.0722 * t[2]) as f64
        } else {
            t[0] as f64
        }
    };
    let n = (values.len() / k.max(1)).max(1) as f64;
    let mean = values.chunks_exact(k.max(1)).map(lum).sum::<f64>() / n;
    let var = values
        .chunks_exact(k.max(1))
        .map(|t| (lum(t) - mean).powi(2))
        .sum::<f64>()
        / n;
    var.sqrt()
}

/// Values restricted from level 0 down the hierarchy: smoothed on each
/// level, then read at the next level's points.
fn restrict(levels: &[Level], fine: &[f32], k: usize) -> Vec<Vec<f32>> {
    let mut out = vec![fine.to_vec()];
    for l in 1..levels.len() {
        let prev = &levels[l - 1];
        let smooth = prev.smooth(&out[l - 1], k);
        let next = &levels[l];
        let mut v = vec![0.0f32; next.len() * k];
        for (i, &id) in next.ids.iter().enumerate() {
            let j = prev.local[id as usize] as usize;
            v[i * k..i * k + k].copy_from_slice(&smooth[j * k..j * k + k]);
        }
        out.push(v);
    }
    out
}

impl Method for Optimization {
    fn name(&self) -> &'static str {
        "optimization"
    }

    fn memory_model(
        &self,
        atlas: &crate::atlas::AtlasParams,
        _: Option<&crate::mesh::TriMesh>,
    ) -> super::MemoryModel {
        // The points: the target count, exceeded up to 9/4 by the lattice's
        // power-of-two steps, and never much denser than the atlas texels.
        // Each holds its neighbourhood vectors over the hierarchy and the
        // synthesis buffers: measured 1.1 to 1.9 kB per point, besides
        // about 100 MB of search structures and pyramids (Mantaflow splash,
        // 7k to 450k points, atlas 64² to 4096²).
        let texels = u64::from(atlas.width) * u64::from(atlas.height);
        let points = (u64::from(self.params.points) * 9 / 4).min(2 * texels);
        super::MemoryModel {
            fixed: (96 << 20)
                + 1800 * points
                + 2 * self.exemplar.memory_bytes()
                + self.frames.iter().map(|e| e.memory_bytes()).sum::<u64>(),
            // Where the fluid mesh is finer than the spacing its vertices
            // are the points (lattice step 1).
            per_triangle: 1000,
            per_texel: 0,
            // Each thread's neighbourhood gathers and search scratch:
            // measured, the peak grows by 13 MiB per thread from 1 to 16.
            per_thread: 14 << 20,
        }
    }

    fn channel_specs(&self) -> Vec<ChannelSpec> {
        crate::exemplar::channels::exemplar_channels(&self.exemplar)
    }

    fn step(&mut self, ctx: &FrameContext<'_>) -> Result<FrameResult, MethodError> {
        let mut clock = StageClock::default();
        // A new exemplar frame is synthesised even on a still surface.
        let changed = self.show_frame(ctx.number);
        let mesh = ctx.mesh;
        let atlas = ctx.atlas;
        let k = self.exemplar.total_channels();
        let mut result = FrameResult::default();
        if mesh.is_empty() {
            self.empty_frame(atlas, &mut result);
            clock.lap("points");
            result.timings = clock.stages;
            return Ok(result);
        }
        let velocity = mesh.velocity().ok_or(MethodError::MissingVelocity {
            frame: ctx.number,
            method: "optimization",
        })?;

        // 1. Points and hierarchy.
        let (h, spacing_rule) = self.spacing(mesh, atlas);
        let prev_lattice = match self.previous_lattice(ctx) {
            Some(l) if is_still(ctx, velocity) && !changed => {
                return Ok(self.still_frame(atlas, l, h, clock));
            }
            other => other,
        };
        let lattice = self.points(mesh, h);
        let m = lattice.m;
        let carried = prev_lattice.is_some();
        let (all_levels, synth_levels) = level_counts(&self.params, carried);
        let levels: Vec<Level> = (0..all_levels).map(|l| lattice.level(1 << l)).collect();
        clock.lap("points");

        // 2. Transport.
        let (carried_level, epsilon) = orientation_carry(h, all_levels);
        let coarsest = &levels[carried_level];
        let carried_texture = match &prev_lattice {
            Some(l) => self.transport(ctx, velocity, &lattice, l, coarsest, epsilon)?,
            None => None,
        };
        let missing = carried_texture.as_ref().map_or(0, |t| t.missing);
        let grid_stats = carried_texture.as_ref().and_then(|t| t.grid);
        let (transported, coarse_orientation) = match carried_texture {
            Some(t) => (Some(t.colours), Some(t.coarse_orientation)),
            None => (None, None),
        };
        clock.lap("transport");

        // 3. Orientation field: the transported one, or the reference
        // directions on a first frame, smoothed over the hierarchy.
        let fine_orientation = orientation::smooth_hierarchy(
            &lattice,
            &levels,
            coarse_orientation,
            self.params.orientation_iterations,
            self.params.orientation_smoothing,
        );
        clock.lap("orientation");

        // 4. Synthesis, coarse to fine.
        let restricted = transported
            .as_ref()
            .map(|t| restrict(&levels[..synth_levels], t, k));
        let mut times = solve::SolveTimes::default();
        let (s, level_stats) = self.synthesise(
            ctx,
            &lattice,
            &levels[..synth_levels],
            restricted.as_deref(),
            &fine_orientation,
            h,
            &mut times,
        )?;
        clock.lap("synthesis");
        split_synthesis(&mut clock, &times);

        // 5. Atlas.
        self.atlas_output(atlas, &lattice, &s, h, &mut result);
        clock.lap("output");

        self.contrast_stats(&s, transported.as_deref(), &mut result.stats);
        self.lattice_stats(&lattice, h, spacing_rule, &mut result.stats);
        let stats = &mut result.stats;
        stats.insert("transported".into(), carried.into());
        stats.insert("transport_missing".into(), missing.into());
        if let Some(g) = grid_stats {
            stats.insert("transport_grid".into(), g.json());
        }
        stats.insert("levels".into(), serde_json::Value::Array(level_stats));

        self.state.m = m;
        self.state.values = s;
        self.state.orientation = fine_orientation.iter().map(|d| d.to_array()).collect();
        self.last_lattice = Some(lattice);
        result.timings = clock.stages;
        Ok(result)
    }

    fn select(&mut self, ctx: &FrameContext<'_>) -> Result<super::Selection, MethodError> {
        self.select_frame(ctx)
    }

    fn resample(
        &mut self,
        ctx: &FrameContext<'_>,
        selection: &super::Selection,
    ) -> Result<FrameResult, MethodError> {
        self.resample_frame(ctx, selection)
    }

    fn save_state(&self) -> Result<Vec<u8>, MethodError> {
        postcard::to_allocvec(&self.state).map_err(|e| MethodError::State(e.to_string()))
    }

    fn load_state(&mut self, bytes: &[u8]) -> Result<(), MethodError> {
        let state: OptimizationState =
            postcard::from_bytes(bytes).map_err(|e| MethodError::State(e.to_string()))?;
        state.check().map_err(MethodError::State)?;
        self.state = state;
        self.last_lattice = None;
        Ok(())
    }
}
