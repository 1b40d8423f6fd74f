//! Several exemplars on one surface (Gagnon, Dagenais, Paquette 2016,
//! Sec. 4, "multiple textures"): every patch carries the index of the
//! exemplar it shows, chosen once, when the patch is created, by one of
//! three strategies ([`ExemplarSelect`]):
//!
//! - **probability**: a discrete distribution over the exemplars (the
//!   weights of `--exemplar a.png:0.3 --exemplar b.png:0.7`, normalised),
//!   drawn from the run's seeded stream keyed like the patch's rotation
//!   (patch id on the first frame, creation point later), so the draw does
//!   not depend on thread count or processing order;
//! - **region**: the index at the patch centre, read from a per-vertex
//!   attribute `exemplar_id` of the input mesh (nearest corner of the
//!   centre's triangle) or, without one, from a region image
//!   ([`RegionImage`]) projected top-down (along y) over the x–z extent of
//!   the first non-empty frame;
//! - **histogram**: local-histogram steering toward the same target
//!   proportions: the new patch takes the exemplar that brings the
//!   exemplar histogram of its neighbourhood (atlas texels covered by the
//!   patches whose centres lie within [`HISTOGRAM_REACH`] radii) closest to
//!   the target, plus the same distance over the whole surface, so
//!   proportions hold locally and the total does not drift;
//! - **attribute**: the exemplar whose range holds a per-vertex scalar of
//!   the input (`--select-by temperature`) at the patch centre, a seeded
//!   draw where ranges overlap ([`super::select_by`]). This one is also
//!   asked again every frame: the methods lower what no longer matches.
//!
//! All exemplars must have the same output channels (names, channel counts
//! and storage formats) and the same feature-map availability (all given
//! or all derived): the atlas has one set of channels, and a patch's
//! erosion and mask read its own exemplar's feature map. Their pixel sizes
//! may differ: uv is normalised, and each keeps its own mip pyramid.
//!
//! With one exemplar nothing here is used: methods take their
//! single-exemplar path, unchanged.

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;

use super::channels::exemplar_channels;
pub use super::select_by::{AttributeRange, SelectBy};
use super::sequence::ExemplarClock;
use super::{Exemplar, ExemplarError, FeatureOrigin};
use crate::mesh::{Attribute, TriMesh};
use crate::surface::SurfacePoint;
use crate::texture::Texture;

pub use crate::mesh::EXEMPLAR_ID;

/// Histogram steering counts the patches whose centres lie within this many
/// patch radii of the new patch's centre \[3] ("a few radii": far enough to
/// hold several patches, near enough to stay local).
pub const HISTOGRAM_REACH: f32 = 3.0;

/// How a new patch picks its exemplar.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ExemplarSelect {
    /// A seeded draw from the exemplars' weights.
    #[default]
    Probability,
    /// The exemplar index at the patch centre (mesh attribute or image).
    Region,
    /// Local-histogram steering toward the weights.
    Histogram,
    /// The exemplar whose attribute range holds the value at the patch
    /// centre ([`SelectBy`]).
    Attribute,
}

crate::named!(ExemplarSelect {
    Probability => "probability",
    Region => "region",
    Histogram => "histogram",
    Attribute => "attribute",
});

/// A region image: grey levels mapped to exemplar indices (black 0, white
/// the last exemplar: index = round(luminance × (count − 1))).
#[derive(Clone, Debug, PartialEq)]
pub struct RegionImage {
    /// Luminance, one channel.
    pub map: Texture,
    pub name: String,
}

impl RegionImage {
    /// Reads a region image (PNG, JPEG or EXR; luminance).
    pub fn load(path: &Path) -> Result<RegionImage, ExemplarError> {
        let d = crate::io::image_read::read_image(path)?;
        Ok(RegionImage::new(
            Texture {
                width: d.texture.width,
                height: d.texture.height,
                channels: 1,
                data: super::feature::luminance(&d.texture),
            },
            path.display().to_string(),
        ))
    }

    pub fn new(map: Texture, name: String) -> RegionImage {
        RegionImage { map, name }
    }

    /// The exemplar index at image uv (nearest texel, clamped to the
    /// image) among `count` exemplars.
    pub fn index_at(&self, u: f32, v: f32, count: usize) -> u32 {
        let (w, h) = (self.map.width.max(1), self.map.height.max(1));
        // Saturating casts: NaN reads texel 0.
        let x = ((u * w as f32) as u32).min(w - 1);
        let y = ((v * h as f32) as u32).min(h - 1);
        let l = self
            .map
            .data
            .get((y * w + x) as usize)
            .copied()
            .unwrap_or(0.0)
            .clamp(0.0, 1.0);
        let last = count.saturating_sub(1);
        ((l * last as f32).round() as usize).min(last) as u32
    }
}

/// Where a region image lies in the world: over `[min, max]` of x (image u)
/// and z (image v), seen from above (along −y). Resolved from the first
/// non-empty frame's bounding box and kept in the method state, so a
/// resumed run projects the same way.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RegionBox {
    pub min: [f32; 2],
    pub max: [f32; 2],
}

impl RegionBox {
    /// The x–z extent of `mesh` (`None` for an empty mesh).
    pub fn of(mesh: &TriMesh) -> Option<RegionBox> {
        let (lo, hi) = mesh.bounding_box()?;
        Some(RegionBox {
            min: [lo.x, lo.z],
            max: [hi.x, hi.z],
        })
    }

    /// Image uv of world point `p`.
    pub fn uv(&self, p: Vec3) -> (f32, f32) {
        let along = |x: f32, k: usize| {
            let span = self.max[k] - self.min[k];
            if span > 0.0 {
                (x - self.min[k]) / span
            } else {
                0.5
            }
        };
        (along(p.x, 0), along(p.z, 1))
    }
}

/// The exemplars of a run, their target proportions and how new patches
/// choose among them.
///
/// An animated exemplar ([`super::sequence`]) is one entry with several
/// frames. The entries' frames lie side by side in one list of *slots*
/// ([`ExemplarSet::exemplars`]): a patch stores its entry, chosen once,
/// and reads the slot [`ExemplarSet::slot`] gives for the frame shown. A
/// still entry has one slot, so without animation slot and entry agree.
#[derive(Clone, Debug)]
pub struct ExemplarSet {
    /// Every entry's frames, entry after entry.
    exemplars: Vec<Arc<Exemplar>>,
    /// Per entry, its first slot and its frame count.
    first: Vec<u32>,
    frames: Vec<u32>,
    /// How animated entries advance.
    pub clock: ExemplarClock,
    /// File (or built-in) name of each entry, for messages.
    names: Vec<String>,
    /// Normalised weights (sum 1).
    weights: Vec<f32>,
    pub select: ExemplarSelect,
    pub region: Option<RegionImage>,
    /// The attribute and ranges of `select = Attribute`.
    pub by: Option<SelectBy>,
}

impl ExemplarSet {
    /// One exemplar: the methods' single-exemplar path.
    pub fn single(exemplar: Arc<Exemplar>) -> ExemplarSet {
        ExemplarSet {
            exemplars: vec![exemplar],
            first: vec![0],
            frames: vec![1],
            clock: ExemplarClock::default(),
            names: vec!["exemplar".into()],
            weights: vec![1.0],
            select: ExemplarSelect::Probability,
            region: None,
            by: None,
        }
    }

    /// Several exemplars `(name, exemplar, weight)`; weights must be finite
    /// and positive and are normalised. Checks that every exemplar has the
    /// channels and feature-map availability of the first (the error names
    /// both).
    pub fn new(
        entries: Vec<(String, Arc<Exemplar>, f32)>,
        select: ExemplarSelect,
        region: Option<RegionImage>,
    ) -> Result<ExemplarSet, ExemplarError> {
        let entries = entries
            .into_iter()
            .map(|(name, e, w)| (name, vec![e], w))
            .collect();
        ExemplarSet::animated(entries, select, region)
    }

    /// Entries `(name, frames, weight)` of one frame (a still exemplar) or
    /// several (an animated one); otherwise as [`ExemplarSet::new`], every
    /// frame checked against the first entry's first.
    pub fn animated(
        entries: Vec<(String, Vec<Arc<Exemplar>>, f32)>,
        select: ExemplarSelect,
        region: Option<RegionImage>,
    ) -> Result<ExemplarSet, ExemplarError> {
        let Some((first_name, first, _)) = entries.first() else {
            return Err(ExemplarError::Layout {
                what: "exemplar list".into(),
                reason: "no exemplar given".into(),
            });
        };
        let layout = |e: &Exemplar| {
            let mut counts = vec![e.colour.channels];
            counts.extend(e.channels.iter().map(|c| c.texture.channels));
            (exemplar_channels(e), counts)
        };
        let given = |e: &Exemplar| matches!(e.feature.origin, FeatureOrigin::Given(_));
        let describe = |e: &Exemplar| {
            let (specs, counts) = layout(e);
            specs
                .iter()
                .zip(&counts)
                .map(|(s, k)| format!("{} ({k} ch, {:?})", s.name, s.format))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let Some(first) = first.first() else {
            return Err(ExemplarError::Layout {
                what: first_name.clone(),
                reason: "an animated exemplar without frames".into(),
            });
        };
        for (name, frames, weight) in &entries {
            if !(weight.is_finite() && *weight > 0.0) {
                return Err(ExemplarError::Weight {
                    what: name.clone(),
                    value: *weight,
                });
            }
            if frames.is_empty() {
                return Err(ExemplarError::Layout {
                    what: name.clone(),
                    reason: "an animated exemplar without frames".into(),
                });
            }
            for e in frames {
                if layout(e) != layout(first) {
                    return Err(ExemplarError::Mismatch {
                        what: name.clone(),
                        other: first_name.clone(),
                        reason: format!("channels {} differ from {}", describe(e), describe(first)),
                    });
                }
                if given(e) != given(first) {
                    let says = |g: bool| if g { "a given" } else { "a derived" };
                    return Err(ExemplarError::Mismatch {
                        what: name.clone(),
                        other: first_name.clone(),
                        reason: format!(
                            "{} feature map where the other has {}",
                            says(given(e)),
                            says(given(first))
                        ),
                    });
                }
            }
        }
        let total: f32 = entries.iter().map(|e| e.2).sum();
        let mut set = ExemplarSet {
            exemplars: Vec::with_capacity(entries.len()),
            first: Vec::with_capacity(entries.len()),
            frames: Vec::with_capacity(entries.len()),
            clock: ExemplarClock::default(),
            names: Vec::with_capacity(entries.len()),
            weights: Vec::with_capacity(entries.len()),
            select,
            region,
            by: None,
        };
        for (name, frames, w) in entries {
            set.names.push(name);
            set.first.push(set.exemplars.len() as u32);
            set.frames.push(frames.len() as u32);
            set.exemplars.extend(frames);
            set.weights.push(w / total);
        }
        Ok(set)
    }

    /// The same set advancing its animated entries by `clock`.
    pub fn with_clock(mut self, clock: ExemplarClock) -> ExemplarSet {
        self.clock = clock;
        self
    }

    /// Whether an entry has more than one frame.
    pub fn is_animated(&self) -> bool {
        self.frames.iter().any(|&n| n > 1)
    }

    /// Frames of entry `entry` (1 for a still exemplar, 0 for no entry).
    pub fn frame_count(&self, entry: u32) -> u32 {
        self.span(entry).map_or(0, |(_, n)| n)
    }

    /// The slots of entry `entry`'s frames (empty for no entry).
    pub fn slots_of(&self, entry: u32) -> std::ops::Range<usize> {
        self.span(entry)
            .map_or(0..0, |(first, n)| first as usize..(first + n) as usize)
    }

    /// Entry `entry`'s first slot and frame count.
    #[inline]
    fn span(&self, entry: u32) -> Option<(u32, u32)> {
        let e = entry as usize;
        Some((*self.first.get(e)?, *self.frames.get(e)?))
    }

    /// The slot of the frame `frame(φ, n)` of entry `entry` for the patch
    /// keyed `key` (its phase φ); the entry's one slot when it is still,
    /// slot 0 for no entry.
    #[inline]
    fn slot_by(&self, entry: u32, seed: u64, key: u64, frame: impl Fn(f64, u32) -> u32) -> u32 {
        match self.span(entry) {
            None => 0,
            Some((first, n)) if n <= 1 => first,
            Some((first, n)) => first + frame(ExemplarClock::phase(seed, key, n), n),
        }
    }

    /// The slot ([`ExemplarSet::exemplars`]) a patch of entry `entry`,
    /// keyed `key` (its id) in a run of `seed`, shows on fluid frame `t`:
    /// exemplar frame ⌊t·rate + φ⌋ mod n ([`ExemplarClock`]). An unknown
    /// entry reads slot 0.
    #[inline]
    pub fn slot(&self, entry: u32, seed: u64, key: u64, t: i32) -> u32 {
        self.slot_by(entry, seed, key, |phase, n| self.clock.frame(t, phase, n))
    }

    /// The slot whose feature map shapes the patch (its erosion and mask)
    /// for its whole life: the frame its phase starts at, ⌊φ⌋. Fixed, so
    /// a fluid at rest keeps every source while the colour animates.
    #[inline]
    pub fn feature_slot(&self, entry: u32, seed: u64, key: u64) -> u32 {
        // φ < n, so ⌊φ⌋ is a frame.
        self.slot_by(entry, seed, key, |phase, n| (phase as u32).min(n - 1))
    }

    /// Builds the mip pyramids of `slots` that are not built yet, in
    /// parallel, before a parallel loop reads them (see
    /// [`Exemplar::build_pyramid`]). Returns how many it built.
    pub fn prepare(&self, slots: impl IntoIterator<Item = u32>) -> usize {
        use rayon::prelude::*;
        let mut wanted: Vec<u32> = slots
            .into_iter()
            .filter(|&s| {
                self.exemplars
                    .get(s as usize)
                    .is_some_and(|e| !e.pyramid_built())
            })
            .collect();
        wanted.sort_unstable();
        wanted.dedup();
        wanted
            .par_iter()
            .for_each(|&s| self.exemplars[s as usize].build_pyramid());
        wanted.len()
    }

    /// One line per animated entry for the user, before the run: its
    /// frames, rate and memory against `budget` bytes.
    pub fn animation_summary(&self, budget: u64) -> Vec<String> {
        let mib = |b: u64| b as f64 / (1 << 20) as f64;
        (0..self.len() as u32)
            .filter(|&e| self.frame_count(e) > 1)
            .map(|e| {
                let slots = &self.exemplars[self.slots_of(e)];
                let bytes: u64 = slots.iter().map(|x| x.memory_bytes()).sum();
                let (w, h) = slots.first().map_or((0, 0), |x| x.size());
                format!(
                    "animated exemplar {}: {} frames of {w}x{h}, {} exemplar frame(s) per \
                     fluid frame, each patch at its own phase; {:.1} MiB with their mip \
                     pyramids (built as each frame is first shown), budget {:.0} MiB",
                    self.names[e as usize],
                    slots.len(),
                    self.clock.rate,
                    mib(bytes),
                    mib(budget)
                )
            })
            .collect()
    }

    /// Bytes of the mip pyramids built so far.
    pub fn built_pyramid_bytes(&self) -> u64 {
        (self.exemplars.iter())
            .filter(|e| e.pyramid_built())
            .map(|e| e.pyramid_bytes())
            .sum()
    }

    /// Selection by attribute: `by` gives one range per exemplar, and
    /// new patches choose by it ([`ExemplarSelect::Attribute`]).
    pub fn with_select_by(mut self, by: SelectBy) -> Result<ExemplarSet, ExemplarError> {
        if by.ranges.len() != self.len() {
            return Err(ExemplarError::Layout {
                what: format!("--select-by {}", by.attribute),
                reason: format!(
                    "{} ranges for {} exemplars: give every exemplar its range (IMG@LO:HI)",
                    by.ranges.len(),
                    self.len()
                ),
            });
        }
        self.select = ExemplarSelect::Attribute;
        self.by = Some(by);
        Ok(self)
    }

    /// Number of entries (an animated exemplar counts once).
    pub fn len(&self) -> usize {
        self.names.len()
    }

    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// The first exemplar: the channel layout every exemplar shares.
    pub fn primary(&self) -> &Arc<Exemplar> {
        &self.exemplars[0]
    }

    /// Every slot: the entries' frames side by side ([`ExemplarSet::slot`]).
    pub fn exemplars(&self) -> &[Arc<Exemplar>] {
        &self.exemplars
    }

    /// Bytes the exemplars hold ([`Exemplar::memory_bytes`]).
    pub fn memory_bytes(&self) -> u64 {
        self.exemplars.iter().map(|e| e.memory_bytes()).sum()
    }

    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Normalised target proportions.
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }

    /// The exemplar a uniform draw `bits` (64 random bits) picks from the
    /// weights.
    pub fn draw(&self, bits: u64) -> u32 {
        let u = (bits >> 40) as f32 / (1u64 << 24) as f32;
        let mut acc = 0.0;
        for (i, w) in self.weights.iter().enumerate() {
            acc += w;
            if u < acc {
                return i as u32;
            }
        }
        (self.weights.len() - 1) as u32
    }

    /// Checks that region selection has a source on `mesh` (the attribute
    /// or the image) and that every `exemplar_id` of `mesh` names an
    /// exemplar; the error names the frame and the vertex.
    pub fn check_mesh(&self, mesh: &TriMesh, frame: i32) -> Result<(), String> {
        if let Some(by) = &self.by {
            return by.check_mesh(mesh, frame);
        }
        if self.select != ExemplarSelect::Region || self.len() < 2 {
            return Ok(());
        }
        match mesh.attributes.get(EXEMPLAR_ID) {
            Some(Attribute::Scalar(ids)) => {
                for (v, &id) in ids.iter().enumerate() {
                    if !(id.is_finite() && id >= 0.0 && id.fract() == 0.0)
                        || id as usize >= self.len()
                    {
                        return Err(format!(
                            "frame {frame}: vertex {v} has exemplar_id {id}; \
                             with {} exemplars it must be an integer from 0 to {}",
                            self.len(),
                            self.len() - 1
                        ));
                    }
                }
                Ok(())
            }
            Some(_) => Err(format!(
                "frame {frame}: the exemplar_id attribute must be one number per vertex"
            )),
            None if self.region.is_some() || mesh.is_empty() => Ok(()),
            None => Err(format!(
                "frame {frame}: --exemplar-select region needs a per-vertex exemplar_id \
                 on the mesh or a region image (--exemplar-region)"
            )),
        }
    }
}

/// The exemplars' texel histogram around a point: one entry per patch,
/// at its centre, weighted by the atlas texels it covers.
#[derive(Clone, Debug, Default)]
pub struct Coverage {
    entries: Vec<(Vec3, u32, f32)>,
}

impl Coverage {
    pub fn push(&mut self, centre: Vec3, exemplar: u32, texels: f32) {
        if texels > 0.0 && centre.is_finite() {
            self.entries.push((centre, exemplar, texels));
        }
    }

    /// Per-exemplar texels of the patches within `reach` of `at` (all of
    /// them for `reach` = ∞), and how many patches counted.
    fn histogram(&self, at: Vec3, reach: f32, count: usize) -> (Vec<f64>, usize) {
        let mut h = vec![0.0f64; count];
        let mut n = 0;
        let r2 = reach * reach;
        for &(c, e, t) in &self.entries {
            if (reach.is_infinite() || c.distance_squared(at) <= r2)
                && let Some(slot) = h.get_mut(e as usize)
            {
                *slot += t as f64;
                n += 1;
            }
        }
        (h, n)
    }
}

/// Chooses the exemplars of a frame's new patches (one per method step).
pub struct Chooser<'a> {
    set: &'a ExemplarSet,
    seed: u64,
    mesh: &'a TriMesh,
    ids: Option<&'a [f32]>,
    region: Option<RegionBox>,
    /// Histogram neighbourhood, world units.
    reach: f32,
    pub coverage: Coverage,
}

/// Stream of the probability draw in [`crate::seed::mix`] (the rotation
/// uses 1, the first frame's Poisson disks 2).
const DRAW_STREAM: u64 = 7;

impl<'a> Chooser<'a> {
    /// `radius`: the patch radius r (the histogram reach is
    /// [`HISTOGRAM_REACH`] × r); `region`: where the region image lies.
    pub fn new(
        set: &'a ExemplarSet,
        seed: u64,
        mesh: &'a TriMesh,
        region: Option<RegionBox>,
        radius: f32,
    ) -> Chooser<'a> {
        let ids = match mesh.attributes.get(EXEMPLAR_ID) {
            Some(Attribute::Scalar(ids)) if ids.len() == mesh.vertex_count() => {
                Some(ids.as_slice())
            }
            _ => None,
        };
        Chooser {
            set,
            seed,
            mesh,
            ids,
            region,
            reach: HISTOGRAM_REACH * radius,
            coverage: Coverage::default(),
        }
    }

    /// The exemplar of a new patch centred at `at`; `key` keys its
    /// probability draw (as the patch's rotation is keyed).
    pub fn choose(&mut self, at: SurfacePoint, key: u64) -> u32 {
        let n = self.set.len();
        if n < 2 {
            return 0;
        }
        let draw = || self.set.draw(crate::seed::mix(self.seed, DRAW_STREAM, key));
        let Some(&corners) = self.mesh.triangles.get(at.triangle as usize) else {
            return draw();
        };
        match self.set.select {
            ExemplarSelect::Probability => draw(),
            ExemplarSelect::Region => {
                if let Some(ids) = self.ids {
                    let mut k = 0;
                    for j in 1..3 {
                        if at.bary[j] > at.bary[k] {
                            k = j;
                        }
                    }
                    let id = ids.get(corners[k] as usize).copied().unwrap_or(0.0);
                    // Checked by ExemplarSet::check_mesh; clamped regardless.
                    (id.max(0.0) as usize).min(n - 1) as u32
                } else if let (Some(image), Some(b)) = (&self.set.region, self.region) {
                    let (u, v) = b.uv(at.position(self.mesh));
                    image.index_at(u, v, n)
                } else {
                    draw()
                }
            }
            ExemplarSelect::Histogram => {
                let p = at.position(self.mesh);
                let (global, all) = self.coverage.histogram(p, f32::INFINITY, n);
                if all == 0 {
                    return draw();
                }
                // The neighbourhood's distance to the target, plus the whole
                // surface's: local mixing, and no drift of the total.
                let mut score = distances(&global, all, self.set.weights());
                let (local, near) = self.coverage.histogram(p, self.reach, n);
                if near > 0 {
                    for (s, d) in score
                        .iter_mut()
                        .zip(distances(&local, near, self.set.weights()))
                    {
                        *s += d;
                    }
                }
                argmin(&score)
            }
            ExemplarSelect::Attribute => match &self.set.by {
                Some(by) => match by.values(self.mesh) {
                    Some(values) => {
                        let x = SelectBy::value_at(values, self.mesh, at);
                        by.draw(x, crate::seed::mix(self.seed, DRAW_STREAM, key))
                    }
                    None => draw(),
                },
                None => draw(),
            },
        }
    }
}

/// For each exemplar e, the squared distance between the proportions of
/// histogram `h` (of `counted` patches) with one more patch of e, of the
/// histogram's mean patch size, and `target`.
pub fn distances(h: &[f64], counted: usize, target: &[f32]) -> Vec<f64> {
    let total: f64 = h.iter().sum();
    let add = total / counted.max(1) as f64;
    let after = total + add;
    (0..h.len())
        .map(|e| {
            h.iter()
                .zip(target)
                .enumerate()
                .map(|(k, (&hk, &t))| {
                    let v = if k == e { hk + add } else { hk };
                    (v / after - t as f64).powi(2)
                })
                .sum()
        })
        .collect()
}

/// The exemplar whose addition brings histogram `h` closest to `target`
/// ([`distances`]); ties go to the lower index.
pub fn steer(h: &[f64], counted: usize, target: &[f32]) -> u32 {
    argmin(&distances(h, counted, target))
}

/// Index of the smallest score (the first of equals).
fn argmin(score: &[f64]) -> u32 {
    let mut best = (f64::INFINITY, 0u32);
    for (e, &d) in score.iter().enumerate() {
        if d < best.0 {
            best = (d, e as u32);
        }
    }
    best.1
}
