//! Velocity at arbitrary points (filled in below).
