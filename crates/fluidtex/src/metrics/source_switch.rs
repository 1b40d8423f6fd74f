//! Source switch share: how much of the surface changes its source patch
//! from one frame to the next *as seen by a point that moves with the
//! fluid*.
//!
//! The harness samples points on the surface of frame t, carries each to
//! frame t+1 with the flow (the exact scene flow in the evaluation, the
//! mesh's velocity with a second-order step on real simulations; see
//! [`crate::coherence`]) and looks up the source patch at both ends. A
//! texture that rides the flow keeps its source on every point away from
//! patch borders; a texture that "boils" changes it on a large share.
//!
//! Only points covered at both ends count (a patch at t and a patch at
//! t+1): a point outside every chart, or on a texel no patch reached, has
//! no source to compare. Even a perfect method shows a floor of a few
//! percent from texel rounding at patch borders, which is why the pass
//! rule compares against the `advect` baseline on the same frames
//! ([`super::Thresholds::summarize_against_floor`]).
//!
//! A method that leaves holes (advect) and one that covers them with new
//! patches differ in *where* a point can switch: where a patch stops
//! covering, the first shows a hole (not counted) and the second a new
//! patch (a switch). [`SourceSwitch::lost`] counts the points of the first
//! kind, and [`SourceSwitch::gained`] the reverse (a hole at t, a patch at
//! t+1: a coverage edge that does not move with the flow, seen from the
//! hole's side), so the two can be compared on the same footing
//! ([`SourceSwitch::changed_share`]). Both directions count: a point carried
//! by the flow stays on the same side of a border that rides the flow, so a
//! method whose borders flicker shows the flicker both ways, and counting
//! only one way would halve it for the method that leaves holes.

use super::{MetricsError, SOURCE_OUTSIDE, SOURCE_UNCOVERED};
use crate::provenance::{
    RENEWAL_DISTORTED, RENEWAL_KEPT, RENEWAL_SHOWN, RENEWAL_UNKNOWN, renewal_forced,
    renewal_forced_by_erosion, renewal_unforced,
};

/// Source switches of one frame pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SourceSwitch {
    /// Points with a patch at both ends.
    pub covered: usize,
    /// Of those, points whose patch differs.
    pub switched: usize,
    /// Points with a patch at t that land on an uncovered texel (a hole)
    /// at t+1; not in `covered`.
    pub lost: usize,
    /// Points on an uncovered texel (a hole) at t that land on a patch at
    /// t+1; not in `covered`.
    pub gained: usize,
}

impl SourceSwitch {
    /// The metric: switched / covered (NaN when nothing was covered).
    pub fn share(&self) -> f64 {
        if self.covered == 0 {
            f64::NAN
        } else {
            self.switched as f64 / self.covered as f64
        }
    }

    /// Share of the points with a patch at either end whose patch changed:
    /// switched, lost or gained, (switched + lost + gained) / (covered +
    /// lost + gained) (NaN when no such point). Equal to
    /// [`SourceSwitch::share`] for a method that leaves no hole.
    pub fn changed_share(&self) -> f64 {
        let n = self.covered + self.lost + self.gained;
        if n == 0 {
            f64::NAN
        } else {
            (self.switched + self.lost + self.gained) as f64 / n as f64
        }
    }
}

/// Whether a provenance value names a patch (not outside, not uncovered).
#[inline]
pub fn is_patch(source: u32) -> bool {
    source != SOURCE_OUTSIDE && source != SOURCE_UNCOVERED
}

/// Counts the points whose source at frame t (`before`) differs from the
/// source at the point carried to frame t+1 (`after`), sample by sample.
pub fn source_switch(before: &[u32], after: &[u32]) -> Result<SourceSwitch, MetricsError> {
    if before.len() != after.len() {
        return Err(MetricsError::Length {
            what: "sources after the carry",
            expected: before.len(),
            got: after.len(),
        });
    }
    let mut out = SourceSwitch {
        covered: 0,
        switched: 0,
        lost: 0,
        gained: 0,
    };
    for (&a, &b) in before.iter().zip(after) {
        if is_patch(a) && is_patch(b) {
            out.covered += 1;
            out.switched += usize::from(a != b);
        } else if is_patch(a) && b == SOURCE_UNCOVERED {
            out.lost += 1;
        } else if a == SOURCE_UNCOVERED && is_patch(b) {
            out.gained += 1;
        }
    }
    Ok(out)
}

/// The switches of one frame pair split by what forced them, from the
/// renewal byte at each point's end (t+1) that the method recorded
/// ([`crate::provenance::RENEWAL_HELD`]): *forced* where the patch that
/// showed the point at t is past the distortion bound δ_max there, is
/// being eroded there (its weight below 1), shows an exemplar the state no
/// longer selects, or no patch showed it; *unforced* where that patch is
/// whole there yet no longer shows it. Counted on the points
/// [`source_switch`] covers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SwitchCauses {
    /// Points with a patch at both ends whose renewal is known.
    pub covered: usize,
    /// Of those, switched and forced.
    pub forced: usize,
    /// Of the forced, those forced only by the erosion of a holder whose
    /// weight is below 1 at the point
    /// ([`crate::provenance::renewal_forced_by_erosion`]): renewal by
    /// distortion before δ_max.
    pub forced_eroding: usize,
    /// Of those, switched and unforced.
    pub unforced: usize,
    /// Of the unforced, those whose previous patch still shows the point by
    /// the method's own reckoning ([`crate::provenance::RENEWAL_SHOWN`]):
    /// the velocity carried the point across a border that the method's
    /// own advection of the patch did not, so no patch was renewed there
    /// (a border crossing).
    pub unforced_shown: usize,
    /// Of the unforced, those whose previous patch still keeps the point
    /// at this frame's weights but does not show it
    /// ([`crate::provenance::RENEWAL_KEPT`]): another patch is drawn on top
    /// of it there.
    pub unforced_on_top: usize,
    /// Of those, points whose previous patch is past δ_max at t+1, switched
    /// or not: on a run that never renews a patch (advect) this is the
    /// *renewal floor*, the share of the surface the distortion bound
    /// would renew.
    pub distorted: usize,
}

impl SwitchCauses {
    fn share(&self, n: usize) -> f64 {
        if self.covered == 0 {
            f64::NAN
        } else {
            n as f64 / self.covered as f64
        }
    }

    /// forced / covered (NaN when no renewal is known).
    pub fn forced_share(&self) -> f64 {
        self.share(self.forced)
    }

    /// unforced / covered (NaN when no renewal is known).
    pub fn unforced_share(&self) -> f64 {
        self.share(self.unforced)
    }

    /// unforced_shown / covered (NaN when no renewal is known).
    pub fn unforced_shown_share(&self) -> f64 {
        self.share(self.unforced_shown)
    }

    /// forced_eroding / covered (NaN when no renewal is known).
    pub fn forced_eroding_share(&self) -> f64 {
        self.share(self.forced_eroding)
    }

    /// unforced_on_top / covered (NaN when no renewal is known).
    pub fn unforced_on_top_share(&self) -> f64 {
        self.share(self.unforced_on_top)
    }

    /// The unforced switches that are neither border crossings nor under a
    /// patch on top, over covered (NaN when no renewal is known).
    pub fn unforced_other_share(&self) -> f64 {
        self.share(self.unforced - self.unforced_shown - self.unforced_on_top)
    }

    /// distorted / covered (NaN when no renewal is known).
    pub fn distorted_share(&self) -> f64 {
        self.share(self.distorted)
    }
}

/// [`SwitchCauses`] of the points with sources `before` (t) and `after`
/// (t+1) and renewal bytes `renewal` (t+1), sample by sample. Every
/// switch with a known renewal is one or the other: one whose previous
/// holder still shows the point by the method's reckoning (the carry and
/// the method's own patch advection put the point on different sides of a
/// border) is unforced, as is the texel-rounding floor at borders.
pub fn switch_causes(
    before: &[u32],
    after: &[u32],
    renewal: &[u8],
) -> Result<SwitchCauses, MetricsError> {
    for (what, len) in [
        ("sources after the carry", after.len()),
        ("renewal bytes", renewal.len()),
    ] {
        if len != before.len() {
            return Err(MetricsError::Length {
                what,
                expected: before.len(),
                got: len,
            });
        }
    }
    let mut out = SwitchCauses::default();
    for ((&a, &b), &r) in before.iter().zip(after).zip(renewal) {
        if !(is_patch(a) && is_patch(b)) || r == RENEWAL_UNKNOWN {
            continue;
        }
        out.covered += 1;
        out.distorted += usize::from(r & RENEWAL_DISTORTED != 0);
        if a != b {
            let unforced = renewal_unforced(r);
            out.forced += usize::from(renewal_forced(r));
            out.forced_eroding += usize::from(renewal_forced_by_erosion(r));
            out.unforced += usize::from(unforced);
            let shown = r & RENEWAL_SHOWN != 0;
            out.unforced_shown += usize::from(unforced && shown);
            out.unforced_on_top += usize::from(unforced && !shown && r & RENEWAL_KEPT != 0);
        }
    }
    Ok(out)
}

/// Two runs' switches over the *same* carried points, counted only where
/// both have a patch at both ends: `(run, floor)`. Each run's own
/// [`source_switch`] counts the points it covers, and a method that covers
/// holes with new patches counts points the floor method (advect, which
/// leaves them as holes) does not; on the common points the two shares
/// differ only by how the patches both methods show there move. Points are
/// `[source at t, source at t+1]`, in the same order for both runs.
pub fn source_switch_same_points(
    run: &[[u32; 2]],
    floor: &[[u32; 2]],
) -> Result<(SourceSwitch, SourceSwitch), MetricsError> {
    if run.len() != floor.len() {
        return Err(MetricsError::Length {
            what: "points of the floor run",
            expected: run.len(),
            got: floor.len(),
        });
    }
    let covered = |p: &[u32; 2]| is_patch(p[0]) && is_patch(p[1]);
    let common: Vec<usize> = (0..run.len())
        .filter(|&i| covered(&run[i]) && covered(&floor[i]))
        .collect();
    let on_common = |points: &[[u32; 2]]| {
        let (before, after): (Vec<u32>, Vec<u32>) =
            common.iter().map(|&i| (points[i][0], points[i][1])).unzip();
        source_switch(&before, &after)
    };
    Ok((on_common(run)?, on_common(floor)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn switches_split_by_the_renewal_at_their_end() {
        use crate::provenance::{
            RENEWAL_ERODING as E, RENEWAL_HELD as H, RENEWAL_KEPT as K, RENEWAL_SHOWN as S,
        };
        const D: u8 = RENEWAL_DISTORTED;
        const U: u8 = RENEWAL_UNKNOWN;
        let before = [1, 1, 1, 1, 1, 1, 1, SOURCE_UNCOVERED, 1, 1, 1, 1];
        let after = [2, 2, 2, 2, 1, 1, 2, 2, 2, 2, 2, 1];
        let renewal = [
            0,
            H | D,
            H,
            H | S | K,
            H | S | D,
            H | S,
            U,
            0,
            H,
            H | E,
            H | K,
            H | E,
        ];
        let c = switch_causes(&before, &after, &renewal).expect("same lengths");
        // Point 6 has no known renewal, point 7 no patch at t.
        assert_eq!(
            c,
            SwitchCauses {
                covered: 10,
                forced: 3,
                forced_eroding: 1,
                unforced: 4,
                unforced_shown: 1,
                unforced_on_top: 1,
                distorted: 2,
            }
        );
        // Of the unforced switches (points 2, 3, 8, 10), point 3's previous
        // patch still shows it (point 5's does too, but it did not switch),
        // point 10's keeps it under another patch, points 2 and 8 lost it
        // otherwise. Point 9's holder was being eroded: forced; point 11's
        // too, but it did not switch.
        assert_eq!(c.unforced_shown_share(), 1.0 / 10.0);
        assert_eq!(c.unforced_on_top_share(), 1.0 / 10.0);
        assert_eq!(c.unforced_other_share(), 2.0 / 10.0);
        assert_eq!(c.forced_share(), 3.0 / 10.0);
        assert_eq!(c.forced_eroding_share(), 1.0 / 10.0);
        assert_eq!(c.unforced_share(), 4.0 / 10.0);
        assert_eq!(c.distorted_share(), 2.0 / 10.0);
        let none = switch_causes(&[1], &[2], &[U]).expect("same lengths");
        assert!(none.unforced_share().is_nan());
        assert!(matches!(
            switch_causes(&[1, 2], &[1, 2], &[0]),
            Err(MetricsError::Length { .. })
        ));
    }

    #[test]
    fn only_points_covered_at_both_ends_count() {
        let before = [
            1,
            1,
            2,
            2,
            SOURCE_OUTSIDE,
            3,
            SOURCE_UNCOVERED,
            4,
            6,
            SOURCE_UNCOVERED,
        ];
        let after = [
            1,
            2,
            2,
            3,
            1,
            SOURCE_UNCOVERED,
            5,
            4,
            SOURCE_OUTSIDE,
            SOURCE_OUTSIDE,
        ];
        let s = source_switch(&before, &after).expect("same lengths");
        assert_eq!(
            s,
            SourceSwitch {
                covered: 5,
                switched: 2,
                lost: 1,
                gained: 1,
            }
        );
        assert_eq!(s.share(), 0.4);
        // A point that leaves every chart is not lost (it has no texel), nor
        // is one that comes from outside every chart gained; a hole that
        // leaves every chart is neither.
        assert_eq!(s.changed_share(), 4.0 / 7.0);
        let no_holes = source_switch(&[1, 2], &[1, 3]).expect("same lengths");
        assert_eq!(no_holes.changed_share(), no_holes.share());
        let none = source_switch(&[SOURCE_OUTSIDE], &[1]).expect("same lengths");
        assert!(none.share().is_nan());
        assert!(matches!(
            source_switch(&[1, 2], &[1]),
            Err(MetricsError::Length { .. })
        ));
    }

    /// A run that fills the floor's holes with new patches switches there;
    /// on the points both cover it is judged on its own patches only.
    #[test]
    fn same_points_count_only_where_both_runs_cover_both_ends() {
        const U: u32 = SOURCE_UNCOVERED;
        const O: u32 = SOURCE_OUTSIDE;
        let run = [
            [1, 1],
            [1, 2],
            [3, 3],
            [4, 5],
            [6, 7],
            [8, 9],
            [2, 2],
            [O, 1],
        ];
        let floor = [
            [1, 1],
            [1, 1],
            [2, 3],
            [U, 4],
            [6, U],
            [O, 1],
            [2, 2],
            [1, 1],
        ];
        let (r, f) = source_switch_same_points(&run, &floor).expect("same lengths");
        // Common: points 0, 1, 2 and 6.
        assert_eq!((r.covered, r.switched), (4, 1));
        assert_eq!((f.covered, f.switched), (4, 1));
        assert_eq!((r.lost, r.gained, f.lost, f.gained), (0, 0, 0, 0));
        // On its own points the run switches 4 of 7; the holes it filled
        // (points 3 and 4) and point 5 no longer count.
        let (b, a): (Vec<u32>, Vec<u32>) = run.iter().map(|p| (p[0], p[1])).unzip();
        assert_eq!(source_switch(&b, &a).expect("same lengths").switched, 4);
        // The same run on both sides: the same counts, every covered point.
        let (x, y) = source_switch_same_points(&run, &run).expect("same lengths");
        assert_eq!(x, y);
        assert_eq!((x.covered, x.switched), (7, 4));
        assert!(matches!(
            source_switch_same_points(&run, &floor[1..]),
            Err(MetricsError::Length { .. })
        ));
    }
}
