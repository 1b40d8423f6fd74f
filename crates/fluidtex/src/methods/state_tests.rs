//! Exemplars chosen by a simulation attribute, end to end through both
//! lapped methods: a plane at rest whose `temperature` falls from hot to
//! cold behind a front that sweeps across it. The hot exemplar is white
//! (range 0.5..1), the cold one black (0..0.5), so the colour of a texel
//! says which exemplar shows there.

use std::sync::Arc;

use glam::Vec3;

use super::registry::{MethodKind, MethodParams};
use super::test_clip::{Clip, grey_exemplar, grid};
use super::{FrameResult, Method, MethodError, SOURCE_OUTSIDE, SOURCE_UNCOVERED};
use crate::exemplar::set::{AttributeRange, SelectBy};
use crate::exemplar::{ExemplarSelect, ExemplarSet};
use crate::mesh::Attribute;

/// Frames before the front starts, and the frames it takes to cross.
const HOT_FRAMES: usize = 4;
const SWEEP_FRAMES: usize = 6;
const FRAMES: usize = 34;
/// Per second: a mismatching weight (or fade) goes in 6 frames at 24 fps.
const RATE: f32 = 4.0;

/// The temperature at `x` (the grid spans [−0.5, 0.5]) on frame `k`: 1
/// everywhere, then 0 behind a front moving along +x, then 0 everywhere.
fn temperature(x: f32, k: usize) -> f32 {
    if k < HOT_FRAMES {
        return 1.0;
    }
    let front = -0.5 + (k - HOT_FRAMES) as f32 / SWEEP_FRAMES as f32;
    if x < front { 0.0 } else { 1.0 }
}

/// A 24×24 plane at rest (zero velocity), with its temperature per frame.
fn cooling_plane() -> Clip {
    let meshes = (0..FRAMES)
        .map(|k| {
            let mut m = grid(24, 1.0 / 24.0, |_| Vec3::ZERO);
            let t = m.positions.iter().map(|p| temperature(p.x, k)).collect();
            m.attributes
                .insert("temperature".into(), Attribute::Scalar(t));
            m
        })
        .collect();
    Clip::from_meshes(meshes, 128)
}

/// Black crust and white glow, drawn by probability.
fn crust_and_glow_drawn() -> ExemplarSet {
    ExemplarSet::new(
        vec![
            (
                "crust.png".into(),
                Arc::new(grey_exemplar(16, |_, _| 0.0)),
                1.0,
            ),
            (
                "glow.png".into(),
                Arc::new(grey_exemplar(16, |_, _| 1.0)),
                1.0,
            ),
        ],
        ExemplarSelect::Probability,
        None,
    )
    .expect("same channels")
}

/// Cold black (0..0.5) and hot white (0.5..1), chosen by temperature, at
/// the constant `rate`: the front is a step, 0.5 past the split wherever
/// it has passed, where the default gain makes a mismatch go within a
/// frame; these tests are about the rate and the lag it leaves
/// (`state_blob_tests` covers the gain).
fn crust_and_glow(rate: f32) -> ExemplarSet {
    let set = crust_and_glow_drawn();
    let ranges = vec![
        AttributeRange::new(0.0, 0.5).expect("range"),
        AttributeRange::new(0.5, 1.0).expect("range"),
    ];
    let by = SelectBy::new("temperature", ranges)
        .with_mismatch_rate(rate)
        .and_then(|b| b.with_mismatch_gain(0.0))
        .expect("rate");
    set.with_select_by(by).expect("two ranges")
}

pub(super) fn build(kind: MethodKind, set: ExemplarSet) -> Box<dyn Method> {
    let mut p = MethodParams::default();
    p.erosion.radius_fraction = 0.06;
    p.erosion.radius_edges = 0.0;
    p.lapped_rigid.radius_fraction = 0.06;
    p.lapped_rigid.radius_edges = 0.0;
    p.build_set(kind, 3, || Ok::<_, MethodError>(set))
        .expect("builds")
}

/// Mean colour of the covered texels: the share of glow shown (1 all
/// glow, 0 all crust).
fn glow_share(r: &FrameResult) -> f64 {
    let source = r.source.as_ref().expect("source");
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (s, c) in source.iter().zip(&r.channels[0].data) {
        if *s != SOURCE_OUTSIDE && *s != SOURCE_UNCOVERED {
            sum += *c as f64;
            n += 1;
        }
    }
    assert!(n > 1000, "only {n} covered texels");
    sum / n as f64
}

#[test]
fn the_cold_exemplar_takes_over_progressively_and_then_holds_still() {
    let clip = cooling_plane();
    for kind in [MethodKind::Erosion, MethodKind::LappedRigid] {
        let mut m = build(kind, crust_and_glow(RATE));
        let results = clip.run(m.as_mut());
        let glow: Vec<f64> = results.iter().map(glow_share).collect();
        println!(
            "{kind}: glow share per frame % {:?}",
            glow.iter()
                .map(|g| (g * 100.0).round() as i32)
                .collect::<Vec<_>>()
        );
        // Hot everywhere: every new patch takes the glow.
        assert!(glow[0] > 0.999, "{kind}: frame 0 shows {}", glow[0]);
        // Cold everywhere, well after 1/rate s: the state agrees.
        let last = FRAMES - 1;
        assert!(
            glow[last] < 0.05,
            "{kind}: the last frame shows {}",
            glow[last]
        );
        // Not a jump: no frame changes more than 40 % of the surface.
        for k in 1..FRAMES {
            assert!(
                (glow[k] - glow[k - 1]).abs() < 0.4,
                "{kind}: frame {k} jumps {} -> {}",
                glow[k - 1],
                glow[k]
            );
        }
        // The crust follows the front: by the end of the sweep part of the
        // surface has turned, not all of it.
        let swept = HOT_FRAMES + SWEEP_FRAMES;
        assert!(
            glow[swept] < 0.9 && glow[swept] > 0.05,
            "{kind}: {} glow at the end of the sweep",
            glow[swept]
        );
        // The state agreement the method reports: all glow on hot, all
        // crust once settled, and in between while the front passes.
        let agree: Vec<f64> = results
            .iter()
            .map(|r| {
                r.stats["state_agreement"]
                    .as_f64()
                    .expect("state_agreement")
            })
            .collect();
        assert_eq!(agree[0], 1.0, "{kind}");
        assert!(agree[last] >= 0.95, "{kind}: {}", agree[last]);
        assert!(
            agree[swept] < 0.95,
            "{kind}: {} during the front",
            agree[swept]
        );
        // At rest in a settled state the texture holds bit for bit.
        assert_eq!(
            results[last].channels,
            results[last - 1].channels,
            "{kind}: the settled frames differ"
        );
    }
}

#[test]
fn without_the_mismatch_rule_old_patches_keep_their_glow() {
    // Control: the same frames and exemplars chosen by probability keep
    // showing glow where the surface went cold.
    let clip = cooling_plane();
    let mut m = build(MethodKind::Erosion, crust_and_glow_drawn());
    let results = clip.run(m.as_mut());
    let last = glow_share(&results[FRAMES - 1]);
    assert!(last > 0.2, "the control shows {last} glow at the end");
}

#[test]
fn a_slower_mismatch_rate_takes_longer() {
    let clip = cooling_plane();
    let frames_to_settle = |rate: f32| {
        let mut m = build(MethodKind::Erosion, crust_and_glow(rate));
        let glow: Vec<f64> = clip.run(m.as_mut()).iter().map(glow_share).collect();
        glow.iter().position(|&g| g < 0.05).unwrap_or(FRAMES)
    };
    let (fast, slow) = (frames_to_settle(RATE), frames_to_settle(RATE / 3.0));
    assert!(
        fast < slow,
        "rate {RATE}: {fast} frames, rate {}: {slow}",
        RATE / 3.0
    );
}

#[test]
fn one_and_two_threads_give_identical_frames() {
    let clip = cooling_plane();
    let go = |threads, kind| clip.run_on_threads(threads, || build(kind, crust_and_glow(RATE)));
    for kind in [MethodKind::Erosion, MethodKind::LappedRigid] {
        assert!(go(1, kind) == go(2, kind), "{kind}");
    }
}

#[test]
fn a_mesh_without_the_attribute_is_a_one_line_error() {
    let mut clip = cooling_plane();
    clip.meshes[0].attributes.remove("temperature");
    let clip = Clip::from_meshes(clip.meshes, 64);
    for kind in [MethodKind::Erosion, MethodKind::LappedRigid] {
        let mut m = build(kind, crust_and_glow(RATE));
        let err = m
            .step(&clip.ctx(0))
            .expect_err("no temperature")
            .to_string();
        assert!(
            err.contains("frame 0") && err.contains("temperature") && !err.contains('\n'),
            "{kind}: {err}"
        );
    }
}

/// A patch of `n` vertices with the given weights now and the frame before.
fn patch_with(weight: Vec<f32>, before: Vec<f32>) -> super::erosion::patch::Patch {
    let n = weight.len();
    super::erosion::patch::Patch {
        id: 0,
        positions: vec![Vec3::ZERO; n],
        rest: vec![glam::Vec2::ZERO; n],
        triangles: Vec::new(),
        pinned: vec![false; n],
        weight,
        weight_before: before,
        weight_older: Vec::new(),
        distorted: Vec::new(),
        mismatched: Vec::new(),
        lod: Vec::new(),
        still: false,
        exemplar: 0,
    }
}

#[test]
fn mismatch_lowers_weights_only_where_the_range_is_violated() {
    let mut p = patch_with(vec![0.9, 1.0, 0.6, 0.1], vec![1.0, 1.0, 0.5, 0.2]);
    p.lower_mismatched(&[None, Some(0.25), Some(0.25), Some(0.5)]);
    assert_eq!(p.weight, vec![0.9, 0.75, 0.25, 0.0]);
    // No weight the frame before (a patch placed this frame): unchanged.
    let mut p = patch_with(vec![0.9, 1.0], Vec::new());
    p.lower_mismatched(&[Some(0.25), Some(0.25)]);
    assert_eq!(p.weight, vec![0.9, 1.0]);
    // Seeded random cases: never raised, untouched where matching, at most
    // the vertex's drop below the frame before where not.
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(41);
    for _ in 0..200 {
        let n = rng.random_range(1..20);
        let w: Vec<f32> = (0..n).map(|_| rng.random()).collect();
        let b: Vec<f32> = (0..n).map(|_| rng.random()).collect();
        let m: Vec<Option<f32>> = (0..n)
            .map(|_| rng.random::<bool>().then(|| rng.random_range(0.0..0.5)))
            .collect();
        let mut p = patch_with(w.clone(), b.clone());
        p.lower_mismatched(&m);
        for v in 0..n {
            assert!(p.weight[v] <= w[v], "raised at {v}");
            match m[v] {
                Some(drop) => assert_eq!(p.weight[v], w[v].min((b[v] - drop).max(0.0))),
                None => assert_eq!(p.weight[v], w[v]),
            }
        }
    }
}

#[test]
fn state_agreement_counts_the_texels_whose_exemplar_matches() {
    let clip = cooling_plane();
    let mut m = build(MethodKind::Erosion, crust_and_glow(RATE));
    let r = m.step(&clip.ctx(0)).expect("step");
    let source = r.source.as_ref().expect("source");
    let set = crust_and_glow(RATE);
    let by = set.by.as_ref().expect("by");
    let agreement = |e: u32| {
        super::lapped::state::state_agreement(&clip.atlases[0], &clip.meshes[0], by, source, |_| {
            Some(e)
        })
    };
    // Frame 0 is hot everywhere: glow (1) agrees at every texel, crust at none.
    assert_eq!(agreement(1), Some(1.0));
    assert_eq!(agreement(0), Some(0.0));
    // Half the plane cold (x < 0): crust agrees on about half the texels.
    let mut half = clip.meshes[0].clone();
    let t = half
        .positions
        .iter()
        .map(|p| if p.x < 0.0 { 0.0 } else { 1.0 })
        .collect();
    half.attributes
        .insert("temperature".into(), Attribute::Scalar(t));
    let a = super::lapped::state::state_agreement(&clip.atlases[0], &half, by, source, |_| Some(0))
        .expect("covered");
    assert!((a - 0.5).abs() < 0.08, "{a}");
    let texels = super::lapped::state::texels_per_exemplar(source, 2, |_| Some(1));
    assert_eq!(texels[0], 0);
    assert!(texels[1] > 1000);
}

#[test]
fn switches_the_state_forces_count_as_forced() {
    // On the plane at rest every texel stays at its point, so the sources
    // of consecutive frames compare texel by texel.
    let clip = cooling_plane();
    let mut m = build(MethodKind::Erosion, crust_and_glow(RATE));
    let results = clip.run(m.as_mut());
    let (mut with_state, mut without_state) = (0usize, 0usize);
    let mut switched = 0usize;
    for k in 1..FRAMES {
        let before = results[k - 1].source.as_ref().expect("source");
        let after = results[k].source.as_ref().expect("source");
        let renewal = results[k].renewal.as_ref().expect("renewal");
        let causes = crate::metrics::switch_causes(before, after, renewal).expect("lengths");
        switched += causes.forced + causes.unforced;
        with_state += causes.unforced;
        // Control: the same bytes without the state bit, nor the eroding
        // bit that the state's lowered weights set (the plane at rest is
        // not distorted anywhere).
        let plain: Vec<u8> = renewal
            .iter()
            .map(|&r| {
                if r == crate::provenance::RENEWAL_UNKNOWN {
                    r
                } else {
                    r & !(crate::provenance::RENEWAL_STATE | crate::provenance::RENEWAL_ERODING)
                }
            })
            .collect();
        without_state += crate::metrics::switch_causes(before, after, &plain)
            .expect("lengths")
            .unforced;
    }
    assert!(switched > 1000, "only {switched} switches");
    assert!(
        with_state * 50 < switched,
        "{with_state} of {switched} switches unforced"
    );
    assert!(
        without_state * 2 > switched,
        "the control: {without_state} of {switched} unforced without the state bit"
    );
}

#[test]
fn a_selection_by_attribute_resamples_into_the_one_pass_frame() {
    // The mismatch marks travel in erosion's selection: a frame resampled
    // from it by a fresh method has the same sources, renewal (forced by
    // the state) and statistics (state agreement).
    let clip = cooling_plane();
    for kind in [MethodKind::Erosion, MethodKind::LappedRigid] {
        let fresh = || build(kind, crust_and_glow(RATE));
        let (mut one_pass, mut selecting) = (fresh(), fresh());
        for k in 0..HOT_FRAMES + SWEEP_FRAMES + 4 {
            let expected = one_pass.step(&clip.ctx(k)).expect("step");
            let selection = selecting.select(&clip.ctx(k)).expect("select");
            let mut ctx = clip.ctx(k);
            let mut resampler = fresh();
            if !selection.needs_previous() {
                ctx.previous = None;
            } else {
                // Methods that replay need the state before the frame.
                let mut before = fresh();
                for j in 0..k {
                    before.step(&clip.ctx(j)).expect("step");
                }
                resampler = before;
            }
            let got = resampler.resample(&ctx, &selection).expect("resample");
            assert!(
                expected.channels == got.channels,
                "{kind} frame {k}: channels"
            );
            assert!(expected.source == got.source, "{kind} frame {k}: sources");
            assert!(expected.renewal == got.renewal, "{kind} frame {k}: renewal");
            assert_eq!(expected.stats, got.stats, "{kind} frame {k}: statistics");
        }
    }
}
