//! One test per way a mesh file can be bad: each must give one exact,
//! one-line message naming the file and the element, never a panic.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use fluidtex::io::ply_write::{PlyEncoding, write_ply};
use fluidtex::io::{FramePattern, FrameRange, IoError, ReadOptions, Sequence, read_mesh};
use fluidtex::mesh::TriMesh;
use glam::Vec3;

fn grid(n: usize) -> TriMesh {
    let positions = (0..n)
        .map(|i| Vec3::new(i as f32, (i % 7) as f32, (i * i % 5) as f32))
        .collect();
    let triangles = (0..n as u32 - 2).map(|i| [i, i + 1, i + 2]).collect();
    TriMesh::new(positions, triangles)
}

fn message(path: &Path) -> String {
    let err = read_mesh(path, &ReadOptions::default()).unwrap_err();
    let text = err.to_string();
    assert!(!text.contains('\n'), "not one line: {text:?}");
    text
}

fn temp(name: &str, bytes: &[u8]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    (dir, path)
}

#[test]
fn truncated_binary_names_the_vertex_where_the_file_ends() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fluid.0003.ply");
    write_ply(&path, &grid(5000), PlyEncoding::BinaryLittleEndian).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let header = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    std::fs::write(&path, &bytes[..header + 4120 * 12 + 5]).unwrap();
    assert_eq!(
        message(&path),
        format!(
            "{}: truncated: expected 5000 vertices, file ends in vertex 4120",
            path.display()
        )
    );
}

#[test]
fn truncated_ascii_names_the_face_where_the_file_ends() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fluid.0004.ply");
    write_ply(&path, &grid(10), PlyEncoding::Ascii).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let cut: Vec<&str> = text.lines().collect();
    std::fs::write(&path, cut[..cut.len() - 3].join("\n")).unwrap();
    assert_eq!(
        message(&path),
        format!(
            "{}: truncated: expected 8 faces, file ends in face 5",
            path.display()
        )
    );
}

#[test]
fn garbled_header() {
    let (_d, path) = temp(
        "fluid.0001.ply",
        b"ply\nformat ascii 1.0\nelement vertex lots\nproperty float x\nend_header\n",
    );
    let msg = message(&path);
    assert!(
        msg.starts_with(&format!("{}: bad header: ", path.display())),
        "{msg}"
    );
    let (_d, path) = temp("fluid.0002.ply", b"PLY?\x00\xff\n");
    assert!(message(&path).starts_with(&format!("{}: bad header: ", path.display())));
    let (_d, path) = temp(
        "fluid.0003.ply",
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n",
    );
    assert_eq!(
        message(&path),
        format!(
            "{}: bad header: vertex element has no property z",
            path.display()
        )
    );
}

#[test]
fn unknown_format() {
    let (_d, path) = temp("fluid.0001.stl", b"solid x\nendsolid x\n");
    assert_eq!(
        message(&path),
        format!(
            "{}: unknown mesh format \"stl\" (expected .ply, .obj or .vtk)",
            path.display()
        )
    );
}

#[test]
fn bad_counts_when_data_outlives_the_header() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fluid.0005.ply");
    write_ply(&path, &grid(3), PlyEncoding::BinaryLittleEndian).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    bytes.extend_from_slice(&[3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]); // a second face
    std::fs::write(&path, &bytes).unwrap();
    assert_eq!(
        message(&path),
        format!(
            "{}: bad counts: 13 bytes of data follow the 3 vertices and 1 face the header declares",
            path.display()
        )
    );
}

#[test]
fn index_out_of_range_names_the_face_of_the_file() {
    let mut text = String::from(
        "ply\nformat ascii 1.0\nelement vertex 1000\nproperty float x\nproperty float y\nproperty float z\n\
         element face 100\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for i in 0..1000 {
        text += &format!("{i} {} 0\n", i % 3);
    }
    for f in 0..100 {
        // Face 88 is a quad whose last corner is out of range.
        if f == 88 {
            text += "4 1 2 3 9999\n";
        } else {
            text += &format!("3 {f} {} {}\n", f + 1, f + 2);
        }
    }
    let (_d, path) = temp("fluid.0012.ply", text.as_bytes());
    assert_eq!(
        message(&path),
        format!(
            "{}: face 88 refers to vertex 9999, but the mesh has 1000 vertices",
            path.display()
        )
    );
}

#[test]
fn nan_position() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fluid.0006.ply");
    let mut mesh = grid(20);
    mesh.positions[12] = Vec3::new(f32::NAN, 0.0, 0.0);
    write_ply(&path, &mesh, PlyEncoding::BinaryLittleEndian).unwrap();
    assert_eq!(
        message(&path),
        format!(
            "{}: vertex 12 has a non-finite position (NaN 0 0)",
            path.display()
        )
    );
}

#[test]
fn nan_velocity() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fluid.0007.ply");
    let mut velocity = vec![Vec3::ONE; 20];
    velocity[12] = Vec3::new(f32::NAN, 0.0, 0.0);
    write_ply(
        &path,
        &grid(20).with_velocity(velocity),
        PlyEncoding::BinaryLittleEndian,
    )
    .unwrap();
    assert_eq!(
        message(&path),
        format!(
            "{}: vertex 12 has a non-finite velocity (NaN 0 0)",
            path.display()
        )
    );
}

#[test]
fn missing_file_and_missing_frame() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fluid.0014.ply");
    assert_eq!(message(&path), format!("{} does not exist", path.display()));
    assert!(matches!(
        read_mesh(&path, &ReadOptions::default()),
        Err(IoError::NotFound { .. })
    ));

    for f in [12, 13, 15] {
        write_ply(
            &dir.path().join(format!("fluid.{f:04}.ply")),
            &grid(5),
            PlyEncoding::BinaryLittleEndian,
        )
        .unwrap();
    }
    let pattern = FramePattern::parse(&format!("{}/fluid.$F4.ply", dir.path().display())).unwrap();
    let seq = Sequence::new(
        pattern,
        "12-15".parse::<FrameRange>().unwrap(),
        ReadOptions::default(),
    );
    let expected = format!("missing frame 14: {} does not exist", path.display());
    assert_eq!(seq.check_present().unwrap_err().to_string(), expected);
    let results: Vec<_> = seq
        .map(|r| r.map(|f| f.number).map_err(|e| e.to_string()))
        .collect();
    assert_eq!(results, vec![Ok(12), Ok(13), Err(expected), Ok(15)]);
}

#[test]
fn empty_file() {
    for name in ["fluid.0001.ply", "fluid.0001.obj", "fluid.0001.vtk"] {
        let (_d, path) = temp(name, b"");
        assert_eq!(
            message(&path),
            format!("{}: the file is empty", path.display())
        );
    }
}

#[test]
fn empty_frame_is_valid() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fluid.0100.ply");
    write_ply(&path, &TriMesh::default(), PlyEncoding::BinaryLittleEndian).unwrap();
    let (mesh, report) = read_mesh(&path, &ReadOptions::default()).unwrap();
    assert!(mesh.is_empty());
    assert_eq!(mesh.vertex_count(), 0);
    assert_eq!(report.dropped_degenerate, 0);
}

#[test]
fn degenerate_triangles_are_dropped_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fluid.0101.ply");
    let mut mesh = grid(10);
    mesh.triangles.push([0, 0, 1]);
    mesh.positions.push(Vec3::new(100.0, 0.0, 0.0));
    mesh.positions.push(Vec3::new(200.0, 0.0, 0.0));
    mesh.positions.push(Vec3::new(300.0, 0.0, 0.0));
    mesh.triangles.push([10, 11, 12]); // collinear
    write_ply(&path, &mesh, PlyEncoding::BinaryLittleEndian).unwrap();
    let (read, report) = read_mesh(&path, &ReadOptions::default()).unwrap();
    assert_eq!(report.dropped_degenerate, 2 + dropped_in_grid(&grid(10)));
    assert_eq!(
        read.triangles.len(),
        mesh.triangles.len() - report.dropped_degenerate
    );
}

/// Degenerate triangles already in `grid` (computed independently of validate).
fn dropped_in_grid(m: &TriMesh) -> usize {
    (0..m.triangles.len())
        .filter(|&t| m.triangle_cross(t) == Vec3::ZERO)
        .count()
}
