//! The switches of a frame pair split by where the carried point lands:
//! the bulk of the liquid, thin sheets, or droplets smaller than a patch.
//! A violent liquid renews its texture for different reasons in each: a
//! droplet that tears off or merges takes its patches with it, a sheet is
//! stretched fast, the bulk should ride the flow.
//!
//! - **Droplet**: the point's connected piece of surface (edge-connected
//!   triangles) has less area than a disc of the patch radius r: it is
//!   smaller than one patch.
//! - **Sheet**: the liquid under the point is thinner than r/2: the point
//!   r/2 below the surface, along the triangle's normal, is outside the
//!   liquid (its closest surface point faces it). The test needs outward
//!   normals, as every simulator writes them.
//! - **Bulk**: everything else.

use std::collections::BTreeMap;

use glam::Vec3;
use serde::Serialize;

use super::PointEnds;
use crate::mesh::{Topology, TriMesh};
use crate::metrics::{self, SourceSwitch};
use crate::surface::{SurfaceIndex, SurfacePoint};

/// Where a surface point lies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Region {
    Bulk,
    Sheet,
    Droplet,
}

impl Region {
    pub const ALL: [Region; 3] = [Region::Bulk, Region::Sheet, Region::Droplet];

    /// The key in `stats.F.json`.
    pub fn name(self) -> &'static str {
        match self {
            Region::Bulk => "bulk",
            Region::Sheet => "sheet",
            Region::Droplet => "droplet",
        }
    }
}

/// Classifies points of one frame's surface ([`Region`]).
pub struct RegionMap<'a> {
    mesh: &'a TriMesh,
    index: &'a SurfaceIndex,
    /// Component label per triangle.
    label: Vec<u32>,
    /// Area per component.
    area: Vec<f64>,
    radius: f32,
}

impl<'a> RegionMap<'a> {
    /// The regions of `mesh` (with its `index` and `topology`) for patches
    /// of radius `radius`.
    pub fn new(
        mesh: &'a TriMesh,
        index: &'a SurfaceIndex,
        topology: &Topology,
        radius: f32,
    ) -> RegionMap<'a> {
        let (label, count) = topology.components();
        let mut area = vec![0.0f64; count as usize];
        for (t, &l) in label.iter().enumerate() {
            if let Some(a) = area.get_mut(l as usize) {
                *a += f64::from(mesh.triangle_area(t));
            }
        }
        RegionMap {
            mesh,
            index,
            label,
            area,
            radius,
        }
    }

    /// The region of `sp`; `None` for a point off the mesh.
    pub fn region(&self, sp: &SurfacePoint) -> Option<Region> {
        let t = sp.triangle as usize;
        let piece = *self.area.get(*self.label.get(t)? as usize)?;
        if piece < std::f64::consts::PI * f64::from(self.radius).powi(2) {
            return Some(Region::Droplet);
        }
        let p = sp.position(self.mesh);
        let n = self.mesh.triangle_normal(t);
        if !(p.is_finite() && n != Vec3::ZERO) {
            return None;
        }
        let depth = 0.5 * self.radius;
        let q = p - n * depth;
        let below = self
            .index
            .closest(q, 2.0 * depth)
            .or_else(|| self.index.closest_unbounded(q))?;
        let facing = self.mesh.triangle_normal(below.location.triangle as usize);
        Some(if (q - below.point).dot(facing) > 0.0 {
            Region::Sheet
        } else {
            Region::Bulk
        })
    }
}

/// The switches of one region: how many points it has with a patch at
/// both ends, and the shares of [`SourceSwitch`] and [`metrics::SwitchCauses`]
/// over them (NaN, written `null`, where none or not recorded).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RegionSwitch {
    pub points: usize,
    pub switch_share: f64,
    pub forced_share: f64,
    pub unforced_share: f64,
}

/// Per region (by [`Region::name`]), the switches of the points `ends`
/// whose carried end lies in that region (`regions`, in the same order; a
/// point without a region counts in none).
pub fn switch_by_region(
    ends: &[PointEnds],
    regions: &[Option<Region>],
) -> BTreeMap<&'static str, RegionSwitch> {
    Region::ALL
        .iter()
        .map(|&r| {
            let mine: Vec<&PointEnds> = (ends.iter().zip(regions))
                .filter(|(_, g)| **g == Some(r))
                .map(|(e, _)| e)
                .collect();
            let s0: Vec<u32> = mine.iter().map(|e| e.sources[0]).collect();
            let s1: Vec<u32> = mine.iter().map(|e| e.sources[1]).collect();
            let r1: Vec<u8> = mine.iter().map(|e| e.renewal).collect();
            // Same lengths by construction: these cannot fail.
            let switch = metrics::source_switch(&s0, &s1).unwrap_or(SourceSwitch {
                covered: 0,
                switched: 0,
                lost: 0,
                gained: 0,
            });
            let causes = metrics::switch_causes(&s0, &s1, &r1).unwrap_or_default();
            (
                r.name(),
                RegionSwitch {
                    points: switch.covered,
                    switch_share: switch.share(),
                    forced_share: causes.forced_share(),
                    unforced_share: causes.unforced_share(),
                },
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::fixtures::icosphere;
    use crate::provenance::{RENEWAL_DISTORTED, RENEWAL_HELD};

    /// A unit sphere (bulk), a flat slab 0.05 thick (sheet) and a small
    /// sphere of radius 0.05 (droplet), apart.
    fn three_pieces() -> TriMesh {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        let mut add = |mesh: &TriMesh, f: &dyn Fn(Vec3) -> Vec3| {
            let base = positions.len() as u32;
            positions.extend(mesh.positions.iter().map(|&p| f(p)));
            triangles.extend(mesh.triangles.iter().map(|t| t.map(|v| v + base)));
        };
        let sphere = icosphere(8);
        add(&sphere, &|p| p);
        // The slab: the sphere squashed to 0.025 half-thickness, 1.5 wide.
        add(&sphere, &|p| {
            Vec3::new(1.5 * p.x + 4.0, 1.5 * p.y, 0.025 * p.z)
        });
        add(&sphere, &|p| 0.05 * p + Vec3::new(-4.0, 0.0, 0.0));
        TriMesh::new(positions, triangles)
    }

    #[test]
    fn pieces_are_told_apart_by_size_and_thickness() {
        let mesh = three_pieces();
        let index = SurfaceIndex::new(&mesh);
        let topology = Topology::new(mesh.positions.len(), &mesh.triangles);
        let map = RegionMap::new(&mesh, &index, &topology, 0.3);
        let mut seen = BTreeMap::new();
        for t in 0..mesh.triangles.len() {
            let sp = SurfacePoint::new(t as u32, [1.0 / 3.0; 3]);
            let p = sp.position(&mesh);
            let expected = if p.x < -3.0 {
                Region::Droplet
            } else if p.x > 2.0 {
                // The slab's rim is rounded: only its flat faces are sheet.
                if (p.x - 4.0).powi(2) + p.y * p.y > 1.0 {
                    continue;
                }
                Region::Sheet
            } else {
                Region::Bulk
            };
            assert_eq!(map.region(&sp), Some(expected), "triangle {t} at {p}");
            *seen.entry(expected).or_insert(0) += 1;
        }
        assert_eq!(seen.len(), 3, "{seen:?}");
        // A point off the mesh has no region.
        assert_eq!(
            map.region(&SurfacePoint::new(u32::MAX, [1.0, 0.0, 0.0])),
            None
        );
    }

    #[test]
    fn switches_are_counted_in_the_region_of_their_end() {
        let ends = [
            ([1, 1], RENEWAL_HELD),
            ([1, 2], RENEWAL_HELD),
            ([3, 4], 0),
            ([5, 6], RENEWAL_HELD | RENEWAL_DISTORTED),
            ([7, 7], RENEWAL_HELD),
        ]
        .map(|(sources, renewal)| PointEnds { sources, renewal });
        let regions = [
            Some(Region::Bulk),
            Some(Region::Bulk),
            Some(Region::Droplet),
            Some(Region::Droplet),
            None,
        ];
        let by = switch_by_region(&ends, &regions);
        assert_eq!(by["bulk"].points, 2);
        assert_eq!(by["bulk"].switch_share, 0.5);
        assert_eq!(
            (by["bulk"].forced_share, by["bulk"].unforced_share),
            (0.0, 0.5)
        );
        assert_eq!(by["droplet"].points, 2);
        assert_eq!(by["droplet"].forced_share, 1.0);
        assert_eq!(by["sheet"].points, 0);
        assert!(by["sheet"].switch_share.is_nan());
    }
}
