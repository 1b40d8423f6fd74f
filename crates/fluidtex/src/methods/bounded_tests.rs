//! Registry-wide: every method that carries patches, at its defaults and
//! under `--preset paper`, keeps its per-frame patch geometry bounded by
//! the surface on a long stretching run at a large radius, not growing
//! with the run's history (issue 60, item 3).

use std::sync::Arc;

use super::registry::{MethodKind, MethodParams};
use super::test_clip::Clip;
use super::{Method, MethodStats};
use crate::named::Named;

/// The per-frame patch geometry a method reports: the patch triangles of
/// the erosion machinery (both layers of `dual-rest`), the receiver pairs
/// of `lapped-rigid`; `None` for a method without patches.
fn patch_geometry(stats: &MethodStats) -> Option<u64> {
    let n = |k: &str| stats.get(k).and_then(serde_json::Value::as_u64);
    n("patch_triangles")
        .or_else(|| Some(n("layer_a_patch_triangles")? + n("layer_b_patch_triangles")?))
        .or_else(|| n("receiver_pairs"))
}

/// The method sections of `--preset paper` (the ledger's lines; the
/// lines outside the method sections are the run's, not a method's).
fn paper_params() -> MethodParams {
    let preset: toml::Table = toml::from_str(&crate::departures::paper_preset()).expect("toml");
    let sections: Vec<&str> = MethodParams::section_keys().iter().map(|s| s.0).collect();
    let methods: toml::Table = (preset.into_iter())
        .filter(|(k, _)| sections.contains(&k.as_str()))
        .collect();
    methods.try_into().expect("the preset's method sections")
}

/// A sphere whose angular speed grows with height, at 1/48 of the frame
/// rate: the shear on the patches grows by two seconds' worth each frame
/// (δ_max = 3 is passed within a frame or two), while the surface stays
/// the same; with `dt` per frame.
fn sheared(frames: i32) -> (Clip, f32) {
    let name = "differential-rotation";
    let mut params = crate::scenes::default_params(name).expect("scene");
    params.resolution = 8;
    params.fps = 0.5;
    params.last = params.first + frames - 1;
    let mut scene = crate::scenes::by_name(name, Some(params)).expect("scene");
    let meshes = (params.first..=params.last)
        .map(|f| scene.frame(f).expect("frame"))
        .collect();
    (Clip::from_meshes(meshes, 48), 1.0 / params.fps as f32)
}

/// Per frame, the patch geometry of `method` on `clip` (`None`: the
/// method has none).
fn geometry_per_frame(method: &mut dyn Method, clip: &Clip, dt: f32) -> Option<Vec<u64>> {
    let mut run = Vec::new();
    for k in 0..clip.meshes.len() {
        let ctx = super::FrameContext { dt, ..clip.ctx(k) };
        // A method without patches says so on its first frame.
        run.push(patch_geometry(&method.step(&ctx).expect("step").stats)?);
    }
    Some(run)
}

/// Whether the geometry levels off: every frame of the second half holds
/// at most 1.5 times the middle frame's, and at most [`PER_TRIANGLE`]
/// per surface triangle.
fn levels_off(run: &[u64], surface: u64) -> bool {
    let middle = run[run.len() / 2];
    run[run.len() / 2..]
        .iter()
        .all(|&g| 2 * g <= 3 * middle && g <= PER_TRIANGLE * surface)
}

/// Patch geometry per surface triangle that no bounded method reaches
/// here: the radius is about the sphere's, so every patch covers half of
/// it, the sheared patches overlap many times, and each needle is split
/// until its distortion passes 4·δ_max (`dual-rest` holds two layers of
/// them: about 300 per surface triangle, `advect` about 200).
const PER_TRIANGLE: u64 = 400;

/// The patch radius: about the sphere's own.
const RADIUS: f32 = 0.35;

#[test]
fn every_patch_method_keeps_its_patch_geometry_bounded_by_the_surface() {
    let (clip, dt) = sheared(12);
    let surface = clip.meshes.iter().map(|m| m.triangle_count() as u64).max();
    let surface = surface.expect("frames");
    let exemplar =
        || Ok::<_, super::MethodError>(Arc::new(crate::exemplar::builtin_pebbles(32, 1)));
    let run = |base: &MethodParams, kind: MethodKind| {
        let mut params = base.clone();
        params.erosion.radius = Some(RADIUS);
        params.lapped_rigid.radius = Some(RADIUS);
        let mut method = params.build(kind, 3, exemplar).expect("builds");
        geometry_per_frame(method.as_mut(), &clip, dt)
    };
    let mut unbounded = Vec::new();
    let mut carrying = Vec::new();
    for &kind in MethodKind::ALL {
        if let Some(geometry) = run(&MethodParams::default(), kind) {
            carrying.push(kind);
            if !levels_off(&geometry, surface) {
                unbounded.push(format!("{kind}: {geometry:?}"));
            }
        }
    }
    // The paper's settings of every method that carries patches (the
    // others have none under any setting).
    let paper = paper_params();
    for &kind in &carrying {
        let geometry = run(&paper, kind).expect("patches");
        if !levels_off(&geometry, surface) {
            unbounded.push(format!("{kind} (paper): {geometry:?}"));
        }
    }
    assert!(
        unbounded.is_empty(),
        "patch geometry per frame on {surface} surface triangles:\n{}",
        unbounded.join("\n")
    );
    let mut names: Vec<&str> = carrying.iter().map(|k| k.name()).collect();
    names.sort_unstable();
    assert_eq!(
        names,
        [
            "advect",
            "blend-deformable",
            "dual-rest",
            "erosion",
            "lapped-rigid"
        ],
        "every method that carries patches is measured"
    );

    // Control: `advect` splitting its distorted triangles without the
    // bound (the code before it) grows with the run, past both tests.
    let params = super::erosion::ErosionParams {
        radius: Some(RADIUS),
        ..Default::default()
    };
    let pebbles = Arc::new(crate::exemplar::builtin_pebbles(32, 1));
    let control = super::erosion::Erosion::with_rules(super::advect::RULES, params, pebbles, 3);
    let mut control = control.expect("params").splitting_without_bound();
    let geometry = geometry_per_frame(&mut control, &clip, dt).expect("patches");
    assert!(
        !levels_off(&geometry, surface) && geometry[11] > 3 * geometry[5],
        "the unbounded control should grow: {geometry:?} on {surface} surface triangles"
    );
}
