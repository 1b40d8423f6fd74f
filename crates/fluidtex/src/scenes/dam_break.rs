//! `dam-break`: a water column collapsing in a tank, simulated with a real
//! SPH solver and reconstructed per frame, so the surface looks like a
//! production liquid (splashes, thin sheets, merging and splitting).
//!
//! * Simulation: salva3d 0.11, DFSPH pressure solver (Bender & Koschier 2015)
//!   with XSPH viscosity. salva's adaptive time step is disabled in its code
//!   (docs/design.md, *Crates and measurements*), so each frame is cut into
//!   equal substeps no longer than the CFL bound 0.4·2r/v, with v the larger
//!   of the fastest particle and the free-fall speed √(2gH) of the column —
//!   without that, particles leak through the walls. Walls and floor are
//!   two layers of boundary particles (open top). Particles that still
//!   escape the tank are deleted.
//! * Surface: splashsurf_lib 0.14 marching cubes on the SPH density
//!   (threshold 0.6 of the rest density), followed by its marching-cubes
//!   cleanup (Moore & Warren 1991 vertex snapping) for triangle quality.
//! * Velocity: per-particle velocities interpolated at the vertices with
//!   splashsurf's `SphInterpolator` (first-order corrected, so the truncated
//!   kernel at the free surface does not shrink them).
//! * Age: every vertex carries a scalar [`AGE`] (seconds), so that a
//!   texturing run can tell water that has travelled from the still
//!   column (`--select-by age`: foam on the spray, calm water behind). It
//!   is carried by the particles: 0 while a particle is still inside the
//!   column's initial box, then the time since it first left it, which
//!   keeps growing if it falls back in (the water has been out). The box
//!   is left only through its two open faces (the dam face x = 0.3 and
//!   the top y = 0.45; the others are tank walls), checked after every
//!   substep, so the departure time is known to a substep. Vertices get it
//!   like the velocity.
//!
//! Units: metres, seconds; y is up (gravity −9.81 m/s² along y), as in
//! Houdini. salva uses nalgebra 0.35 and splashsurf_lib 0.34: vectors cross
//! that border as plain `[f32; 3]`.
//!
//! Both libraries run single-threaded here (salva without its `parallel`
//! feature, splashsurf with multi-threading and SIMD off), so the same
//! parameters and seed give bit-identical meshes on any machine thread count.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use salva3d::LiquidWorld;
use salva3d::math::Vector as SalvaVector;
use salva3d::object::interaction_groups::InteractionGroups;
use salva3d::object::{Boundary, Fluid, FluidHandle};
use salva3d::solver::{DFSPHSolver, XSPHViscosity};
use serde_json::json;

use super::sph::{self, Surfacing, v3};
use super::{Scene, SceneError, SceneInfo, SceneParams};
use crate::mesh::{Attribute, TriMesh};

/// Tank interior: x ∈ [0, 1], y ∈ [0, 0.6], z ∈ [0, 0.3] metres.
pub const TANK: [f32; 3] = [1.0, 0.6, 0.3];
/// Water column at rest: x ∈ [0, 0.3], y ∈ [0, 0.45], full width in z.
pub const COLUMN: [f32; 3] = [0.3, 0.45, 0.3];
/// Gravity (m/s²), along −y.
pub const GRAVITY: f32 = 9.81;
/// Rest density (kg/m³).
pub const REST_DENSITY: f32 = 1000.0;
/// XSPH viscosity coefficient between fluid particles.
pub const XSPH_VISCOSITY: f32 = 0.05;
/// salva's smoothing factor: kernel radius = 2 × factor × particle radius.
pub const SMOOTHING_FACTOR: f32 = 2.0;
/// CFL number of the substeps: dt ≤ CFL · 2r / v.
pub const CFL: f32 = 0.4;
/// splashsurf compact support radius, in particle radii.
pub const SURFACE_SUPPORT: f32 = 4.0;
/// splashsurf marching-cubes cell size, in particle radii.
pub const SURFACE_CUBE: f32 = 1.0;
/// splashsurf iso-surface threshold, relative to the rest density.
pub const SURFACE_THRESHOLD: f32 = 0.6;
/// Initial jitter of the particles, in particle spacings (seeded).
pub const JITTER: f32 = 0.01;
/// Name of the per-vertex age attribute (PLY property), in seconds.
pub const AGE: &str = "age";

const SURFACING: Surfacing = Surfacing {
    support: SURFACE_SUPPORT,
    cube: SURFACE_CUBE,
    threshold: SURFACE_THRESHOLD,
    rest_density: REST_DENSITY,
};

/// The dam-break scene (see the module doc).
pub struct DamBreak {
    params: SceneParams,
    world: LiquidWorld,
    fluid: FluidHandle,
    radius: f32,
    /// Frame whose state the world holds.
    at: i32,
    substeps: u64,
    deleted: usize,
    boundary_particles: usize,
    fluid_particles: usize,
    /// Time (s) each particle first left the column, index for index with
    /// salva's arrays; `None` while it has not.
    left_at: Vec<Option<f64>>,
}

impl DamBreak {
    /// Defaults: 20 particles up the column (≈3.4k fluid particles), 3 s.
    pub fn default_params() -> SceneParams {
        SceneParams {
            resolution: 20,
            fps: 24.0,
            first: 0,
            last: 72,
            seed: 0,
        }
    }

    /// Sets up the tank and the column; frame `params.first` is the rest state.
    pub fn new(params: SceneParams) -> Result<DamBreak, SceneError> {
        params.validate()?;
        if params.resolution > 200 {
            return Err(SceneError::InvalidParameter {
                name: "resolution",
                value: params.resolution.to_string(),
                allowed: "8 to 200 for dam-break (particles up the column)".into(),
            });
        }
        let spacing = COLUMN[1] / params.resolution as f32;
        let radius = 0.5 * spacing;
        let mut rng = Pcg64::seed_from_u64(params.seed);
        let count = |len: f32| ((len / spacing).floor() as usize).max(1);
        let (nx, ny, nz) = (count(COLUMN[0]), count(COLUMN[1]), count(COLUMN[2]));
        let mut particles = Vec::with_capacity(nx * ny * nz);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let mut jitter = || (rng.random::<f32>() - 0.5) * 2.0 * JITTER * spacing;
                    particles.push(v3(
                        (i as f32 + 0.5) * spacing + jitter(),
                        (j as f32 + 0.5) * spacing + jitter(),
                        (k as f32 + 0.5) * spacing + jitter(),
                    ));
                }
            }
        }
        let fluid_particles = particles.len();
        let mut fluid = Fluid::new(
            particles,
            radius,
            REST_DENSITY,
            InteractionGroups::default(),
        );
        fluid
            .nonpressure_forces
            .push(Box::new(XSPHViscosity::new(XSPH_VISCOSITY, 0.0)));
        let walls = wall_particles(spacing);
        let boundary_particles = walls.len();
        let mut world = LiquidWorld::new(
            DFSPHSolver::<salva3d::kernel::CubicSplineKernel>::new(),
            radius,
            SMOOTHING_FACTOR,
            1.0,
        );
        let fluid = world.add_fluid(fluid);
        world.add_boundary(Boundary::new(walls, InteractionGroups::default()));
        Ok(DamBreak {
            params,
            world,
            fluid,
            radius,
            at: params.first,
            substeps: 0,
            deleted: 0,
            boundary_particles,
            fluid_particles,
            left_at: vec![None; fluid_particles],
        })
    }

    /// Whether a particle at `p` has left the column's initial box (through
    /// its open faces: the others are tank walls).
    pub fn outside_column(p: [f32; 3]) -> bool {
        p[0] > COLUMN[0] || p[1] > COLUMN[1]
    }

    /// Records the particles that left the column by time `t`.
    fn note_departures(&mut self, t: f64) {
        let Some(fluid) = self.world.fluids().get(self.fluid) else {
            return;
        };
        for (left, p) in self.left_at.iter_mut().zip(&fluid.positions) {
            if left.is_none() && DamBreak::outside_column([p.x, p.y, p.z]) {
                *left = Some(t);
            }
        }
    }

    /// Advances the world by one frame.
    fn step_frame(&mut self) {
        let frame_dt = (1.0 / self.params.fps) as f32;
        let free_fall = (2.0 * GRAVITY * COLUMN[1]).sqrt();
        let fastest = self
            .world
            .fluids()
            .get(self.fluid)
            .map_or(0.0, sph::fastest);
        let (n, dt) = sph::substeps(frame_dt, self.radius, fastest, free_fall, CFL);
        let gravity = v3(0.0, -GRAVITY, 0.0);
        if let Some(fluid) = self.world.fluids().get(self.fluid) {
            sph::follow_removal(fluid, &mut self.left_at);
        }
        let t0 = self.params.time(self.at);
        for k in 0..n {
            self.world.step(dt, &gravity);
            self.note_departures(t0 + f64::from(k + 1) * f64::from(dt));
        }
        self.substeps += u64::from(n);
        // Remove particles that left the tank (a leak would spray the
        // reconstruction with droplets outside it).
        let margin = 2.0 * self.radius;
        if let Some(fluid) = self.world.fluids_mut().get_mut(self.fluid) {
            self.deleted += sph::delete_outside(fluid, |p| {
                p[0] < -margin
                    || p[0] > TANK[0] + margin
                    || p[1] < -margin
                    || p[2] < -margin
                    || p[2] > TANK[2] + margin
            });
        }
    }

    /// Reconstructs the surface of the current state.
    fn mesh(&self, frame: i32) -> Result<TriMesh, SceneError> {
        let fluid = self
            .world
            .fluids()
            .get(self.fluid)
            .ok_or_else(|| SceneError::Simulation {
                frame,
                message: "the fluid vanished from the world".into(),
            })?;
        let (positions, velocities) = sph::live_state(fluid);
        let t = self.params.time(frame);
        let age: Vec<f32> = sph::live_values(fluid, &self.left_at)
            .into_iter()
            .map(|left| left.map_or(0.0, |l| (t - l).max(0.0) as f32))
            .collect();
        let mut mesh = sph::reconstruct_with(
            &positions,
            Some(&velocities),
            &[(AGE, age.as_slice())],
            self.radius,
            &SURFACING,
            frame,
        )?;
        // A weighted mean of ages ≥ 0, up to rounding.
        if let Some(Attribute::Scalar(a)) = mesh.attributes.get_mut(AGE) {
            for x in a {
                *x = x.max(0.0);
            }
        }
        Ok(mesh)
    }

    /// Live fluid particles.
    pub fn particle_count(&self) -> usize {
        self.fluid_particles - self.deleted
    }
}

/// Two layers of boundary particles outside the floor and the four walls
/// (open top), at the fluid spacing.
fn wall_particles(spacing: f32) -> Vec<SalvaVector<f32>> {
    let mut out = Vec::new();
    let layers = 2;
    let pad = layers as f32 * spacing;
    let n = |len: f32| ((len + 2.0 * pad) / spacing).round() as i32;
    let (nx, ny, nz) = (
        n(TANK[0]),
        ((TANK[1] + pad) / spacing).round() as i32,
        n(TANK[2]),
    );
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = v3(
                    -pad + (i as f32 + 0.5) * spacing,
                    -pad + (j as f32 + 0.5) * spacing,
                    -pad + (k as f32 + 0.5) * spacing,
                );
                let inside_x = p.x > 0.0 && p.x < TANK[0];
                let inside_z = p.z > 0.0 && p.z < TANK[2];
                let above_floor = p.y > 0.0;
                if !(inside_x && inside_z && above_floor) {
                    out.push(p);
                }
            }
        }
    }
    out
}

impl Scene for DamBreak {
    fn info(&self) -> SceneInfo {
        let spacing = 2.0 * self.radius;
        SceneInfo {
            name: "dam-break".into(),
            description: "SPH dam break (salva3d) reconstructed per frame with splashsurf".into(),
            fps: self.params.fps,
            first: self.params.first,
            last: self.params.last,
            parameters: json!({
                "resolution": self.params.resolution,
                "resolution_meaning": "particles along the column height",
                "seed": self.params.seed,
                "units": "metres, seconds; y up",
                "tank": TANK, "column": COLUMN,
                "particle_radius": self.radius, "particle_spacing": spacing,
                "fluid_particles": self.fluid_particles,
                "boundary_particles": self.boundary_particles,
                "boundary_layers": 2,
                "gravity": GRAVITY, "rest_density": REST_DENSITY,
                "solver": "salva3d 0.11 DFSPH, cubic spline kernel",
                "smoothing_factor": SMOOTHING_FACTOR,
                "kernel_radius": self.world.h(),
                "xsph_viscosity": XSPH_VISCOSITY,
                "substeps": format!("ceil(frame_dt / ({CFL} * 2r / max(v_max, sqrt(2 g H))))"),
                "initial_jitter_spacings": JITTER,
                "surface": SURFACING.info(self.radius),
                "velocity": "SphInterpolator::interpolate_vector_quantity, first-order corrected",
                "age": {
                    "attribute": AGE,
                    "particle": "0 until the particle first leaves the column (x > column x or y > column y, checked every substep), then the time since",
                    "vertex": "SphInterpolator::interpolate_scalar_quantity, first-order corrected",
                },
            }),
        }
    }

    fn frame(&mut self, f: i32) -> Result<TriMesh, SceneError> {
        self.params.check_forward(f, self.at)?;
        while self.at < f {
            self.step_frame();
            self.at += 1;
        }
        self.mesh(f)
    }

    fn exact_velocity(&self, _x: Vec3, _t: f64) -> Option<Vec3> {
        None
    }
}
