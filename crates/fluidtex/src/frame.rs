//! One frame as the driver builds it and the methods read it: the frame's
//! [`FrameGeometry`] (surface index, atlas, topology, vertex normals, built
//! once per frame) and the [`StageClock`] that times its stages.
//!
//! Both sides depend on this module and it on neither: the driver
//! ([`crate::driver`]) builds the geometry and calls the method, a method
//! ([`crate::methods`]) reads the geometry through its `FrameContext` and
//! times its own stages with a clock of its own.

use std::time::Instant;

use glam::Vec3;
use thiserror::Error;

use crate::atlas::{Atlas, AtlasError, AtlasParams};
use crate::mesh::{Topology, TriMesh, ValidationReport};
use crate::surface::SurfaceIndex;

/// Everything about one frame's surface that does not depend on the
/// method, built once per frame.
pub struct FrameGeometry {
    /// The input's frame number.
    pub number: i32,
    pub mesh: TriMesh,
    pub index: SurfaceIndex,
    pub atlas: Atlas,
    pub topology: Topology,
    /// Area-weighted vertex normals ([`TriMesh::vertex_normals`]).
    pub normals: Vec<Vec3>,
    /// What validation dropped or repaired when the frame was read.
    pub report: ValidationReport,
}

impl FrameGeometry {
    /// Builds the frame's surface index, topology and normals (stage
    /// `bvh`) and atlas (stage `atlas`).
    pub fn build(
        number: i32,
        mesh: TriMesh,
        report: ValidationReport,
        atlas: &AtlasParams,
        clock: &mut StageClock,
    ) -> Result<FrameGeometry, GeometryError> {
        let index = SurfaceIndex::new(&mesh);
        let topology = Topology::new(mesh.vertex_count(), &mesh.triangles);
        let normals = mesh.vertex_normals();
        clock.lap("bvh");
        let atlas = Atlas::build(&mesh, atlas).map_err(|source| GeometryError {
            frame: number,
            source,
        })?;
        clock.lap("atlas");
        Ok(FrameGeometry {
            number,
            mesh,
            index,
            atlas,
            topology,
            normals,
            report,
        })
    }

    /// Per-vertex normals of the atlas's output mesh: seam copies share
    /// the normal of their source vertex, so shading is smooth across seams.
    pub fn uv_mesh_normals(&self) -> Vec<Vec3> {
        self.atlas
            .uv_mesh
            .source_vertex
            .iter()
            .map(|&v| self.normals.get(v as usize).copied().unwrap_or(Vec3::Z))
            .collect()
    }
}

/// Records the duration of consecutive stages of one frame.
pub struct StageClock {
    last: Instant,
    pub stages: Vec<(&'static str, f64)>,
}

impl Default for StageClock {
    fn default() -> Self {
        StageClock {
            last: Instant::now(),
            stages: Vec::new(),
        }
    }
}

impl StageClock {
    /// Closes the stage that started at the previous call.
    pub fn lap(&mut self, name: &'static str) {
        let now = Instant::now();
        self.stages
            .push((name, now.duration_since(self.last).as_secs_f64()));
        self.last = now;
    }

    /// Starts the next stage now (time since the last lap belongs to no
    /// stage: a frame waiting for its writer).
    pub fn restart(&mut self) {
        self.last = Instant::now();
    }

    /// Appends stages timed elsewhere (a method's own clock) and starts
    /// the next stage now.
    pub fn extend(&mut self, stages: &[(&'static str, f64)]) {
        self.stages.extend_from_slice(stages);
        self.last = Instant::now();
    }

    /// Seconds of every stage so far.
    pub fn total(&self) -> f64 {
        self.stages.iter().map(|(_, s)| s).sum()
    }
}

/// A frame whose atlas could not be built.
#[derive(Debug, Error)]
#[error("frame {frame}: {source}")]
pub struct GeometryError {
    pub frame: i32,
    pub source: AtlasError,
}
