//! Cheap triangle-quality improvement for marching-cubes meshes: tangential
//! relaxation with re-projection onto the exact level set.
//!
//! Marching cubes puts a vertex wherever the surface crosses a grid edge;
//! where it passes close to a grid node, several vertices crowd together and
//! form slivers (min angle near 0°), which would make texture patches erode
//! needlessly. Each iteration moves every interior vertex towards the
//! area-weighted centroid of its incident triangles, keeping only the
//! tangential part of the move (the tangential smoothing of isotropic
//! remeshing, Botsch & Kobbelt 2004, sec. 3; Botsch et al., "Polygon Mesh
//! Processing" 2010, sec. 6.5.1), then takes one Newton step along the vertex
//! normal on the true surface function φ(·, t), so vertices end on the exact
//! surface rather than on the linear interpolant. A move that flips or nearly collapses a
//! triangle is undone for that triangle's vertices. Boundary vertices of open
//! surfaces stay where marching cubes put them (on the domain's faces).
//!
//! Connectivity is untouched, so closedness and orientation carry over.

use glam::DVec3;
use rayon::prelude::*;

use super::flow::Motion;
use crate::mesh::Topology;

/// Iterations of relaxation + projection.
pub const RELAX_ITERATIONS: usize = 3;
/// Newton steps after the last relaxation.
pub const FINAL_NEWTON_STEPS: usize = 1;

/// Relaxes and projects `positions` in place (see the module doc). `h` is
/// the grid cell size; no Newton step moves a vertex by more than h/2.
///
/// Evaluations of φ dominate the cost (each is a backtrace), so the slope of
/// φ along the vertex normal is measured once per vertex (two evaluations,
/// δ = h/20 apart) and reused: the moves are a fraction of a cell, over
/// which |∇φ| barely changes, and a slightly wrong slope only slows Newton's
/// convergence, it does not move its fixed point (φ = 0). Every later step
/// costs one evaluation.
pub fn relax(
    positions: &mut [DVec3],
    triangles: &[[u32; 3]],
    motion: &dyn Motion,
    t: f64,
    h: f64,
    iterations: usize,
) {
    let n = positions.len();
    let topo = Topology::new(n, triangles);
    let fixed: Vec<bool> = (0..n as u32).map(|v| topo.is_boundary_vertex(v)).collect();
    let delta = h / 20.0;
    let normals = vertex_normals(positions, triangles);
    let slopes: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|v| {
            if fixed[v] || normals[v] == DVec3::ZERO {
                return 0.0;
            }
            let x = positions[v];
            (motion.phi(x + delta * normals[v], t) - motion.phi(x, t)) / delta
        })
        .collect();
    let step = |x: DVec3, nrm: DVec3, slope: f64| -> DVec3 {
        // A slope this small means the normal is nearly tangent to the level
        // set (or φ is flat): no trustworthy step.
        if slope.is_nan() || slope.abs() <= 0.05 {
            return x;
        }
        let f = motion.phi(x, t);
        if !f.is_finite() {
            return x;
        }
        x - (f / slope).clamp(-0.5 * h, 0.5 * h) * nrm
    };
    for _ in 0..iterations {
        let old = positions.to_vec();
        let normals = vertex_normals(&old, triangles);
        let centroids = area_centroids(&old, triangles);
        let moved: Vec<DVec3> = (0..n)
            .into_par_iter()
            .map(|v| {
                if fixed[v] || normals[v] == DVec3::ZERO {
                    return old[v];
                }
                let nrm = normals[v];
                let d = centroids[v] - old[v];
                step(old[v] + (d - d.dot(nrm) * nrm), nrm, slopes[v])
            })
            .collect();
        positions.copy_from_slice(&moved);
        undo_flips(positions, &old, triangles);
    }
    for _ in 0..FINAL_NEWTON_STEPS {
        let old = positions.to_vec();
        let normals = vertex_normals(&old, triangles);
        let moved: Vec<DVec3> = (0..n)
            .into_par_iter()
            .map(|v| {
                if fixed[v] || normals[v] == DVec3::ZERO {
                    old[v]
                } else {
                    step(old[v], normals[v], slopes[v])
                }
            })
            .collect();
        positions.copy_from_slice(&moved);
        undo_flips(positions, &old, triangles);
    }
}

fn vertex_normals(p: &[DVec3], triangles: &[[u32; 3]]) -> Vec<DVec3> {
    let mut n = vec![DVec3::ZERO; p.len()];
    for &[a, b, c] in triangles {
        let (pa, pb, pc) = (p[a as usize], p[b as usize], p[c as usize]);
        let cr = (pb - pa).cross(pc - pa);
        for v in [a, b, c] {
            n[v as usize] += cr;
        }
    }
    n.iter().map(|v| v.normalize_or_zero()).collect()
}

/// Per vertex: the area-weighted mean of its triangles' centroids.
fn area_centroids(p: &[DVec3], triangles: &[[u32; 3]]) -> Vec<DVec3> {
    let mut sum = vec![DVec3::ZERO; p.len()];
    let mut weight = vec![0.0f64; p.len()];
    for &[a, b, c] in triangles {
        let (pa, pb, pc) = (p[a as usize], p[b as usize], p[c as usize]);
        let area = 0.5 * (pb - pa).cross(pc - pa).length();
        let centre = (pa + pb + pc) / 3.0;
        for v in [a, b, c] {
            sum[v as usize] += area * centre;
            weight[v as usize] += area;
        }
    }
    (0..p.len())
        .map(|v| {
            if weight[v] > 0.0 {
                sum[v] / weight[v]
            } else {
                p[v]
            }
        })
        .collect()
}

/// Smallest interior angle (radians) of triangle (a, b, c).
fn min_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let q = [a, b, c];
    (0..3)
        .map(|k| {
            let (u, v) = (q[(k + 1) % 3] - q[k], q[(k + 2) % 3] - q[k]);
            u.cross(v).length().atan2(u.dot(v))
        })
        .fold(f64::INFINITY, f64::min)
}

/// Below this min angle a triangle may not get worse (20°, in radians).
const PROTECTED_ANGLE: f64 = 20.0 * std::f64::consts::PI / 180.0;

/// Restores the old position of every vertex of a triangle that the move
/// flipped (normal turned by more than 90°), nearly collapsed (area below 1%
/// of its old area) or made a worse sliver (min angle dropped and is below
/// 20°). Where the surface is thinner than a cell the level set's two sides
/// pull vertices across each other, and this keeps the relaxation from
/// doing harm there. Repeats until nothing changes; the old configuration
/// is a fixed point, so it ends.
fn undo_flips(positions: &mut [DVec3], old: &[DVec3], triangles: &[[u32; 3]]) {
    loop {
        let mut changed = false;
        for &[a, b, c] in triangles {
            let (ia, ib, ic) = (a as usize, b as usize, c as usize);
            let (pa, pb, pc) = (positions[ia], positions[ib], positions[ic]);
            let (oa, ob, oc) = (old[ia], old[ib], old[ic]);
            if (pa, pb, pc) == (oa, ob, oc) {
                continue;
            }
            let new_n = (pb - pa).cross(pc - pa);
            let old_n = (ob - oa).cross(oc - oa);
            let bad = new_n.dot(old_n) <= 0.0 || new_n.length() < 0.01 * old_n.length() || {
                let after = min_angle(pa, pb, pc);
                after < PROTECTED_ANGLE && after < min_angle(oa, ob, oc)
            };
            if bad {
                for v in [ia, ib, ic] {
                    if positions[v] != old[v] {
                        positions[v] = old[v];
                        changed = true;
                    }
                }
            }
        }
        if !changed {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes::flow::{Amplitude, Field, PulledBack, Shape};
    use crate::scenes::marching_cubes::{Grid, extract};

    #[test]
    fn relaxed_vertices_lie_on_the_sphere_and_quality_improves() {
        let centre = DVec3::new(0.503, 0.497, 0.51);
        let motion = PulledBack {
            shape: Shape::Sphere {
                center: centre,
                radius: 0.3,
            },
            field: Field::Shear { gamma: 0.0 },
            amplitude: Amplitude::Constant,
        };
        let grid = Grid::new(DVec3::ZERO, DVec3::ONE, 32);
        let mut c = extract(&motion, 0.0, &grid);
        let min_angle_p5 = |p: &[DVec3]| {
            let mut a: Vec<f64> = c
                .triangles
                .iter()
                .map(|t| {
                    let q = t.map(|i| p[i as usize]);
                    (0..3)
                        .map(|k| {
                            let (u, v) = (q[(k + 1) % 3] - q[k], q[(k + 2) % 3] - q[k]);
                            u.angle_between(v)
                        })
                        .fold(f64::INFINITY, f64::min)
                })
                .collect();
            a.sort_by(f64::total_cmp);
            a[a.len() / 20].to_degrees()
        };
        let before = min_angle_p5(&c.positions);
        let mut p = c.positions.clone();
        relax(&mut p, &c.triangles, &motion, 0.0, grid.h, RELAX_ITERATIONS);
        let after = min_angle_p5(&p);
        assert!(after > before + 5.0, "p5 {before} -> {after}");
        for x in &p {
            let d = (*x - centre).length() - 0.3;
            assert!(d.abs() < 1e-5, "{d}");
        }
        c.positions = p;
        let topo = Topology::new(c.positions.len(), &c.triangles);
        assert_eq!(topo.boundary_edge_count(), 0);
    }
}
