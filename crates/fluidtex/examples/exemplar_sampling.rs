//! Cost of `Exemplar::sample_all` (the lapped fill's per-texel lookup) and
//! `FeatureMap::sample` for small and large exemplars, power-of-two or not,
//! with a patch-like access pattern (a rotated, scaled sweep over the
//! exemplar), of the same sweep through the mip pyramid
//! (`Exemplar::sample_all_lod` at level 3, 8 exemplar texels per step), of
//! building the pyramid (part of `Exemplar::new`), and of generating the
//! built-in pebbles.
//!
//! `cargo run --release -p fluidtex --example exemplar_sampling`

use std::time::Instant;

use fluidtex::exemplar::{
    Exemplar, ExtraChannel, FeatureMap, FeatureOrigin, SampleFormat, builtin_pebbles,
};
use fluidtex::texture::{Texture, Wrap};

fn exemplar(size: u32) -> Exemplar {
    let colour = Texture::filled(size, size, 3, 0.5);
    let extra = ExtraChannel {
        name: "height".into(),
        texture: Texture::filled(size, size, 1, 0.25),
        format: SampleFormat::F32,
    };
    let feature = FeatureMap::new(
        Texture::filled(size, size, 1, 0.5),
        FeatureOrigin::Builtin,
        "bench",
    )
    .expect("valid");
    Exemplar::new(colour, SampleFormat::U8, vec![extra], feature).expect("valid")
}

fn main() {
    let n = 4_000_000usize;
    for size in [256u32, 250, 2048, 2000] {
        let t = Instant::now();
        let e = exemplar(size);
        let build = t.elapsed().as_secs_f64() * 1e3;
        let mut out = vec![0.0f32; e.total_channels()];
        let (c, s) = (0.8f32.cos(), 0.8f32.sin());
        let side = (n as f32).sqrt() as usize;
        let mut acc = 0.0f32;
        let t = Instant::now();
        for i in 0..n {
            let (a, b) = (
                (i % side) as f32 / side as f32,
                (i / side) as f32 / side as f32,
            );
            let (u, v) = (0.2 + 1.3 * (c * a - s * b), 0.1 + 1.3 * (s * a + c * b));
            e.sample_all(u, v, &mut out);
            acc += out[0] + out[3];
        }
        let all = t.elapsed().as_secs_f64() * 1e9 / n as f64;
        let t = Instant::now();
        for i in 0..n {
            let (a, b) = (
                (i % side) as f32 / side as f32,
                (i / side) as f32 / side as f32,
            );
            acc += e
                .feature
                .sample(0.2 + 1.3 * (c * a - s * b), 0.1 + 1.3 * (s * a + c * b));
        }
        let feat = t.elapsed().as_secs_f64() * 1e9 / n as f64;
        // Reference: texture.rs's general sampler on the two textures.
        let t = Instant::now();
        let mut buf = [0.0f32; 4];
        for i in 0..n {
            let (a, b) = (
                (i % side) as f32 / side as f32,
                (i / side) as f32 / side as f32,
            );
            let (u, v) = (0.2 + 1.3 * (c * a - s * b), 0.1 + 1.3 * (s * a + c * b));
            e.colour.sample_bilinear(u, v, Wrap::Repeat, &mut buf[..3]);
            e.channels[0]
                .texture
                .sample_bilinear(u, v, Wrap::Repeat, &mut buf[3..]);
            acc += buf[0] + buf[3];
        }
        let reference = t.elapsed().as_secs_f64() * 1e9 / n as f64;
        // Minified: 8 exemplar texels per step, read at level 3.
        let step = 8.0 / size as f32;
        let t = Instant::now();
        for i in 0..n {
            let (a, b) = ((i % side) as f32 * step, (i / side) as f32 * step);
            let (u, v) = (0.2 + c * a - s * b, 0.1 + s * a + c * b);
            e.sample_all_lod(u, v, 3.0, &mut out);
            acc += out[0] + out[3];
        }
        let lod = t.elapsed().as_secs_f64() * 1e9 / n as f64;
        println!(
            "{size}x{size}, 3+1 channels: Exemplar::new {build:.1} ms (with pyramid), \
             sample_all {all:.1} ns, sample_all_lod(3) {lod:.1} ns, Texture::sample_bilinear x2 {reference:.1} ns, \
             feature sample {feat:.1} ns (checksum {acc:.0})"
        );
    }
    for size in [256u32, 2048] {
        let t4 = Texture::filled(size, size, 4, 0.5);
        let t = Instant::now();
        let levels = fluidtex::exemplar::mip_levels(&t4);
        println!(
            "mip pyramid of a {size}x{size} 4-channel texture: {:.1} ms ({} levels)",
            t.elapsed().as_secs_f64() * 1e3,
            levels.len()
        );
    }
    for _ in 0..3 {
        let t = Instant::now();
        let p = builtin_pebbles(512, 1);
        println!(
            "builtin_pebbles(512): {:.1} ms ({} threads, {} texels)",
            t.elapsed().as_secs_f64() * 1e3,
            rayon::current_num_threads(),
            p.colour.texel_count()
        );
    }
}
