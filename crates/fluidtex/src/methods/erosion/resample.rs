//! Every channel of a frame from its texels' selection: the exemplar read
//! at each texel's footprint level, the transitions, the tone, and the
//! frame's statistics. Shared by a one-pass step and the resampling of a
//! serialised selection, so both write the same bytes.

use super::fill::FillBuffers;
use super::stats::StepCounts;
use super::{Erosion, Texels, exemplars};
use crate::exemplar::tone::ExemplarTone;
use crate::methods::tone::{self, Tone, ToneMap};
use crate::methods::{FrameResult, StageClock};

impl Erosion {
    /// Each exemplar's statistics, measured once: the means for mean
    /// matching and transitions, the variance by level too for contrast
    /// matching (which reads every mip pyramid).
    pub(super) fn exemplar_tones(&mut self) -> &[ExemplarTone] {
        let exemplars = match &self.multi {
            Some(m) => m.set.exemplars(),
            None => std::slice::from_ref(&self.exemplar),
        };
        let contrast = self.rules.erodes && self.params.tone == Tone::Match;
        self.tones.get_or_insert_with(|| {
            if !contrast {
                // No pyramid is read: an animated exemplar's frames keep
                // theirs unbuilt until a patch shows them.
                return exemplars
                    .iter()
                    .map(|e| ExemplarTone::means_of(e))
                    .collect();
            }
            // Every frame of an animated exemplar is measured, so every
            // pyramid is built here: in parallel, not one by one.
            if let Some(m) = &self.multi {
                m.set.prepare(0..exemplars.len() as u32);
            }
            exemplars.iter().map(|e| ExemplarTone::of(e)).collect()
        })
    }

    /// Matches the tone of the composite in `out` as the parameters say
    /// (the erosion method only; see [`crate::methods::tone`]), with `lods`
    /// the footprint pass's levels and `by_id` the exemplar of each patch
    /// id (several exemplars). Returns the maps applied, one per exemplar;
    /// none when nothing was matched.
    pub(super) fn match_tone(
        &mut self,
        out: &mut FillBuffers,
        lods: Option<&[f32]>,
        by_id: Option<&[u32]>,
    ) -> Vec<ToneMap> {
        if !self.rules.erodes || self.params.tone == Tone::Off {
            return Vec::new();
        }
        let mode = self.params.tone;
        let tones = self.exemplar_tones();
        let exemplar_of = |s: u32| {
            by_id
                .zip((s as usize).checked_sub(1))
                .and_then(|(b, i)| b.get(i))
                .map_or(0, |&e| e as usize)
        };
        tone::match_tone(
            mode,
            &mut out.values,
            out.channels,
            &out.source,
            lods,
            exemplar_of,
            tones,
        )
    }

    /// The footprint pass ([`crate::methods::footprint`]) over `out` for the lapped
    /// fills, each texel read from its patch's exemplar (`by_id`); the
    /// levels per texel where `levels` keeps them.
    pub(super) fn filter_footprint(
        &self,
        out: &mut FillBuffers,
        levels: crate::methods::footprint::Levels,
        by_id: Option<&[u32]>,
    ) -> Option<Vec<f32>> {
        (!self.rules.blends)
            .then(|| match (&self.multi, by_id) {
                (Some(m), Some(by_id)) => {
                    let all = m.set.exemplars();
                    crate::methods::footprint::apply_footprint_filtering_by(
                        out,
                        self.exemplar.filter,
                        levels,
                        |s| {
                            let e = by_id.get(s as usize - 1).copied().unwrap_or(0);
                            all.get(e as usize).map_or(&*self.exemplar, |a| a)
                        },
                    )
                }
                _ => crate::methods::footprint::apply_footprint_filtering_by(
                    out,
                    self.exemplar.filter,
                    levels,
                    |_| &*self.exemplar,
                ),
            })
            .flatten()
    }

    /// Every channel from the texels' selection: the footprint pass, the
    /// transitions, the tone; and the frame's statistics, with the levels
    /// per texel where `wants` asks for them.
    pub(super) fn resample_texels(
        &mut self,
        texels: Texels,
        counts: StepCounts,
        mut clock: StageClock,
        wants: crate::methods::Wants,
    ) -> FrameResult {
        let Texels {
            mut out,
            mut blended,
        } = texels;
        // The resampling reads each patch's slot (the frame of an animated
        // exemplar it shows), the statistics its exemplar.
        let by_id = self
            .multi
            .as_ref()
            .map(|_| exemplars::by_id(&self.state.patches, self.state.next_id));
        let slots = self.multi.as_ref().map(|m| {
            if m.set.is_animated() {
                let slots = m.slots_by_id(&self.state.patches, self.state.next_id);
                m.set.prepare(
                    self.state
                        .patches
                        .iter()
                        .filter_map(|p| slots.get(p.id as usize).copied()),
                );
                slots
            } else {
                by_id.clone().unwrap_or_default()
            }
        });
        // Contrast tone matching reads each texel's level.
        // So does a transition, which reads the earlier source at it.
        let levels = if wants.levels
            || (self.rules.erodes && self.params.tone == Tone::Match)
            || !blended.transitions.is_empty()
        {
            crate::methods::footprint::Levels::Keep
        } else {
            crate::methods::footprint::Levels::Drop
        };
        let exemplar_lod = self.filter_footprint(&mut out, levels, slots.as_deref());
        clock.lap("exemplar filter");
        let in_transition = self.blend_transitions(
            &mut out,
            &blended.transitions,
            exemplar_lod.as_deref(),
            slots.as_deref(),
        );
        let in_transition = in_transition.map(|(layers, blended_texels)| {
            blended.layers = Some(layers);
            blended_texels
        });
        clock.lap("transition");
        let tone = self.match_tone(&mut out, exemplar_lod.as_deref(), slots.as_deref());
        clock.lap("tone");
        let mut result = FrameResult {
            channels: crate::exemplar::channels::split_interleaved(
                out.width,
                out.height,
                std::mem::take(&mut out.values),
                &self.exemplar,
            ),
            exemplar_lod,
            ..Default::default()
        };
        self.record_stats(&mut result.stats, &out, counts);
        self.record_frame_extras(
            &mut result.stats,
            &out,
            &tone,
            in_transition,
            by_id.as_deref(),
        );
        result.source = Some(out.source);
        result.uv = Some(out.uv);
        result.renewal = (!out.renewal.is_empty()).then_some(out.renewal);
        result.layers = blended.layers;
        result.timings = clock.stages;
        result
    }

    /// A selected frame's buffers, handed back to `arena` for the next
    /// (nothing resamples them in the selecting phase).
    pub(super) fn keep_spare(&mut self, arena: &crate::methods::FrameArena, texels: Texels) {
        let Texels { out, .. } = texels;
        arena.hand_back(crate::methods::SpentBuffers {
            uv: Some(out.uv),
            values: Some(out.values),
            exemplar_lod: None,
        });
    }
}
