//! Renders of a frame at k × k samples per pixel, box-filtered down to the
//! evaluation's size: the lit view the image metrics read, without the
//! aliasing of one sample per pixel.

use super::PreparedFrame;
use crate::render::{self, Camera};
use crate::texture::Texture;

/// The G-buffer of `frame` seen by `camera` at `k` samples per pixel side
/// (the same pinhole: pixel (x, y) of the fine image lies in pixel
/// (x / k, y / k) of the coarse one), and that camera.
pub(super) fn fine_gbuffer(
    frame: &PreparedFrame,
    camera: &Camera,
    k: u32,
) -> (render::GBuffer, Camera) {
    let fine = Camera {
        width: camera.width * k,
        height: camera.height * k,
        ..*camera
    };
    let mesh = &frame.geometry.atlas.uv_mesh;
    (
        render::rasterize(&mesh.positions, &mesh.triangles, &fine),
        fine,
    )
}

/// Mean of each `k`×`k` block (a box filter and decimation).
pub(super) fn box_filter(image: &Texture, k: u32) -> Texture {
    let (w, h, c) = (image.width / k, image.height / k, image.channels);
    let mut out = Texture::filled(w, h, c, 0.0);
    let norm = 1.0 / (k * k) as f32;
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f32; 4];
            for sy in 0..k {
                for sx in 0..k {
                    let t = image.texel(x * k + sx, y * k + sy);
                    for (s, v) in sum.iter_mut().zip(t) {
                        *s += v;
                    }
                }
            }
            for (o, s) in out.texel_mut(x, y).iter_mut().zip(sum) {
                *o = s * norm;
            }
        }
    }
    out
}

/// A lit render of the colour atlas for pictures (antialiased like the
/// metric renders).
pub(super) fn lit_render(
    frame: &PreparedFrame,
    camera: &Camera,
    colour: &Texture,
    k: u32,
) -> Texture {
    let mesh = &frame.geometry.atlas.uv_mesh;
    let normals = frame.geometry.uv_mesh_normals();
    let background = [0.12, 0.12, 0.14];
    if k > 1 {
        let (gb, fine) = fine_gbuffer(frame, camera, k);
        let image = render::shade_lit(
            &gb,
            &mesh.triangles,
            &normals,
            &mesh.uvs,
            colour,
            &fine,
            background,
        );
        box_filter(&image, k)
    } else {
        render::shade_lit(
            &frame.gbuffer,
            &mesh.triangles,
            &normals,
            &mesh.uvs,
            colour,
            camera,
            background,
        )
    }
}
