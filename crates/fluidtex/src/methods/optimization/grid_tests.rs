//! The narrow-band grid transport ([`super::grid`]) against flows whose
//! answer is known exactly.

use glam::Vec3;
use rand::{Rng, SeedableRng};

use super::grid::{self, Band};
use super::lattice::Lattice;
use super::tests::{assert_moved_one_step_left, plane};
use super::transport::Previous;
use crate::surface::SurfaceIndex;
use crate::surface::velocity::FlowFrame;

fn frame<'a>(mesh: &'a crate::mesh::TriMesh, index: &'a SurfaceIndex) -> FlowFrame<'a> {
    FlowFrame {
        mesh,
        index,
        velocity: mesh.velocity().unwrap_or(&[]),
    }
}

/// The previous frame over `mesh`: `lattice` points with `values` (one
/// channel) and `orientation`.
fn previous<'a>(
    mesh: &'a crate::mesh::TriMesh,
    index: &'a SurfaceIndex,
    lattice: &'a Lattice,
    values: &'a [f32],
    orientation: &'a [Vec3],
) -> Previous<'a> {
    Previous {
        mesh,
        index,
        lattice,
        values,
        channels: 1,
        orientation,
    }
}

#[test]
fn a_band_holds_the_points_cells_dilated_by_its_width() {
    let p = [Vec3::new(0.25, 0.25, 0.25)];
    // The point's cell: its 8 corners; two layers of 26-neighbours around
    // them make a cube 2 + 2·2 nodes wide.
    assert_eq!(Band::around(&p, 1.0, 0).len(), 8);
    assert_eq!(Band::around(&p, 1.0, 2).len(), 6 * 6 * 6);
    // Two points far apart: two separate cubes, nothing between them.
    let two = [p[0], p[0] + Vec3::new(100.0, 0.0, 0.0)];
    assert_eq!(Band::around(&two, 1.0, 1).len(), 2 * 4 * 4 * 4);
}

#[test]
fn interpolation_reproduces_a_linear_field_inside_the_band() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
    let points: Vec<Vec3> = (0..40)
        .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()) * 2.0)
        .collect();
    let band = Band::around(&points, 0.1, 1);
    let field: Vec<Vec3> = (0..band.len())
        .map(|i| {
            let x = band.position(i);
            Vec3::new(2.0 * x.x - x.y, x.z + 1.0, 0.5 * x.x)
        })
        .collect();
    for &p in &points {
        let got = band.interpolate(&field, p).expect("inside the band");
        let want = Vec3::new(2.0 * p.x - p.y, p.z + 1.0, 0.5 * p.x);
        assert!((got - want).length() < 1e-4, "{got} vs {want} at {p}");
    }
    // Control: far outside the band there is nothing to interpolate.
    assert!(band.interpolate(&field, Vec3::splat(50.0)).is_none());
}

#[test]
fn grid_colour_transport_moves_the_texture_by_the_translation() {
    // As the back-tracking test: a translation by exactly one point
    // spacing along x in one frame. The upwind scheme moves the linear
    // coordinate field exactly (two half-cell steps), so every new point
    // whose source is inside the square takes the value one step left.
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
    let previous = previous(&mesh, &index, &lattice, &values, &orientation);
    let f = frame(&mesh, &index);
    let (moved, missing, _, stats) = grid::transport(
        &lattice.positions,
        &[],
        &[],
        &f,
        &f,
        dt,
        step,
        0.5,
        &previous,
    );
    assert_eq!(missing, 0);
    assert_eq!(stats.steps, 2, "CFL 0.5 over one cell");
    assert_eq!(stats.cells, 3, "one cell of reach and two of margin");
    assert!(!stats.capped);
    assert_moved_one_step_left(&lattice, &values, &moved, step);
}

#[test]
fn grid_orientation_turns_with_a_rigid_rotation() {
    // Rigid rotation about z, ω = 1 rad/s, dt = 0.3: Eq. 4's stretching
    // term turns a uniform field by 0.3 rad; its advection term alone
    // (the scalar advection of the components) would leave it at 0.
    let omega = 1.0f32;
    let dt = 0.3f32;
    let mesh = plane(16, 2.0, |p| Vec3::new(-omega * p.y, omega * p.x, 0.0));
    let index = SurfaceIndex::new(&mesh);
    let lattice = Lattice::new(&mesh, 2);
    let orientation = vec![Vec3::X; lattice.len()];
    let values = vec![0.0f32; lattice.len()];
    let previous = previous(&mesh, &index, &lattice, &values, &orientation);
    let f = frame(&mesh, &index);
    let h = 4.0 / 32.0;
    let (_, _, turned, stats) = grid::transport(
        &lattice.positions,
        &lattice.positions,
        &lattice.normals,
        &f,
        &f,
        dt,
        h,
        0.5,
        &previous,
    );
    assert!(stats.steps > 1);
    let want = Vec3::new(dt.cos(), dt.sin(), 0.0);
    let mut checked = 0;
    for (d, p) in turned.iter().zip(&lattice.positions) {
        if p.length() < 1.0 {
            assert!(d.angle_between(want) < 2e-3, "{d} vs {want} at {p}");
            checked += 1;
        }
    }
    assert!(checked > 50, "{checked}");
    // Control: the unturned field is 0.3 rad off.
    assert!((Vec3::X.angle_between(want) - dt).abs() < 1e-5);
}

#[test]
fn steps_keep_the_courant_number_at_one_half() {
    assert_eq!(grid::steps_for(1.0, 1.0, 1.0), 2);
    assert_eq!(grid::steps_for(0.0, 1.0, 1.0), 1);
    assert_eq!(grid::steps_for(10.0, 0.1, 0.1), 20);
    assert_eq!(grid::steps_for(f32::INFINITY, 1.0, 1.0), grid::MAX_STEPS);
    assert_eq!(grid::steps_for(1e9, 1.0, 1.0), grid::MAX_STEPS);
}
