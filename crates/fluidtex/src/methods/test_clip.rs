//! Test support for the methods' unit tests: a few frames of a scene with
//! everything a [`FrameContext`] borrows, built once, and small grey
//! exemplars.

use glam::Vec3;

use super::{FrameContext, FrameResult, Method, PreviousFrame};
use crate::atlas::{Atlas, AtlasParams};
use crate::mesh::{Topology, TriMesh};
use crate::surface::SurfaceIndex;

/// Consecutive frames with their surface index, atlas, topology and normals.
pub(crate) struct Clip {
    pub(crate) meshes: Vec<TriMesh>,
    pub(crate) indices: Vec<SurfaceIndex>,
    pub(crate) atlases: Vec<Atlas>,
    pub(crate) topologies: Vec<Topology>,
    pub(crate) normals: Vec<Vec<Vec3>>,
}

impl Clip {
    /// The frames `meshes`, each with a square atlas of `atlas` texels.
    pub(crate) fn from_meshes(meshes: Vec<TriMesh>, atlas: u32) -> Clip {
        Clip {
            indices: meshes.iter().map(SurfaceIndex::new).collect(),
            atlases: meshes
                .iter()
                .map(|m| Atlas::build(m, &AtlasParams::square(atlas)).expect("atlas"))
                .collect(),
            topologies: meshes
                .iter()
                .map(|m| Topology::new(m.vertex_count(), &m.triangles))
                .collect(),
            normals: meshes.iter().map(TriMesh::vertex_normals).collect(),
            meshes,
        }
    }

    /// Every frame of the clip through `method`, in order.
    pub(crate) fn run(&self, method: &mut dyn Method) -> Vec<FrameResult> {
        (0..self.meshes.len())
            .map(|k| method.step(&self.ctx(k)).expect("step"))
            .collect()
    }

    /// The clip through the method `build` makes, on a pool of `threads`:
    /// each frame's channels and sources, and the state saved at the end
    /// (what must not depend on the thread count).
    pub(crate) fn run_on_threads(
        &self,
        threads: usize,
        build: impl FnOnce() -> Box<dyn Method> + Send,
    ) -> (Vec<ChannelsAndSources>, Vec<u8>) {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| {
            let mut m = build();
            let frames = (self.run(m.as_mut()).into_iter())
                .map(|r| (r.channels, r.source))
                .collect();
            (frames, m.save_state().expect("state"))
        })
    }

    /// The context of frame `k` (numbered from 0, at 24 fps), with frame
    /// k − 1 as the previous one.
    pub(crate) fn ctx(&self, k: usize) -> FrameContext<'_> {
        FrameContext {
            number: k as i32,
            dt: 1.0 / 24.0,
            mesh: &self.meshes[k],
            index: &self.indices[k],
            topology: &self.topologies[k],
            normals: &self.normals[k],
            previous: (k > 0).then(|| PreviousFrame {
                mesh: &self.meshes[k - 1],
                index: &self.indices[k - 1],
            }),
            atlas: &self.atlases[k],
            arena: &crate::methods::arena::FRESH,
        }
    }
}

/// A frame's channels and per-texel sources.
pub(crate) type ChannelsAndSources = (Vec<crate::texture::Texture>, Option<Vec<u32>>);

/// The first `frames` frames of built-in scene `name` at `resolution`.
pub(crate) fn scene(name: &str, resolution: u32, frames: i32, atlas: u32) -> Clip {
    let mut params = crate::scenes::default_params(name).expect("scene");
    params.resolution = resolution;
    params.last = params.first + frames - 1;
    let mut scene = crate::scenes::by_name(name, Some(params)).expect("scene");
    let meshes = (params.first..=params.last)
        .map(|f| scene.frame(f).expect("frame"))
        .collect();
    Clip::from_meshes(meshes, atlas)
}

/// A flat n×n grid of square cells of side `cell` in z = 0, centred on the
/// origin, each cell split along its diagonal, with velocity `v(x)`.
pub(crate) fn grid(n: usize, cell: f32, v: impl Fn(Vec3) -> Vec3) -> TriMesh {
    let mut positions = Vec::new();
    let half = n as f32 * cell / 2.0;
    for j in 0..=n {
        for i in 0..=n {
            positions.push(Vec3::new(
                i as f32 * cell - half,
                j as f32 * cell - half,
                0.0,
            ));
        }
    }
    let w = (n + 1) as u32;
    let mut triangles = Vec::new();
    for j in 0..n as u32 {
        for i in 0..n as u32 {
            let a = j * w + i;
            triangles.push([a, a + 1, a + w + 1]);
            triangles.push([a, a + w + 1, a + w]);
        }
    }
    let velocity = positions.iter().map(|&p| v(p)).collect();
    TriMesh::new(positions, triangles).with_velocity(velocity)
}

/// A `size`² one-channel exemplar with `value(x, y)` at texel (x, y) and a
/// flat feature map.
pub(crate) fn grey_exemplar(
    size: u32,
    value: impl Fn(u32, u32) -> f32,
) -> crate::exemplar::Exemplar {
    use crate::exemplar::{Exemplar, SampleFormat};
    use crate::texture::Texture;
    let data = (0..size * size)
        .map(|i| value(i % size, i / size))
        .collect();
    let colour = Texture::from_data(size, size, 1, data).expect("sizes match");
    Exemplar::new(colour, SampleFormat::U8, Vec::new(), flat_feature(size)).expect("valid exemplar")
}

/// A flat `size`² feature map: the tests' exemplars need one, not its
/// shape.
fn flat_feature(size: u32) -> crate::exemplar::FeatureMap {
    use crate::exemplar::{FeatureMap, FeatureOrigin};
    FeatureMap::new(
        crate::texture::Texture::filled(size, size, 1, 0.5),
        FeatureOrigin::Builtin,
        "test",
    )
    .expect("valid")
}

/// A `size`² exemplar of `total` channels (a colour of up to four, then
/// one-channel extras) of seeded uniform noise in [0, 1): every channel
/// count a lookup may specialise on, 5 and more included.
pub(crate) fn noise_exemplar(size: u32, total: usize, seed: u64) -> crate::exemplar::Exemplar {
    use crate::exemplar::{Exemplar, ExtraChannel, SampleFormat};
    use crate::texture::Texture;
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut noise = |channels: usize| {
        let data = (0..(size * size) as usize * channels)
            .map(|_| rng.random::<f32>())
            .collect();
        Texture::from_data(size, size, channels, data).expect("sizes match")
    };
    let colour = noise(total.clamp(1, 4));
    let extras = (4..total)
        .map(|i| ExtraChannel {
            name: format!("extra{i}"),
            texture: noise(1),
            format: SampleFormat::F32,
        })
        .collect();
    Exemplar::new(colour, SampleFormat::U8, extras, flat_feature(size)).expect("valid exemplar")
}
