//! Golden outputs: a handful of small runs of the real binary (`demo`, one
//! analytic scene per method through `scene` + `run`, and `compare`) whose
//! output files are hashed and checked against the hashes committed in
//! `tests/data/golden/CASE.txt`, one line per file: `HASH  relative/path`.
//!
//! Why: the other tests check properties (coverage, determinism across
//! thread counts, resume); none notices that a refactoring changed a pixel.
//! These hashes do, so a restructuring can prove it kept every output
//! bit-identical, and an intended change shows up as a reviewed diff of the
//! hash files.
//!
//! Every file a run writes is hashed (a new, unlisted file is a mismatch
//! too), after removing only what legitimately varies between two runs of
//! the same build, or between versions:
//! - `stats.F.json`: the wall-clock `seconds` per stage and `stage_order`
//!   (the order of those timings);
//! - `report.json` of `compare`: every `seconds` and `seconds_per_frame`;
//!   `report.md` and `report.html` show timings throughout and are not
//!   hashed (their numbers are the ones of `report.json`);
//! - `mesh.F.glb`: the `asset.generator` string, which holds the version;
//! - `state.bin`: the run fingerprint (a hash of the settings plus the
//!   version, used to refuse resuming a different run); the method, last
//!   frame, patch state and its checksum are hashed.
//!
//! Paths never enter an output: every command runs inside a fresh folder
//! with relative paths. The hash is FNV-1a 64 (the `fnv` crate), stable
//! across platforms. Floating-point results may depend on the CPU (see
//! docs/testing.md): the committed hashes hold for the CI machine's kind.
//!
//! Update, after checking that a change of output is intended:
//! `FLUIDTEX_BLESS=1 cargo test -p fluidtex-cli --test golden`, then review
//! and commit the changed `tests/data/golden/*.txt`.

#![allow(clippy::unwrap_used)]

mod common;

use std::collections::BTreeMap;
use std::hash::Hasher;
use std::path::{Path, PathBuf};

use common::{check_ok, fluidtex};

const VERSION: &str = env!("CARGO_PKG_VERSION");
const BLESS: &str = "FLUIDTEX_BLESS=1 cargo test -p fluidtex-cli --test golden";

/// A scene of 4 frames; the 256² atlas of every run keeps the whole file
/// at a few seconds per case.
const SCENE_FRAMES: &str = "0-3";

#[test]
fn demo_sphere() {
    golden(
        "demo",
        &[],
        &[&[
            "demo",
            "--out",
            "demo",
            "--frames",
            "0-3",
            "--atlas",
            "256",
            "--preview-every",
            "2",
            "--quiet",
        ]],
    );
}

/// With the per-texel switch map (`--switch-map`), which no other case
/// writes.
#[test]
fn erosion_on_the_vortex() {
    scene_case("erosion", "erosion", "vortex", &[], &["--switch-map"]);
}

/// Erosion again, with a file exemplar (derived feature map), an extra
/// channel and previews, on a scene whose topology changes.
#[test]
fn erosion_with_exemplar_channel_and_previews_on_split_merge() {
    scene_case(
        "erosion-exemplar",
        "erosion",
        "split-merge",
        &["gravel.png", "brick.png"],
        &[
            "--exemplar",
            "gravel.png",
            "--channel",
            "rough=brick.png",
            "--preview-every",
            "2",
        ],
    );
}

#[test]
fn advect_on_the_rigid_rotation() {
    scene_case("advect", "advect", "rigid-rotation", &[], &[]);
}

/// A period of 2 frames, so both layers are reset within the 4 frames.
#[test]
fn dual_rest_on_the_differential_rotation() {
    scene_case(
        "dual-rest",
        "dual-rest",
        "differential-rotation",
        &[],
        &["--period", "2"],
    );
}

#[test]
fn blend_deformable_on_the_shear() {
    scene_case("blend-deformable", "blend-deformable", "shear", &[], &[]);
}

#[test]
fn lapped_rigid_on_the_vortex() {
    scene_case("lapped-rigid", "lapped-rigid", "vortex", &[], &[]);
}

/// Few points, so the dev-profile run stays short.
#[test]
fn optimization_on_the_differential_rotation() {
    scene_case(
        "optimization",
        "optimization",
        "differential-rotation",
        &[],
        &["--points", "4000"],
    );
}

#[test]
fn atlas_check_on_enright() {
    scene_case("atlas-check", "atlas-check", "enright", &[], &[]);
}

/// Every method on the stop scene across the moment it stops (frame 48),
/// small meshes and renders: the metrics and pictures of `compare`.
#[test]
fn compare_every_method_on_stop() {
    golden(
        "compare",
        &[],
        &[&[
            "compare",
            "--scenes",
            "stop",
            "--frames",
            "46-49",
            "--atlas",
            "256",
            "--render",
            "64",
            "--resolution",
            "24",
            "--out",
            "compare",
            "--quiet",
        ]],
    );
}

/// `scene SCENE` into `scene/`, then `run --method METHOD` on it into
/// `out/` with the `extra` flags, which may name the test `exemplars`.
fn scene_case(case: &str, method: &str, scene: &str, exemplars: &[&str], extra: &[&str]) {
    let mut run = vec![
        "run",
        "--mesh",
        "scene/fluid.####.ply",
        "--out",
        "out",
        "--atlas",
        "256",
        "--method",
        method,
        "--quiet",
    ];
    run.extend_from_slice(extra);
    golden(
        case,
        exemplars,
        &[
            &[
                "scene",
                scene,
                "--out",
                "scene",
                "--frames",
                SCENE_FRAMES,
                "--quiet",
            ],
            &run,
        ],
    );
}

/// Runs `commands` in a fresh folder (after copying the named test
/// exemplars into it), hashes what they wrote and compares with (or, when
/// blessing, rewrites) `tests/data/golden/CASE.txt`.
fn golden(case: &str, exemplars: &[&str], commands: &[&[&str]]) {
    let dir = tempfile::tempdir().unwrap();
    for name in exemplars {
        std::fs::copy(common::exemplar(name), dir.path().join(name)).unwrap();
    }
    for args in commands {
        let out = fluidtex()
            .current_dir(dir.path())
            .args(*args)
            .output()
            .unwrap();
        check_ok(&out, args);
    }
    let mut actual = BTreeMap::new();
    hash_tree(dir.path(), dir.path(), &mut actual);
    for name in exemplars {
        actual.remove(*name);
    }
    let file = golden_dir().join(format!("{case}.txt"));
    if std::env::var_os("FLUIDTEX_BLESS").is_some_and(|v| v == "1") {
        let mut text = format!(
            "# Golden output hashes of fluidtex (FNV-1a 64 of each file, normalised as\n\
             # crates/fluidtex-cli/tests/golden.rs says). Update: {BLESS}\n"
        );
        for args in commands {
            text.push_str(&format!("# $ fluidtex {}\n", args.join(" ")));
        }
        for (path, hash) in &actual {
            text.push_str(&format!("{hash}  {path}\n"));
        }
        std::fs::create_dir_all(golden_dir()).unwrap();
        std::fs::write(&file, text).unwrap();
        return;
    }
    let text = std::fs::read_to_string(&file)
        .unwrap_or_else(|e| panic!("{}: {e}; write the hashes with: {BLESS}", file.display()));
    let expected: BTreeMap<String, String> = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let (hash, path) = l
                .split_once("  ")
                .unwrap_or_else(|| panic!("{}: bad line {l:?}", file.display()));
            (path.to_string(), hash.to_string())
        })
        .collect();
    let mut problems = Vec::new();
    for (path, hash) in &expected {
        match actual.get(path) {
            None => problems.push(format!("  missing:  {path} (listed, not written)")),
            Some(h) if h != hash => {
                problems.push(format!("  differs:  {path} (expected {hash}, got {h})"))
            }
            Some(_) => {}
        }
    }
    for path in actual.keys().filter(|p| !expected.contains_key(*p)) {
        problems.push(format!("  new:      {path} (written, not listed)"));
    }
    assert!(
        problems.is_empty(),
        "golden case {case}: {} of {} files differ from {}:\n{}\n\
         If the change is intended, rewrite the hashes with\n  {BLESS}\n\
         and review the diff of tests/data/golden/ before committing it.",
        problems.len(),
        expected.len().max(actual.len()),
        file.display(),
        problems.join("\n")
    );
}

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/golden")
}

/// Hashes every file under `dir` (except those that only show timings),
/// keyed by its path relative to `root` with `/` separators.
fn hash_tree(root: &Path, dir: &Path, hashes: &mut BTreeMap<String, String>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            hash_tree(root, &path, hashes);
            continue;
        }
        let name = path.file_name().unwrap().to_str().unwrap();
        if name == "report.md" || name == "report.html" {
            continue;
        }
        let relative: Vec<String> = path
            .strip_prefix(root)
            .unwrap()
            .components()
            .map(|c| c.as_os_str().to_str().unwrap().to_string())
            .collect();
        let bytes = normalise(name, std::fs::read(&path).unwrap());
        let mut h = fnv::FnvHasher::default();
        h.write(&bytes);
        hashes.insert(relative.join("/"), format!("{:016x}", h.finish()));
    }
}

/// The bytes of a file with what legitimately varies removed (see the
/// module documentation).
fn normalise(name: &str, bytes: Vec<u8>) -> Vec<u8> {
    if name.starts_with("stats.") && name.ends_with(".json") {
        let mut v: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
        let map = v.as_object_mut().unwrap();
        assert!(map.remove("seconds").is_some(), "{name}: no seconds");
        map.remove("stage_order");
        serde_json::to_vec_pretty(&v).unwrap()
    } else if name == "report.json" {
        let mut v: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
        remove_timings(&mut v);
        serde_json::to_vec_pretty(&v).unwrap()
    } else if name.ends_with(".glb") {
        glb_without_generator(name, &bytes)
    } else if name == "state.bin" {
        state_without_fingerprint(bytes)
    } else {
        bytes
    }
}

/// Removes `seconds` and `seconds_per_frame` at every depth.
fn remove_timings(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(map) => {
            map.remove("seconds");
            map.remove("seconds_per_frame");
            map.values_mut().for_each(remove_timings);
        }
        serde_json::Value::Array(items) => items.iter_mut().for_each(remove_timings),
        _ => {}
    }
}

/// A glb's JSON chunk without `asset.generator`, followed by its other
/// chunks as written (the header's lengths are left out: they change with
/// the generator's length).
fn glb_without_generator(name: &str, bytes: &[u8]) -> Vec<u8> {
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!(&bytes[..4], b"glTF", "{name}: not a glb");
    let json_len = u32_at(12);
    let mut json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let asset = json["asset"].as_object_mut().unwrap();
    assert!(
        asset.remove("generator").is_some(),
        "{name}: no asset.generator"
    );
    let mut out = serde_json::to_vec(&json).unwrap();
    out.extend_from_slice(&bytes[20 + json_len..]);
    out
}

/// `state.bin` with its fingerprint string (postcard: one length byte, 16
/// hex digits, `-v` and the version) replaced by a fixed marker.
fn state_without_fingerprint(mut bytes: Vec<u8>) -> Vec<u8> {
    let tail = format!("-v{VERSION}");
    let len = 16 + tail.len();
    let found = (len + 1..=bytes.len()).find(|&end| {
        let start = end - len - 1;
        bytes[start] as usize == len
            && bytes[start + 1..start + 17]
                .iter()
                .all(|b| b.is_ascii_hexdigit())
            && bytes[start + 17..end] == *tail.as_bytes()
    });
    let end = found.unwrap_or_else(|| panic!("state.bin: no fingerprint ending in {tail}"));
    bytes.splice(end - len - 1..end, *b"<fingerprint>");
    bytes
}
