//! What a render farm hits: two runs into one folder, a run killed while
//! holding the folder, a disk that fills mid-frame, an atlas that cannot
//! fit in memory. Every test stops the run at an exact point through the
//! test hooks (`fluidtex_cli::test_hooks`), never by timing.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::{Path, PathBuf};

use common::*;

/// A small erosion run (64² atlas unless `extra` says) as arguments.
fn args(pattern: &Path, out: &Path, extra: &[&str]) -> Vec<std::ffi::OsString> {
    let mut a: Vec<std::ffi::OsString> = [
        "run".as_ref(),
        "--mesh".as_ref(),
        pattern.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
        "--quiet".as_ref(),
        // The per-texel switch map too: its write is in the counted order.
        "--switch-map".as_ref(),
    ]
    .map(std::ffi::OsString::from)
    .to_vec();
    // `extra` may set its own atlas size (clap refuses a repeated flag).
    if !extra.contains(&"--atlas") {
        a.extend(["--atlas".into(), "64".into()]);
    }
    a.extend(extra.iter().map(std::ffi::OsString::from));
    a
}

fn scene(dir: &Path, frames: &str) -> PathBuf {
    common::scene(dir, "rigid-rotation", Some("12"), frames)
}

fn hostname() -> String {
    fluidtex::io::lock::hostname()
}

/// Two runs into one folder (a re-queued farm task): the second refuses at
/// once with one line naming the folder and the first run, writes nothing,
/// and the first run then finishes with exactly the files of a run that was
/// alone.
#[test]
fn a_second_run_into_the_same_folder_is_refused_and_the_first_is_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = scene(dir.path(), "0-2");
    let reference = dir.path().join("reference");
    ok(&args(&pattern, &reference, &["--seed", "0"]));

    let out = dir.path().join("out");
    let first = spawn_paused(
        &args(&pattern, &out, &["--seed", "0"]),
        &[("FLUIDTEX_TEST_PAUSE_AFTER_FRAME", "0")],
    );
    let before = files(&out);
    let line = user_error(&args(&pattern, &out, &["--seed", "5"]));
    let expected = format!(
        "error: {}: another fluidtex run is writing here (pid {} on host {}, started ",
        out.display(),
        first.child.id(),
        hostname()
    );
    assert!(
        line.starts_with(&expected),
        "{line}\nexpected {expected}..."
    );
    assert!(
        line.ends_with("s ago); wait for it to end or choose another --out"),
        "{line}"
    );
    assert!(files(&out) == before, "the refused run changed the folder");
    // Also with --resume (a re-queued task resuming into a live run).
    user_error(
        &[
            args(&pattern, &out, &["--seed", "0"]),
            vec!["--resume".into()],
        ]
        .concat(),
    );

    let (success, stderr) = first.resume();
    assert!(success, "{stderr}");
    assert_same_outputs(&reference, &out);
    assert!(!out.join("fluidtex.lock").exists(), "the lock is released");
}

/// A lock file left by a killed run does not block the folder: the next run
/// takes it over with a warning naming the dead run, and releases it.
#[test]
fn a_lock_left_by_a_killed_run_is_taken_over() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let pattern = interop("meshio_ascii.####.ply");
    let run = args(&pattern, &out, &["--method", "atlas-check"]);
    let paused = spawn_paused(&run, &[("FLUIDTEX_TEST_PAUSE_AFTER_FRAME", "1")]);
    let pid = paused.child.id();
    paused.kill();
    let lock = std::fs::read_to_string(out.join("fluidtex.lock")).unwrap();
    assert!(
        lock.starts_with(&format!("pid {pid}\nhost {}\n", hostname())),
        "{lock}"
    );
    let o = fluidtex().args(&run).output().unwrap();
    check_ok(&o, &run);
    let stderr = String::from_utf8_lossy(&o.stderr);
    let warning = format!(
        "warning: {}: took over the lock of a run that is no longer running (pid {pid} on host {}, started ",
        out.join("fluidtex.lock").display(),
        hostname()
    );
    assert!(stderr.starts_with(&warning), "{stderr}");
    assert!(!out.join("fluidtex.lock").exists());
}

/// The files of frame `f` of these runs (erosion, debug outputs on; from
/// the second frame on, the switch map against the frame before).
fn frame_files(f: i32) -> Vec<String> {
    let mut names: Vec<String> = [
        "color", "mesh", "mesh", "mesh", "patches", "source", "stats",
    ]
    .iter()
    .zip(["png", "mtl", "obj", "glb", "png", "exr", "json"])
    .map(|(n, e)| format!("{n}.{f:04}.{e}"))
    .collect();
    if f > 0 {
        names.push(format!("switch.{f:04}.png"));
    }
    names
}

/// A disk that fills in the Nth write (`FLUIDTEX_TEST_FAIL_WRITE=N`: the
/// write fails with ENOSPC after its temporary holds its bytes, the path a
/// real full disk takes through `Staging::write`). The run stops with one
/// line naming the file; every frame's files are all there or none are; no
/// temporary is left; and after "space is freed" the same command with
/// `--resume` writes exactly the files of an uninterrupted run.
///
/// Writes per frame, in order: color.png, mesh.mtl, mesh.obj, mesh.glb,
/// (from frame 1 on) switch.png, then the debug views source.exr and
/// patches.png, stats.json, then state.bin.
#[test]
fn a_full_disk_mid_frame_leaves_no_counted_partial_frame_and_resume_matches() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = scene(dir.path(), "0-2");
    let reference = dir.path().join("reference");
    ok(&args(&pattern, &reference, &[]));
    let cases = [
        (3, "mesh.0000.obj", None),
        (8, "state.bin", Some(0)),
        (12, "mesh.0001.glb", Some(0)),
        (13, "switch.0001.png", Some(0)),
        (15, "patches.0001.png", Some(0)),
        (16, "stats.0001.json", Some(0)),
        (17, "state.bin", Some(1)),
    ];
    for (n, file, complete_through) in cases {
        let out = dir.path().join(format!("fail{n}"));
        let run = args(&pattern, &out, &[]);
        let o = fluidtex()
            .args(&run)
            .env("FLUIDTEX_TEST_FAIL_WRITE", n.to_string())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "write {n}: {stderr}");
        assert_eq!(
            stderr.trim_end(),
            format!(
                "error: {}: No space left on device (os error 28)",
                out.join(file).display()
            ),
            "write {n}"
        );
        assert_eq!(temporaries(&out), Vec::<String>::new(), "write {n}");
        let names = files(&out);
        for f in 0..=2 {
            let present = frame_files(f)
                .iter()
                .filter(|x| names.contains_key(*x))
                .count();
            let all = complete_through.is_some_and(|c| f <= c);
            let want = frame_files(f).len();
            assert_eq!(
                present,
                if all { want } else { 0 },
                "write {n}: frame {f} has {present} of its {want} files"
            );
        }
        // The state counts only frames whose write of state.bin succeeded:
        // with n = 8 frame 0's files are there, but no state counts them.
        assert_eq!(names.contains_key("state.bin"), n > 8, "write {n}");
        assert!(!names.contains_key("fluidtex.lock"), "write {n}: lock kept");

        let mut resume = run.clone();
        resume.push("--resume".into());
        ok(&resume);
        assert_same_outputs(&reference, &out);
    }
}

/// The memory needed is estimated before any frame is read: with 1 GB
/// available, an 8192² atlas is refused with the flag that lowers it, and
/// the frame (a damaged file, which would fail any read) is never read.
/// Control: a 64² atlas with the same memory reads the frame and fails on
/// its damage. The CLI and the library agree on the largest atlas.
#[test]
fn an_impossible_atlas_is_refused_before_any_frame_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    std::fs::create_dir_all(&input).unwrap();
    std::fs::write(input.join("fluid.0001.ply"), b"ply\nthis is no mesh\n").unwrap();
    let pattern = input.join("fluid.####.ply");
    let out = dir.path().join("out");
    let refused = |extra: &[&str]| {
        let run = args(&pattern, &out, extra);
        let o = fluidtex()
            .args(&run)
            .env("FLUIDTEX_TEST_MEMORY_AVAILABLE", "1000000000")
            // The estimate counts the worker threads.
            .env("RAYON_NUM_THREADS", "2")
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1));
        String::from_utf8_lossy(&o.stderr).trim_end().to_string()
    };
    let line = refused(&["--atlas", "8192"]);
    assert!(
        line.starts_with("error: a 8192x8192 atlas needs about ")
            && line.ends_with(
                " of memory and 953 MiB is available: lower --atlas (at most 4352 fits)"
            ),
        "{line}"
    );
    assert!(!out.exists(), "refused before creating the output folder");
    let line = refused(&["--atlas", "64"]);
    assert!(
        line.starts_with(&format!(
            "error: {}: bad header",
            input.join("fluid.0001.ply").display()
        )),
        "{line}"
    );
    // Above the library's limit: refused by the flag check itself.
    let line = user_error(&args(&pattern, &out, &["--atlas", "16385"]));
    assert_eq!(line, "error: --atlas 16385: allowed 16 to 16384 texels");
}

/// A run past `--max-memory` stops after the frame that passed it, with
/// the cause and the method's account in one line and a non-zero exit;
/// `--resume` with a larger limit (here none) writes the files of an
/// uninterrupted run.
#[test]
fn a_run_past_its_memory_limit_stops_with_the_cause_and_resumes_identically() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = scene(dir.path(), "0-3");
    let reference = dir.path().join("reference");
    let args = |out: &Path| -> Vec<std::ffi::OsString> {
        let mut a: Vec<std::ffi::OsString> = vec![
            "run".into(),
            "--mesh".into(),
            pattern.clone().into(),
            "--atlas".into(),
            "64".into(),
            "--quiet".into(),
            "--out".into(),
            out.into(),
        ];
        a.extend(["--max-memory".into(), "0".into()]);
        a
    };
    ok(&args(&reference));
    let limited = dir.path().join("limited");
    let mut first = args(&limited);
    first.truncate(first.len() - 2);
    first.extend(["--max-memory".into(), "1G".into()]);
    let out = fluidtex()
        .args(&first)
        .env("FLUIDTEX_TEST_RESIDENT_MEMORY", (3u64 << 30).to_string())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.is_empty()).collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(
        lines[0].starts_with("error: memory: 3.0 GiB after frame 0 (limit 1.0 GiB): "),
        "{stderr}"
    );
    assert!(
        lines[0].contains(" patches, "),
        "the method's account: {stderr}"
    );
    // Frame 0 is finished and counted; nothing of frame 1 was written.
    assert!(limited.join("color.0000.png").exists());
    assert!(!limited.join("color.0001.png").exists());
    let mut resume = args(&limited);
    resume.push("--resume".into());
    ok(&resume);
    assert_same_outputs(&reference, &limited);
}

/// Writes frames of the unit square at rest, frame `f` a grid of
/// `cells(f)` × `cells(f)` squares (two triangles each, zero velocity);
/// returns the pattern.
fn square_frames(dir: &Path, cells: &[usize]) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    for (f, &n) in cells.iter().enumerate() {
        let mut ply = format!(
            "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
             property float z\nproperty float vx\nproperty float vy\nproperty float vz\n\
             element face {}\nproperty list uchar int vertex_indices\nend_header\n",
            (n + 1) * (n + 1),
            2 * n * n
        );
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (i as f32 / n as f32 - 0.5, j as f32 / n as f32 - 0.5);
                ply.push_str(&format!("{x} {y} 0 0 0 0\n"));
            }
        }
        common::push_grid_faces(&mut ply, n);
        std::fs::write(dir.join(format!("fluid.{f:04}.ply")), ply).unwrap();
    }
    dir.join("fluid.####.ply")
}

/// A frame built to balloon: the liquid at rest, re-meshed 12 times finer
/// on frame 2, so every patch edge is split down to the new mesh's scale
/// (about 100 times the patch triangles, within the frame's splitting).
/// The resident set the checks read is held at 1000 MiB (the hook), under
/// the limit of 1002 MiB after every frame: the after-frame check alone
/// would let the frame through, whatever it grew to. The stages' own
/// count passes the limit inside frame 2's splitting: the run stops there
/// with its one-line memory error naming the stage, frame 2 unwritten, and
/// `--resume` without a limit writes the files of an uninterrupted run.
#[test]
fn a_frame_that_balloons_stops_inside_the_stage_that_grows_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = square_frames(&dir.path().join("square"), &[8, 8, 96]);
    let reference = dir.path().join("reference");
    ok(&args(&pattern, &reference, &["--max-memory", "0"]));
    let limited = dir.path().join("limited");
    let run = |limit: &str| {
        fluidtex()
            .args(args(&pattern, &limited, &["--max-memory", limit]))
            .env("FLUIDTEX_TEST_RESIDENT_MEMORY", (1000u64 << 20).to_string())
            .output()
            .unwrap()
    };
    let out = run("1002M");
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.is_empty()).collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(
        lines[0].starts_with("error: memory: about ")
            && lines[0].contains(" during frame 2's splitting (limit 1002 MiB): ")
            && lines[0].contains(" patches, "),
        "{stderr}"
    );
    // Frames 0 and 1 are written and counted; nothing of frame 2.
    assert!(limited.join("color.0001.png").exists());
    assert!(!limited.join("color.0002.png").exists());
    // Known good: the frames before the balloon passed the same checks,
    // and a limit with room for the frame's growth lets it through.
    let mut resume = args(&pattern, &limited, &["--max-memory", "1200M"]);
    resume.push("--resume".into());
    let o = fluidtex()
        .args(&resume)
        .env("FLUIDTEX_TEST_RESIDENT_MEMORY", (1000u64 << 20).to_string())
        .output()
        .unwrap();
    check_ok(&o, &resume);
    assert_same_outputs(&reference, &limited);
}

/// The estimate a run prints before its first frame bounds the peak
/// resident set it then reaches (`VmHWM`, printed after the run), by no
/// more than twice, for every method, on an SPH dam break (11k triangles)
/// at several atlas sizes; it names the largest frame's triangle count. A
/// machine whose memory would hold the atlas but not the frames and the
/// method's state refuses, after reading the one largest frame, saying so.
#[test]
fn estimates_bound_the_measured_peak() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = common::scene(dir.path(), "dam-break", None, "0-3");
    for (method, atlas, extra) in [
        ("erosion", "512", None),
        // With previews: a preview frame's float patch colours count too.
        ("erosion", "1024", Some("--preview-every=2")),
        ("blend-deformable", "512", None),
        ("dual-rest", "256", None),
        ("lapped-rigid", "512", None),
        ("optimization", "256", None),
        ("atlas-check", "512", None),
    ] {
        let out = dir.path().join(format!("{method}-{atlas}"));
        let mut flags = vec!["--method", method, "--atlas", atlas];
        flags.extend(extra);
        let run = args(&pattern, &out, &flags);
        let run: Vec<_> = run.into_iter().filter(|a| a != "--quiet").collect();
        let o = fluidtex().args(&run).output().unwrap();
        check_ok(&o, &run);
        let stderr = String::from_utf8_lossy(&o.stderr);
        let line = |start: &str| {
            let found = stderr.lines().find(|l| l.starts_with(start));
            found.unwrap_or_else(|| panic!("no {start:?} line: {stderr}"))
        };
        let said = format!("{method} at {atlas}²");
        if method == "blend-deformable" {
            // Its patches keep every triangle they gathered, so its model
            // is sized for a run of about two seconds, not four frames:
            // here only the bound holds.
            let (peak, estimate) = peak_and_estimate(&stderr, &said);
            assert!(estimate >= peak, "{said}: {peak} > {estimate}");
        } else {
            assert_estimate_bounds_peak(&stderr, &said);
        }
        // The triangles named are those of the largest frame.
        let largest = (0..4)
            .map(|f| {
                let stats = std::fs::read(out.join(format!("stats.{f:04}.json"))).unwrap();
                let stats: serde_json::Value = serde_json::from_slice(&stats).unwrap();
                stats["triangles"].as_u64().unwrap()
            })
            .max()
            .unwrap();
        let named = between(line("memory: about "), " and ", " triangles");
        assert_eq!(named, format!("{}k", (largest + 500) / 1000), "{said}");
    }
    // 70 MB hold the program and a 64² atlas, not the frames and the
    // patches of 11k triangles.
    let out = dir.path().join("refused");
    let o = fluidtex()
        .args(args(&pattern, &out, &[]))
        .env("FLUIDTEX_TEST_MEMORY_AVAILABLE", "70000000")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.starts_with("error: a 64x64 atlas with 11k triangles needs about ")
            && stderr.contains(
                " of memory and 66 MiB is available: even without an atlas it needs about "
            ),
        "{stderr}"
    );
}
