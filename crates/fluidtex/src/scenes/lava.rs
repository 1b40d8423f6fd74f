//! `lava`: a viscous stream runs down a sloping channel, slows as it cools
//! and stops — the largest of the 2021 paper's three scales (its lava
//! flow: about 270k triangles), and a test that a texture stops when the
//! fluid stops.
//!
//! * Geometry: a channel of width [`CHANNEL_WIDTH`] and length
//!   [`CHANNEL_LENGTH`] on a plane inclined by [`SLOPE_DEG`], with side and
//!   back walls of height [`WALL_HEIGHT`], open at its lower end. At t = 0 a
//!   block of lava ([`SOURCE_LENGTH`] × [`SOURCE_HEIGHT`], full width) rests
//!   against the back wall; released, it slumps and runs downhill as a
//!   tongue. The simulation runs in the slope's frame (floor y = 0, gravity
//!   tilted by the slope); frames are turned into the world frame (y up,
//!   downhill along +x) when they are written.
//! * Simulation: salva3d 0.11 DFSPH with strong XSPH viscosity and XSPH
//!   friction against the walls (see `viscous-drop` for why XSPH).
//! * Cooling: with c(t) = ((t − COOL_START)/(SOLID − COOL_START))²,
//!   clamped to [0, 1], the lava is slowed from [`COOL_START`] on by a drag
//!   dv/dt = −κ·v with κ = c(t)·[`COOL_DRAG`] s⁻¹ (applied exactly per
//!   substep as v ← v·e^(−κ·dt)), and the weight that drives it shrinks to
//!   g·(1 − c(t)) (the crust carries the rest): a drag alone would leave
//!   the speed g·sin θ·dt that gravity adds within each substep. At
//!   [`SOLID`] the lava is solid: the simulation stops, every vertex
//!   velocity is exactly zero and every later frame is the same mesh, bit
//!   for bit (it is reconstructed once and repeated). Just before, both
//!   the drag and the vanishing weight have brought the speed near zero, so
//!   the stop is not a visible jump. This is what the `stop` analytic scene
//!   does with its velocity ramp, and what lets a texturing method give
//!   bit-identical still frames.
//! * Surface and velocity: as `dam-break` (`sph::reconstruct`),
//!   with a marching-cubes cell of [`SURFACE_CUBE`] particle radii.
//! * Temperature: every vertex carries a scalar [`TEMPERATURE`] in
//!   [0, 1] (1 = molten, as released; 0 = cold crust), so that a texturing
//!   run can change the look of the lava as it cools (`--select-by
//!   temperature`). It is carried by the particles, not painted on the
//!   surface, so it moves with the lava and a vertex gets it the way it
//!   gets its velocity (SPH interpolation of the particles in reach). Lava
//!   loses its heat to the air, so a particle cools the faster the more of
//!   it is open to the air: its exposure e ∈ [0, 1] is 1 minus its
//!   neighbours' kernel weight (within [`EXPOSURE_RADIUS`] spacings) over
//!   that of a particle deep inside, the wall and floor particles counting
//!   as neighbours (the ground insulates; the bottom is not what is seen).
//!   A particle's heat H = e^(−D), with the dose D = ∫ e dt /
//!   [`COOLING_TIME`] added up frame by frame: the thin, exposed parts (the
//!   tongue's tip, edges and top) cool first, and the cold reaches inward
//!   over time. The crust that slows the lava (the drag above) is what
//!   cools its surface, so the temperature also follows c(t): T = H ·
//!   (1 − (1 − [`SOLID_HEAT`])·c(t)). At frame 0 every particle is at 1;
//!   between [`COOL_START`] and [`SOLID`] the surface shows the spread of
//!   H, so a threshold crosses it progressively; at [`SOLID`] every
//!   particle is at most [`SOLID_HEAT`], and, the simulation stopped, the
//!   temperature stops changing with the mesh (it is part of the repeated
//!   solid mesh).
//!
//! `resolution` is the number of particles across the channel (default
//! 24). Units: metres, seconds. Deterministic: single-threaded solver and
//! reconstruction, seeded jitter.

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
use crate::mesh::{Attribute, TriMesh};

/// Inclination of the channel floor (degrees).
pub const SLOPE_DEG: f32 = 15.0;
/// Channel width (m), across z ∈ [−w/2, w/2].
pub const CHANNEL_WIDTH: f32 = 0.2;
/// Channel length along the slope (m); lava past its end is deleted.
pub const CHANNEL_LENGTH: f32 = 1.6;
/// Height of the side and back walls above the floor (m).
pub const WALL_HEIGHT: f32 = 0.1;
/// Length of the lava block along the slope at t = 0 (m).
pub const SOURCE_LENGTH: f32 = 0.25;
/// Height of the lava block above the floor at t = 0 (m).
pub const SOURCE_HEIGHT: f32 = 0.08;
/// Gravity (m/s²), along world −y.
pub const GRAVITY: f32 = 9.81;
/// Rest density (kg/m³).
pub const REST_DENSITY: f32 = 1000.0;
/// XSPH coefficient between fluid particles.
pub const XSPH_VISCOSITY: f32 = 0.5;
/// XSPH coefficient against the wall and floor particles (friction).
pub const WALL_FRICTION: f32 = 0.3;
/// Time (s) at which the cooling drag starts.
pub const COOL_START: f64 = 2.5;
/// Time (s) at which the lava is solid: no motion from then on.
pub const SOLID: f64 = 4.0;
/// Drag rate κ reached at [`SOLID`] (1/s).
pub const COOL_DRAG: f32 = 2000.0;
/// salva's smoothing factor: kernel radius = 2 × factor × particle radius.
pub const SMOOTHING_FACTOR: f32 = 2.0;
/// CFL number of the substeps: dt ≤ CFL · 2r / v.
pub const CFL: f32 = 0.4;
/// Initial jitter of the particles, in particle spacings (seeded).
pub const JITTER: f32 = 0.01;
/// splashsurf compact support radius, in particle radii.
pub const SURFACE_SUPPORT: f32 = 4.0;
/// splashsurf marching-cubes cell size, in particle radii.
pub const SURFACE_CUBE: f32 = 0.35;
/// splashsurf iso-surface threshold, relative to the rest density.
pub const SURFACE_THRESHOLD: f32 = 0.6;
/// Largest `resolution` (particles across the channel).
pub const MAX_RESOLUTION: u32 = 120;
/// Name of the per-vertex temperature attribute (PLY property).
pub const TEMPERATURE: &str = "temperature";
/// Radius (in particle spacings) within which neighbours shield a particle
/// from the air: salva's kernel radius (2 × smoothing factor × radius).
pub const EXPOSURE_RADIUS: f32 = 2.0;
/// Time (s) in which a fully exposed particle's heat falls by a factor e.
/// On the lattice, a particle of a flat free surface has exposure 0.24,
/// one on an edge 0.44, on a corner 0.60 (the layer below: 0), so they
/// lose half their heat in 2.9 s, 1.6 s and 1.2 s: by [`COOL_START`] the
/// tongue's edges and tip are visibly cooler than its flat top, which is
/// still clearly hotter than a corner when the crust sets.
pub const COOLING_TIME: f32 = 1.0;
/// Fraction of its heat H that a particle keeps once the lava is solid:
/// the temperature is at most this from [`SOLID`] on.
pub const SOLID_HEAT: f32 = 0.2;

const SURFACING: Surfacing = Surfacing {
    support: SURFACE_SUPPORT,
    cube: SURFACE_CUBE,
    threshold: SURFACE_THRESHOLD,
    rest_density: REST_DENSITY,
};

/// The lava scene (see the module doc).
pub struct Lava {
    params: SceneParams,
    world: LiquidWorld,
    fluid: FluidHandle,
    radius: f32,
    /// Frame whose state the world holds.
    at: i32,
    /// Simulated time of the world's state (s).
    time: f64,
    substeps: u64,
    deleted: usize,
    boundary_particles: usize,
    fluid_particles: usize,
    /// The solid lava's mesh (slope frame turned to the world), made once.
    solid: Option<TriMesh>,
    /// Cooling dose D of each particle, index for index with salva's
    /// arrays (see the module doc).
    dose: Vec<f32>,
    /// Wall and floor particles (slope frame): neighbours that insulate.
    walls: Vec<[f32; 3]>,
}

/// Slope frame → world frame: a turn about z by −θ, so the slope's
/// downhill +x goes down in the world.
fn to_world(p: Vec3) -> Vec3 {
    let (s, c) = SLOPE_DEG.to_radians().sin_cos();
    Vec3::new(c * p.x + s * p.y, c * p.y - s * p.x, p.z)
}

impl Lava {
    /// Defaults: 24 particles across the channel (≈ 6.5k particles), 5 s
    /// at 24 fps (the lava is solid from frame 96 on).
    pub fn default_params() -> SceneParams {
        SceneParams {
            resolution: 24,
            fps: 24.0,
            first: 0,
            last: 120,
            seed: 0,
        }
    }

    /// Sets up the channel and the lava block; frame `params.first` is the
    /// block at rest.
    pub fn new(params: SceneParams) -> Result<Lava, SceneError> {
        params.validate()?;
        if params.resolution > MAX_RESOLUTION {
            return Err(SceneError::InvalidParameter {
                name: "resolution",
                value: params.resolution.to_string(),
                allowed: format!("8 to {MAX_RESOLUTION} for lava (particles across the channel)"),
            });
        }
        let spacing = CHANNEL_WIDTH / params.resolution as f32;
        let radius = 0.5 * spacing;
        let half = 0.5 * CHANNEL_WIDTH;
        let count = |len: f32| ((len / spacing).floor() as i32).max(1);
        let mut particles = sph::lattice(
            [0.0, 0.0, -half],
            [
                count(SOURCE_LENGTH),
                count(SOURCE_HEIGHT),
                params.resolution as i32,
            ],
            spacing,
            |_| true,
        );
        let mut rng = Pcg64::seed_from_u64(params.seed);
        for p in &mut particles {
            let mut jitter = || (rng.random::<f32>() - 0.5) * 2.0 * JITTER * spacing;
            *p += v3(jitter(), jitter(), jitter());
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
            .push(Box::new(XSPHViscosity::new(XSPH_VISCOSITY, WALL_FRICTION)));
        // Two layers outside the floor, the side walls and the back wall.
        let pad = 2.0 * spacing;
        let n = [
            ((CHANNEL_LENGTH + pad) / spacing).round() as i32,
            ((WALL_HEIGHT + pad) / spacing).round() as i32,
            ((CHANNEL_WIDTH + 2.0 * pad) / spacing).round() as i32,
        ];
        let walls = sph::lattice([-pad, -pad, -half - pad], n, spacing, |p| {
            !(p[0] > 0.0 && p[1] > 0.0 && p[2] > -half && p[2] < half)
        });
        let boundary_particles = walls.len();
        let wall_points = walls.iter().map(|p| [p.x, p.y, p.z]).collect();
        let mut world = LiquidWorld::new(
            DFSPHSolver::<salva3d::kernel::CubicSplineKernel>::new(),
            radius,
            SMOOTHING_FACTOR,
            1.0,
        );
        let fluid = world.add_fluid(fluid);
        world.add_boundary(Boundary::new(walls, InteractionGroups::default()));
        Ok(Lava {
            params,
            world,
            fluid,
            radius,
            at: params.first,
            time: 0.0,
            substeps: 0,
            deleted: 0,
            boundary_particles,
            fluid_particles,
            solid: None,
            dose: vec![0.0; fluid_particles],
            walls: wall_points,
        })
    }

    /// Temperature of a particle with cooling dose `dose` at time `t`: its
    /// heat e^(−dose) times 1 − (1 − [`SOLID_HEAT`])·c(t) (module doc).
    /// 1 for a fresh particle at t = 0, at most [`SOLID_HEAT`] from
    /// [`SOLID`] on, lower for a larger dose.
    pub fn temperature(dose: f32, t: f64) -> f32 {
        let heat = (-dose.max(0.0)).exp();
        let c = Lava::cooled(t);
        // Exactly 1 before cooling and exactly SOLID_HEAT once solid.
        let kept = if c >= 1.0 {
            SOLID_HEAT
        } else {
            1.0 - (1.0 - SOLID_HEAT) * c
        };
        (heat * kept).clamp(0.0, 1.0)
    }

    /// Adds the cooling dose of `span` seconds at the current exposure.
    /// Runs before the substeps of the span, when salva is about to drop
    /// the particles deleted at the end of the last span.
    fn cool(&mut self, span: f32) {
        let Some(fluid) = self.world.fluids().get(self.fluid) else {
            return;
        };
        sph::follow_removal(fluid, &mut self.dose);
        let (positions, _) = sph::live_state(fluid);
        let e = exposure(&positions, &self.walls, 2.0 * self.radius);
        for (d, e) in self.dose.iter_mut().zip(e) {
            *d += e * span / COOLING_TIME;
        }
    }

    /// How far cooling has gone at time `t`: 0 until [`COOL_START`], 1 from
    /// [`SOLID`] on, quadratic in between.
    pub fn cooled(t: f64) -> f32 {
        let a = ((t - COOL_START) / (SOLID - COOL_START)).clamp(0.0, 1.0) as f32;
        a * a
    }

    /// Drag rate κ at time `t` (1/s), see the module doc.
    pub fn drag(t: f64) -> f32 {
        COOL_DRAG * Lava::cooled(t)
    }

    /// Whether the lava is solid at time `t`.
    pub fn is_solid(t: f64) -> bool {
        t >= SOLID
    }

    /// Advances the world to time `t1` (never past [`SOLID`]).
    fn step_to(&mut self, t1: f64) {
        let end = t1.min(SOLID);
        if end <= self.time {
            return;
        }
        let span = (end - self.time) as f32;
        self.cool(span);
        let free_fall = (2.0 * GRAVITY * SOURCE_HEIGHT).sqrt();
        let fastest = self
            .world
            .fluids()
            .get(self.fluid)
            .map_or(0.0, sph::fastest);
        let (n, dt) = sph::substeps(span, self.radius, fastest, free_fall, CFL);
        let (s, c) = SLOPE_DEG.to_radians().sin_cos();
        for k in 0..n {
            let t = self.time + (f64::from(k) + 0.5) * f64::from(dt);
            // The crust carries more and more of the weight as it cools.
            let g = GRAVITY * (1.0 - Lava::cooled(t));
            self.world.step(dt, &v3(g * s, -g * c, 0.0));
            let kappa = Lava::drag(t);
            if kappa > 0.0
                && let Some(fluid) = self.world.fluids_mut().get_mut(self.fluid)
            {
                let factor = (-kappa * dt).exp();
                for v in &mut fluid.velocities {
                    *v *= factor;
                }
            }
        }
        self.substeps += u64::from(n);
        self.time = end;
        let (margin, half) = (2.0 * self.radius, 0.5 * CHANNEL_WIDTH);
        if let Some(fluid) = self.world.fluids_mut().get_mut(self.fluid) {
            self.deleted += sph::delete_outside(fluid, |p| {
                p[0] > CHANNEL_LENGTH + margin
                    || p[0] < -margin
                    || p[1] < -margin
                    || p[2].abs() > half + margin
            });
        }
    }

    /// Live particles' positions in the world frame (for tests: the
    /// centroid).
    pub fn particle_positions(&self) -> Vec<Vec3> {
        self.world
            .fluids()
            .get(self.fluid)
            .map(|f| {
                sph::live_state(f)
                    .0
                    .into_iter()
                    .map(|p| to_world(Vec3::from(p)))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// Live fluid particles.
    pub fn particle_count(&self) -> usize {
        self.fluid_particles - self.deleted
    }

    fn mesh(&self, frame: i32, solid: bool) -> Result<TriMesh, SceneError> {
        let fluid = self
            .world
            .fluids()
            .get(self.fluid)
            .ok_or_else(|| SceneError::Simulation {
                frame,
                message: "the fluid vanished from the world".into(),
            })?;
        let (positions, velocities) = sph::live_state(fluid);
        let velocities = (!solid).then_some(velocities.as_slice());
        let temperature: Vec<f32> = sph::live_values(fluid, &self.dose)
            .into_iter()
            .map(|d| Lava::temperature(d, self.time))
            .collect();
        let scalars = [(TEMPERATURE, temperature.as_slice())];
        let mut mesh = sph::reconstruct_with(
            &positions,
            velocities,
            &scalars,
            self.radius,
            &SURFACING,
            frame,
        )?;
        // A weighted mean of values in [0, 1], up to rounding.
        if let Some(Attribute::Scalar(t)) = mesh.attributes.get_mut(TEMPERATURE) {
            for x in t {
                *x = x.clamp(0.0, 1.0);
            }
        }
        for p in &mut mesh.positions {
            *p = to_world(*p);
        }
        if !solid {
            let turned: Vec<Vec3> = mesh
                .velocity()
                .unwrap_or(&[])
                .iter()
                .map(|&v| to_world(v))
                .collect();
            mesh = mesh.with_velocity(turned);
        }
        Ok(mesh)
    }
}

/// Exposure to the air of each particle of `fluid` (module doc): 1 minus
/// the summed weight (1 − d²/R²)³ of its neighbours within R =
/// [`EXPOSURE_RADIUS`]·`spacing` (fluid and `walls` particles), over that
/// of a particle inside a lattice of that spacing, clamped to [0, 1].
/// Deterministic: neighbours are found in a sorted cell list and summed in
/// a fixed order.
pub fn exposure(fluid: &[[f32; 3]], walls: &[[f32; 3]], spacing: f32) -> Vec<f32> {
    let radius = EXPOSURE_RADIUS * spacing;
    let r2 = radius * radius;
    let weight = |d2: f32| {
        let x = 1.0 - d2 / r2;
        if x > 0.0 { x * x * x } else { 0.0 }
    };
    // A bulk particle's neighbour weight, on the lattice of the release.
    let reach = EXPOSURE_RADIUS.ceil() as i32;
    let mut bulk = 0.0f32;
    for k in -reach..=reach {
        for j in -reach..=reach {
            for i in -reach..=reach {
                if (i, j, k) != (0, 0, 0) {
                    let d = Vec3::new(i as f32, j as f32, k as f32) * spacing;
                    bulk += weight(d.length_squared());
                }
            }
        }
    }
    let cell = |p: &[f32; 3]| {
        let c = |x: f32| (x / radius).floor() as i32;
        (c(p[0]), c(p[1]), c(p[2]))
    };
    let all: Vec<&[f32; 3]> = fluid.iter().chain(walls).collect();
    let mut cells: Vec<((i32, i32, i32), u32)> = all
        .iter()
        .enumerate()
        .map(|(i, p)| (cell(p), i as u32))
        .collect();
    cells.sort_unstable();
    fluid
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let (cx, cy, cz) = cell(p);
            let mut sum = 0.0f32;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let key = (cx + dx, cy + dy, cz + dz);
                        let start = cells.partition_point(|(c, _)| *c < key);
                        for &(c, j) in &cells[start..] {
                            if c != key {
                                break;
                            }
                            if j as usize == i {
                                continue;
                            }
                            let q = all[j as usize];
                            let d = Vec3::from(*q) - Vec3::from(*p);
                            sum += weight(d.length_squared());
                        }
                    }
                }
            }
            if bulk > 0.0 {
                (1.0 - sum / bulk).clamp(0.0, 1.0)
            } else {
                0.0
            }
        })
        .collect()
}

impl Scene for Lava {
    fn info(&self) -> SceneInfo {
        SceneInfo {
            name: "lava".into(),
            description: "viscous SPH stream (salva3d) down a sloping channel that cools and stops"
                .into(),
            fps: self.params.fps,
            first: self.params.first,
            last: self.params.last,
            parameters: json!({
                "resolution": self.params.resolution,
                "resolution_meaning": "particles across the channel",
                "seed": self.params.seed,
                "units": "metres, seconds; y up, downhill along +x",
                "slope_deg": SLOPE_DEG,
                "channel": {"width": CHANNEL_WIDTH, "length": CHANNEL_LENGTH, "wall_height": WALL_HEIGHT},
                "source_block": {"length": SOURCE_LENGTH, "height": SOURCE_HEIGHT},
                "particle_radius": self.radius, "particle_spacing": 2.0 * self.radius,
                "fluid_particles": self.fluid_particles,
                "boundary_particles": self.boundary_particles,
                "gravity": GRAVITY, "rest_density": REST_DENSITY,
                "solver": "salva3d 0.11 DFSPH, cubic spline kernel",
                "smoothing_factor": SMOOTHING_FACTOR,
                "kernel_radius": self.world.h(),
                "xsph_viscosity": XSPH_VISCOSITY,
                "wall_friction_xsph": WALL_FRICTION,
                "cooling": {
                    "drag": "dv/dt = -kappa v, kappa = cool_drag * c(t), c(t) = ((t - cool_start) / (solid - cool_start))^2 clamped to [0, 1]",
                    "weight": "gravity scaled by 1 - c(t)",
                    "cool_start_s": COOL_START, "solid_s": SOLID, "cool_drag": COOL_DRAG,
                    "after_solid": "no motion: zero velocity, the same mesh every frame",
                },
                "temperature": {
                    "attribute": TEMPERATURE,
                    "particle": "T = exp(-D) * (1 - (1 - solid_heat) * c(t)), D = integral of exposure dt / cooling_time, per frame",
                    "exposure": "1 - sum of (1 - d^2/R^2)^3 over fluid and wall neighbours within R, over that of a bulk lattice particle; clamped to [0, 1]",
                    "exposure_radius_spacings": EXPOSURE_RADIUS,
                    "cooling_time_s": COOLING_TIME,
                    "solid_heat": SOLID_HEAT,
                    "vertex": "SphInterpolator::interpolate_scalar_quantity, first-order corrected",
                },
                "substeps": format!("ceil(frame_dt / ({CFL} * 2r / max(v_max, sqrt(2 g H))))"),
                "initial_jitter_spacings": JITTER,
                "surface": SURFACING.info(self.radius),
                "velocity": "SphInterpolator::interpolate_vector_quantity, first-order corrected",
            }),
        }
    }

    fn frame(&mut self, f: i32) -> Result<TriMesh, SceneError> {
        self.params.check_forward(f, self.at)?;
        let t = self.params.time(f);
        self.step_to(t);
        self.at = f;
        if Lava::is_solid(t) {
            if self.solid.is_none() {
                self.solid = Some(self.mesh(f, true)?);
            }
            if let Some(mesh) = &self.solid {
                return Ok(mesh.clone());
            }
        }
        self.mesh(f, false)
    }

    fn exact_velocity(&self, _x: Vec3, _t: f64) -> Option<Vec3> {
        None
    }
}
