//! Sequences end to end: patterns, discovery, lazy reading, velocity names.

#![allow(clippy::unwrap_used)]

use fluidtex::io::ply_write::{PlyEncoding, write_ply};
use fluidtex::io::{FramePattern, FrameRange, IoError, ReadOptions, Sequence};
use fluidtex::mesh::TriMesh;
use glam::Vec3;

fn mesh(frame: i32) -> TriMesh {
    let z = frame as f32;
    TriMesh::new(
        vec![
            Vec3::new(0.0, 0.0, z),
            Vec3::new(1.0, 0.0, z),
            Vec3::new(0.0, 1.0, z),
        ],
        vec![[0, 1, 2]],
    )
    .with_velocity(vec![Vec3::splat(z); 3])
}

#[test]
fn all_three_pattern_styles_read_the_same_frames() {
    let dir = tempfile::tempdir().unwrap();
    for f in -2..=3 {
        write_ply(
            &dir.path().join(format!("fluid.{f:04}.ply")),
            &mesh(f),
            PlyEncoding::BinaryLittleEndian,
        )
        .unwrap();
    }
    for token in ["$F4", "####", "%04d"] {
        let pattern =
            FramePattern::parse(&format!("{}/fluid.{token}.ply", dir.path().display())).unwrap();
        assert_eq!(
            pattern.discover().unwrap(),
            vec![-2, -1, 0, 1, 2, 3],
            "{token}"
        );
        let seq = Sequence::new(pattern, "-2-3".parse().unwrap(), ReadOptions::default());
        assert_eq!(seq.len(), 6);
        for frame in seq {
            let frame = frame.unwrap();
            assert_eq!(frame.mesh, mesh(frame.number), "{token}");
            assert_eq!(
                frame.path.file_name().unwrap().to_str().unwrap(),
                format!("fluid.{:04}.ply", frame.number)
            );
        }
    }
}

#[test]
fn frames_are_read_one_at_a_time_when_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let path = |f: i32| dir.path().join(format!("drop_{f}.ply"));
    write_ply(&path(1), &mesh(1), PlyEncoding::Ascii).unwrap();
    let pattern = FramePattern::parse(&format!("{}/drop_$F.ply", dir.path().display())).unwrap();
    let mut seq = Sequence::new(
        pattern,
        FrameRange::new(1, 3).unwrap(),
        ReadOptions::default(),
    );
    assert_eq!(seq.next().unwrap().unwrap().number, 1);
    // Frames 2 and 3 do not exist yet: nothing has been read ahead.
    write_ply(&path(2), &mesh(20), PlyEncoding::Ascii).unwrap();
    assert_eq!(seq.size_hint(), (2, Some(2)));
    assert_eq!(seq.next().unwrap().unwrap().mesh, mesh(20));
    match seq.next() {
        Some(Err(IoError::MissingFrame { frame: 3, .. })) => {}
        other => panic!("expected missing frame 3, got {other:?}"),
    }
    assert!(seq.next().is_none());
}

#[test]
fn configured_velocity_names_apply_to_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    for f in 1..=2 {
        let text = format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
             property float u\nproperty float w\nproperty float q\nelement face 1\n\
             property list uchar uint vertex_indices\nend_header\n0 0 0 {f} 0 0\n1 0 0 {f} 0 0\n0 1 0 {f} 0 0\n3 0 1 2\n"
        );
        std::fs::write(dir.path().join(format!("s.{f:02}.ply")), text).unwrap();
    }
    let pattern = FramePattern::parse(&format!("{}/s.##.ply", dir.path().display())).unwrap();
    let options = ReadOptions {
        velocity_properties: Some(["u".into(), "w".into(), "q".into()]),
        ..Default::default()
    };
    for frame in Sequence::new(pattern.clone(), FrameRange::new(1, 2).unwrap(), options) {
        let frame = frame.unwrap();
        assert_eq!(
            frame.mesh.velocity().unwrap()[2],
            Vec3::new(frame.number as f32, 0.0, 0.0)
        );
    }
    // Without the option these files have no velocity.
    let first = Sequence::new(
        pattern,
        FrameRange::new(1, 1).unwrap(),
        ReadOptions::default(),
    )
    .next()
    .unwrap()
    .unwrap();
    assert!(first.mesh.velocity().is_none());
}
