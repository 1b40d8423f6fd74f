//! The output atlas of a frame: the fluid mesh cut into charts, each
//! flattened and packed into a W×H texture, with every texel inside a chart
//! knowing the surface point it shows (docs/design.md, *Output atlas*).
//!
//! **Pipeline** ([`Atlas::build`]):
//! 1. segmentation into disc-like charts ([`crate::param::charts`]),
//! 2. LSCM per chart, split until injective ([`crate::param::flatten`]),
//!    charts in parallel; charts too long for the atlas cut into pieces
//!    ([`crate::param::cut`]),
//! 3. packing with a gutter and a scale search ([`crate::param::pack`]),
//! 4. rasterization into row spans grouped in bands ([`rasterize`]).
//!
//! [`Atlas::dilate`] then spreads colours into the gutter ([`dilate`]) and
//! [`Atlas::stretch_stats`] measures the result.
//!
//! **Conventions** (those of [`crate::texture`]): texel (x, y) covers
//! `[x, x+1) × [y, y+1)`, its centre is `(x + 0.5, y + 0.5)`, row 0 is the
//! top; normalised `u = x / W`, `v = y / H` (v = 0 at the top). A texel is
//! *inside a chart* when its centre is inside one of the chart's uv
//! triangles under the fill rule of [`rasterize`], which gives every texel
//! centre to at most one triangle. Seen from the side their normals point to,
//! charts are not mirrored (a writer whose v points up, such as OBJ, stores
//! `1 − v`).
//!
//! **Memory.** Only spans are stored (16 bytes per triangle row), never
//! per-texel data: 2.3 M spans (37 MB) for 100k triangles at 6144², where a
//! per-texel barycentric map would take 450 MB. The fill stage computes barycentrics
//! from a span with [`Atlas::span_barycentrics`].
//!
//! The unwrap is not coherent over time: each frame gets its own atlas.

pub mod dilate;
// Test surfaces, not public API: compiled only for tests and examples.
#[cfg(any(test, feature = "test-fixtures"))]
pub mod fixtures;
pub mod rasterize;
pub mod stretch;
#[cfg(test)]
mod tests;

use std::time::{Duration, Instant};

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use thiserror::Error;

use crate::mesh::{Topology, TriMesh};
use crate::param::charts::{ChartParams, segment};
use crate::param::cut::{cut_long, max_chart_length};
use crate::param::flatten::{FlatChart, flatten_chart};
use crate::param::pack::{PackError, PackParams, normalised, pack};
use crate::texture::Texture;
pub use stretch::StretchStats;

/// Rows per band.
pub const BAND_HEIGHT: u32 = 16;

/// Largest atlas side accepted (fixed-point texel coordinates stay in i32
/// and edge functions in i64).
pub const MAX_SIDE: u32 = 16384;

/// Atlas parameters. Validated once by [`Atlas::build`].
#[derive(Clone, Debug, PartialEq)]
pub struct AtlasParams {
    /// Atlas width W in texels, 1..=16384. Default: 4096.
    pub width: u32,
    /// Atlas height H in texels, 1..=16384. Default: 4096.
    pub height: u32,
    /// Free texels G between charts, 0..=64. Default: 4. Dilation radius up to G/2
    /// keeps each chart's border texels its own at every bilinear lookup.
    pub gutter: u32,
    /// Try the four quarter turns of each chart when packing. Default: true.
    pub allow_rotation: bool,
    /// Chart segmentation (cone angle, size cap, merging; see [`ChartParams`]).
    pub charts: ChartParams,
}

impl Default for AtlasParams {
    fn default() -> Self {
        AtlasParams {
            width: 4096,
            height: 4096,
            gutter: 4,
            allow_rotation: true,
            charts: ChartParams::default(),
        }
    }
}

impl AtlasParams {
    /// Square atlas of the given side, other fields at their defaults.
    pub fn square(side: u32) -> AtlasParams {
        AtlasParams {
            width: side,
            height: side,
            ..AtlasParams::default()
        }
    }

    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), AtlasError> {
        let bad = |name: &'static str, value: String, allowed: &'static str| {
            Err(AtlasError::InvalidParameter {
                name,
                value,
                allowed,
            })
        };
        if !(1..=MAX_SIDE).contains(&self.width) {
            return bad("width", self.width.to_string(), "1..=16384");
        }
        if !(1..=MAX_SIDE).contains(&self.height) {
            return bad("height", self.height.to_string(), "1..=16384");
        }
        if self.gutter > 64 {
            return bad("gutter", self.gutter.to_string(), "0..=64");
        }
        let c = &self.charts;
        if !(c.max_cone_angle_deg > 0.0 && c.max_cone_angle_deg <= 90.0) {
            return bad(
                "charts.max_cone_angle_deg",
                c.max_cone_angle_deg.to_string(),
                "(0, 90]",
            );
        }
        if c.max_chart_triangles == 0 {
            return bad("charts.max_chart_triangles", "0".into(), ">= 1");
        }
        if !(c.compactness >= 0.0 && c.compactness.is_finite()) {
            return bad(
                "charts.compactness",
                c.compactness.to_string(),
                "finite, >= 0",
            );
        }
        if c.relax_iterations > 16 {
            return bad(
                "charts.relax_iterations",
                c.relax_iterations.to_string(),
                "0..=16",
            );
        }
        Ok(())
    }
}

/// Why an atlas could not be built or used.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum AtlasError {
    #[error("atlas parameter {name} = {value} is outside {allowed}")]
    InvalidParameter {
        name: &'static str,
        value: String,
        allowed: &'static str,
    },
    #[error(
        "triangle {triangle} refers to vertex {index}, but the mesh has {vertex_count} vertices"
    )]
    IndexOutOfRange {
        triangle: usize,
        index: u32,
        vertex_count: usize,
    },
    #[error("vertex {vertex} has a non-finite position")]
    NonFinitePosition { vertex: usize },
    #[error(transparent)]
    Pack(#[from] PackError),
    #[error("texture is {got_width}x{got_height}, the atlas is {width}x{height}")]
    TextureSize {
        width: u32,
        height: u32,
        got_width: u32,
        got_height: u32,
    },
    #[error("mesh has {got} triangles, the atlas was built for {expected}")]
    MeshMismatch { expected: usize, got: usize },
    #[error("{got} ids for an atlas of {expected} texels")]
    IdCount { expected: usize, got: usize },
}

/// The atlas's mesh: the input mesh with vertices split along chart seams.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UvMesh {
    /// Position of each output vertex (copied from its source vertex).
    pub positions: Vec<Vec3>,
    /// Normalised atlas coordinates, v = 0 at the top row (texture.rs).
    pub uvs: Vec<Vec2>,
    /// Triangle i is input triangle i, same corner order, in output vertices.
    pub triangles: Vec<[u32; 3]>,
    /// Input vertex of each output vertex.
    pub source_vertex: Vec<u32>,
}

/// Texels [x0, x1) of row y whose centres (x + 0.5, y + 0.5) lie inside `triangle`'s uv footprint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Span {
    pub triangle: u32,
    pub y: u32,
    pub x0: u32,
    pub x1: u32,
}

/// Rows [y0, y1); spans sorted by (triangle, y, x0). Bands partition all rows in order (fixed band height, e.g. 16).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Band {
    pub y0: u32,
    pub y1: u32,
    pub spans: Vec<Span>,
}

/// Wall-clock time of each stage of [`Atlas::build`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AtlasTimings {
    /// Topology and chart segmentation.
    pub segmentation: Duration,
    /// LSCM of every chart, injectivity checks and splits.
    pub lscm: Duration,
    /// Outlines, skyline packing and the scale search.
    pub packing: Duration,
    /// uv mesh assembly and span rasterization.
    pub rasterization: Duration,
    /// Packings tried by the scale search.
    pub packing_attempts: u32,
}

/// A packed, rasterized atlas of one mesh.
#[derive(Clone, Debug)]
pub struct Atlas {
    pub width: u32,
    pub height: u32,
    /// Chart index per input triangle.
    pub chart_of_triangle: Vec<u32>,
    pub chart_count: usize,
    /// Output mesh with vertices split along chart seams; triangle i of uv_mesh is triangle i of the input, same corner order.
    pub uv_mesh: UvMesh,
    /// Texels per world unit (the same for every chart).
    pub scale: f64,
    /// Stage timings of the build (not part of the result proper).
    pub timings: AtlasTimings,
    bands: Vec<Band>,
    /// Fixed-point (1/256 texel) coordinates of each uv_mesh vertex: the
    /// exact geometry the spans were rasterized from.
    fixed: Vec<[i32; 2]>,
    /// The gutter's sources, found on the first dilation and reused by
    /// the later ones at the same radius.
    dilation: std::sync::OnceLock<dilate::DilationMap>,
}

/// Every triangle corner names a vertex, and every vertex used is finite.
fn check_corners(mesh: &TriMesh) -> Result<(), AtlasError> {
    let n = mesh.positions.len();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for &v in tri {
            match mesh.positions.get(v as usize) {
                None => {
                    return Err(AtlasError::IndexOutOfRange {
                        triangle: t,
                        index: v,
                        vertex_count: n,
                    });
                }
                Some(p) if !p.is_finite() => {
                    return Err(AtlasError::NonFinitePosition { vertex: v as usize });
                }
                _ => {}
            }
        }
    }
    Ok(())
}

impl Atlas {
    /// Unwraps, packs and rasterizes `mesh`. An empty mesh gives a valid
    /// atlas with no charts.
    ///
    /// # Errors
    /// Invalid parameters, an out-of-range index or a non-finite position
    /// used by a triangle, or more charts than the atlas can hold.
    pub fn build(mesh: &TriMesh, params: &AtlasParams) -> Result<Atlas, AtlasError> {
        params.validate()?;
        check_corners(mesh)?;
        let n = mesh.positions.len();
        let mut timings = AtlasTimings::default();

        let clock = Instant::now();
        let topology = Topology::new(n, &mesh.triangles);
        let seg = segment(&mesh.positions, &mesh.triangles, &topology, &params.charts);
        timings.segmentation = clock.elapsed();

        let clock = Instant::now();
        let max_len = max_chart_length(mesh.area(), params.width, params.height);
        let flat: Vec<FlatChart> = seg
            .charts
            .par_iter()
            .flat_map_iter(|c| {
                let pieces = flatten_chart(&mesh.positions, &mesh.triangles, c, &params.charts);
                match max_len {
                    Some(len) => {
                        let mut cut = Vec::with_capacity(pieces.len());
                        for p in pieces {
                            cut_long(p, len, &mut cut);
                        }
                        cut
                    }
                    None => pieces,
                }
            })
            .collect();
        timings.lscm = clock.elapsed();

        let clock = Instant::now();
        let packing = pack(
            &flat,
            &PackParams {
                width: params.width,
                height: params.height,
                gutter: params.gutter,
                allow_rotation: params.allow_rotation,
            },
        )?;
        timings.packing = clock.elapsed();
        timings.packing_attempts = packing.attempts;

        let clock = Instant::now();
        let mut uv_mesh = UvMesh {
            triangles: vec![[0; 3]; mesh.triangles.len()],
            ..UvMesh::default()
        };
        let mut fixed = Vec::new();
        let mut chart_of_triangle = vec![0u32; mesh.triangles.len()];
        let sub = rasterize::SUBTEXEL as f64;
        for (c, (chart, coords)) in flat.iter().zip(&packing.texel_coords).enumerate() {
            let base = uv_mesh.positions.len() as u32;
            for (&src, &xy) in chart.vertices.iter().zip(coords) {
                let f = [(xy.x * sub).round() as i32, (xy.y * sub).round() as i32];
                fixed.push(f);
                uv_mesh.positions.push(mesh.positions[src as usize]);
                uv_mesh.source_vertex.push(src);
                uv_mesh.uvs.push(normalised(
                    glam::DVec2::new(f[0] as f64 / sub, f[1] as f64 / sub),
                    params.width,
                    params.height,
                ));
            }
            for (&t, local) in chart.triangles.iter().zip(&chart.local_triangles) {
                uv_mesh.triangles[t as usize] = local.map(|v| base + v);
                chart_of_triangle[t as usize] = c as u32;
            }
        }
        let bands = rasterize::rasterize(&fixed, &uv_mesh.triangles, params.width, params.height);
        timings.rasterization = clock.elapsed();

        Ok(Atlas {
            width: params.width,
            height: params.height,
            chart_of_triangle,
            chart_count: flat.len(),
            uv_mesh,
            scale: packing.scale,
            timings,
            bands,
            fixed,
            dilation: std::sync::OnceLock::new(),
        })
    }

    /// The bands, top to bottom, partitioning rows `0..height`.
    pub fn bands(&self) -> &[Band] {
        &self.bands
    }

    /// Number of texels inside charts.
    pub fn texels_in_charts(&self) -> u64 {
        self.bands
            .iter()
            .flat_map(|b| &b.spans)
            .map(|s| (s.x1 - s.x0) as u64)
            .sum()
    }

    /// Barycentrics (w.r.t. the INPUT triangle's corners, so SurfacePoint{triangle, bary} works on the input mesh) of the texel centres of a span, computed incrementally (affine in x).
    pub fn span_barycentrics(&self, span: &Span) -> impl Iterator<Item = (u32, [f32; 3])> + '_ {
        let (start, step) = self.span_affine(span.triangle, span.x0, span.y);
        let x0 = span.x0;
        (x0..span.x1).map(move |x| {
            let k = (x - x0) as f32;
            let mut bary = [0.0f32; 3];
            for i in 0..3 {
                bary[i] = (start[i] + k * step[i]).clamp(0.0, 1.0);
            }
            (x, bary)
        })
    }

    /// The change of the barycentrics of [`Atlas::span_barycentrics`] from
    /// one texel of a span of `triangle` to the next (before clamping): the
    /// triangle's, whichever span.
    pub fn barycentric_step(&self, triangle: u32) -> [f32; 3] {
        self.span_affine(triangle, 0, 0).1
    }

    /// Unclamped barycentrics of the centre of texel (`x0`, `y`) on
    /// `triangle` and their change per texel to the right, from the exact
    /// fixed-point edge functions.
    fn span_affine(&self, triangle: u32, x0: u32, y: u32) -> ([f32; 3], [f32; 3]) {
        let sub = rasterize::SUBTEXEL;
        let p = self
            .uv_mesh
            .triangles
            .get(triangle as usize)
            .map(|t| {
                t.map(|v| {
                    let f = self.fixed.get(v as usize).copied().unwrap_or([0, 0]);
                    [f[0] as i64, f[1] as i64]
                })
            })
            .unwrap_or([[0, 0]; 3]);
        let edge = |a: [i64; 2], b: [i64; 2], c: [i64; 2]| {
            (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        };
        let area2 = edge(p[0], p[1], p[2]) as f64;
        let c = [x0 as i64 * sub + sub / 2, y as i64 * sub + sub / 2];
        let mut start = [0.0f32; 3];
        let mut step = [0.0f32; 3];
        if area2 != 0.0 {
            for k in 0..3 {
                // λ_k is the edge function of the opposite edge over 2A.
                let (a, b) = (p[(k + 1) % 3], p[(k + 2) % 3]);
                start[k] = (edge(a, b, c) as f64 / area2) as f32;
                step[k] = ((-(b[1] - a[1]) * sub) as f64 / area2) as f32;
            }
        }
        (start, step)
    }

    /// Triangle per texel, u32::MAX outside charts (row-major), for tests, debug and metrics.
    pub fn triangle_map(&self) -> Vec<u32> {
        let w = self.width as usize;
        let mut map = vec![u32::MAX; w * self.height as usize];
        map.par_chunks_mut(w * BAND_HEIGHT as usize)
            .zip(self.bands.par_iter())
            .for_each(|(rows, band)| {
                for s in &band.spans {
                    let row = (s.y - band.y0) as usize * w;
                    rows[row + s.x0 as usize..row + s.x1 as usize].fill(s.triangle);
                }
            });
        map
    }

    /// Fill every texel outside charts whose distance to a chart texel is ≤ radius with the value of the nearest chart texel (deterministic tie-break), so bilinear filtering and mipmaps don't bleed.
    ///
    /// Ties go to the smaller row, then the smaller column.
    ///
    /// # Errors
    /// [`AtlasError::TextureSize`] when `texture` is not the atlas's size.
    pub fn dilate(&self, texture: &mut Texture, radius: u32) -> Result<(), AtlasError> {
        if texture.width != self.width || texture.height != self.height {
            return Err(AtlasError::TextureSize {
                width: self.width,
                height: self.height,
                got_width: texture.width,
                got_height: texture.height,
            });
        }
        self.with_dilation(radius, |map| dilate::dilate(map, self.width, texture));
        Ok(())
    }

    /// [`Atlas::dilate`] for per-texel ids (one `u32` per texel, row-major):
    /// every gutter texel within `radius` of a chart takes the nearest
    /// chart texel's id, exactly as a texture's values would move.
    ///
    /// # Errors
    /// [`AtlasError::IdCount`] when `ids` does not hold one id per texel.
    pub fn dilate_ids(&self, ids: &mut [u32], radius: u32) -> Result<(), AtlasError> {
        let expected = self.width as usize * self.height as usize;
        if ids.len() != expected {
            return Err(AtlasError::IdCount {
                expected,
                got: ids.len(),
            });
        }
        self.with_dilation(radius, |map| {
            dilate::dilate_values(map, self.width, ids, 1);
        });
        Ok(())
    }

    /// `f` with the dilation map at `radius`: the cached one (made by the
    /// first call), or one made for this call at another radius.
    fn with_dilation<R>(&self, radius: u32, f: impl FnOnce(&dilate::DilationMap) -> R) -> R {
        let make = || dilate::DilationMap::new(&self.bands, self.width, self.height, radius);
        let cached = self.dilation.get_or_init(make);
        if cached.radius == radius {
            f(cached)
        } else {
            f(&make())
        }
    }

    /// Area-weighted p50/p95/max of σ₁/σ₂ of the uv → 3-D map, overlapping
    /// texels and fill ratio. `mesh` is the mesh the atlas was built from.
    ///
    /// # Errors
    /// [`AtlasError::MeshMismatch`] when the triangle counts differ,
    /// [`AtlasError::IndexOutOfRange`] for an index outside `mesh`.
    pub fn stretch_stats(&self, mesh: &TriMesh) -> Result<StretchStats, AtlasError> {
        if mesh.triangles.len() != self.uv_mesh.triangles.len() {
            return Err(AtlasError::MeshMismatch {
                expected: self.uv_mesh.triangles.len(),
                got: mesh.triangles.len(),
            });
        }
        for (t, tri) in mesh.triangles.iter().enumerate() {
            if let Some(&index) = tri.iter().find(|&&v| v as usize >= mesh.positions.len()) {
                return Err(AtlasError::IndexOutOfRange {
                    triangle: t,
                    index,
                    vertex_count: mesh.positions.len(),
                });
            }
        }
        Ok(stretch::stretch_stats(self, mesh))
    }
}
