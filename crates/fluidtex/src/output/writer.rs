//! The writer of a frame's files: channel atlases, meshes, previews and
//! debug views, staged and renamed together with `stats.F.json`, then
//! `state.bin`. It runs on the write-behind thread ([`super::write_behind`])
//! or in place, and hands each written frame to the sinks of written frames
//! the run added ([`WrittenFrameSink`]: the coherence numbers).

use std::sync::Arc;

use glam::Vec3;

use crate::exemplar::channels::{ChannelFormat, ChannelSpec};
use crate::frame::{FrameGeometry, StageClock};
use crate::io::{InputGuard, IoError, Staging};
use crate::methods::MethodStats;
use crate::render::{self, Camera};
use crate::texture::Texture;

use super::error::PipelineError;
use super::images::{
    OutChannel, output_error, patch_colours, patch_png, write_channel, write_file,
    write_out_channel, write_source_ids,
};
use super::options::Job;
use super::report::FrameStats;
use super::state::save_state;

/// What the writer needs to know of the method: the same for every frame
/// of a run.
pub(crate) struct MethodInfo {
    pub name: &'static str,
    pub specs: Vec<ChannelSpec>,
}

/// A filled frame on its way to the writer.
pub(super) struct WriteJob {
    pub geometry: Arc<FrameGeometry>,
    /// The number of the frame before, if any.
    pub previous_number: Option<i32>,
    /// The frame before, only where a sink of written frames reads it
    /// ([`Reads`]; [`super::FileSink`]): otherwise the writer would hold
    /// a third frame's geometry while the method fills the next.
    pub previous: Option<Arc<FrameGeometry>>,
    /// Channels dilated into the gutter, colour first.
    pub channels: Vec<OutChannel>,
    pub source: Option<Vec<u32>>,
    /// The method's renewal bytes ([`crate::methods::FrameResult::renewal`]):
    /// which switches the flow forced, for the coherence numbers.
    pub renewal: Option<Vec<u8>>,
    pub method_stats: MethodStats,
    /// Stages so far; the writer adds its own.
    pub clock: StageClock,
    /// [`crate::methods::Method::save_state`] after this frame, taken before
    /// the method moves on to the next, for `state.bin`; `None` where the
    /// run keeps no state (resampling: the selecting phase keeps it).
    pub state: Option<Vec<u8>>,
    /// The frame is resampled only for what the sinks of written frames
    /// keep of it (the coherence data the next frame is measured
    /// against): none of its files is written.
    pub prime: bool,
}

/// What the writer reports of a frame whose files and state are committed.
pub(super) struct Written {
    pub stats: FrameStats,
    /// A primed frame ([`WriteJob::prime`]): nothing written, nothing to count.
    pub primed: bool,
    /// Said to the user before the frame counts done.
    pub warnings: Vec<String>,
}

/// A frame as its files hold it, handed to each [`WrittenFrameSink`] once
/// its channels, meshes and previews are staged (before they are renamed
/// into place, and before the debug views).
pub(crate) struct WrittenFrame<'a> {
    pub geometry: &'a FrameGeometry,
    /// The frame before, where a sink asked for it ([`Reads`]).
    pub previous: Option<&'a FrameGeometry>,
    /// The number of the frame before in this run, if any.
    pub previous_number: Option<i32>,
    /// The method's channels, colour first, and the channels as written.
    pub specs: &'a [ChannelSpec],
    pub channels: &'a [OutChannel],
    /// Each texel's patch id, where the method gives them.
    pub source: Option<&'a [u32]>,
    /// The method's renewal bytes, where it recorded them.
    pub renewal: Option<&'a [u8]>,
}

/// What a sink of written frames may add to a frame: files staged with the
/// frame's own (committed with them), numbers in its stats, a stage on its
/// clock, warnings for the user.
pub(crate) struct FrameAdditions<'f, 's> {
    pub files: &'f mut Staging<'s>,
    pub stats: &'f mut FrameStats,
    pub clock: &'f mut StageClock,
    pub warnings: &'f mut Vec<String>,
}

/// What the sinks of written frames read besides the written frame: the
/// file sink hands the writer only what is read.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Reads {
    /// The method's renewal bytes (the method may skip recording them
    /// otherwise).
    pub renewal: bool,
    /// The geometry of the frame before, on every frame.
    pub previous: bool,
    /// The geometry of the frame before, on the first frame handed over
    /// (a resumed run reloads what it kept of its last finished frame).
    pub first_previous: bool,
}

impl Reads {
    fn or(self, other: Reads) -> Reads {
        Reads {
            renewal: self.renewal || other.renewal,
            previous: self.previous || other.previous,
            first_previous: self.first_previous || other.first_previous,
        }
    }
}

/// Something that reads each frame as written, on the writer's thread:
/// added by the run, called in the order added.
pub(crate) trait WrittenFrameSink: Send {
    /// What it reads besides the written frame.
    fn reads(&self) -> Reads;

    /// Reads `frame`; may stage files and add numbers to its stats
    /// (`out`). An error fails the frame, as a failed write does.
    fn frame(
        &mut self,
        frame: &WrittenFrame<'_>,
        out: &mut FrameAdditions<'_, '_>,
    ) -> Result<(), PipelineError>;
}

/// Writes every file of a frame, hands it to the sinks of written frames
/// and saves the state; on the write-behind thread
/// ([`super::write_behind`]) or in place.
pub(crate) struct FrameWriter<'a> {
    pub(super) job: &'a Job,
    guard: &'a InputGuard,
    pub(super) method: MethodInfo,
    /// The sequence's first frame, from which previews are counted.
    pub(super) first_frame: i32,
    sinks: Vec<Box<dyn WrittenFrameSink + 'a>>,
}

impl<'a> FrameWriter<'a> {
    /// A writer of `job`'s files that never writes over `guard`'s inputs.
    pub(crate) fn new(
        job: &'a Job,
        guard: &'a InputGuard,
        method: MethodInfo,
        first_frame: i32,
    ) -> FrameWriter<'a> {
        FrameWriter {
            job,
            guard,
            method,
            first_frame,
            sinks: Vec::new(),
        }
    }

    /// Adds a sink that reads each frame as written.
    pub(crate) fn add_sink(&mut self, sink: Box<dyn WrittenFrameSink + 'a>) {
        self.sinks.push(sink);
    }

    /// What the sinks read besides the written frames.
    pub(crate) fn reads(&self) -> Reads {
        self.sinks
            .iter()
            .fold(Reads::default(), |all, s| all.or(s.reads()))
    }

    /// Writes the frame of `w`: its files staged, handed to the sinks of
    /// written frames, the debug views, then all committed with its stats
    /// and state.
    pub(super) fn write(&mut self, w: WriteJob) -> Result<Written, PipelineError> {
        let WriteJob {
            geometry: g,
            previous_number,
            previous,
            channels,
            source,
            renewal,
            method_stats,
            mut clock,
            state,
            prime,
        } = w;
        // The time this frame waited for the writer is no stage of it.
        clock.restart();
        let mut warnings = Vec::new();
        let mut stats = frame_stats(self.method.name, &g, method_stats);
        // Every file of the frame is staged, then all are renamed together,
        // then the state counts the frame; a failure before the state is
        // written leaves the frame uncounted and `--resume` redoes it.
        // A primed frame's staged files are dropped, never renamed.
        let mut files = Staging::new(Some(self.guard), self.job.hooks.write.as_ref());
        if !prime {
            self.write_frame(&mut files, &g, &channels, source.as_deref())?;
        }
        clock.lap("write");
        let written = WrittenFrame {
            geometry: &g,
            previous: previous.as_deref(),
            previous_number,
            specs: &self.method.specs,
            channels: &channels,
            source: source.as_deref(),
            renewal: renewal.as_deref(),
        };
        let mut additions = FrameAdditions {
            files: &mut files,
            stats: &mut stats,
            clock: &mut clock,
            warnings: &mut warnings,
        };
        for sink in &mut self.sinks {
            sink.frame(&written, &mut additions)?;
        }
        // The channels (12 bytes a texel in colour alone) are written and
        // measured: not held while the debug views are made from the ids.
        drop(channels);
        if prime {
            return Ok(Written {
                stats,
                primed: true,
                warnings,
            });
        }
        if let Some(ids) = source.filter(|_| self.job.outputs.debug) {
            self.write_debug_views(&mut files, &g, ids)?;
            clock.lap("debug");
        }
        self.commit(files, &mut stats, &clock, state, g.number)?;
        Ok(Written {
            stats,
            primed: false,
            warnings,
        })
    }

    /// Stages `stats.F.json` with the frame's timings, renames every file
    /// of the frame into place, then saves the state: from then on the
    /// frame counts finished.
    fn commit(
        &self,
        mut files: Staging<'_>,
        stats: &mut FrameStats,
        clock: &StageClock,
        state: Option<Vec<u8>>,
        number: i32,
    ) -> Result<(), PipelineError> {
        let job = self.job;
        stats.stage_order = clock.stages.iter().map(|(n, _)| n.to_string()).collect();
        stats.seconds = clock
            .stages
            .iter()
            .map(|(n, s)| (n.to_string(), *s))
            .collect();
        let json = serde_json::to_vec_pretty(&stats).map_err(|e| PipelineError::Output {
            path: job.out_dir.clone(),
            message: e.to_string(),
        })?;
        write_file(
            &mut files,
            &job.out_dir
                .join(format!("stats.{}.json", frame_tag(number))),
            &json,
        )?;
        files.commit()?;
        if let Some(state) = state {
            save_state(job, self.guard, self.method.name, state, number)?;
        }
        if let Some(hook) = &job.hooks.after_frame {
            hook(number);
        }
        Ok(())
    }
}

/// The numbers of `stats.F.json` that the frame's geometry and the method
/// give; the sinks of written frames add theirs, the writer the timings.
fn frame_stats(method: &str, g: &FrameGeometry, method_stats: MethodStats) -> FrameStats {
    FrameStats {
        frame: g.number,
        method: method.to_string(),
        vertices: g.mesh.vertex_count(),
        triangles: g.mesh.triangle_count(),
        dropped_degenerate: g.report.dropped_degenerate,
        charts: g.atlas.chart_count,
        atlas_width: g.atlas.width,
        atlas_height: g.atlas.height,
        atlas_fill: g.atlas.texels_in_charts() as f64
            / (f64::from(g.atlas.width) * f64::from(g.atlas.height)).max(1.0),
        method_stats,
        ..Default::default()
    }
}

/// The frame number as written in file names: at least 4 digits.
pub fn frame_tag(number: i32) -> String {
    if number < 0 {
        format!("-{:04}", -(number as i64))
    } else {
        format!("{number:04}")
    }
}

/// Whether frame `number` gets a `preview.F.png`: every
/// `preview_every` frames counted from the sequence's `first_frame`.
pub(super) fn is_preview_frame(preview_every: u32, first_frame: i32, number: i32) -> bool {
    preview_every > 0 && (number - first_frame).rem_euclid(preview_every as i32) == 0
}

impl FrameWriter<'_> {
    /// Stages the files of one frame that need its channels: channels,
    /// meshes, previews (the debug views follow, [`Self::write_debug_views`]).
    fn write_frame(
        &self,
        files: &mut Staging<'_>,
        g: &FrameGeometry,
        channels: &[OutChannel],
        source: Option<&[u32]>,
    ) -> Result<(), PipelineError> {
        let colour_png = self.write_channels(files, g.number, channels)?;
        let normals = g.uv_mesh_normals();
        self.write_meshes(files, g, &normals, colour_png.as_ref())?;
        self.write_patch_views(files, g, channels, source, &normals)
    }

    /// Each channel atlas under its spec's name; the colour atlas's file
    /// name and PNG bytes, where it is a PNG, for the meshes to embed.
    fn write_channels(
        &self,
        files: &mut Staging<'_>,
        number: i32,
        channels: &[OutChannel],
    ) -> Result<Option<(String, Vec<u8>)>, PipelineError> {
        let tag = frame_tag(number);
        let dir = &self.job.out_dir;
        let method = &self.method;
        let specs = &method.specs;
        if specs.len() != channels.len() {
            return Err(PipelineError::Output {
                path: dir.clone(),
                message: format!(
                    "internal: method {} returned {} channels for {} names",
                    method.name,
                    channels.len(),
                    specs.len()
                ),
            });
        }
        let mut colour_png: Option<(String, Vec<u8>)> = None;
        for (spec, texture) in specs.iter().zip(channels) {
            let file = format!("{}.{tag}.{}", spec.name, spec.format.extension());
            let path = dir.join(&file);
            if let Some(bytes) = write_out_channel(files, &path, texture, spec.format)?
                && colour_png.is_none()
            {
                colour_png = Some((file, bytes));
            }
        }
        Ok(colour_png)
    }

    /// `mesh.F.obj` (with a material naming the colour PNG) and
    /// `mesh.F.glb` (with the PNG embedded), as the job asks.
    fn write_meshes(
        &self,
        files: &mut Staging<'_>,
        g: &FrameGeometry,
        normals: &[Vec3],
        colour_png: Option<&(String, Vec<u8>)>,
    ) -> Result<(), PipelineError> {
        let (job, uv) = (self.job, &g.atlas.uv_mesh);
        let tag = frame_tag(g.number);
        if job.outputs.obj {
            let obj = job.out_dir.join(format!("mesh.{tag}.obj"));
            let material = colour_png.map(|(file, _)| crate::io::obj_write::ObjMaterial {
                name: "fluidtex".to_string(),
                map_kd: file.clone(),
            });
            crate::io::obj_write::stage_obj(
                files,
                &obj,
                &uv.positions,
                &uv.uvs,
                Some(normals),
                &uv.triangles,
                material.as_ref(),
            )?;
        }
        if job.outputs.glb {
            let path = job.out_dir.join(format!("mesh.{tag}.glb"));
            let png = colour_png.map(|(_, b)| b.as_slice());
            // The PNG's bytes go into the file from `colour_png` itself.
            let glb = crate::io::gltf::layout_glb(
                &uv.positions,
                &uv.uvs,
                Some(normals),
                &uv.triangles,
                png,
            )
            .map_err(|reason| IoError::Unwritable {
                path: path.clone(),
                reason,
            })?;
            files.write(&path, |w| glb.write_to(w))?;
        }
        Ok(())
    }

    /// `preview.F.png` on preview frames: the lit render beside the view
    /// of where texels came from.
    fn write_patch_views(
        &self,
        files: &mut Staging<'_>,
        g: &FrameGeometry,
        channels: &[OutChannel],
        source: Option<&[u32]>,
        normals: &[Vec3],
    ) -> Result<(), PipelineError> {
        let number = g.number;
        let preview = is_preview_frame(self.job.outputs.preview_every, self.first_frame, number);
        // A preview frame's channels are handed over as floats.
        let Some(colour) = channels
            .first()
            .and_then(OutChannel::float)
            .filter(|_| preview)
        else {
            return Ok(());
        };
        // The patch colours as floats serve the preview only; the debug
        // file is made in 8 bits from the dilated ids (`patch_png`).
        let patches = match source {
            Some(source) => Some(
                patch_colours(&g.atlas, source, self.patch_view_radius()).map_err(|source| {
                    PipelineError::Atlas {
                        frame: number,
                        source,
                    }
                })?,
            ),
            None => None,
        };
        self.write_preview(files, g, colour, patches.as_ref(), normals)
    }

    /// Gutter texels of the patch views: twice the atlas's, so that the
    /// view's charts stand out at a glance.
    fn patch_view_radius(&self) -> u32 {
        self.job.atlas.gutter.max(1) * 2
    }

    /// The debug views of where texels came from, made from the ids alone:
    /// `source.F.exr`, then `patches.F.png`, which dilates the ids it is
    /// handed (they are not needed after it).
    fn write_debug_views(
        &self,
        files: &mut Staging<'_>,
        g: &FrameGeometry,
        source: Vec<u32>,
    ) -> Result<(), PipelineError> {
        let (job, number, atlas) = (self.job, g.number, &g.atlas);
        let tag = frame_tag(number);
        let path = job.out_dir.join(format!("source.{tag}.exr"));
        let source = write_source_ids(files, &path, atlas, source)?;
        let path = job.out_dir.join(format!("patches.{tag}.png"));
        let bytes =
            patch_png(atlas, source, self.patch_view_radius()).map_err(output_error(&path))?;
        write_file(files, &path, &bytes)
    }

    /// `preview.F.png`: a lit render of the textured mesh beside the patch
    /// view, from a camera framing this frame's surface.
    fn write_preview(
        &self,
        files: &mut Staging<'_>,
        g: &FrameGeometry,
        colour: &Texture,
        patches: Option<&Texture>,
        normals: &[Vec3],
    ) -> Result<(), PipelineError> {
        let Some((lo, hi)) = g.mesh.bounding_box() else {
            return Ok(());
        };
        let uv = &g.atlas.uv_mesh;
        let size = self.job.outputs.preview_size.clamp(16, 8192);
        let camera = Camera::framing(lo, hi, Vec3::new(-0.45, -0.8, -0.4), size, size);
        let gb = render::rasterize(&uv.positions, &uv.triangles, &camera);
        let background = [0.12, 0.12, 0.14];
        let views: Vec<Texture> = std::iter::once(colour)
            .chain(patches)
            .map(|texture| {
                render::shade_lit(
                    &gb,
                    &uv.triangles,
                    normals,
                    &uv.uvs,
                    texture,
                    &camera,
                    background,
                )
            })
            .collect();
        let sheet = render::side_by_side(&views.iter().collect::<Vec<_>>(), 8, background);
        let path = self
            .job
            .out_dir
            .join(format!("preview.{}.png", frame_tag(g.number)));
        write_channel(files, &path, &sheet, ChannelFormat::Png8)?;
        Ok(())
    }
}
