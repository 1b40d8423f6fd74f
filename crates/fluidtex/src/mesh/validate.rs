//! Checks that a mesh read from a user's file can be trusted by every later
//! stage: indices in range, finite positions and attributes, attribute arrays
//! of the right length. Zero-area triangles are not an error (surface
//! reconstruction produces a few); they are dropped and counted.

use thiserror::Error;

use super::{Attribute, TriMesh};

/// What is wrong with a mesh. Element indices are zero-based, as in the file.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MeshError {
    #[error("face {face} refers to vertex {index}, but the mesh has {vertex_count} vertices")]
    IndexOutOfRange {
        face: usize,
        index: u32,
        vertex_count: usize,
    },
    #[error("vertex {vertex} has a non-finite position ({value})")]
    NonFinitePosition { vertex: usize, value: String },
    #[error("vertex {vertex} has a non-finite {attribute} ({value})")]
    NonFiniteAttribute {
        attribute: String,
        vertex: usize,
        value: String,
    },
    #[error("attribute {attribute} has {len} values for {vertex_count} vertices")]
    AttributeLength {
        attribute: String,
        len: usize,
        vertex_count: usize,
    },
}

/// What validation changed in a mesh it accepted.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct ValidationReport {
    /// Triangles removed because their area was zero (or two corners coincide).
    pub dropped_degenerate: usize,
}

/// Validates `mesh` in place: returns the first problem found, or drops
/// degenerate triangles and reports how many went.
pub fn validate(mesh: &mut TriMesh) -> Result<ValidationReport, MeshError> {
    let n = mesh.positions.len();
    for (vertex, p) in mesh.positions.iter().enumerate() {
        if !p.is_finite() {
            return Err(MeshError::NonFinitePosition {
                vertex,
                value: format!("{} {} {}", p.x, p.y, p.z),
            });
        }
    }
    for (face, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&index) = tri.iter().find(|&&i| i as usize >= n) {
            return Err(MeshError::IndexOutOfRange {
                face,
                index,
                vertex_count: n,
            });
        }
    }
    for (name, attr) in &mesh.attributes {
        if attr.len() != n {
            return Err(MeshError::AttributeLength {
                attribute: name.clone(),
                len: attr.len(),
                vertex_count: n,
            });
        }
        let bad = match attr {
            Attribute::Scalar(v) => v
                .iter()
                .position(|x| !x.is_finite())
                .map(|i| (i, format!("{}", v[i]))),
            Attribute::Vec2(v) => v
                .iter()
                .position(|x| !x.is_finite())
                .map(|i| (i, format!("{} {}", v[i].x, v[i].y))),
            Attribute::Vec3(v) => v
                .iter()
                .position(|x| !x.is_finite())
                .map(|i| (i, format!("{} {} {}", v[i].x, v[i].y, v[i].z))),
        };
        if let Some((vertex, value)) = bad {
            return Err(MeshError::NonFiniteAttribute {
                attribute: name.clone(),
                vertex,
                value,
            });
        }
    }
    let before = mesh.triangles.len();
    let positions = &mesh.positions;
    mesh.triangles.retain(|&[a, b, c]| {
        if a == b || b == c || a == c {
            return false;
        }
        let (pa, pb, pc) = (
            positions[a as usize],
            positions[b as usize],
            positions[c as usize],
        );
        (pb - pa).cross(pc - pa).length_squared() > 0.0
    });
    Ok(ValidationReport {
        dropped_degenerate: before - mesh.triangles.len(),
    })
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    fn tri() -> TriMesh {
        TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]])
    }

    #[test]
    fn accepts_a_good_mesh_unchanged() {
        let mut m = tri().with_velocity(vec![Vec3::ONE; 3]);
        let before = m.clone();
        assert_eq!(validate(&mut m), Ok(ValidationReport::default()));
        assert_eq!(m, before);
    }

    #[test]
    fn rejects_out_of_range_index() {
        let mut m = tri();
        m.triangles.push([0, 2, 7]);
        assert_eq!(
            validate(&mut m),
            Err(MeshError::IndexOutOfRange {
                face: 1,
                index: 7,
                vertex_count: 3
            })
        );
    }

    #[test]
    fn rejects_nan_position_and_velocity() {
        let mut m = tri();
        m.positions[2].y = f32::NAN;
        assert!(matches!(
            validate(&mut m),
            Err(MeshError::NonFinitePosition { vertex: 2, .. })
        ));
        let mut m = tri().with_velocity(vec![
            Vec3::ZERO,
            Vec3::new(0.0, f32::INFINITY, 0.0),
            Vec3::ZERO,
        ]);
        let err = validate(&mut m).unwrap_err();
        assert_eq!(
            err.to_string(),
            "vertex 1 has a non-finite velocity (0 inf 0)"
        );
    }

    #[test]
    fn rejects_short_attribute() {
        let mut m = tri().with_velocity(vec![Vec3::ZERO; 2]);
        assert!(matches!(
            validate(&mut m),
            Err(MeshError::AttributeLength {
                len: 2,
                vertex_count: 3,
                ..
            })
        ));
    }

    #[test]
    fn drops_and_counts_degenerate_triangles() {
        let mut m = tri();
        m.positions.push(Vec3::new(2.0, 0.0, 0.0));
        m.triangles.push([0, 1, 3]); // collinear
        m.triangles.push([1, 1, 2]); // repeated corner
        assert_eq!(validate(&mut m).map(|r| r.dropped_degenerate), Ok(2));
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }
}
