//! One level of the point hierarchy: a triangle mesh over a subset of
//! the finest points, with its vertex adjacency, as the lattice and the
//! scattered points both build it.

use glam::Vec3;

/// One level of the hierarchy: a triangle mesh over a subset of the points.
#[derive(Clone)]
pub struct Level {
    /// Lattice stride of this level (1: finest).
    pub stride: u32,
    /// Fine point id of each level vertex (ascending).
    pub ids: Vec<u32>,
    /// Fine point id → level vertex (u32::MAX when absent).
    pub local: Vec<u32>,
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    adj_offsets: Vec<u32>,
    adj: Vec<u32>,
    tri_offsets: Vec<u32>,
    vtris: Vec<u32>,
    /// Mean edge length (world units).
    pub mean_edge: f32,
}

impl Level {
    pub(super) fn new(
        stride: u32,
        positions: Vec<Vec3>,
        normals: Vec<Vec3>,
        ids: Vec<u32>,
        local: Vec<u32>,
        triangles: Vec<[u32; 3]>,
    ) -> Level {
        let n = positions.len();
        let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(triangles.len() * 6);
        let mut vt: Vec<(u32, u32)> = Vec::with_capacity(triangles.len() * 3);
        let mut edge_sum = 0.0f64;
        let mut edge_n = 0usize;
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                pairs.push((a, b));
                pairs.push((b, a));
                vt.push((a, t as u32));
                edge_sum += positions[a as usize].distance(positions[b as usize]) as f64;
                edge_n += 1;
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        vt.sort_unstable();
        let csr = |list: &[(u32, u32)]| {
            let mut off = vec![0u32; n + 1];
            for &(a, _) in list {
                off[a as usize + 1] += 1;
            }
            for i in 0..n {
                off[i + 1] += off[i];
            }
            (off, list.iter().map(|&(_, b)| b).collect::<Vec<u32>>())
        };
        let (adj_offsets, adj) = csr(&pairs);
        let (tri_offsets, vtris) = csr(&vt);
        Level {
            stride,
            ids,
            local,
            positions,
            normals,
            triangles,
            adj_offsets,
            adj,
            tri_offsets,
            vtris,
            mean_edge: if edge_n > 0 {
                (edge_sum / edge_n as f64) as f32
            } else {
                0.0
            },
        }
    }

    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Vertices sharing an edge with `v` (ascending).
    #[inline]
    pub fn neighbours(&self, v: u32) -> &[u32] {
        &self.adj[self.adj_offsets[v as usize] as usize..self.adj_offsets[v as usize + 1] as usize]
    }

    /// Triangles around `v` (ascending).
    #[inline]
    pub fn vertex_triangles(&self, v: u32) -> &[u32] {
        &self.vtris
            [self.tri_offsets[v as usize] as usize..self.tri_offsets[v as usize + 1] as usize]
    }

    /// Averages `k`-float values over each vertex and its 1-ring (Jacobi,
    /// deterministic): the diffusion used after copying values up a level
    /// and to filter values down one.
    pub fn smooth(&self, values: &[f32], k: usize) -> Vec<f32> {
        use rayon::prelude::*;
        let mut out = vec![0.0f32; values.len()];
        out.par_chunks_mut(k).enumerate().for_each(|(v, o)| {
            let nb = self.neighbours(v as u32);
            if nb.is_empty() {
                o.copy_from_slice(&values[v * k..v * k + k]);
                return;
            }
            let w_self = 1.0;
            let w_n = 1.0 / nb.len() as f32;
            for c in 0..k {
                let mut s = 0.0;
                for &u in nb {
                    s += values[u as usize * k + c];
                }
                o[c] = (w_self * values[v * k + c] + w_n * s) / 2.0;
            }
        });
        out
    }
}
