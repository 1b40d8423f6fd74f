//! The ledger's switch test: every row of [`DEPARTURES`] with `preset`
//! lines (the paper's setting of a parameter or run setting) is run on a
//! tiny scene twice, with the defaults and with the lines applied, and the
//! two runs must differ: a switch that changes nothing is either broken or
//! described wrongly in the ledger. The comparison reads each frame's
//! channels, per-texel sources and the method's statistics (so a switch
//! whose only visible effect is a count, such as `seed_texel` at rest,
//! still shows).
//!
//! Scenes are as small as still show each difference: a few frames of a
//! built-in scene at low resolution and a small atlas, or a flat grid with
//! the flow the row needs ([`scene_for`]). Rows whose paper setting only
//! shows under other settings run both sides on those ([`base_for`]). The
//! optimization method runs with few points, a small working exemplar and
//! two levels (its defaults would take minutes in a debug build).

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::Vec3;

use super::{DEPARTURES, Departure};
use crate::exemplar::{ExemplarFilter, builtin_pebbles};
use crate::methods::FrameResult;
use crate::methods::registry::{MethodKind, MethodParams};
use crate::methods::test_clip::{Clip, grid, scene};
use crate::named::Named;

/// What a tiny run is set by: the method parameters and the run's
/// exemplar filter (the one run setting a preset line sets).
#[derive(Clone, Debug, Default, PartialEq)]
struct Settings {
    params: MethodParams,
    filter: ExemplarFilter,
}

/// `settings` with the TOML `lines` (dotted keys, as in the config file
/// and [`Departure::preset`]) applied.
fn apply(settings: &Settings, lines: &str) -> Result<Settings, String> {
    let given: toml::Table = toml::from_str(lines).map_err(|e| format!("{lines:?}: {e}"))?;
    let mut table = settings.params.every_key();
    let mut filter = settings.filter;
    for (key, value) in given {
        match (table.get_mut(&key), value) {
            (Some(toml::Value::Table(section)), toml::Value::Table(keys)) => {
                section.extend(keys);
            }
            (None, toml::Value::String(name)) if key == "exemplar_filter" => {
                filter = ExemplarFilter::from_name(&name)
                    .ok_or_else(|| format!("exemplar_filter = {name:?}: no such filter"))?;
            }
            (_, value) => {
                return Err(format!(
                    "{key} = {value}: neither a method section nor a run setting this test \
                     applies; teach `apply` about it"
                ));
            }
        }
    }
    let params = toml::Value::Table(table)
        .try_into::<MethodParams>()
        .map_err(|e| format!("{lines:?}: {e}"))?;
    Ok(Settings { params, filter })
}

/// The tiny scene a row runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Scene {
    /// `vortex`, resolution 16, 3 frames, atlas 64.
    Vortex,
    /// `vortex`, resolution 10, 16 frames, atlas 96.
    LongVortex,
    /// `differential-rotation`, resolution 12, 2 frames, atlas 64.
    Shear,
    /// A flat grid at rest, then lifted 0.6 off its plane.
    Lift,
    /// A flat grid whose flow converges weakly on its centre.
    Sink,
    /// A slowly turning flat grid, 2 frames, atlas 64 (optimization).
    Turn,
}

fn clip(scene_kind: Scene) -> Clip {
    match scene_kind {
        Scene::Vortex => scene("vortex", 16, 3, 64),
        Scene::LongVortex => scene("vortex", 10, 16, 96),
        Scene::Shear => scene("differential-rotation", 12, 2, 64),
        Scene::Lift => {
            let near = grid(8, 0.125, |_| Vec3::ZERO);
            let mut far = near.clone();
            for p in &mut far.positions {
                p.z += 0.6;
            }
            Clip::from_meshes(vec![near, far], 64)
        }
        Scene::Sink => {
            let mesh = grid(32, 0.0625, |p| Vec3::new(-0.3 * p.x, -0.3 * p.y, 0.0));
            Clip::from_meshes(vec![mesh; 3], 64)
        }
        Scene::Turn => {
            let mesh = grid(8, 0.25, |p| Vec3::new(-p.y, p.x, 0.0) * 0.5);
            let mut next = mesh.clone();
            for (i, p) in next.positions.iter_mut().enumerate() {
                if p.x.abs() < 0.99 && p.y.abs() < 0.99 {
                    p.x += 0.01 * (i as f32 * 1.7).sin();
                }
            }
            Clip::from_meshes(vec![mesh, next], 64)
        }
    }
}

/// The method a row runs: the first it names.
fn method_of(d: &Departure) -> Result<MethodKind, String> {
    let name = d.method.split(',').next().unwrap_or("").trim();
    MethodKind::from_name(name).ok_or_else(|| format!("{}: no method {name:?}", d.what))
}

/// The tiny scene for row `d`.
fn scene_for(d: &Departure) -> Scene {
    match d.key {
        Some("lapped_rigid.far_fraction") => Scene::Lift,
        Some("lapped_rigid.sink_speed") => Scene::Sink,
        Some("erosion.seed_texel" | "erosion.split_edges") => Scene::Shear,
        // Only triangles stretched past δ_max faster than their weights
        // fall differ: the vortex makes them within 16 frames.
        Some("erosion.bound") => Scene::LongVortex,
        _ if d.method.starts_with("optimization") => Scene::Turn,
        _ => Scene::Vortex,
    }
}

/// Settings both sides of row `d` share: where the paper's setting only
/// shows under others (as the row's own effect column says).
fn base_for(d: &Departure) -> &'static str {
    match d.key {
        // With progressive weights no patch erodes its seed texel, and
        // every pinned vertex starts at 1 whatever B_V: the paper's weights
        // on a curved, quickly distorted surface show both.
        Some("erosion.seed_texel") => {
            "erosion.radius_fraction = 0.3\nerosion.delta_max = 1.2\nerosion.delta_onset = 1.0\n\
             erosion.weights = \"paper\"\nerosion.seed_corners = \"paper\""
        }
        // Edges stretch past twice the median edge only where no erosion
        // removes them first.
        Some("erosion.split_edges") => "erosion.delta_max = 1000.0",
        // The corners of p's triangle are interior vertices (B_V = 1 by
        // either rule) unless the patch is about one triangle wide; and
        // progressive weights start every pinned vertex at 1 whatever B_V.
        Some("erosion.seed_corners") => {
            "erosion.radius_fraction = 0.01\nerosion.radius_edges = 0.0\n\
             erosion.weights = \"paper\""
        }
        // At coverage 0.99 no seed texel is left short.
        Some("lapped_rigid.seed_texel") => "lapped_rigid.coverage = 1.0",
        _ if d.method.starts_with("optimization") => {
            "optimization.points = 1500\noptimization.exemplar_texels = 32\n\
             optimization.levels = 2\noptimization.iterations = 2"
        }
        _ => "",
    }
}

/// What a tiny run shows, frame by frame: channels, sources and the
/// method's statistics.
type Shown = Vec<(
    Vec<Vec<f32>>,
    Option<Vec<u32>>,
    BTreeMap<String, serde_json::Value>,
)>;

fn shown(results: Vec<FrameResult>) -> Shown {
    results
        .into_iter()
        .map(|r| {
            let channels = r.channels.into_iter().map(|t| t.data).collect();
            (channels, r.source, r.stats)
        })
        .collect()
}

/// Runs `kind` with `settings` on `scene_kind` (seed 1, the built-in
/// pebbles at 64²).
fn run(kind: MethodKind, settings: &Settings, scene_kind: Scene) -> Result<Shown, String> {
    let exemplar = Arc::new(builtin_pebbles(64, 1).with_filter(settings.filter));
    let mut method = settings
        .params
        .build(kind, 1, || Ok::<_, crate::methods::MethodError>(exemplar))
        .map_err(|e| format!("{kind:?}: {e}"))?;
    let c = clip(scene_kind);
    let mut results = Vec::new();
    for k in 0..c.meshes.len() {
        results.push(
            method
                .step(&c.ctx(k))
                .map_err(|e| format!("frame {k}: {e}"))?,
        );
    }
    Ok(shown(results))
}

/// Runs of one test, cached: the same defaults serve many rows.
#[derive(Default)]
struct Runs(Vec<((MethodKind, Scene, Settings), Shown)>);

impl Runs {
    fn get(
        &mut self,
        kind: MethodKind,
        settings: &Settings,
        scene_kind: Scene,
    ) -> Result<&Shown, String> {
        let key = (kind, scene_kind, settings.clone());
        let at = match self.0.iter().position(|(k, _)| *k == key) {
            Some(at) => at,
            None => {
                let out = run(kind, settings, scene_kind)?;
                self.0.push((key, out));
                self.0.len() - 1
            }
        };
        Ok(&self.0[at].1)
    }
}

/// Checks one row's switch: `Ok` with what differed when its preset
/// lines change the tiny run, an error naming the row otherwise.
fn check_switch(d: &Departure, runs: &mut Runs) -> Result<&'static str, String> {
    check_switch_on(d, scene_for(d), base_for(d), runs)
}

/// [`check_switch`] on `scene_kind`, both sides set by `base` first.
fn check_switch_on(
    d: &Departure,
    scene_kind: Scene,
    base: &str,
    runs: &mut Runs,
) -> Result<&'static str, String> {
    let kind = method_of(d)?;
    let base = apply(&Settings::default(), base)?;
    let paper = apply(&base, d.preset)?;
    if paper == base {
        return Err(format!(
            "{}: the preset lines {:?} set nothing that differs from the defaults",
            d.what, d.preset
        ));
    }
    let ours = runs.get(kind, &base, scene_kind)?.clone();
    let theirs = runs.get(kind, &paper, scene_kind)?;
    let pictures = |s: &Shown| {
        s.iter()
            .map(|f| (f.0.clone(), f.1.clone()))
            .collect::<Vec<_>>()
    };
    if pictures(&ours) != pictures(theirs) {
        Ok("pictures")
    } else if &ours != theirs {
        Ok("statistics")
    } else {
        Err(format!(
            "{}: `{}` leaves the tiny {scene_kind:?} run of {kind:?} unchanged: the switch \
             does nothing there, or the scene cannot show it (give the row a scene in \
             scene_for or settings in base_for)",
            d.what,
            d.preset.replace('\n', "; ")
        ))
    }
}

/// Every row with preset lines changes its tiny run.
#[test]
fn every_switch_changes_its_tiny_scene() {
    let mut runs = Runs::default();
    let mut problems = Vec::new();
    let mut checked = 0;
    for d in DEPARTURES.iter().filter(|d| !d.preset.is_empty()) {
        match check_switch(d, &mut runs) {
            Ok(what) => {
                eprintln!("{} ({}): {what} differ", d.what, d.method);
                checked += 1;
            }
            Err(e) => problems.push(e),
        }
    }
    assert!(problems.is_empty(), "{problems:#?}");
    // Every method family has switches, and all were run.
    assert!(checked >= 25, "{checked} switches checked");
}

/// Known-bad controls: a switch whose preset line sets the default value
/// is caught before anything runs, and one whose value differs but whose
/// scene cannot show it (the sink fade rate on a surface at rest, where no
/// patch is ever a sink) is caught by the comparison; a row naming an
/// unknown setting is an error, not a pass.
#[test]
fn a_switch_that_changes_nothing_is_caught() {
    let fake = |key: Option<&'static str>, preset: &'static str| Departure {
        method: "lapped-rigid",
        paper: "2016 Sec. 3.3",
        what: "a fake switch",
        ours: "",
        paper_setting: "",
        key,
        flag: None,
        preset,
        effect: "",
        measure: "",
        pinned_by: "",
    };
    let mut runs = Runs::default();
    let default_value = fake(
        Some("lapped_rigid.coverage"),
        "lapped_rigid.coverage = 0.99",
    );
    let e = check_switch(&default_value, &mut runs).expect_err("the default value is no switch");
    assert!(e.contains("set nothing that differs"), "{e}");
    // A value that differs, on a scene that cannot show it (at rest, so
    // no patch is ever a sink and the fade rate never acts): the same
    // comparison that passes the real rows must fail it.
    let fade = fake(
        Some("lapped_rigid.sink_fade_rate"),
        "lapped_rigid.sink_fade_rate = 2.0",
    );
    let e = check_switch_on(&fade, Scene::Lift, "", &mut runs).expect_err("nothing changes");
    assert!(e.contains("unchanged"), "{e}");
    let unknown = fake(None, "no_such_setting = 1");
    assert!(check_switch(&unknown, &mut runs).is_err());
}

/// Switches that are not in `--preset paper` yet, with the lines that turn
/// them on: each must still change its tiny run, as a preset row must.
const NOT_IN_THE_PRESET_YET: &[(&str, &str)] = &[(
    "optimization.transport",
    "optimization.transport = \"grid\"",
)];

#[test]
fn switches_not_in_the_preset_yet_change_their_tiny_scene() {
    let mut runs = Runs::default();
    for &(key, lines) in NOT_IN_THE_PRESET_YET {
        let row = DEPARTURES
            .iter()
            .find(|d| d.key == Some(key))
            .unwrap_or_else(|| panic!("no ledger row has the key {key}"));
        assert!(
            row.preset.is_empty(),
            "{key} is in the preset now: take it off NOT_IN_THE_PRESET_YET"
        );
        let with = Departure {
            preset: lines,
            ..*row
        };
        if let Err(e) = check_switch(&with, &mut runs) {
            panic!("{e}");
        }
    }
}
