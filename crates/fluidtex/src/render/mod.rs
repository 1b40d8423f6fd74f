//! A small deterministic software renderer for previews and evaluation.
//!
//! The evaluation harness computes metrics on renders (flow fidelity,
//! popping) and demos show previews, so rendering must be exact about which
//! pixel sees which surface point and identical on any machine and thread
//! count; no GPU is involved. [`rasterize`] fills a [`GBuffer`] (triangle,
//! perspective-correct barycentrics, depth per pixel) once per camera and
//! frame; [`shade_textured`] and [`shade_lit`] turn it into images;
//! [`side_by_side`] builds preview sheets. [`Camera::framing`] gives fixed
//! cameras that frame a bounding box. Pixel and texel conventions are those
//! of [`crate::texture`] (centres at +0.5, row 0 at the top).
//!
//! Written here rather than taken from a crate because what the harness
//! needs is a G-buffer with exact barycentrics and a crack-free fill rule,
//! which drawing crates don't expose, and GPU crates (wgpu) would make
//! results depend on the driver.

pub mod camera;
pub mod raster;
pub mod shade;
pub mod sheet;

pub use camera::{Camera, NEAR_FRACTION};
pub use raster::{BACKGROUND, GBuffer, rasterize};
pub use shade::{shade_lit, shade_textured};
pub use sheet::side_by_side;

#[cfg(test)]
mod tests;
