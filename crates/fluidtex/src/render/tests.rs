//! Tests of the rasterizer: coverage, fill rule, depth, barycentrics,
//! clipping, shading and determinism.

use std::collections::HashMap;

use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use super::*;
use crate::texture::Texture;

/// Eye at the origin looking down −Z, 90° vertical field of view: a point
/// `(x, y, −1)` lands at pixel `(W/2 + x·H/2, H/2 − y·H/2)`.
fn camera(width: u32, height: u32) -> Camera {
    Camera {
        eye: Vec3::ZERO,
        target: Vec3::NEG_Z,
        up: Vec3::Y,
        fov_y_degrees: 90.0,
        width,
        height,
    }
}

/// World point at depth `z` that projects to pixel coordinates `(px, py)`.
fn unproject(cam: &Camera, px: f32, py: f32, z: f32) -> Vec3 {
    let f = 0.5 * cam.height as f32; // tan(45°) = 1
    Vec3::new(
        (px - 0.5 * cam.width as f32) / f * z,
        (0.5 * cam.height as f32 - py) / f * z,
        -z,
    )
}

/// A screen-aligned quad covering pixel coordinates `[x0, x1] × [y0, y1]`,
/// as two triangles with uv (0,0) at the top left, (1,1) at the bottom right.
fn quad(
    cam: &Camera,
    x0: f32,
    y0: f32,
    x1: f32,
    y1: f32,
    z: f32,
) -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<Vec2>) {
    let p = vec![
        unproject(cam, x0, y0, z),
        unproject(cam, x1, y0, z),
        unproject(cam, x1, y1, z),
        unproject(cam, x0, y1, z),
    ];
    let uv = vec![
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(0.0, 1.0),
    ];
    (p, vec![[0, 1, 2], [0, 2, 3]], uv)
}

fn covered_set(gb: &GBuffer) -> Vec<(u32, u32)> {
    (0..gb.height)
        .flat_map(|y| (0..gb.width).map(move |x| (x, y)))
        .filter(|&(x, y)| gb.triangle[(y * gb.width + x) as usize] != BACKGROUND)
        .collect()
}

#[test]
fn quad_covers_exactly_its_pixel_rectangle() {
    let cam = camera(64, 48);
    // Edges between pixel centres, and edges exactly through pixel centres
    // (left/top edges include them, right/bottom edges do not).
    for (x0, y0, x1, y1, xs, ys) in [
        (16.0, 24.0, 48.0, 40.0, 16..48, 24..40),
        (10.5, 5.5, 20.5, 9.5, 10..20, 5..9),
        (3.2, 7.4, 9.7, 8.6, 3..10, 7..9),
    ] {
        let (p, t, _) = quad(&cam, x0, y0, x1, y1, 2.0);
        let gb = rasterize(&p, &t, &cam);
        let expected: Vec<(u32, u32)> = ys
            .clone()
            .flat_map(|y| xs.clone().map(move |x| (x, y)))
            .collect();
        assert_eq!(
            covered_set(&gb),
            expected,
            "quad [{x0}, {x1}] x [{y0}, {y1}]"
        );
        // Each triangle alone covers a disjoint part: nothing drawn twice.
        let a = covered_set(&rasterize(&p, &t[..1], &cam));
        let b = covered_set(&rasterize(&p, &t[1..], &cam));
        assert_eq!(a.len() + b.len(), expected.len());
        assert!(a.iter().all(|px| !b.contains(px)));
    }
}

/// A jittered planar grid of triangles sharing vertices: every pixel inside
/// is drawn by exactly one triangle (watertight, no double coverage).
#[test]
fn shared_edges_cover_every_pixel_exactly_once() {
    let cam = camera(48, 40);
    let mut rng = Pcg64::seed_from_u64(3);
    let n = 8;
    let (x0, y0, size) = (4.3f32, 3.7f32, 32.0f32);
    let mut p = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (mut x, mut y) = (
                x0 + size * i as f32 / n as f32,
                y0 + size * j as f32 / n as f32,
            );
            if i > 0 && i < n && j > 0 && j < n {
                x += rng.random_range(-1.5..1.5);
                y += rng.random_range(-1.5..1.5);
                // Some vertices exactly on pixel centres, to exercise ties.
                if rng.random_bool(0.3) {
                    x = x.floor() + 0.5;
                    y = y.floor() + 0.5;
                }
            }
            p.push(unproject(&cam, x, y, 1.0 + rng.random_range(0.0..0.5)));
        }
    }
    let mut t = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let v = |a: u32, b: u32| b * (n + 1) + a;
            let (a, b, c, d) = (v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
            if rng.random_bool(0.5) {
                t.extend([[a, b, c], [a, c, d]]);
            } else {
                t.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    let mut count: HashMap<(u32, u32), u32> = HashMap::new();
    for k in 0..t.len() {
        for px in covered_set(&rasterize(&p, &t[k..k + 1], &cam)) {
            *count.entry(px).or_insert(0) += 1;
        }
    }
    // The outer boundary is the unjittered square [4.3, 36.3] x [3.7, 35.7].
    for y in 0..cam.height {
        for x in 0..cam.width {
            let inside = (4..36).contains(&x) && (4..36).contains(&y);
            let c = count.get(&(x, y)).copied().unwrap_or(0);
            assert_eq!(c, inside as u32, "pixel ({x}, {y})");
        }
    }
}

/// The shared unit icosphere with `20·4^levels` triangles.
fn icosphere(levels: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let m = crate::atlas::fixtures::icosphere(1 << levels);
    (m.positions, m.triangles)
}

/// A closed sphere mesh has no background pixel inside its silhouette,
/// seen from random directions, and none outside the analytic disc.
#[test]
fn closed_mesh_has_no_cracks() {
    let (p, t) = icosphere(4);
    let mut rng = Pcg64::seed_from_u64(5);
    for case in 0..6 {
        let dir = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let cam = Camera {
            eye: dir.normalize() * 4.0,
            target: Vec3::ZERO,
            up: Vec3::new(rng.random_range(-1.0..1.0), 1.0, 0.3),
            fov_y_degrees: 40.0,
            width: 160,
            height: 120,
        };
        let gb = rasterize(&p, &t, &cam);
        // A sphere of radius 1 at distance 4 on the optical axis projects to
        // a disc of radius f·tan(asin(1/4)).
        let f = 60.0 / (20f32.to_radians()).tan();
        let r = f * (0.25f32).asin().tan();
        let centre = Vec2::new(80.0, 60.0);
        for y in 0..120 {
            for x in 0..160 {
                let d = (Vec2::new(x as f32 + 0.5, y as f32 + 0.5) - centre).length();
                let hit = gb.triangle[(y * 160 + x) as usize] != BACKGROUND;
                if d < r - 1.0 {
                    assert!(
                        hit,
                        "case {case}: crack at ({x}, {y}), {d:.2} px from the centre"
                    );
                } else if d > r + 0.5 {
                    assert!(
                        !hit,
                        "case {case}: pixel ({x}, {y}) outside the silhouette is drawn"
                    );
                }
            }
        }
        // Only the near hemisphere is visible.
        let eye = cam.eye;
        for (i, &tri) in gb.triangle.iter().enumerate() {
            if tri != BACKGROUND {
                let b = gb.bary[i];
                let [a, bb, c] = t[tri as usize];
                let q = p[a as usize] * b[0] + p[bb as usize] * b[1] + p[c as usize] * b[2];
                assert!(
                    q.dot(eye) > 0.0,
                    "case {case}: far side visible at pixel {i}"
                );
            }
        }
    }
}

#[test]
fn depth_test_keeps_the_nearer_triangle() {
    let cam = camera(32, 32);
    let near = [
        unproject(&cam, 2.0, 2.0, 2.0),
        unproject(&cam, 30.0, 2.0, 2.0),
        unproject(&cam, 2.0, 30.0, 2.0),
    ];
    let far = [
        unproject(&cam, 1.0, 1.0, 5.0),
        unproject(&cam, 31.0, 1.0, 5.0),
        unproject(&cam, 1.0, 31.0, 5.0),
    ];
    for (order, near_index) in [([near, far], 0u32), ([far, near], 1u32)] {
        let p: Vec<Vec3> = order.iter().flatten().copied().collect();
        let gb = rasterize(&p, &[[0, 1, 2], [3, 4, 5]], &cam);
        // Pixel (5, 5) is inside both.
        let i = 5 * 32 + 5;
        assert_eq!(gb.triangle[i], near_index);
        assert!((gb.depth[i] - 2.0).abs() < 1e-5, "depth {}", gb.depth[i]);
        // Pixel (1, 1) only sees the far one (its centre is outside the near).
        assert_eq!(gb.triangle[32 + 1], 1 - near_index);
        assert!((gb.depth[32 + 1] - 5.0).abs() < 1e-4);
    }
}

/// Interpolating the corners with a pixel's barycentrics gives a 3-D point
/// that projects back to that pixel's centre, at the stored depth.
#[test]
fn barycentrics_are_perspective_correct() {
    let cam = Camera {
        eye: Vec3::new(0.3, 0.5, 3.0),
        target: Vec3::new(0.0, 0.0, 0.0),
        up: Vec3::Y,
        fov_y_degrees: 50.0,
        width: 96,
        height: 80,
    };
    let mut rng = Pcg64::seed_from_u64(9);
    let mut checked = 0;
    for _ in 0..30 {
        // Steeply tilted triangles, where affine interpolation would be off.
        let p: Vec<Vec3> = (0..3)
            .map(|_| {
                Vec3::new(
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-2.5..1.5),
                )
            })
            .collect();
        let gb = rasterize(&p, &[[0, 1, 2]], &cam);
        for (i, &tri) in gb.triangle.iter().enumerate() {
            if tri == BACKGROUND {
                continue;
            }
            let b = gb.bary[i];
            assert!((b[0] + b[1] + b[2] - 1.0).abs() < 1e-5);
            let q = p[0] * b[0] + p[1] * b[1] + p[2] * b[2];
            let (px, depth) = cam.project(q).expect("in front");
            let centre = Vec2::new((i % 96) as f32 + 0.5, (i / 96) as f32 + 0.5);
            assert!(
                (px - centre).length() < 0.01,
                "reprojection error {}",
                (px - centre).length()
            );
            assert!((depth - gb.depth[i]).abs() < 1e-4 * depth);
            checked += 1;
        }
    }
    assert!(checked > 1000, "only {checked} pixels checked");
}

/// A triangle reaching behind the camera is clipped, not dropped or
/// mirrored: what remains is correct; one wholly behind draws nothing.
#[test]
fn triangles_behind_the_camera_are_clipped() {
    let cam = camera(64, 64);
    // A floor below the eye extending from far in front to behind the eye.
    let p = vec![
        Vec3::new(-3.0, -1.0, -20.0),
        Vec3::new(3.0, -1.0, -20.0),
        Vec3::new(0.0, -1.0, 5.0),
    ];
    let gb = rasterize(&p, &[[0, 1, 2]], &cam);
    assert!(gb.covered() > 200, "covered {}", gb.covered());
    for (i, &tri) in gb.triangle.iter().enumerate() {
        if tri != BACKGROUND {
            let b = gb.bary[i];
            assert!(b.iter().all(|&x| x >= -1e-4), "barycentrics {b:?}");
            let q = p[0] * b[0] + p[1] * b[1] + p[2] * b[2];
            let (px, _) = cam.project(q).expect("visible point is in front");
            let centre = Vec2::new((i % 64) as f32 + 0.5, (i / 64) as f32 + 0.5);
            assert!((px - centre).length() < 0.01);
            // The floor is below the horizon: lower half of the image.
            assert!(i / 64 >= 32);
        }
    }
    let behind = vec![
        Vec3::new(-1.0, 0.0, 1.0),
        Vec3::new(1.0, 0.0, 1.0),
        Vec3::new(0.0, 1.0, 2.0),
    ];
    assert_eq!(rasterize(&behind, &[[0, 1, 2]], &cam).covered(), 0);
    // Bad indices, NaN vertices and a degenerate camera do not panic.
    let nan = vec![Vec3::NAN, Vec3::X, Vec3::Y];
    assert_eq!(rasterize(&nan, &[[0, 1, 2], [0, 1, 7]], &cam).covered(), 0);
    let broken = Camera {
        target: cam.eye,
        ..cam
    };
    assert_eq!(rasterize(&p, &[[0, 1, 2]], &broken).covered(), 0);
    assert_eq!(broken.project(Vec3::NEG_Z), None);
}

#[test]
fn shade_textured_reproduces_a_checker() {
    let cam = camera(64, 48);
    // 32×16 texels mapped 1:1 onto the pixels [16, 48) × [24, 40).
    let (tw, th) = (32u32, 16u32);
    let mut checker = Texture::filled(tw, th, 1, 0.0);
    for y in 0..th {
        for x in 0..tw {
            checker.texel_mut(x, y)[0] = ((x / 2 + y / 2) % 2) as f32;
        }
    }
    let (p, t, uv) = quad(&cam, 16.0, 24.0, 48.0, 40.0, 3.0);
    let gb = rasterize(&p, &t, &cam);
    let img = shade_textured(&gb, &t, &uv, &checker, [0.2, 0.4, 0.6]);
    assert_eq!((img.width, img.height, img.channels), (64, 48, 3));
    for y in 0..48 {
        for x in 0..64 {
            let px = img.texel(x, y);
            if (16..48).contains(&x) && (24..40).contains(&y) {
                let expected = checker.texel(x - 16, y - 24)[0];
                assert!(
                    px.iter().all(|&c| (c - expected).abs() < 1e-3),
                    "({x}, {y}): {px:?} vs {expected}"
                );
            } else {
                assert_eq!(px, &[0.2, 0.4, 0.6]);
            }
        }
    }
    // Lit: a quad facing the camera is lit fully next to the optical axis
    // (image centre (32, 24)), less where the headlight ray is oblique.
    let normals = vec![Vec3::Z; 4];
    let white = Texture::filled(1, 1, 3, 1.0);
    let lit = shade_lit(&gb, &t, &normals, &uv, &white, &cam, [0.0; 3]);
    let centre = lit.texel(31, 24)[0];
    assert!(centre > 0.99 && centre <= 1.0, "{centre}");
    assert!(lit.texel(16, 39)[0] < centre - 0.05);
    assert_eq!(lit.texel(0, 0), &[0.0, 0.0, 0.0]);
}

#[test]
fn rendering_is_identical_on_any_thread_count() {
    let (p, t) = icosphere(3);
    let cam = Camera::framing(
        Vec3::splat(-1.0),
        Vec3::splat(1.0),
        Vec3::new(0.3, -0.2, -1.0),
        200,
        150,
    );
    let render = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| rasterize(&p, &t, &cam))
    };
    let one = render(1);
    assert!(one.covered() > 3000, "covered {}", one.covered());
    for threads in [2, 3, 8] {
        let other = render(threads);
        assert_eq!(one.triangle, other.triangle);
        let bits = |g: &GBuffer| g.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&one), bits(&other));
        assert_eq!(one.bary, other.bary);
    }
}

#[test]
fn camera_projects_and_frames() {
    let cam = camera(64, 48);
    let (px, depth) = cam.project(Vec3::new(0.5, 0.25, -2.0)).expect("in front");
    // focal = 24 px; x = 32 + 24·0.25, y = 24 − 24·0.125.
    assert!((px - Vec2::new(38.0, 21.0)).length() < 1e-5, "{px}");
    assert_eq!(depth, 2.0);
    assert_eq!(cam.project(Vec3::new(0.0, 0.0, 1.0)), None);

    let (lo, hi) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(3.0, 0.5, 2.5));
    for dir in [
        Vec3::NEG_Z,
        Vec3::X,
        Vec3::NEG_Y,
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::ZERO,
    ] {
        for (w, h) in [(320, 180), (100, 300)] {
            let cam = Camera::framing(lo, hi, dir, w, h);
            for i in 0..8 {
                let c = Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                );
                let (px, _) = cam.project(c).expect("in front");
                assert!(
                    px.x >= 0.0 && px.x <= w as f32 && px.y >= 0.0 && px.y <= h as f32,
                    "{dir} {w}x{h}: {px}"
                );
            }
        }
    }
}

#[test]
fn side_by_side_places_images() {
    let a = Texture::filled(2, 3, 1, 0.5);
    let b = Texture::filled(3, 1, 4, 0.9);
    let s = side_by_side(&[&a, &b], 1, [0.0, 0.0, 1.0]);
    assert_eq!((s.width, s.height, s.channels), (6, 3, 3));
    assert_eq!(s.texel(1, 2), &[0.5; 3]);
    assert_eq!(s.texel(2, 0), &[0.0, 0.0, 1.0], "gap");
    assert_eq!(s.texel(3, 0), &[0.9; 3]);
    assert_eq!(s.texel(3, 1), &[0.0, 0.0, 1.0], "below the shorter image");
    assert_eq!(side_by_side(&[], 4, [0.0; 3]).width, 0);
}
