//! One declaration per parameter section: `params!` writes a method's
//! parameter struct (its config section, through serde), its defaults and
//! its command-line flags from one list of fields, so a parameter is
//! documented, defaulted and given a flag in one place.
//!
//! Front ends read the flags as data ([`ParamSection::FLAGS`]): the CLI
//! builds its `run` arguments from them and hands each value back through
//! [`ParamSection::set_flag`], which parses it by the field's type
//! ([`FlagValue`]). Validation stays a method of the struct (`validate`),
//! next to the declaration, because several rules relate two fields.

use std::path::PathBuf;

use crate::named::Named;

/// A field type a flag can set, parsed from the flag's text.
pub trait FlagValue: Sized {
    /// Whether the value is a comma-separated list (which may start with
    /// `-`, as in `--up-axis -1,0,0`).
    const LIST: bool = false;

    /// The names the flag accepts, when it accepts a fixed set.
    fn names() -> Option<Vec<&'static str>> {
        None
    }

    /// The value `text` stands for, or a message saying what was expected.
    fn parse_flag(text: &str) -> Result<Self, String>;

    /// [`FlagValue::parse_flag`]'s verdict alone (front ends check a flag's
    /// text when they read it).
    fn check(text: &str) -> Result<(), String> {
        Self::parse_flag(text).map(|_| ())
    }
}

impl FlagValue for f32 {
    fn parse_flag(text: &str) -> Result<f32, String> {
        text.trim()
            .parse()
            .map_err(|_| format!("{text:?} is not a number"))
    }
}

impl FlagValue for u32 {
    fn parse_flag(text: &str) -> Result<u32, String> {
        text.trim()
            .parse()
            .map_err(|_| format!("{text:?} is not a whole number from 0 to {}", u32::MAX))
    }
}

impl FlagValue for bool {
    fn parse_flag(text: &str) -> Result<bool, String> {
        text.trim()
            .parse()
            .map_err(|_| format!("{text:?} is not true or false"))
    }
}

impl FlagValue for PathBuf {
    fn parse_flag(text: &str) -> Result<PathBuf, String> {
        if text.is_empty() {
            return Err("an empty path".into());
        }
        Ok(PathBuf::from(text))
    }
}

impl FlagValue for Vec<u32> {
    const LIST: bool = true;

    fn parse_flag(text: &str) -> Result<Vec<u32>, String> {
        text.split(',').map(u32::parse_flag).collect()
    }
}

impl FlagValue for [f32; 3] {
    const LIST: bool = true;

    fn parse_flag(text: &str) -> Result<[f32; 3], String> {
        let parts: Vec<f32> = text
            .split(',')
            .map(f32::parse_flag)
            .collect::<Result<_, _>>()?;
        <[f32; 3]>::try_from(parts)
            .map_err(|_| format!("{text:?}: expected three numbers, e.g. 0,1,0"))
    }
}

impl<T: FlagValue> FlagValue for Option<T> {
    const LIST: bool = T::LIST;

    fn names() -> Option<Vec<&'static str>> {
        T::names()
    }

    fn parse_flag(text: &str) -> Result<Option<T>, String> {
        T::parse_flag(text).map(Some)
    }
}

impl<T: Named> FlagValue for T {
    fn names() -> Option<Vec<&'static str>> {
        Some(T::ALL.iter().map(|v| v.name()).collect())
    }

    fn parse_flag(text: &str) -> Result<T, String> {
        T::parse_named("value", text)
    }
}

/// One flag of a parameter section, as `params!` declares it.
#[derive(Clone, Copy, Debug)]
pub struct ParamFlag {
    /// The long flag without its dashes (`delta-max`).
    pub flag: &'static str,
    /// The field (config key) it sets.
    pub field: &'static str,
    /// One line for `--help`, the default in brackets.
    pub help: &'static str,
    /// For a switch (a flag without a value): the text it sets its field
    /// to (`--no-rotation` sets `random_rotation` to `false`).
    pub switch: Option<&'static str>,
    /// The names a value must be one of, when the field is a named setting.
    pub names: fn() -> Option<Vec<&'static str>>,
    /// Whether the value is a comma-separated list.
    pub list: bool,
    /// Whether a text parses as the field's type.
    pub check: fn(&str) -> Result<(), String>,
}

/// A parameter section (`[erosion]`, `[optimization]`, ...) declared by
/// `params!`.
pub trait ParamSection {
    /// Every flag of the section, in declaration order.
    const FLAGS: &'static [ParamFlag];

    /// Sets the field `flag` stands for from the flag's text (a switch's
    /// text is its [`ParamFlag::switch`]).
    fn set_flag(&mut self, flag: &str, text: &str) -> Result<(), String>;

    /// Every field with a TOML value, including those the section leaves
    /// out of its serialisation at their defaults (`--print-config` shows
    /// them all); an unset optional field has none.
    fn every_key(&self) -> toml::Table;
}

/// Declares a parameter section: the struct (serde: `default`,
/// `deny_unknown_fields`), its `Default` from each field's `= value`, and
/// a [`ParamSection`] whose flags are the fields marked
/// `=> "flag" : "help"` (a switch: `=> "no-flag" = "false" : "help"`).
/// Field attributes (doc comments, `serde(...)`) pass through.
macro_rules! params {
    (
        $(#[$sattr:meta])*
        pub struct $name:ident {
            $(
                $(#[$fattr:meta])*
                pub $field:ident : $ty:ty = $default:expr
                $(=> $flag:literal $(= $switch:literal)? : $help:literal)?
            ),* $(,)?
        }
    ) => {
        $(#[$sattr])*
        #[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
        #[serde(default, deny_unknown_fields)]
        pub struct $name {
            $( $(#[$fattr])* pub $field: $ty, )*
        }

        impl Default for $name {
            fn default() -> Self {
                $name { $( $field: $default, )* }
            }
        }

        impl $crate::methods::params::ParamSection for $name {
            const FLAGS: &'static [$crate::methods::params::ParamFlag] = &[
                $($(
                    $crate::methods::params::ParamFlag {
                        flag: $flag,
                        field: stringify!($field),
                        help: $help,
                        switch: $crate::methods::params::params!(@switch $($switch)?),
                        names: <$ty as $crate::methods::params::FlagValue>::names,
                        list: <$ty as $crate::methods::params::FlagValue>::LIST,
                        check: <$ty as $crate::methods::params::FlagValue>::check,
                    },
                )?)*
            ];

            fn set_flag(&mut self, flag: &str, text: &str) -> Result<(), String> {
                match flag {
                    $($(
                        $flag => {
                            self.$field =
                                <$ty as $crate::methods::params::FlagValue>::parse_flag(text)?;
                            Ok(())
                        }
                    )?)*
                    // A section without flags never reads `text`.
                    _ => Err(format!("no {} flag --{flag} {text}", stringify!($name))),
                }
            }

            fn every_key(&self) -> toml::Table {
                let mut table = toml::Table::new();
                $(
                    if let Ok(value) = toml::Value::try_from(&self.$field) {
                        table.insert(stringify!($field).into(), value);
                    }
                )*
                table
            }
        }
    };
    (@switch) => { None };
    (@switch $switch:literal) => { Some($switch) };
}

pub(crate) use params;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::methods::erosion::{ErosionParams, Placement};
    use crate::methods::optimization::OptimizationParams;

    #[test]
    fn values_parse_by_their_type_and_bad_text_says_what_was_expected() {
        assert_eq!(f32::parse_flag(" 0.25"), Ok(0.25));
        assert!(f32::parse_flag("abc").unwrap_err().contains("not a number"));
        assert!(u32::parse_flag("-3").is_err());
        assert_eq!(<Vec<u32>>::parse_flag("33,17,9"), Ok(vec![33, 17, 9]));
        assert_eq!(<[f32; 3]>::parse_flag("-1,0,0.5"), Ok([-1.0, 0.0, 0.5]));
        assert!(
            <[f32; 3]>::parse_flag("1,0")
                .unwrap_err()
                .contains("three numbers")
        );
        assert_eq!(<Option<f32>>::parse_flag("2"), Ok(Some(2.0)));
        assert_eq!(Placement::parse_flag("global"), Ok(Placement::Global));
        assert!(Placement::parse_flag("nowhere").is_err());
        assert_eq!(
            <Option<Placement>>::names(),
            Some(vec!["local", "global"]),
            "an optional named setting lists its names"
        );
        assert!(PathBuf::parse_flag("").is_err());
    }

    #[test]
    fn a_flag_sets_exactly_its_field() {
        // Every flag of a section, set alone from a value that differs from
        // the default, changes that field and no other.
        for spec in ErosionParams::FLAGS {
            let mut params = ErosionParams::default();
            let text = spec
                .switch
                .map(str::to_owned)
                .unwrap_or_else(|| match (spec.names)() {
                    Some(names) => names[names.len() - 1].to_owned(),
                    None if spec.list => "0.5,0.5,0.5".into(),
                    None => "7".into(),
                });
            params.set_flag(spec.flag, &text).expect("a valid value");
            let before = ErosionParams::default().every_key();
            let after = params.every_key();
            let changed: Vec<&String> = after
                .keys()
                .filter(|k| before.get(*k) != after.get(*k))
                .collect();
            assert_eq!(changed, vec![spec.field], "--{}", spec.flag);
        }
        let mut p = OptimizationParams::default();
        assert!(p.set_flag("no-such-flag", "1").is_err());
        assert!(p.set_flag("levels", "three").is_err());
        assert_eq!(
            p,
            OptimizationParams::default(),
            "a failed set changes nothing"
        );
    }

    #[test]
    fn every_key_names_fields_the_serialisation_leaves_out() {
        let p = ErosionParams::default();
        let serialised = toml::Table::try_from(&p).expect("serialisable");
        let every = p.every_key();
        assert!(!serialised.contains_key("transition"));
        assert_eq!(every.get("transition"), Some(&toml::Value::Integer(0)));
        // An unset optional field has no TOML value.
        assert!(!every.contains_key("radius"));
        for key in serialised.keys() {
            assert!(every.contains_key(key), "{key}");
        }
    }
}
