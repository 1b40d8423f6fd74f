//! Animated exemplars end to end: which exemplar frame each patch shows
//! (its phase and the rate), a fluid at rest that keeps its sources while
//! its texture animates, pyramids built only for the frames shown,
//! resumed runs and thread counts, for every method that samples an
//! exemplar.

use std::sync::Arc;

use glam::Vec3;

use super::registry::{MethodKind, MethodParams};
use super::{FrameResult, Method, MethodError};
use crate::exemplar::{
    Exemplar, ExemplarClock, ExemplarSelect, ExemplarSet, FeatureMap, FeatureOrigin,
};
use crate::methods::test_clip::{Clip, grey_exemplar, grid, scene};
use crate::methods::tone::Tone;
use crate::provenance::{SOURCE_OUTSIDE, SOURCE_UNCOVERED};
use crate::texture::Texture;

/// Grey levels of the frames of the test sequence: each frame is flat, so
/// a texel's value says which frame its patch shows.
const LEVELS: [f32; 4] = [0.1, 0.35, 0.6, 0.85];

/// One flat frame per level, each with its own feature map (so patch
/// outlines would move at rest if the erosion read the frame shown).
fn frames(levels: &[f32]) -> Vec<Arc<Exemplar>> {
    levels
        .iter()
        .enumerate()
        .map(|(k, &v)| {
            let e = grey_exemplar(16, move |_, _| v);
            let feature = Texture::from_data(
                16,
                16,
                1,
                (0..256u32)
                    .map(|i| ((i % 16) * 3 + (i / 16) * 5 + k as u32 * 7) % 16)
                    .map(|f| f as f32 / 15.0)
                    .collect(),
            )
            .expect("feature texture");
            let feature = FeatureMap::new(feature, FeatureOrigin::Builtin, "frame").expect("map");
            let e = Exemplar::new(e.colour, e.colour_format, Vec::new(), feature).expect("frame");
            Arc::new(e.deferring_pyramid())
        })
        .collect()
}

/// One animated entry of `frames`, at the default rate.
fn animated_of(frames: Vec<Arc<Exemplar>>) -> ExemplarSet {
    ExemplarSet::animated(
        vec![("grey.####.png".into(), frames, 1.0)],
        ExemplarSelect::Probability,
        None,
    )
    .expect("one layout")
}

fn animated(levels: &[f32], rate: f32) -> ExemplarSet {
    animated_of(frames(levels)).with_clock(ExemplarClock::new(rate).expect("rate"))
}

fn build(params: &MethodParams, kind: MethodKind, set: ExemplarSet, seed: u64) -> Box<dyn Method> {
    params
        .build_set(kind, seed, || Ok::<_, MethodError>(set))
        .expect("builds")
}

/// A 24×24 plane at rest for `frames` frames.
fn plane_at_rest(frames: usize) -> Clip {
    let meshes = (0..frames)
        .map(|_| grid(24, 1.0 / 24.0, |_| Vec3::ZERO))
        .collect();
    Clip::from_meshes(meshes, 96)
}

/// Every covered texel of `r` (frame `t`, one source per texel) shows the
/// level of exemplar frame ⌊t·rate + φ⌋ mod n of its patch; returns how
/// many texels were checked.
fn check_frames_per_patch(r: &FrameResult, t: i32, rate: f32, seed: u64) -> usize {
    let clock = ExemplarClock::new(rate).expect("rate");
    let n = LEVELS.len() as u32;
    let source = r.source.as_ref().expect("sources");
    let colour = &r.channels[0];
    let mut checked = 0;
    for (i, &s) in source.iter().enumerate() {
        if s == SOURCE_OUTSIDE || s == SOURCE_UNCOVERED || s == 0 {
            continue;
        }
        let id = u64::from(s - 1);
        let k = clock.frame(t, ExemplarClock::phase(seed, id, n), n);
        let want = LEVELS[k as usize];
        let got = colour.data[i];
        assert!(
            (got - want).abs() < 1e-4,
            "frame {t}, texel {i}, patch {id}: {got}, expected frame {k} ({want})"
        );
        checked += 1;
    }
    checked
}

#[test]
fn each_patch_shows_the_frame_of_its_phase_and_the_rate() {
    let clip = scene("enright", 16, 4, 64);
    let mut params = MethodParams::default();
    // Tone matching would pull each frame's texels toward a common mean:
    // here every texel must read its frame's level exactly.
    params.erosion.tone = Tone::Off;
    for rate in [1.0, 0.5, -1.0, 2.5] {
        for kind in [MethodKind::Erosion, MethodKind::Advect] {
            let mut m = build(&params, kind, animated(&LEVELS, rate), 7);
            let results = clip.run(m.as_mut());
            for (t, r) in results.iter().enumerate() {
                let checked = check_frames_per_patch(r, t as i32, rate, 7);
                assert!(checked > 1000, "{kind} rate {rate}: only {checked} texels");
            }
            // Patches are out of step: a frame shows several levels.
            let colour = &results[1].channels[0].data;
            let shown = LEVELS
                .iter()
                .filter(|&&l| colour.iter().any(|&v| (v - l).abs() < 1e-4))
                .count();
            assert!(shown >= 3, "{kind} rate {rate}: {shown} levels shown");
        }
    }
}

#[test]
fn a_fluid_at_rest_keeps_its_sources_while_the_texture_animates() {
    let clip = plane_at_rest(5);
    for kind in [
        MethodKind::Erosion,
        MethodKind::Advect,
        MethodKind::BlendDeformable,
        MethodKind::LappedRigid,
        MethodKind::DualRest,
    ] {
        let mut m = build(&MethodParams::default(), kind, animated(&LEVELS, 1.0), 3);
        let results = clip.run(m.as_mut());
        for k in 2..results.len() {
            let (a, b) = (&results[k - 1], &results[k]);
            assert_eq!(a.source, b.source, "{kind}: frame {k} moved its sources");
            let bits = |r: &FrameResult| {
                (r.uv.as_ref().expect("uv").iter())
                    .map(|p| (p.x.to_bits(), p.y.to_bits()))
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(a), bits(b), "{kind}: frame {k} moved its uv");
            assert_ne!(
                a.channels[0].data, b.channels[0].data,
                "{kind}: frame {k} did not animate"
            );
        }
        // A still exemplar holds the texture bit-identical (dual-rest
        // cross-fades its two layers whatever the exemplar).
        if kind == MethodKind::DualRest {
            continue;
        }
        let still = ExemplarSet::single(Arc::new(grey_exemplar(16, |x, y| {
            ((x * 7 + y * 3) % 16) as f32 / 16.0
        })));
        let mut m = build(&MethodParams::default(), kind, still, 3);
        let results = clip.run(m.as_mut());
        assert_eq!(
            results[3].channels, results[4].channels,
            "{kind}: a still exemplar at rest changed"
        );
    }
}

#[test]
fn pyramids_are_built_for_the_frames_shown_only() {
    // Large patches on a small plane: far fewer patches than frames.
    let clip = plane_at_rest(2);
    let levels: Vec<f32> = (0..64).map(|k| k as f32 / 64.0).collect();
    let shown = frames(&levels);
    let set = animated_of(shown.clone());
    let per_frame = shown[0].pyramid_bytes();
    assert!(per_frame > 0);
    assert!(shown.iter().all(|e| !e.pyramid_built()), "built before use");
    // The defaults (mean tone matching reads no pyramid).
    let mut params = MethodParams::default();
    params.erosion.radius_fraction = 0.3;
    params.erosion.radius_edges = 0.0;
    let mut m = build(&params, MethodKind::Erosion, set, 5);
    let results = clip.run(m.as_mut());
    let built = shown.iter().filter(|e| e.pyramid_built()).count();
    // Exactly the frames some patch showed, read off the atlas.
    let mut seen: Vec<u32> = Vec::new();
    for (t, r) in results.iter().enumerate() {
        for &s in r.source.as_ref().expect("sources") {
            if s != SOURCE_OUTSIDE && s != SOURCE_UNCOVERED && s > 0 {
                let phase = ExemplarClock::phase(5, u64::from(s - 1), 64);
                seen.push(ExemplarClock::default().frame(t as i32, phase, 64));
            }
        }
    }
    seen.sort_unstable();
    seen.dedup();
    assert!(
        !seen.is_empty() && seen.len() < 64,
        "{} frames shown",
        seen.len()
    );
    assert!(built >= seen.len(), "{built} built, {} shown", seen.len());
    for &k in &seen {
        assert!(
            shown[k as usize].pyramid_built(),
            "frame {k} shown, not built"
        );
    }
    assert!(
        built < 64,
        "every pyramid was built for {} frames shown",
        seen.len()
    );
    // The control: contrast matching measures every frame at every level,
    // so it builds all 64 pyramids on its first frame.
    let all = frames(&levels);
    let set = animated_of(all.clone());
    params.erosion.tone = Tone::Match;
    let mut m = build(&params, MethodKind::Erosion, set, 5);
    m.step(&clip.ctx(0)).expect("step");
    assert!(all.iter().all(|e| e.pyramid_built()));
}

#[test]
fn one_and_two_threads_and_a_resume_give_identical_frames() {
    let clip = scene("enright", 16, 4, 64);
    let kinds = [MethodKind::Erosion, MethodKind::LappedRigid];
    let go = |threads, kind| {
        clip.run_on_threads(threads, || {
            build(&MethodParams::default(), kind, animated(&LEVELS, 1.0), 4)
        })
    };
    for kind in kinds {
        let one = go(1, kind);
        assert!(
            one == go(2, kind),
            "{kind}: thread count changed the frames"
        );
        let one = one.0;
        // Resumed after frame 1: no phase is saved, yet the same frames.
        let mut a = build(&MethodParams::default(), kind, animated(&LEVELS, 1.0), 4);
        for k in 0..2 {
            a.step(&clip.ctx(k)).expect("step");
        }
        let bytes = a.save_state().expect("save");
        let mut b = build(&MethodParams::default(), kind, animated(&LEVELS, 1.0), 4);
        b.load_state(&bytes).expect("load");
        for (k, frame) in one.iter().enumerate().skip(2) {
            let r = b.step(&clip.ctx(k)).expect("step");
            assert!(
                (&r.channels, &r.source) == (&frame.0, &frame.1),
                "{kind}: resumed frame {k} differs"
            );
        }
    }
}

#[test]
fn optimization_synthesises_each_frame_from_the_frame_shown() {
    let clip = plane_at_rest(3);
    let mut params = MethodParams::default();
    params.optimization.points = 3000;
    params.optimization.levels = 1;
    params.optimization.sizes = vec![9];
    params.optimization.passes_after_first = 1;
    let levels = [0.2, 0.8];
    let mut m = build(&params, MethodKind::Optimization, animated(&levels, 1.0), 2);
    let results = clip.run(m.as_mut());
    // Texels outside the charts read 0; both levels are well above it.
    let mean = |r: &FrameResult| {
        let covered: Vec<f32> = (r.channels[0].data.iter())
            .copied()
            .filter(|&v| v > 0.05)
            .collect();
        assert!(covered.len() > 1000, "{} texels covered", covered.len());
        covered.iter().sum::<f32>() / covered.len() as f32
    };
    // The whole surface shows frame t mod 2, even at rest.
    for (t, r) in results.iter().enumerate() {
        let want = levels[t % 2];
        assert!(
            (mean(r) - want).abs() < 0.02,
            "frame {t}: mean {} instead of {want}",
            mean(r)
        );
    }
}
