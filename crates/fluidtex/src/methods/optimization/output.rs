//! From points to the atlas: every chart texel knows its fluid triangle and
//! barycentrics ([`crate::atlas::Atlas::span_barycentrics`]), which name
//! its cell of the finest lattice; the texel gets the linear interpolation
//! of that cell's three point values, all channels alike.

use rayon::prelude::*;

use super::lattice::Lattice;
use crate::atlas::Atlas;
use crate::exemplar::Exemplar;
use crate::texture::Texture;

/// The atlas channels (one texture per exemplar channel, colour first) of
/// the per-point `values` (`k` floats each). Texels outside charts are 0.
pub fn fill(
    atlas: &Atlas,
    lattice: &Lattice,
    values: &[f32],
    k: usize,
    exemplar: &Exemplar,
) -> Vec<Texture> {
    let w = atlas.width as usize;
    let h = atlas.height as usize;
    let mut buf = vec![0.0f32; w * h * k];
    let bands = atlas.bands();
    if let Some(first) = bands.first() {
        let rows = (first.y1 - first.y0) as usize;
        buf.par_chunks_mut(rows * w * k)
            .zip(bands.par_iter())
            .for_each(|(chunk, band)| {
                let mut tmp = vec![0.0f32; k];
                for span in &band.spans {
                    let row = (span.y - band.y0) as usize * w;
                    for (x, bary) in atlas.span_barycentrics(span) {
                        if (span.triangle as usize) >= lattice.triangles.len() {
                            continue;
                        }
                        lattice.interpolate(values, k, span.triangle as usize, bary, &mut tmp);
                        let at = (row + x as usize) * k;
                        chunk[at..at + k].copy_from_slice(&tmp);
                    }
                }
            });
    }
    let mut layout = vec![exemplar.colour.channels];
    layout.extend(exemplar.channels.iter().map(|c| c.texture.channels));
    let mut offset = 0;
    layout
        .into_iter()
        .map(|c| {
            let data: Vec<f32> = buf
                .par_chunks(k)
                .flat_map_iter(|t| t[offset..offset + c].iter().copied())
                .collect();
            offset += c;
            Texture {
                width: atlas.width,
                height: atlas.height,
                channels: c,
                data,
            }
        })
        .collect()
}

/// Per texel, the exemplar mip level the synthesis showed (`lod` inside
/// charts, NaN outside): the points carry the exemplar resampled to their
/// spacing, so contrast is judged against the exemplar at that level.
pub fn lod_map(atlas: &Atlas, lod: f32) -> Vec<f32> {
    atlas
        .triangle_map()
        .into_par_iter()
        .map(|t| if t == u32::MAX { f32::NAN } else { lod })
        .collect()
}
