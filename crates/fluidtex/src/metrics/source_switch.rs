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

use super::{MetricsError, SOURCE_OUTSIDE, SOURCE_UNCOVERED};

/// Source switches of one frame pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SourceSwitch {
    /// Points with a patch at both ends.
    pub covered: usize,
    /// Of those, points whose patch differs.
    pub switched: usize,
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
    };
    for (&a, &b) in before.iter().zip(after) {
        if is_patch(a) && is_patch(b) {
            out.covered += 1;
            out.switched += usize::from(a != b);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_points_covered_at_both_ends_count() {
        let before = [1, 1, 2, 2, SOURCE_OUTSIDE, 3, SOURCE_UNCOVERED, 4];
        let after = [1, 2, 2, 3, 1, SOURCE_UNCOVERED, 5, 4];
        let s = source_switch(&before, &after).expect("same lengths");
        assert_eq!(
            s,
            SourceSwitch {
                covered: 5,
                switched: 2
            }
        );
        assert_eq!(s.share(), 0.4);
        let none = source_switch(&[SOURCE_OUTSIDE], &[1]).expect("same lengths");
        assert!(none.share().is_nan());
        assert!(matches!(
            source_switch(&[1, 2], &[1]),
            Err(MetricsError::Length { .. })
        ));
    }
}
