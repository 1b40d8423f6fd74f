//! Times the software rasterizer on a 58k-triangle wavy sheet at 1024²
//! (the reference figure in docs/design.md, *Crates and measurements*:
//! 71 ms) and writes a preview sheet (unlit | lit) of the sheet textured
//! with the built-in pebbles.
//!
//! `cargo run --release -p fluidtex --example render_preview -- OUT.png`

use std::time::Instant;

use fluidtex::exemplar::builtin_pebbles;
use fluidtex::render::{Camera, rasterize, shade_lit, shade_textured, side_by_side};
use fluidtex::texture::Texture;
use glam::{Vec2, Vec3};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "target/render-preview.png".into());
    // 171×171 quads = 58,482 triangles.
    let n = 171usize;
    let height =
        |x: f32, z: f32| 0.08 * (6.0 * x).sin() * (4.0 * z).cos() + 0.05 * (11.0 * (x + z)).sin();
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            let (x, z) = (u * 2.0 - 1.0, v * 2.0 - 1.0);
            positions.push(Vec3::new(x, height(x, z), z));
            let e = 1e-3;
            let dx = (height(x + e, z) - height(x - e, z)) / (2.0 * e);
            let dz = (height(x, z + e) - height(x, z - e)) / (2.0 * e);
            normals.push(Vec3::new(-dx, 1.0, -dz).normalize());
            uvs.push(Vec2::new(u, v));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let v = |a: usize, b: usize| (b * (n + 1) + a) as u32;
            triangles.push([v(i, j), v(i, j + 1), v(i + 1, j)]);
            triangles.push([v(i + 1, j), v(i, j + 1), v(i + 1, j + 1)]);
        }
    }
    let camera = Camera::framing(
        Vec3::new(-1.0, -0.2, -1.0),
        Vec3::new(1.0, 0.2, 1.0),
        Vec3::new(0.4, -0.7, 0.6),
        1024,
        1024,
    );

    let mut best = f64::INFINITY;
    let mut gb = rasterize(&positions, &triangles, &camera);
    for _ in 0..5 {
        let t = Instant::now();
        gb = rasterize(&positions, &triangles, &camera);
        best = best.min(t.elapsed().as_secs_f64());
    }
    println!(
        "rasterize: {} triangles at 1024x1024, {} pixels covered, best of 5: {:.1} ms ({} threads)",
        triangles.len(),
        gb.covered(),
        best * 1e3,
        rayon::current_num_threads()
    );
    let pebbles = builtin_pebbles(512, 1);
    let t = Instant::now();
    let unlit = shade_textured(&gb, &triangles, &uvs, &pebbles.colour, [0.1, 0.1, 0.12]);
    println!("shade_textured: {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
    let t = Instant::now();
    let lit = shade_lit(
        &gb,
        &triangles,
        &normals,
        &uvs,
        &pebbles.colour,
        &camera,
        [0.1, 0.1, 0.12],
    );
    println!("shade_lit: {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
    let sheet = side_by_side(&[&unlit, &lit], 8, [1.0, 1.0, 1.0]);
    save(&sheet, &out)?;
    println!("wrote {out}");
    Ok(())
}

fn save(t: &Texture, path: &str) -> Result<(), Box<dyn std::error::Error>> {
    let bytes: Vec<u8> = t
        .data
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    image::save_buffer(
        path,
        &bytes,
        t.width,
        t.height,
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(())
}
