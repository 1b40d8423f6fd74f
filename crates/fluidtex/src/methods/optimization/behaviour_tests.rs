//! Tests that pin the 2007 method's behaviour where it departs from the
//! paper without a parameter (the ledger's behaviour rows,
//! `crates/fluidtex/src/departures.rs`, name them): each checks the
//! row's number or rule from both sides, so a change of behaviour fails
//! here and the row must be revisited.

use std::sync::Arc;

use glam::{Vec2, Vec3};

use super::lattice::{Lattice, Level};
use super::neighbourhood::{self, CellSample, FACING_DOT, Scratch, Window};
use super::search::WorkingExemplar;
use super::*;
use crate::atlas::{Atlas, AtlasParams};
use crate::exemplar::pebbles::builtin_pebbles;
use crate::methods::test_clip::{Clip, grid};

fn pebbles() -> Arc<Exemplar> {
    Arc::new(builtin_pebbles(64, 3))
}

/// The finest level of a flat grid of n × n cells of side `cell`.
fn flat_level(n: usize, cell: f32) -> Level {
    let mesh = grid(n, cell, |_| Vec3::ZERO);
    Lattice::new(&mesh, 1).level(1)
}

/// The level vertex nearest to `p`.
fn vertex_at(level: &Level, p: Vec3) -> u32 {
    let mut best = (0u32, f32::INFINITY);
    for (i, q) in level.positions.iter().enumerate() {
        let d = q.distance(p);
        if d < best.1 {
            best = (i as u32, d);
        }
    }
    best.0
}

/// Builds the neighbourhood of `centre` with frame d = +X: (members, cells).
fn neighbourhood_of(
    level: &Level,
    centre: u32,
    window: Window,
) -> (Vec<(u32, Vec2)>, Vec<CellSample>) {
    let mut scratch = Scratch::new(level);
    let mut members = Vec::new();
    let side = window.grid as usize;
    let mut cells = vec![CellSample::UNCOVERED; side * side];
    neighbourhood::build(
        level,
        centre,
        Vec3::X,
        window,
        &mut scratch,
        &mut members,
        &mut cells,
    );
    (members, cells)
}

/// Ledger: "Transporting the orientation". Only the coarsest level's
/// points are carried, with a vector a quarter of that level's spacing: h
/// at the default three levels (4 h apart), h/4 with one level.
#[test]
fn the_orientation_is_carried_on_the_coarsest_level_only() {
    let h = 0.1;
    assert_eq!(orientation_carry(h, 3), (2, 0.1));
    assert_eq!(orientation_carry(h, 2), (1, 0.05));
    assert_eq!(orientation_carry(h, 1), (0, 0.025));
    // The default hierarchy has three levels, so the finest two get only
    // what is copied up from the coarsest and re-smoothed.
    assert_eq!(OptimizationParams::default().levels, 3);
}

/// Ledger: "The hierarchy on later frames". Footnote 5 (one level after
/// the first frame) holds for synthesis only: every frame builds all
/// `levels`.
#[test]
fn the_whole_hierarchy_is_built_on_every_frame() {
    let defaults = OptimizationParams::default();
    assert_eq!(level_counts(&defaults, false), (3, 3));
    assert_eq!(level_counts(&defaults, true), (3, 1));
    // Scattered points are also drawn and re-tiled at every level.
    let m = Optimization::new(defaults, pebbles(), 1).expect("params");
    assert_eq!(m.point_levels(), 3);
    // Control: with `levels = 1` one level is built.
    let one = OptimizationParams {
        levels: 1,
        ..OptimizationParams::default()
    };
    assert_eq!(level_counts(&one, true), (1, 1));
}

/// Ledger: "Reading a pixel neighbourhood". Each cell reads the flattened
/// triangle that holds its offset: on a plane the interpolated corner
/// positions are exactly the cell's offset in the frame (d, d × n), and
/// an offset past the surface's edge is covered by no triangle.
#[test]
fn pixel_cells_are_read_from_the_flattened_triangles() {
    // 2 × 2 plane, cells of 0.25; the centre at x = 0.5 leaves 2 texels of
    // surface on its +x side.
    let level = flat_level(8, 0.25);
    let centre = vertex_at(&level, Vec3::new(0.5, 0.0, 0.0));
    let window = Window {
        width: 9,
        grid: 9,
        texel: 0.25,
        relaxation: 0,
    };
    let (_, cells) = neighbourhood_of(&level, centre, window);
    let c = level.positions[centre as usize];
    let (e1, e2) = (Vec3::X, Vec3::X.cross(Vec3::Z));
    let (mut covered, mut uncovered) = (0, 0);
    for (k, cell) in cells.iter().enumerate() {
        let (x, y) = ((k % 9) as f32 - 4.0, (k / 9) as f32 - 4.0);
        let want = c + (e1 * x + e2 * y) * 0.25;
        if want.x > 1.0 + 1e-4 {
            assert!(!cell.covered(), "offset ({x}, {y}) lies off the surface");
            uncovered += 1;
            continue;
        }
        assert!(cell.covered(), "offset ({x}, {y}) lies on the surface");
        let mut got = Vec3::ZERO;
        for (&v, &w) in cell.corners.iter().zip(&cell.weights) {
            got += level.positions[v as usize] * w;
        }
        assert!(got.distance(want) < 1e-4, "({x}, {y}): {got} vs {want}");
        covered += 1;
    }
    assert_eq!((covered, uncovered), (63, 18));
}

/// Ledger: "Offsets no triangle covers". They take the mean of the covered
/// ones (or of the members' values when none is covered), not a value read
/// farther along the surface.
#[test]
fn uncovered_offsets_take_the_mean_of_the_covered_ones() {
    let colours = [0.2f32, 0.6, 1.0];
    let at = |v: u32| CellSample {
        corners: [v, v, v],
        weights: [1.0, 0.0, 0.0],
    };
    let cells = [at(0), CellSample::UNCOVERED, at(1)];
    let members = [(2u32, Vec2::ZERO)];
    let mut vector = [0.0f32; 3];
    let mut mean = [0.0f32; 1];
    neighbourhood::fill_query(&cells, &members, &colours, 1, 1, &mut vector, &mut mean);
    assert_eq!(vector, [0.2, 0.4, 0.6]);
    // No covered cell: the members' mean (here their one value, 1.0).
    let none = [CellSample::UNCOVERED; 3];
    neighbourhood::fill_query(&none, &members, &colours, 1, 1, &mut vector, &mut mean);
    assert_eq!(vector, [1.0, 1.0, 1.0]);
}

/// Ledger: "Points facing away from a neighbourhood's centre". A point
/// whose normal makes a dot product below 0.2 with the centre's is left
/// out: at 0.19 it is, at 0.21 it is not.
#[test]
fn points_facing_away_below_dot_0_2_are_dropped() {
    assert_eq!(FACING_DOT, 0.2);
    let members_with = |dot: f32| {
        let mut level = flat_level(8, 0.25);
        let centre = vertex_at(&level, Vec3::ZERO);
        let v = vertex_at(&level, Vec3::new(0.25, 0.0, 0.0));
        level.normals[v as usize] = Vec3::new((1.0 - dot * dot).sqrt(), 0.0, dot);
        let window = Window {
            width: 9,
            grid: 9,
            texel: 0.25,
            relaxation: 0,
        };
        let (members, _) = neighbourhood_of(&level, centre, window);
        members.iter().any(|&(m, _)| m == v)
    };
    assert!(!members_with(0.19));
    assert!(members_with(0.21));
}

/// Ledger: "Exemplar windows at the edges". Windows never exceed the
/// working exemplar (33 → 31 at the 32-texel coarsest level of the
/// default hierarchy), and every texel is a candidate centre, its window
/// wrapping across the exemplar's edges.
#[test]
fn windows_shrink_to_fit_and_candidates_wrap_at_the_edges() {
    let d = OptimizationParams::default();
    let coarsest = (d.exemplar_texels >> (d.levels - 1)).max(8);
    assert_eq!(coarsest, 32);
    assert_eq!(window_width(33, coarsest, coarsest), 31);
    assert_eq!(window_width(33, 33, 33), 33);
    assert_eq!(window_width(17, coarsest, coarsest), 17);
    let ex = WorkingExemplar::new(&pebbles(), 32);
    assert_eq!(ex.candidates(), 32 * 32);
    assert_eq!(ex.position(31), (31, 0));
    assert_eq!(ex.texel(-1, 3), ex.texel(31, 3));
    assert_eq!(ex.texel(5, 32), ex.texel(5, 0));
    // Control: neighbouring texels differ, so the wrap is not trivially true.
    assert_ne!(ex.texel(30, 3), ex.texel(31, 3));
}

/// Ledger: "Points per atlas texel". The spacing is never below one atlas
/// texel: just above the point count that one texel allows, the atlas sets
/// the spacing; just below it, the count does.
#[test]
fn the_spacing_is_never_below_one_atlas_texel() {
    let mesh = grid(4, 0.5, |_| Vec3::ZERO);
    let atlas = Atlas::build(&mesh, &AtlasParams::square(64)).expect("atlas");
    let texel = (1.0 / atlas.scale) as f32;
    // The count whose spacing is one texel: h² = 2A / (√3 n).
    let at_texel = mesh.area() as f32 * 2.0 / (3f32.sqrt() * texel * texel);
    let spacing = |points: f32| {
        let params = OptimizationParams {
            points: points as u32,
            ..OptimizationParams::default()
        };
        let mut m = Optimization::new(params, pebbles(), 1).expect("params");
        let (h, rule) = m.spacing(&mesh, &atlas);
        (h, rule.expect("first frame"))
    };
    let (h, rule) = spacing(at_texel * 1.05);
    assert_eq!((h, rule), (texel, "atlas texel"));
    let (h, rule) = spacing(200_000.0);
    assert_eq!((h, rule), (texel, "atlas texel"));
    let (h, rule) = spacing(at_texel * 0.95);
    assert_eq!(rule, "points");
    assert!(h > texel);
}

/// Ledger: "A frame without motion". Same mesh and zero velocity: no
/// synthesis (the stats say `still`), the previous texture bit for bit; a
/// moving frame is synthesised and changes.
#[test]
fn a_frame_without_motion_skips_synthesis() {
    let params = OptimizationParams {
        points: 2000,
        exemplar_texels: 32,
        sizes: vec![9, 5],
        levels: 2,
        iterations: 2,
        ..OptimizationParams::default()
    };
    let run = |speed: f32| {
        let mesh = grid(8, 0.25, move |p| Vec3::new(-p.y, p.x, 0.0) * speed);
        let clip = Clip::from_meshes(vec![mesh.clone(), mesh], 64);
        let mut m = Optimization::new(params.clone(), pebbles(), 1).expect("params");
        clip.run(&mut m)
    };
    let rest = run(0.0);
    assert_eq!(rest[1].stats.get("still"), Some(&serde_json::json!(true)));
    assert!(!rest[1].stats.contains_key("levels"), "nothing synthesised");
    assert_eq!(rest[1].channels, rest[0].channels);
    let moving = run(1e-3);
    assert_eq!(moving[1].stats.get("still"), None);
    assert!(moving[1].stats.contains_key("levels"));
    assert_ne!(moving[1].channels, moving[0].channels);
}
