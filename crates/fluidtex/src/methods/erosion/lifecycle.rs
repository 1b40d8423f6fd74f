//! A patch's life outside the fill: carried to the frame, seeded on a
//! fresh surface, pruned of the triangles it can no longer show (eroded or
//! hidden), and deleted when it shows nothing. The fill and the update,
//! which decide what shows, are in `mod.rs`, `fill` and `update`.

use rand::SeedableRng;
use rayon::prelude::*;

use super::erode::ErosionTest;
use super::fill::{self, FillBuffers};
use super::patch;
use super::patch::{CarryTable, FrameSurface, Patch, PatchShape};
use super::stats::{Blended, StepCounts};
use super::{Erosion, WeightMode, mix, rotation_for};
use crate::methods::{FrameContext, Method, MethodError};
use crate::surface::poisson::sample_mesh;

impl Erosion {
    /// Drops, from every patch, the triangles that can never show a texel
    /// again ([`Patch::prune_eroded`]), so a patch's cost follows what it
    /// can still show, not its history; returns how many went. Only the
    /// eroding method: `advect` never erodes and `blend-deformable` blends
    /// by weights that may rise again.
    pub(super) fn prune(&mut self, shape: &PatchShape, test: ErosionTest) -> usize {
        if !self.rules.erodes || !self.prune_eroded {
            return 0;
        }
        let tests = self.multi.as_ref().map(|m| m.tests.as_slice());
        let weights_can_rise = self.params.weights == WeightMode::Paper;
        let keep_earlier = self.transition_frames() > 0;
        self.state
            .patches
            .par_iter_mut()
            .map(|p| {
                let test = (self.multi.as_ref())
                    .zip(tests)
                    .and_then(|(m, t)| t.get(m.feature_slot(p) as usize))
                    .copied()
                    .unwrap_or(test);
                p.prune_eroded(&test, shape, weights_can_rise, keep_earlier)
            })
            .sum()
    }

    /// Drops, after the frame's fill, the triangles of each patch that lie
    /// farther than `hidden_reach` × r (in its rest space) from every texel
    /// it showed ([`Patch::prune_hidden`]); returns how many went. Only the
    /// eroding method, and not the patches a transition still shows as an
    /// earlier source.
    ///
    /// Not in the paper, which keeps a patch whole until it shows nothing.
    /// A new patch goes under every older one, so most of its disc starts
    /// hidden; on a splashing liquid, where hundreds of patches are made
    /// per frame, those hidden parts piled up to 6–7 layers of patch
    /// triangles per surface triangle, each advected, split and located
    /// every frame. When an older patch erodes there later, a hidden part
    /// would show a patch that has been stretched all the while; without
    /// it the update makes a fresh one there instead. On frames 2–48 of a
    /// Mantaflow splash (atlas 1024, default radius), a reach of 0.1 r
    /// halved the patch triangles (6.7 → 3.3 per surface triangle), cut the
    /// fill by 39 % and lowered the switch share (46.5 % → 44.4 %), with
    /// 36 % more patches made per frame.
    pub(super) fn prune_hidden(
        &mut self,
        out: &FillBuffers,
        blended: &Blended,
        shape: &PatchShape,
    ) -> usize {
        let reach = self.params.hidden_reach;
        if !self.rules.erodes || !self.prune_eroded || reach <= 0.0 {
            return 0;
        }
        let cell = reach * shape.radius / shape.exemplar_size;
        let patches = &mut self.state.patches;
        // Ids run below next_id (as delete_unused reads them).
        let mut index = vec![u32::MAX; self.state.next_id as usize + 1];
        for (i, p) in patches.iter().enumerate() {
            if let Some(slot) = index.get_mut(p.id as usize) {
                *slot = i as u32;
            }
        }
        let of_source = |s: u32| {
            crate::provenance::patch_of(s)
                .and_then(|id| index.get(id as usize))
                .filter(|&&i| i != u32::MAX)
                .map(|&i| i as usize)
        };
        // Per block of texels in parallel, in order: (patch, cell) of each
        // covered texel, a run of equal pairs kept once (neighbouring
        // texels mostly share both). Each patch sorts its cells after.
        const BLOCK: usize = 1 << 16;
        let pairs: Vec<(usize, (i32, i32))> = (out.source.par_chunks(BLOCK))
            .zip(out.uv.par_chunks(BLOCK))
            .flat_map_iter(|(sources, uvs)| {
                let mut block: Vec<(usize, (i32, i32))> = Vec::new();
                for (&s, &uv) in sources.iter().zip(uvs) {
                    if let Some(i) = of_source(s) {
                        let pair = (i, patch::rest_cell(uv, cell));
                        if block.last() != Some(&pair) {
                            block.push(pair);
                        }
                    }
                }
                block
            })
            .collect();
        let mut shown: Vec<Vec<(i32, i32)>> = vec![Vec::new(); patches.len()];
        for (i, c) in pairs {
            shown[i].push(c);
        }
        let mut whole = vec![false; patches.len()];
        for t in &blended.transitions {
            if let Some(&i) = index.get(t.patch_id as usize).filter(|&&i| i != u32::MAX) {
                whole[i as usize] = true;
            }
        }
        patches
            .par_iter_mut()
            .zip(shown.par_iter_mut())
            .zip(whole.par_iter())
            .map(|((p, cells), &whole)| {
                if whole {
                    0
                } else {
                    p.prune_hidden(cells, cell)
                }
            })
            .sum()
    }

    /// Carries every patch to this frame (or drops them all on a fresh
    /// start of the surface); returns whether `advect` carried patches,
    /// which then are never renewed.
    pub(super) fn advect(
        &mut self,
        ctx: &FrameContext<'_>,
        shape: &PatchShape,
        radius: f32,
        counts: &mut StepCounts,
    ) -> Result<bool, MethodError> {
        let before = self.state.patches.len();
        let mut carried = false;
        if let Some(prev) = ctx.previous
            && !self.state.patches.is_empty()
            && !prev.mesh.is_empty()
        {
            if prev.mesh.velocity().is_none() {
                return Err(MethodError::MissingVelocity {
                    frame: ctx.number - 1,
                    method: self.name(),
                });
            }
            let flow = ctx.flow(self.params.substeps, 0.25 * radius).ok_or(
                MethodError::MissingVelocity {
                    frame: ctx.number,
                    method: self.name(),
                },
            )?;
            // The carry table holds a key, a point and a carry per vertex
            // (40 bytes); the splitting counts its own rounds.
            let budget = ctx.arena.memory();
            let vertices: usize = self.state.patches.iter().map(|p| p.positions.len()).sum();
            if !budget.grow("advection", vertices * 40) {
                budget.check()?;
            }
            let table = CarryTable::new(&self.state.patches, flow, ctx.index, *shape);
            let grow = |bytes| budget.grow("splitting", bytes);
            self.state.patches.par_iter_mut().for_each(|p| {
                if !p.advect_within(|x| table.carry(x), ctx.index, shape, &grow) {
                    p.triangles.clear();
                }
            });
            budget.check()?;
            self.state.patches.retain(|p| !p.triangles.is_empty());
            // `advect` carries what it has; it only places patches on a fresh start.
            carried = !self.rules.renews && !self.state.patches.is_empty();
        } else if ctx.previous.is_none() || ctx.previous.is_some_and(|p| p.mesh.is_empty()) {
            // A fresh start of the surface: patches of an older surface cannot be carried.
            self.state.patches.clear();
        }
        counts.deleted_before = before - self.state.patches.len();
        Ok(carried)
    }

    /// Patches on a Poisson-disk set of the surface; returns how many.
    pub(super) fn seed_distribution(
        &mut self,
        ctx: &FrameContext<'_>,
        surface: &FrameSurface<'_>,
        shape: &PatchShape,
        radius: f32,
        align: Option<glam::Vec3>,
    ) -> usize {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(mix(self.seed, 2, ctx.number as u64));
        let samples = sample_mesh(ctx.mesh, radius, self.params.normal_dot, 30.0, &mut rng);
        let first = self.state.next_id;
        let (seed, random) = (self.seed, self.params.random_rotation);
        let new: Vec<Patch> = samples
            .par_iter()
            .enumerate()
            .filter_map(|(k, s)| {
                let id = first + k as u32;
                Patch::create(
                    id,
                    surface,
                    s.location,
                    shape,
                    rotation_for(seed, random, id as u64),
                    align,
                )
            })
            .collect();
        self.state.next_id += samples.len() as u32;
        let mut new = new;
        if let Some(m) = &self.multi {
            let at = |p: &Patch| samples.get((p.id - first) as usize).map(|s| s.location);
            m.assign_initial(seed, ctx.mesh, radius, &mut new, at);
        }
        let created = new.len();
        self.state.patches.extend(new);
        created
    }

    /// Deletes patches no texel used (Sec. 3); `advect` keeps everything
    /// (a hidden patch is still part of the carried parameterization).
    /// Returns how many went.
    pub(super) fn delete_unused(&mut self, out: &FillBuffers, blend_used: Option<&[u32]>) -> usize {
        let alive_before = self.state.patches.len();
        if self.rules.renews {
            let max_id = self.state.next_id as usize;
            let mut used = vec![false; max_id + 1];
            for &s in &out.source {
                if s != fill::OUTSIDE && s != fill::UNCOVERED && (s as usize) <= max_id {
                    used[s as usize - 1] = true;
                }
            }
            for &id in blend_used.into_iter().flatten() {
                if let Some(u) = used.get_mut(id as usize) {
                    *u = true;
                }
            }
            self.state.patches.retain(|p| used[p.id as usize]);
        }
        alive_before - self.state.patches.len()
    }
}
