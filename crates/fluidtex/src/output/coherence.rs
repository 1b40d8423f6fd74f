//! The coherence numbers of `stats.F.json` (source switch share, forced
//! and unforced switches, by region, colour follow ratio) and
//! `switch.F.png`: a sink of written frames ([`WrittenFrameSink`]) that
//! the run adds when debug outputs are on. It measures what the files
//! hold (ids as `source.F.exr` stores them, grey values as the colour
//! atlas file stores them), so that a resumed run, which reloads the frame
//! before from its files, measures exactly what an uninterrupted one does.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::coherence::{CoherenceSettings, Departure};
use crate::exemplar::channels::{ChannelFormat, ChannelSpec};
use crate::frame::FrameGeometry;
use crate::io::Staging;
use crate::mesh::TriMesh;
use crate::methods::SOURCE_OUTSIDE;
use crate::surface::SurfacePoint;
use crate::texture::Texture;

use super::error::PipelineError;
use super::images::{OutChannel, write_channel};
use super::options::Job;
use super::report::FrameStats;
use super::writer::{FrameAdditions, Reads, WrittenFrame, WrittenFrameSink, frame_tag};

/// How the coherence sink measures. The defaults are the values of the
/// committed thresholds file (`metrics/thresholds.toml`: `[source_switch]`
/// `samples` and `seed`, `[colour_follow]` `min_move_texels` and
/// `min_moving_samples`), written out here so that a run parses no
/// thresholds file; a unit test holds them equal to
/// [`crate::metrics::Thresholds::committed`], so they cannot drift.
#[derive(Clone, Debug, PartialEq)]
pub struct CoherenceSinkSettings {
    /// Sample points and comparison: 20 000 points per frame pair, seed
    /// 2021, colour follow over points moving at least 3 atlas texels and
    /// only with at least 200 of them.
    pub measure: CoherenceSettings,
    /// Also write `switch.F.png` ([`super::OutputOptions::switch_map`])
    /// \[false].
    pub switch_map: bool,
}

impl Default for CoherenceSinkSettings {
    fn default() -> Self {
        CoherenceSinkSettings {
            measure: CoherenceSettings {
                samples: 20_000,
                seed: 2021,
                min_move_texels: 3.0,
                min_moving_samples: 200,
            },
            switch_map: false,
        }
    }
}

/// Measures each written frame against the one before (carried by the
/// meshes' velocity) and keeps what the next frame's measurement needs of
/// it ([`CoherencePrevious`]).
pub(crate) struct CoherenceSink {
    out_dir: PathBuf,
    /// Seconds per frame.
    dt: f32,
    settings: CoherenceSinkSettings,
    /// The run resumed after this frame: the first frame's measurement
    /// reloads it from its files.
    resumed_after: Option<i32>,
    /// What the measurement keeps of the frame before.
    previous: Option<CoherencePrevious>,
}

impl CoherenceSink {
    /// The sink of `job`'s run, resumed after frame `resumed_after` (if so).
    pub(crate) fn new(
        job: &Job,
        settings: CoherenceSinkSettings,
        resumed_after: Option<i32>,
    ) -> CoherenceSink {
        CoherenceSink {
            out_dir: job.out_dir.clone(),
            dt: 1.0 / job.fps,
            settings,
            resumed_after,
            previous: None,
        }
    }
}

impl WrittenFrameSink for CoherenceSink {
    /// The renewal bytes (forced or chosen switches); the frame before's
    /// geometry for the switch map, and on the first frame of a resumed run.
    fn reads(&self) -> Reads {
        Reads {
            renewal: true,
            previous: self.settings.switch_map,
            first_previous: self.resumed_after.is_some(),
        }
    }

    /// Frames without per-texel ids are not measured.
    fn frame(
        &mut self,
        frame: &WrittenFrame<'_>,
        out: &mut FrameAdditions<'_, '_>,
    ) -> Result<(), PipelineError> {
        let Some(ids) = frame.source else {
            return Ok(());
        };
        let (g, prev) = (frame.geometry, frame.previous);
        if self.previous.is_none()
            && let (Some(last), Some(prev)) = (self.resumed_after, prev)
        {
            self.previous = self.reload(frame.specs.first(), prev, last, out.warnings);
        }
        let current = WrittenTexels::of(frame.specs, &g.atlas, ids, frame.channels)
            .with_renewal(frame.renewal.unwrap_or_default());
        if let Some(before) = &self.previous
            && Some(before.number) == frame.previous_number
            && let Some((c, ends)) = self.measure(out.files, prev, before, g, &current)?
        {
            record(out.stats, g, &c, &ends);
        }
        self.previous = Some(CoherencePrevious::of(
            &current,
            g,
            &self.settings.measure,
            self.settings.switch_map,
        ));
        out.clock.lap("coherence");
        Ok(())
    }
}

/// Puts a measured frame's numbers into its stats.
fn record(
    stats: &mut FrameStats,
    g: &FrameGeometry,
    c: &crate::coherence::Coherence,
    ends: &[CarriedEnds],
) {
    // By region needs the patch radius, which the lapped methods report.
    let radius = stats
        .method_stats
        .get("radius")
        .and_then(serde_json::Value::as_f64)
        .filter(|r| *r > 0.0 && r.is_finite());
    if let Some(radius) = radius
        && c.causes.covered > 0
    {
        stats.switch_by_region = Some(switch_regions(g, ends, radius as f32));
    }
    stats.source_switch_share = Some(c.switch_share());
    stats.source_changed_share = Some(c.switch.changed_share());
    if c.causes.covered > 0 {
        stats.switch_forced_share = Some(c.causes.forced_share());
        stats.switch_unforced_share = Some(c.causes.unforced_share());
        stats.switch_unforced_shown_share = Some(c.causes.unforced_shown_share());
        stats.switch_forced_eroding_share = Some(c.causes.forced_eroding_share());
        stats.switch_unforced_on_top_share = Some(c.causes.unforced_on_top_share());
        stats.switch_unforced_other_share = Some(c.causes.unforced_other_share());
        stats.holder_distorted_share = Some(c.causes.distorted_share());
    }
    stats.colour_follow_ratio = Some(c.follow_ratio());
}

/// What the coherence measurement of the next frame needs of this one:
/// its sample points (drawn on its mesh, seeded by its number) and its
/// source and grey value at each, *as written to the files*
/// (`source.F.exr` stores ids as f32; the grey values are those of the
/// colour atlas file), so that a resumed run, which reloads them from
/// those files, measures exactly what an uninterrupted one does. 20 000
/// points instead of the whole atlas: the frame job keeps no atlas-sized
/// copy for the measurement. With the switch map, also the whole written
/// source and grey (the atlas is the driver's previous frame's).
struct CoherencePrevious {
    number: i32,
    /// The sample points (with their positions and velocity) and the
    /// values there; `None` when the frame has no velocity or its data does
    /// not fit its atlas (no measurement).
    points: Option<(Departure, Vec<crate::coherence::PointValue>)>,
    /// Written source and grey per texel, for `switch.F.png` only.
    full: Option<(Vec<u32>, Vec<f32>)>,
}

/// The sample points of the pair (frame `number`, the next): one set per
/// frame pair, seeded by the frame, so a resumed run draws the same points.
fn coherence_points(
    mesh: &TriMesh,
    number: i32,
    settings: &crate::coherence::CoherenceSettings,
) -> Vec<SurfacePoint> {
    let seed = crate::seed::mix(settings.seed, 7, number as u64);
    crate::coherence::sample_surface(mesh, settings.samples, seed)
}

/// The sample points of frame `number` (mesh `mesh`) ready to be carried
/// to the next frame, and `texels`' values there; `None` when the mesh has
/// no velocity or the texels do not fit the atlas.
fn departure_values(
    mesh: &TriMesh,
    number: i32,
    settings: &crate::coherence::CoherenceSettings,
    texels: &impl crate::coherence::Texels,
) -> Option<(Departure, Vec<crate::coherence::PointValue>)> {
    let velocity = mesh.velocity()?;
    let points = coherence_points(mesh, number, settings);
    let values = crate::coherence::point_values(&points, texels).ok()?;
    Some((Departure::of(mesh, velocity, points), values))
}

impl CoherencePrevious {
    /// This frame's data as its files hold it (computed in memory: the
    /// files are committed together with the stats that carry the result).
    fn of(
        current: &WrittenTexels<'_>,
        g: &FrameGeometry,
        settings: &crate::coherence::CoherenceSettings,
        switch_map: bool,
    ) -> CoherencePrevious {
        use crate::coherence::Texels;
        let points = departure_values(&g.mesh, g.number, settings, current);
        let full = switch_map.then(|| {
            let n = current.source.len();
            let source = (0..n).into_par_iter().map(|i| current.source(i)).collect();
            let grey = match current.colour {
                Some((OutChannel::Float(colour), format)) => written_grey(colour, format),
                // Texel by texel, the same values.
                Some(_) => (0..n).into_par_iter().map(|i| current.grey(i)).collect(),
                None => Vec::new(),
            };
            (source, grey)
        });
        CoherencePrevious {
            number: g.number,
            points,
            full,
        }
    }
}

/// A frame's output as its files will hold it, read texel by texel from
/// the method's result (no atlas-sized copy): ids as `source.F.exr` stores
/// them (f32), grey values as the colour atlas file stores them (the same
/// per-texel arithmetic as [`written_grey`]).
struct WrittenTexels<'a> {
    atlas: &'a crate::atlas::Atlas,
    source: &'a [u32],
    /// The colour atlas and its file format; `None` without channels.
    colour: Option<(&'a OutChannel, ChannelFormat)>,
    /// The method's renewal bytes; empty where it records none.
    renewal: &'a [u8],
}

impl<'a> WrittenTexels<'a> {
    fn of(
        specs: &[ChannelSpec],
        atlas: &'a crate::atlas::Atlas,
        source: &'a [u32],
        channels: &'a [OutChannel],
    ) -> WrittenTexels<'a> {
        let colour = match (specs.first(), channels.first()) {
            (Some(spec), Some(colour)) => Some((colour, spec.format)),
            _ => None,
        };
        WrittenTexels {
            atlas,
            source,
            colour,
            renewal: &[],
        }
    }

    /// With the method's renewal bytes (`renewal`, empty: none).
    fn with_renewal(self, renewal: &'a [u8]) -> WrittenTexels<'a> {
        WrittenTexels { renewal, ..self }
    }
}

impl crate::coherence::Texels for WrittenTexels<'_> {
    fn atlas(&self) -> &crate::atlas::Atlas {
        self.atlas
    }

    fn source(&self, i: usize) -> u32 {
        match self.source.get(i) {
            Some(&s) if s != SOURCE_OUTSIDE => s as f32 as u32,
            _ => SOURCE_OUTSIDE,
        }
    }

    fn grey(&self, i: usize) -> f32 {
        let Some((colour, format)) = self.colour else {
            return f32::NAN;
        };
        let channels = colour.channels();
        let c = channels.max(1);
        let texel = i * c..(i + 1) * c;
        match colour {
            OutChannel::Float(t) => t.data.get(texel).map_or(f32::NAN, |texel| {
                written_grey_texel(texel, channels, format)
            }),
            // The samples the PNG holds, scaled as its decoder scales them:
            // the values `written_grey_texel` makes of the floats.
            OutChannel::Eight { samples, .. } => samples.get(texel).map_or(f32::NAN, |texel| {
                grey_of(
                    texel.iter().map(|&q| f32::from(q) / 255.0).collect(),
                    channels,
                )
            }),
        }
    }

    fn renewal(&self, i: usize) -> u8 {
        self.renewal
            .get(i)
            .copied()
            .unwrap_or(crate::provenance::RENEWAL_UNKNOWN)
    }

    fn validate(&self) -> Result<(), crate::metrics::MetricsError> {
        let (w, h) = (self.atlas.width, self.atlas.height);
        crate::metrics::check_len("source", self.source, w, h)?;
        if !self.renewal.is_empty() {
            crate::metrics::check_len("renewal", self.renewal, w, h)?;
        }
        // As many grey values as `written_grey` would give.
        let greys = self.colour.map_or(0, |(c, _)| c.texels());
        let expected = w as usize * h as usize;
        if greys == expected {
            Ok(())
        } else {
            Err(crate::metrics::MetricsError::Length {
                what: "grey",
                expected,
                got: greys,
            })
        }
    }
}

/// [`written_grey`] of one texel (`channels` values): the same arithmetic.
fn written_grey_texel(texel: &[f32], channels: usize, format: ChannelFormat) -> f32 {
    let quantize =
        |levels: f32, x: f32| (((x.clamp(0.0, 1.0) * levels) as f64 + 0.5) as u32) as f32 / levels;
    let data: Vec<f32> = match format {
        ChannelFormat::Png8 => texel.iter().map(|&x| quantize(255.0, x)).collect(),
        ChannelFormat::Png16 => texel.iter().map(|&x| quantize(65535.0, x)).collect(),
        ChannelFormat::Exr => texel.to_vec(),
    };
    grey_of(data, channels)
}

/// The luminance of one texel's `channels` values.
fn grey_of(data: Vec<f32>, channels: usize) -> f32 {
    let one = Texture {
        width: 1,
        height: 1,
        channels,
        data,
    };
    crate::metrics::luminance(&one)
        .first()
        .copied()
        .unwrap_or(f32::NAN)
}

/// The luminance of a colour atlas as the file written in `format` stores
/// it: the same clamping and rounding as the PNG encoder and the same
/// scaling as the decoder (`--resume` reads the file back), so an
/// uninterrupted and a resumed run measure identical values.
fn written_grey(colour: &Texture, format: ChannelFormat) -> Vec<f32> {
    let quantize = |levels: f32| {
        move |x: f32| (((x.clamp(0.0, 1.0) * levels) as f64 + 0.5) as u32) as f32 / levels
    };
    let data: Vec<f32> = match format {
        ChannelFormat::Png8 => colour.data.iter().map(|&x| quantize(255.0)(x)).collect(),
        ChannelFormat::Png16 => colour.data.iter().map(|&x| quantize(65535.0)(x)).collect(),
        ChannelFormat::Exr => colour.data.clone(),
    };
    let texture = Texture {
        width: colour.width,
        height: colour.height,
        channels: colour.channels,
        data,
    };
    crate::metrics::luminance(&texture)
}

/// The luminance of frame `number`'s colour atlas as written in `out_dir`.
fn read_grey(
    out_dir: &Path,
    colour: Option<&ChannelSpec>,
    number: i32,
) -> Result<Vec<f32>, PipelineError> {
    let Some(spec) = colour else {
        return Ok(Vec::new());
    };
    let path = out_dir.join(format!(
        "{}.{}.{}",
        spec.name,
        frame_tag(number),
        spec.format.extension()
    ));
    let decoded = crate::io::image_read::read_image(&path).map_err(|e| PipelineError::Output {
        path: path.clone(),
        message: format!("cannot read it back for the coherence measurement: {e}"),
    })?;
    Ok(crate::metrics::luminance(&decoded.texture))
}

impl CoherenceSink {
    /// After `--resume`: the coherence data of the last finished frame
    /// (`prev`, re-read), from its files (`source.F.exr`, the colour atlas).
    /// `None`, with a warning, when they cannot be read (then the first resumed
    /// frame has no coherence numbers).
    fn reload(
        &self,
        colour: Option<&ChannelSpec>,
        prev: &FrameGeometry,
        last: i32,
        warnings: &mut Vec<String>,
    ) -> Option<CoherencePrevious> {
        let settings = &self.settings.measure;
        let load = || -> Result<CoherencePrevious, String> {
            let path = self.out_dir.join(format!("source.{}.exr", frame_tag(last)));
            let ids = crate::io::image_read::read_image(&path).map_err(|e| e.to_string())?;
            let source: Vec<u32> = ids
                .texture
                .data
                .iter()
                .step_by(ids.texture.channels.max(1))
                .map(|&v| if v < 0.0 { SOURCE_OUTSIDE } else { v as u32 })
                .collect();
            drop(ids);
            let grey = read_grey(&self.out_dir, colour, last).map_err(|e| e.to_string())?;
            let texels = crate::coherence::TexelFrame {
                atlas: &prev.atlas,
                source: &source,
                grey: &grey,
                renewal: &[],
            };
            let points = departure_values(&prev.mesh, last, settings, &texels);
            let full = self.settings.switch_map.then_some((source, grey));
            Ok(CoherencePrevious {
                number: last,
                points,
                full,
            })
        };
        match load() {
            Ok(c) => Some(c),
            Err(e) => {
                warnings.push(format!(
                    "frame {}: no source switch share (frame {last} cannot be reloaded: {e})",
                    last + 1
                ));
                None
            }
        }
    }

    /// Source switch share and colour follow ratio from the frame before
    /// to this one (carried by the meshes' velocity), and, when asked,
    /// `switch.F.png`. `None` when a frame has no velocity or the data does
    /// not fit its atlas.
    fn measure(
        &self,
        files: &mut Staging<'_>,
        prev: Option<&FrameGeometry>,
        before: &CoherencePrevious,
        frame: &FrameGeometry,
        current: &WrittenTexels<'_>,
    ) -> Result<Option<(crate::coherence::Coherence, Vec<CarriedEnds>)>, PipelineError> {
        use crate::coherence::{self, TexelFrame, switch_map};
        use crate::surface::velocity::FlowFrame;
        let Some(v1) = frame.mesh.velocity() else {
            return Ok(None);
        };
        let Some((departure, values)) = &before.points else {
            return Ok(None);
        };
        let settings = &self.settings.measure;
        let dt = self.dt;
        let next = FlowFrame {
            mesh: &frame.mesh,
            index: &frame.index,
            velocity: v1,
        };
        let carried = departure.carry(next, dt);
        let Ok((found, ends)) = coherence::measure_from_ends(&carried, values, current, settings)
        else {
            return Ok(None);
        };
        if self.settings.switch_map
            && let Some((source, grey)) = &before.full
            && let Some(prev) = prev
            && let Some(v0) = prev.mesh.velocity()
        {
            let from = FlowFrame {
                mesh: &prev.mesh,
                index: &prev.index,
                velocity: v0,
            };
            let from_texels = TexelFrame {
                atlas: &prev.atlas,
                source,
                grey,
                renewal: &[],
            };
            if let Ok(map) = switch_map(&from_texels, from, current, next, dt) {
                let image = coherence::switch_image(&map, frame.atlas.width, frame.atlas.height);
                write_channel(
                    files,
                    &self
                        .out_dir
                        .join(format!("switch.{}.png", frame_tag(frame.number))),
                    &image,
                    ChannelFormat::Png8,
                )?;
            }
        }
        Ok(Some((found, carried.to.into_iter().zip(ends).collect())))
    }
}

/// A carried point's location on this frame and what it found at both ends.
type CarriedEnds = (Option<SurfacePoint>, crate::coherence::PointEnds);

/// `stats.F.json`'s `switch_by_region`: the carried points' switches by
/// the region of frame `g` they land in ([`crate::coherence::regions`]).
fn switch_regions(
    g: &FrameGeometry,
    ends: &[CarriedEnds],
    radius: f32,
) -> BTreeMap<&'static str, crate::coherence::regions::RegionSwitch> {
    use crate::coherence::regions::{RegionMap, switch_by_region};
    let map = RegionMap::new(&g.mesh, &g.index, &g.topology, radius);
    let regions: Vec<_> = ends
        .par_iter()
        .map(|(to, _)| to.as_ref().and_then(|sp| map.region(sp)))
        .collect();
    let ends: Vec<_> = ends.iter().map(|e| e.1).collect();
    switch_by_region(&ends, &regions)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::{Atlas, AtlasParams, fixtures::icosphere};
    use crate::coherence::Texels;
    use crate::methods::SOURCE_UNCOVERED;
    use crate::metrics::Thresholds;
    use crate::output::images::written_channels;
    use rand::{Rng, SeedableRng};

    /// The run's coherence settings are the committed thresholds' values,
    /// which it does not parse: the two cannot drift apart.
    #[test]
    fn defaults_are_the_committed_thresholds() {
        let committed = Thresholds::committed().expect("the committed thresholds parse");
        assert_eq!(
            CoherenceSinkSettings::default().measure,
            CoherenceSettings::from_thresholds(&committed)
        );
        assert!(!CoherenceSinkSettings::default().switch_map);
    }

    /// The coherence measurement reads the written values texel by texel:
    /// each must be bit for bit what the whole-atlas conversion (the one a
    /// resumed run's file read-back matches) gives, for every format,
    /// including values outside [0, 1] and ids that f32 rounds.
    #[test]
    fn written_texels_match_the_whole_atlas_conversion() {
        let atlas = Atlas::build(&icosphere(2), &AtlasParams::square(16)).expect("atlas");
        let n = (atlas.width * atlas.height) as usize;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let mut source: Vec<u32> = (0..n).map(|_| rng.random_range(0..40)).collect();
        source[0] = SOURCE_OUTSIDE;
        source[1] = SOURCE_UNCOVERED;
        source[2] = (1 << 24) + 1;
        for channels in [1usize, 3, 4] {
            let data = (0..n * channels)
                .map(|_| rng.random_range(-0.2f32..1.2))
                .collect();
            let colour = Texture {
                width: atlas.width,
                height: atlas.height,
                channels,
                data,
            };
            for format in [
                ChannelFormat::Png8,
                ChannelFormat::Png16,
                ChannelFormat::Exr,
            ] {
                let whole = written_grey(&colour, format);
                // As floats, and (8-bit PNG) as the samples handed to the
                // writer instead.
                let (handed, _) = written_channels(vec![colour.clone()], &[format], true);
                let float = OutChannel::Float(colour.clone());
                assert_eq!(
                    matches!(handed[0], OutChannel::Eight { .. }),
                    format == ChannelFormat::Png8
                );
                for written in [&float, &handed[0]] {
                    let texels = WrittenTexels {
                        atlas: &atlas,
                        source: &source,
                        colour: Some((written, format)),
                        renewal: &[],
                    };
                    texels.validate().expect("fits");
                    for (i, g) in whole.iter().enumerate() {
                        assert_eq!(texels.grey(i).to_bits(), g.to_bits(), "{format:?} {i}");
                    }
                }
            }
        }
        let texels = WrittenTexels {
            atlas: &atlas,
            source: &source,
            colour: None,
            renewal: &[],
        };
        assert!(texels.validate().is_err(), "no colour: nothing to measure");
        assert_eq!(texels.source(0), SOURCE_OUTSIDE);
        assert_eq!(texels.source(1), SOURCE_UNCOVERED);
        assert_eq!(texels.source(2), 1 << 24, "as source.F.exr stores it");
        assert_eq!(texels.source(n), SOURCE_OUTSIDE);
        assert_eq!(texels.source(7), source[7]);
    }
}
