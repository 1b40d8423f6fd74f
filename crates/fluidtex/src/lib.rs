//! fluidtex: textures that ride animated fluid surfaces.
//!
//! The stages of a frame job (boxes) and the data passed between them
//! (arrows); F is the frame being driven. `docs/architecture.md` has the
//! full version of this picture, with the same stage names and a paragraph
//! per stage: change the two together.
//!
//! ```text
//! +------------------------------------------------------------------+
//! | FRAME SOURCE                               pipeline::FrameSource |
//! |   SequenceSource (PLY/OBJ/VTK), UsdSource (CLI), SceneSource     |
//! +------------------------------------------------------------------+
//!       | TriMesh + ValidationReport   (frame F+1, read on the loop thread)
//!       v
//! +------------------------------------------------------------------+
//! | FRAME GEOMETRY                       frame::FrameGeometry::build |
//! |   surface index (BVH), topology, normals, atlas (param/, atlas/) |
//! |   built one frame ahead on a second thread (pipeline::drive)     |
//! +------------------------------------------------------------------+
//!       | PendingFrame = Arc<FrameGeometry> + StageClock
//!       v
//! +------------------------------------------------------------------+
//! | DRIVER                                            driver::Driver |
//! |   keeps F-1's geometry; dilates each channel into the gutter     |-----+
//! +------------------------------------------------------------------+     |
//!       | FrameContext (F and F-1)          ^ FrameResult                  |
//!       v                                   |                              |
//! +------------------------------------------------------------------+     |
//! | METHOD                                           methods::Method |     |
//! |   SELECTION                         RESAMPLING                   |     |
//! |   select(F) --> Selection --------> resample(F, Selection)       |     |
//! |   step(F) = select + resample in one pass                        |     |
//! +------------------------------------------------------------------+     |
//!       +------------------------------------------------------------------+
//!       | DrivenFrame = dilated FrameResult + F's and F-1's geometry + clock
//!       v
//!   driver::FrameSink -------------------------------------+
//!       |                                                  |
//!       v                                                  v
//! +------------------------------------------+    +--------------------------+
//! | FILE SINK                 output/sink.rs |    | EVAL               eval/ |
//! |   FileSink (pipeline::run,               |    |   MetricsSink, in memory |
//! |   `bench`, `demo`)                       |    |   (`fluidtex compare`)   |
//! +------------------------------------------+    +--------------------------+
//!       | WriteJob  (output/write_behind.rs: F is written while F+1 is computed)
//!       v
//! +------------------------------------------------------------------+
//! | WRITER                                          output/writer.rs |
//! |   FrameWriter: channels, meshes, previews, debug views,          |
//! |   stats.F.json, renamed together; then state.bin;                |
//! |   + CoherenceSink (debug outputs): F against F-1                 |
//! +------------------------------------------------------------------+
//!
//! TWO-PHASE RUN (pipeline/phases.rs): the same stages, wired twice
//!   --phase select      FRAME SOURCE -> FRAME GEOMETRY -> DRIVER
//!                       -> METHOD: select only -> selection.F.bin + state.bin
//!   --phase resample    FRAME SOURCE -> FRAME GEOMETRY -> DRIVER
//!     --frames A-B      -> METHOD: resample(selection.F.bin) -> FILE SINK
//!                       -> WRITER (every file but state.bin); frame A-1
//!                       primed first (resampled, nothing written)
//! ```
//!
//! # Entry points
//!
//! - [`pipeline::run`]: a method over a [`pipeline::FrameSource`]
//!   ([`pipeline::SequenceSource`] for files, [`pipeline::SceneSource`] for
//!   built-in scenes) into an output folder, with resume, atomic writes and
//!   per-frame statistics; in one pass or in two phases ([`pipeline::Phase`]).
//! - [`eval::prepare()`] + [`eval::evaluate()`]: a method over a scene in
//!   memory, measured by every metric ([`eval::report`] writes the report).
//! - [`driver::Driver`]: the frame loop both of them run, for a new front
//!   end (implement [`driver::FrameSink`]).
//! - [`methods::Method`]: what a method implements ([`methods::Method::select`],
//!   [`methods::Method::resample`], [`methods::Method::step`]).
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
//! [`pipeline`] (the run loop, frame sources and two-phase run), [`output`]
//! (what a run writes: the file sink and writers, the coherence sink,
//! `state.bin`, selections, the memory estimate, write-behind), [`texture`]
//! (the float image type and texel convention), and the shared vocabulary:
//! [`provenance`] (which patch a texel came from), [`seed`] (seeded random
//! streams),
//! [`named`](mod@named) (settings with names on the command line).
//! [`fuzz`] is the seeded mutation fuzzer the reader tests use;
//! [`departures`] is the ledger of where each method departs from its
//! paper, from which `docs/departures.md` is generated.

pub mod atlas;
pub mod coherence;
pub mod departures;
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
