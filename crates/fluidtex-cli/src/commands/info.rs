//! `fluidtex info PATTERN`: what a sequence holds, frame by frame.

use anyhow::{Context, Result};
use clap::Args;
use fluidtex::mesh::Attribute;
use fluidtex::pipeline::{FrameSource, SequenceSource};

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// Mesh sequence: fluid.$F4.ply, fluid.####.ply or fluid.%04d.ply
    pub pattern: String,
    /// Frame range A-B (or A); default: every frame found
    #[arg(long)]
    pub frames: Option<String>,
    /// PLY velocity property names, e.g. --velocity vel_x,vel_y,vel_z
    #[arg(long, value_delimiter = ',', num_args = 3)]
    pub velocity: Option<Vec<String>>,
    /// USD input: the Mesh prim to read, e.g. /liquid/surface
    #[arg(long)]
    pub prim: Option<String>,
}

pub fn info(a: &InfoArgs) -> Result<()> {
    let options = super::run::read_options(a.velocity.as_deref())?;
    let mut source: Box<dyn FrameSource> = if crate::usd::is_usd(&a.pattern) {
        Box::new(crate::usd::UsdSource::open(
            &a.pattern,
            a.prim.as_deref(),
            a.frames.as_deref(),
        )?)
    } else {
        Box::new(SequenceSource::open(
            &a.pattern,
            a.frames.as_deref(),
            options,
        )?)
    };
    let frames = source.frames();
    println!(
        "sequence {}: {} frames ({}-{})",
        a.pattern,
        frames.len(),
        frames.first().unwrap_or(&0),
        frames.last().unwrap_or(&0)
    );
    println!(
        "{:>6} {:>9} {:>9} {:>8}  {:<34} {:<24} attributes",
        "frame", "vertices", "triangles", "dropped", "bounding box", "|velocity| min..max"
    );
    for f in frames {
        let (mesh, report) = source.read(f).with_context(|| format!("frame {f}"))?;
        let bbox = match mesh.bounding_box() {
            Some((lo, hi)) => format!(
                "({:.3},{:.3},{:.3})-({:.3},{:.3},{:.3})",
                lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
            ),
            None => "empty".to_string(),
        };
        let speed = match mesh.velocity() {
            Some(v) if !v.is_empty() => {
                let (lo, hi) = v
                    .iter()
                    .map(|v| v.length())
                    .fold((f32::MAX, 0.0f32), |(lo, hi), s| (lo.min(s), hi.max(s)));
                format!("{lo:.4}..{hi:.4}")
            }
            Some(_) => "-".to_string(),
            None => "no velocity".to_string(),
        };
        let attrs: Vec<String> = mesh
            .attributes
            .iter()
            .map(|(k, a)| {
                let kind = match a {
                    Attribute::Scalar(_) => "f",
                    Attribute::Vec2(_) => "vec2",
                    Attribute::Vec3(_) => "vec3",
                };
                format!("{k}:{kind}")
            })
            .collect();
        println!(
            "{f:>6} {:>9} {:>9} {:>8}  {bbox:<34} {speed:<24} {}",
            mesh.vertex_count(),
            mesh.triangle_count(),
            report.dropped_degenerate,
            attrs.join(" ")
        );
    }
    Ok(())
}
