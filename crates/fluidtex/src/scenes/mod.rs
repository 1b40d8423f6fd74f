//! Test scenes: animated surfaces with per-vertex velocity, one mesh per frame.
//!
//! Two kinds, both producing what a fluid simulator gives a texturing tool
//! (a new mesh every frame, no vertex correspondence, topology changes):
//!
//! * **Analytic scenes** (`enright`, `vortex`, `rigid-rotation`,
//!   `differential-rotation`, `shear`, `stop`, `split-merge`): the surface at
//!   time t is the zero level set of a known implicit function and the
//!   velocity is known exactly everywhere ([`Scene::exact_velocity`]). For the
//!   flows of the form u(x, t) = a(t)·v(x), particle paths are those of the
//!   steady field v run for the reparametrised time τ(t) = ∫₀ᵗ a, so the
//!   surface is φ₀(Φ₋τ(x)) — the initial signed distance pulled back along
//!   the flow (docs/evaluation.md, "Scenes"). Grid nodes are traced back with RK4
//!   (or a closed-form flow map where one exists, see [`flow`]), the zero
//!   level set is extracted by marching cubes independently every frame
//!   ([`marching_cubes`]), and the mesh is improved by tangential relaxation
//!   with re-projection onto the level set ([`relax`]). Vertex velocity is the
//!   exact field evaluated at the final vertex position.
//! * **`dam-break`**: a liquid from a real SPH simulator (salva3d, DFSPH),
//!   its surface reconstructed per frame by splashsurf_lib and velocities
//!   carried to vertices by SPH interpolation ([`dam_break`], cargo feature
//!   `sph`, on by default). Each vertex also carries the scalar `age`: the
//!   time since its water left the initial column (0 while it has not).
//! * **`viscous-drop`** and **`lava`**: the same SPH pipeline with a strong
//!   XSPH viscosity, at the 2021 paper's two other scales: a blob that falls
//!   onto a plane and spreads ([`viscous_drop`], ≈ 61k triangles), and a
//!   stream down a sloping channel that cools and stops, after which its
//!   frames are bit-identical ([`lava`], ≈ 270k triangles). Each lava
//!   vertex carries the scalar `temperature` in [0, 1] (1 molten, 0 cold
//!   crust), cooling first where the lava is most exposed to the air.
//!
//! Per-vertex scalars like these are state the simulation carries on its
//! particles, which a texturing method can select its exemplar by; the
//! scene writer puts them in the PLY frames as float properties.
//!
//! Time: frame F is at t = (F − first)/fps seconds; velocities are world
//! units per second (docs/design.md, *Time*).
//!
//! Entry points: [`by_name`], [`catalogue`], [`default_params`], the
//! [`Scene`] trait and [`triangle_quality`] (min-angle statistics, used to
//! measure the mesher).

pub mod analytic;
#[cfg(feature = "sph")]
pub mod dam_break;
pub mod flow;
#[cfg(feature = "sph")]
pub mod lava;
pub mod marching_cubes;
pub mod quality;
pub mod relax;
#[cfg(feature = "sph")]
mod sph;
#[cfg(test)]
mod tests;
#[cfg(feature = "sph")]
pub mod viscous_drop;

use glam::Vec3;
use serde::Serialize;
use thiserror::Error;

use crate::mesh::TriMesh;

pub use quality::{QualityStats, triangle_quality};

/// What went wrong building or running a scene.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SceneError {
    #[error("unknown scene '{name}'; valid scenes: {valid}")]
    UnknownScene { name: String, valid: String },
    #[error("scene parameter {name} = {value} is out of range (allowed: {allowed})")]
    InvalidParameter {
        name: &'static str,
        value: String,
        allowed: String,
    },
    #[error("frame {frame} is outside the scene's frame range {first}-{last}")]
    FrameOutOfRange { frame: i32, first: i32, last: i32 },
    #[error(
        "frame {frame} requested after frame {previous}: this simulation scene only steps forward"
    )]
    FrameOrder { frame: i32, previous: i32 },
    #[error("frame {frame}: simulation failed: {message}")]
    Simulation { frame: i32, message: String },
    /// A frame read from the user's files could not be used.
    #[error("frame {frame}: {message}")]
    Input { frame: i32, message: String },
}

/// Frame range, rate, resolution and seed of a scene. Each scene has its own
/// defaults ([`default_params`]); [`by_name`] validates them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SceneParams {
    /// Grid resolution N. Analytic scenes: marching-cubes cells along the
    /// longest side L of the scene's domain, so the cell size is h = L/N and
    /// a surface of area A gets about 3.7·A/h² triangles (measured; the
    /// triangle count grows as N²). `dam-break`: particles along the height
    /// of the water column (particle count grows as N³, triangles as N²).
    /// `viscous-drop`: particles across the drop; `lava`: particles across
    /// the channel (both grow like dam-break's). Allowed 8–2048 (dam-break:
    /// 8–200; viscous-drop and lava: 8–120).
    pub resolution: u32,
    /// Frames per second (default 24); frame F is at t = (F − first)/fps.
    pub fps: f64,
    /// First frame (inclusive).
    pub first: i32,
    /// Last frame (inclusive), ≥ first.
    pub last: i32,
    /// Seed of the scene's random choices. Analytic scenes are exact functions
    /// of time and use none; the SPH scenes jitter their initial particles
    /// with it.
    pub seed: u64,
}

impl SceneParams {
    /// Time in seconds of frame `f`.
    pub fn time(&self, f: i32) -> f64 {
        f64::from(f - self.first) / self.fps
    }

    /// Checks every field; the error names the field, its value and the range.
    pub fn validate(&self) -> Result<(), SceneError> {
        if !(8..=2048).contains(&self.resolution) {
            return Err(SceneError::InvalidParameter {
                name: "resolution",
                value: self.resolution.to_string(),
                allowed: "8 to 2048".into(),
            });
        }
        if !(self.fps.is_finite() && self.fps > 0.0 && self.fps <= 10_000.0) {
            return Err(SceneError::InvalidParameter {
                name: "fps",
                value: self.fps.to_string(),
                allowed: "a finite number in (0, 10000]".into(),
            });
        }
        if self.first > self.last {
            return Err(SceneError::InvalidParameter {
                name: "frames",
                value: format!("{}-{}", self.first, self.last),
                allowed: "first <= last".into(),
            });
        }
        Ok(())
    }

    pub(crate) fn check_frame(&self, f: i32) -> Result<(), SceneError> {
        if f < self.first || f > self.last {
            return Err(SceneError::FrameOutOfRange {
                frame: f,
                first: self.first,
                last: self.last,
            });
        }
        Ok(())
    }

    /// [`SceneParams::check_frame`], and frame `f` is not before `at`, the
    /// frame a simulated scene has reached (it only steps forward).
    #[cfg(feature = "sph")]
    pub(crate) fn check_forward(&self, f: i32, at: i32) -> Result<(), SceneError> {
        self.check_frame(f)?;
        if f < at {
            return Err(SceneError::FrameOrder {
                frame: f,
                previous: at,
            });
        }
        Ok(())
    }
}

/// Description of a scene, written beside its frames so that a run can be
/// reproduced: every parameter, flow constants included.
#[derive(Clone, Debug, Serialize)]
pub struct SceneInfo {
    pub name: String,
    pub description: String,
    pub fps: f64,
    pub first: i32,
    pub last: i32,
    pub parameters: serde_json::Value,
}

/// An animated surface: one triangle mesh per frame with per-vertex velocity.
pub trait Scene: Send {
    fn info(&self) -> SceneInfo;
    /// Mesh of frame `f` (time t = (f − first)/fps) with per-vertex velocity
    /// ([`crate::mesh::VELOCITY`], world units per second). Frames are
    /// requested in increasing order; simulation scenes may require that.
    fn frame(&mut self, f: i32) -> Result<TriMesh, SceneError>;
    /// Exact velocity at `x` and time `t` (seconds) where the scene has one
    /// (analytic scenes), `None` otherwise.
    fn exact_velocity(&self, x: Vec3, t: f64) -> Option<Vec3>;
}

/// Every scene: name and one-line description.
pub fn catalogue() -> &'static [(&'static str, &'static str)] {
    &[
        (
            "enright",
            "3-D Enright deformation of a sphere (T = 3 s); back to the sphere at t = T",
        ),
        (
            "vortex",
            "single 2-D vortex (T = 8 s) swirling a closed rounded puck; texture seen on its top face",
        ),
        (
            "vortex-16",
            "the vortex at half speed, T = 16 s: its path taken twice as slowly, a moderate shear",
        ),
        (
            "rigid-rotation",
            "sphere in rigid rotation about z: geometry constant, texture must turn rigidly",
        ),
        (
            "differential-rotation",
            "sphere whose angular speed grows with height: geometry constant, texture sheared",
        ),
        (
            "shear",
            "open plane under a steady shear flow u = gamma (y - 1/2)",
        ),
        (
            "stop",
            "vortex on the puck ramped to zero velocity, then held still (bit-identical frames)",
        ),
        (
            "split-merge",
            "two drops that approach, merge and separate again (topology 2 -> 1 -> 2)",
        ),
        (
            "dam-break",
            "SPH dam break (salva3d) reconstructed per frame with splashsurf; per-vertex age",
        ),
        (
            "viscous-drop",
            "viscous SPH blob falling onto a plane and spreading (about 61k triangles)",
        ),
        (
            "lava",
            "viscous SPH stream down a slope that cools and stops (about 270k triangles); per-vertex temperature",
        ),
    ]
}

fn unknown(name: &str) -> SceneError {
    SceneError::UnknownScene {
        name: name.to_string(),
        valid: catalogue()
            .iter()
            .map(|(n, _)| *n)
            .collect::<Vec<_>>()
            .join(", "),
    }
}

/// The scenes made by the SPH pipeline (cargo feature `sph`).
pub const SPH_SCENES: [&str; 3] = ["dam-break", "viscous-drop", "lava"];

#[cfg(not(feature = "sph"))]
fn needs_sph(name: &str) -> SceneError {
    SceneError::InvalidParameter {
        name: "scene",
        value: name.into(),
        allowed: format!("a scene built in: {name} needs the cargo feature `sph`"),
    }
}

/// Default parameters of scene `name`.
pub fn default_params(name: &str) -> Result<SceneParams, SceneError> {
    if SPH_SCENES.contains(&name) {
        #[cfg(feature = "sph")]
        return Ok(match name {
            "viscous-drop" => viscous_drop::ViscousDrop::default_params(),
            "lava" => lava::Lava::default_params(),
            _ => dam_break::DamBreak::default_params(),
        });
        #[cfg(not(feature = "sph"))]
        return Err(needs_sph(name));
    }
    analytic::default_params(name).ok_or_else(|| unknown(name))
}

/// Builds scene `name` with `params` (validated), or with its defaults.
pub fn by_name(name: &str, params: Option<SceneParams>) -> Result<Box<dyn Scene>, SceneError> {
    let params = match params {
        Some(p) => p,
        None => default_params(name)?,
    };
    params.validate()?;
    if SPH_SCENES.contains(&name) {
        #[cfg(feature = "sph")]
        return Ok(match name {
            "viscous-drop" => Box::new(viscous_drop::ViscousDrop::new(params)?),
            "lava" => Box::new(lava::Lava::new(params)?),
            _ => Box::new(dam_break::DamBreak::new(params)?),
        });
        #[cfg(not(feature = "sph"))]
        return Err(needs_sph(name));
    }
    analytic::by_name(name, params)
        .map(|s| Box::new(s) as Box<dyn Scene>)
        .ok_or_else(|| unknown(name))
}
