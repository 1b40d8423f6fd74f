//! Turning a [`GBuffer`] into pictures: unlit texture lookups (for metrics)
//! and a lit preview (for people).
//!
//! Both return 3-channel images: a grey texture is replicated into RGB and
//! an alpha channel is ignored. Per-vertex attributes are interpolated with
//! the G-buffer's perspective-correct barycentrics; a pixel whose triangle
//! or attribute index is out of range shows the background.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::camera::Camera;
use super::raster::{BACKGROUND, GBuffer};
use crate::texture::{Texture, Wrap};

/// Share of the lit preview's light that does not depend on orientation.
const AMBIENT: f32 = 0.25;

/// Unlit texture lookup through per-vertex `uvs` (bilinear, clamped at the
/// texture's edges); `background` where nothing was hit.
pub fn shade_textured(
    gb: &GBuffer,
    triangles: &[[u32; 3]],
    uvs: &[Vec2],
    texture: &Texture,
    background: [f32; 3],
) -> Texture {
    shade(gb, background, |i, _, _| {
        let uv = interpolate(gb, i, triangles, uvs)?;
        Some(lookup(texture, uv))
    })
}

/// Lit preview: the texture times a headlight Lambert term (light from the
/// eye, two-sided, so open sheets seen from behind are lit too) plus
/// ambient. `normals` are per vertex and need not be unit length.
pub fn shade_lit(
    gb: &GBuffer,
    triangles: &[[u32; 3]],
    normals: &[Vec3],
    uvs: &[Vec2],
    texture: &Texture,
    camera: &Camera,
    background: [f32; 3],
) -> Texture {
    let Some(view) = camera.view() else {
        return Texture::filled(gb.width, gb.height, 3, 0.0);
    };
    shade(gb, background, |i, x, y| {
        let uv = interpolate(gb, i, triangles, uvs)?;
        let n = interpolate(gb, i, triangles, normals)?.normalize_or_zero();
        let ray = view.ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
        // Degenerate normals get full light rather than a black hole.
        let lambert = if n == Vec3::ZERO {
            1.0
        } else {
            n.dot(ray).abs()
        };
        let light = AMBIENT + (1.0 - AMBIENT) * lambert;
        Some(lookup(texture, uv).map(|c| c * light))
    })
}

/// Runs `colour(pixel index, x, y)` on every hit pixel, in parallel by rows.
fn shade(
    gb: &GBuffer,
    background: [f32; 3],
    colour: impl Fn(usize, u32, u32) -> Option<[f32; 3]> + Sync,
) -> Texture {
    let mut out = Texture::filled(gb.width, gb.height, 3, 0.0);
    let w = gb.width as usize;
    if w == 0 {
        return out;
    }
    out.data
        .par_chunks_mut(3 * w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.chunks_exact_mut(3).enumerate() {
                let i = y * w + x;
                let hit = gb.triangle.get(i).is_some_and(|&t| t != BACKGROUND);
                let c = if hit {
                    colour(i, x as u32, y as u32)
                } else {
                    None
                };
                px.copy_from_slice(&c.unwrap_or(background));
            }
        });
    out
}

/// A per-vertex attribute at pixel `i`, or `None` if any index is invalid.
fn interpolate<T>(gb: &GBuffer, i: usize, triangles: &[[u32; 3]], values: &[T]) -> Option<T>
where
    T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    let tri = triangles.get(*gb.triangle.get(i)? as usize)?;
    let b = gb.bary.get(i)?;
    let v = |k: usize| values.get(tri[k] as usize).copied();
    Some(v(0)? * b[0] + v(1)? * b[1] + v(2)? * b[2])
}

fn lookup(texture: &Texture, uv: Vec2) -> [f32; 3] {
    let mut buf = [0.0f32; 4];
    if texture.texel_count() == 0 {
        return [0.0; 3];
    }
    texture.sample_bilinear(uv.x, uv.y, Wrap::Clamp, &mut buf);
    to_rgb(&buf[..texture.channels.min(4)])
}

pub(crate) fn to_rgb(texel: &[f32]) -> [f32; 3] {
    match texel {
        [r, g, b, ..] => [*r, *g, *b],
        [g, ..] => [*g; 3],
        [] => [0.0; 3],
    }
}
