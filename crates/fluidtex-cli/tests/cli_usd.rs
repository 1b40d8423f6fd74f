//! USD input (`--mesh shot.usda|usdc`) on stages written by Pixar's own
//! library (`usd-core`, see `tests/data/usd/make_usd.py`): the interop
//! sphere as time samples of one Mesh prim, topology changing at frame 2,
//! velocities from the schema's `velocities`; and on damaged copies, which
//! must give one error line naming the file, never a crash.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::{Path, PathBuf};

use common::*;

fn usd(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/usd")
        .join(name)
}

/// Rows of `fluidtex info`: (frame, vertices, triangles, speed range).
fn info_rows(stdout: &str) -> Vec<(String, String, String, String)> {
    stdout
        .lines()
        .skip(2)
        .map(|l| {
            let c: Vec<&str> = l.split_whitespace().collect();
            (c[0].into(), c[1].into(), c[2].into(), c[5].into())
        })
        .collect()
}

#[test]
fn info_reads_time_sampled_topology_and_velocities_from_usda_and_usdc() {
    let ply = info_rows(&ok(&[Path::new("info"), &interop("meshio_ascii.####.ply")]));
    for name in ["falling.usda", "falling.usdc"] {
        let rows = info_rows(&ok(&[Path::new("info"), &usd(name)]));
        let frames: Vec<&str> = rows.iter().map(|r| r.0.as_str()).collect();
        assert_eq!(frames, ["1", "2", "3"], "{name}");
        // 162 points every frame; 320, 319 (one triangle dropped), 320.
        let tris: Vec<&str> = rows.iter().map(|r| r.2.as_str()).collect();
        assert_eq!(tris, ["320", "319", "320"], "{name}");
        for (r, p) in rows.iter().zip(&ply) {
            assert_eq!(r.1, "162", "{name}");
            // The velocities are the PLY's, so the speed ranges agree.
            assert_eq!(r.3, p.3, "{name} frame {}", r.0);
        }
    }
}

#[test]
fn run_on_usdc_gives_the_ply_run_on_the_same_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let from_usd = tmp.path().join("usd");
    let from_ply = tmp.path().join("ply");
    let common = ["--atlas", "64", "--quiet", "--frames", "1"];
    let mut args: Vec<std::ffi::OsString> = vec!["run".into(), "--mesh".into()];
    args.push(usd("falling.usdc").into());
    args.extend(common.iter().map(Into::into));
    args.extend(["--out".into(), from_usd.clone().into()]);
    ok(&args);
    let mut args: Vec<std::ffi::OsString> = vec!["run".into(), "--mesh".into()];
    args.push(interop("meshio_ascii.####.ply").into());
    args.extend(common.iter().map(Into::into));
    args.extend(["--out".into(), from_ply.clone().into()]);
    ok(&args);
    // Same points, faces and velocities: the same atlas, byte for byte.
    for f in ["color.0001.png", "mesh.0001.obj"] {
        assert_eq!(
            std::fs::read(from_usd.join(f)).unwrap(),
            std::fs::read(from_ply.join(f)).unwrap(),
            "{f}"
        );
    }
    // The temporary PLY frames are gone with the run.
    assert!(!from_usd.join("fluid.0001.ply").exists());
}

#[test]
fn prim_is_chosen_by_path_when_there_are_several() {
    let file = usd("two_meshes.usda");
    let line = user_error(&[Path::new("info"), &file]);
    assert!(
        line.contains("2 Mesh prims (/liquid/surface, /liquid/splash); choose one with --prim"),
        "{line}"
    );
    let rows = info_rows(&ok(&[
        Path::new("info"),
        &file,
        Path::new("--prim"),
        Path::new("/liquid/surface"),
    ]));
    assert_eq!(rows.len(), 3);
    let line = user_error(&[
        Path::new("info"),
        &file,
        Path::new("--prim"),
        Path::new("/set/box"),
    ]);
    assert!(
        line.contains("prim /set/box is a Cube, not a Mesh"),
        "{line}"
    );
    let line = user_error(&[
        Path::new("info"),
        &file,
        Path::new("--prim"),
        Path::new("/nope"),
    ]);
    assert!(line.contains("no prim /nope"), "{line}");
}

#[test]
fn damaged_stages_give_one_line_naming_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(usd("falling.usda")).unwrap();
    let binary = std::fs::read(usd("falling.usdc")).unwrap();
    let write = |name: &str, bytes: &[u8]| {
        let p = tmp.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    // Hand-damaged, each with the element the message must name.
    let cases: Vec<(PathBuf, &str)> = vec![
        (write("empty.usdc", b""), "cannot read the USD stage"),
        (
            write("truncated.usdc", &binary[..binary.len() / 2]),
            "cannot read the USD stage",
        ),
        (
            write(
                "syntax.usda",
                text.replacen("def Mesh", "def Mesh {{", 1).as_bytes(),
            ),
            "cannot read the USD stage",
        ),
        (
            write(
                "index.usda",
                text.replacen("1: [0, 137, 53", "1: [0, 9999, 53", 1)
                    .as_bytes(),
            ),
            "/liquid/surface at time 1: faceVertexIndices[1] = 9999: outside the 162 points",
        ),
        (
            write(
                "counts.usda",
                text.replacen("1: [3, 3, 3", "1: [3, 2, 3", 1).as_bytes(),
            ),
            "faceVertexCounts[1] = 2",
        ),
        (
            write(
                "points.usda",
                text.replacen("point3f[] points", "int[] points", 1)
                    .as_bytes(),
            ),
            "points",
        ),
    ];
    for (path, want) in &cases {
        let line = user_error(&[Path::new("info"), path]);
        assert!(line.contains(&path.display().to_string()), "{line}");
        assert!(line.contains(want), "{}: {line}", path.display());
    }
    // Seeded byte damage of the binary file: the reader may refuse it, or
    // (openusd 0.6) panic or abort; every case must end in one line.
    let mut crashed = 0;
    let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for seed in 0..40 {
        let mut bytes = binary.clone();
        for _ in 0..[1, 4, 16][seed % 3] {
            let at = (next() % bytes.len() as u64) as usize;
            bytes[at] = next() as u8;
        }
        let path = write(&format!("damaged{seed}.usdc"), &bytes);
        let out = fluidtex().arg("info").arg(&path).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        if out.status.success() {
            continue; // the damage hit nothing that matters
        }
        assert_eq!(out.status.code(), Some(1), "{}: {stderr}", path.display());
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "{}: {stderr}", path.display());
        assert!(lines[0].starts_with("error: "), "{stderr}");
        assert!(lines[0].contains(&path.display().to_string()), "{stderr}");
        if lines[0].contains("stopped on damaged data") {
            crashed += 1;
        }
    }
    eprintln!(
        "byte damage: {crashed} of 40 copies crashed the reader process and were reported in one line"
    );
}
