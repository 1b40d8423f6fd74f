//! `fluidtex demo`: the whole chain on a built-in analytic scene and the
//! built-in pebbles exemplar, with preview pictures. Needs no input files.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use fluidtex::pipeline::SceneSource;
use fluidtex::scenes;

use super::run::execute;
use super::scene::scene_params;
use crate::config::Config;

/// The demo's scene: a sphere whose angular speed grows with height, so the
/// texture is sheared and erosion has to act, at a size that runs in well
/// under two minutes on two cores.
pub const DEMO_SCENE: &str = "differential-rotation";

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Output folder
    #[arg(long, default_value = "fluidtex-demo")]
    pub out: PathBuf,
    /// Scene to texture (see `fluidtex scene --list`)
    #[arg(long, default_value = DEMO_SCENE)]
    pub scene: String,
    /// Frame range A-B [0-47]
    #[arg(long, default_value = "0-47")]
    pub frames: String,
    /// Texturing method
    #[arg(long, default_value = "erosion", value_parser = crate::config::named::<fluidtex::methods::registry::MethodKind>())]
    pub method: fluidtex::methods::registry::MethodKind,
    /// Atlas size in texels
    #[arg(long, default_value_t = 1024)]
    pub atlas: u32,
    /// Write preview.F.png every N frames
    #[arg(long, default_value_t = 8)]
    pub preview_every: u32,
    /// No progress bar and no summary
    #[arg(long)]
    pub quiet: bool,
}

pub fn demo(a: &DemoArgs) -> Result<()> {
    let params = scene_params(&a.scene, Some(&a.frames), None, None, None)?;
    let scene = scenes::by_name(&a.scene, Some(params))?;
    let mut source = SceneSource::new(scene);
    let mut config = Config {
        method: Some(a.method),
        atlas: Some(a.atlas),
        fps: Some(params.fps as f32),
        ..Default::default()
    };
    config.outputs.preview_every = a.preview_every;
    execute(
        &config,
        a.out.clone(),
        &mut source,
        false,
        a.quiet,
        fluidtex::output::default_memory_limit(),
        fluidtex::pipeline::Phase::OnePass,
    )?;
    if !a.quiet {
        eprintln!(
            "open {}/preview.0000.png (textured | patches), or mesh.FFFF.obj / .glb in any 3-D viewer",
            a.out.display()
        );
    }
    Ok(())
}
