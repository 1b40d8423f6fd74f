//! What an erosion step counts as it goes, and how it reports it in
//! `stats.F.json` (the typed [`Stat`] keys).

use super::Erosion;
use super::fill::{self, FillBuffers};
use crate::methods::{Stat, StatsExt};

/// What one step did, for the statistics.
#[derive(Default)]
pub(super) struct StepCounts {
    /// Patches lost in advection (left the surface, or a fresh start).
    pub(super) deleted_before: usize,
    pub(super) created: usize,
    pub(super) forced: usize,
    pub(super) candidate_pairs: usize,
    /// Patch triangles dropped: wholly eroded for good, or hidden away from
    /// what their patch showed (`hidden_reach`).
    pub(super) pruned: usize,
    /// Patches no texel used.
    pub(super) unused: usize,
    /// Set on the frame that chose the radius.
    pub(super) radius_rule: Option<String>,
}

/// What the blended fill adds to the lapped one.
#[derive(Default)]
pub(super) struct Blended {
    /// Per texel, layers of visible weight.
    pub(super) layers: Option<Vec<u8>>,
    /// Patches that contributed a visible layer.
    pub(super) used: Option<Vec<u32>>,
    /// The lapped fill with a transition: the texels that still show an
    /// earlier source ([`super::transition`]).
    pub(super) transitions: Vec<fill::Transition>,
}

impl Blended {
    /// Texels the update covered hold one new patch each.
    pub(super) fn count_update(&mut self, source: &[u32]) {
        if let Some(layers) = self.layers.as_mut() {
            for (l, &s) in layers.iter_mut().zip(source) {
                if *l == 0 && s != fill::OUTSIDE && s != fill::UNCOVERED {
                    *l = 1;
                }
            }
        }
    }
}

impl Erosion {
    /// The statistics of `stats.F.json`.
    pub(super) fn record_stats(
        &mut self,
        stats: &mut crate::methods::MethodStats,
        out: &FillBuffers,
        counts: StepCounts,
    ) {
        let texels_in_charts = out.source.iter().filter(|&&s| s != fill::OUTSIDE).count();
        let uncovered_after = out.source.iter().filter(|&&s| s == fill::UNCOVERED).count();
        let dropped = std::mem::take(&mut self.dropped_by_reset);
        stats.set(Stat::PatchesAlive, self.state.patches.len());
        stats.set(Stat::PatchesCreated, counts.created);
        stats.set(
            Stat::PatchesDeleted,
            counts.deleted_before + counts.unused + dropped,
        );
        stats.set(Stat::PatchesDeletedUnused, counts.unused);
        stats.set(Stat::PatchesDeletedAdvection, counts.deleted_before);
        stats.set(Stat::TexelsInCharts, texels_in_charts);
        stats.set(Stat::UncoveredTexels, uncovered_after);
        stats.set(Stat::ForcedTexels, counts.forced);
        stats.set(Stat::CandidatePairs, counts.candidate_pairs);
        stats.set(Stat::TrianglesPruned, counts.pruned);
        stats.set(
            Stat::PatchTriangles,
            self.state
                .patches
                .iter()
                .map(|p| p.triangles.len())
                .sum::<usize>(),
        );
        if let Some(r) = self.state.radius {
            stats.set(Stat::Radius, serde_json::json!(r));
        }
        if let Some(rule) = counts.radius_rule {
            stats.set(Stat::RadiusRule, rule);
        }
        if let Some(s) = self.state.exemplar_size {
            stats.set(Stat::ExemplarSize, serde_json::json!(s));
        }
    }

    /// The frame's statistics beyond the counts: the tone maps applied,
    /// the share of covered texels in transition (`blended_texels` of
    /// them, with a transition) and, with several exemplars, the texels
    /// each shows (`by_id`: the exemplar of each patch id).
    pub(super) fn record_frame_extras(
        &self,
        stats: &mut crate::methods::MethodStats,
        out: &FillBuffers,
        tone: &[crate::methods::tone::ToneMap],
        blended_texels: Option<usize>,
        by_id: Option<&[u32]>,
    ) {
        if !tone.is_empty() {
            let gains: Vec<&[f64]> = tone.iter().map(|m| m.gain.as_slice()).collect();
            let means: Vec<&[f64]> = tone.iter().map(|m| m.mean.as_slice()).collect();
            stats.insert("tone_gain".into(), serde_json::json!(gains));
            stats.insert("tone_mean_before".into(), serde_json::json!(means));
        }
        if let Some(blended_texels) = blended_texels {
            let covered = out
                .source
                .iter()
                .filter(|&&s| s != fill::OUTSIDE && s != fill::UNCOVERED)
                .count();
            let share = blended_texels as f64 / covered.max(1) as f64;
            stats.insert("transition_share".into(), serde_json::json!(share));
        }
        if let (Some(m), Some(by_id)) = (&self.multi, by_id) {
            let texels = crate::methods::lapped::state::texels_per_exemplar(
                &out.source,
                m.set.len(),
                |id| by_id.get(id as usize).copied(),
            );
            stats.insert("exemplar_texels".into(), texels.into());
        }
    }
}
