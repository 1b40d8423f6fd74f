//! `fluidtex run --preview-video`: with ffmpeg, `preview.mp4` holds one
//! video frame per preview, H.264, the previews' size, at fps / N; without
//! ffmpeg the run succeeds and says so in one plain line.
//!
//! The ffmpeg test needs `ffmpeg` and `ffprobe` (Debian package `ffmpeg`):
//! without them it prints a note and passes, unless
//! `FLUIDTEX_REQUIRE_TOOLS=1`, in which case it fails.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;
use std::process::{Command, Stdio};

use common::*;

fn run_args(out: &Path, extra: &[&str]) -> Vec<String> {
    let mut a: Vec<String> = [
        "run",
        "--mesh",
        interop("meshio_ascii.####.ply").to_str().unwrap(),
        "--atlas",
        "64",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    a.extend(extra.iter().map(|s| s.to_string()));
    a
}

fn have(tool: &str) -> bool {
    Command::new(tool)
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

#[test]
fn preview_video_has_one_frame_per_preview() {
    if !have("ffmpeg") || !have("ffprobe") {
        let msg = "ffmpeg/ffprobe not found: `apt-get install ffmpeg` to test --preview-video";
        missing_tool("skipping", msg);
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    // Every frame (the default with --preview-video), and every 2nd frame.
    for (every, frames, rate) in [(None, 3, "24/1"), (Some("2"), 2, "12/1")] {
        let out = tmp.path().join(format!("out-{frames}"));
        let mut extra = vec!["--preview-video", "--fps", "24"];
        if let Some(n) = every {
            extra.extend(["--preview-every", n]);
        }
        let o = fluidtex().args(run_args(&out, &extra)).output().unwrap();
        check_ok(&o, &run_args(&out, &extra));
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(
            stderr.contains(&format!("preview.mp4 ({frames} frames)")),
            "{stderr}"
        );
        assert!(!out.join("preview.mp4.tmp").exists());
        let probe = Command::new("ffprobe")
            .args([
                "-v",
                "error",
                "-count_frames",
                "-select_streams",
                "v:0",
                "-show_entries",
                "stream=codec_name,width,height,nb_read_frames,r_frame_rate",
                "-of",
                "json",
            ])
            .arg(out.join("preview.mp4"))
            .output()
            .unwrap();
        assert!(probe.status.success());
        let info: serde_json::Value = serde_json::from_slice(&probe.stdout).unwrap();
        let s = &info["streams"][0];
        let png = image::open(out.join("preview.0001.png")).unwrap();
        assert_eq!(s["codec_name"], "h264", "{info}");
        assert_eq!(s["nb_read_frames"], frames.to_string(), "{info}");
        assert_eq!(s["r_frame_rate"], rate, "{info}");
        assert_eq!(s["width"], png.width() & !1, "{info}");
        assert_eq!(s["height"], png.height() & !1, "{info}");
    }
}

#[test]
fn without_ffmpeg_the_run_succeeds_and_says_so() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let empty = tmp.path().join("empty-path");
    std::fs::create_dir(&empty).unwrap();
    // No ffmpeg on PATH.
    let o = fluidtex()
        .args(run_args(&out, &["--preview-video"]))
        .env("PATH", &empty)
        .output()
        .unwrap();
    check_ok(&o, &run_args(&out, &["--preview-video"]));
    let stderr = String::from_utf8_lossy(&o.stderr);
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(
        lines[0].contains("ffmpeg not found, so preview.mp4 was not written"),
        "{stderr}"
    );
    assert!(!out.join("preview.mp4").exists());
    // The previews themselves are there, one per frame.
    for f in 1..=3 {
        assert!(out.join(format!("preview.{f:04}.png")).exists());
    }
}
