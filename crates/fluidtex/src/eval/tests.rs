//! Harness tests: the report's structure on a known method, the true
//! motion against the analytic rigid rotation, and known-good / known-bad
//! controls for flow, popping and static stop through the whole harness.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::f64::consts::PI;

use glam::{DVec3, Vec2, Vec3};

use super::report::{MethodReport, Report, SceneReport};
use super::*;
use crate::atlas::AtlasParams;
use crate::methods::atlas_check::{AtlasCheck, AtlasCheckParams};
use crate::methods::{
    ChannelFormat, ChannelSpec, FrameContext, FrameResult, SOURCE_OUTSIDE, SOURCE_UNCOVERED,
};
use crate::metrics::Verdict;
use crate::scenes::{self, SceneParams};
use crate::texture::{Texture, Wrap};

/// Rigid rotation of the scene catalogue: ω = π/2 about z through (½,½,½).
const OMEGA: f64 = 0.5 * PI;
const CENTRE: DVec3 = DVec3::new(0.5, 0.5, 0.5);

fn params(name: &str, resolution: u32, first: i32, last: i32) -> SceneParams {
    let mut p = scenes::default_params(name).unwrap();
    p.resolution = resolution;
    p.first = p.first.min(first);
    p.last = p.last.max(last);
    p
}

fn prepared(
    name: &str,
    resolution: u32,
    frames: std::ops::RangeInclusive<i32>,
    atlas: u32,
    render: u32,
) -> (PreparedScene, EvalSettings) {
    let frames: Vec<i32> = frames.collect();
    let mut scene = scenes::by_name(
        name,
        Some(params(name, resolution, frames[0], *frames.last().unwrap())),
    )
    .unwrap();
    let settings = EvalSettings {
        render_size: render,
        view_dir: default_view(name),
        keep_renders: vec![frames[0]],
        ..Default::default()
    };
    let thresholds = Thresholds::committed().unwrap();
    let p = prepare(
        scene.as_mut(),
        &frames,
        &AtlasParams::square(atlas),
        &settings,
        &thresholds,
    )
    .unwrap();
    (p, settings)
}

/// A smooth, non-periodic-looking grey pattern (sum of sinusoids).
fn pattern(size: u32) -> Texture {
    let mut t = Texture::filled(size, size, 1, 0.0);
    for y in 0..size {
        for x in 0..size {
            let (u, v) = (
                x as f32 / size as f32 * std::f32::consts::TAU,
                y as f32 / size as f32 * std::f32::consts::TAU,
            );
            let g = 0.5
                + 0.2 * (3.0 * u + 1.0 * v).sin()
                + 0.15 * (2.0 * u - 5.0 * v).cos()
                + 0.1 * (7.0 * v + 0.3).sin();
            t.texel_mut(x, y)[0] = g;
        }
    }
    t
}

/// Test method: paints the exemplar at uv = the camera-plane coordinates of
/// a point (so the uv map is regular wherever the camera sees the
/// surface). `advect`: the material point under the rigid rotation (a
/// texture that moves exactly with the fluid, the known-good control);
/// otherwise the world point (a texture that stays put). `flicker` adds a
/// per-frame offset (known-bad for static stop).
struct Painted {
    exemplar: Texture,
    right: Vec3,
    up: Vec3,
    /// uv per world unit.
    scale: f32,
    advect: bool,
    flicker: bool,
    fps: f64,
}

impl Method for Painted {
    fn name(&self) -> &'static str {
        "painted"
    }
    fn channel_specs(&self) -> Vec<ChannelSpec> {
        vec![ChannelSpec {
            name: "color".into(),
            format: ChannelFormat::Png8,
        }]
    }
    fn step(&mut self, ctx: &FrameContext<'_>) -> Result<FrameResult, MethodError> {
        let atlas = ctx.atlas;
        let n = atlas.width as usize * atlas.height as usize;
        let mut colour = Texture::filled(atlas.width, atlas.height, 1, 0.0);
        let mut source = vec![SOURCE_OUTSIDE; n];
        let mut uv = vec![Vec2::NAN; n];
        let t = f64::from(ctx.number) / self.fps;
        let w = atlas.width as usize;
        for band in atlas.bands() {
            for span in &band.spans {
                let [a, b, c] = ctx.mesh.corners(span.triangle as usize);
                for (x, bary) in atlas.span_barycentrics(span) {
                    let p = a * bary[0] + b * bary[1] + c * bary[2];
                    let m = if self.advect {
                        let d = p.as_dvec3() - CENTRE;
                        let (s, co) = (-OMEGA * t).sin_cos();
                        (CENTRE + DVec3::new(co * d.x - s * d.y, s * d.x + co * d.y, d.z)).as_vec3()
                    } else {
                        p
                    };
                    let mut q = Vec2::new(m.dot(self.right), m.dot(self.up)) * self.scale;
                    if self.flicker {
                        q.x += 0.01 * ctx.number as f32;
                    }
                    let q = q - q.floor();
                    let i = span.y as usize * w + x as usize;
                    uv[i] = q;
                    source[i] = 1;
                    let mut g = [0.0f32];
                    self.exemplar
                        .sample_bilinear(q.x, q.y, Wrap::Repeat, &mut g);
                    colour.data[i] = g[0];
                }
            }
        }
        Ok(FrameResult {
            channels: vec![colour],
            source: Some(source),
            uv: Some(uv),
            ..Default::default()
        })
    }
    fn save_state(&self) -> Result<Vec<u8>, MethodError> {
        Ok(Vec::new())
    }
    fn load_state(&mut self, _: &[u8]) -> Result<(), MethodError> {
        Ok(())
    }
}

fn painted(scene: &PreparedScene, exemplar: &Texture, advect: bool, flicker: bool) -> Painted {
    let c = &scene.camera;
    let forward = (c.target - c.eye).normalize();
    let right = forward.cross(c.up).normalize();
    let up = right.cross(forward);
    Painted {
        exemplar: exemplar.clone(),
        right,
        up,
        scale: 1.5,
        advect,
        flicker,
        fps: scene.info.fps,
    }
}

fn run(scene: &PreparedScene, method: &mut dyn Method, settings: &EvalSettings) -> MethodRun {
    let thresholds = Thresholds::committed().unwrap();
    evaluate(scene, method, &pattern(128), settings, &thresholds).unwrap()
}

fn verdict(r: &MethodRun, m: Metric) -> Verdict {
    r.summary(m).unwrap().verdict
}

#[test]
fn trace_follows_the_rigid_rotation_exactly() {
    let scene =
        scenes::by_name("rigid-rotation", Some(params("rigid-rotation", 16, 0, 4))).unwrap();
    let p = Vec3::new(0.8, 0.5, 0.55);
    let step = 1.0 / 24.0;
    let q = trace(scene.as_ref(), p, 0.0, step, 4).unwrap();
    let a = OMEGA * step;
    let expected = Vec3::new(
        (0.5 + 0.3 * a.cos()) as f32,
        (0.5 + 0.3 * a.sin()) as f32,
        0.55,
    );
    assert!((q - expected).length() < 1e-6, "{q} vs {expected}");
    // Backwards undoes forwards.
    let back = trace(scene.as_ref(), q, step, -step, 4).unwrap();
    assert!((back - p).length() < 1e-6);
}

#[test]
fn true_motion_of_a_rigid_rotation_is_the_projected_rotation() {
    let (scene, _) = prepared("rigid-rotation", 16, 0..=1, 64, 96);
    let f0 = &scene.frames[0];
    let forward = f0.forward.as_ref().unwrap();
    let dt = 1.0 / scene.info.fps;
    let (s, c) = (OMEGA * dt).sin_cos();
    let mut checked = 0;
    let mut straight_error = 0.0f32;
    for (i, &tri) in f0.gbuffer.triangle.iter().enumerate() {
        if tri == crate::render::BACKGROUND {
            assert!(forward[i].is_nan());
            continue;
        }
        let p = crate::surface::SurfacePoint::new(tri, f0.gbuffer.bary[i])
            .interpolate(&f0.geometry.mesh.triangles, &f0.geometry.mesh.positions);
        let d = p.as_dvec3() - CENTRE;
        let q = (CENTRE + DVec3::new(c * d.x - s * d.y, s * d.x + c * d.y, d.z)).as_vec3();
        let (a, _) = scene.camera.project(p).unwrap();
        let (b, _) = scene.camera.project(q).unwrap();
        let err = (forward[i] - (b - a)).length();
        assert!(err < 2e-3, "pixel {i}: {} vs {}", forward[i], b - a);
        // The first-order motion v·dt misses the arc.
        let v = Vec3::new(-(d.y as f32), d.x as f32, 0.0) * OMEGA as f32;
        let (lin, _) = scene.camera.project(p + v * dt as f32).unwrap();
        straight_error = straight_error.max(((lin - a) - (b - a)).length());
        checked += 1;
    }
    assert!(checked > 1000, "only {checked} pixels on the sphere");
    assert!(
        straight_error > 1e-2,
        "v*dt would be as good: {straight_error}"
    );
    // Backward motion of frame 1 points the other way round.
    let (back, visible) = scene.frames[1].backward.as_ref().unwrap();
    assert!(visible.iter().filter(|&&v| v).count() > checked / 2);
    assert!(back.iter().any(|m| m.length() > 0.5));
}

#[test]
fn atlas_check_report_has_full_coverage_and_every_cell() {
    let (scene, settings) = prepared("rigid-rotation", 16, 0..=2, 64, 64);
    let mut method = AtlasCheck::new(AtlasCheckParams::default()).unwrap();
    let r = run(&scene, &mut method, &settings);
    assert_eq!(r.method, "atlas-check");
    assert_eq!(r.frames.len(), 3);
    assert_eq!(r.summaries.len(), Metric::ALL.len());
    let cov = r.summary(Metric::Coverage).unwrap();
    assert_eq!((cov.frames, cov.max, cov.verdict), (3, 0.0, Verdict::Pass));
    // Never blends: ghost fraction 0 by construction.
    assert_eq!(r.summary(Metric::Ghosting).unwrap().max, 0.0);
    // No uv: no distortion; flow and popping need a previous frame.
    assert_eq!(verdict(&r, Metric::Distortion), Verdict::NoData);
    assert!(r.frames[0].value(Metric::FlowEpe).is_nan());
    assert!(r.frames[0].value(Metric::Popping).is_nan());
    assert!(!r.frames[1].value(Metric::Popping).is_nan());
    // No still frame in a rotation: static stop has no data.
    assert_eq!(verdict(&r, Metric::StaticStop), Verdict::NoData);
    assert_eq!(verdict(&r, Metric::SizeCost), Verdict::NoData);
    assert_eq!(r.renders.len(), 1);
    assert_eq!(r.renders[0].1.width, 64);

    let mr = MethodReport::new(&r, serde_json::json!({"cell": null}));
    let report = Report {
        command: "test".into(),
        atlas_size: 64,
        seed: 0,
        exemplar: "pattern".into(),
        seconds: 0.0,
        scenes: vec![SceneReport::new(
            &scene,
            vec![mr],
            vec![("sheet".into(), "s.png".into())],
        )],
        not_measured: vec![],
    };
    let json: serde_json::Value = serde_json::to_value(&report).unwrap();
    let cells = &json["scenes"][0]["methods"][0]["metrics"];
    assert_eq!(cells.as_array().unwrap().len(), Metric::ALL.len());
    assert_eq!(cells[0]["key"], "coverage");
    assert_eq!(cells[0]["median"], 0.0);
    assert_eq!(cells[0]["pass"], true);
    assert_eq!(
        json["scenes"][0]["methods"][0]["per_frame"]
            .as_array()
            .unwrap()
            .len(),
        3
    );
    let md = report.to_markdown();
    assert!(
        md.contains("| atlas-check | 0 [0, 0] PASS | 0 [0, 0] PASS |"),
        "{md}"
    );
    let html = report.to_html(&Thresholds::committed().unwrap());
    assert_eq!(html.matches("<svg").count(), PER_FRAME.len());
    assert!(html.contains("<img src=\"s.png\">"));
}

#[test]
fn flow_fidelity_passes_a_moving_texture_and_fails_a_fixed_one() {
    let (scene, settings) = prepared("rigid-rotation", 16, 0..=3, 128, 96);
    let exemplar = pattern(128);
    let good = run(
        &scene,
        &mut painted(&scene, &exemplar, true, false),
        &settings,
    );
    let fixed = run(
        &scene,
        &mut painted(&scene, &exemplar, false, false),
        &settings,
    );
    let mut check = AtlasCheck::new(AtlasCheckParams::default()).unwrap();
    let checker = run(&scene, &mut check, &settings);
    let epe = |r: &MethodRun| r.summary(Metric::FlowEpe).unwrap().median;
    assert_eq!(
        verdict(&good, Metric::FlowEpe),
        Verdict::Pass,
        "{}",
        epe(&good)
    );
    assert_eq!(verdict(&good, Metric::FlowAligned), Verdict::Pass);
    assert_eq!(
        verdict(&fixed, Metric::FlowEpe),
        Verdict::Fail,
        "{}",
        epe(&fixed)
    );
    assert_eq!(verdict(&fixed, Metric::FlowAligned), Verdict::Fail);
    assert_eq!(
        verdict(&checker, Metric::FlowEpe),
        Verdict::Fail,
        "{}",
        epe(&checker)
    );
    // A smooth texture that moves exactly does not pop; one that stays put
    // while the surface turns under it does.
    assert_eq!(verdict(&good, Metric::Popping), Verdict::Pass);
    assert_eq!(verdict(&fixed, Metric::Popping), Verdict::Fail);
}

#[test]
fn static_stop_counts_frames_that_change_after_the_fluid_stops() {
    // The stop scene is still from frame 48.
    let (scene, settings) = prepared("stop", 16, 46..=50, 64, 64);
    let still: Vec<bool> = scene.frames.iter().map(|f| f.still).collect();
    assert_eq!(still, [false, false, true, true, true]);
    let exemplar = pattern(64);
    let steady = run(
        &scene,
        &mut painted(&scene, &exemplar, false, false),
        &settings,
    );
    let flicker = run(
        &scene,
        &mut painted(&scene, &exemplar, false, true),
        &settings,
    );
    let s = steady.summary(Metric::StaticStop).unwrap();
    assert_eq!((s.median, s.verdict), (0.0, Verdict::Pass));
    let f = flicker.summary(Metric::StaticStop).unwrap();
    assert_eq!((f.median, f.verdict), (2.0, Verdict::Fail));
    let note = |r: &MethodRun| {
        r.notes
            .iter()
            .find(|n| n.starts_with("static stop"))
            .cloned()
    };
    assert!(note(&flicker).unwrap().ends_with("[49, 50]"));
    assert!(note(&steady).unwrap().ends_with("[]"));
}

#[test]
fn evaluation_is_deterministic() {
    let (scene, settings) = prepared("rigid-rotation", 16, 0..=1, 64, 64);
    let exemplar = pattern(64);
    let a = run(
        &scene,
        &mut painted(&scene, &exemplar, true, false),
        &settings,
    );
    let b = run(
        &scene,
        &mut painted(&scene, &exemplar, true, false),
        &settings,
    );
    for (x, y) in a.frames.iter().zip(&b.frames) {
        let bits = |r: &FrameRecord| r.values.map(f64::to_bits);
        assert_eq!(bits(x), bits(y));
    }
}

#[test]
fn bad_frames_and_settings_are_named() {
    let mut scene = scenes::by_name("stop", Some(params("stop", 16, 0, 84))).unwrap();
    let t = Thresholds::committed().unwrap();
    let atlas = AtlasParams::square(64);
    let s = EvalSettings::default();
    let e = prepare(scene.as_mut(), &[80, 90], &atlas, &s, &t)
        .err()
        .unwrap();
    assert_eq!(
        e.to_string(),
        "scene stop: frame 90 is outside its range 0-84"
    );
    let e = prepare(scene.as_mut(), &[3, 2], &atlas, &s, &t)
        .err()
        .unwrap();
    assert!(e.to_string().contains("increasing"), "{e}");
    let bad = EvalSettings {
        render_size: 8,
        ..Default::default()
    };
    let e = prepare(scene.as_mut(), &[0], &atlas, &bad, &t)
        .err()
        .unwrap();
    assert!(e.to_string().contains("render size = 8"), "{e}");
}

#[test]
fn erosion_follows_a_rigid_rotation_and_the_world_checker_does_not() {
    use crate::methods::erosion::{Erosion, ErosionParams};
    let (scene, settings) = prepared("rigid-rotation", 16, 0..=3, 128, 64);
    let exemplar = crate::exemplar::builtin_pebbles(128, 0);
    let colour = exemplar.colour.clone();
    let thresholds = Thresholds::committed().unwrap();
    let mut erosion =
        Erosion::new(ErosionParams::default(), std::sync::Arc::new(exemplar), 0).unwrap();
    let mut check = AtlasCheck::new(AtlasCheckParams::default()).unwrap();
    let e = evaluate(&scene, &mut erosion, &colour, &settings, &thresholds).unwrap();
    let c = evaluate(&scene, &mut check, &colour, &settings, &thresholds).unwrap();
    let epe = |r: &MethodRun| r.summary(Metric::FlowEpe).unwrap().median;
    let aligned = |r: &MethodRun| r.summary(Metric::FlowAligned).unwrap().median;
    assert_eq!(verdict(&e, Metric::FlowEpe), Verdict::Pass, "{}", epe(&e));
    assert_eq!(verdict(&c, Metric::FlowEpe), Verdict::Fail, "{}", epe(&c));
    // At 64 px the patches are a few pixels wide, so their borders (where
    // the texture is found under another patch, or not at all) keep the
    // aligned share of erosion below 90%; it must still beat the checker.
    assert!(
        aligned(&e) > aligned(&c) + 0.3,
        "{} vs {}",
        aligned(&e),
        aligned(&c)
    );
    assert_eq!(e.summary(Metric::Coverage).unwrap().max, 0.0);
    assert!(e.frames.iter().all(|f| f.patches.is_some_and(|p| p > 0.0)));
}

#[test]
fn colour_follows_a_moving_texture_and_not_a_fixed_one() {
    // 0.065 rad/frame on the rigid rotation: the equator moves ≈ 3.6 texels
    // of the 256² atlas per frame, so the colour follow ratio has points.
    let (scene, settings) = prepared("rigid-rotation", 16, 0..=2, 256, 64);
    let exemplar = pattern(128);
    let good = run(
        &scene,
        &mut painted(&scene, &exemplar, true, false),
        &settings,
    );
    let fixed = run(
        &scene,
        &mut painted(&scene, &exemplar, false, false),
        &settings,
    );
    let follow = |r: &MethodRun| *r.summary(Metric::ColourFollow).unwrap();
    eprintln!(
        "colour follow through the harness: moving {}, fixed {}",
        follow(&good),
        follow(&fixed)
    );
    // Measured: moving 0.0125, fixed 172 (painted in world space, the
    // unmoved colour differs only by the re-meshing's resampling).
    assert!(good.frames[0].value(Metric::ColourFollow).is_nan());
    assert_eq!(follow(&good).frames, 2);
    assert_eq!(follow(&good).verdict, Verdict::Pass);
    assert_eq!(follow(&fixed).verdict, Verdict::Fail);
    // One source everywhere: nothing switches, for either.
    assert_eq!(good.summary(Metric::SourceSwitch).unwrap().max, 0.0);
    assert_eq!(fixed.summary(Metric::SourceSwitch).unwrap().max, 0.0);
}

#[test]
fn source_switch_is_judged_against_advect_on_the_same_frames() {
    let (scene, settings) = prepared("rigid-rotation", 16, 0..=2, 64, 64);
    let exemplar = pattern(64);
    let base = run(
        &scene,
        &mut painted(&scene, &exemplar, true, false),
        &settings,
    );
    let k = PER_FRAME
        .iter()
        .position(|&m| m == Metric::SourceSwitch)
        .unwrap();
    let with_shares = |name: &str, shares: [f64; 3]| {
        let mut r = base.clone();
        r.method = name.into();
        // Without recorded points each run's own share is judged.
        for (f, s) in r.frames.iter_mut().zip(shares) {
            f.values[k] = s;
            f.point_sources.clear();
        }
        r
    };
    let thresholds = Thresholds::committed().unwrap();
    let mut runs = vec![
        with_shares("erosion", [f64::NAN, 0.05, 0.06]),
        with_shares("advect", [f64::NAN, 0.03, 0.03]),
        with_shares("boiling", [f64::NAN, 0.04, 0.2]),
    ];
    judge_against_floor(&mut runs, &thresholds);
    let v = |r: &MethodRun| r.summary(Metric::SourceSwitch).unwrap().verdict;
    // erosion: 2 and 3 points above advect; the second frame fails it.
    assert_eq!(v(&runs[0]), Verdict::Fail);
    assert_eq!(v(&runs[1]), Verdict::Pass);
    assert_eq!(v(&runs[2]), Verdict::Fail);
    runs[0] = with_shares("erosion", [f64::NAN, 0.05, 0.05]);
    judge_against_floor(&mut runs, &thresholds);
    assert_eq!(v(&runs[0]), Verdict::Pass);
    // On the points both cover: erosion's new patch over advect's hole
    // (third point) does not count; its switch on the second does.
    const U: u32 = SOURCE_UNCOVERED;
    runs[0].frames[1].point_sources = vec![[1, 1], [1, 2], [3, 4]];
    runs[1].frames[1].point_sources = vec![[1, 1], [1, 1], [U, 4]];
    runs[0].frames[2].point_sources = vec![[5, 5], [5, 6]];
    runs[1].frames[2].point_sources = vec![[5, 5], [5, 6]];
    runs[2].frames[2].point_sources = vec![[5, 5]];
    judge_against_floor(&mut runs, &thresholds);
    assert_eq!(runs[0].frames[1].switch_same_points, [0.5, 0.0]);
    assert_eq!(runs[0].frames[2].switch_same_points, [0.5, 0.5]);
    assert_eq!(runs[1].frames[1].switch_same_points, [0.0, 0.0]);
    assert!(runs[0].frames[0].switch_same_points[0].is_nan());
    // A run measured on other points is not compared.
    assert!(runs[2].frames[2].switch_same_points[0].is_nan());
    // The verdict is on the points both cover: erosion's 5 % on its own
    // points passed, but on the common support of frame 1 it switches 50 %
    // against advect's 0 %; the cell shows the judged shares.
    assert_eq!(v(&runs[0]), Verdict::Fail);
    let cell = *runs[0].summary(Metric::SourceSwitch).unwrap();
    assert_eq!((cell.min, cell.max), (0.5, 0.5));
    // Frame 2 alone on common support: both 50 %, within 2 points.
    runs[0].frames[1].point_sources.clear();
    judge_against_floor(&mut runs, &thresholds);
    assert_eq!(v(&runs[0]), Verdict::Pass);
    assert_eq!(
        runs[0].summary(Metric::SourceSwitch).unwrap().max,
        0.5,
        "frame 1 falls back to its own 5 %, frame 2 is judged at 50 % against 50 %"
    );
    runs[0].frames[1].point_sources = vec![[1, 1], [1, 2], [3, 4]];
    judge_against_floor(&mut runs, &thresholds);
    let notes_with = |r: &MethodRun, needle: &str| {
        r.notes
            .iter()
            .filter(|n| n.contains(needle))
            .cloned()
            .collect::<Vec<_>>()
    };
    let note = |r: &MethodRun| notes_with(r, "own points");
    assert_eq!(
        note(&runs[0]),
        [
            "source switch share on each run's own points (information; the verdict is on \
             the points both cover): +2.0 points against advect's in the median frame, +2.0 \
             at worst (frame 1)"
        ]
    );
    assert!(
        note(&runs[1]).is_empty(),
        "advect is not compared with itself"
    );
    // The worst frame against the median one, for every run with switches:
    // boiling's 20 % against its lower median of 4 % is 5x.
    let peaks = |r: &MethodRun| notes_with(r, "worst frame is");
    // The peak note of a run: worst frame `text`, e.g. "5.0x ... (20.0 % at frame 2".
    let peak_is = |r: &MethodRun, text: &str, median: &str| {
        assert_eq!(
            peaks(r),
            [format!(
                "source switch share: the worst frame is {text}, median {median})"
            )],
            "{}",
            r.method
        );
    };
    peak_is(
        &runs[2],
        "5.0x the median frame (20.0 % at frame 2",
        "4.0 %",
    );
    // Of equal frames the first is the worst.
    peak_is(&runs[1], "1.0x the median frame (3.0 % at frame 1", "3.0 %");
    // Judging again replaces the note; a run that never switches has none.
    runs[2] = with_shares("boiling", [f64::NAN, 0.0, 0.0]);
    judge_against_floor(&mut runs, &thresholds);
    assert!(peaks(&runs[2]).is_empty());
    assert_eq!(peaks(&runs[0]).len(), 1);
    // A 48-frame run: the start-up wave (frames 0-11, the first lifetime)
    // is left out of the peak rule; a wave after it is not.
    let long = |wave_at: usize| {
        let mut r = base.clone();
        r.method = "waves".into();
        r.frames = (0..48)
            .map(|n| {
                let mut f = base.frames[1].clone();
                f.frame = n;
                f.point_sources.clear();
                f.values[k] = if n as usize == wave_at { 0.3 } else { 0.05 };
                f
            })
            .collect();
        r
    };
    let mut waves = vec![long(5), long(30)];
    judge_against_floor(&mut waves, &thresholds);
    peak_is(
        &waves[0],
        "1.0x the median frame (5.0 % at frame 12",
        "5.0 %",
    );
    peak_is(
        &waves[1],
        "6.0x the median frame (30.0 % at frame 30",
        "5.0 %",
    );
    // Without advect there is nothing to judge against.
    let mut alone = vec![with_shares("erosion", [f64::NAN, 0.05, 0.05])];
    judge_against_floor(&mut alone, &thresholds);
    assert_eq!(v(&alone[0]), Verdict::NoData);
    assert!(
        alone[0]
            .notes
            .iter()
            .any(|n| n.contains("advect was not run"))
    );
}

#[test]
fn flow_aligned_share_is_judged_against_advect_only_where_advect_fails_the_absolute_rule() {
    let (scene, settings) = prepared("rigid-rotation", 16, 0..=1, 64, 64);
    let exemplar = pattern(64);
    let base = run(
        &scene,
        &mut painted(&scene, &exemplar, true, false),
        &settings,
    );
    let with_aligned = |name: &str, median: f64| {
        let mut r = base.clone();
        r.method = name.into();
        let s = r
            .summaries
            .iter_mut()
            .find(|s| s.metric == Metric::FlowAligned)
            .unwrap();
        s.median = median;
        s.verdict = Verdict::of(median >= 0.90);
        r
    };
    let thresholds = Thresholds::committed().unwrap();
    let v = |r: &MethodRun| r.summary(Metric::FlowAligned).unwrap().verdict;
    // advect at 0.80: 0.78 is within 0.03 of it, 0.76 is not.
    let mut runs = vec![
        with_aligned("erosion", 0.78),
        with_aligned("advect", 0.80),
        with_aligned("blend", 0.76),
    ];
    judge_against_floor(&mut runs, &thresholds);
    assert_eq!(
        [v(&runs[0]), v(&runs[1]), v(&runs[2])],
        [Verdict::Pass, Verdict::Pass, Verdict::Fail]
    );
    assert!(runs[0].notes.iter().any(|n| n.contains("advect's 0.800")));
    // Where advect passes the absolute rule, it stands for everyone: 0.89
    // fails although advect's 0.91 is within 0.03.
    let mut runs = vec![with_aligned("erosion", 0.89), with_aligned("advect", 0.91)];
    judge_against_floor(&mut runs, &thresholds);
    assert_eq!([v(&runs[0]), v(&runs[1])], [Verdict::Fail, Verdict::Pass]);
}

#[test]
fn the_fidelity_scale_of_an_output_without_uv_is_its_median_reported_level() {
    // Levels outside charts are NaN and do not count; the median of
    // 1, 2, 2, 3, 5 is level 2, four exemplar texels per atlas texel.
    let lod = [f32::NAN, 2.0, 1.0, f32::NAN, 5.0, 2.0, 3.0];
    assert_eq!(shown_scale(Some(&lod)), 4.0);
    // A magnified exemplar (negative level) is compared at its own scale.
    assert_eq!(shown_scale(Some(&[-1.5, -0.5, -2.0])), 1.0);
    // Nothing reported, or nothing inside a chart: no scale.
    assert!(shown_scale(None).is_nan());
    assert!(shown_scale(Some(&[f32::NAN, f32::NAN])).is_nan());
}

#[test]
fn on_a_strongly_sheared_scene_the_renewal_floor_raises_both_bars() {
    let (scene, settings) = prepared("rigid-rotation", 16, 0..=2, 64, 64);
    let exemplar = pattern(64);
    let base = run(
        &scene,
        &mut painted(&scene, &exemplar, true, false),
        &settings,
    );
    let at = |m: Metric| PER_FRAME.iter().position(|&p| p == m).unwrap();
    let (ks, kp) = (at(Metric::SourceSwitch), at(Metric::Popping));
    // (switch share, popped share, holder past δ_max) per frame 1 and 2.
    let with = |name: &str, frames: [[f64; 3]; 2]| {
        let mut r = base.clone();
        r.method = name.into();
        for (f, v) in r.frames.iter_mut().skip(1).zip(frames) {
            f.values[ks] = v[0];
            f.values[kp] = v[1];
            f.switch_causes.holder_distorted = v[2];
            f.point_sources.clear();
        }
        let popped: Vec<f64> = r.frames.iter().map(|f| f.values[kp]).collect();
        let cell = Thresholds::committed()
            .unwrap()
            .summarize(Metric::Popping, &popped);
        if let Some(s) = r.summaries.iter_mut().find(|s| s.metric == Metric::Popping) {
            *s = cell;
        }
        r
    };
    let thresholds = Thresholds::committed().unwrap();
    let strong = thresholds.popping.strong_shear_scenes[0].clone();
    let runs = || {
        vec![
            // 11 and 20 points above advect's switch share, popping 12 %.
            with("erosion", [[0.14, 0.12, 0.0], [0.23, 0.12, 0.0]]),
            // advect: the renewal floor is 10 % then 20 %.
            with("advect", [[0.03, 0.01, 0.10], [0.03, 0.01, 0.20]]),
            // Switches 15 points above advect's plus the floor on frame 2.
            with("churn", [[0.10, 0.05, 0.0], [0.38, 0.05, 0.0]]),
        ]
    };
    let v = |r: &MethodRun, m: Metric| r.summary(m).unwrap().verdict;
    // Elsewhere the plain rules: erosion fails both.
    let mut plain = runs();
    judge_against_floor_on(&mut plain, &thresholds, "vortex-16");
    assert_eq!(v(&plain[0], Metric::SourceSwitch), Verdict::Fail);
    assert_eq!(v(&plain[0], Metric::Popping), Verdict::Fail);
    // On the strongly sheared scene: switch ≤ advect + floor + 0.02 and
    // popping ≤ floor + 0.02 on every frame.
    let mut sheared = runs();
    judge_against_floor_on(&mut sheared, &thresholds, &strong);
    // Frame 1: popping 12 % against a 10 % floor + 2 points passes exactly.
    assert_eq!(v(&sheared[0], Metric::SourceSwitch), Verdict::Pass);
    assert_eq!(v(&sheared[0], Metric::Popping), Verdict::Pass);
    assert_eq!(v(&sheared[2], Metric::SourceSwitch), Verdict::Fail);
    assert_eq!(v(&sheared[2], Metric::Popping), Verdict::Pass);
    assert!(
        sheared[0]
            .notes
            .iter()
            .any(|n| n.contains("renewal floor") && n.contains("worst 0.200")),
        "{:?}",
        sheared[0].notes
    );
    // A frame's popping above its own floor fails: frame 1 at 13 %.
    let mut over = runs();
    over[0].frames[1].values[kp] = 0.13;
    judge_against_floor_on(&mut over, &thresholds, &strong);
    assert_eq!(v(&over[0], Metric::Popping), Verdict::Fail);
}
