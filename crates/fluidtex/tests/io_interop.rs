//! Files written by third-party programs (meshio 5.3.5, trimesh 5.2.0; see
//! tests/data/interop/README.md). Expected values are those printed by
//! `make_interop.py --print`: positions and velocities are multiples of
//! 1/1024, so they are exact in f32 and compared exactly.

#![allow(clippy::unwrap_used, clippy::excessive_precision)]

use std::path::{Path, PathBuf};

use fluidtex::io::{FramePattern, FrameRange, ReadOptions, Sequence, read_mesh};
use fluidtex::mesh::TriMesh;
use glam::Vec3;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/interop")
        .join(name)
}

fn read(name: &str) -> TriMesh {
    let (mesh, report) = read_mesh(&data(name), &ReadOptions::default()).unwrap();
    assert_eq!(report.dropped_degenerate, 0);
    mesh
}

/// (vertex, position, velocity) per frame, as `make_interop.py --print` prints them.
fn known(frame: i32) -> [(usize, Vec3, Vec3); 3] {
    let v3 = Vec3::new;
    match frame {
        1 => [
            (
                0,
                v3(-0.0126953125, 0.30078125, 0.9375),
                v3(-0.212890625, -0.1318359375, -0.25),
            ),
            (
                17,
                v3(0.404296875, 0.279296875, 1.1875),
                v3(-0.2021484375, 0.0771484375, -0.25),
            ),
            (
                161,
                v3(-0.2255859375, -0.2568359375, 1.0185546875),
                v3(0.0654296875, -0.2373046875, -0.25),
            ),
        ],
        2 => [
            (
                0,
                v3(-0.0126953125, 0.30078125, 0.875),
                v3(-0.42578125, -0.2626953125, -0.5),
            ),
            (
                17,
                v3(0.404296875, 0.279296875, 1.125),
                v3(-0.404296875, 0.154296875, -0.5),
            ),
            (
                161,
                v3(-0.2255859375, -0.2568359375, 0.9560546875),
                v3(0.1318359375, -0.4755859375, -0.5),
            ),
        ],
        _ => [
            (
                0,
                v3(-0.0126953125, 0.30078125, 0.8125),
                v3(-0.6376953125, -0.39453125, -0.75),
            ),
            (
                17,
                v3(0.404296875, 0.279296875, 1.0625),
                v3(-0.6064453125, 0.2314453125, -0.75),
            ),
            (
                161,
                v3(-0.2255859375, -0.2568359375, 0.8935546875),
                v3(0.197265625, -0.712890625, -0.75),
            ),
        ],
    }
}

fn check_frame(mesh: &TriMesh, frame: i32) {
    assert_eq!(mesh.vertex_count(), 162);
    assert_eq!(mesh.triangle_count(), 320);
    let z = 0.0625 * frame as f32;
    assert_eq!(
        mesh.bounding_box(),
        Some((
            Vec3::new(-0.25, -0.625, 0.5 - z),
            Vec3::new(0.75, 0.375, 1.5 - z)
        )),
        "frame {frame}"
    );
    let v = mesh.velocity().expect("velocity");
    for (i, p, vel) in known(frame) {
        assert_eq!(mesh.positions[i], p, "frame {frame} vertex {i}");
        assert_eq!(v[i], vel, "frame {frame} vertex {i}");
    }
    // Every velocity is the rigid spin about the sphere's centre plus the fall.
    let centre = Vec3::new(0.25, -0.125, 1.0 - z);
    let omega = 0.5 * frame as f32;
    for (p, v) in mesh.positions.iter().zip(v) {
        let r = *p - centre;
        let expect = Vec3::new(-omega * r.y, omega * r.x, -0.25 * frame as f32);
        assert!(
            (*v - expect).abs().max_element() <= 1.5 / 1024.0 * frame as f32,
            "{v} vs {expect}"
        );
    }
}

#[test]
fn meshio_ascii_sequence_with_vx_names() {
    let pattern =
        FramePattern::parse(&format!("{}/meshio_ascii.####.ply", data("").display())).unwrap();
    assert_eq!(pattern.discover().unwrap(), vec![1, 2, 3]);
    let seq = Sequence::new(
        pattern,
        FrameRange::new(1, 3).unwrap(),
        ReadOptions::default(),
    );
    let frames: Vec<i32> = seq
        .map(|f| {
            let f = f.unwrap();
            check_frame(&f.mesh, f.number);
            f.number
        })
        .collect();
    assert_eq!(frames, vec![1, 2, 3]);
}

#[test]
fn trimesh_binary_sequence_with_velocity_x_names() {
    let pattern =
        FramePattern::parse(&format!("{}/trimesh_binary.$F4.ply", data("").display())).unwrap();
    for f in Sequence::new(pattern, "1-3".parse().unwrap(), ReadOptions::default()) {
        let f = f.unwrap();
        check_frame(&f.mesh, f.number);
    }
}

#[test]
fn ascii_and_binary_agree_exactly() {
    for frame in 1..=3 {
        let a = read(&format!("meshio_ascii.{frame:04}.ply"));
        let b = read(&format!("trimesh_binary.{frame:04}.ply"));
        assert_eq!(a, b, "frame {frame}");
    }
}

#[test]
fn houdini_style_v_x_names_and_extra_double_attribute() {
    let mesh = read("houdini_style.ply");
    check_frame(&mesh, 2);
    assert_eq!(mesh, read("meshio_ascii.0002.ply"));
    assert_eq!(mesh.attributes.len(), 1, "only velocity is kept");
}

#[test]
fn quads_are_fan_triangulated() {
    let mesh = read("meshio_quads.ply");
    assert_eq!(mesh.vertex_count(), 25);
    assert_eq!(mesh.triangle_count(), 32);
    assert_eq!(mesh.triangles[0], [0, 1, 6]);
    assert_eq!(mesh.triangles[1], [0, 6, 5]);
    assert_eq!(mesh.area(), 1.0);
    assert!(mesh.velocity().is_none());
}

#[test]
fn trimesh_obj_positions() {
    let mesh = read("trimesh.obj");
    assert_eq!(mesh.vertex_count(), 162);
    assert_eq!(mesh.triangle_count(), 320);
    assert!(mesh.velocity().is_none());
    // trimesh prints 8 decimals, so the OBJ holds the rounded values.
    assert_eq!(mesh.positions[0], Vec3::new(-0.01269531, 0.30078125, 0.875));
    // tobj renumbers vertices in first-use order: compare triangle corners,
    // to within the 8-decimal rounding plus one f32 step at magnitude < 2.
    let ply = read("meshio_ascii.0002.ply");
    for t in 0..320 {
        for (a, b) in mesh.corners(t).iter().zip(ply.corners(t)) {
            assert!(
                (*a - b).abs().max_element() <= 1.2e-7,
                "triangle {t}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn meshio_vtk_42_binary_and_51_ascii() {
    let reference = read("meshio_ascii.0002.ply");
    for name in ["meshio_binary_42.vtk", "meshio_ascii_51.vtk"] {
        let mesh = read(name);
        check_frame(&mesh, 2);
        assert_eq!(mesh, reference, "{name}");
    }
}
