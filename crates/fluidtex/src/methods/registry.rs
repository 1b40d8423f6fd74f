//! The methods fluidtex offers, by name: what `--method` accepts, what
//! `compare` runs, and how each is built from its parameters.
//!
//! Adding a method: its folder under `methods/` (a [`Method`]: `step`,
//! and `select` / `resample` where it can split the two, which otherwise
//! replay the frame), a variant here with its name, its arms in
//! [`MethodParams::validate`] and [`MethodParams::build_set`] (plus its
//! parameter section in [`MethodParams`] if it has parameters, which the
//! CLI's config mirrors with a section and flags), and the README.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::atlas_check::{AtlasCheck, AtlasCheckParams};
use super::dual_rest::{DualRest, DualRestParams};
use super::erosion::{Erosion, ErosionParams, Variant};
use super::lapped_rigid::{LappedRigid, LappedRigidParams};
use super::optimization::{Optimization, OptimizationParams};
use super::params::{ParamFlag, ParamSection};
use super::{Method, MethodError};
use crate::exemplar::{Exemplar, ExemplarSet};
use crate::named::Named;

/// A texturing method.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MethodKind {
    /// Eroded deformable lapped textures (Gagnon et al. 2021), the default.
    #[default]
    Erosion,
    /// Baseline: the first frame's patches carried by the flow, never renewed.
    Advect,
    /// Baseline: two erosion layers reset in turn, cross-faded.
    DualRest,
    /// Baseline: deformable patches alpha-blended by weight.
    BlendDeformable,
    /// A world-space checker, to inspect the atlas chain.
    AtlasCheck,
    /// Surface texture optimization with texture transport (Kwatra et al. 2007).
    Optimization,
    /// Dynamic lapped textures with trackers: rigid patches, over-composited
    /// (Gagnon, Dagenais, Paquette 2016).
    LappedRigid,
}

crate::named!(MethodKind {
    Erosion => "erosion",
    Advect => "advect",
    DualRest => "dual-rest",
    BlendDeformable => "blend-deformable",
    AtlasCheck => "atlas-check",
    Optimization => "optimization",
    LappedRigid => "lapped-rigid",
});

impl MethodKind {
    /// Whether the method reads an exemplar (all but the checker).
    pub fn needs_exemplar(self) -> bool {
        self != MethodKind::AtlasCheck
    }
}

impl std::fmt::Display for MethodKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for MethodKind {
    type Err = String;

    fn from_str(s: &str) -> Result<MethodKind, String> {
        MethodKind::parse_named("method", s)
    }
}

/// Declares [`MethodParams`] from its sections, one line each: the
/// struct, and the functions that reach every section's flags and keys.
macro_rules! sections {
    ($(#[$attr:meta])* pub struct $name:ident { $($section:ident : $ty:ty),* $(,)? }) => {
        $(#[$attr])*
        #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
        #[serde(default, deny_unknown_fields)]
        pub struct $name {
            $(pub $section: $ty,)*
        }

        impl $name {
            /// Every section's flags as (section, flag), sections in order.
            /// A flag may be declared by several sections (`--substeps`):
            /// it sets each of them.
            pub fn flags() -> impl Iterator<Item = (&'static str, &'static ParamFlag)> {
                let mut all: Vec<(&'static str, &'static ParamFlag)> = Vec::new();
                $(all.extend(<$ty as ParamSection>::FLAGS.iter().map(|f| (stringify!($section), f)));)*
                all.into_iter()
            }

            /// Sets `--flag text` in every section that declares it.
            pub fn set_flag(&mut self, flag: &str, text: &str) -> Result<(), String> {
                let mut found = false;
                $(
                    if <$ty as ParamSection>::FLAGS.iter().any(|f| f.flag == flag) {
                        self.$section.set_flag(flag, text)?;
                        found = true;
                    }
                )*
                if found { Ok(()) } else { Err(format!("no method flag --{flag}")) }
            }

            /// Every section's [`ParamSection::every_key`], by section name.
            pub fn every_key(&self) -> toml::Table {
                let mut table = toml::Table::new();
                $(table.insert(stringify!($section).into(), toml::Value::Table(self.$section.every_key()));)*
                table
            }
        }
    };
}

sections! {
    /// The parameters of every method, one section each (config keys
    /// `\[erosion]`, `\[dual_rest]`, `\[atlas_check]`, `\[optimization]`,
    /// `\[lapped_rigid]`); a method reads its own section and, for the baselines
    /// built from erosion's patches (`advect`, `blend-deformable`, `dual-rest`),
    /// erosion's.
    pub struct MethodParams {
        erosion: ErosionParams,
        atlas_check: AtlasCheckParams,
        dual_rest: DualRestParams,
        optimization: OptimizationParams,
        lapped_rigid: LappedRigidParams,
    }
}

impl MethodParams {
    /// Range checks of the sections `kind` reads, before any frame is read.
    pub fn validate(&self, kind: MethodKind) -> Result<(), MethodError> {
        match kind {
            MethodKind::Erosion | MethodKind::Advect | MethodKind::BlendDeformable => {
                self.erosion.validate()
            }
            MethodKind::DualRest => {
                self.erosion.validate()?;
                self.dual_rest.validate()
            }
            MethodKind::AtlasCheck => self.atlas_check.validate(),
            MethodKind::Optimization => self.optimization.validate(),
            MethodKind::LappedRigid => self.lapped_rigid.validate(),
        }
    }

    /// Builds `kind`. `exemplar` is called only for methods that read one
    /// ([`MethodKind::needs_exemplar`]).
    pub fn build<E>(
        &self,
        kind: MethodKind,
        seed: u64,
        exemplar: impl FnOnce() -> Result<Arc<Exemplar>, E>,
    ) -> Result<Box<dyn Method>, E>
    where
        E: From<MethodError>,
    {
        self.build_set(kind, seed, || Ok(ExemplarSet::single(exemplar()?)))
    }

    /// Builds `kind` over the exemplars `exemplars` returns (called only
    /// for methods that read one). Several exemplars per surface are
    /// offered by the lapped methods (erosion, its baselines advect and
    /// blend-deformable, lapped-rigid); the others refuse more than one.
    pub fn build_set<E>(
        &self,
        kind: MethodKind,
        seed: u64,
        exemplars: impl FnOnce() -> Result<ExemplarSet, E>,
    ) -> Result<Box<dyn Method>, E>
    where
        E: From<MethodError>,
    {
        self.validate(kind)?;
        if kind == MethodKind::AtlasCheck {
            return Ok(Box::new(AtlasCheck::new(self.atlas_check.clone())?));
        }
        let set = Arc::new(exemplars()?);
        let several = matches!(
            kind,
            MethodKind::Erosion
                | MethodKind::Advect
                | MethodKind::BlendDeformable
                | MethodKind::LappedRigid
        );
        if set.len() > 1 && !several {
            return Err(MethodError::InvalidParameter {
                name: "exemplar",
                value: format!("{} exemplars with --method {}", set.len(), kind.name()),
                allowed: "one exemplar; several per surface with erosion, advect, \
                          blend-deformable or lapped-rigid",
            }
            .into());
        }
        let exemplar = Arc::clone(set.primary());
        let frames = || {
            set.slots_of(0)
                .filter_map(|s| set.exemplars().get(s).cloned())
                .collect()
        };
        let erosion = |variant| -> Result<Box<dyn Method>, MethodError> {
            Ok(Box::new(Erosion::with_exemplars(
                variant,
                self.erosion.clone(),
                Arc::clone(&set),
                seed,
            )?))
        };
        Ok(match kind {
            MethodKind::Erosion => erosion(Variant::Erode)?,
            MethodKind::Advect => erosion(Variant::Advect)?,
            MethodKind::BlendDeformable => erosion(Variant::Blend)?,
            MethodKind::DualRest => Box::new(DualRest::with_exemplars(
                self.dual_rest.clone(),
                self.erosion.clone(),
                Arc::clone(&set),
                seed,
            )?),
            MethodKind::AtlasCheck => Box::new(AtlasCheck::new(self.atlas_check.clone())?),
            MethodKind::Optimization if set.is_animated() => Box::new(Optimization::with_frames(
                self.optimization.clone(),
                frames(),
                set.clock,
                seed,
            )?),
            MethodKind::Optimization => Box::new(Optimization::new(
                self.optimization.clone(),
                exemplar,
                seed,
            )?),
            MethodKind::LappedRigid => Box::new(LappedRigid::with_exemplars(
                self.lapped_rigid.clone(),
                Arc::clone(&set),
                seed,
            )?),
        })
    }
}

/// The field names a `Deserialize` struct asks for (serde hands them to
/// `deserialize_struct`): the keys of a parameter section, including
/// those it leaves out when serialising (the config test and the
/// departures ledger hold their lists against them).
pub fn field_names<'de, T: Deserialize<'de>>() -> &'static [&'static str] {
    use serde::de::{Error as _, Visitor, value::Error};
    struct Fields(&'static [&'static str]);
    impl<'de> serde::Deserializer<'de> for &mut Fields {
        type Error = Error;
        fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Error> {
            Err(Error::custom("field names only"))
        }
        fn deserialize_struct<V: Visitor<'de>>(
            self,
            _: &'static str,
            fields: &'static [&'static str],
            _: V,
        ) -> Result<V::Value, Error> {
            self.0 = fields;
            Err(Error::custom("field names only"))
        }
        serde::forward_to_deserialize_any! {
            bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes
            byte_buf option unit unit_struct newtype_struct seq tuple tuple_struct map
            enum identifier ignored_any
        }
    }
    let mut f = Fields(&[]);
    let _ = T::deserialize(&mut f);
    f.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_method_builds_under_its_own_name() {
        let params = MethodParams::default();
        for &kind in MethodKind::ALL {
            let method = params
                .build(kind, 0, || {
                    Ok::<_, MethodError>(Arc::new(crate::exemplar::builtin_pebbles(16, 0)))
                })
                .expect("defaults are valid");
            assert_eq!(method.name(), kind.name());
        }
    }

    #[test]
    fn parameters_are_checked_before_the_exemplar_is_built() {
        let mut params = MethodParams::default();
        params.erosion.epsilon = 2.0;
        let mut asked = false;
        let err = params
            .build(MethodKind::Erosion, 0, || {
                asked = true;
                Ok::<_, MethodError>(Arc::new(crate::exemplar::builtin_pebbles(16, 0)))
            })
            .err()
            .expect("epsilon out of range");
        assert!(err.to_string().contains("epsilon"), "{err}");
        assert!(
            !asked,
            "the exemplar was loaded before the parameters were checked"
        );
        // The checker reads no exemplar at all.
        let built = MethodParams::default().build(MethodKind::AtlasCheck, 0, || {
            Err::<Arc<Exemplar>, _>(MethodError::State("not needed".into()))
        });
        assert!(built.is_ok());
    }
}
