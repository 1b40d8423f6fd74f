//! Deformable patches (Gagnon et al. 2021, Sec. 4): creation from the fluid
//! mesh around a point, flattening, advection with projection, and the
//! per-vertex weights of Eqs. 1–3.
//!
//! A patch owns a copy of the fluid triangles around its centre p with its
//! own topology; from then on it is independent of the fluid mesh, which is
//! a different mesh every frame. Each vertex keeps its *rest* coordinates:
//! its exemplar uv, fixed at creation, where the exemplar's \[0,1]² covers S
//! world units (so rest coordinates × S are the triangle rest shapes in
//! world units that δ_t compares against).

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use super::distortion::{distortion, triangle_quality_from};
use super::erode::{ErosionTest, Verdict};
use crate::mesh::{Topology, TriMesh};
use crate::methods::FrameContext;
use crate::surface::velocity::FlowInterval;
use crate::surface::{SurfaceIndex, SurfacePoint, closest_point_on_triangle, map_in_query_order};

mod creation;
mod refine;

use self::creation::{Piece, flatten, join_pieces, rest_coordinates, triangles_near};
pub use self::refine::{Freeze, SPLIT_BYTES};

/// Geometric constants every patch shares (docs/design.md, *Patch radius
/// and exemplar size*), world units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchShape {
    /// Patch radius r.
    pub radius: f32,
    /// World extent S covered by the exemplar's \[0,1]².
    pub exemplar_size: f32,
    /// δ_max of Eq. 1.
    pub delta_max: f32,
    /// Distortion below which Q_T stays 1 (1 in the paper's Eq. 1).
    pub delta_onset: f32,
    /// Vertices farther than this from the next frame's surface are removed (r/4, Sec. 4).
    pub far_distance: f32,
    /// B_V = 1 for vertices within this rest distance of p (r/4, Eq. 2).
    pub centre_radius: f32,
    /// World size of one atlas texel this frame (0: no footprint, the
    /// feature map is point-sampled at level 0).
    pub texel_size: f32,
    /// Width of the feature map in texels.
    pub feature_width: f32,
    /// Patch edges longer than this are split at their midpoint after
    /// advection (and at creation), so the patch mesh stays about as fine
    /// as the fluid mesh it rides on; 0 disables it (the paper). See
    /// [`Patch::refine`].
    pub split_length: f32,
    /// Edges longer than this many times their rest length in world units
    /// (rest × S) are never split: their triangles are past the distortion
    /// bound (δ_max for the erosion method; `f32::INFINITY` for the
    /// baselines, which never erode). See [`Patch::refine`].
    pub split_stretch: f32,
    /// A triangle whose distortion δ_t is past this is never split, nor
    /// are its edges (`f32::INFINITY`: no bound): where every triangle is
    /// kept, [`KEPT_SPLIT_DISTORTION`] × δ_max. See [`Patch::refine_within`].
    pub split_distortion: f32,
    /// A new patch starts with w = 1 on its pinned vertices, whatever Q_V
    /// (progressive weights; the paper's w_V = Q_V·B_V from the first frame
    /// when false). Flattening a curved region can leave the centre's Q_V so
    /// low that the patch erodes the very texel it was made for; the patch
    /// then shows nothing, is deleted the next frame, and an identical patch
    /// with a new id replaces it, frame after frame, even on a fluid at rest.
    /// Progressive weights then lower the centre towards Q_V at the erosion
    /// rate, like any other vertex.
    pub whole_centre: bool,
    /// A new patch copies every triangle within r facing p's side, connected
    /// to p's triangle or not (the paper's Sec. 4; [`super::PatchRegion`]).
    pub whole_region: bool,
    /// The corners of the triangle that holds p keep B_V = 1
    /// ([`super::SeedCorners`]).
    pub pin_seed_corners: bool,
}

/// Rounds of [`Patch::refine`] per call: each round halves the longest
/// edges, so 6 rounds shorten an edge by up to 64×, far more than one
/// frame of any flow stretches it.
pub const MAX_SPLIT_ROUNDS: usize = 6;

/// Where every triangle is kept (the baselines `advect`,
/// `blend-deformable`, `dual-rest`, and erosion with `eroded_triangles =
/// "kept"`), a triangle whose distortion is past this many times δ_max is
/// no longer split ([`PatchShape::split_distortion`]).
pub const KEPT_SPLIT_DISTORTION: f32 = 4.0;

/// An edge midpoint farther than this fraction of r from the next surface
/// lies over a gap of the surface and is not split (the default far
/// distance of Sec. 4, r/4).
pub const GAP_FRACTION: f32 = 0.25;

/// The rest-space cell of side `cell` that holds `uv`
/// ([`Patch::prune_hidden`]).
pub fn rest_cell(uv: Vec2, cell: f32) -> (i32, i32) {
    use crate::texture::floor_i32;
    (floor_i32(uv.x / cell), floor_i32(uv.y / cell))
}

/// Where one patch vertex goes over a frame interval: a function of its
/// position alone (and of the flow, the next surface and the shape, the
/// same for every patch of a frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Carry {
    /// It did not move and already lies on the surface: it stays, to the bit.
    Stay,
    /// It moves to this point of the next surface.
    To(Vec3),
    /// It ends farther than the far distance from the next surface: removed.
    Far,
}

/// The [`Carry`] of a vertex at `x`: RK4 through `flow`, then the closest
/// point of the next surface within `shape.far_distance`.
pub fn carry_vertex(
    x: Vec3,
    flow: &FlowInterval<'_>,
    next: &SurfaceIndex,
    shape: &PatchShape,
) -> Carry {
    // A closest-point projection is not idempotent to the last bit: a
    // vertex the flow leaves in place would still creep by ~1e-8 per
    // frame, and a fluid at rest would never give identical frames. A
    // vertex that did not move and already lies on the surface stays.
    let on_surface = 1e-5 * shape.radius;
    let moved = flow.advect(x);
    match next.closest(moved, shape.far_distance) {
        Some(hit) if moved == x && hit.distance <= on_surface => Carry::Stay,
        Some(hit) => Carry::To(hit.point),
        None => Carry::Far,
    }
}

/// The [`Carry`] of every distinct vertex position of a set of patches.
///
/// Patches overlap (that is what lapped textures are), and the patches made
/// in one frame copy the same fluid vertices, which then move identically
/// for as long as both patches keep them: on a dam break the patches hold
/// 2–4.4 copies of each position. The carry is a function of the position,
/// so each distinct position is carried once and every patch looks its
/// vertices up: the same results, to the bit, for a half to three quarters
/// less RK4 and projection work.
pub struct CarryTable<'a> {
    /// Distinct positions (as bits), sorted.
    keys: Vec<[u32; 3]>,
    carries: Vec<Carry>,
    flow: FlowInterval<'a>,
    next: &'a SurfaceIndex,
    shape: PatchShape,
}

impl<'a> CarryTable<'a> {
    /// Carries every distinct vertex position of `patches` (in parallel).
    pub fn new(
        patches: &[Patch],
        flow: FlowInterval<'a>,
        next: &'a SurfaceIndex,
        shape: PatchShape,
    ) -> CarryTable<'a> {
        use rayon::prelude::*;
        let mut keys: Vec<[u32; 3]> = patches
            .par_iter()
            .flat_map_iter(|p| p.positions.iter().map(|&q| key(q)))
            .collect();
        keys.par_sort_unstable();
        keys.dedup();
        // Carried in an order that keeps consecutive BVH queries close
        // (the keys' order runs along x only); results go back by index.
        let points: Vec<Vec3> = keys
            .par_iter()
            .map(|k| Vec3::from_array(k.map(f32::from_bits)))
            .collect();
        let carries = map_in_query_order(&points, |i| carry_vertex(points[i], &flow, next, &shape));
        CarryTable {
            keys,
            carries,
            flow,
            next,
            shape,
        }
    }

    /// The carry of a vertex at `x`: from the table, or computed for a
    /// position the table was not built from.
    pub fn carry(&self, x: Vec3) -> Carry {
        self.get(x)
            .unwrap_or_else(|| carry_vertex(x, &self.flow, self.next, &self.shape))
    }

    /// The carry of a vertex at `x`; `None` for a position the table was not
    /// built from.
    pub fn get(&self, x: Vec3) -> Option<Carry> {
        self.keys
            .binary_search(&key(x))
            .ok()
            .map(|i| self.carries[i])
    }

    /// How many distinct positions were carried.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// Whether no position was carried.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }
}

/// A position as bits: equal keys are equal positions, to the bit (so the
/// carry looked up is exactly the one `carry_vertex` would give).
fn key(q: Vec3) -> [u32; 3] {
    [q.x.to_bits(), q.y.to_bits(), q.z.to_bits()]
}

/// One deformable patch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Patch {
    /// Creation order; lower ids are older and lie on top in the lapped fill.
    pub id: u32,
    /// Current 3-D vertex positions (on the current fluid surface).
    pub positions: Vec<Vec3>,
    /// Rest coordinates = exemplar uv, fixed at creation; the centre p is at (0.5, 0.5).
    pub rest: Vec<Vec2>,
    pub triangles: Vec<[u32; 3]>,
    /// Vertices whose B_V is held at 1: those within r/4 of p (Eq. 2), the
    /// corners of the triangle that held p, so the texel that created the
    /// patch is never eroded by it (the paper's own guard, made exact), and
    /// interior vertices that [`Patch::prune`] left on the border.
    pub pinned: Vec<bool>,
    /// w_V = Q_V · B_V (Eq. 3), refreshed by [`Patch::update_weights`];
    /// kept across frames (and in the saved state) because progressive
    /// weights depend on the previous frame's.
    pub weight: Vec<f32>,
    /// The weights as the frame before left them, per current vertex (set
    /// by [`Patch::update_weights`] after this frame's advection and splits,
    /// kept through its prune; empty for a patch created this frame): which point the patch showed the frame before,
    /// for the renewal record ([`crate::provenance::RENEWAL_HELD`]).
    #[serde(skip)]
    pub weight_before: Vec<f32>,
    /// With a transition of N frames ([`super::transition`]), the weights
    /// of the N − 1 frames before that, most recent first, per current
    /// vertex (an entry of another length: the patch did not exist then).
    /// Saved after the patch state by [`super::transition::save_history`].
    #[serde(skip)]
    pub weight_older: Vec<Vec<f32>>,
    /// Per triangle: past the distortion bound (δ_t ≥ δ_max, Q_T = 0 of
    /// Eq. 1) at this frame's positions; refreshed with the weights.
    #[serde(skip)]
    pub distorted: Vec<bool>,
    /// Per triangle: a corner's exemplar no longer matches the selecting
    /// attribute there ([`Patch::lower_mismatched`]); empty without
    /// selection by attribute. A switch away from such a point is forced
    /// by the fluid's state, as one past δ_max is by the flow.
    #[serde(skip)]
    pub mismatched: Vec<bool>,
    /// Per triangle: the feature-map level matching one atlas texel's
    /// footprint on it (log2 of feature texels per atlas texel along the
    /// most compressed direction), refreshed with the weights.
    #[serde(skip)]
    pub lod: Vec<f32>,
    /// True when the last advection left every vertex exactly in place:
    /// progressive weights then hold still too, so a fluid at rest gives
    /// identical frames (erosion is driven by deformation, and there is none).
    #[serde(skip)]
    pub still: bool,
    /// Index of the exemplar the patch shows (several exemplars per
    /// surface; 0 with one). Saved after the patch state by
    /// [`super::exemplars::Multi::save`], so a one-exemplar state is
    /// unchanged.
    #[serde(skip)]
    pub exemplar: u32,
}

/// Per-creation inputs from the current frame, built once per frame.
pub struct FrameSurface<'a> {
    pub mesh: &'a TriMesh,
    pub topology: &'a Topology,
    pub vertex_normals: &'a [Vec3],
    /// The mesh's BVH, for the triangles near p that the surface does not
    /// join to it (`whole_region`); without it every triangle is tested.
    pub index: Option<&'a SurfaceIndex>,
}

impl<'a> FrameSurface<'a> {
    /// The surface of the frame `ctx` hands a method.
    pub fn of(ctx: &FrameContext<'a>) -> FrameSurface<'a> {
        FrameSurface {
            mesh: ctx.mesh,
            topology: ctx.topology,
            vertex_normals: ctx.normals,
            index: Some(ctx.index),
        }
    }
}

impl Patch {
    /// Creates the patch centred at `at` on the current fluid surface
    /// (Sec. 4): the triangles within distance r of p that face the side of
    /// the normal at p, restricted to the edge-connected component of p's
    /// triangle (unless `shape.whole_region`), copied with their own
    /// topology and flattened by LSCM (Lévy et al. 2002) followed by a
    /// similarity transform so that uv area equals 3-D area / S², p maps to
    /// (0.5, 0.5) and the patch is turned by `rotation` radians. Returns
    /// `None` only if `at` names no triangle.
    pub fn create(
        id: u32,
        surface: &FrameSurface<'_>,
        at: SurfacePoint,
        shape: &PatchShape,
        rotation: f32,
        align: Option<Vec3>,
    ) -> Option<Patch> {
        let mesh = surface.mesh;
        let seed = at.triangle;
        if seed as usize >= mesh.triangles.len() {
            return None;
        }
        let p = at.position(mesh);
        let n_p = {
            let n = at.interpolate(&mesh.triangles, surface.vertex_normals);
            let n = n.normalize_or_zero();
            if n == Vec3::ZERO {
                mesh.triangle_normal(seed as usize)
            } else {
                n
            }
        };
        let r2 = shape.radius * shape.radius;
        let near = |t: u32| {
            let [a, b, c] = mesh.corners(t as usize);
            closest_point_on_triangle(p, a, b, c).distance_squared(p) <= r2
                && mesh.triangle_cross(t as usize).dot(n_p) > 0.0
        };
        // Flood fill over edge neighbours: this is the connected component of
        // the seed among the triangles within r that face n_p.
        let mut connected = surface.topology.grow_region(seed, near);
        connected.sort_unstable();
        let (connected_mesh, connected_source) = mesh.submesh(&connected);
        let connected_flat = flatten(&connected_mesh.positions, &connected_mesh.triangles, n_p);
        let (sub, flat, seed_local) = if shape.whole_region {
            let others = triangles_near(surface, p, shape.radius, &near, &connected);
            let piece = Piece {
                triangles: &connected,
                mesh: connected_mesh,
                source: &connected_source,
                flat: connected_flat,
            };
            join_pieces(mesh, piece, &others, n_p, seed)
        } else {
            let seed_local = connected.binary_search(&seed).unwrap_or(0);
            (connected_mesh, connected_flat, seed_local)
        };
        let [ia, ib, ic] = sub.triangles[seed_local];
        let rest = rest_coordinates(
            &sub, &flat, seed_local, at.bary, n_p, shape, rotation, align,
        );
        let centre = Vec2::splat(0.5);
        let mut pinned: Vec<bool> = rest
            .iter()
            .map(|q| q.distance(centre) * shape.exemplar_size <= shape.centre_radius)
            .collect();
        if shape.pin_seed_corners {
            for v in [ia, ib, ic] {
                pinned[v as usize] = true;
            }
        }
        let mut patch = Patch {
            id,
            positions: sub.positions,
            rest,
            triangles: sub.triangles,
            pinned,
            weight: Vec::new(),
            weight_before: Vec::new(),
            weight_older: Vec::new(),
            distorted: Vec::new(),
            mismatched: Vec::new(),
            lod: Vec::new(),
            still: false,
            exemplar: 0,
        };
        // The copied fluid triangles lie on the surface, so do their edge midpoints.
        let freeze = Freeze::of(shape);
        patch.refine_within(
            shape.split_length,
            shape.split_stretch,
            freeze,
            Some,
            &|_| true,
        );
        patch.update_weights(shape, None);
        if shape.whole_centre {
            for (w, &pinned) in patch.weight.iter_mut().zip(&patch.pinned) {
                if pinned {
                    *w = 1.0;
                }
            }
        }
        Some(patch)
    }

    /// Moves every vertex where `carry` says ([`carry_vertex`]: advected
    /// through the flow by RK4 and projected onto the next frame's surface,
    /// or removed, with its triangles, when it ends farther than
    /// `shape.far_distance` from it; Sec. 4), then refines the stretched
    /// edges. Returns false when nothing is left (the patch is then
    /// deleted). The method passes [`CarryTable::carry`], shared by every
    /// patch of the frame.
    pub fn advect(
        &mut self,
        carry: impl Fn(Vec3) -> Carry,
        next: &SurfaceIndex,
        shape: &PatchShape,
    ) -> bool {
        self.advect_within(carry, next, shape, &|_| true)
    }

    /// [`Patch::advect`], its splitting counting the bytes of each round
    /// with `grow` first ([`Patch::refine_within`]).
    pub fn advect_within(
        &mut self,
        carry: impl Fn(Vec3) -> Carry,
        next: &SurfaceIndex,
        shape: &PatchShape,
        grow: &dyn Fn(usize) -> bool,
    ) -> bool {
        let mut keep = vec![true; self.positions.len()];
        let mut still = true;
        for (i, x) in self.positions.iter_mut().enumerate() {
            match carry(*x) {
                Carry::Stay => {}
                Carry::To(point) => {
                    still &= point == *x;
                    *x = point;
                }
                Carry::Far => {
                    keep[i] = false;
                    still = false;
                }
            }
        }
        if !keep.iter().all(|&k| k) {
            self.triangles
                .retain(|t| t.iter().all(|&v| keep[v as usize]));
            self.compact();
        }
        // A midpoint over a gap of the surface (a patch stretched across two
        // droplets) has nothing to land on, so its edge is left whole. The
        // gap is at most the default far distance r/4 even when a user keeps
        // far vertices (`far_fraction` up to 10): otherwise every such edge
        // finds *some* surface within 10 r, is split at every frame, and the
        // patch grows without bound (tens of GB within 16 frames).
        let gap = shape.far_distance.min(GAP_FRACTION * shape.radius);
        let project = |q| next.closest(q, gap).map(|h| h.point);
        let (length, stretch, freeze) =
            (shape.split_length, shape.split_stretch, Freeze::of(shape));
        if self.refine_within(length, stretch, freeze, project, grow) {
            still = false;
        }
        self.still = still;
        !self.triangles.is_empty()
    }

    /// Drops the triangles that can never show a texel again (see
    /// [`Patch::prune`]): those the erosion test erodes wholly
    /// ([`ErosionTest::triangle_verdict`]) at this frame's weights, and,
    /// when weights may rise again (`weights_can_rise`, the paper's w_V
    /// recomputed every frame), only those whose distortion has also passed
    /// δ_max (Q_T = 0, Eq. 1). With `keep_earlier` (a transition) a triangle
    /// must also be eroded at the weights of every frame the transition
    /// reads ([`Patch::weight_before`], [`Patch::weight_older`]): until then
    /// it is still an earlier source. Returns how many went; a still patch is
    /// skipped (its weights, so its verdicts, are last frame's, already
    /// pruned).
    pub fn prune_eroded(
        &mut self,
        test: &ErosionTest,
        shape: &PatchShape,
        weights_can_rise: bool,
        keep_earlier: bool,
    ) -> usize {
        if self.still || self.weight.len() != self.positions.len() {
            return 0;
        }
        let s = shape.exemplar_size;
        let n = self.positions.len();
        // Eroded at a frame's weights; a table of another length is a
        // frame the patch did not exist in.
        let eroded = |uv: [Vec2; 3], w: [f32; 3]| test.triangle_verdict(uv, w) == Verdict::Eroded;
        let eroded_at = |weights: &[f32], t: &[u32; 3], uv: [Vec2; 3]| {
            weights.len() != n || eroded(uv, t.map(|v| weights[v as usize]))
        };
        let earlier = if keep_earlier {
            std::iter::once(&self.weight_before)
                .chain(self.weight_older.iter())
                .collect()
        } else {
            Vec::new()
        };
        let dead: Vec<bool> = self
            .triangles
            .iter()
            .map(|t| {
                let uv = t.map(|v| self.rest[v as usize]);
                let w = t.map(|v| self.weight[v as usize]);
                eroded(uv, w)
                    && earlier.iter().all(|weights| eroded_at(weights, t, uv))
                    && (!weights_can_rise || {
                        let q = t.map(|v| self.positions[v as usize]);
                        distortion(uv.map(|p| p * s), q).delta >= shape.delta_max as f64
                    })
            })
            .collect();
        self.prune(&dead)
    }

    /// Drops the triangles that lie away from what the patch showed
    /// ([`Erosion::prune_hidden`](super::Erosion)): `shown` holds the rest-space cells
    /// ([`rest_cell`], side `cell`) of the texels it showed on this frame
    /// (sorted here); a triangle is kept when its rest-space bounding box,
    /// grown by one cell, meets one of them. So every triangle that holds a
    /// shown texel stays, and every one farther than two cells from all of
    /// them goes. A still patch is skipped (a fluid at rest keeps its
    /// state to the bit). Returns how many went.
    pub fn prune_hidden(&mut self, shown: &mut Vec<(i32, i32)>, cell: f32) -> usize {
        if self.still || cell.is_nan() || cell <= 0.0 {
            return 0;
        }
        shown.sort_unstable();
        shown.dedup();
        let near = |x0: i32, x1: i32, y0: i32, y1: i32| {
            // The cells of column x within y0..=y1 lie together in `shown`.
            (x0..=x1).any(|x| {
                let k = shown.partition_point(|&c| c < (x, y0));
                k < shown.len() && shown[k].0 == x && shown[k].1 <= y1
            })
        };
        let dead: Vec<bool> = self
            .triangles
            .iter()
            .map(|t| {
                let uv = t.map(|v| self.rest[v as usize]);
                let (lo, hi) = (uv[0].min(uv[1]).min(uv[2]), uv[0].max(uv[1]).max(uv[2]));
                let (a, b) = (rest_cell(lo, cell), rest_cell(hi, cell));
                !near(a.0 - 1, b.0 + 1, a.1 - 1, b.1 + 1)
            })
            .collect();
        self.prune(&dead)
    }

    /// Removes the triangles `dead` marks (indexed like `triangles`) and the
    /// vertices only they used; returns how many triangles went.
    ///
    /// Not in the paper, which keeps every triangle a patch was made with:
    /// under stretching, a wholly eroded part of a patch is still advected,
    /// split ([`Patch::refine`]) and located every frame, and since splitting
    /// follows the stretch it grows with the patch's history, not with what
    /// the patch shows (a 38k-triangle liquid at a large radius reached 10⁸
    /// candidate pairs and the machine's whole memory within 23 frames).
    ///
    /// A vertex that was interior and lies on the patch's border only because
    /// its outer triangles went keeps B_V = 1 (it becomes `pinned`): B_V of
    /// Eq. 2 marks the border the patch was carried to, and making the rim of
    /// every pruned region a new border would erode the patch from there
    /// inwards, one ring of triangles after another, which is not the
    /// deformation-driven erosion the weights stand for.
    pub fn prune(&mut self, dead: &[bool]) -> usize {
        let removed = dead.iter().filter(|&&d| d).count();
        if removed == 0 || dead.len() != self.triangles.len() {
            return 0;
        }
        let n = self.positions.len();
        let border_before = Topology::new(n, &self.triangles);
        let keep = |k: usize| !dead[k];
        self.triangles = (0..dead.len())
            .filter(|&k| keep(k))
            .map(|k| self.triangles[k])
            .collect();
        keep_alive(&mut self.lod, dead);
        keep_alive(&mut self.distorted, dead);
        keep_alive(&mut self.mismatched, dead);
        let border_after = Topology::new(n, &self.triangles);
        for (v, pinned) in self.pinned.iter_mut().enumerate() {
            let v = v as u32;
            if !border_before.is_boundary_vertex(v) && border_after.is_boundary_vertex(v) {
                *pinned = true;
            }
        }
        self.compact();
        removed
    }

    /// Drops vertices no triangle uses, renumbering the rest in order.
    fn compact(&mut self) {
        let mut used = vec![false; self.positions.len()];
        for t in &self.triangles {
            for &v in t {
                used[v as usize] = true;
            }
        }
        let mut remap = vec![u32::MAX; used.len()];
        let mut next = 0u32;
        for (i, &u) in used.iter().enumerate() {
            if u {
                remap[i] = next;
                next += 1;
            }
        }
        let pick = |i: &usize| used[*i];
        self.positions = (0..used.len())
            .filter(pick)
            .map(|i| self.positions[i])
            .collect();
        self.rest = (0..used.len()).filter(pick).map(|i| self.rest[i]).collect();
        self.pinned = (0..used.len())
            .filter(pick)
            .map(|i| self.pinned[i])
            .collect();
        for weights in self.weights_mut() {
            if weights.len() == used.len() {
                *weights = (0..used.len()).filter(pick).map(|i| weights[i]).collect();
            } else {
                weights.clear();
            }
        }
        for t in &mut self.triangles {
            *t = t.map(|v| remap[v as usize]);
        }
    }

    /// Bytes held by the patch's per-vertex and per-triangle tables.
    pub fn geometry_bytes(&self) -> usize {
        use std::mem::size_of;
        let weights = self.weight.len()
            + self.weight_before.len()
            + self.weight_older.iter().map(Vec::len).sum::<usize>();
        self.positions.len() * (size_of::<Vec3>() + size_of::<Vec2>() + 1)
            + weights * size_of::<f32>()
            + self.triangles.len() * (size_of::<[u32; 3]>() + size_of::<f32>() + 1)
    }

    /// Whether the patch's tables agree (see [`super::ErosionState::check`]).
    pub fn check(&self) -> Result<(), String> {
        let n = self.positions.len();
        if self.rest.len() != n || self.pinned.len() != n {
            return Err(format!(
                "{n} vertices, {} rest coordinates, {} pins",
                self.rest.len(),
                self.pinned.len()
            ));
        }
        if self.weight.len() != n && !self.weight.is_empty() {
            return Err(format!("{n} vertices, {} weights", self.weight.len()));
        }
        if let Some(v) =
            (0..n).find(|&v| !(self.positions[v].is_finite() && self.rest[v].is_finite()))
        {
            return Err(format!("vertex {v} is not finite"));
        }
        if let Some(v) = self.weight.iter().position(|w| !(0.0..=1.0).contains(w)) {
            return Err(format!("weight {v} is outside [0, 1]"));
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&v) = tri.iter().find(|&&v| v as usize >= n) {
                return Err(format!("triangle {t} names vertex {v} of {n}"));
            }
        }
        Ok(())
    }

    /// Every per-vertex weight table: this frame's, the frame before's and
    /// the older ones a transition keeps; vertex edits apply to all.
    fn weights_mut(&mut self) -> impl Iterator<Item = &mut Vec<f32>> {
        [&mut self.weight, &mut self.weight_before]
            .into_iter()
            .chain(self.weight_older.iter_mut())
    }

    /// Moves the weights of the frame before into the older ones, keeping
    /// `older` of them (a transition of N frames keeps N − 1); call before
    /// [`Patch::update_weights`], which sets the frame before's anew.
    pub fn remember_weights(&mut self, older: usize) {
        if older == 0 {
            self.weight_older.clear();
            return;
        }
        let before = std::mem::take(&mut self.weight_before);
        self.weight_older.insert(0, before);
        self.weight_older.truncate(older);
    }

    /// Recomputes w_V = Q_V · B_V (Eqs. 1–3): Q_T from the triangle's
    /// distortion δ_t between rest shape (rest × S) and current positions,
    /// Q_V the mean of Q_T over the vertex's triangles, B_V = 1 inside the
    /// current patch mesh and near p, 0 on the rest of its boundary.
    ///
    /// With `max_drop` (progressive weights) the new weight is the target
    /// Q_V·B_V limited to [w_prev − max_drop, w_prev]: a weight never rises
    /// again (an eroded texel does not come back on top of a younger patch)
    /// and falls at a bounded rate (erosion advances a little every frame
    /// instead of in jumps when re-meshing jitters Q_V or vertex removal
    /// makes a new boundary). Without it, or on the first call, it is the
    /// paper's w_V.
    pub fn update_weights(&mut self, shape: &PatchShape, max_drop: Option<f32>) {
        let n = self.positions.len();
        let mut sum = vec![0.0f64; n];
        let mut count = vec![0u32; n];
        let s = shape.exemplar_size;
        // uv per world unit of rest shape × feature texels per uv × world per atlas texel.
        let base = shape.texel_size / s * shape.feature_width;
        self.lod.clear();
        self.distorted.clear();
        self.mismatched.clear();
        for t in &self.triangles {
            let rest = t.map(|v| self.rest[v as usize] * s);
            let q = t.map(|v| self.positions[v as usize]);
            let d = distortion(rest, q);
            // Current length / rest length is at least γ: one atlas texel
            // spans at most 1/γ of rest shape.
            let footprint = base as f64 / d.gamma_min.max(1e-6);
            self.lod.push(if footprint > 1.0 {
                footprint.log2() as f32
            } else {
                0.0
            });
            self.distorted.push(d.delta >= shape.delta_max as f64);
            let quality =
                triangle_quality_from(d.delta, shape.delta_onset as f64, shape.delta_max as f64);
            for &v in t {
                sum[v as usize] += quality;
                count[v as usize] += 1;
            }
        }
        let topology = Topology::new(n, &self.triangles);
        let previous = std::mem::take(&mut self.weight);
        self.weight_before = if previous.len() == n {
            previous.clone()
        } else {
            Vec::new()
        };
        let mut target: Vec<f32> = (0..n)
            .map(|v| {
                let q_v = if count[v] > 0 {
                    sum[v] / count[v] as f64
                } else {
                    0.0
                };
                let b_v = if self.pinned[v] || !topology.is_boundary_vertex(v as u32) {
                    1.0
                } else {
                    0.0
                };
                (q_v * b_v) as f32
            })
            .collect();
        if max_drop.is_some() && self.still && previous.len() == n {
            self.weight = previous;
            return;
        }
        if let Some(drop) = max_drop
            && previous.len() == n
        {
            for (w, &before) in target.iter_mut().zip(&previous) {
                *w = w.min(before).max(before - drop);
            }
        }
        self.weight = target;
    }
}

impl Patch {
    /// Whether triangle `j` shows nothing under the hard bound
    /// ([`super::Bound::Hard`]): it is past δ_max ([`Patch::distorted`])
    /// and some corner's weight is below 1. A triangle stretched past δ_max
    /// by the flow has Q_T = 0, so its corners' weights fall below 1 on the
    /// frame it gets there; the corners still at 1 are a new patch's
    /// centre, which progressive weights hold whole at creation
    /// (`whole_centre`) and keep while the patch does not move. A
    /// flattening can leave the seed's own triangle past δ_max from the
    /// start, and a patch that never showed its seed texel would be
    /// deleted and made again every frame, even on a liquid at rest.
    pub fn past_bound(&self, j: u32) -> bool {
        let j = j as usize;
        let whole = |t: &[u32; 3]| {
            t.iter()
                .all(|&v| self.weight.get(v as usize).is_some_and(|&w| w >= 1.0))
        };
        self.distorted.get(j).is_some_and(|&d| d)
            && self.triangles.get(j).is_some_and(|t| !whole(t))
    }

    /// Lowers the weight of every vertex `mismatched` marks (its exemplar
    /// no longer matches the selecting attribute where it lies,
    /// [`crate::exemplar::SelectBy`]) by the drop it gives below the
    /// frame before's, to no less than 0, as a distorted vertex falls: the
    /// other exemplar then takes the texels over along the feature map,
    /// not by a cross-fade. Never raises a weight; vertices without a
    /// weight the frame before (none yet) keep theirs. Call after
    /// [`Patch::update_weights`].
    pub fn lower_mismatched(&mut self, mismatched: &[Option<f32>]) {
        let n = self.weight.len();
        self.mismatched.clear();
        if mismatched.len() != n {
            return;
        }
        self.mismatched = (self.triangles.iter())
            .map(|t| t.iter().any(|&v| mismatched[v as usize].is_some()))
            .collect();
        if self.weight_before.len() != n {
            return;
        }
        for ((w, &before), &m) in self
            .weight
            .iter_mut()
            .zip(&self.weight_before)
            .zip(mismatched)
        {
            if let Some(drop) = m {
                *w = w.min((before - drop).max(0.0));
            }
        }
    }
}

/// Keeps the per-triangle `values` of the triangles `dead` does not mark;
/// values that do not match the triangles (not computed yet) are cleared.
fn keep_alive<T: Copy>(values: &mut Vec<T>, dead: &[bool]) {
    if values.len() == dead.len() {
        *values = (values.iter().zip(dead))
            .filter(|(_, d)| !**d)
            .map(|(v, _)| *v)
            .collect();
    } else {
        values.clear();
    }
}
