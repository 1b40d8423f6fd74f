//! PLY writer (binary little endian, or ASCII for debugging) with
//! per-vertex `vx vy vz` velocity when the mesh has one, and every scalar
//! attribute (a scene's `temperature`, `age`) as a float property of its
//! own name, so that what a scene simulates beside the motion reaches the
//! texturing run (read back with [`super::ReadOptions::scalar_attributes`]).
//! Used by the scene generator.
//!
//! Written by hand rather than with ply-rs-bw's writer, which goes through
//! its dynamically typed `HashMap` element (slow for 100k vertices); the
//! layout we emit is fixed: `float x y z [vx vy vz] [scalars, by name]`,
//! `list uchar int vertex_indices`. A mesh without scalar attributes is
//! written exactly as before they existed.

use std::io::Write;
use std::path::Path;

use super::{IoError, write_atomic};
use crate::mesh::{Attribute, TriMesh};

/// PLY payload encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyEncoding {
    BinaryLittleEndian,
    Ascii,
}

/// The mesh can be written as it is: every triangle corner names a
/// vertex, and a velocity, if any, is given for every vertex.
fn check_writable(path: &Path, mesh: &TriMesh) -> Result<(), IoError> {
    if let Some(&[a, b, c]) = mesh
        .triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= mesh.positions.len()))
    {
        return Err(IoError::Unwritable {
            path: path.to_path_buf(),
            reason: format!(
                "triangle [{a}, {b}, {c}] indexes past the {} vertices",
                mesh.positions.len()
            ),
        });
    }
    if let Some(v) = mesh.velocity()
        && v.len() != mesh.positions.len()
    {
        return Err(IoError::Unwritable {
            path: path.to_path_buf(),
            reason: format!(
                "{} velocities for {} vertices",
                v.len(),
                mesh.positions.len()
            ),
        });
    }
    Ok(())
}

/// Writes `mesh` (positions, triangles, velocity if present and every
/// scalar attribute, in name order) atomically.
pub fn write_ply(path: &Path, mesh: &TriMesh, encoding: PlyEncoding) -> Result<(), IoError> {
    check_writable(path, mesh)?;
    let velocity = mesh.velocity();
    let scalars = scalar_attributes(path, mesh)?;
    write_atomic(path, |w| {
        let format = match encoding {
            PlyEncoding::BinaryLittleEndian => "binary_little_endian",
            PlyEncoding::Ascii => "ascii",
        };
        write!(
            w,
            "ply\nformat {format} 1.0\ncomment written by fluidtex\nelement vertex {}\n\
             property float x\nproperty float y\nproperty float z\n",
            mesh.positions.len()
        )?;
        if velocity.is_some() {
            w.write_all(b"property float vx\nproperty float vy\nproperty float vz\n")?;
        }
        for (name, _) in &scalars {
            writeln!(w, "property float {name}")?;
        }
        write!(
            w,
            "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
            mesh.triangles.len()
        )?;
        match encoding {
            PlyEncoding::BinaryLittleEndian => {
                let mut buf = Vec::with_capacity(24 * mesh.positions.len().min(1 << 16));
                for (i, p) in mesh.positions.iter().enumerate() {
                    for c in p.to_array() {
                        buf.extend_from_slice(&c.to_le_bytes());
                    }
                    if let Some(v) = velocity {
                        for c in v[i].to_array() {
                            buf.extend_from_slice(&c.to_le_bytes());
                        }
                    }
                    for (_, values) in &scalars {
                        buf.extend_from_slice(&values[i].to_le_bytes());
                    }
                    if buf.len() >= 1 << 20 {
                        w.write_all(&buf)?;
                        buf.clear();
                    }
                }
                for t in &mesh.triangles {
                    buf.push(3);
                    for &i in t {
                        buf.extend_from_slice(&(i as i32).to_le_bytes());
                    }
                    if buf.len() >= 1 << 20 {
                        w.write_all(&buf)?;
                        buf.clear();
                    }
                }
                w.write_all(&buf)?;
            }
            PlyEncoding::Ascii => {
                for (i, p) in mesh.positions.iter().enumerate() {
                    write!(w, "{} {} {}", p.x, p.y, p.z)?;
                    if let Some(v) = velocity {
                        write!(w, " {} {} {}", v[i].x, v[i].y, v[i].z)?;
                    }
                    for (_, values) in &scalars {
                        write!(w, " {}", values[i])?;
                    }
                    w.write_all(b"\n")?;
                }
                for [a, b, c] in &mesh.triangles {
                    writeln!(w, "3 {a} {b} {c}")?;
                }
            }
        }
        Ok(())
    })
}

/// The scalar attributes to write, by name, each checked: one value per
/// vertex, a name a PLY header can hold that no other property has.
fn scalar_attributes<'a>(
    path: &Path,
    mesh: &'a TriMesh,
) -> Result<Vec<(&'a str, &'a [f32])>, IoError> {
    let unwritable = |reason: String| IoError::Unwritable {
        path: path.to_path_buf(),
        reason,
    };
    let mut out = Vec::new();
    for (name, attribute) in &mesh.attributes {
        let Attribute::Scalar(values) = attribute else {
            continue;
        };
        if name.is_empty() || !name.bytes().all(|b| b.is_ascii_graphic()) {
            return Err(unwritable(format!(
                "attribute {name:?} is not a PLY property name (printable ASCII, no spaces)"
            )));
        }
        let taken = ["x", "y", "z"].contains(&name.as_str())
            || (mesh.velocity().is_some() && ["vx", "vy", "vz"].contains(&name.as_str()));
        if taken {
            return Err(unwritable(format!(
                "attribute {name:?} has the name of a position or velocity property"
            )));
        }
        if values.len() != mesh.positions.len() {
            return Err(unwritable(format!(
                "attribute {name} has {} values for {} vertices",
                values.len(),
                mesh.positions.len()
            )));
        }
        out.push((name.as_str(), values.as_slice()));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;
    use crate::io::{ReadOptions, ply::read_ply};

    fn random_mesh(seed: u64) -> TriMesh {
        let mut rng = Pcg64::seed_from_u64(seed);
        let n = rng.random_range(3..200);
        let mut v3 = || {
            Vec3::new(
                rng.random_range(-1e3..1e3),
                rng.random::<f32>(),
                rng.random_range(-1e-6..1e-6),
            )
        };
        let positions: Vec<Vec3> = (0..n).map(|_| v3()).collect();
        let velocity: Vec<Vec3> = (0..n).map(|_| v3()).collect();
        let triangles = (0..rng.random_range(0..300))
            .map(|_| {
                [
                    rng.random_range(0..n as u32),
                    rng.random_range(0..n as u32),
                    rng.random_range(0..n as u32),
                ]
            })
            .collect();
        TriMesh::new(positions, triangles).with_velocity(velocity)
    }

    #[test]
    fn binary_and_ascii_round_trip_bit_exactly_through_our_reader() {
        let dir = tempfile::tempdir().unwrap();
        for seed in 0..8 {
            let mut mesh = random_mesh(seed);
            if seed == 3 {
                mesh.attributes.clear();
            }
            for (enc, name) in [
                (PlyEncoding::BinaryLittleEndian, "b.ply"),
                (PlyEncoding::Ascii, "a.ply"),
            ] {
                let path = dir.path().join(name);
                write_ply(&path, &mesh, enc).unwrap();
                let back = read_ply(&path, &ReadOptions::default()).unwrap();
                assert_eq!(back, mesh, "seed {seed} {enc:?}");
            }
        }
    }

    #[test]
    fn refuses_out_of_range_triangles() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = TriMesh::new(vec![Vec3::ZERO; 3], vec![[0, 1, 3]]);
        let path = dir.path().join("x.ply");
        let err = write_ply(&path, &mesh, PlyEncoding::Ascii).unwrap_err();
        assert!(
            err.to_string()
                .ends_with("x.ply: cannot write: triangle [0, 1, 3] indexes past the 3 vertices")
        );
        assert!(!path.exists());
    }
}
