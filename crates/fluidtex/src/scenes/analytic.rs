//! The analytic scenes: a [`Motion`] meshed every frame on a fixed grid.
//!
//! Every frame is computed from scratch (no state between frames), so frames
//! can be asked for in any order and the same frame is always bit-identical.
//! Constants, domains and default resolutions are below, one function per
//! scene; the surface formulas are in [`super::flow`] and docs/evaluation.md.

use std::f64::consts::PI;

use glam::{DVec3, Vec3};
use serde_json::json;

use super::flow::{Amplitude, Field, Motion, PulledBack, Shape, SplitMerge};
use super::marching_cubes::{BAND_MARGIN, BLOCK, EDGE_CLAMP, Grid, TOP_BLOCK, extract};
use super::relax::{FINAL_NEWTON_STEPS, RELAX_ITERATIONS, relax};
use super::{Scene, SceneError, SceneInfo, SceneParams};
use crate::mesh::TriMesh;

/// One analytic scene (see [`by_name`] for the list).
pub struct AnalyticScene {
    name: &'static str,
    description: &'static str,
    motion: Box<dyn Motion>,
    /// The box the grid covers (before rounding up to whole blocks).
    domain: (DVec3, DVec3),
    grid: Grid,
    params: SceneParams,
    /// Whether the surface is closed (it is open only where it leaves the domain).
    closed: bool,
    relax_iterations: usize,
}

/// What a frame's meshing did, for reports and benchmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeshingStats {
    pub evaluations: usize,
    pub refined_blocks: usize,
}

/// Constants of one scene: its motion, the box it lives in, whether it is
/// closed and its default frames and resolution.
struct Definition {
    description: &'static str,
    motion: Box<dyn Motion>,
    domain: (DVec3, DVec3),
    closed: bool,
    defaults: SceneParams,
}

fn params(resolution: u32, first: i32, last: i32) -> SceneParams {
    SceneParams {
        resolution,
        fps: 24.0,
        first,
        last,
        seed: 0,
    }
}

/// The puck the vortex scenes swirl: the single-vortex disc (radius 0.15 at
/// (0.5, 0.75)) extruded to a slab 0.1 thick, rim rounded with radius 0.025.
const PUCK: Shape = Shape::Puck {
    center: DVec3::new(0.5, 0.75, 0.5),
    radius: 0.15,
    half_height: 0.05,
    rounding: 0.025,
};
const VORTEX_DOMAIN: (DVec3, DVec3) = (DVec3::new(0.0, 0.0, 0.4), DVec3::new(1.0, 1.0, 0.6));
const SPHERE: Shape = Shape::Sphere {
    center: DVec3::splat(0.5),
    radius: 0.3,
};
const SPHERE_DOMAIN: (DVec3, DVec3) = (DVec3::splat(0.15), DVec3::splat(0.85));

fn definition(name: &str, resolution: Option<u32>) -> Option<Definition> {
    let description = super::catalogue()
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, d)| *d)?;
    let d = match name {
        // The plane z = 0.5 over the unit square, γ = 0.5/s. The grid's z
        // range is set from the cell size so the plane passes mid-cell.
        "shear" => {
            let r = f64::from(resolution.unwrap_or(64).max(1));
            let h = 1.0 / r;
            Definition {
                description,
                motion: Box::new(PulledBack {
                    shape: Shape::Plane { height: 0.5 },
                    field: Field::Shear { gamma: 0.5 },
                    amplitude: Amplitude::Constant,
                }),
                domain: (
                    DVec3::new(0.0, 0.0, 0.5 - 1.5 * h),
                    DVec3::new(1.0, 1.0, 0.5 + 1.5 * h),
                ),
                closed: false,
                defaults: params(64, 0, 96),
            }
        }
        // Merged (through the blend) while d < R + k/4 = 0.17: about
        // t ∈ (1.15 s, 2.85 s), frames 28–68 of 0–96.
        "split-merge" => Definition {
            description,
            motion: Box::new(SplitMerge {
                radius: 0.15,
                d_far: 0.25,
                d_near: 0.12,
                blend: 0.08,
                period: 4.0,
                max_correction: 3.0,
            }),
            domain: (DVec3::new(0.05, 0.3, 0.3), DVec3::new(0.95, 0.7, 0.7)),
            closed: true,
            defaults: params(64, 0, 96),
        },
        _ => Definition {
            description,
            ..flow_definition(name)?
        },
    };
    Some(d)
}

/// The scenes that carry a closed shape along a velocity field backwards
/// in time ([`PulledBack`]); the description is filled in by the caller.
fn flow_definition(name: &str) -> Option<Definition> {
    let d = match name {
        // Enright et al. 2002: unit cube, sphere r = 0.15 at (0.35, 0.35, 0.35), T = 3 s;
        // frames 0–72 at 24 fps are exactly one period.
        "enright" => pulled_back(
            PulledBack {
                shape: Shape::Sphere {
                    center: DVec3::splat(0.35),
                    radius: 0.15,
                },
                field: Field::Enright,
                amplitude: Amplitude::Cosine {
                    period: 3.0,
                    speed: 1.0,
                },
            },
            (DVec3::ZERO, DVec3::ONE),
            params(64, 0, 72),
        ),
        // Single vortex, T = 8 s (frames 0–192).
        "vortex" => pulled_back(
            PulledBack {
                shape: PUCK,
                field: Field::SingleVortex,
                amplitude: Amplitude::Cosine {
                    period: 8.0,
                    speed: 1.0,
                },
            },
            VORTEX_DOMAIN,
            params(96, 0, 192),
        ),
        // The same vortex at half the speed with T = 16 s: the path of the
        // T = 8 s vortex taken twice as slowly (frame 2k here is frame k
        // there), a moderately sheared flow.
        "vortex-16" => pulled_back(
            PulledBack {
                shape: PUCK,
                field: Field::SingleVortex,
                amplitude: Amplitude::Cosine {
                    period: 16.0,
                    speed: 0.5,
                },
            },
            VORTEX_DOMAIN,
            params(96, 0, 384),
        ),
        // A quarter turn per second about the vertical axis through the
        // centre: one full turn over frames 0–96.
        "rigid-rotation" => pulled_back(
            PulledBack {
                shape: SPHERE,
                field: Field::RigidRotation {
                    center: DVec3::splat(0.5),
                    omega: 0.5 * PI,
                },
                amplitude: Amplitude::Constant,
            },
            SPHERE_DOMAIN,
            params(40, 0, 96),
        ),
        // ω(ζ) = π/4 + (π/4)/0.3 · ζ: the top pole turns a quarter turn per
        // second, the bottom pole stays still.
        "differential-rotation" => pulled_back(
            PulledBack {
                shape: SPHERE,
                field: Field::DifferentialRotation {
                    center: DVec3::splat(0.5),
                    omega0: 0.25 * PI,
                    omega1: 0.25 * PI / 0.3,
                },
                amplitude: Amplitude::Constant,
            },
            SPHERE_DOMAIN,
            params(40, 0, 96),
        ),
        // The vortex at full speed for 1 s, ramped to 0 over the next second,
        // then still: frames 48–84 are identical.
        "stop" => pulled_back(
            PulledBack {
                shape: PUCK,
                field: Field::SingleVortex,
                amplitude: Amplitude::Ramp {
                    hold: 1.0,
                    ramp: 1.0,
                },
            },
            VORTEX_DOMAIN,
            params(96, 0, 84),
        ),
        _ => return None,
    };
    Some(d)
}

/// A closed [`PulledBack`] scene in `domain`.
fn pulled_back(motion: PulledBack, domain: (DVec3, DVec3), defaults: SceneParams) -> Definition {
    Definition {
        description: "",
        motion: Box::new(motion),
        domain,
        closed: true,
        defaults,
    }
}

/// Default parameters of an analytic scene, `None` for other names.
pub fn default_params(name: &str) -> Option<SceneParams> {
    definition(name, None).map(|d| d.defaults)
}

/// Builds analytic scene `name` (parameters assumed validated), `None` for
/// other names.
pub fn by_name(name: &str, params: SceneParams) -> Option<AnalyticScene> {
    let d = definition(name, Some(params.resolution))?;
    let name = super::catalogue().iter().find(|(n, _)| *n == name)?.0;
    Some(AnalyticScene {
        name,
        description: d.description,
        motion: d.motion,
        domain: d.domain,
        grid: Grid::new(d.domain.0, d.domain.1, params.resolution),
        params,
        closed: d.closed,
        relax_iterations: RELAX_ITERATIONS,
    })
}

impl AnalyticScene {
    /// The marching-cubes grid.
    pub fn grid(&self) -> Grid {
        self.grid
    }

    /// Whether the surface is closed (no boundary edges expected).
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The scene's parameters.
    pub fn params(&self) -> SceneParams {
        self.params
    }

    /// Sets the number of relaxation iterations (0 gives the raw
    /// marching-cubes mesh with vertices on grid edges, for comparisons).
    pub fn set_relax_iterations(&mut self, iterations: usize) {
        self.relax_iterations = iterations;
    }

    /// The surface at time `t` (seconds) with exact per-vertex velocity.
    pub fn mesh_at(&self, t: f64) -> (TriMesh, MeshingStats) {
        let motion = self.motion.as_ref();
        let contour = extract(motion, t, &self.grid);
        let mut positions = contour.positions;
        if self.relax_iterations > 0 {
            relax(
                &mut positions,
                &contour.triangles,
                motion,
                t,
                self.grid.h,
                self.relax_iterations,
            );
        }
        let positions: Vec<Vec3> = positions.iter().map(|p| p.as_vec3()).collect();
        let velocity = positions
            .iter()
            .map(|p| motion.velocity(p.as_dvec3(), t).as_vec3())
            .collect();
        (
            TriMesh::new(positions, contour.triangles).with_velocity(velocity),
            MeshingStats {
                evaluations: contour.evaluations,
                refined_blocks: contour.refined_blocks,
            },
        )
    }

    /// The surface function at (x, t): negative inside.
    pub fn phi(&self, x: Vec3, t: f64) -> f64 {
        self.motion.phi(x.as_dvec3(), t)
    }
}

impl Scene for AnalyticScene {
    fn info(&self) -> SceneInfo {
        SceneInfo {
            name: self.name.to_string(),
            description: self.description.to_string(),
            fps: self.params.fps,
            first: self.params.first,
            last: self.params.last,
            parameters: json!({
                "resolution": self.params.resolution,
                "seed": self.params.seed,
                "seed_note": "unused: analytic scenes are exact functions of time",
                "time": "t = (frame - first) / fps seconds",
                "motion": self.motion.to_json(),
                "closed_surface": self.closed,
                "domain": [self.domain.0.to_array(), self.domain.1.to_array()],
                "mesher": {
                    "method": "narrow-band marching cubes (asymptotic decider) + tangential relaxation with Newton re-projection",
                    "cell_size": self.grid.h,
                    "cells": self.grid.cells,
                    "grid_origin": self.grid.lo.to_array(),
                    "band_blocks": [TOP_BLOCK, BLOCK],
                    "band_margin": BAND_MARGIN,
                    "edge_clamp": EDGE_CLAMP,
                    "relax_iterations": self.relax_iterations,
                    "final_newton_steps": FINAL_NEWTON_STEPS,
                },
                "velocity": "exact field at each vertex (f64, rounded to f32), world units per second",
            }),
        }
    }

    fn frame(&mut self, f: i32) -> Result<TriMesh, SceneError> {
        self.params.check_frame(f)?;
        Ok(self.mesh_at(self.params.time(f)).0)
    }

    fn exact_velocity(&self, x: Vec3, t: f64) -> Option<Vec3> {
        Some(self.motion.velocity(x.as_dvec3(), t).as_vec3())
    }
}
