//! Pieces shared by the SPH scenes (`dam-break`, `viscous-drop`, `lava`):
//! the CFL substep count, boundary particle sheets, per-particle state kept
//! beside salva's arrays, and the per-frame surface reconstruction with
//! splashsurf_lib.
//!
//! Kept in one place so that every SPH scene surfaces its particles the same
//! way (splashsurf marching cubes on the SPH density, Moore & Warren cleanup,
//! first-order corrected SPH interpolation of the velocity and of any
//! per-particle scalar at the vertices) and so that the determinism settings
//! (single-threaded, no SIMD, no spatial decomposition) cannot drift apart
//! between scenes.
//!
//! Per-particle state a scene carries (lava's heat, dam-break's time out of
//! the column) lives in our own arrays, index for index with salva's. salva
//! removes deleted particles by compacting its arrays at the next step
//! ([`follow_removal`] does the same to ours just before), and until then
//! flags them ([`live_values`] leaves them out, as [`live_state`] does).

use glam::Vec3;
use salva3d::math::Vector as SalvaVector;
use salva3d::object::Fluid;
use splashsurf_lib::nalgebra::Vector3 as SsVector;
use splashsurf_lib::sph_interpolation::SphInterpolator;
use splashsurf_lib::{Parameters, SpatialDecomposition};

use super::SceneError;
use crate::mesh::{Attribute, TriMesh};

/// Shorthand for salva's vector type.
pub(crate) fn v3(x: f32, y: f32, z: f32) -> SalvaVector<f32> {
    SalvaVector::new(x, y, z)
}

/// How the particles are surfaced, in particle radii r (splashsurf's
/// parameters).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Surfacing {
    /// Compact support radius of the density kernel, in r.
    pub support: f32,
    /// Marching-cubes cell size, in r. Below 1 the surface gets more
    /// triangles than particles resolve (smooth, finer mesh).
    pub cube: f32,
    /// Iso-surface threshold relative to the rest density.
    pub threshold: f32,
    /// Rest density (kg/m³).
    pub rest_density: f32,
}

impl Surfacing {
    /// The surfacing settings in world units, for a scene's `scene.json`.
    pub(crate) fn info(&self, radius: f32) -> serde_json::Value {
        serde_json::json!({
            "library": "splashsurf_lib 0.14",
            "compact_support_radius": self.support * radius,
            "cube_size": self.cube * radius,
            "iso_threshold": self.threshold,
            "cleanup": "marching_cubes_cleanup, 5 iterations",
        })
    }
}

/// Substeps of one frame: the count n and the step dt = frame_dt / n, with
/// dt ≤ cfl · 2r / v (v: the larger of the fastest particle and `floor_speed`).
pub(crate) fn substeps(
    frame_dt: f32,
    radius: f32,
    fastest: f32,
    floor_speed: f32,
    cfl: f32,
) -> (u32, f32) {
    let max_dt = cfl * 2.0 * radius / fastest.max(floor_speed).max(1e-6);
    let n = (frame_dt / max_dt).ceil().clamp(1.0, 1.0e6) as u32;
    (n, frame_dt / n as f32)
}

/// Speed of the fastest live particle.
pub(crate) fn fastest(fluid: &Fluid) -> f32 {
    fluid
        .velocities
        .iter()
        .zip(&fluid.deleted_particles)
        .filter(|(_, d)| !**d)
        .map(|(v, _)| v.norm())
        .fold(0.0f32, f32::max)
}

/// Deletes (at salva's next step) the live particles for which `outside`
/// holds or whose position is not finite; returns how many.
pub(crate) fn delete_outside(fluid: &mut Fluid, outside: impl Fn([f32; 3]) -> bool) -> usize {
    let mut escaped = Vec::new();
    for (i, p) in fluid.positions.iter().enumerate() {
        let gone =
            !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) || outside([p.x, p.y, p.z]);
        if gone && !fluid.deleted_particles.get(i).copied().unwrap_or(true) {
            escaped.push(i);
        }
    }
    for &i in &escaped {
        fluid.delete_particle_at_next_timestep(i);
    }
    escaped.len()
}

/// Live particles' positions and velocities, in particle order.
pub(crate) fn live_state(fluid: &Fluid) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let live = (0..fluid.positions.len())
        .filter(|&i| !fluid.deleted_particles.get(i).copied().unwrap_or(false));
    live.map(|i| {
        let (p, v) = (fluid.positions[i], fluid.velocities[i]);
        ([p.x, p.y, p.z], [v.x, v.y, v.z])
    })
    .unzip()
}

/// Removes from `state` (one entry per particle of salva's arrays) the
/// entries of the particles salva will remove at its next step. Call just
/// before `world.step`, so that `state` stays index for index with them.
pub(crate) fn follow_removal<T: Copy>(fluid: &Fluid, state: &mut Vec<T>) {
    if fluid.num_deleted_particles() == 0 {
        return;
    }
    let mask = fluid.deleted_particles_mask();
    let mut i = 0;
    state.retain(|_| {
        let deleted = mask.get(i).copied().unwrap_or(false);
        i += 1;
        !deleted
    });
}

/// The entries of `state` (one per particle of salva's arrays) of the live
/// particles, in the order of [`live_state`].
pub(crate) fn live_values<T: Copy>(fluid: &Fluid, state: &[T]) -> Vec<T> {
    let mask = fluid.deleted_particles_mask();
    state
        .iter()
        .enumerate()
        .filter(|&(i, _)| !mask.get(i).copied().unwrap_or(false))
        .map(|(_, &v)| v)
        .collect()
}

/// Reconstructs the surface of particles `positions` (radius `r`) and
/// carries `velocities` to its vertices. `velocities: None` gives every
/// vertex the velocity exactly zero (a fluid at rest).
pub(crate) fn reconstruct(
    positions: &[[f32; 3]],
    velocities: Option<&[[f32; 3]]>,
    r: f32,
    s: &Surfacing,
    frame: i32,
) -> Result<TriMesh, SceneError> {
    reconstruct_with(positions, velocities, &[], r, s, frame)
}

/// splashsurf's parameters for particle radius `r`: single-threaded and
/// without SIMD, so that the surface is the same on every machine.
fn parameters(r: f32, s: &Surfacing) -> Parameters<f32> {
    let mut parameters = Parameters::new(r, s.support * r, s.cube * r);
    parameters.rest_density = s.rest_density;
    parameters.iso_surface_threshold = s.threshold;
    parameters.enable_multi_threading = false;
    parameters.enable_simd = false;
    parameters.spatial_decomposition = SpatialDecomposition::None;
    parameters
}

/// splashsurf's triangles as u32 indices, each checked against the
/// `n` vertices.
fn checked_triangles(triangles: &[[usize; 3]], n: usize) -> Result<Vec<[u32; 3]>, String> {
    let mut out = Vec::with_capacity(triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        let mut corners = [0u32; 3];
        for (k, &i) in tri.iter().enumerate() {
            if i >= n || i > u32::MAX as usize {
                return Err(format!("triangle {t} refers to vertex {i} of {n}"));
            }
            corners[k] = i as u32;
        }
        out.push(corners);
    }
    Ok(out)
}

/// [`reconstruct`], and each named per-particle scalar of `scalars` (one
/// value per particle) carried to the vertices the same way as the
/// velocity (first-order corrected SPH interpolation, so a vertex gets a
/// weighted mean of the particles in reach), as a scalar attribute of
/// that name. A vertex with no particle in reach gets 0. The velocity is
/// the same, bit for bit, with or without scalars.
pub(crate) fn reconstruct_with(
    positions: &[[f32; 3]],
    velocities: Option<&[[f32; 3]]>,
    scalars: &[(&str, &[f32])],
    r: f32,
    s: &Surfacing,
    frame: i32,
) -> Result<TriMesh, SceneError> {
    let fail = |message: String| SceneError::Simulation { frame, message };
    if let Some((name, values)) = scalars.iter().find(|(_, v)| v.len() != positions.len()) {
        return Err(fail(format!(
            "{} values of {name} for {} particles",
            values.len(),
            positions.len()
        )));
    }
    if positions.is_empty() {
        let mut mesh = TriMesh::default().with_velocity(Vec::new());
        for (name, _) in scalars {
            mesh.attributes
                .insert(name.to_string(), Attribute::Scalar(Vec::new()));
        }
        return Ok(mesh);
    }
    let positions: Vec<SsVector<f32>> = positions
        .iter()
        .map(|p| SsVector::new(p[0], p[1], p[2]))
        .collect();
    let mut surface =
        splashsurf_lib::reconstruct_surface::<i64, f32>(&positions, &parameters(r, s))
            .map_err(|e| fail(format!("surface reconstruction: {e}")))?;
    let grid = surface.grid.clone();
    splashsurf_lib::postprocessing::marching_cubes_cleanup(
        &mut surface.mesh,
        &grid,
        None,
        5,
        false,
    );
    let interpolator = if velocities.is_some() || !scalars.is_empty() {
        let densities = surface
            .particle_densities
            .take()
            .ok_or_else(|| fail("splashsurf returned no particle densities".into()))?;
        let rest_mass = s.rest_density * (2.0 * r).powi(3);
        Some(SphInterpolator::new(
            &positions,
            &densities,
            rest_mass,
            s.support * r,
        ))
    } else {
        None
    };
    let velocity: Vec<Vec3> = match (velocities, &interpolator) {
        (Some(velocities), Some(interpolator)) => {
            let velocities: Vec<SsVector<f32>> = velocities
                .iter()
                .map(|v| SsVector::new(v[0], v[1], v[2]))
                .collect();
            interpolator
                .interpolate_vector_quantity(&velocities, &surface.mesh.vertices, true)
                .iter()
                .map(|v| {
                    let v = Vec3::new(v.x, v.y, v.z);
                    // A vertex with no particle in reach has no defined velocity.
                    if v.is_finite() { v } else { Vec3::ZERO }
                })
                .collect()
        }
        _ => vec![Vec3::ZERO; surface.mesh.vertices.len()],
    };
    let mut attributes = Vec::with_capacity(scalars.len());
    if let Some(interpolator) = &interpolator {
        for (name, values) in scalars {
            let at_vertices = interpolator
                .interpolate_scalar_quantity(values, &surface.mesh.vertices, true)
                .into_iter()
                .map(|x| if x.is_finite() { x } else { 0.0 })
                .collect();
            attributes.push((name.to_string(), Attribute::Scalar(at_vertices)));
        }
    }
    let triangles =
        checked_triangles(&surface.mesh.triangles, surface.mesh.vertices.len()).map_err(fail)?;
    let positions = surface
        .mesh
        .vertices
        .iter()
        .map(|v| Vec3::new(v.x, v.y, v.z))
        .collect();
    let mut mesh = TriMesh::new(positions, triangles).with_velocity(velocity);
    mesh.attributes.extend(attributes);
    Ok(mesh)
}

/// Particles of a box lattice at `spacing`: cell centres of
/// `[lo, lo + n·spacing)` on each axis, for which `keep` holds.
pub(crate) fn lattice(
    lo: [f32; 3],
    n: [i32; 3],
    spacing: f32,
    keep: impl Fn([f32; 3]) -> bool,
) -> Vec<SalvaVector<f32>> {
    let mut out = Vec::new();
    for k in 0..n[2].max(0) {
        for j in 0..n[1].max(0) {
            for i in 0..n[0].max(0) {
                let p = [
                    lo[0] + (i as f32 + 0.5) * spacing,
                    lo[1] + (j as f32 + 0.5) * spacing,
                    lo[2] + (k as f32 + 0.5) * spacing,
                ];
                if keep(p) {
                    out.push(v3(p[0], p[1], p[2]));
                }
            }
        }
    }
    out
}
