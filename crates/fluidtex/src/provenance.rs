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

/// Per texel of a frame, what became of the patch that showed its surface
/// point on the frame before: the *previous holder*, found by the method
/// on its own carried patches (the erosion fill, for `erosion` and
/// `advect`). A byte of flags: [`RENEWAL_HELD`], [`RENEWAL_SHOWN`],
/// [`RENEWAL_DISTORTED`], [`RENEWAL_STATE`]; 0 where no patch held the point (it was a hole
/// or is new surface), [`RENEWAL_UNKNOWN`] off the charts or where the
/// method does not say.
///
/// A source switch at a point is *forced* when the flow leaves no choice
/// ([`renewal_forced`]: no previous holder, or one stretched past the
/// distortion bound δ_max there) and *unforced* otherwise
/// ([`renewal_unforced`]: the holder is within the bound there; it eroded
/// the point, or it still shows the point by the method's own reckoning
/// while the flow carried the point across a patch border).
pub const RENEWAL_HELD: u8 = 1;
/// The previous holder still shows the point.
pub const RENEWAL_SHOWN: u8 = 2;
/// The previous holder's triangle at the point is past δ_max (Q_T = 0,
/// Eq. 1 of Gagnon et al. 2021).
pub const RENEWAL_DISTORTED: u8 = 4;
/// The previous holder shows an exemplar that the fluid's state (the
/// attribute of `--select-by`) no longer selects at the point.
pub const RENEWAL_STATE: u8 = 8;
/// No renewal recorded for the texel.
pub const RENEWAL_UNKNOWN: u8 = 0x80;

/// Whether a switch at a texel with renewal byte `r` is forced by the
/// flow or the fluid's state: nothing held the point, or its holder is
/// past δ_max there, or shows an exemplar the state no longer selects.
pub fn renewal_forced(r: u8) -> bool {
    r != RENEWAL_UNKNOWN && (r & RENEWAL_HELD == 0 || r & (RENEWAL_DISTORTED | RENEWAL_STATE) != 0)
}

/// Whether a switch at a texel with renewal byte `r` is unforced: the
/// renewal is known and did not force it.
pub fn renewal_unforced(r: u8) -> bool {
    r != RENEWAL_UNKNOWN && !renewal_forced(r)
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

    #[test]
    fn renewal_bytes_split_into_forced_unforced_and_neither() {
        let (h, s, d) = (RENEWAL_HELD, RENEWAL_SHOWN, RENEWAL_DISTORTED);
        // (byte, forced, unforced)
        let cases = [
            (0, true, false),
            (d, true, false),
            (h, false, true),
            (h | s, false, true),
            (h | d, true, false),
            (h | s | d, true, false),
            (RENEWAL_UNKNOWN, false, false),
        ];
        for (r, forced, unforced) in cases {
            assert_eq!(renewal_forced(r), forced, "forced {r:#x}");
            assert_eq!(renewal_unforced(r), unforced, "unforced {r:#x}");
        }
    }
}
