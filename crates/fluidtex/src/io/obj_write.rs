//! OBJ + MTL writer for meshes with atlas UVs.
//!
//! One `vt` per vertex (atlas UVs are per vertex after chart cutting), so
//! faces are `f a/a b/b c/c` (or `a/a/a` with normals). Our UVs have
//! `v = 0` at the top of the image (see [`crate::texture`]); OBJ's `vt` has
//! `v = 0` at the bottom, so we write `1 − v`. The material file sits next
//! to the OBJ with the same stem and names the colour atlas as `map_Kd` by
//! its relative file name.

use std::io::Write;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::IoError;
use super::atomic::Staging;

/// The one material of an exported mesh.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ObjMaterial {
    /// Material name (`newmtl`/`usemtl`); no whitespace.
    pub name: String,
    /// Colour atlas file name relative to the OBJ (`map_Kd`); no whitespace
    /// or newline, since MTL has no quoting.
    pub map_kd: String,
}

/// The `.mtl` path written beside `obj_path`.
pub fn mtl_path(obj_path: &Path) -> PathBuf {
    obj_path.with_extension("mtl")
}

/// Writes an OBJ (and, with a material, its MTL beside it), atomically:
/// both files appear together or neither does.
pub fn write_obj(
    path: &Path,
    positions: &[Vec3],
    uvs: &[Vec2],
    normals: Option<&[Vec3]>,
    triangles: &[[u32; 3]],
    material: Option<&ObjMaterial>,
) -> Result<(), IoError> {
    let mut files = Staging::new(None, None);
    stage_obj(
        &mut files, path, positions, uvs, normals, triangles, material,
    )?;
    files.commit()
}

/// [`write_obj`] into a group of files that the caller commits.
pub fn stage_obj(
    files: &mut Staging<'_>,
    path: &Path,
    positions: &[Vec3],
    uvs: &[Vec2],
    normals: Option<&[Vec3]>,
    triangles: &[[u32; 3]],
    material: Option<&ObjMaterial>,
) -> Result<(), IoError> {
    let bad = |reason: String| IoError::Unwritable {
        path: path.to_path_buf(),
        reason,
    };
    check_mesh(positions, uvs, normals, triangles).map_err(bad)?;
    let mtl = mtl_path(path);
    let mtl_name = mtl
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| bad("no file name".into()))?;
    if let Some(m) = material {
        for (what, s) in [
            ("material name", &m.name),
            ("map_Kd file name", &m.map_kd),
            ("MTL file name", &mtl_name),
        ] {
            if s.is_empty() || s.chars().any(char::is_whitespace) {
                return Err(bad(format!("{what} {s:?} is empty or has whitespace")));
            }
        }
        files.write(&mtl, |w| {
            writeln!(w, "# written by fluidtex")?;
            writeln!(w, "newmtl {}", m.name)?;
            writeln!(w, "Ka 0 0 0\nKd 1 1 1\nKs 0 0 0\nd 1\nillum 1")?;
            writeln!(w, "map_Kd {}", m.map_kd)
        })?;
    }
    // Formatting numbers is most of the cost: lines are formatted in
    // parallel chunks (each chunk's text in order), then written in order,
    // so the bytes are those of a sequential writer.
    let v = lines(positions, |out, p| {
        writeln!(out, "v {} {} {}", p.x, p.y, p.z)
    });
    let vt = lines(uvs, |out, t| writeln!(out, "vt {} {}", t.x, 1.0 - t.y));
    let vn = normals.map(|ns| lines(ns, |out, n| writeln!(out, "vn {} {} {}", n.x, n.y, n.z)));
    let with_normals = normals.is_some();
    let f = lines(triangles, |out, t| {
        let [a, b, c] = t.map(|i| i + 1);
        if with_normals {
            writeln!(out, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}")
        } else {
            writeln!(out, "f {a}/{a} {b}/{b} {c}/{c}")
        }
    });
    files.write(path, |w| {
        writeln!(w, "# written by fluidtex")?;
        if material.is_some() {
            writeln!(w, "mtllib {mtl_name}")?;
        }
        write_chunks(w, &v)?;
        write_chunks(w, &vt)?;
        if let Some(vn) = &vn {
            write_chunks(w, vn)?;
        }
        if let Some(m) = material {
            writeln!(w, "usemtl {}", m.name)?;
        }
        write_chunks(w, &f)
    })
}

/// Items per formatting chunk (fixed, so the output never depends on threads).
const LINES_PER_CHUNK: usize = 1 << 14;

/// `line` applied to every item, formatted in parallel chunks, in order.
fn lines<T: Sync>(
    items: &[T],
    line: impl Fn(&mut Vec<u8>, &T) -> std::io::Result<()> + Sync,
) -> Vec<Vec<u8>> {
    use rayon::prelude::*;
    items
        .par_chunks(LINES_PER_CHUNK)
        .map(|chunk| {
            let mut out = Vec::with_capacity(chunk.len() * 32);
            for item in chunk {
                // Writing into a Vec cannot fail.
                let _ = line(&mut out, item);
            }
            out
        })
        .collect()
}

fn write_chunks(w: &mut impl Write, chunks: &[Vec<u8>]) -> std::io::Result<()> {
    for c in chunks {
        w.write_all(c)?;
    }
    Ok(())
}

/// Shared by the mesh writers: array lengths agree, indices in range, values finite.
pub(crate) fn check_mesh(
    positions: &[Vec3],
    uvs: &[Vec2],
    normals: Option<&[Vec3]>,
    triangles: &[[u32; 3]],
) -> Result<(), String> {
    let n = positions.len();
    if uvs.len() != n {
        return Err(format!("{} uvs for {n} vertices", uvs.len()));
    }
    if let Some(ns) = normals {
        if ns.len() != n {
            return Err(format!("{} normals for {n} vertices", ns.len()));
        }
        if let Some(i) = ns.iter().position(|v| !v.is_finite()) {
            return Err(format!("normal {i} is not finite"));
        }
    }
    if let Some(i) = positions.iter().position(|v| !v.is_finite()) {
        return Err(format!("vertex {i} is not finite"));
    }
    if let Some(i) = uvs.iter().position(|v| !v.is_finite()) {
        return Err(format!("uv {i} is not finite"));
    }
    if let Some(t) = triangles
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= n))
    {
        return Err(format!("triangle {t} indexes past the {n} vertices"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;

    #[test]
    fn round_trips_through_tobj_with_flipped_v_and_material() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.0001.obj");
        let mut rng = Pcg64::seed_from_u64(7);
        let n = 50;
        let positions: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random_range(-5.0..5.0)))
            .collect();
        let uvs: Vec<Vec2> = (0..n)
            .map(|_| Vec2::new(rng.random(), rng.random()))
            .collect();
        let normals: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(rng.random(), rng.random(), 1.0).normalize())
            .collect();
        let triangles: Vec<[u32; 3]> = (0..80)
            .map(|_| {
                [
                    rng.random_range(0..n),
                    rng.random_range(0..n),
                    rng.random_range(0..n),
                ]
            })
            .collect();
        let mat = ObjMaterial {
            name: "atlas".into(),
            map_kd: "frame.0001.png".into(),
        };
        write_obj(
            &path,
            &positions,
            &uvs,
            Some(&normals),
            &triangles,
            Some(&mat),
        )
        .unwrap();

        let opts = tobj::LoadOptions {
            single_index: true,
            ..Default::default()
        };
        let (models, materials) = tobj::load_obj(&path, &opts).unwrap();
        let materials = materials.unwrap();
        assert_eq!(materials.len(), 1);
        assert_eq!(materials[0].name, "atlas");
        assert_eq!(
            materials[0].diffuse_texture.as_deref(),
            Some("frame.0001.png")
        );
        assert_eq!(models.len(), 1);
        let m = &models[0].mesh;
        assert_eq!(m.material_id, Some(0));
        assert_eq!(m.indices.len(), triangles.len() * 3);
        // single_index renumbers in first-use order; follow the corners.
        for (k, &idx) in m.indices.iter().enumerate() {
            let src = triangles[k / 3][k % 3] as usize;
            let i = idx as usize;
            assert_eq!(&m.positions[3 * i..3 * i + 3], &positions[src].to_array());
            assert_eq!(m.texcoords[2 * i], uvs[src].x);
            assert_eq!(m.texcoords[2 * i + 1], 1.0 - uvs[src].y);
            assert_eq!(&m.normals[3 * i..3 * i + 3], &normals[src].to_array());
        }
    }

    /// Lines are formatted in parallel chunks: with several chunks per
    /// section, on any thread count, the file is byte for byte what one
    /// sequential `writeln!` per line gives.
    #[test]
    fn chunked_lines_are_the_bytes_of_a_sequential_writer() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.obj");
        let mut rng = Pcg64::seed_from_u64(11);
        let n = 2 * LINES_PER_CHUNK + 123;
        let positions: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(rng.random(), rng.random_range(-9.0..9.0), rng.random()))
            .collect();
        let uvs: Vec<Vec2> = (0..n)
            .map(|_| Vec2::new(rng.random(), rng.random()))
            .collect();
        let normals: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(rng.random(), rng.random(), 1.0).normalize())
            .collect();
        let triangles: Vec<[u32; 3]> = (0..3 * LINES_PER_CHUNK + 7)
            .map(|_| [0; 3].map(|_| rng.random_range(0..n as u32)))
            .collect();
        let mat = ObjMaterial {
            name: "atlas".into(),
            map_kd: "big.png".into(),
        };
        let mut want = String::from("# written by fluidtex\nmtllib big.mtl\n");
        for p in &positions {
            want += &format!("v {} {} {}\n", p.x, p.y, p.z);
        }
        for t in &uvs {
            want += &format!("vt {} {}\n", t.x, 1.0 - t.y);
        }
        for v in &normals {
            want += &format!("vn {} {} {}\n", v.x, v.y, v.z);
        }
        want += "usemtl atlas\n";
        for t in &triangles {
            let [a, b, c] = t.map(|i| i + 1);
            want += &format!("f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}\n");
        }
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                write_obj(
                    &path,
                    &positions,
                    &uvs,
                    Some(&normals),
                    &triangles,
                    Some(&mat),
                )
            })
            .unwrap();
            let got = std::fs::read_to_string(&path).unwrap();
            assert!(got == want, "{threads} threads: the bytes differ");
        }
    }

    #[test]
    fn plain_obj_without_material_or_normals() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.obj");
        write_obj(
            &path,
            &[Vec3::ZERO, Vec3::X, Vec3::Y],
            &[Vec2::ZERO, Vec2::X, Vec2::Y],
            None,
            &[[0, 1, 2]],
            None,
        )
        .unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text,
            "# written by fluidtex\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 1\nvt 1 1\nvt 0 0\nf 1/1 2/2 3/3\n"
        );
        assert!(!mtl_path(&path).exists());
    }

    #[test]
    fn rejects_mismatched_arrays_and_bad_names() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.obj");
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let e = write_obj(&path, &p, &[Vec2::ZERO], None, &[[0, 1, 2]], None).unwrap_err();
        assert!(
            e.to_string()
                .ends_with("m.obj: cannot write: 1 uvs for 3 vertices")
        );
        let uv = [Vec2::ZERO; 3];
        let e = write_obj(&path, &p, &uv, None, &[[0, 1, 3]], None).unwrap_err();
        assert!(
            e.to_string()
                .ends_with("cannot write: triangle 0 indexes past the 3 vertices")
        );
        let mat = ObjMaterial {
            name: "a b".into(),
            map_kd: "x.png".into(),
        };
        assert!(write_obj(&path, &p, &uv, None, &[[0, 1, 2]], Some(&mat)).is_err());
        assert!(!path.exists());
    }
}
