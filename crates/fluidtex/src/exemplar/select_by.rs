//! Exemplars chosen by a simulation attribute (`--select-by temperature`):
//! each exemplar shows one range of a per-vertex scalar of the input mesh
//! (`--exemplar crust.png@0:0.4 --exemplar glow.png@0.4:1`), so the
//! texture follows the fluid's state and not only its motion.
//!
//! Two questions are asked of the ranges, and both are answered here so
//! that every method asks them the same way:
//!
//! - **Which exemplar does a new patch take** at a point where the
//!   attribute reads x? One whose range holds x. Where ranges overlap,
//!   the choice is a seeded draw whose probabilities blend across the
//!   overlap: each holding range weighs its depth, the distance from x to
//!   its nearer end, so at the edge of one range its exemplar's share is 0
//!   and it grows linearly into the range ([`SelectBy::probabilities`]).
//!   A value no range holds (colder than the coldest range, or a gap
//!   between ranges) goes to the nearest range: the texture never has a
//!   hole because the simulation left the ranges the user guessed.
//! - **Does a patch still match** where its vertices now lie? Its
//!   exemplar matches x when its range holds x, or when no range holds x
//!   and its range is among the nearest ([`SelectBy::matches`]). The
//!   methods lower what does not match (erosion: the vertex weight;
//!   lapped-rigid: the patch's fade), so the other texture takes over
//!   progressively. How fast follows how far the state has gone past the
//!   value where the exemplar stops matching ([`SelectBy::mismatch_drop`]):
//!   a point barely past it goes at `mismatch_rate`, one far past it up to
//!   1 + `mismatch_gain` times faster, so the texture keeps up with a
//!   fast change without flipping a slowly drifting surface at once.
//!
//! For the statistics, a value is *decisive* when it lies at least
//! [`DECISIVE_MARGIN`] of the ranges' span from every value where the
//! matching exemplars change ([`Decisive`]): there the state leaves no
//! doubt which texture belongs, and the texture must show it.
//!
//! Bounds are closed: at x = 0.4 both `@0:0.4` and `@0.4:1` hold, and a
//! patch of either matches there.

use crate::mesh::{Attribute, TriMesh};
use crate::surface::SurfacePoint;

/// The closed range `[lo, hi]` of the selecting attribute one exemplar
/// shows.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AttributeRange {
    pub lo: f32,
    pub hi: f32,
}

impl AttributeRange {
    /// A range with finite bounds, `lo ≤ hi`; the error says which rule
    /// failed.
    pub fn new(lo: f32, hi: f32) -> Result<AttributeRange, String> {
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(format!("range {lo}:{hi} needs two finite numbers"));
        }
        if lo > hi {
            return Err(format!(
                "range {lo}:{hi} has its low end above its high end"
            ));
        }
        Ok(AttributeRange { lo, hi })
    }

    pub fn holds(&self, x: f32) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// How far x lies from the range (0 inside).
    fn distance(&self, x: f32) -> f32 {
        (self.lo - x).max(x - self.hi).max(0.0)
    }

    /// How deep inside the range x lies: the distance to its nearer end.
    fn depth(&self, x: f32) -> f32 {
        (x - self.lo).min(self.hi - x).max(0.0)
    }
}

/// Default [`SelectBy::mismatch_rate`]: a vertex barely past its range
/// goes from whole to nothing in one second (24 frames), 5× slower than
/// the distortion's `erosion_rate`: a state that only just changed is a
/// slow process, not a tear. Farther past it, [`DEFAULT_MISMATCH_GAIN`]
/// speeds it up.
pub const DEFAULT_MISMATCH_RATE: f32 = 1.0;

/// Default [`SelectBy::mismatch_gain`]: 20, so a point 0.05 of the ranges'
/// span past the switch goes twice as fast as one at it, and a *decisive*
/// one ([`DECISIVE_MARGIN`], 0.2 past) five times as fast: in about 5
/// frames. With a constant rate (gain 0) a point cooling by 2 % of the
/// span per frame is 0.48 past the split when its weight reaches 0, and
/// the agreement on decisive points of a cooling blob falls to 0.05; with
/// 20 the weight reaches 0 about 0.17 past (0.19 at 2.5 % per frame),
/// before the point is decisive, and the blob keeps at least 0.998 on
/// every frame up to 4 % per frame (`methods::state_blob_tests`). 10
/// falls short at 3 %; 40 adds margin past 4 % but switches more of
/// `lava` in one frame (24 % against 21 %).
pub const DEFAULT_MISMATCH_GAIN: f32 = 20.0;

/// Largest [`SelectBy::mismatch_gain`]: at 1000 a point 0.001 of the span
/// past the switch already goes twice as fast; beyond, the gain only makes
/// every mismatch instant.
pub const MAX_MISMATCH_GAIN: f32 = 1000.0;

/// Default margin of the decisive points ([`Decisive`]), a share of the
/// ranges' span ([`SelectBy::span`]): 0.2, a value the state must cross
/// for 10 frames at 2 % of the span per frame.
pub const DECISIVE_MARGIN: f32 = 0.2;

/// The attribute that selects the exemplars and each exemplar's range.
#[derive(Clone, Debug, PartialEq)]
pub struct SelectBy {
    /// Name of the per-vertex scalar on the input mesh.
    pub attribute: String,
    /// One range per exemplar, in exemplar order.
    pub ranges: Vec<AttributeRange>,
    /// How fast what no longer matches goes, per second of animation,
    /// where the state has only just left the exemplar's range \[1]
    /// ([`DEFAULT_MISMATCH_RATE`]): the most an erosion vertex weight
    /// falls, and the fade a lapped-rigid patch loses, per second.
    pub mismatch_rate: f32,
    /// How much faster a point far past the range goes \[20]
    /// ([`DEFAULT_MISMATCH_GAIN`]): the rate is `mismatch_rate` · (1 +
    /// gain · d), d the distance past the switch as a share of the ranges'
    /// span ([`SelectBy::mismatch_drop`]). 0: the constant rate.
    pub mismatch_gain: f32,
}

impl SelectBy {
    pub fn new(attribute: impl Into<String>, ranges: Vec<AttributeRange>) -> SelectBy {
        SelectBy {
            attribute: attribute.into(),
            ranges,
            mismatch_rate: DEFAULT_MISMATCH_RATE,
            mismatch_gain: DEFAULT_MISMATCH_GAIN,
        }
    }

    /// The same selection with another mismatch rate, which must be a
    /// positive number (at most 1000 per second: a weight falls in one
    /// frame well before that).
    pub fn with_mismatch_rate(mut self, rate: f32) -> Result<SelectBy, String> {
        if !(rate.is_finite() && rate > 0.0 && rate <= 1000.0) {
            return Err(format!(
                "mismatch_rate = {rate} must be a positive number of at most 1000 per second"
            ));
        }
        self.mismatch_rate = rate;
        Ok(self)
    }

    /// The same selection with another mismatch gain, from 0 (a constant
    /// rate) to [`MAX_MISMATCH_GAIN`].
    pub fn with_mismatch_gain(mut self, gain: f32) -> Result<SelectBy, String> {
        if !(gain.is_finite() && (0.0..=MAX_MISMATCH_GAIN).contains(&gain)) {
            return Err(format!(
                "mismatch_gain = {gain} must be a number from 0 (a constant rate) to \
                 {MAX_MISMATCH_GAIN}"
            ));
        }
        self.mismatch_gain = gain;
        Ok(self)
    }

    /// The span of the ranges, from the lowest low end to the highest high
    /// end: the scale of [`SelectBy::mismatch_gain`] and of the decisive
    /// margin (0 without ranges or with one point for all).
    pub fn span(&self) -> f32 {
        let lo = self
            .ranges
            .iter()
            .map(|r| r.lo)
            .fold(f32::INFINITY, f32::min);
        let hi = (self.ranges.iter().map(|r| r.hi)).fold(f32::NEG_INFINITY, f32::max);
        if hi > lo { hi - lo } else { 0.0 }
    }

    /// The values where the set of matching exemplars can change: every
    /// range end, and every midpoint between two ends (a gap between
    /// ranges is split at its middle). The set is constant between them.
    fn candidates(&self) -> Vec<f32> {
        let ends: Vec<f32> = self.ranges.iter().flat_map(|r| [r.lo, r.hi]).collect();
        let mut c = ends.clone();
        for (i, a) in ends.iter().enumerate() {
            c.extend(ends[i + 1..].iter().map(|b| 0.5 * (a + b)));
        }
        c.sort_by(f32::total_cmp);
        c.dedup();
        c
    }

    /// How far x lies past the value where exemplar `exemplar` stops
    /// matching: its distance to the nearest value the exemplar matches
    /// (a range end, or the middle of a gap), `None` where it matches. An
    /// exemplar without a range is the whole span away.
    pub fn mismatch(&self, exemplar: u32, x: f32) -> Option<f32> {
        if self.matches(exemplar, x) {
            return None;
        }
        if exemplar as usize >= self.ranges.len() {
            return Some(self.span());
        }
        // The matching set is a union of closed intervals whose ends are
        // candidates, so the nearest matching value is one of them.
        let nearest = (self.candidates().into_iter())
            .filter(|&c| self.matches(exemplar, c))
            .map(|c| (c - x).abs())
            .fold(f32::INFINITY, f32::min);
        Some(if nearest.is_finite() { nearest } else { 0.0 })
    }

    /// The weight (erosion) or fade (lapped-rigid) a point of exemplar
    /// `exemplar` where the attribute reads x loses in `dt` seconds:
    /// `mismatch_rate` · dt · (1 + `mismatch_gain` · d / span), d =
    /// [`SelectBy::mismatch`]; `None` where the exemplar matches. A state
    /// that has just crossed changes the texture slowly, so a surface that
    /// drifts across a bound switches over many frames; one far past it
    /// changes it quickly, so the texture does not lag a fast change.
    pub fn mismatch_drop(&self, exemplar: u32, x: f32, dt: f32) -> Option<f32> {
        let d = self.mismatch(exemplar, x)?;
        let span = self.span();
        let past = if span > 0.0 { (d / span).min(1.0) } else { 0.0 };
        Some(self.mismatch_rate * dt * (1.0 + self.mismatch_gain * past))
    }

    /// The decisive points of this selection with a margin of `margin` of
    /// the span ([`DECISIVE_MARGIN`] by default).
    pub fn decisive(&self, margin: f32) -> Decisive {
        let c = self.candidates();
        let set = |x: f32| {
            let mut s = Vec::new();
            self.deciding(x, |e, _| s.push(e));
            s
        };
        let reach = self.span().max(1.0);
        let splits = (0..c.len())
            .filter(|&i| {
                let left = if i > 0 {
                    0.5 * (c[i - 1] + c[i])
                } else {
                    c[i] - reach
                };
                let right = c.get(i + 1).map_or(c[i] + reach, |n| 0.5 * (c[i] + n));
                let here = set(c[i]);
                set(left) != here || set(right) != here
            })
            .map(|i| c[i])
            .collect();
        Decisive {
            splits,
            margin: margin * self.span(),
        }
    }

    /// The ranges that decide at x: those holding x, or, when none does,
    /// those nearest to it (ties all kept). Calls `f(exemplar, range)`.
    fn deciding(&self, x: f32, mut f: impl FnMut(usize, &AttributeRange)) {
        let held = self.ranges.iter().any(|r| r.holds(x));
        let nearest = if held {
            0.0
        } else {
            self.ranges
                .iter()
                .map(|r| r.distance(x))
                .fold(f32::INFINITY, f32::min)
        };
        for (e, r) in self.ranges.iter().enumerate() {
            if (held && r.holds(x)) || (!held && r.distance(x) == nearest) {
                f(e, r);
            }
        }
    }

    /// Whether exemplar `exemplar` matches the attribute value `x`. A NaN
    /// (a point with no value) matches everything: nothing is eroded for
    /// want of a value.
    pub fn matches(&self, exemplar: u32, x: f32) -> bool {
        if x.is_nan() {
            return true;
        }
        let mut hit = false;
        self.deciding(x, |e, _| hit |= e == exemplar as usize);
        hit
    }

    /// Per exemplar: whether its range holds the whole span of `values`,
    /// so that it matches at every point of the surface and no point of
    /// its patches needs a test this frame (most frames of a state change
    /// are before or after it).
    pub fn matching_everywhere(&self, values: &[f32]) -> Vec<bool> {
        let (lo, hi) = values
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &x| {
                (lo.min(x), hi.max(x))
            });
        self.ranges
            .iter()
            .map(|r| values.is_empty() || (r.holds(lo) && r.holds(hi)))
            .collect()
    }

    /// The probability of each exemplar for a new patch where the
    /// attribute reads x: among the deciding ranges, proportional to their
    /// depth at x, equal where every depth is 0 (a range's edge, a point
    /// range, or x outside all ranges). Sums to 1.
    pub fn probabilities(&self, x: f32) -> Vec<f32> {
        let mut p = vec![0.0f32; self.ranges.len()];
        if x.is_nan() {
            let n = p.len().max(1) as f32;
            p.iter_mut().for_each(|v| *v = 1.0 / n);
            return p;
        }
        let mut count = 0usize;
        let mut total = 0.0f32;
        self.deciding(x, |e, r| {
            p[e] = r.depth(x);
            total += p[e];
            count += 1;
        });
        if total > 0.0 {
            p.iter_mut().for_each(|v| *v /= total);
        } else {
            let mut deciding = vec![false; p.len()];
            self.deciding(x, |e, _| deciding[e] = true);
            for (v, d) in p.iter_mut().zip(deciding) {
                *v = if d { 1.0 / count as f32 } else { 0.0 };
            }
        }
        p
    }

    /// The exemplar a uniform draw `bits` (64 random bits) picks where the
    /// attribute reads x.
    pub fn draw(&self, x: f32, bits: u64) -> u32 {
        let p = self.probabilities(x);
        let u = (bits >> 40) as f32 / (1u64 << 24) as f32;
        let mut acc = 0.0;
        let mut last = 0;
        for (i, w) in p.iter().enumerate() {
            if *w > 0.0 {
                acc += w;
                last = i;
                if u < acc {
                    return i as u32;
                }
            }
        }
        last as u32
    }

    /// The attribute's per-vertex values on `mesh`, when it has them as
    /// one scalar per vertex.
    pub fn values<'m>(&self, mesh: &'m TriMesh) -> Option<&'m [f32]> {
        match mesh.attributes.get(&self.attribute) {
            Some(Attribute::Scalar(v)) if v.len() == mesh.vertex_count() => Some(v),
            _ => None,
        }
    }

    /// The attribute at a surface point (linear over its triangle); NaN
    /// where the mesh has no value there.
    pub fn value_at(values: &[f32], mesh: &TriMesh, at: SurfacePoint) -> f32 {
        let Some(t) = mesh.triangles.get(at.triangle as usize) else {
            return f32::NAN;
        };
        let mut x = 0.0;
        for (k, &v) in t.iter().enumerate() {
            let Some(&value) = values.get(v as usize) else {
                return f32::NAN;
            };
            x += at.bary[k] * value;
        }
        x
    }

    /// Checks that `mesh` (frame `frame`) carries the attribute, one
    /// number per vertex; the error names the frame, the attribute and
    /// what the mesh has instead.
    pub fn check_mesh(&self, mesh: &TriMesh, frame: i32) -> Result<(), String> {
        if mesh.is_empty() {
            return Ok(());
        }
        match mesh.attributes.get(&self.attribute) {
            Some(Attribute::Scalar(v)) => match v.iter().position(|x| !x.is_finite()) {
                Some(vertex) => Err(format!(
                    "frame {frame}: vertex {vertex} has {} = {} (--select-by needs finite values)",
                    self.attribute, v[vertex]
                )),
                None => Ok(()),
            },
            Some(_) => Err(format!(
                "frame {frame}: --select-by {}: the attribute must be one number per vertex",
                self.attribute
            )),
            None => {
                let have: Vec<&str> = mesh.attributes.keys().map(String::as_str).collect();
                Err(format!(
                    "frame {frame}: --select-by {}: the mesh has no per-vertex {} (it has: {})",
                    self.attribute,
                    self.attribute,
                    if have.is_empty() {
                        "no attribute".to_string()
                    } else {
                        have.join(", ")
                    }
                ))
            }
        }
    }
}

/// Which attribute values are *decisive* for a selection
/// ([`SelectBy::decisive`]): those at least `margin` from every split, a
/// value where the set of matching exemplars changes (the shared bound of
/// two ranges, the middle of a gap, the ends of an overlap). Ends that no
/// other range meets are no split: past them the same exemplar is the
/// nearest. Near a split the shown exemplar may lag the state for a while
/// by design; at a decisive point it has had the time to follow.
#[derive(Clone, Debug, PartialEq)]
pub struct Decisive {
    /// The splits, ascending.
    pub splits: Vec<f32>,
    /// In attribute units.
    pub margin: f32,
}

impl Decisive {
    /// Whether x is decisive (NaN never is).
    pub fn holds(&self, x: f32) -> bool {
        !x.is_nan() && self.splits.iter().all(|s| (x - s).abs() >= self.margin)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn ranges(r: &[(f32, f32)]) -> SelectBy {
        SelectBy::new(
            "temperature",
            r.iter()
                .map(|&(lo, hi)| AttributeRange::new(lo, hi).unwrap())
                .collect(),
        )
    }

    #[test]
    fn bounds_are_closed_and_both_sides_of_a_shared_bound_match() {
        let s = ranges(&[(0.0, 0.4), (0.4, 1.0)]);
        assert!(s.matches(0, 0.0) && s.matches(0, 0.4) && !s.matches(0, 0.41));
        assert!(s.matches(1, 0.4) && s.matches(1, 1.0) && !s.matches(1, 0.39));
        // At the shared bound both have depth 0: an even draw.
        assert_eq!(s.probabilities(0.4), vec![0.5, 0.5]);
        assert_eq!(s.probabilities(0.2), vec![1.0, 0.0]);
        assert_eq!(s.probabilities(0.7), vec![0.0, 1.0]);
    }

    #[test]
    fn overlaps_blend_linearly_by_depth() {
        let s = ranges(&[(0.0, 0.5), (0.4, 1.0)]);
        let p = s.probabilities(0.42);
        // Depths 0.08 and 0.02.
        assert!(
            (p[0] - 0.8).abs() < 1e-5 && (p[1] - 0.2).abs() < 1e-5,
            "{p:?}"
        );
        let mid = s.probabilities(0.45);
        assert!((mid[0] - 0.5).abs() < 1e-5, "{mid:?}");
        assert!(s.matches(0, 0.45) && s.matches(1, 0.45));
        // The draw follows the probabilities: u just below 0.8 picks 0, above picks 1.
        let bits = |u: f64| ((u * (1u64 << 24) as f64) as u64) << 40;
        assert_eq!(s.draw(0.42, bits(0.79)), 0);
        assert_eq!(s.draw(0.42, bits(0.81)), 1);
    }

    #[test]
    fn values_outside_every_range_go_to_the_nearest() {
        let s = ranges(&[(0.0, 0.3), (0.6, 1.0)]);
        // Below, above, and in the gap nearer to either side.
        assert_eq!(s.probabilities(-2.0), vec![1.0, 0.0]);
        assert_eq!(s.probabilities(5.0), vec![0.0, 1.0]);
        assert_eq!(s.probabilities(0.35), vec![1.0, 0.0]);
        assert_eq!(s.probabilities(0.55), vec![0.0, 1.0]);
        assert!(s.matches(0, 0.35) && !s.matches(1, 0.35));
        // Exactly between: both nearest, both match, an even draw.
        let s = ranges(&[(0.0, 0.25), (0.75, 1.0)]);
        assert_eq!(s.probabilities(0.5), vec![0.5, 0.5]);
        assert!(s.matches(0, 0.5) && s.matches(1, 0.5));
        // No value: nothing mismatches.
        assert!(s.matches(0, f32::NAN) && s.matches(1, f32::NAN));
    }

    #[test]
    fn probabilities_sum_to_one_on_seeded_random_cases() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(40);
        for _ in 0..500 {
            let n = rng.random_range(1..5);
            let r: Vec<(f32, f32)> = (0..n)
                .map(|_| {
                    let a: f32 = rng.random_range(-1.0..2.0);
                    let b: f32 = rng.random_range(-1.0..2.0);
                    (a.min(b), a.max(b))
                })
                .collect();
            let s = ranges(&r);
            let x: f32 = rng.random_range(-2.0..3.0);
            let p = s.probabilities(x);
            let sum: f32 = p.iter().sum();
            assert!((sum - 1.0).abs() < 1e-4, "{r:?} at {x}: {p:?}");
            // Every exemplar a draw can give matches x.
            for (e, w) in p.iter().enumerate() {
                if *w > 0.0 {
                    assert!(s.matches(e as u32, x), "{r:?} at {x}: {e} drawn, no match");
                }
            }
            let drawn = s.draw(x, rng.random());
            assert!(s.matches(drawn, x));
        }
    }

    #[test]
    fn an_exemplar_matches_everywhere_only_when_its_range_holds_every_value() {
        let s = ranges(&[(0.0, 0.5), (0.5, 1.0)]);
        assert_eq!(s.matching_everywhere(&[0.6, 0.9, 1.0]), vec![false, true]);
        assert_eq!(s.matching_everywhere(&[0.1, 0.5]), vec![true, false]);
        assert_eq!(s.matching_everywhere(&[0.4, 0.6]), vec![false, false]);
        assert_eq!(s.matching_everywhere(&[]), vec![true, true]);
        // Every value of a span a range holds matches (seeded cases).
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(42);
        for _ in 0..200 {
            let v: Vec<f32> = (0..5).map(|_| rng.random_range(-0.2..1.2)).collect();
            for (e, all) in s.matching_everywhere(&v).into_iter().enumerate() {
                if all {
                    assert!(v.iter().all(|&x| s.matches(e as u32, x)), "{v:?}");
                }
            }
        }
    }

    #[test]
    fn bad_mismatch_rates_are_refused() {
        let s = ranges(&[(0.0, 1.0)]);
        assert_eq!(s.mismatch_rate, DEFAULT_MISMATCH_RATE);
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY, 1001.0] {
            assert!(s.clone().with_mismatch_rate(bad).is_err(), "{bad}");
        }
        assert_eq!(s.with_mismatch_rate(2.5).unwrap().mismatch_rate, 2.5);
    }

    #[test]
    fn the_mismatch_is_the_distance_to_the_nearest_matching_value() {
        let s = ranges(&[(0.0, 0.5), (0.5, 1.0)]);
        assert_eq!(s.span(), 1.0);
        assert_eq!(s.mismatch(1, 0.6), None);
        assert_eq!(s.mismatch(1, 0.5), None);
        assert!((s.mismatch(1, 0.3).unwrap() - 0.2).abs() < 1e-6);
        assert!((s.mismatch(0, 0.9).unwrap() - 0.4).abs() < 1e-6);
        // Past the outer ends the nearest range still matches.
        assert_eq!(s.mismatch(0, -3.0), None);
        assert!((s.mismatch(1, -3.0).unwrap() - 3.5).abs() < 1e-6);
        // A gap switches at its middle (0.45): 0.35 is 0.1 past it for
        // the upper exemplar, not 0.25 (its distance to the range).
        let g = ranges(&[(0.0, 0.3), (0.6, 1.0)]);
        assert!((g.mismatch(1, 0.35).unwrap() - 0.1).abs() < 1e-6);
        assert!((g.mismatch(0, 0.5).unwrap() - 0.05).abs() < 1e-6);
        assert_eq!(g.mismatch(0, 0.45), None);
        // An exemplar without a range is the span away; NaN matches.
        assert_eq!(s.mismatch(5, 0.3), Some(1.0));
        assert_eq!(s.mismatch(1, f32::NAN), None);
    }

    #[test]
    fn the_drop_grows_with_the_distance_past_the_range() {
        let dt = 1.0 / 24.0;
        let s = ranges(&[(0.0, 0.5), (0.5, 1.0)]);
        assert_eq!(s.mismatch_gain, DEFAULT_MISMATCH_GAIN);
        assert_eq!(s.mismatch_drop(1, 0.7, dt), None);
        // Just past: the rate; 0.2 past: 1 + 20 · 0.2 = 5 times the rate.
        let at = |x: f32| s.mismatch_drop(1, x, dt).unwrap();
        assert!((at(0.5 - 1e-6) - dt).abs() < 1e-6, "{}", at(0.5 - 1e-6));
        assert!((at(0.3) - 5.0 * dt).abs() < 1e-5, "{}", at(0.3));
        // Monotonic in the distance, and capped at 1 + gain.
        let mut last = 0.0;
        for k in 1..=60 {
            let d = at(0.5 - k as f32 * 0.01);
            assert!(d >= last, "{k}");
            last = d;
        }
        assert!(at(-40.0) <= (1.0 + s.mismatch_gain) * dt + 1e-6);
        // Gain 0: the constant rate of before, and the rate scales it.
        let flat = s.clone().with_mismatch_gain(0.0).unwrap();
        assert_eq!(flat.mismatch_drop(1, 0.0, dt), Some(dt));
        let fast = flat.with_mismatch_rate(4.0).unwrap();
        assert_eq!(fast.mismatch_drop(1, 0.2, dt), Some(4.0 * dt));
        // Bad gains are refused with the key named.
        for bad in [-0.1, f32::NAN, f32::INFINITY, MAX_MISMATCH_GAIN + 1.0] {
            let e = s.clone().with_mismatch_gain(bad).unwrap_err();
            assert!(e.contains("mismatch_gain"), "{e}");
        }
    }

    #[test]
    fn decisive_values_are_clear_of_every_split() {
        let s = ranges(&[(0.0, 0.5), (0.5, 1.0)]);
        let d = s.decisive(DECISIVE_MARGIN);
        // The shared bound splits; the outer ends do not.
        assert_eq!(d.splits, vec![0.5]);
        assert!(d.holds(0.29) && d.holds(0.71) && d.holds(0.0) && d.holds(1.0) && d.holds(-5.0));
        assert!(!d.holds(0.31) && !d.holds(0.69) && !d.holds(0.5) && !d.holds(f32::NAN));
        // A gap splits at its middle, an overlap at both of its ends.
        let near = |a: Vec<f32>, b: &[f32]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6)
        };
        let gap = ranges(&[(0.0, 0.3), (0.6, 1.0)]).decisive(0.1).splits;
        assert!(near(gap.clone(), &[0.45]), "{gap:?}");
        let overlap = ranges(&[(0.0, 0.5), (0.4, 1.0)]).decisive(0.1).splits;
        assert!(near(overlap.clone(), &[0.4, 0.5]), "{overlap:?}");
        // One range, or ranges that match alike everywhere: no split.
        assert!(ranges(&[(0.0, 1.0)]).decisive(0.2).splits.is_empty());
        assert!(
            ranges(&[(0.2, 0.8), (0.2, 0.8)])
                .decisive(0.2)
                .splits
                .is_empty()
        );
        // Seeded cases: the matching set is the same over the whole
        // margin around a decisive value.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(43);
        let set = |s: &SelectBy, x: f32| {
            (0..s.ranges.len() as u32)
                .map(|e| s.matches(e, x))
                .collect::<Vec<_>>()
        };
        for _ in 0..200 {
            let r: Vec<(f32, f32)> = (0..rng.random_range(1..4))
                .map(|_| {
                    let (a, b): (f32, f32) = (rng.random(), rng.random());
                    (a.min(b), a.max(b))
                })
                .collect();
            let s = ranges(&r);
            let d = s.decisive(0.1);
            for _ in 0..20 {
                let x: f32 = rng.random_range(-0.5..1.5);
                if d.holds(x) {
                    for k in -10..=10 {
                        let y = x + d.margin * 0.099 * k as f32;
                        assert_eq!(set(&s, x), set(&s, y), "{r:?}: {x} vs {y}");
                    }
                }
            }
        }
    }

    #[test]
    fn bad_ranges_are_refused() {
        assert!(
            AttributeRange::new(0.5, 0.1)
                .unwrap_err()
                .contains("low end above")
        );
        assert!(AttributeRange::new(f32::NAN, 1.0).is_err());
        assert!(AttributeRange::new(0.0, f32::INFINITY).is_err());
        assert!(AttributeRange::new(0.3, 0.3).is_ok());
    }

    #[test]
    fn the_mesh_check_names_the_frame_and_the_attribute() {
        let s = ranges(&[(0.0, 0.5), (0.5, 1.0)]);
        let mut mesh = TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]);
        let e = s.check_mesh(&mesh, 7).unwrap_err();
        assert!(
            e.contains("frame 7") && e.contains("no per-vertex temperature"),
            "{e}"
        );
        mesh.attributes.insert(
            "temperature".into(),
            Attribute::Scalar(vec![0.1, f32::NAN, 0.2]),
        );
        let e = s.check_mesh(&mesh, 3).unwrap_err();
        assert!(e.contains("vertex 1") && e.contains("temperature"), "{e}");
        mesh.attributes
            .insert("temperature".into(), Attribute::Scalar(vec![0.1, 0.9, 0.2]));
        assert!(s.check_mesh(&mesh, 3).is_ok());
        let at = SurfacePoint::new(0, [0.25, 0.5, 0.25]);
        let x = SelectBy::value_at(s.values(&mesh).unwrap(), &mesh, at);
        assert!((x - (0.025 + 0.45 + 0.05)).abs() < 1e-6, "{x}");
    }
}
