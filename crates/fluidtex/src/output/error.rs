//! The errors of a run: of its frames, its outputs and its resume.

use std::path::PathBuf;

use thiserror::Error;

use crate::atlas::AtlasError;
use crate::driver::DriverError;
use crate::frame::GeometryError;
use crate::io::IoError;
use crate::methods::MethodError;

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
    /// A frame's selection (`selection.F.bin`) cannot be used.
    #[error("frame {frame}: {path}: {message}")]
    Selection {
        frame: i32,
        path: PathBuf,
        message: String,
    },
    /// The estimate ([`super::estimate_memory`]) is above the memory
    /// available; `what` names the atlas (and the triangles where known),
    /// `advice` the way out.
    #[error(
        "{what} needs about {} of memory and {} is available: {advice}",
        gib(*.needed), gib(*.available)
    )]
    Memory {
        what: String,
        needed: u64,
        available: u64,
        advice: String,
    },
    /// The run passed its memory limit (`--max-memory`) after `frame`,
    /// which is written; `detail` is the method's account.
    #[error(
        "memory: {} after frame {frame} (limit {}){}; a smaller --radius or --atlas \
         reduces it, and --resume with a larger --max-memory (0: none) continues",
        gib(*.resident), gib(*.limit), .detail.as_ref().map_or(String::new(), |d| format!(": {d}"))
    )]
    MemoryLimit {
        frame: i32,
        resident: u64,
        limit: u64,
        detail: Option<String>,
    },
    /// A stage of `frame` grew the run past its memory limit
    /// ([`crate::methods::budget`]), before the after-frame check could
    /// see it; the frame is not written. `detail` is the method's account.
    #[error(
        "memory: about {} during frame {frame}'s {stage} (limit {}){}; frame {frame} is not \
         written: a smaller --radius or --atlas reduces it, and --resume with a larger \
         --max-memory (0: none) continues",
        gib(*.resident), gib(*.limit), .detail.as_ref().map_or(String::new(), |d| format!(": {d}"))
    )]
    MemoryInFrame {
        frame: i32,
        stage: &'static str,
        resident: u64,
        limit: u64,
        detail: Option<String>,
    },
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

/// Bytes as "1.3 GiB" or "512 MiB".
pub fn gib(bytes: u64) -> String {
    if bytes >= 1 << 30 {
        format!("{:.1} GiB", bytes as f64 / (1u64 << 30) as f64)
    } else {
        format!("{} MiB", bytes >> 20)
    }
}
