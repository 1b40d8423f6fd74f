//! The optional short transition (`--transition N`, `[erosion]
//! transition`): where a texel's source changes, the texel shows the old and
//! the new source together for N frames, then the new one alone.
//!
//! **Why.** The lapped fill of the 2021 paper shows one patch per texel,
//! so every renewal is a jump from one texture to another in one frame. On
//! a violent liquid a fifth of the surface is renewed per frame; a user can
//! prefer brief cross-fades to those pops. Default 0 keeps the paper.
//!
//! **Which sources.** The fill finds each texel's holder at the weights of
//! each of the N frames before, on this frame's carried patches
//! ([`super::fill::holders`]): which patch
//! would have shown the point then. Each of the N + 1 frames counts once
//! (a box filter over time), so a texel whose source changed k frames ago
//! gives the new source k + 1 shares of N + 1, and at the (N + 1)-th frame
//! after the change it shows the new source alone. The earlier sources are
//! merged into the most recent one that differs from this frame's: two
//! sources per texel at most, and only on texels in transition (the ghost
//! fraction counts exactly those). A texel that had no holder (new surface)
//! shows its new source at once. The old source is read where the texel's
//! point lies in the old patch *now*: the old texture keeps riding the flow
//! while it fades.
//!
//! **How they blend.** A plain cross-fade lowers contrast (two independent
//! textures averaged with weights a and 1 − a keep √(a² + (1 − a)²) of
//! their standard deviation, 0.71 at a half) and shows as a dull, ghosted
//! patch. The variance-preserving blend of Yu et al. 2011 (Eq. 4), as
//! Gagnon et al. 2019 use it, takes the weighted sum of the deviations from
//! the exemplar's mean and divides it by √(Σ wᵢ²): contrast and mean stay
//! the exemplar's, and only the structure is a mix. The weights are chosen
//! so that every frame of the transition turns the texture by the same
//! angle ([`variance_preserving`]).
//!
//! **Patches kept.** A patch that shows nothing this frame but is still an
//! earlier source somewhere is kept alive, and patch triangles are pruned
//! only when eroded at every frame the transition reads.
//!
//! **At rest.** A fluid at rest changes no source, so no texel is in
//! transition and its frames stay identical to the paper's fill.
//!
//! **Resume.** The weights of the frames before (per patch vertex) are
//! saved after the patch state ([`save_history`]), so a resumed run blends
//! exactly as the uninterrupted one.

use std::sync::Arc;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::Erosion;
use super::fill::{FillBuffers, OUTSIDE, Transition, UNCOVERED};
use super::patch::Patch;
use crate::exemplar::Exemplar;
use crate::methods::MethodError;

/// The longest transition, in frames: each frame of it is one more lapped
/// decision per texel in the fill.
pub use super::fill::MAX_TRANSITION_FRAMES as MAX_FRAMES;

/// Blends every texel of `transitions` in `out` (whose values hold the new
/// source as the fill and the footprint pass left them): the earlier
/// source is read at the texel's level (`lods`, level 0 where none) from
/// `exemplar_of(patch id)`, which also gives that exemplar's mean per
/// channel. A texel whose source is now the earlier one (the update gave an
/// uncovered texel back to its old patch), or that is uncovered, is left as
/// it is. Returns the visible layers per texel (0 outside the charts and
/// where uncovered, 2 in transition, 1 elsewhere) and how many texels were
/// blended.
pub fn blend<'e>(
    out: &mut FillBuffers,
    transitions: &[Transition],
    lods: Option<&[f32]>,
    exemplar_of: impl Fn(u32) -> (&'e Exemplar, &'e [f64]) + Sync,
) -> (Vec<u8>, usize) {
    let c = out.channels;
    let mut layers: Vec<u8> = out
        .source
        .iter()
        .map(|&s| u8::from(s != OUTSIDE && s != UNCOVERED))
        .collect();
    if c == 0 || out.values.len() != out.source.len() * c {
        return (layers, 0);
    }
    let source = &out.source;
    let values = &out.values;
    let blended: Vec<(u32, Vec<f32>)> = transitions
        .par_chunks(1024)
        .map(|chunk| {
            let mut old = vec![0.0f32; c];
            let mut texels = Vec::with_capacity(chunk.len());
            let mut mixed = Vec::with_capacity(chunk.len() * c);
            for e in chunk {
                let t = e.texel as usize;
                let Some(&s) = source.get(t) else { continue };
                if s == OUTSIDE || s == UNCOVERED || s == e.patch_id + 1 {
                    continue;
                }
                let (old_exemplar, old_mean) = exemplar_of(e.patch_id);
                let (_, new_mean) = exemplar_of(s - 1);
                let lod = lods.and_then(|l| l.get(t)).copied().unwrap_or(0.0);
                if lod > 0.0 {
                    old_exemplar.sample_all_lod(e.uv.x, e.uv.y, lod, &mut old);
                } else {
                    old_exemplar.sample_all(e.uv.x, e.uv.y, &mut old);
                }
                let new = &values[t * c..(t + 1) * c];
                texels.push(e.texel);
                for ch in 0..c {
                    let (mo, mn) = (mean_at(old_mean, ch), mean_at(new_mean, ch));
                    mixed.push(variance_preserving(new[ch], mn, old[ch], mo, e.share));
                }
            }
            texels
                .into_iter()
                .zip(mixed.chunks_exact(c.max(1)).map(<[f32]>::to_vec))
                .collect::<Vec<_>>()
        })
        .flatten_iter()
        .collect();
    for (t, v) in &blended {
        let t = *t as usize;
        out.values[t * c..(t + 1) * c].copy_from_slice(v);
        layers[t] = 2;
    }
    (layers, blended.len())
}

impl Erosion {
    /// Frames of the transition this run blends over: the parameter's, for
    /// the lapped fills (the blended fill shows every layer anyway).
    pub(super) fn transition_frames(&self) -> u32 {
        if self.rules.blends {
            0
        } else {
            self.params.transition.min(MAX_FRAMES)
        }
    }

    /// Blends the texels in transition ([`blend`]) with
    /// `lods` the footprint pass's levels and `by_id` the exemplar of each
    /// patch id; returns the visible layers per texel and how many texels
    /// were blended, or `None` without a transition.
    pub(super) fn blend_transitions(
        &mut self,
        out: &mut FillBuffers,
        transitions: &[Transition],
        lods: Option<&[f32]>,
        by_id: Option<&[u32]>,
    ) -> Option<(Vec<u8>, usize)> {
        if self.transition_frames() == 0 {
            return None;
        }
        let exemplars: Vec<Arc<Exemplar>> = match &self.multi {
            Some(m) => m.set.exemplars().to_vec(),
            None => vec![Arc::clone(&self.exemplar)],
        };
        let tones = self.exemplar_tones();
        let exemplar_of = |id: u32| {
            let e = by_id
                .and_then(|b| b.get(id as usize))
                .map_or(0, |&e| e as usize)
                .min(exemplars.len() - 1);
            let mean = tones.get(e).map_or(&[][..], |t| t.mean.as_slice());
            (&*exemplars[e], mean)
        };
        Some(blend(out, transitions, lods, exemplar_of))
    }
}

fn mean_at(mean: &[f64], ch: usize) -> f32 {
    mean.get(ch).copied().unwrap_or(0.0) as f32
}

/// Yu et al. 2011, Eq. 4 for two layers: `new` (mean `mean_new`) and `old`
/// (mean `mean_old`), the old one with share `share` of the transition.
/// The means mix linearly by the shares; the deviations from them take the
/// weights cos θ and sin θ with θ = share · π/2, whose squares sum to 1, so
/// Eq. 4's normalisation is built in. Equal steps of the share are then
/// equal turns from one texture to the other: each frame of an N-frame
/// transition changes a texel by about π/(2(N + 1)) of the exemplar's
/// standard deviation, where the shares themselves as weights would take
/// uneven steps (a third of the way through, 27°; the middle step, 37°).
pub fn variance_preserving(new: f32, mean_new: f32, old: f32, mean_old: f32, share: f32) -> f32 {
    let theta = share.clamp(0.0, 1.0) * std::f32::consts::FRAC_PI_2;
    let (w_old, w_new) = theta.sin_cos();
    let mean = (1.0 - share) * mean_new + share * mean_old;
    mean + w_new * (new - mean_new) + w_old * (old - mean_old)
}

/// The weights a transition needs from the frames before, per patch:
/// [`Patch::weight_before`] then [`Patch::weight_older`].
#[derive(Serialize, Deserialize)]
struct History {
    patches: Vec<Vec<Vec<f32>>>,
}

/// The transition's part of the saved state: every patch's weights of the
/// frames before ([`Patch::weight_before`], [`Patch::weight_older`]),
/// which the saved patch state leaves out.
pub fn save_history(patches: &[Patch]) -> Result<Vec<u8>, MethodError> {
    let history = History {
        patches: patches
            .iter()
            .map(|p| {
                std::iter::once(p.weight_before.clone())
                    .chain(p.weight_older.iter().cloned())
                    .collect()
            })
            .collect(),
    };
    postcard::to_allocvec(&history).map_err(|e| MethodError::State(e.to_string()))
}

/// Restores what [`save_history`] wrote onto `patches` and returns the
/// bytes after it.
pub fn load_history<'b>(bytes: &'b [u8], patches: &mut [Patch]) -> Result<&'b [u8], MethodError> {
    let (history, rest) = postcard::take_from_bytes::<History>(bytes).map_err(|e| {
        MethodError::State(format!(
            "transition history: {e} (a state saved without --transition cannot continue with it)"
        ))
    })?;
    if history.patches.len() != patches.len() {
        return Err(MethodError::State(format!(
            "transition history of {} patches for {} patches",
            history.patches.len(),
            patches.len()
        )));
    }
    for (k, (p, mut weights)) in patches.iter_mut().zip(history.patches).enumerate() {
        let n = p.positions.len();
        if let Some(w) = weights
            .iter()
            .find(|w| !(w.is_empty() || w.len() == n) || w.iter().any(|x| !x.is_finite()))
        {
            return Err(MethodError::State(format!(
                "transition history of patch {k} (id {}): {} weights for {n} vertices, or not finite",
                p.id,
                w.len()
            )));
        }
        if weights.is_empty() {
            p.weight_before.clear();
            p.weight_older.clear();
            continue;
        }
        p.weight_before = weights.remove(0);
        p.weight_older = weights;
    }
    Ok(rest)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variance_preserving_keeps_mean_and_contrast_of_independent_layers() {
        // Two independent ±1 layers about mean 0.5: every share keeps the
        // mean, and the blend's variance over the four combinations stays 1.
        for share in [0.1f32, 0.25, 0.5, 0.8] {
            let mut sum = 0.0f64;
            let mut sum_sq = 0.0f64;
            for new in [-1.0f32, 1.0] {
                for old in [-1.0f32, 1.0] {
                    let v = variance_preserving(0.5 + new, 0.5, 0.5 + old, 0.5, share);
                    sum += f64::from(v);
                    sum_sq += f64::from(v - 0.5).powi(2);
                }
            }
            assert!((sum / 4.0 - 0.5).abs() < 1e-6, "mean at share {share}");
            assert!(
                (sum_sq / 4.0 - 1.0).abs() < 1e-5,
                "variance at share {share}"
            );
        }
        // A plain cross-fade at a half would keep half the variance.
        let v = variance_preserving(1.5, 0.5, -0.5, 0.5, 0.5);
        assert!((v - 0.5).abs() < 1e-6, "opposite deviations cancel: {v}");
        let v = variance_preserving(1.5, 0.5, 1.5, 0.5, 0.5);
        assert!(
            (v - (0.5 + 2f32.sqrt())).abs() < 1e-5,
            "equal ones add: {v}"
        );
    }

    #[test]
    fn every_frame_of_a_transition_turns_the_texture_by_the_same_step() {
        // The weights (w_new, w_old) read off unit deviations: each step of
        // the share moves them the same distance, π/(2(N + 1)) to first order.
        for n in [2u32, 4, 8] {
            let weights = |k: u32| {
                let s = k as f32 / (n + 1) as f32;
                let w_new = variance_preserving(1.0, 0.0, 0.0, 0.0, s);
                let w_old = variance_preserving(0.0, 0.0, 1.0, 0.0, s);
                (w_new, w_old)
            };
            let steps: Vec<f32> = (0..=n)
                .map(|k| {
                    let (a, b) = (weights(k), weights(k + 1));
                    ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt()
                })
                .collect();
            let chord = 2.0 * (std::f32::consts::FRAC_PI_4 / (n + 1) as f32).sin();
            for s in &steps {
                assert!((s - chord).abs() < 1e-5, "N = {n}: {steps:?}");
            }
        }
    }

    #[test]
    fn shares_zero_and_one_give_one_layer_back() {
        assert_eq!(variance_preserving(0.9, 0.4, 0.1, 0.6, 0.0), 0.9);
        assert!((variance_preserving(0.9, 0.4, 0.1, 0.6, 1.0) - 0.1).abs() < 1e-6);
    }
}

#[cfg(test)]
mod method_tests {
    use std::sync::Arc;

    use glam::Vec3;

    use super::super::{Erosion, ErosionParams};
    use crate::exemplar::{Exemplar, builtin_pebbles};
    use crate::methods::test_clip::{Clip, scene};
    use crate::methods::{FrameResult, Method};
    use crate::provenance::{SOURCE_OUTSIDE, SOURCE_UNCOVERED};

    fn exemplar() -> Arc<Exemplar> {
        Arc::new(builtin_pebbles(64, 1))
    }

    fn with_transition(n: u32) -> ErosionParams {
        ErosionParams {
            transition: n,
            ..ErosionParams::default()
        }
    }

    fn run(params: ErosionParams, clip: &Clip) -> Vec<FrameResult> {
        let mut m = Erosion::new(params, exemplar(), 4).expect("params");
        (0..clip.meshes.len())
            .map(|k| m.step(&clip.ctx(k)).expect("step"))
            .collect()
    }

    fn layers(r: &FrameResult) -> &[u8] {
        r.layers.as_deref().expect("a transition counts layers")
    }

    #[test]
    fn a_fluid_at_rest_is_the_paper_fill_on_every_frame() {
        let first = scene("rigid-rotation", 12, 1, 96);
        let mesh = first.meshes[0]
            .clone()
            .with_velocity(vec![Vec3::ZERO; first.meshes[0].vertex_count()]);
        let c = Clip::from_meshes(vec![mesh; 5], 96);
        let paper = run(ErosionParams::default(), &c);
        let blended = run(with_transition(4), &c);
        for (k, (p, b)) in paper.iter().zip(&blended).enumerate() {
            assert!(
                p.channels == b.channels,
                "frame {k} differs from the paper's"
            );
            assert_eq!(p.source, b.source, "frame {k}");
            assert!(
                layers(b).iter().all(|&l| l <= 1),
                "frame {k}: nothing in transition"
            );
            assert_eq!(b.stats["transition_share"], 0.0);
        }
    }

    #[test]
    fn only_texels_in_transition_show_two_sources_and_contrast_holds() {
        let c = scene("vortex", 10, 10, 96);
        let results = run(with_transition(3), &c);
        let mut in_transition = 0usize;
        let (mut single, mut pair) = (Vec::new(), Vec::new());
        for (k, r) in results.iter().enumerate() {
            let source = r.source.as_deref().expect("sources");
            let l = layers(r);
            let share = r.stats["transition_share"].as_f64().expect("share");
            let two = l.iter().filter(|&&l| l == 2).count();
            let covered = source
                .iter()
                .filter(|&&s| s != SOURCE_OUTSIDE && s != SOURCE_UNCOVERED)
                .count();
            assert!(
                (share - two as f64 / covered as f64).abs() < 1e-12,
                "frame {k}"
            );
            for (t, (&s, &l)) in source.iter().zip(l).enumerate() {
                let covered = s != SOURCE_OUTSIDE && s != SOURCE_UNCOVERED;
                assert_eq!(l == 0, !covered, "frame {k} texel {t}");
                assert!(l <= 2, "frame {k} texel {t}: at most two sources");
                if k >= 3 {
                    let v = r.channels[0].data[t * 3];
                    match l {
                        1 => single.push(v),
                        2 => pair.push(v),
                        _ => {}
                    }
                }
            }
            if k == 0 {
                assert_eq!(two, 0, "nothing came before the first frame");
            }
            in_transition += two;
        }
        assert!(in_transition > 0, "the vortex renews patches");
        // Variance-preserving: the blended texels keep the contrast of the
        // single ones (a plain cross-fade at shares between 1/4 and 3/4
        // keeps 0.71-0.79 of it).
        let sd = |v: &[f32]| {
            let m = v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64;
            (v.iter().map(|&x| (f64::from(x) - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
        };
        let ratio = sd(&pair) / sd(&single);
        assert!(ratio > 0.9 && ratio < 1.15, "contrast ratio {ratio}");
    }

    #[test]
    fn saved_state_continues_the_transition_exactly() {
        let c = scene("vortex", 10, 7, 96);
        let all = run(with_transition(3), &c);
        let mut first = Erosion::new(with_transition(3), exemplar(), 4).expect("params");
        for k in 0..4 {
            first.step(&c.ctx(k)).expect("step");
        }
        let bytes = first.save_state().expect("save");
        let mut resumed = Erosion::new(with_transition(3), exemplar(), 4).expect("params");
        resumed.load_state(&bytes).expect("load");
        for (k, want) in all.iter().enumerate().skip(4) {
            let r = resumed.step(&c.ctx(k)).expect("step");
            assert!(r.channels == want.channels, "frame {k}");
            assert_eq!(r.source, want.source, "frame {k}");
            assert_eq!(r.layers, want.layers, "frame {k}");
        }
        // A state saved without a transition has no history to continue.
        let mut plain = Erosion::new(ErosionParams::default(), exemplar(), 4).expect("params");
        plain.step(&c.ctx(0)).expect("step");
        let bytes = plain.save_state().expect("save");
        let mut wants = Erosion::new(with_transition(3), exemplar(), 4).expect("params");
        let err = wants.load_state(&bytes).expect_err("no history");
        assert!(err.to_string().contains("transition"), "{err}");
    }

    #[test]
    fn transitions_longer_than_the_bound_are_refused() {
        assert!(with_transition(super::MAX_FRAMES).validate().is_ok());
        let err = with_transition(super::MAX_FRAMES + 1)
            .validate()
            .expect_err("too long");
        assert!(err.to_string().contains("transition"), "{err}");
    }
}
