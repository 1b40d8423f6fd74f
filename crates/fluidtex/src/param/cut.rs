//! Cutting flattened charts that are too long for the atlas.
//!
//! **Why.** The packer scales every chart by one factor, so the longest
//! chart caps the scale: a chart whose longer side is L (world units) fits
//! only while `L · s ≤ W`. One long ribbon (a strip of river, a thin sheet
//! that the segmentation kept whole because it is flat and a disc) then
//! holds the whole atlas at a fraction of its room: a flat 64 × 1 strip in
//! a 256² atlas packs whole at 3.9 texels per unit, 1.5 % of the atlas,
//! and cut into pieces as below it fills more than 40 % (the atlas test
//! `a_long_strip_is_cut_so_that_it_does_not_cap_the_scale`). On the
//! Mantaflow splash the charts that capped the scale were not long sheets
//! but slivers that LSCM had blown up, which [`super::flatten`] now
//! flattens on their own; after that no splash chart (48 frames, 1024²)
//! reaches the bound, and this cut leaves them as they are.
//!
//! **Rule.** With A the surface area of the whole mesh, the packer can at
//! best reach the scale `s_f = √(f · W · H / A)` at which the charts cover
//! a share f = [`TARGET_FILL`] of the atlas. A chart longer than
//! `min(W, H) / s_f` would stop the search below that fill, so it is cut:
//! into k = ⌈L / (0.9 L_max)⌉ slabs across its longer side (in the frame of its
//! minimum-area rectangle, each triangle by its centroid), each slab into its
//! edge-connected pieces, and every piece cut again while it is still too
//! long. The flattening of a piece is the chart's own, restricted to it, so
//! nothing is solved again and every piece stays injective; the cut only
//! adds a seam, which the atlas treats as any other chart border (each side
//! gets its own texels and dilation). A round chart is not cut: a disc of
//! diameter D has `D · s_f < W` at f = 0.75.
//!
//! Charts shorter than the bound are returned untouched, so a mesh without
//! long charts gets exactly the atlas it got before.

use std::collections::HashMap;

use glam::DVec2;

use crate::mesh::Topology;

use super::flatten::FlatChart;
use super::pack::MinAreaRect;

/// The atlas share f that the length bound assumes the packer reaches
/// (the skyline-with-holes packer fills 68–80 % on fluid frames whose
/// charts are not limited by one long sheet).
pub const TARGET_FILL: f64 = 0.75;

/// Slab length as a share of the bound (see [`cut_long`]).
const SLAB_SHARE: f64 = 0.9;

/// The longest chart side (world units) that does not cap the packing
/// scale of a mesh of surface area `area` in a `width × height` atlas
/// (module doc). `None` when the mesh has no area.
pub fn max_chart_length(area: f64, width: u32, height: u32) -> Option<f64> {
    if !area.is_finite() || area <= 0.0 || width == 0 || height == 0 {
        return None;
    }
    let (w, h) = (width as f64, height as f64);
    let scale = (TARGET_FILL * w * h / area).sqrt();
    Some(w.min(h) / scale)
}

/// Appends `chart` to `out`, cut into pieces no longer than `max_len` where
/// its triangles allow (module doc). Pieces come in the order of their
/// lowest triangle, each with its triangles ascending.
pub fn cut_long(chart: FlatChart, max_len: f64, out: &mut Vec<FlatChart>) {
    let n = chart.local_triangles.len();
    if n < 2 {
        out.push(chart);
        return;
    }
    let rect = MinAreaRect::of(&chart);
    if rect.size.x.is_nan() || rect.size.x <= max_len {
        out.push(chart);
        return;
    }
    // Slabs a tenth shorter than the bound: a slab's triangles reach past
    // its edges by up to a triangle, and a piece just over the bound would
    // be halved again into slivers.
    let k = ((rect.size.x / (SLAB_SHARE * max_len)).ceil() as usize).clamp(2, n);
    let slab: Vec<usize> = chart
        .local_triangles
        .iter()
        .map(|t| {
            let c = t
                .map(|v| rect.turn(chart.uv[v as usize].as_dvec2()))
                .iter()
                .fold(DVec2::ZERO, |a, &p| a + p)
                / 3.0;
            ((c.x / rect.size.x * k as f64).floor().max(0.0) as usize).min(k - 1)
        })
        .collect();
    let pieces = connected_within(&chart.local_triangles, chart.vertices.len(), &slab);
    if pieces.len() < 2 {
        // Every centroid in one slab (a few huge triangles): nothing to cut.
        out.push(chart);
        return;
    }
    for piece in pieces {
        cut_long(sub_chart(&chart, &piece), max_len, out);
    }
}

/// Groups triangles into pieces: two triangles sharing an edge
/// ([`Topology`]) are in one piece when they have the same label. Pieces
/// ordered by their first triangle, triangles ascending.
fn connected_within(tris: &[[u32; 3]], vertex_count: usize, label: &[usize]) -> Vec<Vec<usize>> {
    let topo = Topology::new(vertex_count, tris);
    // Labels spread from each piece's first triangle, in index order.
    let mut piece_of = vec![usize::MAX; tris.len()];
    let mut pieces: Vec<Vec<usize>> = Vec::new();
    for first in 0..tris.len() {
        if piece_of[first] != usize::MAX {
            continue;
        }
        let p = pieces.len();
        piece_of[first] = p;
        let mut members = vec![first];
        let mut next = 0;
        while let Some(&t) = members.get(next) {
            next += 1;
            for k in 0..3 {
                for &nb in topo.edge_neighbours(t as u32, k) {
                    let nb = nb as usize;
                    if piece_of[nb] == usize::MAX && label[nb] == label[first] {
                        piece_of[nb] = p;
                        members.push(nb);
                    }
                }
            }
        }
        members.sort_unstable();
        pieces.push(members);
    }
    pieces
}

/// The chart restricted to its local triangles `piece` (ascending), chart
/// vertices renumbered in first-use order.
fn sub_chart(chart: &FlatChart, piece: &[usize]) -> FlatChart {
    let mut local: HashMap<u32, u32> = HashMap::with_capacity(piece.len());
    let mut vertices = Vec::new();
    let mut uv = Vec::new();
    let local_triangles = piece
        .iter()
        .map(|&t| {
            chart.local_triangles[t].map(|v| {
                *local.entry(v).or_insert_with(|| {
                    vertices.push(chart.vertices[v as usize]);
                    uv.push(chart.uv[v as usize]);
                    (vertices.len() - 1) as u32
                })
            })
        })
        .collect();
    FlatChart {
        triangles: piece.iter().map(|&t| chart.triangles[t]).collect(),
        vertices,
        local_triangles,
        uv,
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec2;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;

    /// A flat grid chart of `nx × ny` unit squares (two triangles each),
    /// turned by `angle`, counter-clockwise in image orientation as
    /// flatten returns them.
    fn grid(nx: u32, ny: u32, angle: f32) -> FlatChart {
        let (s, c) = angle.sin_cos();
        let mut uv = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                let (x, y) = (i as f32, j as f32);
                uv.push(Vec2::new(c * x - s * y, s * x + c * y));
            }
        }
        let local_triangles = crate::atlas::fixtures::grid_triangles(nx, ny);
        FlatChart {
            triangles: (0..local_triangles.len() as u32)
                .map(|t| 10 + 2 * t)
                .collect(),
            vertices: (0..uv.len() as u32).map(|v| 1000 + v).collect(),
            local_triangles,
            uv,
        }
    }

    fn area(c: &FlatChart) -> f64 {
        c.local_triangles
            .iter()
            .map(|t| {
                let [a, b, d] = t.map(|v| c.uv[v as usize].as_dvec2());
                0.5 * (b - a).perp_dot(d - a).abs()
            })
            .sum()
    }

    #[test]
    fn the_length_bound_is_the_side_at_the_target_fill() {
        // 1024² atlas, area 16: s_f = √(0.75 · 1024² / 16) = 221.7, so
        // L_max = 1024 / 221.7 = 4.619 = √(16 / 0.75).
        let l = max_chart_length(16.0, 1024, 1024).expect("area");
        assert!((l - (16.0f64 / 0.75).sqrt()).abs() < 1e-12, "{l}");
        // A 2:1 atlas: the shorter side bounds the length.
        let l2 = max_chart_length(16.0, 2048, 1024).expect("area");
        assert!((l2 - 1024.0 / (0.75f64 * 2048.0 * 1024.0 / 16.0).sqrt()).abs() < 1e-12);
        assert_eq!(max_chart_length(0.0, 1024, 1024), None);
        assert_eq!(max_chart_length(f64::NAN, 1024, 1024), None);
    }

    #[test]
    fn a_chart_within_the_bound_is_returned_as_it_was() {
        let chart = grid(10, 4, 0.3);
        let mut out = Vec::new();
        cut_long(chart.clone(), 10.01, &mut out);
        assert_eq!(out, vec![chart]);
    }

    #[test]
    fn a_long_strip_is_cut_into_equal_slabs_that_keep_its_flattening() {
        // A 12 × 2 strip turned by 0.7 rad, bound 5: k = ⌈12 / 4.5⌉ = 3 slabs
        // of 4 columns, each 16 triangles.
        let chart = grid(12, 2, 0.7);
        let mut out = Vec::new();
        cut_long(chart.clone(), 5.0, &mut out);
        assert_eq!(out.len(), 3);
        for piece in &out {
            assert_eq!(piece.local_triangles.len(), 16);
            let rect = MinAreaRect::of(piece);
            assert!((rect.size.x - 4.0).abs() < 1e-4, "{:?}", rect.size);
            assert!(area(piece) > 0.0);
        }
        // Every triangle in exactly one piece, ascending, with its corners'
        // input vertices and uv unchanged.
        let mut all: Vec<u32> = out.iter().flat_map(|p| p.triangles.clone()).collect();
        assert!(out.iter().all(|p| p.triangles.is_sorted()));
        all.sort_unstable();
        assert_eq!(all, chart.triangles);
        for piece in &out {
            for (&t, local) in piece.triangles.iter().zip(&piece.local_triangles) {
                let i = chart
                    .triangles
                    .iter()
                    .position(|&u| u == t)
                    .expect("triangle");
                let orig = chart.local_triangles[i];
                for k in 0..3 {
                    let (v, o) = (local[k] as usize, orig[k] as usize);
                    assert_eq!(piece.vertices[v], chart.vertices[o]);
                    assert_eq!(piece.uv[v], chart.uv[o]);
                }
            }
        }
        // Pieces in the order of their lowest triangle.
        let firsts: Vec<u32> = out.iter().map(|p| p.triangles[0]).collect();
        assert!(firsts.is_sorted(), "{firsts:?}");
    }

    #[test]
    fn random_long_charts_end_within_the_bound_and_lose_no_triangle() {
        let mut rng = Pcg64::seed_from_u64(41);
        for case in 0..20 {
            let (nx, ny) = (rng.random_range(3..40), rng.random_range(1..6));
            let angle = rng.random_range(0.0..std::f32::consts::TAU);
            let bound = rng.random_range(2.0..12.0f64).max(ny as f64 + 0.5);
            let chart = grid(nx, ny, angle);
            let mut out = Vec::new();
            cut_long(chart.clone(), bound, &mut out);
            let total: usize = out.iter().map(|p| p.local_triangles.len()).sum();
            assert_eq!(total, chart.local_triangles.len(), "case {case}");
            assert!((out.iter().map(area).sum::<f64>() - area(&chart)).abs() < 1e-3);
            for piece in &out {
                // A unit-square grid cut by centroids: a slab edge can leave a
                // triangle's half-width (½ unit) beyond the bound.
                let len = MinAreaRect::of(piece).size.x;
                assert!(len <= bound + 1.5, "case {case}: {len} > {bound}");
            }
            if (nx as f64) <= bound {
                assert_eq!(out.len(), 1, "case {case}");
            } else {
                assert!(out.len() >= 2, "case {case}");
            }
        }
    }

    #[test]
    fn a_cut_keeps_each_slab_in_its_connected_pieces() {
        // A U: two 1 × 8 legs joined by a 5 × 1 bottom. Its minimum-area
        // rectangle is 5 × 8 (legs along the long side); cut at 5.5 the legs
        // split across two slabs, and in the upper slab the two legs are
        // separate pieces.
        let mut chart = grid(5, 8, 0.0);
        // Keep the squares of columns 0 and 4 and of row 0 only.
        let keep: Vec<usize> = (0..chart.local_triangles.len())
            .filter(|&t| {
                let sq = t / 2;
                let (i, j) = (sq % 5, sq / 5);
                i == 0 || i == 4 || j == 0
            })
            .collect();
        chart = sub_chart(&chart, &keep);
        let mut out = Vec::new();
        cut_long(chart.clone(), 5.5, &mut out);
        assert_eq!(
            out.len(),
            3,
            "{:?}",
            out.iter().map(|p| p.triangles.len()).collect::<Vec<_>>()
        );
        let sizes: Vec<usize> = out.iter().map(|p| p.local_triangles.len()).collect();
        assert_eq!(sizes.iter().sum::<usize>(), chart.local_triangles.len());
        // The bottom with the legs' lower halves, then each leg's upper half.
        assert_eq!(sizes, vec![2 * (5 + 3 + 3), 8, 8]);
    }
}
