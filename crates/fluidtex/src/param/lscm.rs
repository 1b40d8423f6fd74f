//! Least-squares conformal maps (Lévy, Petitjean, Ray, Maillot 2002, "Least
//! Squares Conformal Maps for Automatic Texture Atlas Generation").
//!
//! **What.** A piecewise-linear map (u, v) of a disc-like triangle mesh to the
//! plane that is as close to conformal (angle preserving) as possible, in the
//! least-squares sense, with two vertices pinned to remove the similarity
//! (translation, rotation, scale) that leaves the energy unchanged.
//!
//! **Energy** (Lévy et al. 2002, section "Least Squares Conformal Maps":
//! conformality in a triangle, then its least-squares sum). On a triangle T with area
//! A_T, the map is conformal when it satisfies the Cauchy–Riemann equations
//! in a local orthonormal frame (x, y) of T:
//! `∂u/∂x − ∂v/∂y = 0` and `∂u/∂y + ∂v/∂x = 0`. With the linear basis
//! functions φ_j of the corners, `∇φ_j = rot90(p_{j+2} − p_{j+1}) / (2 A_T)`
//! = (a_j, b_j), both residuals are the real and imaginary parts of
//! `Σ_j (a_j + i b_j) z_j` with `z_j = u_j + i v_j`, and the energy
//! `C = Σ_T A_T |Σ_j (a_j + i b_j) z_j|²` is the paper's criterion written as
//! `‖M U‖²` with one complex row of M per triangle.
//! As written, the equations select the orientation-preserving solution: a
//! triangle counter-clockwise seen from the side its normal points to stays
//! counter-clockwise in (u, v).
//!
//! **Solve.** Pinned unknowns move to the right-hand side (as in the paper,
//! which pins two vertices to remove the similarity) and the
//! over-determined system is solved through its normal equations
//! `M_fᴴ M_f z_f = −M_fᴴ M_p z_p`, assembled per triangle in complex `f64`:
//! one complex unknown per free vertex, the same quadratic form as the real
//! 2n×2n system with half the rows and a quarter of the index entries
//! (measured 2× faster than the real form through faer). The matrix is
//! Hermitian positive definite for an edge-connected mesh with two distinct
//! pins, so Cholesky applies: faer's sparse Cholesky with AMD ordering for
//! large systems, faer's dense Cholesky for small ones (below ~64 free
//! vertices the symbolic analysis of the sparse path costs more than the
//! whole dense factorization). Sparse QR on the rectangular system measured
//! 6× slower than the normal equations (docs/design.md, *Crates and
//! measurements*). Both paths run sequentially (`Par::Seq`): callers
//! parallelize over patches and charts, and a fixed operation order keeps
//! results bit-identical whatever the thread count.
//!
//! **Pins.** The two vertices extreme along the longest axis of the bounding
//! box (lowest vertex index on ties), placed at (0, 0) and (d, 0) with d their
//! 3-D distance, so the uv scale is close to world units (callers apply their
//! own similarity anyway). The paper pins the two vertices farthest apart;
//! the bounding-box pair is a linear-time stand-in for that.

use faer::Par;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt;
use faer::prelude::*;
use faer::sparse::linalg::cholesky::{SymmetricOrdering, factorize_symbolic_cholesky};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, Side, c64};
use glam::{DVec2, DVec3, Vec2, Vec3};

use super::ParamError;

/// A triangle is degenerate when twice its area is at most this fraction of
/// its longest squared edge (its height is below this fraction of its longest
/// edge). At 1e-9 the triangle is flat at `f32` precision, and its LSCM
/// coefficients (∝ 1/√ratio) would make the normal equations ill-conditioned.
pub const DEGENERATE_RATIO: f64 = 1e-9;

/// Systems with at most this many real unknowns (2 per free vertex) use the
/// dense Cholesky; above, the sparse one. Chosen from `atlas_bench` timings
/// on the 2-core machine: both paths cost the same at 124–158 unknowns
/// (~100–130 triangles, ~0.1 ms).
const DENSE_MAX_UNKNOWNS: usize = 128;

/// True when triangle `(a, b, c)` has (near-)zero area, see [`DEGENERATE_RATIO`].
/// Non-finite corners count as degenerate.
pub fn is_degenerate(a: Vec3, b: Vec3, c: Vec3) -> bool {
    let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
    let twice_area = (b - a).cross(c - a).length();
    let longest = (b - a)
        .length_squared()
        .max((c - b).length_squared())
        .max((a - c).length_squared());
    // NaN fails the comparison and counts as degenerate.
    let healthy = twice_area > DEGENERATE_RATIO * longest;
    !healthy
}

/// Least-squares conformal map (Lévy, Petitjean, Ray, Maillot 2002) of one connected, disc-like triangle mesh.
/// Returns one uv per vertex (world-unit scale is arbitrary; callers apply their own similarity).
///
/// Orientation is preserved: a triangle counter-clockwise around its normal
/// has positive signed area in (u, v). Vertices that no triangle uses get
/// uv (0, 0), the position of the first pinned vertex, so every output is
/// finite. Connectivity is through shared edges (two fans touching at a
/// single vertex are two components: their relative rotation would be
/// undetermined). The mesh need not be manifold, but only a disc gives a
/// fold-free map; closed meshes or meshes with handles return a finite map
/// that overlaps itself.
///
/// Cost is linear in `positions.len()` plus the solve; pass a patch's own
/// vertex array, not the whole surface's.
///
/// # Errors
/// [`ParamError::Empty`], [`ParamError::IndexOutOfRange`],
/// [`ParamError::NonFinitePosition`] (used vertices only),
/// [`ParamError::DegenerateTriangle`] (repeated corner or [`is_degenerate`]),
/// [`ParamError::Disconnected`], [`ParamError::Factorization`].
pub fn lscm(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Vec<Vec2>, ParamError> {
    if triangles.is_empty() {
        return Err(ParamError::Empty);
    }
    let n = positions.len();

    // Compact numbering of the vertices triangles use, in first-use order.
    let mut local = vec![u32::MAX; n];
    let mut used: Vec<u32> = Vec::new();
    let mut local_tris: Vec<[u32; 3]> = Vec::with_capacity(triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        let mut out = [0u32; 3];
        for (k, &v) in tri.iter().enumerate() {
            let Some(p) = positions.get(v as usize) else {
                return Err(ParamError::IndexOutOfRange {
                    triangle: t,
                    index: v,
                    vertex_count: n,
                });
            };
            if local[v as usize] == u32::MAX {
                if !p.is_finite() {
                    return Err(ParamError::NonFinitePosition { vertex: v as usize });
                }
                local[v as usize] = used.len() as u32;
                used.push(v);
            }
            out[k] = local[v as usize];
        }
        let [a, b, c] = *tri;
        if a == b
            || b == c
            || a == c
            || is_degenerate(
                positions[a as usize],
                positions[b as usize],
                positions[c as usize],
            )
        {
            return Err(ParamError::DegenerateTriangle { triangle: t });
        }
        local_tris.push(out);
    }
    check_edge_connected(&local_tris)?;

    let points: Vec<DVec3> = used
        .iter()
        .map(|&v| positions[v as usize].as_dvec3())
        .collect();
    let local_uv = solve(&points, &local_tris)?;

    let mut uv = vec![Vec2::ZERO; n];
    for (l, &v) in used.iter().enumerate() {
        uv[v as usize] = local_uv[l].as_vec2();
    }
    Ok(uv)
}

/// Errors unless every triangle is reachable from triangle 0 through shared
/// edges. Sort-based so it allocates only O(triangles).
fn check_edge_connected(tris: &[[u32; 3]]) -> Result<(), ParamError> {
    let mut edges: Vec<(u32, u32, u32)> = Vec::with_capacity(tris.len() * 3);
    for (t, tri) in tris.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b), t as u32));
        }
    }
    edges.sort_unstable();
    let mut parent: Vec<u32> = (0..tris.len() as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            let p = parent[x as usize];
            parent[x as usize] = parent[p as usize];
            x = p;
        }
        x
    }
    for w in edges.windows(2) {
        if w[0].0 == w[1].0 && w[0].1 == w[1].1 {
            let (ra, rb) = (find(&mut parent, w[0].2), find(&mut parent, w[1].2));
            if ra != rb {
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        }
    }
    let mut components = 0;
    let mut first_outside = None;
    for t in 0..tris.len() as u32 {
        let r = find(&mut parent, t);
        if r == t {
            components += 1;
        }
        if r != 0 && first_outside.is_none() {
            first_outside = Some(t as usize);
        }
    }
    match first_outside {
        None => Ok(()),
        Some(triangle) => Err(ParamError::Disconnected {
            components,
            triangle,
        }),
    }
}

/// The two pinned vertices: extremes along the bounding box's longest axis,
/// lowest index on ties.
fn choose_pins(points: &[DVec3]) -> (usize, usize) {
    let (mut lo, mut hi) = (points[0], points[0]);
    for p in points {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let ext = hi - lo;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let (mut imin, mut imax) = (0, 0);
    for (i, p) in points.iter().enumerate() {
        if p[axis] < points[imin][axis] {
            imin = i;
        }
        if p[axis] > points[imax][axis] {
            imax = i;
        }
    }
    (imin, imax)
}

/// Per-triangle complex coefficients of the corners in the residual
/// `√A_T (r₁ + i r₂) = Σ_j w_j z_j`, z_j = u_j + i v_j: with
/// `∇φ_j = (a_j, b_j)`, `w_j = √A_T (a_j + i b_j)` (the paper's per-triangle
/// coefficients, up to its normalisation of the local frame).
fn corner_weights(p: [DVec3; 3]) -> [c64; 3] {
    let e1 = p[1] - p[0];
    let e2 = p[2] - p[0];
    let l1 = e1.length();
    let x = e1 / l1;
    let y = e1.cross(e2).cross(e1).normalize();
    // Local 2-D corners (counter-clockwise by construction).
    let q = [
        DVec2::ZERO,
        DVec2::new(l1, 0.0),
        DVec2::new(e2.dot(x), e2.dot(y)),
    ];
    let twice_area = l1 * q[2].y;
    let s = (0.5 * twice_area).sqrt() / twice_area;
    std::array::from_fn(|j| {
        // ∇φ_j = rot90(q_{j+2} − q_{j+1}) / 2A.
        let d = q[(j + 2) % 3] - q[(j + 1) % 3];
        c64::new(-d.y * s, d.x * s)
    })
}

/// Solves the pinned LSCM system for validated, connected, non-degenerate
/// local data. Returns one uv per local vertex.
///
/// The normal equations are assembled in complex form, `MᴴM z = −MᴴM_p z_p`
/// (one complex unknown per free vertex): the real 2n×2n system is the same
/// quadratic form, but the complex one has half the rows and a quarter of
/// the index entries, which halves the symbolic work of the factorization.
fn solve(points: &[DVec3], tris: &[[u32; 3]]) -> Result<Vec<DVec2>, ParamError> {
    let nv = points.len();
    let (pin_a, pin_b) = choose_pins(points);
    if pin_a == pin_b {
        // Unreachable after the degeneracy check (all points would coincide).
        return Err(ParamError::DegenerateTriangle { triangle: 0 });
    }
    let pinned = |v: usize| -> c64 {
        if v == pin_a {
            c64::new(0.0, 0.0)
        } else {
            c64::new(points[pin_a].distance(points[pin_b]), 0.0)
        }
    };

    // Unknown index of each local vertex; pins: MAX.
    let mut slot = vec![usize::MAX; nv];
    let mut free = 0;
    for (v, s) in slot.iter_mut().enumerate() {
        if v != pin_a && v != pin_b {
            *s = free;
            free += 1;
        }
    }
    let unknowns = 2 * free;

    let mut rhs = Mat::<c64>::zeros(free, 1);
    // Visits every free-free term (r, c, value) of MᴴM; moves the pinned
    // terms to the right-hand side.
    let assemble = |rhs: &mut Mat<c64>, entry: &mut dyn FnMut(usize, usize, c64)| {
        for tri in tris {
            let w = corner_weights(tri.map(|v| points[v as usize]));
            for i in 0..3 {
                let r = slot[tri[i] as usize];
                if r == usize::MAX {
                    continue;
                }
                let wi = w[i].conj();
                for j in 0..3 {
                    let c = slot[tri[j] as usize];
                    if c == usize::MAX {
                        rhs[(r, 0)] -= wi * w[j] * pinned(tri[j] as usize);
                    } else {
                        entry(r, c, wi * w[j]);
                    }
                }
            }
        }
    };
    let result = if unknowns <= DENSE_MAX_UNKNOWNS {
        let mut h = Mat::<c64>::zeros(free, free);
        assemble(&mut rhs, &mut |r, c, v| h[(r, c)] += v);
        solve_dense(h, &mut rhs)
    } else {
        let mut entries: Vec<Triplet<usize, usize, c64>> = Vec::with_capacity(tris.len() * 6);
        assemble(&mut rhs, &mut |r, c, v| {
            // Lower triangle only; the factorization reads that side.
            if r >= c {
                entries.push(Triplet::new(r, c, v));
            }
        });
        solve_sparse(free, &entries, &mut rhs)
    };
    result.map_err(|reason| ParamError::Factorization { unknowns, reason })?;

    let mut uv = vec![DVec2::ZERO; nv];
    for v in 0..nv {
        let z = if slot[v] == usize::MAX {
            pinned(v)
        } else {
            rhs[(slot[v], 0)]
        };
        uv[v] = DVec2::new(z.re, z.im);
    }
    if let Some(bad) = uv.iter().position(|p| !p.is_finite()) {
        return Err(ParamError::Factorization {
            unknowns,
            reason: format!("non-finite solution at local vertex {bad}"),
        });
    }
    Ok(uv)
}

/// Dense Cholesky solve of `h x = rhs` in place (`h` Hermitian, lower triangle read).
fn solve_dense(mut h: Mat<c64>, rhs: &mut Mat<c64>) -> Result<(), String> {
    let n = h.nrows();
    if n == 0 {
        return Ok(());
    }
    let req = StackReq::any_of(&[
        llt::factor::cholesky_in_place_scratch::<c64>(n, Par::Seq, Default::default()),
        llt::solve::solve_in_place_scratch::<c64>(n, 1, Par::Seq),
    ]);
    let mut buf = MemBuffer::try_new(req).map_err(|e| format!("{e:?}"))?;
    let stack = MemStack::new(&mut buf);
    llt::factor::cholesky_in_place(
        h.as_mut(),
        Default::default(),
        Par::Seq,
        stack,
        Default::default(),
    )
    .map_err(|e| format!("{e:?}"))?;
    llt::solve::solve_in_place_with_conj(h.as_ref(), Conj::No, rhs.as_mut(), Par::Seq, stack);
    Ok(())
}

/// Sparse Cholesky solve of `h x = rhs` in place, `h` given by its lower
/// triangle as triplets (duplicates are summed).
fn solve_sparse(
    n: usize,
    entries: &[Triplet<usize, usize, c64>],
    rhs: &mut Mat<c64>,
) -> Result<(), String> {
    let h = SparseColMat::<usize, c64>::try_new_from_triplets(n, n, entries)
        .map_err(|e| format!("{e:?}"))?;
    let symbolic = factorize_symbolic_cholesky(
        h.symbolic(),
        Side::Lower,
        SymmetricOrdering::Amd,
        Default::default(),
    )
    .map_err(|e| format!("{e:?}"))?;
    let req = StackReq::any_of(&[
        symbolic.factorize_numeric_llt_scratch::<c64>(Par::Seq, Default::default()),
        symbolic.solve_in_place_scratch::<c64>(1, Par::Seq),
    ]);
    let mut buf = MemBuffer::try_new(req).map_err(|e| format!("{e:?}"))?;
    let stack = MemStack::new(&mut buf);
    let mut values = vec![c64::new(0.0, 0.0); symbolic.len_val()];
    let llt = symbolic
        .factorize_numeric_llt(
            &mut values,
            h.as_ref(),
            Side::Lower,
            Default::default(),
            Par::Seq,
            stack,
            Default::default(),
        )
        .map_err(|e| format!("{e}"))?;
    llt.solve_in_place_with_conj(Conj::No, rhs.as_mut(), Par::Seq, stack);
    Ok(())
}

#[cfg(test)]
mod tests {
    use glam::Quat;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;

    /// An `n × n`-vertex grid triangulated counter-clockwise in (i, j).
    fn grid_triangles(n: u32) -> Vec<[u32; 3]> {
        let mut tris = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = j * n + i;
                tris.push([a, a + 1, a + n + 1]);
                tris.push([a, a + n + 1, a + n]);
            }
        }
        tris
    }

    /// Seeded jittered grid in the unit square (2-D) and its triangles.
    fn jittered_patch(n: u32, rng: &mut Pcg64) -> (Vec<Vec2>, Vec<[u32; 3]>) {
        let h = 1.0 / (n - 1) as f32;
        let mut pts = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let jitter = Vec2::new(rng.random_range(-0.3..0.3), rng.random_range(-0.3..0.3));
                pts.push((Vec2::new(i as f32, j as f32) + jitter) * h);
            }
        }
        (pts, grid_triangles(n))
    }

    /// Max distance between `target` and the best similarity image of
    /// `source` (complex least squares, no reflection), relative to the
    /// diameter of `target`.
    fn similarity_error(source: &[DVec2], target: &[DVec2]) -> f64 {
        let n = source.len() as f64;
        let cs = source.iter().sum::<DVec2>() / n;
        let ct = target.iter().sum::<DVec2>() / n;
        // a = Σ conj(z) w / Σ |z|², with z, w centred.
        let (mut num, mut den) = (DVec2::ZERO, 0.0);
        for (s, t) in source.iter().zip(target) {
            let (z, w) = (*s - cs, *t - ct);
            num += DVec2::new(z.x * w.x + z.y * w.y, z.x * w.y - z.y * w.x);
            den += z.length_squared();
        }
        let a = num / den;
        let mut max_err: f64 = 0.0;
        let mut diameter: f64 = 0.0;
        for (s, t) in source.iter().zip(target) {
            let z = *s - cs;
            let mapped = DVec2::new(a.x * z.x - a.y * z.y, a.x * z.y + a.y * z.x) + ct;
            max_err = max_err.max(mapped.distance(*t));
            diameter = diameter.max((*t - ct).length() * 2.0);
        }
        max_err / diameter
    }

    fn as_d(v: &[Vec2]) -> Vec<DVec2> {
        v.iter().map(|p| p.as_dvec2()).collect()
    }

    fn signed_area(uv: &[Vec2], t: [u32; 3]) -> f32 {
        let [a, b, c] = t.map(|i| uv[i as usize]);
        0.5 * (b - a).perp_dot(c - a)
    }

    #[test]
    fn planar_patch_is_reproduced_up_to_a_similarity() {
        for seed in 0..8u64 {
            let mut rng = Pcg64::seed_from_u64(seed);
            // 6x6 .. 34x34 vertices: both the dense and the sparse path.
            let n = 6 + 4 * seed as u32;
            let (flat, tris) = jittered_patch(n, &mut rng);
            let axis = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            let rot = Quat::from_axis_angle(axis, rng.random_range(0.0..std::f32::consts::TAU));
            let scale = rng.random_range(0.1..10.0);
            let shift = Vec3::new(3.0, -2.0, 5.0);
            let pos: Vec<Vec3> = flat
                .iter()
                .map(|p| rot * (p.extend(0.0) * scale) + shift)
                .collect();
            let uv = lscm(&pos, &tris).expect("valid patch");
            let err = similarity_error(&as_d(&flat), &as_d(&uv));
            assert!(err < 1e-4, "seed {seed} ({n}x{n}): relative error {err}");
        }
    }

    #[test]
    fn similarity_check_rejects_a_non_conformal_map() {
        // Control for the test above: a 2:1 stretch is not a similarity.
        let mut rng = Pcg64::seed_from_u64(7);
        let (flat, _) = jittered_patch(8, &mut rng);
        let stretched: Vec<Vec2> = flat.iter().map(|p| Vec2::new(2.0 * p.x, p.y)).collect();
        assert!(similarity_error(&as_d(&flat), &as_d(&stretched)) > 0.05);
    }

    #[test]
    fn developable_prism_unrolls_exactly() {
        // A cylinder sampled on a (θ, z) grid is a prism of planar
        // rectangles: developable, so its conformal map is its unrolling.
        let (nt, nz, r) = (13u32, 9u32, 2.0f32);
        let dtheta = 2.0f32.to_radians() * 10.0;
        let chord = 2.0 * r * (0.5 * dtheta).sin();
        let mut pos = Vec::new();
        let mut unrolled = Vec::new();
        for j in 0..nz {
            for i in 0..nt {
                let th = i as f32 * dtheta;
                let z = j as f32 * 0.4;
                pos.push(Vec3::new(r * th.cos(), r * th.sin(), z));
                unrolled.push(DVec2::new((i as f32 * chord) as f64, z as f64));
            }
        }
        let mut tris = Vec::new();
        for j in 0..nz - 1 {
            for i in 0..nt - 1 {
                let a = j * nt + i;
                // Counter-clockwise seen from outside (normal away from the axis).
                tris.push([a, a + 1, a + nt + 1]);
                tris.push([a, a + nt + 1, a + nt]);
            }
        }
        let uv = lscm(&pos, &tris).expect("valid strip");
        let err = similarity_error(&unrolled, &as_d(&uv));
        assert!(err < 1e-5, "relative error {err}");
    }

    /// Mean absolute difference between the 3-D and 2-D corner angles.
    fn mean_angle_error(pos: &[Vec3], uv: &[Vec2], tris: &[[u32; 3]]) -> f32 {
        let mut sum = 0.0;
        for t in tris {
            for k in 0..3 {
                let (a, b, c) = (
                    t[k] as usize,
                    t[(k + 1) % 3] as usize,
                    t[(k + 2) % 3] as usize,
                );
                let a3 = (pos[b] - pos[a]).angle_between(pos[c] - pos[a]);
                let a2 = (uv[b] - uv[a]).angle_to(uv[c] - uv[a]).abs();
                sum += (a3 - a2).abs();
            }
        }
        sum / (3 * tris.len()) as f32
    }

    #[test]
    fn sphere_cap_keeps_angles_better_than_projection() {
        // Cap of half-angle 70° on the unit sphere around +z, from a polar grid.
        let (rings, sectors) = (10u32, 24u32);
        let mut pos = vec![Vec3::Z];
        for r in 1..=rings {
            let phi = 70f32.to_radians() * r as f32 / rings as f32;
            for s in 0..sectors {
                let th = std::f32::consts::TAU * s as f32 / sectors as f32;
                pos.push(Vec3::new(
                    phi.sin() * th.cos(),
                    phi.sin() * th.sin(),
                    phi.cos(),
                ));
            }
        }
        let ring = |r: u32, s: u32| 1 + (r - 1) * sectors + s % sectors;
        let mut tris = Vec::new();
        for s in 0..sectors {
            tris.push([0, ring(1, s), ring(1, s + 1)]);
        }
        for r in 1..rings {
            for s in 0..sectors {
                let (a, b, c, d) = (
                    ring(r, s),
                    ring(r, s + 1),
                    ring(r + 1, s),
                    ring(r + 1, s + 1),
                );
                tris.push([a, c, d]);
                tris.push([a, d, b]);
            }
        }
        let uv = lscm(&pos, &tris).expect("valid cap");
        let projected: Vec<Vec2> = pos.iter().map(|p| Vec2::new(p.x, p.y)).collect();
        let (e_lscm, e_proj) = (
            mean_angle_error(&pos, &uv, &tris),
            mean_angle_error(&pos, &projected, &tris),
        );
        assert!(
            e_lscm < 0.5 * e_proj,
            "lscm {e_lscm} vs projection {e_proj}"
        );
        for (i, t) in tris.iter().enumerate() {
            assert!(signed_area(&uv, *t) > 0.0, "triangle {i} flipped");
        }
    }

    #[test]
    fn single_triangle_is_similar_and_keeps_orientation() {
        let pos = vec![
            Vec3::new(0.3, 1.0, -2.0),
            Vec3::new(2.0, 1.5, 0.0),
            Vec3::new(-0.5, 3.0, 1.0),
        ];
        let uv = lscm(&pos, &[[0, 1, 2]]).expect("one triangle");
        assert!(signed_area(&uv, [0, 1, 2]) > 0.0);
        let d3 = [
            pos[0].distance(pos[1]),
            pos[1].distance(pos[2]),
            pos[2].distance(pos[0]),
        ];
        let d2 = [
            uv[0].distance(uv[1]),
            uv[1].distance(uv[2]),
            uv[2].distance(uv[0]),
        ];
        for k in 0..3 {
            assert!(
                (d2[k] / d3[k] - d2[0] / d3[0]).abs() < 1e-5,
                "{d2:?} vs {d3:?}"
            );
        }
    }

    #[test]
    fn unused_vertices_get_the_origin() {
        let pos = vec![
            Vec3::new(9.0, 9.0, 9.0),
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(f32::NAN, 0.0, 0.0), // unused: its NaN is never read
        ];
        let uv = lscm(&pos, &[[1, 2, 3]]).expect("valid");
        assert_eq!(uv[0], Vec2::ZERO);
        assert_eq!(uv[4], Vec2::ZERO);
        assert!(uv.iter().all(|p| p.is_finite()));
    }

    #[test]
    fn bad_input_gives_named_errors() {
        let pos = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(5.0, 0.0, 0.0),
        ];
        assert_eq!(lscm(&pos, &[]), Err(ParamError::Empty));
        assert_eq!(
            lscm(&pos, &[[0, 1, 2], [1, 3, 9]]),
            Err(ParamError::IndexOutOfRange {
                triangle: 1,
                index: 9,
                vertex_count: 5
            })
        );
        assert_eq!(
            lscm(&pos, &[[0, 1, 2], [0, 1, 4]]),
            Err(ParamError::DegenerateTriangle { triangle: 1 })
        );
        assert_eq!(
            lscm(&pos, &[[0, 1, 2], [2, 2, 3]]),
            Err(ParamError::DegenerateTriangle { triangle: 1 })
        );
        // Two fans touching at vertex 1 only: not edge-connected.
        let bowtie = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(2.0, -1.0, 0.0),
        ];
        assert_eq!(
            lscm(&bowtie, &[[0, 1, 2], [1, 3, 4]]),
            Err(ParamError::Disconnected {
                components: 2,
                triangle: 1
            })
        );
        let mut nan = pos.clone();
        nan[3].z = f32::NAN;
        assert_eq!(
            lscm(&nan, &[[0, 1, 2], [1, 3, 2]]),
            Err(ParamError::NonFinitePosition { vertex: 3 })
        );
        // Known-good control on the same vertices.
        assert!(lscm(&pos, &[[0, 1, 2], [1, 3, 2]]).is_ok());
    }
}
