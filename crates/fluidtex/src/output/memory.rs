//! The memory a run needs, estimated before the first frame is textured
//! from the atlas size, the output channels, the largest frame's triangle
//! count and the method's own model of what it holds, and what the machine
//! has available (Linux `/proc`).

use crate::atlas::AtlasParams;
use crate::exemplar::channels::{ChannelFormat, ChannelSpec};
use crate::methods::MemoryModel;

use super::error::{PipelineError, gib};
use super::options::OutputOptions;

/// What a run is expected to need in memory at its peak.
#[derive(Clone, Debug, PartialEq)]
pub struct MemoryEstimate {
    pub width: u32,
    pub height: u32,
    /// Bytes held per atlas texel at the peak of a frame (see [`estimate_memory`]).
    pub bytes_per_texel: u64,
    /// Triangles of the largest frame the estimate assumes.
    pub triangles: u64,
    /// Bytes held per triangle of the largest frame: the frames' geometry
    /// and the method's state ([`MemoryModel::per_triangle`]).
    pub bytes_per_triangle: u64,
    /// Bytes that do not scale with the atlas: the program, the method's
    /// fixed part and the triangles' share.
    pub base_bytes: u64,
    /// The estimate in bytes.
    pub bytes: u64,
    /// What the machine has available (`MemAvailable`), where known.
    pub available: Option<u64>,
}

/// The program itself and the built-in exemplar: the resident set of a
/// run on a tiny mesh at a tiny atlas is 15–25 MB.
const PROGRAM_BYTES: u64 = 28 << 20;

/// Bytes per worker thread: its stack, its allocator arena and the scratch
/// buffers of the parallel stages (measured: erosion's peak grows by about
/// 2.4 MiB per thread from 1 to 16 threads).
pub const THREAD_BYTES: u64 = 4 << 20;

/// Bytes per triangle of the frame geometry alive at once (the previous
/// frame, the current one and the next one being read and built): mesh,
/// surface BVH, topology, normals and atlas charts, about 200 bytes per
/// triangle each. Measured: `lapped-rigid`, whose own state is small,
/// holds 0.8 kB per triangle in all between 14k and 85k triangles.
const GEOMETRY_BYTES_PER_TRIANGLE: u64 = 700;

/// Triangles assumed where the source cannot tell the largest frame's
/// count before reading it (a dam-break frame has 85k).
pub const UNKNOWN_TRIANGLES: u64 = 100_000;

/// Components per output channel in the memory estimate (C): an upper
/// bound, colour has 3 or 4.
const ESTIMATE_COMPONENTS: u64 = 4;

/// Bytes per texel of the debug outputs at their peak: the copy of the
/// ids that `patches.F.png` is coloured from (4), and on a run with
/// previews the float patch colours of a preview frame (12; the demo, at
/// 1024² on 14k triangles, peaks at 159 MiB, 5 MiB under the estimate
/// without them). The float ids of `source.F.exr` are made after the
/// frame's channels are dropped.
fn debug_bytes(outputs: &OutputOptions) -> u64 {
    let ids = if outputs.debug { 4 } else { 0 };
    // A preview frame colours its patch view from float patch colours (12).
    let previews = if outputs.preview_every > 0 { 12 } else { 0 };
    // The switch map keeps the frame before's ids (4) and draws its own
    // image (4).
    let switches = if outputs.switch_map { 8 } else { 0 };
    ids + previews + switches
}

/// Bytes per triangle of the frame geometry alive at once: with the
/// switch map, the written frame's predecessor too.
fn geometry_bytes(outputs: &OutputOptions) -> u64 {
    if outputs.switch_map {
        GEOMETRY_BYTES_PER_TRIANGLE * 4 / 3
    } else {
        GEOMETRY_BYTES_PER_TRIANGLE
    }
}

/// Bytes per texel of one frame's quantized channels (C samples per
/// channel, 1, 2 or 4 bytes each): what the encoders read; the compressed
/// image they write is no larger.
fn encode_bytes(channels: &[ChannelSpec]) -> u64 {
    channels
        .iter()
        .map(|c| match c.format {
            ChannelFormat::Png8 => ESTIMATE_COMPONENTS,
            ChannelFormat::Png16 => 2 * ESTIMATE_COMPONENTS,
            ChannelFormat::Exr => 4 * ESTIMATE_COMPONENTS,
        })
        .sum()
}

/// Estimates the peak memory of a run before its first frame is textured.
///
/// Per atlas texel, with C = 4 components per output channel (an upper
/// bound: colour has 3 or 4):
/// - the method's result: C floats per channel and a source id
///   (4·C·channels + 4), and what the method adds
///   ([`MemoryModel::per_texel`]: uv, levels, blend weights);
/// - writing: the quantized channels the encoders read (C bytes per 8-bit
///   channel, 2·C per 16-bit, 4·C per float), with the debug outputs a
///   copy of the ids (4), with previews the float patch colours (12), with
///   the switch map the frame before's ids and the map (8).
///
/// Per triangle of the largest frame: the geometry of the frames alive at
/// once (700 bytes, a third more with the switch map) and the method's
/// state ([`MemoryModel::per_triangle`]).
/// Besides: the program (28 MiB), 4 MiB per worker thread and what the
/// method adds per thread ([`MemoryModel::per_thread`]), and the method's
/// fixed part ([`MemoryModel::fixed`]).
///
/// An upper bound by design, checked against measured peaks (erosion,
/// lapped-rigid and optimization on a Mantaflow splash of 14k–85k
/// triangles, atlas 256² to 4096²: the estimate is 1.1 to 2 times the
/// peak resident set) and by the CLI test
/// `estimates_bound_the_measured_peak`.
pub fn estimate_memory(
    atlas: &AtlasParams,
    channels: &[ChannelSpec],
    outputs: &OutputOptions,
    model: MemoryModel,
    triangles: u64,
) -> MemoryEstimate {
    let components = ESTIMATE_COMPONENTS * channels.len().max(1) as u64;
    let bytes_per_texel =
        4 * components + 4 + model.per_texel + encode_bytes(channels) + debug_bytes(outputs);
    let bytes_per_triangle = geometry_bytes(outputs) + model.per_triangle;
    let threads = rayon::current_num_threads() as u64;
    let base_bytes = PROGRAM_BYTES
        + threads * (THREAD_BYTES + model.per_thread)
        + model.fixed
        + triangles * bytes_per_triangle;
    let texels = u64::from(atlas.width) * u64::from(atlas.height);
    MemoryEstimate {
        width: atlas.width,
        height: atlas.height,
        bytes_per_texel,
        triangles,
        bytes_per_triangle,
        base_bytes,
        bytes: texels * bytes_per_texel + base_bytes,
        available: None,
    }
}

impl MemoryEstimate {
    /// The estimate when frame t is written while frame t+1 is computed
    /// ([`super::write_behind`]): besides the computing frame's peak, the
    /// written frame's quantized channels, its source ids (4) and its
    /// debug views are alive.
    pub fn writing_behind(mut self, channels: &[ChannelSpec], outputs: &OutputOptions) -> Self {
        self.bytes_per_texel += encode_bytes(channels) + 4 + debug_bytes(outputs);
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
        let side =
            ((texels as f64).sqrt() as u64 / 256 * 256).min(u64::from(crate::atlas::MAX_SIDE));
        let mut what = format!("a {}x{} atlas", self.width, self.height);
        if self.triangles > 0 {
            what += &format!(" with {} triangles", count(self.triangles));
        }
        let advice = if side > 0 {
            format!("lower --atlas (at most {side} fits)")
        } else {
            format!(
                "even without an atlas it needs about {} (the program, the frames and \
                 the method's state); texture a coarser mesh, or run on a machine with \
                 more memory",
                gib(self.base_bytes)
            )
        };
        Err(PipelineError::Memory {
            what,
            needed: self.bytes,
            available,
            advice,
        })
    }

    /// "about 1.3 GiB for a 4096x4096 atlas (45 bytes per texel) and 85k
    /// triangles (4.4 kB each); 20.1 GiB available".
    pub fn describe(&self) -> String {
        let available = match self.available {
            Some(a) => format!("{} available", gib(a)),
            None => "available memory unknown".into(),
        };
        format!(
            "about {} for a {}x{} atlas ({} bytes per texel) and {} triangles ({:.1} kB each); {available}",
            gib(self.bytes),
            self.width,
            self.height,
            self.bytes_per_texel,
            count(self.triangles),
            self.bytes_per_triangle as f64 / 1000.0,
        )
    }
}

/// A count as people say it: "850", "85k", "2.1M".
fn count(n: u64) -> String {
    match n {
        0..1_000 => n.to_string(),
        1_000..1_000_000 => format!("{}k", (n + 500) / 1000),
        _ => format!("{:.1}M", n as f64 / 1e6),
    }
}

/// The process's peak resident set (`VmHWM` of `/proc/self/status`) in
/// bytes; `None` where there is no such file.
pub fn peak_memory() -> Option<u64> {
    proc_kib("/proc/self/status", "VmHWM:")
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
