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

/// [`erosion`] with the fixture's state loaded.
fn erosion_with_fixture_state() -> fluidtex::methods::erosion::Erosion {
    let mut m = erosion();
    fluidtex::pipeline::load_state_bytes(
        Path::new("state.bin"),
        &read(&["fuzz/state.bin"])[0],
        &mut m,
    )
    .unwrap();
    m
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
    let m = erosion_with_fixture_state();
    let inner = m.save_state().unwrap();
    let method = std::cell::RefCell::new(m);
    fuzz("method-state", CI_STATE_CASES, vec![inner], |b| {
        one_line(method.borrow_mut().load_state(b).map_err(|e| e.to_string()))
    });
}

/// A state file with a valid checksum can still be crafted: every index
/// and count of the method states is checked on load, and a bad one is
/// one line naming the patch (or tracker) and the element, never a panic
/// in a later frame.
#[test]
fn crafted_method_states_are_refused_in_one_line() {
    use fluidtex::methods::Method;
    use fluidtex::methods::erosion::ErosionState;
    let good: ErosionState = erosion_with_fixture_state().state().clone();
    assert!(good.patches.len() > 3, "the fixture has patches");
    let load = |state: &ErosionState| -> Result<(), String> {
        let bytes = postcard::to_allocvec(state).unwrap();
        erosion().load_state(&bytes).map_err(|e| e.to_string())
    };
    // Known good: the state as saved.
    load(&good).unwrap();
    type Craft = fn(&mut ErosionState);
    let cases: &[(Craft, &str)] = &[
        (|s| s.patches[1].triangles[0][2] = 1_000_000, "patch 1 (id "),
        (
            |s| s.patches[2].rest.pop().map(drop).unwrap_or(()),
            "rest coordinates",
        ),
        (
            |s| s.patches[0].positions[0].x = f32::NAN,
            "vertex 0 is not finite",
        ),
        (
            |s| s.patches[3].weight[0] = 7.0,
            "weight 0 is outside [0, 1]",
        ),
        (|s| s.patches[3].weight.truncate(2), "weights"),
        (|s| s.patches.swap(0, 1), "out of order"),
        (|s| s.next_id = 1, "not below the next id 1"),
        (
            |s| s.radius = Some(-1.0),
            "radius -1 is not a positive number",
        ),
        (
            |s| s.exemplar_size = Some(f32::INFINITY),
            "exemplar size inf",
        ),
    ];
    for (k, (craft, want)) in cases.iter().enumerate() {
        let mut state = good.clone();
        craft(&mut state);
        let err = load(&state).expect_err("crafted");
        assert!(err.contains(want), "case {k}: {err}");
        assert!(!err.contains('\n'), "case {k}: {err}");
    }
    // Seeded random vertex indices: refused exactly when out of range.
    let mut rng = <rand_pcg::Pcg64 as rand::SeedableRng>::seed_from_u64(SEED);
    for case in 0..300 {
        let mut state = good.clone();
        let p = rand::Rng::random_range(&mut rng, 0..state.patches.len());
        let n = state.patches[p].positions.len() as u32;
        let t = rand::Rng::random_range(&mut rng, 0..state.patches[p].triangles.len());
        let v: u32 = if case % 2 == 0 {
            rand::Rng::random_range(&mut rng, 0..2 * n)
        } else {
            rand::Rng::random(&mut rng)
        };
        state.patches[p].triangles[t][case % 3] = v;
        assert_eq!(
            load(&state).is_ok(),
            v < n,
            "case {case}: vertex {v} of {n}"
        );
    }
}

/// The 2016 and 2007 methods' states, crafted the same way.
#[test]
fn crafted_lapped_rigid_and_optimization_states_are_refused() {
    use fluidtex::methods::Method;
    use fluidtex::methods::lapped_rigid::{LappedRigid, LappedRigidState};
    use fluidtex::methods::optimization::{Optimization, OptimizationState};
    let pebbles = std::sync::Arc::new(fluidtex::exemplar::builtin_pebbles(64, 0));
    let tracker = |id: u32| fluidtex::methods::lapped_rigid::trackers::Tracker {
        id,
        position: glam::Vec3::ZERO,
        tangent_tracker: glam::Vec3::X,
        normal: glam::Vec3::Z,
        fade: 1.0,
        sinking: false,
        exemplar: 0,
    };
    let rigid = |state: &LappedRigidState| {
        let mut m = LappedRigid::new(Default::default(), pebbles.clone(), 0).unwrap();
        m.load_state(&postcard::to_allocvec(state).unwrap())
            .map_err(|e| e.to_string())
    };
    let good = LappedRigidState {
        trackers: vec![tracker(0), tracker(3)],
        next_id: 4,
        radius: Some(0.1),
        exemplar_size: Some(0.26),
    };
    rigid(&good).unwrap();
    let mut bad = good.clone();
    bad.trackers[1].id = 0;
    assert!(rigid(&bad).unwrap_err().contains("tracker 1 has id 0"));
    let mut bad = good.clone();
    bad.trackers[0].position.y = f32::NAN;
    assert!(rigid(&bad).unwrap_err().contains("tracker 0 (id 0)"));
    let mut bad = good.clone();
    bad.trackers[1].fade = -0.5;
    assert!(rigid(&bad).is_err());

    let optimization = |state: &OptimizationState| {
        let mut m = Optimization::new(Default::default(), pebbles.clone(), 0).unwrap();
        m.load_state(&postcard::to_allocvec(state).unwrap())
            .map_err(|e| e.to_string())
    };
    let good = OptimizationState {
        spacing: Some(0.01),
        exemplar_texels: Some(128),
        m: 4,
        values: vec![0.5; 6],
        orientation: vec![[1.0, 0.0, 0.0]; 2],
    };
    optimization(&good).unwrap();
    for (m, ok) in [
        (0, true),
        (1, true),
        (128, true),
        (3, false),
        (256, false),
        (u32::MAX, false),
    ] {
        let state = OptimizationState { m, ..good.clone() };
        assert_eq!(optimization(&state).is_ok(), ok, "m = {m}");
    }
    let state = OptimizationState {
        exemplar_texels: Some(1 << 30),
        ..good.clone()
    };
    assert!(optimization(&state).unwrap_err().contains("exemplar width"));
    let state = OptimizationState {
        values: vec![f32::NAN],
        ..good
    };
    assert!(optimization(&state).unwrap_err().contains("point value 0"));
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
        max_memory: None,
        phase: Default::default(),
        hooks: Default::default(),
    };
    fluidtex::pipeline::run(&job, &mut source, &mut erosion(), &mut |_| {}).unwrap();
    std::fs::copy(out.path().join("state.bin"), dir.join("state.bin")).unwrap();
}
