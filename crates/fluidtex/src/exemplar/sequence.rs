//! Animated exemplars: an image sequence (`bubbles.####.png`, the frame
//! tokens of [`crate::io::FramePattern`]) shown as a texture that moves in
//! place while the patches ride the flow.
//!
//! - **Frames.** The colour pattern's files must run without a gap from
//!   the lowest frame number found to the highest; a feature map or an
//!   extra channel given as a pattern must have a file for every one of
//!   those numbers, one given as a plain file serves every frame. Every
//!   frame is the size of the first. A missing or differently sized frame
//!   is refused with the file named.
//! - **Which frame a patch shows.** Each patch draws a phase φ in
//!   `[0, n)` when it is created (seeded, keyed by its id as the other
//!   per-patch draws are, so no state has to be saved for it) and, on
//!   fluid frame t, shows exemplar frame ⌊t·rate + φ⌋ mod n
//!   ([`ExemplarClock`]). Neighbouring patches are thus out of step and
//!   the surface shows no global flicker; at rate 1 one exemplar frame
//!   passes per fluid frame.
//! - **Memory.** The decoded frames are held from the start (their feature
//!   maps are derived per frame); each frame's mip pyramid is built the
//!   first time a patch shows it ([`super::Exemplar::deferring_pyramid`]).
//!   The whole sequence, pyramids included, must fit a budget stated
//!   before anything else is loaded ([`SequenceBudget`]): a sequence over
//!   it is refused after its first frame, not when memory runs out.
//!
//! A fluid at rest keeps every texel's source (patch and uv) from frame to
//! frame: only the colour each source reads changes.

use std::path::{Path, PathBuf};

use super::feature::FeatureMethod;
use super::{Exemplar, ExemplarError};
use crate::io::FramePattern;

/// Exemplar frames shown per fluid frame \[1] (`exemplar_rate`).
pub const DEFAULT_EXEMPLAR_RATE: f32 = 1.0;

/// Memory the frames of the animated exemplars may take together, their
/// pyramids included \[2 GiB] (`--exemplar-memory`).
pub const DEFAULT_SEQUENCE_BUDGET: u64 = 2 << 30;

/// Stream of [`crate::seed::mix`] for the patches' phases.
const PHASE_STREAM: u64 = 11;

/// How an animated exemplar advances: `rate` exemplar frames per fluid
/// frame, each patch offset by its own phase.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExemplarClock {
    pub rate: f32,
}

impl Default for ExemplarClock {
    fn default() -> ExemplarClock {
        ExemplarClock {
            rate: DEFAULT_EXEMPLAR_RATE,
        }
    }
}

impl ExemplarClock {
    /// Checks the rate: finite, and at most one whole sequence per frame
    /// in either direction (a faster one aliases into noise).
    pub fn new(rate: f32) -> Result<ExemplarClock, ExemplarError> {
        if !(rate.is_finite() && rate.abs() <= MAX_RATE) {
            return Err(ExemplarError::InvalidParameter {
                name: "exemplar_rate",
                value: rate,
                min: -MAX_RATE,
                max: MAX_RATE,
            });
        }
        Ok(ExemplarClock { rate })
    }

    /// The phase of the patch `key` (its id), in exemplar frames, `[0, frames)`.
    pub fn phase(seed: u64, key: u64, frames: u32) -> f64 {
        let bits = crate::seed::mix(seed, PHASE_STREAM, key) >> 11;
        bits as f64 / (1u64 << 53) as f64 * f64::from(frames)
    }

    /// The exemplar frame, `[0, frames)`, that a patch of phase `phase`
    /// shows on fluid frame `t`: ⌊t·rate + phase⌋ mod frames.
    pub fn frame(&self, t: i32, phase: f64, frames: u32) -> u32 {
        if frames <= 1 {
            return 0;
        }
        let at = (f64::from(t) * f64::from(self.rate) + phase).floor();
        // |at| stays far below 2^53: t is an i32 and |rate| ≤ MAX_RATE.
        (at as i64).rem_euclid(i64::from(frames)) as u32
    }
}

/// The largest |rate|: a whole sequence of this many frames per fluid frame.
const MAX_RATE: f32 = 1000.0;

/// The memory the animated exemplars' frames may take, stated before they
/// are loaded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SequenceBudget {
    pub bytes: u64,
}

impl Default for SequenceBudget {
    fn default() -> SequenceBudget {
        SequenceBudget {
            bytes: DEFAULT_SEQUENCE_BUDGET,
        }
    }
}

/// An animated exemplar's files: the colour pattern, the extra channels'
/// and the feature map's (each a pattern or a plain file).
#[derive(Clone, Debug)]
pub struct SequenceFiles<'a> {
    pub colour: &'a Path,
    pub channels: &'a [(String, PathBuf)],
    pub feature: Option<&'a Path>,
}

/// Whether `path` names an image sequence: it holds a frame token and no
/// file of that very name exists.
pub fn is_sequence(path: &Path) -> bool {
    !path.is_file()
        && path
            .to_str()
            .is_some_and(|p| FramePattern::parse(p).is_ok())
}

/// Loads every frame of an animated exemplar (see the module doc),
/// refusing a gap, a missing or differently sized file, or a sequence
/// over `budget` (counted with the budget already `used` by others).
/// Returns the frames, their pyramids deferred, and the bytes they take.
pub fn load_sequence(
    files: &SequenceFiles<'_>,
    derive: FeatureMethod,
    budget: SequenceBudget,
    used: u64,
) -> Result<(Vec<Exemplar>, u64), ExemplarError> {
    let colour = pattern(files.colour)?;
    let frames = colour
        .discover()
        .map_err(|e| sequence_error(files.colour, e.to_string()))?;
    let (Some(&first), Some(&last)) = (frames.first(), frames.last()) else {
        return Err(sequence_error(
            files.colour,
            "no file matches this pattern".into(),
        ));
    };
    // Every number between the lowest and the highest found must be there.
    if let Some(missing) = (first..=last).find(|f| frames.binary_search(f).is_err()) {
        return Err(ExemplarError::Sequence {
            what: colour.path(missing).display().to_string(),
            reason: format!(
                "missing: the sequence {} runs from frame {first} to {last}",
                files.colour.display()
            ),
        });
    }
    let channels = files
        .channels
        .iter()
        .map(|(name, path)| Ok((name.clone(), Source::of(path)?)))
        .collect::<Result<Vec<_>, ExemplarError>>()?;
    let feature = files.feature.map(Source::of).transpose()?;
    let first_path = colour.path(first);
    let mut out = Vec::with_capacity(frames.len());
    let mut bytes = 0u64;
    for &f in &frames {
        let path = colour.path(f);
        let exemplar = load_frame(&path, &channels, feature.as_ref(), f, derive)?;
        if exemplar.size() != out.first().map_or(exemplar.size(), Exemplar::size) {
            let (w, h) = exemplar.size();
            let (cw, ch) = out.first().map_or((0, 0), Exemplar::size);
            return Err(ExemplarError::SizeMismatch {
                what: path.display().to_string(),
                width: w,
                height: h,
                colour: first_path.display().to_string(),
                colour_width: cw,
                colour_height: ch,
            });
        }
        let frame_bytes = exemplar.memory_bytes();
        if out.is_empty() {
            // The first frame tells what the whole sequence will take.
            let total = frame_bytes * frames.len() as u64;
            if used + total > budget.bytes {
                return Err(ExemplarError::Budget {
                    what: files.colour.display().to_string(),
                    frames: frames.len(),
                    needed: total,
                    used,
                    budget: budget.bytes,
                });
            }
        }
        bytes += frame_bytes;
        out.push(exemplar.deferring_pyramid());
    }
    Ok((out, bytes))
}

/// A feature map or extra channel of an animated exemplar: one file for
/// every frame, or a sequence of its own.
enum Source {
    Still(PathBuf),
    Frames(FramePattern),
}

impl Source {
    fn of(path: &Path) -> Result<Source, ExemplarError> {
        Ok(if is_sequence(path) {
            Source::Frames(pattern(path)?)
        } else {
            Source::Still(path.to_path_buf())
        })
    }

    /// The file of exemplar frame `frame`, which must exist.
    fn path(&self, frame: i32) -> Result<PathBuf, ExemplarError> {
        match self {
            Source::Still(p) => Ok(p.clone()),
            Source::Frames(pattern) => {
                let p = pattern.path(frame);
                if p.is_file() {
                    Ok(p)
                } else {
                    Err(ExemplarError::Sequence {
                        what: p.display().to_string(),
                        reason: format!(
                            "missing: the colour sequence has frame {frame}, so {} needs it too",
                            pattern.as_str()
                        ),
                    })
                }
            }
        }
    }
}

/// One frame: the colour file with its channels' and feature map's files
/// of the same number ([`Exemplar::load`] checks their sizes).
fn load_frame(
    colour: &Path,
    channels: &[(String, Source)],
    feature: Option<&Source>,
    frame: i32,
    derive: FeatureMethod,
) -> Result<Exemplar, ExemplarError> {
    let channels = channels
        .iter()
        .map(|(name, source)| Ok((name.clone(), source.path(frame)?)))
        .collect::<Result<Vec<_>, ExemplarError>>()?;
    let feature = feature.map(|s| s.path(frame)).transpose()?;
    Exemplar::load(colour, &channels, feature.as_deref(), derive)
}

fn pattern(path: &Path) -> Result<FramePattern, ExemplarError> {
    let text = path
        .to_str()
        .ok_or_else(|| sequence_error(path, "the pattern is not valid UTF-8".into()))?;
    FramePattern::parse(text).map_err(|e| sequence_error(path, e.to_string()))
}

fn sequence_error(path: &Path, reason: String) -> ExemplarError {
    ExemplarError::Sequence {
        what: path.display().to_string(),
        reason,
    }
}

#[cfg(test)]
mod tests;
