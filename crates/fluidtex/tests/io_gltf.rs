//! The .glb writer, checked two ways: parsed back with the `gltf` crate
//! (values compared exactly), and run through the Khronos glTF validator.
//!
//! The validator is a Node package. Install it with
//! `npm install --prefix .tools gltf-validator@2.0.0-dev.3.10` at the
//! workspace root (or point `FLUIDTEX_GLTF_VALIDATOR` at the package
//! folder). Without it the validator test prints a note and passes, unless
//! `FLUIDTEX_REQUIRE_TOOLS=1`, in which case it fails.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

use fluidtex::io::gltf::write_glb;
use fluidtex::io::image::{PngOptions, encode_png};
use fluidtex::texture::Texture;
use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

struct TestMesh {
    positions: Vec<Vec3>,
    uvs: Vec<Vec2>,
    normals: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

/// A wavy grid with a texture atlas layout (uv = grid position).
fn wavy_grid(n: u32, seed: u64) -> TestMesh {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut m = TestMesh {
        positions: vec![],
        uvs: vec![],
        normals: vec![],
        triangles: vec![],
    };
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            m.positions.push(Vec3::new(
                u * 2.0 - 1.0,
                rng.random_range(-0.1..0.1),
                v * 2.0 - 1.0,
            ));
            m.uvs.push(Vec2::new(u, v));
            m.normals
                .push(Vec3::new(rng.random_range(-0.2..0.2), 1.0, 0.0).normalize());
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            m.triangles.push([a, a + n + 1, a + 1]);
            m.triangles.push([a + 1, a + n + 1, a + n + 2]);
        }
    }
    m
}

fn atlas_png() -> Vec<u8> {
    let data = (0..64 * 32 * 3).map(|i| (i % 251) as f32 / 250.0).collect();
    encode_png(
        &Texture::from_data(64, 32, 3, data).unwrap(),
        &PngOptions::default(),
    )
    .unwrap()
}

#[test]
fn glb_parses_back_with_the_gltf_crate() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("frame.0001.glb");
    let m = wavy_grid(9, 3);
    let png = atlas_png();
    write_glb(
        &path,
        &m.positions,
        &m.uvs,
        Some(&m.normals),
        &m.triangles,
        Some(&png),
    )
    .unwrap();

    let (doc, buffers, images) = gltf::import(&path).unwrap();
    let mesh = doc.meshes().next().unwrap();
    let prim = mesh.primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    let positions: Vec<Vec3> = reader.read_positions().unwrap().map(Vec3::from).collect();
    let normals: Vec<Vec3> = reader.read_normals().unwrap().map(Vec3::from).collect();
    let uvs: Vec<Vec2> = reader
        .read_tex_coords(0)
        .unwrap()
        .into_f32()
        .map(Vec2::from)
        .collect();
    let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
    assert_eq!(positions, m.positions);
    assert_eq!(normals, m.normals);
    assert_eq!(
        uvs, m.uvs,
        "glTF uv has v = 0 at the top, like ours: unchanged"
    );
    assert_eq!(
        indices,
        m.triangles.iter().flatten().copied().collect::<Vec<_>>()
    );
    let bounds = prim.bounding_box();
    let (lo, hi) = m
        .positions
        .iter()
        .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    assert_eq!((Vec3::from(bounds.min), Vec3::from(bounds.max)), (lo, hi));

    let material = prim.material();
    let tex = material
        .pbr_metallic_roughness()
        .base_color_texture()
        .unwrap()
        .texture();
    let sampler = tex.sampler();
    assert_eq!(sampler.mag_filter(), Some(gltf::texture::MagFilter::Linear));
    assert_eq!(sampler.min_filter(), Some(gltf::texture::MinFilter::Linear));
    assert_eq!(sampler.wrap_s(), gltf::texture::WrappingMode::ClampToEdge);
    assert_eq!(sampler.wrap_t(), gltf::texture::WrappingMode::ClampToEdge);
    assert_eq!((images[0].width, images[0].height), (64, 32));
    let expect: Vec<u8> = (0..64 * 32 * 3)
        .map(|i| ((i % 251) as f32 / 250.0 * 255.0).round() as u8)
        .collect();
    assert_eq!(images[0].pixels, expect);
}

fn validator() -> Option<(PathBuf, PathBuf)> {
    let dir = match std::env::var_os("FLUIDTEX_GLTF_VALIDATOR") {
        Some(d) => PathBuf::from(d),
        None => {
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.tools/node_modules/gltf-validator")
        }
    };
    let node_ok = Command::new("node")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/gltf_validate.js");
    (node_ok && dir.join("package.json").is_file()).then(|| (dir.canonicalize().unwrap(), script))
}

fn validate(file: &Path) -> serde_json::Value {
    let (dir, script) = validator().unwrap();
    let out = Command::new("node")
        .arg(script)
        .arg(dir)
        .arg(file)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "validator failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn glb_passes_the_khronos_validator() {
    if validator().is_none() {
        let msg = "Khronos glTF validator not found: run `npm install --prefix .tools gltf-validator@2.0.0-dev.3.10` \
                   at the workspace root, or set FLUIDTEX_GLTF_VALIDATOR";
        if std::env::var("FLUIDTEX_REQUIRE_TOOLS").as_deref() == Ok("1") {
            panic!("{msg} (FLUIDTEX_REQUIRE_TOOLS=1)");
        }
        eprintln!("note: skipping: {msg}");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let m = wavy_grid(12, 5);
    let png = atlas_png();
    let cases = [
        ("full.glb", true, true),
        ("no_normals.glb", false, true),
        ("untextured.glb", false, false),
    ];
    for (name, with_normals, with_png) in cases {
        let normals = with_normals.then_some(m.normals.as_slice());
        let png = with_png.then_some(png.as_slice());
        let path = dir.path().join(name);
        write_glb(&path, &m.positions, &m.uvs, normals, &m.triangles, png).unwrap();
        let report = validate(&path);
        assert_eq!(report["errors"], 0, "{name}: {report}");
        assert_eq!(report["warnings"], 0, "{name}: {report}");
    }
    // A vanished fluid: empty scene, still valid.
    let path = dir.path().join("empty.glb");
    write_glb(&path, &[], &[], None, &[], Some(&png)).unwrap();
    let report = validate(&path);
    assert_eq!(report["errors"], 0, "empty: {report}");
    // Known-bad control: the validator must catch a corrupted accessor.
    let path = dir.path().join("bad.glb");
    write_glb(&path, &m.positions, &m.uvs, None, &m.triangles, None).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    let at = bytes.windows(4).position(|w| w == b"VEC3").unwrap();
    bytes[at + 3] = b'4'; // same length, so the container stays intact
    std::fs::write(&path, &bytes).unwrap();
    let report = validate(&path);
    assert!(report["errors"].as_u64().unwrap() > 0, "{report}");
}
