//! A frame's source switches by cause ([`CauseShares`]) and the per-frame
//! renewal floor ([`renewal_floor_growth`]): the numbers the rulings on
//! violent liquids read (docs/evaluation.md).

use crate::metrics;

/// One frame's switches by cause, as shares of the points covered at both
/// ends whose renewal the method records ([`metrics::SwitchCauses`]); NaN
/// where it records none.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CauseShares {
    /// Forced switches: no previous holder, or one past δ_max, being eroded
    /// (weight below 1) or showing an exemplar the state no longer selects.
    pub forced: f64,
    /// Of those, forced by the erosion of a distorted holder alone.
    pub forced_eroding: f64,
    /// Unforced switches: the holder is whole at the point.
    pub unforced: f64,
    /// Of those, border crossings: the holder still shows the point by the
    /// method's own carry.
    pub unforced_border: f64,
    /// Of those, a patch drawn on top of a holder that still keeps it.
    pub unforced_on_top: f64,
    /// The unforced switches of no cause above.
    pub unforced_other: f64,
    /// Points whose previous holder is past δ_max at the point, switched or
    /// not: on advect, which never renews, the cumulative renewal floor.
    pub holder_distorted: f64,
    /// How much `holder_distorted` grew since the frame before (0 where it
    /// fell; NaN on the first measured frame): on advect, the share of the
    /// surface the flow pushed past δ_max on this frame alone, the
    /// per-frame renewal floor of the violent-flow ruling.
    pub holder_distorted_new: f64,
}

impl CauseShares {
    /// Nothing recorded.
    pub const NONE: CauseShares = CauseShares {
        forced: f64::NAN,
        forced_eroding: f64::NAN,
        unforced: f64::NAN,
        unforced_border: f64::NAN,
        unforced_on_top: f64::NAN,
        unforced_other: f64::NAN,
        holder_distorted: f64::NAN,
        holder_distorted_new: f64::NAN,
    };

    /// The shares of `c`, with the growth of the holder-past-δ_max share
    /// from `before` (that share on the frame before, NaN if unknown).
    pub fn of(c: &metrics::SwitchCauses, before: f64) -> CauseShares {
        let holder_distorted = c.distorted_share();
        CauseShares {
            forced: c.forced_share(),
            forced_eroding: c.forced_eroding_share(),
            unforced: c.unforced_share(),
            unforced_border: c.unforced_shown_share(),
            unforced_on_top: c.unforced_on_top_share(),
            unforced_other: c.unforced_other_share(),
            holder_distorted,
            holder_distorted_new: renewal_floor_growth(before, holder_distorted),
        }
    }
}

/// The per-frame renewal floor from the cumulative one on the frame before
/// (`before`) and this frame (`now`): its growth, never below 0 (patches
/// that relax back under δ_max do not make room for others); NaN where
/// either is unknown.
pub fn renewal_floor_growth(before: f64, now: f64) -> f64 {
    if before.is_finite() && now.is_finite() {
        (now - before).max(0.0)
    } else {
        f64::NAN
    }
}
