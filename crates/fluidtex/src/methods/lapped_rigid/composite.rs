//! The atlas of the 2016 method (Gagnon, Dagenais, Paquette 2016,
//! Sec. 3.3, Algorithm 1): every chart texel composites the patches whose
//! receivers hold its fluid triangle, in layer order, with the over
//! operator: α = falloff × mask × fade, older patches on top.
//!
//! Compositing runs front to back (oldest first): a layer's contribution
//! is α times the transparency left above it, and the loop stops once
//! the texel reaches `coverage` (what lies below is renormalised away).
//! Back-to-front over (the paper's loop) gives the same colour up to that
//! cut; front to back lets a new patch below only change what its
//! elders leave visible, which is the point of the layering: a patch
//! appears *under* the others, nothing pops.
//!
//! Algorithm 1 as printed hides what lies beneath by the falloff alone
//! and adds the mask-weighted colour, so a clear part of a mask shows
//! black; [`Composite::Paper`] runs it so, α then being the hidden share.
//!
//! A texel whose accumulated α stays below `coverage` is uncovered and
//! goes to the distribution update, with its partial sums, so new patches
//! below continue its composite. A covered texel's colour is the sum
//! divided by its α (α ≥ coverage, so at most a 1 − coverage rescale).
//!
//! Per texel the method also records the *heaviest* layer (its patch is
//! the texel's source, its uv the texel's uv, as for every blending method
//! of [`crate::methods`]) and how many layers carry at least
//! [`VISIBLE_LAYER_WEIGHT`] of the result (the ghost metric's input).
//!
//! Texels are visited by the shared band walk of [`crate::methods::lapped`]
//! (bands of rows in parallel, each writing only its own rows:
//! bit-identical whatever the thread count); this file is what one texel
//! does with its layers.

use glam::{Vec2, Vec3};

use super::falloff::{FalloffAt, PatchMask, angle_between, falloff};
use super::receivers::Receivers;
use super::trackers::Frame;
use crate::atlas::Atlas;
use crate::exemplar::Exemplar;
use crate::exemplar::feature::FeatureSampler;
use crate::mesh::TriMesh;
use crate::methods::SOURCE_UNCOVERED;
use crate::methods::lapped::bands::for_each_span;
use crate::methods::lapped::{
    AtTexel, BandResult, BandTexel, TexelBuffers, TexelRows, TriangleLists, fill_bands,
};

pub use crate::methods::lapped::VISIBLE_LAYER_WEIGHT;

/// Per fluid triangle, the patches (index in the tracker list = age order)
/// whose receivers hold it.
pub type LayerLists = TriangleLists<u32>;

/// Gathers the receivers of every patch, in patch order, so every
/// triangle's list is sorted by age.
pub fn layer_lists(receivers: &[Receivers], triangle_count: usize) -> LayerLists {
    let pairs: Vec<(u32, u32)> = receivers
        .iter()
        .enumerate()
        .flat_map(|(i, r)| r.triangles.iter().map(move |&f| (f, i as u32)))
        .collect();
    TriangleLists::build(&pairs, triangle_count)
}

/// One patch as the compositing sees it.
#[derive(Clone, Copy, Debug)]
pub struct Layer {
    pub id: u32,
    pub frame: Frame,
    pub fade: f32,
    /// The slot the patch shows this frame: its exemplar's index, or
    /// with an animated exemplar the frame its phase gives
    /// ([`crate::exemplar::ExemplarSet::slot`]); 0 with one exemplar.
    pub exemplar: u32,
    /// The slot whose feature map shapes the patch's mask, fixed for its
    /// life ([`crate::exemplar::ExemplarSet::feature_slot`]); `exemplar`
    /// without animation.
    pub feature: u32,
}

impl MultiComposite<'_> {
    /// The slot tracker `id` of exemplar `entry` shows this frame.
    pub fn slot(&self, entry: u32, id: u32) -> u32 {
        self.set.slot(entry, self.seed, u64::from(id), self.frame)
    }

    /// The slot whose feature map shapes tracker `id`'s mask.
    pub fn feature_slot(&self, entry: u32, id: u32) -> u32 {
        self.set.feature_slot(entry, self.seed, u64::from(id))
    }
}

/// How a layer is composited over what lies beneath it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Composite {
    /// The over operator with α = falloff × mask × fade, for the layer's
    /// colour and for what it hides: Algorithm 1's line read as alpha
    /// blending, where a clear part of the mask shows what lies beneath.
    #[default]
    Over,
    /// Algorithm 1 as printed: what lies beneath is scaled by 1 − falloff
    /// (× fade) only, the layer's colour by falloff × mask. A clear part
    /// of the mask inside the receivers then hides the layers beneath and
    /// shows nothing (black where no colour is added).
    Paper,
}

crate::named!(Composite {
    Over => "over",
    Paper => "paper",
});

/// What compositing reads per exemplar when there are several.
pub struct MultiComposite<'a> {
    /// Every slot of the set (each frame of an animated exemplar is one):
    /// a layer's [`Layer::exemplar`] indexes these.
    pub exemplars: &'a [std::sync::Arc<Exemplar>],
    pub set: &'a crate::exemplar::ExemplarSet,
    /// The run's seed and the fluid frame: which frame of an animated
    /// exemplar a tracker shows.
    pub seed: u64,
    pub frame: i32,
    pub features: Vec<FeatureSampler<'a>>,
    /// [`CompositeContext::base_lod`] of each exemplar (its own size).
    pub base_lods: Vec<Option<f32>>,
}

/// Everything compositing reads.
pub struct CompositeContext<'a> {
    pub mesh: &'a TriMesh,
    /// Unit vertex normals of the fluid mesh.
    pub vertex_normals: &'a [Vec3],
    /// ψ_{α=1} and ψ_{α=0} (radians).
    pub opaque: f32,
    pub transparent: f32,
    /// Where the falloff's angle is taken (per texel or per vertex).
    pub falloff_at: FalloffAt,
    /// How a layer hides what lies beneath it.
    pub composite: Composite,
    pub layers: &'a [Layer],
    pub exemplar: &'a Exemplar,
    pub mask: &'a PatchMask,
    pub feature: FeatureSampler<'a>,
    /// Mip level of an atlas texel seen head-on (log2 of exemplar texels
    /// per atlas texel); `None`: the exemplar is read at level 0.
    pub base_lod: Option<f32>,
    /// α below which a texel is uncovered.
    pub coverage: f32,
    /// Smallest contribution composited; a patch with none is unused.
    pub keep_weight: f32,
    /// Several exemplars: each layer reads its own exemplar, feature map
    /// (for the mask) and base level; `None`: `exemplar`, `feature` and
    /// `base_lod` for every layer.
    pub multi: Option<&'a MultiComposite<'a>>,
}

/// Where a texel lies for the alpha falloff: its smooth normal (the
/// interpolated vertex normal) and its place on its fluid triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shading {
    pub normal: Vec3,
    pub triangle: u32,
    pub bary: [f32; 3],
}

/// The heaviest layer of a texel so far.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Heaviest {
    pub id: u32,
    pub uv: Vec2,
    pub weight: f32,
    pub lod: f32,
}

/// A texel's composite in progress.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TexelSum {
    /// Accumulated α.
    pub alpha: f32,
    pub heaviest: Option<Heaviest>,
    /// Contribution of every layer composited so far.
    pub contributions: Vec<f32>,
}

/// A chart texel the fill left below `coverage`, with its partial composite.
#[derive(Clone, Debug, PartialEq)]
pub struct Uncovered {
    /// Row-major texel index.
    pub texel: u32,
    pub triangle: u32,
    pub bary: [f32; 3],
    pub sum: TexelSum,
}

impl AtTexel for Uncovered {
    fn texel(&self) -> u32 {
        self.texel
    }
}

/// Per-texel results, with a layer count and an exemplar level per texel
/// (`TexelBuffers::new(..).with_layers()`); values stay unnormalised while
/// a texel is open.
pub type CompositeBuffers = TexelBuffers;

/// Where one texel writes.
pub struct TexelOut<'b> {
    pub values: &'b mut [f32],
    pub source: &'b mut u32,
    pub uv: &'b mut Vec2,
    pub layers: &'b mut u8,
    pub lod: &'b mut f32,
}

impl<'a> CompositeContext<'a> {
    /// The same context over other layers (the distribution update
    /// composites each new patch alone).
    pub fn with_layers<'b>(&self, layers: &'b [Layer]) -> CompositeContext<'b>
    where
        'a: 'b,
    {
        CompositeContext { layers, ..*self }
    }

    /// The smooth surface normal at a texel: its fluid triangle's vertex
    /// normals interpolated at `bary`, normalised (the triangle's own
    /// normal `n` where they cancel).
    #[inline]
    pub fn texel_normal(&self, f: u32, bary: [f32; 3], n: Vec3) -> Vec3 {
        let t = self.mesh.triangles[f as usize];
        let s: Vec3 = (0..3)
            .map(|k| {
                self.vertex_normals
                    .get(t[k] as usize)
                    .copied()
                    .unwrap_or(Vec3::ZERO)
                    * bary[k]
            })
            .sum();
        let s = s.normalize_or_zero();
        if s == Vec3::ZERO { n } else { s }
    }

    /// Where the texel at `bary` on fluid triangle `f` (unit normal `n`)
    /// lies for the falloff.
    #[inline]
    pub fn shading(&self, f: u32, bary: [f32; 3], n: Vec3) -> Shading {
        Shading {
            normal: self.texel_normal(f, bary, n),
            triangle: f,
            bary,
        }
    }

    /// The alpha falloff of layer `i` at a texel: from the angle of its
    /// smooth normal, or (`FalloffAt::Vertex`, the paper's) the falloffs
    /// of its triangle's vertex normals interpolated at the texel.
    #[inline]
    pub fn falloff_alpha(&self, i: u32, at: &Shading) -> f32 {
        let frame = &self.layers[i as usize].frame;
        let of = |normal: Vec3| {
            falloff(
                angle_between(normal, frame.normal),
                self.opaque,
                self.transparent,
            )
        };
        match self.falloff_at {
            FalloffAt::Texel => of(at.normal),
            FalloffAt::Vertex => {
                let t = self.mesh.triangles[at.triangle as usize];
                (0..3)
                    .map(|k| {
                        let vn = self.vertex_normals.get(t[k] as usize).copied();
                        // A vertex without a normal takes the texel's.
                        let vn = vn.filter(|v| *v != Vec3::ZERO).unwrap_or(at.normal);
                        at.bary[k] * of(vn)
                    })
                    .sum()
            }
        }
    }

    /// Composites layer `i` under what `sum` holds, at surface point `x`
    /// (lying as `shading` says, on a fluid triangle of unit normal `n`).
    /// Returns the layer's contribution (0 when it shows nothing here).
    ///
    /// By default the falloff angle is taken between the frame's normal and
    /// the *interpolated* vertex normal, not by interpolating per-vertex
    /// alphas (`FalloffAt::Vertex`, the paper's):
    /// the same at vertices, but a patch is then exactly opaque at its own
    /// tracker (θ = 0 there), so a new patch always covers the texel that
    /// created it, also on meshes too coarse for ψ (where a corner's normal
    /// is already past ψ_{α=1}); per-vertex alphas made such patches miss
    /// their seed, vanish and come back every frame.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub fn add_layer(
        &self,
        i: u32,
        shading: &Shading,
        x: Vec3,
        n: Vec3,
        sum: &mut TexelSum,
        values: &mut [f32],
        sample: &mut [f32],
    ) -> f32 {
        let a_fall = self.falloff_alpha(i, shading);
        if a_fall <= 0.0 {
            return 0.0;
        }
        let layer = &self.layers[i as usize];
        let uv = layer.frame.uv(x);
        let (exemplar, feature, base_lod) = match self.multi {
            None => (self.exemplar, &self.feature, self.base_lod),
            Some(m) => {
                let (e, f) = (layer.exemplar as usize, layer.feature as usize);
                match (m.exemplars.get(e), m.features.get(f), m.base_lods.get(e)) {
                    (Some(x), Some(f), Some(&b)) => (&**x, f, b),
                    _ => (self.exemplar, &self.feature, self.base_lod),
                }
            }
        };
        let a = a_fall * self.mask.sample(uv, feature) * layer.fade;
        // The share of the texel this layer takes from what lies beneath:
        // its colour's weight, or as printed its falloff alone.
        let left = 1.0 - sum.alpha;
        let (w, hidden) = match self.composite {
            Composite::Over => {
                let w = a.min(1.0) * left;
                (w, w)
            }
            Composite::Paper => (a.min(1.0) * left, (a_fall * layer.fade).min(1.0) * left),
        };
        // A layer that changes the texel by less than keep_weight is
        // dropped, not added: a patch is used exactly when it changed a
        // texel, so deleting the unused ones changes nothing and a fluid
        // at rest stays identical.
        if hidden <= 0.0 || hidden < self.keep_weight {
            return 0.0;
        }
        sum.alpha += hidden;
        if w <= 0.0 {
            // As printed, a clear part of the mask hides and adds nothing.
            return hidden;
        }
        let lod = match base_lod {
            // The orthographic projection stretches the exemplar by
            // 1/cos θ across the tilt of the fluid triangle.
            Some(base) => {
                let cos = n.dot(layer.frame.normal).abs().max(0.05);
                (base - cos.log2()).max(0.0)
            }
            None => 0.0,
        };
        exemplar.sample_all_lod(uv.x, uv.y, lod, sample);
        for (o, s) in values.iter_mut().zip(sample.iter()) {
            *o += w * s;
        }
        sum.contributions.push(w);
        if sum.heaviest.is_none_or(|h| w > h.weight) {
            sum.heaviest = Some(Heaviest {
                id: layer.id,
                uv,
                weight: w,
                lod,
            });
        }
        hidden
    }

    /// Normalises a texel whose composite is complete and records its
    /// provenance. A texel with nothing composited stays uncovered.
    pub fn finish(&self, sum: &TexelSum, out: TexelOut<'_>) {
        let Some(h) = sum.heaviest.filter(|_| sum.alpha > 0.0) else {
            *out.source = SOURCE_UNCOVERED;
            return;
        };
        let inv = 1.0 / sum.alpha;
        for v in out.values.iter_mut() {
            *v *= inv;
        }
        *out.source = h.id + 1;
        *out.uv = h.uv;
        *out.lod = h.lod;
        let visible = sum
            .contributions
            .iter()
            .filter(|&&w| w >= VISIBLE_LAYER_WEIGHT * sum.alpha)
            .count();
        *out.layers = visible.min(u8::MAX as usize) as u8;
    }
}

/// What the fill produced besides the buffers.
pub struct FillOutcome {
    /// Texels below `coverage`, in texel order, with their partial sums.
    pub uncovered: Vec<Uncovered>,
    /// Indices (in the layer list) of patches that contributed at least
    /// `keep_weight` somewhere, sorted, without repeats.
    pub used: Vec<u32>,
}

/// Composites every chart texel of `atlas` (module doc).
pub fn fill(
    ctx: &CompositeContext<'_>,
    atlas: &Atlas,
    lists: &LayerLists,
    out: &mut CompositeBuffers,
) -> FillOutcome {
    let merged = fill_bands(atlas, out.rows(), |band, mut rows| {
        let mut result = BandResult::default();
        let mut sample = vec![0.0f32; rows.channels];
        let mut sum = TexelSum::default();
        for_each_span(ctx.mesh, atlas, band, |span| {
            let list = lists.of(span.triangle);
            for texel in span.texels() {
                ctx.composite_texel(&texel, list, &mut rows, &mut sum, &mut sample, &mut result);
            }
            // Keeps the list short on large bands; the merge sorts again.
            result.used.sort_unstable();
            result.used.dedup();
        });
        result
    });
    FillOutcome {
        uncovered: merged.uncovered,
        used: merged.used,
    }
}

impl CompositeContext<'_> {
    /// Composites the layers of `list` at one texel, oldest first, until it
    /// reaches coverage; finishes it, or records it as uncovered with its
    /// partial sum. `sum` is scratch space, reset here.
    fn composite_texel(
        &self,
        texel: &BandTexel,
        list: &[u32],
        rows: &mut TexelRows<'_>,
        sum: &mut TexelSum,
        sample: &mut [f32],
        result: &mut BandResult<Uncovered>,
    ) {
        let t = texel.t;
        sum.alpha = 0.0;
        sum.heaviest = None;
        sum.contributions.clear();
        let c = rows.channels;
        let values = &mut rows.values[t * c..(t + 1) * c];
        values.fill(0.0);
        let shading = self.shading(texel.triangle, texel.bary, texel.n);
        for &i in list {
            // A texel is complete once it reaches coverage: a patch the
            // update adds below it later in this frame never reaches it
            // next frame either, so a fluid at rest gives identical frames.
            if sum.alpha >= self.coverage {
                break;
            }
            let wgt = self.add_layer(i, &shading, texel.p, texel.n, sum, values, sample);
            if wgt > 0.0 {
                result.used.push(i);
            }
        }
        if sum.alpha >= self.coverage {
            self.finish(
                sum,
                TexelOut {
                    values,
                    source: &mut rows.source[t],
                    uv: &mut rows.uv[t],
                    layers: &mut rows.layers[t],
                    lod: &mut rows.lod[t],
                },
            );
        } else {
            rows.source[t] = SOURCE_UNCOVERED;
            result.uncovered.push(Uncovered {
                texel: (rows.base + t) as u32,
                triangle: texel.triangle,
                bary: texel.bary,
                sum: sum.clone(),
            });
        }
    }
}
