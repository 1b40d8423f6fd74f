//! Tests that pin the erosion method's behaviour where it departs from
//! the 2021 paper without a parameter (the ledger's behaviour rows,
//! `crates/fluidtex/src/departures.rs`, name them): each checks the
//! row's number from both sides.

use glam::Vec3;

use super::fill::{LocateTolerance, TriFrame};

/// Ledger: "How far a patch triangle reaches". A point is located in a
/// patch triangle down to barycentric −0.05 and up to r/8 off its plane,
/// so a triangle covers a band past its edges: −0.04 covers, −0.06 does
/// not; r/8 − ε covers, r/8 + ε does not.
#[test]
fn a_patch_triangle_covers_to_barycentric_minus_0_05_and_r_over_8_off_its_plane() {
    let radius = 0.8;
    let tolerance = LocateTolerance::for_radius(radius);
    assert_eq!(tolerance.min_bary, -0.05);
    assert_eq!(tolerance.max_plane_distance, radius / 8.0);
    let frame = TriFrame::new(Vec3::ZERO, Vec3::X, Vec3::Y).expect("a triangle");
    let held = |x: Vec3| {
        let (bary, plane) = frame.locate(x);
        tolerance.holds(bary, plane)
    };
    // Past the edge x = 0 (barycentric of the corner at +X is x).
    assert!(held(Vec3::new(-0.04, 0.5, 0.0)));
    assert!(!held(Vec3::new(-0.06, 0.5, 0.0)));
    // Off the plane, inside the triangle.
    assert!(held(Vec3::new(0.2, 0.2, 0.1 - 1e-3)));
    assert!(!held(Vec3::new(0.2, 0.2, 0.1 + 1e-3)));
    assert!(held(Vec3::new(0.2, 0.2, -0.1 + 1e-3)));
}
