//! Who showed a texel's point before: the lapped decision of earlier
//! frames, taken on this frame's carried patches. Two readers need it, and
//! one search serves both:
//! - the renewal record ([`crate::provenance::RENEWAL_HELD`] and the other
//!   flags): the *previous holder* is the first patch in candidate order
//!   (oldest first) that holds the point and whose texel there survived
//!   erosion at the weights of the frame before; whether it still shows
//!   the point, and whether it is past δ_max there, split the switches into
//!   forced and unforced;
//! - a transition ([`super::super::transition`]): the holders at the weights of
//!   each of the N frames before, which give the earlier source a texel
//!   still shows and its share.
//!
//! The search walks the candidates once, in the fill's order, and goes past
//! this frame's hit only while some earlier frame has no holder yet (weights
//! that rise again, a texel new to the surface), so it costs little beyond
//! the hit's own search. A point's erosion test at this frame's and at
//! the earlier frames' weights reads the feature map once: the test's
//! left-hand side depends on the point's patch uv and feature level, not
//! on the weight (on a splash frame at 6144², 13–19 % off the fill).

use glam::{Vec2, Vec3};

use super::super::erode::Verdict;
use super::{CornerData, FillContext, Hit, Located, SpanCandidate, verdict_in};

/// The longest transition, in frames ([`super::super::transition`]): each
/// frame of it is one more lapped decision per texel in the fill.
pub const MAX_TRANSITION_FRAMES: u32 = 8;
const MAX_FRAMES: u32 = MAX_TRANSITION_FRAMES;

/// A texel in transition: the earlier source it still shows beside its
/// own ([`super::super::transition`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transition {
    /// Texel index in the atlas.
    pub texel: u32,
    /// Id of the earlier source's patch.
    pub patch_id: u32,
    /// Where the texel's point lies in that patch now (it is carried with
    /// the flow like every patch).
    pub uv: Vec2,
    /// Share of the earlier source, in (0, 1).
    pub share: f32,
}

/// An earlier frame's holder: patch index, uv at the point, and whether
/// its triangle there is past δ_max.
type Holder = (u32, Vec2, Forced);

impl FillContext<'_> {
    /// [`FillContext::resolve_in_span`]'s hit (the same, by the same tests
    /// in the same order), the texel's renewal byte, and with a transition
    /// ([`FillContext::transition`] > 0) the earlier source it still shows.
    ///
    /// Each of this frame and the N frames before counts once (a frame
    /// without a holder does not count), a box filter over time: where the
    /// source changed k frames ago the new one weighs k + 1 of N + 1. Every
    /// earlier source is merged into the most recent one that differs from
    /// this frame's, so that a texel shows two sources at most.
    #[inline]
    pub(super) fn resolve_with_holders(
        &self,
        cands: &[SpanCandidate],
        k: u32,
        x: Vec3,
    ) -> (Option<Hit>, u8, Option<Transition>) {
        let levels = (self.transition.min(MAX_FRAMES) as usize).max(1);
        let mut hit = None;
        // Per earlier frame (index 0: the frame before).
        let mut holders = [None::<Holder>; MAX_FRAMES as usize];
        let mut open = levels;
        for group in cands.chunk_by(|a, b| a.patch == b.patch) {
            let Some((c, bary)) = self.span_holder(group, k, x) else {
                continue;
            };
            let located = c.corners.located(c.tri, bary);
            // Every frame's test at this point reads the same feature
            // value and uv: only the weight differs.
            let mut lhs = None;
            if hit.is_none() {
                hit = self.decide_with(&mut lhs, c.patch, located, c.verdict);
            }
            for (level, holder) in holders.iter_mut().enumerate().take(levels) {
                if holder.is_none() && self.held_at(c, bary, level, located, &mut lhs) {
                    // Whether the holder still keeps the point at this
                    // frame's weights: the hit when it is this patch, one
                    // more test (its left-hand side already read) when an
                    // earlier patch won.
                    let kept = match hit {
                        Some(h) => {
                            h.patch == c.patch
                                || (level == 0
                                    && self
                                        .decide_with(&mut lhs, c.patch, located, c.verdict)
                                        .is_some())
                        }
                        None => false,
                    };
                    let forced = Forced {
                        distorted: c.corners.distorted,
                        mismatched: c.corners.mismatched,
                        // Only a test that erodes makes a low weight a
                        // cause (advect carries weights it never uses).
                        eroding: located.w < 1.0 && self.erosion_of(c.patch).1.can_erode(),
                        kept,
                    };
                    *holder = Some((c.patch, located.uv, forced));
                    open -= 1;
                }
            }
            if hit.is_some() && open == 0 {
                break;
            }
        }
        let renewal = renewal_byte(holders[0], hit);
        let transition = (self.transition > 0)
            .then(|| self.earlier_source(&holders[..levels], hit))
            .flatten();
        (hit, renewal, transition)
    }

    /// The earlier source of a texel whose holders at the frames before
    /// are `earlier` and whose hit now is `hit` (`None`: uncovered now; the
    /// update will give it a new patch, which counts as this frame's).
    fn earlier_source(&self, earlier: &[Option<Holder>], hit: Option<Hit>) -> Option<Transition> {
        let now = hit.map(|h| h.patch);
        let present = 1 + earlier.iter().flatten().count();
        let same = 1 + earlier
            .iter()
            .flatten()
            .filter(|h| Some(h.0) == now)
            .count();
        let &(patch, uv, _) = earlier.iter().flatten().find(|h| Some(h.0) != now)?;
        Some(Transition {
            texel: 0,
            patch_id: self.patches[patch as usize].id,
            uv,
            share: (present - same) as f32 / present as f32,
        })
    }

    /// Whether candidate `c`'s texel at barycentrics `bary` survived
    /// erosion at the weights of `level` + 1 frames before.
    /// `located`: the point in `c` at this frame's weights, whose uv and
    /// level every frame's test shares; `lhs`: the erosion test's
    /// left-hand side there, once read.
    #[inline]
    fn held_at(
        &self,
        c: &SpanCandidate,
        bary: [f32; 3],
        level: usize,
        located: Located,
        lhs: &mut Option<f32>,
    ) -> bool {
        let verdict = match level {
            0 => c.verdict_before,
            _ => self
                .verdicts_older
                .get(level - 1)
                .map_or(Verdict::Eroded, |table| verdict_in(table, c.patch, c.tri)),
        };
        match verdict {
            Verdict::Kept => true,
            Verdict::Eroded => false,
            Verdict::Test => {
                let w = match level {
                    0 => c.corners.located_before(c.tri, bary).w,
                    _ => {
                        let patch = &self.patches[c.patch as usize];
                        let Some(weights) = patch
                            .weight_older
                            .get(level - 1)
                            .filter(|w| w.len() == patch.positions.len())
                        else {
                            return false;
                        };
                        let t = patch.triangles[c.tri as usize];
                        CornerData {
                            w: t.map(|v| weights[v as usize]),
                            ..c.corners
                        }
                        .located(c.tri, bary)
                        .w
                    }
                };
                self.kept_with(lhs, c.patch, located, w)
            }
        }
    }
}

/// The renewal byte of a texel whose holder the frame before is `holder`
/// and whose hit now is `hit`.
fn renewal_byte(holder: Option<Holder>, hit: Option<Hit>) -> u8 {
    use crate::provenance::{
        RENEWAL_DISTORTED, RENEWAL_ERODING, RENEWAL_HELD, RENEWAL_KEPT, RENEWAL_SHOWN,
        RENEWAL_STATE,
    };
    let Some((patch, _, forced)) = holder else {
        return 0;
    };
    let mut r = RENEWAL_HELD;
    if hit.is_some_and(|h| h.patch == patch) {
        r |= RENEWAL_SHOWN;
    }
    if forced.kept {
        r |= RENEWAL_KEPT;
    }
    if forced.eroding {
        r |= RENEWAL_ERODING;
    }
    if forced.distorted {
        r |= RENEWAL_DISTORTED;
    }
    if forced.mismatched {
        r |= RENEWAL_STATE;
    }
    r
}

/// Why the holder of a point may have to give it up there: past δ_max
/// (the flow), being eroded by its weight (below 1 at the point, this
/// frame), or showing an exemplar the fluid's state no longer selects;
/// and whether it still keeps the point at this frame's weights.
#[derive(Clone, Copy, Debug, Default)]
struct Forced {
    distorted: bool,
    mismatched: bool,
    eroding: bool,
    kept: bool,
}
