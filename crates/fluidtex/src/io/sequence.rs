//! Frame patterns, frame ranges and lazily read mesh sequences.
//!
//! A pattern holds exactly one frame token in its file name:
//!
//! | token | example | frame 7 |
//! |---|---|---|
//! | `$F` + padding (Houdini) | `fluid.$F4.ply` | `fluid.0007.ply` |
//! | `$F` unpadded | `fluid.$F.ply` | `fluid.7.ply` |
//! | run of `#`, one per digit | `fluid.###.ply` | `fluid.007.ply` |
//! | printf `%d` / `%0Nd` | `fluid.%04d.ply` | `fluid.0007.ply` |
//!
//! **Negative frames are allowed** (Houdini pre-roll frames are negative).
//! They format as printf's `%0Nd` does: the sign counts towards the width,
//! so frame −7 with padding 4 is `-007`. A range is written `A-B` or `A`,
//! e.g. `1-240`, `-10-5`, `-10--1`.
//!
//! A path with no token that names an existing file is accepted by
//! [`FramePattern::parse_or_file`] as a one-frame sequence, frame 0, so a
//! single mesh can be inspected or textured as it is.
//!
//! [`Sequence`] reads one frame per `next()`: memory is bounded by one frame
//! whatever the sequence length.

use std::path::{Path, PathBuf};
use std::str::FromStr;

use super::{IoError, ReadOptions, read_mesh};
use crate::mesh::{TriMesh, ValidationReport};

/// A file path with one frame-number token.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FramePattern {
    /// Everything before the token, directories included.
    prefix: String,
    /// Everything after the token (no directory separator).
    suffix: String,
    /// Minimum digit count, zero-padded (0 = unpadded).
    padding: usize,
    /// The pattern as the user wrote it, for messages.
    text: String,
    /// A single file without a token: frame 0 is `text`, no other exists.
    single: bool,
}

impl FramePattern {
    /// Parses a pattern (see the module doc for the accepted tokens).
    pub fn parse(text: &str) -> Result<FramePattern, IoError> {
        let err = |reason: &str| IoError::Pattern {
            pattern: text.to_string(),
            reason: reason.to_string(),
        };
        let bytes = text.as_bytes();
        let mut found: Option<(usize, usize, usize)> = None; // (start, end, padding)
        let mut i = 0;
        while i < bytes.len() {
            let token = match bytes[i] {
                b'$' if bytes.get(i + 1) == Some(&b'F') => {
                    let digits = count_digits(&bytes[i + 2..]);
                    let pad = parse_pad(&text[i + 2..i + 2 + digits])
                        .ok_or_else(|| err("bad $F padding"))?;
                    Some((i, i + 2 + digits, pad))
                }
                b'#' => {
                    let n = bytes[i..].iter().take_while(|&&b| b == b'#').count();
                    Some((i, i + n, n))
                }
                b'%' => {
                    let digits = count_digits(&bytes[i + 1..]);
                    if bytes.get(i + 1 + digits) != Some(&b'd') {
                        return Err(err("only %d and %0Nd printf tokens are supported"));
                    }
                    let spec = &text[i + 1..i + 1 + digits];
                    if !spec.is_empty() && !spec.starts_with('0') {
                        return Err(err("space-padded %Nd is not a frame pattern; use %0Nd"));
                    }
                    let pad = parse_pad(spec).ok_or_else(|| err("bad %d padding"))?;
                    Some((i, i + 2 + digits, pad))
                }
                _ => None,
            };
            match token {
                Some(t) if found.is_some() => {
                    let _ = t;
                    return Err(err("more than one frame token"));
                }
                Some(t) => {
                    i = t.1;
                    found = Some(t);
                }
                None => i += 1,
            }
        }
        let (start, end, padding) =
            found.ok_or_else(|| err("no frame token ($F4, #### or %04d)"))?;
        let suffix = &text[end..];
        if suffix.contains(['/', std::path::MAIN_SEPARATOR]) {
            return Err(err(
                "the frame token must be in the file name, not a directory",
            ));
        }
        Ok(FramePattern {
            prefix: text[..start].to_string(),
            suffix: suffix.to_string(),
            padding,
            text: text.to_string(),
            single: false,
        })
    }

    /// [`FramePattern::parse`], except that a path without a frame token
    /// naming an existing file is a one-frame sequence (frame 0).
    pub fn parse_or_file(text: &str) -> Result<FramePattern, IoError> {
        match FramePattern::parse(text) {
            Err(e) if Path::new(text).is_file() && !text.contains(['#', '%', '$']) => {
                let _ = e;
                Ok(FramePattern {
                    prefix: String::new(),
                    suffix: String::new(),
                    padding: 0,
                    text: text.to_string(),
                    single: true,
                })
            }
            other => other,
        }
    }

    /// The file name of `frame`.
    pub fn path(&self, frame: i32) -> PathBuf {
        if self.single {
            // Any other frame names a file that cannot exist, so asking for
            // it fails as a missing frame does.
            return if frame == 0 {
                PathBuf::from(&self.text)
            } else {
                PathBuf::from(format!(
                    "{} (frame {frame}; a single file has only frame 0)",
                    self.text
                ))
            };
        }
        PathBuf::from(format!(
            "{}{}{}",
            self.prefix,
            self.format_frame(frame),
            self.suffix
        ))
    }

    fn format_frame(&self, frame: i32) -> String {
        format!("{frame:0width$}", width = self.padding)
    }

    /// The pattern as written.
    pub fn as_str(&self) -> &str {
        &self.text
    }

    /// Frames whose file exists, sorted. A file matches only if its name is
    /// exactly what [`FramePattern::path`] gives for its number, so
    /// `fluid.12.ply` does not match `fluid.####.ply`.
    pub fn discover(&self) -> Result<Vec<i32>, IoError> {
        if self.single {
            return Ok(if Path::new(&self.text).is_file() {
                vec![0]
            } else {
                Vec::new()
            });
        }
        let (dir, name_prefix) = match self.prefix.rfind(['/', std::path::MAIN_SEPARATOR]) {
            Some(k) => (&self.prefix[..=k], &self.prefix[k + 1..]),
            None => ("", self.prefix.as_str()),
        };
        let dir_path = if dir.is_empty() {
            Path::new(".")
        } else {
            Path::new(dir)
        };
        let entries = std::fs::read_dir(dir_path).map_err(|e| IoError::os(dir_path, e))?;
        let mut frames = Vec::new();
        for entry in entries {
            let entry = entry.map_err(|e| IoError::os(dir_path, e))?;
            let name = entry.file_name();
            let Some(name) = name.to_str() else { continue };
            let Some(middle) = name
                .strip_prefix(name_prefix)
                .and_then(|m| m.strip_suffix(self.suffix.as_str()))
            else {
                continue;
            };
            if let Ok(frame) = middle.parse::<i32>()
                && self.format_frame(frame) == middle
                && entry.path().is_file()
            {
                frames.push(frame);
            }
        }
        frames.sort_unstable();
        frames.dedup();
        Ok(frames)
    }
}

fn count_digits(b: &[u8]) -> usize {
    b.iter().take_while(|b| b.is_ascii_digit()).count()
}

/// Padding from a digit string ("" = 0); `None` when absurdly large.
fn parse_pad(s: &str) -> Option<usize> {
    if s.is_empty() {
        return Some(0);
    }
    s.parse::<usize>().ok().filter(|&p| p <= 32)
}

/// An inclusive range of frame numbers, `first <= last`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRange {
    pub first: i32,
    pub last: i32,
}

impl FrameRange {
    /// A validated range.
    pub fn new(first: i32, last: i32) -> Result<FrameRange, IoError> {
        if first > last {
            return Err(IoError::Range {
                text: format!("{first}-{last}"),
                reason: format!("first frame {first} is after last frame {last}"),
            });
        }
        Ok(FrameRange { first, last })
    }

    /// Number of frames in the range.
    pub fn len(&self) -> usize {
        (i64::from(self.last) - i64::from(self.first) + 1).max(0) as usize
    }

    /// Never true for a validated range; here for API completeness.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The frame numbers in order.
    pub fn frames(&self) -> impl Iterator<Item = i32> + use<> {
        self.first..=self.last
    }
}

impl FromStr for FrameRange {
    type Err = IoError;

    /// `A-B` or `A`; either number may be negative (`-10--1`).
    fn from_str(s: &str) -> Result<FrameRange, IoError> {
        let err = |reason: &str| IoError::Range {
            text: s.to_string(),
            reason: reason.to_string(),
        };
        let t = s.trim();
        // The separator is the first '-' after the first character.
        let sep = t
            .char_indices()
            .skip(1)
            .find(|&(_, c)| c == '-')
            .map(|(k, _)| k);
        let num = |x: &str| {
            x.trim()
                .parse::<i32>()
                .map_err(|_| err(&format!("{x:?} is not a frame number")))
        };
        let (first, last) = match sep {
            Some(k) => (num(&t[..k])?, num(&t[k + 1..])?),
            None => {
                let f = num(t)?;
                (f, f)
            }
        };
        FrameRange::new(first, last)
            .map_err(|_| err(&format!("first frame {first} is after last frame {last}")))
    }
}

/// One frame of a sequence, read and validated.
#[derive(Clone, Debug)]
pub struct Frame {
    pub number: i32,
    pub path: PathBuf,
    pub mesh: TriMesh,
    pub report: ValidationReport,
}

/// A lazily read sequence of frames: each `next()` reads one file.
#[derive(Clone, Debug)]
pub struct Sequence {
    pattern: FramePattern,
    range: FrameRange,
    options: ReadOptions,
    next: i64,
}

impl Sequence {
    pub fn new(pattern: FramePattern, range: FrameRange, options: ReadOptions) -> Sequence {
        Sequence {
            pattern,
            range,
            next: i64::from(range.first),
            options,
        }
    }

    pub fn pattern(&self) -> &FramePattern {
        &self.pattern
    }

    pub fn range(&self) -> FrameRange {
        self.range
    }

    /// Checks that every frame's file exists without reading any, so a run
    /// can fail before hours of work rather than at the missing frame.
    pub fn check_present(&self) -> Result<(), IoError> {
        for frame in self.range.frames() {
            let path = self.pattern.path(frame);
            if !path.is_file() {
                return Err(IoError::MissingFrame { frame, path });
            }
        }
        Ok(())
    }

    /// Reads one frame of the pattern (in or out of the range).
    pub fn read_frame(&self, frame: i32) -> Result<Frame, IoError> {
        let path = self.pattern.path(frame);
        match read_mesh(&path, &self.options) {
            Ok((mesh, report)) => Ok(Frame {
                number: frame,
                path,
                mesh,
                report,
            }),
            Err(IoError::NotFound { path }) => Err(IoError::MissingFrame { frame, path }),
            Err(e) => Err(e),
        }
    }
}

impl Iterator for Sequence {
    type Item = Result<Frame, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.next > i64::from(self.range.last) {
            return None;
        }
        let frame = self.next as i32;
        self.next += 1;
        Some(self.read_frame(frame))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = (i64::from(self.range.last) - self.next + 1).max(0) as usize;
        (left, Some(left))
    }
}

impl ExactSizeIterator for Sequence {}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(s: &str) -> FramePattern {
        FramePattern::parse(s).unwrap()
    }

    #[test]
    fn tokens_format_frames() {
        assert_eq!(p("fluid.$F4.ply").path(7), PathBuf::from("fluid.0007.ply"));
        assert_eq!(p("fluid.$F.ply").path(7), PathBuf::from("fluid.7.ply"));
        assert_eq!(
            p("fluid.$F3.ply").path(1234),
            PathBuf::from("fluid.1234.ply")
        );
        assert_eq!(
            p("a/b/fluid.####.ply").path(12),
            PathBuf::from("a/b/fluid.0012.ply")
        );
        assert_eq!(p("fluid_%04d.ply").path(3), PathBuf::from("fluid_0003.ply"));
        assert_eq!(p("fluid_%d.ply").path(3), PathBuf::from("fluid_3.ply"));
        assert_eq!(p("fluid.$F4.ply").path(-7), PathBuf::from("fluid.-007.ply"));
        assert_eq!(p("$F2").path(5), PathBuf::from("05"));
    }

    #[test]
    fn a_single_file_is_frame_zero() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("blob.ply");
        std::fs::write(&file, b"ply").unwrap();
        let text = file.to_str().unwrap();
        let p = FramePattern::parse_or_file(text).unwrap();
        assert_eq!(p.discover().unwrap(), vec![0]);
        assert_eq!(p.path(0), file);
        assert!(!p.path(1).exists());
        // A missing file without a token is still a bad pattern.
        let missing = dir.path().join("none.ply");
        let e = FramePattern::parse_or_file(missing.to_str().unwrap()).unwrap_err();
        assert!(e.to_string().contains("no frame token"), "{e}");
        // A real pattern is unchanged.
        let q = FramePattern::parse_or_file("f.####.ply").unwrap();
        assert_eq!(q.path(3), PathBuf::from("f.0003.ply"));
    }

    #[test]
    fn bad_patterns_are_named() {
        for (text, reason) in [
            ("fluid.ply", "no frame token ($F4, #### or %04d)"),
            ("f.$F4.##.ply", "more than one frame token"),
            (
                "f.%4d.ply",
                "space-padded %Nd is not a frame pattern; use %0Nd",
            ),
            ("f.%s.ply", "only %d and %0Nd printf tokens are supported"),
            (
                "f$F4/mesh.ply",
                "the frame token must be in the file name, not a directory",
            ),
        ] {
            let e = FramePattern::parse(text).unwrap_err();
            assert_eq!(
                e.to_string(),
                format!("invalid frame pattern {text:?}: {reason}")
            );
        }
    }

    #[test]
    fn ranges_parse_with_negative_frames() {
        let r = |s: &str| s.parse::<FrameRange>().unwrap();
        assert_eq!(
            r("1-240"),
            FrameRange {
                first: 1,
                last: 240
            }
        );
        assert_eq!(
            r("12"),
            FrameRange {
                first: 12,
                last: 12
            }
        );
        assert_eq!(
            r("-10-5"),
            FrameRange {
                first: -10,
                last: 5
            }
        );
        assert_eq!(
            r("-10--1"),
            FrameRange {
                first: -10,
                last: -1
            }
        );
        assert_eq!(r(" 3 - 4 "), FrameRange { first: 3, last: 4 });
        assert_eq!(r("1-240").len(), 240);
        let e = "9-3".parse::<FrameRange>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "invalid frame range \"9-3\": first frame 9 is after last frame 3"
        );
        let e = "1-x".parse::<FrameRange>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "invalid frame range \"1-x\": \"x\" is not a frame number"
        );
        assert!("".parse::<FrameRange>().is_err());
        assert!(FrameRange::new(2, 1).is_err());
    }

    #[test]
    fn discover_matches_exact_padding_only() {
        let dir = tempfile::tempdir().unwrap();
        for name in [
            "f.0001.ply",
            "f.0003.ply",
            "f.12.ply",
            "f.0002.obj",
            "f.-001.ply",
            "g.0005.ply",
            "f.00004.ply",
        ] {
            std::fs::write(dir.path().join(name), b"x").unwrap();
        }
        std::fs::create_dir(dir.path().join("f.0009.ply")).unwrap();
        let pat = p(&format!("{}/f.####.ply", dir.path().display()));
        assert_eq!(pat.discover().unwrap(), vec![-1, 1, 3]);
    }
}
