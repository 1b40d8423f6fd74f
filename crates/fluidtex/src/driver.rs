//! The frame driver: the one loop every front end runs a method through.
//!
//! Per frame it takes the frame's [`FrameGeometry`] (built once: surface
//! index, atlas, topology, vertex normals), hands the method a
//! [`FrameContext`] with this frame and the one before, merges the method's
//! stage timings into the frame's [`StageClock`], dilates the channels into
//! the atlas gutter, and hands the finished frame to a [`FrameSink`]. The
//! driver keeps the previous frame's geometry (shared, not copied), so a
//! method never rebuilds what another stage already has.
//!
//! Three sinks use it: `pipeline::run` writes files (and `bench` reads
//! that run's timings), `eval::evaluate` measures metrics in memory.

use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;
use thiserror::Error;

use crate::atlas::{Atlas, AtlasError, AtlasParams};
use crate::mesh::{Topology, TriMesh, ValidationReport};
use crate::methods::{FrameContext, FrameResult, Method, MethodError};
use crate::surface::SurfaceIndex;

/// Everything about one frame's surface that does not depend on the
/// method, built once per frame.
pub struct FrameGeometry {
    /// The input's frame number.
    pub number: i32,
    pub mesh: TriMesh,
    pub index: SurfaceIndex,
    pub atlas: Atlas,
    pub topology: Topology,
    /// Area-weighted vertex normals ([`TriMesh::vertex_normals`]).
    pub normals: Vec<Vec3>,
    /// What validation dropped or repaired when the frame was read.
    pub report: ValidationReport,
}

impl FrameGeometry {
    /// Builds the frame's surface index, topology and normals (stage
    /// `bvh`) and atlas (stage `atlas`).
    pub fn build(
        number: i32,
        mesh: TriMesh,
        report: ValidationReport,
        atlas: &AtlasParams,
        clock: &mut StageClock,
    ) -> Result<FrameGeometry, DriverError> {
        let index = SurfaceIndex::new(&mesh);
        let topology = Topology::new(mesh.vertex_count(), &mesh.triangles);
        let normals = mesh.vertex_normals();
        clock.lap("bvh");
        let atlas = Atlas::build(&mesh, atlas).map_err(|source| DriverError::Atlas {
            frame: number,
            source,
        })?;
        clock.lap("atlas");
        Ok(FrameGeometry {
            number,
            mesh,
            index,
            atlas,
            topology,
            normals,
            report,
        })
    }

    /// Per-vertex normals of the atlas's output mesh: seam copies share
    /// the normal of their source vertex, so shading is smooth across seams.
    pub fn uv_mesh_normals(&self) -> Vec<Vec3> {
        self.atlas
            .uv_mesh
            .source_vertex
            .iter()
            .map(|&v| self.normals.get(v as usize).copied().unwrap_or(Vec3::Z))
            .collect()
    }
}

/// Records the duration of consecutive stages of one frame.
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

    /// Appends stages timed elsewhere (a method's own clock) and starts
    /// the next stage now.
    pub fn extend(&mut self, stages: &[(&'static str, f64)]) {
        self.stages.extend_from_slice(stages);
        self.last = Instant::now();
    }

    /// Seconds of every stage so far.
    pub fn total(&self) -> f64 {
        self.stages.iter().map(|(_, s)| s).sum()
    }
}

/// Errors of the driver itself (a sink has its own error type, which
/// converts from this one).
#[derive(Debug, Error)]
pub enum DriverError {
    #[error("frame {frame}: {source}")]
    Atlas { frame: i32, source: AtlasError },
    #[error(transparent)]
    Method(#[from] MethodError),
}

/// A frame the method has filled, as handed to a [`FrameSink`].
pub struct DrivenFrame<'a> {
    /// The method that filled the frame (its name, channels and state).
    pub method: &'a dyn Method,
    pub geometry: &'a Arc<FrameGeometry>,
    /// The frame before in this run, where there is one.
    pub previous: Option<&'a FrameGeometry>,
    /// Channels dilated into the gutter.
    pub result: FrameResult,
    /// Stages so far: the caller's (read, bvh, atlas), the method's, dilate.
    pub clock: &'a mut StageClock,
}

/// What happens to each finished frame: files, metrics, timings.
pub trait FrameSink {
    type Error: From<DriverError>;

    fn frame(&mut self, frame: DrivenFrame<'_>) -> Result<(), Self::Error>;
}

/// A frame ready to be driven: its geometry and the clock its building
/// started.
pub struct PendingFrame {
    pub geometry: Arc<FrameGeometry>,
    pub clock: StageClock,
}

/// Runs one method over frames, one at a time.
pub struct Driver<'m> {
    method: &'m mut dyn Method,
    dt: f32,
    dilate_radius: u32,
    previous: Option<Arc<FrameGeometry>>,
}

impl<'m> Driver<'m> {
    /// A driver at `dt` seconds per frame that dilates channels by
    /// `dilate_radius` texels.
    pub fn new(method: &'m mut dyn Method, dt: f32, dilate_radius: u32) -> Driver<'m> {
        Driver {
            method,
            dt,
            dilate_radius,
            previous: None,
        }
    }

    /// The method being driven.
    pub fn method(&self) -> &dyn Method {
        self.method
    }

    /// Sets the frame before the next one (a resumed run re-reads its last
    /// finished frame).
    pub fn set_previous(&mut self, previous: Option<Arc<FrameGeometry>>) {
        self.previous = previous;
    }

    /// The frame before the next one.
    pub fn previous(&self) -> Option<&FrameGeometry> {
        self.previous.as_deref()
    }

    /// Lets the method fill `frame`, dilates, and hands it to `sink`; the
    /// frame becomes the previous one.
    pub fn step<S: FrameSink>(
        &mut self,
        frame: PendingFrame,
        sink: &mut S,
    ) -> Result<(), S::Error> {
        let PendingFrame {
            geometry,
            mut clock,
        } = frame;
        let g = &*geometry;
        if self.method.needs_velocity() && !g.mesh.is_empty() && g.mesh.velocity().is_none() {
            return Err(DriverError::from(MethodError::MissingVelocity {
                frame: g.number,
                method: self.method.name(),
            })
            .into());
        }
        let ctx = FrameContext::new(self.dt, g, self.previous.as_deref());
        let mut result = self.method.step(&ctx).map_err(DriverError::from)?;
        clock.extend(&result.timings);
        for channel in &mut result.channels {
            g.atlas
                .dilate(channel, self.dilate_radius)
                .map_err(|source| DriverError::Atlas {
                    frame: g.number,
                    source,
                })?;
        }
        clock.lap("dilate");
        sink.frame(DrivenFrame {
            method: &*self.method,
            geometry: &geometry,
            previous: self.previous.as_deref(),
            result,
            clock: &mut clock,
        })?;
        self.previous = Some(geometry);
        Ok(())
    }
}

/// Geometry of `meshes` as frames 0, 1, 2, ... (for tests and tools that
/// hold a short clip in memory).
pub fn clip_geometry(
    meshes: Vec<TriMesh>,
    atlas: &AtlasParams,
) -> Result<Vec<Arc<FrameGeometry>>, DriverError> {
    meshes
        .into_iter()
        .enumerate()
        .map(|(k, mesh)| {
            let mut clock = StageClock::default();
            FrameGeometry::build(
                k as i32,
                mesh,
                ValidationReport::default(),
                atlas,
                &mut clock,
            )
            .map(Arc::new)
        })
        .collect()
}

/// The method's raw results (no dilation, no sink) over consecutive
/// `frames`, each after the one before.
pub fn step_clip(
    method: &mut dyn Method,
    frames: &[Arc<FrameGeometry>],
    dt: f32,
) -> Result<Vec<FrameResult>, MethodError> {
    (0..frames.len())
        .map(|k| {
            let previous = k.checked_sub(1).map(|j| &*frames[j]);
            method.step(&FrameContext::new(dt, &frames[k], previous))
        })
        .collect()
}
