//! State-driven textures keep up with the state (the decisive-points
//! rule of `docs/evaluation.md`): a creeping blob whose temperature falls
//! with time and height, by [`COOLING`] of the range per frame, textured by
//! erosion with a cold exemplar (0..0.5) and a hot one (0.5..1). On every
//! frame the shown exemplar must match the temperature on at least 0.9 of
//! the *decisive* texels (at least 0.2 from the split); the known-bad
//! control is the constant mismatch rate of before (gain 0, rate 1), under
//! which a patch takes a whole second to go while the state moves 0.6
//! past the split.

use std::sync::Arc;

use glam::Vec3;

use super::registry::MethodKind;
use super::state_tests::build;
use super::test_clip::Clip;
use super::{FrameResult, SOURCE_OUTSIDE, SOURCE_UNCOVERED};
use crate::exemplar::lava::{LavaState, builtin_lava};
use crate::exemplar::set::{AttributeRange, SelectBy};
use crate::exemplar::{ExemplarSelect, ExemplarSet};
use crate::mesh::Attribute;
use crate::provenance::RENEWAL_STATE;

const FRAMES: usize = 40;
/// Temperature lost per frame, as a share of the ranges' span (0..1):
/// above the rule's 2 %.
const COOLING: f32 = 0.025;
/// The top is this much colder than the bottom: the split sweeps the
/// blob from top to bottom over 12 frames, not all at once.
const LAPSE: f32 = 0.3;
/// Creeping speed along +x, world units per second (the blob is 1 wide).
const CREEP: f32 = 0.05;
/// The rule.
const DECISIVE_FLOOR: f64 = 0.9;

/// The blob's temperature at relative height `h` (0 bottom, 1 top) on
/// frame `k`: `start` at the bottom on frame 0, clamped to the ranges.
fn temperature(h: f32, k: usize, start: f32, cooling: f32) -> f32 {
    (start - cooling * k as f32 - LAPSE * h).clamp(0.0, 1.0)
}

/// A flattened icosphere (1 wide, 0.6 high) creeping along +x at
/// [`CREEP`], `start` warm at the bottom on frame 0 and cooling by
/// `cooling` per frame. It only translates, so every frame uses frame 0's
/// atlas: a texel is the same material point on every frame, and sources
/// compare texel by texel.
fn cooling_blob(start: f32, cooling: f32) -> Clip {
    let rest = crate::atlas::fixtures::icosphere(8);
    let shape = |p: Vec3| Vec3::new(0.5 * p.x, 0.3 * p.y, 0.5 * p.z);
    let meshes = (0..FRAMES)
        .map(|k| {
            let shift = Vec3::X * CREEP * k as f32 / 24.0;
            let positions: Vec<Vec3> = rest.positions.iter().map(|&p| shape(p) + shift).collect();
            let t = (positions.iter())
                .map(|p| temperature((p.y + 0.3) / 0.6, k, start, cooling))
                .collect();
            let velocity = vec![Vec3::X * CREEP; positions.len()];
            let mut m = crate::mesh::TriMesh::new(positions, rest.triangles.clone())
                .with_velocity(velocity);
            m.attributes
                .insert("temperature".into(), Attribute::Scalar(t));
            m
        })
        .collect();
    let mut clip = Clip::from_meshes(meshes, 128);
    let first = clip.atlases[0].clone();
    clip.atlases.iter_mut().for_each(|a| *a = first.clone());
    clip
}

/// The built-in crust (0..0.5) and glow (0.5..1), chosen by temperature
/// with `rate` and `gain`. Their own feature maps matter: a glow patch
/// keeps its cracks until its weight is nearly 0, so the whole fall of the
/// weight is what the texture waits for (a flat feature map would let a
/// patch go at half weight).
fn crust_and_glow(rate: f32, gain: f32) -> ExemplarSet {
    let lava = |state| Arc::new(builtin_lava(state, 64, 1));
    let set = ExemplarSet::new(
        vec![
            ("crust".into(), lava(LavaState::Crust), 1.0),
            ("glow".into(), lava(LavaState::Glow), 1.0),
        ],
        ExemplarSelect::Probability,
        None,
    )
    .expect("same channels");
    let ranges = vec![
        AttributeRange::new(0.0, 0.5).expect("range"),
        AttributeRange::new(0.5, 1.0).expect("range"),
    ];
    let by = SelectBy::new("temperature", ranges)
        .with_mismatch_rate(rate)
        .and_then(|b| b.with_mismatch_gain(gain))
        .expect("valid");
    set.with_select_by(by).expect("two ranges")
}

/// Per frame: the agreement on decisive texels (1 where none is
/// covered), over all covered texels, and the share of texels covered
/// on both frames whose source the state forced to switch.
struct Run {
    decisive: Vec<f64>,
    all: Vec<f64>,
    state_switches: Vec<f64>,
}

impl Run {
    fn of(results: &[FrameResult]) -> Run {
        let stat = |r: &FrameResult, key: &str| r.stats.get(key).and_then(|v| v.as_f64());
        let covered = |s: u32| s != SOURCE_OUTSIDE && s != SOURCE_UNCOVERED;
        let mut state_switches = vec![0.0];
        for k in 1..results.len() {
            let before = results[k - 1].source.as_ref().expect("source");
            let after = results[k].source.as_ref().expect("source");
            let renewal = results[k].renewal.as_ref().expect("renewal");
            let (mut both, mut forced) = (0usize, 0usize);
            for ((&a, &b), &r) in before.iter().zip(after).zip(renewal) {
                if covered(a) && covered(b) {
                    both += 1;
                    forced += usize::from(a != b && r & RENEWAL_STATE != 0);
                }
            }
            state_switches.push(forced as f64 / both.max(1) as f64);
        }
        Run {
            decisive: (results.iter())
                .map(|r| stat(r, "state_agreement_decisive").unwrap_or(1.0))
                .collect(),
            all: (results.iter())
                .map(|r| stat(r, "state_agreement").expect("state_agreement"))
                .collect(),
            state_switches,
        }
    }

    fn worst_decisive(&self) -> (usize, f64) {
        (self.decisive.iter().copied().enumerate())
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .expect("frames")
    }

    fn print(&self, what: &str) {
        let pct = |v: &[f64]| {
            v.iter()
                .map(|x| (x * 100.0).round() as i32)
                .collect::<Vec<_>>()
        };
        println!("{what}: decisive agreement % {:?}", pct(&self.decisive));
        println!("{what}: agreement % {:?}", pct(&self.all));
        println!(
            "{what}: state-forced switches % {:?}",
            pct(&self.state_switches)
        );
    }
}

fn run(clip: &Clip, set: ExemplarSet) -> Run {
    let mut m = build(MethodKind::Erosion, set);
    Run::of(&clip.run(m.as_mut()))
}

#[test]
fn a_cooling_blob_keeps_its_decisive_points_in_agreement() {
    // The top crosses the split on frame 10 and is decisive from 18; the
    // bottom crosses on 22, decisive from 30.
    let clip = cooling_blob(1.05, COOLING);
    let defaults = SelectBy::new("temperature", Vec::new());
    let new = run(
        &clip,
        crust_and_glow(defaults.mismatch_rate, defaults.mismatch_gain),
    );
    new.print("defaults");
    let (frame, worst) = new.worst_decisive();
    assert!(
        worst >= DECISIVE_FLOOR,
        "defaults: decisive agreement {worst} at frame {frame}"
    );
    // The state did move the texture: the blob went from glow to crust.
    assert!(
        new.all[0] > 0.99 && new.all[FRAMES - 1] > 0.99,
        "{:?}",
        new.all
    );
    // Spread over frames: no frame switches more than a quarter of the
    // surface by the state, and the switches take at least 8 frames.
    let most = new.state_switches.iter().copied().fold(0.0, f64::max);
    let busy = new.state_switches.iter().filter(|&&s| s > 0.01).count();
    assert!(
        most < 0.25 && busy >= 8,
        "switches: at most {most} in a frame, {busy} frames over 1 %"
    );

    // The known-bad control: the constant rate of before lags by most of
    // a second and fails the rule.
    let old = run(&clip, crust_and_glow(1.0, 0.0));
    old.print("constant rate 1");
    let (frame, worst) = old.worst_decisive();
    assert!(
        worst < DECISIVE_FLOOR,
        "the control meets the rule ({worst} at frame {frame}): the test cannot fail"
    );
}

#[test]
fn a_slowly_cooling_blob_switches_over_many_frames() {
    // A quarter of the speed: the split takes 48 frames to sweep the
    // blob's height (the top crosses on frame 4, is decisive from 36), and
    // the texture follows with few switches a frame.
    let clip = cooling_blob(0.825, COOLING / 4.0);
    let new = run(&clip, crust_and_glow(1.0, 20.0));
    new.print("slow, defaults");
    let (frame, worst) = new.worst_decisive();
    assert!(worst >= DECISIVE_FLOOR, "{worst} at frame {frame}");
    let most = new.state_switches.iter().copied().fold(0.0, f64::max);
    assert!(most < 0.1, "{most} of the surface in one frame");
}
