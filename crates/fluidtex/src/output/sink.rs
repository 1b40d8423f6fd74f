//! The file sink: the frame loop's end of the writer. It takes what the
//! writer needs of the method (its state after the frame, before the
//! method moves on), hands the frame over ([`super::write_behind`]) and
//! passes the writer's reports on to the observer, in frame order.

use std::sync::Arc;

use crate::driver::{DrivenFrame, FrameSink};
use crate::exemplar::channels::ChannelFormat;

use super::error::PipelineError;
use super::images::written_channels;
use super::report::Event;
use super::write_behind::{self, Mode, Worker};
use super::writer::{FrameWriter, Reads, WriteJob, Written, is_preview_frame};

/// The sink of `pipeline::run`, on the frame loop's thread: hands each
/// frame to the [`FrameWriter`] and reports the written ones.
pub(crate) struct FileSink<'w, 'a, 'o> {
    writer: &'w mut Worker<'a, WriteJob, Written, PipelineError>,
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
    /// What the writer's sinks of written frames read besides the frame.
    reads: Reads,
    /// Nothing submitted yet and a sink reads the first frame's previous
    /// geometry ([`Reads::first_previous`]).
    first_pending: bool,
    /// Whether `state.bin` follows each frame (not when resampling).
    saves_state: bool,
    /// The next frame is resampled for the sinks of written frames only
    /// ([`WriteJob::prime`]).
    priming: bool,
}

/// Runs `body` (the frame loop) with a [`FileSink`] whose frames `writer`
/// writes, behind on a second thread or in place (`mode`). Every frame
/// handed over is written (and reported to `observer`) before this returns,
/// whether or not a later one failed: `--resume` goes on from them. Returns
/// the number of frames written; a write error comes before `body`'s, since
/// it belongs to an earlier frame.
pub(crate) fn write_frames(
    mode: Mode,
    mut writer: FrameWriter<'_>,
    observer: &mut dyn FnMut(Event<'_>),
    body: impl FnOnce(&mut FileSink<'_, '_, '_>) -> Result<(), PipelineError>,
) -> Result<usize, PipelineError> {
    let reads = writer.reads();
    let preview_every = writer.job.outputs.preview_every;
    let formats: Vec<ChannelFormat> = writer.method.specs.iter().map(|s| s.format).collect();
    let first_frame = writer.first_frame;
    let saves_state = writer.job.phase != super::Phase::Resample;
    write_behind::scope(
        mode,
        move |w: WriteJob| writer.write(w),
        |worker| -> Result<usize, PipelineError> {
            let mut sink = FileSink {
                writer: worker,
                observer,
                done: 0,
                preview_every,
                formats,
                first_frame,
                spent_values: None,
                reads,
                first_pending: reads.first_previous,
                saves_state,
                priming: false,
            };
            let looped = body(&mut sink);
            // The frames already handed over are written (and counted)
            // whether or not a later one failed: `--resume` goes on from them.
            let finished = sink.writer.finish();
            let reported = sink.report(finished);
            // A write error belongs to an earlier frame than the loop's.
            reported?;
            looped?;
            Ok(sink.done)
        },
    )
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

    /// Where a sink of written frames reads them (the coherence sink, which
    /// comes with the debug outputs).
    fn reads_renewal(&self) -> bool {
        self.reads.renewal
    }

    fn frame(&mut self, frame: DrivenFrame<'_>) -> Result<(), PipelineError> {
        let DrivenFrame {
            method,
            geometry,
            previous,
            result,
            clock,
        } = frame;
        let state = self.saves_state.then(|| method.save_state()).transpose()?;
        let prime = std::mem::take(&mut self.priming);
        // The per-texel uv and mip levels go back to the method; the layer
        // counts are the evaluation's too, and are not kept while the frame
        // is written. 8-bit channels travel as the samples their PNG holds
        // (previews shade the floats).
        let preview = is_preview_frame(self.preview_every, self.first_frame, geometry.number);
        let (channels, spent) = written_channels(result.channels, &self.formats, !preview);
        self.spent_values = spent;
        // The frame before is written already; its geometry goes along only
        // where the writer reads more of it than the coherence data it kept.
        let keep_previous = self.reads.previous || std::mem::take(&mut self.first_pending);
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
            prime,
        });
        let ready = self.writer.ready();
        self.report(ready)
    }
}

impl FileSink<'_, '_, '_> {
    /// Tells the observer `event` (the frame loop's own reports).
    pub(crate) fn observe(&mut self, event: Event<'_>) {
        (self.observer)(event);
    }

    /// The next frame is resampled only for what the sinks of written
    /// frames keep of it: the frame before a resampled range, which its
    /// first frame's coherence numbers are measured against.
    pub(crate) fn prime_next(&mut self) {
        self.priming = true;
    }

    /// Tells the observer of each written frame (and of what went wrong
    /// in writing it, as the first error).
    fn report(
        &mut self,
        results: Vec<Result<Written, PipelineError>>,
    ) -> Result<(), PipelineError> {
        for written in results {
            let Written {
                stats,
                primed,
                warnings,
            } = written?;
            for w in warnings {
                (self.observer)(Event::Warning(w));
            }
            if primed {
                continue;
            }
            (self.observer)(Event::Done { stats: &stats });
            self.done += 1;
        }
        Ok(())
    }
}
