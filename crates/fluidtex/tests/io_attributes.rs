//! Named per-vertex scalar attributes (issue 40: a simulation's
//! `temperature` or `age` reaching the texturing methods): kept by the PLY
//! and VTK readers only when asked for (`ReadOptions::scalar_attributes`)
//! or all of them (`all_scalar_attributes`, for `fluidtex info`), written
//! by the scene writer, refused with the file and the attribute named when
//! absent or not finite. Known-good values come from files written by
//! meshio (tests/data/interop): `houdini_style.ply` has `double density =
//! linspace(0, 1, 162)`, the VTK files an `int id = 0..161`.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use fluidtex::io::ply::parse_ply;
use fluidtex::io::ply_write::{PlyEncoding, write_ply};
use fluidtex::io::vtk::parse_vtk;
use fluidtex::io::{FramePattern, IoError, ReadOptions, Sequence, read_mesh};
use fluidtex::mesh::{Attribute, TriMesh};
use glam::Vec3;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/interop")
        .join(name)
}

fn asking(names: &[&str]) -> ReadOptions {
    ReadOptions {
        scalar_attributes: names.iter().map(|n| n.to_string()).collect(),
        ..Default::default()
    }
}

fn every() -> ReadOptions {
    ReadOptions {
        all_scalar_attributes: true,
        ..Default::default()
    }
}

fn scalar<'a>(mesh: &'a TriMesh, name: &str) -> &'a [f32] {
    match mesh.attributes.get(name) {
        Some(Attribute::Scalar(v)) => v,
        other => panic!("{name}: {other:?}"),
    }
}

/// A quad with velocity and two scalar attributes whose values need every
/// bit of an f32 (an ASCII round trip must print them exactly).
fn hot_quad() -> TriMesh {
    let mut m = TriMesh::new(
        vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .with_velocity(vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE]);
    m.attributes.insert(
        "temperature".into(),
        Attribute::Scalar(vec![1.0, 0.1, 1.0 / 3.0, 1e-30]),
    );
    m.attributes.insert(
        "age".into(),
        Attribute::Scalar(vec![0.0, 2.5, 1234.567, f32::MIN_POSITIVE]),
    );
    m
}

#[test]
fn scalar_attributes_round_trip_through_the_scene_writer_ascii_and_binary() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = hot_quad();
    for (enc, name) in [
        (PlyEncoding::BinaryLittleEndian, "b.ply"),
        (PlyEncoding::Ascii, "a.ply"),
    ] {
        let path = dir.path().join(name);
        write_ply(&path, &mesh, enc).unwrap();
        let header = std::fs::read(&path).unwrap();
        let header = String::from_utf8_lossy(&header[..300]);
        assert!(
            header.contains(
                "property float vz\nproperty float age\nproperty float temperature\nelement face"
            ),
            "scalars after velocity, by name: {header}"
        );
        let (back, _) = read_mesh(&path, &asking(&["temperature", "age"])).unwrap();
        assert_eq!(back, mesh, "{enc:?}");
        let (back, _) = read_mesh(&path, &every()).unwrap();
        assert_eq!(back, mesh, "{enc:?}: every scalar");
        let (back, _) = read_mesh(&path, &asking(&["age"])).unwrap();
        assert_eq!(back.attributes.len(), 2, "{enc:?}: velocity and age");
        assert_eq!(scalar(&back, "age"), scalar(&mesh, "age"));
        // Control: by default no extra attribute is read, as before.
        let (back, _) = read_mesh(&path, &ReadOptions::default()).unwrap();
        let mut plain = mesh.clone();
        plain.attributes.retain(|k, _| k == "velocity");
        assert_eq!(back, plain, "{enc:?}: default options");
    }
}

#[test]
fn a_mesh_without_scalars_is_written_as_before() {
    // The bytes of the writer before scalar attributes existed: header
    // with velocity only, then 6 floats per vertex.
    let dir = tempfile::tempdir().unwrap();
    let mut mesh = hot_quad();
    mesh.attributes.retain(|k, _| k == "velocity");
    let path = dir.path().join("v.ply");
    write_ply(&path, &mesh, PlyEncoding::BinaryLittleEndian).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let head = "ply\nformat binary_little_endian 1.0\ncomment written by fluidtex\nelement vertex 4\n\
                property float x\nproperty float y\nproperty float z\n\
                property float vx\nproperty float vy\nproperty float vz\n\
                element face 2\nproperty list uchar int vertex_indices\nend_header\n";
    assert_eq!(&bytes[..head.len()], head.as_bytes());
    assert_eq!(bytes.len(), head.len() + 4 * 24 + 2 * 13);
}

#[test]
fn the_writer_refuses_names_a_ply_header_cannot_hold() {
    let dir = tempfile::tempdir().unwrap();
    for (name, why) in [
        ("two words", "is not a PLY property name"),
        ("vx", "has the name of a position or velocity property"),
    ] {
        let mut mesh = hot_quad();
        mesh.attributes
            .insert(name.into(), Attribute::Scalar(vec![0.0; 4]));
        let path = dir.path().join("x.ply");
        let err = write_ply(&path, &mesh, PlyEncoding::Ascii).unwrap_err();
        assert!(err.to_string().contains(why), "{err}");
        assert!(!path.exists());
    }
}

#[test]
fn any_numeric_property_type_is_read_as_f32() {
    let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                property float z\nproperty int count\nproperty uchar level\nproperty double heat\n\
                property short cold\nproperty float nx\nelement face 0\n\
                property list uchar int vertex_indices\nend_header\n\
                0 0 0 -7 255 0.25 -3 1\n1 0 0 2147483647 0 1e300 7 0\n";
    let names = ["count", "level", "heat", "cold"];
    let m = parse_ply(Path::new("t.ply"), text.as_bytes(), &asking(&names)).unwrap();
    assert_eq!(scalar(&m, "count"), [-7.0, 2147483647.0]);
    assert_eq!(scalar(&m, "level"), [255.0, 0.0]);
    assert_eq!(scalar(&m, "heat"), [0.25, f32::INFINITY]);
    assert_eq!(scalar(&m, "cold"), [-3.0, 7.0]);
    assert_eq!(m.attributes.len(), 4, "nothing else");
    // Every scalar but positions, velocity and normals.
    let all = parse_ply(Path::new("t.ply"), text.as_bytes(), &every()).unwrap();
    let kept: Vec<&str> = all.attributes.keys().map(String::as_str).collect();
    assert_eq!(kept, ["cold", "count", "heat", "level"]);
    // A requested normal is kept all the same.
    let n = parse_ply(Path::new("t.ply"), text.as_bytes(), &asking(&["nx", "y"])).unwrap();
    assert_eq!(scalar(&n, "nx"), [1.0, 0.0]);
    assert_eq!(scalar(&n, "y"), [0.0, 0.0]);
}

#[test]
fn binary_int_property_and_velocity_component() {
    let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty float x\n\
        property float y\nproperty float z\nproperty float vx\nproperty float vy\nproperty float vz\n\
        property int id\nend_header\n"
        .to_vec();
    for (k, id) in [(0.0f32, 41i32), (1.0, -5)] {
        for c in [k, 0.0, 0.0, 0.5, k, 2.0] {
            b.extend_from_slice(&c.to_be_bytes());
        }
        b.extend_from_slice(&id.to_be_bytes());
    }
    let m = parse_ply(Path::new("b.ply"), &b, &asking(&["id", "vy"])).unwrap();
    assert_eq!(scalar(&m, "id"), [41.0, -5.0]);
    assert_eq!(scalar(&m, "vy"), [0.0, 1.0]);
    assert_eq!(m.velocity().unwrap()[1], Vec3::new(0.5, 1.0, 2.0));
}

#[test]
fn meshio_density_double_is_read_when_asked() {
    let path = data("houdini_style.ply");
    let (m, _) = read_mesh(&path, &asking(&["density"])).unwrap();
    let d = scalar(&m, "density");
    assert_eq!(d.len(), 162);
    assert_eq!((d[0], d[161]), (0.0, 1.0));
    for (i, &x) in d.iter().enumerate() {
        assert!((x - i as f32 / 161.0).abs() < 1e-6, "vertex {i}: {x}");
    }
    // Control: the default read keeps only the velocity (io_interop).
    let (plain, _) = read_mesh(&path, &ReadOptions::default()).unwrap();
    assert_eq!(plain.attributes.len(), 1);
    // And `info`'s read keeps density alone (v_x v_y v_z are velocity).
    let (all, _) = read_mesh(&path, &every()).unwrap();
    let kept: Vec<&str> = all.attributes.keys().map(String::as_str).collect();
    assert_eq!(kept, ["density", "velocity"]);
}

#[test]
fn a_missing_attribute_names_the_file_the_attribute_and_what_there_is() {
    let err = read_mesh(
        &data("houdini_style.ply"),
        &asking(&["density", "temperature"]),
    )
    .unwrap_err();
    assert!(matches!(err, IoError::MissingAttribute { .. }), "{err:?}");
    assert_eq!(
        err.to_string(),
        format!(
            "{}: no per-vertex scalar attribute \"temperature\" (the file's scalar vertex \
             properties: v_x, v_y, v_z, density)",
            data("houdini_style.ply").display()
        )
    );
    let err = read_mesh(&data("trimesh.obj"), &asking(&["age"])).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{}: no per-vertex scalar attribute \"age\" (the file's scalar vertex properties: none)",
            data("trimesh.obj").display()
        )
    );
    let err = read_mesh(&data("meshio_ascii_51.vtk"), &asking(&["age"])).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{}: no per-vertex scalar attribute \"age\" (the file's scalar vertex properties: id)",
            data("meshio_ascii_51.vtk").display()
        )
    );
    // A list property is not a scalar one.
    let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                property float z\nproperty list uchar float w\nend_header\n0 0 0 1 5\n";
    let err = parse_ply(Path::new("t.ply"), text.as_bytes(), &asking(&["w"])).unwrap_err();
    assert_eq!(
        err.to_string(),
        "t.ply: no per-vertex scalar attribute \"w\" (the file's scalar vertex properties: none)"
    );
    // Control: the same files without the request read fine.
    for name in ["houdini_style.ply", "trimesh.obj", "meshio_ascii_51.vtk"] {
        read_mesh(&data(name), &ReadOptions::default()).unwrap();
    }
}

#[test]
fn a_non_finite_requested_value_is_refused_naming_vertex_and_attribute() {
    let dir = tempfile::tempdir().unwrap();
    let mut mesh = hot_quad();
    mesh.attributes.insert(
        "temperature".into(),
        Attribute::Scalar(vec![0.5, f32::NAN, 0.5, 0.5]),
    );
    let path = dir.path().join("nan.ply");
    write_ply(&path, &mesh, PlyEncoding::BinaryLittleEndian).unwrap();
    let err = read_mesh(&path, &asking(&["temperature"])).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{}: vertex 1 has a non-finite temperature (NaN)",
            path.display()
        )
    );
    // Control: not asked for, the NaN is not read (as before).
    read_mesh(&path, &ReadOptions::default()).unwrap();
    read_mesh(&path, &asking(&["age"])).unwrap();
    // ASCII: the token is refused while parsing; the message names the
    // property.
    let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                property float z\nproperty float temperature\nend_header\n0 0 0 1\n0 1 0 -inf\n";
    let err = parse_ply(
        Path::new("t.ply"),
        text.as_bytes(),
        &asking(&["temperature"]),
    )
    .unwrap_err();
    assert_eq!(
        err.to_string(),
        "t.ply: vertex 1: has a non-finite temperature (0 1 0 -inf)"
    );
    // VTK: validation names it.
    let vtk = dir.path().join("nan.vtk");
    std::fs::write(
        &vtk,
        "# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 0 1 0\n\
         POLYGONS 1 4\n3 0 1 2\nPOINT_DATA 3\nSCALARS heat double 1\nLOOKUP_TABLE default\n1 2 inf\n",
    )
    .unwrap();
    let err = read_mesh(&vtk, &asking(&["heat"])).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!("{}: vertex 2 has a non-finite heat (inf)", vtk.display())
    );
    read_mesh(&vtk, &ReadOptions::default()).unwrap();
}

#[test]
fn vtk_one_component_point_arrays_are_kept_when_asked() {
    for name in ["meshio_ascii_51.vtk", "meshio_binary_42.vtk"] {
        let (m, _) = read_mesh(&data(name), &asking(&["id"])).unwrap();
        let expect: Vec<f32> = (0..162).map(|i| i as f32).collect();
        assert_eq!(scalar(&m, "id"), expect, "{name}");
        assert!(m.velocity().is_some());
        let (all, _) = read_mesh(&data(name), &every()).unwrap();
        assert_eq!(all, m, "{name}: every scalar is id");
        let (plain, _) = read_mesh(&data(name), &ReadOptions::default()).unwrap();
        assert_eq!(plain.attributes.len(), 1, "{name}: velocity only");
    }
    // SCALARS sections; cell data and 3-component arrays are not scalars.
    let text = "# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n\
                0 0 0 1 0 0 0 1 0\nPOLYGONS 1 4\n3 0 1 2\nCELL_DATA 1\nSCALARS area float 1\n\
                LOOKUP_TABLE default\n0.5\nPOINT_DATA 3\nSCALARS temperature float\n\
                LOOKUP_TABLE default\n0.25 0.5 1\nVECTORS velocity float\n0 0 0 0 0 0 0 0 0\n";
    let parse = |o: &ReadOptions| parse_vtk(Path::new("s.vtk"), text.as_bytes(), o);
    let m = parse(&asking(&["temperature"])).unwrap();
    assert_eq!(scalar(&m, "temperature"), [0.25, 0.5, 1.0]);
    let all = parse(&every()).unwrap();
    assert_eq!(all, m);
    let err = parse(&asking(&["area"])).unwrap_err();
    assert_eq!(
        err.to_string(),
        "s.vtk: no per-vertex scalar attribute \"area\" (the file's scalar vertex properties: temperature)"
    );
}

#[test]
fn a_sequence_hands_the_request_to_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = hot_quad();
    for f in 1..=2 {
        write_ply(
            &dir.path().join(format!("s.{f:04}.ply")),
            &mesh,
            PlyEncoding::BinaryLittleEndian,
        )
        .unwrap();
    }
    let pattern = FramePattern::parse(&format!("{}/s.####.ply", dir.path().display())).unwrap();
    let seq = Sequence::new(pattern.clone(), "1-2".parse().unwrap(), asking(&["age"]));
    for f in seq {
        assert_eq!(scalar(&f.unwrap().mesh, "age"), scalar(&mesh, "age"));
    }
    let seq = Sequence::new(pattern, "1-2".parse().unwrap(), asking(&["salinity"]));
    for f in seq {
        let err = f.unwrap_err();
        assert!(
            err.to_string()
                .contains("no per-vertex scalar attribute \"salinity\""),
            "{err}"
        );
    }
}
