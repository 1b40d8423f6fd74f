//! Timings of the output atlas, stage by stage, on a generated liquid-like
//! surface, and of LSCM on single patches.
//!
//! ```text
//! cargo run --release -p fluidtex --example atlas_bench -- TRIS ATLAS [THREADS]
//! cargo run --release -p fluidtex --example atlas_bench -- lscm [N]
//! cargo run --release -p fluidtex --example atlas_bench -- mesh FILE ATLAS [THREADS]
//! ```
//! TRIS: approximate triangle count of the surface (default 20000); ATLAS:
//! atlas side in texels (default 1024); THREADS: rayon threads (default: all
//! cores). `lscm` times single patches of N×N vertices (default: a range
//! from 18 to 4050 triangles; 8 → 98 triangles, 32 → 1922 triangles).

use std::time::Instant;

use fluidtex::atlas::{Atlas, AtlasParams, fixtures};
use fluidtex::param::lscm;
use fluidtex::texture::Texture;
use glam::Vec3;

/// A wavy square patch of `n × n` vertices (2 (n−1)² triangles).
fn patch(n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut pos = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
            pos.push(Vec3::new(x, y, 0.3 * (3.0 * x).sin() * (2.0 * y).cos()));
        }
    }
    let mut tris = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = j * n + i;
            tris.push([a, a + 1, a + n + 1]);
            tris.push([a, a + n + 1, a + n]);
        }
    }
    (pos, tris)
}

fn bench_lscm() {
    // 8×8 → 98 triangles, 32×32 → 1922 triangles.
    let only: Option<u32> = std::env::args().nth(2).and_then(|a| a.parse().ok());
    for n in [4u32, 8, 12, 16, 24, 32, 46] {
        if only.is_some_and(|o| o != n) {
            continue;
        }
        let (pos, tris) = patch(n);
        let reps = (40_000 / tris.len()).max(5);
        let t = Instant::now();
        for _ in 0..reps {
            if let Err(e) = std::hint::black_box(lscm(&pos, &tris)) {
                eprintln!("lscm failed: {e}");
                return;
            }
        }
        let dt = t.elapsed().as_secs_f64() / reps as f64;
        println!(
            "lscm {:5} triangles ({:4} vertices): {:8.1} µs/call ({reps} calls)",
            tris.len(),
            n * n,
            dt * 1e6
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("lscm") {
        bench_lscm();
        return;
    }
    // `mesh PATH SIDE [THREADS]`: a mesh file instead of the generated blob.
    let file = (args.first().map(String::as_str) == Some("mesh")).then(|| args[1..].to_vec());
    // There, the side and threads come one place earlier: no TRIS.
    let args = file.clone().map_or(args, |a| {
        let mut shifted = vec![String::from("0")];
        shifted.extend(a.iter().skip(1).cloned());
        shifted
    });
    let arg = |i: usize, default: u32| -> u32 {
        args.get(i)
            .map(|a| {
                a.parse()
                    .unwrap_or_else(|_| panic!("argument {a} is not a number"))
            })
            .unwrap_or(default)
    };
    let (tris, side, threads) = (arg(0, 20_000), arg(1, 1024), arg(2, 0));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads as usize)
        .build()
        .expect("thread pool");
    let (mesh, name) = match file.as_ref().and_then(|f| f.first()) {
        Some(path) => {
            let options = fluidtex::io::ReadOptions::default();
            match fluidtex::io::read_mesh(std::path::Path::new(path), &options) {
                Ok((mesh, _)) => (mesh, path.clone()),
                Err(e) => {
                    eprintln!("{e}");
                    return;
                }
            }
        }
        None => (fixtures::liquid_blob(tris, 1), "liquid_blob".to_string()),
    };
    pool.install(|| run(&mesh, &name, side));
}

fn run(mesh: &fluidtex::mesh::TriMesh, name: &str, side: u32) {
    println!(
        "surface: {name}, {} triangles, {} vertices; atlas {side}x{side}, {} threads",
        mesh.triangles.len(),
        mesh.positions.len(),
        rayon::current_num_threads()
    );
    let params = AtlasParams::square(side);
    let t = Instant::now();
    let atlas = match Atlas::build(mesh, &params) {
        Ok(a) => a,
        Err(e) => {
            eprintln!("atlas failed: {e}");
            return;
        }
    };
    let build = t.elapsed();
    let tm = atlas.timings;
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;

    let mut tex = Texture::filled(side, side, 3, 0.0);
    for band in atlas.bands() {
        for s in &band.spans {
            let c = [s.triangle as f32, 1.0, 0.5];
            for x in s.x0..s.x1 {
                tex.texel_mut(x, s.y).copy_from_slice(&c);
            }
        }
    }
    let t = Instant::now();
    atlas
        .dilate(&mut tex, params.gutter / 2)
        .expect("texture has the atlas size");
    let dilation = t.elapsed();

    let t = Instant::now();
    let mut texels = 0u64;
    for band in atlas.bands() {
        for s in &band.spans {
            for (_, b) in atlas.span_barycentrics(s) {
                texels += (b[0] >= 0.0) as u64;
            }
        }
    }
    let bary = t.elapsed();

    let stats = atlas.stretch_stats(mesh).expect("same mesh");
    let spans: usize = atlas.bands().iter().map(|b| b.spans.len()).sum();
    println!(
        "segmentation {:7.1} ms\nlscm         {:7.1} ms\npacking      {:7.1} ms ({} attempts)\nrasterize    {:7.1} ms\nbuild total  {:7.1} ms\ndilation     {:7.1} ms (radius {}, 3 channels)\nbarycentrics {:7.1} ms (all texels, one thread)",
        ms(tm.segmentation),
        ms(tm.lscm),
        ms(tm.packing),
        tm.packing_attempts,
        ms(tm.rasterization),
        ms(build),
        ms(dilation),
        params.gutter / 2,
        ms(bary),
    );
    println!(
        "charts {}, spans {spans}, texels in charts {texels} ({:.1}%), scale {:.1} texels/unit",
        atlas.chart_count,
        100.0 * stats.fill_ratio,
        atlas.scale
    );
    println!(
        "stretch σ1/σ2: p50 {:.3}, p95 {:.3}, max {:.2}; overlapping texels {}",
        stats.p50, stats.p95, stats.max, stats.overlapping_texels
    );
    // A change meant only to speed the atlas up must leave this unchanged.
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for uv in &atlas.uv_mesh.uvs {
        for v in [uv.x.to_bits(), uv.y.to_bits()] {
            hash = (hash ^ v as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }
    println!("uv hash {hash:016x}");
}
