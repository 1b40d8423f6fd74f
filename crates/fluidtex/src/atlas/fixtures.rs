//! Procedural closed surfaces for atlas tests and `examples/atlas_bench.rs`:
//! a geodesic sphere, a torus, and a liquid-like blob (a sphere displaced by
//! smooth seeded noise, with detached droplets), alone or in a splash of
//! many small droplets. Closed surfaces are the
//! hard case for charting: none of them can be flattened in one piece.

use std::collections::BTreeMap;

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use crate::mesh::TriMesh;

/// The triangles of an `nx × ny` grid of quads over the `(nx + 1) ×
/// (ny + 1)` vertices numbered row by row, two triangles per quad,
/// counter-clockwise in a y-up frame.
pub fn grid_triangles(nx: u32, ny: u32) -> Vec<[u32; 3]> {
    let id = |i: u32, j: u32| j * (nx + 1) + i;
    let mut triangles = Vec::with_capacity(2 * (nx * ny) as usize);
    for j in 0..ny {
        for i in 0..nx {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    triangles
}

/// A flat square \[lo, hi]² at height `z`, `n × n` quads ([`grid_triangles`]),
/// facing +z, or −z when `flip` (every triangle's corners reversed).
pub fn square_sheet(n: u32, lo: f32, hi: f32, z: f32, flip: bool) -> TriMesh {
    let at = move |k: u32| lo + (hi - lo) * (k as f32 / n as f32);
    let positions = (0..=n)
        .flat_map(|j| (0..=n).map(move |i| Vec3::new(at(i), at(j), z)))
        .collect();
    let triangles = (grid_triangles(n, n).into_iter())
        .map(|t| if flip { [t[0], t[2], t[1]] } else { t })
        .collect();
    TriMesh::new(positions, triangles)
}

/// Unit sphere from an icosahedron whose faces are split into
/// `frequency²` triangles each (20·frequency² triangles, frequency ≥ 1),
/// counter-clockwise seen from outside.
pub fn icosphere(frequency: u32) -> TriMesh {
    let f = frequency.max(1);
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let corners = [
        Vec3::new(-1.0, t, 0.0),
        Vec3::new(1.0, t, 0.0),
        Vec3::new(-1.0, -t, 0.0),
        Vec3::new(1.0, -t, 0.0),
        Vec3::new(0.0, -1.0, t),
        Vec3::new(0.0, 1.0, t),
        Vec3::new(0.0, -1.0, -t),
        Vec3::new(0.0, 1.0, -t),
        Vec3::new(t, 0.0, -1.0),
        Vec3::new(t, 0.0, 1.0),
        Vec3::new(-t, 0.0, -1.0),
        Vec3::new(-t, 0.0, 1.0),
    ];
    let faces: [[u32; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    // A point is keyed by its integer barycentric weights on the original
    // corners, so points on shared edges weld exactly.
    let mut index: BTreeMap<Vec<(u32, u32)>, u32> = BTreeMap::new();
    let mut positions = Vec::new();
    let mut vertex = |weights: [(u32, u32); 3]| -> u32 {
        let mut key: Vec<(u32, u32)> = weights.iter().copied().filter(|w| w.1 > 0).collect();
        key.sort_unstable();
        *index.entry(key.clone()).or_insert_with(|| {
            let p: Vec3 = key
                .iter()
                .map(|&(c, w)| corners[c as usize] * w as f32)
                .sum();
            positions.push(p.normalize());
            (positions.len() - 1) as u32
        })
    };
    let mut triangles = Vec::new();
    for face in faces {
        let [a, b, c] = face;
        let mut id = |i: u32, j: u32| vertex([(a, f - i - j), (b, i), (c, j)]);
        for j in 0..f {
            for i in 0..f - j {
                let (p, q, r) = (id(i, j), id(i + 1, j), id(i, j + 1));
                triangles.push([p, q, r]);
                if i + j + 2 <= f {
                    let s = id(i + 1, j + 1);
                    triangles.push([q, s, r]);
                }
            }
        }
    }
    TriMesh::new(positions, triangles)
}

/// Torus around z with radii `major` > `minor`, `nu × nv` quads split in
/// two, counter-clockwise seen from outside.
pub fn torus(major: f32, minor: f32, nu: u32, nv: u32) -> TriMesh {
    let mut positions = Vec::new();
    for j in 0..nv {
        let v = std::f32::consts::TAU * j as f32 / nv as f32;
        for i in 0..nu {
            let u = std::f32::consts::TAU * i as f32 / nu as f32;
            let r = major + minor * v.cos();
            positions.push(Vec3::new(r * u.cos(), r * u.sin(), minor * v.sin()));
        }
    }
    let id = |i: u32, j: u32| (j % nv) * nu + (i % nu);
    let mut triangles = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    TriMesh::new(positions, triangles)
}

/// A liquid-like surface of about `triangles` triangles: a unit sphere
/// displaced radially by a sum of seeded sinusoids (smooth bumps and
/// hollows, amplitude ≈ 0.3) plus eight small detached droplets.
pub fn liquid_blob(triangles: u32, seed: u64) -> TriMesh {
    let mut rng = Pcg64::seed_from_u64(seed);
    let main_freq = ((0.9 * triangles as f32 / 20.0).sqrt().round() as u32).max(2);
    let mut mesh = icosphere(main_freq);
    let waves: Vec<(Vec3, f32, f32, f32)> = (0..7)
        .map(|_| {
            (
                random_direction(&mut rng, Vec3::X),
                rng.random_range(1.5..4.5),
                rng.random_range(0.0..std::f32::consts::TAU),
                rng.random_range(0.02..0.07),
            )
        })
        .collect();
    for p in &mut mesh.positions {
        let d: f32 = waves
            .iter()
            .map(|(dir, freq, phase, amp)| amp * (freq * dir.dot(*p) + phase).sin())
            .sum();
        *p *= 1.0 + d;
    }
    let drop_tris = (triangles as f32 * 0.1 / 8.0).max(20.0);
    let drop_freq = ((drop_tris / 20.0).sqrt().round() as u32).max(1);
    for _ in 0..8 {
        let centre = random_direction(&mut rng, Vec3::Y) * rng.random_range(1.6..2.2);
        let radius = rng.random_range(0.08..0.2);
        append_sphere(&mut mesh, &icosphere(drop_freq), centre, radius);
    }
    mesh
}

/// A splashy frame: [`liquid_blob`] of about `triangles` triangles plus
/// `droplets` small spheres (80 or 180 triangles, radius 0.03–0.15) in a
/// shell around it, the many small charts a splash from another simulator
/// gives the packer.
pub fn splash(triangles: u32, droplets: u32, seed: u64) -> TriMesh {
    let mut mesh = liquid_blob(triangles, seed);
    let mut rng = Pcg64::seed_from_u64(seed ^ 0x5eed);
    for _ in 0..droplets {
        let centre = random_direction(&mut rng, Vec3::Z) * rng.random_range(1.5..3.0);
        let radius = rng.random_range(0.03..0.15);
        append_sphere(
            &mut mesh,
            &icosphere(rng.random_range(2..=3)),
            centre,
            radius,
        );
    }
    mesh
}

/// A direction from a uniform draw in the cube (`fallback` if it is ~0).
fn random_direction(rng: &mut Pcg64, fallback: Vec3) -> Vec3 {
    Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
    .normalize_or(fallback)
}

/// Appends `sphere` (a unit sphere) scaled by `radius` at `centre`.
fn append_sphere(mesh: &mut TriMesh, sphere: &TriMesh, centre: Vec3, radius: f32) {
    let base = mesh.positions.len() as u32;
    mesh.positions
        .extend(sphere.positions.iter().map(|p| centre + *p * radius));
    mesh.triangles
        .extend(sphere.triangles.iter().map(|t| t.map(|v| v + base)));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Topology;

    fn assert_closed_and_outward(mesh: &TriMesh, centre_of: impl Fn(Vec3) -> Vec3) {
        let topo = Topology::new(mesh.positions.len(), &mesh.triangles);
        assert_eq!(topo.boundary_edge_count(), 0);
        for t in 0..mesh.triangles.len() {
            let [a, b, c] = mesh.corners(t);
            let centroid = (a + b + c) / 3.0;
            let out = centroid - centre_of(centroid);
            assert!(
                mesh.triangle_cross(t).dot(out) > 0.0,
                "triangle {t} faces inward"
            );
        }
    }

    #[test]
    fn icosphere_is_a_closed_outward_sphere() {
        let m = icosphere(4);
        assert_eq!(m.triangles.len(), 320);
        assert_eq!(m.positions.len(), 162); // 10 f² + 2
        assert_closed_and_outward(&m, |_| Vec3::ZERO);
    }

    #[test]
    fn torus_is_closed_and_outward() {
        let m = torus(1.0, 0.3, 24, 12);
        assert_eq!(m.triangles.len(), 576);
        assert_closed_and_outward(&m, |p| Vec3::new(p.x, p.y, 0.0).normalize() * 1.0);
    }
}
