//! Points on the surface and their hierarchy: every fluid triangle is
//! subdivided into a regular barycentric lattice of `m` steps per edge
//! (m = 2^k), shared along edges and at corners, so the points of the
//! finest level form a closed triangle mesh of the fluid surface.
//!
//! **Why a lattice by default and not random points + repulsion (the
//! paper's Sec. IV-A, selectable: [`Lattice::scattered`], [`super::scatter`]).**
//! The paper places points by Turk's repulsion and re-tiles the surface
//! with them (3–15 minutes per frame by its own account). A subdivision
//! lattice gives the same three things the synthesis needs: (1) points at
//! about a chosen density per unit area (the fluid mesh of a grid
//! simulation has a nearly constant density, and `m` is chosen per frame
//! from the target spacing; see the price below), (2) a triangle mesh connecting them for free, and
//! (3) exactly nested levels: level ℓ is the lattice of stride 2^ℓ, a
//! subset of the finest points, so coarse-to-fine copying is exact. It
//! also makes the atlas output exact and cheap: an atlas texel knows its
//! fluid triangle and barycentrics, which name its lattice cell directly
//! ([`Lattice::locate`]). The price is that point spacing follows the
//! fluid mesh's triangle shapes (slivers stay slivers), within a factor of
//! about two of the target; neighbourhood coordinates are measured in world
//! units, so this changes sampling density, not texture scale. Scattered
//! points cost more: placing and re-tiling 200k points on three levels
//! takes about 7 s a frame on 2 cores, against 0.3 s for the lattice.
//!
//! When the fluid mesh is already as coarse as a level asks for (m = 1),
//! that level reuses the fluid vertices: denser than its texel size, which
//! costs time but not quality.

use std::collections::HashMap;

use glam::Vec3;

pub use super::level::Level;
use super::scatter::Scatter;
use crate::mesh::TriMesh;

/// The finest lattice of one frame: point ids, positions and normals.
pub struct Lattice {
    /// Steps per fluid edge (a power of two).
    pub m: u32,
    /// The fluid mesh's triangles, their corners as point ids (corner
    /// order kept).
    pub triangles: Vec<[u32; 3]>,
    vertex_count: u32,
    /// Sorted fluid edge (lo, hi) → edge index.
    edges: HashMap<u64, u32>,
    edge_count: u32,
    /// Offsets of interior lattice rows (see [`Lattice::id`]).
    row_offset: Vec<u32>,
    interior_per_triangle: u32,
    /// Position and unit normal of every point.
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    /// Scattered points in place of the lattice (`placement = "repulsion"`):
    /// then every query below is answered by them.
    scatter: Option<Box<Scatter>>,
}

fn edge_key(a: u32, b: u32) -> u64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    ((lo as u64) << 32) | hi as u64
}

impl Lattice {
    /// The lattice of `mesh` with `m` steps per edge (m ≥ 1).
    pub fn new(mesh: &TriMesh, m: u32) -> Lattice {
        let m = m.max(1);
        // Corner points are the fluid vertices that some triangle uses, in
        // vertex order: every point then belongs to the finest level, whose
        // vertex k is point k (the synthesis and the atlas index the finest
        // values by point id). A vertex no triangle uses (one left behind
        // by a dropped zero-area triangle) gets no point.
        let mut corner = vec![u32::MAX; mesh.vertex_count()];
        for &v in mesh.triangles.iter().flatten() {
            corner[v as usize] = 0;
        }
        let mut used = Vec::new();
        for (v, c) in corner.iter_mut().enumerate() {
            if *c == 0 {
                *c = used.len() as u32;
                used.push(v);
            }
        }
        let triangles: Vec<[u32; 3]> = (mesh.triangles.iter())
            .map(|t| t.map(|v| corner[v as usize]))
            .collect();
        let mut edges = HashMap::with_capacity(triangles.len() * 2);
        let mut edge_count = 0u32;
        let mut edge_ends = Vec::new();
        for tri in &triangles {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                edges.entry(edge_key(a, b)).or_insert_with(|| {
                    edge_ends.push((a.min(b), a.max(b)));
                    edge_count += 1;
                    edge_count - 1
                });
            }
        }
        // Interior points (i, j), i ≥ 1, j ≥ 1, i + j ≤ m − 1, row by row in i.
        let mut row_offset = vec![0u32; m as usize + 1];
        for i in 1..m as usize {
            row_offset[i + 1] = row_offset[i] + (m as usize - 1 - i) as u32;
        }
        let interior_per_triangle = if m >= 3 { (m - 1) * (m - 2) / 2 } else { 0 };
        let vertex_count = used.len() as u32;
        let total = vertex_count as usize
            + edge_count as usize * (m as usize - 1)
            + triangles.len() * interior_per_triangle as usize;
        let all_normals = mesh.vertex_normals();
        let vp: Vec<Vec3> = used.iter().map(|&v| mesh.positions[v]).collect();
        let vn: Vec<Vec3> = used.iter().map(|&v| all_normals[v]).collect();
        let mut positions = Vec::with_capacity(total);
        let mut normals = Vec::with_capacity(total);
        positions.extend_from_slice(&vp);
        normals.extend_from_slice(&vn);
        let mf = m as f32;
        for &(a, b) in &edge_ends {
            let (pa, pb) = (vp[a as usize], vp[b as usize]);
            let (na, nb) = (vn[a as usize], vn[b as usize]);
            for s in 1..m {
                let f = s as f32 / mf;
                positions.push(pa.lerp(pb, f));
                normals.push(na.lerp(nb, f).normalize_or_zero());
            }
        }
        for tri in &triangles {
            let p = tri.map(|v| vp[v as usize]);
            let n = tri.map(|v| vn[v as usize]);
            for i in 1..m {
                for j in 1..(m - i) {
                    let (wb, wc) = (i as f32 / mf, j as f32 / mf);
                    let wa = 1.0 - wb - wc;
                    positions.push(p[0] * wa + p[1] * wb + p[2] * wc);
                    normals.push((n[0] * wa + n[1] * wb + n[2] * wc).normalize_or_zero());
                }
            }
        }
        Lattice {
            m,
            triangles,
            vertex_count,
            edges,
            edge_count,
            row_offset,
            interior_per_triangle,
            positions,
            normals,
            scatter: None,
        }
    }

    /// Random points spread by repulsion over `mesh` at spacing h, with
    /// `levels` nested levels, drawn from `seed` ([`Scatter`]). `m` is 1
    /// and `triangles` are the fluid mesh's own.
    pub fn scattered(mesh: &TriMesh, h: f32, levels: usize, seed: u64) -> Lattice {
        let scatter = Scatter::new(mesh, h, levels, seed);
        Lattice {
            m: 1,
            triangles: mesh.triangles.clone(),
            vertex_count: 0,
            edges: HashMap::new(),
            edge_count: 0,
            row_offset: Vec::new(),
            interior_per_triangle: 0,
            positions: scatter.positions().to_vec(),
            normals: scatter.normals().to_vec(),
            scatter: Some(Box::new(scatter)),
        }
    }

    /// Whether the points are scattered rather than a lattice.
    pub fn is_scattered(&self) -> bool {
        self.scatter.is_some()
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    fn edge_point(&self, p: u32, q: u32, s: u32) -> u32 {
        let e = self.edges.get(&edge_key(p, q)).copied().unwrap_or(0);
        let s = if p < q { s } else { self.m - s };
        self.vertex_count + e * (self.m - 1) + (s - 1)
    }

    /// The point at lattice coordinates (i, j) of triangle `t`: barycentric
    /// weights ((m − i − j)/m, i/m, j/m) on its corners.
    pub fn id(&self, t: usize, i: u32, j: u32) -> u32 {
        let [a, b, c] = self.triangles[t];
        let m = self.m;
        match (i, j) {
            (0, 0) => a,
            _ if i == m => b,
            _ if j == m => c,
            (_, 0) => self.edge_point(a, b, i),
            (0, _) => self.edge_point(a, c, j),
            _ if i + j == m => self.edge_point(b, c, j),
            _ => {
                self.vertex_count
                    + self.edge_count * (m - 1)
                    + t as u32 * self.interior_per_triangle
                    + self.row_offset[i as usize]
                    + (j - 1)
            }
        }
    }

    /// The three points and weights of the lattice cell (of stride
    /// `stride`) holding barycentric location `bary` of triangle `t`.
    pub fn locate_stride(&self, t: usize, bary: [f32; 3], stride: u32) -> [(u32, f32); 3] {
        if let Some(s) = &self.scatter {
            let (x, n) = s.fluid_point(self.triangles[t], bary);
            return s.locate(s.level_index(stride), x, n);
        }
        let n = (self.m / stride.max(1)).max(1);
        let nf = n as f32;
        let u = (bary[1] * nf).clamp(0.0, nf);
        let v = (bary[2] * nf).clamp(0.0, nf);
        let i = (u.floor() as u32).min(n - 1);
        let j = (v.floor() as u32).min(n - 1 - i);
        let (fu, fv) = (u - i as f32, v - j as f32);
        let q = stride.max(1);
        let at = |a: u32, b: u32| self.id(t, a * q, b * q);
        if fu + fv <= 1.0 || i + j + 1 >= n {
            let (wb, wc) = (fu.clamp(0.0, 1.0), fv.clamp(0.0, 1.0));
            let wa = (1.0 - wb - wc).max(0.0);
            let s = wa + wb + wc;
            [
                (at(i, j), wa / s),
                (at(i + 1, j), wb / s),
                (at(i, j + 1), wc / s),
            ]
        } else {
            [
                (at(i + 1, j), 1.0 - fv),
                (at(i + 1, j + 1), fu + fv - 1.0),
                (at(i, j + 1), 1.0 - fu),
            ]
        }
    }

    /// [`Lattice::locate_stride`] on the finest lattice.
    pub fn locate(&self, t: usize, bary: [f32; 3]) -> [(u32, f32); 3] {
        self.locate_stride(t, bary, 1)
    }

    /// Interpolates per-point values (`k` floats per point) at `bary` of `t`.
    pub fn interpolate(&self, values: &[f32], k: usize, t: usize, bary: [f32; 3], out: &mut [f32]) {
        out[..k].fill(0.0);
        for (id, w) in self.locate(t, bary) {
            let src = &values[id as usize * k..id as usize * k + k];
            for (o, s) in out.iter_mut().zip(src) {
                *o += w * s;
            }
        }
    }

    /// The lattice cells of stride `q` (a power of two dividing m) as
    /// triangles of point ids, in each fluid triangle's orientation.
    pub fn cells(&self, q: u32) -> Vec<[u32; 3]> {
        let n = self.m / q;
        let mut tris = Vec::with_capacity(self.triangles.len() * (n * n) as usize);
        for t in 0..self.triangles.len() {
            for i in 0..n {
                for j in 0..(n - i) {
                    let at = |a: u32, b: u32| self.id(t, a * q, b * q);
                    tris.push([at(i, j), at(i + 1, j), at(i, j + 1)]);
                    if i + j + 1 < n {
                        tris.push([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                    }
                }
            }
        }
        tris
    }

    /// The level of stride `stride` (a power of two dividing m; values
    /// above m are clamped to m: the fluid vertices themselves).
    pub fn level(&self, stride: u32) -> Level {
        if let Some(s) = &self.scatter {
            return s.levels[s.level_index(stride)].clone();
        }
        let q = stride.clamp(1, self.m);
        let tris = self.cells(q);
        let mut local = vec![u32::MAX; self.len()];
        let mut ids: Vec<u32> = tris.iter().flatten().copied().collect();
        ids.sort_unstable();
        ids.dedup();
        for (k, &id) in ids.iter().enumerate() {
            local[id as usize] = k as u32;
        }
        let triangles: Vec<[u32; 3]> = tris.iter().map(|t| t.map(|v| local[v as usize])).collect();
        Level::new(
            q,
            ids.iter().map(|&i| self.positions[i as usize]).collect(),
            ids.iter().map(|&i| self.normals[i as usize]).collect(),
            ids,
            local,
            triangles,
        )
    }

    /// Interpolates per-point values (`k` floats each) known on the level
    /// of stride `from` onto every point of the level of stride `to`
    /// (`to` ≤ `from`), writing into `out` indexed by fine point id. Points
    /// on shared edges are written by the first triangle that holds them.
    pub fn prolong(&self, from: &Level, values: &[f32], k: usize, to: &Level, out: &mut [f32]) {
        if let Some(s) = &self.scatter {
            return s.prolong(from, values, k, to, out);
        }
        let mut done = vec![false; to.ids.len()];
        let (qf, qt) = (from.stride, to.stride);
        let nt = self.m / qt;
        let mut buf = vec![0.0f32; k];
        for t in 0..self.triangles.len() {
            for i in 0..=nt {
                for j in 0..=(nt - i) {
                    let id = self.id(t, i * qt, j * qt);
                    let l = to.local[id as usize];
                    if l == u32::MAX || done[l as usize] {
                        continue;
                    }
                    done[l as usize] = true;
                    let bary = [
                        1.0 - (i + j) as f32 / nt as f32,
                        i as f32 / nt as f32,
                        j as f32 / nt as f32,
                    ];
                    buf.fill(0.0);
                    for (pid, w) in self.locate_stride(t, bary, qf) {
                        let fl = from.local[pid as usize] as usize;
                        for c in 0..k {
                            buf[c] += w * values[fl * k + c];
                        }
                    }
                    out[l as usize * k..l as usize * k + k].copy_from_slice(&buf);
                }
            }
        }
    }
}

impl Lattice {
    /// The values of level `from` carried up to the finer level `to`
    /// ([`Lattice::prolong`]), then diffused by `sweeps` rounds of
    /// [`Level::smooth`] at the finer level: the 2007 paper's up-sampling
    /// (copy, then diffusion; it names no count) where `sweeps` > 0.
    pub fn upsample(
        &self,
        from: &Level,
        values: &[f32],
        k: usize,
        to: &Level,
        sweeps: u32,
    ) -> Vec<f32> {
        let mut up = vec![0.0f32; to.len() * k];
        self.prolong(from, values, k, to, &mut up);
        for _ in 0..sweeps {
            up = to.smooth(&up, k);
        }
        up
    }
}
