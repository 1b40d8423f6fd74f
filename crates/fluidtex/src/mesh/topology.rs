//! Adjacency built on demand from a [`TriMesh`](super::TriMesh)'s index array.
//!
//! Fluid meshes are often non-manifold (an edge shared by more than two
//! triangles where sheets touch), so this is not a half-edge structure: an
//! edge is matched by its sorted vertex pair, and triangles are neighbours
//! when they share one. Everything is built by sorting, so results do not
//! depend on hashing or thread count.

/// Vertex-to-triangle incidence, triangle edge-neighbours and edge counts.
#[derive(Clone, Debug)]
pub struct Topology {
    /// CSR offsets into `vertex_tris`: triangles around vertex v are
    /// `vertex_tris[vertex_offsets[v]..vertex_offsets[v + 1]]`, ascending.
    vertex_offsets: Vec<u32>,
    vertex_tris: Vec<u32>,
    /// Per triangle and edge k (corner k to corner k+1): the other triangles
    /// sharing that edge, as CSR like the above.
    edge_offsets: Vec<u32>,
    edge_neighbours: Vec<u32>,
    /// Per vertex: true when it lies on an edge used by exactly one triangle.
    boundary_vertex: Vec<bool>,
}

impl Topology {
    /// Builds the adjacency of `triangles` over `vertex_count` vertices.
    pub fn new(vertex_count: usize, triangles: &[[u32; 3]]) -> Topology {
        // Vertex -> triangles by counting sort.
        let mut vertex_offsets = vec![0u32; vertex_count + 1];
        for tri in triangles {
            for &v in tri {
                vertex_offsets[v as usize + 1] += 1;
            }
        }
        for i in 0..vertex_count {
            vertex_offsets[i + 1] += vertex_offsets[i];
        }
        let mut fill = vertex_offsets.clone();
        let mut vertex_tris = vec![0u32; triangles.len() * 3];
        for (t, tri) in triangles.iter().enumerate() {
            for &v in tri {
                vertex_tris[fill[v as usize] as usize] = t as u32;
                fill[v as usize] += 1;
            }
        }

        // Edges: (min, max, triangle, k), sorted so equal edges are adjacent.
        let mut edges: Vec<(u32, u32, u32, u8)> = Vec::with_capacity(triangles.len() * 3);
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                edges.push((a.min(b), a.max(b), t as u32, k as u8));
            }
        }
        edges.sort_unstable();
        let mut counts = vec![0u32; triangles.len() * 3 + 1];
        let mut boundary_vertex = vec![false; vertex_count];
        let mut groups = Vec::new();
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && edges[j].0 == edges[i].0 && edges[j].1 == edges[i].1 {
                j += 1;
            }
            if j - i == 1 {
                boundary_vertex[edges[i].0 as usize] = true;
                boundary_vertex[edges[i].1 as usize] = true;
            }
            for e in &edges[i..j] {
                counts[(e.2 as usize) * 3 + e.3 as usize + 1] += (j - i - 1) as u32;
            }
            groups.push((i, j));
            i = j;
        }
        for i in 0..triangles.len() * 3 {
            counts[i + 1] += counts[i];
        }
        let edge_offsets = counts;
        let mut fill = edge_offsets.clone();
        let mut edge_neighbours = vec![0u32; edge_offsets[triangles.len() * 3] as usize];
        for (i, j) in groups {
            for a in &edges[i..j] {
                for b in &edges[i..j] {
                    if a.2 != b.2 || a.3 != b.3 {
                        let slot = (a.2 as usize) * 3 + a.3 as usize;
                        edge_neighbours[fill[slot] as usize] = b.2;
                        fill[slot] += 1;
                    }
                }
            }
        }
        Topology {
            vertex_offsets,
            vertex_tris,
            edge_offsets,
            edge_neighbours,
            boundary_vertex,
        }
    }

    /// Triangles using vertex `v`, ascending.
    #[inline]
    pub fn vertex_triangles(&self, v: u32) -> &[u32] {
        let v = v as usize;
        &self.vertex_tris[self.vertex_offsets[v] as usize..self.vertex_offsets[v + 1] as usize]
    }

    /// Triangles sharing edge `k` (corner k to corner k+1) of triangle `t`.
    #[inline]
    pub fn edge_neighbours(&self, t: u32, k: usize) -> &[u32] {
        let slot = t as usize * 3 + k;
        &self.edge_neighbours
            [self.edge_offsets[slot] as usize..self.edge_offsets[slot + 1] as usize]
    }

    /// All triangles sharing an edge with `t` (with repeats where an edge is
    /// shared by several).
    pub fn triangle_neighbours(&self, t: u32) -> impl Iterator<Item = u32> + '_ {
        (0..3).flat_map(move |k| self.edge_neighbours(t, k).iter().copied())
    }

    /// The edge-connected region grown from triangle `seed` through the
    /// triangles `accept` admits (the seed itself always belongs), in the
    /// order they were reached. A patch's footprint and a tracker's
    /// receivers both grow this way, so neither jumps to a disjoint sheet
    /// of the surface that happens to lie within reach.
    pub fn grow_region(&self, seed: u32, mut accept: impl FnMut(u32) -> bool) -> Vec<u32> {
        let mut taken = vec![seed];
        let mut seen = std::collections::HashSet::from([seed]);
        let mut head = 0;
        while head < taken.len() {
            let t = taken[head];
            head += 1;
            for nb in self.triangle_neighbours(t) {
                if seen.insert(nb) && accept(nb) {
                    taken.push(nb);
                }
            }
        }
        taken
    }

    /// True when edge `k` of triangle `t` belongs to no other triangle.
    #[inline]
    pub fn is_boundary_edge(&self, t: u32, k: usize) -> bool {
        self.edge_neighbours(t, k).is_empty()
    }

    /// True when vertex `v` lies on a boundary edge.
    #[inline]
    pub fn is_boundary_vertex(&self, v: u32) -> bool {
        self.boundary_vertex[v as usize]
    }

    /// Number of boundary edges (0 for a closed mesh).
    pub fn boundary_edge_count(&self) -> usize {
        (0..self.edge_offsets.len() - 1)
            .filter(|&s| self.edge_offsets[s] == self.edge_offsets[s + 1])
            .count()
    }

    /// Edge-connected component label per triangle (labels 0.. in order of
    /// the lowest triangle index of each component) and the component count.
    pub fn components(&self) -> (Vec<u32>, u32) {
        let n = self.edge_offsets.len() / 3;
        let mut label = vec![u32::MAX; n];
        let mut next = 0;
        let mut stack = Vec::new();
        for seed in 0..n {
            if label[seed] != u32::MAX {
                continue;
            }
            label[seed] = next;
            stack.push(seed as u32);
            while let Some(t) = stack.pop() {
                for nb in self.triangle_neighbours(t) {
                    if label[nb as usize] == u32::MAX {
                        label[nb as usize] = next;
                        stack.push(nb);
                    }
                }
            }
            next += 1;
        }
        (label, next)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles sharing edge 0-2 plus a separate triangle.
    fn mesh() -> Vec<[u32; 3]> {
        vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]]
    }

    #[test]
    fn incidence_and_neighbours() {
        let topo = Topology::new(7, &mesh());
        assert_eq!(topo.vertex_triangles(0), &[0, 1]);
        assert_eq!(topo.vertex_triangles(5), &[2]);
        assert_eq!(topo.edge_neighbours(0, 2), &[1]); // edge 2-0
        assert_eq!(topo.edge_neighbours(1, 0), &[0]); // edge 0-2
        assert!(topo.is_boundary_edge(0, 0));
        assert_eq!(topo.boundary_edge_count(), 7);
        assert!((0..7).all(|v| topo.is_boundary_vertex(v)));
        assert_eq!(topo.components(), (vec![0, 0, 1], 2));
    }

    #[test]
    fn closed_tetrahedron_has_no_boundary() {
        let tris = vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]];
        let topo = Topology::new(4, &tris);
        assert_eq!(topo.boundary_edge_count(), 0);
        assert!((0..4).all(|v| !topo.is_boundary_vertex(v)));
        for t in 0..4 {
            assert_eq!(topo.triangle_neighbours(t).count(), 3);
        }
    }

    #[test]
    fn non_manifold_edge_links_all_its_triangles() {
        let tris = vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]];
        let topo = Topology::new(5, &tris);
        let mut nb: Vec<u32> = topo.edge_neighbours(0, 0).to_vec();
        nb.sort();
        assert_eq!(nb, vec![1, 2]);
        assert!(!topo.is_boundary_edge(0, 0));
        assert_eq!(topo.boundary_edge_count(), 6);
    }
}
