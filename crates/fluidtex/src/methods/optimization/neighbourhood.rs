//! Vertex and pixel neighbourhoods around a centre point (paper Sec. V-A).
//!
//! **Vertex neighbourhood.** The points connected to the centre c, laid
//! out in c's frame (d, d × n) in texel units: the one-ring by projection
//! of (v − c), then ring after ring, each point placed at the average of
//! the positions its already-placed neighbours predict for it (their own
//! position plus the edge vector expressed in c's frame, rescaled to keep
//! the edge's 3-D length, which is what unfolding a curved surface does to
//! first order). Points whose normal turns away from c's (the other side of
//! a thin sheet) are left out. Points with |x|, |y| < w/2 are members.
//! On a curved surface the prediction depends on the path taken; the paper
//! then relaxes the layout, which [`Window::relaxation`] sweeps do: each
//! point but the centre moves to the mean of what all its placed
//! neighbours predict (Gauss–Seidel on the sum over edges of the squared
//! difference between the laid-out and the predicted edge, which every
//! move lowers). By default no sweep is made: the averaged first layout is
//! what the rest of the method was tuned on.
//!
//! **Pixel neighbourhood.** The colours at integer texel offsets of c's
//! frame: the flattened triangles are rasterised and each offset gets the
//! barycentric interpolation of its triangle's corner colours — the same
//! "which triangle holds this offset" answer as the paper's surface
//! marching, read from the flattening instead of walking the surface again.
//! The search compares a g × g subsample of the w × w neighbourhood (stride
//! (w − 1)/(g − 1) texels); offsets no triangle covers take the mean of
//! the covered ones.

use glam::{Vec2, Vec3};

use super::lattice::Level;

/// Smallest dot product of a point's normal with the centre's for the
/// point to join a vertex neighbourhood: below it the point is taken for
/// the other side of a thin sheet (the paper gives no threshold).
pub const FACING_DOT: f32 = 0.2;

/// Per-thread scratch (marks indexed by level vertex / triangle).
pub struct Scratch {
    stamp: Vec<u32>,
    pstamp: Vec<u32>,
    tri_stamp: Vec<u32>,
    generation: u32,
    coords: Vec<Vec2>,
    placed: Vec<u32>,
    layer: Vec<u32>,
    next: Vec<u32>,
}

impl Scratch {
    pub fn new(level: &Level) -> Scratch {
        Scratch {
            stamp: vec![0; level.len()],
            pstamp: vec![0; level.len()],
            tri_stamp: vec![0; level.triangles.len()],
            generation: 0,
            coords: vec![Vec2::ZERO; level.len()],
            placed: Vec::new(),
            layer: Vec::new(),
            next: Vec::new(),
        }
    }
}

/// The shape of one neighbourhood pass.
#[derive(Clone, Copy, Debug)]
pub struct Window {
    /// Pixel neighbourhood width w (odd).
    pub width: u32,
    /// Search grid g × g (odd, ≤ w).
    pub grid: u32,
    /// World size of one texel at this level.
    pub texel: f32,
    /// Relaxation sweeps of the vertex neighbourhood's layout (module doc).
    pub relaxation: u32,
}

impl Window {
    /// Texel stride between search grid samples.
    pub fn stride(&self) -> u32 {
        ((self.width - 1) / (self.grid - 1).max(1)).max(1)
    }

    pub fn half_grid(&self) -> i32 {
        (self.grid as i32 - 1) / 2
    }
}

/// Where one search-grid cell of a pixel neighbourhood reads its colour:
/// the barycentric interpolation of three level vertices, or nothing (the
/// cell fell outside every flattened triangle).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellSample {
    /// Corner level vertices; `u32::MAX` in the first slot: uncovered.
    pub corners: [u32; 3],
    pub weights: [f32; 3],
}

impl CellSample {
    pub const UNCOVERED: CellSample = CellSample {
        corners: [u32::MAX; 3],
        weights: [0.0; 3],
    };

    #[inline]
    pub fn covered(&self) -> bool {
        self.corners[0] != u32::MAX
    }
}

/// Builds the vertex neighbourhood of `centre` (with frame `d`): appends
/// its members (level vertices) and their texel coordinates to `members`,
/// and writes into `cells` (g × g) where each search-grid sample of its
/// pixel neighbourhood reads its colour. Both depend on the geometry and
/// the orientation only, not on the colours, so a pass builds them once
/// and re-reads the colours every iteration ([`fill_query`]).
pub fn build(
    level: &Level,
    centre: u32,
    d: Vec3,
    window: Window,
    scratch: &mut Scratch,
    members: &mut Vec<(u32, Vec2)>,
    cells: &mut [CellSample],
) {
    let g = flatten_rings(level, centre, d, window, scratch);
    let half = window.width as f32 / 2.0;
    members.extend(
        scratch
            .placed
            .iter()
            .map(|&v| (v, scratch.coords[v as usize]))
            .filter(|(_, x)| x.x.abs() < half && x.y.abs() < half),
    );

    rasterise(level, window, scratch, g, cells);
}

/// Flattens the level around `centre` ring by ring into the frame (d,
/// d × n): each new vertex is placed at the mean of its placed neighbours'
/// coordinates plus the edge to them, turned into the plane and kept at its
/// 3-D length (texel units of `window`). Vertices facing away from the
/// centre's normal are skipped; rings stop beyond the window. Returns the
/// scratch generation marking this neighbourhood.
fn flatten_rings(
    level: &Level,
    centre: u32,
    d: Vec3,
    window: Window,
    scratch: &mut Scratch,
) -> u32 {
    scratch.generation = scratch.generation.wrapping_add(1);
    if scratch.generation == 0 {
        scratch.stamp.fill(0);
        scratch.pstamp.fill(0);
        scratch.tri_stamp.fill(0);
        scratch.generation = 1;
    }
    let g = scratch.generation;
    let c = centre as usize;
    let n_c = level.normals[c];
    let e1 = d;
    let e2 = d.cross(n_c);
    let inv = 1.0 / window.texel;
    let reach = window.width as f32 / 2.0 + 1.5;
    let p_c = level.positions[c];

    scratch.placed.clear();
    scratch.layer.clear();
    scratch.stamp[c] = g;
    scratch.pstamp[c] = g;
    scratch.coords[c] = Vec2::ZERO;
    scratch.placed.push(centre);
    scratch.layer.push(centre);
    // Ring by ring.
    while !scratch.layer.is_empty() {
        scratch.next.clear();
        for &u in &scratch.layer {
            for &v in level.neighbours(u) {
                if scratch.stamp[v as usize] != g {
                    scratch.stamp[v as usize] = g;
                    scratch.next.push(v);
                }
            }
        }
        // Predictions only from vertices placed in earlier rings.
        let ring_start = scratch.placed.len();
        for idx in 0..scratch.next.len() {
            let v = scratch.next[idx];
            let vi = v as usize;
            let p_v = level.positions[vi];
            if level.normals[vi].dot(n_c) < FACING_DOT {
                continue;
            }
            let mut sum = Vec2::ZERO;
            let mut count = 0.0f32;
            for &u in level.neighbours(v) {
                let ui = u as usize;
                if scratch.pstamp[ui] == g {
                    sum += scratch.coords[ui] + predicted_edge(level, (e1, e2, inv), u, v);
                    count += 1.0;
                }
            }
            if count == 0.0 {
                let e = p_v - p_c;
                sum = Vec2::new(e.dot(e1), e.dot(e2)) * inv;
                count = 1.0;
            }
            scratch.coords[vi] = sum / count;
            scratch.placed.push(v);
        }
        scratch.layer.clear();
        for idx in ring_start..scratch.placed.len() {
            let v = scratch.placed[idx];
            scratch.pstamp[v as usize] = g;
            let x = scratch.coords[v as usize];
            if x.x.abs() <= reach && x.y.abs() <= reach {
                scratch.layer.push(v);
            }
        }
    }
    for _ in 0..window.relaxation {
        relax(level, (e1, e2, inv), scratch, g);
    }
    g
}

/// The edge from `u` to `v` laid into the frame (`e1`, `e2`) in texel units
/// (`inv` per world unit), at its 3-D length.
#[inline]
fn predicted_edge(level: &Level, (e1, e2, inv): (Vec3, Vec3, f32), u: u32, v: u32) -> Vec2 {
    let e = level.positions[v as usize] - level.positions[u as usize];
    let mut e2d = Vec2::new(e.dot(e1), e.dot(e2));
    let l2 = e2d.length();
    if l2 > 1e-12 {
        e2d *= e.length() / l2;
    }
    e2d * inv
}

/// One Gauss–Seidel sweep over the placed points but the centre (module
/// doc): each moves to the mean of its placed neighbours' predictions.
fn relax(level: &Level, frame: (Vec3, Vec3, f32), scratch: &mut Scratch, g: u32) {
    for idx in 1..scratch.placed.len() {
        let v = scratch.placed[idx];
        let mut sum = Vec2::ZERO;
        let mut count = 0.0f32;
        for &u in level.neighbours(v) {
            if scratch.pstamp[u as usize] == g {
                sum += scratch.coords[u as usize] + predicted_edge(level, frame, u, v);
                count += 1.0;
            }
        }
        if count > 0.0 {
            scratch.coords[v as usize] = sum / count;
        }
    }
}

/// The layout's misfit: over the edges between placed points, the sum of
/// squared differences between the laid-out edge and the predicted one
/// (what [`relax`] lowers).
#[cfg(test)]
pub(super) fn layout_misfit(level: &Level, centre: u32, d: Vec3, window: Window) -> (f64, usize) {
    let mut scratch = Scratch::new(level);
    let g = flatten_rings(level, centre, d, window, &mut scratch);
    let n_c = level.normals[centre as usize];
    let frame = (d, d.cross(n_c), 1.0 / window.texel);
    let mut misfit = 0.0f64;
    for &v in &scratch.placed {
        for &u in level.neighbours(v) {
            if u < v && scratch.pstamp[u as usize] == g {
                let laid = scratch.coords[v as usize] - scratch.coords[u as usize];
                misfit += f64::from((laid - predicted_edge(level, frame, u, v)).length_squared());
            }
        }
    }
    (misfit, scratch.placed.len())
}

/// The pixel neighbourhood: the flattened triangles (all three corners
/// placed in generation `g`) rasterised onto the g × g search grid.
fn rasterise(
    level: &Level,
    window: Window,
    scratch: &mut Scratch,
    g: u32,
    cells: &mut [CellSample],
) {
    let hg = window.half_grid();
    let side = window.grid as usize;
    let stride = window.stride() as f32;
    cells.fill(CellSample::UNCOVERED);
    let placed_gen = g;
    for pi in 0..scratch.placed.len() {
        let v = scratch.placed[pi];
        for &t in level.vertex_triangles(v) {
            if scratch.tri_stamp[t as usize] == placed_gen {
                continue;
            }
            scratch.tri_stamp[t as usize] = placed_gen;
            let tri = level.triangles[t as usize];
            if !tri.iter().all(|&x| scratch.pstamp[x as usize] == g) {
                continue;
            }
            let q = tri.map(|x| scratch.coords[x as usize] / stride);
            let lo = q[0].min(q[1]).min(q[2]);
            let hi = q[0].max(q[1]).max(q[2]);
            let (x0, x1) = ((lo.x.ceil() as i32).max(-hg), (hi.x.floor() as i32).min(hg));
            let (y0, y1) = ((lo.y.ceil() as i32).max(-hg), (hi.y.floor() as i32).min(hg));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let cell = (y + hg) as usize * side + (x + hg) as usize;
                    if cells[cell].covered() {
                        continue;
                    }
                    let Some(b) = crate::surface::barycentric_2d(
                        Vec2::new(x as f32, y as f32),
                        q[0],
                        q[1],
                        q[2],
                    ) else {
                        continue;
                    };
                    if b.iter().any(|&w| w < -1e-4) {
                        continue;
                    }
                    cells[cell] = CellSample {
                        corners: tri,
                        weights: b,
                    };
                }
            }
        }
    }
}

/// The search vector of a pixel neighbourhood (g × g × `k_search` colour
/// values of the `k`-float `colours`) from its `cells`; uncovered samples
/// take the mean of the covered ones (or of the `members` when none is).
pub fn fill_query(
    cells: &[CellSample],
    members: &[(u32, Vec2)],
    colours: &[f32],
    k: usize,
    k_search: usize,
    vector: &mut [f32],
    mean: &mut [f32],
) {
    mean.fill(0.0);
    let mut count = 0usize;
    for (cell, s) in cells.iter().enumerate() {
        if !s.covered() {
            continue;
        }
        let (tri, b) = (s.corners, s.weights);
        let out = &mut vector[cell * k_search..cell * k_search + k_search];
        for (ch, o) in out.iter_mut().enumerate() {
            *o = b[0] * colours[tri[0] as usize * k + ch]
                + b[1] * colours[tri[1] as usize * k + ch]
                + b[2] * colours[tri[2] as usize * k + ch];
        }
    }
    for (cell, s) in cells.iter().enumerate() {
        if s.covered() {
            for ch in 0..k_search {
                mean[ch] += vector[cell * k_search + ch];
            }
            count += 1;
        }
    }
    if count == 0 {
        for &(v, _) in members {
            for ch in 0..k_search {
                mean[ch] += colours[v as usize * k + ch];
            }
        }
        count = members.len();
    }
    if count > 0 {
        for m in mean.iter_mut() {
            *m /= count as f32;
        }
    }
    for (cell, s) in cells.iter().enumerate() {
        if !s.covered() {
            vector[cell * k_search..cell * k_search + k_search].copy_from_slice(mean);
        }
    }
}
