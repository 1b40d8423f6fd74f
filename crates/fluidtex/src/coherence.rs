//! Temporal coherence of a method's output between two frames: does the
//! texture ride the flow? Measures [`metrics::source_switch`] and
//! [`metrics::colour_follow`] on atlases, the way a user would check run
//! outputs (`source.F.exr` and the colour atlas of two consecutive frames).
//!
//! 1. [`sample_surface`]: `samples` points on M_t, area-weighted, from a
//!    seeded RNG (sequential draws: the same points for any thread count).
//! 2. Carry each point to frame t+1 and locate it on M_{t+1} (closest
//!    point), together with the *unmoved* point's location:
//!    [`carry_by_velocity`] with the meshes' per-vertex velocity, or
//!    [`Carried::locate`] with positions the caller carried (the evaluation
//!    harness traces the scene's exact flow).
//! 3. [`measure`]: the source at both ends (nearest texel) and the grey
//!    value at t, at the carried point and at the unmoved point at t+1
//!    (bilinear); the distance moved in atlas texels of t+1.
//!
//! [`switch_map`] is the per-texel picture of the same question for
//! `switch.F.png`: every covered texel of frame t+1 carried *back* to frame
//! t, and whether its source was the same there.
//!
//! **Velocity carry** (real simulations have no exact flow): a second-order
//! step, the velocity at t averaged with the velocity at t+1 sampled at the
//! first-order end point (closest point of M_{t+1}):
//! `q = p + dt/2 · (v_t(p) + v_{t+1}(p + dt · v_t(p)))`.
//!
//! **Lookups.** A surface point's atlas position is its triangle's atlas uv
//! interpolated at its barycentrics, in texels `(u W, v H)` (texel centres
//! at +0.5, [`crate::texture`]). The source is read at the texel containing
//! that position (ids cannot be interpolated): near a chart border that
//! texel can lie outside the chart, and the point then counts as not
//! covered — part of the measurement's floor. Grey values are bilinear on
//! the gutter-dilated atlas, so chart borders read chart colours.

use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;

use crate::atlas::{Atlas, BAND_HEIGHT};
use crate::mesh::TriMesh;
use crate::metrics::{
    self, ColourFollow, MetricsError, SOURCE_OUTSIDE, SourceSwitch, SwitchCauses, Thresholds,
    is_patch,
};
use crate::provenance::{RENEWAL_UNKNOWN, renewal_forced};
use crate::surface::velocity::FlowFrame;
use crate::surface::{SurfaceIndex, SurfacePoint, map_in_query_order};
use crate::texture::Texture;

/// How the coherence metrics are sampled (from the committed thresholds).
#[derive(Clone, Debug, PartialEq)]
pub struct CoherenceSettings {
    /// Points sampled on frame t [20 000].
    pub samples: usize,
    /// Seed of the sample positions [thresholds: 2021].
    pub seed: u64,
    /// Points moving fewer atlas texels are not used by the colour follow
    /// ratio \[3].
    pub min_move_texels: f32,
    /// Fewer moving points give no colour follow ratio \[200].
    pub min_moving_samples: usize,
}

impl CoherenceSettings {
    /// The settings of the committed thresholds file.
    pub fn from_thresholds(t: &Thresholds) -> CoherenceSettings {
        CoherenceSettings {
            samples: t.source_switch.samples as usize,
            seed: t.source_switch.seed,
            min_move_texels: t.colour_follow.min_move_texels,
            min_moving_samples: t.colour_follow.min_moving_samples as usize,
        }
    }
}

/// `count` points on `mesh`, uniformly distributed by area, from `seed`.
/// Empty for a mesh without area.
pub fn sample_surface(mesh: &TriMesh, count: usize, seed: u64) -> Vec<SurfacePoint> {
    let mut cumulative = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0f64;
    for t in 0..mesh.triangles.len() {
        total += mesh.triangle_area(t) as f64;
        cumulative.push(total);
    }
    if !(total > 0.0 && total.is_finite()) {
        return Vec::new();
    }
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..count)
        .map(|_| {
            let r = rng.random::<f64>() * total;
            // First triangle whose cumulative area exceeds r: zero-area
            // triangles are never chosen.
            let t = cumulative
                .partition_point(|&c| c <= r)
                .min(cumulative.len() - 1);
            // Uniform on the triangle (square-root warp of the unit square).
            let s = rng.random::<f32>().sqrt();
            let u = rng.random::<f32>();
            SurfacePoint::new(t as u32, [1.0 - s, s * (1.0 - u), s * u])
        })
        .collect()
}

/// Points of frame t and where they are at frame t+1.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Carried {
    /// The sample points on M_t.
    pub from: Vec<SurfacePoint>,
    /// The carried point's closest location on M_{t+1} (`None`: it could
    /// not be carried or M_{t+1} is empty).
    pub to: Vec<Option<SurfacePoint>>,
    /// The unmoved point's closest location on M_{t+1}.
    pub still: Vec<Option<SurfacePoint>>,
    /// Distance between the point and its carried position (world units;
    /// NaN where not carried).
    pub moved: Vec<f32>,
}

impl Carried {
    /// Locates on M_{t+1} (`next`) the points `from` of `from_mesh` and
    /// their `carried` positions (one per point, `None` where the caller
    /// could not carry it). Parallel; the result does not depend on the
    /// thread count.
    pub fn locate(
        from_mesh: &TriMesh,
        from: Vec<SurfacePoint>,
        carried: &[Option<Vec3>],
        next: &SurfaceIndex,
    ) -> Carried {
        let at = Placed::of(from_mesh, &from);
        Carried::locate_placed(search_hint(from_mesh), from, &at, carried, next)
    }

    /// [`Carried::locate`] with the points' positions already found.
    fn locate_placed(
        hint: f32,
        from: Vec<SurfacePoint>,
        at: &Placed,
        carried: &[Option<Vec3>],
        next: &SurfaceIndex,
    ) -> Carried {
        let closest = |p: Vec3| {
            next.closest(p, hint)
                .or_else(|| next.closest_unbounded(p))
                .map(|h| h.location)
        };
        let located: Vec<(Option<SurfacePoint>, Option<SurfacePoint>, f32)> = at.map(|i, p| {
            let q = carried.get(i).copied().flatten().filter(|q| q.is_finite());
            let still = p.and_then(closest);
            match (p, q) {
                (Some(p), Some(q)) => (closest(q), still, (q - p).length()),
                _ => (None, still, f32::NAN),
            }
        });
        let mut out = Carried {
            from,
            ..Carried::default()
        };
        for (to, still, moved) in located {
            out.to.push(to);
            out.still.push(still);
            out.moved.push(moved);
        }
        out
    }
}

/// Carries `from` (points of `prev`) to frame t+1 by the meshes' per-vertex
/// velocity with the second-order step of the module doc, `dt` seconds.
/// `prev_velocity` is `prev`'s per-vertex velocity; `next` the frame t+1
/// flow frame.
pub fn carry_by_velocity(
    prev: &TriMesh,
    prev_velocity: &[Vec3],
    next: FlowFrame<'_>,
    dt: f32,
    from: Vec<SurfacePoint>,
) -> Carried {
    Departure::of(prev, prev_velocity, from).carry(next, dt)
}

/// What [`carry_by_velocity`] reads of frame t, taken while frame t is at
/// hand: each sample point's position and velocity there. The frame job
/// keeps this (a few hundred kB for 20 000 points) instead of frame t's
/// mesh, closest-point index and atlas (~130 MB at 300k triangles), which
/// it would otherwise hold until frame t+1 is measured.
#[derive(Clone, Debug)]
pub struct Departure {
    hint: f32,
    from: Vec<SurfacePoint>,
    at: Placed,
    /// `v_t` at each point; `None` where the point has no position or
    /// velocity.
    velocity: Vec<Option<Vec3>>,
}

impl Departure {
    /// The points `from` of `prev`, whose per-vertex velocity is
    /// `prev_velocity`.
    pub fn of(prev: &TriMesh, prev_velocity: &[Vec3], from: Vec<SurfacePoint>) -> Departure {
        let at = Placed::of(prev, &from);
        let velocity = from
            .par_iter()
            .zip(at.positions.par_iter())
            .map(|(sp, p)| p.and_then(|_| interpolate(prev, prev_velocity, sp)))
            .collect();
        Departure {
            hint: search_hint(prev),
            from,
            at,
            velocity,
        }
    }

    /// The sample points, on frame t's mesh.
    pub fn points(&self) -> &[SurfacePoint] {
        &self.from
    }

    /// The points carried to frame t+1 (`next`) and located there.
    pub fn carry(&self, next: FlowFrame<'_>, dt: f32) -> Carried {
        let carried: Vec<Option<Vec3>> = self.at.map(|i, p| {
            let p = p?;
            let v0 = self.velocity[i]?;
            let v1 = next.sample(p + v0 * dt, self.hint)?;
            Some(p + (v0 + v1) * (0.5 * dt))
        });
        Carried::locate_placed(self.hint, self.from.clone(), &self.at, &carried, next.index)
    }
}

/// Sample points' positions on their mesh (`None` where a point has none),
/// found once for every pass over them. The points are random, so each
/// pass runs its closest-point queries in [`map_in_query_order`]: queries
/// close in space follow each other and revisit the same part of the tree
/// (the coherence stage took half the time at 20 000 points on 85k
/// triangles), and every answer is the same as in index order.
#[derive(Clone, Debug)]
struct Placed {
    positions: Vec<Option<Vec3>>,
    /// The positions as query keys; NaN where none (queried last).
    keys: Vec<Vec3>,
}

impl Placed {
    fn of(mesh: &TriMesh, points: &[SurfacePoint]) -> Placed {
        let positions: Vec<Option<Vec3>> = points.par_iter().map(|sp| position(mesh, sp)).collect();
        let keys = positions.iter().map(|p| p.unwrap_or(Vec3::NAN)).collect();
        Placed { positions, keys }
    }

    /// `f(i, position of point i)` for every point, in index order.
    fn map<T: Send>(&self, f: impl Fn(usize, Option<Vec3>) -> T + Sync) -> Vec<T> {
        map_in_query_order(&self.keys, |i| f(i, self.positions[i]))
    }
}

/// One frame's output as the coherence metrics read it: per texel (row-major
/// index) its source and grey value. [`TexelFrame`] holds both as arrays;
/// the frame job reads them straight from the method's result
/// (`pipeline`), without atlas-sized copies.
pub trait Texels: Sync {
    /// The frame's atlas (size, uv mesh, texel scale).
    fn atlas(&self) -> &Atlas;
    /// Provenance of texel `i` (the values of [`crate::metrics`]),
    /// [`SOURCE_OUTSIDE`] out of range.
    fn source(&self, i: usize) -> u32;
    /// Grey value of texel `i` (luminance of the gutter-dilated colour
    /// atlas, [`metrics::luminance`]), NaN out of range.
    fn grey(&self, i: usize) -> f32;
    /// Renewal byte of texel `i` ([`crate::provenance::RENEWAL_HELD`] and
    /// the other flags): what became of the patch that showed the point
    /// the frame before. [`RENEWAL_UNKNOWN`] where the method does not say.
    fn renewal(&self, i: usize) -> u8 {
        let _ = i;
        RENEWAL_UNKNOWN
    }
    /// Both per-texel arrays fit the atlas.
    fn validate(&self) -> Result<(), MetricsError>;
}

/// One frame's output as arrays.
#[derive(Clone, Copy)]
pub struct TexelFrame<'a> {
    pub atlas: &'a Atlas,
    /// Provenance per texel (the values of [`crate::metrics`]).
    pub source: &'a [u32],
    /// Grey value per texel (luminance of the gutter-dilated colour atlas,
    /// [`metrics::luminance`]).
    pub grey: &'a [f32],
    /// Renewal byte per texel ([`Texels::renewal`]); empty where the
    /// method records none.
    pub renewal: &'a [u8],
}

impl Texels for TexelFrame<'_> {
    fn atlas(&self) -> &Atlas {
        self.atlas
    }

    fn source(&self, i: usize) -> u32 {
        self.source.get(i).copied().unwrap_or(SOURCE_OUTSIDE)
    }

    fn grey(&self, i: usize) -> f32 {
        self.grey.get(i).copied().unwrap_or(f32::NAN)
    }

    fn renewal(&self, i: usize) -> u8 {
        self.renewal.get(i).copied().unwrap_or(RENEWAL_UNKNOWN)
    }

    fn validate(&self) -> Result<(), MetricsError> {
        metrics::check_len("source", self.source, self.atlas.width, self.atlas.height)?;
        metrics::check_len("grey", self.grey, self.atlas.width, self.atlas.height)?;
        if self.renewal.is_empty() {
            Ok(())
        } else {
            metrics::check_len("renewal", self.renewal, self.atlas.width, self.atlas.height)
        }
    }
}

/// The position of `sp` in `frame`'s atlas, in texels.
fn atlas_position(frame: &impl Texels, sp: &SurfacePoint) -> Option<Vec2> {
    let atlas = frame.atlas();
    let uv = &atlas.uv_mesh;
    let tri = uv.triangles.get(sp.triangle as usize)?;
    let mut p = Vec2::ZERO;
    for (k, &v) in tri.iter().enumerate() {
        p += *uv.uvs.get(v as usize)? * sp.bary[k];
    }
    let p = p * Vec2::new(atlas.width as f32, atlas.height as f32);
    p.is_finite().then_some(p)
}

/// The index of the texel containing `sp`, if it lies in the atlas.
fn texel_at(frame: &impl Texels, sp: &SurfacePoint) -> Option<usize> {
    let atlas = frame.atlas();
    let (w, h) = (atlas.width as f32, atlas.height as f32);
    match atlas_position(frame, sp) {
        Some(p) if p.x >= 0.0 && p.y >= 0.0 && p.x < w && p.y < h => {
            Some(p.y as usize * atlas.width as usize + p.x as usize)
        }
        _ => None,
    }
}

/// The source at `sp` (the texel containing it), [`SOURCE_OUTSIDE`]
/// where there is none.
fn source_at(frame: &impl Texels, sp: &SurfacePoint) -> u32 {
    texel_at(frame, sp).map_or(SOURCE_OUTSIDE, |i| frame.source(i))
}

/// The grey value at `sp`, bilinear and clamped at the atlas border;
/// NaN where the point has no atlas position.
fn grey_at(frame: &impl Texels, sp: &SurfacePoint) -> f32 {
    let Some(p) = atlas_position(frame, sp) else {
        return f32::NAN;
    };
    let atlas = frame.atlas();
    let (w, h) = (atlas.width as i64, atlas.height as i64);
    let (x, y) = (p.x - 0.5, p.y - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let at = |xi: i64, yi: i64| {
        let i = yi.clamp(0, h - 1) * w + xi.clamp(0, w - 1);
        frame.grey(i as usize)
    };
    let (x0, y0) = (x0 as i64, y0 as i64);
    let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
    let bottom = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// What frame t's output holds at one sample point: its source and grey
/// value (the `before` end of [`measure`]). The frame job keeps these for
/// the 20 000 points of the next pair instead of frame t's whole atlas.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointValue {
    pub source: u32,
    pub grey: f32,
}

/// The source and grey value of `frame` at each of `points`, in order
/// (parallel; the same for any thread count).
pub fn point_values(
    points: &[SurfacePoint],
    frame: &impl Texels,
) -> Result<Vec<PointValue>, MetricsError> {
    frame.validate()?;
    Ok(points
        .par_iter()
        .map(|sp| PointValue {
            source: source_at(frame, sp),
            grey: grey_at(frame, sp),
        })
        .collect())
}

/// Both coherence metrics of one frame pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coherence {
    pub switch: SourceSwitch,
    /// The switches split into forced and unforced (all zero where the
    /// method records no renewal).
    pub causes: SwitchCauses,
    pub follow: ColourFollow,
}

impl Coherence {
    /// [`SourceSwitch::share`].
    pub fn switch_share(&self) -> f64 {
        self.switch.share()
    }

    /// [`ColourFollow::ratio`].
    pub fn follow_ratio(&self) -> f64 {
        self.follow.ratio()
    }
}

/// Looks up `carried` in frame t's output (`before`) and frame t+1's
/// (`after`) and measures both metrics.
pub fn measure(
    carried: &Carried,
    before: &impl Texels,
    after: &impl Texels,
    settings: &CoherenceSettings,
) -> Result<Coherence, MetricsError> {
    measure_with_points(carried, before, after, settings).map(|(c, _)| c)
}

/// [`measure`], and each point's source at both ends (`[t, t+1]`, in the
/// order of `carried`): two runs measured on the same carried points can
/// then be compared on the points both cover
/// ([`metrics::source_switch_same_points`]).
pub fn measure_with_points(
    carried: &Carried,
    before: &impl Texels,
    after: &impl Texels,
    settings: &CoherenceSettings,
) -> Result<(Coherence, Vec<[u32; 2]>), MetricsError> {
    before.validate()?;
    after.validate()?;
    let values = point_values(&carried.from, before)?;
    let (c, ends) = measure_points(carried, &values, after, settings)?;
    Ok((c, ends.into_iter().map(|e| e.sources).collect()))
}

/// [`measure`] with frame t's output already looked up at the carried
/// points ([`point_values`] of `carried.from`): the same result.
pub fn measure_from(
    carried: &Carried,
    before: &[PointValue],
    after: &impl Texels,
    settings: &CoherenceSettings,
) -> Result<Coherence, MetricsError> {
    after.validate()?;
    measure_points(carried, before, after, settings).map(|(c, _)| c)
}

/// [`measure_from`], and what each point found at both ends.
pub fn measure_from_ends(
    carried: &Carried,
    before: &[PointValue],
    after: &impl Texels,
    settings: &CoherenceSettings,
) -> Result<(Coherence, Vec<PointEnds>), MetricsError> {
    after.validate()?;
    measure_points(carried, before, after, settings)
}

/// One carried point's sources at both ends (`[t, t+1]`) and the renewal
/// byte at its end ([`Texels::renewal`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PointEnds {
    pub sources: [u32; 2],
    pub renewal: u8,
}

/// [`measure_from`] with each point's sources at both ends.
fn measure_points(
    carried: &Carried,
    before: &[PointValue],
    after: &impl Texels,
    settings: &CoherenceSettings,
) -> Result<(Coherence, Vec<PointEnds>), MetricsError> {
    let n = carried.from.len();
    for len in [
        carried.to.len(),
        carried.still.len(),
        carried.moved.len(),
        before.len(),
    ] {
        if len != n {
            return Err(MetricsError::Length {
                what: "carried points",
                expected: n,
                got: len,
            });
        }
    }
    let texels_per_unit = after.atlas().scale as f32;
    let per_point: Vec<(u32, u32, f32, f32, f32, f32, u8)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let (s1, c1, r1) = match &carried.to[i] {
                Some(to) => match texel_at(after, to) {
                    Some(t) => (after.source(t), grey_at(after, to), after.renewal(t)),
                    None => (SOURCE_OUTSIDE, grey_at(after, to), RENEWAL_UNKNOWN),
                },
                None => (SOURCE_OUTSIDE, f32::NAN, RENEWAL_UNKNOWN),
            };
            let c2 = carried.still[i]
                .as_ref()
                .map_or(f32::NAN, |s| grey_at(after, s));
            (
                before[i].source,
                s1,
                before[i].grey,
                c1,
                c2,
                carried.moved[i] * texels_per_unit,
                r1,
            )
        })
        .collect();
    let column =
        |k: usize| -> Vec<f32> { per_point.iter().map(|p| [p.2, p.3, p.4, p.5][k]).collect() };
    let s0: Vec<u32> = per_point.iter().map(|p| p.0).collect();
    let s1: Vec<u32> = per_point.iter().map(|p| p.1).collect();
    let r1: Vec<u8> = per_point.iter().map(|p| p.6).collect();
    let found = Coherence {
        switch: metrics::source_switch(&s0, &s1)?,
        causes: metrics::switch_causes(&s0, &s1, &r1)?,
        follow: metrics::colour_follow(
            &column(0),
            &column(1),
            &column(2),
            &column(3),
            settings.min_move_texels,
            settings.min_moving_samples,
        )?,
    };
    let ends = (s0.into_iter().zip(s1).zip(r1))
        .map(|((a, b), renewal)| PointEnds {
            sources: [a, b],
            renewal,
        })
        .collect();
    Ok((found, ends))
}

/// What [`switch_map`] found at one texel of frame t+1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SwitchTexel {
    /// Outside every chart.
    Outside,
    /// No patch here, or the point carried back to frame t found none.
    Unmeasured,
    /// The same patch as where the point was at frame t.
    Same,
    /// Another patch than where the point was at frame t, not forced by
    /// the flow as far as the method says (or it does not say).
    Switched,
    /// Another patch, forced by the flow: the patch of frame t is past the
    /// distortion bound here, or none showed the point
    /// ([`crate::provenance::renewal_forced`]).
    Forced,
}

impl SwitchTexel {
    /// The colour in `switch.F.png`: unforced (or unexplained) switch red,
    /// forced switch amber, same grey, unmeasured dark blue, outside black.
    pub fn colour(self) -> [f32; 3] {
        match self {
            SwitchTexel::Outside => [0.0, 0.0, 0.0],
            SwitchTexel::Unmeasured => [0.1, 0.1, 0.35],
            SwitchTexel::Same => [0.5, 0.5, 0.5],
            SwitchTexel::Switched => [1.0, 0.0, 0.0],
            SwitchTexel::Forced => [1.0, 0.75, 0.0],
        }
    }
}

/// Per texel of frame t+1 (`after`, drawn from `after_flow.mesh`): carries
/// its surface point back to frame t with the second-order velocity step
/// (mirrored: `p = q − dt/2 · (v_{t+1}(q) + v_t(q − dt · v_{t+1}(q)))`) and
/// compares the sources. Row-major, atlas-sized; parallel over bands, the
/// same for any thread count.
pub fn switch_map(
    before: &impl Texels,
    before_flow: FlowFrame<'_>,
    after: &impl Texels,
    after_flow: FlowFrame<'_>,
    dt: f32,
) -> Result<Vec<SwitchTexel>, MetricsError> {
    before.validate()?;
    after.validate()?;
    let atlas = after.atlas();
    let w = atlas.width as usize;
    let hint = search_hint(after_flow.mesh);
    let mut map = vec![SwitchTexel::Outside; w * atlas.height as usize];
    map.par_chunks_mut(w * BAND_HEIGHT as usize)
        .zip(atlas.bands().par_iter())
        .for_each(|(rows, band)| {
            for span in &band.spans {
                let row = (span.y - band.y0) as usize * w;
                for (x, bary) in atlas.span_barycentrics(span) {
                    let i = span.y as usize * w + x as usize;
                    let sp = SurfacePoint::new(span.triangle, bary);
                    let here = after.source(i);
                    let state = if !is_patch(here) {
                        SwitchTexel::Unmeasured
                    } else {
                        let back = carry_back(&sp, before_flow, after_flow, dt, hint);
                        match back.map(|b| source_at(before, &b)) {
                            Some(s) if is_patch(s) && s == here => SwitchTexel::Same,
                            Some(s) if is_patch(s) && renewal_forced(after.renewal(i)) => {
                                SwitchTexel::Forced
                            }
                            Some(s) if is_patch(s) => SwitchTexel::Switched,
                            _ => SwitchTexel::Unmeasured,
                        }
                    };
                    if let Some(t) = rows.get_mut(row + x as usize) {
                        *t = state;
                    }
                }
            }
        });
    Ok(map)
}

/// Where the point `sp` of frame t+1 was at frame t: the mirrored
/// second-order step of [`switch_map`], located on M_t.
fn carry_back(
    sp: &SurfacePoint,
    before: FlowFrame<'_>,
    after: FlowFrame<'_>,
    dt: f32,
    hint: f32,
) -> Option<SurfacePoint> {
    let q = position(after.mesh, sp)?;
    let v1 = interpolate(after.mesh, after.velocity, sp)?;
    let v0 = before.sample(q - v1 * dt, hint)?;
    let p = q - (v0 + v1) * (0.5 * dt);
    before
        .index
        .closest(p, hint)
        .or_else(|| before.index.closest_unbounded(p))
        .map(|h| h.location)
}

/// The `switch.F.png` image of a [`switch_map`].
pub fn switch_image(map: &[SwitchTexel], width: u32, height: u32) -> Texture {
    let data = map.iter().flat_map(|s| s.colour()).collect();
    Texture {
        width,
        height,
        channels: 3,
        data,
    }
}

/// Bound of the first closest-point search: points are carried a small
/// fraction of the surface's extent per frame; farther ones fall back to an
/// unbounded search.
fn search_hint(mesh: &TriMesh) -> f32 {
    mesh.bounding_box()
        .map_or(1.0, |(lo, hi)| ((hi - lo).length() * 0.05).max(1e-6))
}

fn position(mesh: &TriMesh, sp: &SurfacePoint) -> Option<Vec3> {
    interpolate(mesh, &mesh.positions, sp)
}

/// `values` (per vertex of `mesh`) at `sp`; `None` for an index out of range.
fn interpolate(mesh: &TriMesh, values: &[Vec3], sp: &SurfacePoint) -> Option<Vec3> {
    let tri = mesh.triangles.get(sp.triangle as usize)?;
    let mut out = Vec3::ZERO;
    for (k, &v) in tri.iter().enumerate() {
        out += *values.get(v as usize)? * sp.bary[k];
    }
    Some(out)
}

pub mod regions;

#[cfg(test)]
mod tests;
