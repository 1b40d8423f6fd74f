//! Indexed triangle meshes with named per-vertex attributes.
//!
//! A [`TriMesh`] is the plain representation every stage shares: a vertex
//! array, a triangle index array and named per-vertex attribute arrays beside
//! them (velocity, uv, ...). Adjacency is never stored in the mesh; it is
//! built on demand by [`topology::Topology`], because most meshes we see live
//! for one frame and many consumers never need it.

pub mod topology;
pub mod validate;

use std::collections::BTreeMap;

use glam::{Vec2, Vec3};

pub use topology::Topology;
pub use validate::{MeshError, ValidationReport, validate};

/// Name of the per-vertex velocity attribute (world units per second).
pub const VELOCITY: &str = "velocity";

/// Name of the per-vertex attribute (and PLY vertex property) holding the
/// exemplar index of region selection ([`crate::exemplar::ExemplarSet`]).
pub const EXEMPLAR_ID: &str = "exemplar_id";

/// One named per-vertex attribute array. Its length equals the vertex count.
#[derive(Clone, Debug, PartialEq)]
pub enum Attribute {
    Scalar(Vec<f32>),
    Vec2(Vec<Vec2>),
    Vec3(Vec<Vec3>),
}

impl Attribute {
    /// Number of elements (vertices) the attribute holds.
    pub fn len(&self) -> usize {
        match self {
            Attribute::Scalar(v) => v.len(),
            Attribute::Vec2(v) => v.len(),
            Attribute::Vec3(v) => v.len(),
        }
    }

    /// True when the attribute holds no element.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of float components per element.
    pub fn components(&self) -> usize {
        match self {
            Attribute::Scalar(_) => 1,
            Attribute::Vec2(_) => 2,
            Attribute::Vec3(_) => 3,
        }
    }

    /// Keeps only the elements whose index is listed, in that order.
    pub fn gather(&self, indices: &[u32]) -> Attribute {
        fn pick<T: Copy>(v: &[T], idx: &[u32]) -> Vec<T> {
            idx.iter().map(|&i| v[i as usize]).collect()
        }
        match self {
            Attribute::Scalar(v) => Attribute::Scalar(pick(v, indices)),
            Attribute::Vec2(v) => Attribute::Vec2(pick(v, indices)),
            Attribute::Vec3(v) => Attribute::Vec3(pick(v, indices)),
        }
    }
}

/// An indexed triangle mesh with named per-vertex attributes.
///
/// Triangles are counter-clockwise seen from the side their normal points to.
/// Invariants (checked by [`validate()`]): every index is below
/// `positions.len()`, every attribute has `positions.len()` elements.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex attributes by name, ordered so iteration is deterministic.
    pub attributes: BTreeMap<String, Attribute>,
}

impl TriMesh {
    pub fn new(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Self {
        TriMesh {
            positions,
            triangles,
            attributes: BTreeMap::new(),
        }
    }

    /// Builder-style attachment of the velocity attribute.
    pub fn with_velocity(mut self, velocity: Vec<Vec3>) -> Self {
        self.attributes
            .insert(VELOCITY.to_string(), Attribute::Vec3(velocity));
        self
    }

    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// True when the mesh has no triangle (the fluid may vanish).
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Per-vertex velocity, if the mesh carries one.
    pub fn velocity(&self) -> Option<&[Vec3]> {
        match self.attributes.get(VELOCITY) {
            Some(Attribute::Vec3(v)) => Some(v),
            _ => None,
        }
    }

    /// The three corner positions of triangle `t`.
    #[inline]
    pub fn corners(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Unnormalised normal of triangle `t` (length = twice its area).
    #[inline]
    pub fn triangle_cross(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.corners(t);
        (b - a).cross(c - a)
    }

    /// Unit normal of triangle `t` (zero for a degenerate triangle).
    #[inline]
    pub fn triangle_normal(&self, t: usize) -> Vec3 {
        self.triangle_cross(t).normalize_or_zero()
    }

    #[inline]
    pub fn triangle_area(&self, t: usize) -> f32 {
        0.5 * self.triangle_cross(t).length()
    }

    /// Sum of the triangle areas.
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| self.triangle_area(t) as f64)
            .sum()
    }

    /// Area-weighted vertex normals (unit length; zero for isolated vertices).
    pub fn vertex_normals(&self) -> Vec<Vec3> {
        let mut n = vec![Vec3::ZERO; self.positions.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            let c = self.triangle_cross(t);
            for &v in tri {
                n[v as usize] += c;
            }
        }
        n.iter().map(|v| v.normalize_or_zero()).collect()
    }

    /// Axis-aligned bounding box `(min, max)`, `None` for a mesh without vertices.
    pub fn bounding_box(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))),
        )
    }

    /// Mean edge length over all triangle edges (0 for an empty mesh).
    pub fn mean_edge_length(&self) -> f32 {
        if self.triangles.is_empty() {
            return 0.0;
        }
        let mut sum = 0.0f64;
        for t in 0..self.triangles.len() {
            let [a, b, c] = self.corners(t);
            sum += (a.distance(b) + b.distance(c) + c.distance(a)) as f64;
        }
        (sum / (3 * self.triangles.len()) as f64) as f32
    }

    /// A new mesh made of the listed triangles only, with vertices renumbered
    /// in first-use order and attributes carried along. Returns the mesh and,
    /// per new vertex, the index of the vertex it came from.
    pub fn submesh(&self, triangles: &[u32]) -> (TriMesh, Vec<u32>) {
        let mut remap = vec![u32::MAX; self.positions.len()];
        let mut source = Vec::new();
        let mut tris = Vec::with_capacity(triangles.len());
        for &t in triangles {
            let mut out = [0u32; 3];
            for (k, &v) in self.triangles[t as usize].iter().enumerate() {
                if remap[v as usize] == u32::MAX {
                    remap[v as usize] = source.len() as u32;
                    source.push(v);
                }
                out[k] = remap[v as usize];
            }
            tris.push(out);
        }
        let positions = source.iter().map(|&v| self.positions[v as usize]).collect();
        let attributes = self
            .attributes
            .iter()
            .map(|(k, a)| (k.clone(), a.gather(&source)))
            .collect();
        (
            TriMesh {
                positions,
                triangles: tris,
                attributes,
            },
            source,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> TriMesh {
        TriMesh::new(
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .with_velocity(vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE])
    }

    #[test]
    fn area_normal_and_bbox_of_a_unit_quad() {
        let m = quad();
        assert_eq!(m.area(), 1.0);
        assert_eq!(m.triangle_normal(0), Vec3::Z);
        assert_eq!(
            m.bounding_box(),
            Some((Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0)))
        );
        assert!(m.vertex_normals().iter().all(|n| *n == Vec3::Z));
    }

    #[test]
    fn submesh_renumbers_and_carries_attributes() {
        let m = quad();
        let (s, src) = m.submesh(&[1]);
        assert_eq!(src, vec![0, 2, 3]);
        assert_eq!(s.triangles, vec![[0, 1, 2]]);
        assert_eq!(s.positions[1], Vec3::new(1.0, 1.0, 0.0));
        assert_eq!(s.velocity(), Some(&[Vec3::X, Vec3::Z, Vec3::ONE][..]));
    }
}
