use std::path::{Path, PathBuf};

use image::{ImageBuffer, Luma, Rgb};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use super::*;
use crate::exemplar::feature::FeatureMethod;

/// Writes an RGB frame of `w × h` whose red is `level` at `path`.
fn frame(path: &Path, w: u32, h: u32, level: u8) {
    ImageBuffer::from_fn(w, h, |x, y| {
        Rgb([level, (x * 7 % 256) as u8, (y * 5 % 256) as u8])
    })
    .save(path)
    .expect("frame written");
}

/// A sequence `wave.0001.png` ... of `count` 16×16 frames in `dir`.
fn sequence(dir: &Path, count: u32) -> PathBuf {
    for k in 1..=count {
        frame(
            &dir.join(format!("wave.{k:04}.png")),
            16,
            16,
            (k * 20) as u8,
        );
    }
    dir.join("wave.####.png")
}

fn files(colour: &Path) -> SequenceFiles<'_> {
    SequenceFiles {
        colour,
        channels: &[],
        feature: None,
    }
}

fn load(files: &SequenceFiles<'_>) -> Result<(Vec<Exemplar>, u64), ExemplarError> {
    load_sequence(
        files,
        FeatureMethod::Luminance,
        SequenceBudget::default(),
        0,
    )
}

#[test]
fn frame_index_is_floor_of_time_times_rate_plus_phase_mod_length() {
    let c = |rate| ExemplarClock::new(rate).expect("rate");
    // Exact cases of ⌊t·rate + φ⌋ mod n.
    assert_eq!(c(1.0).frame(0, 0.0, 8), 0);
    assert_eq!(c(1.0).frame(5, 0.0, 8), 5);
    assert_eq!(c(1.0).frame(9, 0.0, 8), 1);
    assert_eq!(c(1.0).frame(3, 6.5, 8), 1); // ⌊9.5⌋ = 9 → 1
    assert_eq!(c(0.5).frame(3, 0.0, 8), 1); // ⌊1.5⌋
    assert_eq!(c(0.5).frame(3, 0.6, 8), 2); // ⌊2.1⌋
    assert_eq!(c(2.0).frame(7, 1.0, 8), 7); // ⌊15⌋ mod 8
    assert_eq!(c(-1.0).frame(1, 0.0, 8), 7); // ⌊−1⌋ mod 8, never negative
    assert_eq!(c(1.0).frame(-3, 0.0, 8), 5); // Houdini pre-roll frames
    assert_eq!(c(0.0).frame(100, 3.9, 8), 3); // a frozen animation
    assert_eq!(c(1.0).frame(4, 2.0, 1), 0); // a still exemplar
    // Seeded random cases against the formula in exact arithmetic.
    let mut rng = Pcg64::seed_from_u64(17);
    for _ in 0..2000 {
        let n = rng.random_range(1..40u32);
        let rate = rng.random_range(-4..=4) as f32 * 0.25;
        let t = rng.random_range(-500..500);
        let phase = ExemplarClock::phase(rng.random(), rng.random(), n);
        assert!((0.0..f64::from(n)).contains(&phase), "phase {phase} of {n}");
        let want = (f64::from(t) * f64::from(rate) + phase).floor() as i64;
        let got = c(rate).frame(t, phase, n);
        assert_eq!(
            i64::from(got),
            want.rem_euclid(i64::from(n)),
            "t {t} rate {rate}"
        );
    }
}

#[test]
fn phases_are_seeded_per_patch_and_spread_over_the_sequence() {
    // Same seed and key: same phase; another seed or key: another one.
    assert_eq!(
        ExemplarClock::phase(3, 10, 16),
        ExemplarClock::phase(3, 10, 16)
    );
    assert_ne!(
        ExemplarClock::phase(3, 10, 16),
        ExemplarClock::phase(4, 10, 16)
    );
    assert_ne!(
        ExemplarClock::phase(3, 10, 16),
        ExemplarClock::phase(3, 11, 16)
    );
    // Over many patches every frame is a starting frame about as often.
    let mut counts = [0u32; 16];
    for id in 0..16_000 {
        counts[ExemplarClock::phase(9, id, 16) as usize] += 1;
    }
    assert!(
        counts.iter().all(|&c| (800..1200).contains(&c)),
        "{counts:?}"
    );
}

#[test]
fn absurd_rates_are_refused() {
    for rate in [f32::NAN, f32::INFINITY, 1e6, -1e6] {
        let err = ExemplarClock::new(rate).expect_err("refused");
        assert!(err.to_string().contains("exemplar_rate"), "{err}");
    }
}

#[test]
fn a_sequence_loads_every_frame_with_its_pyramid_deferred() {
    let dir = tempfile::tempdir().expect("temp dir");
    let colour = sequence(dir.path(), 5);
    assert!(is_sequence(&colour));
    assert!(!is_sequence(&dir.path().join("wave.0001.png")), "a file");
    let (frames, bytes) = load(&files(&colour)).expect("loads");
    assert_eq!(frames.len(), 5);
    assert!(frames.iter().all(|e| !e.pyramid_built()));
    assert_eq!(
        bytes,
        frames.iter().map(Exemplar::memory_bytes).sum::<u64>()
    );
    // In frame order: frame k's red is 20·k.
    for (k, e) in frames.iter().enumerate() {
        let red = e.colour.data[0];
        assert!(
            (red - (20 * (k + 1)) as f32 / 255.0).abs() < 1e-6,
            "frame {k}"
        );
    }
}

#[test]
fn a_missing_frame_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().expect("temp dir");
    let colour = sequence(dir.path(), 6);
    std::fs::remove_file(dir.path().join("wave.0004.png")).expect("removed");
    let err = load(&files(&colour)).expect_err("gap").to_string();
    assert!(
        err.contains("wave.0004.png") && err.contains("missing"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    // No file at all.
    let none = dir.path().join("none.####.png");
    let err = load(&files(&none)).expect_err("empty").to_string();
    assert!(
        err.contains("none.####.png") && err.contains("no file"),
        "{err}"
    );
}

#[test]
fn a_differently_sized_frame_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().expect("temp dir");
    let colour = sequence(dir.path(), 4);
    frame(&dir.path().join("wave.0003.png"), 16, 12, 9);
    let err = load(&files(&colour)).expect_err("size").to_string();
    assert!(err.contains("wave.0003.png is 16x12"), "{err}");
    assert!(err.contains("wave.0001.png is 16x16"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
}

#[test]
fn feature_and_channel_sequences_follow_the_colour_frames() {
    let dir = tempfile::tempdir().expect("temp dir");
    let colour = sequence(dir.path(), 3);
    for k in 1..=3u32 {
        ImageBuffer::from_fn(16, 16, |_, _| Luma([(k * 60) as u8]))
            .save(dir.path().join(format!("feat.{k:04}.png")))
            .expect("written");
        ImageBuffer::from_fn(16, 16, |_, _| Luma([(k * 30) as u8]))
            .save(dir.path().join(format!("disp.{k:04}.png")))
            .expect("written");
    }
    let feature = dir.path().join("feat.####.png");
    let channels = vec![("displacement".to_string(), dir.path().join("disp.####.png"))];
    let with = SequenceFiles {
        colour: &colour,
        channels: &channels,
        feature: Some(&feature),
    };
    let (frames, _) = load(&with).expect("loads");
    for (k, e) in frames.iter().enumerate() {
        let want = (60 * (k + 1)) as f32 / 255.0;
        assert!(
            (e.feature.map.data[0] - want).abs() < 1e-6,
            "feature of frame {k}"
        );
        let disp = (30 * (k + 1)) as f32 / 255.0;
        assert!(
            (e.channels[0].texture.data[0] - disp).abs() < 1e-6,
            "channel of frame {k}"
        );
    }
    // A plain file serves every frame.
    let still = dir.path().join("feat.0002.png");
    let (frames, _) = load(&SequenceFiles {
        feature: Some(&still),
        ..files(&colour)
    })
    .expect("loads");
    assert!(
        frames
            .iter()
            .all(|e| e.feature.map.data[0] == 120.0 / 255.0)
    );
    // A feature sequence lacking a colour frame's number names the file.
    std::fs::remove_file(dir.path().join("feat.0003.png")).expect("removed");
    let err = load(&with).expect_err("missing feature frame").to_string();
    assert!(
        err.contains("feat.0003.png") && err.contains("missing"),
        "{err}"
    );
}

#[test]
fn a_sequence_over_the_budget_is_refused_before_it_is_loaded() {
    let dir = tempfile::tempdir().expect("temp dir");
    let colour = sequence(dir.path(), 4);
    let (frames, bytes) = load(&files(&colour)).expect("loads");
    let per_frame = frames[0].memory_bytes();
    assert_eq!(bytes, 4 * per_frame);
    let tight = SequenceBudget { bytes };
    assert!(load_sequence(&files(&colour), FeatureMethod::Luminance, tight, 0).is_ok());
    let err = load_sequence(&files(&colour), FeatureMethod::Luminance, tight, 1)
        .expect_err("one byte over")
        .to_string();
    assert!(
        err.contains("wave.####.png: 4 frames") && err.contains("--exemplar-memory"),
        "{err}"
    );
}
