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
//!                    io (PNG/EXR atlas, OBJ+MTL, glb, stats JSON; atomic)
//! ```
//!
//! Modules, one per concept: [`mesh`], [`surface`], [`param`], [`atlas`],
//! [`exemplar`], [`methods`], [`metrics`], [`coherence`] (does the texture ride the flow: measured on outputs), [`eval`] (the evaluation harness), [`render`], [`scenes`], [`io`], and [`texture`] (the float image type and texel convention);
//! [`fuzz`] is the seeded mutation fuzzer the reader tests use.

pub mod atlas;
pub mod coherence;
pub mod driver;
pub mod eval;
pub mod exemplar;
pub mod fuzz;
pub mod io;
pub mod mesh;
pub mod methods;
pub mod metrics;
pub mod named;
pub mod param;
pub mod pipeline;
pub mod provenance;
pub mod render;
pub mod scenes;
pub mod seed;
pub mod surface;
pub mod texture;
