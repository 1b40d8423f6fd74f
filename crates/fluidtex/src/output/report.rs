//! What a run reports: each frame's numbers (`stats.F.json`) and the
//! progress events front ends show.

use std::collections::BTreeMap;

use serde::Serialize;

use super::memory::MemoryEstimate;

/// Per-frame numbers, also written as `stats.F.json`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct FrameStats {
    pub frame: i32,
    pub method: String,
    pub vertices: usize,
    pub triangles: usize,
    pub dropped_degenerate: usize,
    pub charts: usize,
    pub atlas_width: u32,
    pub atlas_height: u32,
    /// Share of atlas texels inside charts: how tightly the packer filled
    /// the atlas (the rest is gutter and space between charts).
    pub atlas_fill: f64,
    /// Share of surface points carried by the velocity from the previous
    /// frame, with a patch at both ends, whose patch changed
    /// ([`crate::coherence`]); with debug outputs, when the method gives
    /// per-texel sources and both frames have velocity. `null`: nothing
    /// was covered.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source_switch_share: Option<f64>,
    /// Of the same points with a patch at either frame, the share whose
    /// patch changed: switched, now over a hole, or come from one
    /// ([`crate::metrics::SourceSwitch::changed_share`]): what compares a
    /// method that leaves holes with one that fills them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source_changed_share: Option<f64>,
    /// Of the points of `source_switch_share`, the share that switched
    /// because the flow forced it: the patch that showed the point the
    /// frame before is stretched past δ_max there, or none showed it
    /// ([`crate::metrics::SwitchCauses`]); methods that record each texel's
    /// previous patch only (erosion, advect).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch_forced_share: Option<f64>,
    /// The selecting phase of a two-phase run: bytes of the frame's
    /// `selection.F.bin` payload (reported, not written to a file).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub selection_bytes: Option<usize>,
    /// The share that switched though the patch of the frame before is
    /// within δ_max there: switches the method chose, not the flow.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch_unforced_share: Option<f64>,
    /// Of those, the share whose patch of the frame before still shows the
    /// point by the method's own advection: the velocity carried the point
    /// across a border the patch's own advection did not (a disagreement
    /// between the two carries, no renewal).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch_unforced_shown_share: Option<f64>,
    /// Of the points of `source_switch_share`, the share forced by the
    /// erosion of a patch whose weight at the point is below 1 (stretched
    /// past δ_onset), within δ_max: renewal by distortion before the bound.
    /// Counted in `switch_forced_share`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch_forced_eroding_share: Option<f64>,
    /// Of the unforced switches, the share whose patch of the frame before
    /// still passes the erosion test there, with another patch drawn on
    /// top of it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch_unforced_on_top_share: Option<f64>,
    /// The unforced switches that are neither border crossings
    /// (`switch_unforced_shown_share`) nor under a patch on top.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch_unforced_other_share: Option<f64>,
    /// The share whose patch of the frame before is past δ_max there,
    /// switched or not; on `advect`, which never renews, the share of the
    /// surface the distortion bound would renew (the renewal floor). Its
    /// growth from one frame's file to the next is advect's *per-frame*
    /// renewal floor, which `compare` reports (docs/evaluation.md); it is
    /// not written here, since a farm resamples a shot in chunks that run
    /// side by side, where the frame before's file may not exist yet.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holder_distorted_share: Option<f64>,
    /// The same points by the region they land in: `bulk`, `sheet` (liquid
    /// thinner than r/2 under the point) and `droplet` (a piece of surface
    /// smaller than a disc of radius r), each with its number of points
    /// covered at both ends and its switch, forced and unforced shares
    /// ([`crate::coherence::regions`]); methods with a patch radius only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switch_by_region: Option<BTreeMap<&'static str, crate::coherence::regions::RegionSwitch>>,
    /// Colour follow ratio over the same points (see
    /// [`crate::metrics::colour_follow`]); `null` when too few points moved.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub colour_follow_ratio: Option<f64>,
    #[serde(flatten)]
    pub method_stats: BTreeMap<String, serde_json::Value>,
    /// Seconds per stage: read, bvh, atlas, the method's stages, dilate, write.
    pub seconds: BTreeMap<String, f64>,
    /// Stage names in order (the map above is sorted by name).
    pub stage_order: Vec<String>,
}

/// Progress reports for front ends.
pub enum Event<'a> {
    /// Starting frame `number`, the `index`-th of `total` to process.
    Start {
        number: i32,
        index: usize,
        total: usize,
    },
    /// Frame finished.
    Done { stats: &'a FrameStats },
    /// Something the user should know that did not stop the run.
    Warning(String),
    /// The memory estimate, made before the first frame.
    Memory(MemoryEstimate),
}
