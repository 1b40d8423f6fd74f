//! Distribution update (Gagnon et al. 2021, Sec. 4 and 5.1): texels left
//! uncovered by the lapped fill receive new, full-size patches placed *below*
//! all existing ones, until no chart texel is uncovered.
//!
//! Because new patches go to the bottom of the stack, they can only change
//! texels that were uncovered: every covered texel keeps its source. So the
//! update only ever re-tests the uncovered texels, and only those whose
//! fluid triangle lies near the new patch.
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
//! were uncovered texels.

use std::collections::HashMap;

use glam::Vec2;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::fill::{Candidates, FillBuffers, FillContext, Hit, Uncovered, patch_frames};
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
    let mesh = inputs.surface.mesh;
    let mut covered = vec![false; uncovered.len()];
    // Uncovered texels by fluid triangle, in texel order.
    let mut by_triangle: HashMap<u32, Vec<u32>> = HashMap::new();
    for (k, u) in uncovered.iter().enumerate() {
        by_triangle.entry(u.triangle).or_default().push(k as u32);
    }
    let point = |u: &Uncovered| crate::surface::SurfacePoint::new(u.triangle, u.bary);
    let mut cursor = 0usize;
    loop {
        // Seeds of this round.
        let seeds: Vec<usize> = match inputs.placement {
            Placement::Local => {
                while cursor < uncovered.len() && covered[cursor] {
                    cursor += 1;
                }
                if cursor == uncovered.len() {
                    break;
                }
                vec![cursor]
            }
            Placement::Global => {
                let mut disks = DiskSet::new(inputs.shape.radius, inputs.normal_dot);
                let mut chosen = Vec::new();
                for (k, u) in uncovered.iter().enumerate() {
                    if covered[k] {
                        continue;
                    }
                    let x = point(u).position(mesh);
                    if disks.try_insert(x, mesh.triangle_normal(u.triangle as usize)) {
                        chosen.push(k);
                    }
                }
                if chosen.is_empty() {
                    break;
                }
                chosen
            }
        };
        stats.rounds += 1;
        let first_id = *next_id;
        let created: Vec<(Patch, usize)> = seeds
            .par_iter()
            .enumerate()
            .filter_map(|(k, &s)| {
                let id = first_id + k as u32;
                Patch::create(
                    id,
                    inputs.surface,
                    point(&uncovered[s]),
                    &inputs.shape,
                    (inputs.rotation)(point(&uncovered[s])),
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
            let at = point(&uncovered[seed]);
            if let Some(c) = chooser.as_deref_mut() {
                patch.exemplar = c.choose(at, super::location_key(at));
            }
            let mut shown = 0usize;
            let one = std::slice::from_ref(&patch);
            let frames = patch_frames(one);
            let ctx = FillContext {
                mesh,
                patches: one,
                frames: &frames,
                exemplar: template.exemplar,
                feature: template.feature,
                test: template.test,
                tolerance: template.tolerance,
                multi: template.multi,
            };
            let candidates =
                Candidates::build(mesh, inputs.index, one, &frames, template.tolerance);
            let mut touched: Vec<u32> = by_triangle
                .keys()
                .copied()
                .filter(|&f| !candidates.of(f).is_empty())
                .collect();
            touched.sort_unstable();
            for f in touched {
                let list = candidates.of(f);
                let [a, b, c] = mesh.corners(f as usize);
                let n = (b - a).cross(c - a).normalize_or_zero();
                for &k in &by_triangle[&f] {
                    let k = k as usize;
                    if covered[k] {
                        continue;
                    }
                    let u = &uncovered[k];
                    let x = a * u.bary[0] + b * u.bary[1] + c * u.bary[2];
                    if let Some(hit) = ctx.resolve(list, x, n) {
                        out.write(u.texel as usize, hit, patch.id, ctx.exemplar_of(0));
                        covered[k] = true;
                        shown += 1;
                    }
                }
            }
            if !covered[seed] {
                // See the module doc: the creating texel is the patch centre.
                let hit = Hit {
                    patch: 0,
                    uv: Vec2::splat(0.5),
                };
                out.write(
                    uncovered[seed].texel as usize,
                    hit,
                    patch.id,
                    ctx.exemplar_of(0),
                );
                covered[seed] = true;
                stats.forced += 1;
                shown += 1;
            }
            if let Some(c) = chooser.as_deref_mut() {
                c.coverage
                    .push(at.position(mesh), patch.exemplar, shown as f32);
            }
            patches.push(patch);
        }
    }
    stats
}
