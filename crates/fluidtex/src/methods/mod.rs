//! Texturing methods, one module each, behind one interface.
//!
//! A method is given, frame after frame, the fluid mesh (with velocity), its
//! BVH, the previous frame's mesh and the frame's atlas; it updates its own
//! state and fills the atlas channels plus, where it has them, per-texel
//! provenance (source patch and exemplar uv). I/O, atlases, metrics and
//! reports are shared, so a method is one folder here.
//!
//! - [`erosion`]: eroded deformable lapped textures, Gagnon et al. 2021 (default).
//! - [`atlas_check`]: a world-space checker, to look at the atlas chain itself.
//!
//! [`footprint`] is a post-pass of the lapped methods: minified exemplar
//! texels are re-read through the exemplar's mip pyramid.

pub mod atlas_check;
pub mod dual_rest;
pub mod erosion;
pub mod footprint;
pub mod lapped_rigid;

use std::collections::BTreeMap;
use std::time::Instant;

use glam::Vec2;
use thiserror::Error;

use crate::atlas::Atlas;
use crate::mesh::TriMesh;
pub use crate::pipeline::{ChannelFormat, ChannelSpec};
use crate::surface::SurfaceIndex;
use crate::texture::Texture;

/// A frame as methods see it.
pub struct FrameContext<'a> {
    /// The input's frame number.
    pub number: i32,
    /// Seconds per frame (1 / fps).
    pub dt: f32,
    pub mesh: &'a TriMesh,
    pub index: &'a SurfaceIndex,
    /// The frame before, when this is not the first frame of the run.
    pub previous: Option<PreviousFrame<'a>>,
    pub atlas: &'a Atlas,
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
    /// Method statistics for `stats.F.json` (patches alive, created, ...).
    pub stats: BTreeMap<String, serde_json::Value>,
    /// Seconds per stage, in order.
    pub timings: Vec<(&'static str, f64)>,
}

/// Source value of a texel outside every chart.
pub const SOURCE_OUTSIDE: u32 = u32::MAX;
/// Source value of a chart texel nothing covers.
pub const SOURCE_UNCOVERED: u32 = 0;

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
}

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

    /// The state needed to continue after the last step (for `--resume`).
    fn save_state(&self) -> Result<Vec<u8>, MethodError>;

    /// Restores a state written by [`Method::save_state`].
    fn load_state(&mut self, bytes: &[u8]) -> Result<(), MethodError>;
}

/// Records the duration of consecutive stages.
pub struct StageClock {
    last: Instant,
    pub stages: Vec<(&'static str, f64)>,
}

impl Default for StageClock {
    fn default() -> Self {
        StageClock {
            last: Instant::now(),
            stages: Vec::new(),
        }
    }
}

impl StageClock {
    /// Closes the stage that started at the previous call.
    pub fn lap(&mut self, name: &'static str) {
        let now = Instant::now();
        self.stages
            .push((name, now.duration_since(self.last).as_secs_f64()));
        self.last = now;
    }
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
