//! The `blend-deformable` baseline (docs/design.md, *Baselines*):
//! deformable patches with the weights of Eqs. 1–3 of the 2021 paper,
//! alpha-blended by weight ([`super::erosion::blend`]) instead of lapped;
//! new patches where no patch has weight left, deletion of patches no
//! texel sees. It shows what blending costs (ghosting, lost contrast) that
//! erosion's one source per texel avoids.
//!
//! It is the erosion machinery ([`super::erosion`]) under these rules, with
//! the erosion method's parameters (`[erosion]`).

use super::erosion::Rules;

/// Patches blended by weight and renewed, never eroded texel by texel.
pub const RULES: Rules = Rules {
    name: "blend-deformable",
    erodes: false,
    blends: true,
    renews: true,
};
