//! The walk every lapped fill makes over the atlas: bands of rows in
//! parallel, spans of one fluid triangle within a band, texels along a span.
//!
//! A fill supplies only what a texel does with the patches it meets; this
//! module cuts the per-texel buffers into the bands' rows, gives each span
//! its fluid triangle, unit normal and texel surface points (computed one
//! way, so every fill sees the same bits), and merges the bands' results:
//! uncovered texels sorted by texel, used patches sorted without repeats.
//! Each band writes only its own rows, so the outputs are bit-identical
//! whatever the thread count.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::AtTexel;
use crate::atlas::{Atlas, Band};
use crate::mesh::TriMesh;
use crate::provenance::SOURCE_OUTSIDE;

/// The per-texel outputs of a lapped fill, whole atlas: the exemplar's
/// channels, the provenance (patch id + 1, or outside / uncovered) and the
/// patch uv; blending fills add a visible-layer count and the exemplar
/// level per texel.
pub struct TexelBuffers {
    pub width: u32,
    pub height: u32,
    /// Exemplar channels, interleaved (`channels` per texel).
    pub channels: usize,
    pub values: Vec<f32>,
    /// [`SOURCE_OUTSIDE`], [`crate::provenance::SOURCE_UNCOVERED`] or
    /// patch id + 1.
    pub source: Vec<u32>,
    /// Patch uv per texel (exemplar coordinates), NaN where no patch.
    pub uv: Vec<Vec2>,
    /// Visible layers per texel; empty unless [`TexelBuffers::with_layers`].
    pub layers: Vec<u8>,
    /// Exemplar mip level per texel (NaN where none); empty unless
    /// [`TexelBuffers::with_layers`].
    pub lod: Vec<f32>,
    /// Per texel, what became of the patch that showed its point the frame
    /// before ([`crate::provenance::RENEWAL_HELD`] and the other flags);
    /// empty unless [`TexelBuffers::with_renewal`].
    pub renewal: Vec<u8>,
    /// When set, the erosion fill records only source and uv and leaves
    /// `values` to a later pass that samples every covered texel once, at
    /// its footprint's level ([`crate::methods::footprint`]): a level-0
    /// read that is overwritten anyway would cost most of the frame with a
    /// large exemplar.
    pub defer_values: bool,
}

impl TexelBuffers {
    /// Every texel outside the charts, values 0, uv NaN.
    pub fn new(width: u32, height: u32, channels: usize) -> TexelBuffers {
        TexelBuffers::reusing(width, height, channels, None, None, None)
    }

    /// [`TexelBuffers::new`], refilling `spare_uv`, `spare_values` and
    /// `spare_source` (a spent frame's buffers, lent by the frame's
    /// [`crate::methods::FrameArena`]) where they have the size.
    pub fn reusing(
        width: u32,
        height: u32,
        channels: usize,
        spare_uv: Option<Vec<Vec2>>,
        spare_values: Option<Vec<f32>>,
        spare_source: Option<Vec<u32>>,
    ) -> TexelBuffers {
        let n = width as usize * height as usize;
        TexelBuffers {
            width,
            height,
            channels,
            // Zeroed pages the kernel maps on first touch, or a spent
            // frame's values zeroed on every core.
            values: match spare_values {
                Some(v) if v.len() == n * channels => refilled(Some(v), n * channels, 0.0),
                _ => vec![0.0; n * channels],
            },
            // Filled on every core: at 6144² these two are 450 MB, whose
            // serial fill (and page faults) showed in every frame's time.
            source: refilled(spare_source, n, SOURCE_OUTSIDE),
            uv: refilled(spare_uv, n, Vec2::NAN),
            layers: Vec::new(),
            lod: Vec::new(),
            renewal: Vec::new(),
            defer_values: false,
        }
    }

    /// Also a layer count (0) and an exemplar level (NaN) per texel.
    pub fn with_layers(mut self) -> TexelBuffers {
        let n = self.source.len();
        self.layers = vec![0; n];
        self.lod = filled(n, f32::NAN);
        self
    }

    /// Also a renewal byte per texel ([`crate::provenance::RENEWAL_UNKNOWN`]
    /// until the fill records one).
    pub fn with_renewal(mut self) -> TexelBuffers {
        self.renewal = filled(self.source.len(), crate::provenance::RENEWAL_UNKNOWN);
        self
    }

    /// All the buffers as rows from the first texel, for [`fill_bands`].
    pub fn rows(&mut self) -> TexelRows<'_> {
        TexelRows {
            base: 0,
            channels: self.channels,
            values: &mut self.values,
            source: &mut self.source,
            uv: &mut self.uv,
            layers: &mut self.layers,
            lod: &mut self.lod,
            renewal: &mut self.renewal,
        }
    }
}

/// `n` copies of `value`, written in parallel.
fn filled<T: Copy + Send + Sync>(n: usize, value: T) -> Vec<T> {
    let mut v = Vec::with_capacity(n);
    v.par_extend(rayon::iter::repeat_n(value, n));
    v
}

/// [`filled`], into `spare` when it holds exactly `n` values: its pages
/// are mapped already.
fn refilled<T: Copy + Send + Sync>(spare: Option<Vec<T>>, n: usize, value: T) -> Vec<T> {
    match spare {
        Some(mut v) if v.len() == n => {
            v.par_iter_mut().for_each(|x| *x = value);
            v
        }
        _ => filled(n, value),
    }
}

/// Rows of the per-texel outputs of a fill: the whole atlas (`base` 0)
/// as a fill hands it to [`fill_bands`], or one band's rows as the band
/// receives them. Texel `t` of the rows is `source[t]`,
/// `values[t * channels..(t + 1) * channels]`, and so on; a buffer the fill
/// does not keep is empty.
pub struct TexelRows<'a> {
    /// Row-major atlas index of the first texel.
    pub base: usize,
    /// Values per texel in `values`.
    pub channels: usize,
    pub values: &'a mut [f32],
    pub source: &'a mut [u32],
    pub uv: &'a mut [Vec2],
    /// Visible layers per texel (blending fills); may be empty.
    pub layers: &'a mut [u8],
    /// Exemplar mip level per texel; may be empty.
    pub lod: &'a mut [f32],
    /// Renewal byte per texel; may be empty.
    pub renewal: &'a mut [u8],
}

impl TexelRows<'_> {
    /// The values of texel `t`.
    #[inline]
    pub fn values_of(&mut self, t: usize) -> &mut [f32] {
        let c = self.channels;
        &mut self.values[t * c..(t + 1) * c]
    }
}

/// What a band (and, merged, the whole fill) leaves for later stages.
pub struct BandResult<U> {
    /// Texels the fill left uncovered, in texel order once merged.
    pub uncovered: Vec<U>,
    /// Indices of the patches that showed somewhere, sorted without
    /// repeats once merged (empty for fills that do not track them).
    pub used: Vec<u32>,
}

impl<U> Default for BandResult<U> {
    fn default() -> Self {
        BandResult {
            uncovered: Vec::new(),
            used: Vec::new(),
        }
    }
}

/// Cuts `buffer` into one slice per band (`texels` texels of `per_texel`
/// entries each); an empty buffer gives an empty slice per band.
fn cut<T>(buffer: &mut [T], texels: usize, per_texel: usize, bands: usize) -> Vec<&mut [T]> {
    if buffer.is_empty() || per_texel == 0 {
        return (0..bands).map(|_| <&mut [T]>::default()).collect();
    }
    buffer.chunks_mut(texels * per_texel).collect()
}

/// Runs `fill` on every band of `atlas` in parallel, each with its own rows
/// of `out`, and merges what the bands return (module doc).
pub fn fill_bands<U, F>(atlas: &Atlas, out: TexelRows<'_>, fill: F) -> BandResult<U>
where
    U: AtTexel + Send,
    F: Fn(&Band, TexelRows<'_>) -> BandResult<U> + Sync,
{
    let bands = atlas.bands();
    let Some(first) = bands.first() else {
        return BandResult::default();
    };
    let w = atlas.width as usize;
    let texels = (first.y1 - first.y0) as usize * w;
    let c = out.channels;
    let n = bands.len();
    let rows: Vec<TexelRows<'_>> = cut(out.values, texels, c, n)
        .into_iter()
        .zip(cut(out.source, texels, 1, n))
        .zip(cut(out.uv, texels, 1, n))
        .zip(cut(out.layers, texels, 1, n))
        .zip(cut(out.lod, texels, 1, n))
        .zip(cut(out.renewal, texels, 1, n))
        .zip(bands)
        .map(
            |((((((values, source), uv), layers), lod), renewal), band)| TexelRows {
                base: band.y0 as usize * w,
                channels: c,
                values,
                source,
                uv,
                layers,
                lod,
                renewal,
            },
        )
        .collect();
    let results: Vec<BandResult<U>> = rows
        .into_par_iter()
        .zip(bands.par_iter())
        .map(|(rows, band)| fill(band, rows))
        .collect();
    merge(results)
}

/// Concatenates the bands' results, uncovered texels sorted by texel (each
/// texel is in one band only, so the order is total) and used patches
/// sorted without repeats.
fn merge<U: AtTexel>(results: Vec<BandResult<U>>) -> BandResult<U> {
    let mut all = BandResult::default();
    for r in results {
        all.uncovered.extend(r.uncovered);
        all.used.extend(r.used);
    }
    all.uncovered.sort_unstable_by_key(|u| u.texel());
    all.used.sort_unstable();
    all.used.dedup();
    all
}

/// One span of chart texels, all on one fluid triangle.
pub struct SpanTexels<'a> {
    pub triangle: u32,
    /// Unit normal of the fluid triangle.
    pub normal: Vec3,
    /// Corners of the fluid triangle.
    pub corners: [Vec3; 3],
    /// Band texel index of the span row's first texel.
    row: usize,
    /// (x, barycentrics) of each texel, left to right; never empty.
    texels: &'a [(u32, [f32; 3])],
}

/// One chart texel as a span hands it over.
#[derive(Clone, Copy, Debug)]
pub struct BandTexel {
    /// Texel index from the band's first texel.
    pub t: usize,
    /// Index of the texel in its span.
    pub k: u32,
    /// Surface point and unit normal of its fluid triangle.
    pub p: Vec3,
    pub n: Vec3,
    pub triangle: u32,
    pub bary: [f32; 3],
}

impl SpanTexels<'_> {
    /// The surface point at barycentrics `bary` of the span's triangle.
    #[inline]
    pub fn point(&self, bary: [f32; 3]) -> Vec3 {
        let [a, b, c] = self.corners;
        a * bary[0] + b * bary[1] + c * bary[2]
    }

    /// Number of texels (at least 1).
    pub fn len(&self) -> u32 {
        self.texels.len() as u32
    }

    /// Always false: empty spans are skipped by [`for_each_span`].
    pub fn is_empty(&self) -> bool {
        self.texels.is_empty()
    }

    /// Barycentrics of the first texel.
    pub fn first_barycentrics(&self) -> [f32; 3] {
        self.texels.first().map_or([1.0, 0.0, 0.0], |t| t.1)
    }

    /// The span's texels, left to right.
    pub fn texels(&self) -> impl Iterator<Item = BandTexel> + '_ {
        self.texels
            .iter()
            .enumerate()
            .map(move |(k, &(x, bary))| BandTexel {
                t: self.row + x as usize,
                k: k as u32,
                p: self.point(bary),
                n: self.normal,
                triangle: self.triangle,
                bary,
            })
    }
}

/// Visits every non-empty span of `band` in span order.
pub fn for_each_span(
    mesh: &TriMesh,
    atlas: &Atlas,
    band: &Band,
    mut visit: impl FnMut(&SpanTexels<'_>),
) {
    let w = atlas.width as usize;
    let base = band.y0 as usize * w;
    let mut texels: Vec<(u32, [f32; 3])> = Vec::new();
    for span in &band.spans {
        texels.clear();
        texels.extend(atlas.span_barycentrics(span));
        if texels.is_empty() {
            continue;
        }
        let f = span.triangle;
        let corners = mesh.corners(f as usize);
        let [a, b, c] = corners;
        visit(&SpanTexels {
            triangle: f,
            normal: (b - a).cross(c - a).normalize_or_zero(),
            corners,
            row: span.y as usize * w - base,
            texels: &texels,
        });
    }
}
