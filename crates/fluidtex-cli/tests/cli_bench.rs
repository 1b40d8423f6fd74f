//! `fluidtex bench --mesh`: timing a user's own sequence through the real
//! binary, and its one-line errors on bad input.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::{Path, PathBuf};

use common::*;

/// A tiny `rigid-rotation` sequence (frames 0-2) written by `fluidtex scene`
/// into `dir`; returns its `fluid.####.ply` pattern.
fn tiny_sequence(dir: &Path) -> PathBuf {
    ok(&[
        "scene".as_ref(),
        "rigid-rotation".as_ref(),
        "--resolution".as_ref(),
        "10".as_ref(),
        "--frames".as_ref(),
        "0-2".as_ref(),
        "--out".as_ref(),
        dir.as_os_str(),
        "--quiet".as_ref(),
    ]);
    dir.join("fluid.####.ply")
}

/// The per-frame rows of the table (lines that start with a frame number).
fn frame_rows(stdout: &str) -> Vec<i32> {
    stdout
        .lines()
        .filter_map(|l| l.split_whitespace().next()?.parse().ok())
        .collect()
}

#[test]
fn bench_times_a_users_sequence_and_reports_threads_cpu_and_memory() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = tiny_sequence(&dir.path().join("scene"));
    let out = dir.path().join("out");
    let stdout = ok(&[
        "bench".as_ref(),
        "--mesh".as_ref(),
        pattern.as_os_str(),
        "--atlas".as_ref(),
        "64".as_ref(),
        "--threads".as_ref(),
        "1".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(
        stdout.contains("3 frames, 1 threads"),
        "header missing:\n{stdout}"
    );
    assert_eq!(frame_rows(&stdout), [0, 1, 2], "{stdout}");
    // A user's sequence is read from disk: `read` counts in the total.
    assert!(stdout.contains("total = sum of the stages"), "{stdout}");
    for part in ["mean*", "wall clock:", "cpu use:", "peak memory:"] {
        assert!(stdout.contains(part), "no {part:?} in:\n{stdout}");
    }
    // The whole frame job ran: every frame was written where --out says.
    assert!(has_file(&out, "0002"), "frame 2 not written");

    // --range picks the frames.
    let stdout = ok(&[
        "bench".as_ref(),
        "--mesh".as_ref(),
        pattern.as_os_str(),
        "--range".as_ref(),
        "1-2".as_ref(),
        "--atlas".as_ref(),
        "64".as_ref(),
    ]);
    assert_eq!(frame_rows(&stdout), [1, 2], "{stdout}");
}

/// Whether a file whose name holds `tag` lies anywhere under `dir`.
fn has_file(dir: &Path, tag: &str) -> bool {
    std::fs::read_dir(dir).unwrap().any(|e| {
        let e = e.unwrap();
        let p = e.path();
        if p.is_dir() {
            has_file(&p, tag)
        } else {
            e.file_name().to_string_lossy().contains(tag)
        }
    })
}

#[test]
fn bench_on_a_bad_sequence_fails_with_one_clear_line() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = tiny_sequence(&dir.path().join("scene"));
    let bench = |mesh: &Path, extra: &[&str]| {
        let mut args: Vec<std::ffi::OsString> = vec![
            "bench".into(),
            "--mesh".into(),
            mesh.into(),
            "--atlas".into(),
            "64".into(),
        ];
        args.extend(extra.iter().map(Into::into));
        args
    };

    let missing = dir.path().join("nowhere/fluid.####.ply");
    let line = user_error(&bench(&missing, &[]));
    assert!(line.contains("nowhere"), "{line}");

    let line = user_error(&bench(&pattern, &["--range", "0-0"]));
    assert!(line.contains("at least 2"), "{line}");

    let line = user_error(&bench(&pattern, &["--patches", "50"]));
    assert!(line.contains("--patches"), "{line}");

    let line = user_error(&bench(&pattern, &["--velocity", "a,b"]));
    assert!(line.contains("--velocity"), "{line}");

    // The known-good twin: the same command on the good sequence succeeds.
    ok(&bench(&pattern, &[]));
}
