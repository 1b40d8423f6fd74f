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

use thiserror::Error;

use crate::atlas::{AtlasError, AtlasParams};
use crate::frame::{FrameGeometry, GeometryError, StageClock};
use crate::mesh::{TriMesh, ValidationReport};
use crate::methods::{
    FrameArena, FrameContext, FrameResult, Method, MethodError, Selection, SpentBuffers, Wants,
};

/// Errors of the driver itself (a sink has its own error type, which
/// converts from this one).
#[derive(Debug, Error)]
pub enum DriverError {
    #[error("frame {frame}: {source}")]
    Atlas { frame: i32, source: AtlasError },
    #[error(transparent)]
    Method(#[from] MethodError),
}

impl From<GeometryError> for DriverError {
    fn from(GeometryError { frame, source }: GeometryError) -> DriverError {
        DriverError::Atlas { frame, source }
    }
}

/// A frame the method has filled, as handed to a [`FrameSink`].
pub struct DrivenFrame<'a> {
    /// The method that filled the frame (its name, channels and state).
    pub method: &'a dyn Method,
    pub geometry: &'a Arc<FrameGeometry>,
    /// The frame before in this run, where there is one (shared: a sink
    /// may keep it beyond the call, as the write-behind writer does).
    pub previous: Option<&'a Arc<FrameGeometry>>,
    /// Channels dilated into the gutter.
    pub result: FrameResult,
    /// Stages so far: the caller's (read, bvh, atlas), the method's, dilate.
    pub clock: &'a mut StageClock,
}

/// What happens to each finished frame: files, metrics, timings.
pub trait FrameSink {
    type Error: From<DriverError>;

    fn frame(&mut self, frame: DrivenFrame<'_>) -> Result<(), Self::Error>;

    /// Whether [`FrameSink::frame`] reads the result's per-texel uv and
    /// exemplar levels; when not, the method is not asked for the levels
    /// and the driver keeps the uv for the next frame (its
    /// [`FrameArena`]).
    fn reads_evaluation_buffers(&self) -> bool {
        true
    }

    /// Whether [`FrameSink::frame`] reads the result's renewal bytes (the
    /// forced / unforced split of the switches); when not, the method may
    /// skip recording them.
    fn reads_renewal(&self) -> bool {
        true
    }

    /// The last frame's interleaved channel values, when the sink took what
    /// it needs of them and has no further use for the buffer; the driver
    /// keeps it for the next frame's step (its [`FrameArena`]). The default
    /// keeps nothing back.
    fn spent_values(&mut self) -> Option<Vec<f32>> {
        None
    }
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
    /// The per-texel buffers lent to each frame's step, refilled with what
    /// the sink no longer needs.
    arena: FrameArena,
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
            arena: FrameArena::new(),
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

    /// Sets the memory the stages of the next frames may grow to
    /// ([`crate::methods::budget`]): the run's limit, checked inside the
    /// stages as well as after each frame.
    pub fn set_memory_budget(&mut self, budget: crate::methods::budget::MemoryBudget) {
        self.arena.set_memory(budget);
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
        self.finish_frame(frame, sink, |method, ctx| method.step(ctx))
    }

    /// Phase 1 of a two-phase run: the method advances to `frame` and
    /// returns its selection ([`Method::select`]); nothing is resampled.
    /// The frame becomes the previous one.
    pub fn select(&mut self, frame: &Arc<FrameGeometry>) -> Result<Selection, DriverError> {
        self.check_velocity(frame)?;
        self.arena.memory().start_frame(frame.number);
        let ctx =
            FrameContext::new(self.dt, frame, self.previous.as_deref()).with_arena(&self.arena);
        let selection = self.method.select(&ctx)?;
        self.previous = Some(Arc::clone(frame));
        Ok(selection)
    }

    /// Phase 2: the method resamples `frame` from its `selection`
    /// ([`Method::resample`]), after the frame set with
    /// [`Driver::set_previous`]; then as [`Driver::step`].
    pub fn resample<S: FrameSink>(
        &mut self,
        frame: PendingFrame,
        selection: &Selection,
        sink: &mut S,
    ) -> Result<(), S::Error> {
        self.finish_frame(frame, sink, |method, ctx| method.resample(ctx, selection))
    }

    /// A frame without the velocity the method needs is an input error.
    fn check_velocity(&self, g: &FrameGeometry) -> Result<(), DriverError> {
        if self.method.needs_velocity() && !g.mesh.is_empty() && g.mesh.velocity().is_none() {
            return Err(DriverError::from(MethodError::MissingVelocity {
                frame: g.number,
                method: self.method.name(),
            }));
        }
        Ok(())
    }

    /// The frame's result from `fill`, dilated, handed to `sink`; the
    /// frame becomes the previous one.
    fn finish_frame<S: FrameSink>(
        &mut self,
        frame: PendingFrame,
        sink: &mut S,
        fill: impl FnOnce(&mut dyn Method, &FrameContext<'_>) -> Result<FrameResult, MethodError>,
    ) -> Result<(), S::Error> {
        let PendingFrame {
            geometry,
            mut clock,
        } = frame;
        let g = &*geometry;
        self.check_velocity(g)?;
        self.arena.set_wants(Wants {
            levels: sink.reads_evaluation_buffers(),
            renewal: sink.reads_renewal(),
        });
        self.arena.memory().start_frame(g.number);
        let ctx = FrameContext::new(self.dt, g, self.previous.as_deref()).with_arena(&self.arena);
        let mut result = fill(&mut *self.method, &ctx).map_err(DriverError::from)?;
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
        let mut spent = SpentBuffers::default();
        if !sink.reads_evaluation_buffers() {
            spent.uv = result.uv.take();
            spent.exemplar_lod = result.exemplar_lod.take();
        }
        sink.frame(DrivenFrame {
            method: &*self.method,
            geometry: &geometry,
            previous: self.previous.as_ref(),
            result,
            clock: &mut clock,
        })?;
        spent.values = sink.spent_values();
        self.arena.hand_back(spent);
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
            .map_err(DriverError::from)
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
