//! Tests of loading, sampling, the built-in pebbles and derived feature maps.

use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageBuffer, Luma, LumaA, Rgb, Rgba};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use super::feature::{self, DistanceParams};
use super::*;

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/exemplars")
}

fn ramp(w: u32, h: u32, channels: usize, offset: f32) -> Texture {
    let data = (0..w as usize * h as usize * channels)
        .map(|i| offset + i as f32 / 1000.0)
        .collect();
    Texture::from_data(w, h, channels, data).expect("sizes match")
}

fn flat_feature(w: u32, h: u32, value: f32) -> FeatureMap {
    FeatureMap::new(
        Texture::filled(w, h, 1, value),
        FeatureOrigin::Builtin,
        "test",
    )
    .expect("valid")
}

fn two_channel_exemplar(w: u32, h: u32) -> Exemplar {
    let extra = ExtraChannel {
        name: "height".into(),
        texture: ramp(w, h, 1, 5.0),
        format: SampleFormat::F32,
    };
    Exemplar::new(
        ramp(w, h, 3, 0.0),
        SampleFormat::U8,
        vec![extra],
        flat_feature(w, h, 0.5),
    )
    .expect("valid exemplar")
}

// ---------------------------------------------------------------- sampling

#[test]
fn sample_all_at_texel_centres_returns_texels_exactly() {
    for (w, h) in [(8, 4), (5, 3), (16, 16), (7, 1)] {
        let e = two_channel_exemplar(w, h);
        assert_eq!(e.total_channels(), 4);
        let mut out = [0.0f32; 4];
        for y in 0..h {
            for x in 0..w {
                let (u, v) = ((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
                e.sample_all(u, v, &mut out);
                assert_eq!(
                    &out[..3],
                    e.colour.texel(x, y),
                    "{w}x{h} colour at ({x},{y})"
                );
                assert_eq!(
                    out[3],
                    e.channels[0].texture.texel(x, y)[0],
                    "extra at ({x},{y})"
                );
            }
        }
    }
}

/// Interleaved atlas values split back into the exemplar's textures: the
/// colour and the extra channel of each texel land in their own texture
/// (a shifted offset would swap them), and a colour-only exemplar keeps the
/// very buffer it was given.
#[test]
fn interleaved_values_split_into_the_exemplar_textures() {
    let e = two_channel_exemplar(4, 3);
    let values: Vec<f32> = (0..12 * 4).map(|i| i as f32).collect();
    let split = super::channels::split_interleaved(4, 3, values.clone(), &e);
    assert_eq!(split.len(), 2);
    assert_eq!((split[0].channels, split[1].channels), (3, 1));
    for t in 0..12 {
        assert_eq!(&split[0].data[t * 3..t * 3 + 3], &values[t * 4..t * 4 + 3]);
        assert_eq!(split[1].data[t], values[t * 4 + 3]);
    }
    let colour_only = Exemplar::new(
        ramp(4, 3, 3, 0.0),
        SampleFormat::U8,
        Vec::new(),
        flat_feature(4, 3, 0.5),
    )
    .expect("valid exemplar");
    let values: Vec<f32> = (0..12 * 3).map(|i| i as f32 * 0.5).collect();
    let pointer = values.as_ptr();
    let split = super::channels::split_interleaved(4, 3, values, &colour_only);
    assert_eq!(split.len(), 1);
    assert_eq!(
        (split[0].width, split[0].height, split[0].channels),
        (4, 3, 3)
    );
    assert_eq!(split[0].data.as_ptr(), pointer, "moved, not copied");
    assert_eq!(split[0].data[7], 3.5);
}

#[test]
fn sample_all_wraps_around() {
    for (w, h) in [(8, 4), (5, 3)] {
        let e = two_channel_exemplar(w, h);
        let (mut a, mut b) = ([0.0f32; 4], [0.0f32; 4]);
        // Whole periods away: the same texel centre.
        let (u, v) = (1.5 / w as f32, 0.5 / h as f32);
        e.sample_all(u, v, &mut a);
        for (du, dv) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 2.0), (-3.0, -1.0)] {
            e.sample_all(u + du, v + dv, &mut b);
            assert_eq!(a, b, "{w}x{h} shifted by ({du}, {dv})");
        }
        // u = 0 lies halfway between the last and the first column.
        e.sample_all(0.0, 0.5 / h as f32, &mut a);
        let (first, last) = (e.colour.texel(0, 0), e.colour.texel(w - 1, 0));
        for k in 0..3 {
            assert!((a[k] - 0.5 * (first[k] + last[k])).abs() < 1e-6);
        }
    }
}

#[test]
fn feature_sample_is_exact_at_centres_and_wraps() {
    let map = Texture::from_data(3, 2, 1, vec![0.0, 0.2, 0.4, 0.6, 0.8, 1.0]).expect("sizes");
    let f = FeatureMap::new(map, FeatureOrigin::Builtin, "test").expect("valid");
    assert_eq!(f.sample(1.5 / 3.0, 0.25), 0.2);
    assert_eq!(f.sample(1.5 / 3.0 + 2.0, 0.75 - 1.0), 0.8);
    // Between the last and first column of row 0: (0.4 + 0.0) / 2.
    assert!((f.sample(0.0, 0.25) - 0.2).abs() < 1e-6);
}

/// The erosion normaliser of a constant map `c` is `sqrt(c + D)` at the texel
/// centre closest to (0.5, 0.5).
#[test]
fn erosion_normaliser_of_constant_map() {
    let f = flat_feature(4, 4, 0.25);
    // Nearest centres are (0.375, 0.375) etc.: ‖·‖ = 0.125·√2.
    let d = 1.0 - (0.125f32 * 2f32.sqrt()) / 0.5;
    assert!((f.erosion_normaliser() - (0.25 + d).sqrt()).abs() < 1e-6);
}

// ------------------------------------------------------------ mip pyramid

/// A random exemplar with a 3-channel colour and a 1-channel extra.
fn noisy_exemplar(w: u32, h: u32, seed: u64) -> Exemplar {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut random = |c: usize| {
        let data = (0..w as usize * h as usize * c)
            .map(|_| rng.random::<f32>())
            .collect();
        Texture::from_data(w, h, c, data).expect("sizes match")
    };
    let extra = ExtraChannel {
        name: "height".into(),
        texture: random(1),
        format: SampleFormat::F32,
    };
    Exemplar::new(
        random(3),
        SampleFormat::U8,
        vec![extra],
        flat_feature(w, h, 0.5),
    )
    .expect("valid exemplar")
}

#[test]
fn lod_zero_is_the_bilinear_lookup_exactly() {
    let mut rng = Pcg64::seed_from_u64(21);
    for (w, h) in [(64, 64), (37, 20), (1, 5)] {
        let e = noisy_exemplar(w, h, 3);
        let (mut a, mut b) = ([0.0f32; 4], [0.0f32; 4]);
        for _ in 0..300 {
            let (u, v) = (rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
            e.sample_all(u, v, &mut a);
            for lod in [0.0, -0.0, -3.0, f32::NAN, f32::NEG_INFINITY] {
                e.sample_all_lod(u, v, lod, &mut b);
                assert_eq!(
                    a.map(f32::to_bits),
                    b.map(f32::to_bits),
                    "{w}x{h} lod {lod}"
                );
            }
            // Continuous at 0: a tiny positive level is almost level 0.
            e.sample_all_lod(u, v, 1e-6, &mut b);
            for k in 0..4 {
                assert!((a[k] - b[k]).abs() < 1e-5);
            }
        }
    }
}

#[test]
fn pyramid_levels_keep_the_mean_and_end_at_one_texel() {
    for (w, h) in [(256, 256), (37, 20), (5, 3), (1, 6)] {
        let e = noisy_exemplar(w, h, 5);
        let levels = mip_levels(&e.colour);
        let base = e.colour.mean_std();
        let last = levels.last().expect("levels");
        assert_eq!((last.width, last.height), (1, 1), "{w}x{h}");
        assert_eq!(levels.len() as f32, e.max_lod() + 1.0);
        for (k, l) in levels.iter().enumerate() {
            assert_eq!(l.width, (w >> k).max(1));
            assert_eq!(l.height, (h >> k).max(1));
            for (c, (m, _)) in l.mean_std().iter().enumerate() {
                assert!(
                    (m - base[c].0).abs() < 1e-5,
                    "{w}x{h} level {k} channel {c}: {m}"
                );
            }
        }
        // The coarsest lookup is the mean of every channel, anywhere.
        let mut out = [0.0f32; 4];
        e.sample_all_lod(0.3, 0.8, 1000.0, &mut out);
        for c in 0..3 {
            assert!((f64::from(out[c]) - base[c].0).abs() < 1e-5);
        }
        let height = e.channels[0].texture.mean_std()[0].0;
        assert!((f64::from(out[3]) - height).abs() < 1e-5);
    }
}

#[test]
fn a_level_averages_the_texels_it_covers() {
    // 4x2 -> 2x1 -> 1x1; and an odd 3x1 -> 1x1 weighs all three equally.
    let t = Texture::from_data(4, 2, 1, vec![0., 1., 2., 3., 4., 5., 6., 7.]).expect("sizes");
    let l = mip_levels(&t);
    assert_eq!(l[1].data, vec![2.5, 4.5]);
    assert_eq!(l[2].data, vec![3.5]);
    let t = Texture::from_data(3, 1, 1, vec![0., 3., 9.]).expect("sizes");
    assert_eq!(mip_levels(&t)[1].data, vec![4.0]);
    // 5 -> 2: each coarse texel takes 2.5 fine ones.
    let t = Texture::from_data(5, 1, 1, vec![2., 2., 4., 6., 6.]).expect("sizes");
    let d = &mip_levels(&t)[1].data;
    assert!(
        (d[0] - 2.4).abs() < 1e-6 && (d[1] - 5.6).abs() < 1e-6,
        "{d:?}"
    );
}

#[test]
fn trilinear_mixes_the_two_levels_around_lod_and_tiles() {
    let e = noisy_exemplar(32, 16, 8);
    let levels = mip_levels(&e.colour);
    let mut rng = Pcg64::seed_from_u64(4);
    let (mut got, mut fine, mut coarse) = ([0.0f32; 4], [0.0f32; 3], [0.0f32; 3]);
    for _ in 0..200 {
        let (u, v) = (rng.random_range(-1.0..2.0), rng.random_range(-1.0..2.0));
        let lod = rng.random_range(0.01f32..4.0);
        let k = lod.floor() as usize;
        let t = lod - k as f32;
        e.sample_all_lod(u, v, lod, &mut got);
        levels[k].sample_bilinear(u, v, crate::texture::Wrap::Repeat, &mut fine);
        levels[k + 1].sample_bilinear(u, v, crate::texture::Wrap::Repeat, &mut coarse);
        for c in 0..3 {
            let want = fine[c] + (coarse[c] - fine[c]) * t;
            assert!((got[c] - want).abs() < 1e-5, "lod {lod} at ({u}, {v})");
        }
        // Every level repeats like the exemplar.
        let mut shifted = [0.0f32; 4];
        e.sample_all_lod(u + 1.0, v - 2.0, lod, &mut shifted);
        for c in 0..4 {
            assert!((shifted[c] - got[c]).abs() < 1e-4);
        }
    }
}

/// The fixed-width lookup answers for its own channel count only, with
/// the general lookup's values bit for bit: at every kind of level (NaN,
/// ≤ 0, between two levels, whole, past the coarsest) and at coordinates
/// far outside the exemplar.
#[test]
fn fixed_width_lookup_is_the_general_lookup_bit_for_bit() {
    fn fixed(e: &Exemplar, n: usize, u: f32, v: f32, lod: f32) -> Option<Vec<f32>> {
        match n {
            1 => e.sample_lod_fixed::<1>(u, v, lod).map(|a| a.to_vec()),
            2 => e.sample_lod_fixed::<2>(u, v, lod).map(|a| a.to_vec()),
            3 => e.sample_lod_fixed::<3>(u, v, lod).map(|a| a.to_vec()),
            4 => e.sample_lod_fixed::<4>(u, v, lod).map(|a| a.to_vec()),
            _ => e.sample_lod_fixed::<5>(u, v, lod).map(|a| a.to_vec()),
        }
    }
    let mut rng = Pcg64::seed_from_u64(31);
    for total in 1..=5usize {
        let e = crate::methods::test_clip::noise_exemplar(16, total, total as u64);
        let max = e.max_lod();
        for _ in 0..400 {
            let (u, v) = if rng.random_bool(0.05) {
                (rng.random_range(-1e6..1e6), rng.random_range(-1e6..1e6))
            } else {
                (rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0))
            };
            let lod = match rng.random_range(0..8) {
                0 => f32::NAN,
                1 => -rng.random::<f32>(),
                2 => 0.0,
                3 => rng.random_range(1..=max as u32) as f32,
                4 => max + rng.random_range(0.0..3.0),
                _ => rng.random_range(0.0..max),
            };
            let mut want = vec![0.0f32; total];
            e.sample_all_lod(u, v, lod, &mut want);
            let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            for n in 1..=5 {
                let got = fixed(&e, n, u, v, lod);
                if n == total {
                    let got = got.expect("its own channel count");
                    assert_eq!(
                        bits(&got),
                        bits(&want),
                        "{total} channels, lod {lod} at ({u}, {v})"
                    );
                } else {
                    assert!(got.is_none(), "{n} of {total} channels");
                }
            }
        }
    }
}

#[test]
fn filter_defaults_to_trilinear() {
    let e = noisy_exemplar(8, 8, 1);
    assert_eq!(e.filter, ExemplarFilter::Trilinear);
    assert_eq!(
        e.with_filter(ExemplarFilter::Unfiltered).filter,
        ExemplarFilter::Unfiltered
    );
    assert_eq!(builtin_pebbles(32, 0).filter, ExemplarFilter::Trilinear);
}

// ----------------------------------------------------------------- loading

fn save(img: DynamicImage, dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(name);
    img.save(&p).expect("test image written");
    p
}

#[test]
fn loads_each_format_and_depth() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let l8 = save(
        DynamicImage::ImageLuma8(ImageBuffer::from_raw(2, 1, vec![0u8, 255]).expect("buf")),
        d,
        "l8.png",
    );
    let la8 = save(
        DynamicImage::ImageLumaA8(
            ImageBuffer::<LumaA<u8>, _>::from_raw(1, 1, vec![51u8, 102]).expect("buf"),
        ),
        d,
        "la8.png",
    );
    let rgb8 = save(
        DynamicImage::ImageRgb8(
            ImageBuffer::<Rgb<u8>, _>::from_raw(1, 2, vec![255, 0, 51, 0, 255, 102]).expect("buf"),
        ),
        d,
        "rgb8.png",
    );
    let rgba8 = save(
        DynamicImage::ImageRgba8(
            ImageBuffer::<Rgba<u8>, _>::from_raw(1, 1, vec![1, 2, 3, 4]).expect("buf"),
        ),
        d,
        "rgba8.png",
    );
    let l16 = save(
        DynamicImage::ImageLuma16(
            ImageBuffer::<Luma<u16>, _>::from_raw(3, 1, vec![0u16, 65535, 1000]).expect("buf"),
        ),
        d,
        "l16.png",
    );
    let rgb16 = save(
        DynamicImage::ImageRgb16(
            ImageBuffer::<Rgb<u16>, _>::from_raw(1, 1, vec![1u16, 30000, 65535]).expect("buf"),
        ),
        d,
        "rgb16.png",
    );
    let rgbf = save(
        DynamicImage::ImageRgb32F(
            ImageBuffer::<Rgb<f32>, _>::from_raw(2, 1, vec![0.25, 1.5, -0.5, 2.0, 0.0, 0.125])
                .expect("buf"),
        ),
        d,
        "rgbf.exr",
    );
    let rgbaf = save(
        DynamicImage::ImageRgba32F(
            ImageBuffer::<Rgba<f32>, _>::from_raw(1, 1, vec![0.1, 0.2, 0.3, 0.5]).expect("buf"),
        ),
        d,
        "rgbaf.exr",
    );
    // A flat grey JPEG decodes to its level up to JPEG rounding.
    let jpg = save(
        DynamicImage::ImageRgb8(ImageBuffer::from_pixel(8, 8, Rgb([128u8, 128, 128]))),
        d,
        "grey.jpg",
    );
    let grey_exr = d.join("grey.exr");
    write_grey_exr(&grey_exr, 3, 2, &[0.0, 0.5, 1.0, 0.25, 0.75, 0.125]);

    let read = |p: &Path| crate::io::image_read::read_image(p).expect("decodes");
    let check = |p: &Path, w: u32, h: u32, c: usize, f: SampleFormat, data: &[f32]| {
        let d = read(p);
        assert_eq!(
            (d.texture.width, d.texture.height, d.texture.channels),
            (w, h, c),
            "{p:?}"
        );
        assert_eq!(d.format, f, "{p:?}");
        assert_eq!(d.texture.data, data, "{p:?}");
    };
    check(&l8, 2, 1, 1, SampleFormat::U8, &[0.0, 1.0]);
    check(&la8, 1, 1, 4, SampleFormat::U8, &[0.2, 0.2, 0.2, 0.4]);
    check(
        &rgb8,
        1,
        2,
        3,
        SampleFormat::U8,
        &[1.0, 0.0, 0.2, 0.0, 1.0, 0.4],
    );
    check(
        &rgba8,
        1,
        1,
        4,
        SampleFormat::U8,
        &[1.0 / 255.0, 2.0 / 255.0, 3.0 / 255.0, 4.0 / 255.0],
    );
    check(
        &l16,
        3,
        1,
        1,
        SampleFormat::U16,
        &[0.0, 1.0, 1000.0 / 65535.0],
    );
    check(
        &rgb16,
        1,
        1,
        3,
        SampleFormat::U16,
        &[1.0 / 65535.0, 30000.0 / 65535.0, 1.0],
    );
    check(
        &rgbf,
        2,
        1,
        3,
        SampleFormat::F32,
        &[0.25, 1.5, -0.5, 2.0, 0.0, 0.125],
    );
    check(&rgbaf, 1, 1, 4, SampleFormat::F32, &[0.1, 0.2, 0.3, 0.5]);
    check(
        &grey_exr,
        3,
        2,
        1,
        SampleFormat::F32,
        &[0.0, 0.5, 1.0, 0.25, 0.75, 0.125],
    );
    let j = read(&jpg);
    assert_eq!((j.texture.channels, j.format), (3, SampleFormat::U8));
    assert!(
        j.texture
            .data
            .iter()
            .all(|&v| (v - 128.0 / 255.0).abs() <= 2.0 / 255.0)
    );

    // The whole exemplar: colour + 16-bit extra channel + given feature map.
    let e = Exemplar::load(
        &rgb8,
        &[(
            "rough".into(),
            save(
                DynamicImage::ImageLuma16(
                    ImageBuffer::from_raw(1, 2, vec![0u16, 65535]).expect("buf"),
                ),
                d,
                "rough.png",
            ),
        )],
        Some(&save(
            DynamicImage::ImageLuma8(ImageBuffer::from_raw(1, 2, vec![255u8, 0]).expect("buf")),
            d,
            "feature.png",
        )),
        FeatureMethod::Auto,
    )
    .expect("loads");
    assert_eq!(e.colour_format, SampleFormat::U8);
    assert_eq!(e.channels[0].format, SampleFormat::U16);
    assert_eq!(e.total_channels(), 4);
    assert_eq!(e.feature.map.data, vec![1.0, 0.0]);
    assert!(matches!(e.feature.origin, FeatureOrigin::Given(_)));
}

fn write_grey_exr(path: &Path, w: usize, h: usize, values: &[f32]) {
    use exr::prelude::*;
    let channel = AnyChannel::new("Y", FlatSamples::F32(values.to_vec()));
    let layer = Layer::new(
        (w, h),
        LayerAttributes::named("grey"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    Image::from_layer(layer)
        .write()
        .to_file(path)
        .expect("EXR written");
}

/// A colour feature map becomes Rec. 709 luminance.
#[test]
fn colour_feature_map_is_reduced_to_luminance() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let colour = save(
        DynamicImage::ImageLuma8(ImageBuffer::from_pixel(2, 2, Luma([10u8]))),
        d,
        "c.png",
    );
    let fm = save(
        DynamicImage::ImageRgb8(ImageBuffer::from_pixel(2, 2, Rgb([255u8, 0, 0]))),
        d,
        "f.png",
    );
    let e = Exemplar::load(&colour, &[], Some(&fm), FeatureMethod::Auto).expect("loads");
    assert_eq!(e.feature.map.channels, 1);
    assert!(e.feature.map.data.iter().all(|&v| v == 0.2126));
}

/// Ledger (2021): "A feature map nobody gave". Without one, a feature map
/// is derived from the colour (`FeatureMethod::Auto`); a given one is read
/// as given.
#[test]
fn without_a_feature_map_one_is_derived_and_a_given_one_is_used_as_given() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let colour = save(
        DynamicImage::ImageLuma8(ImageBuffer::from_fn(16, 16, |x, y| {
            Luma([if (x / 4 + y / 4) % 2 == 0 { 40u8 } else { 220 }])
        })),
        d,
        "c.png",
    );
    let given = save(
        DynamicImage::ImageLuma8(ImageBuffer::from_pixel(16, 16, Luma([51u8]))),
        d,
        "f.png",
    );
    let derived = Exemplar::load(&colour, &[], None, FeatureMethod::Auto).expect("loads");
    assert!(matches!(derived.feature.origin, FeatureOrigin::Derived(_)));
    let colour_texture = Exemplar::load(&colour, &[], Some(&given), FeatureMethod::Auto)
        .expect("loads")
        .colour;
    let want = feature::derive(
        &colour_texture,
        FeatureMethod::Auto,
        &DistanceParams::default(),
    )
    .expect("derives")
    .map;
    assert_eq!(derived.feature.map.data, want.map.data);
    let read = Exemplar::load(&colour, &[], Some(&given), FeatureMethod::Auto).expect("loads");
    assert_eq!(read.feature.origin, FeatureOrigin::Given(given.clone()));
    assert!(
        read.feature
            .map
            .data
            .iter()
            .all(|&v| (v - 0.2).abs() < 1e-6)
    );
    // Control: the derived map is not the given one.
    assert_ne!(derived.feature.map.data, read.feature.map.data);
}

// ------------------------------------------------------------------ errors

#[test]
fn each_error_names_the_file() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let ok = save(
        DynamicImage::ImageLuma8(ImageBuffer::from_pixel(4, 3, Luma([10u8]))),
        d,
        "ok.png",
    );
    let small = save(
        DynamicImage::ImageLuma8(ImageBuffer::from_pixel(2, 3, Luma([10u8]))),
        d,
        "small.png",
    );
    let garbage = d.join("garbage.png");
    std::fs::write(&garbage, b"definitely not an image").expect("written");
    let nan = save(
        DynamicImage::ImageRgb32F(
            ImageBuffer::from_raw(2, 1, vec![0.0, 0.0, 0.0, 0.0, f32::NAN, 0.0]).expect("buf"),
        ),
        d,
        "nan.exr",
    );
    let big = d.join("big.exr");
    write_grey_exr(
        &big,
        4,
        3,
        &[0.5, 0.5, 1.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5],
    );
    let missing = d.join("missing.png");

    let load = |colour: &Path, extra: Option<&Path>, feature: Option<&Path>| {
        let extras: Vec<(String, PathBuf)> = extra
            .map(|p| ("disp".to_string(), p.to_path_buf()))
            .into_iter()
            .collect();
        Exemplar::load(colour, &extras, feature, FeatureMethod::Luminance)
    };
    let message = |r: Result<Exemplar, ExemplarError>| r.expect_err("must fail").to_string();

    let m = message(load(&missing, None, None));
    assert!(m.contains("missing.png") && m.contains("not found"), "{m}");
    let m = message(load(&garbage, None, None));
    assert!(m.contains("garbage.png") && m.contains("decode"), "{m}");
    let m = message(load(&ok, Some(&small), None));
    assert!(
        m.contains("small.png") && m.contains("2x3") && m.contains("4x3"),
        "{m}"
    );
    let m = message(load(&ok, None, Some(&small)));
    assert!(
        m.contains("small.png") && m.contains("2x3") && m.contains("4x3"),
        "{m}"
    );
    let m = message(load(&nan, None, None));
    assert!(
        m.contains("nan.exr") && m.contains("NaN") && m.contains("(1, 0)"),
        "{m}"
    );
    let m = message(load(&ok, None, Some(&big)));
    assert!(
        m.contains("big.exr") && m.contains("1.5") && m.contains("(2, 0)"),
        "{m}"
    );
    let m = message(load(&ok, Some(&missing), None));
    assert!(m.contains("missing.png"), "{m}");
    assert!(!m.contains('\n'), "one line: {m}");

    // Zero size and duplicate names are caught when assembling in memory
    // (image encoders refuse to write empty images).
    let empty = Texture::filled(0, 0, 3, 0.0);
    assert!(matches!(
        Exemplar::new(empty, SampleFormat::U8, vec![], flat_feature(1, 1, 0.0)),
        Err(ExemplarError::Image(ImageError::ZeroSize { .. }))
    ));
    let extra = || ExtraChannel {
        name: "d".into(),
        texture: Texture::filled(2, 2, 1, 0.0),
        format: SampleFormat::U8,
    };
    assert!(matches!(
        Exemplar::new(
            Texture::filled(2, 2, 3, 0.0),
            SampleFormat::U8,
            vec![extra(), extra()],
            flat_feature(2, 2, 0.0)
        ),
        Err(ExemplarError::DuplicateChannel { .. })
    ));
    assert!(matches!(
        FeatureMap::new(Texture::filled(2, 2, 3, 0.5), FeatureOrigin::Builtin, "rgb"),
        Err(ExemplarError::FeatureChannels { channels: 3, .. })
    ));
    // A struct literal with a wrong data length is rejected, not sampled.
    let broken = Texture {
        width: 2,
        height: 2,
        channels: 3,
        data: vec![0.0; 5],
    };
    assert!(matches!(
        Exemplar::new(broken, SampleFormat::U8, vec![], flat_feature(2, 2, 0.0)),
        Err(ExemplarError::Layout { .. })
    ));
    let bad = DistanceParams {
        relative_prominence: 2.0,
        ..Default::default()
    };
    let m = feature::derive(&Texture::filled(2, 2, 1, 0.0), FeatureMethod::Auto, &bad)
        .expect_err("invalid parameter")
        .to_string();
    assert!(m.contains("relative_prominence") && m.contains('2'), "{m}");
}

// ----------------------------------------------------------------- pebbles

/// How the difference across the wrap seam compares with the differences
/// between interior neighbours: the seam column's (row's) summed absolute
/// difference divided by the largest interior column (row) difference. A
/// tileable image is at most 1 (its seam is just another column pair); a
/// crop of a larger image is well above.
fn seam_ratio(t: &Texture) -> (f64, f64) {
    let (w, h) = (t.width, t.height);
    let diff = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs() as f64)
            .sum::<f64>()
    };
    let column = |x0: u32, x1: u32| {
        (0..h)
            .map(|y| diff(t.texel(x0, y), t.texel(x1, y)))
            .sum::<f64>()
    };
    let row = |y0: u32, y1: u32| {
        (0..w)
            .map(|x| diff(t.texel(x, y0), t.texel(x, y1)))
            .sum::<f64>()
    };
    let worst_column = (0..w - 1).map(|x| column(x, x + 1)).fold(0.0, f64::max);
    let worst_row = (0..h - 1).map(|y| row(y, y + 1)).fold(0.0, f64::max);
    (column(w - 1, 0) / worst_column, row(h - 1, 0) / worst_row)
}

#[test]
fn pebbles_tile_seamlessly() {
    let p = builtin_pebbles(256, 3);
    for t in [&p.colour, &p.feature.map] {
        let (rx, ry) = seam_ratio(t);
        assert!(rx <= 1.0 && ry <= 1.0, "seams visible: {rx:.2}, {ry:.2}");
    }
    // Known-bad control: a crop of a larger photograph does not tile.
    let gravel = crate::io::image_read::read_image(&data_dir().join("gravel.png")).expect("gravel");
    let (rx, ry) = seam_ratio(&gravel.texture);
    assert!(
        rx > 1.0 && ry > 1.0,
        "control should show seams: {rx:.2}, {ry:.2}"
    );
}

#[test]
fn pebbles_are_deterministic_across_seeds_and_threads() {
    let a = builtin_pebbles(128, 9);
    let b = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .expect("pool")
        .install(|| builtin_pebbles(128, 9));
    assert_eq!(a, b);
    assert_ne!(a.colour, builtin_pebbles(128, 10).colour);
    // Sizes other than powers of two work too.
    assert_eq!(builtin_pebbles(100, 9).colour.width, 100);
    assert_eq!(builtin_pebbles(0, 9).colour.width, 8, "size clamped");
}

#[test]
fn pebble_feature_map_follows_stones() {
    let layout = pebbles::pebbles_with_masks(256, 5);
    let f = &layout.exemplar.feature.map.data;
    let stones = layout
        .stone
        .iter()
        .filter(|&&s| s != pebbles::CREVICE)
        .count();
    let crevices = layout.stone.len() - stones;
    assert!(
        crevices > layout.stone.len() / 50,
        "crevices exist: {crevices}"
    );
    assert!(stones > layout.stone.len() / 2, "stones dominate: {stones}");
    let mut peak = std::collections::BTreeMap::<u32, f32>::new();
    let mut inside = 0.0f64;
    for (&s, &v) in layout.stone.iter().zip(f) {
        if s == pebbles::CREVICE {
            assert_eq!(v, 0.0, "crevices are 0");
        } else {
            assert!(v > 0.0, "stone texels are above 0");
            inside += v as f64;
            let e = peak.entry(s).or_insert(0.0);
            *e = e.max(v);
        }
    }
    assert!(
        inside / stones as f64 > 0.5,
        "mean height inside stones {}",
        inside / stones as f64
    );
    assert!(peak.len() >= 40, "{} stones", peak.len());
    assert!(
        peak.values().all(|&p| p == 1.0),
        "every stone peaks at 1: {peak:?}"
    );
    assert_eq!(layout.exemplar.feature.origin, FeatureOrigin::Builtin);
}

// ------------------------------------------------------- derived features

/// Discs of radius `r` at `centres` (texel units) on a 96×80 torus,
/// `inside` within, `outside` elsewhere.
fn discs(centres: &[(f32, f32)], r: f32, inside: f32, outside: f32) -> Texture {
    let (w, h) = (96u32, 80u32);
    let mut t = Texture::filled(w, h, 1, outside);
    for y in 0..h {
        for x in 0..w {
            if disc_distance(centres, x, y, w, h) < r {
                t.texel_mut(x, y)[0] = inside;
            }
        }
    }
    t
}

/// Toroidal distance from texel centre (x, y) to the nearest disc centre.
fn disc_distance(centres: &[(f32, f32)], x: u32, y: u32, w: u32, h: u32) -> f32 {
    centres
        .iter()
        .map(|&(cx, cy)| {
            let dx = (x as f32 + 0.5 - cx).abs();
            let dy = (y as f32 + 0.5 - cy).abs();
            let (dx, dy) = (dx.min(w as f32 - dx), dy.min(h as f32 - dy));
            (dx * dx + dy * dy).sqrt()
        })
        .fold(f32::INFINITY, f32::min)
}

#[test]
fn distance_feature_of_discs_peaks_at_centres() {
    // Different radii are fine as each disc is normalised on its own; one
    // disc straddles the corner of the torus.
    let centres = [(24.0, 20.0), (70.0, 30.0), (40.0, 60.0), (1.0, 2.0)];
    let r = 11.0;
    for (inside, outside) in [(0.8, 0.2), (0.1, 0.9)] {
        let t = discs(&centres, r, inside, outside);
        let d =
            feature::derive(&t, FeatureMethod::Auto, &DistanceParams::default()).expect("derives");
        assert_eq!(
            d.map.origin,
            FeatureOrigin::Derived(FeatureMethod::DistanceTransform),
            "polarity {inside}"
        );
        let f = &d.map.map;
        for &(cx, cy) in &centres {
            // The maximum within the disc is 1 and within 1 texel of the centre.
            let mut best = (f32::MIN, 0.0f32);
            for y in 0..f.height {
                for x in 0..f.width {
                    let dist = disc_distance(&[(cx, cy)], x, y, f.width, f.height);
                    if dist < r && f.texel(x, y)[0] > best.0 {
                        best = (f.texel(x, y)[0], dist);
                    }
                }
            }
            assert_eq!(best.0, 1.0, "disc at ({cx}, {cy}) peaks at 1");
            assert!(best.1 <= 1.0, "peak {:.2} texels from the centre", best.1);
        }
        for y in 0..f.height {
            for x in 0..f.width {
                let dist = disc_distance(&centres, x, y, f.width, f.height);
                let v = f.texel(x, y)[0];
                if dist > r + 1.0 {
                    assert_eq!(v, 0.0, "outside at ({x}, {y})");
                } else if dist < r - 1.5 {
                    // Inside, the map falls off linearly from the centre.
                    let expected = 1.0 - dist / r;
                    assert!((v - expected).abs() < 0.2, "({x},{y}): {v} vs {expected}");
                }
            }
        }
    }
}

#[test]
fn auto_chooses_by_separability() {
    let load = |name: &str| {
        crate::io::image_read::read_image(&data_dir().join(format!("{name}.png"))).expect(name)
    };
    let p = DistanceParams::default();
    let chosen = |name: &str| {
        let d = feature::derive(&load(name).texture, FeatureMethod::Auto, &p).expect("derives");
        (d.map.origin, d.separability)
    };
    let (brick, eta) = chosen("brick");
    assert_eq!(
        brick,
        FeatureOrigin::Derived(FeatureMethod::DistanceTransform),
        "η = {eta}"
    );
    let (grass, eta) = chosen("grass");
    assert_eq!(
        grass,
        FeatureOrigin::Derived(FeatureMethod::Luminance),
        "η = {eta}"
    );
    // Noise has no two classes.
    let mut rng = Pcg64::seed_from_u64(1);
    let noise: Vec<f32> = (0..64 * 64).map(|_| rng.random::<f32>()).collect();
    let t = Texture::from_data(64, 64, 1, noise).expect("sizes");
    let d = feature::derive(&t, FeatureMethod::Auto, &p).expect("derives");
    assert_eq!(
        d.map.origin,
        FeatureOrigin::Derived(FeatureMethod::Luminance)
    );
    // A constant image has nothing to threshold: luminance even when asked.
    let d = feature::derive(
        &Texture::filled(8, 8, 3, 0.5),
        FeatureMethod::DistanceTransform,
        &p,
    )
    .expect("derives");
    assert_eq!(
        d.map.origin,
        FeatureOrigin::Derived(FeatureMethod::Luminance)
    );
}

#[test]
fn derived_maps_are_valid_and_tile() {
    let gravel = crate::io::image_read::read_image(&data_dir().join("gravel.png")).expect("gravel");
    for method in [FeatureMethod::Luminance, FeatureMethod::DistanceTransform] {
        let d =
            feature::derive(&gravel.texture, method, &DistanceParams::default()).expect("derives");
        feature::check_map(&d.map.map, "derived").expect("in [0, 1], one channel");
        assert_eq!((d.map.map.width, d.map.map.height), (512, 512));
    }
    // The pebbles' colour → distance map must tile as the colour does.
    let p = builtin_pebbles(128, 2);
    let d = feature::derive(
        &p.colour,
        FeatureMethod::DistanceTransform,
        &DistanceParams::default(),
    )
    .expect("derives");
    let (rx, ry) = seam_ratio(&d.map.map);
    assert!(rx <= 1.0 && ry <= 1.0, "derived map seams: {rx:.2} {ry:.2}");
}
