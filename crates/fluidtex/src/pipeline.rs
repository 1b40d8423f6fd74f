//! The frame job: read a frame, build its BVH and atlas, let the method
//! fill the atlas, dilate, write every output atomically, save the method's
//! state; repeat. Frames are streamed (at most the previous and the current
//! mesh are held), so memory does not grow with the sequence length.
//!
//! This module is the run loop (with its look-ahead thread) and the frame
//! sources; what is written, and how, is [`crate::output`]'s: the file
//! sink and writers, the coherence sink, `state.bin`, the memory estimate.
//! The types front ends use from there are re-exported here.
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

mod phases;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use crate::driver::{Driver, PendingFrame};
use crate::frame::{FrameGeometry, GeometryError, StageClock};
use crate::io::InputGuard;
use crate::mesh::{TriMesh, ValidationReport};
use crate::methods::Method;
use crate::output::write_behind::Mode;
use crate::output::{
    CoherenceSink, CoherenceSinkSettings, FileSink, FrameWriter, MethodInfo, write_frames,
};

pub use crate::exemplar::channels::{ChannelFormat, ChannelSpec};
pub use crate::output::{
    Event, FrameHook, FrameStats, Job, MemoryEstimate, OutputOptions, Phase, PipelineError,
    TestHooks, UNKNOWN_TRIANGLES, available_memory, estimate_memory, frame_tag, load_state_bytes,
    patch_colour, proc_kib, resident_memory,
};

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
    /// The largest frame's mesh, for the memory estimate made before the
    /// first frame; `None` where the source cannot tell without reading
    /// every frame (the estimate then assumes [`UNKNOWN_TRIANGLES`]).
    fn largest_frame(&mut self) -> Result<Option<TriMesh>, PipelineError> {
        Ok(None)
    }
}

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    pub frames_done: usize,
    pub resumed_after: Option<i32>,
    pub seconds: f64,
}

/// Runs `method` over every frame of `source`: the [`Driver`] with a sink
/// that writes each frame's files.
pub fn run(
    job: &Job,
    source: &mut dyn FrameSource,
    method: &mut dyn Method,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Summary, PipelineError> {
    match job.phase {
        Phase::OnePass => {}
        Phase::Select => return phases::select(job, source, method, observer),
        Phase::Resample => return phases::resample(job, source, method, observer),
    }
    let start = Instant::now();
    // Everything that can be refused without reading a frame, first.
    job.atlas.validate().map_err(PipelineError::AtlasParams)?;
    let mode = check_memory(job, source, method, observer)?;
    let specs = method.channel_specs();
    // Held until this function returns, on success and on error alike.
    let lock = open_output(job, observer)?;
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
    let info = MethodInfo {
        name: method.name(),
        specs,
    };
    let mut writer = FrameWriter::new(job, &guard, info, first_frame);
    add_coherence(job, &mut writer, resumed_after);
    let mut driver = job_driver(job, method);
    driver.set_previous(previous);
    let done = write_frames(mode, writer, observer, |sink| {
        drive(
            job,
            source,
            &frames,
            &mut OnePass {
                job,
                driver: &mut driver,
                sink,
            },
        )
    })?;
    drop(lock);
    Ok(Summary {
        frames_done: done,
        resumed_after,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The coherence numbers come with the debug outputs: the sink that
/// measures them, for a run resumed after `resumed_after` (if so).
fn add_coherence(job: &Job, writer: &mut FrameWriter<'_>, resumed_after: Option<i32>) {
    if job.outputs.debug {
        let settings = CoherenceSinkSettings {
            switch_map: job.outputs.switch_map,
            ..Default::default()
        };
        writer.add_sink(Box::new(CoherenceSink::new(job, settings, resumed_after)));
    }
}

/// The driver of `job`'s frames: its frame time, and dilation over the
/// gutter (twice its width, at least 2 texels).
fn job_driver<'m>(job: &Job, method: &'m mut dyn Method) -> Driver<'m> {
    use crate::methods::budget::{MemoryBudget, Resident};
    let mut driver = Driver::new(method, 1.0 / job.fps, job.atlas.gutter.max(1) * 2);
    // The limit is checked inside the stages that grow, against the same
    // resident set as after each frame (or the test hook's).
    let resident = match job.hooks.resident_memory {
        Some(bytes) => Resident::Fixed(bytes),
        None => Resident::Read(resident_memory),
    };
    driver.set_memory_budget(MemoryBudget::new(job.max_memory, resident));
    driver
}

/// A frame that a stage ended on the memory budget
/// ([`crate::methods::MethodError::Memory`]) as the run's memory error,
/// with the method's account; any other error as it is.
fn within_frame(e: PipelineError, driver: &Driver<'_>) -> PipelineError {
    match e {
        PipelineError::Method(crate::methods::MethodError::Memory(trip)) => {
            PipelineError::MemoryInFrame {
                frame: trip.frame,
                stage: trip.stage,
                resident: trip.resident,
                limit: trip.limit,
                detail: driver.method().memory_report(),
            }
        }
        e => e,
    }
}

/// The memory estimate of the run, refused where the machine has less
/// available and reported to `observer`; returns how frames are written.
fn check_memory(
    job: &Job,
    source: &mut dyn FrameSource,
    method: &dyn Method,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Mode, PipelineError> {
    let estimate = fitting_estimate(job, source, method)?;
    let (mode, estimate) = write_mode(job, estimate, &method.channel_specs(), observer);
    observer(Event::Memory(estimate));
    Ok(mode)
}

/// The memory estimate of `job` (its largest frame's triangles from
/// `source`, what `method` holds) with what the machine has available,
/// refused where it does not fit. An atlas that cannot fit on its own is
/// refused before any frame is read.
fn fitting_estimate(
    job: &Job,
    source: &mut dyn FrameSource,
    method: &dyn Method,
) -> Result<MemoryEstimate, PipelineError> {
    let available = job.hooks.available_memory.or_else(available_memory);
    let estimate = |triangles: u64, largest: Option<&TriMesh>| {
        estimate_memory(
            &job.atlas,
            &method.channel_specs(),
            &job.outputs,
            method.memory_model(&job.atlas, largest),
            triangles,
        )
        .with_available(available)
    };
    estimate(0, None).check()?;
    let largest = source.largest_frame()?;
    let triangles = largest
        .as_ref()
        .map_or(UNKNOWN_TRIANGLES, |m| m.triangles.len() as u64);
    let estimate = estimate(triangles, largest.as_ref());
    estimate.check()?;
    Ok(estimate)
}

/// Creates the output folder and takes its lock (taken before the
/// temporaries are cleaned, which would otherwise delete those of a run
/// still writing).
fn open_output(
    job: &Job,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<crate::io::lock::Acquired, PipelineError> {
    open_output_locking(job, observer, crate::io::lock::LOCK_FILE)
}

/// [`open_output`] with the lock file `lock`.
fn open_output_locking(
    job: &Job,
    observer: &mut dyn FnMut(Event<'_>),
    lock: &str,
) -> Result<crate::io::lock::Acquired, PipelineError> {
    std::fs::create_dir_all(&job.out_dir).map_err(|e| PipelineError::Output {
        path: job.out_dir.clone(),
        message: format!("cannot create the output folder: {e}"),
    })?;
    let lock = crate::io::OutputLock::acquire_named(&job.out_dir, lock)?;
    if let Some(stale) = &lock.stale {
        observer(Event::Warning(format!(
            "{}: took over the lock of a run that is no longer running ({})",
            lock.lock.path().display(),
            stale.describe()
        )));
    }
    Ok(lock)
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
    each: &mut dyn FrameLoop,
) -> Result<(), PipelineError> {
    let total = frames.len();
    std::thread::scope(|scope| {
        let mut ahead = frames
            .first()
            .map(|&number| Ahead::start(scope, job, source, number));
        for (k, &number) in frames.iter().enumerate() {
            each.observe(Event::Start {
                number,
                index: k,
                total,
            });
            let Some(this) = ahead.take() else { break };
            let (geometry, clock) = this.finish()?;
            if geometry.report.dropped_degenerate > 0 {
                each.observe(Event::Warning(format!(
                    "frame {number}: dropped {} zero-area triangles",
                    geometry.report.dropped_degenerate
                )));
            }
            ahead = frames
                .get(k + 1)
                .map(|&next| Ahead::start(scope, job, source, next));
            each.frame(PendingFrame {
                geometry: Arc::new(geometry),
                clock,
            })?;
        }
        Ok(())
    })
}

/// What [`drive`] does with each built frame, and where its events go.
trait FrameLoop {
    fn observe(&mut self, event: Event<'_>);
    fn frame(&mut self, frame: PendingFrame) -> Result<(), PipelineError>;
}

/// The one-pass run: each frame stepped and handed to the file sink.
struct OnePass<'a, 'd, 'm, 'w, 's, 'o, 'p> {
    job: &'a Job,
    driver: &'d mut Driver<'m>,
    sink: &'s mut FileSink<'w, 'o, 'p>,
}

impl FrameLoop for OnePass<'_, '_, '_, '_, '_, '_, '_> {
    fn observe(&mut self, event: Event<'_>) {
        self.sink.observe(event);
    }

    fn frame(&mut self, frame: PendingFrame) -> Result<(), PipelineError> {
        let number = frame.geometry.number;
        (self.driver.step(frame, self.sink)).map_err(|e| within_frame(e, self.driver))?;
        check_memory_limit(self.job, number, self.driver)
    }
}

/// Stops the run after frame `number` (handed to the sink, so it is
/// written and counted) when the process holds more than the job's limit:
/// a run whose state grows with its history ends with the cause named
/// instead of in the kernel's OOM killer, and `--resume` goes on.
fn check_memory_limit(job: &Job, number: i32, driver: &Driver<'_>) -> Result<(), PipelineError> {
    let Some(limit) = job.max_memory else {
        return Ok(());
    };
    let Some(resident) = job.hooks.resident_memory.or_else(resident_memory) else {
        return Ok(());
    };
    if resident <= limit {
        return Ok(());
    }
    Err(PipelineError::MemoryLimit {
        frame: number,
        resident,
        limit,
        detail: driver.method().memory_report(),
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
) -> (Mode, MemoryEstimate) {
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
    let Some(last) = crate::output::load_for_resume(job, method)? else {
        return Ok((None, None));
    };
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

    /// Reads the frame with the largest file: the frames of a simulation
    /// share one format and one set of properties, so the file size
    /// follows the element counts.
    fn largest_frame(&mut self) -> Result<Option<TriMesh>, PipelineError> {
        let size =
            |f: i32| std::fs::metadata(self.sequence.pattern().path(f)).map_or(0, |m| m.len());
        let Some(largest) = self.frames.iter().copied().max_by_key(|&f| (size(f), -f)) else {
            return Ok(None);
        };
        Ok(Some(self.sequence.read_frame(largest)?.mesh))
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
        Self::open_with(pattern, range, fps, name, crate::io::ReadOptions::default())
    }

    /// [`SequenceScene::open`] with reader options (e.g. the attribute
    /// that selects the exemplars, which every frame must carry).
    pub fn open_with(
        pattern: &str,
        range: Option<&str>,
        fps: f64,
        name: &str,
        options: crate::io::ReadOptions,
    ) -> Result<SequenceScene, PipelineError> {
        let source = SequenceSource::open(pattern, range, options)?;
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

    /// The first frame's count: a scene's surface changes little in size
    /// over its frames, and generating every one would double the run.
    fn largest_frame(&mut self) -> Result<Option<TriMesh>, PipelineError> {
        let Some(&first) = self.frames.first() else {
            return Ok(None);
        };
        Ok(Some(self.read(first)?.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::AtlasParams;
    use crate::methods::{FrameContext, FrameResult, MethodError};

    /// The erosion method, noting the sizes of the buffers each frame's
    /// arena lends it.
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
            let lent = frame.arena.take();
            self.handed.push((
                lent.uv.as_ref().map_or(0, Vec::len),
                lent.exemplar_lod.as_ref().map_or(0, Vec::len),
                lent.values.as_ref().map_or(0, Vec::len),
            ));
            frame.arena.hand_back(lent);
            self.inner.step(frame)
        }
        fn save_state(&self) -> Result<Vec<u8>, MethodError> {
            self.inner.save_state()
        }
        fn load_state(&mut self, bytes: &[u8]) -> Result<(), MethodError> {
            self.inner.load_state(bytes)
        }
    }

    /// No file holds the per-texel uv or exemplar levels, so `run` keeps
    /// the uv after every frame, whole, and lends it to the next frame's
    /// step; the levels it does not ask for are never made (the wrapper
    /// of the recycling protocol before the arena hid that: it did not
    /// pass the question on, so erosion made levels nobody read). The
    /// colour values come back too, except from preview frames (the
    /// preview shades them). The first frame is lent nothing.
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
                max_memory: None,
                phase: Default::default(),
                hooks: Default::default(),
            };
            let exemplar = std::sync::Arc::new(crate::exemplar::builtin_pebbles(64, 0));
            let mut method = Recycling {
                inner: crate::methods::erosion::Erosion::new(Default::default(), exemplar, 0)
                    .expect("params"),
                handed: Vec::new(),
            };
            run(&job, &mut source, &mut method, &mut |_| {}).expect("run");
            let want: Vec<_> = std::iter::once((0, 0, 0))
                .chain(values[..2].iter().map(|&v| (n, 0, v)))
                .collect();
            assert_eq!(method.handed, want, "previews every {preview_every}");
        }
    }

    /// Write-behind needs a second frame's buffers: with memory for the
    /// serial estimate only, frames are written in place with one warning;
    /// with memory for both, behind, with no warning and the larger
    /// estimate reported; a test can ask for in place. The added bytes per
    /// texel are exactly the written frame's: quantized channels, ids and
    /// debug ids.
    #[test]
    fn write_behind_only_where_its_memory_is_available() {
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
            max_memory: None,
            phase: Default::default(),
            hooks: TestHooks {
                available_memory: Some(available),
                write_in_place: in_place,
                ..Default::default()
            },
        };
        let model = crate::methods::MemoryModel::default();
        let estimate = |outputs: &OutputOptions| {
            estimate_memory(
                &AtlasParams::square(1024),
                &channels,
                outputs,
                model,
                50_000,
            )
        };
        let serial = estimate(&OutputOptions::default());
        let behind = serial
            .clone()
            .writing_behind(&channels, &OutputOptions::default());
        // The written frame's 4 8-bit samples, 4 ids and 4 debug ids.
        assert_eq!(behind.bytes_per_texel - serial.bytes_per_texel, 4 + 4 + 4);
        assert_eq!(behind.bytes - serial.bytes, (1 << 20) * 12);
        let no_debug = OutputOptions {
            debug: false,
            ..Default::default()
        };
        let lean = estimate(&no_debug);
        assert_eq!(
            lean.clone()
                .writing_behind(&channels, &no_debug)
                .bytes_per_texel
                - lean.bytes_per_texel,
            8
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
