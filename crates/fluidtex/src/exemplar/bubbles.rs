//! A procedural animated exemplar, `builtin:bubbles`: foam bubbles that
//! swell and burst on dark water, as a looping sequence of frames, so an
//! animated exemplar can be tried with no files.
//!
//! Each cell of a grid on the torus holds one bubble at a jittered site
//! with its own size and its own point in the cycle. Over one cycle (the
//! sequence's length) its radius swells as sin(π s)^½ of its life s in
//! [0, 1) and drops back to zero, so frame n wraps to frame 0 seamlessly
//! and the bubbles do not pulse together. A bubble shows a bright rim, a
//! faint film and a highlight; the water between them carries value noise.
//!
//! The feature map is the bubble's dome height: the water between bubbles
//! erodes first and the bubbles last, so erosion follows their outlines.
//! Everything is a function of texel, frame and seed: bit-identical on any
//! thread count.

use super::Exemplar;
use super::lava::{noise, procedural, smoothstep, unit};
use crate::seed::mix;

/// Bubbles per side of the exemplar.
const CELLS: u32 = 7;
/// How far a site may move from its cell's centre, in cells.
const JITTER: f32 = 0.3;
/// Largest and smallest full radius, in cells.
const RADIUS: (f32, f32) = (0.22, 0.48);
/// Rim width, as a share of the radius.
const RIM: f32 = 0.12;
/// Sizes and frame counts accepted; others are clamped into range.
const SIZE_RANGE: (u32, u32) = (8, 4096);
const FRAME_RANGE: (u32, u32) = (1, 1024);
/// Stream of [`mix`] for the bubbles.
const BUBBLE_STREAM: u64 = 50;

/// Frames of the built-in bubbles sequence: one cycle.
pub const BUBBLE_FRAMES: u32 = 16;

/// The frames of the built-in bubbles, `size × size` texels (clamped to
/// `[8, 4096]`), `frames` of them (clamped to `[1, 1024]`), 3 colour
/// channels stored as 8-bit, each with its own feature map and its mip
/// pyramid deferred until shown ([`Exemplar::deferring_pyramid`]).
pub fn builtin_bubbles(size: u32, frames: u32, seed: u64) -> Vec<Exemplar> {
    let size = size.clamp(SIZE_RANGE.0, SIZE_RANGE.1);
    let frames = frames.clamp(FRAME_RANGE.0, FRAME_RANGE.1);
    (0..frames)
        .map(|k| bubble_frame(size, k as f32 / frames as f32, seed).deferring_pyramid())
        .collect()
}

/// One frame at cycle time `time` ∈ [0, 1).
fn bubble_frame(size: u32, time: f32, seed: u64) -> Exemplar {
    procedural(size, |u, v| texel(seed, time, u, v))
}

/// Colour and feature value at uv `(u, v)` at cycle time `time`.
fn texel(seed: u64, time: f32, u: f32, v: f32) -> ([f32; 3], f32) {
    let (x, y) = (u * CELLS as f32, v * CELLS as f32);
    let grain = noise(seed, u, v, 14) * 0.6 + noise(seed, u, v, 42) * 0.4;
    let water = [0.04 + 0.05 * grain, 0.12 + 0.08 * grain, 0.16 + 0.1 * grain];
    // The bubble whose dome is highest here (bubbles may overlap).
    let mut best: Option<(f32, f32, f32, f32)> = None; // (height, d/r, dx, dy)
    let (cx, cy) = (x.floor() as i32, y.floor() as i32);
    for dy in -1..=1 {
        for dx in -1..=1 {
            let (i, j) = (cx + dx, cy + dy);
            let cell = i.rem_euclid(CELLS as i32) as u64
                + CELLS as u64 * j.rem_euclid(CELLS as i32) as u64;
            // Four independent draws per bubble.
            let draw = |k: u64| unit(mix(seed, BUBBLE_STREAM, 4 * cell + k));
            let sx = i as f32 + 0.5 + JITTER * (draw(0) * 2.0 - 1.0);
            let sy = j as f32 + 0.5 + JITTER * (draw(1) * 2.0 - 1.0);
            let full = RADIUS.0 + (RADIUS.1 - RADIUS.0) * draw(2);
            let life = (time + draw(3)).fract();
            let r = full * (std::f32::consts::PI * life).sin().max(0.0).sqrt();
            if r <= 1e-3 {
                continue;
            }
            let (ox, oy) = (x - sx, y - sy);
            let q = (ox * ox + oy * oy).sqrt() / r;
            if q < 1.0 {
                let height = (1.0 - q * q).sqrt();
                if best.is_none_or(|b| height > b.0) {
                    best = Some((height, q, ox / r, oy / r));
                }
            }
        }
    }
    let Some((height, q, ox, oy)) = best else {
        return (water, 0.0);
    };
    let rim = smoothstep(1.0 - 2.0 * RIM, 1.0 - RIM * 0.5, q)
        * (1.0 - smoothstep(1.0 - RIM * 0.5, 1.0, q));
    let film = [0.55, 0.72, 0.78];
    let glint = smoothstep(0.35, 0.0, ((ox + 0.4).powi(2) + (oy + 0.4).powi(2)).sqrt());
    let mut c = [0.0; 3];
    for k in 0..3 {
        let body = water[k] + 0.18 * (film[k] - water[k]);
        c[k] = (body + rim * (0.85 - body) + glint * 0.6).clamp(0.0, 1.0);
    }
    (c, height.clamp(0.0, 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bubbles_loop_tile_and_are_deterministic() {
        let a = builtin_bubbles(32, 4, 3);
        let b = builtin_bubbles(32, 4, 3);
        assert_eq!(a.len(), 4);
        assert_eq!(a, b);
        // The frames differ: the bubbles swell and burst.
        assert_ne!(a[0].colour.data, a[1].colour.data);
        assert_ne!(a[0].feature.map.data, a[2].feature.map.data);
        // Another seed is another foam.
        assert_ne!(builtin_bubbles(32, 4, 4)[0].colour.data, a[0].colour.data);
        // Deferred pyramids, built on request and read the same as an
        // eager exemplar's.
        assert!(a.iter().all(|e| !e.pyramid_built()));
        let eager = bubble_frame(32, 0.25, 3);
        let mut x = [0.0; 3];
        let mut y = [0.0; 3];
        a[1].sample_all_lod(0.3, 0.7, 2.5, &mut x);
        assert!(a[1].pyramid_built(), "a filtered read builds the pyramid");
        eager.sample_all_lod(0.3, 0.7, 2.5, &mut y);
        assert_eq!(x, y);
        // Values in range and a feature map that is 0 on open water and
        // rises inside bubbles.
        for (k, e) in builtin_bubbles(64, 4, 3).iter().enumerate() {
            assert!(e.colour.data.iter().all(|v| (0.0..=1.0).contains(v)));
            let f = &e.feature.map.data;
            let water = f.iter().filter(|&&v| v == 0.0).count() as f32 / f.len() as f32;
            let domes = f.iter().filter(|&&v| v > 0.8).count();
            assert!(
                (0.1..0.9).contains(&water) && domes > 0,
                "frame {k}: {water} water, {domes}"
            );
        }
    }

    #[test]
    fn the_cycle_wraps_and_the_image_tiles() {
        let close = |a: ([f32; 3], f32), b: ([f32; 3], f32)| {
            (a.1 - b.1).abs() < 0.05 && a.0.iter().zip(b.0).all(|(x, y)| (x - y).abs() < 0.05)
        };
        for k in 0..64 {
            let (u, v) = ((k as f32 * 0.618).fract(), (k as f32 * 0.382).fract());
            // The end of the cycle meets its start.
            assert!(
                close(texel(9, 0.9999, u, v), texel(9, 0.0, u, v)),
                "at ({u}, {v})"
            );
            // u = 0 and u = 1 (and v) are the same place on the torus.
            assert!(close(texel(9, 0.4, 0.0, v), texel(9, 0.4, 1.0, v)));
            assert!(close(texel(9, 0.4, u, 0.0), texel(9, 0.4, u, 1.0)));
        }
    }
}
