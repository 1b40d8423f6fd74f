//! Several exemplars per surface in the erosion method (and the baselines
//! built from its patches): each [`Patch`] carries the index of its
//! exemplar ([`Patch::exemplar`]), chosen at creation by the run's
//! [`ExemplarSet`] strategy ([`crate::exemplar::set`]); the fill reads
//! every channel, the feature map and the erosion normaliser of that
//! exemplar ([`MultiFill`]).
//!
//! The single-exemplar path does not come here at all: its fill context has
//! no [`MultiFill`], and its saved state is byte for byte what it was
//! before exemplar ids existed. With several exemplars the ids (and where
//! a region image lies) are saved *after* that state ([`MultiState`]), so
//! a resumed run continues with the same choices.

use std::sync::Arc;

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use super::erode::ErosionTest;
use super::feature_levels::{FeatureLevelSampler, FeatureLevels};
use super::patch::Patch;
use crate::exemplar::set::{Chooser, Coverage, RegionBox, SelectBy};
use crate::exemplar::{Exemplar, ExemplarSelect, ExemplarSet};
use crate::mesh::TriMesh;
use crate::methods::MethodError;
use crate::provenance::{SOURCE_OUTSIDE as OUTSIDE, SOURCE_UNCOVERED as UNCOVERED};
use crate::surface::SurfacePoint;
use crate::surface::bvh::SurfaceIndex;

/// The exemplars of a multi-exemplar (or animated) run and what the
/// erosion derives from each slot (feature-map levels, erosion test): a
/// patch stores its entry ([`Patch::exemplar`]) and reads the slot of the
/// frame shown ([`Multi::slot`]).
pub struct Multi {
    pub set: Arc<ExemplarSet>,
    /// One per slot ([`ExemplarSet::exemplars`]).
    pub levels: Vec<FeatureLevels>,
    /// One per slot, built with the single test (r/S known).
    pub tests: Vec<ErosionTest>,
    /// Where the region image lies, resolved on the first non-empty frame.
    pub region: Option<RegionBox>,
    /// The run's seed (the patches' phases) and the fluid frame being
    /// textured: which frame of an animated exemplar a patch shows.
    pub seed: u64,
    pub frame: i32,
}

/// What the fill reads per patch exemplar.
pub struct MultiFill<'a> {
    pub exemplars: &'a [Arc<Exemplar>],
    pub features: Vec<FeatureLevelSampler<'a>>,
    pub tests: &'a [ErosionTest],
    /// Per patch id, for an animated set: the slot shown this frame and
    /// the feature slot, looked up once per frame rather than hashed per
    /// texel. Empty without animation (slot = entry).
    slots: Vec<u32>,
    feature_slots: Vec<u32>,
    multi: &'a Multi,
}

impl MultiFill<'_> {
    /// The slot patch `p` reads this frame.
    #[inline]
    pub fn slot(&self, p: &Patch) -> usize {
        match self.slots.get(p.id as usize) {
            Some(&s) => s as usize,
            // A patch created after the table (the update's): computed.
            None => self.multi.slot(p) as usize,
        }
    }

    /// The slot whose feature map and erosion test shape patch `p`
    /// ([`ExemplarSet::feature_slot`]).
    #[inline]
    pub fn feature_slot(&self, p: &Patch) -> usize {
        match self.feature_slots.get(p.id as usize) {
            Some(&s) => s as usize,
            None => self.multi.feature_slot(p) as usize,
        }
    }
}

/// The part of the state only a multi-exemplar run has, saved after the
/// patch state.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MultiState {
    /// Exemplar index of each patch, in patch order.
    pub exemplars: Vec<u32>,
    pub region: Option<RegionBox>,
}

impl Multi {
    pub fn new(set: Arc<ExemplarSet>, seed: u64) -> Multi {
        let levels = set
            .exemplars()
            .iter()
            .map(|e| FeatureLevels::new(&e.feature))
            .collect();
        Multi {
            set,
            levels,
            tests: Vec::new(),
            region: None,
            seed,
            frame: 0,
        }
    }

    /// The slot patch `p` reads on the current frame.
    #[inline]
    pub fn slot(&self, p: &Patch) -> u32 {
        self.set
            .slot(p.exemplar, self.seed, u64::from(p.id), self.frame)
    }

    /// The slot whose feature map and erosion test shape patch `p`.
    #[inline]
    pub fn feature_slot(&self, p: &Patch) -> u32 {
        self.set
            .feature_slot(p.exemplar, self.seed, u64::from(p.id))
    }

    /// The fill's view of one frame over `patches` (ids below `next_id`):
    /// with an animated set, the slots each patch reads, their pyramids
    /// built (each frame's when first shown).
    pub fn fill(&self, patches: &[Patch], next_id: u32) -> MultiFill<'_> {
        let (slots, feature_slots) = if self.set.is_animated() {
            let slots = self.slots_by_id(patches, next_id);
            self.set.prepare(
                patches
                    .iter()
                    .filter_map(|p| slots.get(p.id as usize).copied()),
            );
            (slots, by_id_of(patches, next_id, |p| self.feature_slot(p)))
        } else {
            (Vec::new(), Vec::new())
        };
        MultiFill {
            exemplars: self.set.exemplars(),
            features: self.levels.iter().map(FeatureLevels::samplers).collect(),
            tests: &self.tests,
            slots,
            feature_slots,
            multi: self,
        }
    }

    /// The slot of each patch id (ids up to `next_id`; unknown ids read 0).
    pub fn slots_by_id(&self, patches: &[Patch], next_id: u32) -> Vec<u32> {
        by_id_of(patches, next_id, |p| self.slot(p))
    }

    /// A chooser for this frame's new patches; with histogram steering its
    /// coverage starts from `patches` and the fill's `source`.
    pub fn chooser<'a>(
        &'a self,
        seed: u64,
        mesh: &'a crate::mesh::TriMesh,
        radius: f32,
        patches: &[Patch],
        source: &[u32],
    ) -> Chooser<'a> {
        let mut c = Chooser::new(&self.set, seed, mesh, self.region, radius);
        if self.set.select == ExemplarSelect::Histogram {
            c.coverage = coverage(patches, source);
        }
        c
    }

    /// Chooses the exemplars of the first frame's patches, in id order;
    /// each counts as one patch of equal size for histogram steering.
    pub fn assign_initial(
        &self,
        seed: u64,
        mesh: &crate::mesh::TriMesh,
        radius: f32,
        patches: &mut [Patch],
        at: impl Fn(&Patch) -> Option<SurfacePoint>,
    ) {
        let mut c = Chooser::new(&self.set, seed, mesh, self.region, radius);
        for p in patches.iter_mut() {
            let Some(point) = at(p) else { continue };
            p.exemplar = c.choose(point, p.id as u64);
            c.coverage.push(point.position(mesh), p.exemplar, 1.0);
        }
    }

    /// Per vertex of `p`: the weight it loses this frame (`dt` seconds)
    /// because its exemplar no longer matches the selecting attribute at
    /// the surface point nearest the vertex ([`SelectBy::mismatch_drop`]:
    /// the farther past the range, the more), `None` where it matches.
    /// Vertices farther than `reach` from the surface match; runs not
    /// selecting by attribute mismatch nowhere: empty. `everywhere`: per
    /// exemplar, whether it matches the whole surface this frame
    /// ([`SelectBy::matching_everywhere`]); its patches are not tested.
    pub fn mismatched(
        &self,
        p: &Patch,
        mesh: &TriMesh,
        index: &SurfaceIndex,
        reach: f32,
        everywhere: &[bool],
        dt: f32,
    ) -> Vec<Option<f32>> {
        let Some(by) = &self.set.by else {
            return Vec::new();
        };
        if everywhere.get(p.exemplar as usize) == Some(&true) {
            return Vec::new();
        }
        let Some(values) = by.values(mesh) else {
            return Vec::new();
        };
        p.positions
            .iter()
            .map(|&q| {
                let h = index.closest(q, reach)?;
                by.mismatch_drop(p.exemplar, SelectBy::value_at(values, mesh, h.location), dt)
            })
            .collect()
    }

    /// The state after the patches: exemplar ids in patch order.
    pub fn save(&self, patches: &[Patch]) -> Result<Vec<u8>, MethodError> {
        let state = MultiState {
            exemplars: patches.iter().map(|p| p.exemplar).collect(),
            region: self.region,
        };
        postcard::to_allocvec(&state).map_err(|e| MethodError::State(e.to_string()))
    }

    /// Restores what [`Multi::save`] wrote onto `patches`; every id must
    /// name an exemplar.
    pub fn load(&mut self, bytes: &[u8], patches: &mut [Patch]) -> Result<(), MethodError> {
        let state: MultiState = if bytes.is_empty() {
            MultiState::default()
        } else {
            postcard::from_bytes(bytes).map_err(|e| MethodError::State(e.to_string()))?
        };
        if state.exemplars.len() != patches.len() {
            return Err(MethodError::State(format!(
                "{} exemplar ids for {} patches (a state saved with one exemplar cannot \
                 continue with several)",
                state.exemplars.len(),
                patches.len()
            )));
        }
        let n = self.set.len();
        for (p, &e) in patches.iter_mut().zip(&state.exemplars) {
            if e as usize >= n {
                return Err(MethodError::State(format!(
                    "patch {} shows exemplar {e}, but {n} exemplars are given",
                    p.id
                )));
            }
            p.exemplar = e;
        }
        self.region = state.region;
        Ok(())
    }
}

/// The patch centre p: the vertex whose rest coordinates lie nearest
/// (0.5, 0.5) (a pinned vertex, within r/4 of p).
pub fn patch_centre(p: &Patch) -> Option<Vec3> {
    let c = Vec2::splat(0.5);
    p.rest
        .iter()
        .zip(&p.positions)
        .min_by(|a, b| a.0.distance_squared(c).total_cmp(&b.0.distance_squared(c)))
        .map(|(_, &x)| x)
}

/// The exemplar histogram of the fill: every patch at its centre, weighted
/// by the atlas texels it shows (`source` holds patch id + 1).
pub fn coverage(patches: &[Patch], source: &[u32]) -> Coverage {
    let mut texels = std::collections::HashMap::<u32, u32>::new();
    for &s in source {
        if s != OUTSIDE && s != UNCOVERED && s > 0 {
            *texels.entry(s - 1).or_default() += 1;
        }
    }
    let mut c = Coverage::default();
    for p in patches {
        if let (Some(&t), Some(centre)) = (texels.get(&p.id), patch_centre(p)) {
            c.push(centre, p.exemplar, t as f32);
        }
    }
    c
}

/// Exemplar index by patch id (ids up to `next_id`; unknown ids read 0).
pub fn by_id(patches: &[Patch], next_id: u32) -> Vec<u32> {
    by_id_of(patches, next_id, |p| p.exemplar)
}

/// `of(p)` by patch id (ids up to `next_id`; unknown ids read 0).
fn by_id_of(patches: &[Patch], next_id: u32, of: impl Fn(&Patch) -> u32) -> Vec<u32> {
    let mut out = vec![0u32; next_id as usize + 1];
    for p in patches {
        if let Some(slot) = out.get_mut(p.id as usize) {
            *slot = of(p);
        }
    }
    out
}
