//! Counts in a header never make a reader reserve memory before the data
//! proves it exists: a PLY claiming 10¹² vertices, a face of 4·10⁹ corners,
//! a VTK claiming 10¹² points or cells, images claiming 60000² pixels are
//! refused with one line while the whole binary may allocate at most
//! [`BOUND`] more bytes than it held at the start (a capped global
//! allocator; a reservation past the cap aborts the test binary with
//! "memory allocation of N bytes failed").
//!
//! One test only: the cap is global to the binary, and a second test
//! running beside this one would share it.

#![allow(clippy::unwrap_used)]

use std::path::Path;

use fluidtex::io::ReadOptions;

#[global_allocator]
static ALLOCATOR: cap::Cap<std::alloc::System> = cap::Cap::new(std::alloc::System, usize::MAX);

/// What any of these tiny inputs may make a reader allocate.
const BOUND: usize = 64 << 20;

fn ply(header_counts: (&str, &str), body: &[u8], format: &str) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat {format} 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uint int vertex_indices\nend_header\n",
        header_counts.0, header_counts.1
    )
    .into_bytes();
    b.extend_from_slice(body);
    b
}

/// A PNG chunk with its length and CRC.
fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut c = (data.len() as u32).to_be_bytes().to_vec();
    let mut body = kind.to_vec();
    body.extend_from_slice(data);
    c.extend_from_slice(&body);
    c.extend_from_slice(&crc32(&body).to_be_bytes());
    c
}

#[test]
fn header_counts_do_not_reserve_memory_the_data_does_not_hold() {
    let opts = ReadOptions::default();
    let three = b"0 0 0\n1 0 0\n0 1 0\n";
    let mut bin = Vec::new();
    for v in [0f32; 9] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    // One face whose corner count says 4·10⁹ (uint list count).
    let mut face = bin.clone();
    face.extend_from_slice(&4_000_000_000u32.to_le_bytes());
    face.extend_from_slice(&[0; 12]);
    let head = "# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\n";
    // A PNG claiming 60000x60000 RGBA16, with a token of pixel data.
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&60000u32.to_be_bytes());
    ihdr.extend_from_slice(&60000u32.to_be_bytes());
    ihdr.extend_from_slice(&[16, 6, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &ihdr));
    png.extend(chunk(b"IDAT", &[0x78, 0x9c, 0x63, 0, 0, 0, 1, 0, 1]));
    png.extend(chunk(b"IEND", &[]));
    // An EXR whose data window says 60000x60000: an 8x8 file, patched.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("small.exr");
    let tex = fluidtex::texture::Texture::filled(8, 8, 1, 0.5);
    fluidtex::io::image::write_exr(&path, &tex, &Default::default()).unwrap();
    let mut exr = std::fs::read(&path).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = exr
        .windows(key.len())
        .position(|w| w == key)
        .expect("a dataWindow attribute")
        + key.len()
        + 4; // the attribute's byte size
    exr[at + 8..at + 12].copy_from_slice(&59_999i32.to_le_bytes());
    exr[at + 12..at + 16].copy_from_slice(&59_999i32.to_le_bytes());

    let ply = |b: &[u8]| fluidtex::io::ply::parse_ply(Path::new("huge.ply"), b, &opts).map(|_| ());
    let vtk = |b: &str| {
        fluidtex::io::vtk::parse_vtk(Path::new("huge.vtk"), b.as_bytes(), &opts).map(|_| ())
    };
    let image = |b: &[u8], what: &str| fluidtex::io::image_read::decode_image(b, what).map(|_| ());

    // Every reader runs under the cap; the asserts run after it is lifted
    // (a failing assert's backtrace needs memory of its own).
    ALLOCATOR.set_limit(ALLOCATOR.allocated() + BOUND).unwrap();
    // Control: the cap is in force, so an over-reservation fails.
    let capped = Vec::<u8>::new().try_reserve(2 * BOUND).is_err();
    let errors: Vec<String> = [
        ply(&ply_bytes(("1000000000000", "1"), three, "ascii")).map_err(|e| e.to_string()),
        ply(&ply_bytes(("3", "1000000000000"), b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "ascii"))
            .map_err(|e| e.to_string()),
        ply(&ply_bytes(("1000000000000", "0"), &bin, "binary_little_endian"))
            .map_err(|e| e.to_string()),
        ply(&ply_bytes(("3", "1"), &face, "binary_little_endian")).map_err(|e| e.to_string()),
        vtk(&format!("{head}POINTS 1000000000000 float\n0 0 0\n")).map_err(|e| e.to_string()),
        vtk(&format!(
            "{head}POINTS 3 float\n0 0 0 1 0 0 0 1 0\nPOLYGONS 1000000000000 4000000000000\n3 0 1 2\n"
        ))
        .map_err(|e| e.to_string()),
        image(&png, "huge.png").map_err(|e| e.to_string()),
        image(&exr, "huge.exr").map_err(|e| e.to_string()),
    ]
    .into_iter()
    .map(|r| r.err().unwrap_or_else(|| "no error".into()))
    .collect();
    ALLOCATOR.set_limit(usize::MAX).unwrap();

    assert!(capped, "the allocation cap is not in force");
    let expected = [
        "huge.ply: truncated: expected 1000000000000 vertices, file ends in vertex 3",
        "huge.ply: truncated: expected 1000000000000 faces, file ends in face 1",
        "huge.ply: truncated: expected 1000000000000 vertices, file ends in vertex 3",
        "huge.ply: truncated: expected 1 face, file ends in face 0",
        "huge.vtk: truncated: expected 1000000000000 points, file ends in point 1",
        "huge.vtk: ",
        "huge.png: cannot decode image: the header says 60000x60000 pixels, more than",
        "huge.exr: cannot decode image: the header says 60000x60000 pixels, more than",
    ];
    for (e, x) in errors.iter().zip(expected) {
        assert!(e.starts_with(x), "{e}\nexpected: {x}...");
    }
}

fn ply_bytes(header_counts: (&str, &str), body: &[u8], format: &str) -> Vec<u8> {
    ply(header_counts, body, format)
}

/// CRC-32 (PNG's), bitwise: a test needs no table.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}
