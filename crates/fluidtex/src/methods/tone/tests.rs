use rand::{Rng, SeedableRng};

use super::*;
use crate::exemplar::tone::{ExemplarTone, TONE_LOD_STEP};
use crate::exemplar::{Exemplar, builtin_pebbles};
use crate::methods::test_clip::grey_exemplar;

/// Per-channel mean and population variance of the covered texels.
fn stats(
    values: &[f32],
    source: &[u32],
    c: usize,
    keep: impl Fn(u32) -> bool,
) -> (Vec<f64>, Vec<f64>) {
    let rows: Vec<&[f32]> = values
        .chunks_exact(c)
        .zip(source)
        .filter(|(_, s)| **s != SOURCE_OUTSIDE && **s != SOURCE_UNCOVERED && keep(**s))
        .map(|(v, _)| v)
        .collect();
    let n = rows.len() as f64;
    let mean: Vec<f64> = (0..c)
        .map(|ch| rows.iter().map(|r| f64::from(r[ch])).sum::<f64>() / n)
        .collect();
    let var = (0..c)
        .map(|ch| {
            rows.iter()
                .map(|r| (f64::from(r[ch]) - mean[ch]).powi(2))
                .sum::<f64>()
                / n
        })
        .collect();
    (mean, var)
}

/// A composite of `n` texels read from `exemplar` at seeded random
/// positions and levels in `[0, max_lod]`, one texel in 10 outside the
/// charts and one in 17 uncovered (both holding a marker value).
fn mosaic(
    exemplar: &Exemplar,
    n: usize,
    max_lod: f32,
    seed: u64,
) -> (Vec<f32>, Vec<u32>, Vec<f32>) {
    let c = exemplar.total_channels();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut values = vec![0.0f32; n * c];
    let mut source = vec![0u32; n];
    let mut lods = vec![f32::NAN; n];
    for i in 0..n {
        let v = &mut values[i * c..(i + 1) * c];
        if i % 10 == 3 {
            source[i] = SOURCE_OUTSIDE;
            v.fill(-7.0);
        } else if i % 17 == 5 {
            source[i] = SOURCE_UNCOVERED;
            v.fill(9.0);
        } else {
            source[i] = 1 + rng.random_range(0..5u32);
            lods[i] = rng.random_range(0.0..=max_lod);
            exemplar.sample_all_lod(rng.random(), rng.random(), lods[i], v);
        }
    }
    (values, source, lods)
}

#[test]
fn exemplar_tone_of_a_checker_and_of_a_flat_exemplar() {
    let checker = grey_exemplar(64, |x, y| ((x + y) % 2) as f32);
    let tone = ExemplarTone::of(&checker);
    assert_eq!(tone.mean, vec![0.5]);
    assert_eq!(
        tone.variance_by_lod.len(),
        (checker.max_lod() / TONE_LOD_STEP) as usize + 1
    );
    // A bilinear read of a one-texel checker at offsets (a, b) within a
    // cell is 0.5 ± 0.5 (1 − 2a)(1 − 2b): over evenly spread offsets its
    // variance is 0.25 / 9 = 1/36, not the texels' 0.25. Level 1 and above
    // average each 2 × 2 block to 0.5 exactly.
    let v0 = tone.variance_by_lod[0][0];
    assert!((v0 - 1.0 / 36.0).abs() < 5e-4, "level-0 variance {v0}");
    let mid = tone.variance_by_lod[2][0];
    assert!(mid > 0.0 && mid < v0, "level 0.5 lies between: {mid}");
    for (k, v) in tone.variance_by_lod.iter().enumerate().skip(4) {
        assert!(v[0] < 1e-12, "level {}: {}", k as f32 * TONE_LOD_STEP, v[0]);
    }
    let flat = ExemplarTone::of(&grey_exemplar(32, |_, _| 0.25));
    assert_eq!(flat.mean, vec![0.25]);
    assert!(flat.variance_by_lod.iter().all(|v| v[0] == 0.0));
}

#[test]
fn the_variance_at_a_level_interpolates_the_table() {
    let tone = ExemplarTone {
        mean: vec![0.0, 0.0],
        variance_by_lod: vec![vec![4.0, 1.0], vec![2.0, 1.0], vec![1.0, 0.0]],
    };
    let at = |lod: f32| {
        let mut out = vec![0.0; 2];
        tone.add_variance_at(lod, &mut out);
        out
    };
    assert_eq!(at(0.0), vec![4.0, 1.0]);
    assert_eq!(at(f32::NAN), vec![4.0, 1.0]);
    assert_eq!(at(-3.0), vec![4.0, 1.0]);
    assert_eq!(at(TONE_LOD_STEP / 2.0), vec![3.0, 1.0]);
    assert_eq!(at(TONE_LOD_STEP * 1.5), vec![1.5, 0.5]);
    assert_eq!(at(100.0), vec![1.0, 0.0]);
}

#[test]
fn a_composite_biased_towards_bright_texels_gets_the_exemplar_tone() {
    let exemplar = builtin_pebbles(64, 3);
    let tones = vec![ExemplarTone::of(&exemplar)];
    let c = exemplar.total_channels();
    let (mut values, source, _) = mosaic(&exemplar, 20_000, 0.0, 1);
    // Keep the brighter half of the covered texels, as erosion keeping
    // stone tops does; the others become uncovered.
    let mut firsts: Vec<f32> = values
        .chunks_exact(c)
        .zip(&source)
        .filter(|(_, s)| **s > 0 && **s != SOURCE_OUTSIDE)
        .map(|(v, _)| v[0])
        .collect();
    firsts.sort_by(f32::total_cmp);
    let median = firsts[firsts.len() / 2];
    let source: Vec<u32> = source
        .iter()
        .zip(values.chunks_exact(c))
        .map(|(&s, v)| {
            if s != SOURCE_OUTSIDE && v[0] < median {
                SOURCE_UNCOVERED
            } else {
                s
            }
        })
        .collect();
    let before = values.clone();
    // `mean` shifts each channel to the exemplar's mean and keeps its
    // variance; `off` changes nothing.
    let mut shifted = values.clone();
    let shift = match_tone(Tone::Mean, &mut shifted, c, &source, None, |_| 0, &tones);
    assert!(shift[0].gain.iter().all(|&g| g == 1.0));
    let (mean_before, var_before) = stats(&before, &source, c, |_| true);
    let (mean_shifted, var_shifted) = stats(&shifted, &source, c, |_| true);
    for ch in 0..c {
        assert!((mean_shifted[ch] - tones[0].mean[ch]).abs() < 1e-5);
        assert!((var_shifted[ch] / var_before[ch] - 1.0).abs() < 1e-4);
        assert!(
            mean_before[ch] > tones[0].mean[ch] + 0.02,
            "the composite was biased"
        );
    }
    let mut untouched = values.clone();
    assert!(match_tone(Tone::Off, &mut untouched, c, &source, None, |_| 0, &tones).is_empty());
    assert_eq!(untouched, before);
    let maps = match_tone(Tone::Match, &mut values, c, &source, None, |_| 0, &tones);
    assert_eq!(maps.len(), 1);
    assert!(
        maps[0].mean[0] > tones[0].mean[0] + 0.02,
        "the composite was biased: {:?}",
        maps[0].mean
    );
    let (mean, var) = stats(&values, &source, c, |_| true);
    for ch in 0..c {
        assert!(
            (mean[ch] - tones[0].mean[ch]).abs() < 1e-5,
            "channel {ch}: mean {} vs {}",
            mean[ch],
            tones[0].mean[ch]
        );
        let reference = tones[0].variance_by_lod[0][ch];
        assert!(
            (var[ch] / reference - 1.0).abs() < 1e-4,
            "channel {ch}: variance {} vs {reference}",
            var[ch]
        );
    }
    for ((a, b), s) in values
        .chunks_exact(c)
        .zip(before.chunks_exact(c))
        .zip(&source)
    {
        if *s == SOURCE_OUTSIDE || *s == SOURCE_UNCOVERED {
            assert_eq!(a, b, "a texel without a source is left as it is");
        }
    }
}

#[test]
fn an_honest_mosaic_read_at_its_levels_is_nearly_unchanged() {
    let exemplar = builtin_pebbles(64, 5);
    let tones = vec![ExemplarTone::of(&exemplar)];
    let c = exemplar.total_channels();
    let (values, source, lods) = mosaic(&exemplar, 60_000, 3.0, 2);
    let mut matched = values.clone();
    let maps = match_tone(
        Tone::Match,
        &mut matched,
        c,
        &source,
        Some(&lods),
        |_| 0,
        &tones,
    );
    for ch in 0..c {
        assert!(
            (maps[0].gain[ch] - 1.0).abs() < 0.03,
            "channel {ch}: gain {}",
            maps[0].gain[ch]
        );
        let spread = tones[0].variance_by_lod[0][ch].sqrt();
        assert!(
            (maps[0].mean[ch] - tones[0].mean[ch]).abs() < 0.02 * spread,
            "channel {ch}"
        );
    }
    // Control: judged against level 0 alone, the same mosaic looks too
    // flat and would be stretched.
    let mut flat = values.clone();
    let wrong = match_tone(Tone::Match, &mut flat, c, &source, None, |_| 0, &tones);
    assert!(
        wrong[0].gain.iter().all(|&g| g > 1.08),
        "gains without levels {:?}",
        wrong[0].gain
    );
}

#[test]
fn each_exemplar_is_matched_to_its_own_tone() {
    let dark = grey_exemplar(32, |x, y| 0.1 + 0.1 * ((x * 7 + y * 3) % 5) as f32 / 4.0);
    let light = grey_exemplar(32, |x, y| 0.6 + 0.3 * ((x * 5 + y * 11) % 7) as f32 / 6.0);
    let tones = vec![ExemplarTone::of(&dark), ExemplarTone::of(&light)];
    // Every texel of both groups at 0.5: each group must move to its own mean.
    let n = 1000;
    let source: Vec<u32> = (0..n as u32).map(|i| 1 + i % 4).collect();
    let mut values: Vec<f32> = (0..n)
        .map(|i| 0.45 + 0.1 * (i % 13) as f32 / 12.0)
        .collect();
    let group = |s: u32| (s as usize - 1) % 2;
    let maps = match_tone(Tone::Match, &mut values, 1, &source, None, group, &tones);
    assert_eq!(maps.len(), 2);
    for (g, tone) in tones.iter().enumerate() {
        let (mean, _) = stats(&values, &source, 1, |s| group(s) == g);
        assert!(
            (mean[0] - tone.mean[0]).abs() < 1e-5,
            "exemplar {g}: {} vs {}",
            mean[0],
            tone.mean[0]
        );
    }
    assert!(tones[1].mean[0] - tones[0].mean[0] > 0.4);
}

#[test]
fn the_same_bits_for_one_and_two_threads() {
    let exemplar = builtin_pebbles(32, 7);
    let tones = vec![ExemplarTone::of(&exemplar)];
    let c = exemplar.total_channels();
    // Several chunks, the last one partial.
    let (values, source, lods) = mosaic(&exemplar, 3 * CHUNK + 123, 2.0, 3);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        let mut v = values.clone();
        let maps = pool
            .install(|| match_tone(Tone::Match, &mut v, c, &source, Some(&lods), |_| 0, &tones));
        (v.iter().map(|x| x.to_bits()).collect::<Vec<_>>(), maps)
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one, two);
    assert_ne!(
        one.0,
        values.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        "the map changed something"
    );
}

#[test]
fn mismatched_sizes_leave_the_composite_alone() {
    let exemplar = builtin_pebbles(32, 7);
    let tones = vec![ExemplarTone::of(&exemplar)];
    let (values, source, lods) = mosaic(&exemplar, 500, 1.0, 4);
    let c = exemplar.total_channels();
    for (channels, lods) in [(c + 1, Some(&lods[..])), (c, Some(&lods[..10]))] {
        let mut v = values.clone();
        assert!(match_tone(Tone::Match, &mut v, channels, &source, lods, |_| 0, &tones).is_empty());
        assert_eq!(v, values);
    }
    let mut v = values.clone();
    assert!(match_tone(Tone::Match, &mut v, c, &source, None, |_| 0, &[]).is_empty());
    assert_eq!(v, values);
}
