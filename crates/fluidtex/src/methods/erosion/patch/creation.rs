//! Making a new patch's rest shape (Gagnon et al. 2021, Sec. 4): the fluid
//! triangles around p, flattened by LSCM (projection where it fails), the
//! pieces LSCM cannot reach fitted to it, and the rest coordinates (exemplar
//! uv) each vertex keeps for the patch's life.

use glam::{Vec2, Vec3};

use super::{FrameSurface, PatchShape};
use crate::mesh::TriMesh;

/// The fluid triangles within r of `p` for which `near` holds, outside
/// `connected` (sorted), in increasing order: through the BVH's box query
/// when the surface has one, else by testing every triangle.
pub(super) fn triangles_near(
    surface: &FrameSurface<'_>,
    p: Vec3,
    radius: f32,
    near: &impl Fn(u32) -> bool,
    connected: &[u32],
) -> Vec<u32> {
    let mut found = Vec::new();
    let consider = |t: u32| {
        if connected.binary_search(&t).is_err() && near(t) {
            found.push(t);
        }
    };
    match surface.index {
        Some(index) => {
            index.triangles_in_box(p - Vec3::splat(radius), p + Vec3::splat(radius), consider)
        }
        None => (0..surface.mesh.triangles.len() as u32).for_each(consider),
    }
    found.sort_unstable();
    found.dedup();
    found
}

/// The piece of a new patch that holds p, flattened.
pub(super) struct Piece<'a> {
    /// Its fluid triangles, sorted.
    pub(super) triangles: &'a [u32],
    pub(super) mesh: TriMesh,
    /// The fluid vertex of each of its vertices.
    pub(super) source: &'a [u32],
    pub(super) flat: Vec<Vec2>,
}

/// The patch mesh of `piece` and the triangles `others` (sorted, disjoint
/// from it), with its flat coordinates and the local index of `seed`. The
/// other triangles have no surface path to p, so LSCM cannot place them:
/// they take the affine map that best (least squares) sends the piece's
/// vertices, projected on the tangent plane of `n_p`, to their flat
/// coordinates, which is the piece's own flattening where the surface is
/// flat and a projection along `n_p` elsewhere.
pub(super) fn join_pieces(
    mesh: &TriMesh,
    piece: Piece<'_>,
    others: &[u32],
    n_p: Vec3,
    seed: u32,
) -> (TriMesh, Vec<Vec2>, usize) {
    if others.is_empty() {
        let seed_local = piece.triangles.binary_search(&seed).unwrap_or(0);
        return (piece.mesh, piece.flat, seed_local);
    }
    let (a, b) = n_p.normalize_or(Vec3::Z).any_orthonormal_pair();
    let project = |x: Vec3| [f64::from(x.dot(a)), f64::from(x.dot(b))];
    let map = TangentMap::fit(
        piece.mesh.positions.iter().map(|&x| project(x)),
        piece.flat.iter().map(|q| [f64::from(q.x), f64::from(q.y)]),
    );
    let flat_of: std::collections::HashMap<u32, Vec2> = piece
        .source
        .iter()
        .copied()
        .zip(piece.flat.iter().copied())
        .collect();
    let mut all: Vec<u32> = piece.triangles.iter().chain(others).copied().collect();
    all.sort_unstable();
    let (sub, source) = mesh.submesh(&all);
    let flat = source
        .iter()
        .zip(&sub.positions)
        .map(|(v, &x)| match flat_of.get(v) {
            Some(&q) => q,
            None => map.apply(project(x)),
        })
        .collect();
    let seed_local = all.binary_search(&seed).unwrap_or(0);
    (sub, flat, seed_local)
}

/// An affine map of the plane, q ↦ A q + t.
struct TangentMap {
    a: [[f64; 2]; 2],
    t: [f64; 2],
}

impl TangentMap {
    /// The least-squares affine map from the points `from` to `to`; where
    /// `from` spans no area (collinear), the translation of the centroids.
    fn fit(from: impl Iterator<Item = [f64; 2]>, to: impl Iterator<Item = [f64; 2]>) -> TangentMap {
        let (from, to): (Vec<[f64; 2]>, Vec<[f64; 2]>) = from.zip(to).unzip();
        let centroid = |points: &[[f64; 2]]| {
            let n = points.len().max(1) as f64;
            let sum = points
                .iter()
                .fold([0.0, 0.0], |s, q| [s[0] + q[0], s[1] + q[1]]);
            [sum[0] / n, sum[1] / n]
        };
        let (qm, fm) = (centroid(&from), centroid(&to));
        // Normal equations: A = (Σ f̃ q̃ᵀ)(Σ q̃ q̃ᵀ)⁻¹.
        let (mut qq, mut fq) = ([[0.0f64; 2]; 2], [[0.0f64; 2]; 2]);
        for (q, f) in from.iter().zip(&to) {
            let dq = [q[0] - qm[0], q[1] - qm[1]];
            let df = [f[0] - fm[0], f[1] - fm[1]];
            for i in 0..2 {
                for j in 0..2 {
                    qq[i][j] += dq[i] * dq[j];
                    fq[i][j] += df[i] * dq[j];
                }
            }
        }
        let det = qq[0][0] * qq[1][1] - qq[0][1] * qq[1][0];
        let scale = qq[0][0] * qq[1][1];
        let a = if det > 1e-12 * scale && det.is_finite() {
            let inv = [
                [qq[1][1] / det, -qq[0][1] / det],
                [-qq[1][0] / det, qq[0][0] / det],
            ];
            let mut a = [[0.0f64; 2]; 2];
            for i in 0..2 {
                for j in 0..2 {
                    a[i][j] = fq[i][0] * inv[0][j] + fq[i][1] * inv[1][j];
                }
            }
            a
        } else {
            [[1.0, 0.0], [0.0, 1.0]]
        };
        let t = [
            fm[0] - (a[0][0] * qm[0] + a[0][1] * qm[1]),
            fm[1] - (a[1][0] * qm[0] + a[1][1] * qm[1]),
        ];
        TangentMap { a, t }
    }

    fn apply(&self, q: [f64; 2]) -> Vec2 {
        let a = &self.a;
        Vec2::new(
            (a[0][0] * q[0] + a[0][1] * q[1] + self.t[0]) as f32,
            (a[1][0] * q[0] + a[1][1] * q[1] + self.t[1]) as f32,
        )
    }
}

/// The rest coordinates (exemplar uv) of a new patch's vertices: `sub`
/// flattened (`flat`, by [`flatten`]), unmirrored seen from `n_p`, scaled so that uv area
/// equals 3-D area / S², the point at `bary` of triangle `seed_local` at
/// (0.5, 0.5), turned by `rotation` (or aligned to `align`).
#[allow(clippy::too_many_arguments)]
pub(super) fn rest_coordinates(
    sub: &TriMesh,
    flat: &[Vec2],
    seed_local: usize,
    bary: [f32; 3],
    n_p: Vec3,
    shape: &PatchShape,
    rotation: f32,
    align: Option<Vec3>,
) -> Vec<Vec2> {
    // Orientation: seen from the side the normal points to, the exemplar
    // must not be mirrored. Our uv has v pointing down (texture.rs), so an
    // unmirrored map has negative signed uv area for CCW triangles.
    let signed: f64 = sub
        .triangles
        .iter()
        .map(|t| {
            let (a, b, c) = (
                flat[t[0] as usize],
                flat[t[1] as usize],
                flat[t[2] as usize],
            );
            (b - a).perp_dot(c - a) as f64
        })
        .sum();
    let flip = if signed > 0.0 { -1.0 } else { 1.0 };
    let flat: Vec<Vec2> = flat.iter().map(|q| Vec2::new(q.x, q.y * flip)).collect();
    let uv_area = signed.abs() * 0.5;
    let area_3d = sub.area();
    let scale = if uv_area > 0.0 {
        ((area_3d / (shape.exemplar_size as f64).powi(2)) / uv_area).sqrt() as f32
    } else {
        1.0 / shape.exemplar_size
    };
    let [ia, ib, ic] = sub.triangles[seed_local];
    let p_flat =
        flat[ia as usize] * bary[0] + flat[ib as usize] * bary[1] + flat[ic as usize] * bary[2];
    let rotation = match align {
        Some(axis) => {
            let [a, b, c] = sub.triangles[seed_local].map(|v| v as usize);
            let corners = [sub.positions[a], sub.positions[b], sub.positions[c]];
            let flat_corners = [flat[a], flat[b], flat[c]];
            aligned_rotation(corners, flat_corners, n_p, axis).unwrap_or(rotation)
        }
        None => rotation,
    };
    let (sin, cos) = rotation.sin_cos();
    flat.iter()
        .map(|&q| {
            let d = (q - p_flat) * scale;
            Vec2::new(cos * d.x - sin * d.y, sin * d.x + cos * d.y) + Vec2::splat(0.5)
        })
        .collect()
}

/// The rotation (radians, applied to the flattened patch) that turns the
/// exemplar's up, −v in uv (v points down), to `axis` projected on the
/// tangent plane of `normal`, carried into the flat patch through the
/// linear map of the seed triangle (3-D corners to flat corners). Where the
/// axis is nearly normal to the surface, a fixed perpendicular axis stands in.
/// `None` for a degenerate seed triangle.
fn aligned_rotation(corners: [Vec3; 3], flat: [Vec2; 3], normal: Vec3, axis: Vec3) -> Option<f32> {
    let n = normal.normalize_or_zero();
    let project = |a: Vec3| a - n * a.dot(n);
    let mut along = project(axis.normalize_or_zero());
    if along.length() < 0.2 {
        along = project(axis.any_orthonormal_vector());
    }
    // Linear map of the seed triangle: 3-D edge e_k ↦ flat edge f_k; a
    // tangent vector t = α e1 + β e2 maps to α f1 + β f2.
    let (e1, e2) = (corners[1] - corners[0], corners[2] - corners[0]);
    let (f1, f2) = (flat[1] - flat[0], flat[2] - flat[0]);
    let (g11, g12, g22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = g11 * g22 - g12 * g12;
    if det <= f32::EPSILON * g11 * g22 {
        return None;
    }
    let (r1, r2) = (along.dot(e1), along.dot(e2));
    let alpha = (g22 * r1 - g12 * r2) / det;
    let beta = (g11 * r2 - g12 * r1) / det;
    let d = f1 * alpha + f2 * beta;
    if d.length_squared() == 0.0 || !d.is_finite() {
        return None;
    }
    // Rotate d onto (0, −1).
    Some(-std::f32::consts::FRAC_PI_2 - d.y.atan2(d.x))
}

/// Flattens one connected patch: LSCM, or, should it fail (degenerate
/// input), the orthogonal projection onto the tangent plane of `normal`,
/// which is what the 2016 method uses for every patch.
pub(super) fn flatten(positions: &[Vec3], triangles: &[[u32; 3]], normal: Vec3) -> Vec<Vec2> {
    if let Ok(uv) = crate::param::lscm::lscm(positions, triangles)
        && uv.iter().all(|q| q.is_finite())
    {
        return uv;
    }
    let n = if normal.length_squared() > 0.0 {
        normal.normalize()
    } else {
        Vec3::Z
    };
    let (a, b) = n.any_orthonormal_pair();
    positions
        .iter()
        .map(|&q| Vec2::new(q.dot(a), q.dot(b)))
        .collect()
}
