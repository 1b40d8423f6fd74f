//! Refinement of a patch's stretched triangles ([`Patch::refine`]): edges
//! longer than the split length are split at their midpoint, projected
//! onto the surface, within the bounds that keep a patch's triangles
//! following the surface it covers rather than its history.

use glam::Vec3;

use super::super::distortion::distortion;
use super::{MAX_SPLIT_ROUNDS, Patch, PatchShape};

/// The distortion bound of [`Patch::refine_within`]: triangles whose δ_t,
/// between rest shape (rest × `exemplar_size`) and current positions, is
/// past `max_delta` are never split.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Freeze {
    pub exemplar_size: f32,
    pub max_delta: f32,
}

impl Freeze {
    /// The bound of `shape` ([`PatchShape::split_distortion`]); `None`
    /// without one.
    pub fn of(shape: &PatchShape) -> Option<Freeze> {
        shape.split_distortion.is_finite().then_some(Freeze {
            exemplar_size: shape.exemplar_size,
            max_delta: shape.split_distortion,
        })
    }
}

/// Bytes a long edge side found by [`Patch::refine`] may add: its entry
/// in the round's list (16), and, split, a vertex (position, rest, pin and
/// up to three weights: 33) and two triangles with their per-triangle
/// tables (2 × 18), doubled for the vectors' spare capacity.
pub const SPLIT_BYTES: usize = 16 + 2 * (33 + 36);

impl Patch {
    /// Splits every edge longer than `max_length` at its midpoint, until
    /// none is left or [`MAX_SPLIT_ROUNDS`] rounds have run; returns whether
    /// anything was split. Not in the paper: a stretched patch triangle is a
    /// long chord of the curved fluid surface, its middle far from the
    /// surface, so texels there fail to locate in it and its coverage
    /// flickers from frame to frame as the surface is re-meshed. The new
    /// vertex goes to `project(midpoint)` (`None`: the edge is left whole,
    /// as when it spans a gap of the surface); its rest coordinates are the
    /// midpoint of the edge's, so the texture carried by the patch is
    /// unchanged up to that projection. Edges are split longest first, and
    /// each round splits only edges whose triangles no other split of the
    /// round touched, so the result does not depend on any hash order.
    ///
    /// An edge longer than `max_stretch` times its rest length in world
    /// units (rest × S) is left whole (`f32::INFINITY`: no bound): its
    /// triangles are past δ_max (Q_T = 0), eroding for good, and splitting
    /// them would multiply exactly the triangles a violent flow tears apart
    /// (each round quadruples them, up to 4⁶ per triangle in one frame).
    /// With the bound, halving keeps an edge's stretch, so an edge is split
    /// about log2(max_stretch · rest / max_length) times over its whole
    /// life at most, and a patch holds a bounded multiple of the triangles
    /// it was made with.
    pub fn refine(
        &mut self,
        max_length: f32,
        max_stretch: f32,
        project: impl Fn(Vec3) -> Option<Vec3>,
    ) -> bool {
        self.refine_within(max_length, max_stretch, None, project, &|_| true)
    }

    /// [`Patch::refine`], leaving whole the triangles `freeze` says are
    /// distorted beyond use (and their edges, so the mesh stays without
    /// T-junctions), and counting the bytes each round may add with `grow`
    /// before it splits (a frame's memory budget,
    /// [`crate::methods::budget`]); where `grow` refuses, the splitting
    /// stops there. A round quadruples the patch at most, so a patch never
    /// grows past its budget by more than one round.
    ///
    /// Why the distortion bound: where a method keeps every triangle (the
    /// baselines), the edge bound of `max_stretch` does not hold a patch
    /// to the surface it covers. Under shear, midpoint splits turn a
    /// triangle into needles whose edges along the shear are each short
    /// enough or within the stretch, while the needles keep halving in
    /// rest area: on a sheared sphere at a large radius the first frame's
    /// patches grew from 13 to 240 triangles per surface triangle in 32
    /// frames with edges past 2·δ_max left whole. A triangle's distortion
    /// δ_t is kept by its children (the same affine map, up to the
    /// projection), so a triangle past the bound has no descendants, and
    /// one within it holds a bounded multiple of its rest area in
    /// split-length triangles.
    pub fn refine_within(
        &mut self,
        max_length: f32,
        max_stretch: f32,
        freeze: Option<Freeze>,
        project: impl Fn(Vec3) -> Option<Vec3>,
        grow: &dyn Fn(usize) -> bool,
    ) -> bool {
        if max_length <= 0.0 || !max_length.is_finite() {
            return false;
        }
        let mut frozen = self.frozen(freeze);
        let is_frozen = |frozen: &[bool], k: u32| frozen.get(k as usize).copied().unwrap_or(false);
        let limit = max_length * max_length;
        let stretch2 = max_stretch * max_stretch;
        let mut changed = false;
        for _ in 0..MAX_SPLIT_ROUNDS {
            let mut long = self.long_sides(limit, stretch2);
            if long.is_empty() || !grow(long.len() * SPLIT_BYTES) {
                break;
            }
            long.sort_unstable_by(|x, y| {
                y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2))
            });
            let mut touched = vec![false; self.triangles.len()];
            let mut split_any = false;
            let mut i = 0;
            while i < long.len() {
                let edge = long[i].1;
                let mut j = i;
                while j < long.len() && long[j].1 == edge {
                    j += 1;
                }
                // Every triangle holding this edge, not only the long sides found.
                let holders: Vec<u32> = long[i..j].iter().map(|x| x.2).collect();
                i = j;
                if holders
                    .iter()
                    .any(|&k| touched[k as usize] || is_frozen(&frozen, k))
                {
                    continue;
                }
                let [a, b] = edge;
                let (pa, pb) = (self.positions[a as usize], self.positions[b as usize]);
                let Some(m) = project((pa + pb) * 0.5) else {
                    continue;
                };
                let mid = self.positions.len() as u32;
                self.positions.push(m);
                self.rest
                    .push((self.rest[a as usize] + self.rest[b as usize]) * 0.5);
                self.pinned
                    .push(self.pinned[a as usize] && self.pinned[b as usize]);
                let n = self.positions.len();
                for weights in self.weights_mut() {
                    if weights.len() + 1 == n {
                        let w = 0.5 * (weights[a as usize] + weights[b as usize]);
                        weights.push(w);
                    }
                }
                for k in holders {
                    touched[k as usize] = true;
                    let t = self.triangles[k as usize];
                    // Rotate so the split edge is (t0, t1) in the triangle's own order.
                    let r = (0..3)
                        .find(|&e| {
                            let (u, v) = (t[e], t[(e + 1) % 3]);
                            [u.min(v), u.max(v)] == edge
                        })
                        .unwrap_or(0);
                    let (u, v, w) = (t[r], t[(r + 1) % 3], t[(r + 2) % 3]);
                    self.triangles[k as usize] = [u, mid, w];
                    self.triangles.push([mid, v, w]);
                    touched.push(true);
                    if !frozen.is_empty() {
                        frozen.push(false);
                    }
                }
                split_any = true;
            }
            if !split_any {
                break;
            }
            changed = true;
        }
        changed
    }

    /// Per triangle: distorted beyond use by `freeze` at the positions a
    /// refinement starts from (children of a split start unfrozen, as
    /// their parent was); empty without a bound.
    fn frozen(&self, freeze: Option<Freeze>) -> Vec<bool> {
        let Some(f) = freeze else {
            return Vec::new();
        };
        (self.triangles.iter())
            .map(|t| {
                let rest = t.map(|v| self.rest[v as usize] * f.exemplar_size);
                let q = t.map(|v| self.positions[v as usize]);
                distortion(rest, q).delta > f64::from(f.max_delta)
            })
            .collect()
    }

    /// (squared length, edge, triangle) for every edge side longer than
    /// √`limit` and stretched at most √`stretch2` times its rest length.
    fn long_sides(&self, limit: f32, stretch2: f32) -> Vec<(f32, [u32; 2], u32)> {
        let mut long = Vec::new();
        for (k, t) in self.triangles.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                let l = self.positions[a as usize].distance_squared(self.positions[b as usize]);
                let rest = self.rest[a as usize].distance_squared(self.rest[b as usize]);
                // NaN (no bound, zero rest length) splits as before.
                let bound = stretch2 * rest;
                if l > limit && (l <= bound || bound.is_nan()) {
                    long.push((l, [a.min(b), a.max(b)], k as u32));
                }
            }
        }
        long
    }
}
