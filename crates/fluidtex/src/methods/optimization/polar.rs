//! Polar maps of a level's vertices, and the diffusion of orientation
//! angles through them: the 2007 paper's orientation smoothing (Sec. IV-B,
//! after Zhang et al.'s polar map), selected by
//! `orientation_smoothing = "polar"`.
//!
//! **The polar map of a vertex.** Walking around v's fan of triangles, the
//! k-th edge leaves v at the accumulated corner angle A_k; a closed fan
//! totals Θ (2π on a flat vertex, less at a cone, more at a saddle), and
//! the polar angle of that edge is φ_k = A_k·2π/Θ, so the angles around
//! every vertex span one full turn. An orientation is a polar angle θ_v.
//!
//! **Carrying an angle along an edge.** A vector at u makes the angle
//! θ_u − φ_uv with the edge towards v; at v the same edge, continued,
//! leaves at φ_vu + π. So u's orientation seen from v is
//! θ_u − φ_uv + φ_vu + π (the discrete parallel transport of the polar
//! maps). One diffusion step sets θ_v to the direction of the sum of the
//! unit vectors of θ_v and of every neighbour's carried angle.
//!
//! **Where the map cannot be built** (a non-manifold vertex, a fan whose
//! edges fold over each other in the tangent plane, a zero-length edge),
//! the vertex falls back to plain tangent-plane angles (Θ = 2π, no
//! rescaling), which is the projection the default smoothing uses. An edge
//! whose far end does not list the near one is carried by projection too.
//! An open fan (a vertex on the surface's border) keeps its angles
//! unscaled: the paper gives no rule for it.
//!
//! **Angles and vectors.** The transport and the layout work on 3-D
//! vectors, so a level's field goes from vectors to angles before the
//! diffusion and back after. Both directions are the same piecewise-linear
//! map between the polar angle and the angle in the vertex's tangent plane
//! (edge k's polar angle ↔ edge k's projected direction, linear between),
//! so they are exact inverses. The angles handed out are measured from a
//! reference vector stored at each vertex, as the paper's are: world X
//! projected on the tangent plane (the default smoothing's start), so the
//! paper's start, polar angle 0 everywhere, is a field without jumps.
//!
//! Written here: the polar map needs the level's fans, which no mesh crate
//! we use builds on our lattice levels.

use std::f32::consts::{PI, TAU};

use glam::Vec3;
use rayon::prelude::*;

use super::lattice::Level;
use super::tangent::{reference, tangent};

/// The polar maps of every vertex of one level.
pub struct PolarMaps {
    /// Per vertex: its fan's first edge in `edges` (CSR offsets).
    offsets: Vec<u32>,
    /// Per fan edge: the neighbour it leads to, in fan order.
    edges: Vec<u32>,
    /// Per fan edge: accumulated corner angle A_k from the first edge.
    along: Vec<f32>,
    /// Per fan edge: its direction's angle in the tangent plane's basis.
    beta: Vec<f32>,
    /// Per vertex: the fan's total angle (Θ when closed; the last A_k when
    /// open).
    total: Vec<f32>,
    /// Per vertex: polar angle per radian of corner angle (2π/Θ on a
    /// closed fan, 1 otherwise).
    scale: Vec<f32>,
    /// Per vertex: whether the fan closes around the vertex.
    closed: Vec<bool>,
    /// Per vertex: the polar angle, measured from the first fan edge, of
    /// the reference vector, which is the zero of the angles handed out.
    zero: Vec<f32>,
}

/// One vertex's fan before it is stored.
struct Fan {
    edges: Vec<u32>,
    along: Vec<f32>,
    beta: Vec<f32>,
    total: f32,
    scale: f32,
    closed: bool,
}

/// The tangent-plane basis of a vertex: `reference(n)` and n × it.
fn basis(n: Vec3) -> (Vec3, Vec3) {
    let t1 = reference(n);
    (t1, n.cross(t1))
}

/// `b − a` taken into [0, 2π).
#[inline]
fn ccw(a: f32, b: f32) -> f32 {
    (b - a).rem_euclid(TAU)
}

impl PolarMaps {
    pub fn new(level: &Level) -> PolarMaps {
        let fans: Vec<Fan> = (0..level.len() as u32)
            .into_par_iter()
            .map(|v| walked_fan(level, v).unwrap_or_else(|| projected_fan(level, v)))
            .collect();
        let mut maps = PolarMaps {
            offsets: Vec::with_capacity(fans.len() + 1),
            edges: Vec::new(),
            along: Vec::new(),
            beta: Vec::new(),
            total: Vec::with_capacity(fans.len()),
            scale: Vec::with_capacity(fans.len()),
            closed: Vec::with_capacity(fans.len()),
            zero: Vec::new(),
        };
        maps.offsets.push(0);
        for fan in fans {
            maps.edges.extend(&fan.edges);
            maps.along.extend(&fan.along);
            maps.beta.extend(&fan.beta);
            maps.offsets.push(maps.edges.len() as u32);
            maps.total.push(fan.total);
            maps.scale.push(fan.scale);
            maps.closed.push(fan.closed);
        }
        // The reference vector has tangent-plane angle 0 in the basis.
        maps.zero = (0..maps.total.len() as u32)
            .map(|v| maps.polar_angle(v, 0.0))
            .collect();
        maps
    }

    fn range(&self, v: u32) -> std::ops::Range<usize> {
        self.offsets[v as usize] as usize..self.offsets[v as usize + 1] as usize
    }

    /// Whether `v`'s map rescales its angles (a closed fan walked over its
    /// triangles); false where it fell back to tangent-plane angles.
    pub fn is_closed(&self, v: u32) -> bool {
        self.closed[v as usize]
    }

    /// 2π/Θ of `v` (1 where the map is not rescaled).
    pub fn scale(&self, v: u32) -> f32 {
        self.scale[v as usize]
    }

    /// Polar angle at `v` of the edge towards `u`, if `u` is in v's fan.
    pub fn edge_angle(&self, v: u32, u: u32) -> Option<f32> {
        let r = self.range(v);
        let k = self.edges[r.clone()].iter().position(|&e| e == u)?;
        Some(self.scale[v as usize] * self.along[r.start + k] - self.zero[v as usize])
    }

    /// The angle in v's tangent-plane basis of polar angle `theta`.
    fn plane_angle(&self, v: u32, theta: f32) -> f32 {
        let r = self.range(v);
        let (along, beta) = (&self.along[r.clone()], &self.beta[r]);
        let total = self.total[v as usize];
        let Some(&b0) = beta.first() else {
            return theta;
        };
        // Polar angles span one turn; corner angles span the fan's total.
        let g = theta.rem_euclid(TAU) / self.scale[v as usize];
        let m = along.len();
        // Sector k runs from edge k to edge k + 1 (to edge 0 past the last
        // edge of a closed fan; the gap of an open fan otherwise).
        let k = along.partition_point(|&a| a <= g).saturating_sub(1);
        let (a_end, b_end) = if k + 1 < m {
            (along[k + 1], beta[k + 1])
        } else if self.closed[v as usize] {
            (total, b0)
        } else {
            (TAU, b0)
        };
        let span = a_end - along[k];
        let turn = match ccw(beta[k], b_end) {
            0.0 if k + 1 >= m => TAU,
            t => t,
        };
        let f = if span > 0.0 {
            (g - along[k]) / span
        } else {
            0.0
        };
        beta[k] + f * turn
    }

    /// The polar angle at `v` of the tangent-plane angle `b`.
    fn polar_angle(&self, v: u32, b: f32) -> f32 {
        let r = self.range(v);
        let (along, beta) = (&self.along[r.clone()], &self.beta[r]);
        let total = self.total[v as usize];
        let m = along.len();
        if m == 0 {
            return b;
        }
        // The sector the direction lies in, counter-clockwise from edge k
        // (a direction on edge k + 1 may be taken as the end of sector k:
        // both give the same angle).
        let mut k = m - 1;
        for j in 0..m - 1 {
            if ccw(beta[j], b) <= ccw(beta[j], beta[j + 1]) {
                k = j;
                break;
            }
        }
        let (a_end, b_end) = if k + 1 < m {
            (along[k + 1], beta[k + 1])
        } else if self.closed[v as usize] {
            (total, beta[0])
        } else {
            (TAU, beta[0])
        };
        let turn = match ccw(beta[k], b_end) {
            0.0 => TAU,
            t => t,
        };
        let f = (ccw(beta[k], b) / turn).min(1.0);
        let g = along[k] + (a_end - along[k]) * f;
        self.scale[v as usize] * g
    }

    /// The unit tangent vector at `v` (normal `n`) of polar angle `theta`.
    pub fn vector(&self, v: u32, n: Vec3, theta: f32) -> Vec3 {
        let (t1, t2) = basis(n);
        let b = self.plane_angle(v, theta + self.zero[v as usize]);
        t1 * b.cos() + t2 * b.sin()
    }

    /// The polar angle at `v` (normal `n`) of the tangent vector `d`.
    pub fn angle(&self, v: u32, n: Vec3, d: Vec3) -> f32 {
        let (t1, t2) = basis(n);
        let d = tangent(d, n);
        self.polar_angle(v, d.dot(t2).atan2(d.dot(t1))) - self.zero[v as usize]
    }

    /// The edge's polar angles at both ends, (φ_uv, φ_vu), where each
    /// polar map lists the other end.
    fn turn(&self, u: u32, v: u32) -> Option<(f32, f32)> {
        Some((self.edge_angle(u, v)?, self.edge_angle(v, u)?))
    }

    /// u's orientation `theta_u` carried along the edge to `v` with its
    /// [`PolarMaps::turn`], or by projection into v's tangent plane where
    /// there is none.
    fn carry_by(
        &self,
        level: &Level,
        u: u32,
        theta_u: f32,
        v: u32,
        turn: Option<(f32, f32)>,
    ) -> f32 {
        match turn {
            Some((phi_uv, phi_vu)) => theta_u - phi_uv + phi_vu + PI,
            None => {
                let d = self.vector(u, level.normals[u as usize], theta_u);
                self.angle(v, level.normals[v as usize], d)
            }
        }
    }

    /// u's orientation `theta_u` carried along the edge to `v`.
    pub fn carry(&self, level: &Level, u: u32, theta_u: f32, v: u32) -> f32 {
        self.carry_by(level, u, theta_u, v, self.turn(u, v))
    }
}

/// The neighbours of a vertex in fan order, from the (next, previous)
/// corners of each of its triangles, and whether the fan closes; `None`
/// when the triangles do not form one fan (a non-manifold vertex, or
/// several pieces).
fn ring_order(others: &[[u32; 2]]) -> Option<(Vec<u32>, bool)> {
    // Each neighbour is on two of v's triangles inside the fan, one on its
    // border; a third makes the vertex non-manifold.
    let mut count: Vec<(u32, u32)> = Vec::with_capacity(others.len() * 2);
    for &u in others.iter().flatten() {
        match count.iter_mut().find(|(w, _)| *w == u) {
            Some((_, c)) => *c += 1,
            None => count.push((u, 1)),
        }
    }
    if count.iter().any(|&(_, c)| c > 2) {
        return None;
    }
    let border: Vec<u32> = count
        .iter()
        .filter(|&&(_, c)| c == 1)
        .map(|&(u, _)| u)
        .collect();
    let closed = border.is_empty();
    let start = match border.as_slice() {
        [] => others[0][0],
        [a, b] => *a.min(b),
        _ => return None,
    };
    let mut order = vec![start];
    let mut used = vec![false; others.len()];
    let mut cur = start;
    while let Some(t) = (0..others.len()).find(|&t| !used[t] && others[t].contains(&cur)) {
        used[t] = true;
        cur = if others[t][0] == cur {
            others[t][1]
        } else {
            others[t][0]
        };
        if closed && cur == start {
            break;
        }
        order.push(cur);
    }
    if used.iter().any(|&u| !u) || (closed && cur != start) {
        return None;
    }
    Some((order, closed))
}

/// v's fan walked triangle by triangle over shared edges, or `None` where
/// it is not a disc or half-disc whose edges keep their order when
/// projected on the tangent plane.
fn walked_fan(level: &Level, v: u32) -> Option<Fan> {
    let tris = level.vertex_triangles(v);
    let others: Vec<[u32; 2]> = tris
        .iter()
        .map(|&t| {
            let tri = level.triangles[t as usize];
            let i = tri.iter().position(|&c| c == v).unwrap_or(0);
            [tri[(i + 1) % 3], tri[(i + 2) % 3]]
        })
        .collect();
    if others.is_empty() {
        return None;
    }
    let (order, closed) = ring_order(&others)?;
    let p = level.positions[v as usize];
    let n = level.normals[v as usize];
    let dirs: Vec<Vec3> = order
        .iter()
        .map(|&u| (level.positions[u as usize] - p).normalize_or_zero())
        .collect();
    if dirs.contains(&Vec3::ZERO) {
        return None;
    }
    // Counter-clockwise about n, like the tangent-plane angles.
    let turning: f32 = dirs.windows(2).map(|w| w[0].cross(w[1]).dot(n)).sum();
    let (order, dirs) = if turning < 0.0 {
        (
            order.into_iter().rev().collect(),
            dirs.into_iter().rev().collect(),
        )
    } else {
        (order, dirs)
    };
    let (t1, t2) = basis(n);
    let beta: Vec<f32> = dirs
        .iter()
        .map(|d| {
            let q = tangent(*d, n);
            q.dot(t2).atan2(q.dot(t1))
        })
        .collect();
    let m = dirs.len();
    let sectors = if closed { m } else { m - 1 };
    let corner = |k: usize| dirs[k].angle_between(dirs[(k + 1) % m]);
    let turn = |k: usize| ccw(beta[k], beta[(k + 1) % m]);
    // The projected edges must turn the same way as the fan, by less than
    // half a turn per triangle, and once around in all for a closed fan.
    let turns: f32 = (0..sectors).map(turn).sum();
    if (0..sectors).any(|k| turn(k) <= 0.0 || turn(k) >= PI)
        || (closed && (turns - TAU).abs() > 1e-3)
        || (!closed && turns >= TAU)
    {
        return None;
    }
    let mut along = Vec::with_capacity(m);
    let mut total = 0.0f32;
    for k in 0..m {
        along.push(total);
        if k < sectors {
            total += corner(k);
        }
    }
    if closed && !(total > 0.0 && total.is_finite()) {
        return None;
    }
    Some(Fan {
        edges: order,
        along,
        beta,
        total,
        scale: if closed { TAU / total } else { 1.0 },
        closed,
    })
}

/// The fallback: v's neighbours by their angle in the tangent plane, one
/// closed turn of 2π, no rescaling (the projection of the default
/// smoothing).
fn projected_fan(level: &Level, v: u32) -> Fan {
    let p = level.positions[v as usize];
    let n = level.normals[v as usize];
    let (t1, t2) = basis(n);
    let mut edges: Vec<(f32, u32)> = level
        .neighbours(v)
        .iter()
        .filter_map(|&u| {
            let q = level.positions[u as usize] - p;
            let q = q - n * q.dot(n);
            (q.length_squared() > 1e-20).then(|| (q.dot(t2).atan2(q.dot(t1)), u))
        })
        .collect();
    edges.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    edges.dedup_by(|a, b| a.0 == b.0);
    let b0 = edges.first().map_or(0.0, |e| e.0);
    Fan {
        along: edges.iter().map(|e| e.0 - b0).collect(),
        beta: edges.iter().map(|e| e.0).collect(),
        edges: edges.iter().map(|e| e.1).collect(),
        total: TAU,
        scale: 1.0,
        closed: true,
    }
}

/// `iterations` Jacobi steps of polar-angle diffusion on `level`; `d` is
/// given and returned as tangent vectors.
pub fn diffuse(level: &Level, maps: &PolarMaps, d: &mut Vec<Vec3>, iterations: u32) {
    if iterations == 0 {
        return;
    }
    let mut theta: Vec<f32> = (0..level.len())
        .into_par_iter()
        .map(|v| maps.angle(v as u32, level.normals[v], d[v]))
        .collect();
    // Each edge's turn, looked up once for every iteration, in the order
    // of the level's neighbour lists.
    let turns: Vec<Vec<Option<(f32, f32)>>> = (0..level.len() as u32)
        .into_par_iter()
        .map(|v| {
            level
                .neighbours(v)
                .iter()
                .map(|&u| maps.turn(u, v))
                .collect()
        })
        .collect();
    for _ in 0..iterations {
        theta = (0..level.len() as u32)
            .into_par_iter()
            .map(|v| {
                let own = theta[v as usize];
                let (mut s, mut c) = own.sin_cos();
                for (&u, &turn) in level.neighbours(v).iter().zip(&turns[v as usize]) {
                    let carried = maps.carry_by(level, u, theta[u as usize], v, turn);
                    let (su, cu) = carried.sin_cos();
                    s += su;
                    c += cu;
                }
                if s * s + c * c > 1e-12 {
                    s.atan2(c)
                } else {
                    own
                }
            })
            .collect();
    }
    *d = (0..level.len())
        .into_par_iter()
        .map(|v| maps.vector(v as u32, level.normals[v], theta[v]))
        .collect();
}

/// The field of polar angle 0 at every vertex of `level`: each vertex's
/// reference vector, the paper's start on a fresh surface.
pub fn zero_angle(level: &Level, maps: &PolarMaps) -> Vec<Vec3> {
    (0..level.len())
        .into_par_iter()
        .map(|v| maps.vector(v as u32, level.normals[v], 0.0))
        .collect()
}
