//! Selection apart from resampling, for every method: a frame resampled
//! from its serialised selection, by a method built afresh, is the
//! one-pass frame bit for bit (channels, sources, uv, levels, layers,
//! renewal, statistics). The patch methods' and the optimization's own
//! selections need the frame's geometry alone; the test toy keeps the
//! trait's default, a replay of the frame from the state before it.

use std::sync::Arc;

use super::registry::{MethodKind, MethodParams};
use super::{FrameResult, Method, MethodError, Selection};
use crate::exemplar::ExemplarSet;
use crate::methods::test_clip::{Clip, noise_exemplar, scene};
use crate::named::Named;

fn build(params: &MethodParams, kind: MethodKind) -> Box<dyn Method> {
    let exemplar = Arc::new(noise_exemplar(64, 4, 3));
    params
        .build_set(kind, 11, || {
            Ok::<_, MethodError>(ExemplarSet::single(exemplar))
        })
        .expect("builds")
}

fn bits(values: &Option<Vec<f32>>) -> Option<Vec<u32>> {
    values
        .as_ref()
        .map(|v| v.iter().map(|x| x.to_bits()).collect())
}

/// Everything of a result a file or a metric reads, but the timings.
fn assert_same(label: &str, a: &FrameResult, b: &FrameResult) {
    assert_eq!(a.channels.len(), b.channels.len(), "{label}: channels");
    for (x, y) in a.channels.iter().zip(&b.channels) {
        let (x, y): (Vec<u32>, Vec<u32>) = (
            x.data.iter().map(|v| v.to_bits()).collect(),
            y.data.iter().map(|v| v.to_bits()).collect(),
        );
        assert!(x == y, "{label}: channel values differ");
    }
    assert!(a.source == b.source, "{label}: sources differ");
    let uv = |r: &FrameResult| {
        r.uv.as_ref()
            .map(|v| v.iter().flat_map(|p| [p.x, p.y]).collect::<Vec<f32>>())
    };
    assert!(bits(&uv(a)) == bits(&uv(b)), "{label}: uv differs");
    assert!(
        bits(&a.exemplar_lod) == bits(&b.exemplar_lod),
        "{label}: levels differ"
    );
    assert!(a.layers == b.layers, "{label}: layers differ");
    assert!(a.renewal == b.renewal, "{label}: renewal differs");
    assert_eq!(a.stats, b.stats, "{label}: statistics differ");
}

/// Steps `kind` over `clip` in one pass, selects it in a second instance,
/// and resamples every frame in a fresh third one; returns the selections.
fn round_trip(params: &MethodParams, kind: MethodKind, clip: &Clip) -> Vec<Selection> {
    round_trip_built(|| build(params, kind), clip)
}

/// [`round_trip`] of the method `build` makes (the same one each call).
pub(super) fn round_trip_built(build: impl Fn() -> Box<dyn Method>, clip: &Clip) -> Vec<Selection> {
    let mut one_pass = build();
    let mut selecting = build();
    let name = one_pass.name();
    let mut selections = Vec::new();
    for k in 0..clip.meshes.len() {
        let expected = one_pass.step(&clip.ctx(k)).expect("step");
        let selection = selecting.select(&clip.ctx(k)).expect("select");
        let mut fresh = build();
        let mut ctx = clip.ctx(k);
        if !selection.needs_previous() {
            // The frame's geometry alone.
            ctx.previous = None;
        }
        let got = fresh.resample(&ctx, &selection).expect("resample");
        assert_same(&format!("{name} frame {k}"), &expected, &got);
        selections.push(selection);
    }
    // Selecting advanced the state as the one-pass run did.
    assert_eq!(
        one_pass.save_state().expect("state"),
        selecting.save_state().expect("state"),
        "{name}: state after the last frame"
    );
    selections
}

#[test]
fn every_method_resamples_its_selection_into_the_one_pass_frame() {
    let clip = scene("vortex", 16, 5, 128);
    let params = MethodParams::default();
    for &kind in MethodKind::ALL {
        let selections = round_trip(&params, kind, &clip);
        // Every method of the registry selects on its own; only the test
        // toy keeps the trait's default and replays.
        let own = kind != MethodKind::Toy;
        assert!(
            selections.iter().all(|s| s.needs_previous() != own),
            "{}: selection kind",
            kind.name()
        );
    }
}

#[test]
fn erosion_selections_with_a_transition_and_switches_resample_exactly() {
    // A sheared flow renews patches every frame; a transition reads the
    // weights of earlier frames, which the selection carries.
    let clip = scene("vortex", 16, 6, 128);
    let mut params = MethodParams::default();
    params.erosion.transition = 2;
    params.erosion.radius_fraction = 0.03;
    params.erosion.radius_edges = 0.0;
    let selections = round_trip(&params, MethodKind::Erosion, &clip);
    // Compact: patches, not per-texel arrays (12 bytes a texel).
    let texels = (clip.atlases[0].width * clip.atlases[0].height) as usize;
    for s in &selections {
        assert!(s.bytes().len() < texels * 12, "{} bytes", s.bytes().len());
    }
}

#[test]
fn dual_rest_selections_resample_exactly_across_both_resets() {
    // A period of 4 resets layer A on frames 0 and 4, layer B on 2: the
    // clip crosses each reset, and a layer reset on a frame is selected
    // from its fresh patches.
    let clip = scene("vortex", 16, 6, 128);
    let mut params = MethodParams::default();
    params.dual_rest.period = 4;
    let selections = round_trip(&params, MethodKind::DualRest, &clip);
    assert!(selections.iter().all(|s| !s.needs_previous()));
    // A damaged selection is refused in one line.
    let mut fresh = build(&params, MethodKind::DualRest);
    let bytes = selections[3].bytes();
    for damaged in [
        Selection::Own(bytes[..bytes.len() / 2].to_vec()),
        Selection::Replay(bytes.to_vec()),
    ] {
        let err = fresh
            .resample(&clip.ctx(3), &damaged)
            .expect_err("damaged")
            .to_string();
        assert!(err.contains("selection") && !err.contains('\n'), "{err}");
    }
}

#[test]
fn lapped_rigid_selections_resample_exactly_with_random_placement() {
    // The paper's placement draws new trackers at random (a generator
    // seeded per frame) and leaves short seed texels open: resampling
    // makes the same trackers again from the frame's geometry alone.
    let clip = scene("vortex", 16, 4, 128);
    let mut params = MethodParams::default();
    params.lapped_rigid.placement = crate::methods::lapped_rigid::distribution::Placement::Random;
    params.lapped_rigid.seed_texel = crate::methods::erosion::SeedTexel::Paper;
    let selections = round_trip(&params, MethodKind::LappedRigid, &clip);
    // Compact: the trackers, not per-texel arrays (12 bytes a texel).
    let texels = (clip.atlases[0].width * clip.atlases[0].height) as usize;
    for s in &selections {
        assert!(!s.needs_previous());
        assert!(s.bytes().len() < texels, "{} bytes", s.bytes().len());
    }
    // Another method's selection, or a damaged one, is refused in one line.
    let mut erosion = build(&params, MethodKind::Erosion);
    let foreign = erosion.select(&clip.ctx(0)).expect("select");
    let bytes = selections[1].bytes();
    let mut fresh = build(&params, MethodKind::LappedRigid);
    for damaged in [
        foreign,
        Selection::Own(bytes[..bytes.len() / 2].to_vec()),
        Selection::Replay(bytes.to_vec()),
    ] {
        let err = fresh
            .resample(&clip.ctx(1), &damaged)
            .expect_err("damaged")
            .to_string();
        assert!(err.contains("selection") && !err.contains('\n'), "{err}");
    }
}

#[test]
fn optimization_selections_with_scattered_points_resample_exactly() {
    // The paper's placement: the frame's points are rebuilt from its mesh
    // and the spacing the selection carries.
    let clip = scene("vortex", 16, 3, 96);
    let mut params = MethodParams::default();
    params.optimization.points = 3000;
    params.optimization.placement = crate::methods::optimization::Placement::Repulsion;
    let selections = round_trip(&params, MethodKind::Optimization, &clip);
    assert!(selections.iter().all(|s| !s.needs_previous()));
    // A lattice run's selection (no spacing) does not fit scattered points,
    // nor the other way round.
    let mut lattice = params.clone();
    lattice.optimization.placement = crate::methods::optimization::Placement::Lattice;
    let from_lattice = build(&lattice, MethodKind::Optimization)
        .select(&clip.ctx(0))
        .expect("select");
    for (make, selection) in [(&params, &from_lattice), (&lattice, &selections[0])] {
        let err = build(make, MethodKind::Optimization)
            .resample(&clip.ctx(0), selection)
            .expect_err("misfit")
            .to_string();
        assert!(
            err.contains("selection") && err.contains("placement"),
            "{err}"
        );
    }
}

#[test]
fn a_damaged_or_foreign_selection_is_refused_in_one_line() {
    let clip = scene("vortex", 16, 2, 64);
    let params = MethodParams::default();
    let mut selecting = build(&params, MethodKind::Erosion);
    let selection = selecting.select(&clip.ctx(0)).expect("select");
    let bytes = selection.bytes().to_vec();
    let mut fresh = build(&params, MethodKind::Erosion);
    for (label, damaged) in [
        (
            "truncated",
            Selection::Own(bytes[..bytes.len() / 2].to_vec()),
        ),
        ("empty", Selection::Own(Vec::new())),
        ("replayed", Selection::Replay(bytes.clone())),
    ] {
        let err = fresh
            .resample(&clip.ctx(0), &damaged)
            .expect_err(label)
            .to_string();
        assert!(err.contains("selection"), "{label}: {err}");
        assert!(!err.contains('\n'), "{label}: {err}");
    }
    // A replayed selection is not one erosion reads, nor erosion's one a
    // replaying method's.
    let mut rigid = build(&params, MethodKind::LappedRigid);
    assert!(rigid.resample(&clip.ctx(0), &selection).is_err());
}
