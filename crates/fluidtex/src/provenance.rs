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
/// [`RENEWAL_DISTORTED`], [`RENEWAL_STATE`], [`RENEWAL_ERODING`],
/// [`RENEWAL_KEPT`]; 0 where no patch held the point (it was a hole
/// or is new surface), [`RENEWAL_UNKNOWN`] off the charts or where the
/// method does not say.
///
/// A source switch at a point is *forced* when the flow or the fluid's
/// state leaves no choice ([`renewal_forced`]: no previous holder, one
/// stretched past the distortion bound δ_max there, one being eroded there
/// because the flow distorts it, or one whose exemplar the state no longer
/// selects) and *unforced* otherwise ([`renewal_unforced`]: the holder is
/// whole there; another patch now shows the point on top of it, or it
/// still shows the point by the method's own reckoning while the flow
/// carried the point across a patch border).
pub const RENEWAL_HELD: u8 = 1;
/// The previous holder still shows the point.
pub const RENEWAL_SHOWN: u8 = 2;
/// The previous holder's triangle at the point is past δ_max (Q_T = 0,
/// Eq. 1 of Gagnon et al. 2021).
pub const RENEWAL_DISTORTED: u8 = 4;
/// The previous holder shows an exemplar that the fluid's state (the
/// attribute of `--select-by`) no longer selects at the point.
pub const RENEWAL_STATE: u8 = 8;
/// The previous holder is being eroded at the point: its interpolated
/// weight there, at this frame's weights, is below 1. The weight decides
/// because it is what the erosion test reads: w_V = Q_V·B_V (Eqs. 1–3)
/// under the paper's weights, falling towards that target at the erosion
/// rate under progressive weights. Q_V < 1 once a triangle of the vertex
/// is stretched past δ_onset; B_V = 0 on the patch mesh's rim, which moves
/// inwards only where the flow tore the patch or erosion already removed
/// its triangles. A switch there is *forced by distortion*: the method
/// renews what the flow stretched, as the distortion bound demands.
pub const RENEWAL_ERODING: u8 = 16;
/// The previous holder still passes the erosion test at the point at this
/// frame's weights: if it does not show the point, another patch does on
/// top of it (or the point was carried across a border).
pub const RENEWAL_KEPT: u8 = 32;
/// No renewal recorded for the texel.
pub const RENEWAL_UNKNOWN: u8 = 0x80;

/// Whether a switch at a texel with renewal byte `r` is forced by the
/// flow or the fluid's state: nothing held the point, or its holder is
/// past δ_max there, is being eroded there ([`RENEWAL_ERODING`]), or shows
/// an exemplar the state no longer selects.
pub fn renewal_forced(r: u8) -> bool {
    r != RENEWAL_UNKNOWN
        && (r & RENEWAL_HELD == 0 || r & (RENEWAL_DISTORTED | RENEWAL_STATE | RENEWAL_ERODING) != 0)
}

/// Whether a switch at a texel with renewal byte `r` is forced by the
/// erosion of a distorted holder alone ([`RENEWAL_ERODING`]): held, within
/// δ_max, showing an exemplar the state still selects, but with its weight
/// below 1 at the point.
pub fn renewal_forced_by_erosion(r: u8) -> bool {
    r != RENEWAL_UNKNOWN
        && r & RENEWAL_HELD != 0
        && r & (RENEWAL_DISTORTED | RENEWAL_STATE) == 0
        && r & RENEWAL_ERODING != 0
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
        let (e, k, st) = (RENEWAL_ERODING, RENEWAL_KEPT, RENEWAL_STATE);
        // (byte, forced, unforced, forced by erosion alone)
        let cases = [
            (0, true, false, false),
            (d, true, false, false),
            (h, false, true, false),
            (h | s, false, true, false),
            (h | k, false, true, false),
            (h | s | k, false, true, false),
            (h | d, true, false, false),
            (h | s | d, true, false, false),
            (h | e, true, false, true),
            (h | e | s | k, true, false, true),
            (h | e | d, true, false, false),
            (h | e | st, true, false, false),
            (h | st, true, false, false),
            (e, true, false, false),
            (RENEWAL_UNKNOWN, false, false, false),
        ];
        for (r, forced, unforced, by_erosion) in cases {
            assert_eq!(renewal_forced(r), forced, "forced {r:#x}");
            assert_eq!(renewal_unforced(r), unforced, "unforced {r:#x}");
            assert_eq!(
                renewal_forced_by_erosion(r),
                by_erosion,
                "by erosion {r:#x}"
            );
        }
    }
}
