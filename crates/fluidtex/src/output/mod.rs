//! What a run writes and keeps: the job's description, the file sink, the
//! writers, the coherence numbers of `stats.F.json`, `state.bin` and the
//! memory estimate; [`crate::pipeline`] runs the frame loop over them.
//!
//! ```text
//!  pipeline::run ──► Driver ──► FileSink (sink.rs, frame loop's thread)
//!                                  │ WriteJob: channels as written, ids,
//!                                  │ method state; through write_behind.rs
//!                                  ▼
//!                    FrameWriter (writer.rs, write-behind thread)
//!                      ├─ channel atlases, meshes, preview (images.rs)
//!                      ├─ sinks of written frames: CoherenceSink
//!                      │    (coherence.rs, added with debug outputs)
//!                      ├─ source.F.exr, patches.F.png (images.rs)
//!                      ├─ stats.F.json (report.rs), all renamed together
//!                      └─ state.bin (state.rs)
//! ```
//!
//! The types a run shares with its front ends (the [`Job`], its
//! [`OutputOptions`], [`PipelineError`], [`FrameStats`], [`Event`]) live
//! here, below [`crate::pipeline`], which re-exports them: the frame loop
//! imports this module and nothing here imports the loop.
//!
//! One file per concept: `options` (the job), `error`, `report` (per-frame
//! numbers and progress events), `memory` (the up-front estimate and its
//! `/proc` parsing), `state` (`state.bin`: writing, reading, checks),
//! `images` (atlas and debug image encoding), `writer` (a frame's files),
//! `coherence` (the coherence sink and its settings), `sink` (the frame
//! loop's end of the writer) and [`write_behind`].

mod coherence;
mod error;
mod images;
mod memory;
mod options;
mod report;
mod selection;
mod sink;
mod state;
pub mod write_behind;
mod writer;

pub use coherence::CoherenceSinkSettings;
pub use error::{PipelineError, gib};
pub use images::patch_colour;
pub use memory::{
    MemoryEstimate, UNKNOWN_TRIANGLES, available_memory, default_memory_limit, estimate_memory,
    parse_size, peak_memory, proc_kib, resident_memory,
};
pub use options::{FrameHook, Job, OutputOptions, Phase, TestHooks};
pub use report::{Event, FrameStats};
pub use selection::{SavedSelection, selection_path};
pub use state::load_state_bytes;
pub use writer::frame_tag;

pub(crate) use coherence::CoherenceSink;
pub(crate) use sink::{FileSink, write_frames};
pub(crate) use state::{STATE_FILE, load_for_resume, save_state};
pub(crate) use writer::{FrameWriter, MethodInfo};
