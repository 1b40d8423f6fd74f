//! Exemplar-size cost (docs/evaluation.md: time(2048²) / time(256²) ≤ 1.15) of the
//! erosion method's frame step, with the mip filtering on and off: the same
//! scene, atlas and exemplar world size, only the exemplar's resolution
//! changes (so the 2048² exemplar is shown 8× more minified). Exemplars
//! are built before timing starts (their pyramid is built once, there).
//!
//! `cargo run --release -p fluidtex --example exemplar_size_cost`

use std::sync::Arc;
use std::time::Instant;

use fluidtex::atlas::AtlasParams;
use fluidtex::driver::clip_geometry;
use fluidtex::exemplar::{
    Exemplar, ExemplarFilter, FeatureMap, FeatureOrigin, SampleFormat, builtin_pebbles,
};
use fluidtex::methods::erosion::{Erosion, ErosionParams};
use fluidtex::methods::{FrameContext, Method};
use fluidtex::texture::Texture;

/// The 256² pebbles tiled `size / 256` times (the same picture at a higher
/// resolution would need the generator at that size; for timing only the
/// size matters).
fn pebbles(size: u32) -> Exemplar {
    let small = builtin_pebbles(256, 1);
    let k = size / 256;
    let tile = |t: &Texture| {
        let mut out = Texture::filled(size, size, t.channels, 0.0);
        for y in 0..size {
            for x in 0..size {
                out.texel_mut(x, y)
                    .copy_from_slice(t.texel(x / k % 256, y / k % 256));
            }
        }
        out
    };
    let feature = FeatureMap::new(
        tile(&small.feature.map),
        FeatureOrigin::Builtin,
        "tiled pebbles",
    )
    .expect("valid");
    Exemplar::new(tile(&small.colour), SampleFormat::U8, Vec::new(), feature).expect("valid")
}

fn main() {
    let name = "rigid-rotation";
    let mut params = fluidtex::scenes::default_params(name).expect("scene");
    params.resolution = 32;
    params.last = params.first + 6;
    let mut scene = fluidtex::scenes::by_name(name, Some(params)).expect("scene");
    let meshes: Vec<_> = (params.first..=params.last)
        .map(|f| scene.frame(f).expect("frame"))
        .collect();
    let frames = clip_geometry(meshes, &AtlasParams::square(1024)).expect("atlas");
    // One exemplar texel per atlas texel at 256².
    let size_world = 256.0 / frames[0].atlas.scale as f32;
    let exemplars = [256u32, 2048].map(|s| {
        let t = Instant::now();
        let e = pebbles(s);
        println!(
            "{s}x{s} exemplar built in {:.0} ms (tiling + pyramid)",
            t.elapsed().as_secs_f64() * 1e3
        );
        e
    });
    for filter in [ExemplarFilter::Trilinear, ExemplarFilter::Unfiltered] {
        let mut times = Vec::new();
        for e in &exemplars {
            let ex = Arc::new(e.clone().with_filter(filter));
            let p = ErosionParams {
                exemplar_size: Some(size_world),
                ..Default::default()
            };
            let mut m = Erosion::new(p, ex, 0).expect("params");
            let mut best = f64::INFINITY;
            for k in 0..frames.len() {
                let previous = k.checked_sub(1).map(|j| &*frames[j]);
                let ctx = FrameContext::new(1.0 / 24.0, &frames[k], previous);
                let t = Instant::now();
                let r = m.step(&ctx).expect("step");
                let secs = t.elapsed().as_secs_f64();
                // The first frame places the initial patches: not typical.
                if k > 0 {
                    best = best.min(secs);
                }
                if k + 1 == frames.len() {
                    let filter_secs: f64 = r
                        .timings
                        .iter()
                        .filter(|(n, _)| *n == "exemplar filter")
                        .map(|(_, s)| s)
                        .sum();
                    println!(
                        "{filter:?} {}x{}: best step {:.1} ms (filter pass {:.1} ms)",
                        e.size().0,
                        e.size().1,
                        best * 1e3,
                        filter_secs * 1e3
                    );
                }
            }
            times.push(best);
        }
        println!(
            "{filter:?}: time(2048²)/time(256²) = {:.3}",
            times[1] / times[0]
        );
    }
}
