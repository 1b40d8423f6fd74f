//! Binary glTF 2.0 (`.glb`) writer: one mesh, one material whose base
//! colour is an embedded PNG.
//!
//! Written directly (the format is a 12-byte header, a JSON chunk and a
//! binary chunk) rather than through the `gltf` crate, whose writing side is
//! its JSON model only. Layout of the binary chunk, each view 4-byte aligned:
//! positions (`VEC3` f32, with the `min`/`max` the spec requires), normals
//! (optional), `TEXCOORD_0` (`VEC2` f32), indices (`SCALAR` u32), PNG bytes.
//! glTF's UV origin is the top-left of the image, like ours, so UVs are
//! written unchanged. The sampler is linear with clamp-to-edge, matching
//! how atlases are sampled ([`crate::texture::Wrap::Clamp`]). A mesh with
//! no triangle (the fluid vanished) gives a valid file with an empty scene,
//! since glTF accessors cannot be empty.

use std::io::Write;
use std::path::Path;

use glam::{Vec2, Vec3};
use serde_json::{Value, json};

use super::obj_write::check_mesh;
use super::{IoError, write_atomic};

const GLB_MAGIC: u32 = 0x4654_6C67; // "glTF"
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const LINEAR: u32 = 9729;
const CLAMP_TO_EDGE: u32 = 33071;

/// Writes a `.glb` atomically. `base_color_png` is the colour atlas, already
/// PNG-encoded (see [`super::image::encode_png`]).
pub fn write_glb(
    path: &Path,
    positions: &[Vec3],
    uvs: &[Vec2],
    normals: Option<&[Vec3]>,
    triangles: &[[u32; 3]],
    base_color_png: Option<&[u8]>,
) -> Result<(), IoError> {
    let glb = layout_glb(positions, uvs, normals, triangles, base_color_png).map_err(|reason| {
        IoError::Unwritable {
            path: path.to_path_buf(),
            reason,
        }
    })?;
    write_atomic(path, |w| glb.write_to(w))
}

/// Builds the `.glb` bytes in memory.
pub fn encode_glb(
    positions: &[Vec3],
    uvs: &[Vec2],
    normals: Option<&[Vec3]>,
    triangles: &[[u32; 3]],
    base_color_png: Option<&[u8]>,
) -> Result<Vec<u8>, String> {
    layout_glb(positions, uvs, normals, triangles, base_color_png).map(|g| g.to_bytes())
}

/// A `.glb` laid out and ready to write: the header with the JSON chunk
/// and the binary chunk's own header, the mesh's buffer views, then the
/// embedded PNG as the chunk's last view. The PNG is borrowed and written
/// from the caller's bytes: at 6144² it is tens of MB, which the file would
/// otherwise copy twice more in memory (into the binary chunk, then into
/// the file's bytes) before writing them.
pub struct Glb<'a> {
    head: Vec<u8>,
    mesh: Vec<u8>,
    image: &'a [u8],
    /// Zeros after the image, to the chunk's 4-byte end.
    padding: usize,
}

impl Glb<'_> {
    /// The file's size in bytes.
    fn len(&self) -> usize {
        self.head.len() + self.mesh.len() + self.image.len() + self.padding
    }

    /// Writes the file's bytes to `w`.
    pub fn write_to(&self, w: &mut impl Write) -> std::io::Result<()> {
        w.write_all(&self.head)?;
        w.write_all(&self.mesh)?;
        w.write_all(self.image)?;
        w.write_all(&[0; 3][..self.padding])
    }

    /// The file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.len());
        for part in [&self.head, &self.mesh, self.image, &[0; 3][..self.padding]] {
            out.extend_from_slice(part);
        }
        out
    }
}

/// Lays out the `.glb` of a mesh with atlas UVs and, optionally, the
/// colour atlas as its one material's base colour.
pub fn layout_glb<'a>(
    positions: &[Vec3],
    uvs: &[Vec2],
    normals: Option<&[Vec3]>,
    triangles: &[[u32; 3]],
    base_color_png: Option<&'a [u8]>,
) -> Result<Glb<'a>, String> {
    check_mesh(positions, uvs, normals, triangles)?;
    let mut json = json!({
        "asset": { "version": "2.0", "generator": concat!("fluidtex ", env!("CARGO_PKG_VERSION")) },
        "scene": 0,
    });
    if triangles.is_empty() {
        json["scenes"] = json!([{}]);
        return Ok(assemble(&json, Vec::new(), &[]));
    }
    // The buffer views in this order: positions, normals, uvs, indices,
    // the colour image.
    let mut buffer = GlbBuffer::default();
    let mut primitive = buffer.primitive(positions, uvs, normals, triangles);
    let mut image: &[u8] = &[];
    if let Some(png) = base_color_png {
        buffer.base_colour(&mut json, png);
        primitive["material"] = json!(0);
        image = png;
    }
    json["scenes"] = json!([{ "nodes": [0] }]);
    json["nodes"] = json!([{ "mesh": 0 }]);
    json["meshes"] = json!([{ "primitives": [primitive] }]);
    let GlbBuffer {
        bin,
        views,
        accessors,
    } = buffer;
    json["accessors"] = Value::Array(accessors);
    json["bufferViews"] = Value::Array(views);
    json["buffers"] = json!([{ "byteLength": bin.len() + image.len().next_multiple_of(4) }]);
    Ok(assemble(&json, bin, image))
}

/// The binary chunk as it is filled, with its buffer views and accessors.
#[derive(Default)]
struct GlbBuffer {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl GlbBuffer {
    /// Appends `data` (padded to 4 bytes) as a new buffer view; its index.
    fn view(&mut self, data: &[u8], target: Option<u32>) -> usize {
        let offset = self.bin.len();
        self.bin.extend_from_slice(data);
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let mut v = json!({ "buffer": 0, "byteOffset": offset, "byteLength": data.len() });
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.views.push(v);
        self.views.len() - 1
    }

    /// A vertex attribute of little-endian floats, `kind` ("VEC3", "VEC2")
    /// per vertex; the accessor's index. `bounds` go with positions, whose
    /// accessor must state them.
    fn floats(
        &mut self,
        values: impl Iterator<Item = f32>,
        count: usize,
        kind: &str,
        bounds: Option<(Vec3, Vec3)>,
    ) -> usize {
        let bytes: Vec<u8> = values.flat_map(f32::to_le_bytes).collect();
        let view = self.view(&bytes, Some(ARRAY_BUFFER));
        let mut accessor =
            json!({ "bufferView": view, "componentType": FLOAT, "count": count, "type": kind });
        if let Some((lo, hi)) = bounds {
            accessor["min"] = json!(lo.to_array());
            accessor["max"] = json!(hi.to_array());
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// The triangle list's attributes and indices, as a glTF primitive.
    fn primitive(
        &mut self,
        positions: &[Vec3],
        uvs: &[Vec2],
        normals: Option<&[Vec3]>,
        triangles: &[[u32; 3]],
    ) -> Value {
        let bounds = positions.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
        let position = self.floats(flat3(positions), positions.len(), "VEC3", Some(bounds));
        let mut attributes = json!({ "POSITION": position });
        if let Some(ns) = normals {
            let normal = self.floats(flat3(ns), ns.len(), "VEC3", None);
            attributes["NORMAL"] = json!(normal);
        }
        let uv = self.floats(
            uvs.iter().flat_map(|t| t.to_array()),
            uvs.len(),
            "VEC2",
            None,
        );
        attributes["TEXCOORD_0"] = json!(uv);
        let idx: Vec<u8> = triangles
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let idx_view = self.view(&idx, Some(ELEMENT_ARRAY_BUFFER));
        self.accessors.push(json!({
            "bufferView": idx_view, "componentType": UNSIGNED_INT, "count": triangles.len() * 3, "type": "SCALAR",
        }));
        let indices = self.accessors.len() - 1;
        json!({ "attributes": attributes, "indices": indices, "mode": 4 })
    }

    /// Adds the view of `png`, which follows the views so far in the
    /// binary chunk (the caller writes its bytes there: [`Glb`]), and the
    /// one material that shows it as base colour.
    fn base_colour(&mut self, json: &mut Value, png: &[u8]) {
        self.views
            .push(json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": png.len() }));
        let img_view = self.views.len() - 1;
        json["images"] = json!([{ "bufferView": img_view, "mimeType": "image/png" }]);
        json["samplers"] = json!([{
            "magFilter": LINEAR, "minFilter": LINEAR, "wrapS": CLAMP_TO_EDGE, "wrapT": CLAMP_TO_EDGE,
        }]);
        json["textures"] = json!([{ "sampler": 0, "source": 0 }]);
        json["materials"] = json!([{
            "name": "atlas",
            "pbrMetallicRoughness": {
                "baseColorTexture": { "index": 0 },
                "metallicFactor": 0.0,
                "roughnessFactor": 1.0,
            },
        }]);
    }
}

/// The coordinates of `v`, one after another.
fn flat3(v: &[Vec3]) -> impl Iterator<Item = f32> + '_ {
    v.iter().flat_map(|p| p.to_array())
}

/// Header + JSON chunk (space-padded) + BIN chunk (the mesh's views, then
/// `image`, zero-padded), the chunk only if it has bytes.
fn assemble<'a>(json: &Value, mesh: Vec<u8>, image: &'a [u8]) -> Glb<'a> {
    let mut text = json.to_string().into_bytes();
    text.resize(text.len().next_multiple_of(4), b' ');
    let bin_len = (mesh.len() + image.len()).next_multiple_of(4);
    let total = 12 + 8 + text.len() + if bin_len == 0 { 0 } else { 8 + bin_len };
    let mut head = Vec::with_capacity(12 + 8 + text.len() + 8);
    for word in [GLB_MAGIC, 2, total as u32, text.len() as u32, CHUNK_JSON] {
        head.extend_from_slice(&word.to_le_bytes());
    }
    head.extend_from_slice(&text);
    if bin_len > 0 {
        head.extend_from_slice(&(bin_len as u32).to_le_bytes());
        head.extend_from_slice(&CHUNK_BIN.to_le_bytes());
    }
    let padding = bin_len - mesh.len() - image.len();
    Glb {
        head,
        mesh,
        image,
        padding,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_are_aligned_and_lengths_add_up() {
        let png = [1u8, 2, 3, 4, 5]; // odd length to exercise padding
        let b = encode_glb(
            &[Vec3::ZERO, Vec3::X, Vec3::Y],
            &[Vec2::ZERO, Vec2::X, Vec2::Y],
            None,
            &[[0, 1, 2]],
            Some(&png),
        )
        .unwrap();
        let word = |k: usize| u32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]) as usize;
        assert_eq!(word(0), GLB_MAGIC as usize);
        assert_eq!(word(4), 2);
        assert_eq!(word(8), b.len());
        let json_len = word(12);
        assert_eq!(json_len % 4, 0);
        let bin_at = 20 + json_len;
        assert_eq!(word(bin_at + 4), CHUNK_BIN as usize);
        assert_eq!(word(bin_at) % 4, 0);
        assert_eq!(bin_at + 8 + word(bin_at), b.len());
        let json: Value = serde_json::from_slice(&b[20..bin_at]).unwrap();
        assert_eq!(json["buffers"][0]["byteLength"], json!(word(bin_at)));
        assert_eq!(json["accessors"][0]["min"], json!([0.0, 0.0, 0.0]));
        assert_eq!(json["accessors"][0]["max"], json!([1.0, 1.0, 0.0]));
    }

    #[test]
    fn the_borrowed_png_lands_in_its_view_whatever_its_padding() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let uvs = [Vec2::ZERO, Vec2::X, Vec2::Y];
        let normals = [Vec3::Z; 3];
        for n in 0..9u8 {
            let png: Vec<u8> = (1..=n).collect();
            for normals in [None, Some(&normals[..])] {
                let glb = layout_glb(&positions, &uvs, normals, &[[0, 1, 2]], Some(&png)).unwrap();
                let b = glb.to_bytes();
                let mut written = Vec::new();
                glb.write_to(&mut written).unwrap();
                assert_eq!(written, b, "write_to and to_bytes agree");
                assert_eq!(glb.len(), b.len());
                let word = |k: usize| u32::from_le_bytes(b[k..k + 4].try_into().unwrap()) as usize;
                let bin_at = 20 + word(12);
                let json: Value = serde_json::from_slice(&b[20..bin_at]).unwrap();
                let view = &json["bufferViews"]
                    [json["images"][0]["bufferView"].as_u64().unwrap() as usize];
                let offset = view["byteOffset"].as_u64().unwrap() as usize;
                assert_eq!(offset % 4, 0);
                assert_eq!(view["byteLength"], json!(png.len()));
                let image_at = bin_at + 8 + offset;
                assert_eq!(&b[image_at..image_at + png.len()], &png[..]);
                // Zero padding to the chunk's end, which is the file's.
                assert!(b[image_at + png.len()..].iter().all(|&z| z == 0));
                assert_eq!(
                    b.len() - (image_at + png.len()),
                    png.len().next_multiple_of(4) - png.len()
                );
                assert_eq!(json["buffers"][0]["byteLength"], json!(word(bin_at)));
            }
        }
    }

    #[test]
    fn empty_mesh_gives_an_empty_scene() {
        let b = encode_glb(&[], &[], None, &[], Some(&[0u8; 8])).unwrap();
        let json: Value = serde_json::from_slice(&b[20..]).unwrap();
        assert_eq!(json["scenes"], json!([{}]));
        assert!(json.get("meshes").is_none());
        assert_eq!(
            b.len(),
            20 + u32::from_le_bytes([b[12], b[13], b[14], b[15]]) as usize
        );
    }
}
