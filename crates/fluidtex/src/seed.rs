//! Seeded random streams. Every random choice of a run draws from a stream
//! derived from (seed, stream, index) — a patch id, a frame number — so
//! results do not depend on processing order or thread count, and a resumed
//! run draws what an uninterrupted one would.

/// A well-mixed 64-bit value from (seed, stream, index) (SplitMix64
/// finaliser).
pub fn mix(seed: u64, stream: u64, index: u64) -> u64 {
    let mut z = seed
        ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::mix;

    #[test]
    fn streams_differ_and_repeat() {
        assert_eq!(mix(1, 2, 3), mix(1, 2, 3));
        assert_ne!(mix(1, 2, 3), mix(1, 3, 2));
        assert_ne!(mix(1, 2, 3), mix(2, 2, 3));
        // Known value: the stream is part of the output format (seeds of
        // committed goldens), so it must never change silently.
        assert_eq!(mix(0, 0, 0), 0);
        assert_eq!(mix(0, 1, 0), {
            let mut z: u64 = 0x9E37_79B9_7F4A_7C15;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        });
    }
}
