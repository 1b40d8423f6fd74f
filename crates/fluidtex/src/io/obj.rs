//! Wavefront OBJ reader (positions and faces only), built on tobj 4.
//!
//! OBJ carries no velocity; a sequence read from OBJ needs velocity from
//! elsewhere. tobj triangulates polygons as fans and renumbers vertices per
//! object (`o`/`g`), dropping vertices no face uses; we concatenate the
//! objects in file order. Materials, normals and texture coordinates are
//! ignored. tobj's errors carry no line number, so ours name the kind of
//! record that failed (e.g. "a face cannot be parsed").

use std::path::Path;

use glam::Vec3;

use super::{IoError, read_bytes};
use crate::mesh::TriMesh;

/// Reads an OBJ file into a mesh without attributes. Not validated;
/// [`super::read_mesh`] does that.
pub fn read_obj(path: &Path) -> Result<TriMesh, IoError> {
    let bytes = read_bytes(path)?;
    parse_obj(path, &bytes)
}

/// Parses OBJ bytes; `path` is used in error messages only.
pub fn parse_obj(path: &Path, bytes: &[u8]) -> Result<TriMesh, IoError> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ..Default::default()
    };
    let without_uv_and_normals = drop_vt_vn(bytes);
    let (models, _materials) =
        tobj::load_obj_buf(&mut &without_uv_and_normals[..], &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| IoError::Malformed {
            path: path.to_path_buf(),
            reason: describe(&e),
        })?;
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for model in &models {
        let offset = positions.len() as u32;
        let m = &model.mesh;
        positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2])),
        );
        triangles.extend(
            m.indices
                .chunks_exact(3)
                .map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]),
        );
    }
    Ok(TriMesh::new(positions, triangles))
}

/// The file without its `vt` and `vn` records. We ignore both, and tobj
/// 4.0.5 computes `vt * 2 + 1` and `vn * 3 + 2` for a face's texture and
/// normal indices unchecked: a huge index (`f 1/9223372036854775807 ...`)
/// overflows, a panic in debug builds and a wrong index in release (found
/// by the fuzz tests, `obj_face_with_a_huge_uv_index`). Without the
/// records, tobj never looks at those indices.
fn drop_vt_vn(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(bytes.len());
    for line in bytes.split_inclusive(|&b| b == b'\n') {
        let t = line.trim_ascii_start();
        let is = |k: &[u8]| t.starts_with(k) && t.get(2).is_none_or(|b| b.is_ascii_whitespace());
        if !(is(b"vt") || is(b"vn")) {
            out.extend_from_slice(line);
        }
    }
    out
}

fn describe(e: &tobj::LoadError) -> String {
    use tobj::LoadError as E;
    match e {
        E::PositionParseError => "a vertex position (v) cannot be parsed".into(),
        E::FaceParseError => "a face (f) cannot be parsed".into(),
        E::InvalidPolygon => "a face has fewer than 3 corners".into(),
        E::FaceVertexOutOfBounds => "a face refers to a vertex that does not exist".into(),
        E::NormalParseError | E::TexcoordParseError | E::ColorParseError => {
            format!("cannot be parsed ({e})")
        }
        other => format!("not a readable OBJ file ({other})"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression (fuzz case obj 460, seed 0x5eedf1d7): tobj overflowed computing the offset
    /// of a huge texture or normal index.
    #[test]
    fn obj_face_with_a_huge_uv_index() {
        for face in [
            "f 1/9223372036854775807 2/1 3/1",
            "f 1//9223372036854775807 2//1 3//1",
        ] {
            let text = format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n{face}\n");
            let m = parse_obj(Path::new("t.obj"), text.as_bytes()).unwrap();
            assert_eq!(m.triangles, vec![[0, 1, 2]]);
        }
    }

    #[test]
    fn quad_and_triangle_in_two_objects() {
        let text = b"# test\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\no a\nf 1/1/1 2/1/1 3/1/1 4/1/1\no b\nf -4 -3 -1\n";
        let m = parse_obj(Path::new("t.obj"), text).unwrap();
        assert_eq!(m.triangles.len(), 3);
        // Each object is renumbered; positions follow the corners.
        let tri = |t: usize| m.corners(t);
        assert_eq!(tri(0), [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)]);
        assert_eq!(tri(1), [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]);
        assert_eq!(tri(2), [Vec3::ZERO, Vec3::X, Vec3::Y]);
        assert!(m.velocity().is_none());
    }

    #[test]
    fn errors_name_the_record() {
        let err =
            parse_obj(Path::new("t.obj"), b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap_err();
        assert_eq!(
            err.to_string(),
            "t.obj: a face refers to a vertex that does not exist"
        );
    }

    #[test]
    fn never_panics_on_truncated_or_corrupted_input() {
        let good = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0.5 0.5\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf 1//1 3//1 4//1\n";
        let mut cases = Vec::new();
        for n in 0..good.len() {
            cases.push(good[..n].to_vec());
            for b in [b'/', b'-', b' ', b'\n', b'x', b'0', 0xff] {
                let mut c = good.to_vec();
                c[n] = b;
                cases.push(c);
            }
        }
        for c in cases {
            let r = std::panic::catch_unwind(|| parse_obj(Path::new("t.obj"), &c).map(|_| ()));
            assert!(r.is_ok(), "panicked on {:?}", String::from_utf8_lossy(&c));
        }
    }
}
