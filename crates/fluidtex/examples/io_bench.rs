//! Prints how long reading meshes and writing each output takes.
//!
//! ```sh
//! cargo run --release -p fluidtex --example io_bench [EXEMPLAR.png]
//! ```
//!
//! Mesh: a 100k-vertex, 200k-triangle binary PLY with velocity (read), and a
//! 100k-triangle mesh with UVs and normals (OBJ and glb writes). Atlases:
//! 2048² and 6144² RGB, filled with 64-pixel pieces of the exemplar at
//! seeded random offsets (like lapped patches); without an exemplar, with
//! seeded value noise. Each figure is the best of a few runs. "1 thread"
//! runs inside a one-thread rayon pool; the others use all cores.

use std::path::Path;
use std::time::{Duration, Instant};

use fluidtex::io::gltf::write_glb;
use fluidtex::io::image::{
    ExrCompression, ExrOptions, ExrSample, PngCompression, PngEncoder, PngOptions, encode_png,
    write_exr,
};
use fluidtex::io::obj_write::{ObjMaterial, write_obj};
use fluidtex::io::ply_write::{PlyEncoding, write_ply};
use fluidtex::io::{ReadOptions, read_mesh};
use fluidtex::mesh::TriMesh;
use fluidtex::texture::Texture;
use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

fn best<T>(runs: usize, mut f: impl FnMut() -> T) -> (Duration, T) {
    let mut best = Duration::MAX;
    let mut out = None;
    for _ in 0..runs {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed());
        out = Some(r);
    }
    (best, out.expect("runs > 0"))
}

fn ms(d: Duration) -> String {
    format!("{:8.1} ms", d.as_secs_f64() * 1e3)
}

/// A bumpy sphere as an (n+1)² grid in latitude/longitude.
fn grid_mesh(n: u32) -> (TriMesh, Vec<Vec2>) {
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            let (th, ph) = (u * std::f32::consts::TAU, v * std::f32::consts::PI);
            let r = 1.0 + 0.05 * (7.0 * th).sin() * (5.0 * ph).cos();
            positions.push(Vec3::new(
                r * ph.sin() * th.cos(),
                r * ph.cos(),
                r * ph.sin() * th.sin(),
            ));
            uvs.push(Vec2::new(u, v));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            triangles.push([a, a + n + 1, a + 1]);
            triangles.push([a + 1, a + n + 1, a + n + 2]);
        }
    }
    let velocity = positions
        .iter()
        .map(|p| Vec3::new(-p.z, 0.1, p.x))
        .collect();
    (
        TriMesh::new(positions, triangles).with_velocity(velocity),
        uvs,
    )
}

fn atlas(size: u32, exemplar: Option<&image::RgbImage>, seed: u64) -> Texture {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut tex = Texture::filled(size, size, 3, 0.0);
    const PIECE: u32 = 64;
    match exemplar {
        Some(ex) => {
            for ty in (0..size).step_by(PIECE as usize) {
                for tx in (0..size).step_by(PIECE as usize) {
                    let (ox, oy) = (
                        rng.random_range(0..ex.width()),
                        rng.random_range(0..ex.height()),
                    );
                    for y in ty..(ty + PIECE).min(size) {
                        for x in tx..(tx + PIECE).min(size) {
                            let p = ex
                                .get_pixel((ox + x - tx) % ex.width(), (oy + y - ty) % ex.height());
                            let t = tex.texel_mut(x, y);
                            for c in 0..3 {
                                t[c] = f32::from(p[c]) / 255.0;
                            }
                        }
                    }
                }
            }
        }
        None => {
            let lattice: Vec<f32> = (0..65 * 65 * 3).map(|_| rng.random()).collect();
            for y in 0..size {
                for x in 0..size {
                    let (fx, fy) = (x as f32 / size as f32 * 64.0, y as f32 / size as f32 * 64.0);
                    let (ix, iy) = (fx as usize, fy as usize);
                    let (ax, ay) = (fx.fract(), fy.fract());
                    let noise: f32 = rng.random_range(-0.04..0.04);
                    let t = tex.texel_mut(x, y);
                    for (c, tc) in t.iter_mut().enumerate() {
                        let l = |i: usize, j: usize| lattice[(j * 65 + i) * 3 + c];
                        let top = l(ix, iy) * (1.0 - ax) + l(ix + 1, iy) * ax;
                        let bot = l(ix, iy + 1) * (1.0 - ax) + l(ix + 1, iy + 1) * ax;
                        *tc = top * (1.0 - ay) + bot * ay + noise;
                    }
                }
            }
        }
    }
    tex
}

fn main() {
    let dir = tempfile::tempdir().expect("temp dir");
    let threads = rayon::current_num_threads();
    println!("io_bench: {threads} rayon threads");
    mesh_reads(dir.path());
    mesh_writes(dir.path());
    let exemplar = std::env::args()
        .nth(1)
        .map(|p| image::open(Path::new(&p)).expect("exemplar").to_rgb8());
    println!(
        "atlas content: {}",
        if exemplar.is_some() {
            "exemplar pieces"
        } else {
            "value noise"
        }
    );
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    for size in [2048u32, 6144] {
        let tex = atlas(size, exemplar.as_ref(), 1);
        let runs = if size > 4096 { 2 } else { 3 };
        png_writes(&tex, runs, &one);
        exr_writes(dir.path(), &tex, runs);
    }
}

/// Reading (and writing back) 100k vertices, 200k triangles as a binary
/// PLY with velocity.
fn mesh_reads(dir: &Path) {
    let (big, _) = grid_mesh(315);
    let ply = dir.join("fluid.0001.ply");
    write_ply(&ply, &big, PlyEncoding::BinaryLittleEndian).expect("write ply");
    let (t, (m, _)) = best(5, || {
        read_mesh(&ply, &ReadOptions::default()).expect("read")
    });
    println!(
        "read binary PLY   {} vertices, {} triangles: {}",
        m.vertex_count(),
        m.triangle_count(),
        ms(t)
    );
    let (t, _) = best(3, || {
        write_ply(&ply, &big, PlyEncoding::BinaryLittleEndian).expect("write")
    });
    println!(
        "write binary PLY  (same mesh):                    {}",
        ms(t)
    );
}

/// Writing a 100k-triangle mesh with uvs and normals as OBJ and as glb.
fn mesh_writes(dir: &Path) {
    let (mesh, uvs) = grid_mesh(223);
    let normals = mesh.vertex_normals();
    let mat = ObjMaterial {
        name: "atlas".into(),
        map_kd: "frame.0001.png".into(),
    };
    let obj = dir.join("frame.0001.obj");
    let (t, _) = best(3, || {
        write_obj(
            &obj,
            &mesh.positions,
            &uvs,
            Some(&normals),
            &mesh.triangles,
            Some(&mat),
        )
        .expect("obj")
    });
    println!(
        "write OBJ+MTL     {} vertices, {} triangles: {}",
        mesh.vertex_count(),
        mesh.triangle_count(),
        ms(t)
    );
    let png = encode_png(&Texture::filled(256, 256, 3, 0.5), &PngOptions::default()).expect("png");
    let glb = dir.join("frame.0001.glb");
    let (t, _) = best(3, || {
        write_glb(
            &glb,
            &mesh.positions,
            &uvs,
            Some(&normals),
            &mesh.triangles,
            Some(&png),
        )
        .expect("glb")
    });
    println!(
        "write glb         {} vertices, {} triangles: {}",
        mesh.vertex_count(),
        mesh.triangle_count(),
        ms(t)
    );
}

fn mb(n: usize) -> f64 {
    n as f64 / 1e6
}

/// The atlas as PNG: the parallel encoder with fdeflate (the default) and
/// with miniz at levels 1 and 6, on all threads and on `one`, and the image
/// crate's encoder for reference.
fn png_writes(tex: &Texture, runs: usize, one: &rayon::ThreadPool) {
    let size = tex.width;
    let threads = rayon::current_num_threads();
    let png_all = |encoder, compression| {
        let opts = PngOptions {
            encoder,
            compression,
            ..Default::default()
        };
        best(runs, || encode_png(tex, &opts).expect("png"))
    };
    let (fastest, level1) = (PngCompression::Fastest, PngCompression::Deflate(1));
    let runs_of = [
        ("parallel fdeflate", PngEncoder::Parallel, fastest, false),
        ("parallel fdeflate", PngEncoder::Parallel, fastest, true),
        ("parallel level 1 ", PngEncoder::Parallel, level1, false),
        ("parallel level 1 ", PngEncoder::Parallel, level1, true),
        (
            "parallel level 6 ",
            PngEncoder::Parallel,
            PngCompression::Deflate(6),
            false,
        ),
        ("image crate fast ", PngEncoder::Image, fastest, true),
    ];
    for (label, encoder, compression, one_thread) in runs_of {
        let (t, b) = if one_thread {
            one.install(|| png_all(encoder, compression))
        } else {
            png_all(encoder, compression)
        };
        let on = if one_thread { 1 } else { threads };
        println!(
            "{size}² PNG {label}, {on:2} thread(s): {}  {:7.1} MB",
            ms(t),
            mb(b.len())
        );
    }
}

/// The atlas as 16-bit EXR under each compression, on all threads and on one.
fn exr_writes(dir: &Path, tex: &Texture, runs: usize) {
    let size = tex.width;
    let threads = rayon::current_num_threads();
    for (name, compression) in [
        ("ZIP16", ExrCompression::Zip16),
        ("PIZ", ExrCompression::Piz),
        ("none", ExrCompression::None),
    ] {
        for single in [false, true] {
            let path = dir.join("atlas.exr");
            let opts = ExrOptions {
                sample: ExrSample::F16,
                compression,
                channel_names: None,
                single_threaded: single,
            };
            let (t, _) = best(runs, || write_exr(&path, tex, &opts).expect("exr"));
            let len = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
            let th = if single {
                "1 thread".to_string()
            } else {
                format!("{threads} threads")
            };
            println!(
                "{size}² EXR f16 {name:5} {th:>10}:      {}  {:7.1} MB",
                ms(t),
                mb(len as usize)
            );
        }
    }
}
