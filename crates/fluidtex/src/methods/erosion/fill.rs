//! The lapped fill (Gagnon et al. 2021, Sec. 5.1): every atlas texel takes
//! its value from exactly one patch texel — the topmost (oldest) patch whose
//! texel there survives erosion — and never from a blend.
//!
//! This is the hot loop of the method, organised for the speed target of
//! docs/design.md, *Scale and speed*:
//! - Locating a surface point in a patch needs the patch triangle whose
//!   footprint contains it. Per frame, every patch triangle is matched with
//!   the fluid triangles its (slightly enlarged) bounding box meets, through
//!   the fluid mesh's BVH; the pairs are sorted into per-fluid-triangle
//!   candidate lists ordered by patch age ([`candidates`]). A texel then
//!   only tests the few patch triangles listed for its own fluid triangle.
//! - A patch triangle is a chord of the curved surface, so a surface point
//!   is located by orthogonal projection onto the triangle's plane; the
//!   triangle of the patch with the largest smallest barycentric wins, and a
//!   small negative tolerance closes the slivers that curvature opens
//!   between neighbouring chords.
//! - Texels are visited by the band walk of [`crate::methods::lapped`]
//!   (bands of rows in parallel, each writing only its own rows:
//!   deterministic whatever the thread count); this file adds the per-span
//!   candidate pruning and the per-texel decision.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

pub use self::holders::{MAX_TRANSITION_FRAMES, Transition};
use super::erode::{ErosionTest, Verdict};
use super::exemplars::MultiFill;
use super::feature_levels::FeatureLevelSampler;
use super::patch::Patch;
use crate::atlas::{Atlas, Band};
use crate::exemplar::Exemplar;
use crate::mesh::TriMesh;
pub(crate) use crate::methods::lapped::BandTexel;
use crate::methods::lapped::bands::{SpanTexels, for_each_span};
use crate::methods::lapped::{BandResult, TexelBuffers, fill_bands};

pub mod candidates;
pub mod holders;

pub(crate) use self::candidates::patch_pairs_list;
pub use self::candidates::{
    Candidates, FluidTriangle, FluidTriangles, LocateTolerance, TriFrame, patch_frames,
};
#[cfg(test)]
pub(crate) use self::candidates::{patch_pairs, prism_box};

pub use crate::provenance::{SOURCE_OUTSIDE as OUTSIDE, SOURCE_UNCOVERED as UNCOVERED};

/// Everything the fill reads.
#[derive(Clone, Copy)]
pub struct FillContext<'a> {
    pub mesh: &'a TriMesh,
    /// `mesh`'s triangles as the candidate search reads them.
    pub fluid: &'a FluidTriangles,
    pub patches: &'a [Patch],
    pub frames: &'a [Vec<Option<TriFrame>>],
    pub exemplar: &'a Exemplar,
    pub feature: &'a FeatureLevelSampler<'a>,
    pub test: ErosionTest,
    pub tolerance: LocateTolerance,
    /// Several exemplars: each patch reads its own exemplar, feature map
    /// and erosion test ([`Patch::exemplar`]); `None`: every patch reads
    /// `exemplar`, `feature` and `test`.
    pub multi: Option<&'a MultiFill<'a>>,
    /// Per patch triangle (indexed like `frames`), what the erosion test
    /// says of all its points ([`FillContext::erosion_verdicts`]); a triangle not listed
    /// (an empty slice) is tested texel by texel.
    pub verdicts: &'a [Vec<Verdict>],
    /// The same verdicts at the weights of the frame before
    /// ([`FillContext::verdicts_before`]), for the renewal record; empty
    /// when the fill records none.
    pub verdicts_before: &'a [Vec<Verdict>],
    /// With a transition of N frames, the verdicts at the weights of the
    /// N − 1 frames before that ([`Patch::weight_older`]), most recent
    /// first; empty without.
    pub verdicts_older: &'a [Vec<Vec<Verdict>>],
    /// Frames of the transition ([`super::transition`]); 0: one source per
    /// texel, the paper's fill.
    pub transition: u32,
    /// A patch triangle past δ_max shows nothing ([`super::Bound::Hard`]):
    /// this frame's verdict of every [`Patch::distorted`] triangle is
    /// [`Verdict::Eroded`].
    pub hard_bound: bool,
}

/// The per-triangle erosion verdicts a fill reads ([`FillContext`]'s
/// `verdicts`, `verdicts_before`, `verdicts_older`), computed once per
/// frame.
pub struct VerdictTables {
    now: Vec<Vec<Verdict>>,
    before: Vec<Vec<Verdict>>,
    older: Vec<Vec<Vec<Verdict>>>,
}

impl VerdictTables {
    /// This frame's verdicts of `unjudged`'s patches; the frame before's
    /// where the fill records the renewal (`renewal`) or blends a
    /// transition, and the older frames' a transition reads.
    pub fn of(unjudged: &FillContext<'_>, renewal: bool) -> VerdictTables {
        let history = unjudged.transition > 0;
        VerdictTables {
            now: unjudged.erosion_verdicts(),
            before: if renewal || history {
                unjudged.verdicts_before()
            } else {
                Vec::new()
            },
            older: if history {
                unjudged.verdicts_older(unjudged.transition as usize - 1)
            } else {
                Vec::new()
            },
        }
    }

    /// `unjudged` reading these verdicts.
    pub fn judge<'a>(&'a self, unjudged: FillContext<'a>) -> FillContext<'a> {
        FillContext {
            verdicts: &self.now,
            verdicts_before: &self.before,
            verdicts_older: &self.older,
            ..unjudged
        }
    }
}

/// Where a surface point lies in a patch.
#[derive(Clone, Copy, Debug)]
pub(super) struct Located {
    /// The patch triangle that holds it.
    pub(super) triangle: u32,
    /// Patch (exemplar) uv.
    pub(super) uv: Vec2,
    /// Interpolated weight w.
    pub(super) w: f32,
    /// Feature-map level of the triangle.
    pub(super) lod: f32,
}

/// What the lapped decision reads of one patch triangle at its corners:
/// rest uv and weight, and the triangle's feature level. The span walk
/// gathers them once per fluid triangle and candidate
/// ([`SpanPruner::prepare`]) instead of once per texel from the patch's
/// arrays: those reads, scattered over every patch, were about a quarter
/// of the fill's time in a profile (85k triangles, 6144² atlas).
#[derive(Clone, Copy, Debug)]
pub(super) struct CornerData {
    pub(super) uv: [Vec2; 3],
    pub(super) w: [f32; 3],
    pub(super) lod: f32,
    /// The weights of the frame before (0 for a patch created this frame).
    pub(super) w_before: [f32; 3],
    /// The triangle is past δ_max ([`Patch::distorted`]).
    pub(super) distorted: bool,
    /// Its exemplar no longer matches the fluid's state ([`Patch::mismatched`]).
    pub(super) mismatched: bool,
}

impl CornerData {
    /// Triangle `j` of `patch`.
    #[inline]
    fn of(patch: &Patch, j: u32) -> CornerData {
        let t = patch.triangles[j as usize];
        CornerData {
            uv: t.map(|v| patch.rest[v as usize]),
            w: t.map(|v| patch.weight[v as usize]),
            lod: patch.lod.get(j as usize).copied().unwrap_or(0.0),
            w_before: t.map(|v| patch.weight_before.get(v as usize).copied().unwrap_or(0.0)),
            distorted: patch.distorted.get(j as usize).copied().unwrap_or(false),
            mismatched: patch.mismatched.get(j as usize).copied().unwrap_or(false),
        }
    }

    /// The point at barycentrics `bary` (clamped to the triangle) of
    /// triangle `j`, whose corners these are.
    #[inline]
    pub(super) fn located(&self, j: u32, bary: [f32; 3]) -> Located {
        let b = bary.map(|v| v.max(0.0));
        let s = b[0] + b[1] + b[2];
        let b = b.map(|v| v / s);
        let uv = self.uv[0] * b[0] + self.uv[1] * b[1] + self.uv[2] * b[2];
        let w = self.w[0] * b[0] + self.w[1] * b[1] + self.w[2] * b[2];
        Located {
            triangle: j,
            uv,
            w,
            lod: self.lod,
        }
    }

    /// [`CornerData::located`] with the weights of the frame before.
    #[inline]
    pub(super) fn located_before(&self, j: u32, bary: [f32; 3]) -> Located {
        CornerData {
            w: self.w_before,
            ..*self
        }
        .located(j, bary)
    }
}

/// What a texel resolved to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Index of the patch in the patch list.
    pub patch: u32,
    /// Patch (exemplar) uv at the texel.
    pub uv: Vec2,
}

impl FillContext<'_> {
    /// Locates `x` (on fluid triangle with unit normal `n`) in patch `i`
    /// among the listed patch triangles; returns the patch uv and weight.
    #[inline]
    pub fn locate(
        &self,
        i: u32,
        tris: impl Iterator<Item = u32>,
        x: Vec3,
        n: Vec3,
    ) -> Option<(Vec2, f32, f32)> {
        self.locate_triangle(i, tris, x, n)
            .map(|l| (l.uv, l.w, l.lod))
    }

    /// [`FillContext::locate`], with the patch triangle that holds `x`.
    #[inline]
    fn locate_triangle(
        &self,
        i: u32,
        tris: impl Iterator<Item = u32>,
        x: Vec3,
        n: Vec3,
    ) -> Option<Located> {
        let frames = &self.frames[i as usize];
        let facing = tris.filter_map(|j| {
            let frame = frames[j as usize].as_ref()?;
            (frame.normal.dot(n) > 0.0).then_some((j, frame))
        });
        let (j, bary) = self.best_holder(facing, x)?;
        Some(self.located(i, j, bary))
    }

    /// Of the listed triangles (facing the point's side), the one that
    /// holds `x`: within the plane distance, and with the largest smallest
    /// barycentric above the tolerance (the first of equals); with the
    /// barycentrics of `x` there.
    #[inline]
    fn best_holder<'f, T>(
        &self,
        listed: impl Iterator<Item = (T, &'f TriFrame)>,
        x: Vec3,
    ) -> Option<(T, [f32; 3])> {
        let mut best: Option<(T, [f32; 3], f32)> = None;
        for (j, frame) in listed {
            let (bary, plane) = frame.locate(x);
            if !self.tolerance.holds(bary, plane) {
                continue;
            }
            let m = bary[0].min(bary[1]).min(bary[2]);
            if best.as_ref().is_none_or(|b| m > b.2) {
                best = Some((j, bary, m));
            }
        }
        best.map(|(j, bary, _)| (j, bary))
    }

    /// Patch `i`'s uv, weight and feature level at barycentrics `bary` of
    /// its triangle `j` (clamped to the triangle).
    #[inline]
    fn located(&self, i: u32, j: u32, bary: [f32; 3]) -> Located {
        CornerData::of(&self.patches[i as usize], j).located(j, bary)
    }

    /// The lapped decision for patch `i` at `x` among the listed patch
    /// triangles: its uv when it holds `x` and its texel there survives
    /// erosion. A triangle whose [`Verdict`] is known skips the feature
    /// lookup; the answer is the same either way.
    #[inline]
    fn hit(&self, i: u32, tris: impl Iterator<Item = u32>, x: Vec3, n: Vec3) -> Option<Hit> {
        let l = self.locate_triangle(i, tris, x, n)?;
        self.decide(i, l, self.verdict(i, l.triangle))
    }

    /// The lapped decision at a located point: its hit when the patch's
    /// texel there survives erosion.
    #[inline]
    pub(super) fn decide(&self, i: u32, l: Located, verdict: Verdict) -> Option<Hit> {
        self.decide_with(&mut None, i, l, verdict)
    }

    /// [`FillContext::decide`], reading the erosion test's left-hand side
    /// at `l` from `lhs` when it was read already (and keeping it there).
    #[inline]
    pub(super) fn decide_with(
        &self,
        lhs: &mut Option<f32>,
        i: u32,
        l: Located,
        verdict: Verdict,
    ) -> Option<Hit> {
        let kept = match verdict {
            Verdict::Kept => true,
            Verdict::Eroded => false,
            Verdict::Test => self.kept_with(lhs, i, l, l.w),
        };
        kept.then_some(Hit { patch: i, uv: l.uv })
    }

    /// The verdict of triangle `j` of patch `i` ([`Verdict::Test`] when
    /// none was computed). The fill's tables already hold the hard bound
    /// ([`FillContext::erosion_verdicts`]); without tables (the update
    /// tests its new patches so) it is applied here, so that a texel the
    /// update covers is one the next frame's fill covers too.
    #[inline]
    fn verdict(&self, i: u32, j: u32) -> Verdict {
        let past_bound = self.hard_bound
            && self.verdicts.is_empty()
            && (self.patches.get(i as usize)).is_some_and(|p| p.past_bound(j));
        if past_bound {
            Verdict::Eroded
        } else {
            verdict_in(self.verdicts, i, j)
        }
    }

    /// The verdict of triangle `j` of patch `i` at the weights of the frame
    /// before ([`Verdict::Test`] when none was computed).
    #[inline]
    fn verdict_before(&self, i: u32, j: u32) -> Verdict {
        verdict_in(self.verdicts_before, i, j)
    }

    /// The exemplar patch `i` (index in the patch list) shows.
    #[inline]
    pub fn exemplar_of(&self, i: u32) -> &Exemplar {
        match self.multi {
            None => self.exemplar,
            Some(m) => self
                .patches
                .get(i as usize)
                .and_then(|p| m.exemplars.get(m.slot(p)))
                .map_or(self.exemplar, |e| e),
        }
    }

    /// True when patch `i` survives erosion at `located` with weight `w`,
    /// its feature map read at the point's level (see
    /// [`super::feature_levels`]). The left-hand side comes from `lhs`
    /// when an earlier test of the same point read it (the same value:
    /// same patch, uv and level), and is kept there otherwise.
    #[inline]
    pub(super) fn kept_with(
        &self,
        lhs: &mut Option<f32>,
        i: u32,
        located: Located,
        w: f32,
    ) -> bool {
        let value = *lhs.get_or_insert_with(|| self.erosion_lhs(i, located.uv, located.lod));
        !ErosionTest::eroded_lhs(value, w)
    }

    /// The left-hand side of patch `i`'s erosion test at uv `uv`, its
    /// feature map read at level `lod` ([`ErosionTest::lhs`]): what
    /// [`FillContext::kept_with`] compares with 1 − w. It does not depend on the
    /// weight, so one point tested at several frames' weights reads the
    /// feature map once ([`FillContext::resolve_with_holders`]).
    #[inline]
    pub(super) fn erosion_lhs(&self, i: u32, uv: Vec2, lod: f32) -> f32 {
        let (feature, test) = self.erosion_of(i);
        let f = feature.sample(uv.x, uv.y, lod);
        test.lhs(f, uv.x, uv.y)
    }

    /// The feature map and erosion test of patch `i`.
    #[inline]
    fn erosion_of(&self, i: u32) -> (&FeatureLevelSampler<'_>, ErosionTest) {
        match self.multi {
            None => (self.feature, self.test),
            Some(m) => {
                let e = self
                    .patches
                    .get(i as usize)
                    .map_or(0, |p| m.feature_slot(p));
                match (m.features.get(e), m.tests.get(e)) {
                    (Some(f), Some(&t)) => (f, t),
                    _ => (self.feature, self.test),
                }
            }
        }
    }

    /// Per patch triangle (indexed like the frames), what the erosion test
    /// says of all its points ([`ErosionTest::triangle_verdict`]): for
    /// [`FillContext::verdicts`]. Computed once per frame, it lets the fill
    /// skip the feature lookup on triangles wholly kept and pass over
    /// patches wholly eroded ([`Candidates::without_eroded`]).
    pub fn erosion_verdicts(&self) -> Vec<Vec<Verdict>> {
        let mut tables = self.verdicts_at(|p| Some(&p.weight));
        if self.hard_bound {
            for (table, p) in tables.iter_mut().zip(self.patches) {
                for (j, verdict) in table.iter_mut().enumerate() {
                    if p.past_bound(j as u32) {
                        *verdict = Verdict::Eroded;
                    }
                }
            }
        }
        tables
    }

    /// [`FillContext::erosion_verdicts`] at the weights of the frame before
    /// ([`Patch::weight_before`]): where each patch could have shown a
    /// texel then. A patch created this frame showed nothing (all
    /// [`Verdict::Eroded`]).
    pub fn verdicts_before(&self) -> Vec<Vec<Verdict>> {
        self.verdicts_at(|p| {
            (p.weight_before.len() == p.positions.len()).then_some(&p.weight_before)
        })
    }

    /// [`FillContext::erosion_verdicts`] at each of the older weights a
    /// transition keeps ([`Patch::weight_older`]), most recent first:
    /// `levels` tables (a patch that did not exist then: all eroded).
    pub fn verdicts_older(&self, levels: usize) -> Vec<Vec<Vec<Verdict>>> {
        (0..levels)
            .map(|k| {
                self.verdicts_at(|p| {
                    p.weight_older
                        .get(k)
                        .filter(|w| w.len() == p.positions.len())
                })
            })
            .collect()
    }

    /// The triangle verdicts at per-vertex weights `weights` of a patch
    /// (`None`: every triangle eroded).
    fn verdicts_at(
        &self,
        weights: impl Fn(&Patch) -> Option<&Vec<f32>> + Sync,
    ) -> Vec<Vec<Verdict>> {
        self.patches
            .par_iter()
            .enumerate()
            .map(|(i, p)| {
                let Some(weight) = weights(p) else {
                    return vec![Verdict::Eroded; p.triangles.len()];
                };
                let (_, test) = self.erosion_of(i as u32);
                p.triangles
                    .iter()
                    .map(|t| {
                        let uv = t.map(|v| p.rest[v as usize]);
                        let w = t.map(|v| weight[v as usize]);
                        test.triangle_verdict(uv, w)
                    })
                    .collect()
            })
            .collect()
    }

    /// The lapped decision for one surface point: the first patch, in the
    /// candidate order (oldest first), that contains the point and whose
    /// texel there is not eroded.
    #[inline]
    pub fn resolve(&self, candidates: &[(u32, u32)], x: Vec3, n: Vec3) -> Option<Hit> {
        candidates
            .chunk_by(|a, b| a.0 == b.0)
            .find_map(|group| self.hit(group[0].0, group.iter().map(|c| c.1), x, n))
    }
}

/// A chart texel left uncovered by the fill.
pub use crate::methods::lapped::ChartTexel as Uncovered;

/// The fill's per-texel results (the shared lapped buffers; the lapped
/// fill keeps no layer count or level).
pub type FillBuffers = TexelBuffers;

impl TexelBuffers {
    /// Writes the result of a hit at texel `t`.
    #[inline]
    pub fn write(&mut self, t: usize, hit: Hit, id: u32, exemplar: &Exemplar) {
        let c = self.channels;
        if !self.defer_values {
            exemplar.sample_all(hit.uv.x, hit.uv.y, &mut self.values[t * c..(t + 1) * c]);
        }
        self.source[t] = id + 1;
        self.uv[t] = hit.uv;
    }
}

/// A candidate patch triangle of one span, with the range of the span's
/// texels (indices from the span start) where it may contain the texel.
/// It carries the triangle's locating frame, erosion verdict and corner
/// data, so the per-texel decision reads them from the span's short list
/// instead of from the per-patch tables.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SpanCandidate {
    pub(crate) patch: u32,
    pub(crate) tri: u32,
    pub(crate) lo: u32,
    pub(crate) hi: u32,
    frame: TriFrame,
    pub(super) verdict: Verdict,
    pub(super) verdict_before: Verdict,
    pub(super) corners: CornerData,
}

/// The span pruning of one fluid triangle. Along a span the surface point
/// is affine in the texel index, and so are a candidate triangle's
/// barycentrics and plane distance: each acceptance condition of
/// [`FillContext::locate`] holds on an interval of texels, found from its
/// value at the span's first texel and its change per texel. Over a fluid
/// triangle those quantities are affine in the triangle's barycentrics, so
/// [`SpanPruner::prepare`] takes them at the three corners and their change
/// per texel once per triangle, and [`SpanPruner::prune`] only interpolates
/// per span (no projection and no division per span and candidate). The
/// intervals are widened by a texel, and the bounds by a small slack, so
/// they only prune; every texel is still decided by the exact per-texel test.
#[derive(Default)]
pub(crate) struct SpanPruner {
    /// The fluid triangle prepared for (`None`: none yet).
    triangle: Option<u32>,
    lines: Vec<CandidateLines>,
}

/// One candidate patch triangle on the prepared fluid triangle: the
/// acceptance quantities (l1, l2, plane distance) at the fluid triangle's
/// corners, and each condition's change per texel with its reciprocal.
#[derive(Clone, Copy, Debug)]
struct CandidateLines {
    patch: u32,
    tri: u32,
    frame: TriFrame,
    verdict: Verdict,
    verdict_before: Verdict,
    corners: CornerData,
    /// `at_corners[q][c]`: quantity q (l1, l2, h) at corner c.
    at_corners: [[f32; 3]; 3],
    /// Per condition (b0, b1, b2, h, −h): change per texel and 1 / change
    /// (0 where the change is negligible).
    slope: [f32; 5],
    inverse: [f32; 5],
}

impl SpanPruner {
    /// Prepares the candidates `list` of the span's fluid triangle, unless
    /// they are prepared already (spans come grouped by triangle). A
    /// candidate facing away from the triangle is dropped here: the
    /// per-texel test rejects it at every texel of the triangle.
    fn prepare(
        &mut self,
        ctx: &FillContext<'_>,
        atlas: &Atlas,
        list: &[(u32, u32)],
        span: &SpanTexels<'_>,
    ) {
        if self.triangle == Some(span.triangle) {
            return;
        }
        self.triangle = Some(span.triangle);
        self.lines.clear();
        let s = atlas.barycentric_step(span.triangle);
        for &(i, j) in list {
            let Some(frame) = ctx.frames[i as usize][j as usize] else {
                continue;
            };
            if frame.normal.dot(span.normal) <= 0.0 {
                continue;
            }
            let at = span.corners.map(|q| frame.locate(q));
            let at_corners = [
                at.map(|(b, _)| b[1]),
                at.map(|(b, _)| b[2]),
                at.map(|(_, h)| h),
            ];
            let [d1, d2, dh] = at_corners.map(|q| q[0] * s[0] + q[1] * s[1] + q[2] * s[2]);
            let slope = [-d1 - d2, d1, d2, dh, -dh];
            let inverse = slope.map(|d| if d.abs() < 1e-12 { 0.0 } else { 1.0 / d });
            self.lines.push(CandidateLines {
                patch: i,
                tri: j,
                frame,
                verdict: ctx.verdict(i, j),
                verdict_before: ctx.verdict_before(i, j),
                corners: CornerData::of(&ctx.patches[i as usize], j),
                at_corners,
                slope,
                inverse,
            });
        }
    }

    /// The prepared candidates that may contain some texel of a span of `n`
    /// texels whose first texel has barycentrics `first`, each with the
    /// texel range where it may, into `out`.
    fn prune(
        &self,
        tolerance: LocateTolerance,
        first: [f32; 3],
        n: u32,
        out: &mut Vec<SpanCandidate>,
    ) {
        out.clear();
        let last = n.saturating_sub(1) as f32;
        let bary_min = tolerance.min_bary - 1e-4;
        let plane_min = -tolerance.max_plane_distance - 1e-4;
        let bounds = [bary_min, bary_min, bary_min, plane_min, plane_min];
        let at = |q: [f32; 3]| q[0] * first[0] + q[1] * first[1] + q[2] * first[2];
        for line in &self.lines {
            let [l1, l2, h] = line.at_corners.map(at);
            let start = [1.0 - l1 - l2, l1, l2, h, -h];
            let (mut lo, mut hi) = (0.0f32, last);
            for c in 0..5 {
                // start + slope k >= bound
                if line.inverse[c] == 0.0 {
                    if start[c] < bounds[c] {
                        hi = -1.0;
                    }
                } else {
                    let k = (bounds[c] - start[c]) * line.inverse[c];
                    if line.slope[c] > 0.0 {
                        lo = lo.max(k - 1.0);
                    } else {
                        hi = hi.min(k + 1.0);
                    }
                }
                if lo > hi {
                    break;
                }
            }
            if lo <= hi && hi >= 0.0 && lo <= last {
                // Saturating casts; widen outwards by rounding lo down and hi up.
                let lo = lo.max(0.0) as u32;
                let hi = (hi.min(last) + 0.999_999) as u32;
                out.push(SpanCandidate {
                    patch: line.patch,
                    tri: line.tri,
                    lo,
                    hi: hi.min(n.saturating_sub(1)),
                    frame: line.frame,
                    verdict: line.verdict,
                    verdict_before: line.verdict_before,
                    corners: line.corners,
                });
            }
        }
    }
}

impl FillContext<'_> {
    /// [`FillContext::resolve`] for texel `k` of a span, among the span's
    /// pruned candidates. They face the span's side and carry their frame
    /// and verdict ([`SpanPruner::prepare`]), so the texel tests what
    /// [`FillContext::hit`] would test, in the same order, with the same
    /// arithmetic: the same result.
    #[inline]
    fn resolve_in_span(&self, cands: &[SpanCandidate], k: u32, x: Vec3) -> Option<Hit> {
        cands.chunk_by(|a, b| a.patch == b.patch).find_map(|group| {
            let (c, bary) = self.span_holder(group, k, x)?;
            self.decide(c.patch, c.corners.located(c.tri, bary), c.verdict)
        })
    }

    /// Of one patch's span candidates (`group`), the triangle that holds
    /// texel `k` at `x`, with its barycentrics ([`FillContext::best_holder`]
    /// over the candidates whose interval holds the texel).
    #[inline]
    pub(super) fn span_holder<'c>(
        &self,
        group: &'c [SpanCandidate],
        k: u32,
        x: Vec3,
    ) -> Option<(&'c SpanCandidate, [f32; 3])> {
        let listed = group
            .iter()
            .filter(|c| c.lo <= k && k <= c.hi)
            .map(|c| (c, &c.frame));
        self.best_holder(listed, x)
    }
}

/// Triangle `j` of patch `i` in a per-patch verdict table
/// ([`Verdict::Test`] where it has none).
#[inline]
pub(super) fn verdict_in(table: &[Vec<Verdict>], i: u32, j: u32) -> Verdict {
    table
        .get(i as usize)
        .and_then(|v| v.get(j as usize))
        .copied()
        .unwrap_or(Verdict::Test)
}

/// Per patch triangle, [`Verdict::Eroded`] only where it is eroded both at
/// this frame's weights (`now`) and at every earlier frame's the fill
/// reads (`earlier`: the frame before's, then a transition's older ones),
/// and [`Verdict::Test`] elsewhere: the triangles
/// [`Candidates::without_eroded`] may drop when the fill also looks for
/// each texel's earlier holders.
pub fn eroded_at_every_frame(
    now: &[Vec<Verdict>],
    earlier: &[&[Vec<Verdict>]],
) -> Vec<Vec<Verdict>> {
    now.iter()
        .enumerate()
        .map(|(i, v)| {
            v.iter()
                .enumerate()
                .map(|(j, &n)| {
                    let all = n == Verdict::Eroded
                        && earlier.iter().all(|table| {
                            table.get(i).and_then(|b| b.get(j)).copied() == Some(Verdict::Eroded)
                        });
                    if all { Verdict::Eroded } else { Verdict::Test }
                })
                .collect()
        })
        .collect()
}

/// A span's candidates grouped by patch (in candidate order: oldest
/// first), each with the triangles whose interval holds texel `k`.
pub(crate) fn patch_groups(
    cands: &[SpanCandidate],
    k: u32,
) -> impl Iterator<Item = (u32, impl Iterator<Item = u32> + '_)> + '_ {
    cands.chunk_by(|a, b| a.patch == b.patch).map(move |group| {
        let tris = group
            .iter()
            .filter(move |c| c.lo <= k && k <= c.hi)
            .map(|c| c.tri);
        (group[0].patch, tris)
    })
}

/// Visits every chart texel of `band` in texel order, with the span's
/// candidates pruned by [`SpanPruner`]: the walk the lapped and the
/// blended fills share.
pub(crate) fn walk_band(
    ctx: &FillContext<'_>,
    atlas: &Atlas,
    candidates: &Candidates,
    band: &Band,
    mut visit: impl FnMut(&BandTexel, &[SpanCandidate]),
) {
    let mut cands = Vec::new();
    let mut pruner = SpanPruner::default();
    for_each_span(ctx.mesh, atlas, band, |span| {
        pruner.prepare(ctx, atlas, candidates.of(span.triangle), span);
        pruner.prune(
            ctx.tolerance,
            span.first_barycentrics(),
            span.len(),
            &mut cands,
        );
        for texel in span.texels() {
            visit(&texel, &cands);
        }
    });
}

/// Fills every chart texel of `atlas` (parallel by bands) and returns the
/// texels no patch covered, in texel order.
pub fn fill(
    ctx: &FillContext<'_>,
    atlas: &Atlas,
    candidates: &Candidates,
    out: &mut FillBuffers,
) -> Vec<Uncovered> {
    fill_with_transitions(ctx, atlas, candidates, out).0
}

/// [`fill`], and with a transition ([`FillContext::transition`] > 0) the
/// texels that show an earlier source beside their own, in texel order.
pub fn fill_with_transitions(
    ctx: &FillContext<'_>,
    atlas: &Atlas,
    candidates: &Candidates,
    out: &mut FillBuffers,
) -> (Vec<Uncovered>, Vec<Transition>) {
    let defer = out.defer_values;
    let transitions = std::sync::Mutex::new(Vec::new());
    let merged = fill_bands(atlas, out.rows(), |band, mut rows| {
        let mut uncovered = Vec::new();
        let mut fading = Vec::new();
        let track = !rows.renewal.is_empty();
        walk_band(ctx, atlas, candidates, band, |texel, cands| {
            let t = texel.t;
            let resolved = if track || ctx.transition > 0 {
                let (hit, renewal, earlier) = ctx.resolve_with_holders(cands, texel.k, texel.p);
                if track {
                    rows.renewal[t] = renewal;
                }
                if let Some(mut e) = earlier {
                    e.texel = (rows.base + t) as u32;
                    fading.push(e);
                }
                hit
            } else {
                ctx.resolve_in_span(cands, texel.k, texel.p)
            };
            match resolved {
                Some(hit) => {
                    if !defer {
                        let values = rows.values_of(t);
                        ctx.exemplar_of(hit.patch)
                            .sample_all(hit.uv.x, hit.uv.y, values);
                    }
                    rows.source[t] = ctx.patches[hit.patch as usize].id + 1;
                    rows.uv[t] = hit.uv;
                }
                None => {
                    rows.source[t] = UNCOVERED;
                    uncovered.push(Uncovered {
                        texel: (rows.base + t) as u32,
                        triangle: texel.triangle,
                        bary: texel.bary,
                    });
                }
            }
        });
        if !fading.is_empty() {
            // A poisoned lock only means another band panicked, which
            // the pool re-raises anyway.
            if let Ok(mut all) = transitions.lock() {
                all.extend(fading);
            }
        }
        BandResult {
            uncovered,
            used: Vec::new(),
        }
    });
    let mut transitions = transitions.into_inner().unwrap_or_default();
    transitions.sort_unstable_by_key(|e| e.texel);
    (merged.uncovered, transitions)
}
