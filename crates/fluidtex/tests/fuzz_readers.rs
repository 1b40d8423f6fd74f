//! Seeded mutation fuzzing of every reader over committed fixtures
//! ([`fluidtex::fuzz`]): PLY ASCII and binary, OBJ, VTK (ASCII and binary),
//! exemplar images (PNG 8/16-bit, EXR half/float) and `state.bin`. The TOML
//! config is fuzzed in the CLI crate (`cli_fuzz_config`).
//!
//! Fails on any panic, any case slower than 2 s, a hang (the watchdog ends
//! the binary after 30 s) and any allocation that would take the binary
//! past [`ALLOC_CAP`] live bytes (the capped global allocator refuses it
//! and the process aborts with "memory allocation of N bytes failed").
//!
//! Case counts: [`CI_CASES`] per mesh and image reader and
//! [`CI_STATE_CASES`] per state reader (a state case decodes 90 KB): the
//! whole file takes about 10 s of CPU (measured: 20000 cases of every
//! reader took 38 s on one core of the 2-core machine). For a longer
//! developer run:
//! `FLUIDTEX_FUZZ_CASES=200000 cargo test --release -p fluidtex --test fuzz_readers`;
//! `FLUIDTEX_FUZZ_SEED=N` changes the seed; `FLUIDTEX_FUZZ_CASE=K` replays
//! one case of every reader.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use fluidtex::fuzz::{Failure, Fuzz, SEED};
use fluidtex::io::ReadOptions;

#[global_allocator]
static ALLOCATOR: cap::Cap<std::alloc::System> = cap::Cap::new(std::alloc::System, usize::MAX);

/// Live bytes the whole binary may hold: readers run on inputs under
/// 20 KB, so anything near this is an allocation the data did not prove.
const ALLOC_CAP: usize = 1 << 30;

/// Cases per mesh or image reader in CI.
const CI_CASES: u64 = 10_000;
/// Cases per state reader in CI.
const CI_STATE_CASES: u64 = 3_000;

fn cap_allocations() {
    // Other tests of this binary may already hold memory; cap from there.
    let _ = ALLOCATOR.set_limit(ALLOCATOR.allocated() + ALLOC_CAP);
}

fn cases(ci: u64) -> u64 {
    std::env::var("FLUIDTEX_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(ci)
}

fn seed() -> u64 {
    std::env::var("FLUIDTEX_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(SEED)
}

fn data(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(path)
}

fn read(paths: &[&str]) -> Vec<Vec<u8>> {
    paths
        .iter()
        .map(|p| std::fs::read(data(p)).unwrap())
        .collect()
}

/// Runs `read` over the cases and fails with every failure listed.
fn fuzz<T>(reader: &str, ci_cases: u64, fixtures: Vec<Vec<u8>>, read: impl Fn(&[u8]) -> T) {
    cap_allocations();
    let f = Fuzz::new(reader, seed(), fixtures);
    if let Some(case) = std::env::var("FLUIDTEX_FUZZ_CASE")
        .ok()
        .and_then(|v| v.parse().ok())
    {
        f.replay(case, read);
        return;
    }
    let n = cases(ci_cases);
    let start = std::time::Instant::now();
    let failures: Vec<Failure> = f.run(n, read);
    eprintln!(
        "fuzz {reader}: {n} cases, seed {:#x}, {:.1} s, {} failures",
        f.seed,
        start.elapsed().as_secs_f64(),
        failures.len()
    );
    let list: Vec<String> = failures.iter().take(20).map(|x| x.to_string()).collect();
    assert!(failures.is_empty(), "{}", list.join("\n"));
}

/// A reader's result on a mesh, then the validation `read_mesh` runs.
fn validated(parsed: Result<fluidtex::mesh::TriMesh, fluidtex::io::IoError>) -> Result<(), String> {
    let mut mesh = parsed.map_err(|e| e.to_string())?;
    fluidtex::mesh::validate(&mut mesh).map_err(|e| e.to_string())?;
    Ok(())
}

/// An error must be one line.
fn one_line(r: Result<(), String>) {
    if let Err(e) = r {
        assert!(!e.contains('\n'), "two-line error: {e}");
    }
}

#[test]
fn fuzz_ply_ascii() {
    let fixtures = read(&[
        "interop/meshio_ascii.0001.ply",
        "interop/houdini_style.ply",
        "interop/meshio_quads.ply",
    ]);
    let opts = ReadOptions::default();
    fuzz("ply-ascii", CI_CASES, fixtures, |b| {
        one_line(validated(fluidtex::io::ply::parse_ply(
            Path::new("f.ply"),
            b,
            &opts,
        )))
    });
}

#[test]
fn fuzz_ply_binary() {
    let fixtures = read(&["interop/trimesh_binary.0001.ply", "fuzz/big_endian.ply"]);
    let opts = ReadOptions::default();
    fuzz("ply-binary", CI_CASES, fixtures, |b| {
        one_line(validated(fluidtex::io::ply::parse_ply(
            Path::new("f.ply"),
            b,
            &opts,
        )))
    });
}

#[test]
fn fuzz_obj() {
    let fixtures = read(&["interop/trimesh.obj", "fuzz/polygons.obj"]);
    fuzz("obj", CI_CASES, fixtures, |b| {
        one_line(validated(fluidtex::io::obj::parse_obj(
            Path::new("f.obj"),
            b,
        )))
    });
}

#[test]
fn fuzz_vtk() {
    let fixtures = read(&[
        "interop/meshio_ascii_51.vtk",
        "interop/meshio_binary_42.vtk",
    ]);
    let opts = ReadOptions::default();
    fuzz("vtk", CI_CASES, fixtures, |b| {
        one_line(validated(fluidtex::io::vtk::parse_vtk(
            Path::new("f.vtk"),
            b,
            &opts,
        )))
    });
}

#[test]
fn fuzz_exemplar_images() {
    let fixtures = read(&[
        "fuzz/rgb8.png",
        "fuzz/grey16.png",
        "fuzz/rgba_half.exr",
        "fuzz/y_float.exr",
    ]);
    fuzz("image", CI_CASES, fixtures, |b| {
        one_line(
            fluidtex::io::image_read::decode_image(b, "f.png")
                .map(|_| ())
                .map_err(|e| e.to_string()),
        )
    });
}

/// The erosion method `state.bin` fixture was written for.
fn erosion() -> fluidtex::methods::erosion::Erosion {
    fluidtex::methods::erosion::Erosion::new(
        Default::default(),
        std::sync::Arc::new(fluidtex::exemplar::builtin_pebbles(64, 0)),
        0,
    )
    .unwrap()
}

#[test]
fn fuzz_state_file() {
    let fixtures = read(&["fuzz/state.bin"]);
    let method = std::cell::RefCell::new(erosion());
    // Known good: the fixture loads.
    let last = fluidtex::pipeline::load_state_bytes(
        Path::new("state.bin"),
        &fixtures[0],
        &mut *method.borrow_mut(),
    )
    .unwrap();
    assert_eq!(last, 2);
    // Known bad: an older version is named as such, not as damage; a
    // flipped bit in the method state fails the checksum.
    let load = |b: &[u8]| {
        fluidtex::pipeline::load_state_bytes(Path::new("state.bin"), b, &mut *method.borrow_mut())
            .unwrap_err()
            .to_string()
    };
    let mut old = fixtures[0].clone();
    assert_eq!(old[0], 2, "postcard writes version 2 as one byte");
    old[0] = 1;
    assert_eq!(
        load(&old),
        "cannot resume: state.bin: state version 1 is not 2"
    );
    let mut flipped = fixtures[0].clone();
    let mid = flipped.len() / 2;
    flipped[mid] ^= 4;
    assert_eq!(
        load(&flipped),
        "cannot resume: state.bin: damaged state file (checksum mismatch)"
    );
    fuzz("state.bin", CI_STATE_CASES, fixtures, |b| {
        one_line(
            fluidtex::pipeline::load_state_bytes(
                Path::new("state.bin"),
                b,
                &mut *method.borrow_mut(),
            )
            .map(|_| ())
            .map_err(|e| e.to_string()),
        )
    });
}

/// The method's own state decoder, under the file's checksum: damage that
/// the checksum would catch is fed to it directly.
#[test]
fn fuzz_method_state() {
    use fluidtex::methods::Method;
    let mut m = erosion();
    fluidtex::pipeline::load_state_bytes(
        Path::new("state.bin"),
        &read(&["fuzz/state.bin"])[0],
        &mut m,
    )
    .unwrap();
    let inner = m.save_state().unwrap();
    let method = std::cell::RefCell::new(m);
    fuzz("method-state", CI_STATE_CASES, vec![inner], |b| {
        one_line(method.borrow_mut().load_state(b).map_err(|e| e.to_string()))
    });
}

/// How the fixtures under `tests/data/fuzz/` were made; rerun with
/// `cargo test -p fluidtex --test fuzz_readers -- --ignored` after a change
/// of a format (e.g. a new `state.bin` version), then commit them.
#[test]
#[ignore]
fn regenerate_fuzz_fixtures() {
    use fluidtex::io::image::{ExrOptions, ExrSample, PngDepth, PngOptions};
    use fluidtex::texture::Texture;
    let dir = data("fuzz");
    std::fs::create_dir_all(&dir).unwrap();
    let tex = |c: usize| {
        let data = (0..8 * 8 * c).map(|i| (i % 13) as f32 / 12.0).collect();
        Texture::from_data(8, 8, c, data).unwrap()
    };
    let png = |depth| PngOptions {
        depth,
        ..Default::default()
    };
    fluidtex::io::image::write_png(&dir.join("rgb8.png"), &tex(3), &png(PngDepth::Eight)).unwrap();
    fluidtex::io::image::write_png(&dir.join("grey16.png"), &tex(1), &png(PngDepth::Sixteen))
        .unwrap();
    let exr = |sample| ExrOptions {
        sample,
        ..Default::default()
    };
    fluidtex::io::image::write_exr(&dir.join("rgba_half.exr"), &tex(4), &exr(ExrSample::F16))
        .unwrap();
    fluidtex::io::image::write_exr(&dir.join("y_float.exr"), &tex(1), &exr(ExrSample::F32))
        .unwrap();
    // A binary big-endian PLY with a quad, short velocity and an extra element.
    let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty double x\n\
        property float y\nproperty float z\nproperty short vx\nproperty short vy\nproperty short vz\n\
        element face 2\nproperty list uchar uint vertex_indices\nelement extra 1\nproperty int a\nend_header\n"
        .to_vec();
    for k in 0..4u8 {
        b.extend_from_slice(&f64::from(k % 2).to_be_bytes());
        b.extend_from_slice(&f32::from(k / 2).to_be_bytes());
        b.extend_from_slice(&[0, 0, 0, 0, 0, 1, 0, 2, 0, 3]);
    }
    b.push(4);
    for i in [0u32, 1, 3, 2] {
        b.extend_from_slice(&i.to_be_bytes());
    }
    b.push(3);
    for i in [0u32, 1, 2] {
        b.extend_from_slice(&i.to_be_bytes());
    }
    b.extend_from_slice(&7i32.to_be_bytes());
    std::fs::write(dir.join("big_endian.ply"), b).unwrap();
    std::fs::write(
        dir.join("polygons.obj"),
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1\nvt 0 0\nvn 0 0 1\n\
         o a\nf 1/1/1 2/1/1 3/1/1 4/1/1\ng b\nf -5 -4 -1\nf 2 3 5\n",
    )
    .unwrap();
    // state.bin: frames 0-2 of a small rigid rotation with the erosion
    // method and the 64² built-in pebbles, as `erosion()` above.
    let scene = fluidtex::scenes::by_name(
        "rigid-rotation",
        Some(fluidtex::scenes::SceneParams {
            resolution: 10,
            fps: 24.0,
            first: 0,
            last: 2,
            seed: 0,
        }),
    )
    .unwrap();
    let mut source = fluidtex::pipeline::SceneSource::new(scene);
    let out = tempfile::tempdir().unwrap();
    let job = fluidtex::pipeline::Job {
        out_dir: out.path().to_path_buf(),
        atlas: fluidtex::atlas::AtlasParams::square(64),
        fps: 24.0,
        outputs: Default::default(),
        resume: false,
        fingerprint: "fuzz".into(),
        hooks: Default::default(),
    };
    fluidtex::pipeline::run(&job, &mut source, &mut erosion(), &mut |_| {}).unwrap();
    std::fs::copy(out.path().join("state.bin"), dir.join("state.bin")).unwrap();
}
