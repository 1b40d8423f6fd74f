//! Z-buffer triangle rasterization into a [`GBuffer`].
//!
//! Half-space rasterization with integer edge functions (Pineda 1988, "A
//! parallel algorithm for polygon rasterization"): vertices are snapped to
//! 1/256 pixel, so the edge function of an edge shared by two triangles is
//! exactly the negation in one of what it is in the other, and the top-left
//! fill rule (as in Direct3D) gives every pixel centre on a shared edge to
//! exactly one of them — no cracks, no pixel drawn twice. Barycentrics are
//! perspective-correct: `b/z` and `1/z` are affine in screen space, so they
//! are interpolated there and divided per pixel.
//!
//! Triangles crossing the near plane are clipped in view space
//! (Sutherland–Hodgman, Sutherland & Hodgman 1974) and the pieces keep
//! barycentrics of the original triangle. Pieces reaching farther than
//! 2²¹ pixels from the image (where products of snapped coordinates could
//! overflow 64-bit integers) are clipped to the image in screen space; the
//! watertight guarantee holds for everything else.
//!
//! Parallel over bands of 16 rows: triangles are binned to bands in index
//! order, each band owns its rows of the buffers, and within a pixel the
//! first triangle (lowest index) wins depth ties — the result does not
//! depend on the thread count.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::camera::{Camera, View};

/// `GBuffer::triangle` value of pixels where nothing was hit.
pub const BACKGROUND: u32 = u32::MAX;

/// What each pixel sees: triangle index, perspective-correct barycentrics
/// and depth. Row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct GBuffer {
    pub width: u32,
    pub height: u32,
    /// Triangle index per pixel, [`BACKGROUND`] where nothing was hit.
    pub triangle: Vec<u32>,
    /// Barycentric coordinates in the hit triangle (weight `k` on corner
    /// `k` of `triangles[t]`); zeros on background.
    pub bary: Vec<[f32; 3]>,
    /// Distance along the view direction; `f32::INFINITY` on background.
    pub depth: Vec<f32>,
}

impl GBuffer {
    /// A buffer where every pixel is background.
    pub fn empty(width: u32, height: u32) -> GBuffer {
        let n = width as usize * height as usize;
        GBuffer {
            width,
            height,
            triangle: vec![BACKGROUND; n],
            bary: vec![[0.0; 3]; n],
            depth: vec![f32::INFINITY; n],
        }
    }

    /// Number of pixels that hit a triangle.
    pub fn covered(&self) -> usize {
        self.triangle.iter().filter(|&&t| t != BACKGROUND).count()
    }
}

const SUBPIXEL: i64 = 256;
const HALF_PIXEL: i64 = SUBPIXEL / 2;
/// Snapped coordinates stay within ±2²⁹, edge-function products within ±2⁶¹.
const GUARD: f32 = (1 << 21) as f32;
const BAND: usize = 16;
const SETUP_CHUNK: usize = 4096;

/// A triangle ready to rasterize: snapped screen vertices with positive
/// orientation, the attributes that are affine in screen space, and its
/// pixel bounding box (inclusive).
#[derive(Clone, Copy, Debug)]
struct ScreenTri {
    v: [[i64; 2]; 3],
    /// `1/z` per vertex.
    q: [f64; 3],
    /// Barycentrics (w.r.t. the original triangle) per vertex.
    b: [Vec3; 3],
    triangle: u32,
    inv_area: f64,
    /// Edge functions must reach this value to count as inside: 0 on
    /// top-left edges, 1 otherwise.
    bias: [i64; 3],
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
}

/// A polygon vertex during clipping.
#[derive(Clone, Copy, Debug)]
struct ClipVertex {
    view: Vec3,
    bary: Vec3,
}

/// A polygon vertex in screen space: position, `1/z` and `b/z`.
#[derive(Clone, Copy, Debug)]
struct ScreenVertex {
    s: Vec2,
    q: f64,
    bq: [f64; 3],
}

/// Rasterizes `triangles` (indices into `positions`) seen by `camera`.
/// Triangles with an index out of range or a non-finite vertex are
/// skipped; a degenerate camera gives an all-background buffer. Both
/// windings are drawn (no back-face culling).
pub fn rasterize(positions: &[Vec3], triangles: &[[u32; 3]], camera: &Camera) -> GBuffer {
    let mut gb = GBuffer::empty(camera.width, camera.height);
    let Some(view) = camera.view() else {
        return gb;
    };
    let (w, h) = (camera.width as usize, camera.height as usize);
    let view_positions: Vec<Vec3> = positions.par_iter().map(|&p| view.view_space(p)).collect();

    let chunks: Vec<Vec<ScreenTri>> = triangles
        .par_chunks(SETUP_CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            let mut out = Vec::with_capacity(chunk.len());
            for (k, tri) in chunk.iter().enumerate() {
                let index = (c * SETUP_CHUNK + k) as u32;
                let corner = |i: u32| view_positions.get(i as usize).copied();
                if let (Some(a), Some(b), Some(c)) =
                    (corner(tri[0]), corner(tri[1]), corner(tri[2]))
                    && a.is_finite()
                    && b.is_finite()
                    && c.is_finite()
                {
                    setup(index, [a, b, c], &view, w, h, &mut out);
                }
            }
            out
        })
        .collect();
    let screen: Vec<ScreenTri> = chunks.into_iter().flatten().collect();

    let bands = h.div_ceil(BAND);
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); bands];
    for (i, t) in screen.iter().enumerate() {
        for bin in &mut bins[t.y0 / BAND..=t.y1 / BAND] {
            bin.push(i as u32);
        }
    }

    gb.triangle
        .par_chunks_mut(BAND * w)
        .zip(gb.bary.par_chunks_mut(BAND * w))
        .zip(gb.depth.par_chunks_mut(BAND * w))
        .zip(bins.par_iter())
        .enumerate()
        .for_each(|(band, (((ids, bary), depth), list))| {
            let y_start = band * BAND;
            let rows = ids.len() / w;
            for &s in list {
                draw(&screen[s as usize], y_start, rows, w, ids, bary, depth);
            }
        });
    gb
}

/// Clips one triangle and appends its screen-space pieces.
fn setup(
    index: u32,
    corners: [Vec3; 3],
    view: &View,
    w: usize,
    h: usize,
    out: &mut Vec<ScreenTri>,
) {
    let mut poly: Vec<ClipVertex> = corners
        .iter()
        .zip([Vec3::X, Vec3::Y, Vec3::Z])
        .map(|(&v, b)| ClipVertex { view: v, bary: b })
        .collect();
    if corners.iter().any(|c| c.z < view.near) {
        poly = clip_near(&poly, view.near);
        if poly.len() < 3 {
            return;
        }
    }
    let mut screen: Vec<ScreenVertex> = poly
        .iter()
        .map(|v| {
            let q = 1.0 / v.view.z as f64;
            ScreenVertex {
                s: view.pixel(v.view),
                q,
                bq: [
                    v.bary.x as f64 * q,
                    v.bary.y as f64 * q,
                    v.bary.z as f64 * q,
                ],
            }
        })
        .collect();
    if screen
        .iter()
        .any(|v| !v.s.is_finite() || v.s.abs().max_element() > GUARD)
    {
        screen = clip_to_image(&screen, w as f32, h as f32);
    }
    for i in 1..screen.len().saturating_sub(1) {
        if let Some(t) = screen_tri(index, [screen[0], screen[i], screen[i + 1]], w, h) {
            out.push(t);
        }
    }
}

/// Keeps the part of a convex polygon with depth ≥ `near`.
fn clip_near(poly: &[ClipVertex], near: f32) -> Vec<ClipVertex> {
    let mut out = Vec::with_capacity(poly.len() + 1);
    for (i, &a) in poly.iter().enumerate() {
        let b = poly[(i + 1) % poly.len()];
        let (ina, inb) = (a.view.z >= near, b.view.z >= near);
        if ina {
            out.push(a);
        }
        if ina != inb {
            let t = (near - a.view.z) / (b.view.z - a.view.z);
            out.push(ClipVertex {
                view: a.view.lerp(b.view, t).with_z(near),
                bary: a.bary.lerp(b.bary, t),
            });
        }
    }
    out
}

/// Clips a screen polygon to the image grown by one pixel, interpolating
/// the screen-affine attributes.
fn clip_to_image(poly: &[ScreenVertex], w: f32, h: f32) -> Vec<ScreenVertex> {
    let planes: [(usize, f32, bool); 4] = [
        (0, -1.0, true),
        (0, w + 1.0, false),
        (1, -1.0, true),
        (1, h + 1.0, false),
    ];
    let mut poly = poly.to_vec();
    for (axis, bound, keep_above) in planes {
        let inside = |v: &ScreenVertex| {
            let c = v.s[axis];
            if keep_above { c >= bound } else { c <= bound }
        };
        let mut out = Vec::with_capacity(poly.len() + 1);
        for (i, &a) in poly.iter().enumerate() {
            let b = poly[(i + 1) % poly.len()];
            if inside(&a) {
                out.push(a);
            }
            if inside(&a) != inside(&b) {
                let t = ((bound - a.s[axis]) / (b.s[axis] - a.s[axis])) as f64;
                let lerp = |x: f64, y: f64| x + (y - x) * t;
                let mut s = a.s.lerp(b.s, t as f32);
                s[axis] = bound;
                out.push(ScreenVertex {
                    s,
                    q: lerp(a.q, b.q),
                    bq: [
                        lerp(a.bq[0], b.bq[0]),
                        lerp(a.bq[1], b.bq[1]),
                        lerp(a.bq[2], b.bq[2]),
                    ],
                });
            }
        }
        poly = out;
        if poly.len() < 3 {
            return poly;
        }
    }
    poly
}

/// Snaps, orients and bounds one screen triangle; `None` when it has no
/// area or covers no pixel centre's bounding box.
fn screen_tri(index: u32, mut v: [ScreenVertex; 3], w: usize, h: usize) -> Option<ScreenTri> {
    let snap = |s: Vec2| {
        [
            (s.x * SUBPIXEL as f32).round() as i64,
            (s.y * SUBPIXEL as f32).round() as i64,
        ]
    };
    let mut p = v.map(|x| snap(x.s));
    let orient = |p: &[[i64; 2]; 3]| {
        (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0])
    };
    let mut area = orient(&p);
    if area == 0 {
        return None;
    }
    if area < 0 {
        p.swap(1, 2);
        v.swap(1, 2);
        area = -area;
    }
    let lo = |a: usize| p.iter().map(|c| c[a]).min().unwrap_or(0);
    let hi = |a: usize| p.iter().map(|c| c[a]).max().unwrap_or(0);
    // Pixels whose centre (x + ½) lies within the snapped bounds.
    let first = |m: i64| (m - HALF_PIXEL + SUBPIXEL - 1).div_euclid(SUBPIXEL);
    let last = |m: i64| (m - HALF_PIXEL).div_euclid(SUBPIXEL);
    let (x0, x1) = (first(lo(0)).max(0), last(hi(0)).min(w as i64 - 1));
    let (y0, y1) = (first(lo(1)).max(0), last(hi(1)).min(h as i64 - 1));
    if x0 > x1 || y0 > y1 {
        return None;
    }
    let mut bias = [1i64; 3];
    for (i, b) in bias.iter_mut().enumerate() {
        let (a, c) = (p[(i + 1) % 3], p[(i + 2) % 3]);
        let (coef_x, coef_y) = (a[1] - c[1], c[0] - a[0]);
        // Left edge: the inside lies towards +x; top edge (y down): +y.
        if coef_x > 0 || (coef_x == 0 && coef_y > 0) {
            *b = 0;
        }
    }
    let b = |x: &ScreenVertex| {
        Vec3::new(
            (x.bq[0] / x.q) as f32,
            (x.bq[1] / x.q) as f32,
            (x.bq[2] / x.q) as f32,
        )
    };
    Some(ScreenTri {
        v: p,
        q: v.map(|x| x.q),
        b: [b(&v[0]), b(&v[1]), b(&v[2])],
        triangle: index,
        inv_area: 1.0 / area as f64,
        bias,
        x0: x0 as usize,
        x1: x1 as usize,
        y0: y0 as usize,
        y1: y1 as usize,
    })
}

/// Draws the rows of `t` inside the band starting at row `y_start`.
fn draw(
    t: &ScreenTri,
    y_start: usize,
    rows: usize,
    w: usize,
    ids: &mut [u32],
    bary: &mut [[f32; 3]],
    depth: &mut [f32],
) {
    let ya = t.y0.max(y_start);
    let yb = t.y1.min(y_start + rows - 1);
    // Edge i runs from vertex i+1 to vertex i+2: E(p) = cx·(px−ax) + cy·(py−ay).
    let edges: [(i64, i64, [i64; 2]); 3] = [0, 1, 2].map(|i| {
        let (a, c) = (t.v[(i + 1) % 3], t.v[(i + 2) % 3]);
        (a[1] - c[1], c[0] - a[0], a)
    });
    let px0 = t.x0 as i64 * SUBPIXEL + HALF_PIXEL;
    for y in ya..=yb {
        let py = y as i64 * SUBPIXEL + HALF_PIXEL;
        let mut e = edges.map(|(cx, cy, a)| cx * (px0 - a[0]) + cy * (py - a[1]));
        let step = edges.map(|(cx, _, _)| cx * SUBPIXEL);
        let row = (y - y_start) * w;
        for x in t.x0..=t.x1 {
            if e[0] >= t.bias[0] && e[1] >= t.bias[1] && e[2] >= t.bias[2] {
                let l = [
                    e[0] as f64 * t.inv_area,
                    e[1] as f64 * t.inv_area,
                    e[2] as f64 * t.inv_area,
                ];
                let lq = [l[0] * t.q[0], l[1] * t.q[1], l[2] * t.q[2]];
                let q = lq[0] + lq[1] + lq[2];
                let z = (1.0 / q) as f32;
                let i = row + x;
                if z < depth[i] {
                    depth[i] = z;
                    ids[i] = t.triangle;
                    let b = (t.b[0] * lq[0] as f32 + t.b[1] * lq[1] as f32 + t.b[2] * lq[2] as f32)
                        / q as f32;
                    bary[i] = b.to_array();
                }
            }
            e[0] += step[0];
            e[1] += step[1];
            e[2] += step[2];
        }
    }
}
