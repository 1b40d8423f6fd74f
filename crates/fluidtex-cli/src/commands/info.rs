//! `fluidtex info PATTERN`: what a sequence holds, frame by frame.
//!
//! Every per-vertex scalar property of the files is read
//! ([`ReadOptions::all_scalar_attributes`]) and listed with its range,
//! e.g. `temperature:f[0.012..0.998]`, so that a user can see which
//! attribute `--select-by` could use and over which values, before a run.

use anyhow::{Context, Result};
use clap::Args;
use fluidtex::io::ReadOptions;
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
    let options = ReadOptions {
        all_scalar_attributes: true,
        ..super::run::read_options(a.velocity.as_deref())?
    };
    let mut source: Box<dyn FrameSource> = if crate::usd::is_usd(&a.pattern) {
        Box::new(crate::usd::UsdSource::open_with(
            &a.pattern,
            a.prim.as_deref(),
            a.frames.as_deref(),
            options,
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
            .map(|(k, a)| match a {
                Attribute::Scalar(v) => format!("{k}:f[{}]", range(v)),
                Attribute::Vec2(_) => format!("{k}:vec2"),
                Attribute::Vec3(_) => format!("{k}:vec3"),
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

/// "lo..hi" of a scalar attribute (3 decimals), "-" when it is empty.
fn range(values: &[f32]) -> String {
    let Some(&first) = values.first() else {
        return "-".to_string();
    };
    let (lo, hi) = values
        .iter()
        .fold((first, first), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    format!("{lo:.3}..{hi:.3}")
}

#[cfg(test)]
mod tests {
    use super::range;

    #[test]
    fn ranges_are_printed_with_three_decimals() {
        assert_eq!(range(&[0.5, 0.012, 0.998]), "0.012..0.998");
        assert_eq!(range(&[2.0]), "2.000..2.000");
        assert_eq!(range(&[-1.5, 161.0]), "-1.500..161.000");
        assert_eq!(range(&[]), "-");
    }
}
