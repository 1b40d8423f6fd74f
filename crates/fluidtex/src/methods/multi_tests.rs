//! Several exemplars per surface, end to end through both lapped methods
//! (erosion and lapped-rigid): shares of the probability and histogram
//! strategies on the Enright scene, region maps (mesh attribute and image),
//! state round trips with exemplar ids, thread independence and input
//! errors.

use std::sync::Arc;

use glam::Vec3;

use super::registry::{MethodKind, MethodParams};
use super::{FrameResult, Method, MethodError};
use crate::exemplar::feature::{FeatureMap, FeatureOrigin};
use crate::exemplar::set::{EXEMPLAR_ID, RegionImage};
use crate::exemplar::{
    Exemplar, ExemplarError, ExemplarSelect, ExemplarSet, ExtraChannel, SampleFormat,
};
use crate::mesh::Attribute;
use crate::methods::test_clip::{Clip, scene};
use crate::named::Named;
use crate::texture::Texture;

/// A flat grey exemplar of `value` (size `size`², flat feature map).
fn flat(value: f32, size: u32) -> Exemplar {
    let n = (size * size) as usize;
    let colour = Texture::from_data(size, size, 1, vec![value; n]).expect("texture");
    let feature = FeatureMap::new(
        Texture::from_data(size, size, 1, vec![0.5; n]).expect("texture"),
        FeatureOrigin::Builtin,
        "flat",
    )
    .expect("feature");
    Exemplar::new(colour, SampleFormat::U8, Vec::new(), feature).expect("exemplar")
}

/// Black (exemplar 0) and white (exemplar 1) at 30 / 70 %; the two differ
/// in pixel size on purpose (uv is normalised).
fn black_white(select: ExemplarSelect) -> ExemplarSet {
    ExemplarSet::new(
        vec![
            ("black.png".into(), Arc::new(flat(0.0, 16)), 0.3),
            ("white.png".into(), Arc::new(flat(1.0, 8)), 0.7),
        ],
        select,
        None,
    )
    .expect("same channels")
}

fn build(kind: MethodKind, set: ExemplarSet, seed: u64) -> Box<dyn Method> {
    build_with(&MethodParams::default(), kind, set, seed)
}

fn build_with(
    params: &MethodParams,
    kind: MethodKind,
    set: ExemplarSet,
    seed: u64,
) -> Box<dyn Method> {
    params
        .build_set(kind, seed, || Ok::<_, MethodError>(set))
        .expect("builds")
}

/// Patches of half the default radius whatever the edge length: more of
/// them to check.
fn small_patches() -> MethodParams {
    let mut p = MethodParams::default();
    p.erosion.radius_fraction = 0.02;
    p.erosion.radius_edges = 0.0;
    p.lapped_rigid.radius_fraction = 0.02;
    p.lapped_rigid.radius_edges = 0.0;
    p
}

/// Share of covered texels showing exemplar 1 (white), per frame, from the
/// method's statistics, checked against the colour channel itself.
fn white_shares(results: &[FrameResult]) -> Vec<f64> {
    results
        .iter()
        .map(|r| {
            let texels: Vec<u64> = r.stats["exemplar_texels"]
                .as_array()
                .expect("exemplar_texels")
                .iter()
                .map(|v| v.as_u64().expect("count"))
                .collect();
            let total = (texels[0] + texels[1]) as f64;
            assert!(total > 0.0);
            // The colour agrees: a flat exemplar shows its own value
            // wherever it is the (heaviest) source.
            let source = r.source.as_ref().expect("source");
            let colour = &r.channels[0].data;
            let white = source
                .iter()
                .zip(colour)
                .filter(|(s, _)| **s != super::SOURCE_OUTSIDE && **s != super::SOURCE_UNCOVERED)
                .filter(|(_, c)| **c > 0.5)
                .count() as f64;
            let share = texels[1] as f64 / total;
            assert!(
                (white / total - share).abs() < 0.05,
                "colour says {} white, sources say {share}",
                white / total
            );
            share
        })
        .collect()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// The 30 / 70 test on the Enright scene, frames 0–24, seeds 1–4
/// (per-frame shares printed with `--nocapture`). Steering must hold the
/// mean share over the seeds within 3 points of the target, every seed
/// within 7 (measured: 0.708, 0.682, 0.709, 0.638 for erosion; old patches
/// stretch under the Enright flow and steering only chooses for new ones),
/// and keep every frame closer to it than the plain draw does on the same
/// seeds; the draw
/// must get the target on average over the seeds (within 6 points: with
/// some fifty to a hundred patches per frame and one seeded draw each, a
/// single seed can be 20 points off).
#[test]
fn enright_30_70_by_probability_and_by_histogram() {
    let clip = scene("enright", 24, 25, 128);
    let seeds = 1..=4u64;
    for kind in [MethodKind::Erosion, MethodKind::LappedRigid] {
        let mut summary = Vec::new();
        for select in [ExemplarSelect::Probability, ExemplarSelect::Histogram] {
            let (mut means, mut errors) = (Vec::new(), Vec::new());
            for seed in seeds.clone() {
                let mut m = build(kind, black_white(select), seed);
                let v = white_shares(&clip.run(m.as_mut()));
                let mae = v.iter().map(|x| (x - 0.7).abs()).sum::<f64>() / v.len() as f64;
                println!(
                    "{kind} {select:?} seed {seed}: white share {:.3} (mean abs error per frame \
                     {mae:.3}), per frame % {:?}",
                    mean(&v),
                    v.iter()
                        .map(|x| (x * 100.0).round() as i32)
                        .collect::<Vec<_>>()
                );
                means.push(mean(&v));
                errors.push(mae);
            }
            summary.push((means, mean(&errors)));
        }
        let (draw, draw_error) = &summary[0];
        let (steer, steer_error) = &summary[1];
        println!(
            "{kind}: probability {:.3} over the seeds (per-frame error {draw_error:.3}), \
             histogram {:.3} (per-frame error {steer_error:.3})",
            mean(draw),
            mean(steer)
        );
        assert!(
            (mean(draw) - 0.7).abs() < 0.06,
            "{kind}: the draw gives {draw:?}"
        );
        assert!(
            (mean(steer) - 0.7).abs() < 0.03,
            "{kind}: steering gives {steer:?}"
        );
        for s in steer {
            assert!((s - 0.7).abs() < 0.07, "{kind}: steering gives {steer:?}");
        }
        assert!(
            steer_error < draw_error,
            "{kind}: steering is off by {steer_error} per frame, the draw by {draw_error}"
        );
    }
}

/// The Enright sphere with `exemplar_id` 1 where x > 0.35 (its centre),
/// 0 elsewhere.
fn with_regions(mut clip: Clip) -> Clip {
    for m in &mut clip.meshes {
        let ids = m
            .positions
            .iter()
            .map(|p| if p.x > 0.35 { 1.0 } else { 0.0 })
            .collect();
        m.attributes
            .insert(EXEMPLAR_ID.into(), Attribute::Scalar(ids));
    }
    clip
}

/// Every first-frame patch away from the region border shows its region's
/// exemplar; `wrong` counts those that do not.
fn region_mismatches(method: &mut dyn Method, clip: &Clip, kind: MethodKind) -> (usize, usize) {
    method.step(&clip.ctx(0)).expect("step");
    let bytes = method.save_state().expect("state");
    let mut checked = 0;
    let mut wrong = 0;
    let mut look = |centre: Vec3, exemplar: u32, r: f32| {
        // Away from the border by more than an edge length and the
        // distance between a patch centre and its creation point.
        if (centre.x - 0.35).abs() > 2.0 * r {
            checked += 1;
            if exemplar != (centre.x > 0.35) as u32 {
                wrong += 1;
            }
        }
    };
    match kind {
        MethodKind::LappedRigid => {
            let mut m = super::lapped_rigid::LappedRigid::with_exemplars(
                Default::default(),
                Arc::new(black_white(ExemplarSelect::Region)),
                0,
            )
            .expect("params");
            m.load_state(&bytes).expect("round trip");
            let r = m.state().radius.expect("radius");
            for t in &m.state().trackers {
                look(t.position, t.exemplar, r);
            }
        }
        _ => {
            let mut m = super::erosion::Erosion::with_exemplars(
                super::erosion::EROSION,
                Default::default(),
                Arc::new(black_white(ExemplarSelect::Region)),
                0,
            )
            .expect("params");
            m.load_state(&bytes).expect("round trip");
            let r = m.state().radius.expect("radius");
            for p in &m.state().patches {
                let centre = super::erosion::exemplars::patch_centre(p).expect("vertices");
                look(centre, p.exemplar, r);
            }
        }
    }
    (checked, wrong)
}

#[test]
fn a_region_attribute_gives_each_region_its_exemplar() {
    let clip = with_regions(scene("enright", 32, 1, 96));
    for kind in [MethodKind::Erosion, MethodKind::LappedRigid] {
        let mut m = build_with(
            &small_patches(),
            kind,
            black_white(ExemplarSelect::Region),
            2,
        );
        let (checked, wrong) = region_mismatches(m.as_mut(), &clip, kind);
        assert!(checked > 10, "{kind}: only {checked} patches checked");
        assert_eq!(wrong, 0, "{kind}: {wrong} of {checked} in the wrong region");
        // Control: drawn by probability, the regions are ignored.
        let mut m = build_with(
            &small_patches(),
            kind,
            black_white(ExemplarSelect::Probability),
            2,
        );
        let (checked, wrong) = region_mismatches(m.as_mut(), &clip, kind);
        assert!(
            wrong > checked / 10,
            "{kind}: the control matched the regions"
        );
    }
}

#[test]
fn a_region_image_projects_from_above() {
    // Left half black (0), right half white (1), over the x-z extent of
    // the first frame: the sphere spans x in [0.2, 0.5] at frame 0, so the
    // border falls at its centre x = 0.35.
    let image = RegionImage::new(
        Texture::from_data(2, 1, 1, vec![0.0, 1.0]).expect("texture"),
        "regions.png".into(),
    );
    let mut set = black_white(ExemplarSelect::Region);
    set.region = Some(image);
    let clip = scene("enright", 32, 1, 96);
    for kind in [MethodKind::Erosion, MethodKind::LappedRigid] {
        let mut m = build_with(&small_patches(), kind, set.clone(), 2);
        let (checked, wrong) = region_mismatches(m.as_mut(), &clip, kind);
        assert!(
            checked > 10 && wrong == 0,
            "{kind}: {wrong} of {checked} wrong"
        );
    }
}

#[test]
fn region_selection_without_a_map_and_bad_ids_are_one_line_errors() {
    let clip = scene("enright", 16, 1, 64);
    let mut m = build(MethodKind::Erosion, black_white(ExemplarSelect::Region), 0);
    let err = m.step(&clip.ctx(0)).expect_err("no region source");
    assert!(err.to_string().contains("exemplar_id"), "{err}");
    let mut bad = with_regions(scene("enright", 16, 1, 64));
    if let Some(Attribute::Scalar(ids)) = bad.meshes[0].attributes.get_mut(EXEMPLAR_ID) {
        ids[7] = 2.0;
    }
    let bad = Clip::from_meshes(bad.meshes, 64);
    let mut m = build(
        MethodKind::LappedRigid,
        black_white(ExemplarSelect::Region),
        0,
    );
    let err = m
        .step(&bad.ctx(0))
        .expect_err("id 2 of 2 exemplars")
        .to_string();
    assert!(
        err.contains("frame 0") && err.contains("vertex 7") && !err.contains('\n'),
        "{err}"
    );
}

#[test]
fn state_round_trip_keeps_exemplar_ids() {
    let clip = scene("enright", 20, 4, 96);
    for kind in [MethodKind::Erosion, MethodKind::LappedRigid] {
        let mut a = build(kind, black_white(ExemplarSelect::Histogram), 9);
        for k in 0..3 {
            a.step(&clip.ctx(k)).expect("step");
        }
        let bytes = a.save_state().expect("save");
        let mut b = build(kind, black_white(ExemplarSelect::Histogram), 9);
        b.load_state(&bytes).expect("load");
        assert_eq!(b.save_state().expect("save"), bytes, "{kind}");
        let (ra, rb) = (
            a.step(&clip.ctx(3)).expect("step"),
            b.step(&clip.ctx(3)).expect("step"),
        );
        assert_eq!(ra.channels, rb.channels, "{kind}: resumed frame differs");
        assert_eq!(ra.source, rb.source, "{kind}");
        // A one-exemplar state cannot continue with two.
        let mut one = build(kind, ExemplarSet::single(Arc::new(flat(0.0, 8))), 9);
        one.step(&clip.ctx(0)).expect("step");
        let single = one.save_state().expect("save");
        let mut two = build(kind, black_white(ExemplarSelect::Histogram), 9);
        assert!(two.load_state(&single).is_err(), "{kind}");
    }
}

#[test]
fn one_and_two_threads_give_identical_frames() {
    let clip = scene("enright", 20, 3, 96);
    let go = |threads, kind, select| {
        clip.run_on_threads(threads, || build(kind, black_white(select), 4))
    };
    for kind in [MethodKind::Erosion, MethodKind::LappedRigid] {
        for select in [ExemplarSelect::Probability, ExemplarSelect::Histogram] {
            assert!(
                go(1, kind, select) == go(2, kind, select),
                "{kind} {select:?}"
            );
        }
    }
}

#[test]
fn exemplars_must_share_channels_and_feature_availability() {
    let mut with_disp = flat(0.5, 8);
    with_disp.channels.push(ExtraChannel {
        name: "displacement".into(),
        texture: Texture::from_data(8, 8, 1, vec![0.2; 64]).expect("texture"),
        format: SampleFormat::F32,
    });
    with_disp.repack().expect("valid");
    let err = ExemplarSet::new(
        vec![
            ("a.png".into(), Arc::new(flat(0.0, 8)), 1.0),
            ("b.png".into(), Arc::new(with_disp), 1.0),
        ],
        ExemplarSelect::Probability,
        None,
    )
    .expect_err("b has a displacement channel, a has none");
    let msg = err.to_string();
    assert!(
        msg.contains("a.png") && msg.contains("b.png") && msg.contains("displacement"),
        "{msg}"
    );
    assert!(!msg.contains('\n'));
    // A given feature map beside a derived one.
    let mut given = flat(1.0, 8);
    given.feature.origin = FeatureOrigin::Given("b_feature.png".into());
    let err = ExemplarSet::new(
        vec![
            ("a.png".into(), Arc::new(flat(0.0, 8)), 1.0),
            ("b.png".into(), Arc::new(given), 1.0),
        ],
        ExemplarSelect::Probability,
        None,
    )
    .expect_err("feature availability differs");
    assert!(matches!(err, ExemplarError::Mismatch { .. }), "{err}");
    // Weights must be positive.
    let err = ExemplarSet::new(
        vec![("a.png".into(), Arc::new(flat(0.0, 8)), 0.0)],
        ExemplarSelect::Probability,
        None,
    )
    .expect_err("zero weight");
    assert!(err.to_string().contains("a.png"), "{err}");
    // Control: different pixel sizes with the same channels are fine.
    assert!(
        ExemplarSet::new(
            vec![
                ("a.png".into(), Arc::new(flat(0.0, 8)), 1.0),
                ("b.png".into(), Arc::new(flat(1.0, 32)), 3.0),
            ],
            ExemplarSelect::Probability,
            None,
        )
        .is_ok_and(|s| s.weights() == [0.25, 0.75])
    );
}

#[test]
fn only_the_lapped_methods_take_several_exemplars() {
    for &kind in MethodKind::ALL {
        let built = MethodParams::default().build_set(kind, 0, || {
            Ok::<_, MethodError>(black_white(ExemplarSelect::Probability))
        });
        let several = matches!(
            kind,
            MethodKind::Erosion
                | MethodKind::Advect
                | MethodKind::BlendDeformable
                | MethodKind::LappedRigid
                | MethodKind::AtlasCheck
        );
        assert_eq!(built.is_ok(), several, "{kind}");
    }
}

#[test]
fn the_ply_reader_keeps_exemplar_id() {
    let text = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nproperty uchar exemplar_id\nelement face 1\nproperty list uchar int vertex_indices\n\
end_header\n0 0 0 0\n1 0 0 1\n0 1 0 1\n3 0 1 2\n";
    let m = crate::io::ply::parse_ply(
        std::path::Path::new("t.ply"),
        text,
        &crate::io::ReadOptions::default(),
    )
    .expect("parses");
    assert_eq!(
        m.attributes.get(EXEMPLAR_ID),
        Some(&Attribute::Scalar(vec![0.0, 1.0, 1.0]))
    );
}

#[test]
fn selections_with_several_exemplars_resample_exactly() {
    // The histogram strategy picks a new patch's exemplar from the
    // frame's composite, and each patch shows its own exemplar: the
    // selection carries the ids, and resampling alone picks the same.
    let clip = scene("enright", 16, 3, 128);
    for kind in [MethodKind::Erosion, MethodKind::LappedRigid] {
        let make = || build(kind, black_white(ExemplarSelect::Histogram), 5);
        let selections = super::selection_tests::round_trip_built(make, &clip);
        assert!(selections.iter().all(|s| !s.needs_previous()), "{kind:?}");
    }
}
