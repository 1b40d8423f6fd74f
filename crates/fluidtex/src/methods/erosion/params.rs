//! The erosion method's parameters ([`ErosionParams`]), with their
//! defaults, their ranges and the settings they choose between: one
//! config section (`[erosion]`) and one CLI flag per field.

use serde::{Deserialize, Serialize};

use super::transition;
use super::update::Placement;
use crate::methods::tone::Tone;
use crate::methods::{MethodError, check_range};

crate::methods::params::params! {
    /// Parameters of the erosion method. Defaults follow docs/design.md and the
    /// 2021 paper; every field is also a config key and a CLI flag.
    pub struct ErosionParams {
        /// Patch radius r in world units (Sec. 4). `None`: `radius_fraction` ×
        /// the bounding-box diagonal of the first non-empty frame.
        pub radius: Option<f32> = None
            => "radius" : "Patch radius r in world units [bbox diagonal / 25]",
        /// Default r as a fraction of the first frame's bounding-box diagonal [1/25].
        pub radius_fraction: f32 = 1.0 / 25.0,
        /// World size S covered by the exemplar's \[0,1]². `None`:
        /// `exemplar_scale` × r.
        pub exemplar_size: Option<f32> = None
            => "exemplar-size" : "World size covered by the exemplar [2.6 r]; also sets optimization's (its width, [exemplar_texels point spacings])",
        /// Default S as a multiple of r [2.6]: our choice (the paper gives none), a
        /// margin of 0.3 r around the patch's disc of radius r.
        pub exemplar_scale: f32 = 2.6,
        /// δ_max of Eq. 1 \[3]: triangles at or beyond this distortion have Q_T = 0.
        pub delta_max: f32 = 3.0
            => "delta-max" : "Maximal triangle distortion δ_max (Eq. 1) [3]",
        /// Distortion at which erosion starts: Q_T of Eq. 1 stays 1 up to δ_onset
        /// and falls linearly to 0 at δ_max \[1.5; 1 is the paper's Eq. 1, where
        /// any distortion lowers Q_T]. Above 1, a patch sheared by a slow flow
        /// keeps every texel until its distortion is visible instead of shedding
        /// a thin band of texels every frame from its first frame on; it comes
        /// with a faster `erosion_rate` so patches are still gone by δ_max.
        pub delta_onset: f32 = 1.5
            => "delta-onset" : "Distortion at which erosion starts: Q_T = 1 below it, then falls linearly to 0 at δ_max [1.5; 1: the paper's Eq. 1]",
        /// ε of the erosion test, Sec. 5.2 [0.1], in (0, 1).
        pub epsilon: f32 = 0.1
            => "epsilon" : "Erosion ε (Sec. 5.2) [0.1]",
        /// Vertices farther than this fraction of r from the next surface are removed [1/4] (Sec. 4).
        pub far_fraction: f32 = 0.25
            => "far-fraction" : "Remove patch vertices farther than this × r from the surface [0.25]",
        /// B_V = 1 within this fraction of r of the patch centre [1/4] (Eq. 2).
        pub centre_fraction: f32 = 0.25
            => "centre-fraction" : "Never erode within this × r of a patch centre (Eq. 2) [0.25]",
        /// Poisson disks whose normals have a smaller dot product do not block each other [0.9].
        pub normal_dot: f32 = 0.9,
        /// RK4 steps per frame \[1].
        pub substeps: u32 = 1
            => "substeps" : "RK4 substeps per frame [1]; also sets optimization's transport substeps",
        /// Random rotation of each patch at creation [true] (seeded per patch id,
        /// or per creation point for patches the update adds).
        pub random_rotation: bool = true
            => "no-rotation" = "false" : "Disable the random rotation of new patches",
        /// New-patch placement \[local]: `local` (the paper) or `global`.
        pub placement: Placement = Placement::Local
            => "placement" : "New patch placement: local (the paper) or global",
        /// How vertex weights w_V evolve over time \[progressive] (see [`WeightMode`]).
        pub weights: WeightMode = WeightMode::Progressive
            => "weights" : "Weights over time: progressive (monotone, rate-limited) or paper",
        /// Progressive weights: the largest decrease of w_V per second of
        /// animation [4.8, i.e. 0.2 per frame at 24 fps], so a patch takes at
        /// least 1/rate seconds to erode from whole to nothing.
        pub erosion_rate: f32 = 4.8
            => "erosion-rate" : "Progressive weights: largest fall of w per second [4.8]",
        /// Reach of the centre falloff D(u, v) of the erosion test (Sec. 5.2)
        /// \[footprint] (see [`Falloff`]).
        pub falloff: Falloff = Falloff::Footprint
            => "falloff" : "Where the erosion falloff D reaches 0: footprint (r/S) or paper (0.5)",
        /// Orientation of the exemplar on new patches \[random] (see [`Orientation`]).
        pub orientation: Orientation = Orientation::Random
            => "orientation" : "Exemplar orientation on new patches: random or aligned (with --up-axis)",
        /// World direction the exemplar's up follows with `orientation = aligned` [0, 1, 0].
        pub up_axis: [f32; 3] = [0.0, 1.0, 0.0]
            => "up-axis" : "World direction the exemplar's up follows with --orientation aligned [0,1,0]",
        /// The default r is never below this many median edge lengths of the
        /// first frame \[4]: a patch must hold enough fluid triangles that
        /// re-meshing noise does not dominate its shape.
        pub radius_edges: f32 = 4.0
            => "radius-edges" : "Default r is never below this many median edge lengths [4]",
        /// Patch edges longer than this many median edge lengths of the current
        /// frame are split at their midpoint after advection \[2] (0: never, as
        /// in the paper). A stretched patch triangle is a long chord of the
        /// curved surface whose middle leaves the surface, so its coverage
        /// flickers as the fluid is re-meshed (see [`super::patch::Patch::refine`]).
        pub split_edges: f32 = 2.0
            => "split-edges" : "Split patch edges longer than this many median edge lengths of the frame (0: never, the paper) [2]",
        /// After each frame, a patch keeps only the triangles within about this
        /// fraction of r (in its rest space) of a texel it showed \[0.1]; the
        /// rest lie hidden under older patches and go (0: every triangle is
        /// kept until the patch shows nothing, as in the paper). See
        /// `Erosion::prune_hidden`.
        pub hidden_reach: f32 = 0.1
            => "hidden-reach" : "Erosion: after each frame a patch keeps only the triangles within this fraction of r of a texel it showed; the rest, hidden under older patches, go (0: keep them, the paper) [0.1]",
        /// Per frame, each channel's mean over the covered texels is moved to
        /// the exemplar's \[mean]; `match` also matches its contrast to the
        /// exemplar's as shown (see [`crate::methods::tone`]): the
        /// feature-guided compositing of Sec. 5.1–5.2 shows high-feature texels
        /// more often than the exemplar has them. `off` leaves the composite as
        /// the paper makes it. Only the erosion method itself; the baselines
        /// are never matched.
        pub tone: Tone = Tone::Mean
            => "tone" : "Erosion: per frame, move each channel's mean to the exemplar's (mean), also match its contrast (match), or keep the paper's composite (off) [mean]",
        /// Frames over which a texel whose source changes shows its old and its
        /// new source together \[0: the paper, one source per texel always]
        /// (see [`transition`]). Up to [`transition::MAX_FRAMES`]. Left out of
        /// the settings (and so of a run's fingerprint) at 0.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub transition: u32 = 0
            => "transition" : "Erosion: frames over which a texel whose source changes shows the old and the new source, blended preserving contrast (0: one source per texel, the paper) [0]",
        /// Which fluid triangles a new patch copies (Sec. 4) \[connected] (see
        /// [`PatchRegion`]). Left out of the settings at its default.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub patch_region: PatchRegion = PatchRegion::Connected
            => "patch-region" : "Which triangles within r a new patch copies: connected (to p's triangle) or paper (every one facing p's side) [connected]",
        /// Whether the corners of the triangle that holds p keep B_V = 1 (Eq. 2)
        /// \[pinned] (see [`SeedCorners`]). Left out of the settings at its
        /// default.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub seed_corners: SeedCorners = SeedCorners::Pinned
            => "seed-corners" : "B_V = 1 at the corners of p's triangle too (pinned) or only within r/4 of p (paper, Eq. 2) [pinned]",
        /// What becomes of the texel a new patch was made for when the patch
        /// erodes it (Sec. 5.1) \[forced] (see [`SeedTexel`]). Left out of the
        /// settings at its default.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub seed_texel: SeedTexel = SeedTexel::Forced
            => "seed-texel" : "A new patch that erodes its own seed texel: it gets it anyway (forced) or the texel stays uncovered (paper) [forced]",
        /// How the erosion test reads the feature map F_m (Sec. 5.2) \[mip]
        /// (see [`FeatureFilter`]). Left out of the settings at its default.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub feature_filter: FeatureFilter = FeatureFilter::Mip
            => "feature-filter" : "The erosion test reads the feature map at the atlas texel's mip level (mip) or at full resolution (full, the paper) [mip]",
        /// What becomes of the patch triangles the erosion test erodes whole
        /// for good \[dropped] (see [`ErodedTriangles`]). Left out of the
        /// settings at its default.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub eroded_triangles: ErodedTriangles = ErodedTriangles::Dropped
            => "eroded-triangles" : "Patch triangles eroded whole for good: dropped each frame (dropped) or kept until the patch dies (kept, the paper; memory grows with the run on a shearing flow) [dropped]",
        /// Whether a patch triangle stretched past δ_max still shows texels
        /// its vertex weights keep \[hard] (see [`Bound`]). Left out of the
        /// settings at its default.
        #[serde(skip_serializing_if = "crate::methods::is_default")]
        pub bound: Bound = Bound::Hard
            => "bound" : "Erosion: a patch triangle past δ_max shows nothing (hard) or what its vertex weights keep (paper: Q_V averages Q_T over a vertex's triangles) [hard]",
    }
}

/// What a patch triangle stretched past δ_max may show.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Bound {
    /// Nothing: the erosion test treats it as eroded whole, so no texel is
    /// ever shown past the distortion bound. Eq. 1 sets Q_T = 0 there, but
    /// Eq. 3's vertex weight Q_V is the mean of Q_T over the vertex's
    /// triangles, so a triangle past δ_max between whole neighbours keeps
    /// weights well above 0 and shows its high-feature texels; and the
    /// erosion rate of progressive weights lags a flow that stretches a
    /// triangle from δ_onset past δ_max within a few frames. On a dam
    /// break (frames 6–17, atlas 512) both let the area-weighted p95 of δ
    /// reach 3.56 with δ_max = 3.
    #[default]
    Hard,
    /// The paper's: only the vertex weights decide, through the erosion
    /// test.
    Paper,
}

/// Which fluid triangles a new patch copies. Both keep only the triangles
/// within r of p that do not face away from the normal at p (Sec. 4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PatchRegion {
    /// Only those edge-connected, through such triangles, to p's triangle:
    /// a piece of liquid within r that the surface does not join to p (a
    /// droplet, the far wall of a thin gap) gets no texture from a patch
    /// whose flattening cannot place it.
    #[default]
    Connected,
    /// The paper's: every such triangle, connected or not. The piece that
    /// holds p is flattened by LSCM; the others continue its flattening
    /// (the affine map that best takes their projections on p's tangent
    /// plane to the flattened piece's uv), since no surface path ties them
    /// to p.
    Paper,
}

/// Which vertices of a new patch hold B_V = 1 besides Eq. 2's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SeedCorners {
    /// Also the three corners of the triangle that holds p: B_V interpolates
    /// to 1 at p, so a patch never erodes the texel it was made for (Eq. 2's
    /// guard made exact where the triangle is larger than r/4).
    #[default]
    Pinned,
    /// The paper's Eq. 2: interior vertices and those within r/4 of p only.
    Paper,
}

/// What becomes of the texel a new patch was made for when the patch does
/// not show it (erosion: the patch erodes it; `lapped-rigid`: its composite
/// stays short of coverage).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SeedTexel {
    /// The texel is closed by its patch anyway (erosion: at the patch
    /// centre; `lapped-rigid`: with what it has, or the patch centre where
    /// nothing showed) and counted in `forced_texels`: every texel is
    /// covered.
    #[default]
    Forced,
    /// The papers': the texel is left to the patches still to come; where
    /// none covers it, it stays uncovered (counted in `uncovered_texels`).
    /// The papers would ask for another patch there; ours are made
    /// deterministically from the point, so the same patch would come back,
    /// and the texel seeds no other this frame.
    Paper,
}

/// How the erosion test reads F_m.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FeatureFilter {
    /// From the feature map's mip level matching one atlas texel on the
    /// patch triangle ([`super::feature_levels`]).
    #[default]
    Mip,
    /// The paper's: bilinear at full resolution, whatever the atlas.
    Full,
}

/// How the vertex weights w_V of Eq. 3 evolve from frame to frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WeightMode {
    /// w_V never increases and falls by at most `erosion_rate` per second
    /// towards Q_V·B_V: an eroded texel never comes back, and a patch erodes
    /// progressively instead of losing a large part of itself in one frame
    /// (re-meshing jitters Q_V, and a new boundary drops B_V to 0 at once).
    #[default]
    Progressive,
    /// The paper's: w_V = Q_V·B_V recomputed from scratch every frame.
    Paper,
}

/// Where D(u, v) of the erosion test reaches 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Falloff {
    /// At the patch's own footprint, uv distance r/S from the centre: every
    /// patch is eroded along the features from its creation on, whatever S.
    #[default]
    Footprint,
    /// The paper's formula: at uv distance 0.5, the edge of the exemplar
    /// square. With S = 2.6 r the patch ends at uv distance ≈ 0.385, so D
    /// stays ≥ 0.23 on the patch and an undistorted patch keeps its
    /// polygonal border.
    Paper,
}

/// Orientation of the exemplar on a new patch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Orientation {
    /// A seeded random rotation per patch: right for stochastic exemplars
    /// (pebbles, gravel, foam).
    #[default]
    Random,
    /// The exemplar's up follows `up_axis` projected on the tangent plane at
    /// the patch centre, then is carried (deformed) with the patch: right for
    /// oriented exemplars (bricks, streaks).
    Aligned,
}

impl ErosionParams {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), MethodError> {
        if let Some(r) = self.radius {
            check_range("radius", r, f32::MIN_POSITIVE, f32::MAX, "> 0")?;
        }
        check_range(
            "radius_fraction",
            self.radius_fraction,
            1e-4,
            1.0,
            "[0.0001, 1]",
        )?;
        if let Some(s) = self.exemplar_size {
            check_range("exemplar_size", s, f32::MIN_POSITIVE, f32::MAX, "> 0")?;
        }
        check_range(
            "exemplar_scale",
            self.exemplar_scale,
            0.1,
            100.0,
            "[0.1, 100]",
        )?;
        check_range("delta_max", self.delta_max, 1.0001, 1000.0, "(1, 1000]")?;
        if !(self.delta_onset >= 1.0 && self.delta_onset < self.delta_max) {
            return Err(MethodError::InvalidParameter {
                name: "delta_onset",
                value: self.delta_onset.to_string(),
                allowed: "[1, delta_max)",
            });
        }
        check_range("epsilon", self.epsilon, 0.0, 0.9999, "[0, 1)")?;
        check_range("far_fraction", self.far_fraction, 1e-3, 10.0, "[0.001, 10]")?;
        check_range("centre_fraction", self.centre_fraction, 0.0, 1.0, "[0, 1]")?;
        check_range("normal_dot", self.normal_dot, -1.0, 1.0, "[-1, 1]")?;
        check_range("substeps", self.substeps as f32, 1.0, 64.0, "1..=64")?;
        check_range(
            "erosion_rate",
            self.erosion_rate,
            1e-3,
            1e6,
            "[0.001, 1e6] per second",
        )?;
        check_range("radius_edges", self.radius_edges, 0.0, 1000.0, "[0, 1000]")?;
        check_range(
            "transition",
            self.transition as f32,
            0.0,
            transition::MAX_FRAMES as f32,
            "0..=8 frames",
        )?;
        if self.split_edges != 0.0 {
            check_range(
                "split_edges",
                self.split_edges,
                0.5,
                1000.0,
                "0 or [0.5, 1000]",
            )?;
        }
        check_range("hidden_reach", self.hidden_reach, 0.0, 10.0, "[0, 10]")?;
        let axis = glam::Vec3::from(self.up_axis);
        if !axis.is_finite() || axis.length() < 1e-6 {
            return Err(MethodError::InvalidParameter {
                name: "up_axis",
                value: format!("{:?}", self.up_axis),
                allowed: "a finite, non-zero direction",
            });
        }
        Ok(())
    }
}

crate::named!(WeightMode {
    Progressive => "progressive",
    Paper => "paper",
});
crate::named!(Falloff {
    Footprint => "footprint",
    Paper => "paper",
});
crate::named!(PatchRegion {
    Connected => "connected",
    Paper => "paper",
});
/// What becomes of a patch's triangles that can never show a texel again.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ErodedTriangles {
    /// Dropped each frame, and edges stretched past δ_max are no longer
    /// split ([`Erosion::prune`](super::Erosion)): a patch's cost follows
    /// what it can still show, not the run's history.
    #[default]
    Dropped,
    /// Kept until the patch shows nothing, as the paper keeps a patch
    /// (hidden parts too: `hidden_reach` is then unused), and edges past
    /// δ_max split as any other: on a flow that shears without end, a
    /// patch's triangles and their splits grow with the length of the run.
    Kept,
}

crate::named!(ErodedTriangles {
    Dropped => "dropped",
    Kept => "kept",
});
crate::named!(SeedCorners {
    Pinned => "pinned",
    Paper => "paper",
});
crate::named!(SeedTexel {
    Forced => "forced",
    Paper => "paper",
});
crate::named!(FeatureFilter {
    Mip => "mip",
    Full => "full",
});
crate::named!(Bound {
    Hard => "hard",
    Paper => "paper",
});
crate::named!(Orientation {
    Random => "random",
    Aligned => "aligned",
});
