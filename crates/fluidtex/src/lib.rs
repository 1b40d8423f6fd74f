//! fluidtex: textures that ride animated fluid surfaces.
//!
//! The pipeline, per frame of a fluid simulation:
//!
//! ```text
//!  mesh sequence ──► io (read, validate) ──► TriMesh + velocity
//!                                               │
//!        ┌──────────────────────────────────────┤
//!        ▼                                      ▼
//!  surface (BVH, closest point,          atlas (charts, LSCM, packing,
//!   velocity, Poisson disk)               per-texel surface points)
//!        │                                      │
//!        └──────────► methods (erosion = Gagnon et al. 2021, ...) ◄── exemplar
//!                          │  fills atlas channels + per-texel provenance
//!                          ▼
//!      output (file sink, writers, coherence sink, state.bin) + io
//!            (PNG/EXR atlas, OBJ+MTL, glb, stats JSON; atomic)
//! ```
//!
//! # Entry points
//!
//! - [`pipeline::run`]: a method over a frame source ([`pipeline::SequenceSource`]
//!   for files, [`pipeline::SceneSource`] for built-in scenes) into an
//!   output folder, with resume, atomic writes and per-frame statistics.
//! - [`eval::prepare()`] + [`eval::evaluate()`]: a method over a scene in
//!   memory, measured by every metric ([`eval::report`] writes the report).
//! - [`driver::Driver`]: the frame loop both of them run, for a new front
//!   end (implement [`driver::FrameSink`]).
//! - [`methods::registry`]: every method by name ([`methods::registry::MethodKind`])
//!   and how it is built from its parameters ([`methods::registry::MethodParams`]).
//!
//! # Cargo features
//!
//! - `sph` (default): the SPH dam-break scene (salva3d + splashsurf_lib).
//!   Without it every other scene, method and reader is available.
//! - `test-fixtures`: small atlas fixtures for this crate's own tests and
//!   examples; not part of the API.
//!
//! # Modules
//!
//! One per concept: [`mesh`], [`surface`], [`param`], [`atlas`],
//! [`exemplar`], [`methods`], [`driver`] (the frame loop), [`frame`] (one
//! frame's geometry and stage clock, shared by the driver and the methods),
//! [`metrics`],
//! [`coherence`] (does the texture ride the flow: measured on outputs),
//! [`eval`] (the evaluation harness), [`render`], [`scenes`], [`io`],
//! [`pipeline`] (the run loop and frame sources), [`output`] (what a run
//! writes: the file sink and writers, the coherence sink, `state.bin`, the
//! memory estimate, write-behind), [`texture`] (the float image type and
//! texel convention), and the shared vocabulary: [`provenance`] (which
//! patch a texel came from), [`seed`] (seeded random streams),
//! [`named`](mod@named) (settings with names on the command line).
//! [`fuzz`] is the seeded mutation fuzzer the reader tests use.

pub mod atlas;
pub mod coherence;
pub mod driver;
pub mod eval;
pub mod exemplar;
pub mod frame;
pub mod fuzz;
pub mod io;
pub mod mesh;
pub mod methods;
pub mod metrics;
pub mod named;
pub mod output;
pub mod param;
pub mod pipeline;
pub mod provenance;
pub mod render;
pub mod scenes;
pub mod seed;
pub mod surface;
pub mod texture;
