//! Tests that pin `lapped-rigid`'s behaviour where it departs from the
//! 2016 paper without a parameter (the ledger's behaviour rows,
//! `crates/fluidtex/src/departures.rs`, name them): each checks the
//! row's number or rule from both sides.

use std::sync::Arc;

use glam::Vec3;

use super::distribution::{Placement, SinkRule, apply_sink};
use super::trackers::Tracker;
use super::*;
use crate::exemplar::builtin_pebbles;
use crate::methods::test_clip::{Clip, grid};
use crate::surface::SurfaceIndex;

fn tracker_at(id: u32, p: Vec3, radius: f32) -> Tracker {
    Tracker {
        id,
        position: p,
        tangent_tracker: p + Vec3::X * (0.5 * radius),
        normal: Vec3::Z,
        fade: 1.0,
        sinking: false,
        exemplar: 0,
    }
}

/// Ledger: "Where new trackers go, and when they are composited". Each
/// new tracker is composited before the next seed is drawn, so no seed
/// falls where an earlier new patch of the frame is opaque: the new
/// trackers of a frame lie at least r/2 apart (a hard mask, opaque out to
/// the patch's footprint), under either placement. A batch drawn over the
/// uncovered area at once, as the paper distributes them, has no such
/// bound.
#[test]
fn new_trackers_are_placed_and_composited_one_at_a_time() {
    let radius = 0.3;
    let mesh = grid(32, 0.0625, |_| Vec3::ZERO);
    let clip = Clip::from_meshes(vec![mesh.clone(), mesh], 128);
    for placement in [Placement::First, Placement::Random] {
        let params = LappedRigidParams {
            radius: Some(radius),
            mask_feature_weight: 0.0,
            mask_softness: 0.0,
            placement,
            ..Default::default()
        };
        let mut m = LappedRigid::new(params, Arc::new(builtin_pebbles(64, 1)), 3).expect("params");
        // One old tracker; the rest of the 2 × 2 plane is uncovered.
        m.set_state(LappedRigidState {
            trackers: vec![tracker_at(0, Vec3::new(-0.7, 0.0, 0.0), radius)],
            next_id: 1,
            radius: Some(radius),
            exemplar_size: Some(2.6 * radius),
        });
        let r = m.step(&clip.ctx(1)).expect("step");
        assert_eq!(r.stats["uncovered_texels"], 0);
        let new: Vec<Vec3> = (m.state().trackers.iter())
            .filter(|t| t.id >= 1)
            .map(|t| t.position)
            .collect();
        assert!(new.len() >= 4, "{placement:?}: {} new trackers", new.len());
        let mut closest = f32::INFINITY;
        for (j, b) in new.iter().enumerate() {
            for a in &new[..j] {
                closest = closest.min(a.distance(*b));
            }
        }
        assert!(
            closest > 0.5 * radius,
            "{placement:?}: two new trackers {closest} apart"
        );
    }
}

/// Ledger: "The tangent tracker and the sink test's corners". T sits r/2
/// along the tangent, and the sink test samples the flow at the frame's
/// corners P + (r/2)(±t ± b), r/√2 from P.
#[test]
fn the_tangent_tracker_is_at_half_r_and_the_sink_corners_at_r_over_sqrt2() {
    let radius = 0.8;
    let mut t = tracker_at(0, Vec3::new(0.1, 0.2, 0.0), radius);
    t.rebuild(
        t.position,
        t.position + Vec3::new(0.3, 0.3, 0.0),
        Vec3::Z,
        radius,
    );
    assert!((t.tangent_tracker.distance(t.position) - 0.4).abs() < 1e-6);
    let corners = t.corners(radius);
    for c in corners {
        let d = c.distance(t.position);
        assert!(
            (d - radius * std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-6,
            "{d}"
        );
    }
    // The four are distinct: a square around P.
    assert!(corners[0].distance(corners[2]) > 1.5 * radius * 0.7);
}

/// Ledger: "A sink stays a sink". Once every corner moves inward faster
/// than `sink_speed` × r (r/4 per second), the tracker is marked, and
/// stays marked when the flow diverges or stops (its fade then holds);
/// just below the speed it is never marked.
#[test]
fn a_sink_stays_marked_when_the_flow_stops_converging() {
    let radius = 0.5;
    let rule = SinkRule {
        radius,
        min_speed: 0.25 * radius,
        fade_rate: 1.0,
        dt: 1.0 / 24.0,
    };
    // v = −k p: a corner r/√2 from the centre moves inward at k r/√2, so
    // the threshold r/4 is crossed at k = √2/4 ≈ 0.354.
    let step = |t: &mut Tracker, k: f32| {
        let mesh = grid(8, 0.25, move |p| -p * k);
        let index = SurfaceIndex::new(&mesh);
        let flow = FlowFrame {
            mesh: &mesh,
            index: &index,
            velocity: mesh.velocity().expect("velocity"),
        };
        apply_sink(t, &flow, &rule)
    };
    let mut below = tracker_at(0, Vec3::ZERO, radius);
    assert!(!step(&mut below, 0.35));
    assert_eq!(below.fade, 1.0);
    let mut t = tracker_at(0, Vec3::ZERO, radius);
    assert!(step(&mut t, 0.36));
    let faded = t.fade;
    assert!(faded < 1.0);
    // Diverging flow: still a sink, the fade holds.
    assert!(step(&mut t, -1.0));
    assert_eq!(t.fade, faded);
    // No flow: still a sink, the fade holds.
    assert!(step(&mut t, 0.0));
    assert_eq!(t.fade, faded);
    assert!(t.sinking);
}
