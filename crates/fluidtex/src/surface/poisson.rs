//! Poisson-disk sampling on surfaces (filled in below).
