//! `fluidtex compare`: every method on the same scenes, seed, exemplar and
//! atlas size, measured by the evaluation harness (`fluidtex::eval`), with a
//! report in JSON, Markdown and HTML plus pictures. See docs/compare.md.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use fluidtex::eval::report::{MethodReport, Report, SceneReport, contact_sheet};
use fluidtex::eval::{self, EvalSettings, MethodRun};
use fluidtex::exemplar::ExemplarSet;
use fluidtex::io::FrameRange;
use fluidtex::io::image::{PngOptions, encode_png};
use fluidtex::metrics::Thresholds;
use fluidtex::pipeline::SequenceScene;
use fluidtex::scenes;
use fluidtex::texture::Texture;

use super::run::{build_exemplar_set, build_job, build_method_over};
use crate::config::{Config, ExemplarEntry};
use fluidtex::methods::registry::MethodKind;
use fluidtex::named::Named;

/// Scenes compared by default.
pub const DEFAULT_SCENES: &str = "vortex,differential-rotation,stop";
/// Scene resolution cap of the default comparison (marching-cubes cells
/// along the domain's longest side): small meshes, so the whole default
/// comparison runs in minutes on two cores.
pub const DEFAULT_RESOLUTION_CAP: u32 = 48;
/// Frames per scene by default.
pub const DEFAULT_FRAMES: i32 = 12;

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// Scenes, comma-separated (see `fluidtex scene --list`)
    #[arg(long, default_value = DEFAULT_SCENES)]
    pub scenes: String,
    /// Methods, comma-separated [every method]
    #[arg(long)]
    pub methods: Option<String>,
    /// Output folder for report.json, report.md, report.html and pictures
    #[arg(long)]
    pub out: PathBuf,
    /// Frame range A-B for every scene [per scene: its first 12 frames; stop: 40-55, across the stop]
    #[arg(long)]
    pub frames: Option<String>,
    /// Atlas size in texels (square)
    #[arg(long, default_value_t = 512)]
    pub atlas: u32,
    /// Scene resolution (marching-cubes cells) [the scene's default, at most 48]
    #[arg(long)]
    pub resolution: Option<u32>,
    /// Side of the square evaluation renders in pixels
    #[arg(long, default_value_t = 256)]
    pub render: u32,
    /// Seed of every random choice
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Colour exemplar (PNG, JPEG, EXR); default: built-in pebbles
    #[arg(long)]
    pub exemplar: Option<PathBuf>,
    /// TOML config (as `fluidtex run --config`) whose method sections
    /// ([erosion], [dual_rest], ...) set the compared methods' parameters;
    /// its mesh, method, frames and output keys are ignored, and compare's
    /// own --atlas, --seed and --exemplar win over the file's
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Compare on your own simulation instead of the scenes: a mesh
    /// sequence with per-vertex velocity, as `fluidtex run --mesh` reads it
    /// (e.g. 'sim/fluid.####.ply'); with --frames A-B, or every frame found.
    /// Metrics that need an exact flow carry by the input velocity.
    #[arg(long)]
    pub mesh: Option<String>,
    /// Frames per second of --mesh (its velocities are per second)
    #[arg(long, default_value_t = 24.0)]
    pub fps: f64,
    /// Also run every method under `--preset paper` (docs/departures.md),
    /// reported beside it as `METHOD (paper)` and judged by the same rules:
    /// the default and the published algorithm side by side
    #[arg(long)]
    pub paper: bool,
    /// Exemplars chosen by this per-vertex scalar of the scene (lava's
    /// temperature, dam-break's age): the config's `[[exemplars]]` with
    /// their `range`, or else builtin:glow@0.5:1 and builtin:crust@0:0.5;
    /// the report gains each method's state agreement. Default methods:
    /// those that take several exemplars
    #[arg(long, value_name = "ATTR")]
    pub select_by: Option<String>,
    /// No progress lines
    #[arg(long)]
    pub quiet: bool,
}

/// The name of a method's run under `--preset paper` in the report.
pub fn paper_name(method: &str) -> String {
    format!("{method} (paper)")
}

fn split_list(what: &str, text: &str) -> Result<Vec<String>> {
    let items: Vec<String> = text
        .split(',')
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .collect();
    if items.is_empty() {
        bail!("--{what}: give at least one name");
    }
    Ok(items)
}

/// The frames evaluated on `scene` (first..last of its parameters).
fn window(scene: &str, first: i32, last: i32, range: Option<FrameRange>) -> (i32, i32) {
    match range {
        Some(r) => (r.first, r.last),
        // The stop scene is still from frame 48: straddle it.
        None if scene == "stop" => (40.max(first), 55.min(last)),
        None => (first, (first + DEFAULT_FRAMES - 1).min(last)),
    }
}

/// The parameters of `method` in `config` (its own section, if it has one).
fn method_parameters(config: &Config, method: &str) -> serde_json::Value {
    // Every section, defaults included (the config leaves some out).
    let all = serde_json::to_value(&config.params).unwrap_or_default();
    let section = all
        .get(method.replace('-', "_"))
        .cloned()
        .unwrap_or(serde_json::Value::Null);
    serde_json::json!({
        "method": method,
        "seed": config.seed,
        "atlas": config.atlas,
        "exemplar": config.exemplar.as_ref().map(|p| p.display().to_string()),
        "parameters": section,
    })
}

/// The configurations `compare` runs: the defaults with the file's keys
/// (`--config`), and with `--paper` the same under the paper preset.
fn variants(a: &CompareArgs) -> Result<(Config, Option<Config>)> {
    // A config file brings the methods' parameters (e.g. an erosion
    // δ_max to weigh against the defaults); the scene decides the input.
    let file = Config::load_with_preset(a.config.as_deref(), None)?;
    let for_compare = |file: Config| {
        let mut config = Config {
            atlas: Some(a.atlas),
            seed: Some(a.seed),
            exemplar: a.exemplar.clone().or(file.exemplar.clone()),
            mesh: None,
            method: None,
            frames: None,
            out: None,
            ..file
        };
        if let Some(attribute) = &a.select_by {
            config.select_by = Some(attribute.clone());
            if config.exemplars.is_empty() && config.exemplar.is_none() {
                config.exemplars = lava_pair();
            }
        }
        config
    };
    let base = for_compare(file);
    // The file's own keys still win over the preset, as in `run`.
    let paper = a
        .paper
        .then(|| Config::load_with_preset(a.config.as_deref(), Some("paper")).map(for_compare))
        .transpose()?;
    Ok((base, paper))
}

pub fn compare(a: &CompareArgs) -> Result<()> {
    let start = Instant::now();
    let scene_names = match &a.mesh {
        Some(_) => vec![MESH_SCENE.to_string()],
        None => split_list("scenes", &a.scenes)?,
    };
    if a.mesh.is_none() {
        for s in &scene_names {
            scenes::default_params(s)?;
        }
    }
    if !(a.fps.is_finite() && a.fps > 0.0 && a.fps <= 1000.0) {
        bail!("--fps {}: allowed above 0 up to 1000", a.fps);
    }
    let (method_names, kinds) = methods_of(a)?;
    let range = a
        .frames
        .as_deref()
        .map(str::parse::<FrameRange>)
        .transpose()?;
    if !(32..=4096).contains(&a.render) {
        bail!("--render {}: allowed 32 to 4096 pixels", a.render);
    }
    let (base, paper) = variants(a)?;
    // Validates the atlas size and gives the atlas parameters `run` uses.
    let job = build_job(&base, a.out.clone(), false)?;
    // The metrics compare with the first exemplar (the one exemplar of a
    // plain run).
    // Each variant's exemplars are built once and shared by every scene and
    // method (the preset changes no exemplar key, so the paper's set is the
    // same images; it is built from its own config all the same).
    let base_set = build_exemplar_set(&base)?;
    let paper_set = paper.as_ref().map(build_exemplar_set).transpose()?;
    let exemplar = base_set.primary().colour.clone();
    let thresholds = Thresholds::committed()?;
    // Build every method once up front so a bad configuration fails before
    // any scene is generated.
    for (config, set) in std::iter::once((&base, &base_set)).chain(paper.iter().zip(&paper_set)) {
        for &kind in &kinds {
            build_method_over(
                &Config {
                    method: Some(kind),
                    ..config.clone()
                },
                set,
            )?;
        }
    }
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("{}: cannot create the output folder", a.out.display()))?;
    // Every scene's parameters and window, checked before any work.
    let plans = match &a.mesh {
        Some(pattern) => vec![plan_mesh(a, pattern)?],
        None => scene_names
            .iter()
            .map(|name| plan_scene(a, name, range))
            .collect::<Result<Vec<_>>>()?,
    };
    let session = Session {
        args: a,
        base: &base,
        paper: paper.as_ref(),
        base_set: &base_set,
        paper_set: paper_set.as_ref(),
        atlas: &job.atlas,
        exemplar: &exemplar,
        thresholds: &thresholds,
        method_names: &method_names,
        kinds: &kinds,
    };
    let scene_reports = plans
        .into_iter()
        .map(|plan| session.scene(plan))
        .collect::<Result<Vec<_>>>()?;
    let report = Report {
        command: compare_command_line(a, &method_names),
        atlas_size: a.atlas,
        seed: a.seed,
        exemplar: exemplar_text(a, &base),
        seconds: start.elapsed().as_secs_f64(),
        scenes: scene_reports,
        not_measured: vec![
            "exemplar-size cost (time with a 2048² exemplar / time with 256²): needs two \
             extra runs per method and scene; not part of the per-scene report"
                .into(),
        ],
    };
    write_reports(&a.out, &report, &thresholds)?;
    session.say(format!(
        "compare: {} scenes x {} methods in {:.0} s -> {}",
        scene_names.len(),
        method_names.len(),
        report.seconds,
        a.out.join("report.html").display()
    ));
    Ok(())
}

/// How the report names the exemplars: the one given, or each of several
/// with its range (the first is the metrics' reference).
fn exemplar_text(a: &CompareArgs, base: &Config) -> String {
    if base.exemplars.is_empty() {
        return a
            .exemplar
            .as_ref()
            .map_or("built-in pebbles".into(), |p| p.display().to_string());
    }
    let each: Vec<String> = (base.exemplars.iter())
        .map(|e| match e.range {
            Some([lo, hi]) => format!("{}@{lo}:{hi}", e.path.display()),
            None => e.path.display().to_string(),
        })
        .collect();
    let by = (base.select_by.as_ref()).map_or(String::new(), |s| format!(" by {s}"));
    format!("{}{by} (metrics against the first)", each.join(", "))
}

/// The methods compared by default with `--select-by`: those that take
/// several exemplars and choose them per patch (advect as the floor).
const STATE_METHODS: &[&str] = &["erosion", "advect", "lapped-rigid"];

/// The lava pair `--select-by` compares when the config names no
/// exemplars: glow above 0.5, crust below.
fn lava_pair() -> Vec<ExemplarEntry> {
    [("builtin:glow", [0.5, 1.0]), ("builtin:crust", [0.0, 0.5])]
        .into_iter()
        .map(|(path, range)| ExemplarEntry {
            path: path.into(),
            range: Some(range),
            ..Default::default()
        })
        .collect()
}

/// The methods asked for (every method by default), by name and kind.
fn methods_of(a: &CompareArgs) -> Result<(Vec<String>, Vec<MethodKind>)> {
    let names = match &a.methods {
        Some(m) => split_list("methods", m)?,
        None if a.select_by.is_some() => STATE_METHODS.iter().map(|m| m.to_string()).collect(),
        None => MethodKind::ALL
            .iter()
            .map(|m| m.name().to_string())
            .collect(),
    };
    let kinds = names
        .iter()
        .map(|m| MethodKind::parse_named("method", m).map_err(anyhow::Error::msg))
        .collect::<Result<Vec<MethodKind>>>()?;
    Ok((names, kinds))
}

/// One scene to measure: where its frames come from and its window.
struct ScenePlan<'a> {
    name: &'a str,
    input: PlanInput,
    first: i32,
    last: i32,
}

/// A built-in scene with its parameters, or the user's own sequence
/// (`--mesh`).
enum PlanInput {
    Scene(scenes::SceneParams),
    Files(Box<SequenceScene>),
}

/// The scene name of `--mesh` in the report and the picture files.
const MESH_SCENE: &str = "mesh";

/// The plan of `--mesh`: every frame of the sequence checked present.
fn plan_mesh(a: &CompareArgs, pattern: &str) -> Result<ScenePlan<'static>> {
    let options = fluidtex::io::ReadOptions {
        scalar_attributes: a.select_by.iter().cloned().collect(),
        ..Default::default()
    };
    let files = SequenceScene::open_with(pattern, a.frames.as_deref(), a.fps, MESH_SCENE, options)
        .with_context(|| format!("--mesh {pattern}"))?;
    let info = scenes::Scene::info(&files);
    Ok(ScenePlan {
        name: MESH_SCENE,
        input: PlanInput::Files(Box::new(files)),
        first: info.first,
        last: info.last,
    })
}

/// A scene's parameters as `compare` runs it, its window checked.
fn plan_scene<'a>(
    a: &CompareArgs,
    name: &'a str,
    range: Option<FrameRange>,
) -> Result<ScenePlan<'a>> {
    let mut params = scenes::default_params(name)?;
    params.resolution = match a.resolution {
        Some(r) => r,
        None => params.resolution.min(DEFAULT_RESOLUTION_CAP),
    };
    params.seed = a.seed;
    params.validate()?;
    let (first, last) = window(name, params.first, params.last, range);
    if first < params.first || last > params.last {
        bail!(
            "--frames {first}-{last}: scene {name} has frames {}-{}",
            params.first,
            params.last
        );
    }
    Ok(ScenePlan {
        name,
        input: PlanInput::Scene(params),
        first,
        last,
    })
}

/// What every scene of one `compare` shares.
struct Session<'a> {
    args: &'a CompareArgs,
    base: &'a Config,
    /// With `--paper`: the same under `--preset paper`.
    paper: Option<&'a Config>,
    /// The exemplars of `base` and of `paper`, built once.
    base_set: &'a ExemplarSet,
    paper_set: Option<&'a ExemplarSet>,
    atlas: &'a fluidtex::atlas::AtlasParams,
    exemplar: &'a Texture,
    thresholds: &'a Thresholds,
    method_names: &'a [String],
    kinds: &'a [MethodKind],
}

impl Session<'_> {
    fn say(&self, msg: String) {
        if !self.args.quiet {
            eprintln!("{msg}");
        }
    }

    /// Prepares one scene, runs every method on it, and writes its pictures.
    fn scene(&self, plan: ScenePlan<'_>) -> Result<SceneReport> {
        let ScenePlan {
            name,
            input,
            first,
            last,
        } = plan;
        let (mut scene, source): (Box<dyn scenes::Scene>, String) = match input {
            PlanInput::Files(files) => (files, "your files".into()),
            PlanInput::Scene(params) => (
                scenes::by_name(name, Some(params))?,
                format!("resolution {}", params.resolution),
            ),
        };
        let frames: Vec<i32> = (first..=last).collect();
        let keep = picture_frames(&frames);
        let settings = EvalSettings {
            render_size: self.args.render,
            view_dir: eval::default_view(name),
            keep_renders: keep.clone(),
            dilate_radius: self.atlas.gutter.max(1) * 2,
            ..Default::default()
        };
        self.say(format!(
            "{name}: preparing frames {first}-{last} ({source})"
        ));
        let prepared = eval::prepare(
            scene.as_mut(),
            &frames,
            self.atlas,
            &settings,
            self.thresholds,
        )
        .with_context(|| format!("scene {name}"))?;
        let mut runs: Vec<MethodRun> = Vec::new();
        let mut parameters = Vec::new();
        // Each method's paper run right after its default run.
        let variants: Vec<(&Config, &ExemplarSet, bool)> =
            std::iter::once((self.base, self.base_set, false))
                .chain(self.paper.zip(self.paper_set).map(|(p, s)| (p, s, true)))
                .collect();
        for (m, &kind) in self.method_names.iter().zip(self.kinds) {
            for &(base, set, is_paper) in &variants {
                let config = Config {
                    method: Some(kind),
                    ..base.clone()
                };
                let mut method = build_method_over(&config, set)?;
                let clock = Instant::now();
                let mut run = eval::evaluate(
                    &prepared,
                    method.as_mut(),
                    self.exemplar,
                    &settings,
                    self.thresholds,
                )
                .with_context(|| format!("scene {name}, method {m}"))?;
                let label = if is_paper { paper_name(m) } else { m.clone() };
                self.say(format!(
                    "{name} / {label}: {} frames in {:.1} s",
                    run.frames.len(),
                    clock.elapsed().as_secs_f64()
                ));
                let mut p = method_parameters(&config, m);
                if is_paper {
                    run.method = label.clone();
                    p["method"] = label.into();
                    p["preset"] = "paper".into();
                }
                parameters.push(p);
                runs.push(run);
            }
        }
        // The source switch share passes relative to advect on the same
        // frames (and, on a strongly sheared scene, so does popping, against
        // advect's renewal floor): judged once every method of the scene
        // has run.
        eval::judge_against_floor_on(&mut runs, self.thresholds, name);
        let reports = runs
            .iter()
            .zip(parameters)
            .map(|(run, p)| MethodReport::new(run, p))
            .collect();
        let images = write_pictures(&self.args.out, name, &keep, &runs)?;
        Ok(SceneReport::new(&prepared, reports, images))
    }
}

/// report.json, report.md and report.html in `out`.
fn write_reports(out: &Path, report: &Report, thresholds: &Thresholds) -> Result<()> {
    let json = serde_json::to_vec_pretty(report)?;
    write(&out.join("report.json"), &json)?;
    write(&out.join("report.md"), report.to_markdown().as_bytes())?;
    write(
        &out.join("report.html"),
        report.to_html(thresholds).as_bytes(),
    )
}

/// The command line that `a` stands for, as `report.json` records it.
pub(crate) fn compare_command_line(a: &CompareArgs, methods: &[String]) -> String {
    let input = match &a.mesh {
        Some(m) => format!("--mesh '{m}' --fps {}", a.fps),
        None => format!("--scenes {}", a.scenes),
    };
    let mut s = format!(
        "fluidtex compare {input} --methods {} --atlas {} --render {} --seed {}",
        methods.join(","),
        a.atlas,
        a.render,
        a.seed
    );
    if let Some(f) = &a.frames {
        s.push_str(&format!(" --frames {f}"));
    }
    if let Some(r) = a.resolution {
        s.push_str(&format!(" --resolution {r}"));
    }
    if let Some(e) = &a.exemplar {
        s.push_str(&format!(" --exemplar {}", e.display()));
    }
    if a.paper {
        s.push_str(" --paper");
    }
    if let Some(attribute) = &a.select_by {
        s.push_str(&format!(" --select-by {attribute}"));
    }
    s
}

/// The frames shown in pictures: up to 6, evenly spread, first and last
/// included.
fn picture_frames(frames: &[i32]) -> Vec<i32> {
    let n = frames.len();
    if n <= 6 {
        return frames.to_vec();
    }
    let mut out: Vec<i32> = (0..6).map(|k| frames[k * (n - 1) / 5]).collect();
    out.dedup();
    out
}

fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    fluidtex::io::write_atomic(path, |w| std::io::Write::write_all(w, bytes))?;
    Ok(())
}

fn write_png(path: &Path, t: &Texture) -> Result<()> {
    let bytes = encode_png(t, &PngOptions::default())
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    write(path, &bytes)
}

/// Side-by-side frames (methods left to right) for the first, middle and
/// last kept frame, and a contact sheet (a row per method, a column per
/// kept frame). Returns (caption, file name) pairs.
fn write_pictures(
    out: &Path,
    scene: &str,
    keep: &[i32],
    runs: &[MethodRun],
) -> Result<Vec<(String, String)>> {
    let background = [0.12, 0.12, 0.14];
    let mut images = Vec::new();
    let names: Vec<&str> = runs.iter().map(|r| r.method.as_str()).collect();
    let picks: Vec<i32> = match keep {
        [] => Vec::new(),
        [only] => vec![*only],
        [first, .., last] => {
            let mid = keep[keep.len() / 2];
            let mut v = vec![*first, mid, *last];
            v.dedup();
            v
        }
    };
    for f in picks {
        let row: Vec<&Texture> = runs
            .iter()
            .filter_map(|r| r.renders.iter().find(|(n, _)| *n == f).map(|(_, t)| t))
            .collect();
        if row.is_empty() {
            continue;
        }
        let file = format!("{scene}_frame{f:04}.png");
        write_png(
            &out.join(&file),
            &fluidtex::render::side_by_side(&row, 8, background),
        )?;
        images.push((
            format!("{scene}, frame {f}: {} (left to right)", names.join(" | ")),
            file,
        ));
    }
    let thumbs: Vec<Vec<Texture>> = runs
        .iter()
        .map(|r| {
            r.renders
                .iter()
                .map(|(_, t)| fluidtex::metrics::rescale(t, 0.5).unwrap_or_else(|_| t.clone()))
                .collect()
        })
        .collect();
    let rows: Vec<Vec<&Texture>> = thumbs.iter().map(|r| r.iter().collect()).collect();
    if rows.iter().any(|r| !r.is_empty()) {
        let file = format!("{scene}_sheet.png");
        write_png(&out.join(&file), &contact_sheet(&rows, 4, background))?;
        images.push((
            format!(
                "{scene} contact sheet: rows {}, columns frames {}",
                names.join(", "),
                keep.iter()
                    .map(|f| f.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            file,
        ));
    }
    Ok(images)
}
