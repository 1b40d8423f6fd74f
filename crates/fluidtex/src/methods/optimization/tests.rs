//! Tests of the optimisation method: each names the property it checks
//! and can fail (controls included where a property could hold by accident).

use std::sync::Arc;

use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};

use super::histogram::Quantiles;
use super::lattice::Lattice;
use super::neighbourhood::Window;
use super::search::{SearchIndex, WorkingExemplar, candidate_vector, ssd};
use super::solve::{LevelInput, SolveTimes, optimise};
use super::transport::{self, Previous};
use super::*;
use crate::atlas::{Atlas, AtlasParams};
use crate::exemplar::pebbles::builtin_pebbles;
use crate::mesh::TriMesh;
use crate::methods::{FrameContext, PreviousFrame};
use crate::surface::SurfaceIndex;

/// Gauss-Newton steps of the sub-texel registration under test (the
/// method itself runs `super::solve::REFINE_STEPS`, which is 0).
const TESTED_REFINE_STEPS: u32 = 2;

/// A flat square \[-half, half]² in z = 0, n × n quads, velocity `f`.
pub(super) fn plane(n: usize, half: f32, f: impl Fn(Vec3) -> Vec3) -> TriMesh {
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            positions.push(Vec3::new(
                (i as f32 / n as f32 * 2.0 - 1.0) * half,
                (j as f32 / n as f32 * 2.0 - 1.0) * half,
                0.0,
            ));
        }
    }
    let w = (n + 1) as u32;
    let mut triangles = Vec::new();
    for j in 0..n as u32 {
        for i in 0..n as u32 {
            let a = j * w + i;
            triangles.push([a, a + 1, a + w + 1]);
            triangles.push([a, a + w + 1, a + w]);
        }
    }
    let v = positions.iter().map(|&p| f(p)).collect();
    TriMesh::new(positions, triangles).with_velocity(v)
}

fn flow<'a>(
    from: (&'a TriMesh, &'a SurfaceIndex),
    to: (&'a TriMesh, &'a SurfaceIndex),
    dt: f32,
) -> FlowInterval<'a> {
    FlowInterval {
        from: FlowFrame {
            mesh: from.0,
            index: from.1,
            velocity: from.0.velocity().unwrap_or(&[]),
        },
        to: Some(FlowFrame {
            mesh: to.0,
            index: to.1,
            velocity: to.0.velocity().unwrap_or(&[]),
        }),
        dt,
        substeps: 1,
        search_hint: 0.5,
    }
}

#[test]
fn lattice_is_shared_along_edges_and_locates_exactly() {
    let mesh = plane(3, 1.0, |_| Vec3::ZERO);
    let lattice = Lattice::new(&mesh, 4);
    // V + E(m−1) + T(m−1)(m−2)/2 points: 16 + 33·3 + 18·3.
    assert_eq!(lattice.len(), 16 + 33 * 3 + 18 * 3);
    // Every lattice point's position matches its barycentric definition,
    // whichever triangle names it (shared edges give one id).
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.corners(t);
        for i in 0..=4u32 {
            for j in 0..=(4 - i) {
                let p =
                    a * ((4 - i - j) as f32 / 4.0) + b * (i as f32 / 4.0) + c * (j as f32 / 4.0);
                let id = lattice.id(t, i, j) as usize;
                assert!(
                    (lattice.positions[id] - p).length() < 1e-6,
                    "t{t} ({i},{j})"
                );
            }
        }
    }
    // A linear function is reproduced exactly by locate + interpolate.
    let f = |p: Vec3| 0.3 * p.x - 0.7 * p.y + 2.0;
    let values: Vec<f32> = lattice.positions.iter().map(|&p| f(p)).collect();
    let mut out = [0.0f32];
    for (t, bary) in [
        (0usize, [0.2f32, 0.5, 0.3]),
        (7, [0.9, 0.05, 0.05]),
        (17, [0.0, 0.5, 0.5]),
    ] {
        lattice.interpolate(&values, 1, t, bary, &mut out);
        let [a, b, c] = mesh.corners(t);
        let p = a * bary[0] + b * bary[1] + c * bary[2];
        assert!((out[0] - f(p)).abs() < 1e-5);
    }
    // Levels nest: stride 2 holds every second point, and its triangles
    // cover the same area.
    let coarse = lattice.level(2);
    let fine = lattice.level(1);
    assert_eq!(fine.len(), lattice.len());
    // Corners and one midpoint per fluid edge; no interior points at m = 2.
    assert_eq!(coarse.len(), 16 + 33);
    let area = |l: &super::lattice::Level| -> f32 {
        l.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| l.positions[v as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    };
    assert!((area(&coarse) - 4.0).abs() < 1e-4 && (area(&fine) - 4.0).abs() < 1e-4);
}

#[test]
fn orientation_transport_rotates_with_a_rigid_rotation() {
    // Rigid rotation about z, ω = 1 rad/s, dt = 0.3: every orientation must
    // turn by 0.3 rad, not just be translated (scalar advection of the
    // components would leave it at 0 rad).
    let omega = 1.0f32;
    let dt = 0.3f32;
    // The square is four times the checked disc, so back-tracked points and
    // the smoothing of their neighbours stay away from its border (where the
    // velocity read at the closest point is no longer the rotation).
    let mesh = plane(32, 4.0, |p| Vec3::new(-omega * p.y, omega * p.x, 0.0));
    let index = SurfaceIndex::new(&mesh);
    let prev_lattice = Lattice::new(&mesh, 2);
    let prev_orientation = vec![Vec3::X; prev_lattice.len()];
    let values = vec![0.0f32; prev_lattice.len()];
    let previous = Previous {
        mesh: &mesh,
        index: &index,
        lattice: &prev_lattice,
        values: &values,
        channels: 1,
        orientation: &prev_orientation,
    };
    let back = flow((&mesh, &index), (&mesh, &index), -dt);
    let forward = flow((&mesh, &index), (&mesh, &index), dt);
    let lattice = Lattice::new(&mesh, 4);
    let levels: Vec<_> = (0..3).map(|l| lattice.level(1 << l)).collect();
    let coarsest = &levels[2];
    let coarse = transport::orientations(
        &coarsest.positions,
        &coarsest.normals,
        &back,
        &forward,
        &previous,
        0.01,
    );
    let want = Vec3::new(dt.cos(), dt.sin(), 0.0);
    let angle = |d: Vec3| d.angle_between(want);
    let inside = |p: Vec3| p.length() < 1.0;
    let mut checked = 0;
    for (d, p) in coarse.iter().zip(&coarsest.positions) {
        if inside(*p) {
            assert!(angle(*d) < 1e-3, "transported {d} vs {want} at {p}");
            checked += 1;
        }
    }
    assert!(checked > 20, "{checked}");
    // Re-smoothing (with the propagation up the hierarchy) keeps it.
    let fine = orientation::smooth_hierarchy(
        &lattice,
        &levels,
        Some(coarse),
        10,
        orientation::Smoothing::Projected,
    );
    assert_eq!(fine.len(), lattice.len());
    for (d, p) in fine.iter().zip(&lattice.positions) {
        if inside(*p) {
            assert!(angle(*d) < 1e-3, "smoothed {d} vs {want} at {p}");
        }
    }
    // Control: a field that was not rotated is ≈ 0.3 rad off.
    assert!((Vec3::X.angle_between(want) - dt).abs() < 1e-5);
}

#[test]
fn colour_transport_moves_the_texture_by_the_translation() {
    // Translation by exactly one lattice step along x in one frame: every
    // new point whose source lies inside the square takes the (random)
    // value of the point one step to its left.
    let n = 8;
    let m = 2;
    let step = 2.0 / (n * m) as f32;
    let dt = 0.25;
    let u = Vec3::new(step / dt, 0.0, 0.0);
    let mesh = plane(n, 1.0, |_| u);
    let index = SurfaceIndex::new(&mesh);
    let lattice = Lattice::new(&mesh, m as u32);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let values: Vec<f32> = (0..lattice.len()).map(|_| rng.random::<f32>()).collect();
    let orientation = vec![Vec3::X; lattice.len()];
    let previous = Previous {
        mesh: &mesh,
        index: &index,
        lattice: &lattice,
        values: &values,
        channels: 1,
        orientation: &orientation,
    };
    let back = flow((&mesh, &index), (&mesh, &index), -dt);
    let (moved, missing) = transport::colours(&lattice.positions, &back, &previous);
    assert_eq!(missing, 0);
    assert_moved_one_step_left(&lattice, &values, &moved, step);
}

/// Every point whose source, one lattice `step` to its left, lies inside
/// the square holds the source's value in `moved`; and the texture did
/// move (most points changed value), the control.
pub(super) fn assert_moved_one_step_left(
    lattice: &Lattice,
    values: &[f32],
    moved: &[f32],
    step: f32,
) {
    let by_position = |p: Vec3| {
        lattice
            .positions
            .iter()
            .position(|q| (*q - p).length() < 1e-4)
    };
    let (mut checked, mut changed) = (0, 0);
    for (i, &p) in lattice.positions.iter().enumerate() {
        let src = p - Vec3::new(step, 0.0, 0.0);
        if src.x < -1.0 + 1e-4 {
            continue;
        }
        let Some(j) = by_position(src) else { continue };
        assert!((moved[i] - values[j]).abs() < 1e-4, "point {i} at {p}");
        checked += 1;
        changed += usize::from((values[i] - values[j]).abs() > 1e-3);
    }
    assert!(checked > 200, "{checked}");
    assert!(changed > checked * 9 / 10);
}

fn pebbles(size: u32) -> Arc<Exemplar> {
    Arc::new(builtin_pebbles(size, 3))
}

#[test]
fn accelerated_search_matches_brute_force() {
    let exemplar = pebbles(64);
    let ex = WorkingExemplar::new(&exemplar, 48);
    let window = Window {
        width: 9,
        grid: 9,
        texel: 1.0,
        relaxation: 0,
    };
    let index = SearchIndex::new(&ex, window, 16);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let mut q = vec![0.0f32; index.dims];
    let mut buf = vec![0.0f32; index.dims];
    let mut worst = 1.0f32;
    for trial in 0..60 {
        let i = rng.random_range(0..ex.candidates() as u32);
        candidate_vector(&ex, window, i, &mut q);
        let noise = if trial < 20 { 0.0 } else { 0.05 };
        for x in &mut q {
            *x += noise * (rng.random::<f32>() - 0.5);
        }
        // Exact in the reduced space: the k-d tree's nearest is the scan's.
        let (_, d_tree) = index.nearest_reduced(&q).expect("tree");
        let (_, d_scan) = index.brute_force_reduced(&q);
        assert!(
            (d_tree - d_scan).abs() <= 1e-6 * d_scan.max(1.0),
            "{d_tree} vs {d_scan}"
        );
        // With re-ranking, within ε of the full-space optimum; exact for
        // exemplar neighbourhoods themselves.
        let (found, d_found) = index.nearest(&ex, &q, &mut buf);
        let (_, d_best) = index.brute_force(&ex, &q);
        if noise == 0.0 {
            assert_eq!(d_found, 0.0, "trial {trial}: candidate {found}");
        } else {
            worst = worst.max(d_found / d_best.max(1e-12));
        }
    }
    // ε = 5 %: measured 1.000 (every noisy query found the optimum).
    assert!(worst <= 1.05, "re-ranked / brute-force distance {worst}");
}

#[test]
fn exact_search_finds_the_full_window_optimum() {
    // The paper's search: the whole 17 × 17 window against every candidate.
    // Its answer is the brute-force optimum over that window, and never
    // worse than the PCA search over a 5 × 5 subsample of the same window,
    // judged on the whole window; the subsample search, the control, misses
    // the optimum on some queries.
    let exemplar = pebbles(64);
    let ex = WorkingExemplar::new(&exemplar, 40);
    let full = Window {
        width: 17,
        grid: 17,
        texel: 1.0,
        relaxation: 0,
    };
    let sub = Window { grid: 5, ..full };
    let exact = SearchIndex::exact(&ex, full);
    let pca = SearchIndex::new(&ex, sub, 4);
    assert_eq!(exact.dims, 17 * 17 * 3);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(12);
    let (mut q, mut buf) = (vec![0.0f32; exact.dims], vec![0.0f32; exact.dims]);
    let (mut q_sub, mut buf_sub) = (vec![0.0f32; pca.dims], vec![0.0f32; pca.dims]);
    let mut missed = 0;
    for trial in 0..40 {
        let i = rng.random_range(0..ex.candidates() as u32);
        candidate_vector(&ex, full, i, &mut q);
        for x in &mut q {
            *x += 0.3 * (rng.random::<f32>() - 0.5);
        }
        let (found, d) = exact.nearest(&ex, &q, &mut buf);
        assert_eq!((found, d), exact.brute_force(&ex, &q), "trial {trial}");
        // The same query as the 5 × 5 subsample (stride 4) sees it.
        for b in 0..5 {
            for a in 0..5 {
                let (cell, at) = (b * 5 + a, (b * 4) * 17 + a * 4);
                q_sub[cell * 3..cell * 3 + 3].copy_from_slice(&q[at * 3..at * 3 + 3]);
            }
        }
        let (found_sub, _) = pca.nearest(&ex, &q_sub, &mut buf_sub);
        candidate_vector(&ex, full, found_sub, &mut buf);
        let d_sub = ssd(&q, &buf);
        assert!(d <= d_sub, "trial {trial}: exact {d} > subsample {d_sub}");
        missed += usize::from(d < d_sub);
    }
    assert!(missed > 0, "the subsample search found every optimum");
}

/// A flat square level with a uniform orientation, its working exemplar
/// and passes, for synthesis tests.
/// `texel_factor` scales the world size of an exemplar texel against the
/// point spacing (1: members land on whole texels); `refine`: Gauss–Newton
/// steps of the sub-texel registration.
fn flat_synthesis(
    exemplar_texels: u32,
    sizes: &[u32],
    seed: u64,
    texel_factor: f32,
    refine: u32,
    histogram: Histogram,
) -> (Vec<f32>, Vec<super::solve::PassReport>, WorkingExemplar) {
    let stop = (4, 0.0);
    flat_synthesis_until(
        exemplar_texels,
        sizes,
        seed,
        texel_factor,
        refine,
        histogram,
        stop,
    )
}

/// [`flat_synthesis`] with `(iterations, convergence)` of the passes.
fn flat_synthesis_until(
    exemplar_texels: u32,
    sizes: &[u32],
    seed: u64,
    texel_factor: f32,
    refine: u32,
    histogram: Histogram,
    (iterations, convergence): (u32, f32),
) -> (Vec<f32>, Vec<super::solve::PassReport>, WorkingExemplar) {
    let exemplar = pebbles(128);
    let mesh = plane(24, 1.0, |_| Vec3::ZERO);
    let lattice = Lattice::new(&mesh, 4);
    let level = lattice.level(1);
    let texel = 2.0 / (24.0 * 4.0) * texel_factor;
    let ex = WorkingExemplar::new(&exemplar, exemplar_texels);
    let passes: Vec<SearchIndex> = sizes
        .iter()
        .map(|&w| {
            SearchIndex::new(
                &ex,
                Window {
                    width: w,
                    grid: 9.min(w),
                    texel,
                    relaxation: 0,
                },
                16,
            )
        })
        .collect();
    let orientation = vec![Vec3::X; level.len()];
    let quantiles = Quantiles::new(&ex);
    let k = ex.channels;
    let mut s = vec![0.0f32; level.len() * k];
    for (v, o) in s.chunks_mut(k).enumerate() {
        let pick = mix(seed, 0, v as u64) % ex.candidates() as u64;
        let (x, y) = ex.position(pick as u32);
        o.copy_from_slice(ex.texel(x, y));
    }
    let input = LevelInput {
        level: &level,
        orientation: &orientation,
        exemplar: &ex,
        passes: &passes,
        transported: None,
        coherence: 1.0,
        spacing: 0.25,
        iterations,
        convergence,
        robust: 0.8,
        refine,
        histogram: (histogram == Histogram::Matched).then_some(&quantiles),
    };
    let mut times = SolveTimes::default();
    let reports = optimise(&input, &mut s, &mut times);
    (s, reports, ex)
}

#[test]
fn a_pass_stops_at_the_first_iteration_that_barely_lowers_the_energy() {
    // The same synthesis with and without a tolerance runs the same
    // iterations until the tolerance stops the first pass: at the first
    // iteration whose energy is less than 2 % below the one before (or
    // where the untolerant run stopped). Every pass that goes on lowered
    // the energy by at least 2 % at each earlier step.
    let run = |convergence| {
        flat_synthesis_until(48, &[17, 9], 5, 1.0, 0, Histogram::Paper, (30, convergence)).1
    };
    let (free, tolerant) = (run(0.0), run(0.02));
    let after: Vec<f64> = free[0].energies.iter().map(|e| e.1).collect();
    let stop = (1..after.len())
        .find(|&i| after[i - 1] - after[i] < 0.02 * after[i - 1])
        .map_or(after.len(), |i| i + 1);
    assert_eq!(tolerant[0].energies[..], free[0].energies[..stop]);
    // The control: the tolerance stopped the first pass early.
    assert!(stop < after.len(), "no early stop: {:?}", free[0].energies);
    for t in &tolerant {
        let e: Vec<f64> = t.energies.iter().map(|e| e.1).collect();
        for w in e.windows(2).take(e.len().saturating_sub(2)) {
            assert!(w[0] - w[1] >= 0.02 * w[0], "pass {}: {e:?}", t.width);
        }
    }
}

#[test]
fn averaging_never_increases_energy_and_each_pass_ends_lower() {
    // Integer matches, and matches registered to sub-texel offsets on
    // points that do not fall on exemplar texels: z is fixed during the
    // averaging either way.
    for (factor, refine) in [(1.0, 0), (0.77, TESTED_REFINE_STEPS)] {
        check_energy_decrease(factor, refine);
    }
}

fn check_energy_decrease(texel_factor: f32, refine: u32) {
    for histogram in [Histogram::Paper, Histogram::Matched] {
        check_pass_energies(texel_factor, refine, histogram);
    }
}

fn check_pass_energies(texel_factor: f32, refine: u32, histogram: Histogram) {
    let (_, reports, _) = flat_synthesis(48, &[17, 9], 5, texel_factor, refine, histogram);
    assert_eq!(reports.len(), 2);
    for r in &reports {
        assert!(r.iterations >= 1);
        for &(before, after) in &r.energies {
            assert!(
                after <= before * (1.0 + 1e-9),
                "w{}: {before} -> {after}",
                r.width
            );
        }
        assert!(
            r.end() < r.start(),
            "w{}: {} -> {}",
            r.width,
            r.start(),
            r.end()
        );
    }
    // Control: the first averaging from random texels removes most energy.
    assert!(reports[0].energies[0].1 < 0.7 * reports[0].energies[0].0);
}

#[test]
fn histogram_matching_keeps_the_search_on_textured_neighbourhoods() {
    // Members off the exemplar's texels (texel = 0.77 spacing), so
    // overlapping predictions disagree by fractions of a texel and their
    // average is softer than the exemplar.
    let contrast = |histogram| {
        let (s, reports, ex) = flat_synthesis(48, &[17, 9], 5, 0.77, 0, histogram);
        let k = ex.channels;
        let sigma = |v: &[f32]| luminance_sigma(v, k, ex.colour);
        let last = reports.last().expect("a pass").prediction_contrast;
        (sigma(&s) / sigma(&ex.data), last)
    };
    let (paper_s, paper_z) = contrast(Histogram::Paper);
    let (matched_s, matched_z) = contrast(Histogram::Matched);
    eprintln!("paper: s {paper_s:.3} z {paper_z:.3}; matched: s {matched_s:.3} z {matched_z:.3}");
    // Control: the paper's average drifts to soft matches.
    assert!(paper_z < 0.8 && paper_s < 0.8, "{paper_s} {paper_z}");
    // Matched: the values have the exemplar's spread, and so do the
    // exemplar neighbourhoods the search picks for them.
    assert!((matched_s - 1.0).abs() < 0.02, "{matched_s}");
    // (0.84 against the paper's 0.53 here; 0.95–0.97 on the vortex scene.)
    assert!(matched_z >= 0.8 && matched_z > paper_z + 0.2, "{matched_z}");
}

/// A 9 × 9 vertex neighbourhood turned by 0.4 rad with members 1.3 texels
/// apart: real-valued texel coordinates, as members have on a surface.
fn turned_members() -> Vec<(u32, Vec2)> {
    let (c, s) = (0.4f32.cos(), 0.4f32.sin());
    let mut out = Vec::new();
    for j in -4..=4 {
        for i in -4..=4 {
            let p = Vec2::new(i as f32, j as f32) * 1.3;
            out.push((
                out.len() as u32,
                Vec2::new(c * p.x - s * p.y, s * p.x + c * p.y),
            ));
        }
    }
    out
}

/// s at the members: the exemplar read at `origin` + `delta` + x.
fn read_at(ex: &WorkingExemplar, origin: Vec2, delta: Vec2, members: &[(u32, Vec2)]) -> Vec<f32> {
    let k = ex.channels;
    let mut s = vec![0.0f32; members.len() * k];
    for &(v, x) in members {
        let p = origin + delta + x;
        ex.bilinear(p.x, p.y, &mut s[v as usize * k..v as usize * k + k]);
    }
    s
}

/// ‖s − z(shift)‖² over the colour channels, z read at `origin` + `shift`.
fn match_ssd(
    ex: &WorkingExemplar,
    origin: Vec2,
    shift: Vec2,
    members: &[(u32, Vec2)],
    s: &[f32],
) -> f64 {
    let (k, kc) = (ex.channels, ex.colour);
    let mut z = vec![0.0f32; k];
    let mut e = 0.0f64;
    for &(v, x) in members {
        let p = origin + shift + x;
        ex.bilinear(p.x, p.y, &mut z);
        for ch in 0..kc {
            let d = (s[v as usize * k + ch] - z[ch]) as f64;
            e += d * d;
        }
    }
    e
}

/// A random whole-texel position in [0, n)².
fn whole_texel(rng: &mut impl Rng, n: i32) -> Vec2 {
    Vec2::new(rng.random_range(0..n) as f32, rng.random_range(0..n) as f32)
}

#[test]
fn refinement_recovers_a_sub_texel_translation() {
    let ex = WorkingExemplar::new(&pebbles(128), 48);
    let members = turned_members();
    let steps = TESTED_REFINE_STEPS;
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let mut worst = 0.0f32;
    for _ in 0..40 {
        let origin = whole_texel(&mut rng, 48);
        let delta = Vec2::new(rng.random_range(-0.45..0.45), rng.random_range(-0.45..0.45));
        let s = read_at(&ex, origin, delta, &members);
        let shift =
            super::solve::refine_shift(&ex, origin, &members, &s, ex.channels, ex.colour, steps);
        worst = worst.max((shift - delta).abs().max_element());
    }
    eprintln!("worst sub-texel error {worst:.4} texel ({steps} steps)");
    assert!(worst <= TOL_SHIFT, "worst error {worst} texel");
    // Control: no steps, no shift (the integer match the search returns).
    let s = read_at(&ex, Vec2::new(7.0, 9.0), Vec2::new(0.3, -0.2), &members);
    let none = super::solve::refine_shift(
        &ex,
        Vec2::new(7.0, 9.0),
        &members,
        &s,
        ex.channels,
        ex.colour,
        0,
    );
    assert_eq!(none, Vec2::ZERO);
}

/// Tolerance of the recovered sub-texel offset, in texels (measured: 0.004
/// with 2 steps over 40 offsets up to 0.45 texel).
const TOL_SHIFT: f32 = 0.05;

#[test]
fn refinement_never_increases_a_match_ssd() {
    let ex = WorkingExemplar::new(&pebbles(128), 48);
    let (k, kc) = (ex.channels, ex.colour);
    let members = turned_members();
    let mut rng = rand::rngs::StdRng::seed_from_u64(12);
    let mut lowered = 0;
    for trial in 0..60 {
        let origin = whole_texel(&mut rng, 48);
        // Targets the exemplar does not contain exactly: a shifted read
        // plus noise, or (every third trial) another place entirely.
        let mut s = if trial % 3 == 0 {
            let other = Vec2::new(
                rng.random_range(0..48) as f32,
                rng.random_range(0..48) as f32,
            );
            read_at(&ex, other, Vec2::ZERO, &members)
        } else {
            let delta = Vec2::new(rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5));
            read_at(&ex, origin, delta, &members)
        };
        for x in &mut s {
            *x += rng.random_range(-0.1..0.1);
        }
        let shift = super::solve::refine_shift(&ex, origin, &members, &s, k, kc, 4);
        assert!(shift.abs().max_element() <= 0.5, "{shift}");
        let before = match_ssd(&ex, origin, Vec2::ZERO, &members, &s);
        let after = match_ssd(&ex, origin, shift, &members, &s);
        assert!(
            after <= before * (1.0 + 1e-9),
            "trial {trial}: {before} -> {after}"
        );
        lowered += usize::from(after < 0.9 * before);
    }
    // Control: on the shifted targets refinement does lower the SSD.
    assert!(lowered >= 20, "lowered {lowered} of 60");
}

#[test]
fn flat_synthesis_keeps_the_exemplar_contrast() {
    // A flat square, identity orientation (the reference field of a plane
    // is world X everywhere), first frame: 3 levels from random texels.
    let mesh = plane(24, 1.0, |_| Vec3::ZERO);
    let index = SurfaceIndex::new(&mesh);
    let atlas = Atlas::build(&mesh, &AtlasParams::square(256)).expect("atlas");
    let params = OptimizationParams {
        // h = √(2A/(√3 N)) = 2/96: the point spacing of the m = 4 lattice,
        // so neighbourhood offsets land on exemplar texels.
        points: 10641,
        exemplar_texels: 48,
        // The paper's average, with the iterations it needs: the matched
        // histogram (the default) would hold the spread by construction
        // (its own test is
        // histogram_matching_keeps_the_search_on_textured_neighbourhoods).
        histogram: Histogram::Paper,
        iterations: 5,
        convergence: 0.0,
        ..Default::default()
    };
    let mut m = Optimization::new(params, pebbles(128), 4).expect("params");
    let ctx = FrameContext {
        number: 0,
        dt: 1.0 / 24.0,
        mesh: &mesh,
        index: &index,
        topology: &crate::mesh::Topology::new(mesh.vertex_count(), &mesh.triangles),
        normals: &mesh.vertex_normals(),
        previous: None,
        atlas: &atlas,
        arena: &crate::methods::arena::FRESH,
    };
    m.step(&ctx).expect("step");
    for d in &m.state().orientation {
        assert!((Vec3::from(*d) - Vec3::X).length() < 1e-5);
    }
    let ex = WorkingExemplar::new(&pebbles(128), 48);
    let k = ex.channels;
    let lum = |v: &[f32]| -> Vec<f32> {
        let t = crate::texture::Texture {
            width: (v.len() / k) as u32,
            height: 1,
            channels: k,
            data: v.to_vec(),
        };
        crate::metrics::luminance(&t)
    };
    let sd = |x: &[f32]| {
        let m = x.iter().map(|&v| v as f64).sum::<f64>() / x.len() as f64;
        (x.iter().map(|&v| (v as f64 - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
    };
    let s = &m.state().values;
    let rho = sd(&lum(s)) / sd(&lum(&ex.data));
    eprintln!("flat-square contrast ratio {rho:.3}");
    assert!(rho >= 0.85, "contrast ratio {rho}");
    // Control: neighbour averaging (a blur) of the same points loses it.
    let level = Lattice::new(&mesh, m.state().m).level(1);
    let mut b = s.clone();
    for _ in 0..6 {
        b = level.smooth(&b, k);
    }
    assert!(sd(&lum(&b)) / sd(&lum(&ex.data)) < 0.85);
}

fn small_params() -> OptimizationParams {
    OptimizationParams {
        points: 6000,
        exemplar_texels: 48,
        sizes: vec![17, 9],
        levels: 2,
        iterations: 2,
        convergence: 0.0,
        ..Default::default()
    }
}

/// Frames of a slowly rotating plane: (mesh, index, atlas).
fn frames(count: usize) -> Vec<(TriMesh, SurfaceIndex, Atlas)> {
    (0..count)
        .map(|f| {
            let a = 0.1 * f as f32;
            let mut mesh = plane(12, 1.0, |p| Vec3::new(-p.y, p.x, 0.0) * 0.5);
            // Jitter the interior vertices per frame so meshes differ.
            for (i, p) in mesh.positions.iter_mut().enumerate() {
                if p.x.abs() < 0.99 && p.y.abs() < 0.99 {
                    p.x += 0.01 * ((i as f32 * 1.7 + a).sin());
                }
            }
            let index = SurfaceIndex::new(&mesh);
            let atlas = Atlas::build(&mesh, &AtlasParams::square(96)).expect("atlas");
            (mesh, index, atlas)
        })
        .collect()
}

fn run(
    method: &mut Optimization,
    data: &[(TriMesh, SurfaceIndex, Atlas)],
    from: usize,
) -> Vec<Vec<f32>> {
    (from..data.len())
        .map(|f| {
            let (mesh, index, atlas) = &data[f];
            let previous = (f > 0).then(|| PreviousFrame {
                mesh: &data[f - 1].0,
                index: &data[f - 1].1,
            });
            let ctx = FrameContext {
                number: f as i32,
                dt: 1.0 / 24.0,
                mesh,
                index,
                topology: &crate::mesh::Topology::new(mesh.vertex_count(), &mesh.triangles),
                normals: &mesh.vertex_normals(),
                previous,
                atlas,
                arena: &crate::methods::arena::FRESH,
            };
            let r = method.step(&ctx).expect("step");
            r.channels.into_iter().flat_map(|t| t.data).collect()
        })
        .collect()
}

/// [`run`] from frame 0 with `params` (seed 1, pebbles) on `threads` threads.
fn run_on_threads(
    threads: usize,
    params: OptimizationParams,
    data: &[(TriMesh, SurfaceIndex, Atlas)],
) -> Vec<Vec<f32>> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    pool.install(|| {
        let mut m = Optimization::new(params, pebbles(64), 1).expect("params");
        run(&mut m, data, 0)
    })
}

#[test]
fn deterministic_across_thread_counts_and_resume_is_identical() {
    let data = frames(3);
    let one = run_on_threads(1, small_params(), &data);
    let two = run_on_threads(2, small_params(), &data);
    assert_eq!(one.len(), 3);
    for (a, b) in one.iter().zip(&two) {
        assert!(a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
    }
    // The texture is not flat (control against a trivially equal output).
    assert!(one[2].iter().any(|&v| (v - one[2][0]).abs() > 0.05));
    // Resume: frames 0-1, save, a new instance loads and does frame 2.
    let mut first = Optimization::new(small_params(), pebbles(64), 1).expect("params");
    let head = run(&mut first, &data[..2], 0);
    let bytes = first.save_state().expect("save");
    let mut resumed = Optimization::new(small_params(), pebbles(64), 1).expect("params");
    resumed.load_state(&bytes).expect("load");
    let tail = run(&mut resumed, &data, 2);
    assert_eq!(head[1], one[1]);
    assert_eq!(tail[0], one[2]);
    // Control: a different seed gives a different texture.
    let mut other = Optimization::new(small_params(), pebbles(64), 2).expect("params");
    let diff = run(&mut other, &data[..1], 0);
    assert_ne!(diff[0], one[0]);
    // A corrupt state is an error, not a panic.
    assert!(resumed.load_state(&[0xff, 0xff, 0xff]).is_err());
}

#[test]
fn whole_window_searches_synthesise_the_same_on_any_thread_count() {
    let data = frames(2);
    let params = |search| OptimizationParams {
        exemplar_texels: 24,
        sizes: vec![9, 5],
        search,
        ..small_params()
    };
    let go = |search, threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let mut m = Optimization::new(params(search), pebbles(64), 1).expect("params");
            run(&mut m, &data, 0)
        })
    };
    let exact = go(Search::Exact, 1);
    assert_eq!(exact, go(Search::Exact, 2));
    assert!(exact[1].iter().any(|&v| (v - exact[1][0]).abs() > 0.05));
    // Control: the PCA search, re-ranking 8 candidates, matches other
    // neighbourhoods at some points.
    assert_ne!(exact, go(Search::Pca, 1));
    // The paper's clustering, the same whatever the threads.
    let clustered = go(Search::Clustered, 1);
    assert_eq!(clustered, go(Search::Clustered, 3));
}

#[test]
fn a_vertex_no_triangle_uses_changes_nothing() {
    // A validated frame keeps the vertices of the zero-area triangles it
    // dropped: here one such vertex comes first, so every used vertex's id
    // is one above its place among the used ones (this panicked on a
    // Mantaflow splash frame, an index past the finest level's points).
    let plain = frames(2);
    let with_stray: Vec<_> = plain
        .iter()
        .map(|(mesh, _, _)| {
            let mut positions = vec![Vec3::new(5.0, 5.0, 5.0)];
            positions.extend_from_slice(&mesh.positions);
            let mut velocity = vec![Vec3::ZERO];
            velocity.extend_from_slice(mesh.velocity().expect("velocity"));
            let triangles = mesh.triangles.iter().map(|t| t.map(|v| v + 1)).collect();
            let mesh = TriMesh::new(positions, triangles).with_velocity(velocity);
            let index = SurfaceIndex::new(&mesh);
            let atlas = Atlas::build(&mesh, &AtlasParams::square(96)).expect("atlas");
            (mesh, index, atlas)
        })
        .collect();
    let lattice = Lattice::new(&with_stray[0].0, 2);
    assert_eq!(lattice.len(), Lattice::new(&plain[0].0, 2).len());
    assert_eq!(lattice.level(1).ids.len(), lattice.len());
    let mut a = Optimization::new(small_params(), pebbles(64), 1).expect("params");
    let mut b = Optimization::new(small_params(), pebbles(64), 1).expect("params");
    assert_eq!(run(&mut b, &with_stray, 0), run(&mut a, &plain, 0));
}

#[test]
fn a_still_liquid_keeps_its_texture_bit_for_bit() {
    // The same plane three times: at rest, then with a slow flow.
    let still = |speed: f32| {
        let mesh = plane(12, 1.0, move |p| Vec3::new(-p.y, p.x, 0.0) * speed);
        let index = SurfaceIndex::new(&mesh);
        let atlas = Atlas::build(&mesh, &AtlasParams::square(96)).expect("atlas");
        (mesh, index, atlas)
    };
    let rest: Vec<_> = (0..3).map(|_| still(0.0)).collect();
    let mut m = Optimization::new(small_params(), pebbles(64), 1).expect("params");
    let out = run(&mut m, &rest, 0);
    assert_eq!(out[1], out[0]);
    assert_eq!(out[2], out[0]);
    // Control: the same mesh with a velocity is re-synthesised, and the
    // texture changes.
    let moving: Vec<_> = (0..2).map(|_| still(1e-3)).collect();
    let mut m = Optimization::new(small_params(), pebbles(64), 1).expect("params");
    let out = run(&mut m, &moving, 0);
    assert_ne!(out[1], out[0]);
}

#[test]
fn frames_carry_texture_and_report_stats() {
    let data = frames(2);
    let params = OptimizationParams {
        passes_after_first: 1,
        ..small_params()
    };
    let mut m = Optimization::new(params, pebbles(64), 1).expect("params");
    let topologies: Vec<_> = data
        .iter()
        .map(|d| crate::mesh::Topology::new(d.0.vertex_count(), &d.0.triangles))
        .collect();
    let normals: Vec<_> = data.iter().map(|d| d.0.vertex_normals()).collect();
    let ctx = |f: usize| FrameContext {
        number: f as i32,
        dt: 1.0 / 24.0,
        mesh: &data[f].0,
        index: &data[f].1,
        topology: &topologies[f],
        normals: &normals[f],
        previous: (f > 0).then(|| PreviousFrame {
            mesh: &data[f - 1].0,
            index: &data[f - 1].1,
        }),
        atlas: &data[f].2,
        arena: &crate::methods::arena::FRESH,
    };
    let widths = |stats: &serde_json::Value| -> Vec<Vec<u64>> {
        let levels = stats.as_array().expect("levels");
        levels
            .iter()
            .map(|l| {
                let passes = l["passes"].as_array().expect("passes");
                passes.iter().filter_map(|p| p["width"].as_u64()).collect()
            })
            .collect()
    };
    let r0 = m.step(&ctx(0)).expect("frame 0");
    assert_eq!(r0.stats["transported"], false);
    // A first frame runs every size on every level ...
    assert_eq!(widths(&r0.stats["levels"]), [vec![17, 9], vec![17, 9]]);
    let r1 = m.step(&ctx(1)).expect("frame 1");
    assert_eq!(r1.stats["transported"], true);
    // ... a carried one the last `passes_after_first` on one level.
    assert_eq!(widths(&r1.stats["levels"]), [vec![9]]);
    assert!(r1.stats["points"].as_u64().unwrap_or(0) > 1000);
    assert_eq!(r1.channels.len(), 1);
    assert!(r1.source.is_none() && r1.uv.is_none());
    let names: Vec<&str> = r1.timings.iter().map(|t| t.0).collect();
    assert_eq!(
        names,
        [
            "points",
            "transport",
            "orientation",
            "neighbourhoods",
            "search",
            "solve",
            "output"
        ]
    );
}

#[test]
fn bad_parameters_are_errors() {
    let bad = |p: OptimizationParams| Optimization::new(p, pebbles(16), 0).is_err();
    assert!(bad(OptimizationParams {
        sizes: vec![8],
        ..Default::default()
    }));
    assert!(bad(OptimizationParams {
        sizes: vec![],
        ..Default::default()
    }));
    assert!(bad(OptimizationParams {
        coherence: f32::NAN,
        ..Default::default()
    }));
    assert!(bad(OptimizationParams {
        search_grid: 4,
        ..Default::default()
    }));
    assert!(bad(OptimizationParams {
        passes_after_first: 0,
        ..Default::default()
    }));
    // Fewer sizes than carried passes: every size runs, not an error.
    assert!(!bad(OptimizationParams {
        sizes: vec![9],
        ..Default::default()
    }));
    assert!(!bad(OptimizationParams::default()));
    let _ = Vec2::ZERO;
}

/// The 2007 paper's relaxation of a vertex neighbourhood's layout: on a
/// plane the ring-by-ring layout is already exact and relaxing leaves it
/// so; on a sphere it is not, and every sweep count lowers the misfit.
#[test]
fn relaxation_lowers_the_layout_misfit_on_a_curved_surface() {
    use super::neighbourhood::layout_misfit;
    let window = |relaxation| Window {
        width: 17,
        grid: 9,
        texel: 0.02,
        relaxation,
    };
    let flat = Lattice::new(&plane(16, 1.0, |_| Vec3::ZERO), 2);
    let level = flat.level(0);
    let centre = (level.len() / 2) as u32;
    for sweeps in [0, 4] {
        let (misfit, placed) = layout_misfit(&level, centre, Vec3::X, window(sweeps));
        assert!(placed > 50);
        assert!(misfit < 1e-6, "flat, {sweeps} sweeps: {misfit}");
    }
    let sphere = Lattice::new(&crate::atlas::fixtures::icosphere(3), 1);
    let level = sphere.level(0);
    let centre = 0u32;
    let n = level.normals[0];
    let d = n.any_orthonormal_vector();
    let misfits: Vec<f64> = [0, 1, 4, 16]
        .iter()
        .map(|&k| layout_misfit(&level, centre, d, window(k)).0)
        .collect();
    assert!(
        misfits[0] > 1e-3,
        "the curved layout is inexact: {misfits:?}"
    );
    for w in misfits.windows(2) {
        assert!(w[1] < w[0], "{misfits:?}");
    }
}

/// The paper's up-sampling: no sweep is exactly the interpolation; each
/// diffusion sweep lowers the roughness (sum of squared differences along
/// the finer level's edges) of seeded random coarse values and keeps their
/// mean within 2 %.
#[test]
fn upsampling_diffusion_smooths_what_the_copy_carries_up() {
    let lattice = Lattice::new(&plane(8, 1.0, |_| Vec3::ZERO), 4);
    let (coarse, fine) = (lattice.level(1), lattice.level(0));
    let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
    let values: Vec<f32> = (0..coarse.len()).map(|_| rng.random::<f32>()).collect();
    let mut copied = vec![0.0f32; fine.len()];
    lattice.prolong(&coarse, &values, 1, &fine, &mut copied);
    assert_eq!(lattice.upsample(&coarse, &values, 1, &fine, 0), copied);
    let roughness = |x: &[f32]| {
        (0..fine.len() as u32)
            .flat_map(|v| fine.neighbours(v).iter().map(move |&u| (u, v)))
            .map(|(u, v)| f64::from(x[u as usize] - x[v as usize]).powi(2))
            .sum::<f64>()
    };
    let mean = |x: &[f32]| x.iter().map(|&v| f64::from(v)).sum::<f64>() / x.len() as f64;
    let mut last = roughness(&copied);
    for sweeps in 1..4 {
        let up = lattice.upsample(&coarse, &values, 1, &fine, sweeps);
        let r = roughness(&up);
        assert!(r < last, "{sweeps} sweeps: {r} against {last}");
        assert!((mean(&up) - mean(&copied)).abs() < 0.02 * mean(&copied));
        last = r;
    }
}

/// Every vertex of an icosphere's lattice gets a closed polar map, and the
/// angle defects 2π − Θ they rescale by add up to 4π (Gauss–Bonnet on a
/// closed surface of genus 0): the fans are walked whole, each corner
/// once. Control: tangent-plane angles (the fallback) have no defect.
#[test]
fn polar_maps_of_a_sphere_add_up_to_its_total_curvature() {
    use super::polar::PolarMaps;
    use std::f64::consts::{PI, TAU};
    let lattice = Lattice::new(&crate::atlas::fixtures::icosphere(2), 2);
    let level = lattice.level(0);
    let maps = PolarMaps::new(&level);
    let mut defect = 0.0f64;
    for v in 0..level.len() as u32 {
        assert!(maps.is_closed(v), "vertex {v} fell back");
        let theta = TAU / f64::from(maps.scale(v));
        defect += TAU - theta;
    }
    assert!((defect - 4.0 * PI).abs() < 1e-3, "total defect {defect}");
    // The flat control: a plane's interior vertices have none.
    let flat = Lattice::new(&plane(4, 1.0, |_| Vec3::ZERO), 2).level(0);
    let flat_maps = PolarMaps::new(&flat);
    let interior: Vec<u32> = (0..flat.len() as u32)
        .filter(|&v| flat_maps.is_closed(v))
        .collect();
    assert!(interior.len() > 20);
    for v in interior {
        assert!((flat_maps.scale(v) - 1.0).abs() < 1e-5);
    }
}

/// Polar angle → tangent vector → polar angle is the identity at every
/// vertex of a curved lattice (seeded random angles), each edge's polar
/// angle gives that edge's direction projected on the tangent plane, and
/// polar angle 0 is the reference vector.
#[test]
fn polar_angles_and_tangent_vectors_are_inverse_maps() {
    use super::polar::PolarMaps;
    use super::tangent::tangent;
    let mut mesh = crate::atlas::fixtures::icosphere(2);
    // Squash it so that the fans are uneven.
    mesh.positions.iter_mut().for_each(|p| p.z *= 0.5);
    let lattice = Lattice::new(&mesh, 2);
    let level = lattice.level(0);
    let maps = PolarMaps::new(&level);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let wrap = |a: f32| {
        (a + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI
    };
    for v in 0..level.len() as u32 {
        let n = level.normals[v as usize];
        for _ in 0..8 {
            let theta = rng.random::<f32>() * std::f32::consts::TAU;
            let d = maps.vector(v, n, theta);
            assert!((d.length() - 1.0).abs() < 1e-4 && d.dot(n).abs() < 1e-4);
            let back = maps.angle(v, n, d);
            assert!(wrap(back - theta).abs() < 1e-3, "v {v}: {theta} -> {back}");
        }
        let zero = maps.vector(v, n, 0.0);
        assert!(zero.angle_between(super::tangent::reference(n)) < 1e-3);
        for &u in level.neighbours(v) {
            let phi = maps
                .edge_angle(v, u)
                .expect("a walked fan lists every neighbour");
            let edge = tangent(level.positions[u as usize] - level.positions[v as usize], n);
            assert!(
                maps.vector(v, n, phi).angle_between(edge) < 1e-3,
                "edge {v}-{u}"
            );
        }
    }
}

/// On a plane the polar maps are the tangent-plane angles, so the paper's
/// smoothing gives the projected one's field (after 3 iterations, from a
/// seeded random field that both change by much more).
#[test]
fn polar_and_projected_smoothing_agree_on_a_plane() {
    use super::orientation::{self, Smoothing};
    let lattice = Lattice::new(&plane(6, 1.0, |_| Vec3::ZERO), 2);
    let levels = vec![lattice.level(0)];
    let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
    let start: Vec<Vec3> = (0..levels[0].len())
        .map(|_| {
            let a = rng.random::<f32>() * std::f32::consts::TAU;
            Vec3::new(a.cos(), a.sin(), 0.0)
        })
        .collect();
    let run = |mode| orientation::smooth_hierarchy(&lattice, &levels, Some(start.clone()), 3, mode);
    let (projected, polar) = (run(Smoothing::Projected), run(Smoothing::Polar));
    let moved = projected
        .iter()
        .zip(&start)
        .filter(|(a, b)| a.angle_between(**b) > 0.1)
        .count();
    assert!(moved > start.len() / 2, "{moved} of {}", start.len());
    for (v, (a, b)) in projected.iter().zip(&polar).enumerate() {
        assert!(a.angle_between(*b) < 1e-3, "vertex {v}: {a} vs {b}");
    }
}

/// The paper's smoothing makes neighbours agree through the polar maps'
/// transport on a sphere: from a seeded random field, which disagrees by
/// about π/2 along edges on average (the control), the mean disagreement
/// falls with every iteration count, to under 40 % at 20.
#[test]
fn polar_smoothing_makes_neighbours_agree_on_a_sphere() {
    use super::polar::{self, PolarMaps};
    let lattice = Lattice::new(&crate::atlas::fixtures::icosphere(2), 2);
    let level = lattice.level(0);
    let maps = PolarMaps::new(&level);
    let disagreement = |d: &[Vec3]| {
        let theta: Vec<f32> = (0..level.len())
            .map(|v| maps.angle(v as u32, level.normals[v], d[v]))
            .collect();
        let (mut sum, mut n) = (0.0f64, 0usize);
        for v in 0..level.len() as u32 {
            for &u in level.neighbours(v) {
                let carried = maps.carry(&level, u, theta[u as usize], v);
                let diff = (carried - theta[v as usize] + std::f32::consts::PI)
                    .rem_euclid(std::f32::consts::TAU)
                    - std::f32::consts::PI;
                sum += f64::from(diff.abs());
                n += 1;
            }
        }
        sum / n as f64
    };
    let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
    let random: Vec<Vec3> = (0..level.len())
        .map(|v| {
            let a = rng.random::<f32>() * std::f32::consts::TAU;
            maps.vector(v as u32, level.normals[v], a)
        })
        .collect();
    let r = disagreement(&random);
    assert!(
        (r - std::f64::consts::FRAC_PI_2).abs() < 0.2,
        "random field {r}"
    );
    let (start, before) = (random, r);
    assert!(before > 0.5, "zero-angle start {before}");
    let mut last = before;
    for iterations in [5, 10, 20] {
        let mut d = start.clone();
        polar::diffuse(&level, &maps, &mut d, iterations);
        let after = disagreement(&d);
        assert!(after < last, "{iterations} iterations: {last} -> {after}");
        last = after;
    }
    // What is left is mostly around the field's unavoidable singularities.
    assert!(last < before / 2.5, "{before} -> {last}");
}

#[test]
fn scattered_points_are_deterministic_resume_exactly_and_differ_from_the_lattice() {
    // The paper's placement: random points spread by repulsion. The
    // previous frame's points are rebuilt from its mesh alone (the seed
    // and the mesh draw them), so a resumed run carries the same texture.
    let data = frames(3);
    let params = || OptimizationParams {
        placement: Placement::Repulsion,
        ..small_params()
    };
    let one = run_on_threads(1, params(), &data);
    let two = run_on_threads(2, params(), &data);
    assert_eq!(one, two);
    let mut first = Optimization::new(params(), pebbles(64), 1).expect("params");
    run(&mut first, &data[..2], 0);
    let bytes = first.save_state().expect("save");
    let mut resumed = Optimization::new(params(), pebbles(64), 1).expect("params");
    resumed.load_state(&bytes).expect("load");
    assert_eq!(run(&mut resumed, &data, 2)[0], one[2]);
    // Control: the lattice gives another texture from the same seed.
    let mut lattice = Optimization::new(small_params(), pebbles(64), 1).expect("params");
    let other = run(&mut lattice, &data, 0);
    for (a, b) in one.iter().zip(&other) {
        assert_eq!(a.len(), b.len());
        assert_ne!(a, b);
    }
    // A textured surface: not flat, and carried (later frames start from
    // the transported texture, so they stay close to the first).
    assert!(one[2].iter().any(|&v| (v - one[2][0]).abs() > 0.05));
}

#[test]
fn scattered_points_keep_the_lattice_density_and_report_it() {
    let data = frames(1);
    let mut stats = Vec::new();
    for placement in [Placement::Lattice, Placement::Repulsion] {
        let params = OptimizationParams {
            placement,
            ..small_params()
        };
        let mut m = Optimization::new(params, pebbles(64), 1).expect("params");
        let (mesh, index, atlas) = &data[0];
        let ctx = FrameContext {
            number: 0,
            dt: 1.0 / 24.0,
            mesh,
            index,
            topology: &crate::mesh::Topology::new(mesh.vertex_count(), &mesh.triangles),
            normals: &mesh.vertex_normals(),
            previous: None,
            atlas,
            arena: &crate::methods::arena::FRESH,
        };
        let r = m.step(&ctx).expect("step");
        let get = |k: &str| r.stats[k].as_f64().expect(k);
        stats.push((get("points"), get("spacing"), get("lattice_steps")));
    }
    let ((lattice, h, _), (scattered, h2, steps)) = (stats[0], stats[1]);
    // The same spacing h, and about 2A / (√3 h²) points (area 4).
    assert_eq!(h, h2);
    let expected = 8.0 / (3f64.sqrt() * h * h);
    assert!(
        (scattered - expected).abs() <= 1.0,
        "{scattered} {expected}"
    );
    assert!(
        (0.5..2.0).contains(&(lattice / scattered)),
        "{lattice} {scattered}"
    );
    assert_eq!(steps, 1.0);
}
