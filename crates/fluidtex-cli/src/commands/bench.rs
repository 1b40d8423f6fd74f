//! `fluidtex bench`: per-stage timings of the whole frame job on a generated
//! surface of a chosen size. Meshes are generated before timing starts, so
//! the figures cover what a production run does per frame: BVH, atlas
//! unwrap, the method's stages, dilation and writing.

use std::collections::BTreeMap;
use std::path::PathBuf;

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
    /// Rayon threads (default: all cores)
    #[arg(long)]
    pub threads: Option<usize>,
    /// Folder for the written frames (default: a temporary folder)
    #[arg(long)]
    pub out: Option<PathBuf>,
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
}

/// One frame's figures: frame, stage seconds, stage order, method stats.
type BenchRow = (
    i32,
    BTreeMap<String, f64>,
    Vec<String>,
    BTreeMap<String, serde_json::Value>,
);

pub fn bench(a: &BenchArgs) -> Result<()> {
    if a.frames < 2 {
        bail!("--frames {}: need at least 2", a.frames);
    }
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("cannot size the thread pool")?;
    }
    // Calibrate the scene resolution to the requested triangle count: the
    // count grows with the square of the resolution for surface meshes.
    let probe = scene_params(&a.scene, None, None, None, None)?;
    let first = probe.first;
    let mut s = scenes::by_name(&a.scene, Some(probe))?;
    let t0 = s.frame(first)?.triangle_count().max(1);
    let resolution = ((probe.resolution as f64) * (a.triangles as f64 / t0 as f64).sqrt())
        .round()
        .clamp(8.0, 2048.0) as u32;
    let last = first + a.frames as i32 - 1;
    let params = scene_params(
        &a.scene,
        Some(&format!("{first}-{last}")),
        Some(resolution),
        None,
        None,
    )?;
    let mut scene = scenes::by_name(&a.scene, Some(params))?;
    eprintln!(
        "generating {} frames of {} at resolution {resolution} ...",
        a.frames, a.scene
    );
    let mut frames = Vec::new();
    for f in first..=last {
        let mut mesh = scene.frame(f)?;
        fluidtex::mesh::validate(&mut mesh)?;
        frames.push((f, mesh));
    }
    let tris = frames[0].1.triangle_count();
    let mut config = Config {
        method: Some(a.method),
        atlas: Some(a.atlas),
        fps: Some(params.fps as f32),
        ..Default::default()
    };
    config.outputs.obj = true;
    config.outputs.glb = true;
    config.outputs.debug = false;
    config.erosion.placement = a.placement;
    if let Some(n) = a.patches {
        let area = frames[0].1.area();
        // Dart throwing reaches about 0.7 A / r² disks.
        config.erosion.radius = Some((0.7 * area / n.max(1) as f64).sqrt() as f32);
    }
    let tmp;
    let out = match &a.out {
        Some(p) => p.clone(),
        None => {
            tmp = tempfile::tempdir()?;
            tmp.path().to_path_buf()
        }
    };
    let mut method = build_method(&config)?;
    let job = build_job(&config, out, false)?;
    let mut rows: Vec<BenchRow> = Vec::new();
    let mut observer = |e: Event<'_>| {
        if let Event::Done { stats } = e {
            rows.push((
                stats.frame,
                stats.seconds.clone(),
                stats.stage_order.clone(),
                stats.method_stats.clone(),
            ));
        }
    };
    let mut source = Memory { frames };
    pipeline::run(&job, &mut source, method.as_mut(), &mut observer)?;

    let threads = rayon::current_num_threads();
    println!(
        "{} on {} ({tris} triangles), atlas {}², {} frames, {threads} threads",
        a.method, a.scene, a.atlas, a.frames
    );
    let Some((_, _, order, _)) = rows.last() else {
        bail!("no frame was processed")
    };
    let order = order.clone();
    print!("{:<8}", "frame");
    for s in &order {
        print!("{s:>10}");
    }
    println!("{:>10}{:>9}{:>9}", "total", "patches", "created");
    let mut sums: BTreeMap<String, f64> = BTreeMap::new();
    for (k, (f, secs, _, ms)) in rows.iter().enumerate() {
        print!("{f:<8}");
        let mut total = 0.0;
        for s in &order {
            let v = secs.get(s).copied().unwrap_or(0.0);
            total += if s == "read" { 0.0 } else { v };
            print!("{v:>10.3}");
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
    for s in &order {
        let v = sums.get(s).copied().unwrap_or(0.0) / n;
        total += if s == "read" { 0.0 } else { v };
        print!("{v:>10.3}");
    }
    println!("{total:>10.3}");
    println!(
        "(* frames after the first; 'read' copies pre-generated meshes and is left out of the total)"
    );
    Ok(())
}
