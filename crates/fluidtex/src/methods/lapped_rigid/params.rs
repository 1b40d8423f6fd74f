//! The parameters of `--method lapped-rigid` (config section
//! `[lapped_rigid]`, flags `--rigid-...`): their declaration with defaults
//! and docs, and their checks.

use std::path::PathBuf;

use super::{SeedTexel, composite, distribution, falloff};
use crate::methods::lapped::{PatchScale, ScaleKeys};
use crate::methods::{MethodError, check_ranges};

crate::methods::params::params! {
    /// Parameters of the 2016 method. Every field is also a config key
    /// (`\[lapped_rigid]`) and a `--rigid-...` flag.
    pub struct LappedRigidParams {
        /// Patch size r in world units (Sec. 3.1.3: the Poisson-disk radius and
        /// the receiver distance of Sec. 3.2.1). `None`: as erosion's default,
        /// `radius_fraction` × the first frame's bounding-box diagonal, at least
        /// `radius_edges` median edge lengths.
        pub radius: Option<f32> = None
            => "rigid-radius" : "lapped-rigid: patch size r in world units [bbox diagonal / 25]",
        /// Default r as a fraction of the first frame's bounding-box diagonal \[1/25].
        pub radius_fraction: f32 = 1.0 / 25.0
            => "rigid-radius-fraction" : "lapped-rigid: default r as a fraction of the bbox diagonal [0.04]",
        /// The default r is never below this many median edge lengths \[4].
        pub radius_edges: f32 = 4.0
            => "rigid-radius-edges" : "lapped-rigid: default r is never below this many median edge lengths [4]",
        /// World size S covered by the exemplar's \[0,1]² (Sec. 3.2.2, "based on
        /// the patch size"). `None`: `exemplar_scale` × r.
        pub exemplar_size: Option<f32> = None
            => "rigid-exemplar-size" : "lapped-rigid: world size covered by the exemplar [exemplar_scale × r]",
        /// Default S as a multiple of r \[2.6], erosion's convention, so both
        /// methods show the exemplar at the same scale.
        pub exemplar_scale: f32 = 2.6
            => "rigid-exemplar-scale" : "lapped-rigid: default exemplar size as a multiple of r [2.6]",
        /// φ_max in degrees \[130] (Sec. 3.2.1, the paper's value): receivers
        /// whose normal turns farther from the frame normal are rejected.
        pub phi_max: f32 = 130.0
            => "rigid-phi-max" : "lapped-rigid: φ_max, receivers turning farther from the frame normal are rejected, degrees [130]",
        /// ψ_{α=1} in degrees \[30] (Sec. 3.2.1; the paper gives no value):
        /// receiver points whose (interpolated vertex) normal is closer to the
        /// frame normal are opaque. At 30° the
        /// orthographic stretch 1/cos θ is at most 1.15.
        pub alpha_opaque: f32 = 30.0
            => "rigid-alpha-opaque" : "lapped-rigid: ψ_{α=1}, receiver vertices within this angle are opaque, degrees [30]",
        /// ψ_{α=0} in degrees \[60] (Sec. 3.2.1; the paper gives no value):
        /// vertices farther are transparent (stretch 2 at 60°). Requires
        /// ψ_{α=1} < ψ_{α=0} < φ_max.
        pub alpha_transparent: f32 = 60.0
            => "rigid-alpha-transparent" : "lapped-rigid: ψ_{α=0}, receiver vertices beyond this angle are transparent, degrees [60]",
        /// Where the falloff's angle is taken \[texel]: at each texel from its
        /// interpolated normal, or per receiver vertex with the alphas
        /// interpolated (`vertex`, Sec. 3.2.1). See [`falloff::FalloffAt`].
        /// Left out of the settings at its default.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub falloff_at: falloff::FalloffAt = falloff::FalloffAt::Texel
            => "rigid-falloff-at" : "lapped-rigid: the alpha falloff's angle per texel from its interpolated normal (texel) or per receiver vertex, alphas interpolated (vertex, the paper) [texel]",
        /// A tracker farther than this fraction of r from the next surface after
        /// advection has left it and is deleted \[1/4] (erosion's removal
        /// distance); 0: never, the tracker goes to the closest surface point
        /// however far (the paper has no such rule).
        pub far_fraction: f32 = 0.25
            => "rigid-far-fraction" : "lapped-rigid: trackers farther than this × r from the next surface are deleted (0: never, the paper) [0.25]",
        /// RK4 steps per frame \[1] (Sec. 3.1.1).
        pub substeps: u32 = 1
            => "rigid-substeps" : "lapped-rigid: RK4 substeps per frame [1]",
        /// Poisson disks of the first frame whose normals have a smaller dot
        /// product do not block each other \[0.9], so both sides of a thin sheet
        /// get trackers.
        pub normal_dot: f32 = 0.9
            => "rigid-normal-dot" : "lapped-rigid: first-frame Poisson disks with normals less aligned do not block [0.9]",
        /// Random tangent direction for each new tracker \[true] (seeded).
        pub random_rotation: bool = true
            => "rigid-no-rotation" = "false" : "lapped-rigid: no random tangent direction for new trackers",
        /// A texel whose composite α is below this is uncovered and seeds a new
        /// tracker \[0.99] (Sec. 3.3: "no opaque patch"; 1 would demand exact
        /// opacity from soft masks).
        pub coverage: f32 = 0.99
            => "rigid-coverage" : "lapped-rigid: composite alpha below which a texel seeds a tracker [0.99]",
        /// Contributions below this are dropped [1/255 ≈ 0.0039, invisible in
        /// 8 bits]; a patch left with none is unused and deleted (Sec. 3.1.3).
        /// Dropping rather than merely not counting them keeps deletion exact:
        /// removing an unused patch changes no texel.
        pub keep_weight: f32 = 1.0 / 255.0
            => "rigid-keep-weight" : "lapped-rigid: contributions below this are dropped, a patch with none is deleted [1/255]",
        /// Patch mask image (Algorithm 1's Mask; luminance over the exemplar's
        /// \[0,1]², 0 outside). `None`: derived from the feature map.
        pub mask: Option<PathBuf> = None
            => "mask" : "lapped-rigid: patch mask image (grey, covers the exemplar square); default: from the feature map",
        /// Derived mask: how far the feature map moves the border \[0.05]
        /// (see [`falloff::PatchMask::derived_value`]). The feature map is
        /// fine-grained, so on a slow liquid, where a patch turns a little
        /// each frame, a large weight flips which patch is on top from
        /// frame to frame: at 0.2 a tenth of a viscous drop's points
        /// changed patch per frame, 4 points over the carried texture of
        /// `advect`; at 0.05 it is within 2 points on every frame, and the
        /// borders still follow the strongest features.
        pub mask_feature_weight: f32 = 0.05
            => "rigid-mask-feature-weight" : "lapped-rigid: derived mask, how far features move the patch border [0.05]",
        /// Derived mask: width of the soft border \[0.2] in units of the radial
        /// profile (0 at the footprint r/S, 1 at the centre).
        pub mask_softness: f32 = 0.2
            => "rigid-mask-softness" : "lapped-rigid: derived mask, width of the soft border [0.2]",
        /// Sink test: every frame corner must move toward the centre faster than
        /// this many r per second \[0.25] (Sec. 3.1.3).
        pub sink_speed: f32 = 0.25
            => "rigid-sink-speed" : "lapped-rigid: sink test, corners must move inward faster than this × r per second [0.25]",
        /// Sink fade speed \[1]: 1 fades a sink out in the time the flow takes
        /// to carry its corners to its centre (Sec. 3.1.3: a rate proportional
        /// to the inward speed).
        pub sink_fade_rate: f32 = 1.0
            => "rigid-sink-fade-rate" : "lapped-rigid: sink fade speed (1: gone when the corners would reach the centre) [1]",
        /// Where new trackers go \[first] (see [`distribution::Placement`]).
        /// Left out of the settings at its default.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub placement: distribution::Placement = distribution::Placement::First
            => "rigid-placement" : "lapped-rigid: new trackers at the first uncovered texel (first) or at random uncovered texels (random, the paper) [first]",
        /// What becomes of a seed texel its own new patch leaves short
        /// \[forced] (see [`distribution::cover`]). Left out of the settings at
        /// its default.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub seed_texel: SeedTexel = SeedTexel::Forced
            => "rigid-seed-texel" : "lapped-rigid: a seed texel its patch leaves short is closed anyway (forced) or left to later trackers (paper) [forced]",
        /// How a layer hides what lies beneath \[over] (Algorithm 1; see
        /// [`composite::Composite`]). Left out of the settings at its
        /// default.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub composite: composite::Composite = composite::Composite::Over
            => "rigid-composite" : "lapped-rigid: a layer hides what lies beneath by its falloff × mask (over) or, as Algorithm 1 is printed, by its falloff alone (paper) [over]",
    }
}

impl LappedRigidParams {
    /// Checks every field's range and ψ_{α=1} < ψ_{α=0} < φ_max.
    pub fn validate(&self) -> Result<(), MethodError> {
        self.scale().validate(&ScaleKeys {
            radius: "lapped_rigid.radius",
            radius_fraction: "lapped_rigid.radius_fraction",
            radius_edges: "lapped_rigid.radius_edges",
            exemplar_size: "lapped_rigid.exemplar_size",
            exemplar_scale: "lapped_rigid.exemplar_scale",
        })?;
        self.validate_angles()?;
        if self.far_fraction != 0.0 {
            check_ranges(&[(
                "lapped_rigid.far_fraction",
                self.far_fraction,
                1e-3,
                10.0,
                "0 or [0.001, 10]",
            )])?;
        }
        check_ranges(&[
            (
                "lapped_rigid.substeps",
                self.substeps as f32,
                1.0,
                64.0,
                "1..=64",
            ),
            (
                "lapped_rigid.normal_dot",
                self.normal_dot,
                -1.0,
                1.0,
                "[-1, 1]",
            ),
            (
                "lapped_rigid.coverage",
                self.coverage,
                0.01,
                1.0,
                "[0.01, 1]",
            ),
            (
                "lapped_rigid.keep_weight",
                self.keep_weight,
                0.0,
                1.0,
                "[0, 1]",
            ),
        ])?;
        self.validate_mask()?;
        check_ranges(&[
            (
                "lapped_rigid.sink_speed",
                self.sink_speed,
                0.0,
                1e6,
                "[0, 1e6] r per second",
            ),
            (
                "lapped_rigid.sink_fade_rate",
                self.sink_fade_rate,
                1e-3,
                1e6,
                "[0.001, 1e6]",
            ),
        ])
    }

    /// The scale settings r, S and the rules that default them.
    pub fn scale(&self) -> PatchScale {
        PatchScale {
            radius: self.radius,
            radius_fraction: self.radius_fraction,
            radius_edges: self.radius_edges,
            exemplar_size: self.exemplar_size,
            exemplar_scale: self.exemplar_scale,
        }
    }

    /// φ_max, ψ_{α=1}, ψ_{α=0} and their order.
    fn validate_angles(&self) -> Result<(), MethodError> {
        check_ranges(&[
            (
                "lapped_rigid.phi_max",
                self.phi_max,
                1.0,
                180.0,
                "[1, 180] degrees",
            ),
            (
                "lapped_rigid.alpha_opaque",
                self.alpha_opaque,
                0.0,
                180.0,
                "[0, 180] degrees",
            ),
            (
                "lapped_rigid.alpha_transparent",
                self.alpha_transparent,
                0.0,
                180.0,
                "[0, 180] degrees",
            ),
        ])?;
        if !(self.alpha_opaque < self.alpha_transparent && self.alpha_transparent < self.phi_max) {
            return Err(MethodError::InvalidParameter {
                name: "lapped_rigid.alpha_opaque/alpha_transparent/phi_max",
                value: format!(
                    "{} / {} / {}",
                    self.alpha_opaque, self.alpha_transparent, self.phi_max
                ),
                allowed: "alpha_opaque < alpha_transparent < phi_max",
            });
        }
        Ok(())
    }

    /// The derived mask's weights, which must leave its centre opaque.
    fn validate_mask(&self) -> Result<(), MethodError> {
        check_ranges(&[
            (
                "lapped_rigid.mask_feature_weight",
                self.mask_feature_weight,
                0.0,
                1.0,
                "[0, 1]",
            ),
            (
                "lapped_rigid.mask_softness",
                self.mask_softness,
                0.0,
                1.0,
                "[0, 1]",
            ),
        ])?;
        if self.mask.is_none() && self.mask_feature_weight + self.mask_softness >= 1.0 {
            return Err(MethodError::InvalidParameter {
                name: "lapped_rigid.mask_feature_weight + mask_softness",
                value: (self.mask_feature_weight + self.mask_softness).to_string(),
                allowed: "< 1, so the derived mask is opaque at the patch centre",
            });
        }
        Ok(())
    }
}
