//! The memory a run needs, estimated before any frame is read from the
//! atlas size and the output channels alone, and what the machine has
//! available (Linux `/proc`).

use crate::atlas::AtlasParams;
use crate::exemplar::channels::{ChannelFormat, ChannelSpec};

use super::error::{PipelineError, gib};
use super::options::OutputOptions;

/// What a run is expected to need in memory, from the atlas size and the
/// output channels alone (known before any frame is read).
#[derive(Clone, Debug, PartialEq)]
pub struct MemoryEstimate {
    pub width: u32,
    pub height: u32,
    /// Bytes held per atlas texel at the peak of a frame (see [`estimate_memory`]).
    pub bytes_per_texel: u64,
    /// Bytes that do not scale with the atlas (meshes, exemplar, patches).
    pub base_bytes: u64,
    /// The estimate in bytes.
    pub bytes: u64,
    /// What the machine has available (`MemAvailable`), where known.
    pub available: Option<u64>,
}

/// Memory the frames of a run need besides the atlas: two meshes with their
/// BVHs, the exemplar and the patch state. 256 MiB covers a dam-break frame
/// (85k triangles, 5k patches) with room; a heavier scene is not refused
/// for it, since the check only catches atlases that cannot fit.
const BASE_BYTES: u64 = 256 << 20;

/// Components per output channel in the memory estimate (C): an upper
/// bound, colour has 3 or 4.
const ESTIMATE_COMPONENTS: u64 = 4;

/// Bytes per texel of the debug outputs, an upper bound: the float patch
/// colours of a preview frame (12), the dilated copy of the ids that
/// `patches.F.png` is coloured from (4) and the ids as floats that
/// `source.F.exr` takes without a copy (4). The channels are dropped before
/// the last two are made, and those two are not alive together.
fn debug_bytes(outputs: &OutputOptions) -> u64 {
    if outputs.debug { 12 + 4 + 4 } else { 0 }
}

/// Bytes per texel of the encoders: quantized samples and the compressed
/// image, about 2 bytes per component (4 for 16-bit and float).
fn encode_bytes(channels: &[ChannelSpec]) -> u64 {
    channels
        .iter()
        .map(|c| match c.format {
            ChannelFormat::Png8 => 2 * ESTIMATE_COMPONENTS,
            ChannelFormat::Png16 | ChannelFormat::Exr => 4 * ESTIMATE_COMPONENTS,
        })
        .sum()
}

/// Estimates the memory of a run before any frame is read.
///
/// Per atlas texel, at the peak of a frame (the write, while the method's
/// result is alive), with C = 4 components per output channel (an upper
/// bound: colour is 3 or 4):
/// - the method's fill: C floats per channel, a source id and a uv
///   (4·C·channels + 12 bytes), and its result textures (4·C·channels + 8);
/// - the debug outputs: 20 at most (float patch colours on preview frames,
///   12; a copy of the ids for `patches.F.png`, 4; float ids for
///   `source.F.exr`, 4);
/// - encoding: quantized samples and the compressed image, about 2 bytes
///   per component (up to 4 for 16-bit).
///
/// An upper bound by design. Measured (erosion demo, built-in pebbles,
/// one 8-bit colour channel): peak RSS 104 MB at 1024² and 253 MB at
/// 2048², a slope of 49 bytes per texel against the estimate's 80.
pub fn estimate_memory(
    atlas: &AtlasParams,
    channels: &[ChannelSpec],
    outputs: &OutputOptions,
) -> MemoryEstimate {
    let components = ESTIMATE_COMPONENTS * channels.len().max(1) as u64;
    let bytes_per_texel =
        4 * components + 12 + 4 * components + 8 + debug_bytes(outputs) + encode_bytes(channels);
    let texels = u64::from(atlas.width) * u64::from(atlas.height);
    MemoryEstimate {
        width: atlas.width,
        height: atlas.height,
        bytes_per_texel,
        base_bytes: BASE_BYTES,
        bytes: texels * bytes_per_texel + BASE_BYTES,
        available: None,
    }
}

impl MemoryEstimate {
    /// The estimate when frame t is written while frame t+1 is computed
    /// ([`super::write_behind`]): besides the computing frame's peak, the
    /// written frame's channels (4·C·channels bytes per texel: floats on
    /// preview frames; an 8-bit PNG channel is handed over as its C bytes
    /// otherwise, so this is the bound), its source ids (4), its debug
    /// views and its encoders' buffers are alive.
    pub fn writing_behind(mut self, channels: &[ChannelSpec], outputs: &OutputOptions) -> Self {
        let written = 4 * ESTIMATE_COMPONENTS * channels.len().max(1) as u64
            + 4
            + debug_bytes(outputs)
            + encode_bytes(channels);
        self.bytes_per_texel += written;
        self.bytes =
            u64::from(self.width) * u64::from(self.height) * self.bytes_per_texel + self.base_bytes;
        self
    }

    /// The same estimate with the available memory recorded.
    pub fn with_available(mut self, available: Option<u64>) -> MemoryEstimate {
        self.available = available;
        self
    }

    /// Refuses an estimate above the available memory (never where the
    /// available memory is unknown), naming the largest square atlas that
    /// fits.
    pub fn check(&self) -> Result<(), PipelineError> {
        let Some(available) = self.available else {
            return Ok(());
        };
        if self.bytes <= available {
            return Ok(());
        }
        let texels = available.saturating_sub(self.base_bytes) / self.bytes_per_texel.max(1);
        // Whole multiples of 256 texels: atlas sizes people type.
        let side = (texels as f64).sqrt() as u64 / 256 * 256;
        Err(PipelineError::Memory {
            width: self.width,
            height: self.height,
            needed: self.bytes,
            available,
            fits: side.min(u64::from(crate::atlas::MAX_SIDE)) as u32,
        })
    }

    /// "about 1.3 GiB for a 4096x4096 atlas (80 bytes per texel); 20.1 GiB available".
    pub fn describe(&self) -> String {
        let available = match self.available {
            Some(a) => format!("{} available", gib(a)),
            None => "available memory unknown".into(),
        };
        format!(
            "about {} for a {}x{} atlas ({} bytes per texel); {available}",
            gib(self.bytes),
            self.width,
            self.height,
            self.bytes_per_texel
        )
    }
}

/// The process's resident set (`VmRSS` of `/proc/self/status`) in bytes;
/// `None` where there is no such file.
pub fn resident_memory() -> Option<u64> {
    proc_kib("/proc/self/status", "VmRSS:")
}

/// The memory limit of a run that names none: what the process holds now
/// plus nine tenths of what the machine has available, so a run that grows
/// stops with its cause named while the machine still has a tenth to
/// spare (for the write in flight, and for everything else it runs);
/// `None` where `/proc` says nothing (other systems: no limit).
pub fn default_memory_limit() -> Option<u64> {
    let available = available_memory()?;
    Some(resident_memory().unwrap_or(0) + available / 10 * 9)
}

/// Parses a memory size: bytes, or a number with a binary suffix `K`,
/// `M`, `G` or `T` (`KiB`, `MB`, ... read alike), e.g. `5.5G`, `800M`;
/// `0` is 0 (no limit).
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let digits = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(digits);
    let shift = match unit
        .trim()
        .to_ascii_uppercase()
        .trim_end_matches("IB")
        .trim_end_matches('B')
    {
        "" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return Err(format!("{text:?}: unknown unit (use K, M, G or T)")),
    };
    let value: f64 = number
        .parse()
        .map_err(|_| format!("{text:?}: not a size (e.g. 5.5G, 800M or bytes)"))?;
    let bytes = value * 2f64.powi(shift);
    if !(bytes.is_finite() && bytes < 1e18) {
        return Err(format!("{text:?}: too large"));
    }
    Ok(bytes as u64)
}

/// `MemAvailable` of `/proc/meminfo` in bytes; `None` where there is no
/// such file (other systems: the check is skipped).
pub fn available_memory() -> Option<u64> {
    proc_kib("/proc/meminfo", "MemAvailable:")
}

/// A `key: N kB` line of a Linux `/proc` file (`/proc/meminfo`,
/// `/proc/self/status`) in bytes; `None` where the file or line is missing.
pub fn proc_kib(path: &str, key: &str) -> Option<u64> {
    let text = std::fs::read_to_string(path).ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line
        .trim_start_matches(key)
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    kib.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_units_and_bad_ones_are_named() {
        for (text, bytes) in [
            ("0", 0u64),
            ("1048576", 1 << 20),
            ("800M", 800 << 20),
            ("800MiB", 800 << 20),
            ("5.5G", 11 << 29),
            ("2gb", 2 << 30),
            ("1T", 1 << 40),
            ("4k", 4096),
        ] {
            assert_eq!(parse_size(text), Ok(bytes), "{text}");
        }
        for bad in ["", "G", "5X", "-1G", "1e3", "1.2.3M", "99999999999T"] {
            let err = parse_size(bad).expect_err(bad);
            assert!(err.starts_with(&format!("{bad:?}")), "{err}");
        }
    }

    #[test]
    fn the_default_limit_leaves_a_tenth_of_the_available_memory() {
        let (Some(limit), Some(available)) = (default_memory_limit(), available_memory()) else {
            return; // no /proc here: no default limit either
        };
        assert!(limit >= available / 10 * 9, "{limit} {available}");
        assert!(limit < available + resident_memory().unwrap_or(0) + (1 << 30));
    }
}
