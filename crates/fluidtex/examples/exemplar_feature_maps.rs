//! Writes the built-in pebbles exemplar and the derived feature maps of the
//! CC0 test exemplars as PNGs, and prints what each derivation measured.
//!
//! `cargo run --release -p fluidtex --example exemplar_feature_maps -- OUT_DIR`

use std::path::{Path, PathBuf};
use std::time::Instant;

use fluidtex::exemplar::feature::{self, DistanceParams, FeatureMethod};
use fluidtex::exemplar::{Exemplar, builtin_pebbles};
use fluidtex::texture::Texture;

fn save(t: &Texture, path: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let bytes: Vec<u8> = t
        .data
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    let colour = match t.channels {
        1 => image::ExtendedColorType::L8,
        3 => image::ExtendedColorType::Rgb8,
        _ => image::ExtendedColorType::Rgba8,
    };
    image::save_buffer(path, &bytes, t.width, t.height, colour)?;
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "target/feature-maps".into()),
    );
    std::fs::create_dir_all(&out)?;

    let start = Instant::now();
    let pebbles = builtin_pebbles(512, 1);
    println!(
        "builtin_pebbles(512): {:.1} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
    save(&pebbles.colour, &out.join("pebbles.png"))?;
    save(&pebbles.feature.map, &out.join("pebbles-feature.png"))?;
    // 2×2 tiling shows whether the seams are visible.
    let tiled = tile(&pebbles.colour, 2);
    save(&tiled, &out.join("pebbles-tiled.png"))?;

    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/exemplars");
    for name in ["gravel", "brick", "grass"] {
        let path = data.join(format!("{name}.png"));
        let ex = Exemplar::load(&path, &[], None, FeatureMethod::Luminance)?;
        for method in [
            FeatureMethod::Luminance,
            FeatureMethod::DistanceTransform,
            FeatureMethod::Auto,
        ] {
            let start = Instant::now();
            let d = feature::derive(&ex.colour, method, &DistanceParams::default())?;
            let ms = start.elapsed().as_secs_f64() * 1e3;
            println!(
                "{name:6} {method:?}: chose {:?}, separability {:.3}, thickness {:.2} px, {ms:.1} ms",
                d.map.origin, d.separability, d.thickness
            );
            save(
                &d.map.map,
                &out.join(format!("{name}-{method:?}.png").to_lowercase()),
            )?;
        }
    }
    Ok(())
}

fn tile(t: &Texture, n: u32) -> Texture {
    let mut out = Texture::filled(t.width * n, t.height * n, t.channels, 0.0);
    for y in 0..out.height {
        for x in 0..out.width {
            let src = t.texel(x % t.width, y % t.height).to_vec();
            out.texel_mut(x, y).copy_from_slice(&src);
        }
    }
    out
}
