//! Atlas fill (share of atlas texels inside charts), chart count, scale, the
//! time of each atlas stage per frame of a mesh sequence, and on the generated liquid
//! blob: the measurement behind the packer's fill figures.
//!
//! ```text
//! cargo run --release -p fluidtex --example pack_fill -- PATTERN FIRST LAST [SIDE] [THREADS]
//! cargo run --release -p fluidtex --example pack_fill -- blob [TRIS] [SIDE] [THREADS]
//! cargo run --release -p fluidtex --example pack_fill -- splash [TRIS] [DROPLETS] [SIDE]
//! ```
//! PATTERN: a path with `{}` standing for the 4-digit frame number, e.g.
//! `/data/dam/fluid.{}.ply`; SIDE: atlas side (default 1024); THREADS:
//! rayon threads (default: all cores; the blob and splash take it as their
//! last argument too). `splash` is the blob plus DROPLETS small spheres
//! (fixtures::splash). Default atlas parameters otherwise.

use std::path::PathBuf;

use fluidtex::atlas::{Atlas, AtlasParams, fixtures};
use fluidtex::io::{ReadOptions, read_mesh};
use fluidtex::mesh::TriMesh;

fn number(args: &[String], i: usize, default: u32) -> u32 {
    args.get(i)
        .map(|a| {
            a.parse()
                .unwrap_or_else(|_| panic!("argument {a} is not a number"))
        })
        .unwrap_or(default)
}

fn report(name: &str, mesh: &TriMesh, side: u32) {
    let atlas = match Atlas::build(mesh, &AtlasParams::square(side)) {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{name}: atlas failed: {e}");
            return;
        }
    };
    let stats = match atlas.stretch_stats(mesh) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{name}: {e}");
            return;
        }
    };
    println!(
        "{name:>12} {:7} tris {:5} charts  fill {:5.1}%  scale {:9.2}  segmentation {:6.1} ms  lscm {:6.1} ms  packing {:7.1} ms ({} tries)  rasterization {:5.1} ms  p95 {:.3}  overlap {}",
        mesh.triangles.len(),
        atlas.chart_count,
        100.0 * stats.fill_ratio,
        atlas.scale,
        atlas.timings.segmentation.as_secs_f64() * 1e3,
        atlas.timings.lscm.as_secs_f64() * 1e3,
        atlas.timings.packing.as_secs_f64() * 1e3,
        atlas.timings.packing_attempts,
        atlas.timings.rasterization.as_secs_f64() * 1e3,
        stats.p95,
        stats.overlapping_texels,
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mode = args.first().map(String::as_str);
    // The thread count is the last argument: 4th for the blob, 5th otherwise.
    let threads = number(&args, if mode == Some("blob") { 3 } else { 4 }, 0);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads as usize)
        .build()
        .expect("thread pool");
    pool.install(|| {
        if mode == Some("blob") {
            let (tris, side) = (number(&args, 1, 20_000), number(&args, 2, 1024));
            report("blob", &fixtures::liquid_blob(tris, 7), side);
            return;
        }
        if mode == Some("splash") {
            let (tris, drops, side) = (
                number(&args, 1, 8000),
                number(&args, 2, 40),
                number(&args, 3, 512),
            );
            report("splash", &fixtures::splash(tris, drops, 3), side);
            return;
        }
        let Some(pattern) = args.first() else {
            eprintln!("usage: pack_fill PATTERN FIRST LAST [SIDE] [THREADS] | blob [TRIS] [SIDE]");
            return;
        };
        let (first, last, side) = (
            number(&args, 1, 0),
            number(&args, 2, 0),
            number(&args, 3, 1024),
        );
        for f in first..=last {
            let path = PathBuf::from(pattern.replace("{}", &format!("{f:04}")));
            match read_mesh(&path, &ReadOptions::default()) {
                Ok((mesh, _)) => report(&format!("frame {f}"), &mesh, side),
                Err(e) => eprintln!("{}: {e}", path.display()),
            }
        }
    });
}
