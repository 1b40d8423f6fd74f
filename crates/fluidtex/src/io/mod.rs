//! Reading fluid mesh sequences and images, and writing every per-frame
//! output.
//!
//! **Reading.** [`read_mesh`] picks a reader from the file extension
//! ([`ply`], [`obj`], [`vtk`]), then runs [`mesh::validate()`]: indices out of
//! range and NaN/inf positions or velocities are errors, zero-area triangles
//! are dropped and counted in the returned [`ValidationReport`]. A frame with
//! no face is valid (the fluid can vanish) and reads as an empty mesh.
//! [`sequence`] turns a frame pattern (`fluid.$F4.ply`, `fluid.####.ply`,
//! `fluid.%04d.ply`) and a frame range into a lazy stream of frames, so memory
//! is bounded by one frame whatever the sequence length. [`image_read`]
//! reads PNG, JPEG and EXR images (exemplars, feature maps, our own
//! outputs read back) into float textures, beside [`image`], which writes
//! them.
//!
//! **Writing.** Every output goes through [`atomic::write_atomic`]: a temp
//! file in the target directory, synced, then renamed, so a killed run never
//! leaves a half-written file; [`atomic::Staging`] groups the files of a
//! frame so that they appear together or not at all;
//! [`atomic::InputGuard`] refuses to overwrite one of the run's inputs;
//! [`lock::OutputLock`] keeps a second run out of a folder being written.
//! Formats: atlas images ([`image`]: PNG 8/16-bit with a parallel deflate,
//! EXR f16/f32), meshes with atlas UVs ([`obj_write`]: OBJ + MTL;
//! [`gltf`]: binary glTF 2.0), and PLY with velocity ([`ply_write`], used
//! by the scene generator).
//!
//! **Errors.** One [`IoError`] for meshes and outputs; image reading has
//! its own [`image_read::ImageError`], which the exemplar's errors wrap.
//! A message is one line that names the file and, where it applies, the
//! element (`face 88`, `vertex 12`, `frame 14`), e.g.
//! `fluid.0012.ply: face 88 refers to vertex 9999, but the mesh has 1000 vertices`.
//! Element indices are zero-based, as in the file.

pub mod atomic;
mod decoded;
mod exr_read;
pub mod gltf;
pub mod image;
pub mod image_read;
pub mod lock;
pub mod obj;
pub mod obj_write;
pub mod ply;
pub mod ply_write;
pub mod sequence;
pub mod vtk;

use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::mesh::{self, MeshError, TriMesh, ValidationReport};

pub use atomic::{
    InputGuard, Staging, WriteHook, remove_stale_temporaries, remove_stale_temporaries_of,
    write_atomic,
};
pub use lock::OutputLock;
pub use sequence::{Frame, FramePattern, FrameRange, Sequence};

/// Everything that can go wrong reading or writing a file.
#[derive(Debug, Error)]
pub enum IoError {
    #[error("{} does not exist", .path.display())]
    NotFound { path: PathBuf },
    #[error("missing frame {frame}: {} does not exist", .path.display())]
    MissingFrame { frame: i32, path: PathBuf },
    #[error("{}: the file is empty", .path.display())]
    Empty { path: PathBuf },
    #[error("{}: unknown mesh format {ext:?} (expected .ply, .obj or .vtk)", .path.display())]
    UnknownFormat { path: PathBuf, ext: String },
    /// The header (PLY, VTK) or overall structure cannot be understood.
    #[error("{}: bad header: {reason}", .path.display())]
    Header { path: PathBuf, reason: String },
    #[error("{}: truncated: expected {}, file ends in {} {}", .path.display(), counted(*.expected, .element), .element, .at)]
    Truncated {
        path: PathBuf,
        element: String,
        expected: usize,
        at: usize,
    },
    /// One element (vertex, face, cell, line) cannot be read.
    #[error("{}: {element} {index}: {reason}", .path.display())]
    Element {
        path: PathBuf,
        element: String,
        index: usize,
        reason: String,
    },
    /// A file that cannot be parsed, where no element index is known.
    #[error("{}: {reason}", .path.display())]
    Malformed { path: PathBuf, reason: String },
    /// Element counts disagree with the data (trailing data, mismatched arrays).
    #[error("{}: bad counts: {reason}", .path.display())]
    Counts { path: PathBuf, reason: String },
    #[error("{}: {source}", .path.display())]
    Mesh { path: PathBuf, source: MeshError },
    #[error("{}: {source}", .path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("invalid frame pattern {pattern:?}: {reason}")]
    Pattern { pattern: String, reason: String },
    #[error("invalid frame range {text:?}: {reason}")]
    Range { text: String, reason: String },
    #[error("{}: refusing to overwrite an input of this run", .path.display())]
    OverwritesInput { path: PathBuf },
    /// Another run holds the output folder's lock ([`lock`]).
    #[error("{}: another fluidtex run is writing here ({holder}); wait for it to end or choose another --out", .dir.display())]
    Locked { dir: PathBuf, holder: String },
    /// A scalar attribute named in [`ReadOptions::scalar_attributes`] that
    /// the file does not have; `available` lists those it has.
    #[error("{}: no per-vertex scalar attribute {attribute:?} (the file's scalar vertex properties: {})", .path.display(), list_or_none(.available))]
    MissingAttribute {
        path: PathBuf,
        attribute: String,
        available: Vec<String>,
    },
    /// Data handed to a writer that the format cannot hold.
    #[error("{}: cannot write: {reason}", .path.display())]
    Unwritable { path: PathBuf, reason: String },
}

impl IoError {
    /// Wraps an OS error, turning "not found" into [`IoError::NotFound`].
    pub(crate) fn os(path: &Path, source: std::io::Error) -> IoError {
        if source.kind() == std::io::ErrorKind::NotFound {
            IoError::NotFound {
                path: path.to_path_buf(),
            }
        } else {
            IoError::Io {
                path: path.to_path_buf(),
                source,
            }
        }
    }
}

/// Options for reading meshes.
///
/// Scalar per-vertex attributes (a simulation's `temperature`, `age`, ...)
/// are kept only when asked for, so that a run that does not use them
/// reads, allocates and validates exactly what it did before: a file's
/// other properties cost nothing.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Names of the three per-vertex velocity properties in PLY files.
    /// Default `None`: the first complete triple among `vx vy vz`,
    /// `velocity_x velocity_y velocity_z` and `v_x v_y v_z` (Houdini), or no
    /// velocity if none is present. When set, a file without these
    /// properties is an error.
    pub velocity_properties: Option<[String; 3]>,
    /// Name of the 3-component point-data array holding velocity in VTK
    /// files. Default `None`: the first of `velocity`, `Velocity`, `vel`,
    /// `v`, or no velocity. When set, a file without it is an error.
    pub vtk_velocity_array: Option<String>,
    /// Per-vertex scalar properties (PLY) or 1-component point-data arrays
    /// (VTK) to keep as [`crate::mesh::Attribute::Scalar`] under their own
    /// name, converted to `f32` from any numeric type. A file without one
    /// of them is an [`IoError::MissingAttribute`] (OBJ files have none);
    /// a non-finite value is refused by validation, naming the vertex.
    /// Default empty: no extra attribute is read.
    pub scalar_attributes: Vec<String>,
    /// Keep every scalar per-vertex property that is not a position,
    /// velocity or normal component (for `fluidtex info`), as well as those
    /// of `scalar_attributes`. Each kept attribute is validated like a
    /// requested one. Default false.
    pub all_scalar_attributes: bool,
}

impl ReadOptions {
    /// The error for requested scalar attributes a file lacks, or `None`
    /// when it has them all; `available` lists the file's scalar per-vertex
    /// properties (for the message).
    pub(crate) fn missing_scalar(
        &self,
        path: &Path,
        found: &[&str],
        available: &[String],
    ) -> Option<IoError> {
        let missing = self
            .scalar_attributes
            .iter()
            .find(|n| !found.contains(&n.as_str()))?;
        Some(IoError::MissingAttribute {
            path: path.to_path_buf(),
            attribute: missing.clone(),
            available: available.to_vec(),
        })
    }
}

/// "a, b, c", or "none" for an empty list.
fn list_or_none(names: &[String]) -> String {
    if names.is_empty() {
        "none".to_string()
    } else {
        names.join(", ")
    }
}

/// Whether a per-vertex property name is a normal component (`nx`,
/// `normal_x`, ...), which [`ReadOptions::all_scalar_attributes`] leaves
/// out like positions and velocity.
pub(crate) fn is_normal_like(name: &str) -> bool {
    matches!(
        name,
        "nx" | "ny" | "nz" | "normal_x" | "normal_y" | "normal_z" | "n_x" | "n_y" | "n_z"
    )
}

/// Mesh file formats [`read_mesh`] understands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    Ply,
    Obj,
    Vtk,
}

impl MeshFormat {
    /// The format named by `path`'s extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<MeshFormat, IoError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        match ext.as_str() {
            "ply" => Ok(MeshFormat::Ply),
            "obj" => Ok(MeshFormat::Obj),
            "vtk" => Ok(MeshFormat::Vtk),
            _ => Err(IoError::UnknownFormat {
                path: path.to_path_buf(),
                ext,
            }),
        }
    }
}

/// Reads a triangle mesh (PLY, OBJ or legacy VTK, by extension), with
/// per-vertex velocity where the file has one, and validates it.
pub fn read_mesh(
    path: &Path,
    options: &ReadOptions,
) -> Result<(TriMesh, ValidationReport), IoError> {
    let format = MeshFormat::from_path(path)?;
    let mut mesh = match format {
        MeshFormat::Ply => ply::read_ply(path, options)?,
        MeshFormat::Obj => {
            let mesh = obj::read_obj(path)?;
            // OBJ has no per-vertex scalar property to read one from.
            if let Some(e) = options.missing_scalar(path, &[], &[]) {
                return Err(e);
            }
            mesh
        }
        MeshFormat::Vtk => vtk::read_vtk(path, options)?,
    };
    let report = mesh::validate(&mut mesh).map_err(|source| IoError::Mesh {
        path: path.to_path_buf(),
        source,
    })?;
    Ok((mesh, report))
}

/// "1 face", "5000 vertices": a count with its element name.
pub(crate) fn counted(n: usize, element: &str) -> String {
    if n == 1 {
        return format!("1 {element}");
    }
    let plural = match element {
        "vertex" => "vertices".to_string(),
        "index" => "indices".to_string(),
        e if e.ends_with('s') || e.ends_with('x') => format!("{e}es"),
        e => format!("{e}s"),
    };
    format!("{n} {plural}")
}

/// Reads a whole file, mapping "not found" and "empty" to their own errors.
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::os(path, e))?;
    if bytes.is_empty() {
        return Err(IoError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(bytes)
}

/// Appends the triangles of a polygon as a fan around its first corner.
/// Returns false (and appends nothing) for a polygon with fewer than three
/// corners.
pub(crate) fn fan(polygon: &[u32], out: &mut Vec<[u32; 3]>) -> bool {
    let Some((&first, rest)) = polygon.split_first() else {
        return false;
    };
    if rest.len() < 2 {
        return false;
    }
    out.extend(rest.windows(2).map(|w| [first, w[0], w[1]]));
    true
}

/// Test helper of every reader: `parse` must return (an error is fine) on
/// every prefix of `good` and on `good` with any one byte replaced by a
/// few troublesome values, never panic.
#[cfg(test)]
pub(crate) fn assert_no_panic_on_damage<T>(good: &[u8], parse: impl Fn(&[u8]) -> T) {
    for n in 0..good.len() {
        let mut cases = vec![good[..n].to_vec()];
        for b in [0u8, 0xff, 0x7f, b'9', b' ', b'\n', b'-'] {
            let mut c = good.to_vec();
            c[n] = b;
            cases.push(c);
        }
        for c in cases {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                let _ = parse(&c);
            }));
            assert!(r.is_ok(), "panicked on {:?}", String::from_utf8_lossy(&c));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fan_triangulates_polygons_around_the_first_corner() {
        let mut out = Vec::new();
        assert!(fan(&[4, 5, 6], &mut out));
        assert!(fan(&[0, 1, 2, 3, 7], &mut out));
        assert!(!fan(&[0, 1], &mut out));
        assert!(!fan(&[], &mut out));
        assert_eq!(counted(5000, "vertex"), "5000 vertices");
        assert_eq!(counted(1, "face"), "1 face");
        assert_eq!(counted(0, "cell"), "0 cells");
        assert_eq!(out, vec![[4, 5, 6], [0, 1, 2], [0, 2, 3], [0, 3, 7]]);
    }

    #[test]
    fn format_from_extension_is_case_insensitive_and_names_unknown_ones() {
        assert_eq!(
            MeshFormat::from_path(Path::new("a/b.PLY")).unwrap(),
            MeshFormat::Ply
        );
        assert_eq!(
            MeshFormat::from_path(Path::new("x.vtk")).unwrap(),
            MeshFormat::Vtk
        );
        let err = MeshFormat::from_path(Path::new("fluid.0001.stl")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "fluid.0001.stl: unknown mesh format \"stl\" (expected .ply, .obj or .vtk)"
        );
    }
}
