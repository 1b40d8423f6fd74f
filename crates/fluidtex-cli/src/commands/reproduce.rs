//! `fluidtex reproduce`: each paper's headline comparison beside ours, on
//! the same kind of input, written to `docs/reproduction.md`.
//!
//! The work is a fixed [`Plan`]: `compare --paper` on two Mantaflow
//! liquids (a violent splash and a slow viscous one, baked by
//! `tools/mantaflow_splash.py`), plus timing runs of each method at the
//! papers' triangle or point counts on the generated scenes. The report puts
//! the paper's figure, ours, the input and the command in one row.
//!
//! The report takes most of an hour on two cores, too long for CI. So its
//! first lines record a **fingerprint**: a SHA-256 of everything the command
//! would use — the version, the plan's commands, the bake recipes, every
//! method's default parameters, the paper preset and the committed
//! thresholds. `tests/reproduction_report.rs` recomputes it with
//! [`fingerprint`] and fails when the committed report no longer matches
//! what the command would do now (then regenerate it). The input files'
//! own hashes are listed in the report too; they are information, since a
//! clone holds the bake recipe, not the bakes.

mod report;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::bench::{BenchRow, time_generated};
use super::compare::{CompareArgs, DEFAULT_SCENES, compare, compare_command_line};
use crate::config::Config;
use fluidtex::io::FrameRange;
use fluidtex::methods::registry::{MethodKind, MethodParams};
use fluidtex::named::Named;

/// One liquid the comparisons run on.
#[derive(Clone, Copy, Debug)]
pub struct Input {
    /// `--splash` / `--viscous`, and the work folder's name.
    pub key: &'static str,
    /// What it is, for the report.
    pub what: &'static str,
    /// How to bake it (run from the repository root; `OUT` is the folder).
    pub bake: &'static str,
    /// The frames compared.
    pub frames: &'static str,
}

/// One timing run: a method at a paper's size on a generated scene.
#[derive(Clone, Copy, Debug)]
pub struct Timed {
    /// Its key in `timings.json` and the report.
    pub id: &'static str,
    /// `--method`.
    pub method: &'static str,
    /// Under `--preset paper`.
    pub paper_preset: bool,
    /// `--scene`.
    pub scene: &'static str,
    /// `--triangles`: the paper's count for its own scene.
    pub triangles: usize,
    /// `--atlas`.
    pub atlas: u32,
    /// `--frames` (the first is left out of the means).
    pub frames: u32,
}

impl Timed {
    /// The `fluidtex bench` line that measures the same thing.
    pub fn command(&self) -> String {
        format!(
            "fluidtex bench --scene {} --triangles {} --atlas {} --frames {} --method {}{}",
            self.scene,
            self.triangles,
            self.atlas,
            self.frames,
            self.method,
            if self.paper_preset {
                " --preset paper"
            } else {
                ""
            }
        )
    }
}

/// Everything `reproduce` runs.
#[derive(Clone, Debug)]
pub struct Plan {
    pub inputs: Vec<Input>,
    pub compare_atlas: u32,
    pub timings: Vec<Timed>,
}

const BAKE: &str =
    "blender -b --factory-startup --python-exit-code 1 --python tools/mantaflow_splash.py --";

impl Default for Plan {
    fn default() -> Plan {
        let timed = |id, method, scene, triangles, atlas| Timed {
            id,
            method,
            paper_preset: false,
            scene,
            triangles,
            atlas,
            frames: 3,
        };
        Plan {
            inputs: vec![
                Input {
                    key: "splash",
                    what: "a violent splash: a dam break and a thrown ball in a closed 2 × 1 × 1.2 \
                           box (Mantaflow, resolution 80), 20k–61k triangles on these frames",
                    bake: "OUT --frames 48",
                    frames: "10-21",
                },
                Input {
                    key: "viscous",
                    what: "a slow viscous liquid: a honey-like ball dropped on the floor of a \
                           1 × 1 × 1 box, slumping and creeping (Mantaflow with viscosity, \
                           resolution 64), about 12k triangles, moving at 1–11 cm/s",
                    bake: "OUT --scene viscous --res 64 --frames 48",
                    frames: "12-23",
                },
            ],
            compare_atlas: 512,
            timings: vec![
                timed("2021-dam-break", "erosion", "dam-break", 85_000, 2048),
                timed("2021-viscous-drop", "erosion", "viscous-drop", 61_000, 2048),
                timed("2021-lava", "erosion", "lava", 271_000, 2048),
                timed("2016-dam-break", "lapped-rigid", "dam-break", 65_000, 2048),
                timed("2016-lava", "lapped-rigid", "lava", 260_000, 2048),
                Timed {
                    paper_preset: true,
                    ..timed("2007-dam-break", "optimization", "dam-break", 7_000, 512)
                },
            ],
        }
    }
}

impl Plan {
    /// The `compare` arguments for `input` read from `mesh`, into `out`.
    pub(crate) fn compare_args(&self, input: &Input, mesh: &str, out: PathBuf) -> CompareArgs {
        CompareArgs {
            scenes: DEFAULT_SCENES.to_string(),
            methods: None,
            out,
            frames: Some(input.frames.to_string()),
            atlas: self.compare_atlas,
            resolution: None,
            render: 256,
            seed: 0,
            exemplar: None,
            config: None,
            mesh: Some(mesh.to_string()),
            fps: 24.0,
            paper: true,
            select_by: None,
            quiet: false,
        }
    }

    /// Every command the plan runs, with `INPUT` for a liquid's frames: the
    /// bakes, the comparisons, the timings.
    pub fn commands(&self) -> Vec<String> {
        let mut out = Vec::new();
        for input in &self.inputs {
            out.push(format!("{BAKE} {}", input.bake));
            let a = self.compare_args(input, "INPUT", PathBuf::from(input.key));
            out.push(compare_command_line(&a, &all_methods()));
        }
        out.extend(self.timings.iter().map(Timed::command));
        out
    }
}

/// Every method's `--method` name, in the registry's order.
pub(crate) fn all_methods() -> Vec<String> {
    MethodKind::ALL
        .iter()
        .map(|m| m.name().to_string())
        .collect()
}

/// The SHA-256 (hex) of everything `plan` would use: the version, its
/// commands, the default parameters, the paper preset, the thresholds.
pub fn fingerprint(plan: &Plan) -> String {
    let mut h = Sha256::new();
    let mut part = |name: &str, text: &str| {
        h.update(name.as_bytes());
        h.update((text.len() as u64).to_le_bytes());
        h.update(text.as_bytes());
    };
    part("version", env!("CARGO_PKG_VERSION"));
    for c in plan.commands() {
        part("command", &c);
    }
    let defaults = serde_json::to_string(&MethodParams::default()).unwrap_or_default();
    part("defaults", &defaults);
    part("paper preset", &fluidtex::departures::paper_preset());
    part("thresholds", fluidtex::metrics::committed_thresholds_text());
    format!("{:x}", h.finalize())
}

#[derive(Args, Debug)]
pub struct ReproduceArgs {
    /// The splash's frames, baked with `tools/mantaflow_splash.py -- OUT --frames 48`
    /// (e.g. 'splash/mesh/fluid.####.ply')
    #[arg(long)]
    pub splash: String,
    /// The viscous liquid's frames, baked with
    /// `tools/mantaflow_splash.py -- OUT --scene viscous --res 64 --frames 48`
    #[arg(long)]
    pub viscous: String,
    /// Folder for the comparisons and timings (kept: a second run reuses
    /// every step whose command has not changed)
    #[arg(long)]
    pub work: PathBuf,
    /// The report to write
    #[arg(long, default_value = "docs/reproduction.md")]
    pub out: PathBuf,
}

/// One timing run's figures, as kept in `timings.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TimingResult {
    /// The command it stands for ([`Timed::command`]).
    pub command: String,
    /// Triangles of the first frame.
    pub triangles: usize,
    /// Mean seconds per stage over the frames after the first.
    pub stages: BTreeMap<String, f64>,
    /// Mean wall-clock seconds per frame after the first.
    pub wall_per_frame: f64,
    /// The method's statistics, per frame after the first.
    pub stats: Vec<BTreeMap<String, serde_json::Value>>,
    /// Rayon threads it ran on.
    pub threads: usize,
}

pub fn reproduce(a: &ReproduceArgs) -> Result<()> {
    let plan = Plan::default();
    let start = Instant::now();
    std::fs::create_dir_all(&a.work)
        .with_context(|| format!("cannot create {}", a.work.display()))?;
    // A step is reused only under the same fingerprint: a changed default
    // or preset leaves the commands as they were but not their results.
    let print = fingerprint(&plan);
    let stamp = a.work.join("fingerprint.txt");
    let same = std::fs::read_to_string(&stamp).is_ok_and(|t| t.trim() == print);
    if !same {
        write(&stamp, format!("{print}\n").as_bytes())?;
    }
    let mut compared = Vec::new();
    for input in &plan.inputs {
        let mesh = if input.key == "splash" {
            &a.splash
        } else {
            &a.viscous
        };
        let range: FrameRange = input.frames.parse()?;
        let files = input_files(mesh, range)?;
        let out = a.work.join(input.key);
        let args = plan.compare_args(input, mesh, out.clone());
        let command = compare_command_line(&args, &all_methods());
        let report_path = out.join("report.json");
        if same && reusable(&report_path, &command) {
            eprintln!(
                "reproduce: {}: reusing {}",
                input.key,
                report_path.display()
            );
        } else {
            compare(&args).with_context(|| format!("comparing on {}", input.key))?;
        }
        let report = read_json(&report_path)?;
        compared.push((*input, files, report, out));
    }
    let timings = run_timings(&plan, &a.work, same)?;
    let text = report::render(&plan, &fingerprint(&plan), &compared, &timings, &a.out)?;
    write(&a.out, text.as_bytes())?;
    eprintln!(
        "reproduce: wrote {} in {:.0} s",
        a.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Whether `report` holds a comparison made by `command`.
fn reusable(report: &Path, command: &str) -> bool {
    read_json(report)
        .ok()
        .and_then(|v| {
            v.get("command")
                .and_then(|c| c.as_str())
                .map(|c| c == command)
        })
        .unwrap_or(false)
}

fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    fluidtex::io::write_atomic(path, |w| std::io::Write::write_all(w, bytes))
        .with_context(|| format!("cannot write {}", path.display()))
}

fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_slice(&text).with_context(|| format!("{}: not valid JSON", path.display()))
}

/// The files of `pattern` in `range`, each with its SHA-256, so the
/// report says exactly which bake it was made on.
fn input_files(pattern: &str, range: FrameRange) -> Result<Vec<(String, String)>> {
    let pattern = fluidtex::io::FramePattern::parse(pattern)?;
    let mut out = Vec::new();
    for f in range.frames() {
        let path = pattern.path(f);
        let bytes = std::fs::read(&path)
            .with_context(|| format!("{}: frame {f} cannot be read", path.display()))?;
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        out.push((name, format!("{:x}", Sha256::digest(&bytes))));
    }
    Ok(out)
}

/// Runs (or, with `reuse`, takes from `work/timings.json`) every timing
/// of `plan`.
fn run_timings(plan: &Plan, work: &Path, reuse: bool) -> Result<BTreeMap<String, TimingResult>> {
    let path = work.join("timings.json");
    let mut kept: BTreeMap<String, TimingResult> = read_json(&path)
        .ok()
        .filter(|_| reuse)
        .and_then(|v| serde_json::from_value(v).ok())
        .unwrap_or_default();
    for t in &plan.timings {
        if kept.get(t.id).is_some_and(|r| r.command == t.command()) {
            eprintln!("reproduce: {}: reusing its timing", t.id);
            continue;
        }
        eprintln!("reproduce: timing {}", t.command());
        let result = time_one(t, &work.join("frames").join(t.id))?;
        kept.insert(t.id.to_string(), result);
        // Kept after every run, so an interrupted reproduction resumes.
        let text = serde_json::to_vec_pretty(&kept)?;
        write(&path, &text)?;
    }
    kept.retain(|id, _| plan.timings.iter().any(|t| t.id == id));
    Ok(kept)
}

fn time_one(t: &Timed, out: &Path) -> Result<TimingResult> {
    let method = MethodKind::parse_named("method", t.method).map_err(anyhow::Error::msg)?;
    let base = Config::load_with_preset(None, t.paper_preset.then_some("paper"))?;
    let mut config = Config {
        method: Some(method),
        atlas: Some(t.atlas),
        ..base
    };
    config.outputs.obj = true;
    config.outputs.glb = true;
    let (triangles, timing) =
        time_generated(t.scene, t.triangles, t.frames, config, out.to_path_buf())?;
    let rows: &[BenchRow] = &timing.rows;
    if rows.is_empty() {
        bail!("{}: no frame was timed", t.id);
    }
    let after = (rows.len() - 1).max(1) as f64;
    Ok(TimingResult {
        command: t.command(),
        triangles,
        stages: timing.stage_means(),
        wall_per_frame: timing.after_first.unwrap_or(timing.wall) / after,
        stats: rows
            .iter()
            .skip(usize::from(rows.len() > 1))
            .map(|r| r.3.clone())
            .collect(),
        threads: rayon::current_num_threads(),
    })
}
