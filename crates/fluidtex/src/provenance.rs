//! Per-texel provenance: which patch a texel's texture came from. One
//! encoding for methods, files (`source.F.exr`, `patches.F.png`) and
//! metrics: a `u32` per texel that is [`SOURCE_OUTSIDE`] off the charts,
//! [`SOURCE_UNCOVERED`] where no patch reached, and patch id + 1 otherwise
//! (so that 0 can mean "nothing" and ids start at 0).

/// A texel outside every chart, or a background pixel.
pub const SOURCE_OUTSIDE: u32 = u32::MAX;
/// A chart texel (or surface pixel) that no patch reached.
pub const SOURCE_UNCOVERED: u32 = 0;

/// The source value of patch `id`.
pub fn of_patch(id: u32) -> u32 {
    id + 1
}

/// The patch of a source value, if a patch covers the texel.
pub fn patch_of(source: u32) -> Option<u32> {
    match source {
        SOURCE_OUTSIDE | SOURCE_UNCOVERED => None,
        s => Some(s - 1),
    }
}

/// Whether a source value lies on a chart (covered or not).
pub fn in_chart(source: u32) -> bool {
    source != SOURCE_OUTSIDE
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patch_ids_round_trip_and_the_two_markers_are_no_patch() {
        for id in [0, 1, 7, u32::MAX - 2] {
            assert_eq!(patch_of(of_patch(id)), Some(id));
        }
        assert_eq!(patch_of(SOURCE_OUTSIDE), None);
        assert_eq!(patch_of(SOURCE_UNCOVERED), None);
        assert!(in_chart(SOURCE_UNCOVERED) && !in_chart(SOURCE_OUTSIDE));
    }
}
