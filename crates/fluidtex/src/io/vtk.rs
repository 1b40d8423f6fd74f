//! Legacy VTK reader for the surface meshes splashsurf writes.
//!
//! splashsurf writes legacy VTK 4.2, binary (big endian, as the legacy
//! format requires), `DATASET UNSTRUCTURED_GRID` with triangle cells, and
//! point attributes as `FIELD` arrays. We read that and its neighbours:
//! ASCII or binary; `UNSTRUCTURED_GRID` (`CELLS` + `CELL_TYPES`, in the 4.x
//! count-prefixed layout or the 5.x `OFFSETS`/`CONNECTIVITY` layout) or
//! `POLYDATA` (`POLYGONS`, `TRIANGLE_STRIPS`); point data as `VECTORS`,
//! `NORMALS`, `SCALARS` (any component count) or `FIELD` arrays. Velocity is
//! the 3-component point array named in [`ReadOptions::vtk_velocity_array`]
//! or, by default, the first of `velocity`, `Velocity`, `vel`, `v`.
//! A 1-component point array named in [`ReadOptions::scalar_attributes`]
//! (a simulation's `temperature`, ...) becomes a scalar attribute of that
//! name; the others are read past, as before.
//!
//! Written by hand because the one Rust crate for it (vtkio) brings an XML
//! stack and its legacy reader had open bugs splashsurf works around; the
//! legacy format is a handful of keyword lines followed by arrays.
//! Vertex, line and poly-line cells are skipped; volume cells are an error.
//! `long`/`unsigned_long` are read as 8 bytes (64-bit Linux writers).

use std::path::Path;

use glam::Vec3;

use super::{IoError, ReadOptions, read_bytes};
use crate::mesh::{Attribute, MeshError, TriMesh};

/// Default names of the velocity array, tried in order.
pub const VELOCITY_ARRAYS: [&str; 4] = ["velocity", "Velocity", "vel", "v"];

/// Reads a legacy VTK file into a mesh (velocity attached when present).
/// Not validated; [`super::read_mesh`] does that.
pub fn read_vtk(path: &Path, options: &ReadOptions) -> Result<TriMesh, IoError> {
    let bytes = read_bytes(path)?;
    parse_vtk(path, &bytes, options)
}

/// Parses legacy VTK bytes; `path` is used in error messages only.
pub fn parse_vtk(path: &Path, bytes: &[u8], options: &ReadOptions) -> Result<TriMesh, IoError> {
    let mut c = Cursor {
        path,
        bytes,
        pos: 0,
        binary: false,
    };
    let polydata = read_header(&mut c)?;
    let mut sections = Sections::read(&mut c, options)?;
    let positions = sections
        .positions
        .take()
        .ok_or_else(|| c.header("no POINTS section"))?;
    let n = positions.len();
    let triangles = sections.triangles(&c, polydata, n)?;
    let mut mesh = TriMesh::new(positions, triangles);
    if let Some(v) = sections.velocity {
        if v.len() != n {
            return Err(IoError::Counts {
                path: path.to_path_buf(),
                reason: format!("velocity has {} values for {n} points", v.len()),
            });
        }
        mesh = mesh.with_velocity(v);
    } else if let Some(name) = &options.vtk_velocity_array {
        return Err(c.header(&format!("no 3-component point array named {name:?}")));
    }
    let found: Vec<&str> = sections.scalars.iter().map(|(k, _)| k.as_str()).collect();
    if let Some(e) = options.missing_scalar(path, &found, &sections.scalar_names) {
        return Err(e);
    }
    for (name, values) in sections.scalars {
        if values.len() != n {
            return Err(IoError::Counts {
                path: path.to_path_buf(),
                reason: format!("{name} has {} values for {n} points", values.len()),
            });
        }
        mesh.attributes.insert(name, Attribute::Scalar(values));
    }
    Ok(mesh)
}

/// Reads the four header lines; returns true for POLYDATA, false for an
/// UNSTRUCTURED_GRID.
fn read_header(c: &mut Cursor<'_>) -> Result<bool, IoError> {
    let magic = c.line()?;
    if !magic.starts_with("# vtk DataFile") {
        return Err(c.header("not a legacy VTK file (first line is not \"# vtk DataFile ...\")"));
    }
    let _title = c.line()?;
    c.binary = match c.line()?.trim() {
        "ASCII" => false,
        "BINARY" => true,
        other => return Err(c.header(&format!("expected ASCII or BINARY, found {other:?}"))),
    };
    let dataset = c.keyword_line()?;
    match dataset.as_slice() {
        [k, t] if k == "DATASET" && t == "UNSTRUCTURED_GRID" => Ok(false),
        [k, t] if k == "DATASET" && t == "POLYDATA" => Ok(true),
        _ => Err(c.header(&format!(
            "expected DATASET UNSTRUCTURED_GRID or POLYDATA, found {:?}",
            dataset.join(" ")
        ))),
    }
}

/// What the sections after the header hold.
#[derive(Default)]
struct Sections {
    positions: Option<Vec<Vec3>>,
    polygons: Vec<Vec<u32>>,
    cell_types: Option<Vec<u32>>,
    velocity: Option<Vec<Vec3>>,
    /// Point count of the current POINT_DATA section, or 0 in CELL_DATA.
    section_len: usize,
    in_point_data: bool,
    /// Rank in the wanted names of the velocity kept so far.
    best_rank: usize,
    /// Kept 1-component point arrays (the first of a name), in file order.
    scalars: Vec<(String, Vec<f32>)>,
    /// Names of every 1-component point array, for messages.
    scalar_names: Vec<String>,
}

fn vec3s(values: &[f64]) -> Vec<Vec3> {
    values
        .chunks_exact(3)
        .map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32))
        .collect()
}

impl Sections {
    /// Reads every section to the end of the file.
    fn read(c: &mut Cursor<'_>, options: &ReadOptions) -> Result<Sections, IoError> {
        let wanted: Vec<&str> = match &options.vtk_velocity_array {
            Some(name) => vec![name.as_str()],
            None => VELOCITY_ARRAYS.to_vec(),
        };
        let mut s = Sections {
            best_rank: usize::MAX,
            ..Default::default()
        };
        while !c.at_end() {
            let words = c.keyword_line()?;
            let Some(key) = words.first() else { continue };
            match key.as_str() {
                "POINTS" => {
                    let n = c.count(&words, 1)?;
                    let ty = c.word(&words, 2)?;
                    s.positions = Some(vec3s(&c.array(n.saturating_mul(3), ty, "point", 3)?));
                }
                "CELLS" | "POLYGONS" | "TRIANGLE_STRIPS" | "VERTICES" | "LINES" => {
                    let element = if key == "CELLS" { "cell" } else { "polygon" };
                    let lists = c.cell_lists(&words, element)?;
                    match key.as_str() {
                        "CELLS" | "POLYGONS" => s.polygons = lists,
                        "TRIANGLE_STRIPS" => s
                            .polygons
                            .extend(lists.iter().flat_map(|l| strip(l)).map(|t| t.to_vec())),
                        _ => {} // points and lines carry no surface
                    }
                }
                "CELL_TYPES" => {
                    let n = c.count(&words, 1)?;
                    let v = c.array(n, "int", "cell type", 1)?;
                    s.cell_types = Some(v.iter().map(|&t| t as u32).collect());
                }
                "POINT_DATA" | "CELL_DATA" => {
                    s.section_len = c.count(&words, 1)?;
                    s.in_point_data = key == "POINT_DATA";
                }
                "VECTORS" | "NORMALS" | "SCALARS" | "FIELD" => {
                    s.read_attributes(c, &words, &wanted, options)?;
                }
                "METADATA" => c.skip_metadata()?,
                other => return Err(c.header(&format!("unsupported section {other:?}"))),
            }
        }
        Ok(s)
    }

    /// Reads an attribute section (to get past it); keeps the best-ranked
    /// 3-component point array of `wanted` as the velocity, and the
    /// 1-component point arrays `options` asks for.
    fn read_attributes(
        &mut self,
        c: &mut Cursor<'_>,
        words: &[String],
        wanted: &[&str],
        options: &ReadOptions,
    ) -> Result<(), IoError> {
        for (name, comps, values) in c.attribute_arrays(words, self.section_len)? {
            let any = !options.scalar_attributes.is_empty() || options.all_scalar_attributes;
            if any && self.in_point_data && comps == 1 && !self.scalar_names.contains(&name) {
                self.scalar_names.push(name.clone());
                let asked = options.scalar_attributes.contains(&name);
                let every = options.all_scalar_attributes && !super::is_normal_like(&name);
                if asked || every {
                    let v = values.iter().map(|&x| x as f32).collect();
                    self.scalars.push((name.clone(), v));
                }
            }
            let rank = wanted.iter().position(|w| *w == name);
            if let (true, 3, Some(rank)) = (self.in_point_data, comps, rank)
                && rank < self.best_rank
            {
                self.best_rank = rank;
                self.velocity = Some(vec3s(&values));
            }
        }
        Ok(())
    }

    /// The cell type of cell `i`, when the file has cell types.
    fn cell_type(&self, i: usize) -> Option<u32> {
        self.cell_types.as_ref().and_then(|t| t.get(i)).copied()
    }

    /// Whether cell `i` is a surface cell (polydata cells all are).
    fn is_surface(&self, c: &Cursor<'_>, polydata: bool, i: usize) -> Result<bool, IoError> {
        let path = c.path;
        match (&self.cell_types, polydata) {
            (_, true) => Ok(true),
            (Some(types), false) => {
                let t = types.get(i).copied().ok_or_else(|| IoError::Counts {
                    path: path.to_path_buf(),
                    reason: format!(
                        "{} cells but {} cell types",
                        self.polygons.len(),
                        types.len()
                    ),
                })?;
                match t {
                    5..=9 => Ok(true),  // triangle, strip, polygon, pixel, quad
                    1..=4 => Ok(false), // vertex, poly-vertex, line, poly-line
                    other => Err(IoError::Element {
                        path: path.to_path_buf(),
                        element: "cell".into(),
                        index: i,
                        reason: format!("has type {other}, not a surface cell"),
                    }),
                }
            }
            (None, false) if self.polygons.is_empty() => Ok(true),
            (None, false) => Err(c.header("CELLS without CELL_TYPES")),
        }
    }

    /// The surface cells as triangles over `n` points.
    fn triangles(
        &self,
        c: &Cursor<'_>,
        polydata: bool,
        n: usize,
    ) -> Result<Vec<[u32; 3]>, IoError> {
        let path = c.path;
        let mut triangles = Vec::with_capacity(self.polygons.len());
        for (i, poly) in self.polygons.iter().enumerate() {
            if !self.is_surface(c, polydata, i)? {
                continue;
            }
            if let Some(&index) = poly.iter().find(|&&k| k as usize >= n) {
                return Err(IoError::Mesh {
                    path: path.to_path_buf(),
                    source: MeshError::IndexOutOfRange {
                        face: i,
                        index,
                        vertex_count: n,
                    },
                });
            }
            if self.cell_type(i) == Some(6) {
                triangles.extend(strip(poly));
            } else if self.cell_type(i) == Some(8) && poly.len() == 4 {
                // A pixel's corners are in raster order, not around the boundary.
                triangles.push([poly[0], poly[1], poly[3]]);
                triangles.push([poly[0], poly[3], poly[2]]);
            } else if !super::fan(poly, &mut triangles) {
                return Err(IoError::Element {
                    path: path.to_path_buf(),
                    element: "cell".into(),
                    index: i,
                    reason: format!("has {} corners; a face needs at least 3", poly.len()),
                });
            }
        }
        Ok(triangles)
    }
}

/// Triangles of a strip, alternating orientation so all face the same way.
fn strip(s: &[u32]) -> Vec<[u32; 3]> {
    s.windows(3)
        .enumerate()
        .map(|(k, w)| {
            if k % 2 == 0 {
                [w[0], w[1], w[2]]
            } else {
                [w[1], w[0], w[2]]
            }
        })
        .collect()
}

struct Cursor<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    pos: usize,
    binary: bool,
}

impl Cursor<'_> {
    fn header(&self, reason: &str) -> IoError {
        IoError::Header {
            path: self.path.to_path_buf(),
            reason: reason.to_string(),
        }
    }

    fn at_end(&mut self) -> bool {
        self.skip_space();
        self.pos >= self.bytes.len()
    }

    fn skip_space(&mut self) {
        while self
            .bytes
            .get(self.pos)
            .is_some_and(|b| b.is_ascii_whitespace())
        {
            self.pos += 1;
        }
    }

    /// The rest of the current line (without the newline), consumed.
    fn line(&mut self) -> Result<String, IoError> {
        if self.pos >= self.bytes.len() {
            return Err(self.header("the file ends inside the header"));
        }
        let rest = &self.bytes[self.pos..];
        let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
        self.pos += (end + 1).min(rest.len());
        Ok(String::from_utf8_lossy(&rest[..end])
            .trim_end_matches('\r')
            .to_string())
    }

    /// The next non-blank line, split into words.
    fn keyword_line(&mut self) -> Result<Vec<String>, IoError> {
        self.skip_space();
        Ok(self
            .line()?
            .split_whitespace()
            .map(str::to_string)
            .collect())
    }

    fn word<'w>(&self, words: &'w [String], k: usize) -> Result<&'w str, IoError> {
        words
            .get(k)
            .map(String::as_str)
            .ok_or_else(|| self.header(&format!("{:?} is missing a field", words.join(" "))))
    }

    fn count(&self, words: &[String], k: usize) -> Result<usize, IoError> {
        let w = self.word(words, k)?;
        w.parse()
            .map_err(|_| self.header(&format!("{w:?} is not a count in {:?}", words.join(" "))))
    }

    /// Reads `n` numbers of type `ty`; `element`/`per` name the element
    /// (`point`, 3 values each) for truncation messages.
    fn array(
        &mut self,
        n: usize,
        ty: &str,
        element: &str,
        per: usize,
    ) -> Result<Vec<f64>, IoError> {
        let truncated = |at: usize| IoError::Truncated {
            path: self.path.to_path_buf(),
            element: element.to_string(),
            expected: n / per.max(1),
            at: at / per.max(1),
        };
        let mut out = Vec::with_capacity(n.min(self.bytes.len().saturating_sub(self.pos)));
        if self.binary {
            let size =
                type_size(ty).ok_or_else(|| self.header(&format!("unknown data type {ty:?}")))?;
            let available = (self.bytes.len() - self.pos) / size;
            if available < n {
                return Err(truncated(available));
            }
            for chunk in self.bytes[self.pos..self.pos + n * size].chunks_exact(size) {
                out.push(decode_be(chunk, ty));
            }
            self.pos += n * size;
        } else {
            type_size(ty).ok_or_else(|| self.header(&format!("unknown data type {ty:?}")))?;
            for i in 0..n {
                self.skip_space();
                let rest = &self.bytes[self.pos..];
                let end = rest
                    .iter()
                    .position(|b| b.is_ascii_whitespace())
                    .unwrap_or(rest.len());
                if end == 0 {
                    return Err(truncated(i));
                }
                let token = String::from_utf8_lossy(&rest[..end]);
                let value: f64 = token.parse().map_err(|_| IoError::Element {
                    path: self.path.to_path_buf(),
                    element: element.to_string(),
                    index: i / per.max(1),
                    reason: format!("{token:?} is not a number"),
                })?;
                out.push(value);
                self.pos += end;
            }
        }
        Ok(out)
    }

    /// Reads a cell list section (`CELLS`/`POLYGONS`/...), either the 4.x
    /// layout (`n size`, then per cell a count and its indices) or the 5.x
    /// layout (`OFFSETS` and `CONNECTIVITY` arrays).
    fn cell_lists(&mut self, words: &[String], element: &str) -> Result<Vec<Vec<u32>>, IoError> {
        let n = self.count(words, 1)?;
        let size = self.count(words, 2)?;
        let save = self.pos;
        let next = self.keyword_line()?;
        if next.first().map(String::as_str) == Some("OFFSETS") {
            let offsets = self.array(n, self.word(&next, 1)?.to_string().as_str(), "offset", 1)?;
            let conn_words = self.keyword_line()?;
            if conn_words.first().map(String::as_str) != Some("CONNECTIVITY") {
                return Err(self.header("OFFSETS not followed by CONNECTIVITY"));
            }
            let conn = self.array(
                size,
                self.word(&conn_words, 1)?.to_string().as_str(),
                "index",
                1,
            )?;
            let mut lists = Vec::with_capacity(n.saturating_sub(1));
            for (i, w) in offsets.windows(2).enumerate() {
                let (a, b) = (w[0] as usize, w[1] as usize);
                let cell = conn.get(a..b).ok_or_else(|| IoError::Element {
                    path: self.path.to_path_buf(),
                    element: element.to_string(),
                    index: i,
                    reason: format!("offsets {a}..{b} fall outside the {size} indices"),
                })?;
                lists.push(self.indices(cell, element, i)?);
            }
            return Ok(lists);
        }
        self.pos = save;
        let flat = self.array(size, "int", element, 1)?;
        let mut lists = Vec::with_capacity(n.min(flat.len()));
        let mut k = 0usize;
        for i in 0..n {
            let count = *flat.get(k).ok_or_else(|| IoError::Counts {
                path: self.path.to_path_buf(),
                reason: format!("{n} {element}s declared, the {size} values hold only {i}"),
            })? as usize;
            let cell = flat
                .get(k + 1..(k + 1).saturating_add(count))
                .ok_or_else(|| IoError::Counts {
                    path: self.path.to_path_buf(),
                    reason: format!("{element} {i} runs past the {size} values declared"),
                })?;
            lists.push(self.indices(cell, element, i)?);
            k = k + 1 + count;
        }
        if k != size {
            return Err(IoError::Counts {
                path: self.path.to_path_buf(),
                reason: format!("{n} {element}s use {k} of the {size} values declared"),
            });
        }
        Ok(lists)
    }

    fn indices(&self, cell: &[f64], element: &str, i: usize) -> Result<Vec<u32>, IoError> {
        cell.iter()
            .map(|&x| {
                if x >= 0.0 && x <= u32::MAX as f64 && x.fract() == 0.0 {
                    Ok(x as u32)
                } else {
                    Err(IoError::Element {
                        path: self.path.to_path_buf(),
                        element: element.to_string(),
                        index: i,
                        reason: format!("has the invalid point index {x}"),
                    })
                }
            })
            .collect()
    }

    /// Reads one attribute section and returns its arrays as
    /// `(name, components, values)`.
    fn attribute_arrays(
        &mut self,
        words: &[String],
        tuples: usize,
    ) -> Result<Vec<(String, usize, Vec<f64>)>, IoError> {
        let key = self.word(words, 0)?.to_string();
        match key.as_str() {
            "VECTORS" | "NORMALS" => {
                let name = self.word(words, 1)?.to_string();
                let ty = self.word(words, 2)?.to_string();
                let v = self.array(tuples.saturating_mul(3), &ty, "point", 3)?;
                Ok(vec![(name, 3, v)])
            }
            "SCALARS" => {
                let name = self.word(words, 1)?.to_string();
                let ty = self.word(words, 2)?.to_string();
                let comps = match words.get(3) {
                    Some(w) => w
                        .parse()
                        .map_err(|_| self.header(&format!("bad SCALARS component count {w:?}")))?,
                    None => 1,
                };
                let lut = self.keyword_line()?;
                if lut.first().map(String::as_str) != Some("LOOKUP_TABLE") {
                    return Err(self.header("SCALARS without LOOKUP_TABLE"));
                }
                let v = self.array(tuples.saturating_mul(comps), &ty, "point", comps)?;
                Ok(vec![(name, comps, v)])
            }
            _ => {
                let k = self.count(words, 2)?;
                let mut out = Vec::new();
                for _ in 0..k {
                    let w = self.keyword_line()?;
                    let name = self.word(&w, 0)?.to_string();
                    let comps = self.count(&w, 1)?;
                    let n = self.count(&w, 2)?;
                    let ty = self.word(&w, 3)?.to_string();
                    let v = self.array(n.saturating_mul(comps), &ty, "point", comps)?;
                    out.push((name, comps, v));
                }
                Ok(out)
            }
        }
    }

    /// Skips a 5.x `METADATA` block, which ends at a blank line.
    fn skip_metadata(&mut self) -> Result<(), IoError> {
        while self.pos < self.bytes.len() {
            if self.line()?.trim().is_empty() {
                break;
            }
        }
        Ok(())
    }
}

fn type_size(ty: &str) -> Option<usize> {
    Some(match ty {
        "bit" => return None,
        "char" | "unsigned_char" | "vtktypeint8" | "vtktypeuint8" => 1,
        "short" | "unsigned_short" | "vtktypeint16" | "vtktypeuint16" => 2,
        "int" | "unsigned_int" | "float" | "vtktypeint32" | "vtktypeuint32" | "vtktypefloat32" => 4,
        "long" | "unsigned_long" | "double" | "vtktypeint64" | "vtktypeuint64"
        | "vtktypefloat64" => 8,
        _ => return None,
    })
}

/// Decodes one big-endian value; `b.len()` equals `type_size(ty)`.
fn decode_be(b: &[u8], ty: &str) -> f64 {
    let mut a = [0u8; 8];
    a[..b.len()].copy_from_slice(b);
    match ty {
        "char" | "vtktypeint8" => f64::from(a[0] as i8),
        "unsigned_char" | "vtktypeuint8" => f64::from(a[0]),
        "short" | "vtktypeint16" => f64::from(i16::from_be_bytes([a[0], a[1]])),
        "unsigned_short" | "vtktypeuint16" => f64::from(u16::from_be_bytes([a[0], a[1]])),
        "int" | "vtktypeint32" => f64::from(i32::from_be_bytes([a[0], a[1], a[2], a[3]])),
        "unsigned_int" | "vtktypeuint32" => f64::from(u32::from_be_bytes([a[0], a[1], a[2], a[3]])),
        "float" | "vtktypefloat32" => f64::from(f32::from_be_bytes([a[0], a[1], a[2], a[3]])),
        "long" | "vtktypeint64" => i64::from_be_bytes(a) as f64,
        "unsigned_long" | "vtktypeuint64" => u64::from_be_bytes(a) as f64,
        _ => f64::from_be_bytes(a),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(b: &[u8]) -> Result<TriMesh, IoError> {
        parse_vtk(Path::new("s.vtk"), b, &ReadOptions::default())
    }

    #[test]
    fn ascii_unstructured_grid_with_field_velocity_and_a_vertex_cell() {
        let text = b"# vtk DataFile Version 4.2\nsurface\nASCII\nDATASET UNSTRUCTURED_GRID\n\
POINTS 4 float\n0 0 0 1 0 0 1 1 0\n0 1 0\nCELLS 3 11\n3 0 1 2\n4 0 1 2 3\n1 3\nCELL_TYPES 3\n5\n9\n1\n\
POINT_DATA 4\nFIELD FieldData 2\nid 1 4 int\n0 1 2 3\nvelocity 3 4 float\n1 2 3 4 5 6 7 8 9 10 11 12\n";
        let m = parse(text).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.velocity().unwrap()[3], Vec3::new(10.0, 11.0, 12.0));
    }

    #[test]
    fn binary_polydata_with_vectors() {
        let mut b =
            b"# vtk DataFile Version 3.0\nt\nBINARY\nDATASET POLYDATA\nPOINTS 3 double\n".to_vec();
        for x in [0.0f64, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
            b.extend_from_slice(&x.to_be_bytes());
        }
        b.extend_from_slice(b"\nPOLYGONS 1 4\n");
        for i in [3i32, 0, 1, 2] {
            b.extend_from_slice(&i.to_be_bytes());
        }
        b.extend_from_slice(b"\nPOINT_DATA 3\nVECTORS vel float\n");
        for x in [1.0f32, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 3.0] {
            b.extend_from_slice(&x.to_be_bytes());
        }
        b.push(b'\n');
        let m = parse(&b).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert_eq!(m.velocity().unwrap()[2], Vec3::new(0.0, 0.0, 3.0));
        // Truncating inside the points names the point.
        let err = parse(&b[..80]).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("s.vtk: truncated: expected 3 points, file ends in point"),
            "{err}"
        );
    }

    #[test]
    fn vtk5_offsets_and_connectivity() {
        let text = b"# vtk DataFile Version 5.1\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n\
0 0 0 1 0 0 1 1 0 0 1 0\nCELLS 3 7\nOFFSETS vtktypeint64\n0 3 7\nCONNECTIVITY vtktypeint64\n0 1 2 0 1 2 3\n\
CELL_TYPES 2\n5\n9\n";
        let m = parse(text).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn errors_name_the_cell() {
        let head = "# vtk DataFile Version 4.2\ns\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 3 float\n0 0 0 1 0 0 0 1 0\n";
        let err =
            parse(format!("{head}CELLS 1 4\n3 0 1 7\nCELL_TYPES 1\n5\n").as_bytes()).unwrap_err();
        assert_eq!(
            err.to_string(),
            "s.vtk: face 0 refers to vertex 7, but the mesh has 3 vertices"
        );
        let err = parse(format!("{head}CELLS 1 5\n4 0 1 2 0\nCELL_TYPES 1\n10\n").as_bytes())
            .unwrap_err();
        assert_eq!(
            err.to_string(),
            "s.vtk: cell 0: has type 10, not a surface cell"
        );
        let err =
            parse(format!("{head}CELLS 2 4\n3 0 1 2\nCELL_TYPES 1\n5\n").as_bytes()).unwrap_err();
        assert_eq!(
            err.to_string(),
            "s.vtk: bad counts: 2 cells declared, the 4 values hold only 1"
        );
    }

    /// Every truncation and several single-byte corruptions at every offset
    /// of an ASCII and a binary file: errors are fine, panics are not.
    #[test]
    fn never_panics_on_truncated_or_corrupted_input() {
        let ascii = b"# vtk DataFile Version 4.2\nsurface\nASCII\nDATASET UNSTRUCTURED_GRID\n\
POINTS 4 float\n0 0 0 1 0 0 1 1 0 0 1 0\nCELLS 2 9\n3 0 1 2\n4 0 1 2 3\nCELL_TYPES 2\n5\n9\n\
POINT_DATA 4\nVECTORS velocity float\n1 2 3 4 5 6 7 8 9 10 11 12\n"
            .to_vec();
        let mut binary =
            b"# vtk DataFile Version 4.2\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 3 float\n"
                .to_vec();
        for x in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
            binary.extend_from_slice(&x.to_be_bytes());
        }
        binary.extend_from_slice(b"\nCELLS 1 4\n");
        for i in [3i32, 0, 1, 2] {
            binary.extend_from_slice(&i.to_be_bytes());
        }
        binary.extend_from_slice(b"\nCELL_TYPES 1\n");
        binary.extend_from_slice(&5i32.to_be_bytes());
        binary.extend_from_slice(b"\nPOINT_DATA 3\nFIELD FieldData 1\nvelocity 3 3 double\n");
        for x in 0..9 {
            binary.extend_from_slice(&f64::from(x).to_be_bytes());
        }
        for good in [ascii, binary] {
            assert!(parse(&good).is_ok());
            crate::io::assert_no_panic_on_damage(&good, |c| parse(c).map(|_| ()));
        }
    }
}
