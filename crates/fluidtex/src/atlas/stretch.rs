//! Quality measures of an atlas: conformal stretch, overlap, fill.

use super::{Atlas, rasterize::SUBTEXEL};
use crate::mesh::TriMesh;

/// Quality of an atlas's parameterization.
#[derive(Clone, Debug, PartialEq)]
pub struct StretchStats {
    /// Area-weighted (3-D area) median over triangles of σ₁/σ₂, the ratio
    /// of the singular values of the uv → 3-D map (1 = conformal).
    pub p50: f32,
    /// Area-weighted 95th percentile of σ₁/σ₂.
    pub p95: f32,
    /// Largest σ₁/σ₂ of a triangle with non-zero 3-D area (∞ when such a
    /// triangle has zero uv area).
    pub max: f32,
    /// Texels claimed by more than one triangle, counted once per extra
    /// claim (0 for a valid atlas).
    pub overlapping_texels: u64,
    /// Share of atlas texels inside charts.
    pub fill_ratio: f64,
    /// Triangles left out of the percentiles because their 3-D area is 0.
    pub zero_area_triangles: usize,
}

/// σ₁/σ₂ of the map from the flat triangle `uv` to the 3-D triangle `q`
/// (singular values as in Sorkine et al. 2002; docs/design.md, *Triangle
/// distortion*).
pub(crate) fn conformal_ratio(uv: [[f64; 2]; 3], q: [[f64; 3]; 3]) -> f64 {
    let [(s1, t1), (s2, t2), (s3, t3)] = uv.map(|p| (p[0], p[1]));
    let a2 = (s2 - s1) * (t3 - t1) - (s3 - s1) * (t2 - t1);
    if a2 == 0.0 {
        return f64::INFINITY;
    }
    let mut ss = [0.0; 3];
    let mut st = [0.0; 3];
    for k in 0..3 {
        ss[k] = ((t2 - t3) * q[0][k] + (t3 - t1) * q[1][k] + (t1 - t2) * q[2][k]) / a2;
        st[k] = ((s3 - s2) * q[0][k] + (s1 - s3) * q[1][k] + (s2 - s1) * q[2][k]) / a2;
    }
    let dot = |u: &[f64; 3], v: &[f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let (a, b, c) = (dot(&ss, &ss), dot(&ss, &st), dot(&st, &st));
    let root = ((a - c) * (a - c) + 4.0 * b * b).sqrt();
    let big = (0.5 * (a + c + root)).sqrt();
    let small = (0.5 * (a + c - root).max(0.0)).sqrt();
    if small > 0.0 {
        big / small
    } else {
        f64::INFINITY
    }
}

pub(crate) fn stretch_stats(atlas: &Atlas, mesh: &TriMesh) -> StretchStats {
    let mut samples: Vec<(f64, f64)> = Vec::with_capacity(mesh.triangles.len());
    let mut zero_area = 0;
    let mut max: f64 = 1.0;
    for (i, tri) in mesh.triangles.iter().enumerate() {
        let q = tri.map(|v| mesh.positions[v as usize].as_dvec3());
        let w = 0.5 * (q[1] - q[0]).cross(q[2] - q[0]).length();
        if w <= 0.0 {
            zero_area += 1;
            continue;
        }
        let uv = atlas.uv_mesh.triangles[i].map(|v| {
            let f = atlas.fixed[v as usize];
            [f[0] as f64 / SUBTEXEL as f64, f[1] as f64 / SUBTEXEL as f64]
        });
        let r = conformal_ratio(uv, q.map(|p| p.to_array()));
        max = max.max(r);
        samples.push((r, w));
    }
    samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = samples.iter().map(|s| s.1).sum();
    let quantile = |p: f64| -> f32 {
        let mut acc = 0.0;
        for &(r, w) in &samples {
            acc += w;
            if acc >= p * total {
                return r as f32;
            }
        }
        samples.last().map_or(1.0, |s| s.0 as f32)
    };
    StretchStats {
        p50: quantile(0.5),
        p95: quantile(0.95),
        max: max as f32,
        overlapping_texels: overlapping_texels(atlas),
        fill_ratio: atlas.texels_in_charts() as f64 / (atlas.width as f64 * atlas.height as f64),
        zero_area_triangles: zero_area,
    }
}

/// Texels covered by two or more spans (each triangle is rasterized on its
/// own, so this is an independent check of the fill rule and the packing).
pub(crate) fn overlapping_texels(atlas: &Atlas) -> u64 {
    let mut total = 0u64;
    for band in atlas.bands() {
        let mut s: Vec<(u32, u32, u32)> = band.spans.iter().map(|s| (s.y, s.x0, s.x1)).collect();
        s.sort_unstable();
        let mut row = u32::MAX;
        let mut end = 0u32;
        for (y, x0, x1) in s {
            if y != row {
                row = y;
                end = 0;
            }
            if x0 < end {
                total += (x1.min(end) - x0) as u64;
            }
            end = end.max(x1);
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conformal_ratio_of_known_maps() {
        let uv = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        // Rotation + uniform scale: conformal.
        let r = conformal_ratio(uv, [[1.0, 1.0, 1.0], [1.0, 3.0, 1.0], [-1.0, 1.0, 1.0]]);
        assert!((r - 1.0).abs() < 1e-12, "{r}");
        // 3:1 stretch along x.
        let r = conformal_ratio(uv, [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
        assert!((r - 3.0).abs() < 1e-12, "{r}");
        // Mirrored uv (negative area) gives the same ratio.
        let mirrored = [[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]];
        let r = conformal_ratio(
            mirrored,
            [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [3.0, 0.0, 0.0]],
        );
        assert!((r - 3.0).abs() < 1e-12, "{r}");
        assert_eq!(
            conformal_ratio([[0.0, 0.0]; 3], [[0.0; 3]; 3]),
            f64::INFINITY
        );
    }
}
