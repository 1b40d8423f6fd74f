//! Eroded deformable lapped textures (Gagnon et al. 2021).

pub mod distortion;
pub mod erode;
