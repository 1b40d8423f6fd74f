//! `run --preview-video`: the run's `preview.F.png` frames as `preview.mp4`.
//!
//! A post-step after the run, with the `ffmpeg` program (Debian package
//! `ffmpeg`) rather than a video encoder in the binary: H.264 in MP4 is what
//! every player and review tool opens, and ffmpeg is where artists already
//! have it. Without ffmpeg the run still succeeds and says plainly that no
//! video was written.
//!
//! The frames are linked (or copied) into a temporary folder as a gap-free
//! numbered sequence, so previews written every N frames, any output folder
//! name and any frame numbering give the same ffmpeg command. The video
//! plays at `fps / N`, i.e. in the simulation's own time.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{Context, Result, bail};

/// What the post-step did.
#[derive(Debug, PartialEq)]
pub enum Outcome {
    Written { path: PathBuf, frames: usize },
    NoFfmpeg,
    NoPreviews,
}

impl Outcome {
    /// The line to print.
    pub fn describe(&self) -> String {
        match self {
            Outcome::Written { path, frames } => {
                format!("preview video: {} ({frames} frames)", path.display())
            }
            Outcome::NoFfmpeg => "preview video: ffmpeg not found, so preview.mp4 was not written \
                                  (install ffmpeg, e.g. `apt-get install ffmpeg`, and run again with --resume)"
                .to_string(),
            Outcome::NoPreviews => {
                "preview video: no preview.F.png in the output folder, so no preview.mp4".to_string()
            }
        }
    }
}

/// The `preview.F.png` files of `dir`, in frame order.
pub fn preview_frames(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut frames = Vec::new();
    for e in std::fs::read_dir(dir).with_context(|| format!("{}", dir.display()))? {
        let e = e.with_context(|| format!("{}", dir.display()))?;
        let name = e.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(num) = name
            .strip_prefix("preview.")
            .and_then(|r| r.strip_suffix(".png"))
        else {
            continue;
        };
        if let Ok(f) = num.parse::<i32>() {
            frames.push((f, e.path()));
        }
    }
    frames.sort();
    Ok(frames.into_iter().map(|(_, p)| p).collect())
}

fn ffmpeg_available() -> bool {
    Command::new("ffmpeg")
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Writes `dir/preview.mp4` from the previews in `dir`, shown one after the
/// other at `fps / every` frames per second.
pub fn write(dir: &Path, fps: f32, every: u32) -> Result<Outcome> {
    let frames = preview_frames(dir)?;
    if frames.is_empty() {
        return Ok(Outcome::NoPreviews);
    }
    if !ffmpeg_available() {
        return Ok(Outcome::NoFfmpeg);
    }
    let seq = tempfile::tempdir().context("preview video: cannot make a temporary folder")?;
    for (i, f) in frames.iter().enumerate() {
        let link = seq.path().join(format!("{i:06}.png"));
        if std::fs::hard_link(f, &link).is_err() {
            std::fs::copy(f, &link)
                .with_context(|| format!("preview video: cannot copy {}", f.display()))?;
        }
    }
    let out = dir.join("preview.mp4");
    let tmp = dir.join("preview.mp4.tmp");
    let rate = fps / every.max(1) as f32;
    let result = Command::new("ffmpeg")
        .args(["-hide_banner", "-loglevel", "error", "-nostdin", "-y"])
        .args(["-framerate", &format!("{rate}")])
        .arg("-i")
        .arg(seq.path().join("%06d.png"))
        // H.264 in yuv420p wants even sides.
        .args(["-vf", "scale=trunc(iw/2)*2:trunc(ih/2)*2"])
        .args(["-c:v", "libx264", "-pix_fmt", "yuv420p", "-f", "mp4"])
        .arg(&tmp)
        .stdin(Stdio::null())
        .output()
        .context("preview video: cannot start ffmpeg")?;
    if !result.status.success() {
        let _ = std::fs::remove_file(&tmp);
        let stderr = String::from_utf8_lossy(&result.stderr);
        let last = stderr
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("no message");
        bail!("{}: ffmpeg failed: {last}", out.display());
    }
    std::fs::rename(&tmp, &out).with_context(|| format!("{}", out.display()))?;
    Ok(Outcome::Written {
        path: out,
        frames: frames.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn previews_are_found_in_frame_order() {
        let dir = tempfile::tempdir().expect("tempdir");
        for n in [
            "preview.0010.png",
            "preview.0002.png",
            "preview.-001.png",
            "preview.x.png",
            "color.0001.png",
        ] {
            std::fs::write(dir.path().join(n), b"x").expect("write");
        }
        let names: Vec<String> = preview_frames(dir.path())
            .expect("scan")
            .iter()
            .map(|p| p.file_name().expect("name").to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            names,
            ["preview.-001.png", "preview.0002.png", "preview.0010.png"]
        );
    }

    #[test]
    fn no_previews_means_no_video_and_no_ffmpeg_call() {
        let dir = tempfile::tempdir().expect("tempdir");
        assert_eq!(write(dir.path(), 24.0, 1).expect("ok"), Outcome::NoPreviews);
        assert!(!dir.path().join("preview.mp4").exists());
    }
}
