//! Two procedural lava exemplars, the molten `glow` and the cooled
//! `crust`, drawn on one crack network so that selecting by temperature
//! (`--select-by temperature --exemplar builtin:glow@0.5:1 --exemplar
//! builtin:crust@0:0.5`) shows a flow whose glowing cracks close into
//! crust, with no files to fetch.
//!
//! The cracks are the borders of a Voronoi diagram of jittered sites on a
//! torus (one site per cell, as in [`super::pebbles`]), so both images
//! tile. The distance to the border is approximated by half the gap
//! between the nearest and second-nearest site distances, F2 − F1
//! (Worley 1996), which is exact on the border and grows into the plates.
//!
//! - **glow**: wide cracks, bright yellow-orange at their centre, fading
//!   to dark red plates that still glow faintly. Its feature map is the
//!   crack's brightness: cracks are what a viewer reads in molten lava, so
//!   they erode last, and a glow patch that no longer matches the
//!   temperature loses its plates first and its cracks last: the cracks
//!   narrow and close.
//! - **crust**: thin dark cracks between grey basalt plates, lighter at
//!   the plate rims. Its feature map is the distance into the plate, as
//!   the pebbles' height: plates are kept, cracks erode first.
//!
//! Value noise on the same torus varies both. Everything is a function of
//! the texel and the seed, so the images are bit-identical on any thread
//! count.

use rayon::prelude::*;

use super::{Exemplar, FeatureMap, FeatureOrigin, SampleFormat};
use crate::seed::mix;
use crate::texture::Texture;

/// Plates per side of the exemplar.
const CELLS: u32 = 6;
/// How far a site may move from its cell's centre, in cells.
const JITTER: f32 = 0.4;
/// Half width of a glowing crack, in cells.
const GLOW_CRACK: f32 = 0.16;
/// Half width of a crust crack, in cells.
const CRUST_CRACK: f32 = 0.03;
/// Sizes accepted by [`builtin_lava`]; others are clamped into range.
const SIZE_RANGE: (u32, u32) = (8, 8192);
/// Streams of [`mix`] for the sites and the noise lattice.
const SITE_STREAM: u64 = 40;
const NOISE_STREAM: u64 = 41;

/// Which of the two lava exemplars.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LavaState {
    /// Molten: wide glowing cracks.
    Glow,
    /// Cooled: thin dark cracks between basalt plates.
    Crust,
}

crate::named!(LavaState {
    Glow => "glow",
    Crust => "crust",
});

/// The built-in lava exemplar of `state`, `size × size` texels (clamped
/// to `[8, 8192]`), 3 colour channels stored as 8-bit, with its own
/// feature map. Deterministic in `(state, size, seed)`; tiles seamlessly;
/// both states share the crack network of `seed`.
pub fn builtin_lava(state: LavaState, size: u32, seed: u64) -> Exemplar {
    let size = size.clamp(SIZE_RANGE.0, SIZE_RANGE.1);
    procedural(size, |u, v| texel(state, seed, u, v))
}

/// A `size²` exemplar of 3 colour channels stored as 8-bit and a feature
/// map, drawn by `texel(u, v)` (colour, feature value, both in [0, 1]) at
/// every texel centre, in parallel: the lava and bubble generators.
pub(super) fn procedural(
    size: u32,
    texel: impl Fn(f32, f32) -> ([f32; 3], f32) + Sync,
) -> Exemplar {
    let n = size as usize;
    let texels: Vec<([f32; 3], f32)> = (0..n * n)
        .into_par_iter()
        .map(|i| {
            let u = ((i % n) as f32 + 0.5) / size as f32;
            let v = ((i / n) as f32 + 0.5) / size as f32;
            texel(u, v)
        })
        .collect();
    let colour = Texture {
        width: size,
        height: size,
        channels: 3,
        data: texels.iter().flat_map(|(c, _)| *c).collect(),
    };
    let feature = FeatureMap {
        map: Texture {
            width: size,
            height: size,
            channels: 1,
            data: texels.iter().map(|(_, f)| *f).collect(),
        },
        origin: FeatureOrigin::Builtin,
    };
    // Sizes match and values are finite and in [0, 1] by construction.
    Exemplar::assemble(colour, SampleFormat::U8, Vec::new(), feature)
}

/// Colour and feature value at uv `(u, v)` in [0, 1)².
fn texel(state: LavaState, seed: u64, u: f32, v: f32) -> ([f32; 3], f32) {
    let d = border_distance(seed, u * CELLS as f32, v * CELLS as f32);
    let grain = noise(seed, u, v, 16) * 0.65 + noise(seed, u, v, 48) * 0.35;
    match state {
        LavaState::Glow => {
            // Crack brightness: 1 on the border, 0 at GLOW_CRACK into the plate.
            let c = smoothstep(GLOW_CRACK, 0.0, d);
            let heat = (c * (0.85 + 0.3 * grain)).clamp(0.0, 1.0);
            let plate = [0.22 + 0.1 * grain, 0.04 + 0.02 * grain, 0.02];
            let hot = [1.0, 0.62 + 0.3 * heat, 0.12 + 0.25 * heat * heat];
            let colour = lerp3(plate, hot, heat.powf(0.8));
            (clamp3(colour), c.clamp(0.0, 1.0))
        }
        LavaState::Crust => {
            let inside = smoothstep(0.0, CRUST_CRACK, d);
            // Plate rims catch the light; interiors are rougher and darker.
            let rim = smoothstep(CRUST_CRACK, 2.5 * CRUST_CRACK, d)
                * (1.0 - smoothstep(2.5 * CRUST_CRACK, 0.2, d));
            let base = 0.13 + 0.12 * grain + 0.05 * rim;
            let colour = [base * 1.05, base, base * 0.95];
            let crack = [0.03, 0.025, 0.025];
            let feature = smoothstep(0.0, 0.3, d);
            (clamp3(lerp3(crack, colour, inside)), feature)
        }
    }
}

/// Approximate distance, in cells, from point `(x, y)` (cell units on the
/// torus of [`CELLS`] cells) to the nearest Voronoi border: (F2 − F1) / 2.
fn border_distance(seed: u64, x: f32, y: f32) -> f32 {
    let (cx, cy) = (x.floor() as i32, y.floor() as i32);
    let (mut f1, mut f2) = (f32::INFINITY, f32::INFINITY);
    for dy in -2..=2 {
        for dx in -2..=2 {
            let (sx, sy) = site(seed, cx + dx, cy + dy);
            let dist = ((sx - x).powi(2) + (sy - y).powi(2)).sqrt();
            if dist < f1 {
                f2 = f1;
                f1 = dist;
            } else if dist < f2 {
                f2 = dist;
            }
        }
    }
    0.5 * (f2 - f1)
}

/// The Voronoi site of cell `(i, j)` (any integers, wrapped on the torus
/// of [`CELLS`] cells), in cell units: the cell's centre moved by up to
/// [`JITTER`] on each axis, by two independent 24-bit draws of one hash.
fn site(seed: u64, i: i32, j: i32) -> (f32, f32) {
    let cell = i.rem_euclid(CELLS as i32) as u64 + CELLS as u64 * j.rem_euclid(CELLS as i32) as u64;
    let h = mix(seed, SITE_STREAM, cell);
    // `unit` reads the top 24 bits: x takes bits 40–63, y bits 16–39.
    let jx = unit(h) * 2.0 - 1.0;
    let jy = unit(h << 24) * 2.0 - 1.0;
    (i as f32 + 0.5 + JITTER * jx, j as f32 + 0.5 + JITTER * jy)
}

/// Tileable value noise in [0, 1] at uv `(u, v)` on a `lattice`² grid.
pub(super) fn noise(seed: u64, u: f32, v: f32, lattice: u32) -> f32 {
    let (x, y) = (u * lattice as f32, v * lattice as f32);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (smooth(x - x0), smooth(y - y0));
    let at = |i: f32, j: f32| {
        let i = (i as i64).rem_euclid(lattice as i64) as u64;
        let j = (j as i64).rem_euclid(lattice as i64) as u64;
        unit(mix(
            seed,
            NOISE_STREAM + lattice as u64,
            i + j * lattice as u64,
        ))
    };
    let top = at(x0, y0) + (at(x0 + 1.0, y0) - at(x0, y0)) * fx;
    let bottom = at(x0, y0 + 1.0) + (at(x0 + 1.0, y0 + 1.0) - at(x0, y0 + 1.0)) * fx;
    top + (bottom - top) * fy
}

/// The top 24 bits of `h` as a number in [0, 1).
pub(super) fn unit(h: u64) -> f32 {
    ((h >> 40) & 0xFF_FFFF) as f32 / (1u32 << 24) as f32
}

fn smooth(t: f32) -> f32 {
    t * t * (3.0 - 2.0 * t)
}

/// 0 at `a`, 1 at `b` (either order), smooth in between.
pub(super) fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    smooth(((x - a) / (b - a)).clamp(0.0, 1.0))
}

fn lerp3(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * t)
}

fn clamp3(c: [f32; 3]) -> [f32; 3] {
    c.map(|x| x.clamp(0.0, 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::named::Named;

    fn luminance(e: &Exemplar) -> f32 {
        let d = &e.colour.data;
        d.iter().sum::<f32>() / d.len() as f32
    }

    /// The sites are jittered on both axes: over every cell of eight seeds,
    /// each offset
    /// from the cell centre spreads over most of ±JITTER with a mean near
    /// 0. Control: reading y from `h >> 24` (bits that `unit` shifts out)
    /// gave every site the same y offset, −JITTER, so the cracks ran in
    /// rows.
    #[test]
    fn voronoi_sites_are_jittered_on_both_axes() {
        let (mut xs, mut ys) = (Vec::new(), Vec::new());
        for seed in 0..8 {
            for j in 0..CELLS as i32 {
                for i in 0..CELLS as i32 {
                    let (x, y) = site(seed, i, j);
                    xs.push(x - i as f32 - 0.5);
                    ys.push(y - j as f32 - 0.5);
                }
            }
        }
        for (axis, d) in [("x", &xs), ("y", &ys)] {
            let n = d.len() as f32;
            let mean = d.iter().sum::<f32>() / n;
            let sd = (d.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / n).sqrt();
            assert!(mean.abs() < 0.2 * JITTER, "{axis}: mean {mean}");
            // A uniform draw on ±J has sd J/√3 ≈ 0.577 J.
            assert!(sd > 0.45 * JITTER, "{axis}: sd {sd}");
            assert!(d.iter().all(|v| v.abs() <= JITTER));
        }
        let h = mix(7, SITE_STREAM, 3);
        assert_eq!(unit(h >> 24), 0.0, "the old draw was always 0");
        // Wrapped cells share their site, moved by whole tori.
        let (a, b) = (site(7, 1, 2), site(7, 1 + CELLS as i32, 2 - CELLS as i32));
        assert!((a.0 + CELLS as f32 - b.0).abs() < 1e-5 && (a.1 - CELLS as f32 - b.1).abs() < 1e-5);
    }

    #[test]
    fn glow_is_bright_where_its_features_are_and_crust_is_dark() {
        let glow = builtin_lava(LavaState::Glow, 64, 1);
        let crust = builtin_lava(LavaState::Crust, 64, 1);
        assert!(luminance(&glow) > 1.5 * luminance(&crust));
        // Glow: the brightest texels are its features (cracks); the
        // control, crust, has its features on the plates, away from them.
        let red_at_feature = |e: &Exemplar, high: bool| {
            let (mut sum, mut n) = (0.0, 0);
            for (k, f) in e.feature.map.data.iter().enumerate() {
                if (*f > 0.8) == high && (*f < 0.2) != high {
                    sum += e.colour.data[3 * k];
                    n += 1;
                }
            }
            assert!(n > 20, "{n} texels");
            sum / n as f32
        };
        assert!(red_at_feature(&glow, true) > 0.9, "glowing cracks");
        assert!(red_at_feature(&glow, false) < 0.4, "dark plates");
        assert!(red_at_feature(&crust, true) > red_at_feature(&crust, false));
    }

    #[test]
    fn both_states_share_the_cracks_and_tile() {
        let glow = builtin_lava(LavaState::Glow, 96, 5);
        let crust = builtin_lava(LavaState::Crust, 96, 5);
        // Where the glow's crack is brightest the crust has a crack too.
        let mut both = 0;
        let mut cracks = 0;
        for (g, c) in glow.feature.map.data.iter().zip(&crust.feature.map.data) {
            if *g > 0.95 {
                cracks += 1;
                both += usize::from(*c < 0.15);
            }
        }
        assert!(cracks > 50 && both * 10 > cracks * 9, "{both} of {cracks}");
        // Another seed moves the cracks.
        let other = builtin_lava(LavaState::Glow, 96, 6);
        assert_ne!(glow.feature.map.data, other.feature.map.data);
        // Tiling: the pattern is periodic in u and v with period 1.
        for k in 0..50 {
            let (u, v) = (k as f32 * 0.0197, (k * 7 % 50) as f32 * 0.0201);
            for state in [LavaState::Glow, LavaState::Crust] {
                let (a, fa) = texel(state, 5, u, v);
                let (b, fb) = texel(state, 5, u + 1.0, v - 1.0);
                assert!(
                    (fa - fb).abs() < 1e-3,
                    "{state:?} at ({u}, {v}): {fa} vs {fb}"
                );
                assert!((a[0] - b[0]).abs() < 1e-3, "{state:?} at ({u}, {v})");
            }
        }
    }

    #[test]
    fn the_same_inputs_give_the_same_bits_on_any_thread_count() {
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("pool")
            .install(|| builtin_lava(LavaState::Crust, 48, 2));
        assert_eq!(one, builtin_lava(LavaState::Crust, 48, 2));
        assert_eq!(LavaState::parse_named("lava", "glow"), Ok(LavaState::Glow));
    }
}
