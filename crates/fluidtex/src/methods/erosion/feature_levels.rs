//! The feature map at several resolutions, for the erosion test.
//!
//! The erosion test compares F_m at a texel's patch uv against 1 − w. When
//! one atlas texel covers many feature-map texels (a small atlas, a large
//! exemplar, or a patch compressed by the flow), point samples of F_m are
//! noise at the texel scale: the erosion border dissolves into speckle that
//! re-rolls every frame as the patch moves by a fraction of a texel, and
//! every speckle that flips is a texel changing its source patch. Sampling
//! F_m from a level whose texels match the atlas texel's footprint keeps
//! the border a smooth curve that moves with the patch.
//!
//! Levels are the exemplar's own pyramid ([`crate::exemplar::mip_levels`]),
//! each kept as a [`FeatureMap`] sampled with the same lattice as level 0,
//! so that level 0 gives exactly the paper's bilinear F_m; sampling is
//! bilinear within a level and linear between levels.

use crate::exemplar::feature::{FeatureMap, FeatureSampler};
use crate::exemplar::mip_levels;

/// The feature map and its successive 2×2 reductions down to one texel
/// along the shorter side.
pub struct FeatureLevels {
    levels: Vec<FeatureMap>,
}

impl FeatureLevels {
    pub fn new(map: &FeatureMap) -> FeatureLevels {
        let mut levels = Vec::new();
        for texture in mip_levels(&map.map) {
            // Averages of values in [0, 1] stay in [0, 1]; should a check
            // still refuse, the coarser levels are simply not used.
            match FeatureMap::new(texture, map.origin.clone(), "feature map level") {
                Ok(level) => levels.push(level),
                Err(_) => break,
            }
        }
        if levels.is_empty() {
            levels.push(map.clone());
        }
        FeatureLevels { levels }
    }

    /// Number of levels (1 = the map alone).
    pub fn len(&self) -> usize {
        self.levels.len()
    }

    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }

    /// Width of level 0 in texels.
    pub fn width(&self) -> u32 {
        self.levels.first().map_or(1, |l| l.map.width)
    }

    /// Samplers of every level, set up once per frame.
    pub fn samplers(&self) -> FeatureLevelSampler<'_> {
        FeatureLevelSampler {
            levels: self.levels.iter().map(FeatureMap::sampler).collect(),
        }
    }
}

/// Trilinear sampling of [`FeatureLevels`].
pub struct FeatureLevelSampler<'a> {
    levels: Vec<FeatureSampler<'a>>,
}

impl FeatureLevelSampler<'_> {
    /// F_m at (u, v) for a footprint of 2^`lod` level-0 texels: level 0
    /// (bilinear, exactly the map) for lod ≤ 0 or NaN.
    #[inline]
    pub fn sample(&self, u: f32, v: f32, lod: f32) -> f32 {
        let top = self.levels.len().saturating_sub(1);
        if lod.is_nan() || lod <= 0.0 || top == 0 {
            return self.levels.first().map_or(0.0, |s| s.sample(u, v));
        }
        let lod = lod.min(top as f32);
        // lod > 0 here, so truncation is the floor (and no libm call).
        let l = (lod as usize).min(top);
        let f = lod - l as f32;
        let a = self.levels[l].sample(u, v);
        if f == 0.0 || l == top {
            return a;
        }
        a + (self.levels[l + 1].sample(u, v) - a) * f
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exemplar::feature::FeatureOrigin;
    use crate::texture::Texture;

    fn checker(n: u32) -> FeatureMap {
        let data = (0..n * n).map(|i| ((i % n + i / n) % 2) as f32).collect();
        let t = Texture {
            width: n,
            height: n,
            channels: 1,
            data,
        };
        FeatureMap::new(t, FeatureOrigin::Builtin, "checker").expect("valid map")
    }

    #[test]
    fn levels_halve_down_to_one_texel_and_keep_the_mean() {
        let map = checker(16);
        let levels = FeatureLevels::new(&map);
        assert_eq!(levels.len(), 5); // 16, 8, 4, 2, 1
        for l in &levels.levels {
            let mean: f32 = l.map.data.iter().sum::<f32>() / l.map.data.len() as f32;
            assert!((mean - 0.5).abs() < 1e-6);
        }
        // A one-texel checker averages to a flat 0.5 from level 1 on.
        assert!(
            levels.levels[1]
                .map
                .data
                .iter()
                .all(|&v| (v - 0.5).abs() < 1e-6)
        );
    }

    #[test]
    fn lod_zero_is_the_map_itself_and_coarse_lods_are_flat() {
        let map = checker(16);
        let levels = FeatureLevels::new(&map);
        let s = levels.samplers();
        for k in 0..50 {
            let (u, v) = ((k as f32 * 0.137).fract(), (k as f32 * 0.291).fract());
            assert_eq!(s.sample(u, v, 0.0), map.sample(u, v));
            assert_eq!(s.sample(u, v, -3.0), map.sample(u, v));
            assert!((s.sample(u, v, 2.0) - 0.5).abs() < 1e-6);
        }
        // Control: level 0 of a checker at texel centres is 0 or 1, not 0.5.
        assert_eq!(s.sample(0.5 / 16.0, 0.5 / 16.0, 0.0), 0.0);
        assert_eq!(s.sample(1.5 / 16.0, 0.5 / 16.0, 0.0), 1.0);
    }
}
