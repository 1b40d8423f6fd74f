//! `state.bin`: the method state after the last finished frame, written
//! once every file of the frame is committed, read back by `--resume`
//! (with its version, checksum and configuration checks).

use std::io::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::io::{InputGuard, Staging};
use crate::methods::Method;

use super::error::PipelineError;
use super::options::Job;

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

pub(crate) const STATE_FILE: &str = "state.bin";
/// 2: the checksum was added.
const STATE_VERSION: u32 = 2;

/// `--resume`'s read of `state.bin` in `job.out_dir`: `None` where there is
/// none; otherwise, once the file is found to be written by a run with the
/// same configuration and method, loads its method state into `method` and
/// returns the last finished frame.
pub(crate) fn load_for_resume(
    job: &Job,
    method: &mut dyn Method,
) -> Result<Option<i32>, PipelineError> {
    let Some(saved) = read_state(&job.out_dir)? else {
        return Ok(None);
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
    Ok(Some(saved.last_frame))
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

/// Replaces `state.bin` by the method state after `frame` (atomically):
/// from now on the frame counts finished.
pub(crate) fn save_state(
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
    files.write(&job.out_dir.join(STATE_FILE), |w| w.write_all(&bytes))?;
    Ok(files.commit()?)
}
