//! Distribution update (Gagnon et al. 2021, Sec. 4 and 5.1): texels left
//! uncovered by the lapped fill receive new, full-size patches placed *below*
//! all existing ones, until no chart texel is uncovered.
//!
//! Because new patches go to the bottom of the stack, they can only change
//! texels that were uncovered: every covered texel keeps its source. So the
//! update only ever re-tests the uncovered texels, and only those whose
//! fluid triangle lies near the new patch.
//!
//! **Cores.** The default placement makes one patch at a time, each
//! depending on what the ones before it covered, so the loop itself is
//! sequential. Within one patch the work is split: its candidate pairs are
//! searched in ranges of patch triangles, and its hits found by fluid
//! triangle, on every core, then written in order (the same texels and
//! values as a walk in order: each texel lies in one fluid triangle and its
//! hit depends only on the patch).
//!
//! Two placements:
//! - [`Placement::Local`], the paper's: a new patch at the first uncovered
//!   texel in atlas order, fill what it covers, repeat.
//! - [`Placement::Global`], the paper's suggested future work: Poisson-disk
//!   selection (spacing r) over *all* uncovered texels at once, one patch
//!   per selected texel, fill, repeat with what remains.
//!
//! Termination: the texel that created a patch is its centre p, where D = 1
//! and B_V = 1 (pinned vertices), so it survives erosion whenever Q_V does;
//! should a wildly distorted creation still erode it, it is assigned to its
//! own patch anyway and counted as `forced`, so every new patch covers at
//! least one texel and the loop ends after at most as many patches as there
//! were uncovered texels. With the paper's rule ([`super::SeedTexel::Paper`])
//! such a texel is left uncovered instead, and the same bound holds: every
//! new patch settles its seed texel one way or the other.

use std::collections::HashMap;

use glam::Vec2;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::fill::{
    FillBuffers, FillContext, FluidTriangles, Hit, LocateTolerance, TriFrame, Uncovered,
    patch_frames,
};
use super::patch::{FrameSurface, Patch, PatchShape};
use crate::exemplar::set::Chooser;
use crate::surface::SurfaceIndex;
use crate::surface::poisson::DiskSet;

/// Where new patches are centred when texels are uncovered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Placement {
    /// The paper's: one patch at the first uncovered texel, repeat.
    #[default]
    Local,
    /// Poisson-disk centres over all uncovered texels at once.
    Global,
}

crate::named!(Placement {
    Local => "local",
    Global => "global",
});

/// What the update did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UpdateStats {
    pub created: usize,
    /// Texels assigned to their own new patch although eroded there.
    pub forced: usize,
    pub rounds: usize,
}

/// Everything the update reads besides the patches.
pub struct UpdateInputs<'a> {
    pub surface: &'a FrameSurface<'a>,
    pub index: &'a SurfaceIndex,
    pub shape: PatchShape,
    pub placement: Placement,
    /// Normal agreement below which Poisson disks do not block (0.9).
    pub normal_dot: f32,
    /// Rotation of a new patch created at a surface point.
    pub rotation: &'a (dyn Fn(crate::surface::SurfacePoint) -> f32 + Sync),
    /// The world axis the exemplar's up follows (aligned orientation).
    pub align: Option<glam::Vec3>,
    /// A new patch that erodes its own seed texel gets it anyway (see the
    /// module doc); false: the texel stays uncovered this frame (the
    /// paper's [`super::SeedTexel::Paper`]).
    pub force_seed: bool,
}

/// Covers every texel in `uncovered`, appending new patches to `patches`.
/// With several exemplars, `chooser` picks each new patch's exemplar (in
/// creation order, before its fill) and is told what the patch covered.
pub fn cover(
    template: &FillContext<'_>,
    inputs: &UpdateInputs<'_>,
    patches: &mut Vec<Patch>,
    next_id: &mut u32,
    uncovered: &[Uncovered],
    out: &mut FillBuffers,
    mut chooser: Option<&mut Chooser<'_>>,
) -> UpdateStats {
    let mut stats = UpdateStats::default();
    if uncovered.is_empty() {
        return stats;
    }
    let mut holes = Holes::new(uncovered);
    while let Some(seeds) = holes.next_seeds(inputs) {
        stats.rounds += 1;
        let first_id = *next_id;
        let created: Vec<(Patch, usize)> = seeds
            .par_iter()
            .enumerate()
            .filter_map(|(k, &s)| {
                let at = holes.point(s);
                let id = first_id + k as u32;
                Patch::create(
                    id,
                    inputs.surface,
                    at,
                    &inputs.shape,
                    (inputs.rotation)(at),
                    inputs.align,
                )
                .map(|p| (p, s))
            })
            .collect();
        *next_id += seeds.len() as u32;
        if created.is_empty() {
            break;
        }
        for (mut patch, seed) in created {
            stats.created += 1;
            let at = holes.point(seed);
            if let Some(c) = chooser.as_deref_mut() {
                patch.exemplar = c.choose(at, super::location_key(at));
            }
            let (shown, forced) = holes.fill(template, inputs, &patch, seed, out);
            stats.forced += usize::from(forced);
            if let Some(c) = chooser.as_deref_mut() {
                c.coverage.push(
                    at.position(inputs.surface.mesh),
                    patch.exemplar,
                    shown as f32,
                );
            }
            patches.push(patch);
        }
    }
    stats
}

/// The update's uncovered texels and which of them new patches covered.
struct Holes<'u> {
    uncovered: &'u [Uncovered],
    covered: Vec<bool>,
    /// Uncovered texels by fluid triangle, in texel order.
    by_triangle: HashMap<u32, Vec<u32>>,
    /// Local placement: no texel before it is uncovered.
    cursor: usize,
}

impl<'u> Holes<'u> {
    fn new(uncovered: &'u [Uncovered]) -> Holes<'u> {
        let mut by_triangle: HashMap<u32, Vec<u32>> = HashMap::new();
        for (k, u) in uncovered.iter().enumerate() {
            by_triangle.entry(u.triangle).or_default().push(k as u32);
        }
        Holes {
            uncovered,
            covered: vec![false; uncovered.len()],
            by_triangle,
            cursor: 0,
        }
    }

    fn point(&self, k: usize) -> crate::surface::SurfacePoint {
        let u = &self.uncovered[k];
        crate::surface::SurfacePoint::new(u.triangle, u.bary)
    }

    /// The texels new patches are centred at this round; `None` when every
    /// texel is covered.
    fn next_seeds(&mut self, inputs: &UpdateInputs<'_>) -> Option<Vec<usize>> {
        match inputs.placement {
            Placement::Local => {
                while self.cursor < self.uncovered.len() && self.covered[self.cursor] {
                    self.cursor += 1;
                }
                (self.cursor < self.uncovered.len()).then(|| vec![self.cursor])
            }
            Placement::Global => {
                let mesh = inputs.surface.mesh;
                let mut disks = DiskSet::new(inputs.shape.radius, inputs.normal_dot);
                let mut chosen = Vec::new();
                for (k, u) in self.uncovered.iter().enumerate() {
                    if self.covered[k] {
                        continue;
                    }
                    let x = self.point(k).position(mesh);
                    if disks.try_insert(x, mesh.triangle_normal(u.triangle as usize)) {
                        chosen.push(k);
                    }
                }
                (!chosen.is_empty()).then_some(chosen)
            }
        }
    }

    /// Fills the still uncovered texels new patch `patch` (made at texel
    /// `seed`) shows; returns how many, and whether the seed texel had to
    /// be assigned to it without showing it (see the module doc).
    fn fill(
        &mut self,
        template: &FillContext<'_>,
        inputs: &UpdateInputs<'_>,
        patch: &Patch,
        seed: usize,
        out: &mut FillBuffers,
    ) -> (usize, bool) {
        let mesh = inputs.surface.mesh;
        let one = std::slice::from_ref(patch);
        let frames = patch_frames(one);
        let ctx = FillContext {
            mesh,
            patches: one,
            frames: &frames,
            ..*template
        };
        let candidates = PatchCandidates::build(
            template.fluid,
            inputs.index,
            patch,
            frames.first().map_or(&[][..], Vec::as_slice),
            template.tolerance,
        );
        // The patch's hits, found in parallel by fluid triangle: a texel's
        // hit depends only on the patch and the texel, and each texel lies
        // in one fluid triangle, so writing them afterwards gives what a
        // walk in order writes. The default (local) placement makes one
        // patch at a time, so this is where the update uses every core.
        let groups: Vec<(u32, &[(u32, u32)])> = candidates.groups().collect();
        let (covered, by_triangle, uncovered) = (&self.covered, &self.by_triangle, self.uncovered);
        let hits: Vec<(u32, Hit)> = groups
            .par_iter()
            .flat_map_iter(|&(f, list)| {
                let mut found = Vec::new();
                if let Some(texels) = by_triangle.get(&f) {
                    let [a, b, c] = mesh.corners(f as usize);
                    let n = (b - a).cross(c - a).normalize_or_zero();
                    for &k in texels {
                        if covered[k as usize] {
                            continue;
                        }
                        let u = &uncovered[k as usize];
                        let x = a * u.bary[0] + b * u.bary[1] + c * u.bary[2];
                        if let Some(hit) = ctx.resolve(list, x, n) {
                            found.push((k, hit));
                        }
                    }
                }
                found
            })
            .collect();
        let mut shown = hits.len();
        for (k, hit) in hits {
            let u = &self.uncovered[k as usize];
            out.write(u.texel as usize, hit, patch.id, ctx.exemplar_of(0));
            self.covered[k as usize] = true;
        }
        let forced = !self.covered[seed] && inputs.force_seed;
        if forced {
            // See the module doc: the creating texel is the patch centre.
            let hit = Hit {
                patch: 0,
                uv: Vec2::splat(0.5),
            };
            let texel = self.uncovered[seed].texel as usize;
            out.write(texel, hit, patch.id, ctx.exemplar_of(0));
            shown += 1;
        }
        // Settled either way. With the paper's rule the texel stays
        // uncovered: another patch made here would be this one again, so
        // none is asked for this frame, and the placement moves on.
        self.covered[seed] = true;
        (shown, forced)
    }
}

/// The fluid triangles one new patch may cover, each with its candidate
/// (patch index 0, patch triangle) pairs: exactly what
/// [`super::fill::Candidates::build`] gives for the patch alone (the same
/// BVH query and prism test, the same order: by fluid triangle, then patch
/// triangle), but sparse. `Candidates` holds an offset per fluid triangle
/// of the whole mesh; built once per new patch, that array (and a scan of
/// every uncovered triangle against it) made the update's cost grow with
/// the mesh size times the number of new patches. Here the cost is the
/// patch's own candidates.
struct PatchCandidates {
    /// (fluid triangle, patch triangle), sorted.
    pairs: Vec<(u32, u32)>,
    /// `pairs` as `resolve` takes them: (patch index 0, patch triangle).
    entries: Vec<(u32, u32)>,
}

impl PatchCandidates {
    fn build(
        fluid: &FluidTriangles,
        index: &SurfaceIndex,
        patch: &Patch,
        frames: &[Option<TriFrame>],
        tolerance: LocateTolerance,
    ) -> PatchCandidates {
        let mut pairs = super::fill::patch_pairs_list(fluid, index, patch, frames, tolerance);
        pairs.sort_unstable();
        let entries = pairs.iter().map(|&(_, j)| (0, j)).collect();
        PatchCandidates { pairs, entries }
    }

    /// Each fluid triangle with candidates, in increasing order, with them.
    fn groups(&self) -> impl Iterator<Item = (u32, &[(u32, u32)])> + '_ {
        let mut start = 0;
        std::iter::from_fn(move || {
            let &(f, _) = self.pairs.get(start)?;
            let end = start
                + self.pairs[start..]
                    .iter()
                    .take_while(|&&(g, _)| g == f)
                    .count();
            let group = &self.entries[start..end];
            start = end;
            Some((f, group))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::fill::Candidates;
    use super::*;
    use crate::mesh::TriMesh;
    use crate::methods::test_clip::scene;
    use crate::surface::SurfacePoint;

    /// New patches made every `step`-th triangle of the differential
    /// rotation's first frame (radius 1/8 of its box diagonal), each
    /// handed to `visit` with the frame's mesh, index and triangles and
    /// the locating tolerance.
    fn each_patch(
        step: usize,
        mut visit: impl FnMut(u32, &Patch, &TriMesh, &SurfaceIndex, &FluidTriangles, LocateTolerance),
    ) {
        let c = scene("differential-rotation", 12, 1, 64);
        let (mesh, index) = (&c.meshes[0], &c.indices[0]);
        let surface = FrameSurface {
            mesh,
            topology: &c.topologies[0],
            vertex_normals: &c.normals[0],
            index: Some(index),
        };
        let (lo, hi) = mesh.bounding_box().expect("surface");
        let radius = (hi - lo).length() / 8.0;
        let shape = super::super::tests::shape(radius);
        let tolerance = LocateTolerance::for_radius(radius);
        let fluid = FluidTriangles::new(mesh);
        for t in (0..mesh.triangle_count() as u32).step_by(step) {
            let at = SurfacePoint::new(t, [0.2, 0.3, 0.5]);
            if let Some(patch) = Patch::create(t, &surface, at, &shape, 0.3, None) {
                visit(t, &patch, mesh, index, &fluid, tolerance);
            }
        }
    }

    /// The sparse candidates of a new patch are those of the whole-mesh
    /// array, fluid triangle by fluid triangle and in the same order, for
    /// patches all over a curved surface (so the update's results are
    /// unchanged; the golden outputs check the same end to end).
    #[test]
    fn patch_candidates_are_those_of_the_whole_mesh_array() {
        let mut checked = 0;
        each_patch(37, |t, patch, mesh, index, fluid, tolerance| {
            let one = std::slice::from_ref(patch);
            let frames = patch_frames(one);
            let whole = Candidates::build(fluid, index, one, &frames, tolerance);
            let local = PatchCandidates::build(fluid, index, patch, &frames[0], tolerance);
            let mut groups = local.groups();
            let mut covered = 0;
            for f in 0..mesh.triangle_count() as u32 {
                let want = whole.of(f);
                if want.is_empty() {
                    continue;
                }
                assert_eq!(groups.next(), Some((f, want)), "patch at {t}");
                covered += 1;
            }
            assert_eq!(groups.next(), None, "patch at {t}");
            assert!(covered > 10, "patch at {t}: {covered} fluid triangles");
            checked += 1;
        });
        assert!(checked > 5, "{checked} patches");
    }

    /// The pair search split into ranges of patch triangles (on several
    /// threads) lists exactly the pairs, in the order, of the search in
    /// one piece, for ranges of 1, 3 and 64 triangles.
    #[test]
    fn pairs_searched_in_ranges_are_those_searched_in_one_piece() {
        let mut split = 0;
        each_patch(53, |t, patch, _, index, fluid, tolerance| {
            let frames = patch_frames(std::slice::from_ref(patch));
            let mut whole = Vec::new();
            super::super::fill::patch_pairs(fluid, index, patch, &frames[0], tolerance, |f, j| {
                whole.push((f, j))
            });
            assert!(!whole.is_empty(), "patch at {t}");
            for range in [1, 3, 64] {
                let ranged = super::super::fill::candidates::patch_pairs_ranged(
                    fluid, index, patch, &frames[0], tolerance, range,
                );
                assert_eq!(ranged, whole, "patch at {t}, ranges of {range}");
            }
            split += usize::from(patch.triangles.len() > 3);
        });
        assert!(split > 5, "{split} patches");
    }
}
