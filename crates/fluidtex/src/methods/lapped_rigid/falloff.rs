//! Patch opacity of the 2016 method: the alpha falloff with the angle
//! between a receiver vertex's normal and the patch frame's normal (Gagnon,
//! Dagenais, Paquette 2016, Sec. 3.2.1), times the exemplar's patch mask
//! (Sec. 3.3, Algorithm 1).
//!
//! Why a falloff: the uv of a receiver is an orthographic projection onto
//! the frame's plane, so the texture is stretched by 1/cos θ where the
//! surface turns away from the frame. Vertices past ψ_{α=1} fade and those
//! past ψ_{α=0} are transparent, which bounds the visible stretch.
//!
//! Why a mask: a patch drawn opaque up to its receiver boundary would show
//! the polygonal outline of the receiver set as a seam. The mask gives
//! every patch a soft, irregular border; the paper takes it from the user,
//! and so does `--mask IMG`; without one it is derived from the feature map
//! so the border follows the exemplar's features (pebbles end at their own
//! outline instead of being cut).

use std::path::Path;

use glam::Vec2;

use crate::exemplar::feature::FeatureSampler;
use crate::texture::{Texture, Wrap};

/// Where the alpha falloff's angle is taken.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FalloffAt {
    /// At each texel, from its interpolated vertex normal: a patch is
    /// opaque at its own tracker (θ = 0 there), however coarse the mesh.
    #[default]
    Texel,
    /// The paper's (Sec. 3.2.1): per receiver vertex, from the vertex
    /// normal, and the vertices' alphas interpolated across each triangle.
    Vertex,
}

crate::named!(FalloffAt {
    Texel => "texel",
    Vertex => "vertex",
});

/// The alpha of a receiver vertex whose normal makes angle `theta`
/// (radians) with the frame's normal: 1 up to `opaque`, 0 from
/// `transparent` on, linear between (`opaque` < `transparent`).
#[inline]
pub fn falloff(theta: f32, opaque: f32, transparent: f32) -> f32 {
    if theta <= opaque {
        1.0
    } else if theta >= transparent {
        0.0
    } else {
        (transparent - theta) / (transparent - opaque)
    }
}

/// The angle (radians, in \[0, π]) between two unit vectors, robust near 0
/// and π (atan2 of the cross and dot products, not acos of the dot).
#[inline]
pub fn angle_between(a: glam::Vec3, b: glam::Vec3) -> f32 {
    a.cross(b).length().atan2(a.dot(b))
}

/// The soft patch mask M(u, v) of Algorithm 1, in patch uv (the frame
/// centre P is at (0.5, 0.5)).
#[derive(Clone, Debug)]
pub enum PatchMask {
    /// A user image covering the exemplar's \[0, 1]²: its luminance, 0
    /// outside the square.
    Image(Texture),
    /// Derived from the feature map F (see [`PatchMask::derived_value`]).
    Derived {
        /// uv distance from the centre where the radial profile reaches 0:
        /// r / S, the patch's own footprint.
        reach: f32,
        /// How much the features move the border \[0.2, the default of
        /// `lapped_rigid.mask_feature_weight`].
        feature_weight: f32,
        /// Width of the soft border in profile units \[0.2, the default of
        /// `lapped_rigid.mask_softness`].
        softness: f32,
    },
}

impl PatchMask {
    /// Reads a mask image (PNG, JPEG or EXR; luminance, alpha ignored).
    /// The error names the file.
    pub fn from_file(path: &Path) -> Result<PatchMask, String> {
        let decoded = crate::io::image_read::read_image(path).map_err(|e| e.to_string())?;
        let t = decoded.texture;
        let data = crate::exemplar::feature::luminance(&t);
        if let Some(k) = data.iter().position(|v| !v.is_finite()) {
            return Err(format!(
                "{}: mask texel {k} is not a finite number",
                path.display()
            ));
        }
        let data = data.into_iter().map(|v| v.clamp(0.0, 1.0)).collect();
        Texture::from_data(t.width, t.height, 1, data)
            .map(PatchMask::Image)
            .map_err(|e| format!("{}: {e}", path.display()))
    }

    /// The derived mask at uv: with D = max(0, 1 − |uv − (½, ½)| / reach)
    /// and F the feature value, `smoothstep(0, softness, D − w (1 − F))`.
    /// At the centre D = 1, so the mask is 1 whenever w ≤ 1 − softness;
    /// at the footprint's edge D = 0 and the mask is 0; in between, texels
    /// of strong features (F near 1) stay opaque further out than the
    /// background, so the border follows the features.
    #[inline]
    pub fn derived_value(
        uv: Vec2,
        feature: f32,
        reach: f32,
        feature_weight: f32,
        softness: f32,
    ) -> f32 {
        let d = (1.0 - uv.distance(Vec2::splat(0.5)) / reach).max(0.0);
        let s = d - feature_weight * (1.0 - feature);
        smoothstep(softness, s)
    }

    /// M at `uv`; `feature` samples the exemplar's feature map.
    #[inline]
    pub fn sample(&self, uv: Vec2, feature: &FeatureSampler<'_>) -> f32 {
        match self {
            PatchMask::Image(t) => {
                if !(0.0..=1.0).contains(&uv.x) || !(0.0..=1.0).contains(&uv.y) {
                    return 0.0;
                }
                let mut out = [0.0];
                t.sample_bilinear(uv.x, uv.y, Wrap::Clamp, &mut out);
                out[0]
            }
            PatchMask::Derived {
                reach,
                feature_weight,
                softness,
            } => {
                // Outside the footprint D = 0 and the mask is 0 whatever F.
                if uv.distance_squared(Vec2::splat(0.5)) >= reach * reach {
                    return 0.0;
                }
                let f = feature.sample(uv.x, uv.y);
                PatchMask::derived_value(uv, f, *reach, *feature_weight, *softness)
            }
        }
    }
}

/// 0 below 0, 1 above `width`, the cubic Hermite step between.
#[inline]
fn smoothstep(width: f32, x: f32) -> f32 {
    if width <= 0.0 {
        return if x > 0.0 { 1.0 } else { 0.0 };
    }
    let t = (x / width).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A feature map stand-in used where no exemplar is at hand (tests).
#[cfg(test)]
pub(crate) fn flat_feature(value: f32) -> crate::exemplar::FeatureMap {
    crate::exemplar::FeatureMap {
        map: Texture::filled(4, 4, 1, value),
        origin: crate::exemplar::FeatureOrigin::Builtin,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn falloff_equals_its_formula_at_given_angles() {
        let (a1, a0) = (30f32.to_radians(), 60f32.to_radians());
        for (deg, want) in [
            (0.0f32, 1.0f32),
            (29.9, 1.0),
            (30.0, 1.0),
            (37.5, 0.75),
            (45.0, 0.5),
            (52.5, 0.25),
            (60.0, 0.0),
            (90.0, 0.0),
            (129.0, 0.0),
        ] {
            let got = falloff(deg.to_radians(), a1, a0);
            assert!((got - want).abs() < 1e-5, "{deg}°: {got} != {want}");
        }
    }

    #[test]
    fn angle_between_is_exact_at_known_angles() {
        use glam::Vec3;
        for deg in [0.0f32, 1e-3, 10.0, 90.0, 130.0, 179.9] {
            let r = deg.to_radians();
            let b = Vec3::new(r.sin(), 0.0, r.cos());
            let got = angle_between(Vec3::Z, b).to_degrees();
            assert!((got - deg).abs() < 1e-3, "{deg} vs {got}");
        }
    }

    #[test]
    fn the_derived_mask_is_opaque_at_the_centre_and_zero_at_the_footprint() {
        let feature = flat_feature(0.0);
        let s = feature.sampler();
        let mask = PatchMask::Derived {
            reach: 0.3,
            feature_weight: 0.5,
            softness: 0.25,
        };
        assert_eq!(mask.sample(Vec2::splat(0.5), &s), 1.0);
        assert_eq!(mask.sample(Vec2::new(0.5 + 0.3, 0.5), &s), 0.0);
        // With F = 0 the profile D − 0.5 crosses 0 at half the reach.
        assert!(mask.sample(Vec2::new(0.5 + 0.15, 0.5), &s) < 1e-6);
        assert_eq!(mask.sample(Vec2::new(0.5 + 0.2, 0.5), &s), 0.0);
        let inside = mask.sample(Vec2::new(0.5 + 0.05, 0.5), &s);
        assert!(inside > 0.99, "{inside}");
        // A strong feature keeps the same texel opaque further out.
        let strong = flat_feature(1.0);
        let at = Vec2::new(0.5 + 0.15, 0.5);
        assert!(mask.sample(at, &strong.sampler()) > 0.99);
    }
}
