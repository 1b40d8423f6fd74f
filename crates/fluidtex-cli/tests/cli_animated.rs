//! Animated exemplars through the binary (issue 40): an image sequence or
//! `builtin:bubbles` as `--exemplar`, `--exemplar-rate`, the memory
//! statement before the run, a liquid at rest that keeps its sources,
//! thread counts and a killed run, and the one-line refusals.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::{Path, PathBuf};

use common::*;
use image::{ImageBuffer, Rgb};

/// Writes the frames `first..=last` of a 32×32 RGB sequence `wave.####.png`
/// (a stripe that moves with the frame) into `dir`; returns the pattern.
fn wave(dir: &Path, first: u32, last: u32) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    for k in first..=last {
        write_frame(&dir.join(format!("wave.{k:04}.png")), 32, 32, k);
    }
    dir.join("wave.####.png")
}

fn write_frame(path: &Path, w: u32, h: u32, k: u32) {
    ImageBuffer::from_fn(w, h, |x, y| {
        let on = (x + 4 * k) % 16 < 8;
        Rgb([if on { 220 } else { 30 }, (y * 8 % 256) as u8, 90])
    })
    .save(path)
    .unwrap();
}

fn run_args(mesh: &Path, out: &Path, exemplar: &Path, extra: &[&str]) -> Vec<String> {
    let mut a: Vec<String> = [
        "run",
        "--mesh",
        mesh.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--atlas",
        "128",
        "--exemplar",
        exemplar.to_str().unwrap(),
    ]
    .map(String::from)
    .to_vec();
    a.extend(extra.iter().map(|s| s.to_string()));
    a
}

fn read(out: &Path, name: &str) -> Vec<u8> {
    std::fs::read(out.join(name)).unwrap()
}

#[test]
fn a_sequence_animates_in_place_on_a_liquid_at_rest() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = cooling_grid(&dir.path().join("in"), 5, |_, _| 0.5);
    let seq = wave(&dir.path().join("tex"), 1, 8);
    let out = dir.path().join("out");
    let args = run_args(&mesh, &out, &seq, &["--exemplar-rate", "0.5"]);
    let run = fluidtex().args(&args).output().unwrap();
    check_ok(&run, &args);
    let stderr = String::from_utf8(run.stderr).unwrap();
    // The sequence and its memory are stated before the run.
    let said = stderr
        .lines()
        .find(|l| l.starts_with("animated exemplar"))
        .unwrap_or_else(|| panic!("{stderr}"));
    assert!(
        said.contains("wave.####.png: 8 frames of 32x32") && said.contains("0.5 exemplar frame"),
        "{said}"
    );
    assert!(said.contains("budget 2048 MiB"), "{said}");
    // At rest: the sources never move, the colour changes every frame.
    for f in 2..5 {
        let (a, b) = (format!("{:04}", f - 1), format!("{f:04}"));
        assert_eq!(
            read(&out, &format!("source.{a}.exr")),
            read(&out, &format!("source.{b}.exr")),
            "frame {f}"
        );
        assert_ne!(
            read(&out, &format!("color.{a}.png")),
            read(&out, &format!("color.{b}.png")),
            "frame {f}"
        );
    }
    // The control: the same run with one still frame holds its colour.
    let still = dir.path().join("still");
    ok(&run_args(
        &mesh,
        &still,
        &dir.path().join("tex/wave.0003.png"),
        &[],
    ));
    assert_eq!(
        read(&still, "color.0003.png"),
        read(&still, "color.0004.png")
    );
}

#[test]
fn one_or_two_threads_and_a_killed_run_give_the_same_files() {
    let dir = tempfile::tempdir().unwrap();
    // A flow, so patches are created and eroded while the texture plays.
    let mesh = scene(dir.path(), "vortex", Some("12"), "0-7");
    let bubbles = PathBuf::from("builtin:bubbles");
    let args = |out: &Path| run_args(&mesh, out, &bubbles, &["--exemplar-rate", "1"]);
    let one = dir.path().join("one");
    let out = fluidtex()
        .args(args(&one))
        .env("RAYON_NUM_THREADS", "1")
        .output()
        .unwrap();
    check_ok(&out, &args(&one));
    let two = dir.path().join("two");
    let out = fluidtex()
        .args(args(&two))
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .unwrap();
    check_ok(&out, &args(&two));
    assert_same_outputs(&one, &two);
    let killed = dir.path().join("killed");
    let paused = spawn_paused(&args(&killed), &[("FLUIDTEX_TEST_PAUSE_AFTER_FRAME", "3")]);
    assert_eq!(paused.line, "fluidtex-test: paused after frame 3");
    paused.kill();
    let mut resume = args(&killed);
    resume.push("--resume".into());
    ok(&resume);
    assert_same_outputs(&one, &killed);
}

#[test]
fn bad_sequences_and_settings_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = cooling_grid(&dir.path().join("in"), 2, |_, _| 0.5);
    let out = dir.path().join("out");
    let tex = dir.path().join("tex");
    // A gap: frame 3 of 1..5 is missing.
    let seq = wave(&tex, 1, 5);
    std::fs::remove_file(tex.join("wave.0003.png")).unwrap();
    let err = user_error(&run_args(&mesh, &out, &seq, &[]));
    assert!(err.contains("wave.0003.png: missing"), "{err}");
    // A frame of another size.
    write_frame(&tex.join("wave.0003.png"), 32, 16, 3);
    let err = user_error(&run_args(&mesh, &out, &seq, &[]));
    assert!(err.contains("wave.0003.png is 32x16"), "{err}");
    write_frame(&tex.join("wave.0003.png"), 32, 32, 3);
    // No file matches.
    let none = tex.join("none.####.png");
    let err = user_error(&run_args(&mesh, &out, &none, &[]));
    assert!(err.contains("none.####.png: no file matches"), "{err}");
    // Over the budget (a 0 MiB budget holds nothing).
    let err = user_error(&run_args(&mesh, &out, &seq, &["--exemplar-memory", "0"]));
    assert!(
        err.contains("5 frames take") && err.contains("--exemplar-memory"),
        "{err}"
    );
    // A rate without an animated exemplar, and an absurd rate.
    let still = tex.join("wave.0001.png");
    let err = user_error(&run_args(&mesh, &out, &still, &["--exemplar-rate", "2"]));
    assert!(
        err.contains("--exemplar-rate needs an animated exemplar"),
        "{err}"
    );
    let err = user_error(&run_args(&mesh, &out, &seq, &["--exemplar-rate", "1e9"]));
    assert!(err.contains("exemplar_rate"), "{err}");
    // A feature sequence lacking a frame the colour has.
    let feature = tex.join("feat.####.png");
    for k in [1, 2, 4, 5] {
        write_frame(&tex.join(format!("feat.{k:04}.png")), 32, 32, k);
    }
    let err = user_error(&run_args(
        &mesh,
        &out,
        &seq,
        &["--feature", feature.to_str().unwrap()],
    ));
    assert!(err.contains("feat.0003.png: missing"), "{err}");
    // Nothing was written by any of them.
    assert!(!out.join("color.0000.png").exists());
}
