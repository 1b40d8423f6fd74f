//! Texturing methods, one module each, behind one interface.

pub mod erosion;
