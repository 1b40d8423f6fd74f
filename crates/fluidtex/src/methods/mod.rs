//! Texturing methods, one module each, behind one interface.
//!
//! A method is given, frame after frame, the fluid mesh (with velocity), its
//! BVH, the previous frame's mesh and the frame's atlas; it updates its own
//! state and fills the atlas channels plus, where it has them, per-texel
//! provenance (source patch and exemplar uv). I/O, atlases, metrics and
//! reports are shared, so a method is one folder here.
//!
//! - [`erosion`]: eroded deformable lapped textures, Gagnon et al. 2021
//!   (default); its patch machinery also runs two baselines under their
//!   own [`erosion::Rules`]: [`advect`] (the first frame's patches carried,
//!   never renewed) and [`blend_deformable`] (patches alpha-blended by
//!   weight).
//! - [`dual_rest`]: two erosion layers reset in turn and cross-faded.
//! - [`lapped_rigid`]: dynamic lapped textures with trackers, Gagnon et
//!   al. 2016.
//! - [`optimization`]: surface texture optimization with transport,
//!   Kwatra et al. 2007.
//! - [`atlas_check`]: a world-space checker, to look at the atlas chain itself.
//!
//! A frame is *selected* (which source shows at each texel, [`Selection`],
//! serialisable) and *resampled* (every channel from the selection);
//! [`Method::step`] does both in one pass, a two-phase run does them in
//! different processes. The patch methods (erosion's patches, dual-rest's
//! two layers, lapped-rigid's trackers), the optimization (its points'
//! values) and the checker (its cell) select on their own.
//!
//! [`footprint`] is a post-pass of the lapped methods: minified exemplar
//! texels are re-read through the exemplar's mip pyramid. [`lapped`] holds
//! what the patch methods (erosion and its baselines, lapped-rigid) share:
//! per-triangle patch lists, the band walk over the atlas with its
//! deterministic merge, and the bookkeeping of coverage-driven insertion.

pub mod advect;
pub mod arena;
pub mod atlas_check;
pub mod blend_deformable;
pub mod budget;
pub mod dual_rest;
pub mod erosion;
pub mod flags;
pub mod footprint;
pub mod lapped;
pub mod lapped_rigid;
pub mod optimization;
pub mod params;
pub mod registry;
pub mod tone;
#[cfg(test)]
pub mod toy;

#[cfg(test)]
mod animated_tests;
#[cfg(test)]
mod bounded_tests;
#[cfg(test)]
mod multi_tests;
#[cfg(test)]
mod selection_tests;
#[cfg(test)]
mod state_blob_tests;
#[cfg(test)]
mod state_tests;
#[cfg(test)]
pub(crate) mod test_clip;

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use thiserror::Error;

pub use self::arena::{FrameArena, SpentBuffers, Wants};
use crate::atlas::Atlas;
pub use crate::exemplar::channels::{ChannelFormat, ChannelSpec};
use crate::frame::FrameGeometry;
pub use crate::frame::StageClock;
use crate::mesh::{Topology, TriMesh};
use crate::surface::SurfaceIndex;
use crate::surface::velocity::{FlowFrame, FlowInterval};
use crate::texture::Texture;

/// Whether a setting is at its default: the settings added after runs
/// were fingerprinted are left out of the serialized parameters there
/// (`#[serde(skip_serializing_if = "crate::methods::is_default")]`), so
/// earlier runs keep their fingerprint and resume.
pub(crate) fn is_default<T: Default + PartialEq>(value: &T) -> bool {
    *value == T::default()
}

/// A frame as methods see it.
pub struct FrameContext<'a> {
    /// The input's frame number.
    pub number: i32,
    /// Seconds per frame (1 / fps).
    pub dt: f32,
    pub mesh: &'a TriMesh,
    pub index: &'a SurfaceIndex,
    /// The mesh's adjacency, built once per frame by the driver.
    pub topology: &'a Topology,
    /// Area-weighted vertex normals of `mesh`.
    pub normals: &'a [Vec3],
    /// The frame before, when this is not the first frame of the run.
    pub previous: Option<PreviousFrame<'a>>,
    pub atlas: &'a Atlas,
    /// The per-texel buffers lent to this frame's step, and what its
    /// result must carry ([`arena`]).
    pub arena: &'a FrameArena,
}

impl<'a> FrameContext<'a> {
    /// The context of `frame` after `previous`.
    pub fn new(
        dt: f32,
        frame: &'a FrameGeometry,
        previous: Option<&'a FrameGeometry>,
    ) -> FrameContext<'a> {
        FrameContext {
            number: frame.number,
            dt,
            mesh: &frame.mesh,
            index: &frame.index,
            topology: &frame.topology,
            normals: &frame.normals,
            previous: previous.map(|p| PreviousFrame {
                mesh: &p.mesh,
                index: &p.index,
            }),
            atlas: &frame.atlas,
            arena: &arena::FRESH,
        }
    }

    /// The same frame, its buffers lent by `arena`.
    pub fn with_arena(self, arena: &'a FrameArena) -> FrameContext<'a> {
        FrameContext { arena, ..self }
    }

    /// The flow that carries points from the previous frame to this one
    /// (RK4 with `substeps` per frame, closest-point searches starting at
    /// `search_hint`), when both frames have a surface with velocity.
    pub fn flow(&self, substeps: u32, search_hint: f32) -> Option<FlowInterval<'a>> {
        let prev = self.previous?;
        if prev.mesh.is_empty() || self.mesh.is_empty() {
            return None;
        }
        Some(FlowInterval {
            from: FlowFrame {
                mesh: prev.mesh,
                index: prev.index,
                velocity: prev.mesh.velocity()?,
            },
            to: Some(FlowFrame {
                mesh: self.mesh,
                index: self.index,
                velocity: self.mesh.velocity()?,
            }),
            dt: self.dt,
            substeps,
            search_hint,
        })
    }
}

/// The previous frame's surface, which carries the flow to this one.
#[derive(Clone, Copy)]
pub struct PreviousFrame<'a> {
    pub mesh: &'a TriMesh,
    pub index: &'a SurfaceIndex,
}

/// What a method produced for one frame.
#[derive(Debug, Default)]
pub struct FrameResult {
    /// One texture per exemplar channel (colour first), atlas-sized, chart
    /// texels filled, gutter not yet dilated.
    pub channels: Vec<Texture>,
    /// Per texel: [`SOURCE_OUTSIDE`], [`SOURCE_UNCOVERED`] or patch id + 1.
    pub source: Option<Vec<u32>>,
    /// Per texel exemplar uv of the source (NaN where none). A blending
    /// method gives the uv of its heaviest layer.
    pub uv: Option<Vec<Vec2>>,
    /// Per texel, how many layers of normalised weight ≥ 0.05 were blended
    /// (the ghost-fraction input). `None` for methods that never blend:
    /// every covered texel has exactly one layer.
    pub layers: Option<Vec<u8>>,
    /// Per texel, the exemplar mip level its channels were read at
    /// ([`footprint`]; NaN where no source). `None`: every texel was read
    /// at level 0 (unfiltered or blended), as far as the method knows.
    pub exemplar_lod: Option<Vec<f32>>,
    /// Per texel, what became of the patch that showed its point the frame
    /// before ([`crate::provenance::RENEWAL_HELD`] and the other flags):
    /// whether a source switch there was forced by the flow. `None` for
    /// methods that do not track it.
    pub renewal: Option<Vec<u8>>,
    /// Method statistics for `stats.F.json` (patches alive, created, ...).
    pub stats: MethodStats,
    /// Seconds per stage, in order.
    pub timings: Vec<(&'static str, f64)>,
}

pub use crate::provenance::{SOURCE_OUTSIDE, SOURCE_UNCOVERED};

/// A method statistic of `stats.F.json`, by key: the one spelling that
/// methods write and front ends, reports and the harness read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stat {
    PatchesAlive,
    PatchesCreated,
    PatchesDeleted,
    PatchesDeletedUnused,
    PatchesDeletedAdvection,
    TexelsInCharts,
    UncoveredTexels,
    ForcedTexels,
    CandidatePairs,
    /// Patch triangles dropped this frame because the erosion test can
    /// never show a texel of them again.
    TrianglesPruned,
    /// Triangles held by all live patches after the frame.
    PatchTriangles,
    /// Patch radius r in world units.
    Radius,
    /// Why the default radius is what it is (a sentence).
    RadiusRule,
    /// World size S covered by the exemplar's [0, 1]² (the distortion
    /// metric's rest scale).
    ExemplarSize,
    /// dual-rest: the weight of layer A in the mix.
    WeightA,
    /// With selection by attribute: the share of covered texels whose
    /// exemplar matches the attribute there.
    StateAgreement,
    /// The same over the covered texels whose attribute is decisive: at
    /// least [`crate::exemplar::select_by::DECISIVE_MARGIN`] of the
    /// ranges' span from every split between ranges.
    StateAgreementDecisive,
}

crate::named!(Stat {
    PatchesAlive => "patches_alive",
    PatchesCreated => "patches_created",
    PatchesDeleted => "patches_deleted",
    PatchesDeletedUnused => "patches_deleted_unused",
    PatchesDeletedAdvection => "patches_deleted_advection",
    TexelsInCharts => "texels_in_charts",
    UncoveredTexels => "uncovered_texels",
    ForcedTexels => "forced_texels",
    CandidatePairs => "candidate_pairs",
    TrianglesPruned => "triangles_pruned",
    PatchTriangles => "patch_triangles",
    Radius => "radius",
    RadiusRule => "radius_rule",
    ExemplarSize => "exemplar_size",
    WeightA => "weight_a",
    StateAgreement => "state_agreement",
    StateAgreementDecisive => "state_agreement_decisive",
});

/// Method statistics as written to `stats.F.json`: typed keys, JSON values.
pub type MethodStats = BTreeMap<String, serde_json::Value>;

/// Typed access to [`MethodStats`].
pub trait StatsExt {
    fn set(&mut self, key: Stat, value: impl Into<serde_json::Value>);
    fn value(&self, key: Stat) -> Option<&serde_json::Value>;
    fn number(&self, key: Stat) -> Option<f64> {
        self.value(key).and_then(serde_json::Value::as_f64)
    }
    fn text(&self, key: Stat) -> Option<&str> {
        self.value(key).and_then(serde_json::Value::as_str)
    }
}

impl StatsExt for MethodStats {
    fn set(&mut self, key: Stat, value: impl Into<serde_json::Value>) {
        use crate::named::Named;
        self.insert(key.name().to_string(), value.into());
    }

    fn value(&self, key: Stat) -> Option<&serde_json::Value> {
        use crate::named::Named;
        self.get(key.name())
    }
}

/// Errors of a method's frame step or state handling.
#[derive(Debug, Error)]
pub enum MethodError {
    #[error("frame {frame}: the mesh has no per-vertex velocity, which the {method} method needs")]
    MissingVelocity { frame: i32, method: &'static str },
    #[error("parameter {name} = {value} is out of range (allowed: {allowed})")]
    InvalidParameter {
        name: &'static str,
        value: String,
        allowed: &'static str,
    },
    #[error("saved state cannot be read: {0}")]
    State(String),
    /// Input a method cannot use, said in one line naming the frame and
    /// element (e.g. a per-vertex `exemplar_id` naming no exemplar).
    #[error("{0}")]
    Input(String),
    /// A stage of the frame grew past the run's memory limit
    /// ([`budget::MemoryBudget`]); the run reports it as its memory error.
    #[error(
        "memory: about {} bytes during frame {}'s {} (limit {} bytes)",
        .0.resident, .0.frame, .0.stage, .0.limit
    )]
    Memory(budget::Trip),
}

impl MethodError {
    /// A selection of `method` that does not read, in one line.
    pub fn selection(method: &str, e: impl std::fmt::Display) -> MethodError {
        MethodError::State(format!("{method} selection: {e}"))
    }
}

/// What a method holds in memory besides the per-texel result every
/// method returns (channels and source ids), for the estimate a run makes
/// before its first frame ([`crate::output::estimate_memory`]). Each
/// method's figures come from measured peaks; the default is the patch
/// methods' (the largest).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryModel {
    /// Bytes held whatever the surface (exemplars beyond the built-in one,
    /// search structures, synthesis points).
    pub fixed: u64,
    /// Bytes per triangle of the largest frame at the peak of a frame
    /// (patch geometry, candidate pairs), besides the frames' geometry.
    pub per_triangle: u64,
    /// Bytes per atlas texel besides the result's channels and ids (uv,
    /// exemplar level, renewal flags, blend weights).
    pub per_texel: u64,
    /// Bytes per worker thread besides the 4 MiB every run counts
    /// (per-thread scratch of the method's parallel stages).
    pub per_thread: u64,
}

impl Default for MemoryModel {
    /// The patch methods': see [`erosion::Erosion`]'s model.
    fn default() -> MemoryModel {
        MemoryModel {
            fixed: 0,
            per_triangle: PATCH_BYTES_PER_TRIANGLE,
            per_texel: 13,
            per_thread: 0,
        }
    }
}

/// Bytes per surface triangle a patch method holds at the peak of a frame:
/// its patch triangles (3 to 10 per surface triangle, each with its
/// vertices, weights and flattened uv) and the fill's candidate pairs (40
/// to 70 per surface triangle). Measured on a Mantaflow splash: 3.5 kB per
/// triangle over a 48-frame run, 4.5 kB when a run starts at the splash's
/// largest frame (85k triangles), where every patch is created at once.
pub const PATCH_BYTES_PER_TRIANGLE: u64 = 3700;

/// One texturing method.
pub trait Method: Send {
    /// The name used on the command line.
    fn name(&self) -> &'static str;

    /// Whether frames must carry per-vertex velocity.
    fn needs_velocity(&self) -> bool {
        true
    }

    /// Names and formats of the channels [`Method::step`] returns, in order.
    fn channel_specs(&self) -> Vec<ChannelSpec>;

    /// Advances to `frame` and fills its atlas.
    fn step(&mut self, frame: &FrameContext<'_>) -> Result<FrameResult, MethodError>;

    /// Phase 1 of a two-phase run: advances to `frame` as [`Method::step`]
    /// does and returns the frame's [`Selection`] (which source shows at
    /// each texel, serialised), not its channels. The default replays:
    /// the selection is the state before the frame, and
    /// [`Method::resample`] runs the whole step again from it.
    fn select(&mut self, frame: &FrameContext<'_>) -> Result<Selection, MethodError> {
        let before = self.save_state()?;
        self.step(frame)?;
        Ok(Selection::Replay(before))
    }

    /// Phase 2: the result of `frame` from its [`Selection`], written by
    /// [`Method::select`] of a method built with the same settings (in
    /// this process or another). The files made of it are those of a
    /// one-pass run. A replayed selection needs `frame.previous`.
    fn resample(
        &mut self,
        frame: &FrameContext<'_>,
        selection: &Selection,
    ) -> Result<FrameResult, MethodError> {
        match selection {
            Selection::Replay(before) => {
                self.load_state(before)?;
                self.step(frame)
            }
            Selection::Own(_) => Err(MethodError::State(format!(
                "frame {}: the selection is not one the {} method writes",
                frame.number,
                self.name()
            ))),
        }
    }

    /// The state needed to continue after the last step (for `--resume`).
    fn save_state(&self) -> Result<Vec<u8>, MethodError>;

    /// Restores a state written by [`Method::save_state`].
    fn load_state(&mut self, bytes: &[u8]) -> Result<(), MethodError>;

    /// What the method holds in memory at the peak of a frame with an atlas
    /// of `atlas`, for the estimate made before the first frame; `largest`
    /// is the largest frame's mesh where the source could tell.
    fn memory_model(
        &self,
        atlas: &crate::atlas::AtlasParams,
        largest: Option<&crate::mesh::TriMesh>,
    ) -> MemoryModel {
        let _ = (atlas, largest);
        MemoryModel::default()
    }

    /// The method's own account of its largest structures, for the
    /// message of a run stopped by its memory limit (e.g. "370 patches,
    /// 1.2 M patch triangles, 3.9 GiB of patch geometry"); `None` where
    /// nothing it keeps grows with the run.
    fn memory_report(&self) -> Option<String> {
        None
    }
}

/// A frame's selection, serialised: what a later process needs, besides
/// the frame's geometry, to resample the frame into the bytes of a
/// one-pass run ([`Method::select`], [`Method::resample`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Selection {
    /// The method's own compact selection (for the patch methods: the
    /// patches, their geometry and weights, as the frame's fill reads
    /// them): resampled from the frame's geometry alone.
    Own(Vec<u8>),
    /// The method's state before the frame: resampling replays the
    /// frame's whole step, so it needs the frame before's geometry too.
    Replay(Vec<u8>),
}

impl Selection {
    /// Whether resampling needs the frame before ([`Selection::Replay`]).
    pub fn needs_previous(&self) -> bool {
        matches!(self, Selection::Replay(_))
    }

    /// The bytes of a method's own selection; a replayed one is refused in
    /// one line naming `method`, which writes only its own.
    pub fn own(&self, method: &str) -> Result<&[u8], MethodError> {
        match self {
            Selection::Own(bytes) => Ok(bytes),
            Selection::Replay(_) => Err(MethodError::selection(
                method,
                format!("a replayed one, which {method} does not write"),
            )),
        }
    }

    /// [`Selection::own`], taking the bytes.
    pub fn into_own(self, method: &str) -> Result<Vec<u8>, MethodError> {
        match self {
            Selection::Own(bytes) => Ok(bytes),
            replayed => replayed.own(method).map(<[u8]>::to_vec),
        }
    }

    /// `selected` as `method`'s own selection (postcard).
    pub fn encode<T: Serialize>(method: &str, selected: &T) -> Result<Selection, MethodError> {
        postcard::to_allocvec(selected)
            .map(Selection::Own)
            .map_err(|e| MethodError::selection(method, e))
    }

    /// What [`Selection::encode`] wrote for `method`; a replayed or
    /// damaged selection is refused in one line.
    pub fn decode<T: serde::de::DeserializeOwned>(&self, method: &str) -> Result<T, MethodError> {
        postcard::from_bytes(self.own(method)?).map_err(|e| MethodError::selection(method, e))
    }

    /// The serialised bytes, whichever the kind.
    pub fn bytes(&self) -> &[u8] {
        match self {
            Selection::Own(b) | Selection::Replay(b) => b,
        }
    }
}

/// A `channels`-channel texture of the atlas's size with every chart texel
/// set by `paint(span, barycentrics, texel)` (0 elsewhere), and its source
/// map: 1 at chart texels (one source for the whole surface, never
/// uncovered), [`SOURCE_OUTSIDE`] elsewhere. For methods that paint the
/// surface directly, without patches.
pub(crate) fn paint_charts(
    atlas: &crate::atlas::Atlas,
    channels: usize,
    paint: impl Fn(&crate::atlas::Span, [f32; 3], &mut [f32]) + Sync,
) -> (crate::texture::Texture, Vec<u32>) {
    use rayon::prelude::*;
    let w = atlas.width as usize;
    let mut texture = crate::texture::Texture::filled(atlas.width, atlas.height, channels, 0.0);
    let mut source = vec![SOURCE_OUTSIDE; w * atlas.height as usize];
    if let Some(first) = atlas.bands().first() {
        let rows = (first.y1 - first.y0) as usize;
        texture
            .data
            .par_chunks_mut(rows * w * channels)
            .zip(source.par_chunks_mut(rows * w))
            .zip(atlas.bands().par_iter())
            .for_each(|((data, src), band)| {
                for span in &band.spans {
                    let row = (span.y - band.y0) as usize * w;
                    for (x, bary) in atlas.span_barycentrics(span) {
                        let t = row + x as usize;
                        paint(span, bary, &mut data[t * channels..(t + 1) * channels]);
                        src[t] = 1;
                    }
                }
            });
    }
    (texture, source)
}

/// Checks `lo <= value <= hi` for a parameter.
pub(crate) fn check_range(
    name: &'static str,
    value: f32,
    lo: f32,
    hi: f32,
    allowed: &'static str,
) -> Result<(), MethodError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(MethodError::InvalidParameter {
            name,
            value: value.to_string(),
            allowed,
        })
    }
}

/// [`check_range`] over rows of (name, value, lo, hi, allowed), in order:
/// the first failing row is the error.
pub(crate) fn check_ranges(
    rows: &[(&'static str, f32, f32, f32, &'static str)],
) -> Result<(), MethodError> {
    rows.iter()
        .try_for_each(|&(name, v, lo, hi, allowed)| check_range(name, v, lo, hi, allowed))
}

/// A loaded state's patch or tracker radius and exemplar size: positive
/// and finite where resolved.
pub(crate) fn check_scale(radius: Option<f32>, exemplar_size: Option<f32>) -> Result<(), String> {
    for (name, v) in [("radius", radius), ("exemplar size", exemplar_size)] {
        if let Some(v) = v
            && !(v.is_finite() && v > 0.0)
        {
            return Err(format!("{name} {v} is not a positive number"));
        }
    }
    Ok(())
}

/// The `k`-th id of a loaded state's patch list (`what`: patch, tracker):
/// above the one before (`last`, updated), below `next_id`.
pub(crate) fn check_id(
    k: usize,
    id: u32,
    last: &mut Option<u32>,
    next_id: u32,
    what: &str,
) -> Result<(), String> {
    if id >= next_id || last.is_some_and(|l| id <= l) {
        return Err(format!(
            "{what} {k} has id {id}, out of order or not below the next id {next_id}"
        ));
    }
    *last = Some(id);
    Ok(())
}
