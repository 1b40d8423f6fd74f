//! `fluidtex bench`: per-stage timings of the whole frame job on a generated
//! surface of a chosen size, or on the user's own sequence (`--mesh`, as
//! `fluidtex run --mesh`). Generated meshes are made before timing starts,
//! so the figures cover what a production run does per frame: BVH, atlas
//! unwrap, the method's stages, dilation and writing (a user's sequence is
//! read from disk as in a run: `read` is then real work). Besides the
//! per-stage table it prints the wall-clock seconds per frame, the thread
//! count, the CPU use (on a shared machine, CPU seconds say more than wall
//! clock) and the peak memory.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use fluidtex::mesh::{TriMesh, ValidationReport};
use fluidtex::pipeline::{self, Event, FrameSource, PipelineError};
use fluidtex::scenes;

use super::run::{build_job, build_method};
use super::scene::scene_params;
use crate::config::{Config, named};
use fluidtex::methods::erosion::Placement;
use fluidtex::methods::registry::MethodKind;
use fluidtex::methods::{Stat, StatsExt};

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Approximate triangle count of the generated surface
    #[arg(long, default_value_t = 20_000)]
    pub triangles: usize,
    /// Atlas size in texels
    #[arg(long, default_value_t = 2048)]
    pub atlas: u32,
    /// Frames to time (the first, which places the initial patches, is reported apart)
    #[arg(long, default_value_t = 5)]
    pub frames: u32,
    /// Approximate number of patches (sets the patch radius); default radius = diagonal / 25
    #[arg(long)]
    pub patches: Option<usize>,
    /// Scene that generates the surface
    #[arg(long, default_value = "enright")]
    pub scene: String,
    /// Method to time
    #[arg(long, default_value = "erosion", value_parser = named::<MethodKind>())]
    pub method: MethodKind,
    /// New patch placement
    #[arg(long, default_value = "local", value_parser = named::<Placement>())]
    pub placement: Placement,
    /// Run the method under a preset (`paper`: as its paper publishes it, docs/departures.md)
    #[arg(long)]
    pub preset: Option<String>,
    /// Rayon threads (default: all cores)
    #[arg(long)]
    pub threads: Option<usize>,
    /// Folder for the written frames (default: a temporary folder)
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Time your own sequence instead of a generated one:
    /// fluid.$F4.ply, fluid.####.ply, fluid.%04d.ply or a USD stage
    #[arg(long)]
    pub mesh: Option<String>,
    /// With --mesh: frame range A-B (default: every frame found; --frames then does not apply)
    #[arg(long = "range")]
    pub range: Option<String>,
    /// With --mesh: PLY velocity property names, e.g. --velocity vel_x,vel_y,vel_z
    #[arg(long, value_delimiter = ',', num_args = 1)]
    pub velocity: Option<Vec<String>>,
    /// With --mesh and a USD stage: the Mesh prim to read
    #[arg(long)]
    pub prim: Option<String>,
    /// Colour exemplar (default: the built-in pebbles)
    #[arg(long)]
    pub exemplar: Option<PathBuf>,
    /// Also write the debug outputs (patches.F.png, source.F.exr, the coherence numbers), as `run` does by default
    #[arg(long)]
    pub debug: bool,
    /// Time the 2007 method's exemplar searches instead of a frame job: for each
    /// window of the paper's passes, build seconds, time per query and agreement
    /// with the exact scan (on --exemplar, default the built-in pebbles at 256²)
    #[arg(long)]
    pub exemplar_search: bool,
    /// With --exemplar-search: candidates the clustered search compares per query
    #[arg(long, default_value_t = 64)]
    pub checks: u32,
    /// With --exemplar-search: queries per window
    #[arg(long, default_value_t = 400)]
    pub queries: usize,
}

struct Memory {
    frames: Vec<(i32, TriMesh)>,
}

impl FrameSource for Memory {
    fn frames(&self) -> Vec<i32> {
        self.frames.iter().map(|(f, _)| *f).collect()
    }

    fn read(&mut self, f: i32) -> Result<(TriMesh, ValidationReport), PipelineError> {
        self.frames
            .iter()
            .find(|(g, _)| *g == f)
            .map(|(_, m)| (m.clone(), ValidationReport::default()))
            .ok_or_else(|| PipelineError::Source(format!("frame {f} was not generated")))
    }

    fn largest_frame(&mut self) -> Result<Option<TriMesh>, PipelineError> {
        let most = self.frames.iter().max_by_key(|(_, m)| m.triangles.len());
        Ok(most.map(|(_, m)| m.clone()))
    }
}

/// One frame's figures: frame, stage seconds, stage order, method stats.
pub(crate) type BenchRow = (
    i32,
    BTreeMap<String, f64>,
    Vec<String>,
    BTreeMap<String, serde_json::Value>,
);

pub fn bench(a: &BenchArgs) -> Result<()> {
    if a.mesh.is_none() && a.frames < 2 {
        bail!("--frames {}: need at least 2", a.frames);
    }
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("cannot size the thread pool")?;
    }
    if a.exemplar_search {
        return bench_exemplar_search(a);
    }
    if let Some(pattern) = &a.mesh {
        return bench_sequence(a, pattern);
    }
    let (frames, fps) = generate(&a.scene, a.triangles, a.frames)?;
    let tris = frames[0].1.triangle_count();
    let mut config = bench_config(a)?;
    config.fps = Some(fps);
    if let Some(n) = a.patches {
        let area = frames[0].1.area();
        // Dart throwing reaches about 0.7 A / r² disks.
        config.params.erosion.radius = Some((0.7 * area / n.max(1) as f64).sqrt() as f32);
    }
    let mut source = Memory { frames };
    let title = format!("{} ({tris} triangles)", a.scene);
    time_run(a, &config, &mut source, &title, false)
}

/// `frames` frames of the generated `scene` from its first, at the
/// resolution that gives about `triangles` triangles on the first, with
/// the scene's frame rate.
fn generate(scene: &str, triangles: usize, frames: u32) -> Result<(Vec<(i32, TriMesh)>, f32)> {
    // Calibrate the scene resolution to the requested triangle count: the
    // count grows with the square of the resolution for surface meshes.
    let probe = scene_params(scene, None, None, None, None)?;
    let first = probe.first;
    let mut s = scenes::by_name(scene, Some(probe))?;
    let t0 = s.frame(first)?.triangle_count().max(1);
    let resolution = ((probe.resolution as f64) * (triangles as f64 / t0 as f64).sqrt())
        .round()
        .clamp(8.0, 2048.0) as u32;
    let last = first + frames as i32 - 1;
    let params = scene_params(
        scene,
        Some(&format!("{first}-{last}")),
        Some(resolution),
        None,
        None,
    )?;
    let mut generator = scenes::by_name(scene, Some(params))?;
    eprintln!("generating {frames} frames of {scene} at resolution {resolution} ...");
    let mut out = Vec::new();
    for f in first..=last {
        let mut mesh = generator.frame(f)?;
        fluidtex::mesh::validate(&mut mesh)?;
        out.push((f, mesh));
    }
    Ok((out, params.fps as f32))
}

/// Times `config`'s method on `frames` frames of the generated `scene` at
/// about `triangles` triangles (`fluidtex reproduce`'s timing rows): the
/// first frame's triangle count and the run's figures.
pub(crate) fn time_generated(
    scene: &str,
    triangles: usize,
    frames: u32,
    mut config: Config,
    out: PathBuf,
) -> Result<(usize, Timing)> {
    let (frames, fps) = generate(scene, triangles, frames)?;
    let tris = frames[0].1.triangle_count();
    config.fps = Some(fps);
    let mut source = Memory { frames };
    Ok((tris, Timing::run(&config, out, &mut source)?))
}

/// `--exemplar-search`: the searches of the 2007 method side by side on
/// the finest level's working exemplar, at the default `exemplar_texels`.
fn bench_exemplar_search(a: &BenchArgs) -> Result<()> {
    use fluidtex::methods::optimization::{OptimizationParams, search_bench};
    let exemplar = match &a.exemplar {
        Some(path) => fluidtex::exemplar::Exemplar::load(
            path,
            &[],
            None,
            fluidtex::exemplar::FeatureMethod::default(),
        )?,
        None => fluidtex::exemplar::pebbles::builtin_pebbles(256, 1),
    };
    if a.queries == 0 || a.checks == 0 {
        bail!("--queries and --checks must be at least 1");
    }
    let p = OptimizationParams::default();
    let (w, h) = exemplar.size();
    println!(
        "exemplar {w}x{h}, working exemplar {} texels wide, {} threads, {} queries per window",
        p.exemplar_texels,
        rayon::current_num_threads(),
        a.queries
    );
    println!("window  search     build s  query us  exact  within 10%  mean SSD ratio");
    let rows = search_bench::measure(
        &exemplar,
        p.exemplar_texels,
        &p.sizes,
        a.checks as usize,
        (p.rerank as usize, p.search_grid),
        a.queries,
    );
    for r in rows {
        println!(
            "{:>4}²   {:<9} {:>8.2} {:>9.1} {:>6.3} {:>11.3} {:>15.3}",
            r.window, r.search, r.build_s, r.query_us, r.exact_share, r.within_10, r.mean_ratio
        );
    }
    Ok(())
}

/// The settings every bench run shares: method, atlas, outputs, preset.
fn bench_config(a: &BenchArgs) -> Result<Config> {
    let base = Config::load_with_preset(None, a.preset.as_deref())?;
    let mut config = Config {
        method: Some(a.method),
        atlas: Some(a.atlas),
        exemplar: a.exemplar.clone(),
        ..base
    };
    config.outputs.obj = true;
    config.outputs.glb = true;
    config.outputs.debug = a.debug;
    if a.preset.is_none() {
        config.params.erosion.placement = a.placement;
    }
    Ok(config)
}

/// `--mesh`: the user's own sequence, read from disk frame by frame.
fn bench_sequence(a: &BenchArgs, pattern: &str) -> Result<()> {
    let config = bench_config(a)?;
    if let Some(n) = a.patches {
        bail!("--patches {n}: only for generated scenes (give a config radius instead)");
    }
    let options = super::run::read_options(a.velocity.as_deref())?;
    if crate::usd::is_usd(pattern) {
        let mut source =
            crate::usd::UsdSource::open(pattern, a.prim.as_deref(), a.range.as_deref())?;
        return time_run(a, &config, &mut source, pattern, true);
    }
    let mut source = pipeline::SequenceSource::open(pattern, a.range.as_deref(), options)?;
    time_run(a, &config, &mut source, pattern, true)
}

/// Runs the frame job over `source` and prints the per-stage table, the
/// wall-clock time per frame, the thread count, CPU use and peak memory.
fn time_run(
    a: &BenchArgs,
    config: &Config,
    source: &mut dyn FrameSource,
    title: &str,
    count_read: bool,
) -> Result<()> {
    // The mean leaves out the first frame (it places the initial patches).
    let n = source.frames().len();
    if n < 2 {
        bail!("{title}: {n} frame(s) to time, need at least 2");
    }
    let tmp;
    let out = match &a.out {
        Some(p) => p.clone(),
        None => {
            tmp = tempfile::tempdir()?;
            tmp.path().to_path_buf()
        }
    };
    let timing = Timing::run(config, out, source)?;
    let threads = rayon::current_num_threads();
    println!(
        "{} on {title}, atlas {}², {} frames, {threads} threads",
        a.method,
        a.atlas,
        timing.rows.len()
    );
    timing.print_table(count_read)?;
    timing.print_totals();
    Ok(())
}

/// What one timed run measured.
pub(crate) struct Timing {
    /// A row per frame, in order.
    pub(crate) rows: Vec<BenchRow>,
    /// Seconds from the start of the second frame to the end of the run:
    /// the frames after the first, each computed and written. (Gaps between
    /// finished frames would not do: with write-behind a frame is reported
    /// finished while the next is being computed, so the first gap is
    /// short by up to a frame.)
    pub(crate) after_first: Option<f64>,
    /// Wall-clock seconds of the whole run.
    pub(crate) wall: f64,
    /// CPU seconds (user + system) of the run, where the system says.
    cpu: Option<f64>,
}

impl Timing {
    /// Each stage's mean seconds over the frames after the first (all
    /// frames where there is one), by stage name.
    pub(crate) fn stage_means(&self) -> BTreeMap<String, f64> {
        let skip = usize::from(self.rows.len() > 1);
        let counted = &self.rows[skip..];
        let mut sums: BTreeMap<String, f64> = BTreeMap::new();
        for (_, secs, _, _) in counted {
            for (s, v) in secs {
                *sums.entry(s.clone()).or_default() += v;
            }
        }
        let n = counted.len().max(1) as f64;
        sums.values_mut().for_each(|v| *v /= n);
        sums
    }

    /// Runs the frame job over `source` into `out`, keeping each frame's
    /// stage timings and method statistics.
    fn run(config: &Config, out: PathBuf, source: &mut dyn FrameSource) -> Result<Timing> {
        let mut method = build_method(config)?;
        let job = build_job(config, out, false)?;
        let mut rows: Vec<BenchRow> = Vec::new();
        let mut second_start: Option<Instant> = None;
        let start = Instant::now();
        let cpu_start = cpu_seconds();
        let mut observer = |e: Event<'_>| {
            if let Event::Start { index: 1, .. } = e {
                second_start = Some(Instant::now());
            }
            if let Event::Done { stats } = e {
                rows.push((
                    stats.frame,
                    stats.seconds.clone(),
                    stats.stage_order.clone(),
                    stats.method_stats.clone(),
                ));
            }
        };
        pipeline::run(&job, source, method.as_mut(), &mut observer)?;
        let wall = start.elapsed().as_secs_f64();
        let cpu = cpu_seconds().zip(cpu_start).map(|(b, a)| b - a);
        Ok(Timing {
            rows,
            after_first: second_start.map(|t| t.elapsed().as_secs_f64()),
            wall,
            cpu,
        })
    }

    /// A line per frame with each stage's seconds, the total and the
    /// patch counts, then the mean of the frames after the first.
    fn print_table(&self, count_read: bool) -> Result<()> {
        let rows = &self.rows;
        let Some((_, _, order, _)) = rows.last() else {
            bail!("no frame was processed")
        };
        // `read` copies pre-generated meshes unless the sequence is read
        // from disk: it then counts in the total.
        let counted = |s: &str, v: f64| if s == "read" && !count_read { 0.0 } else { v };
        print!("{:<8}", "frame");
        // A column per stage, wide enough for its name ("exemplar filter").
        let width = |s: &str| s.len().max(9) + 1;
        for s in order {
            print!("{s:>w$}", w = width(s));
        }
        println!("{:>10}{:>9}{:>9}", "total", "patches", "created");
        let mut sums: BTreeMap<String, f64> = BTreeMap::new();
        for (k, (f, secs, _, ms)) in rows.iter().enumerate() {
            print!("{f:<8}");
            let mut total = 0.0;
            for s in order {
                let v = secs.get(s).copied().unwrap_or(0.0);
                total += counted(s, v);
                print!("{v:>w$.3}", w = width(s));
                if k > 0 {
                    *sums.entry(s.clone()).or_default() += v;
                }
            }
            let get = |key| {
                ms.value(key)
                    .map(|v| v.to_string())
                    .unwrap_or_else(|| "-".into())
            };
            println!(
                "{total:>10.3}{:>9}{:>9}",
                get(Stat::PatchesAlive),
                get(Stat::PatchesCreated)
            );
        }
        let n = (rows.len() - 1).max(1) as f64;
        print!("{:<8}", "mean*");
        let mut total = 0.0;
        for s in order {
            let v = sums.get(s).copied().unwrap_or(0.0) / n;
            total += counted(s, v);
            print!("{v:>w$.3}", w = width(s));
        }
        println!("{total:>10.3}");
        if count_read {
            println!("(* frames after the first; total = sum of the stages)");
        } else {
            println!(
                "(* frames after the first; 'read' copies pre-generated meshes and is left out of the total)"
            );
        }
        Ok(())
    }

    /// Wall clock per frame, CPU use and peak memory.
    fn print_totals(&self) {
        let wall = self.wall;
        if let Some(after_first) = self.after_first
            && self.rows.len() > 1
        {
            let mean = after_first / (self.rows.len() - 1) as f64;
            println!("wall clock: {mean:.3} s/frame after the first, {wall:.1} s in all");
        }
        if let Some(cpu) = self.cpu {
            println!(
                "cpu use: {:.0} % of {} % ({cpu:.1} s user+sys over {wall:.1} s)",
                100.0 * cpu / wall.max(1e-9),
                100 * std::thread::available_parallelism().map_or(1, |n| n.get()),
            );
        }
        match peak_memory() {
            Some(bytes) => println!(
                "peak memory: {:.2} GiB (VmHWM)",
                bytes as f64 / (1u64 << 30) as f64
            ),
            None => println!("peak memory: unknown on this system"),
        }
    }
}

/// The process's peak resident memory (Linux `VmHWM`), in bytes.
fn peak_memory() -> Option<u64> {
    fluidtex::pipeline::proc_kib("/proc/self/status", "VmHWM:")
}

/// User + system CPU seconds of the process so far (Linux `/proc/self/stat`,
/// fields 14 and 15, in clock ticks of 1/100 s, the kernel's USER_HZ).
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) may hold spaces; fields after it follow ')'.
    let rest = stat.rsplit_once(')')?.1;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}
