//! The default patch radius, from the first frame's extent and edge
//! lengths (docs/design.md, *Patch radius and exemplar size*).

use super::ErosionParams;

/// The default patch radius (docs/design.md, *Patch radius and exemplar
/// size*): `radius_fraction` × the first frame's bounding-box diagonal, but
/// never below `radius_edges` median edge lengths, so that a patch spans
/// enough fluid triangles for its shape and its far-vertex test (r/4) to
/// stand above the re-meshing noise of the surface. Returns r and a sentence
/// saying which rule won.
pub fn default_radius(mesh: &crate::mesh::TriMesh, params: &ErosionParams) -> (f32, String) {
    let (lo, hi) = mesh.bounding_box().unwrap_or_default();
    let diagonal = lo.distance(hi);
    let by_extent = params.radius_fraction * diagonal;
    let edge = median_edge_length(mesh);
    let by_edges = params.radius_edges * edge;
    if by_edges > by_extent {
        (
            by_edges,
            format!(
                "r = {by_edges:.4} = {} × the median edge length {edge:.4} of the first frame \
                 (larger than {} × its bounding-box diagonal = {by_extent:.4})",
                params.radius_edges, params.radius_fraction
            ),
        )
    } else {
        (
            by_extent,
            format!(
                "r = {by_extent:.4} = {} × the first frame's bounding-box diagonal {diagonal:.4} \
                 (at least {} median edge lengths = {by_edges:.4})",
                params.radius_fraction, params.radius_edges
            ),
        )
    }
}

/// Median length of the mesh's triangle edges (each interior edge counted
/// twice, which does not move the median of a closed or nearly closed mesh).
pub fn median_edge_length(mesh: &crate::mesh::TriMesh) -> f32 {
    let mut lengths: Vec<f32> = (0..mesh.triangle_count())
        .flat_map(|t| {
            let [a, b, c] = mesh.corners(t);
            [a.distance(b), b.distance(c), c.distance(a)]
        })
        .filter(|l| l.is_finite())
        .collect();
    if lengths.is_empty() {
        return 0.0;
    }
    let mid = lengths.len() / 2;
    let (_, m, _) = lengths.select_nth_unstable_by(mid, f32::total_cmp);
    *m
}
