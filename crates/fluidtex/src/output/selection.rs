//! `selection.F.bin`: the selection of frame F ([`crate::methods::Selection`]),
//! written by the selecting phase of a two-phase run and read by the
//! resampling phase, in this process or on another machine. Like
//! `state.bin` it carries a version, the run's configuration fingerprint,
//! the method and a checksum, so a file of another run, another method or
//! a damaged one is refused with one line naming it.

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::io::Staging;
use crate::methods::Selection;

use super::error::PipelineError;
use super::options::Job;
use super::writer::frame_tag;

/// 1: the first layout.
const SELECTION_VERSION: u32 = 1;

/// A frame's selection and where it stands in its run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SavedSelection {
    version: u32,
    fingerprint: String,
    method: String,
    /// The frame selected.
    pub frame: i32,
    /// The frame before it in the selecting run (`None`: it is the first).
    pub previous: Option<i32>,
    /// The selecting run's first frame, from which previews are counted.
    pub first_frame: i32,
    pub selection: Selection,
    /// CRC-32 of the selection's bytes (postcard has no check of its own).
    checksum: u32,
}

/// Where frame `frame`'s selection is in `out_dir`.
pub fn selection_path(out_dir: &Path, frame: i32) -> PathBuf {
    out_dir.join(format!("selection.{}.bin", frame_tag(frame)))
}

impl SavedSelection {
    /// The selection of `frame` of `job`'s run of `method`.
    pub fn new(
        job: &Job,
        method: &str,
        frame: i32,
        previous: Option<i32>,
        first_frame: i32,
        selection: Selection,
    ) -> SavedSelection {
        SavedSelection {
            version: SELECTION_VERSION,
            fingerprint: job.fingerprint.clone(),
            method: method.to_string(),
            frame,
            previous,
            first_frame,
            checksum: crc32fast::hash(selection.bytes()),
            selection,
        }
    }

    /// Stages the file in `files` (committed with the frame's state).
    pub(crate) fn stage(&self, job: &Job, files: &mut Staging<'_>) -> Result<(), PipelineError> {
        let path = selection_path(&job.out_dir, self.frame);
        let bytes = postcard::to_allocvec(self).map_err(|e| PipelineError::Output {
            path: path.clone(),
            message: e.to_string(),
        })?;
        files.write(&path, |w| w.write_all(&bytes))?;
        Ok(())
    }

    /// Reads frame `frame`'s selection for `job`'s run of `method`.
    pub fn read(job: &Job, method: &str, frame: i32) -> Result<SavedSelection, PipelineError> {
        let path = selection_path(&job.out_dir, frame);
        let refuse = |message: String| PipelineError::Selection {
            frame,
            path: path.clone(),
            message,
        };
        let bytes = std::fs::read(&path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                refuse("not there: run `fluidtex run --phase select` over the frames first".into())
            } else {
                refuse(e.to_string())
            }
        })?;
        let damaged = |e: postcard::Error| refuse(format!("damaged selection file ({e})"));
        let (version, _) = postcard::take_from_bytes::<u32>(&bytes).map_err(damaged)?;
        if version != SELECTION_VERSION {
            return Err(refuse(format!(
                "selection version {version} is not {SELECTION_VERSION}"
            )));
        }
        let saved: SavedSelection = postcard::from_bytes(&bytes).map_err(damaged)?;
        if crc32fast::hash(saved.selection.bytes()) != saved.checksum {
            return Err(refuse("damaged selection file (checksum mismatch)".into()));
        }
        if saved.fingerprint != job.fingerprint || saved.method != method {
            return Err(refuse(format!(
                "written by a run with another configuration or method ({}); resample with \
                 the settings the frames were selected with",
                saved.method
            )));
        }
        if saved.frame != frame {
            return Err(refuse(format!("holds frame {}", saved.frame)));
        }
        Ok(saved)
    }
}
