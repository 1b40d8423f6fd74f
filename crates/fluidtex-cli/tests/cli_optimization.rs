//! `--method optimization` from the command line: a generated scene runs
//! end to end with its stats, the same bytes on 1 and 2 threads, and the
//! same bytes after a SIGKILL and `--resume`; bad parameters are one-line
//! errors. Small sizes (atlas 96², a few thousand points) so it runs in
//! seconds.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::{Path, PathBuf};

use common::*;

fn make_scene(dir: &Path, frames: &str) -> PathBuf {
    let scene = dir.join("scene");
    ok(&[
        "scene".as_ref(),
        "vortex".as_ref(),
        "--frames".as_ref(),
        frames.as_ref(),
        "--resolution".as_ref(),
        "16".as_ref(),
        "--out".as_ref(),
        scene.as_os_str(),
        "--quiet".as_ref(),
    ]);
    scene.join("fluid.####.ply")
}

fn args(pattern: &Path, out: &Path) -> Vec<String> {
    [
        "run",
        "--method",
        "optimization",
        "--mesh",
        pattern.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--atlas",
        "96",
        "--points",
        "3000",
        "--exemplar-texels",
        "32",
        "--sizes",
        "9,5",
        "--iterations",
        "2",
        "--levels",
        "2",
        "--no-obj",
        "--no-glb",
        "--quiet",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect()
}

#[test]
fn runs_a_scene_with_stats_and_the_same_bytes_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = make_scene(dir.path(), "0-2");
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("t{threads}"));
        let a = args(&pattern, &out);
        let o = fluidtex()
            .env("RAYON_NUM_THREADS", threads)
            .args(&a)
            .output()
            .unwrap();
        check_ok(&o, &a);
    }
    assert_same_outputs(&dir.path().join("t1"), &dir.path().join("t2"));
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("t1/stats.0001.json")).unwrap())
            .unwrap();
    let text = stats.to_string();
    for key in [
        "\"points\"",
        "\"transported\":true",
        "energy_start",
        "energy_end",
        "search",
    ] {
        assert!(text.contains(key), "{key} missing from {text}");
    }
    // The colour atlas is not flat.
    let colour = image(&dir.path().join("t1/color.0002.png"));
    let lo = colour.data.iter().copied().fold(f32::MAX, f32::min);
    let hi = colour.data.iter().copied().fold(f32::MIN, f32::max);
    assert!(hi - lo > 0.3, "{lo}..{hi}");
}

#[test]
fn resume_after_sigkill_gives_the_same_files() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = make_scene(dir.path(), "0-4");
    let reference = dir.path().join("reference");
    ok(&args(&pattern, &reference));
    let killed = dir.path().join("killed");
    let a = args(&pattern, &killed);
    let paused = spawn_paused(&a, &[("FLUIDTEX_TEST_PAUSE_AFTER_FRAME", "2")]);
    assert_eq!(paused.line, "fluidtex-test: paused after frame 2");
    paused.kill();
    let mut resume = a.clone();
    resume.push("--resume".into());
    let out = fluidtex().args(&resume).output().unwrap();
    check_ok(&out, &resume);
    assert_same_outputs(&reference, &killed);
}

#[test]
fn bad_parameters_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = make_scene(dir.path(), "0-0");
    let mut a = args(&pattern, &dir.path().join("out"));
    a.extend(["--sizes".into(), "8".into()]);
    let err = user_error(&a);
    assert!(
        err.contains("sizes") && err.trim().lines().count() == 1,
        "{err}"
    );
    let config = dir.path().join("bad.toml");
    std::fs::write(&config, "[optimization]\npoynts = 5\n").unwrap();
    let err = user_error(&[
        "run".as_ref(),
        "--config".as_ref(),
        config.as_os_str(),
        "--mesh".as_ref(),
        pattern.as_os_str(),
        "--out".as_ref(),
        dir.path().join("o2").as_os_str(),
    ]);
    assert!(err.contains("poynts"), "{err}");
}
