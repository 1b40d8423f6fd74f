//! The candidate search of the lapped fill: per frame, every patch
//! triangle is matched with the fluid triangles its slightly enlarged
//! bounding box (a prism around the triangle, as thick as the locate
//! tolerance) meets, through the fluid mesh's BVH, and the pairs are sorted
//! into per-fluid-triangle lists in patch order (oldest first). Also the
//! per-triangle projection frames ([`TriFrame`]) the fill locates points
//! with, and the tolerance ([`LocateTolerance`]) both share.

use glam::Vec3;
use rayon::prelude::*;

use super::super::erode::Verdict;
use super::super::patch::Patch;
use crate::mesh::TriMesh;
use crate::methods::lapped::TriangleLists;
use crate::surface::SurfaceIndex;
use crate::surface::bvh::boxes_meet;

/// How a surface point is located in a patch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocateTolerance {
    /// Smallest barycentric accepted (a small negative number).
    pub min_bary: f32,
    /// Largest distance of the point from the patch triangle's plane.
    pub max_plane_distance: f32,
}

impl LocateTolerance {
    /// The method's tolerance for patches of radius `radius`: barycentrics
    /// down to −0.05 (closing the slivers between neighbouring chords) and
    /// an eighth of the radius off the triangle's plane.
    pub fn for_radius(radius: f32) -> LocateTolerance {
        LocateTolerance {
            min_bary: -0.05,
            max_plane_distance: 0.125 * radius,
        }
    }

    /// Whether a point with barycentrics `bary` in a patch triangle and
    /// `plane` off its plane lies in it: within the tolerance, so a patch
    /// triangle also covers a thin band past its edges.
    #[inline]
    pub fn holds(&self, bary: [f32; 3], plane: f32) -> bool {
        plane.abs() <= self.max_plane_distance && bary[0].min(bary[1]).min(bary[2]) >= self.min_bary
    }
}

/// Precomputed projection onto one patch triangle's plane: barycentrics
/// of the projection of x are (1 − l1 − l2, l1, l2) with l1 = d1·(x − o),
/// l2 = d2·(x − o) (dual basis of the edge vectors).
#[derive(Clone, Copy, Debug)]
pub struct TriFrame {
    origin: Vec3,
    d1: Vec3,
    d2: Vec3,
    pub(in crate::methods::erosion) normal: Vec3,
}

impl TriFrame {
    /// `None` for a degenerate (collapsed) triangle, which then covers nothing.
    pub fn new(a: Vec3, b: Vec3, c: Vec3) -> Option<TriFrame> {
        let (e1, e2) = (b - a, c - a);
        let (g11, g12, g22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let det = g11 * g22 - g12 * g12;
        let normal = e1.cross(e2).normalize_or_zero();
        if det <= f32::EPSILON * g11 * g22 || normal == Vec3::ZERO {
            return None;
        }
        let inv = 1.0 / det;
        Some(TriFrame {
            origin: a,
            d1: (e1 * g22 - e2 * g12) * inv,
            d2: (e2 * g11 - e1 * g12) * inv,
            normal,
        })
    }

    /// False when no point of fluid triangle `f` can be located in this
    /// triangle: the fluid triangle faces away, or all its corners lie
    /// beyond the same plane of the tolerance prism (the prism and the
    /// triangle are convex, so one separating plane suffices).
    #[inline]
    pub fn may_cover(&self, fluid: &FluidTriangle, tolerance: LocateTolerance) -> bool {
        if fluid.cross.dot(self.normal) <= 0.0 {
            return false;
        }
        let corners = fluid.corners.map(|q| self.locate(q));
        let d = tolerance.max_plane_distance;
        if corners.iter().all(|(_, h)| *h > d) || corners.iter().all(|(_, h)| *h < -d) {
            return false;
        }
        (0..3).all(|k| corners.iter().any(|(b, _)| b[k] >= tolerance.min_bary))
    }

    /// Barycentrics of the projection of `x` and its signed plane distance.
    #[inline]
    pub fn locate(&self, x: Vec3) -> ([f32; 3], f32) {
        let d = x - self.origin;
        let (l1, l2) = (self.d1.dot(d), self.d2.dot(d));
        ([1.0 - l1 - l2, l1, l2], self.normal.dot(d))
    }
}

/// A fluid triangle's corners and edge cross product, side by side: the
/// candidate search tests each fluid triangle against every patch triangle
/// whose box it meets, and gathering them through the index buffer each
/// time cost more than the test itself at the papers' mesh sizes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FluidTriangle {
    pub corners: [Vec3; 3],
    /// (b − a) × (c − a), as [`TriMesh::triangle_cross`].
    pub cross: Vec3,
}

/// [`FluidTriangle`]s of one frame's mesh, by triangle index.
pub struct FluidTriangles(Vec<FluidTriangle>);

impl FluidTriangles {
    pub fn new(mesh: &TriMesh) -> FluidTriangles {
        FluidTriangles(
            (0..mesh.triangle_count())
                .into_par_iter()
                .map(|t| FluidTriangle {
                    corners: mesh.corners(t),
                    cross: mesh.triangle_cross(t),
                })
                .collect(),
        )
    }

    /// Triangle `f` (the BVH only yields indices of the mesh it was built
    /// on, which this was built from too).
    #[inline]
    pub fn get(&self, f: u32) -> Option<&FluidTriangle> {
        self.0.get(f as usize)
    }

    pub fn len(&self) -> usize {
        self.0.len()
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// Locating frames of every triangle of every patch, in patch order.
pub fn patch_frames(patches: &[Patch]) -> Vec<Vec<Option<TriFrame>>> {
    patches
        .par_iter()
        .map(|p| {
            p.triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|v| p.positions[v as usize]);
                    TriFrame::new(a, b, c)
                })
                .collect()
        })
        .collect()
}

/// Pairs counted at once against a frame's memory budget
/// ([`Candidates::build_within`]): 2 MiB of pairs per count.
pub const GROW_PAIRS: usize = 1 << 16;

/// Bytes counted per candidate pair: held twice at the peak (a patch's
/// own list and the grouped lists), 8 bytes each, doubled for the
/// vectors' spare capacity.
const PAIR_BYTES: usize = 32;

/// Per fluid triangle, the (patch index, patch triangle) pairs that may
/// cover its texels, sorted by patch index (= age) then triangle
/// ([`TriangleLists`]: `of`, `len`, `is_empty`).
pub struct Candidates(TriangleLists<(u32, u32)>);

impl std::ops::Deref for Candidates {
    type Target = TriangleLists<(u32, u32)>;

    fn deref(&self) -> &TriangleLists<(u32, u32)> {
        &self.0
    }
}

impl Candidates {
    /// Matches every patch triangle with the fluid triangles that may hold
    /// texels it covers: those whose bounding box meets the patch
    /// triangle's, enlarged by the plane tolerance (a BVH query), that face
    /// the same side and that are not separated from the triangle's
    /// tolerance prism by one of its planes ([`TriFrame::may_cover`]). The
    /// prism test is exact for what [`super::FillContext::locate`] accepts, so it
    /// prunes without changing any result.
    pub fn build(
        fluid: &FluidTriangles,
        index: &SurfaceIndex,
        patches: &[Patch],
        frames: &[Vec<Option<TriFrame>>],
        tolerance: LocateTolerance,
    ) -> Candidates {
        Candidates::build_within(fluid, index, patches, frames, tolerance, &|_| true)
    }

    /// [`Candidates::build`], counting the bytes of every [`GROW_PAIRS`]
    /// pairs of a patch with `grow` as they are held (a frame's memory
    /// budget, [`crate::methods::budget`]); where `grow` refuses, no more
    /// pairs are kept and the list is incomplete (the frame then ends on
    /// the budget's error).
    pub fn build_within(
        fluid: &FluidTriangles,
        index: &SurfaceIndex,
        patches: &[Patch],
        frames: &[Vec<Option<TriFrame>>],
        tolerance: LocateTolerance,
        grow: &(dyn Fn(usize) -> bool + Sync),
    ) -> Candidates {
        let per_patch: Vec<Vec<(u32, u32)>> = patches
            .par_iter()
            .zip(frames.par_iter())
            .map(|(p, frames)| {
                // A pair is held twice at the peak (here and in the
                // grouped lists), 8 bytes each, with spare capacity: 32
                // bytes counted per pair, every GROW_PAIRS pairs and for
                // the rest at the end.
                let mut out = Vec::new();
                let mut refused = false;
                patch_pairs(fluid, index, p, frames, tolerance, |f, j| {
                    if !refused {
                        out.push((f, j));
                        if out.len() % GROW_PAIRS == 0 {
                            refused = !grow(GROW_PAIRS * PAIR_BYTES);
                        }
                    }
                });
                if !refused {
                    grow(out.len() % GROW_PAIRS * PAIR_BYTES);
                }
                out
            })
            .collect();
        // Grouped in (patch, triangle) order, so each list is in that order.
        Candidates(TriangleLists::from_groups(
            &per_patch,
            fluid.len(),
            |i, j| (i as u32, j),
        ))
    }

    /// The candidates without the patches that cannot show on a fluid
    /// triangle because every one of their triangles listed there is
    /// wholly eroded (`verdicts` from [`super::FillContext::erosion_verdicts`]). Whichever of
    /// those triangles would hold a texel, the lapped decision passes the
    /// patch by, so the lapped fill's result is unchanged; the blended fill,
    /// which shows eroded layers too, must keep them.
    pub fn without_eroded(self, verdicts: &[Vec<Verdict>]) -> Candidates {
        let eroded = |&(i, j): &(u32, u32)| {
            verdicts.get(i as usize).and_then(|v| v.get(j as usize)) == Some(&Verdict::Eroded)
        };
        Candidates(
            self.0
                .retain_runs(|a, b| a.0 == b.0, |run| !run.iter().all(eroded)),
        )
    }
}

/// The candidate pairs of one patch, as `emit(fluid triangle, patch
/// triangle)`: patch triangle by patch triangle in order, the fluid
/// triangles whose bounding box meets the patch triangle's box enlarged by
/// the plane tolerance and that pass [`TriFrame::may_cover`], each once
/// (in no particular order within one patch triangle).
///
/// One BVH query per patch triangle made this the costliest part of the
/// fill on fine meshes (3.3 s of 7.4 per frame on one core at 300k
/// triangles: 740k patch triangles, each query descending the whole
/// tree). A patch's triangles lie close together, so one query for the
/// whole patch's box gathers every fluid triangle any of them can meet,
/// and a uniform grid over those ([`NearGrid`]) answers each patch
/// triangle from a few cells. The test per fluid triangle is the BVH's own
/// on the BVH's boxes ([`boxes_meet`]), so the pairs are exactly those of
/// one BVH query per patch triangle.
pub(crate) fn patch_pairs(
    fluid: &FluidTriangles,
    index: &SurfaceIndex,
    patch: &Patch,
    frames: &[Option<TriFrame>],
    tolerance: LocateTolerance,
    mut emit: impl FnMut(u32, u32),
) {
    if let Some(search) = PairSearch::new(index, patch, frames, tolerance) {
        search.walk(fluid, frames, tolerance, 0..frames.len(), &mut emit);
    }
}

/// [`patch_pairs`] as a list, the patch's triangles split between threads:
/// each range of patch triangles keeps its own record of tested fluid
/// triangles, and the ranges' pairs are joined in order, so the list is
/// the one [`patch_pairs`] emits. For one large patch at a time (the
/// update's), where nothing else runs beside it.
pub(crate) fn patch_pairs_list(
    fluid: &FluidTriangles,
    index: &SurfaceIndex,
    patch: &Patch,
    frames: &[Option<TriFrame>],
    tolerance: LocateTolerance,
) -> Vec<(u32, u32)> {
    /// Patch triangles per range: a few BVH-cell walks each, enough to
    /// outweigh a range's own record.
    const RANGE: usize = 64;
    patch_pairs_ranged(fluid, index, patch, frames, tolerance, RANGE)
}

/// [`patch_pairs_list`] in ranges of `range` patch triangles.
pub(crate) fn patch_pairs_ranged(
    fluid: &FluidTriangles,
    index: &SurfaceIndex,
    patch: &Patch,
    frames: &[Option<TriFrame>],
    tolerance: LocateTolerance,
    range: usize,
) -> Vec<(u32, u32)> {
    let range = range.max(1);
    let Some(search) = PairSearch::new(index, patch, frames, tolerance) else {
        return Vec::new();
    };
    let ranges: Vec<std::ops::Range<usize>> = (0..frames.len())
        .step_by(range)
        .map(|a| a..(a + range).min(frames.len()))
        .collect();
    ranges
        .into_par_iter()
        .flat_map_iter(|range| {
            let mut pairs = Vec::new();
            search.walk(fluid, frames, tolerance, range, &mut |f, j| {
                pairs.push((f, j))
            });
            pairs
        })
        .collect()
}

/// One patch's pair search: its triangles' prism boxes and the fluid
/// triangles near the patch ([`patch_pairs`]).
struct PairSearch {
    boxes: Vec<Option<(Vec3, Vec3)>>,
    grid: NearGrid,
}

impl PairSearch {
    /// `None` when no triangle of the patch can hold a point.
    fn new(
        index: &SurfaceIndex,
        patch: &Patch,
        frames: &[Option<TriFrame>],
        tolerance: LocateTolerance,
    ) -> Option<PairSearch> {
        let boxes: Vec<Option<(Vec3, Vec3)>> = patch
            .triangles
            .iter()
            .zip(frames)
            .map(|(t, frame)| {
                let frame = frame.as_ref()?;
                Some(prism_box(
                    t.map(|v| patch.positions[v as usize]),
                    frame,
                    tolerance,
                ))
            })
            .collect();
        let (lo, hi) = boxes
            .iter()
            .flatten()
            .copied()
            .reduce(|(l0, h0), (l1, h1)| (l0.min(l1), h0.max(h1)))?;
        let grid = NearGrid::new(index, lo, hi);
        Some(PairSearch { boxes, grid })
    }

    /// Emits the pairs of the patch triangles in `range`, in order.
    fn walk(
        &self,
        fluid: &FluidTriangles,
        frames: &[Option<TriFrame>],
        tolerance: LocateTolerance,
        range: std::ops::Range<usize>,
        emit: &mut impl FnMut(u32, u32),
    ) {
        let grid = &self.grid;
        // The patch triangle that last tested each gathered fluid triangle:
        // one found in several cells of a query is tested once.
        let mut tested = vec![u32::MAX; grid.triangles.len()];
        for j in range {
            let (Some(Some((lo, hi))), Some(Some(frame))) = (self.boxes.get(j), frames.get(j))
            else {
                continue;
            };
            let (j, lo, hi) = (j as u32, *lo, *hi);
            grid.visit(lo, hi, |k| {
                let (f, (a, b)) = (grid.triangles[k], grid.boxes[k]);
                if std::mem::replace(&mut tested[k], j) != j
                    && boxes_meet(a, b, lo, hi)
                    && fluid.get(f).is_some_and(|t| frame.may_cover(t, tolerance))
                {
                    emit(f, j);
                }
            });
        }
    }
}

/// A box around every point a texel can be located at in the patch
/// triangle `corners` ([`super::FillContext::locate`]: smallest barycentric ≥
/// `min_bary`, plane distance ≤ `max_plane_distance`): the box of that
/// prism (the triangle grown to the barycentric tolerance, swept along its
/// normal), widened by a slack far above float rounding, and never beyond
/// the triangle's own box grown by the plane distance on every axis.
///
/// The grown box on every axis was the first filter of the candidate
/// search; on a fine mesh it holds about five times the fluid triangles
/// that the prism test keeps, and the prism test per fluid triangle was
/// most of the search. A fluid triangle whose box misses this one cannot
/// hold a texel the patch triangle would take, so no texel's answer
/// changes; only the count of candidate pairs drops.
pub(crate) fn prism_box(
    corners: [Vec3; 3],
    frame: &TriFrame,
    tolerance: LocateTolerance,
) -> (Vec3, Vec3) {
    let [a, b, c] = corners;
    let m = tolerance.min_bary;
    let d = tolerance.max_plane_distance;
    let grown = [
        a + (b - a) * m + (c - a) * m,
        b + (a - b) * m + (c - b) * m,
        c + (a - c) * m + (b - c) * m,
    ];
    let sweep = frame.normal.abs() * d;
    let lo = grown[0].min(grown[1]).min(grown[2]) - sweep;
    let hi = grown[0].max(grown[1]).max(grown[2]) + sweep;
    let slack =
        Vec3::splat(1e-3 * (hi - lo).max_element() + 1e-6 * lo.abs().max(hi.abs()).max_element());
    let margin = Vec3::splat(d);
    (
        (lo - slack).max(a.min(b).min(c) - margin),
        (hi + slack).min(a.max(b).max(c) + margin),
    )
}

/// The fluid triangles whose box meets one box (a patch's), binned by their
/// boxes on a uniform grid over it, so that a box within it finds the
/// triangles it may meet in the few cells it covers. Written here because
/// the BVH crates at hand answer one box at a time from the root, and the
/// point of this is to answer hundreds of nearby boxes from one gather;
/// the bins are the project's [`TriangleLists`], keyed by cell.
/// The cell of a coordinate is one monotone function of it, for triangle
/// boxes and query boxes alike, so two boxes that meet share a cell.
pub(crate) struct NearGrid {
    /// The gathered fluid triangles ...
    triangles: Vec<u32>,
    /// ... and their boxes ([`SurfaceIndex::triangle_box`]).
    boxes: Vec<(Vec3, Vec3)>,
    cells: Cells,
    /// Per cell, indices into `triangles`.
    bins: TriangleLists<u32>,
}

/// The cells of a [`NearGrid`].
#[derive(Clone, Copy, Debug)]
struct Cells {
    origin: Vec3,
    /// Cells per unit length (0: one cell).
    scale: f32,
    dims: [usize; 3],
}

impl Cells {
    /// The cell of coordinate `x` on `axis`: monotone in `x`, clamped to
    /// the grid (the saturating cast takes negatives and NaN to 0).
    #[inline]
    fn cell(&self, x: f32, axis: usize) -> usize {
        let o = self.origin.to_array()[axis];
        (((x - o) * self.scale) as usize).min(self.dims[axis] - 1)
    }

    /// Calls `f` with every cell (x fastest) the box `[lo, hi]` covers.
    #[inline]
    fn each(&self, lo: Vec3, hi: Vec3, mut f: impl FnMut(usize)) {
        let (lo, hi) = (lo.to_array(), hi.to_array());
        let range = |axis: usize| self.cell(lo[axis], axis)..=self.cell(hi[axis], axis);
        let [dx, dy, _] = self.dims;
        for z in range(2) {
            for y in range(1) {
                for x in range(0) {
                    f(x + dx * (y + dy * z));
                }
            }
        }
    }

    /// Cells about `size` wide over `extent`, at most `budget` of them
    /// (larger cells where more would be needed).
    fn fit(origin: Vec3, extent: Vec3, mut size: f32, budget: usize) -> Cells {
        loop {
            if !(size > 0.0 && size.is_finite()) {
                return Cells {
                    origin,
                    scale: 0.0,
                    dims: [1; 3],
                };
            }
            // Saturating casts: a non-finite extent gives a huge count,
            // which the budget sends round again with larger cells.
            let dims = (extent / size)
                .to_array()
                .map(|e| (e as usize).saturating_add(1));
            let count = dims.iter().try_fold(1usize, |n, &d| n.checked_mul(d));
            if count.is_some_and(|n| n <= budget) {
                return Cells {
                    origin,
                    scale: 1.0 / size,
                    dims,
                };
            }
            size *= 2.0;
        }
    }
}

impl NearGrid {
    /// Gathers the triangles of `index` whose box meets `[lo, hi]` and bins
    /// them on cells about as large as their boxes, at most four cells per
    /// triangle (and 64 more).
    pub(crate) fn new(index: &SurfaceIndex, lo: Vec3, hi: Vec3) -> NearGrid {
        let mut triangles = Vec::new();
        index.triangles_in_box(lo, hi, |f| triangles.push(f));
        // A triangle the index gave always has a box; the fallback only
        // keeps this total.
        let boxes: Vec<(Vec3, Vec3)> = triangles
            .iter()
            .map(|&f| index.triangle_box(f).unwrap_or((lo, hi)))
            .collect();
        let extent = (hi - lo).max(Vec3::ZERO);
        let mean = boxes
            .iter()
            .map(|(a, b)| (*b - *a).max_element())
            .filter(|e| e.is_finite())
            .sum::<f32>()
            / boxes.len().max(1) as f32;
        // Cell size barely matters (0.5 to 4 times this measured within
        // 10 % at 300k triangles): the prism boxes keep the queries small.
        let size = mean.max(extent.max_element() / 256.0);
        let cells = Cells::fit(lo, extent, size, 4 * triangles.len() + 64);
        // (cell, triangle) pairs grouped by cell: the lists the candidate
        // search keeps per fluid triangle, here per cell.
        let mut pairs = Vec::new();
        for (k, (a, b)) in boxes.iter().enumerate() {
            cells.each(*a, *b, |c| pairs.push((c as u32, k as u32)));
        }
        let [dx, dy, dz] = cells.dims;
        let bins = TriangleLists::build(&pairs, dx * dy * dz);
        NearGrid {
            triangles,
            boxes,
            cells,
            bins,
        }
    }

    /// Calls `f` with the index (into the gathered triangles) of every
    /// entry in the cells the box `[lo, hi]` covers; a triangle in several
    /// of them comes once per cell.
    #[inline]
    fn visit(&self, lo: Vec3, hi: Vec3, mut f: impl FnMut(usize)) {
        self.cells.each(lo, hi, |c| {
            for &k in self.bins.of(c as u32) {
                f(k as usize);
            }
        });
    }
}
