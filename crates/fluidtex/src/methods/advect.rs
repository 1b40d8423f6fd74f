//! The `advect` baseline (docs/design.md, *Baselines*): the first frame's
//! lapped texture (patches placed and covered as the erosion method places
//! them) carried by the flow and never regenerated: no erosion, no new
//! patches, no deletion. It stretches without bound and opens holes where
//! the surface grows, which is what the comparisons measure against.
//!
//! It is the erosion machinery ([`super::erosion`]) under these rules, with
//! the erosion method's parameters (`[erosion]`).

use super::erosion::Rules;

/// Patches carried, never eroded nor renewed.
pub const RULES: Rules = Rules {
    name: "advect",
    erodes: false,
    blends: false,
    renews: false,
};
