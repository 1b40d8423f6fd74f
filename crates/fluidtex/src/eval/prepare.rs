//! The method-independent half of an evaluation: meshes, atlases, per-texel
//! surface points, the fixed camera, G-buffers, interior masks and the true
//! motion per pixel. Built once per scene and shared by every method, so
//! that all methods see bit-identical inputs.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::truth::{TruthMotion, true_motion};
use super::{EvalError, EvalSettings};
use std::sync::Arc;

use crate::atlas::{Atlas, AtlasParams};
use crate::coherence::{Carried, CoherenceSettings, carry_by_velocity, sample_surface};
use crate::frame::{FrameGeometry, GeometryError, StageClock};
use crate::mesh::TriMesh;
use crate::metrics::{Thresholds, interior_mask};
use crate::render::{BACKGROUND, Camera, GBuffer, rasterize};
use crate::scenes::{Scene, SceneInfo};
use crate::surface::SurfacePoint;

/// One frame of a prepared scene.
pub struct PreparedFrame {
    /// The scene's frame number.
    pub number: i32,
    /// Scene time of the frame (s).
    pub time: f64,
    /// Mesh, surface index, atlas, topology and normals, as the driver
    /// hands them to every method.
    pub geometry: Arc<FrameGeometry>,
    /// Surface point per atlas texel (NaN outside charts).
    pub points: Vec<Vec3>,
    /// Chart id per atlas texel (`u32::MAX` outside charts).
    pub chart: Vec<u32>,
    /// Every vertex velocity is exactly zero: the fluid is still.
    pub still: bool,
    /// What the evaluation camera sees.
    pub gbuffer: GBuffer,
    /// Pixels away from silhouettes, depth edges and the image border.
    pub interior: Vec<bool>,
    /// True motion to the next frame (px), per pixel of this frame; `None`
    /// for the last frame.
    pub forward: Option<Vec<Vec2>>,
    /// True motion from the previous frame (px) per pixel of this frame
    /// (where the pixel's point was at the previous frame, relative to
    /// where it is now, negated: the displacement over the frame), and
    /// whether that point was visible then. `None` for the first frame.
    pub backward: Option<(Vec<Vec2>, Vec<bool>)>,
    /// Surface points sampled on this frame and carried to the next one by
    /// the true motion (the scene's exact flow where it has one, else the
    /// mesh velocity with a second-order step), located on the next mesh;
    /// for the source switch share and the colour follow ratio. `None` for
    /// the last frame.
    pub carried: Option<Carried>,
}

/// A scene's frames ready for evaluation.
pub struct PreparedScene {
    pub info: SceneInfo,
    /// Seconds per frame.
    pub dt: f32,
    pub camera: Camera,
    pub frames: Vec<PreparedFrame>,
    /// How the true motion was obtained (for the report).
    pub truth: TruthMotion,
}

/// Generates `frames` (increasing, inside the scene's range) of `scene`,
/// with atlases of `atlas` and renders of `settings`.
pub fn prepare(
    scene: &mut dyn Scene,
    frames: &[i32],
    atlas: &AtlasParams,
    settings: &EvalSettings,
    thresholds: &Thresholds,
) -> Result<PreparedScene, EvalError> {
    settings.validate()?;
    let info = scene.info();
    check_frames(&info, frames)?;
    let dt = (1.0 / info.fps) as f32;
    let mut meshes = Vec::with_capacity(frames.len());
    for &f in frames {
        let mut mesh = scene.frame(f)?;
        let report = crate::mesh::validate(&mut mesh).map_err(|e| EvalError::Mesh {
            frame: f,
            message: e.to_string(),
        })?;
        meshes.push((mesh, report));
    }
    let camera = window_camera(meshes.iter().map(|(m, _)| m), settings);
    let mut out: Vec<PreparedFrame> = Vec::with_capacity(frames.len());
    for (&number, (mesh, report)) in frames.iter().zip(meshes) {
        let time = (f64::from(number - info.first)) / info.fps;
        let geometry =
            FrameGeometry::build(number, mesh, report, atlas, &mut StageClock::default())
                .map_err(|GeometryError { frame, source }| EvalError::Atlas { frame, source })?;
        out.push(prepare_frame(time, geometry, &camera, thresholds)?);
    }
    let truth = TruthMotion::of(&*scene, settings.trace_substeps);
    for k in 1..out.len() {
        let (before, after) = out.split_at_mut(k);
        let motion = Motion {
            scene: &*scene,
            truth: &truth,
            camera: &camera,
            dt,
            thresholds,
        };
        motion.attach(&mut before[k - 1], &mut after[0]);
    }
    Ok(PreparedScene {
        info,
        dt,
        camera,
        frames: out,
        truth,
    })
}

/// `frames` must be non-empty, increasing and inside the scene's range.
fn check_frames(info: &SceneInfo, frames: &[i32]) -> Result<(), EvalError> {
    if frames.is_empty() {
        return Err(EvalError::Frames(format!("scene {}: no frames", info.name)));
    }
    if frames.windows(2).any(|w| w[1] <= w[0]) {
        return Err(EvalError::Frames(format!(
            "scene {}: frames must be increasing",
            info.name
        )));
    }
    if let Some(&f) = frames.iter().find(|&&f| f < info.first || f > info.last) {
        return Err(EvalError::Frames(format!(
            "scene {}: frame {f} is outside its range {}-{}",
            info.name, info.first, info.last
        )));
    }
    Ok(())
}

/// One camera for the whole window, framing every frame's surface, so a
/// surface that travels stays in view.
fn window_camera<'m>(meshes: impl Iterator<Item = &'m TriMesh>, settings: &EvalSettings) -> Camera {
    let (lo, hi) = meshes.filter_map(|m| m.bounding_box()).fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(l, h), (a, b)| (l.min(a), h.max(b)),
    );
    let (lo, hi) = if lo.x <= hi.x {
        (lo, hi)
    } else {
        (Vec3::ZERO, Vec3::ONE)
    };
    Camera::framing(
        lo,
        hi,
        settings.view_dir,
        settings.render_size,
        settings.render_size,
    )
}

/// A frame's texel points, render G-buffer and interior mask; its motion
/// is attached later ([`Motion::attach`]).
fn prepare_frame(
    time: f64,
    geometry: FrameGeometry,
    camera: &Camera,
    thresholds: &Thresholds,
) -> Result<PreparedFrame, EvalError> {
    let number = geometry.number;
    let (mesh, a) = (&geometry.mesh, &geometry.atlas);
    let (points, chart) = texel_points(mesh, a);
    let still = mesh
        .velocity()
        .is_some_and(|v| !v.is_empty() && v.iter().all(|v| *v == Vec3::ZERO));
    let gbuffer = rasterize(&a.uv_mesh.positions, &a.uv_mesh.triangles, camera);
    let foreground: Vec<bool> = gbuffer.triangle.iter().map(|&t| t != BACKGROUND).collect();
    let interior = interior_mask(
        gbuffer.width,
        gbuffer.height,
        &foreground,
        Some(&gbuffer.depth),
        &thresholds.silhouette,
    )
    .map_err(|source| EvalError::Metrics {
        frame: number,
        what: "interior mask",
        source,
    })?;
    Ok(PreparedFrame {
        number,
        time,
        geometry: Arc::new(geometry),
        points,
        chart,
        still,
        gbuffer,
        interior,
        forward: None,
        backward: None,
        carried: None,
    })
}

/// What the true motion between two prepared frames reads.
struct Motion<'a> {
    scene: &'a dyn Scene,
    truth: &'a TruthMotion,
    camera: &'a Camera,
    dt: f32,
    thresholds: &'a Thresholds,
}

impl Motion<'_> {
    /// The true motion from `prev` to `next`: forward on `prev`, backward
    /// (with visibility) on `next`, and the carried sample points.
    fn attach(&self, prev: &mut PreparedFrame, next: &mut PreparedFrame) {
        let step = (next.number - prev.number) as f64 * f64::from(self.dt);
        let motion = |frame: &PreparedFrame, step: f64| {
            true_motion(
                self.scene,
                self.truth,
                &frame.geometry.mesh,
                &frame.gbuffer,
                self.camera,
                frame.time,
                step,
            )
        };
        prev.forward = Some(motion(prev, step).0);
        let (back, depth) = motion(next, -step);
        // `back` is where the point was minus where it is; the metrics want
        // the displacement over the frame, and whether the point was seen.
        let visible = visible_before(&back, &depth, &next.gbuffer, &prev.gbuffer, self.thresholds);
        next.backward = Some((back.into_iter().map(|m| -m).collect(), visible));
        prev.carried = Some(carry_points(
            self.scene,
            self.truth,
            prev,
            next,
            step,
            self.thresholds,
        ));
    }
}

/// Samples points on `prev` (seeded by the committed thresholds and the
/// frame number) and carries them `step` seconds to `next`.
fn carry_points(
    scene: &dyn Scene,
    truth: &TruthMotion,
    prev: &PreparedFrame,
    next: &PreparedFrame,
    step: f64,
    thresholds: &Thresholds,
) -> Carried {
    let settings = CoherenceSettings::from_thresholds(thresholds);
    let seed = crate::seed::mix(settings.seed, 7, prev.number as u64);
    let points = sample_surface(&prev.geometry.mesh, settings.samples, seed);
    match (
        truth,
        prev.geometry.mesh.velocity(),
        next.geometry.mesh.velocity(),
    ) {
        (TruthMotion::Exact { substeps }, _, _) => {
            // Sequential: `Scene` is `Send` but not `Sync`.
            let carried: Vec<Option<Vec3>> = points
                .iter()
                .map(|sp| {
                    let p = sp
                        .interpolate(&prev.geometry.mesh.triangles, &prev.geometry.mesh.positions);
                    super::trace(scene, p, prev.time, step, *substeps)
                })
                .collect();
            Carried::locate(&prev.geometry.mesh, points, &carried, &next.geometry.index)
        }
        (TruthMotion::MeshVelocity, Some(v0), Some(v1)) => carry_by_velocity(
            &prev.geometry.mesh,
            v0,
            crate::surface::velocity::FlowFrame {
                mesh: &next.geometry.mesh,
                index: &next.geometry.index,
                velocity: v1,
            },
            step as f32,
            points,
        ),
        // No way to carry: nothing is measured.
        _ => Carried::locate(&prev.geometry.mesh, points, &[], &next.geometry.index),
    }
}

/// Surface point and chart id per atlas texel.
fn texel_points(mesh: &TriMesh, atlas: &Atlas) -> (Vec<Vec3>, Vec<u32>) {
    let tri = atlas.triangle_map();
    let w = atlas.width as usize;
    let mut points = vec![Vec3::NAN; tri.len()];
    for band in atlas.bands() {
        for span in &band.spans {
            let row = span.y as usize * w;
            for (x, bary) in atlas.span_barycentrics(span) {
                if let Some(p) = points.get_mut(row + x as usize) {
                    *p = SurfacePoint::new(span.triangle, bary)
                        .interpolate(&mesh.triangles, &mesh.positions);
                }
            }
        }
    }
    let chart = tri
        .iter()
        .map(|&t| {
            atlas
                .chart_of_triangle
                .get(t as usize)
                .copied()
                .unwrap_or(u32::MAX)
        })
        .collect();
    (points, chart)
}

/// Per pixel of the later frame: was its point, moved back to the earlier
/// frame, the surface the earlier frame shows there (not hidden behind
/// another part of it, not off the surface)?
fn visible_before(
    back_px: &[Vec2],
    back_depth: &[f32],
    next: &GBuffer,
    prev: &GBuffer,
    thresholds: &Thresholds,
) -> Vec<bool> {
    let (w, h) = (next.width as usize, next.height as usize);
    let jump = thresholds.silhouette.relative_depth_jump;
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            if next.triangle[i] == BACKGROUND {
                return false;
            }
            let m = back_px[i];
            if !m.is_finite() {
                return false;
            }
            let p = Vec2::new((i % w) as f32 + 0.5, (i / w) as f32 + 0.5) + m;
            if p.x < 0.0 || p.y < 0.0 || p.x >= w as f32 || p.y >= h as f32 {
                return false;
            }
            let j = p.y as usize * w + p.x as usize;
            let d = back_depth[i];
            // Hidden: the earlier frame shows something nearer there (or
            // nothing). The tolerance is the silhouette test's depth jump.
            prev.triangle[j] != BACKGROUND && d <= prev.depth[j] * (1.0 + jump)
        })
        .collect()
}
