//! `fluidtex scene NAME --out DIR`: write a generated scene as a PLY sequence.
//!
//! Each frame holds what the scene gives (`io::ply_write`): positions,
//! velocity and every per-vertex scalar it carries (`lava`: `temperature`,
//! `dam-break`: `age`), so that the frames can be textured by those
//! attributes like a user's simulation (`--select-by`).

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use fluidtex::io::InputGuard;
use fluidtex::io::ply_write::{PlyEncoding, write_ply};
use fluidtex::pipeline::frame_tag;
use fluidtex::scenes::{self, SceneParams};

use crate::progress::Progress;

// The field docs are the `--help` text, printed verbatim by clap: `[24]`
// is a default, not an intra-doc link.
#[allow(rustdoc::broken_intra_doc_links)]
#[derive(Args, Debug, Default)]
pub struct SceneArgs {
    /// Scene name (see --list)
    pub name: Option<String>,
    /// List the scenes and exit
    #[arg(long)]
    pub list: bool,
    /// Output folder: fluid.FFFF.ply per frame (positions, velocity and the
    /// scene's per-vertex scalars: lava's temperature, dam-break's age) and
    /// scene.json
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Frame range A-B (default: the scene's own)
    #[arg(long)]
    pub frames: Option<String>,
    /// Grid resolution (default: the scene's own; larger = more triangles)
    #[arg(long)]
    pub resolution: Option<u32>,
    /// Seed (scenes with random choices)
    #[arg(long)]
    pub seed: Option<u64>,
    /// Frames per second [24]
    #[arg(long)]
    pub fps: Option<f64>,
    /// Write ASCII PLY instead of binary
    #[arg(long)]
    pub ascii: bool,
    /// No progress bar and no summary
    #[arg(long)]
    pub quiet: bool,
}

/// The scene parameters `a` asks for, on top of the scene's defaults.
pub fn scene_params(
    name: &str,
    frames: Option<&str>,
    resolution: Option<u32>,
    seed: Option<u64>,
    fps: Option<f64>,
) -> Result<SceneParams> {
    let mut p = scenes::default_params(name)?;
    if let Some(r) = frames {
        let range: fluidtex::io::FrameRange = r.parse()?;
        p.first = range.first;
        p.last = range.last;
    }
    if let Some(r) = resolution {
        p.resolution = r;
    }
    if let Some(s) = seed {
        p.seed = s;
    }
    if let Some(f) = fps {
        p.fps = f;
    }
    p.validate()?;
    Ok(p)
}

pub fn scene(a: &SceneArgs) -> Result<()> {
    if a.list || a.name.is_none() {
        println!("scenes:");
        for (name, what) in scenes::catalogue() {
            println!("  {name:<22} {what}");
        }
        if a.name.is_none() && !a.list {
            bail!("give a scene name, e.g. fluidtex scene vortex --out vortex");
        }
        return Ok(());
    }
    let name = a.name.as_deref().unwrap_or_default();
    let out = a.out.clone().context("no output folder: give --out DIR")?;
    let params = scene_params(name, a.frames.as_deref(), a.resolution, a.seed, a.fps)?;
    let mut scene = scenes::by_name(name, Some(params))?;
    std::fs::create_dir_all(&out)
        .with_context(|| format!("{}: cannot create the folder", out.display()))?;
    let info = scene.info();
    let json = serde_json::to_vec_pretty(&info)?;
    let guard = InputGuard::default();
    guard.write_atomic(&out.join("scene.json"), |w| {
        std::io::Write::write_all(w, &json)
    })?;
    let encoding = if a.ascii {
        PlyEncoding::Ascii
    } else {
        PlyEncoding::BinaryLittleEndian
    };
    let progress = Progress::new((info.last - info.first + 1) as u64, name, a.quiet);
    let mut triangles = 0usize;
    for f in info.first..=info.last {
        progress.set_message(format!("frame {f}"));
        let mesh = scene.frame(f)?;
        triangles = triangles.max(mesh.triangle_count());
        write_ply(
            &out.join(format!("fluid.{}.ply", frame_tag(f))),
            &mesh,
            encoding,
        )?;
        progress.inc();
    }
    progress.finish();
    if !a.quiet {
        eprintln!(
            "{name}: frames {}-{} (up to {triangles} triangles) -> {}/fluid.####.ply",
            info.first,
            info.last,
            out.display()
        );
    }
    Ok(())
}
