//! The `dual-rest` baseline (docs/design.md, *Baselines*): the production
//! habit of two rest parameterizations, each advected with the flow and
//! reset to a fresh one every `period` frames, half a period apart, and
//! cross-faded so that each is invisible at the moment it resets. Stretch
//! stays bounded by one period of advection, at the price of ghosts (two
//! textures visible at once, contrast down to ≈ 0.71 at the 50% point) and a
//! pulse per period.
//!
//! Each parameterization is an [`advect`] instance of the patch
//! machinery (a lapped texture placed on the frame where it resets). A
//! frame's selection is the two layers' own selections and the phase
//! origin: resampled, each layer gives its frame and the two are
//! cross-faded, from the frame's geometry alone.
//!
//! With φ = (frames since the first) mod period / period, layer A resets at
//! φ = 0 and layer B at φ = ½; their weights are the triangle waves
//! w_A = 1 − |2φ − 1| and w_B = 1 − w_A, so the layer that resets always
//! has weight 0 at that frame.

use std::sync::Arc;

use glam::Vec2;
use serde::{Deserialize, Serialize};

use super::advect;
use super::erosion::{Erosion, ErosionParams};
use super::lapped::VISIBLE_LAYER_WEIGHT;
use super::{
    ChannelSpec, FrameContext, FrameResult, Method, MethodError, MethodStats, SOURCE_OUTSIDE,
    SOURCE_UNCOVERED, Selection, Stat, StatsExt,
};
use crate::exemplar::Exemplar;
use crate::texture::Texture;

crate::methods::params::params! {
    /// Parameters of the `dual-rest` baseline.
    pub struct DualRestParams {
        /// Frames between two resets of the same layer \[24]; the layers reset
        /// half a period apart. At least 2.
        pub period: u32 = 24
            => "period" : "dual-rest: frames between two resets of a layer [24]",
    }
}

impl DualRestParams {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), MethodError> {
        if self.period < 2 {
            return Err(MethodError::InvalidParameter {
                name: "dual_rest.period",
                value: self.period.to_string(),
                allowed: "at least 2 frames",
            });
        }
        Ok(())
    }
}

/// The two cross-faded advected layers.
pub struct DualRest {
    params: DualRestParams,
    layers: [Erosion; 2],
    /// The first frame number seen (the phase origin).
    first: Option<i32>,
}

/// The saved state, and a frame's selection: the phase origin and each
/// layer's bytes (its state, or its own selection).
#[derive(Serialize, Deserialize)]
struct SavedDualRest {
    first: Option<i32>,
    a: Vec<u8>,
    b: Vec<u8>,
}

/// A different seed stream for layer B, so that the two layers placed on
/// the same first frame are different textures.
const LAYER_B_SEED: u64 = 0x5DEE_CE66_D1CE_4E5B;

impl DualRest {
    pub fn new(
        params: DualRestParams,
        erosion: ErosionParams,
        exemplar: Arc<Exemplar>,
        seed: u64,
    ) -> Result<DualRest, MethodError> {
        let set = Arc::new(crate::exemplar::ExemplarSet::single(exemplar));
        DualRest::with_exemplars(params, erosion, set, seed)
    }

    /// The baseline over the exemplars of `set` (one entry, still or
    /// animated: each layer's patches show their own frames).
    pub fn with_exemplars(
        params: DualRestParams,
        erosion: ErosionParams,
        set: Arc<crate::exemplar::ExemplarSet>,
        seed: u64,
    ) -> Result<DualRest, MethodError> {
        params.validate()?;
        let a = Erosion::with_exemplars(advect::RULES, erosion.clone(), Arc::clone(&set), seed)?;
        let b = Erosion::with_exemplars(advect::RULES, erosion, set, seed ^ LAYER_B_SEED)?;
        Ok(DualRest {
            params,
            layers: [a, b],
            first: None,
        })
    }

    /// Fixes the phase origin on the first frame and resets the layer
    /// whose turn frame `number` is; returns layer A's weight.
    fn start_frame(&mut self, number: i32) -> f32 {
        self.first.get_or_insert(number);
        let (k, wa) = self.phase(number);
        if k == 0 {
            self.layers[0].reset();
        }
        if k == self.params.period / 2 {
            self.layers[1].reset();
        }
        wa
    }

    /// Frames since the first frame, modulo the period, and layer A's weight.
    fn phase(&self, number: i32) -> (u32, f32) {
        let first = self.first.unwrap_or(number);
        let p = self.params.period as i64;
        let k = (number as i64 - first as i64).rem_euclid(p) as u32;
        let phi = k as f32 / self.params.period as f32;
        (k, 1.0 - (2.0 * phi - 1.0).abs())
    }
}

impl Method for DualRest {
    fn name(&self) -> &'static str {
        "dual-rest"
    }

    fn memory_model(
        &self,
        atlas: &crate::atlas::AtlasParams,
        largest: Option<&crate::mesh::TriMesh>,
    ) -> super::MemoryModel {
        // Two advected layers (measured: 4.5 kB per triangle with a run
        // starting at a splash's largest frame, against one layer's 3.7)
        // and, per texel, the second layer's result besides the first.
        let layer = self.layers[0].memory_model(atlas, largest);
        super::MemoryModel {
            fixed: layer.fixed,
            per_triangle: layer.per_triangle + 800,
            per_texel: 2 * layer.per_texel + 4 * 4 + 4,
            per_thread: 0,
        }
    }

    fn channel_specs(&self) -> Vec<ChannelSpec> {
        self.layers[0].channel_specs()
    }

    fn step(&mut self, ctx: &FrameContext<'_>) -> Result<FrameResult, MethodError> {
        let wa = self.start_frame(ctx.number);
        let ra = self.layers[0].step(ctx)?;
        let rb = self.layers[1].step(ctx)?;
        Ok(cross_fade(ra, rb, wa))
    }

    /// Each layer selects on its own (erosion's patches).
    fn select(&mut self, ctx: &FrameContext<'_>) -> Result<Selection, MethodError> {
        self.start_frame(ctx.number);
        let [a, b] = [0, 1].map(|k| self.layers[k].select(ctx));
        let selected = SavedDualRest {
            first: self.first,
            a: a?.into_own(self.name())?,
            b: b?.into_own(self.name())?,
        };
        Selection::encode(self.name(), &selected)
    }

    fn resample(
        &mut self,
        ctx: &FrameContext<'_>,
        selection: &Selection,
    ) -> Result<FrameResult, MethodError> {
        let selected: SavedDualRest = selection.decode(self.name())?;
        self.first = selected.first;
        let (_, wa) = self.phase(ctx.number);
        let ra = self.layers[0].resample(ctx, &Selection::Own(selected.a))?;
        let rb = self.layers[1].resample(ctx, &Selection::Own(selected.b))?;
        Ok(cross_fade(ra, rb, wa))
    }

    fn save_state(&self) -> Result<Vec<u8>, MethodError> {
        let saved = SavedDualRest {
            first: self.first,
            a: self.layers[0].save_state()?,
            b: self.layers[1].save_state()?,
        };
        postcard::to_allocvec(&saved).map_err(|e| MethodError::State(e.to_string()))
    }

    fn load_state(&mut self, bytes: &[u8]) -> Result<(), MethodError> {
        let saved: SavedDualRest =
            postcard::from_bytes(bytes).map_err(|e| MethodError::State(e.to_string()))?;
        self.first = saved.first;
        self.layers[0].load_state(&saved.a)?;
        self.layers[1].load_state(&saved.b)?;
        Ok(())
    }
}

/// Blends layer results `a` (weight `wa`) and `b` (weight 1 − `wa`) texel
/// by texel; where only one layer covers a texel it is shown alone. Patch
/// ids are interleaved (A's k → 2k, B's k → 2k + 1) so the two layers'
/// patches stay distinct in `source`.
fn cross_fade(a: FrameResult, b: FrameResult, wa: f32) -> FrameResult {
    let empty = Vec::new();
    let sa = a.source.as_ref().unwrap_or(&empty);
    let sb = b.source.as_ref().unwrap_or(&empty);
    let mix = TexelMix::new(sa, sb, wa);
    let channels: Vec<Texture> = a
        .channels
        .iter()
        .zip(&b.channels)
        .map(|(ta, tb)| mix.blend(ta, tb))
        .collect();
    let uv = match (&a.uv, &b.uv) {
        (Some(ua), Some(ub)) => Some(mix.dominant(ua, ub, Vec2::NAN)),
        _ => None,
    };
    // The level of the layer whose uv is reported: the one that dominates.
    let exemplar_lod = match (&a.exemplar_lod, &b.exemplar_lod) {
        (Some(la), Some(lb)) => Some(mix.dominant(la, lb, f32::NAN)),
        _ => None,
    };
    let stats = merged_stats(&a, &b, &mix.source, wa);
    let mut timings = a.timings;
    for (name, secs) in b.timings {
        match timings.iter_mut().find(|(n, _)| *n == name) {
            Some(slot) => slot.1 += secs,
            None => timings.push((name, secs)),
        }
    }
    FrameResult {
        channels,
        source: Some(mix.source),
        uv,
        layers: Some(mix.layers),
        exemplar_lod,
        // Two layers cross-faded: no single previous holder per texel.
        renewal: None,
        stats,
        timings,
    }
}

/// Per texel, the weight of each layer and what the mix shows.
struct TexelMix {
    /// (weight of A, weight of B).
    shares: Vec<(f32, f32)>,
    source: Vec<u32>,
    layers: Vec<u8>,
}

impl TexelMix {
    /// Both layers where both cover a texel (`wa` and 1 − `wa`), the one
    /// that covers it otherwise; the source is the heavier layer's patch.
    fn new(sa: &[u32], sb: &[u32], wa: f32) -> TexelMix {
        let wb = 1.0 - wa;
        let n = sa.len();
        let covered = |s: u32| s != SOURCE_OUTSIDE && s != SOURCE_UNCOVERED;
        let relabel = |s: u32, layer: u32| {
            if covered(s) {
                2 * (s - 1) + layer + 1
            } else {
                s
            }
        };
        let mut mix = TexelMix {
            shares: Vec::with_capacity(n),
            source: Vec::with_capacity(n),
            layers: Vec::with_capacity(n),
        };
        for t in 0..n {
            let (ca, cb) = (covered(sa[t]), sb.get(t).is_some_and(|&s| covered(s)));
            let (xa, xb) = match (ca, cb) {
                (true, true) => (wa, wb),
                (true, false) => (1.0, 0.0),
                (false, true) => (0.0, 1.0),
                (false, false) => (0.0, 0.0),
            };
            mix.shares.push((xa, xb));
            let visible =
                u8::from(xa >= VISIBLE_LAYER_WEIGHT) + u8::from(xb >= VISIBLE_LAYER_WEIGHT);
            mix.layers.push(visible);
            mix.source.push(if !ca && !cb {
                sa[t]
            } else if xa >= xb {
                relabel(sa[t], 0)
            } else {
                relabel(sb[t], 1)
            });
        }
        mix
    }

    /// One channel texture of A and B mixed by the shares (A's texel
    /// where A alone shows or nothing does).
    fn blend(&self, ta: &Texture, tb: &Texture) -> Texture {
        let ch = ta.channels;
        let mut out = ta.clone();
        for (t, &(xa, xb)) in self.shares.iter().enumerate() {
            if xa == 1.0 || (xa == 0.0 && xb == 0.0) {
                continue;
            }
            for c in 0..ch {
                let i = t * ch + c;
                out.data[i] = xa * ta.data[i] + xb * tb.data[i];
            }
        }
        out
    }

    /// Per texel, the value of the dominant layer (A on ties), `missing`
    /// where its buffer is short.
    fn dominant<T: Copy>(&self, a: &[T], b: &[T], missing: T) -> Vec<T> {
        self.shares
            .iter()
            .enumerate()
            .map(|(t, &(xa, xb))| {
                let l = if xb > xa { b } else { a };
                l.get(t).copied().unwrap_or(missing)
            })
            .collect()
    }
}

/// Both layers' statistics (prefixed `layer_a_`, `layer_b_`), the patch
/// counts summed, and the mix's own coverage.
fn merged_stats(a: &FrameResult, b: &FrameResult, source: &[u32], wa: f32) -> MethodStats {
    let mut stats = std::collections::BTreeMap::new();
    for (prefix, r) in [("a", a), ("b", b)] {
        for (k, v) in &r.stats {
            stats.insert(format!("layer_{prefix}_{k}"), v.clone());
        }
    }
    let sum = |key| {
        let n = |s: &MethodStats| s.value(key).and_then(|v| v.as_u64()).unwrap_or(0);
        n(&a.stats) + n(&b.stats)
    };
    for key in [
        Stat::PatchesAlive,
        Stat::PatchesCreated,
        Stat::PatchesDeleted,
        Stat::ForcedTexels,
    ] {
        stats.set(key, sum(key));
    }
    let in_charts = source.iter().filter(|&&s| s != SOURCE_OUTSIDE).count();
    let uncovered = source.iter().filter(|&&s| s == SOURCE_UNCOVERED).count();
    stats.set(Stat::TexelsInCharts, in_charts);
    stats.set(Stat::UncoveredTexels, uncovered);
    stats.set(Stat::WeightA, wa);
    stats
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::{Atlas, AtlasParams};
    use crate::exemplar::builtin_pebbles;
    use crate::methods::PreviousFrame;
    use crate::surface::SurfaceIndex;

    fn texture(values: &[f32]) -> Texture {
        Texture {
            width: values.len() as u32,
            height: 1,
            channels: 1,
            data: values.to_vec(),
        }
    }

    fn result(values: &[f32], source: &[u32]) -> FrameResult {
        FrameResult {
            channels: vec![texture(values)],
            source: Some(source.to_vec()),
            uv: Some(vec![glam::Vec2::ZERO; source.len()]),
            ..Default::default()
        }
    }

    #[test]
    fn weights_are_triangle_waves_zero_at_each_reset() {
        let ex = Arc::new(builtin_pebbles(32, 1));
        let mut m = DualRest::new(
            DualRestParams { period: 8 },
            ErosionParams::default(),
            ex,
            0,
        )
        .expect("params");
        m.first = Some(10);
        let want = [0.0, 0.25, 0.5, 0.75, 1.0, 0.75, 0.5, 0.25, 0.0];
        for (k, &w) in want.iter().enumerate() {
            assert_eq!(m.phase(10 + k as i32), ((k % 8) as u32, w), "frame {k}");
        }
        // Layer B resets at k = 4, where A has all the weight.
        assert_eq!(m.phase(14).1, 1.0);
        let bad = DualRest::new(
            DualRestParams { period: 1 },
            ErosionParams::default(),
            Arc::new(builtin_pebbles(32, 1)),
            0,
        );
        assert!(bad.is_err());
    }

    #[test]
    fn cross_fade_mixes_covered_texels_and_keeps_lone_ones() {
        let out = SOURCE_OUTSIDE;
        let a = result(&[1.0, 2.0, 3.0, 0.0], &[1, 2, 0, out]);
        let b = result(&[5.0, 6.0, 7.0, 0.0], &[3, 0, 4, out]);
        let r = cross_fade(a, b, 0.25);
        // Texel 0 both (0.25·1 + 0.75·5), 1 only A, 2 only B, 3 outside.
        assert_eq!(r.channels[0].data, vec![4.0, 2.0, 7.0, 0.0]);
        assert_eq!(r.layers, Some(vec![2, 1, 1, 0]));
        // B is heavier at texel 0: its patch 2 becomes 2·2 + 1 = 5, + 1.
        assert_eq!(r.source, Some(vec![6, 3, 8, out]));
        assert_eq!(r.stats["uncovered_texels"], 0);
        assert_eq!(r.stats["texels_in_charts"], 3);
        // A weight under 0.05 is not a visible layer.
        let a = result(&[1.0], &[1]);
        let b = result(&[5.0], &[1]);
        assert_eq!(cross_fade(a, b, 0.01).layers, Some(vec![1]));
    }

    #[test]
    fn layers_reset_half_a_period_apart() {
        let mut params = crate::scenes::default_params("differential-rotation").expect("scene");
        params.resolution = 10;
        params.last = params.first + 6;
        let mut scene =
            crate::scenes::by_name("differential-rotation", Some(params)).expect("scene");
        let meshes: Vec<_> = (params.first..=params.last)
            .map(|f| scene.frame(f).expect("frame"))
            .collect();
        let indices: Vec<_> = meshes.iter().map(SurfaceIndex::new).collect();
        let atlases: Vec<_> = meshes
            .iter()
            .map(|m| Atlas::build(m, &AtlasParams::square(64)).expect("atlas"))
            .collect();
        let mut m = DualRest::new(
            DualRestParams { period: 4 },
            ErosionParams::default(),
            Arc::new(builtin_pebbles(32, 1)),
            3,
        )
        .expect("params");
        let mut created = Vec::new();
        for k in 0..meshes.len() {
            let ctx = FrameContext {
                number: k as i32,
                dt: 1.0 / 24.0,
                mesh: &meshes[k],
                topology: &crate::mesh::Topology::new(
                    meshes[k].vertex_count(),
                    &meshes[k].triangles,
                ),
                normals: &meshes[k].vertex_normals(),
                index: &indices[k],
                previous: (k > 0).then(|| PreviousFrame {
                    mesh: &meshes[k - 1],
                    index: &indices[k - 1],
                }),
                atlas: &atlases[k],
                arena: &crate::methods::arena::FRESH,
            };
            let r = m.step(&ctx).expect("step");
            let n = |key: &str| r.stats[key].as_u64().unwrap_or(0) > 0;
            created.push((n("layer_a_patches_created"), n("layer_b_patches_created")));
            assert_eq!(r.stats["uncovered_texels"], 0, "frame {k}");
        }
        // A: frames 0 and 4; B: frame 0 (start) and frames 2 and 6.
        let want = [
            (true, true),
            (false, false),
            (false, true),
            (false, false),
            (true, false),
            (false, false),
            (false, true),
        ];
        assert_eq!(created, want);
    }
}
