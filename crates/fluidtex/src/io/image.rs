//! Writing textures (atlases, debug images) as PNG or EXR.
//!
//! **PNG.** 8- or 16-bit gray, gray-alpha, RGB or RGBA from a 1–4 channel
//! [`Texture`]: values are clamped to [0, 1] and rounded (NaN becomes 0).
//! Large atlases must not cost more to write than to compute
//! (docs/design.md, *Scale and speed*), and a single deflate stream is
//! sequential, so the default encoder ([`PngEncoder::Parallel`]) splits the
//! filtered image into fixed strips of rows and deflates them on the rayon
//! pool, each strip as raw deflate blocks ending in a sync flush (byte
//! aligned, not final), the last one final; the strips concatenate into one
//! valid zlib stream whose Adler-32 is combined from the strips' (zlib's
//! `adler32_combine`). The technique is mtpng's; we do not use the mtpng
//! crate because it links the C zlib (libz-sys), and no pure-Rust crate
//! encodes PNG in parallel. Strip boundaries depend only on the image size,
//! never on the thread count, so the bytes are identical however many
//! threads run. [`PngEncoder::Image`] (the image crate, single-threaded,
//! fast deflate) is kept as a reference and for comparison in `io_bench`.
//!
//! **Strip compression.** By default ([`PngCompression::Fastest`]) each
//! strip is coded by the fdeflate crate: one deflate block with a fixed
//! Huffman code made for filtered PNG rows, plus runs of zeros, and no
//! search for repeats. On a 6144² colour atlas it is 4× faster than miniz
//! at level 1 on one core and its file is 10 % smaller (0.18 s and 33.7 MB
//! against 0.74 s and 37.3 MB); on flat debug colours it is 2–3× faster and
//! 15–35 % larger. The block shape relied on below is checked by a test
//! against the fdeflate version in `Cargo.lock`, and a stream without it is
//! deflated by miniz instead. fdeflate writes a whole zlib stream, so a strip's
//! output is cut to its deflate block and made joinable here: the block's
//! final bit is cleared, and after its end-of-block code an empty stored
//! block brings the stream to a byte boundary, which is what a zlib sync
//! flush writes (`join_fdeflate_block`). [`PngCompression::Deflate`]
//! (miniz at a level, each strip starting with an empty history, ~1 %
//! larger than one stream) is the choice for smaller files.
//!
//! **EXR.** 16- or 32-bit float, 1–4 channels, named `Y`, `Y A`, `R G B`,
//! `R G B A` by default; written by the exr crate, which compresses blocks
//! in parallel on its own rayon pool.

use std::io::Write;
use std::path::Path;

use miniz_oxide::deflate::core::{
    CompressorOxide, TDEFLFlush, TDEFLStatus, compress_to_output, create_comp_flags_from_zip_params,
};
use rayon::prelude::*;

use super::atomic::Staging;
use super::{IoError, write_atomic};
use crate::texture::Texture;

/// PNG sample depth.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PngDepth {
    /// 8 bits per sample (default).
    #[default]
    Eight,
    /// 16 bits per sample, for height/displacement channels.
    Sixteen,
}

/// Which PNG encoder to use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PngEncoder {
    /// Strip-parallel deflate on the rayon pool (default; see module doc).
    #[default]
    Parallel,
    /// The image crate's encoder, single-threaded, fast compression.
    Image,
}

/// How the parallel encoder compresses each strip (module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PngCompression {
    /// fdeflate's fixed code for filtered rows (default): atlases are
    /// rewritten every frame, so speed wins.
    #[default]
    Fastest,
    /// miniz deflate at level 1 (fastest) to 9 (smallest).
    Deflate(u8),
}

impl PngCompression {
    fn check(self) -> Result<(), String> {
        match self {
            PngCompression::Deflate(level) if !(1..=9).contains(&level) => {
                Err(format!("PNG deflate level {level} is outside 1..=9"))
            }
            _ => Ok(()),
        }
    }
}

/// PNG writing options.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PngOptions {
    /// Sample depth. Default [`PngDepth::Eight`].
    pub depth: PngDepth,
    /// Encoder. Default [`PngEncoder::Parallel`].
    pub encoder: PngEncoder,
    /// Compression of the parallel encoder's strips. Default
    /// [`PngCompression::Fastest`].
    pub compression: PngCompression,
}

/// EXR sample type.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ExrSample {
    /// Half float (default): enough for colour, half the size.
    #[default]
    F16,
    F32,
}

/// EXR block compression.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ExrCompression {
    None,
    Rle,
    /// zlib over 16 scan lines: smallest, but the slowest here (5.7 s for a
    /// 6144² RGB f16 atlas on one core).
    Zip16,
    /// Wavelet + Huffman (default): lossless, 2.6 s for the same atlas, the
    /// fastest compressed option measured by `io_bench`.
    #[default]
    Piz,
}

/// EXR writing options.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ExrOptions {
    /// Sample type. Default [`ExrSample::F16`].
    pub sample: ExrSample,
    /// Compression. Default [`ExrCompression::Piz`].
    pub compression: ExrCompression,
    /// One name per channel. Default `None`: `Y`, `Y A`, `R G B`, `R G B A`.
    pub channel_names: Option<Vec<String>>,
    /// Compress on one thread only (for measurements). Default false.
    pub single_threaded: bool,
}

/// Whether every encoder takes `tex` (1 to 4 channels, not empty, as many
/// values as texels × channels): what [`encode_png`] checks first.
pub fn encodable(tex: &Texture) -> bool {
    check_texture(tex).is_ok()
}

/// Checks what every encoder assumes about a texture.
fn check_texture(tex: &Texture) -> Result<(), String> {
    if !(1..=4).contains(&tex.channels) {
        return Err(format!(
            "a texture needs 1 to 4 channels, got {}",
            tex.channels
        ));
    }
    if tex.width == 0 || tex.height == 0 {
        return Err(format!("{}x{} texture is empty", tex.width, tex.height));
    }
    let expected = tex.texel_count().saturating_mul(tex.channels);
    if tex.data.len() != expected {
        return Err(format!(
            "{} values for a {}x{}x{} texture",
            tex.data.len(),
            tex.width,
            tex.height,
            tex.channels
        ));
    }
    Ok(())
}

/// Encodes a texture as PNG bytes.
pub fn encode_png(tex: &Texture, options: &PngOptions) -> Result<Vec<u8>, String> {
    check_texture(tex)?;
    options.compression.check()?;
    match options.encoder {
        PngEncoder::Parallel => Ok(encode_png_parallel(tex, options.depth, options.compression)),
        PngEncoder::Image => {
            encode_png_image_crate(tex, options.depth, &quantize(tex, options.depth))
        }
    }
}

/// Encodes an 8-bit image made row by row with the parallel encoder and
/// `compression`: `row(y, samples)` writes row `y`'s samples
/// (`channels` interleaved per pixel, quantized as [`quantize_8`] does).
/// The same bytes [`encode_png`] gives for the texture the rows were
/// quantized from, without holding the image: for images made directly in
/// 8 bits (debug colours), each strip of the encoder makes its own rows.
pub fn encode_png_8_rows(
    width: u32,
    height: u32,
    channels: usize,
    compression: PngCompression,
    row: impl Fn(usize, &mut [u8]) + Sync,
) -> Result<Vec<u8>, String> {
    if !(1..=4).contains(&channels) || width == 0 || height == 0 {
        return Err(format!(
            "cannot encode a {width}x{height} image with {channels} channels"
        ));
    }
    compression.check()?;
    Ok(encode_png_rows(
        (width, height, channels),
        1,
        compression,
        row,
    ))
}

/// One 8-bit PNG sample from a value: clamped to [0, 1], scaled and
/// rounded half up (NaN gives 0), as [`encode_png`] quantizes.
#[inline]
pub fn quantize_8(x: f32) -> u8 {
    round_half_up(x.clamp(0.0, 1.0) * 255.0) as u8
}

/// Writes a texture as a PNG file, atomically.
pub fn write_png(path: &Path, tex: &Texture, options: &PngOptions) -> Result<(), IoError> {
    let bytes = encode_png(tex, options).map_err(|reason| IoError::Unwritable {
        path: path.to_path_buf(),
        reason,
    })?;
    write_atomic(path, |w| w.write_all(&bytes))
}

/// Samples in PNG order: 8-bit, or 16-bit big endian; clamped and rounded.
fn quantize(tex: &Texture, depth: PngDepth) -> Vec<u8> {
    match depth {
        PngDepth::Eight => quantize_8_all(&tex.data),
        PngDepth::Sixteen => tex
            .data
            .par_iter()
            .with_min_len(1 << 16)
            .flat_map_iter(|&x| quantize_16(x).to_be_bytes())
            .collect(),
    }
}

/// [`quantize_8`] of every value, on every core: an 8-bit PNG's samples.
pub fn quantize_8_all(values: &[f32]) -> Vec<u8> {
    values
        .par_iter()
        .with_min_len(1 << 16)
        .map(|&x| quantize_8(x))
        .collect()
}

/// One 16-bit PNG sample from a value, as [`quantize_8`] at 16 bits.
#[inline]
fn quantize_16(x: f32) -> u16 {
    round_half_up(x.clamp(0.0, 1.0) * 65535.0) as u16
}

/// `v + 0.5` in f64, for `as` to truncate: that is `v.round()` for
/// `v >= 0` (NaN casts to 0) without the libm call `f32::round` becomes on
/// baseline x86-64. Adding 0.5 in f64 is exact for any f32 below 2^28, so
/// halves round up, as `round` does for non-negative values. 2.4× faster
/// on a 6144² atlas.
#[inline]
fn round_half_up(v: f32) -> f64 {
    f64::from(v) + 0.5
}

fn color_type(channels: usize) -> u8 {
    match channels {
        1 => 0, // gray
        2 => 4, // gray + alpha
        3 => 2, // RGB
        _ => 6, // RGBA
    }
}

/// Uncompressed bytes per strip; fixed so output never depends on threads.
const STRIP_BYTES: usize = 1 << 18;

fn encode_png_parallel(tex: &Texture, depth: PngDepth, compression: PngCompression) -> Vec<u8> {
    // Each strip quantizes its own rows: no 8- or 16-bit copy of the whole
    // texture is made (at 6144² RGB that is 113 MiB of fresh pages).
    let len = tex.width as usize * tex.channels;
    let values = |y: usize| &tex.data[y * len..][..len];
    let dims = (tex.width, tex.height, tex.channels);
    match depth {
        PngDepth::Eight => encode_png_rows(dims, 1, compression, |y, out| {
            for (o, &x) in out.iter_mut().zip(values(y)) {
                *o = quantize_8(x);
            }
        }),
        PngDepth::Sixteen => encode_png_rows(dims, 2, compression, |y, out| {
            for (o, &x) in out.chunks_exact_mut(2).zip(values(y)) {
                o.copy_from_slice(&quantize_16(x).to_be_bytes());
            }
        }),
    }
}

/// The parallel encoder over rows made one at a time: `row(y, samples)`
/// writes row `y`'s samples in PNG order (big endian at 16 bits). The
/// image is cut into strips of whole rows ([`STRIP_BYTES`]); each strip
/// makes and filters its rows, is compressed on its own and joined with a
/// sync flush, so the bytes never depend on the thread count.
fn encode_png_rows(
    (width, height, channels): (u32, u32, usize),
    bytes_per_sample: usize,
    compression: PngCompression,
    row: impl Fn(usize, &mut [u8]) + Sync,
) -> Vec<u8> {
    let bpp = channels * bytes_per_sample;
    let len = width as usize * bpp;
    let rows_per_strip = (STRIP_BYTES / (len + 1)).max(1);
    let strips = (height as usize).div_ceil(rows_per_strip);
    let parts: Vec<(Vec<u8>, u32, usize)> = (0..strips)
        .into_par_iter()
        .map(|s| {
            let y0 = s * rows_per_strip;
            let y1 = (y0 + rows_per_strip).min(height as usize);
            let mut filtered = Vec::with_capacity((y1 - y0) * (len + 1));
            // Two row buffers: Paeth reads the row above, which for the
            // strip's first row belongs to the strip before.
            let (mut prev, mut cur) = (vec![0u8; len], vec![0u8; len]);
            if y0 > 0 {
                row(y0 - 1, &mut prev);
            }
            for y in y0..y1 {
                row(y, &mut cur);
                filter_paeth(&cur, (y > 0).then_some(prev.as_slice()), bpp, &mut filtered);
                std::mem::swap(&mut prev, &mut cur);
            }
            let last = s + 1 == strips;
            let (out, adler) = match compression {
                PngCompression::Fastest => fdeflate_strip(&filtered, last),
                PngCompression::Deflate(level) => miniz_strip(&filtered, level, last),
            };
            (out, adler, filtered.len())
        })
        .collect();

    let mut adler = 1u32;
    for (_, a, len) in &parts {
        adler = adler32_combine(adler, *a, *len);
    }
    let trailer = adler.to_be_bytes();
    // The zlib stream (header, the strips' deflate, Adler-32) goes into the
    // IDAT chunks from its pieces, not from a joined copy: at 6144² that
    // copy is tens of MB of fresh memory per frame.
    let mut stream: Vec<&[u8]> = Vec::with_capacity(parts.len() + 2);
    stream.push(&[0x78, 0x01]);
    stream.extend(parts.iter().map(|p| p.0.as_slice()));
    stream.push(&trailer);
    let zlib_len: usize = stream.iter().map(|p| p.len()).sum();

    // Room for the stream and 12 bytes of framing per chunk.
    let mut png = Vec::with_capacity(zlib_len + 64 + zlib_len.div_ceil(IDAT_BYTES) * 12);
    png.extend_from_slice(b"\x89PNG\r\n\x1a\n");
    let mut ihdr = Vec::with_capacity(13);
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[(8 * bytes_per_sample) as u8, color_type(channels), 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    idat_chunks(&mut png, &stream);
    chunk(&mut png, b"IEND", &[]);
    png
}

/// Raw deflate of one strip by miniz at `level`, and the strip's Adler-32:
/// ends with a sync flush (byte aligned, not final) unless it is the
/// `last` strip.
fn miniz_strip(filtered: &[u8], level: u8, last: bool) -> (Vec<u8>, u32) {
    let flags = create_comp_flags_from_zip_params(i32::from(level), -15, 0);
    let mut out = Vec::with_capacity(filtered.len() / 2 + 64);
    let mut c = CompressorOxide::new(flags);
    let flush = if last {
        TDEFLFlush::Finish
    } else {
        TDEFLFlush::Sync
    };
    let (status, consumed) = compress_to_output(&mut c, filtered, flush, |chunk| {
        out.extend_from_slice(chunk);
        true
    });
    // An in-memory callback cannot fail, so miniz always consumes all.
    debug_assert!(status != TDEFLStatus::BadParam && consumed == filtered.len());
    (out, simd_adler32::adler32(&filtered))
}

/// Bytes of the zlib header that fdeflate writes before its block.
const ZLIB_HEADER: usize = 2;
/// Bytes of the Adler-32 that fdeflate writes after its block.
const ZLIB_TRAILER: usize = 4;

/// fdeflate's zlib stream of `data`.
fn fdeflate_zlib(data: &[u8]) -> std::io::Result<Vec<u8>> {
    let mut c = fdeflate::Compressor::new(Vec::with_capacity(data.len() / 2 + 64))?;
    c.write_data(data)?;
    c.finish()
}

/// Raw deflate of one strip by fdeflate, joinable as [`miniz_strip`]'s,
/// and the strip's Adler-32 (fdeflate's own, from its trailer).
fn fdeflate_strip(filtered: &[u8], last: bool) -> (Vec<u8>, u32) {
    // Writing to a vector cannot fail; should it ever, miniz codes the
    // strip instead of losing it.
    match fdeflate_zlib(filtered)
        .ok()
        .and_then(|zlib| join_fdeflate_block(zlib, last))
    {
        Some(block) => block,
        None => miniz_strip(filtered, 1, last),
    }
}

/// fdeflate's zlib stream cut to its deflate block, with the Adler-32 of
/// its trailer; unless `last`, made joinable: not final, and followed by
/// an empty stored block that ends byte aligned (a zlib sync flush).
/// `None` when the stream does not have the one-block shape this relies on
/// (then the caller codes it again).
///
/// fdeflate writes a single dynamic-Huffman block right after the 2-byte
/// zlib header, so the block's first header bit (BFINAL) is bit 0 of the
/// block's first byte. It ends the block with its end-of-block code, whose
/// last bit is 1 in fdeflate's fixed code, then pads with zero bits to a
/// byte: the highest set bit of the block's last byte is where the block
/// ends. A stored block's 3 header bits (all zero: not final, type 00) go
/// right after it, zero padding to the byte, then LEN = 0 and NLEN = !0.
fn join_fdeflate_block(mut zlib: Vec<u8>, last: bool) -> Option<(Vec<u8>, u32)> {
    if zlib.len() <= ZLIB_HEADER + ZLIB_TRAILER || zlib[ZLIB_HEADER] & 1 == 0 {
        return None;
    }
    let trailer = zlib.split_off(zlib.len() - ZLIB_TRAILER);
    let adler = u32::from_be_bytes(trailer.try_into().ok()?);
    let end = *zlib.last()?;
    if end == 0 {
        return None;
    }
    zlib.drain(..ZLIB_HEADER);
    let mut block = zlib;
    if !last {
        block[0] &= !1;
        let free_bits = end.leading_zeros();
        if free_bits < 3 {
            block.push(0);
        }
        block.extend_from_slice(&[0x00, 0x00, 0xff, 0xff]);
    }
    Some((block, adler))
}

/// PNG filter type 4 (Paeth) for one row, prefixed by its filter byte.
/// Paeth compresses photographic atlases best of the fixed filters and
/// costs little next to deflate.
fn filter_paeth(cur: &[u8], prev: Option<&[u8]>, bpp: usize, out: &mut Vec<u8>) {
    out.push(4);
    match prev {
        None => {
            // With no previous row Paeth reduces to Sub.
            out.extend_from_slice(&cur[..bpp.min(cur.len())]);
            out.extend(
                cur[bpp.min(cur.len())..]
                    .iter()
                    .zip(cur)
                    .map(|(&x, &a)| x.wrapping_sub(a)),
            );
        }
        Some(prev) => {
            out.extend(
                cur.iter()
                    .zip(prev)
                    .take(bpp)
                    .map(|(&x, &b)| x.wrapping_sub(b)),
            );
            // Slices rather than `skip` so that the loop vectorizes.
            let (cur_rest, prev_rest) = (&cur[bpp.min(cur.len())..], &prev[bpp.min(prev.len())..]);
            out.extend(
                cur_rest
                    .iter()
                    .zip(prev_rest)
                    .zip(cur.iter().zip(prev))
                    .map(|((&x, &b), (&a, &c))| x.wrapping_sub(paeth(a, b, c))),
            );
        }
    }
}

#[inline]
fn paeth(a: u8, b: u8, c: u8) -> u8 {
    // With p = a + b - c: |p - a| = |b - c|, |p - b| = |a - c|,
    // |p - c| = |a + b - 2c|; written so, the selects vectorize.
    let (ia, ib, ic) = (i16::from(a), i16::from(b), i16::from(c));
    let (pa, pb, pc) = ((ib - ic).abs(), (ia - ic).abs(), (ia + ib - 2 * ic).abs());
    if pa <= pb && pa <= pc {
        a
    } else if pb <= pc {
        b
    } else {
        c
    }
}

/// Adler-32 of the concatenation of two blocks (zlib's `adler32_combine`).
fn adler32_combine(adler1: u32, adler2: u32, len2: usize) -> u32 {
    const BASE: u64 = 65521;
    let rem = len2 as u64 % BASE;
    let (a1, b1) = (u64::from(adler1 & 0xffff), u64::from(adler1 >> 16));
    let (a2, b2) = (u64::from(adler2 & 0xffff), u64::from(adler2 >> 16));
    let sum1 = (a1 + a2 + BASE - 1) % BASE;
    let sum2 = (rem * a1 % BASE + b1 + b2 + BASE - rem) % BASE;
    (sum1 | (sum2 << 16)) as u32
}

/// Bytes of the zlib stream per IDAT chunk (the last one holds the rest).
const IDAT_BYTES: usize = 1 << 20;

/// The zlib stream made of `pieces` as IDAT chunks of [`IDAT_BYTES`], each
/// with its CRC: the chunks [`chunk`] would write for the joined stream cut
/// every [`IDAT_BYTES`].
fn idat_chunks(png: &mut Vec<u8>, pieces: &[&[u8]]) {
    let mut next_piece = pieces.iter().copied();
    let mut pending: &[u8] = &[];
    let mut left: usize = pieces.iter().map(|p| p.len()).sum();
    while left > 0 {
        let size = left.min(IDAT_BYTES);
        png.extend_from_slice(&(size as u32).to_be_bytes());
        png.extend_from_slice(b"IDAT");
        let mut crc = crc32fast::Hasher::new();
        crc.update(b"IDAT");
        let mut need = size;
        while need > 0 {
            if pending.is_empty() {
                let Some(next) = next_piece.next() else {
                    break; // `left` counts the pieces' bytes: never reached
                };
                pending = next;
            }
            let (take, rest) = pending.split_at(need.min(pending.len()));
            png.extend_from_slice(take);
            crc.update(take);
            need -= take.len();
            pending = rest;
        }
        png.extend_from_slice(&crc.finalize().to_be_bytes());
        left -= size;
    }
}

fn chunk(png: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    png.extend_from_slice(&(data.len() as u32).to_be_bytes());
    png.extend_from_slice(kind);
    png.extend_from_slice(data);
    let mut h = crc32fast::Hasher::new();
    h.update(kind);
    h.update(data);
    png.extend_from_slice(&h.finalize().to_be_bytes());
}

fn encode_png_image_crate(tex: &Texture, depth: PngDepth, raw: &[u8]) -> Result<Vec<u8>, String> {
    use image::ImageEncoder;
    use image::codecs::png::{CompressionType, FilterType, PngEncoder as ImgPng};
    let ty = match (tex.channels, depth) {
        (1, PngDepth::Eight) => image::ExtendedColorType::L8,
        (2, PngDepth::Eight) => image::ExtendedColorType::La8,
        (3, PngDepth::Eight) => image::ExtendedColorType::Rgb8,
        (_, PngDepth::Eight) => image::ExtendedColorType::Rgba8,
        (1, PngDepth::Sixteen) => image::ExtendedColorType::L16,
        (2, PngDepth::Sixteen) => image::ExtendedColorType::La16,
        (3, PngDepth::Sixteen) => image::ExtendedColorType::Rgb16,
        (_, PngDepth::Sixteen) => image::ExtendedColorType::Rgba16,
    };
    // image takes 16-bit samples in native order.
    let native: Vec<u8>;
    let data = match depth {
        PngDepth::Eight => raw,
        PngDepth::Sixteen => {
            native = raw
                .chunks_exact(2)
                .flat_map(|b| u16::from_be_bytes([b[0], b[1]]).to_ne_bytes())
                .collect();
            &native
        }
    };
    let mut out = Vec::new();
    ImgPng::new_with_quality(&mut out, CompressionType::Fast, FilterType::Adaptive)
        .write_image(data, tex.width, tex.height, ty)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

fn default_channel_names(channels: usize) -> Vec<String> {
    let names: &[&str] = match channels {
        1 => &["Y"],
        2 => &["Y", "A"],
        3 => &["R", "G", "B"],
        _ => &["R", "G", "B", "A"],
    };
    names.iter().map(|s| s.to_string()).collect()
}

/// Writes a texture as an EXR file, atomically.
pub fn write_exr(path: &Path, tex: &Texture, options: &ExrOptions) -> Result<(), IoError> {
    let mut files = Staging::new(None, None);
    stage_exr(&mut files, path, tex, options)?;
    files.commit()
}

/// [`write_exr`] into a group of files that the caller commits.
pub fn stage_exr(
    files: &mut Staging<'_>,
    path: &Path,
    tex: &Texture,
    options: &ExrOptions,
) -> Result<(), IoError> {
    check_exr_texture(path, tex)?;
    let planes = exr_planes(&tex.data, tex.channels, options.sample);
    stage_exr_planes(files, path, (tex.width, tex.height), planes, options)?;
    Ok(())
}

/// [`stage_exr`] taking the texture and handing it back, values
/// unchanged, once written: the values of a one-channel texture written as
/// 32-bit floats become the file's plane as they are, without the copy
/// [`stage_exr`] makes (150 MB for a 6144² id map), and the caller gets
/// its buffer back.
pub fn stage_exr_owned(
    files: &mut Staging<'_>,
    path: &Path,
    tex: Texture,
    options: &ExrOptions,
) -> Result<Texture, IoError> {
    use exr::prelude::FlatSamples;
    check_exr_texture(path, &tex)?;
    let size = (tex.width, tex.height);
    if (tex.channels, options.sample) != (1, ExrSample::F32) {
        let planes = exr_planes(&tex.data, tex.channels, options.sample);
        stage_exr_planes(files, path, size, planes, options)?;
        return Ok(tex);
    }
    let Texture {
        width,
        height,
        channels,
        data,
    } = tex;
    let mut planes = stage_exr_planes(files, path, size, vec![FlatSamples::F32(data)], options)?;
    match planes.pop() {
        Some(FlatSamples::F32(data)) => Ok(Texture {
            width,
            height,
            channels,
            data,
        }),
        _ => Err(IoError::Unwritable {
            path: path.to_path_buf(),
            reason: "internal: the written plane did not come back".into(),
        }),
    }
}

/// [`check_texture`] as the error of writing `path`.
fn check_exr_texture(path: &Path, tex: &Texture) -> Result<(), IoError> {
    check_texture(tex).map_err(|reason| IoError::Unwritable {
        path: path.to_path_buf(),
        reason,
    })
}

/// One plane of samples per channel of `channels`-interleaved values.
fn exr_planes(data: &[f32], channels: usize, sample: ExrSample) -> Vec<exr::prelude::FlatSamples> {
    use exr::prelude::{FlatSamples, f16};
    (0..channels)
        .map(|k| {
            let plane = data.chunks_exact(channels).map(|texel| texel[k]);
            match sample {
                ExrSample::F16 => FlatSamples::F16(plane.map(f16::from_f32).collect()),
                ExrSample::F32 => FlatSamples::F32(plane.collect()),
            }
        })
        .collect()
}

/// Writes channel planes (each `width × height` samples, rows top to
/// bottom) as an EXR file and hands them back; the texture checks are the
/// caller's.
fn stage_exr_planes(
    files: &mut Staging<'_>,
    path: &Path,
    (width, height): (u32, u32),
    planes: Vec<exr::prelude::FlatSamples>,
    options: &ExrOptions,
) -> Result<Vec<exr::prelude::FlatSamples>, IoError> {
    use exr::prelude::*;
    let bad = |reason: String| IoError::Unwritable {
        path: path.to_path_buf(),
        reason,
    };
    let names = match &options.channel_names {
        Some(n) => n.clone(),
        None => default_channel_names(planes.len()),
    };
    if names.len() != planes.len() {
        return Err(bad(format!(
            "{} channel names for {} channels",
            names.len(),
            planes.len()
        )));
    }
    for (k, n) in names.iter().enumerate() {
        if n.is_empty() || names[..k].contains(n) {
            return Err(bad(format!("channel name {n:?} is empty or repeated")));
        }
    }
    let channels: Vec<AnyChannel<FlatSamples>> = names
        .iter()
        .zip(planes)
        .map(|(name, samples)| AnyChannel::new(name.as_str(), samples))
        .collect();
    let compression = match options.compression {
        ExrCompression::None => Compression::Uncompressed,
        ExrCompression::Rle => Compression::RLE,
        ExrCompression::Zip16 => Compression::ZIP16,
        ExrCompression::Piz => Compression::PIZ,
    };
    let encoding = Encoding {
        compression,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new(
        (width as usize, height as usize),
        LayerAttributes::default(),
        encoding,
        AnyChannels::sort(channels.into()),
    );
    let image = Image::from_layer(layer);
    let single = options.single_threaded;
    files.write(path, |w| {
        let writer = image.write();
        let result = if single {
            writer.non_parallel().to_buffered(w)
        } else {
            writer.to_buffered(w)
        };
        result.map_err(|e| std::io::Error::other(e.to_string()))
    })?;
    // The planes, in the file's order (sorted by name), back to the caller.
    Ok(image
        .layer_data
        .channel_data
        .list
        .into_iter()
        .map(|c| c.sample_data)
        .collect())
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;

    fn random_texture(seed: u64, w: u32, h: u32, c: usize) -> Texture {
        let mut rng = Pcg64::seed_from_u64(seed);
        // Smooth gradient plus noise, with out-of-range values to clamp.
        let data = (0..w as usize * h as usize * c)
            .map(|i| (i % 97) as f32 / 80.0 - 0.1 + rng.random_range(-0.05..0.05))
            .collect();
        Texture::from_data(w, h, c, data).unwrap()
    }

    fn decode(bytes: &[u8]) -> image::DynamicImage {
        image::load_from_memory_with_format(bytes, image::ImageFormat::Png).unwrap()
    }

    #[test]
    fn idat_chunks_from_pieces_are_the_joined_stream_cut_every_mebibyte() {
        let mut rng = Pcg64::seed_from_u64(7);
        for total in [
            1usize,
            9,
            IDAT_BYTES,
            IDAT_BYTES + 1,
            2 * IDAT_BYTES + 12_345,
        ] {
            // Pieces of random sizes, empty ones included, and one piece
            // longer than a chunk whenever the stream has one.
            let mut pieces: Vec<Vec<u8>> = Vec::new();
            let mut made = 0;
            while made < total {
                let n = rng
                    .random_range(0..=IDAT_BYTES + IDAT_BYTES / 2)
                    .min(total - made);
                pieces.push((0..n).map(|_| rng.random()).collect());
                made += n;
            }
            let slices: Vec<&[u8]> = pieces.iter().map(Vec::as_slice).collect();
            let mut got = Vec::new();
            idat_chunks(&mut got, &slices);
            let joined = pieces.concat();
            let mut want = Vec::new();
            for part in joined.chunks(IDAT_BYTES) {
                chunk(&mut want, b"IDAT", part);
            }
            assert_eq!(got.len(), want.len(), "{total} bytes");
            assert!(got == want, "{total} bytes");
        }
    }

    #[test]
    fn rows_made_in_8_bits_encode_to_the_same_bytes() {
        // 517×300×3 and 300×2000×1 span several strips: a strip's first
        // row is filtered against the row the strip before made.
        for (w, h, c) in [
            (1u32, 1u32, 3usize),
            (517, 300, 3),
            (300, 2000, 1),
            (64, 700, 1),
            (33, 9, 4),
        ] {
            let tex = random_texture(u64::from(w), w, h, c);
            let samples: Vec<u8> = tex.data.iter().map(|&x| quantize_8(x)).collect();
            let len = w as usize * c;
            let rows = |y: usize, out: &mut [u8]| out.copy_from_slice(&samples[y * len..][..len]);
            for compression in [PngCompression::Fastest, PngCompression::Deflate(1)] {
                let want = encode_png(
                    &tex,
                    &PngOptions {
                        compression,
                        ..Default::default()
                    },
                )
                .unwrap();
                assert_eq!(encode_png_8_rows(w, h, c, compression, rows).unwrap(), want);
            }
        }
        let rows = |_: usize, out: &mut [u8]| out.fill(0);
        let fastest = PngCompression::Fastest;
        assert!(encode_png_8_rows(2, 2, 5, fastest, rows).is_err());
        assert!(encode_png_8_rows(0, 2, 3, fastest, rows).is_err());
        assert!(encode_png_8_rows(2, 2, 3, PngCompression::Deflate(0), rows).is_err());
        assert!(encode_png_8_rows(2, 2, 3, PngCompression::Deflate(10), rows).is_err());
    }

    /// fdeflate strips joined as the encoder joins them: a zlib header,
    /// the strips' blocks, the combined Adler-32.
    fn join_strips(strips: &[&[u8]]) -> Vec<u8> {
        let mut z = vec![0x78, 0x01];
        let mut adler = 1u32;
        for (i, s) in strips.iter().enumerate() {
            let last = i + 1 == strips.len();
            let zlib = fdeflate_zlib(s).unwrap();
            let (block, a) = join_fdeflate_block(zlib, last).expect("fdeflate's one-block shape");
            assert_eq!((block.clone(), a), fdeflate_strip(s, last));
            assert_eq!(a, simd_adler32::adler32(s), "the trailer's Adler-32");
            z.extend_from_slice(&block);
            adler = adler32_combine(adler, a, s.len());
        }
        z.extend_from_slice(&adler.to_be_bytes());
        z
    }

    #[test]
    fn fdeflate_strips_join_into_one_stream_wherever_a_block_ends() {
        // Strips like filtered rows (small values, runs of zeros) and
        // random bytes, of random lengths: each ends its block at some bit
        // of its last byte, and the join must hold for all eight (the
        // stored block's header fits the padding, or spills into a byte).
        let mut rng = Pcg64::seed_from_u64(2021);
        let mut ends = [0usize; 8];
        for case in 0..200 {
            let strips: Vec<Vec<u8>> = (0..rng.random_range(1..5))
                .map(|_| {
                    let n = rng.random_range(1..3000);
                    (0..n)
                        .map(|_| match case % 3 {
                            0 => rng.random(),
                            1 if rng.random_bool(0.3) => 0,
                            _ => rng.random_range(0..6u8).wrapping_sub(3),
                        })
                        .collect()
                })
                .collect();
            for s in &strips[..strips.len() - 1] {
                let zlib = fdeflate_zlib(s).unwrap();
                let end = zlib[zlib.len() - ZLIB_TRAILER - 1];
                ends[end.leading_zeros() as usize] += 1;
            }
            let refs: Vec<&[u8]> = strips.iter().map(Vec::as_slice).collect();
            let joined = join_strips(&refs);
            let whole = miniz_oxide::inflate::decompress_to_vec_zlib(&joined).unwrap();
            assert_eq!(whole, strips.concat(), "case {case}");
        }
        assert!(
            ends.iter().all(|&n| n > 0),
            "block ends by free bits: {ends:?}"
        );
        // A stream without fdeflate's shape (here: its block marked not
        // final) is refused, and the strip is deflated by miniz instead.
        let mut zlib = fdeflate::compress_to_vec(b"abc");
        zlib[ZLIB_HEADER] &= !1;
        assert_eq!(join_fdeflate_block(zlib, true), None);
    }

    #[test]
    fn adler_combine_matches_the_whole() {
        let mut rng = Pcg64::seed_from_u64(1);
        for _ in 0..20 {
            let n = rng.random_range(0..5000);
            let data: Vec<u8> = (0..n).map(|_| rng.random()).collect();
            let k = rng.random_range(0..=n);
            let (a, b) = data.split_at(k);
            let combined = adler32_combine(
                simd_adler32::adler32(&a),
                simd_adler32::adler32(&b),
                b.len(),
            );
            assert_eq!(combined, simd_adler32::adler32(&data.as_slice()));
        }
    }

    #[test]
    fn parallel_png_decodes_to_the_quantized_texture_for_every_layout() {
        for (seed, (w, h)) in [(1u32, 1u32), (3, 700), (517, 300), (64, 64)]
            .into_iter()
            .enumerate()
        {
            for c in 1..=4 {
                let tex = random_texture(seed as u64, w, h, c);
                for depth in [PngDepth::Eight, PngDepth::Sixteen] {
                    let ours = encode_png(
                        &tex,
                        &PngOptions {
                            depth,
                            ..Default::default()
                        },
                    )
                    .unwrap();
                    let reference = encode_png(
                        &tex,
                        &PngOptions {
                            depth,
                            encoder: PngEncoder::Image,
                            ..Default::default()
                        },
                    )
                    .unwrap();
                    let deflated = encode_png(
                        &tex,
                        &PngOptions {
                            depth,
                            compression: PngCompression::Deflate(6),
                            ..Default::default()
                        },
                    )
                    .unwrap();
                    let (a, b) = (decode(&ours), decode(&reference));
                    assert_eq!(a.color(), b.color(), "{w}x{h}x{c} {depth:?}");
                    assert_eq!(a.as_bytes(), b.as_bytes(), "{w}x{h}x{c} {depth:?}");
                    assert_eq!(decode(&deflated).as_bytes(), b.as_bytes());
                    if depth == PngDepth::Eight {
                        let expect: Vec<u8> = tex
                            .data
                            .iter()
                            .map(|&x| round_half_up(x.clamp(0.0, 1.0) * 255.0) as u8)
                            .collect();
                        assert_eq!(a.as_bytes(), &expect[..]);
                    }
                }
            }
        }
    }

    #[test]
    fn parallel_png_is_identical_for_any_thread_count() {
        let tex = random_texture(9, 1000, 900, 3);
        let enc = || encode_png(&tex, &PngOptions::default()).unwrap();
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(enc);
        let three = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap()
            .install(enc);
        assert_eq!(one, three);
    }

    #[test]
    fn clamps_and_rounds_known_values() {
        let tex = Texture::from_data(4, 1, 1, vec![-1.0, 0.5, 0.2, f32::NAN]).unwrap();
        let png = encode_png(&tex, &PngOptions::default()).unwrap();
        assert_eq!(decode(&png).as_bytes(), &[0, 128, 51, 0]);
        let png = encode_png(
            &tex,
            &PngOptions {
                depth: PngDepth::Sixteen,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(
            decode(&png).to_luma16().into_raw(),
            vec![0, 32768, 13107, 0]
        );
    }

    #[test]
    fn rejects_bad_textures_and_levels() {
        let tex = Texture {
            width: 2,
            height: 2,
            channels: 3,
            data: vec![0.0; 5],
        };
        assert_eq!(
            encode_png(&tex, &PngOptions::default()).unwrap_err(),
            "5 values for a 2x2x3 texture"
        );
        let tex = Texture::filled(2, 2, 3, 0.0);
        assert!(
            encode_png(
                &tex,
                &PngOptions {
                    compression: PngCompression::Deflate(0),
                    ..Default::default()
                }
            )
            .is_err()
        );
        let empty = Texture::filled(0, 3, 1, 0.0);
        assert_eq!(
            encode_png(&empty, &PngOptions::default()).unwrap_err(),
            "0x3 texture is empty"
        );
    }

    #[test]
    fn exr_round_trips_with_names_and_types() {
        use exr::prelude::*;
        let dir = tempfile::tempdir().unwrap();
        for (c, sample) in [
            (1, ExrSample::F32),
            (3, ExrSample::F16),
            (4, ExrSample::F32),
            (2, ExrSample::F16),
        ] {
            let tex = random_texture(c as u64, 37, 21, c);
            let path = dir.path().join(format!("t{c}.exr"));
            write_exr(
                &path,
                &tex,
                &ExrOptions {
                    sample,
                    ..Default::default()
                },
            )
            .unwrap();
            let img = read_all_flat_layers_from_file(&path).unwrap();
            let layer = &img.layer_data[0];
            assert_eq!(layer.size, Vec2(37, 21));
            let names = default_channel_names(c);
            for (k, name) in names.iter().enumerate() {
                let ch = layer
                    .channel_data
                    .list
                    .iter()
                    .find(|ch| ch.name.eq(name.as_str()))
                    .unwrap();
                let values = ch.sample_data.values_as_f32().collect::<Vec<f32>>();
                let expect: Vec<f32> = tex.data.iter().skip(k).step_by(c).copied().collect();
                match sample {
                    ExrSample::F32 => assert_eq!(values, expect),
                    ExrSample::F16 => {
                        let halves: Vec<f32> =
                            expect.iter().map(|&x| f16::from_f32(x).to_f32()).collect();
                        assert_eq!(values, halves);
                    }
                }
            }
        }
        let tex = random_texture(0, 4, 4, 2);
        let opts = ExrOptions {
            channel_names: Some(vec!["height".into(), "height".into()]),
            ..Default::default()
        };
        assert!(write_exr(&dir.path().join("bad.exr"), &tex, &opts).is_err());
        let opts = ExrOptions {
            channel_names: Some(vec!["height".into(), "mask".into()]),
            ..Default::default()
        };
        write_exr(&dir.path().join("named.exr"), &tex, &opts).unwrap();
    }

    #[test]
    fn exr_of_an_owned_texture_has_the_same_bytes_and_comes_back() {
        let dir = tempfile::tempdir().unwrap();
        for (c, sample) in [
            (1, ExrSample::F32),
            (1, ExrSample::F16),
            (3, ExrSample::F32),
        ] {
            let tex = random_texture(7 + c as u64, 29, 17, c);
            let options = ExrOptions {
                sample,
                ..Default::default()
            };
            let (borrowed, owned) = (dir.path().join("b.exr"), dir.path().join("o.exr"));
            write_exr(&borrowed, &tex, &options).unwrap();
            let mut files = Staging::new(None, None);
            let back = stage_exr_owned(&mut files, &owned, tex.clone(), &options).unwrap();
            files.commit().unwrap();
            assert!(
                back == tex,
                "{c} channels, {sample:?}: handed back unchanged"
            );
            let (b, o) = (
                std::fs::read(&borrowed).unwrap(),
                std::fs::read(&owned).unwrap(),
            );
            assert!(b.len() > 100, "{} bytes", b.len());
            assert_eq!(b, o, "{c} channels, {sample:?}");
        }
        let mut files = Staging::new(None, None);
        let bad = Texture {
            width: 3,
            height: 2,
            channels: 1,
            data: vec![0.0; 5],
        };
        let error = stage_exr_owned(
            &mut files,
            &dir.path().join("bad.exr"),
            bad,
            &ExrOptions::default(),
        );
        assert!(error.is_err());
    }
}
