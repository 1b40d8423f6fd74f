//! A run in two phases (`--phase select`, then `--phase resample` over
//! ranges of frames in separate processes, at once) writes the files
//! of a one-pass run, byte for byte: for erosion, whose selection is its
//! patches, and for lapped-rigid, which replays the frame from the state
//! before it. Resampling a frame that was never selected is one line.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;

use common::*;

fn args(method: &str, pattern: &Path, out: &Path, extra: &[&str]) -> Vec<std::ffi::OsString> {
    let mut a: Vec<std::ffi::OsString> = [
        "run".as_ref(),
        "--mesh".as_ref(),
        pattern.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
        "--method".as_ref(),
        method.as_ref(),
        "--atlas".as_ref(),
        "96".as_ref(),
        "--preview-every".as_ref(),
        "2".as_ref(),
        "--quiet".as_ref(),
    ]
    .map(std::ffi::OsString::from)
    .to_vec();
    a.extend(extra.iter().map(std::ffi::OsString::from));
    a
}

fn selections(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = files(dir)
        .into_keys()
        .filter(|n| n.starts_with("selection."))
        .collect();
    names.sort();
    names
}

#[test]
fn select_then_resample_in_ranges_writes_the_one_pass_files() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = small_vortex(dir.path());
    for method in ["erosion", "lapped-rigid"] {
        let reference = dir.path().join(format!("{method}-one-pass"));
        ok(&args(method, &pattern, &reference, &[]));
        let split = dir.path().join(format!("{method}-split"));
        ok(&args(method, &pattern, &split, &["--phase", "select"]));
        // Phase 1 writes selections and the state, nothing else.
        let mut written: Vec<String> = files(&split).into_keys().collect();
        written.retain(|n| n != "state.bin");
        let want: Vec<String> = (0..=5).map(|f| format!("selection.{f:04}.bin")).collect();
        assert_eq!(written, want, "{method}: phase 1 files");
        // Two ranges at once, each in its own process.
        let running: Vec<_> = ["3-5", "0-2"]
            .map(|range| {
                let a = args(
                    method,
                    &pattern,
                    &split,
                    &["--phase", "resample", "--frames", range],
                );
                let child = fluidtex()
                    .args(&a)
                    .stdout(std::process::Stdio::piped())
                    .stderr(std::process::Stdio::piped())
                    .spawn()
                    .unwrap();
                (a, child)
            })
            .into_iter()
            .collect();
        for (a, child) in running {
            check_ok(&child.wait_with_output().unwrap(), &a);
        }
        let two = assert_two_phase_matches(&reference, &split);
        assert_eq!(selections(&split).len(), 6);
        // The coherence numbers of a range's first frame are there too.
        let stats: serde_json::Value = serde_json::from_slice(&two["stats.0003.json"]).unwrap();
        assert!(
            stats["source_switch_share"].is_number(),
            "{method}: {stats}"
        );
    }
}

#[test]
fn resampling_before_selecting_or_with_other_settings_is_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = small_vortex(dir.path());
    let out = dir.path().join("split");
    let err = user_error(&args(
        "erosion",
        &pattern,
        &out,
        &["--phase", "resample", "--frames", "2-3"],
    ));
    assert!(err.contains("frame 2: "), "{err}");
    assert!(err.contains("selection.0002.bin"), "{err}");
    assert!(err.contains("--phase select"), "{err}");
    ok(&args(
        "erosion",
        &pattern,
        &out,
        &["--phase", "select", "--frames", "0-2"],
    ));
    let err = user_error(&args(
        "erosion",
        &pattern,
        &out,
        &["--phase", "resample", "--frames", "1", "--seed", "9"],
    ));
    assert!(err.contains("another configuration"), "{err}");
    // A damaged selection is refused, not read.
    let path = out.join("selection.0001.bin");
    let mut bytes = std::fs::read(&path).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x55;
    std::fs::write(&path, bytes).unwrap();
    let err = user_error(&args(
        "erosion",
        &pattern,
        &out,
        &["--phase", "resample", "--frames", "1"],
    ));
    assert!(err.contains("selection.0001.bin: damaged"), "{err}");
}

/// A farm's faults: phase 1 killed in the middle of a write and run again
/// with `--resume`, then a range killed in the middle of a frame's write
/// (its lock and a temporary left behind) and requeued: the files are
/// those of a one-pass run, and nothing of the killed runs is left.
#[test]
fn killed_phases_resume_to_the_one_pass_files() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = small_vortex(dir.path());
    let reference = dir.path().join("one-pass");
    ok(&args("erosion", &pattern, &reference, &[]));
    let split = dir.path().join("split");
    let select = args("erosion", &pattern, &split, &["--phase", "select"]);
    spawn_paused(&select, &[("FLUIDTEX_TEST_PAUSE_IN_WRITE", "5")]).kill();
    assert_eq!(temporaries(&split).len(), 1, "the killed write's temporary");
    let mut again = select.clone();
    again.push("--resume".into());
    ok(&again);
    let resample = args(
        "erosion",
        &pattern,
        &split,
        &["--phase", "resample", "--frames", "0-5", "--resume"],
    );
    spawn_paused(&resample, &[("FLUIDTEX_TEST_PAUSE_IN_WRITE", "12")]).kill();
    // The frame's files staged so far, none renamed.
    assert!(!temporaries(&split).is_empty());
    assert!(split.join("fluidtex.resample.0000-0005.lock").exists());
    ok(&resample);
    assert_eq!(temporaries(&split), Vec::<String>::new());
    assert_two_phase_matches(&reference, &split);
}
