//! Tests of the footprint post-pass: the level of known uv maps, a
//! minified checker that must keep its mean and lose its aliasing, thread
//! independence, and less popping on a rigid rotation through the erosion
//! method.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::Arc;

use glam::{Mat2, Vec2};

use super::*;
use crate::exemplar::ExemplarFilter;
use crate::methods::test_clip::grey_exemplar;

/// A `size`² grey checker of `square`-texel squares, 0 and 1.
fn checker(size: u32, square: u32) -> Exemplar {
    grey_exemplar(size, |x, y| ((x / square + y / square) % 2) as f32)
}

/// Fill buffers of a `w × h` atlas covered by source 1 with the affine uv
/// map `uv = origin + m · (x + ½, y + ½)` and the values the lapped fill
/// writes there (bilinear at level 0).
fn affine(w: u32, h: u32, m: Mat2, origin: Vec2, ex: &Exemplar) -> FillBuffers {
    let mut out = FillBuffers::new(w, h, ex.total_channels());
    let c = out.channels;
    for y in 0..h as usize {
        for x in 0..w as usize {
            let t = y * w as usize + x;
            let uv = origin + m * Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            out.uv[t] = uv;
            out.source[t] = 1;
            ex.sample_all(uv.x, uv.y, &mut out.values[t * c..(t + 1) * c]);
        }
    }
    out
}

fn mean_var(values: &[f32]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    let var = values
        .iter()
        .map(|&v| (f64::from(v) - mean).powi(2))
        .sum::<f64>()
        / n;
    (mean, var)
}

#[test]
fn footprint_of_an_affine_map_gives_its_level() {
    let ex = checker(256, 2);
    // Columns of the Jacobian in exemplar texels per atlas texel: lengths
    // 8 (rotated) and 2, so the level is log2(8) = 3 everywhere.
    let (s, co) = 0.3f32.sin_cos();
    let m = Mat2::from_cols(Vec2::new(co, s) * 8.0, Vec2::new(-s, co) * 2.0) / 256.0;
    let mut out = affine(16, 12, m, Vec2::new(0.1, 0.7), &ex);
    let lod = apply_footprint_filtering(&mut out, &ex).expect("trilinear by default");
    for (t, &l) in lod.iter().enumerate() {
        assert!((l - 3.0).abs() < 1e-3, "texel {t}: {l}");
    }
    // Magnified (half a texel per atlas texel): level 0.
    let mut out = affine(8, 8, Mat2::IDENTITY * (0.5 / 256.0), Vec2::ZERO, &ex);
    let lod = apply_footprint_filtering(&mut out, &ex).expect("trilinear");
    assert!(lod.iter().all(|&l| l == 0.0), "{lod:?}");
}

#[test]
fn footprint_ignores_other_sources_and_seams() {
    let ex = checker(64, 2);
    let m = Mat2::IDENTITY * (4.0 / 64.0);
    let mut out = affine(12, 6, m, Vec2::ZERO, &ex);
    let w = 12;
    // Columns 6.. are another chart showing the same patch far away (a
    // seam: the uv jumps by 0.37), and row 0 belongs to another patch
    // whose uv is unrelated.
    for y in 0..6 {
        for x in 6..12 {
            out.uv[y * w + x] += Vec2::new(0.37, 0.0);
        }
    }
    for x in 0..w {
        out.source[x] = 2;
        out.uv[x] = Vec2::new(0.9, 0.1) * x as f32;
    }
    // A texel outside the charts, and one alone in its patch.
    out.source[5 * w + 11] = OUTSIDE;
    out.source[3 * w] = 3;
    let lod = apply_footprint_filtering(&mut out, &ex).expect("trilinear");
    for y in 1..6 {
        for x in 0..w {
            let t = y * w + x;
            match (out.source[t], x, y) {
                (OUTSIDE, ..) => assert!(lod[t].is_nan()),
                (3, ..) => assert_eq!(lod[t], 0.0, "isolated texel"),
                _ => assert!((lod[t] - 2.0).abs() < 1e-4, "texel ({x}, {y}): {}", lod[t]),
            }
        }
    }
    // Row 0 (its own patch, one row high) takes its horizontal step for
    // the missing vertical one: |(0.9, 0.1)| · 64 texels.
    let want = (Vec2::new(0.9, 0.1) * 64.0).length().log2();
    for (x, l) in lod[..w].iter().enumerate() {
        assert!((l - want).abs() < 1e-4, "row 0, x {x}: {l}");
    }
}

/// A 256² checker of 2-texel squares shown at 8 exemplar texels per atlas
/// texel (rotated, so point samples do not fall on a lattice of the
/// checker): the filtered atlas keeps the checker's mean within 1 % and
/// has almost no per-texel variance left; read at level 0 the same atlas
/// is aliased noise.
#[test]
fn minified_checker_keeps_its_mean_and_loses_its_aliasing() {
    let ex = checker(256, 2);
    let (s, co) = 0.37f32.sin_cos();
    let m = Mat2::from_cols(Vec2::new(co, s), Vec2::new(-s, co)) * (8.0 / 256.0);
    let mut out = affine(96, 96, m, Vec2::new(0.013, 0.029), &ex);
    let (point_mean, point_var) = mean_var(&out.values);
    apply_footprint_filtering(&mut out, &ex).expect("trilinear");
    let (mean, var) = mean_var(&out.values);
    eprintln!(
        "checker at 8 texels/texel: level 0 mean {point_mean:.4} var {point_var:.4}; \
         filtered mean {mean:.4} var {var:.2e}"
    );
    assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
    // The control aliases: bilinear point samples of this checker have a
    // variance of ≈ 0.11 wherever they fall.
    assert!(point_var > 0.08, "level-0 variance {point_var}");
    assert!(
        var < 0.01 * point_var,
        "filtered variance {var} vs {point_var}"
    );
}

#[test]
fn unfiltered_exemplars_are_left_as_the_fill_wrote_them() {
    let ex = checker(64, 2).with_filter(ExemplarFilter::Unfiltered);
    let m = Mat2::IDENTITY * (8.0 / 64.0);
    let mut out = affine(10, 10, m, Vec2::ZERO, &ex);
    let before = out.values.clone();
    assert_eq!(apply_footprint_filtering(&mut out, &ex), None);
    assert_eq!(out.values, before);
}

/// The pass computes its levels tile by tile, each neighbour difference
/// once; they must be [`texel_lod`]'s bit for bit. Random atlases that
/// span several tiles and bands and end mid-tile, with runs of one source
/// (outside, uncovered, three patches, one of them on a larger exemplar),
/// uv seams, and infinite or NaN uvs.
#[test]
fn tile_levels_are_the_per_texel_levels() {
    use rand::{Rng, SeedableRng};
    let small = checker(16, 2);
    let large = checker(64, 2);
    let exemplar_of = |s: u32| if s == 3 { &large } else { &small };
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let (mut positive, mut zero, mut none) = (0, 0, 0);
    for (w, h) in [
        (1u32, 1u32),
        (150, 37),
        (64, 16),
        (65, 17),
        (3, 40),
        (200, 3),
    ] {
        let mut out = FillBuffers::new(w, h, 1);
        let (mut s, mut p) = (1u32, Vec2::ZERO);
        for t in 0..(w * h) as usize {
            if rng.random_bool(0.15) {
                s = [OUTSIDE, UNCOVERED, 1, 2, 3][rng.random_range(0..5)];
            }
            p += Vec2::new(rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2));
            if rng.random_bool(0.05) {
                p = Vec2::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
            }
            out.source[t] = s;
            out.uv[t] = match rng.random_range(0..40) {
                0 => Vec2::new(f32::NAN, p.y),
                1 => Vec2::new(p.x, f32::INFINITY),
                _ => p,
            };
        }
        let mut dropped = FillBuffers::new(w, h, 1);
        dropped.source.clone_from(&out.source);
        dropped.uv.clone_from(&out.uv);
        let lods =
            apply_footprint_filtering_by(&mut out, ExemplarFilter::Trilinear, Levels::Keep, |s| {
                exemplar_of(s)
            })
            .expect("trilinear");
        // Levels kept per tile only: the same values, no levels returned.
        let none_kept = apply_footprint_filtering_by(
            &mut dropped,
            ExemplarFilter::Trilinear,
            Levels::Drop,
            |s| exemplar_of(s),
        );
        assert!(none_kept.is_none(), "{w}x{h}");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&out.values), bits(&dropped.values), "{w}x{h}");
        for y in 0..h as usize {
            for x in 0..w as usize {
                let t = y * w as usize + x;
                let (ew, eh) = exemplar_of(out.source[t]).size();
                let texels = Vec2::new(ew as f32, eh as f32);
                let want = texel_lod(&out.source, &out.uv, w as usize, x, y, texels);
                match want {
                    None => {
                        none += 1;
                        assert!(lods[t].is_nan(), "{w}x{h} ({x}, {y}): {}", lods[t]);
                    }
                    Some(l) => {
                        if l > 0.0 {
                            positive += 1
                        } else {
                            zero += 1
                        }
                        assert_eq!(lods[t].to_bits(), l.to_bits(), "{w}x{h} ({x}, {y})");
                    }
                }
            }
        }
    }
    // Every kind of answer occurred.
    assert!(
        positive > 1000 && zero > 100 && none > 1000,
        "{positive} {zero} {none}"
    );
}

/// Whatever the channel count (the pass has a loop of its own for each of
/// 1 to 4 channels and a general one), every texel with a level holds the
/// general lookup at that level, bit for bit, and every other texel keeps
/// what the fill wrote.
#[test]
fn every_channel_count_holds_the_general_lookup_at_its_level() {
    use crate::methods::test_clip::noise_exemplar;
    let (w, h) = (70u32, 24u32);
    for total in 1..=5usize {
        let small = noise_exemplar(16, total, 1);
        let large = noise_exemplar(64, total, 2);
        let exemplar_of = |s: u32| if s == 2 { &large } else { &small };
        let mut out = FillBuffers::new(w, h, total);
        for y in 0..h as usize {
            // uv steps from 0.01 to 0.09 a texel down the rows: levels 0
            // and above on both exemplars.
            let step = 0.01 * 1.1f32.powi(y as i32);
            for x in 0..w as usize {
                let t = y * w as usize + x;
                out.source[t] = match x {
                    0..30 => 1,
                    30..60 => 2,
                    _ if y % 2 == 0 => OUTSIDE,
                    _ => UNCOVERED,
                };
                out.uv[t] = Vec2::new(x as f32 * step, y as f32 * step * 0.7 + x as f32 * 0.003);
                for (k, v) in out.values[t * total..(t + 1) * total]
                    .iter_mut()
                    .enumerate()
                {
                    *v = 7.0 + (t * total + k) as f32;
                }
            }
        }
        let before = out.values.clone();
        let lods =
            apply_footprint_filtering_by(&mut out, ExemplarFilter::Trilinear, Levels::Keep, |s| {
                exemplar_of(s)
            })
            .expect("trilinear");
        let (mut positive, mut zero) = (0, 0);
        for (t, &lod) in lods.iter().enumerate() {
            let got = &out.values[t * total..(t + 1) * total];
            if lod.is_nan() {
                assert_eq!(
                    got,
                    &before[t * total..(t + 1) * total],
                    "{total} channels, texel {t}"
                );
                continue;
            }
            if lod > 0.0 {
                positive += 1;
            } else {
                zero += 1;
            }
            let mut want = vec![0.0f32; total];
            let p = out.uv[t];
            exemplar_of(out.source[t]).sample_all_lod(p.x, p.y, lod, &mut want);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(got),
                bits(&want),
                "{total} channels, texel {t}, lod {lod}"
            );
        }
        assert!(positive > 300 && zero > 100, "{total}: {positive} {zero}");
    }
}

#[test]
fn one_and_two_threads_give_identical_results() {
    let ex = crate::exemplar::builtin_pebbles(128, 3);
    let m = Mat2::from_cols(Vec2::new(3.0, 1.0), Vec2::new(-0.5, 2.0)) / 128.0;
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let mut out = affine(64, 48, m, Vec2::new(0.2, 0.4), &ex);
            let lod = apply_footprint_filtering(&mut out, &ex).expect("trilinear");
            (
                out.values,
                lod.iter().map(|l| l.to_bits()).collect::<Vec<_>>(),
            )
        })
    };
    assert!(run(1) == run(2));
}

/// A minified exemplar on the rigid rotation, through the erosion method
/// and the harness: read at level 0 the atlas is noise that changes every
/// frame; filtered, popping (changes under the true motion) must drop.
#[test]
fn filtering_lowers_popping_on_a_rigid_rotation() {
    use crate::eval::{EvalSettings, evaluate, prepare};
    use crate::methods::erosion::{Erosion, ErosionParams};
    use crate::metrics::{Metric, Thresholds};

    let name = "rigid-rotation";
    let mut params = crate::scenes::default_params(name).unwrap();
    params.resolution = 16;
    params.first = 0;
    params.last = 3;
    let mut scene = crate::scenes::by_name(name, Some(params)).unwrap();
    let settings = EvalSettings {
        render_size: 96,
        view_dir: crate::eval::default_view(name),
        fidelity_every: 100,
        ..Default::default()
    };
    let thresholds = Thresholds::committed().unwrap();
    let atlas = crate::atlas::AtlasParams::square(128);
    let prepared = prepare(
        scene.as_mut(),
        &[0, 1, 2, 3],
        &atlas,
        &settings,
        &thresholds,
    )
    .unwrap();
    let pebbles = crate::exemplar::builtin_pebbles(512, 1);
    let colour = pebbles.colour.clone();
    // The exemplar spans a small world size: ~8 exemplar texels per atlas
    // texel.
    let texel = 1.0 / prepared.frames[0].geometry.atlas.scale as f32;
    let erosion = ErosionParams {
        exemplar_size: Some(512.0 / 8.0 * texel),
        // Small patches on this coarse sphere: many patch borders in view.
        radius_edges: 0.0,
        ..Default::default()
    };
    let run = |filter: ExemplarFilter| {
        let ex = Arc::new(pebbles.clone().with_filter(filter));
        let mut m = Erosion::new(erosion.clone(), ex, 0).unwrap();
        evaluate(&prepared, &mut m, &colour, &settings, &thresholds).unwrap()
    };
    let filtered = run(ExemplarFilter::Trilinear);
    let point = run(ExemplarFilter::Unfiltered);
    let popping = |r: &crate::eval::MethodRun| r.summary(Metric::Popping).unwrap().mean;
    let contrast = |r: &crate::eval::MethodRun| r.summary(Metric::Contrast).unwrap().min;
    eprintln!(
        "rigid rotation, pebbles at 8 texels/texel: popping {:.4} filtered vs {:.4} level 0; \
         contrast {:.3} vs {:.3} (sigma shown by lod in quarters {:.3?})",
        popping(&filtered),
        popping(&point),
        contrast(&filtered),
        contrast(&point),
        crate::metrics::exemplar_sigma_by_lod(&colour)
    );
    assert!(
        popping(&filtered) < 0.5 * popping(&point),
        "{} vs {}",
        popping(&filtered),
        popping(&point)
    );
}

/// The minified checker through the erosion method itself: the chart
/// texels' mean stays within 1 % of the checker's and their variance
/// collapses; read at level 0 (the control) they keep most of it.
#[test]
fn erosion_atlas_of_a_minified_checker_keeps_its_mean() {
    use crate::atlas::{Atlas, AtlasParams};
    use crate::methods::erosion::{Erosion, ErosionParams};
    use crate::methods::{FrameContext, Method, PreviousFrame};
    use crate::surface::SurfaceIndex;

    let name = "rigid-rotation";
    let mut params = crate::scenes::default_params(name).unwrap();
    params.resolution = 16;
    params.last = params.first + 1;
    let mut scene = crate::scenes::by_name(name, Some(params)).unwrap();
    let meshes: Vec<_> = (params.first..=params.last)
        .map(|f| scene.frame(f).unwrap())
        .collect();
    let indices: Vec<_> = meshes.iter().map(SurfaceIndex::new).collect();
    let atlases: Vec<_> = meshes
        .iter()
        .map(|m| Atlas::build(m, &AtlasParams::square(128)).unwrap())
        .collect();
    // 256² checker of 2-texel squares at 8 exemplar texels per atlas texel.
    let erosion = ErosionParams {
        exemplar_size: Some(32.0 / atlases[0].scale as f32),
        ..Default::default()
    };
    let run = |filter: ExemplarFilter| {
        let ex = Arc::new(checker(256, 2).with_filter(filter));
        let mut m = Erosion::new(erosion.clone(), ex, 4).unwrap();
        let mut last = None;
        for k in 0..meshes.len() {
            let ctx = FrameContext {
                number: k as i32,
                dt: 1.0 / 24.0,
                mesh: &meshes[k],
                topology: &crate::mesh::Topology::new(
                    meshes[k].vertex_count(),
                    &meshes[k].triangles,
                ),
                normals: &meshes[k].vertex_normals(),
                index: &indices[k],
                previous: (k > 0).then(|| PreviousFrame {
                    mesh: &meshes[k - 1],
                    index: &indices[k - 1],
                }),
                atlas: &atlases[k],
                arena: &crate::methods::arena::FRESH,
            };
            last = Some(m.step(&ctx).unwrap());
        }
        let r = last.unwrap();
        let source = r.source.as_deref().unwrap();
        let values: Vec<f32> = source
            .iter()
            .zip(&r.channels[0].data)
            .filter(|(s, _)| **s != OUTSIDE)
            .map(|(_, &v)| v)
            .collect();
        let lods: Vec<f32> = r.exemplar_lod.iter().flatten().copied().collect();
        (mean_var(&values), lods)
    };
    let ((mean, var), lods) = run(ExemplarFilter::Trilinear);
    let ((point_mean, point_var), none) = run(ExemplarFilter::Unfiltered);
    let mut finite: Vec<f32> = lods.into_iter().filter(|l| l.is_finite()).collect();
    finite.sort_by(f32::total_cmp);
    let median = finite[finite.len() / 2];
    eprintln!(
        "erosion, checker at 8 texels/texel: median lod {median:.2}; filtered mean {mean:.4} \
         var {var:.2e}; level 0 mean {point_mean:.4} var {point_var:.4}"
    );
    assert!(none.is_empty(), "unfiltered runs report no levels");
    assert!((median - 3.0).abs() < 0.25, "median lod {median}");
    assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
    assert!(point_var > 0.08, "level-0 variance {point_var}");
    assert!(
        var < 0.05 * point_var,
        "filtered variance {var} vs {point_var}"
    );
}
