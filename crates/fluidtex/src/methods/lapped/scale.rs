//! The patch scale: radius r and the world size S the exemplar covers.
//!
//! Every patch method reads the same five settings (given r, or r from the
//! first frame's size and edge length; given S, or S as a multiple of r)
//! and resolves them once, on the first frame with a surface, keeping them
//! in its saved state so a resumed run keeps its scale. The settings stay
//! flat keys of each method's config section (`[erosion] radius = ...`,
//! `[lapped_rigid] radius = ...`): a `#[serde(flatten)]` struct would keep
//! the keys but cannot be combined with the sections' `deny_unknown_fields`
//! (serde does not support the pair), and a typo in a key must stay an
//! error. So a section lends its five fields to a [`PatchScale`] value
//! ([`crate::methods::lapped_rigid::LappedRigidParams::scale`]) and the
//! rules live here once.

use super::super::{MethodError, check_range};
use crate::mesh::TriMesh;

/// The scale settings of a patch method's section.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchScale {
    /// r in world units; `None`: [`PatchScale::default_radius`].
    pub radius: Option<f32>,
    /// Default r as a fraction of the first frame's bounding-box diagonal.
    pub radius_fraction: f32,
    /// The default r is never below this many median edge lengths.
    pub radius_edges: f32,
    /// S in world units; `None`: `exemplar_scale` × r.
    pub exemplar_size: Option<f32>,
    /// Default S as a multiple of r.
    pub exemplar_scale: f32,
}

/// The config keys of a section's scale settings, for messages.
pub struct ScaleKeys {
    pub radius: &'static str,
    pub radius_fraction: &'static str,
    pub radius_edges: &'static str,
    pub exemplar_size: &'static str,
    pub exemplar_scale: &'static str,
}

/// r and S once resolved, with how r was chosen on the frame that chose it.
#[derive(Clone, Debug, PartialEq)]
pub struct Resolved {
    pub radius: f32,
    pub exemplar_size: f32,
    /// A sentence saying which rule set r; `None` when r was already known.
    pub radius_rule: Option<String>,
}

impl PatchScale {
    /// Range checks, in key order; errors name `keys`.
    pub fn validate(&self, keys: &ScaleKeys) -> Result<(), MethodError> {
        if let Some(r) = self.radius {
            check_range(keys.radius, r, f32::MIN_POSITIVE, f32::MAX, "> 0")?;
        }
        check_range(
            keys.radius_fraction,
            self.radius_fraction,
            1e-4,
            1.0,
            "[0.0001, 1]",
        )?;
        check_range(
            keys.radius_edges,
            self.radius_edges,
            0.0,
            1000.0,
            "[0, 1000]",
        )?;
        if let Some(s) = self.exemplar_size {
            check_range(keys.exemplar_size, s, f32::MIN_POSITIVE, f32::MAX, "> 0")?;
        }
        check_range(
            keys.exemplar_scale,
            self.exemplar_scale,
            0.1,
            100.0,
            "[0.1, 100]",
        )
    }

    /// The default r on `mesh` and the rule that chose it (erosion's rule,
    /// [`crate::methods::erosion::default_radius`], so all patch methods
    /// agree on the scale of a scene).
    pub fn default_radius(&self, mesh: &TriMesh) -> (f32, String) {
        let like = crate::methods::erosion::ErosionParams {
            radius_fraction: self.radius_fraction,
            radius_edges: self.radius_edges,
            ..Default::default()
        };
        crate::methods::erosion::default_radius(mesh, &like)
    }

    /// r and S for this frame: the kept values when `radius` and
    /// `exemplar_size` (the method's state) hold them, else resolved on
    /// `mesh` and stored there.
    pub fn resolve(
        &self,
        mesh: &TriMesh,
        radius: &mut Option<f32>,
        exemplar_size: &mut Option<f32>,
    ) -> Resolved {
        let mut radius_rule = None;
        let r = match *radius {
            Some(r) => r,
            None => {
                let (r, rule) = match self.radius {
                    Some(r) => (r, "given".to_string()),
                    None => self.default_radius(mesh),
                };
                radius_rule = Some(rule);
                *radius = Some(r);
                r
            }
        };
        let s = *exemplar_size.get_or_insert(self.exemplar_size.unwrap_or(self.exemplar_scale * r));
        Resolved {
            radius: r,
            exemplar_size: s,
            radius_rule,
        }
    }
}
