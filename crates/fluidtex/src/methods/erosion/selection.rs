//! The erosion family's selection of a frame, serialised: the patches as
//! the frame's fill reads them (carried, created, weighted and pruned),
//! with what a patch keeps only for the frame (the weights of the frames
//! before, the distortion and footprint level per triangle, whether it
//! stood still) and the counts of the stages before the fill.
//!
//! Which patch shows at a texel is the lapped rule evaluated on these
//! patches (oldest on top, the erosion test of their weights), and new
//! patches are placed by the update from the same rule, so the fill and
//! the update run again on them in the resampling process, from the
//! frame's geometry alone: a few MB of patches instead of per-texel
//! arrays (12 bytes a texel, 450 MB at 6144²). The advection, the costly
//! and sequential stage, is what the selecting phase keeps to itself.

use serde::{Deserialize, Serialize};

use super::stats::StepCounts;
use super::{Erosion, ErosionState};
use crate::exemplar::set::RegionBox;
use crate::methods::MethodError;

/// The counts of the stages before the fill, and where the fill starts.
#[derive(Serialize, Deserialize)]
struct Header {
    /// Whether `advect` carried its patches (no update); `None`: the
    /// fluid vanished, no fill.
    carried: Option<bool>,
    deleted_before: u64,
    created: u64,
    pruned: u64,
    radius_rule: Option<String>,
    dropped_by_reset: u64,
    /// Several exemplars: where the region image lies (resolved on the
    /// run's first frame with a surface, not on this one).
    region: Option<RegionBox>,
}

/// What a patch keeps for the frame only (skipped in the saved state).
#[derive(Serialize)]
struct PatchFrameRef<'a> {
    weight_before: &'a [f32],
    weight_older: &'a [Vec<f32>],
    distorted: &'a [bool],
    mismatched: &'a [bool],
    lod: &'a [f32],
    still: bool,
    exemplar: u32,
}

/// [`PatchFrameRef`] as read back (the same layout).
#[derive(Deserialize)]
struct PatchFrame {
    weight_before: Vec<f32>,
    weight_older: Vec<Vec<f32>>,
    distorted: Vec<bool>,
    mismatched: Vec<bool>,
    lod: Vec<f32>,
    still: bool,
    exemplar: u32,
}

fn state_error(e: impl std::fmt::Display) -> MethodError {
    MethodError::State(format!("selection: {e}"))
}

impl Erosion {
    /// The selection of the frame whose stages before the fill just ran.
    pub(super) fn snapshot(
        &self,
        carried: Option<bool>,
        counts: &StepCounts,
    ) -> Result<Vec<u8>, MethodError> {
        let header = Header {
            carried,
            deleted_before: counts.deleted_before as u64,
            created: counts.created as u64,
            pruned: counts.pruned as u64,
            radius_rule: counts.radius_rule.clone(),
            dropped_by_reset: self.dropped_by_reset as u64,
            region: self.multi.as_ref().and_then(|m| m.region),
        };
        let frames: Vec<PatchFrameRef<'_>> = (self.state.patches.iter())
            .map(|p| PatchFrameRef {
                weight_before: &p.weight_before,
                weight_older: &p.weight_older,
                distorted: &p.distorted,
                mismatched: &p.mismatched,
                lod: &p.lod,
                still: p.still,
                exemplar: p.exemplar,
            })
            .collect();
        postcard::to_allocvec(&(&header, &self.state, &frames)).map_err(state_error)
    }

    /// Restores a selection written by [`Erosion::snapshot`]: the patches
    /// as the frame's fill reads them. Returns the counts so far and
    /// whether `advect` carried (`None`: no surface).
    pub(super) fn restore(
        &mut self,
        bytes: &[u8],
    ) -> Result<(StepCounts, Option<bool>), MethodError> {
        let (header, mut state, frames): (Header, ErosionState, Vec<PatchFrame>) =
            postcard::from_bytes(bytes).map_err(state_error)?;
        state.check().map_err(state_error)?;
        if frames.len() != state.patches.len() {
            return Err(state_error(format!(
                "{} patch records for {} patches",
                frames.len(),
                state.patches.len()
            )));
        }
        let exemplars = self.multi.as_ref().map_or(1, |m| m.set.len()) as u32;
        for (k, (p, f)) in state.patches.iter_mut().zip(frames).enumerate() {
            let (vertices, triangles) = (p.positions.len(), p.triangles.len());
            let fits = |n: usize, of: usize| n == 0 || n == of;
            if !(fits(f.weight_before.len(), vertices)
                && fits(f.distorted.len(), triangles)
                && fits(f.mismatched.len(), triangles)
                && fits(f.lod.len(), triangles)
                && f.exemplar < exemplars
                && f.weight_before.iter().chain(&f.lod).all(|v| v.is_finite())
                && f.weight_older.iter().flatten().all(|v| v.is_finite()))
            {
                return Err(state_error(format!(
                    "patch {k} (id {}): its frame record does not fit its {vertices} vertices \
                     and {triangles} triangles, or names exemplar {} of {exemplars}",
                    p.id, f.exemplar
                )));
            }
            p.weight_before = f.weight_before;
            p.weight_older = f.weight_older;
            p.distorted = f.distorted;
            p.mismatched = f.mismatched;
            p.lod = f.lod;
            p.still = f.still;
            p.exemplar = f.exemplar;
        }
        self.state = state;
        self.dropped_by_reset = header.dropped_by_reset as usize;
        if let Some(m) = &mut self.multi {
            m.region = header.region;
        }
        let counts = StepCounts {
            deleted_before: header.deleted_before as usize,
            created: header.created as usize,
            pruned: header.pruned as usize,
            radius_rule: header.radius_rule,
            ..StepCounts::default()
        };
        Ok((counts, header.carried))
    }
}
