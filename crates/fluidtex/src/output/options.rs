//! The job a run is given: where it writes, which files, how the atlas is
//! built, and the hooks tests stop it with.

use std::path::PathBuf;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::atlas::AtlasParams;
use crate::io::WriteHook;

/// Which files are written per frame besides the channel atlases.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OutputOptions {
    /// `mesh.F.obj` + `mesh.F.mtl` [true].
    pub obj: bool,
    /// `mesh.F.glb` [true].
    pub glb: bool,
    /// `patches.F.png`, `source.F.exr` and the coherence numbers of
    /// `stats.F.json` (the run adds the coherence sink) [true].
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
    /// Stop after the frame whose resident memory passes this many bytes
    /// (`None`: never); see [`crate::output::default_memory_limit`].
    pub max_memory: Option<u64>,
    /// One pass, or one of the two phases of a split run \[one pass].
    pub phase: Phase,
    /// Test hooks; front ends leave them at their default (none).
    pub hooks: TestHooks,
}

/// How a run goes through its frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Phase {
    /// Every frame selected and resampled, its files written.
    #[default]
    OnePass,
    /// Phase 1: the sequential pass; per frame `selection.F.bin` and
    /// `state.bin`, no channels.
    Select,
    /// Phase 2: each frame resampled from its `selection.F.bin` alone
    /// (frames in any order, in any process), every file of a one-pass
    /// run written but `state.bin`.
    Resample,
}

crate::named!(Phase {
    OnePass => "one-pass",
    Select => "select",
    Resample => "resample",
});

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
    /// Resident memory in bytes to check the memory limit with, instead
    /// of the process's `VmRSS`.
    pub resident_memory: Option<u64>,
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
            .field("resident_memory", &self.resident_memory)
            .finish()
    }
}
