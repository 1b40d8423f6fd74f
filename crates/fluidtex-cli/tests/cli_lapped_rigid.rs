//! `fluidtex run --method lapped-rigid` (the 2016 method) through the
//! binary: it runs on a generated scene, gives the same files whatever the
//! thread count and after a kill and `--resume`, takes its parameters from
//! flags and from `[lapped_rigid]`, refuses bad ones in one line, and has
//! its row in `fluidtex compare`.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;

use common::*;

fn make_scene(dir: &Path, frames: &str) -> std::path::PathBuf {
    let scene = dir.join("scene");
    ok(&[
        "scene".as_ref(),
        "rigid-rotation".as_ref(),
        "--resolution".as_ref(),
        "16".as_ref(),
        "--frames".as_ref(),
        frames.as_ref(),
        "--out".as_ref(),
        scene.as_os_str(),
        "--quiet".as_ref(),
    ]);
    scene.join("fluid.####.ply")
}

fn rigid_args(pattern: &Path, out: &Path) -> Vec<std::ffi::OsString> {
    [
        "run".as_ref(),
        "--method".as_ref(),
        "lapped-rigid".as_ref(),
        "--mesh".as_ref(),
        pattern.as_os_str(),
        "--atlas".as_ref(),
        "128".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
        "--quiet".as_ref(),
    ]
    .map(std::ffi::OsString::from)
    .to_vec()
}

fn stats(dir: &Path, f: i32) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join(format!("stats.{f:04}.json"))).unwrap()).unwrap()
}

#[test]
fn runs_covers_everything_and_ignores_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = make_scene(dir.path(), "0-3");
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("t{threads}"));
        let args = rigid_args(&pattern, &out);
        let o = fluidtex()
            .env("RAYON_NUM_THREADS", threads)
            .args(&args)
            .output()
            .unwrap();
        check_ok(&o, &args);
    }
    let t1 = dir.path().join("t1");
    for f in 0..=3 {
        let s = stats(&t1, f);
        assert_eq!(s["method"], "lapped-rigid");
        assert_eq!(s["uncovered_texels"], 0, "frame {f}");
        assert!(s["patches_alive"].as_u64().unwrap() > 0);
        assert!(t1.join(format!("color.{f:04}.png")).exists());
        assert!(t1.join(format!("mesh.{f:04}.glb")).exists());
    }
    assert_same_outputs(&t1, &dir.path().join("t2"));
}

/// Killed with SIGKILL after frame 2 (the run pauses itself there, so the
/// kill always lands between frames 2 and 3), then `--resume`d: the same
/// files as an uninterrupted run.
#[test]
fn resume_after_sigkill_gives_the_same_files() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = make_scene(dir.path(), "0-5");
    let reference = dir.path().join("reference");
    ok(&rigid_args(&pattern, &reference));
    let killed = dir.path().join("killed");
    let args = rigid_args(&pattern, &killed);
    let paused = spawn_paused(&args, &[("FLUIDTEX_TEST_PAUSE_AFTER_FRAME", "2")]);
    assert_eq!(paused.line, "fluidtex-test: paused after frame 2");
    paused.kill();
    assert!(!killed.join("color.0003.png").exists());
    let mut resume = args.clone();
    resume.push("--resume".into());
    let out = fluidtex().args(&resume).output().unwrap();
    check_ok(&out, &resume);
    assert_same_outputs(&reference, &killed);
}

#[test]
fn parameters_come_from_flags_and_the_config_and_bad_ones_are_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = make_scene(dir.path(), "0-1");
    // A given radius reaches the method, from a flag and from the file.
    let out = dir.path().join("flag");
    let mut args = rigid_args(&pattern, &out);
    args.extend(["--rigid-radius".into(), "0.2".into()]);
    ok(&args);
    assert!((stats(&out, 0)["radius"].as_f64().unwrap() - 0.2).abs() < 1e-6);
    let config = dir.path().join("shot.toml");
    std::fs::write(&config, "[lapped_rigid]\nradius = 0.25\nphi_max = 120.0\n").unwrap();
    let out = dir.path().join("file");
    let mut args = rigid_args(&pattern, &out);
    args.extend(["--config".into(), config.clone().into_os_string()]);
    ok(&args);
    assert!((stats(&out, 0)["radius"].as_f64().unwrap() - 0.25).abs() < 1e-6);

    let mut bad = rigid_args(&pattern, &dir.path().join("bad"));
    bad.extend(["--rigid-alpha-opaque".into(), "70".into()]);
    let line = user_error(&bad);
    assert!(line.contains("alpha_opaque"), "{line}");
    let mut bad = rigid_args(&pattern, &dir.path().join("bad2"));
    bad.extend(["--mask".into(), dir.path().join("no-such-mask.png").into()]);
    let line = user_error(&bad);
    assert!(line.contains("no-such-mask.png"), "{line}");
    std::fs::write(&config, "[lapped_rigid]\nphi_maxx = 120.0\n").unwrap();
    let mut bad = rigid_args(&pattern, &dir.path().join("bad3"));
    bad.extend(["--config".into(), config.into_os_string()]);
    let line = user_error(&bad);
    assert!(line.contains("phi_maxx"), "{line}");
}

#[test]
fn compare_has_a_lapped_rigid_row() {
    let dir = tempfile::tempdir().unwrap();
    let args: Vec<String> = [
        "fluidtex",
        "compare",
        "--quiet",
        "--scenes",
        "rigid-rotation",
        "--methods",
        "lapped-rigid",
        "--frames",
        "0-1",
        "--atlas",
        "64",
        "--resolution",
        "12",
        "--render",
        "48",
        "--out",
    ]
    .iter()
    .map(|s| s.to_string())
    .chain([dir.path().display().to_string()])
    .collect();
    fluidtex_cli::run(args).unwrap();
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(md.contains("| lapped-rigid | 0 [0, 0] PASS |"), "{md}");
}
