//! A run in two phases, for a render farm: phase 1 ([`select`]) is the
//! sequential pass (frame F's patches need frame F − 1's) and writes per
//! frame only its selection (`selection.F.bin`) and `state.bin`; phase 2
//! ([`resample`]) turns each frame's selection into every file a one-pass
//! run writes, frames independent of each other, so ranges of frames go
//! to as many processes (or machines sharing the folder) as there are, at
//! once and beside phase 1 (a range holds only its own lock,
//! `fluidtex.resample.A-B.lock`). Phase 1 then phase 2 over all frames
//! writes the bytes of a one-pass run, the `selection.F.bin` files added
//! and `stats.F.json`'s timings aside (its seconds, as for any two runs,
//! and the names of the stages timed, which differ between the phases).
//!
//! Only the advection and creation (and the methods' state) are phase 1's
//! alone: erosion's fill and update run in both phases (the selecting
//! phase needs the coverage to place new patches), which is why its
//! selection is the patches and not per-texel arrays.
//!
//! The coherence numbers of frame F (with debug outputs) measure it
//! against frame F − 1 as written: a resampled range whose first frame
//! has one before resamples that one too, first, for the measurement
//! alone (none of its files is written).

use std::sync::Arc;
use std::time::Instant;

use super::{
    FrameLoop, FrameSource, Summary, add_coherence, check_memory, check_memory_limit, drive,
    fitting_estimate, job_driver, open_output, open_output_locking, resume, within_frame,
};
use crate::driver::{Driver, PendingFrame};
use crate::frame::{FrameGeometry, StageClock};
use crate::io::{InputGuard, Staging};
use crate::methods::Method;
use crate::output::{
    Event, FileSink, FrameStats, FrameWriter, Job, MethodInfo, PipelineError, STATE_FILE,
    SavedSelection, frame_tag, save_state, write_frames,
};

/// Phase 1: every frame of `source` selected, its selection and the
/// method's state written; `--resume` goes on after the last finished one.
pub(super) fn select(
    job: &Job,
    source: &mut dyn FrameSource,
    method: &mut dyn Method,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Summary, PipelineError> {
    let start = Instant::now();
    job.atlas.validate().map_err(PipelineError::AtlasParams)?;
    fitting_estimate(job, source, method)?;
    let lock = open_output(job, observer)?;
    let guard = InputGuard::new(source.input_paths());
    // Only its own: resampled ranges may be writing beside it.
    crate::io::remove_stale_temporaries_of(&job.out_dir, &guard, |target| {
        target == STATE_FILE || target.starts_with("selection.")
    })?;
    let mut frames = source.frames();
    let first_frame = frames.first().copied().unwrap_or(0);
    let (previous, resumed_after) = if job.resume {
        resume(job, source, method, &mut frames)?
    } else {
        (None, None)
    };
    let name = method.name();
    let mut driver = job_driver(job, method);
    driver.set_previous(previous);
    let mut selecting = Selecting {
        job,
        guard: &guard,
        name,
        first_frame,
        driver: &mut driver,
        observer,
        done: 0,
    };
    drive(job, source, &frames, &mut selecting)?;
    let done = selecting.done;
    drop(lock);
    Ok(Summary {
        frames_done: done,
        resumed_after,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Phase 1's frame loop.
struct Selecting<'a, 'd, 'm, 'o> {
    job: &'a Job,
    guard: &'a InputGuard,
    name: &'static str,
    first_frame: i32,
    driver: &'d mut Driver<'m>,
    observer: &'o mut dyn FnMut(Event<'_>),
    done: usize,
}

impl FrameLoop for Selecting<'_, '_, '_, '_> {
    fn observe(&mut self, event: Event<'_>) {
        (self.observer)(event);
    }

    /// The frame selected; its selection, then the state after it,
    /// committed (a frame counts finished once `state.bin` says so).
    fn frame(&mut self, frame: PendingFrame) -> Result<(), PipelineError> {
        let PendingFrame {
            geometry,
            mut clock,
        } = frame;
        let (job, number) = (self.job, geometry.number);
        let previous = self.driver.previous().map(|p| p.number);
        let selection =
            (self.driver.select(&geometry)).map_err(|e| within_frame(e.into(), self.driver))?;
        clock.lap("select");
        let saved = SavedSelection::new(
            job,
            self.name,
            number,
            previous,
            self.first_frame,
            selection,
        );
        let mut files = Staging::new(Some(self.guard), job.hooks.write.as_ref());
        saved.stage(job, &mut files)?;
        files.commit()?;
        let state = self.driver.method().save_state()?;
        save_state(job, self.guard, self.name, state, number)?;
        clock.lap("write");
        if let Some(hook) = &job.hooks.after_frame {
            hook(number);
        }
        let stats = FrameStats {
            frame: number,
            method: self.name.to_string(),
            vertices: geometry.mesh.vertex_count(),
            triangles: geometry.mesh.triangle_count(),
            selection_bytes: Some(saved.selection.bytes().len()),
            seconds: clock
                .stages
                .iter()
                .map(|(n, s)| (n.to_string(), *s))
                .collect(),
            ..Default::default()
        };
        (self.observer)(Event::Done { stats: &stats });
        self.done += 1;
        check_memory_limit(job, number, self.driver)
    }
}

/// Phase 2: each frame of `source` resampled from its selection in
/// `job.out_dir`, every file of a one-pass run written (but `state.bin`,
/// phase 1's). With `--resume`, frames whose `stats.F.json` is there are
/// done already.
pub(super) fn resample(
    job: &Job,
    source: &mut dyn FrameSource,
    method: &mut dyn Method,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Summary, PipelineError> {
    let start = Instant::now();
    job.atlas.validate().map_err(PipelineError::AtlasParams)?;
    let mode = check_memory(job, source, method, observer)?;
    let specs = method.channel_specs();
    // Ranges are resampled side by side, and beside the selecting run:
    // each holds the lock of its range, and removes only the temporaries
    // of its own frames' files (others may be another process's files in
    // flight).
    let listed = source.frames();
    let range = match (listed.first(), listed.last()) {
        (Some(a), Some(b)) => format!("{}-{}", frame_tag(*a), frame_tag(*b)),
        _ => "none".to_string(),
    };
    let lock = open_output_locking(job, observer, &format!("fluidtex.resample.{range}.lock"))?;
    let guard = InputGuard::new(source.input_paths());
    let tags: Vec<String> = listed
        .iter()
        .map(|&f| format!(".{}.", frame_tag(f)))
        .collect();
    crate::io::remove_stale_temporaries_of(&job.out_dir, &guard, |target| {
        !target.starts_with("selection.") && tags.iter().any(|t| target.contains(t.as_str()))
    })?;
    let frames: Vec<i32> = (listed.iter().copied())
        .filter(|&f| !(job.resume && is_written(job, f)))
        .collect();
    let Some(&first) = frames.first() else {
        drop(lock);
        return Ok(Summary::default());
    };
    let name = method.name();
    let head = SavedSelection::read(job, name, first)?;
    // The frame before the range, resampled for the coherence numbers of
    // its first frame only.
    let prime = head.previous.filter(|_| job.outputs.debug);
    let mut writer = FrameWriter::new(job, &guard, MethodInfo { name, specs }, head.first_frame);
    add_coherence(job, &mut writer, None);
    let mut driver = job_driver(job, method);
    let total = frames.len();
    // The first frame's selection is read once.
    let mut head = Some(head);
    let done = write_frames(mode, writer, observer, |sink| {
        let primed = prime.map(|p| (p, true));
        let listed = frames.iter().map(|&f| (f, false));
        for (k, (number, prime)) in primed.into_iter().chain(listed).enumerate() {
            if !prime {
                sink.observe(Event::Start {
                    number,
                    index: k - usize::from(primed.is_some()),
                    total,
                });
            }
            let saved = match head.take_if(|h| h.frame == number && !prime) {
                Some(h) => h,
                None => SavedSelection::read(job, name, number)?,
            };
            resample_frame(job, source, &mut driver, sink, &saved, prime)?;
        }
        Ok(())
    })?;
    drop(lock);
    Ok(Summary {
        frames_done: done,
        resumed_after: None,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Whether frame `f`'s files are all written: `stats.F.json` is renamed
/// into place last.
fn is_written(job: &Job, f: i32) -> bool {
    job.out_dir
        .join(format!("stats.{}.json", frame_tag(f)))
        .is_file()
}

/// Frame `saved.frame` resampled into `sink`, after the frame before
/// where the selection or the measurement reads it.
fn resample_frame(
    job: &Job,
    source: &mut dyn FrameSource,
    driver: &mut Driver<'_>,
    sink: &mut FileSink<'_, '_, '_>,
    saved: &SavedSelection,
    prime: bool,
) -> Result<(), PipelineError> {
    if driver.previous().map(|p| p.number) != saved.previous {
        // Not the frame just resampled: read it where the method replays
        // the frame from it; otherwise the frame has none here (and no
        // coherence numbers, unless primed).
        let previous = match saved.previous {
            Some(p) if saved.selection.needs_previous() => Some(Arc::new(build(job, source, p)?.0)),
            _ => None,
        };
        driver.set_previous(previous);
    }
    let (geometry, clock) = build(job, source, saved.frame)?;
    if prime {
        sink.prime_next();
    }
    driver.resample(
        PendingFrame {
            geometry: Arc::new(geometry),
            clock,
        },
        &saved.selection,
        sink,
    )
}

/// Frame `number` read and built.
fn build(
    job: &Job,
    source: &mut dyn FrameSource,
    number: i32,
) -> Result<(FrameGeometry, StageClock), PipelineError> {
    let mut clock = StageClock::default();
    let (mesh, report) = source.read(number)?;
    clock.lap("read");
    let geometry = FrameGeometry::build(number, mesh, report, &job.atlas, &mut clock)?;
    Ok((geometry, clock))
}
