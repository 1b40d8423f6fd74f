//! `viscous-drop`: a blob of viscous liquid falls onto a plane and spreads
//! into a thick pancake — the smallest of the 2021 paper's three scales
//! (its viscous drop: about 61k triangles).
//!
//! * Simulation: salva3d 0.11 DFSPH (as `dam-break`) with a strong XSPH
//!   viscosity between fluid particles ([`XSPH_VISCOSITY`]) and XSPH
//!   friction with the floor ([`FLOOR_FRICTION`]). XSPH pulls each
//!   particle's velocity towards its neighbours' every substep; salva's
//!   implicit DFSPH viscosity (Weiler et al. 2018) would be the physical
//!   choice, but it costs a solve per substep and gains nothing a texturing
//!   test can see, so a large XSPH coefficient stands in for the viscosity
//!   (it is why the blob spreads slowly instead of splashing).
//! * Floor: two layers of boundary particles, a square of side
//!   2·[`FLOOR_HALF`] centred under the drop; particles that fall off its
//!   edge are deleted.
//! * Surface and velocity: as `dam-break` (`sph::reconstruct`),
//!   with a marching-cubes cell of [`SURFACE_CUBE`] particle radii: finer
//!   than the particles, so the smooth blob gets the paper's triangle count
//!   from a few thousand particles.
//!
//! `resolution` is the number of particles across the drop's diameter
//! (default 20: ≈ 4.2k fluid particles). Units: metres, seconds; y up.
//! Deterministic: single-threaded solver and reconstruction, seeded jitter.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use salva3d::LiquidWorld;
use salva3d::object::interaction_groups::InteractionGroups;
use salva3d::object::{Boundary, Fluid, FluidHandle};
use salva3d::solver::{DFSPHSolver, XSPHViscosity};
use serde_json::json;

use super::sph::{self, Surfacing, v3};
use super::{Scene, SceneError, SceneInfo, SceneParams};
use crate::mesh::TriMesh;

/// Radius of the drop at rest (m).
pub const DROP_RADIUS: f32 = 0.05;
/// Height of the drop's centre above the floor at t = 0 (m): it falls
/// 0.015 m, hitting the floor at about 0.5 m/s (faster, the blob splashes
/// into a thin sheet instead of spreading).
pub const DROP_HEIGHT: f32 = 0.065;
/// Half side of the square floor (m), centred under the drop.
pub const FLOOR_HALF: f32 = 0.3;
/// Gravity (m/s²), along −y.
pub const GRAVITY: f32 = 9.81;
/// Rest density (kg/m³).
pub const REST_DENSITY: f32 = 1000.0;
/// XSPH coefficient between fluid particles (0 = inviscid; water scenes
/// use 0.05).
pub const XSPH_VISCOSITY: f32 = 0.9;
/// XSPH coefficient against the floor particles: friction that slows the
/// spreading rim.
pub const FLOOR_FRICTION: f32 = 0.5;
/// salva's smoothing factor: kernel radius = 2 × factor × particle radius.
pub const SMOOTHING_FACTOR: f32 = 2.0;
/// CFL number of the substeps: dt ≤ CFL · 2r / v.
pub const CFL: f32 = 0.4;
/// Initial jitter of the particles, in particle spacings (seeded).
pub const JITTER: f32 = 0.01;
/// splashsurf compact support radius, in particle radii.
pub const SURFACE_SUPPORT: f32 = 4.0;
/// splashsurf marching-cubes cell size, in particle radii.
pub const SURFACE_CUBE: f32 = 0.8;
/// splashsurf iso-surface threshold, relative to the rest density.
pub const SURFACE_THRESHOLD: f32 = 0.6;
/// Largest `resolution` (particles across the diameter): 200 would be
/// 4 M particles.
pub const MAX_RESOLUTION: u32 = 120;

const SURFACING: Surfacing = Surfacing {
    support: SURFACE_SUPPORT,
    cube: SURFACE_CUBE,
    threshold: SURFACE_THRESHOLD,
    rest_density: REST_DENSITY,
};

/// The viscous-drop scene (see the module doc).
pub struct ViscousDrop {
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
}

impl ViscousDrop {
    /// Defaults: 20 particles across the drop (≈ 4.2k particles), 2 s at
    /// 24 fps.
    pub fn default_params() -> SceneParams {
        SceneParams {
            resolution: 20,
            fps: 24.0,
            first: 0,
            last: 48,
            seed: 0,
        }
    }

    /// Sets up the floor and the drop; frame `params.first` is the drop
    /// at rest in the air.
    pub fn new(params: SceneParams) -> Result<ViscousDrop, SceneError> {
        params.validate()?;
        if params.resolution > MAX_RESOLUTION {
            return Err(SceneError::InvalidParameter {
                name: "resolution",
                value: params.resolution.to_string(),
                allowed: format!(
                    "8 to {MAX_RESOLUTION} for viscous-drop (particles across the drop)"
                ),
            });
        }
        let spacing = 2.0 * DROP_RADIUS / params.resolution as f32;
        let radius = 0.5 * spacing;
        let mut rng = Pcg64::seed_from_u64(params.seed);
        let n = params.resolution as i32;
        let lo = -DROP_RADIUS;
        let mut particles = sph::lattice([lo, lo, lo], [n, n, n], spacing, |p| {
            p[0] * p[0] + p[1] * p[1] + p[2] * p[2] <= DROP_RADIUS * DROP_RADIUS
        });
        for p in &mut particles {
            let mut jitter = || (rng.random::<f32>() - 0.5) * 2.0 * JITTER * spacing;
            *p += v3(jitter(), DROP_HEIGHT + jitter(), jitter());
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
            .push(Box::new(XSPHViscosity::new(XSPH_VISCOSITY, FLOOR_FRICTION)));
        // Two layers under y = 0.
        let cells = (2.0 * FLOOR_HALF / spacing).round() as i32;
        let floor = sph::lattice(
            [-FLOOR_HALF, -2.0 * spacing, -FLOOR_HALF],
            [cells, 2, cells],
            spacing,
            |_| true,
        );
        let boundary_particles = floor.len();
        let mut world = LiquidWorld::new(
            DFSPHSolver::<salva3d::kernel::CubicSplineKernel>::new(),
            radius,
            SMOOTHING_FACTOR,
            1.0,
        );
        let fluid = world.add_fluid(fluid);
        world.add_boundary(Boundary::new(floor, InteractionGroups::default()));
        Ok(ViscousDrop {
            params,
            world,
            fluid,
            radius,
            at: params.first,
            substeps: 0,
            deleted: 0,
            boundary_particles,
            fluid_particles,
        })
    }

    /// Advances the world by one frame.
    fn step_frame(&mut self) {
        let frame_dt = (1.0 / self.params.fps) as f32;
        let impact = (2.0 * GRAVITY * DROP_HEIGHT).sqrt();
        let fastest = self
            .world
            .fluids()
            .get(self.fluid)
            .map_or(0.0, sph::fastest);
        let (n, dt) = sph::substeps(frame_dt, self.radius, fastest, impact, CFL);
        let gravity = v3(0.0, -GRAVITY, 0.0);
        for _ in 0..n {
            self.world.step(dt, &gravity);
        }
        self.substeps += u64::from(n);
        // Particles that fell off the floor's edge (or leaked through it).
        let below = -4.0 * self.radius;
        if let Some(fluid) = self.world.fluids_mut().get_mut(self.fluid) {
            self.deleted += sph::delete_outside(fluid, |p| p[1] < below);
        }
    }

    /// Live fluid particles.
    pub fn particle_count(&self) -> usize {
        self.fluid_particles - self.deleted
    }

    /// Live particles' positions (for tests: the footprint).
    pub fn particle_positions(&self) -> Vec<[f32; 3]> {
        self.world
            .fluids()
            .get(self.fluid)
            .map(|f| sph::live_state(f).0)
            .unwrap_or_default()
    }
}

impl Scene for ViscousDrop {
    fn info(&self) -> SceneInfo {
        SceneInfo {
            name: "viscous-drop".into(),
            description: "viscous SPH blob (salva3d) falling onto a plane and spreading".into(),
            fps: self.params.fps,
            first: self.params.first,
            last: self.params.last,
            parameters: json!({
                "resolution": self.params.resolution,
                "resolution_meaning": "particles across the drop's diameter",
                "seed": self.params.seed,
                "units": "metres, seconds; y up",
                "drop_radius": DROP_RADIUS, "drop_height": DROP_HEIGHT,
                "floor_half_side": FLOOR_HALF,
                "particle_radius": self.radius, "particle_spacing": 2.0 * self.radius,
                "fluid_particles": self.fluid_particles,
                "boundary_particles": self.boundary_particles,
                "gravity": GRAVITY, "rest_density": REST_DENSITY,
                "solver": "salva3d 0.11 DFSPH, cubic spline kernel",
                "smoothing_factor": SMOOTHING_FACTOR,
                "kernel_radius": self.world.h(),
                "xsph_viscosity": XSPH_VISCOSITY,
                "floor_friction_xsph": FLOOR_FRICTION,
                "substeps": format!("ceil(frame_dt / ({CFL} * 2r / max(v_max, sqrt(2 g h))))"),
                "initial_jitter_spacings": JITTER,
                "surface": SURFACING.info(self.radius),
                "velocity": "SphInterpolator::interpolate_vector_quantity, first-order corrected",
            }),
        }
    }

    fn frame(&mut self, f: i32) -> Result<TriMesh, SceneError> {
        self.params.check_forward(f, self.at)?;
        while self.at < f {
            self.step_frame();
            self.at += 1;
        }
        let fluid = self
            .world
            .fluids()
            .get(self.fluid)
            .ok_or_else(|| SceneError::Simulation {
                frame: f,
                message: "the fluid vanished from the world".into(),
            })?;
        let (positions, velocities) = sph::live_state(fluid);
        sph::reconstruct(&positions, Some(&velocities), self.radius, &SURFACING, f)
    }

    fn exact_velocity(&self, _x: Vec3, _t: f64) -> Option<Vec3> {
        None
    }
}
