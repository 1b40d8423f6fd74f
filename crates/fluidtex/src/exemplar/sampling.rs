//! Tiled bilinear lookup for exemplars: the lattice arithmetic shared by
//! [`super::Exemplar::sample_all`] and [`super::FeatureMap::sample`].
//!
//! The convention is the one of [`crate::texture`] (texel centres at +0.5,
//! `v = 0` at the top, bilinear after subtracting 0.5), with
//! [`crate::texture::Wrap::Repeat`] folding. It is written again here rather
//! than calling [`crate::texture::Texture::sample_bilinear`] because the lapped
//! fill calls it once per atlas texel and patch: folding by a bit mask for
//! power-of-two sizes (and one remainder otherwise) and reading one
//! interleaved buffer of all channels is what keeps the cost independent of
//! the exemplar's resolution and channel count.

/// Where a bilinear lookup reads: the linear indices of the four texels
/// (top-left, top-right, bottom-left, bottom-right) and the weights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Footprint {
    pub texels: [usize; 4],
    pub fx: f32,
    pub fy: f32,
}

/// Folds one axis of a repeating lattice.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Axis {
    size: u32,
    scale: f32,
    /// `size - 1` when `size` is a power of two.
    mask: Option<u32>,
}

impl Axis {
    fn new(size: u32) -> Axis {
        Axis {
            size,
            scale: size as f32,
            mask: size.is_power_of_two().then(|| size - 1),
        }
    }

    /// Lower and upper texel index and the weight of the upper one.
    #[inline(always)]
    fn fold(&self, coord: f32) -> (u32, u32, f32) {
        let p = coord * self.scale - 0.5;
        // The cast saturates, so absurd coordinates read some texel
        // instead of panicking.
        let i = crate::texture::floor_i32(p);
        let frac = p - i as f32;
        match self.mask {
            Some(mask) => {
                let a = (i as u32) & mask;
                (a, (a + 1) & mask, frac)
            }
            None => {
                let a = i.rem_euclid(self.size as i32) as u32;
                let b = if a + 1 == self.size { 0 } else { a + 1 };
                (a, b, frac)
            }
        }
    }
}

/// A `width × height` lattice that repeats in both directions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Lattice {
    x: Axis,
    y: Axis,
}

impl Lattice {
    /// Both sizes must be at least 1 (callers validate that first).
    pub fn new(width: u32, height: u32) -> Lattice {
        Lattice {
            x: Axis::new(width.max(1)),
            y: Axis::new(height.max(1)),
        }
    }

    /// The four texels a bilinear lookup at `(u, v)` reads, with wrap-around.
    #[inline(always)]
    pub fn footprint(&self, u: f32, v: f32) -> Footprint {
        let (x0, x1, fx) = self.x.fold(u);
        let (y0, y1, fy) = self.y.fold(v);
        let w = self.x.size as usize;
        let (r0, r1) = (y0 as usize * w, y1 as usize * w);
        Footprint {
            texels: [
                r0 + x0 as usize,
                r0 + x1 as usize,
                r1 + x0 as usize,
                r1 + x1 as usize,
            ],
            fx,
            fy,
        }
    }
}

/// Bilinear blend of `stride`-channel texels read from `data` into `out`
/// (`min(out.len(), stride)` values). Reads nothing out of bounds: a
/// footprint from the matching [`Lattice`] always lies inside `data`.
/// Strides of 1 to 4 (every exemplar with at most one extra channel) take
/// a fixed-width path the compiler turns into vector arithmetic; the
/// operations per channel are the same, so the values are too, bit for bit.
#[inline(always)]
pub(crate) fn blend(data: &[f32], stride: usize, f: &Footprint, out: &mut [f32]) {
    match stride {
        4 => write(out, bilinear::<4>(data, f)),
        3 => write(out, bilinear::<3>(data, f)),
        2 => write(out, bilinear::<2>(data, f)),
        1 => write(out, bilinear::<1>(data, f)),
        _ => blend_any(data, stride, f, out),
    }
}

fn blend_any(data: &[f32], stride: usize, f: &Footprint, out: &mut [f32]) {
    let texel = |i: usize| data.get(i * stride..(i + 1) * stride).unwrap_or(&[]);
    let [a, b, c, d] = f.texels.map(texel);
    let (fx, fy) = (f.fx, f.fy);
    for ((((o, &a), &b), &c), &d) in out.iter_mut().zip(a).zip(b).zip(c).zip(d) {
        let top = a + (b - a) * fx;
        let bottom = c + (d - c) * fx;
        *o = top + (bottom - top) * fy;
    }
}

/// The `N` channels of texel `i` (zeros past the end, which a footprint
/// never reaches).
#[inline(always)]
fn texel<const N: usize>(data: &[f32], i: usize) -> [f32; N] {
    data.get(i * N..(i + 1) * N)
        .and_then(|s| <[f32; N]>::try_from(s).ok())
        .unwrap_or([0.0; N])
}

/// Bilinear lookup of `N`-channel texels, in the operation order of
/// [`blend_any`].
///
/// The four texels are read as slices of `data`, each channel straight
/// into the arithmetic: gathering them into arrays first (`[i; 4].map`)
/// compiled to a call that stored them to the stack piecewise and loaded
/// them back whole, a store-forwarding stall on every lookup that cost
/// more than the lookup's own arithmetic.
#[inline(always)]
pub(crate) fn bilinear<const N: usize>(data: &[f32], f: &Footprint) -> [f32; N] {
    let at = |i: usize| {
        data.get(i * N..(i + 1) * N)
            .and_then(|s| <&[f32; N]>::try_from(s).ok())
    };
    let [ia, ib, ic, id] = f.texels;
    let (Some(a), Some(b), Some(c), Some(d)) = (at(ia), at(ib), at(ic), at(id)) else {
        return bilinear_clipped::<N>(data, f);
    };
    lerp_texels([a, b, c, d], f)
}

/// [`bilinear`] where a texel lies past the end of `data` (which no
/// footprint of the matching [`Lattice`] does): such a texel reads as zeros.
#[cold]
fn bilinear_clipped<const N: usize>(data: &[f32], f: &Footprint) -> [f32; N] {
    let [a, b, c, d] = f.texels.map(|i| texel::<N>(data, i));
    lerp_texels([&a, &b, &c, &d], f)
}

/// The bilinear blend of four texels (top-left, top-right, bottom-left,
/// bottom-right) with the footprint's weights, channel by channel.
#[inline(always)]
fn lerp_texels<const N: usize>([a, b, c, d]: [&[f32; N]; 4], f: &Footprint) -> [f32; N] {
    let mut o = [0.0f32; N];
    for k in 0..N {
        let top = a[k] + (b[k] - a[k]) * f.fx;
        let bottom = c[k] + (d[k] - c[k]) * f.fx;
        o[k] = top + (bottom - top) * f.fy;
    }
    o
}

#[inline(always)]
fn write<const N: usize>(out: &mut [f32], values: [f32; N]) {
    for (o, v) in out.iter_mut().zip(values) {
        *o = v;
    }
}

/// `a + (b − a) t` channel by channel: the blend of two levels'
/// lookups with weight `t` on the coarse one `b`.
#[inline(always)]
pub(crate) fn lerp<const N: usize>(a: [f32; N], b: [f32; N], t: f32) -> [f32; N] {
    let mut o = [0.0f32; N];
    for k in 0..N {
        o[k] = a[k] + (b[k] - a[k]) * t;
    }
    o
}

/// Trilinear blend: the bilinear lookups `fine` and `coarse` (each its
/// level's texels and footprint) mixed with weight `t` on the coarse one.
/// Fixed-width for strides 1 to 4, as [`blend`].
#[inline(always)]
pub(crate) fn blend_levels(
    fine: (&[f32], &Footprint),
    coarse: (&[f32], &Footprint),
    stride: usize,
    t: f32,
    out: &mut [f32],
) {
    #[inline(always)]
    fn mix<const N: usize>(
        fine: (&[f32], &Footprint),
        coarse: (&[f32], &Footprint),
        t: f32,
    ) -> [f32; N] {
        lerp(
            bilinear::<N>(fine.0, fine.1),
            bilinear::<N>(coarse.0, coarse.1),
            t,
        )
    }
    match stride {
        4 => write(out, mix::<4>(fine, coarse, t)),
        3 => write(out, mix::<3>(fine, coarse, t)),
        2 => write(out, mix::<2>(fine, coarse, t)),
        1 => write(out, mix::<1>(fine, coarse, t)),
        _ => blend_levels_any(fine, coarse, stride, t, out),
    }
}

fn blend_levels_any(
    fine: (&[f32], &Footprint),
    coarse: (&[f32], &Footprint),
    stride: usize,
    t: f32,
    out: &mut [f32],
) {
    let bilinear = |data: &'_ [f32], f: &Footprint, c: usize| {
        let at = |i: usize| data.get(i * stride + c).copied().unwrap_or(0.0);
        let [a, b, cc, d] = f.texels.map(at);
        let top = a + (b - a) * f.fx;
        let bottom = cc + (d - cc) * f.fx;
        top + (bottom - top) * f.fy
    };
    for (c, o) in out.iter_mut().take(stride).enumerate() {
        let a = bilinear(fine.0, fine.1, c);
        let b = bilinear(coarse.0, coarse.1, c);
        *o = a + (b - a) * t;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::{Texture, Wrap};
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// The fast path must agree with the reference sampler of texture.rs
    /// (up to the rounding of the reordered lerp) on power-of-two and other sizes.
    #[test]
    fn agrees_with_reference_sampler() {
        let mut rng = Pcg64::seed_from_u64(7);
        for (w, h) in [(8, 4), (5, 3), (1, 7), (16, 16), (6, 1)] {
            let data: Vec<f32> = (0..w * h * 2).map(|_| rng.random::<f32>()).collect();
            let t = Texture::from_data(w, h, 2, data.clone()).expect("sizes match");
            let lattice = Lattice::new(w, h);
            for _ in 0..500 {
                let u = rng.random_range(-3.0f32..3.0);
                let v = rng.random_range(-3.0f32..3.0);
                let (mut fast, mut slow) = ([0.0; 2], [0.0; 2]);
                blend(&data, 2, &lattice.footprint(u, v), &mut fast);
                t.sample_bilinear(u, v, Wrap::Repeat, &mut slow);
                for k in 0..2 {
                    assert!((fast[k] - slow[k]).abs() < 1e-5, "{w}x{h} at ({u}, {v})");
                }
            }
        }
    }

    #[test]
    fn absurd_coordinates_do_not_panic() {
        let lattice = Lattice::new(3, 5);
        let data = vec![1.0; 15];
        let mut out = [0.0];
        for u in [f32::NAN, f32::INFINITY, -1e30, 1e30] {
            blend(&data, 1, &lattice.footprint(u, 0.3), &mut out);
        }
    }

    /// The fixed-width paths of strides 1 to 4 give the generic path's
    /// values bit for bit (same operations per channel), bilinear and
    /// trilinear, for any output length; a path that fused or reordered
    /// the lerps would differ in the last bits on some of these draws.
    #[test]
    fn fixed_width_paths_match_the_generic_path_bit_for_bit() {
        let mut rng = Pcg64::seed_from_u64(11);
        for stride in 1..=5usize {
            let (w, h) = (7u32, 4u32);
            let texels = (w * h) as usize;
            let fine: Vec<f32> = (0..texels * stride)
                .map(|_| rng.random_range(-2.0f32..2.0))
                .collect();
            let coarse: Vec<f32> = (0..texels * stride)
                .map(|_| rng.random_range(-2.0f32..2.0))
                .collect();
            let lattice = Lattice::new(w, h);
            for _ in 0..400 {
                let f = lattice.footprint(
                    rng.random_range(-2.0f32..2.0),
                    rng.random_range(-2.0f32..2.0),
                );
                let c = lattice.footprint(
                    rng.random_range(-2.0f32..2.0),
                    rng.random_range(-2.0f32..2.0),
                );
                let t = rng.random::<f32>();
                let len = rng.random_range(1..=stride + 1);
                let (mut fast, mut slow) = (vec![9.0f32; len], vec![9.0f32; len]);
                blend(&fine, stride, &f, &mut fast);
                blend_any(&fine, stride, &f, &mut slow);
                assert_eq!(
                    fast.map_bits(),
                    slow.map_bits(),
                    "bilinear, stride {stride}"
                );
                let (mut fast, mut slow) = (vec![9.0f32; len], vec![9.0f32; len]);
                blend_levels((&fine, &f), (&coarse, &c), stride, t, &mut fast);
                blend_levels_any((&fine, &f), (&coarse, &c), stride, t, &mut slow);
                assert_eq!(
                    fast.map_bits(),
                    slow.map_bits(),
                    "trilinear, stride {stride}"
                );
            }
        }
    }

    /// A footprint reaching past the texels (which no lattice of the
    /// data's size makes) reads zeros there on the fixed-width path, as
    /// the generic texel read does, instead of panicking.
    #[test]
    fn texels_past_the_end_read_as_zeros() {
        let data = [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0];
        let f = Footprint {
            texels: [0, 1, 5, 1],
            fx: 0.25,
            fy: 0.5,
        };
        let mut out = [9.0f32; 3];
        blend(&data, 3, &f, &mut out);
        for k in 0..3 {
            let (a, b) = (data[k], data[3 + k]);
            let top = a + (b - a) * 0.25;
            let bottom = 0.0 + (b - 0.0) * 0.25;
            assert_eq!(out[k], top + (bottom - top) * 0.5, "channel {k}");
        }
    }

    trait Bits {
        fn map_bits(&self) -> Vec<u32>;
    }

    impl Bits for Vec<f32> {
        fn map_bits(&self) -> Vec<u32> {
            self.iter().map(|v| v.to_bits()).collect()
        }
    }
}
