//! The command line used as a user would: `info` on third-party sequences,
//! `run` with both methods, `scene` → `run`, `demo`, determinism across
//! thread counts, and resuming after a real SIGKILL.
//!
//! Inputs are the interop meshes of the library's test data (written by
//! meshio and trimesh, see `crates/fluidtex/tests/data/interop/README.md`)
//! and small generated scenes; atlases are 128² so the file runs in seconds.

#![allow(clippy::unwrap_used)]

mod common;

use std::collections::BTreeSet;
use std::path::Path;

use common::*;

const FRAMES: [i32; 3] = [1, 2, 3];

/// Bounding box of interop frame `f`, as `make_interop.py --print` gave it
/// (README of the interop data): the sphere falls 1/16 per frame.
fn known_bbox(f: i32) -> ([f32; 3], [f32; 3]) {
    let dz = 0.0625 * (f - 1) as f32;
    ([-0.25, -0.625, 0.4375 - dz], [0.75, 0.375, 1.4375 - dz])
}

/// The `bounding box` column of `fluidtex info`.
fn bbox_text((lo, hi): ([f32; 3], [f32; 3])) -> String {
    format!(
        "({:.3},{:.3},{:.3})-({:.3},{:.3},{:.3})",
        lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    )
}

/// Min and max speed of a frame, from our own parse of the ASCII file.
fn speed_text(ply: &AsciiPly) -> String {
    let speeds: Vec<f64> = ply
        .velocities
        .iter()
        .map(|v| v.iter().map(|&c| f64::from(c).powi(2)).sum::<f64>().sqrt())
        .collect();
    let lo = speeds.iter().copied().fold(f64::MAX, f64::min);
    let hi = speeds.iter().copied().fold(0.0, f64::max);
    format!("{lo:.4}..{hi:.4}")
}

/// The rows of `fluidtex info` output, split into columns.
fn info_rows(stdout: &str) -> Vec<Vec<String>> {
    stdout
        .lines()
        .skip(2)
        .map(|l| l.split_whitespace().map(str::to_string).collect())
        .collect()
}

#[test]
fn info_prints_the_known_counts_bounds_and_speeds_of_the_interop_sequences() {
    for stem in ["meshio_ascii", "trimesh_binary"] {
        let pattern = interop(&format!("{stem}.####.ply"));
        let stdout = ok(&[Path::new("info"), &pattern]);
        assert_eq!(
            stdout.lines().next().unwrap(),
            format!("sequence {}: 3 frames (1-3)", pattern.display())
        );
        let rows = info_rows(&stdout);
        assert_eq!(rows.len(), 3, "{stdout}");
        for (row, f) in rows.iter().zip(FRAMES) {
            // Expected values come from the ASCII file parsed here, and from
            // the README: the binary file holds the same numbers.
            let ply = read_meshio_ascii(&interop(&format!("meshio_ascii.000{f}.ply")));
            let lo = ply.positions.iter().fold([f32::MAX; 3], |a, p| {
                [a[0].min(p[0]), a[1].min(p[1]), a[2].min(p[2])]
            });
            let hi = ply.positions.iter().fold([f32::MIN; 3], |a, p| {
                [a[0].max(p[0]), a[1].max(p[1]), a[2].max(p[2])]
            });
            assert_eq!((lo, hi), known_bbox(f), "our parse agrees with the README");
            let expect = [
                f.to_string(),
                "162".into(),
                "320".into(),
                "0".into(),
                bbox_text(known_bbox(f)),
                speed_text(&ply),
                "velocity:vec3".into(),
            ];
            assert_eq!(row, &expect, "{stem} frame {f}:\n{stdout}");
        }
        // Control: a range selects frames.
        let stdout = ok(&[
            Path::new("info"),
            &pattern,
            Path::new("--frames"),
            Path::new("2"),
        ]);
        assert_eq!(info_rows(&stdout).len(), 1);
        assert_eq!(info_rows(&stdout)[0][0], "2");
    }
    let speed1 = speed_text(&read_meshio_ascii(&interop("meshio_ascii.0001.ply")));
    assert_eq!(speed1, "0.2500..0.3538", "known frame-1 speeds");
}

#[test]
fn info_on_the_trimesh_obj_named_as_a_sequence() {
    let dir = tempfile::tempdir().unwrap();
    copy_interop(dir.path(), &[("trimesh.obj", "trimesh.0002.obj")]);
    let stdout = ok(&[Path::new("info"), &dir.path().join("trimesh.####.obj")]);
    let rows = info_rows(&stdout);
    assert_eq!(
        rows,
        [[
            "2",
            "162",
            "320",
            "0",
            &bbox_text(known_bbox(2)),
            "no",
            "velocity"
        ]
        .map(String::from)
        .to_vec()]
    );
}

/// Bug: a single mesh file (no frame token) is refused by `info`:
/// `error: invalid frame pattern ".../trimesh.obj": no frame token`.
#[test]
fn info_on_a_single_file_without_a_frame_token() {
    let stdout = ok(&[Path::new("info"), &interop("trimesh.obj")]);
    let rows = info_rows(&stdout);
    assert_eq!(rows.len(), 1, "{stdout}");
    assert_eq!(
        &rows[0][1..5],
        ["162", "320", "0", &bbox_text(known_bbox(2))]
    );
}

/// The outputs of one frame of `run`, checked file by file.
fn check_frame_outputs(
    out: &Path,
    f: i32,
    method: &str,
    atlas: u32,
    input: &AsciiPly,
    validator: Option<&(std::path::PathBuf, std::path::PathBuf)>,
) -> serde_json::Value {
    let tag = format!("{f:04}");
    for name in [
        "color.F.png",
        "mesh.F.obj",
        "mesh.F.mtl",
        "mesh.F.glb",
        "stats.F.json",
        "patches.F.png",
        "source.F.exr",
    ] {
        let name = name.replace('F', &tag);
        assert!(out.join(&name).is_file(), "{name} missing");
    }
    for name in ["color", "patches"] {
        let t = image(&out.join(format!("{name}.{tag}.png")));
        assert_eq!((t.width, t.height), (atlas, atlas), "{name}.{tag}.png");
    }
    let ids = image(&out.join(format!("source.{tag}.exr")));
    assert_eq!((ids.width, ids.height, ids.channels), (atlas, atlas, 1));

    // OBJ: the input's vertices (seam vertices repeated), one uv and one
    // normal per vertex, the input's triangle count, and a material whose
    // map_Kd is this frame's colour atlas.
    let obj = std::fs::read_to_string(out.join(format!("mesh.{tag}.obj"))).unwrap();
    let lines = |p: &'static str| obj.lines().filter(move |l| l.starts_with(p));
    let v: Vec<[f32; 3]> = lines("v ")
        .map(|l| {
            let n: Vec<f32> = l[2..]
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            [n[0], n[1], n[2]]
        })
        .collect();
    let vt: Vec<Vec<f32>> = lines("vt ")
        .map(|l| {
            l[3..]
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect()
        })
        .collect();
    assert_eq!(vt.len(), v.len(), "mesh.{tag}.obj: vt count");
    assert_eq!(lines("vn ").count(), v.len(), "mesh.{tag}.obj: vn count");
    assert!(
        vt.iter()
            .all(|uv| uv.len() == 2 && uv.iter().all(|c| (0.0..=1.0).contains(c))),
        "uvs in [0,1]"
    );
    assert!(v.len() >= input.positions.len());
    for p in &v {
        // Written with 8 significant digits: compare within that.
        assert!(
            input
                .positions
                .iter()
                .any(|q| (0..3).all(|k| (p[k] - q[k]).abs() <= 1e-7 * q[k].abs().max(1.0))),
            "mesh.{tag}.obj: vertex {p:?} is not an input vertex"
        );
    }
    let faces: Vec<&str> = lines("f ").collect();
    assert_eq!(faces.len(), input.faces, "mesh.{tag}.obj: triangle count");
    for face in &faces {
        let corners: Vec<&str> = face[2..].split_whitespace().collect();
        assert_eq!(corners.len(), 3, "{face}");
        for c in corners {
            let k: Vec<usize> = c.split('/').map(|x| x.parse().unwrap()).collect();
            assert_eq!(k.len(), 3, "{face}: v/vt/vn");
            assert!(k.iter().all(|&i| (1..=v.len()).contains(&i)), "{face}");
        }
    }
    let mtllib: Vec<&str> = lines("mtllib ").collect();
    assert_eq!(mtllib, [format!("mtllib mesh.{tag}.mtl")]);
    let mtl = std::fs::read_to_string(out.join(format!("mesh.{tag}.mtl"))).unwrap();
    let map_kd: Vec<&str> = mtl.lines().filter(|l| l.starts_with("map_Kd ")).collect();
    assert_eq!(map_kd, [format!("map_Kd color.{tag}.png")]);
    assert_eq!(
        lines("usemtl ").count(),
        1,
        "mesh.{tag}.obj uses its material"
    );

    // glb: a glTF 2 container whose length field is the file size, valid
    // to the Khronos validator.
    let glb_path = out.join(format!("mesh.{tag}.glb"));
    let glb = std::fs::read(&glb_path).unwrap();
    assert_eq!(&glb[0..4], b"glTF");
    assert_eq!(u32::from_le_bytes(glb[4..8].try_into().unwrap()), 2);
    assert_eq!(
        u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize,
        glb.len()
    );
    if let Some(v) = validator {
        let report = validate_glb(v, &glb_path);
        assert_eq!(report["errors"], 0, "mesh.{tag}.glb: {report}");
        assert_eq!(report["warnings"], 0, "mesh.{tag}.glb: {report}");
    }

    // stats: the documented keys (FrameStats) with this frame's values.
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join(format!("stats.{tag}.json"))).unwrap())
            .unwrap();
    assert_eq!(stats["frame"], f);
    assert_eq!(stats["method"], method);
    assert_eq!(stats["vertices"], input.positions.len());
    assert_eq!(stats["triangles"], input.faces);
    assert_eq!(stats["dropped_degenerate"], 0);
    assert_eq!(stats["atlas_width"], atlas);
    assert_eq!(stats["atlas_height"], atlas);
    assert!(stats["charts"].as_u64().unwrap() >= 1);
    let stages: Vec<&str> = stats["stage_order"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap())
        .collect();
    assert_eq!(stages.first(), Some(&"read"));
    // With debug outputs, the coherence measurement and then the debug
    // views follow the write.
    let tail: Vec<&str> = stages
        .iter()
        .copied()
        .skip_while(|s| *s != "write")
        .collect();
    assert!(
        matches!(tail.as_slice(), ["write"] | ["write", "coherence", "debug"]),
        "stages after the write: {tail:?}"
    );
    let timed: BTreeSet<&str> = stats["seconds"]
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    assert_eq!(timed, stages.iter().copied().collect::<BTreeSet<_>>());
    assert!(
        stats["seconds"]
            .as_object()
            .unwrap()
            .values()
            .all(|s| s.as_f64().unwrap() >= 0.0)
    );
    stats
}

#[test]
fn atlas_check_writes_every_output_of_the_interop_sequences() {
    let validator = gltf_validator();
    let dir = tempfile::tempdir().unwrap();
    for stem in ["meshio_ascii", "trimesh_binary"] {
        let out = dir.path().join(stem);
        let pattern = interop(&format!("{stem}.####.ply"));
        let args = [
            "run".as_ref(),
            "--mesh".as_ref(),
            pattern.as_os_str(),
            "--method".as_ref(),
            "atlas-check".as_ref(),
            "--atlas".as_ref(),
            "128".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ];
        ok(&args);
        for f in FRAMES {
            let input = read_meshio_ascii(&interop(&format!("meshio_ascii.000{f}.ply")));
            let stats =
                check_frame_outputs(&out, f, "atlas-check", 128, &input, validator.as_ref());
            assert!(stats["cell"].as_f64().unwrap() > 0.0);
        }
        let mut names: Vec<String> = files(&out).into_keys().collect();
        names.sort();
        assert_eq!(
            names.len(),
            3 * 7 + 1,
            "7 files per frame and state.bin (no switch map unless asked): {names:?}"
        );
    }
    // Both files hold the same numbers, so the textures and meshes are the
    // same bytes; only state.bin (it records the input pattern) and the
    // timings differ.
    let a = files(&dir.path().join("meshio_ascii"));
    let b = files(&dir.path().join("trimesh_binary"));
    for (name, bytes) in &a {
        match name.as_str() {
            "state.bin" => {}
            n if n.starts_with("stats.") => {
                assert_eq!(stats_without_timings(bytes), stats_without_timings(&b[n]))
            }
            n => assert!(bytes == &b[n], "{n} differs between ASCII and binary input"),
        }
    }
}

#[test]
fn atlas_check_on_the_trimesh_obj() {
    let dir = tempfile::tempdir().unwrap();
    copy_interop(&dir.path().join("in"), &[("trimesh.obj", "frame.0002.obj")]);
    let out = dir.path().join("out");
    ok(&[
        "run".as_ref(),
        "--mesh".as_ref(),
        dir.path().join("in/frame.####.obj").as_os_str(),
        "--method".as_ref(),
        "atlas-check".as_ref(),
        "--atlas".as_ref(),
        "128".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    let input = read_meshio_ascii(&interop("meshio_ascii.0002.ply"));
    check_frame_outputs(
        &out,
        2,
        "atlas-check",
        128,
        &input,
        gltf_validator().as_ref(),
    );
}

/// `fluidtex scene NAME --out DIR` writes `DIR/fluid.####.ply`; `run` with
/// the default (erosion) method covers every chart texel in every frame.
#[test]
fn scene_then_run_with_erosion_covers_every_texel() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    ok(&[
        "scene".as_ref(),
        "rigid-rotation".as_ref(),
        "--resolution".as_ref(),
        "12".as_ref(),
        "--frames".as_ref(),
        "0-2".as_ref(),
        "--out".as_ref(),
        scene.as_os_str(),
        "--quiet".as_ref(),
    ]);
    let mut names: Vec<String> = files(&scene).into_keys().collect();
    names.sort();
    assert_eq!(
        names,
        [
            "fluid.0000.ply",
            "fluid.0001.ply",
            "fluid.0002.ply",
            "scene.json"
        ]
    );
    let info: serde_json::Value =
        serde_json::from_slice(&std::fs::read(scene.join("scene.json")).unwrap()).unwrap();
    assert_eq!(
        (&info["name"], &info["first"], &info["last"]),
        (&"rigid-rotation".into(), &0.into(), &2.into())
    );
    let pattern = scene.join("fluid.####.ply");
    let listing = ok(&[Path::new("info"), &pattern]);
    assert!(listing.starts_with(&format!("sequence {}: 3 frames (0-2)", pattern.display())));

    let out = dir.path().join("out");
    ok(&[
        "run".as_ref(),
        "--mesh".as_ref(),
        pattern.as_os_str(),
        "--atlas".as_ref(),
        "128".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
        "--switch-map".as_ref(),
    ]);
    for (row, f) in info_rows(&listing).iter().zip(0..=2) {
        let tag = format!("{f:04}");
        let stats: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join(format!("stats.{tag}.json"))).unwrap())
                .unwrap();
        assert_eq!(stats["method"], "erosion");
        assert_eq!(stats["uncovered_texels"], 0, "frame {f}");
        assert_eq!(stats["vertices"].to_string(), row[1]);
        assert_eq!(stats["triangles"].to_string(), row[2]);
        for key in [
            "patches_alive",
            "patches_created",
            "patches_deleted",
            "patches_deleted_unused",
            "patches_deleted_advection",
            "forced_texels",
            "radius",
            "exemplar_size",
        ] {
            assert!(stats[key].is_number(), "frame {f}: no {key}");
        }
        // The per-texel patch ids agree with the counts: every chart texel
        // has a patch (id + 1 >= 1), none is uncovered (0), the rest is
        // outside the charts (-1).
        let ids = image(&out.join(format!("source.{tag}.exr")));
        let covered = ids.data.iter().filter(|&&s| s >= 1.0).count();
        let uncovered = ids.data.iter().filter(|&&s| s == 0.0).count();
        let outside = ids.data.iter().filter(|&&s| s == -1.0).count();
        assert_eq!(covered as u64, stats["texels_in_charts"].as_u64().unwrap());
        assert_eq!(uncovered, 0);
        assert_eq!(covered + outside, 128 * 128);
        // The packer's fill is the chart texels' share of the atlas.
        assert_eq!(
            stats["atlas_fill"].as_f64().unwrap(),
            covered as f64 / (128.0 * 128.0),
            "frame {f}"
        );
        let alive = stats["patches_alive"].as_u64().unwrap();
        assert!(alive > 0);
        let distinct: BTreeSet<u32> = ids
            .data
            .iter()
            .filter(|&&s| s >= 1.0)
            .map(|&s| s as u32)
            .collect();
        assert!(
            distinct.len() as u64 <= alive,
            "frame {f}: ids of dead patches"
        );
        let color = image(&out.join(format!("color.{tag}.png")));
        assert_eq!((color.width, color.height), (128, 128));
        // Coherence with the frame before (none for the first frame): the
        // share is a share, and switch.F.png marks the same texels: the
        // ids of this frame's covered texels are red, amber or grey (or
        // dark blue where the point carried back found no patch), the rest
        // black.
        let switch = out.join(format!("switch.{tag}.png"));
        if f == 0 {
            assert!(stats.get("source_switch_share").is_none());
            assert!(!switch.exists());
            continue;
        }
        let share = stats["source_switch_share"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&share), "frame {f}: {share}");
        assert!(stats.get("colour_follow_ratio").is_some(), "frame {f}");
        // Every switch is forced by the flow or not, as the method says.
        let forced = stats["switch_forced_share"].as_f64().unwrap();
        let unforced = stats["switch_unforced_share"].as_f64().unwrap();
        assert!(
            (forced + unforced - share).abs() < 1e-9,
            "frame {f}: {forced} + {unforced} against {share}"
        );
        // Of the unforced, those whose earlier patch still shows the point.
        let shown = stats["switch_unforced_shown_share"].as_f64().unwrap();
        assert!(
            (0.0..=unforced).contains(&shown),
            "frame {f}: {shown} of {unforced}"
        );
        assert!(stats["holder_distorted_share"].as_f64().unwrap() <= 1.0);
        // The same points by region: all of this sphere's are bulk.
        let regions = &stats["switch_by_region"];
        for r in ["bulk", "sheet", "droplet"] {
            assert!(regions[r]["points"].is_u64(), "frame {f}: {r}");
        }
        assert!(regions["bulk"]["points"].as_u64().unwrap() > 0, "frame {f}");
        let map = image(&switch);
        assert_eq!((map.width, map.height), (128, 128));
        for (px, &id) in map.data.chunks_exact(3).zip(&ids.data) {
            let known = [
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 0.75, 0.0],
                [0.5, 0.5, 0.5],
                [0.1, 0.1, 0.35],
            ];
            let colour = known
                .iter()
                .position(|k| k.iter().zip(px).all(|(a, b)| (a - b).abs() < 0.01));
            match colour {
                Some(0) => assert_eq!(id, -1.0, "frame {f}: black on a chart texel"),
                Some(_) => assert!(id >= 1.0, "frame {f}: colour outside the charts"),
                None => panic!("frame {f}: unexpected colour {px:?}"),
            }
        }
    }
}

#[test]
fn demo_writes_previews_and_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    ok(&[
        "demo".as_ref(),
        "--frames".as_ref(),
        "0-3".as_ref(),
        "--atlas".as_ref(),
        "256".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
        "--quiet".as_ref(),
    ]);
    let names: BTreeSet<String> = files(&out).into_keys().collect();
    for f in 0..=3 {
        for kind in [
            "color.F.png",
            "mesh.F.obj",
            "mesh.F.mtl",
            "mesh.F.glb",
            "stats.F.json",
        ] {
            let name = kind.replace('F', &format!("{f:04}"));
            assert!(names.contains(&name), "{name} missing: {names:?}");
        }
        let stats: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join(format!("stats.{f:04}.json"))).unwrap())
                .unwrap();
        assert_eq!(stats["uncovered_texels"], 0);
        assert_eq!(stats["atlas_width"], 256);
    }
    // One preview every 8 frames from the first: only frame 0 here. It is
    // two 512² views (textured | patches) side by side, 8 pixels apart.
    let previews: Vec<&String> = names.iter().filter(|n| n.starts_with("preview.")).collect();
    assert_eq!(previews, ["preview.0000.png"]);
    let p = image(&out.join("preview.0000.png"));
    assert_eq!((p.width, p.height), (2 * 512 + 8, 512));
    // Both halves draw the same surface from the same camera, so they
    // cover exactly the same pixels; the textured half is textured (its
    // luminance varies over the surface) and differs from the patch view.
    let background = p.texel(0, 0).to_vec();
    let lum = |t: &[f32]| 0.2126 * t[0] + 0.7152 * t[1] + 0.0722 * t[2];
    let mut covered = 0usize;
    let mut differ = 0usize;
    let mut sum = 0.0f64;
    let mut sum2 = 0.0f64;
    for y in 0..512 {
        for x in 0..512 {
            let textured = p.texel(x, y);
            let patches = p.texel(x + 512 + 8, y);
            let drawn = textured != background.as_slice();
            assert_eq!(
                drawn,
                patches != background.as_slice(),
                "pixel ({x}, {y}): the two views cover different pixels"
            );
            if drawn {
                covered += 1;
                differ += usize::from(textured != patches);
                let l = f64::from(lum(textured));
                sum += l;
                sum2 += l * l;
            }
        }
    }
    let share = covered as f64 / (512.0 * 512.0);
    // The camera frames the sphere: it fills a good part of the view.
    assert!(
        (0.2..0.9).contains(&share),
        "surface covers {share:.3} of the view"
    );
    let mean = sum / covered as f64;
    let sd = (sum2 / covered as f64 - mean * mean).max(0.0).sqrt();
    assert!(
        sd > 0.03,
        "textured half is nearly flat: luminance sd {sd:.4}"
    );
    assert!(
        differ as f64 > 0.9 * covered as f64,
        "the textured view matches the patch view on {} of {covered} pixels",
        covered - differ
    );
}

/// The erosion run of a small generated scene, as a list of arguments.
fn erosion_args(pattern: &Path, out: &Path) -> Vec<std::ffi::OsString> {
    [
        "run".as_ref(),
        "--mesh".as_ref(),
        pattern.as_os_str(),
        "--atlas".as_ref(),
        "128".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
        "--quiet".as_ref(),
        // The per-texel switch map too, so resume is checked on it.
        "--switch-map".as_ref(),
    ]
    .map(std::ffi::OsString::from)
    .to_vec()
}

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

/// Neither the thread count nor where frames are written (behind the next
/// frame's computation, or in place before it) changes a byte.
#[test]
fn thread_count_and_write_behind_do_not_change_the_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = make_scene(dir.path(), "0-3");
    for (name, threads, in_place) in [
        ("t1", "1", false),
        ("t2", "2", false),
        ("inplace", "2", true),
    ] {
        let out = dir.path().join(name);
        let args = erosion_args(&pattern, &out);
        let mut command = fluidtex();
        command.env("RAYON_NUM_THREADS", threads).args(&args);
        if in_place {
            command.env("FLUIDTEX_TEST_WRITE_IN_PLACE", "1");
        }
        let o = command.output().unwrap();
        check_ok(&o, &args);
    }
    assert_same_outputs(&dir.path().join("t1"), &dir.path().join("t2"));
    assert_same_outputs(&dir.path().join("t2"), &dir.path().join("inplace"));
}

/// The files of frame `f` an erosion run with `--switch-map` of a sequence
/// starting at frame 0 writes (the switch map from the second frame on).
fn frame_files(f: i32) -> Vec<String> {
    let mut names = vec![
        "color.F.png",
        "mesh.F.mtl",
        "mesh.F.obj",
        "mesh.F.glb",
        "patches.F.png",
        "source.F.exr",
        "stats.F.json",
    ];
    if f > 0 {
        names.push("switch.F.png");
    }
    names
        .iter()
        .map(|n| n.replace('F', &format!("{f:04}")))
        .collect()
}

/// A run killed with SIGKILL right after frame 2 is counted finished, then
/// rerun with `--resume`, writes the same bytes as an uninterrupted run.
///
/// Deterministic: the run itself stops after frame 2
/// (`FLUIDTEX_TEST_PAUSE_AFTER_FRAME=2`, it waits on its stdin) and the
/// test kills it there with a real SIGKILL, so the path tested is always
/// "killed between frames 2 and 3, lock file left behind", whatever the
/// machine's load. The run inside a write is the next test.
#[test]
fn resume_after_sigkill_gives_the_same_files() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = make_scene(dir.path(), "0-7");
    let reference = dir.path().join("reference");
    ok(&erosion_args(&pattern, &reference));

    let killed = dir.path().join("killed");
    let args = erosion_args(&pattern, &killed);
    let paused = spawn_paused(&args, &[("FLUIDTEX_TEST_PAUSE_AFTER_FRAME", "2")]);
    assert_eq!(paused.line, "fluidtex-test: paused after frame 2");
    let pid = paused.child.id();
    paused.kill();
    // Exactly frames 0-2, the state and the dead run's lock; every file
    // complete.
    let reference_files = files(&reference);
    let after_kill = files(&killed);
    let mut expected: Vec<String> = (0..=2).flat_map(frame_files).collect();
    expected.extend(["fluidtex.lock".to_string(), "state.bin".to_string()]);
    expected.sort();
    assert_eq!(after_kill.keys().cloned().collect::<Vec<_>>(), expected);
    for (name, bytes) in &after_kill {
        match name.as_str() {
            "state.bin" => {}
            "fluidtex.lock" => {
                let text = String::from_utf8_lossy(bytes);
                assert!(text.starts_with(&format!("pid {pid}\n")), "{text}");
            }
            n if n.starts_with("stats.") => assert_eq!(
                stats_without_timings(bytes),
                stats_without_timings(&reference_files[n])
            ),
            n => assert!(bytes == &reference_files[n], "{n} differs after the kill"),
        }
    }

    let mut resume = args.clone();
    resume.push("--resume".into());
    let out = fluidtex().args(&resume).output().unwrap();
    check_ok(&out, &resume);
    // The stale lock was noticed and taken over, then released.
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(&format!(
            "took over the lock of a run that is no longer running (pid {pid} on host "
        )),
        "{stderr}"
    );
    assert_same_outputs(&reference, &killed);
}

/// Bug: a SIGKILL during a write leaves `.<name>.<random>.tmp` in the
/// output folder, and `--resume` leaves it there for good.
///
/// Deterministic: the run stops inside its 11th write
/// (`FLUIDTEX_TEST_PAUSE_IN_WRITE=11`), the third file of frame 1, with
/// that file's temporary on disk, and the test kills it there; the real
/// kill-inside-a-write path runs every time (no hand-made temporary).
#[test]
fn resume_removes_the_temporary_of_a_killed_write() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = make_scene(dir.path(), "0-2");
    let reference = dir.path().join("reference");
    ok(&erosion_args(&pattern, &reference));
    let out = dir.path().join("out");
    let args = erosion_args(&pattern, &out);
    // Writes per frame: its 7 files, then state.bin; 11 = frame 1's third.
    let paused = spawn_paused(&args, &[("FLUIDTEX_TEST_PAUSE_IN_WRITE", "11")]);
    let temporary = paused
        .line
        .strip_prefix("fluidtex-test: paused in write 11: ")
        .unwrap()
        .to_string();
    let name = Path::new(&temporary).file_name().unwrap().to_string_lossy();
    assert!(name.starts_with(".mesh.0001.obj."), "{name}");
    paused.kill();
    // Frame 1's first three files are temporaries (staged, never renamed);
    // none of its files is visible.
    let left = temporaries(&out);
    let prefixes: Vec<String> = left
        .iter()
        .map(|t| t.rsplitn(3, '.').nth(2).unwrap().to_string())
        .collect();
    assert_eq!(
        prefixes,
        [".color.0001.png", ".mesh.0001.mtl", ".mesh.0001.obj"],
        "{left:?}"
    );
    for f in frame_files(1) {
        assert!(!out.join(&f).exists(), "{f} visible before its frame ended");
    }
    let mut resume = args.clone();
    resume.push("--resume".into());
    ok(&resume);
    assert_eq!(temporaries(&out), Vec::<String>::new());
    assert_same_outputs(&reference, &out);
}

/// Bug: every output is created with mode 0600 (the temp file's mode is
/// kept by the rename), so other users of a shared render farm cannot read
/// the textures. A file the user creates in the same folder gets the
/// umask's mode (0644 under the usual umask 022).
#[cfg(unix)]
#[test]
fn outputs_get_the_same_permissions_as_any_new_file() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    ok(&[
        "run".as_ref(),
        "--mesh".as_ref(),
        interop("meshio_ascii.####.ply").as_os_str(),
        "--frames".as_ref(),
        "1".as_ref(),
        "--method".as_ref(),
        "atlas-check".as_ref(),
        "--atlas".as_ref(),
        "64".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    let control = out.join("control.txt");
    std::fs::write(&control, b"x").unwrap();
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    let expected = mode(&control);
    for name in files(&out).keys() {
        assert_eq!(
            mode(&out.join(name)),
            expected,
            "{name}: mode {:o}, a new file gets {expected:o}",
            mode(&out.join(name))
        );
    }
}

/// `--transition 2`: texels whose source changes show both sources for two
/// frames, and a run killed after frame 3 resumes into the same bytes (the
/// weights of the frames before travel in `state.bin`).
#[test]
fn a_transition_resumes_exactly_and_reports_its_share() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    ok(&[
        "scene".as_ref(),
        "vortex".as_ref(),
        "--resolution".as_ref(),
        "16".as_ref(),
        "--frames".as_ref(),
        "0-7".as_ref(),
        "--out".as_ref(),
        scene.as_os_str(),
        "--quiet".as_ref(),
    ]);
    let pattern = scene.join("fluid.####.ply");
    let with_transition = |out: &Path| {
        let mut args = erosion_args(&pattern, out);
        args.extend(["--transition", "2"].map(std::ffi::OsString::from));
        args
    };
    let reference = dir.path().join("reference");
    ok(&with_transition(&reference));
    let shares: Vec<f64> = (0..=7)
        .map(|f| {
            let bytes = std::fs::read(reference.join(format!("stats.{f:04}.json"))).unwrap();
            let stats: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
            stats["transition_share"].as_f64().unwrap()
        })
        .collect();
    assert_eq!(shares[0], 0.0, "nothing came before frame 0");
    assert!(
        shares.iter().all(|s| (0.0..1.0).contains(s)) && shares.iter().any(|&s| s > 0.0),
        "{shares:?}"
    );

    let killed = dir.path().join("killed");
    let args = with_transition(&killed);
    let paused = spawn_paused(&args, &[("FLUIDTEX_TEST_PAUSE_AFTER_FRAME", "3")]);
    assert_eq!(paused.line, "fluidtex-test: paused after frame 3");
    paused.kill();
    let mut resume = args.clone();
    resume.push("--resume".into());
    let out = fluidtex().args(&resume).output().unwrap();
    check_ok(&out, &resume);
    assert_same_outputs(&reference, &killed);
}
