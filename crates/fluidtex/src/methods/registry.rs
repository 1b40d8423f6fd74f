//! The methods fluidtex offers, by name: what `--method` accepts, what
//! `compare` runs, and how each is built from its parameters.
//!
//! Adding a method (the steps, in order):
//! 1. Its module under `methods/`: a [`Method`] (`step`, and `select` /
//!    `resample` where it can split the two; otherwise they replay the
//!    frame), a constructor from its parameter section and its exemplars,
//!    and, if it has parameters, their [`params!`](super::params)
//!    declaration (struct, defaults, docs, flags) and `validate`.
//! 2. One line in `registry!` below: its variant, doc and
//!    [`MethodSpec`] (name, exemplars read, how it is checked and built).
//! 3. If it has parameters, one line in `sections!`
//!    ([`MethodParams`]), marked `=> when_set` so that the fingerprints of
//!    runs made before it hold. The CLI's `Config` flattens
//!    [`MethodParams`]: the section is a config table and its flags are
//!    `run`'s with nothing written there.
//! 4. The README's methods table.
//!
//! The test-only `toy` method (`methods/toy.rs`) is added exactly so.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::atlas_check::{AtlasCheck, AtlasCheckParams};
use super::dual_rest::{DualRest, DualRestParams};
use super::erosion::{Erosion, ErosionParams};
use super::lapped_rigid::{LappedRigid, LappedRigidParams};
use super::optimization::{Optimization, OptimizationParams};
use super::params::{ParamFlag, ParamSection};
use super::{Method, MethodError, advect, blend_deformable, erosion};
use crate::exemplar::{Exemplar, ExemplarSet};
use crate::named::Named;

/// How many exemplars a method reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exemplars {
    /// None (the checker).
    None,
    /// One, still or animated.
    One,
    /// One or several per surface (the lapped methods).
    Several,
}

/// A method as the registry knows it.
#[derive(Clone, Copy)]
pub struct MethodSpec {
    /// Its name: `--method`, state files, reports (the enum's serde name).
    pub name: &'static str,
    /// The exemplars it reads.
    pub exemplars: Exemplars,
    /// Range checks of the sections it reads, before any frame is read.
    pub validate: fn(&MethodParams) -> Result<(), MethodError>,
    /// The method, seeded, over its exemplars (`None` for
    /// [`Exemplars::None`]).
    pub build: BuildFn,
}

/// How a [`MethodSpec`] builds its method: from the parameter sections, a
/// seed and its exemplars.
pub type BuildFn =
    fn(&MethodParams, u64, Option<Arc<ExemplarSet>>) -> Result<Box<dyn Method>, MethodError>;

/// The exemplars a method that reads them was given.
fn given(set: Option<Arc<ExemplarSet>>) -> Result<Arc<ExemplarSet>, MethodError> {
    set.ok_or_else(|| MethodError::State("the method reads an exemplar and was given none".into()))
}

/// Declares [`MethodKind`] from one line per method: `Variant => spec`.
macro_rules! registry {
    ($(
        $(#[doc = $doc:literal])*
        $(#[cfg($cfg:meta)])?
        $variant:ident => $spec:expr
    ),* $(,)?) => {
        /// A texturing method.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
        #[serde(rename_all = "kebab-case")]
        pub enum MethodKind {
            $( $(#[doc = $doc])* $(#[cfg($cfg)])? $variant, )*
        }

        impl MethodKind {
            /// What the registry knows of the method.
            pub fn spec(self) -> MethodSpec {
                match self {
                    $( $(#[cfg($cfg)])? MethodKind::$variant => $spec, )*
                }
            }
        }

        impl Named for MethodKind {
            const ALL: &'static [Self] = &[$( $(#[cfg($cfg)])? MethodKind::$variant, )*];

            fn name(self) -> &'static str {
                self.spec().name
            }
        }
    };
}

registry! {
    /// Eroded deformable lapped textures (Gagnon et al. 2021), the default.
    Erosion => MethodSpec {
        name: "erosion",
        exemplars: Exemplars::Several,
        validate: |p| p.erosion.validate(),
        build: |p, seed, set| {
            let e = Erosion::with_exemplars(erosion::EROSION, p.erosion.clone(), given(set)?, seed);
            Ok(Box::new(e?))
        },
    },
    /// Baseline: the first frame's patches carried by the flow, never renewed.
    Advect => MethodSpec {
        name: "advect",
        exemplars: Exemplars::Several,
        validate: |p| p.erosion.validate(),
        build: |p, seed, set| {
            let e = Erosion::with_exemplars(advect::RULES, p.erosion.clone(), given(set)?, seed);
            Ok(Box::new(e?))
        },
    },
    /// Baseline: two erosion layers reset in turn, cross-faded.
    DualRest => MethodSpec {
        name: "dual-rest",
        exemplars: Exemplars::One,
        validate: |p| p.erosion.validate().and_then(|()| p.dual_rest.validate()),
        build: |p, seed, set| {
            let (d, e) = (p.dual_rest.clone(), p.erosion.clone());
            Ok(Box::new(DualRest::with_exemplars(d, e, given(set)?, seed)?))
        },
    },
    /// Baseline: deformable patches alpha-blended by weight.
    BlendDeformable => MethodSpec {
        name: "blend-deformable",
        exemplars: Exemplars::Several,
        validate: |p| p.erosion.validate(),
        build: |p, seed, set| {
            let rules = blend_deformable::RULES;
            let e = Erosion::with_exemplars(rules, p.erosion.clone(), given(set)?, seed);
            Ok(Box::new(e?))
        },
    },
    /// A world-space checker, to inspect the atlas chain.
    AtlasCheck => MethodSpec {
        name: "atlas-check",
        exemplars: Exemplars::None,
        validate: |p| p.atlas_check.validate(),
        build: |p, _, _| Ok(Box::new(AtlasCheck::new(p.atlas_check.clone())?)),
    },
    /// Surface texture optimization with texture transport (Kwatra et al. 2007).
    Optimization => MethodSpec {
        name: "optimization",
        exemplars: Exemplars::One,
        validate: |p| p.optimization.validate(),
        build: |p, seed, set| {
            let o = Optimization::with_set(p.optimization.clone(), &*given(set)?, seed);
            Ok(Box::new(o?))
        },
    },
    /// Dynamic lapped textures with trackers: rigid patches, over-composited
    /// (Gagnon, Dagenais, Paquette 2016).
    LappedRigid => MethodSpec {
        name: "lapped-rigid",
        exemplars: Exemplars::Several,
        validate: |p| p.lapped_rigid.validate(),
        build: |p, seed, set| {
            let l = LappedRigid::with_exemplars(p.lapped_rigid.clone(), given(set)?, seed);
            Ok(Box::new(l?))
        },
    },
    /// A flat grey, only in tests: the method added by the steps above.
    #[cfg(test)]
    Toy => super::toy::SPEC,
}

// `registry!` writes the enum and takes no `#[default]`.
#[allow(clippy::derivable_impls)]
impl Default for MethodKind {
    fn default() -> MethodKind {
        MethodKind::Erosion
    }
}

impl MethodKind {
    /// Whether the method reads an exemplar (all but the checker).
    pub fn needs_exemplar(self) -> bool {
        self.spec().exemplars != Exemplars::None
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
/// A section written `name: Type => when_set` is left out of a config's
/// serialised form while at its defaults (it came after runs were
/// fingerprinted).
macro_rules! sections {
    ($(#[$attr:meta])* pub struct $name:ident {
        $($(#[cfg($cfg:meta)])? $section:ident : $ty:ty $(=> $when:ident)?),* $(,)?
    }) => {
        $(#[$attr])*
        #[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
        #[serde(default, deny_unknown_fields)]
        pub struct $name {
            $($(#[cfg($cfg)])? pub $section: $ty,)*
        }

        /// Every section, for reading a config's text with toml's own
        /// deserializer (`check_sections`): the other keys of the file
        /// are ignored, so the error of a section's key keeps its line.
        #[derive(Default, Deserialize)]
        #[serde(default)]
        #[allow(dead_code)] // read only for its errors
        struct SectionsOfAFile {
            $($(#[cfg($cfg)])? $section: $ty,)*
        }

        impl $name {
            /// Serialises the sections as a config file keeps them: a
            /// section marked `=> when_set` (added after runs were
            /// fingerprinted) only when it is not at its defaults, so the
            /// fingerprints of older runs hold. For
            /// `#[serde(flatten, serialize_with = ...)]` in a config.
            pub fn serialize_as_config<S: serde::Serializer>(
                &self,
                serializer: S,
            ) -> Result<S::Ok, S::Error> {
                use serde::ser::SerializeMap;
                let mut map = serializer.serialize_map(None)?;
                $(
                    $(#[cfg($cfg)])?
                    sections!(@entry map, self, $section $(, $when)?);
                )*
                map.end()
            }

            /// Every section's keys (its struct's fields, unset options
            /// included), by section name, sections in order.
            pub fn section_keys() -> Vec<(&'static str, &'static [&'static str])> {
                vec![$( $(#[cfg($cfg)])? (stringify!($section), field_names::<$ty>()), )*]
            }

            /// Reads the method sections of a whole config file's text
            /// (every other key ignored) with toml's own deserializer, for
            /// the line of an error that a flattened read loses.
            pub fn check_sections(text: &str) -> Result<(), toml::de::Error> {
                toml::from_str::<SectionsOfAFile>(text).map(|_| ())
            }

            /// Every section's flags as (section, flag), sections in order.
            /// A flag may be declared by several sections (`--substeps`):
            /// it sets each of them.
            pub fn flags() -> impl Iterator<Item = (&'static str, &'static ParamFlag)> {
                let mut all: Vec<(&'static str, &'static ParamFlag)> = Vec::new();
                $(
                    $(#[cfg($cfg)])?
                    all.extend(<$ty as ParamSection>::FLAGS.iter().map(|f| (stringify!($section), f)));
                )*
                all.into_iter()
            }

            /// Sets `--flag text` in every section that declares it.
            pub fn set_flag(&mut self, flag: &str, text: &str) -> Result<(), String> {
                let mut found = false;
                $(
                    $(#[cfg($cfg)])?
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
                $(
                    $(#[cfg($cfg)])?
                    table.insert(stringify!($section).into(), toml::Value::Table(self.$section.every_key()));
                )*
                table
            }
        }
    };
    (@entry $map:ident, $self:ident, $section:ident) => {
        $map.serialize_entry(stringify!($section), &$self.$section)?;
    };
    (@entry $map:ident, $self:ident, $section:ident, when_set) => {
        if !super::is_default(&$self.$section) {
            $map.serialize_entry(stringify!($section), &$self.$section)?;
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
        optimization: OptimizationParams => when_set,
        lapped_rigid: LappedRigidParams => when_set,
        #[cfg(test)]
        toy: super::toy::ToyParams,
    }
}

impl MethodParams {
    /// Range checks of the sections `kind` reads, before any frame is read.
    pub fn validate(&self, kind: MethodKind) -> Result<(), MethodError> {
        (kind.spec().validate)(self)
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
        let spec = kind.spec();
        if spec.exemplars == Exemplars::None {
            return Ok((spec.build)(self, seed, None)?);
        }
        let set = Arc::new(exemplars()?);
        if set.len() > 1 && spec.exemplars != Exemplars::Several {
            return Err(MethodError::InvalidParameter {
                name: "exemplar",
                value: format!("{} exemplars with --method {}", set.len(), kind.name()),
                allowed: "one exemplar; several per surface with erosion, advect, \
                          blend-deformable or lapped-rigid",
            }
            .into());
        }
        Ok((spec.build)(self, seed, Some(set))?)
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
            // The config's spelling (serde) is the registry's name.
            assert_eq!(serde_json::to_value(kind).ok(), Some(kind.name().into()));
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
