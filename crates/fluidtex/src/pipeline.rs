//! The frame job: read a frame, build its BVH and atlas, let the method
//! fill the atlas, dilate, write every output atomically, save the method's
//! state; repeat. Frames are streamed (at most the previous and the current
//! mesh are held), so memory does not grow with the sequence length.
//!
//! Resume: after all outputs of frame F are written, `state.bin` is replaced
//! (atomically) by the method state after F. `--resume` reads it, re-reads
//! frame F as the previous frame and continues with F+1; because the state
//! is the whole carried state and every RNG stream is derived from (seed,
//! frame or patch id), the files are the same as those of an uninterrupted run.
//!
//! Robustness: a run holds the output folder's lock ([`crate::io::lock`])
//! from start to end, so a second run into the same folder refuses at once.
//! The files of a frame are staged and renamed together
//! ([`crate::io::Staging`]) before `state.bin` counts the frame finished: a
//! full disk mid-frame leaves none of that frame's files and the previous
//! state, and `--resume` (after space is freed) writes exactly the files of
//! an uninterrupted run. Before any frame is read the run estimates the
//! memory it needs ([`estimate_memory`]) and refuses when the machine has
//! less available.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use std::sync::Arc;

use crate::atlas::{AtlasError, AtlasParams};
use crate::coherence::Departure;
use crate::driver::{DrivenFrame, Driver, DriverError, FrameSink, PendingFrame};
use crate::frame::{FrameGeometry, GeometryError, StageClock};
use crate::io::image::{ExrOptions, ExrSample, PngDepth, PngOptions};
use crate::io::{InputGuard, IoError, Staging, WriteHook};
use crate::mesh::{TriMesh, ValidationReport};
use crate::methods::{Method, MethodError, SOURCE_OUTSIDE, SOURCE_UNCOVERED};
use crate::render::{self, Camera};
use crate::surface::SurfacePoint;
use crate::texture::Texture;
use glam::Vec3;
use rayon::prelude::*;

pub use crate::exemplar::channels::{ChannelFormat, ChannelSpec};

/// Which files are written per frame besides the channel atlases.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OutputOptions {
    /// `mesh.F.obj` + `mesh.F.mtl` [true].
    pub obj: bool,
    /// `mesh.F.glb` [true].
    pub glb: bool,
    /// `patches.F.png`, `source.F.exr` and the coherence numbers of
    /// `stats.F.json` [true].
    pub debug: bool,
    /// Write `preview.F.png` every this many frames (0: never) \[0].
    pub preview_every: u32,
    /// Preview width in pixels \[512].
    pub preview_size: u32,
    /// With `debug`: also `switch.F.png`, the per-texel switch map \[false].
    /// It carries every covered texel back to the frame before (two
    /// closest-point queries each: about 48 s per frame at 6144² on two
    /// cores), so it is written only when asked; the share in
    /// `stats.F.json` comes from 20 000 sampled points either way. Left out
    /// of the settings' fingerprint when off, so older runs resume.
    #[serde(skip_serializing_if = "is_false")]
    pub switch_map: bool,
}

fn is_false(b: &bool) -> bool {
    !*b
}

impl Default for OutputOptions {
    fn default() -> Self {
        OutputOptions {
            obj: true,
            glb: true,
            debug: true,
            preview_every: 0,
            preview_size: 512,
            switch_map: false,
        }
    }
}

/// Where frames come from: a file sequence or a generated scene.
pub trait FrameSource {
    /// The frame numbers to process, in order.
    fn frames(&self) -> Vec<i32>;
    /// Reads frame `f`. Frames are requested in increasing order, except
    /// that on resume the last finished frame is read once first.
    fn read(&mut self, f: i32) -> Result<(TriMesh, ValidationReport), PipelineError>;
    /// Input files (never overwritten by outputs).
    fn input_paths(&self) -> Vec<PathBuf> {
        Vec::new()
    }
}

/// A frame job.
#[derive(Clone, Debug)]
pub struct Job {
    pub out_dir: PathBuf,
    pub atlas: AtlasParams,
    /// Frames per second of the input \[24].
    pub fps: f32,
    pub outputs: OutputOptions,
    /// Continue from `state.bin` in `out_dir`.
    pub resume: bool,
    /// Identifies the configuration; a resumed run must match it.
    pub fingerprint: String,
    /// Test hooks; front ends leave them at their default (none).
    pub hooks: TestHooks,
}

/// Hooks that let tests stop a run at an exact point instead of racing it.
#[derive(Clone, Default)]
pub struct TestHooks {
    /// Called in every atomic write of the run (see [`WriteHook`]); writes
    /// are counted in a fixed order, so "the Nth write" is the same file in
    /// every run of the same job.
    pub write: Option<WriteHook>,
    /// Memory available to the run in bytes, instead of the machine's
    /// `MemAvailable`, for testing the up-front memory check.
    pub available_memory: Option<u64>,
    /// Called with the frame's number once its files and `state.bin` are
    /// committed, on the thread that wrote them (before it takes the next
    /// frame): a test that pauses here knows exactly which files exist.
    pub after_frame: Option<FrameHook>,
    /// Write each frame before computing the next, as a run without the
    /// memory for write-behind does (tests compare the two).
    pub write_in_place: bool,
}

/// See [`TestHooks::after_frame`].
pub type FrameHook = Arc<dyn Fn(i32) + Send + Sync>;

impl std::fmt::Debug for TestHooks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TestHooks")
            .field("write", &self.write.as_ref().map(|_| "hook"))
            .field("available_memory", &self.available_memory)
            .field("after_frame", &self.after_frame.as_ref().map(|_| "hook"))
            .field("write_in_place", &self.write_in_place)
            .finish()
    }
}

/// Errors of the frame job.
#[derive(Debug, Error)]
pub enum PipelineError {
    #[error(transparent)]
    Io(#[from] IoError),
    #[error("frame {frame}: {source}")]
    Atlas { frame: i32, source: AtlasError },
    /// Atlas parameters refused before any frame is read.
    #[error("{0}")]
    AtlasParams(AtlasError),
    #[error(transparent)]
    Method(#[from] MethodError),
    #[error("{0}")]
    Source(String),
    #[error("{path}: {message}")]
    Output { path: PathBuf, message: String },
    #[error("cannot resume: {0}")]
    Resume(String),
    #[error(
        "a {width}x{height} atlas needs about {} of memory and {} is available: \
         lower --atlas (at most {fits} fits)",
        gib(*.needed), gib(*.available)
    )]
    Memory {
        width: u32,
        height: u32,
        needed: u64,
        available: u64,
        fits: u32,
    },
}

/// Per-frame numbers, also written as `stats.F.json`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct FrameStats {
    pub frame: i32,
    pub method: String,
    pub vertices: usize,
    pub triangles: usize,
    pub dropped_degenerate: usize,
    pub charts: usize,
    pub atlas_width: u32,
    pub atlas_height: u32,
    /// Share of atlas texels inside charts: how tightly the packer filled
    /// the atlas (the rest is gutter and space between charts).
    pub atlas_fill: f64,
    /// Share of surface points carried by the velocity from the previous
    /// frame, with a patch at both ends, whose patch changed
    /// ([`crate::coherence`]); with debug outputs, when the method gives
    /// per-texel sources and both frames have velocity. `null`: nothing
    /// was covered.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source_switch_share: Option<f64>,
    /// Of the same points with a patch at either frame, the share whose
    /// patch changed: switched, now over a hole, or come from one
    /// ([`crate::metrics::SourceSwitch::changed_share`]): what compares a
    /// method that leaves holes with one that fills them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source_changed_share: Option<f64>,
    /// Of the points of `source_switch_share`, the share that switched
    /// because the flow forced it: the patch that showed the point the
    /// frame before is stretched past δ_max there, or none showed it
    /// ([`crate::metrics::SwitchCauses`]); methods that record each texel's
    /// previous patch only (erosion, advect).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch_forced_share: Option<f64>,
    /// The share that switched though the patch of the frame before is
    /// within δ_max there: switches the method chose, not the flow.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch_unforced_share: Option<f64>,
    /// The share whose patch of the frame before is past δ_max there,
    /// switched or not; on `advect`, which never renews, the share of the
    /// surface the distortion bound would renew (the renewal floor).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holder_distorted_share: Option<f64>,
    /// The same points by the region they land in: `bulk`, `sheet` (liquid
    /// thinner than r/2 under the point) and `droplet` (a piece of surface
    /// smaller than a disc of radius r), each with its number of points
    /// covered at both ends and its switch, forced and unforced shares
    /// ([`crate::coherence::regions`]); methods with a patch radius only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch_by_region: Option<BTreeMap<&'static str, crate::coherence::regions::RegionSwitch>>,
    /// Colour follow ratio over the same points (see
    /// [`crate::metrics::colour_follow`]); `null` when too few points moved.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub colour_follow_ratio: Option<f64>,
    #[serde(flatten)]
    pub method_stats: BTreeMap<String, serde_json::Value>,
    /// Seconds per stage: read, bvh, atlas, the method's stages, dilate, write.
    pub seconds: BTreeMap<String, f64>,
    /// Stage names in order (the map above is sorted by name).
    pub stage_order: Vec<String>,
}

/// Progress reports for front ends.
pub enum Event<'a> {
    /// Starting frame `number`, the `index`-th of `total` to process.
    Start {
        number: i32,
        index: usize,
        total: usize,
    },
    /// Frame finished.
    Done { stats: &'a FrameStats },
    /// Something the user should know that did not stop the run.
    Warning(String),
    /// The memory estimate, made before the first frame.
    Memory(MemoryEstimate),
}

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    pub frames_done: usize,
    pub resumed_after: Option<i32>,
    pub seconds: f64,
}

#[derive(Serialize, Deserialize)]
struct SavedState {
    version: u32,
    fingerprint: String,
    method: String,
    last_frame: i32,
    method_state: Vec<u8>,
    /// CRC-32 of `method_state`. Postcard has no integrity check of its
    /// own, and a flipped bit in a patch position would decode into a state
    /// that breaks the next frame; with the checksum a damaged file is
    /// refused on load, with one line.
    checksum: u32,
}

const STATE_FILE: &str = "state.bin";
/// 2: the checksum was added.
const STATE_VERSION: u32 = 2;

/// Runs `method` over every frame of `source`: the [`Driver`] with a sink
/// that writes each frame's files.
pub fn run(
    job: &Job,
    source: &mut dyn FrameSource,
    method: &mut dyn Method,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Summary, PipelineError> {
    let start = Instant::now();
    // Everything that can be refused without reading a frame, first.
    job.atlas.validate().map_err(PipelineError::AtlasParams)?;
    let specs = method.channel_specs();
    let estimate = estimate_memory(&job.atlas, &specs, &job.outputs)
        .with_available(job.hooks.available_memory.or_else(available_memory));
    estimate.check()?;
    let (mode, estimate) = write_mode(job, estimate, &specs, observer);
    observer(Event::Memory(estimate));
    std::fs::create_dir_all(&job.out_dir).map_err(|e| PipelineError::Output {
        path: job.out_dir.clone(),
        message: format!("cannot create the output folder: {e}"),
    })?;
    // Held until this function returns, on success and on error alike;
    // taken before the temporaries are cleaned, which would otherwise
    // delete those of a run still writing.
    let lock = crate::io::OutputLock::acquire(&job.out_dir)?;
    if let Some(stale) = &lock.stale {
        observer(Event::Warning(format!(
            "{}: took over the lock of a run that is no longer running ({})",
            lock.lock.path().display(),
            stale.describe()
        )));
    }
    let guard = InputGuard::new(source.input_paths());
    // A run killed inside a write leaves its temporary behind.
    crate::io::remove_stale_temporaries(&job.out_dir, &guard)?;
    let mut frames = source.frames();
    let (previous, resumed_after) = if job.resume {
        resume(job, source, method, &mut frames)?
    } else {
        (None, None)
    };
    // Previews are taken every n frames counted from the sequence's first
    // frame, so a resumed run writes the same previews.
    let first_frame = source.frames().first().copied().unwrap_or(0);
    let formats: Vec<ChannelFormat> = specs.iter().map(|s| s.format).collect();
    let mut writer = FrameWriter {
        job,
        guard: &guard,
        method: MethodInfo {
            name: method.name(),
            specs,
        },
        first_frame,
        coherence_prev: None,
        // The coherence settings are committed constants: parsed once per run.
        coherence_settings: crate::coherence::CoherenceSettings::from_thresholds(
            &crate::metrics::Thresholds::committed().map_err(|e| PipelineError::Output {
                path: job.out_dir.clone(),
                message: format!("internal: {e}"),
            })?,
        ),
        resumed_after,
    };
    let mut driver = Driver::new(method, 1.0 / job.fps, job.atlas.gutter.max(1) * 2);
    driver.set_previous(previous);
    let done = crate::write_behind::scope(
        mode,
        move |w: WriteJob| writer.write(w),
        |worker| -> Result<usize, PipelineError> {
            let mut sink = FileSink {
                writer: worker,
                observer,
                done: 0,
                preview_every: job.outputs.preview_every,
                formats,
                first_frame,
                spent_values: None,
                switch_map: job.outputs.switch_map,
                debug: job.outputs.debug,
                reload_pending: resumed_after.is_some(),
            };
            let looped = drive(job, source, &frames, &mut driver, &mut sink);
            // The frames already handed over are written (and counted)
            // whether or not a later one failed: `--resume` goes on from them.
            let finished = sink.writer.finish();
            let reported = sink.report(finished);
            // A write error belongs to an earlier frame than the loop's.
            reported?;
            looped?;
            Ok(sink.done)
        },
    )?;
    drop(lock);
    Ok(Summary {
        frames_done: done,
        resumed_after,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Reads, builds and drives every frame of `frames` into `sink`.
///
/// Frame k + 1 is read as soon as frame k is built and its geometry
/// (surface index, atlas) is built on a second thread while frame k is
/// driven: the geometry does not depend on the method, and its stages
/// (the chart packing above all) keep less than both cores busy, so the
/// method's parallel stages fill the gaps. One frame is built ahead, never
/// more, so memory grows by one frame's geometry (O(mesh), not O(atlas)).
/// Whatever goes wrong with frame k + 1 is reported after frame k is
/// handed to the sink, as when frames were built one after another: the
/// frames before a bad one are written, and `--resume` goes on from them.
fn drive(
    job: &Job,
    source: &mut dyn FrameSource,
    frames: &[i32],
    driver: &mut Driver<'_>,
    sink: &mut FileSink<'_, '_, '_>,
) -> Result<(), PipelineError> {
    let total = frames.len();
    std::thread::scope(|scope| {
        let mut ahead = frames
            .first()
            .map(|&number| Ahead::start(scope, job, source, number));
        for (k, &number) in frames.iter().enumerate() {
            (sink.observer)(Event::Start {
                number,
                index: k,
                total,
            });
            let Some(this) = ahead.take() else { break };
            let (geometry, clock) = this.finish()?;
            if geometry.report.dropped_degenerate > 0 {
                (sink.observer)(Event::Warning(format!(
                    "frame {number}: dropped {} zero-area triangles",
                    geometry.report.dropped_degenerate
                )));
            }
            ahead = frames
                .get(k + 1)
                .map(|&next| Ahead::start(scope, job, source, next));
            driver.step(
                PendingFrame {
                    geometry: Arc::new(geometry),
                    clock,
                },
                sink,
            )?;
        }
        Ok(())
    })
}

/// A frame read and being built on a scoped thread ([`drive`]).
enum Ahead<'scope> {
    Building(std::thread::ScopedJoinHandle<'scope, Built>),
    /// The read failed: reported when the frame's turn comes.
    Unread(PipelineError),
}

/// A built frame and the clock of its read and build stages.
type Built = Result<(FrameGeometry, StageClock), GeometryError>;

impl<'scope> Ahead<'scope> {
    /// Reads frame `number` here (sources read in frame order and need not
    /// be shared across threads) and builds its geometry on a new thread.
    fn start<'env>(
        scope: &'scope std::thread::Scope<'scope, 'env>,
        job: &'env Job,
        source: &mut dyn FrameSource,
        number: i32,
    ) -> Ahead<'scope> {
        let mut clock = StageClock::default();
        let (mesh, report) = match source.read(number) {
            Ok(read) => read,
            Err(e) => return Ahead::Unread(e),
        };
        clock.lap("read");
        Ahead::Building(scope.spawn(move || {
            // The build's stages are timed from where they start on
            // this thread, not from the end of the read.
            clock.restart();
            FrameGeometry::build(number, mesh, report, &job.atlas, &mut clock).map(|g| (g, clock))
        }))
    }

    /// Waits for the frame's geometry (a panic while building it goes on
    /// here, as if it had been built in place).
    fn finish(self) -> Result<(FrameGeometry, StageClock), PipelineError> {
        match self {
            Ahead::Unread(e) => Err(e),
            Ahead::Building(handle) => match handle.join() {
                Ok(built) => Ok(built?),
                Err(panic) => std::panic::resume_unwind(panic),
            },
        }
    }
}

/// Write-behind where memory allows a second frame in flight (and no test
/// asked for writes in place); otherwise frames are written one after
/// another, with a warning when memory is the reason. Returns the mode and
/// the memory estimate that goes with it.
fn write_mode(
    job: &Job,
    serial: MemoryEstimate,
    channels: &[ChannelSpec],
    observer: &mut dyn FnMut(Event<'_>),
) -> (crate::write_behind::Mode, MemoryEstimate) {
    use crate::write_behind::Mode;
    if job.hooks.write_in_place {
        return (Mode::Inline, serial);
    }
    let behind = serial.clone().writing_behind(channels, &job.outputs);
    if behind.check().is_ok() {
        return (Mode::Behind, behind);
    }
    observer(Event::Warning(format!(
        "writing each frame before computing the next: writing it behind would need {}",
        behind.describe()
    )));
    (Mode::Inline, serial)
}

/// Loads the saved state of the run in `job.out_dir` (if any) into
/// `method`, drops the finished frames from `frames` and re-reads the last
/// finished one: it is the previous frame of the next. Returns it and its
/// number.
fn resume(
    job: &Job,
    source: &mut dyn FrameSource,
    method: &mut dyn Method,
    frames: &mut Vec<i32>,
) -> Result<(Option<Arc<FrameGeometry>>, Option<i32>), PipelineError> {
    let Some(saved) = read_state(&job.out_dir)? else {
        return Ok((None, None));
    };
    if saved.fingerprint != job.fingerprint || saved.method != method.name() {
        return Err(PipelineError::Resume(format!(
            "{} was written by a run with another configuration or method ({}); \
                 rerun without --resume or with the same settings",
            job.out_dir.join(STATE_FILE).display(),
            saved.method
        )));
    }
    method.load_state(&saved.method_state)?;
    let last = saved.last_frame;
    let mut previous = None;
    if frames.contains(&last) {
        let (mesh, report) = source.read(last)?;
        let geometry =
            FrameGeometry::build(last, mesh, report, &job.atlas, &mut StageClock::default())?;
        previous = Some(Arc::new(geometry));
    }
    frames.retain(|&f| f > last);
    Ok((previous, Some(last)))
}

impl From<GeometryError> for PipelineError {
    fn from(e: GeometryError) -> PipelineError {
        PipelineError::from(DriverError::from(e))
    }
}

impl From<DriverError> for PipelineError {
    fn from(e: DriverError) -> PipelineError {
        match e {
            DriverError::Atlas { frame, source } => PipelineError::Atlas { frame, source },
            DriverError::Method(m) => PipelineError::Method(m),
        }
    }
}

/// The sink of `run`, on the frame loop's thread: takes what the writer
/// needs of the method (its state after this frame, before the method moves
/// on), hands the frame to the [`FrameWriter`] and passes the writer's
/// reports on to the observer, in frame order.
struct FileSink<'w, 'a, 'o> {
    writer: &'w mut crate::write_behind::Worker<'a, WriteJob, Written, PipelineError>,
    observer: &'o mut dyn FnMut(Event<'_>),
    done: usize,
    /// `outputs.preview_every` of the job.
    preview_every: u32,
    /// The file format of each channel, in the method's order.
    formats: Vec<ChannelFormat>,
    /// The sequence's first frame, from which previews are counted.
    first_frame: i32,
    /// The float values of the last frame's colour atlas, once its 8-bit
    /// samples were taken ([`FrameSink::spent_values`]).
    spent_values: Option<Vec<f32>>,
    /// `outputs.switch_map`: the switch map reads the frame before's atlas.
    switch_map: bool,
    /// `outputs.debug`: the coherence numbers read the renewal bytes.
    debug: bool,
    /// Resumed and nothing submitted yet: the first frame's writer reloads
    /// the coherence data of the frame before from its files.
    reload_pending: bool,
}

impl FrameSink for FileSink<'_, '_, '_> {
    type Error = PipelineError;

    /// No file holds the per-texel uv or exemplar levels.
    fn reads_evaluation_buffers(&self) -> bool {
        false
    }

    fn spent_values(&mut self) -> Option<Vec<f32>> {
        self.spent_values.take()
    }

    /// The coherence numbers, which read them, come with the debug outputs.
    fn reads_renewal(&self) -> bool {
        self.debug
    }

    fn frame(&mut self, frame: DrivenFrame<'_>) -> Result<(), PipelineError> {
        let DrivenFrame {
            method,
            geometry,
            previous,
            result,
            clock,
        } = frame;
        let state = method.save_state()?;
        // The per-texel uv and mip levels go back to the method; the layer
        // counts are the evaluation's too, and are not kept while the frame
        // is written. 8-bit channels travel as the samples their PNG holds
        // (previews shade the floats).
        let preview = is_preview_frame(self.preview_every, self.first_frame, geometry.number);
        let (channels, spent) = written_channels(result.channels, &self.formats, !preview);
        self.spent_values = spent;
        // The frame before is written already; its geometry goes along only
        // where the writer reads more of it than the coherence data it kept.
        let keep_previous = self.switch_map || std::mem::take(&mut self.reload_pending);
        self.writer.submit(WriteJob {
            geometry: Arc::clone(geometry),
            previous_number: previous.map(|p| p.number),
            previous: previous.filter(|_| keep_previous).cloned(),
            channels,
            source: result.source,
            renewal: result.renewal,
            method_stats: result.stats,
            clock: std::mem::take(clock),
            state,
        });
        let ready = self.writer.ready();
        self.report(ready)
    }
}

impl FileSink<'_, '_, '_> {
    /// Tells the observer of each written frame (and of what went wrong
    /// in writing it, as the first error).
    fn report(
        &mut self,
        results: Vec<Result<Written, PipelineError>>,
    ) -> Result<(), PipelineError> {
        for written in results {
            let Written { stats, warnings } = written?;
            for w in warnings {
                (self.observer)(Event::Warning(w));
            }
            (self.observer)(Event::Done { stats: &stats });
            self.done += 1;
        }
        Ok(())
    }
}

/// Whether frame `number` gets a `preview.F.png`: every
/// `preview_every` frames counted from the sequence's `first_frame`.
fn is_preview_frame(preview_every: u32, first_frame: i32, number: i32) -> bool {
    preview_every > 0 && (number - first_frame).rem_euclid(preview_every as i32) == 0
}

/// One channel atlas on its way to the writer.
enum OutChannel {
    /// As the method made it.
    Float(Texture),
    /// The 8-bit samples of a [`ChannelFormat::Png8`] channel, quantized as
    /// the PNG encoder quantizes ([`crate::io::image::quantize_8`]): what
    /// the file and the coherence numbers read of it, a quarter of the
    /// floats' memory while the frame is written.
    Eight {
        width: u32,
        height: u32,
        channels: usize,
        samples: Vec<u8>,
    },
}

impl OutChannel {
    /// The float atlas, where the channel still has it.
    fn float(&self) -> Option<&Texture> {
        match self {
            OutChannel::Float(t) => Some(t),
            OutChannel::Eight { .. } => None,
        }
    }

    /// Components per texel.
    fn channels(&self) -> usize {
        match self {
            OutChannel::Float(t) => t.channels,
            OutChannel::Eight { channels, .. } => *channels,
        }
    }

    /// Texels held (values ÷ components).
    fn texels(&self) -> usize {
        match self {
            OutChannel::Float(t) => t.data.len() / t.channels.max(1),
            OutChannel::Eight {
                channels, samples, ..
            } => samples.len() / (*channels).max(1),
        }
    }
}

/// The channels as the writer takes them: with `eight`, each 8-bit PNG
/// channel that the encoder can take becomes its samples (in parallel,
/// on the computing thread), and the first such channel's floats come back
/// for the method to fill again (with a colour-only exemplar they are the
/// fill's own values buffer); the others stay floats.
fn written_channels(
    channels: Vec<Texture>,
    formats: &[ChannelFormat],
    eight: bool,
) -> (Vec<OutChannel>, Option<Vec<f32>>) {
    let mut spent = None;
    let out = channels
        .into_iter()
        .enumerate()
        .map(|(k, t)| {
            let quantizable = eight
                && formats.get(k) == Some(&ChannelFormat::Png8)
                && crate::io::image::encodable(&t);
            if !quantizable {
                return OutChannel::Float(t);
            }
            let channel = OutChannel::Eight {
                width: t.width,
                height: t.height,
                channels: t.channels,
                samples: crate::io::image::quantize_8_all(&t.data),
            };
            if spent.is_none() {
                spent = Some(t.data);
            }
            channel
        })
        .collect();
    (out, spent)
}

/// What the writer needs to know of the method: the same for every frame
/// of a run.
struct MethodInfo {
    name: &'static str,
    specs: Vec<ChannelSpec>,
}

/// A filled frame on its way to the writer.
struct WriteJob {
    geometry: Arc<FrameGeometry>,
    /// The number of the frame before, if any.
    previous_number: Option<i32>,
    /// The frame before, only with the switch map and for the first frame
    /// of a resumed run ([`FileSink`]): otherwise the writer would hold
    /// a third frame's geometry while the method fills the next.
    previous: Option<Arc<FrameGeometry>>,
    /// Channels dilated into the gutter, colour first.
    channels: Vec<OutChannel>,
    source: Option<Vec<u32>>,
    /// The method's renewal bytes ([`crate::methods::FrameResult::renewal`]):
    /// which switches the flow forced, for the coherence numbers.
    renewal: Option<Vec<u8>>,
    method_stats: crate::methods::MethodStats,
    /// Stages so far; the writer adds its own.
    clock: StageClock,
    /// [`Method::save_state`] after this frame, taken before the method
    /// moves on to the next, for `state.bin`.
    state: Vec<u8>,
}

/// What the writer reports of a frame whose files and state are committed.
struct Written {
    stats: FrameStats,
    /// Said to the user before the frame counts done.
    warnings: Vec<String>,
}

/// Writes every file of a frame, measures its coherence and saves the
/// state; on the write-behind thread ([`crate::write_behind`]) or in place.
struct FrameWriter<'a> {
    job: &'a Job,
    guard: &'a InputGuard,
    method: MethodInfo,
    first_frame: i32,
    /// What the coherence measurement keeps of the frame before.
    coherence_prev: Option<CoherencePrevious>,
    coherence_settings: crate::coherence::CoherenceSettings,
    resumed_after: Option<i32>,
}

impl FrameWriter<'_> {
    fn write(&mut self, w: WriteJob) -> Result<Written, PipelineError> {
        let WriteJob {
            geometry: g,
            previous_number,
            previous,
            channels,
            source,
            renewal,
            method_stats,
            mut clock,
            state,
        } = w;
        // The time this frame waited for the writer is no stage of it.
        clock.restart();
        let job = self.job;
        let number = g.number;
        let mut warnings = Vec::new();
        let mut stats = FrameStats {
            frame: number,
            method: self.method.name.to_string(),
            vertices: g.mesh.vertex_count(),
            triangles: g.mesh.triangle_count(),
            dropped_degenerate: g.report.dropped_degenerate,
            charts: g.atlas.chart_count,
            atlas_width: g.atlas.width,
            atlas_height: g.atlas.height,
            atlas_fill: g.atlas.texels_in_charts() as f64
                / (f64::from(g.atlas.width) * f64::from(g.atlas.height)).max(1.0),
            method_stats,
            ..Default::default()
        };
        // Every file of the frame is staged, then all are renamed together,
        // then the state counts the frame; a failure before the state is
        // written leaves the frame uncounted and `--resume` redoes it.
        let mut files = Staging::new(Some(self.guard), job.hooks.write.as_ref());
        self.write_frame(&mut files, &g, &channels, source.as_deref())?;
        clock.lap("write");
        // The ids of the debug outputs (coherence numbers, then the views).
        let debug = source.filter(|_| job.outputs.debug);
        if let Some(ids) = debug.as_deref() {
            let prev = previous.as_deref();
            if self.coherence_prev.is_none()
                && let (Some(last), Some(prev)) = (self.resumed_after, prev)
            {
                self.coherence_prev = reload_coherence(
                    job,
                    self.method.specs.first(),
                    prev,
                    last,
                    &self.coherence_settings,
                    &mut warnings,
                );
            }
            let current = WrittenTexels::of(&self.method.specs, &g.atlas, ids, &channels)
                .with_renewal(renewal.as_deref().unwrap_or_default());
            if let Some(before) = &self.coherence_prev
                && Some(before.number) == previous_number
                && let Some((c, ends)) =
                    self.measure_coherence(&mut files, prev, before, &g, &current)?
            {
                // By region needs the patch radius, which the lapped methods report.
                let radius = stats
                    .method_stats
                    .get("radius")
                    .and_then(serde_json::Value::as_f64)
                    .filter(|r| *r > 0.0 && r.is_finite());
                if let Some(radius) = radius
                    && c.causes.covered > 0
                {
                    stats.switch_by_region = Some(switch_regions(&g, &ends, radius as f32));
                }
                stats.source_switch_share = Some(c.switch_share());
                stats.source_changed_share = Some(c.switch.changed_share());
                if c.causes.covered > 0 {
                    stats.switch_forced_share = Some(c.causes.forced_share());
                    stats.switch_unforced_share = Some(c.causes.unforced_share());
                    stats.holder_distorted_share = Some(c.causes.distorted_share());
                }
                stats.colour_follow_ratio = Some(c.follow_ratio());
            }
            self.coherence_prev = Some(CoherencePrevious::of(
                &current,
                &g,
                &self.coherence_settings,
                job.outputs.switch_map,
            ));
            clock.lap("coherence");
        }
        // The channels (12 bytes a texel in colour alone) are written and
        // measured: not held while the debug views are made from the ids.
        drop(channels);
        if let Some(ids) = debug {
            self.write_debug_views(&mut files, &g, ids)?;
            clock.lap("debug");
        }
        stats.stage_order = clock.stages.iter().map(|(n, _)| n.to_string()).collect();
        stats.seconds = clock
            .stages
            .iter()
            .map(|(n, s)| (n.to_string(), *s))
            .collect();
        let json = serde_json::to_vec_pretty(&stats).map_err(|e| PipelineError::Output {
            path: job.out_dir.clone(),
            message: e.to_string(),
        })?;
        write_file(
            &mut files,
            &job.out_dir
                .join(format!("stats.{}.json", frame_tag(number))),
            &json,
        )?;
        files.commit()?;
        save_state(job, self.guard, self.method.name, state, number)?;
        if let Some(hook) = &job.hooks.after_frame {
            hook(number);
        }
        Ok(Written { stats, warnings })
    }
}

/// The frame number as written in file names: at least 4 digits.
pub fn frame_tag(number: i32) -> String {
    if number < 0 {
        format!("-{:04}", -(number as i64))
    } else {
        format!("{number:04}")
    }
}

fn read_state(dir: &Path) -> Result<Option<SavedState>, PipelineError> {
    let path = dir.join(STATE_FILE);
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(PipelineError::Resume(format!("{}: {e}", path.display()))),
    };
    parse_state(&path, &bytes).map(Some)
}

/// Decodes `state.bin` bytes into `method` as `--resume` does, without the
/// configuration check; returns the last finished frame. For tests of
/// damaged state files (the fuzz tests feed it thousands).
pub fn load_state_bytes(
    path: &Path,
    bytes: &[u8],
    method: &mut dyn Method,
) -> Result<i32, PipelineError> {
    let saved = parse_state(path, bytes)?;
    if saved.method != method.name() {
        return Err(PipelineError::Resume(format!(
            "{}: written by method {}, not {}",
            path.display(),
            saved.method,
            method.name()
        )));
    }
    method.load_state(&saved.method_state)?;
    Ok(saved.last_frame)
}

fn parse_state(path: &Path, bytes: &[u8]) -> Result<SavedState, PipelineError> {
    let damaged = |e: postcard::Error| {
        PipelineError::Resume(format!("{}: damaged state file ({e})", path.display()))
    };
    // The version first (the file's first field): a file of another
    // version has another layout, and would otherwise read as damaged.
    let (version, _) = postcard::take_from_bytes::<u32>(bytes).map_err(damaged)?;
    if version != STATE_VERSION {
        return Err(PipelineError::Resume(format!(
            "{}: state version {version} is not {STATE_VERSION}",
            path.display(),
        )));
    }
    let saved: SavedState = postcard::from_bytes(bytes).map_err(damaged)?;
    if crc32fast::hash(&saved.method_state) != saved.checksum {
        return Err(PipelineError::Resume(format!(
            "{}: damaged state file (checksum mismatch)",
            path.display()
        )));
    }
    Ok(saved)
}

fn save_state(
    job: &Job,
    guard: &InputGuard,
    method: &str,
    method_state: Vec<u8>,
    frame: i32,
) -> Result<(), PipelineError> {
    let saved = SavedState {
        version: STATE_VERSION,
        fingerprint: job.fingerprint.clone(),
        method: method.to_string(),
        last_frame: frame,
        checksum: crc32fast::hash(&method_state),
        method_state,
    };
    let bytes = postcard::to_allocvec(&saved).map_err(|e| PipelineError::Output {
        path: job.out_dir.join(STATE_FILE),
        message: e.to_string(),
    })?;
    let mut files = Staging::new(Some(guard), job.hooks.write.as_ref());
    write_file(&mut files, &job.out_dir.join(STATE_FILE), &bytes)?;
    Ok(files.commit()?)
}

/// What the coherence measurement of the next frame needs of this one:
/// its sample points (drawn on its mesh, seeded by its number) and its
/// source and grey value at each, *as written to the files*
/// (`source.F.exr` stores ids as f32; the grey values are those of the
/// colour atlas file), so that a resumed run, which reloads them from
/// those files, measures exactly what an uninterrupted one does. 20 000
/// points instead of the whole atlas: the frame job keeps no atlas-sized
/// copy for the measurement. With the switch map, also the whole written
/// source and grey (the atlas is the driver's previous frame's).
struct CoherencePrevious {
    number: i32,
    /// The sample points (with their positions and velocity) and the
    /// values there; `None` when the frame has no velocity or its data does
    /// not fit its atlas (no measurement).
    points: Option<(Departure, Vec<crate::coherence::PointValue>)>,
    /// Written source and grey per texel, for `switch.F.png` only.
    full: Option<(Vec<u32>, Vec<f32>)>,
}

/// The sample points of the pair (frame `number`, the next): one set per
/// frame pair, seeded by the frame, so a resumed run draws the same points.
fn coherence_points(
    mesh: &TriMesh,
    number: i32,
    settings: &crate::coherence::CoherenceSettings,
) -> Vec<SurfacePoint> {
    let seed = crate::seed::mix(settings.seed, 7, number as u64);
    crate::coherence::sample_surface(mesh, settings.samples, seed)
}

/// The sample points of frame `number` (mesh `mesh`) ready to be carried
/// to the next frame, and `texels`' values there; `None` when the mesh has
/// no velocity or the texels do not fit the atlas.
fn departure_values(
    mesh: &TriMesh,
    number: i32,
    settings: &crate::coherence::CoherenceSettings,
    texels: &impl crate::coherence::Texels,
) -> Option<(Departure, Vec<crate::coherence::PointValue>)> {
    let velocity = mesh.velocity()?;
    let points = coherence_points(mesh, number, settings);
    let values = crate::coherence::point_values(&points, texels).ok()?;
    Some((Departure::of(mesh, velocity, points), values))
}

impl CoherencePrevious {
    /// This frame's data as its files hold it (computed in memory: the
    /// files are committed together with the stats that carry the result).
    fn of(
        current: &WrittenTexels<'_>,
        g: &FrameGeometry,
        settings: &crate::coherence::CoherenceSettings,
        switch_map: bool,
    ) -> CoherencePrevious {
        use crate::coherence::Texels;
        let points = departure_values(&g.mesh, g.number, settings, current);
        let full = switch_map.then(|| {
            let n = current.source.len();
            let source = (0..n).into_par_iter().map(|i| current.source(i)).collect();
            let grey = match current.colour {
                Some((OutChannel::Float(colour), format)) => written_grey(colour, format),
                // Texel by texel, the same values.
                Some(_) => (0..n).into_par_iter().map(|i| current.grey(i)).collect(),
                None => Vec::new(),
            };
            (source, grey)
        });
        CoherencePrevious {
            number: g.number,
            points,
            full,
        }
    }
}

/// A frame's output as its files will hold it, read texel by texel from
/// the method's result (no atlas-sized copy): ids as `source.F.exr` stores
/// them (f32), grey values as the colour atlas file stores them (the same
/// per-texel arithmetic as [`written_grey`]).
struct WrittenTexels<'a> {
    atlas: &'a crate::atlas::Atlas,
    source: &'a [u32],
    /// The colour atlas and its file format; `None` without channels.
    colour: Option<(&'a OutChannel, ChannelFormat)>,
    /// The method's renewal bytes; empty where it records none.
    renewal: &'a [u8],
}

impl<'a> WrittenTexels<'a> {
    fn of(
        specs: &[ChannelSpec],
        atlas: &'a crate::atlas::Atlas,
        source: &'a [u32],
        channels: &'a [OutChannel],
    ) -> WrittenTexels<'a> {
        let colour = match (specs.first(), channels.first()) {
            (Some(spec), Some(colour)) => Some((colour, spec.format)),
            _ => None,
        };
        WrittenTexels {
            atlas,
            source,
            colour,
            renewal: &[],
        }
    }

    /// With the method's renewal bytes (`renewal`, empty: none).
    fn with_renewal(self, renewal: &'a [u8]) -> WrittenTexels<'a> {
        WrittenTexels { renewal, ..self }
    }
}

impl crate::coherence::Texels for WrittenTexels<'_> {
    fn atlas(&self) -> &crate::atlas::Atlas {
        self.atlas
    }

    fn source(&self, i: usize) -> u32 {
        match self.source.get(i) {
            Some(&s) if s != SOURCE_OUTSIDE => s as f32 as u32,
            _ => SOURCE_OUTSIDE,
        }
    }

    fn grey(&self, i: usize) -> f32 {
        let Some((colour, format)) = self.colour else {
            return f32::NAN;
        };
        let channels = colour.channels();
        let c = channels.max(1);
        let texel = i * c..(i + 1) * c;
        match colour {
            OutChannel::Float(t) => t.data.get(texel).map_or(f32::NAN, |texel| {
                written_grey_texel(texel, channels, format)
            }),
            // The samples the PNG holds, scaled as its decoder scales them:
            // the values `written_grey_texel` makes of the floats.
            OutChannel::Eight { samples, .. } => samples.get(texel).map_or(f32::NAN, |texel| {
                grey_of(
                    texel.iter().map(|&q| f32::from(q) / 255.0).collect(),
                    channels,
                )
            }),
        }
    }

    fn renewal(&self, i: usize) -> u8 {
        self.renewal
            .get(i)
            .copied()
            .unwrap_or(crate::provenance::RENEWAL_UNKNOWN)
    }

    fn validate(&self) -> Result<(), crate::metrics::MetricsError> {
        let (w, h) = (self.atlas.width, self.atlas.height);
        crate::metrics::check_len("source", self.source, w, h)?;
        if !self.renewal.is_empty() {
            crate::metrics::check_len("renewal", self.renewal, w, h)?;
        }
        // As many grey values as `written_grey` would give.
        let greys = self.colour.map_or(0, |(c, _)| c.texels());
        let expected = w as usize * h as usize;
        if greys == expected {
            Ok(())
        } else {
            Err(crate::metrics::MetricsError::Length {
                what: "grey",
                expected,
                got: greys,
            })
        }
    }
}

/// [`written_grey`] of one texel (`channels` values): the same arithmetic.
fn written_grey_texel(texel: &[f32], channels: usize, format: ChannelFormat) -> f32 {
    let quantize =
        |levels: f32, x: f32| (((x.clamp(0.0, 1.0) * levels) as f64 + 0.5) as u32) as f32 / levels;
    let data: Vec<f32> = match format {
        ChannelFormat::Png8 => texel.iter().map(|&x| quantize(255.0, x)).collect(),
        ChannelFormat::Png16 => texel.iter().map(|&x| quantize(65535.0, x)).collect(),
        ChannelFormat::Exr => texel.to_vec(),
    };
    grey_of(data, channels)
}

/// The luminance of one texel's `channels` values.
fn grey_of(data: Vec<f32>, channels: usize) -> f32 {
    let one = Texture {
        width: 1,
        height: 1,
        channels,
        data,
    };
    crate::metrics::luminance(&one)
        .first()
        .copied()
        .unwrap_or(f32::NAN)
}

/// The luminance of a colour atlas as the file written in `format` stores
/// it: the same clamping and rounding as the PNG encoder and the same
/// scaling as the decoder (`--resume` reads the file back), so an
/// uninterrupted and a resumed run measure identical values.
fn written_grey(colour: &Texture, format: ChannelFormat) -> Vec<f32> {
    let quantize = |levels: f32| {
        move |x: f32| (((x.clamp(0.0, 1.0) * levels) as f64 + 0.5) as u32) as f32 / levels
    };
    let data: Vec<f32> = match format {
        ChannelFormat::Png8 => colour.data.iter().map(|&x| quantize(255.0)(x)).collect(),
        ChannelFormat::Png16 => colour.data.iter().map(|&x| quantize(65535.0)(x)).collect(),
        ChannelFormat::Exr => colour.data.clone(),
    };
    let texture = Texture {
        width: colour.width,
        height: colour.height,
        channels: colour.channels,
        data,
    };
    crate::metrics::luminance(&texture)
}

/// The luminance of frame `number`'s colour atlas as written.
fn read_grey(
    job: &Job,
    colour: Option<&ChannelSpec>,
    number: i32,
) -> Result<Vec<f32>, PipelineError> {
    let Some(spec) = colour else {
        return Ok(Vec::new());
    };
    let path = job.out_dir.join(format!(
        "{}.{}.{}",
        spec.name,
        frame_tag(number),
        spec.format.extension()
    ));
    let decoded = crate::io::image_read::read_image(&path).map_err(|e| PipelineError::Output {
        path: path.clone(),
        message: format!("cannot read it back for the coherence measurement: {e}"),
    })?;
    Ok(crate::metrics::luminance(&decoded.texture))
}

/// After `--resume`: the coherence data of the last finished frame
/// (`prev`, re-read), from its files (`source.F.exr`, the colour atlas).
/// `None`, with a warning, when they cannot be read (then the first resumed
/// frame has no coherence numbers).
fn reload_coherence(
    job: &Job,
    colour: Option<&ChannelSpec>,
    prev: &FrameGeometry,
    last: i32,
    settings: &crate::coherence::CoherenceSettings,
    warnings: &mut Vec<String>,
) -> Option<CoherencePrevious> {
    let load = || -> Result<CoherencePrevious, String> {
        let path = job.out_dir.join(format!("source.{}.exr", frame_tag(last)));
        let ids = crate::io::image_read::read_image(&path).map_err(|e| e.to_string())?;
        let source: Vec<u32> = ids
            .texture
            .data
            .iter()
            .step_by(ids.texture.channels.max(1))
            .map(|&v| if v < 0.0 { SOURCE_OUTSIDE } else { v as u32 })
            .collect();
        drop(ids);
        let grey = read_grey(job, colour, last).map_err(|e| e.to_string())?;
        let texels = crate::coherence::TexelFrame {
            atlas: &prev.atlas,
            source: &source,
            grey: &grey,
            renewal: &[],
        };
        let points = departure_values(&prev.mesh, last, settings, &texels);
        let full = job.outputs.switch_map.then_some((source, grey));
        Ok(CoherencePrevious {
            number: last,
            points,
            full,
        })
    };
    match load() {
        Ok(c) => Some(c),
        Err(e) => {
            warnings.push(format!(
                "frame {}: no source switch share (frame {last} cannot be reloaded: {e})",
                last + 1
            ));
            None
        }
    }
}

impl FrameWriter<'_> {
    /// Source switch share and colour follow ratio from the frame before
    /// to this one (carried by the meshes' velocity), and, when asked,
    /// `switch.F.png`. `None` when a frame has no velocity or the data does
    /// not fit its atlas.
    fn measure_coherence(
        &self,
        files: &mut Staging<'_>,
        prev: Option<&FrameGeometry>,
        before: &CoherencePrevious,
        frame: &FrameGeometry,
        current: &WrittenTexels<'_>,
    ) -> Result<Option<(crate::coherence::Coherence, Vec<CarriedEnds>)>, PipelineError> {
        use crate::coherence::{self, TexelFrame, switch_map};
        use crate::surface::velocity::FlowFrame;
        let Some(v1) = frame.mesh.velocity() else {
            return Ok(None);
        };
        let Some((departure, values)) = &before.points else {
            return Ok(None);
        };
        let settings = &self.coherence_settings;
        let dt = 1.0 / self.job.fps;
        let next = FlowFrame {
            mesh: &frame.mesh,
            index: &frame.index,
            velocity: v1,
        };
        let carried = departure.carry(next, dt);
        let Ok((found, ends)) = coherence::measure_from_ends(&carried, values, current, settings)
        else {
            return Ok(None);
        };
        if self.job.outputs.switch_map
            && let Some((source, grey)) = &before.full
            && let Some(prev) = prev
            && let Some(v0) = prev.mesh.velocity()
        {
            let from = FlowFrame {
                mesh: &prev.mesh,
                index: &prev.index,
                velocity: v0,
            };
            let from_texels = TexelFrame {
                atlas: &prev.atlas,
                source,
                grey,
                renewal: &[],
            };
            if let Ok(map) = switch_map(&from_texels, from, current, next, dt) {
                let image = coherence::switch_image(&map, frame.atlas.width, frame.atlas.height);
                write_channel(
                    files,
                    &self
                        .job
                        .out_dir
                        .join(format!("switch.{}.png", frame_tag(frame.number))),
                    &image,
                    ChannelFormat::Png8,
                )?;
            }
        }
        Ok(Some((found, carried.to.into_iter().zip(ends).collect())))
    }
}

/// A carried point's location on this frame and what it found at both ends.
type CarriedEnds = (Option<SurfacePoint>, crate::coherence::PointEnds);

/// `stats.F.json`'s `switch_by_region`: the carried points' switches by
/// the region of frame `g` they land in ([`crate::coherence::regions`]).
fn switch_regions(
    g: &FrameGeometry,
    ends: &[CarriedEnds],
    radius: f32,
) -> BTreeMap<&'static str, crate::coherence::regions::RegionSwitch> {
    use crate::coherence::regions::{RegionMap, switch_by_region};
    let map = RegionMap::new(&g.mesh, &g.index, &g.topology, radius);
    let regions: Vec<_> = ends
        .par_iter()
        .map(|(to, _)| to.as_ref().and_then(|sp| map.region(sp)))
        .collect();
    let ends: Vec<_> = ends.iter().map(|e| e.1).collect();
    switch_by_region(&ends, &regions)
}

fn write_file(files: &mut Staging<'_>, path: &Path, bytes: &[u8]) -> Result<(), PipelineError> {
    files.write(path, |w| w.write_all(bytes))?;
    Ok(())
}

/// The patch colours of every texel, dilated into the gutter.
fn patch_colours(
    atlas: &crate::atlas::Atlas,
    source: &[u32],
    radius: u32,
) -> Result<Texture, AtlasError> {
    let mut colours = Texture::filled(atlas.width, atlas.height, 3, 0.0);
    colours
        .data
        .par_chunks_mut(3)
        .zip(source.par_iter())
        .with_min_len(1 << 14)
        .for_each(|(c, &s)| c.copy_from_slice(&patch_colour(s)));
    atlas.dilate(&mut colours, radius)?;
    Ok(colours)
}

/// `patches.F.png` without a float colour atlas: the ids are dilated as
/// ids (dilation copies the nearest chart texel's value, so dilating ids
/// and then colouring them is dilating the colours) and each strip of the
/// PNG encoder colours its own rows straight to 8 bits. The same bytes as
/// encoding [`patch_colours`], holding one id per texel instead of twelve
/// bytes of colour. The ids are dilated where they are (the frame's last
/// use of them), not in a copy: 151 MB of fresh pages at 6144².
fn patch_png(
    atlas: &crate::atlas::Atlas,
    mut ids: Vec<u32>,
    radius: u32,
) -> Result<Vec<u8>, String> {
    atlas
        .dilate_ids(&mut ids, radius)
        .map_err(|e| e.to_string())?;
    let width = atlas.width as usize;
    let compression = PngOptions::default().compression;
    crate::io::image::encode_png_8_rows(atlas.width, atlas.height, 3, compression, |y, rgb| {
        // Ids come in runs along a row: one hash per run.
        let mut last: Option<(u32, [u8; 3])> = None;
        for (out, &id) in rgb.chunks_exact_mut(3).zip(&ids[y * width..][..width]) {
            let colour = match last {
                Some((l, c)) if l == id => c,
                _ => {
                    let c = patch_colour(id).map(crate::io::image::quantize_8);
                    last = Some((id, c));
                    c
                }
            };
            out.copy_from_slice(&colour);
        }
    })
}

/// A colour per patch id for `patches.F.png` (the paper's Fig. 1, left):
/// outside charts black, uncovered magenta, patches hashed to bright colours.
pub fn patch_colour(source: u32) -> [f32; 3] {
    match source {
        SOURCE_OUTSIDE => [0.0, 0.0, 0.0],
        SOURCE_UNCOVERED => [1.0, 0.0, 1.0],
        s => {
            let h = crate::seed::mix(0x5eed, 3, s as u64);
            let c = |k: u32| 0.25 + 0.7 * (((h >> (k * 16)) & 0xffff) as f32 / 65535.0);
            [c(0), c(1), c(2)]
        }
    }
}

impl FrameWriter<'_> {
    /// Stages the files of one frame that need its channels: channels,
    /// meshes, previews (the debug views follow, [`Self::write_debug_views`]).
    fn write_frame(
        &self,
        files: &mut Staging<'_>,
        g: &FrameGeometry,
        channels: &[OutChannel],
        source: Option<&[u32]>,
    ) -> Result<(), PipelineError> {
        let colour_png = self.write_channels(files, g.number, channels)?;
        let normals = g.uv_mesh_normals();
        self.write_meshes(files, g, &normals, colour_png.as_ref())?;
        self.write_patch_views(files, g, channels, source, &normals)
    }

    /// Each channel atlas under its spec's name; the colour atlas's file
    /// name and PNG bytes, where it is a PNG, for the meshes to embed.
    fn write_channels(
        &self,
        files: &mut Staging<'_>,
        number: i32,
        channels: &[OutChannel],
    ) -> Result<Option<(String, Vec<u8>)>, PipelineError> {
        let tag = frame_tag(number);
        let dir = &self.job.out_dir;
        let method = &self.method;
        let specs = &method.specs;
        if specs.len() != channels.len() {
            return Err(PipelineError::Output {
                path: dir.clone(),
                message: format!(
                    "internal: method {} returned {} channels for {} names",
                    method.name,
                    channels.len(),
                    specs.len()
                ),
            });
        }
        let mut colour_png: Option<(String, Vec<u8>)> = None;
        for (spec, texture) in specs.iter().zip(channels) {
            let file = format!("{}.{tag}.{}", spec.name, spec.format.extension());
            let path = dir.join(&file);
            if let Some(bytes) = write_out_channel(files, &path, texture, spec.format)?
                && colour_png.is_none()
            {
                colour_png = Some((file, bytes));
            }
        }
        Ok(colour_png)
    }

    /// `mesh.F.obj` (with a material naming the colour PNG) and
    /// `mesh.F.glb` (with the PNG embedded), as the job asks.
    fn write_meshes(
        &self,
        files: &mut Staging<'_>,
        g: &FrameGeometry,
        normals: &[Vec3],
        colour_png: Option<&(String, Vec<u8>)>,
    ) -> Result<(), PipelineError> {
        let (job, uv) = (self.job, &g.atlas.uv_mesh);
        let tag = frame_tag(g.number);
        if job.outputs.obj {
            let obj = job.out_dir.join(format!("mesh.{tag}.obj"));
            let material = colour_png.map(|(file, _)| crate::io::obj_write::ObjMaterial {
                name: "fluidtex".to_string(),
                map_kd: file.clone(),
            });
            crate::io::obj_write::stage_obj(
                files,
                &obj,
                &uv.positions,
                &uv.uvs,
                Some(normals),
                &uv.triangles,
                material.as_ref(),
            )?;
        }
        if job.outputs.glb {
            let path = job.out_dir.join(format!("mesh.{tag}.glb"));
            let png = colour_png.map(|(_, b)| b.as_slice());
            // The PNG's bytes go into the file from `colour_png` itself.
            let glb = crate::io::gltf::layout_glb(
                &uv.positions,
                &uv.uvs,
                Some(normals),
                &uv.triangles,
                png,
            )
            .map_err(|reason| IoError::Unwritable {
                path: path.clone(),
                reason,
            })?;
            files.write(&path, |w| glb.write_to(w))?;
        }
        Ok(())
    }

    /// `preview.F.png` on preview frames: the lit render beside the view
    /// of where texels came from.
    fn write_patch_views(
        &self,
        files: &mut Staging<'_>,
        g: &FrameGeometry,
        channels: &[OutChannel],
        source: Option<&[u32]>,
        normals: &[Vec3],
    ) -> Result<(), PipelineError> {
        let number = g.number;
        let preview = is_preview_frame(self.job.outputs.preview_every, self.first_frame, number);
        // A preview frame's channels are handed over as floats.
        let Some(colour) = channels
            .first()
            .and_then(OutChannel::float)
            .filter(|_| preview)
        else {
            return Ok(());
        };
        // The patch colours as floats serve the preview only; the debug
        // file is made in 8 bits from the dilated ids (`patch_png`).
        let patches = match source {
            Some(source) => Some(
                patch_colours(&g.atlas, source, self.patch_view_radius()).map_err(|source| {
                    PipelineError::Atlas {
                        frame: number,
                        source,
                    }
                })?,
            ),
            None => None,
        };
        self.write_preview(files, g, colour, patches.as_ref(), normals)
    }

    /// Gutter texels of the patch views: twice the atlas's, so that the
    /// view's charts stand out at a glance.
    fn patch_view_radius(&self) -> u32 {
        self.job.atlas.gutter.max(1) * 2
    }

    /// The debug views of where texels came from, made from the ids alone:
    /// `source.F.exr`, then `patches.F.png`, which dilates the ids it is
    /// handed (they are not needed after it).
    fn write_debug_views(
        &self,
        files: &mut Staging<'_>,
        g: &FrameGeometry,
        source: Vec<u32>,
    ) -> Result<(), PipelineError> {
        let (job, number, atlas) = (self.job, g.number, &g.atlas);
        let tag = frame_tag(number);
        let path = job.out_dir.join(format!("source.{tag}.exr"));
        let source = write_source_ids(files, &path, atlas, source)?;
        let path = job.out_dir.join(format!("patches.{tag}.png"));
        let bytes =
            patch_png(atlas, source, self.patch_view_radius()).map_err(output_error(&path))?;
        write_file(files, &path, &bytes)
    }

    /// `preview.F.png`: a lit render of the textured mesh beside the patch
    /// view, from a camera framing this frame's surface.
    fn write_preview(
        &self,
        files: &mut Staging<'_>,
        g: &FrameGeometry,
        colour: &Texture,
        patches: Option<&Texture>,
        normals: &[Vec3],
    ) -> Result<(), PipelineError> {
        let Some((lo, hi)) = g.mesh.bounding_box() else {
            return Ok(());
        };
        let uv = &g.atlas.uv_mesh;
        let size = self.job.outputs.preview_size.clamp(16, 8192);
        let camera = Camera::framing(lo, hi, Vec3::new(-0.45, -0.8, -0.4), size, size);
        let gb = render::rasterize(&uv.positions, &uv.triangles, &camera);
        let background = [0.12, 0.12, 0.14];
        let views: Vec<Texture> = std::iter::once(colour)
            .chain(patches)
            .map(|texture| {
                render::shade_lit(
                    &gb,
                    &uv.triangles,
                    normals,
                    &uv.uvs,
                    texture,
                    &camera,
                    background,
                )
            })
            .collect();
        let sheet = render::side_by_side(&views.iter().collect::<Vec<_>>(), 8, background);
        let path = self
            .job
            .out_dir
            .join(format!("preview.{}.png", frame_tag(g.number)));
        write_channel(files, &path, &sheet, ChannelFormat::Png8)?;
        Ok(())
    }
}

/// `source.F.exr`: each texel's source patch id as a float, -1 outside
/// the charts; hands the ids back.
///
/// The ids become floats in their own buffer and turn back into the same
/// ids once the file is written: every id below 2^24 is an integer an f32
/// holds exactly. That saves a second atlas-sized buffer at the frame's
/// peak of memory (151 MB at 6144²). Ids from 2^24 up (16.7 million
/// patches: never met) take a float copy instead.
fn write_source_ids(
    files: &mut Staging<'_>,
    path: &Path,
    atlas: &crate::atlas::Atlas,
    source: Vec<u32>,
) -> Result<Vec<u32>, PipelineError> {
    const EXACT: u32 = 1 << 24;
    let as_float = |s: u32| if s == SOURCE_OUTSIDE { -1.0 } else { s as f32 };
    let texture = |data| Texture {
        width: atlas.width,
        height: atlas.height,
        channels: 1,
        data,
    };
    let options = exr_channel_options();
    let exact = source
        .par_iter()
        .with_min_len(1 << 16)
        .all(|&s| s < EXACT || s == SOURCE_OUTSIDE);
    if !exact {
        let ids = source
            .par_iter()
            .with_min_len(1 << 16)
            .map(|&s| as_float(s))
            .collect();
        crate::io::image::stage_exr_owned(files, path, texture(ids), &options)?;
        return Ok(source);
    }
    let mut ids: Vec<f32> = bytemuck::cast_vec(source);
    ids.par_iter_mut()
        .with_min_len(1 << 16)
        .for_each(|x| *x = as_float(x.to_bits()));
    let mut ids = crate::io::image::stage_exr_owned(files, path, texture(ids), &options)?.data;
    ids.par_iter_mut().with_min_len(1 << 16).for_each(|x| {
        let s = if *x < 0.0 { SOURCE_OUTSIDE } else { *x as u32 };
        *x = f32::from_bits(s);
    });
    Ok(bytemuck::cast_vec(ids))
}

/// How a channel in [`ChannelFormat::Exr`] is written: 32-bit floats.
fn exr_channel_options() -> ExrOptions {
    ExrOptions {
        sample: ExrSample::F32,
        ..Default::default()
    }
}

/// An encoder's message as the error of writing `path`.
fn output_error(path: &Path) -> impl Fn(String) -> PipelineError + '_ {
    move |message| PipelineError::Output {
        path: path.to_path_buf(),
        message,
    }
}

/// [`write_channel`] of a channel as the writer receives it.
fn write_out_channel(
    files: &mut Staging<'_>,
    path: &Path,
    channel: &OutChannel,
    format: ChannelFormat,
) -> Result<Option<Vec<u8>>, PipelineError> {
    match channel {
        OutChannel::Float(t) => write_channel(files, path, t, format),
        OutChannel::Eight {
            width,
            height,
            channels,
            samples,
        } => {
            // The same bytes as encoding the floats they were quantized from.
            let row = *width as usize * channels;
            let compression = PngOptions::default().compression;
            let bytes = crate::io::image::encode_png_8_rows(
                *width,
                *height,
                *channels,
                compression,
                |y, out| out.copy_from_slice(&samples[y * row..(y + 1) * row]),
            )
            .map_err(output_error(path))?;
            write_file(files, path, &bytes)?;
            Ok(Some(bytes))
        }
    }
}

/// Writes one channel atlas; returns the PNG bytes for PNG formats (the
/// glb embeds the colour atlas without encoding it twice).
fn write_channel(
    files: &mut Staging<'_>,
    path: &Path,
    texture: &Texture,
    format: ChannelFormat,
) -> Result<Option<Vec<u8>>, PipelineError> {
    let depth = match format {
        ChannelFormat::Png8 => PngDepth::Eight,
        ChannelFormat::Png16 => PngDepth::Sixteen,
        ChannelFormat::Exr => {
            crate::io::image::stage_exr(files, path, texture, &exr_channel_options())?;
            return Ok(None);
        }
    };
    let options = PngOptions {
        depth,
        ..Default::default()
    };
    let bytes = crate::io::image::encode_png(texture, &options).map_err(output_error(path))?;
    write_file(files, path, &bytes)?;
    Ok(Some(bytes))
}

/// What a run is expected to need in memory, from the atlas size and the
/// output channels alone (known before any frame is read).
#[derive(Clone, Debug, PartialEq)]
pub struct MemoryEstimate {
    pub width: u32,
    pub height: u32,
    /// Bytes held per atlas texel at the peak of a frame (see [`estimate_memory`]).
    pub bytes_per_texel: u64,
    /// Bytes that do not scale with the atlas (meshes, exemplar, patches).
    pub base_bytes: u64,
    /// The estimate in bytes.
    pub bytes: u64,
    /// What the machine has available (`MemAvailable`), where known.
    pub available: Option<u64>,
}

/// Memory the frames of a run need besides the atlas: two meshes with their
/// BVHs, the exemplar and the patch state. 256 MiB covers a dam-break frame
/// (85k triangles, 5k patches) with room; a heavier scene is not refused
/// for it, since the check only catches atlases that cannot fit.
const BASE_BYTES: u64 = 256 << 20;

/// Components per output channel in the memory estimate (C): an upper
/// bound, colour has 3 or 4.
const ESTIMATE_COMPONENTS: u64 = 4;

/// Bytes per texel of the debug outputs, an upper bound: the float patch
/// colours of a preview frame (12), the dilated copy of the ids that
/// `patches.F.png` is coloured from (4) and the ids as floats that
/// `source.F.exr` takes without a copy (4). The channels are dropped before
/// the last two are made, and those two are not alive together.
fn debug_bytes(outputs: &OutputOptions) -> u64 {
    if outputs.debug { 12 + 4 + 4 } else { 0 }
}

/// Bytes per texel of the encoders: quantized samples and the compressed
/// image, about 2 bytes per component (4 for 16-bit and float).
fn encode_bytes(channels: &[ChannelSpec]) -> u64 {
    channels
        .iter()
        .map(|c| match c.format {
            ChannelFormat::Png8 => 2 * ESTIMATE_COMPONENTS,
            ChannelFormat::Png16 | ChannelFormat::Exr => 4 * ESTIMATE_COMPONENTS,
        })
        .sum()
}

/// Estimates the memory of a run before any frame is read.
///
/// Per atlas texel, at the peak of a frame (the write, while the method's
/// result is alive), with C = 4 components per output channel (an upper
/// bound: colour is 3 or 4):
/// - the method's fill: C floats per channel, a source id and a uv
///   (4·C·channels + 12 bytes), and its result textures (4·C·channels + 8);
/// - the debug outputs: 20 at most (float patch colours on preview frames,
///   12; a copy of the ids for `patches.F.png`, 4; float ids for
///   `source.F.exr`, 4);
/// - encoding: quantized samples and the compressed image, about 2 bytes
///   per component (up to 4 for 16-bit).
///
/// An upper bound by design. Measured (erosion demo, built-in pebbles,
/// one 8-bit colour channel): peak RSS 104 MB at 1024² and 253 MB at
/// 2048², a slope of 49 bytes per texel against the estimate's 80.
pub fn estimate_memory(
    atlas: &AtlasParams,
    channels: &[ChannelSpec],
    outputs: &OutputOptions,
) -> MemoryEstimate {
    let components = ESTIMATE_COMPONENTS * channels.len().max(1) as u64;
    let bytes_per_texel =
        4 * components + 12 + 4 * components + 8 + debug_bytes(outputs) + encode_bytes(channels);
    let texels = u64::from(atlas.width) * u64::from(atlas.height);
    MemoryEstimate {
        width: atlas.width,
        height: atlas.height,
        bytes_per_texel,
        base_bytes: BASE_BYTES,
        bytes: texels * bytes_per_texel + BASE_BYTES,
        available: None,
    }
}

impl MemoryEstimate {
    /// The estimate when frame t is written while frame t+1 is computed
    /// ([`crate::write_behind`]): besides the computing frame's peak, the
    /// written frame's channels (4·C·channels bytes per texel: floats on
    /// preview frames; an 8-bit PNG channel is handed over as its C bytes
    /// otherwise, so this is the bound), its source ids (4), its debug
    /// views and its encoders' buffers are alive.
    pub fn writing_behind(mut self, channels: &[ChannelSpec], outputs: &OutputOptions) -> Self {
        let written = 4 * ESTIMATE_COMPONENTS * channels.len().max(1) as u64
            + 4
            + debug_bytes(outputs)
            + encode_bytes(channels);
        self.bytes_per_texel += written;
        self.bytes =
            u64::from(self.width) * u64::from(self.height) * self.bytes_per_texel + self.base_bytes;
        self
    }

    /// The same estimate with the available memory recorded.
    pub fn with_available(mut self, available: Option<u64>) -> MemoryEstimate {
        self.available = available;
        self
    }

    /// Refuses an estimate above the available memory (never where the
    /// available memory is unknown), naming the largest square atlas that
    /// fits.
    pub fn check(&self) -> Result<(), PipelineError> {
        let Some(available) = self.available else {
            return Ok(());
        };
        if self.bytes <= available {
            return Ok(());
        }
        let texels = available.saturating_sub(self.base_bytes) / self.bytes_per_texel.max(1);
        // Whole multiples of 256 texels: atlas sizes people type.
        let side = (texels as f64).sqrt() as u64 / 256 * 256;
        Err(PipelineError::Memory {
            width: self.width,
            height: self.height,
            needed: self.bytes,
            available,
            fits: side.min(u64::from(crate::atlas::MAX_SIDE)) as u32,
        })
    }

    /// "about 1.3 GiB for a 4096x4096 atlas (80 bytes per texel); 20.1 GiB available".
    pub fn describe(&self) -> String {
        let available = match self.available {
            Some(a) => format!("{} available", gib(a)),
            None => "available memory unknown".into(),
        };
        format!(
            "about {} for a {}x{} atlas ({} bytes per texel); {available}",
            gib(self.bytes),
            self.width,
            self.height,
            self.bytes_per_texel
        )
    }
}

/// `MemAvailable` of `/proc/meminfo` in bytes; `None` where there is no
/// such file (other systems: the check is skipped).
pub fn available_memory() -> Option<u64> {
    proc_kib("/proc/meminfo", "MemAvailable:")
}

/// A `key: N kB` line of a Linux `/proc` file (`/proc/meminfo`,
/// `/proc/self/status`) in bytes; `None` where the file or line is missing.
pub fn proc_kib(path: &str, key: &str) -> Option<u64> {
    let text = std::fs::read_to_string(path).ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line
        .trim_start_matches(key)
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    kib.checked_mul(1024)
}

/// Bytes as "1.3 GiB" or "512 MiB".
fn gib(bytes: u64) -> String {
    if bytes >= 1 << 30 {
        format!("{:.1} GiB", bytes as f64 / (1u64 << 30) as f64)
    } else {
        format!("{} MiB", bytes >> 20)
    }
}

/// Frames read from files named by a pattern.
pub struct SequenceSource {
    sequence: crate::io::Sequence,
    frames: Vec<i32>,
}

impl SequenceSource {
    /// Opens `pattern` over `range` (`A-B` or `A`), or over every frame
    /// found on disk when `range` is `None`. Every frame's file is checked
    /// up front, so a missing frame fails the run before any work.
    pub fn open(
        pattern: &str,
        range: Option<&str>,
        options: crate::io::ReadOptions,
    ) -> Result<SequenceSource, PipelineError> {
        use crate::io::{FramePattern, FrameRange, Sequence};
        let pattern = FramePattern::parse_or_file(pattern)?;
        let range = match range {
            Some(text) => text.parse::<FrameRange>()?,
            None => {
                let found = pattern.discover()?;
                match (found.first(), found.last()) {
                    (Some(&a), Some(&b)) => FrameRange::new(a, b)?,
                    _ => {
                        return Err(PipelineError::Source(format!(
                            "no file matches {} (give --frames, or check the pattern)",
                            pattern.as_str()
                        )));
                    }
                }
            }
        };
        let sequence = Sequence::new(pattern, range, options);
        sequence.check_present()?;
        Ok(SequenceSource {
            frames: range.frames().collect(),
            sequence,
        })
    }
}

impl FrameSource for SequenceSource {
    fn frames(&self) -> Vec<i32> {
        self.frames.clone()
    }

    fn read(&mut self, f: i32) -> Result<(TriMesh, ValidationReport), PipelineError> {
        let frame = self.sequence.read_frame(f)?;
        Ok((frame.mesh, frame.report))
    }

    fn input_paths(&self) -> Vec<PathBuf> {
        self.frames
            .iter()
            .map(|&f| self.sequence.pattern().path(f))
            .collect()
    }
}

/// A user's mesh sequence as an evaluation scene (`fluidtex compare
/// --mesh`): frames read and validated as `fluidtex run` reads them, no
/// exact flow (the harness then carries by the input velocity and says so
/// in the report).
pub struct SequenceScene {
    source: SequenceSource,
    name: String,
    pattern: String,
    fps: f64,
    frames: Vec<i32>,
}

impl SequenceScene {
    /// `pattern` over `range` (every frame found when `None`), at `fps`,
    /// named `name` in reports; at least two frames.
    pub fn open(
        pattern: &str,
        range: Option<&str>,
        fps: f64,
        name: &str,
    ) -> Result<SequenceScene, PipelineError> {
        let source = SequenceSource::open(pattern, range, crate::io::ReadOptions::default())?;
        let frames = source.frames();
        if frames.len() < 2 {
            return Err(PipelineError::Source(format!(
                "{pattern}: a comparison needs at least two frames"
            )));
        }
        Ok(SequenceScene {
            source,
            name: name.to_string(),
            pattern: pattern.to_string(),
            fps,
            frames,
        })
    }
}

impl crate::scenes::Scene for SequenceScene {
    fn info(&self) -> crate::scenes::SceneInfo {
        crate::scenes::SceneInfo {
            name: self.name.clone(),
            description: format!("your simulation, {}", self.pattern),
            fps: self.fps,
            first: self.frames.first().copied().unwrap_or(0),
            last: self.frames.last().copied().unwrap_or(0),
            parameters: serde_json::json!({ "mesh": self.pattern, "fps": self.fps }),
        }
    }

    fn frame(&mut self, f: i32) -> Result<TriMesh, crate::scenes::SceneError> {
        let input = |message: String| crate::scenes::SceneError::Input { frame: f, message };
        let (mesh, _) = self.source.read(f).map_err(|e| input(e.to_string()))?;
        if mesh.velocity().is_none() {
            return Err(input(format!(
                "{}: no per-vertex velocity, which the comparison carries points by",
                self.source.sequence.pattern().path(f).display()
            )));
        }
        Ok(mesh)
    }

    fn exact_velocity(&self, _: glam::Vec3, _: f64) -> Option<glam::Vec3> {
        None
    }
}

/// Frames generated by a scene of [`crate::scenes`].
pub struct SceneSource {
    scene: Box<dyn crate::scenes::Scene>,
    frames: Vec<i32>,
}

impl SceneSource {
    pub fn new(scene: Box<dyn crate::scenes::Scene>) -> SceneSource {
        let info = scene.info();
        SceneSource {
            frames: (info.first..=info.last).collect(),
            scene,
        }
    }
}

impl FrameSource for SceneSource {
    fn frames(&self) -> Vec<i32> {
        self.frames.clone()
    }

    fn read(&mut self, f: i32) -> Result<(TriMesh, ValidationReport), PipelineError> {
        let mut mesh = self
            .scene
            .frame(f)
            .map_err(|e| PipelineError::Source(e.to_string()))?;
        let report = crate::mesh::validate(&mut mesh)
            .map_err(|e| PipelineError::Source(format!("scene frame {f}: {e}")))?;
        Ok((mesh, report))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::{Atlas, AtlasParams, fixtures::icosphere};
    use crate::coherence::Texels;
    use crate::methods::{FrameContext, FrameResult, MethodError, SpentBuffers};
    use rand::{Rng, SeedableRng};

    /// The erosion method, noting the sizes of what `recycle` hands it.
    struct Recycling {
        inner: crate::methods::erosion::Erosion,
        handed: Vec<(usize, usize, usize)>,
    }

    impl Method for Recycling {
        fn name(&self) -> &'static str {
            self.inner.name()
        }
        fn channel_specs(&self) -> Vec<ChannelSpec> {
            self.inner.channel_specs()
        }
        fn step(&mut self, frame: &FrameContext<'_>) -> Result<FrameResult, MethodError> {
            self.inner.step(frame)
        }
        fn save_state(&self) -> Result<Vec<u8>, MethodError> {
            self.inner.save_state()
        }
        fn load_state(&mut self, bytes: &[u8]) -> Result<(), MethodError> {
            self.inner.load_state(bytes)
        }
        fn recycle(&mut self, spent: SpentBuffers) {
            self.handed.push((
                spent.uv.as_ref().map_or(0, Vec::len),
                spent.exemplar_lod.as_ref().map_or(0, Vec::len),
                spent.values.as_ref().map_or(0, Vec::len),
            ));
            self.inner.recycle(spent);
        }
    }

    /// No file holds the per-texel uv or exemplar levels, so `run` hands
    /// both back to the method after every frame, whole; the colour values
    /// come back too, except on preview frames (the preview shades them).
    #[test]
    fn run_hands_the_evaluation_buffers_back_after_every_frame() {
        let scene = crate::scenes::by_name(
            "rigid-rotation",
            Some(crate::scenes::SceneParams {
                resolution: 10,
                fps: 24.0,
                first: 0,
                last: 2,
                seed: 0,
            }),
        )
        .expect("scene");
        let mut source = SceneSource::new(scene);
        let out = tempfile::tempdir().expect("tempdir");
        let n = 64 * 64;
        for (preview_every, values) in [(0, [3 * n; 3]), (2, [0, 3 * n, 0])] {
            let job = Job {
                out_dir: out.path().join(format!("every{preview_every}")),
                atlas: AtlasParams::square(64),
                fps: 24.0,
                outputs: OutputOptions {
                    preview_every,
                    preview_size: 32,
                    ..Default::default()
                },
                resume: false,
                fingerprint: "recycle".into(),
                hooks: Default::default(),
            };
            let exemplar = std::sync::Arc::new(crate::exemplar::builtin_pebbles(64, 0));
            let mut method = Recycling {
                inner: crate::methods::erosion::Erosion::new(Default::default(), exemplar, 0)
                    .expect("params"),
                handed: Vec::new(),
            };
            run(&job, &mut source, &mut method, &mut |_| {}).expect("run");
            let want: Vec<_> = values.iter().map(|&v| (n, n, v)).collect();
            assert_eq!(method.handed, want, "previews every {preview_every}");
        }
    }

    /// An 8-bit channel handed to the writer as its samples writes the
    /// bytes its floats would (values outside [0, 1] and NaN included), and
    /// its floats come back for the method; previews, other formats and
    /// textures no encoder takes stay floats.
    #[test]
    fn eight_bit_channels_write_the_bytes_of_their_floats() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let sizes = [(1, 1, 1), (7, 3, 3), (33, 17, 4), (64, 9, 2), (5, 40, 3)];
        for (k, &(width, height, channels)) in sizes.iter().enumerate() {
            let data = (0..width as usize * height as usize * channels)
                .map(|i| match i % 11 {
                    0 => f32::NAN,
                    1 => -0.3,
                    2 => 1.7,
                    _ => rng.random::<f32>(),
                })
                .collect();
            let t = Texture {
                width,
                height,
                channels,
                data,
            };
            let (handed, spent) = written_channels(vec![t.clone()], &[ChannelFormat::Png8], true);
            assert_eq!(spent.as_deref().map(bits), Some(bits(&t.data)), "{k}");
            let OutChannel::Eight { samples, .. } = &handed[0] else {
                panic!("{k}: an 8-bit channel is handed over as samples");
            };
            let want: Vec<u8> = t
                .data
                .iter()
                .map(|&x| crate::io::image::quantize_8(x))
                .collect();
            assert_eq!(samples, &want, "{k}");
            let mut files = Staging::new(None, None);
            let eight = dir.path().join(format!("eight{k}.png"));
            let float = dir.path().join(format!("float{k}.png"));
            let a = write_out_channel(&mut files, &eight, &handed[0], ChannelFormat::Png8)
                .expect("write");
            let b = write_channel(&mut files, &float, &t, ChannelFormat::Png8).expect("write");
            files.commit().expect("commit");
            assert!(a.is_some() && a == b, "{k}: same PNG bytes");
            assert_eq!(std::fs::read(&eight).ok(), b, "{k}: the file holds them");
        }
        let t = Texture {
            width: 4,
            height: 4,
            channels: 3,
            data: vec![0.5; 48],
        };
        let floats = |c: &[OutChannel]| c.iter().map(|c| c.float().is_some()).collect::<Vec<_>>();
        let (handed, spent) = written_channels(vec![t.clone()], &[ChannelFormat::Png8], false);
        assert_eq!(
            (floats(&handed), spent),
            (vec![true], None),
            "a preview frame"
        );
        let formats = [
            ChannelFormat::Png16,
            ChannelFormat::Exr,
            ChannelFormat::Png8,
        ];
        let (handed, spent) = written_channels(vec![t.clone(); 4], &formats, true);
        assert_eq!(floats(&handed), vec![true, true, false, true]);
        assert_eq!(spent.map(|v| v.len()), Some(48));
        let bad = Texture {
            channels: 5,
            data: vec![0.5; 80],
            ..t
        };
        let (handed, spent) = written_channels(vec![bad], &[ChannelFormat::Png8], true);
        assert_eq!((floats(&handed), spent), (vec![true], None), "5 channels");
    }

    /// `source.F.exr` holds each id as a float (-1 outside) and the ids come
    /// back unchanged, whether they went through the file in their own
    /// buffer or, with an id past 2^24, through a copy.
    #[test]
    fn source_ids_come_back_from_their_file() {
        let atlas = Atlas::build(&icosphere(2), &AtlasParams::square(16)).expect("atlas");
        let n = (atlas.width * atlas.height) as usize;
        let dir = tempfile::tempdir().expect("tempdir");
        let mut rng = rand_pcg::Pcg64::seed_from_u64(12);
        for big in [false, true] {
            let mut ids: Vec<u32> = (0..n).map(|_| rng.random_range(0..5000)).collect();
            ids[0] = SOURCE_OUTSIDE;
            ids[1] = SOURCE_UNCOVERED;
            ids[2] = (1 << 24) - 1;
            if big {
                ids[3] = (1 << 24) + 1;
            }
            let path = dir.path().join(format!("source{big}.exr"));
            let mut files = Staging::new(None, None);
            let back = write_source_ids(&mut files, &path, &atlas, ids.clone()).expect("write");
            files.commit().expect("commit");
            assert_eq!(back, ids, "big ids: {big}");
            let read = crate::io::image_read::read_image(&path).expect("read");
            assert_eq!(read.texture.data.len(), n);
            for (i, (&v, &id)) in read.texture.data.iter().zip(&ids).enumerate() {
                let want = if id == SOURCE_OUTSIDE {
                    -1.0
                } else {
                    id as f32
                };
                assert_eq!(v.to_bits(), want.to_bits(), "texel {i}, big ids: {big}");
            }
        }
    }

    /// The coherence measurement reads the written values texel by texel:
    /// each must be bit for bit what the whole-atlas conversion (the one a
    /// resumed run's file read-back matches) gives, for every format,
    /// including values outside [0, 1] and ids that f32 rounds.
    #[test]
    fn written_texels_match_the_whole_atlas_conversion() {
        let atlas = Atlas::build(&icosphere(2), &AtlasParams::square(16)).expect("atlas");
        let n = (atlas.width * atlas.height) as usize;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let mut source: Vec<u32> = (0..n).map(|_| rng.random_range(0..40)).collect();
        source[0] = SOURCE_OUTSIDE;
        source[1] = SOURCE_UNCOVERED;
        source[2] = (1 << 24) + 1;
        for channels in [1usize, 3, 4] {
            let data = (0..n * channels)
                .map(|_| rng.random_range(-0.2f32..1.2))
                .collect();
            let colour = Texture {
                width: atlas.width,
                height: atlas.height,
                channels,
                data,
            };
            for format in [
                ChannelFormat::Png8,
                ChannelFormat::Png16,
                ChannelFormat::Exr,
            ] {
                let whole = written_grey(&colour, format);
                // As floats, and (8-bit PNG) as the samples handed to the
                // writer instead.
                let (handed, _) = written_channels(vec![colour.clone()], &[format], true);
                let float = OutChannel::Float(colour.clone());
                assert_eq!(
                    matches!(handed[0], OutChannel::Eight { .. }),
                    format == ChannelFormat::Png8
                );
                for written in [&float, &handed[0]] {
                    let texels = WrittenTexels {
                        atlas: &atlas,
                        source: &source,
                        colour: Some((written, format)),
                        renewal: &[],
                    };
                    texels.validate().expect("fits");
                    for (i, g) in whole.iter().enumerate() {
                        assert_eq!(texels.grey(i).to_bits(), g.to_bits(), "{format:?} {i}");
                    }
                }
            }
        }
        let texels = WrittenTexels {
            atlas: &atlas,
            source: &source,
            colour: None,
            renewal: &[],
        };
        assert!(texels.validate().is_err(), "no colour: nothing to measure");
        assert_eq!(texels.source(0), SOURCE_OUTSIDE);
        assert_eq!(texels.source(1), SOURCE_UNCOVERED);
        assert_eq!(texels.source(2), 1 << 24, "as source.F.exr stores it");
        assert_eq!(texels.source(n), SOURCE_OUTSIDE);
        assert_eq!(texels.source(7), source[7]);
    }

    /// `patches.F.png` made in 8 bits from the dilated ids is byte for byte
    /// the float colour atlas encoded as before (ids dilate as colours do),
    /// with outside, uncovered and large ids.
    #[test]
    fn patch_png_from_ids_is_the_colour_atlas_encoded() {
        let atlas = Atlas::build(&icosphere(2), &AtlasParams::square(96)).expect("atlas");
        let n = (atlas.width * atlas.height) as usize;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        let mut source: Vec<u32> = (0..n).map(|_| rng.random_range(0..500)).collect();
        // The chart texels keep their ids; the rest are outside.
        let inside = atlas.triangle_map();
        for (s, &t) in source.iter_mut().zip(&inside) {
            if t == u32::MAX {
                *s = SOURCE_OUTSIDE;
            }
        }
        let chart: Vec<usize> = (0..n).filter(|&i| inside[i] != u32::MAX).collect();
        assert!(chart.len() > 100, "{} chart texels", chart.len());
        source[chart[0]] = SOURCE_UNCOVERED;
        source[chart[1]] = (1 << 24) - 1;
        for radius in [1, 4] {
            let want = crate::io::image::encode_png(
                &patch_colours(&atlas, &source, radius).expect("dilate"),
                &PngOptions::default(),
            )
            .expect("encode");
            let got = patch_png(&atlas, source.clone(), radius).expect("encode");
            assert!(got == want, "radius {radius}: the bytes differ");
        }
        // Ids past 2^24 (not exact as floats) are coloured as themselves.
        source[chart[2]] = 1 << 24;
        source[chart[3]] = u32::MAX - 1;
        let want = crate::io::image::encode_png(
            &patch_colours(&atlas, &source, 3).expect("dilate"),
            &PngOptions::default(),
        )
        .expect("encode");
        assert!(patch_png(&atlas, source.clone(), 3).expect("encode") == want);
        assert!(
            patch_png(&atlas, source[1..].to_vec(), 3).is_err(),
            "one id short"
        );
    }

    /// Write-behind needs a second frame's buffers: with memory for the
    /// serial estimate only, frames are written in place with one warning;
    /// with memory for both, behind, with no warning and the larger
    /// estimate reported; a test can ask for in place. The added bytes per
    /// texel are exactly the written frame's: channels, ids, debug views
    /// and encoders.
    #[test]
    fn write_behind_only_where_its_memory_is_available() {
        use crate::write_behind::Mode;
        let channels = vec![ChannelSpec {
            name: "color".into(),
            format: ChannelFormat::Png8,
        }];
        let job = |available: u64, in_place: bool| Job {
            out_dir: PathBuf::from("unused"),
            atlas: AtlasParams::square(1024),
            fps: 24.0,
            outputs: OutputOptions::default(),
            resume: false,
            fingerprint: String::new(),
            hooks: TestHooks {
                available_memory: Some(available),
                write_in_place: in_place,
                ..Default::default()
            },
        };
        let serial = estimate_memory(
            &AtlasParams::square(1024),
            &channels,
            &OutputOptions::default(),
        );
        let behind = serial
            .clone()
            .writing_behind(&channels, &OutputOptions::default());
        // 4·4 channel floats + 4 ids + 20 debug + 8 encoding.
        assert_eq!(
            behind.bytes_per_texel - serial.bytes_per_texel,
            16 + 4 + 20 + 8
        );
        assert_eq!(behind.bytes - serial.bytes, (1 << 20) * 48);
        let no_debug = OutputOptions {
            debug: false,
            ..Default::default()
        };
        let lean = estimate_memory(&AtlasParams::square(1024), &channels, &no_debug);
        assert_eq!(
            lean.clone()
                .writing_behind(&channels, &no_debug)
                .bytes_per_texel
                - lean.bytes_per_texel,
            28
        );
        for (available, in_place, mode, warned) in [
            (behind.bytes, false, Mode::Behind, false),
            (behind.bytes - 1, false, Mode::Inline, true),
            (serial.bytes, false, Mode::Inline, true),
            (behind.bytes, true, Mode::Inline, false),
        ] {
            let job = job(available, in_place);
            let mut warnings = Vec::new();
            let mut observer = |e: Event<'_>| {
                if let Event::Warning(w) = e {
                    warnings.push(w);
                }
            };
            let estimate = serial.clone().with_available(Some(available));
            let (got, reported) = write_mode(&job, estimate, &channels, &mut observer);
            assert_eq!(got, mode, "available {available}, in place {in_place}");
            assert_eq!(warnings.len(), usize::from(warned), "{warnings:?}");
            let expected = if mode == Mode::Behind {
                &behind
            } else {
                &serial
            };
            assert_eq!(reported.bytes, expected.bytes);
        }
    }
}
