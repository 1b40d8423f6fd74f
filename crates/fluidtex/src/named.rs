//! Enumerated settings that have a name on the command line and in config
//! files (`--method erosion`, `placement = "local"`): one list of names per
//! type, used for parsing, for messages and by front ends (clap's possible
//! values), so a name is never spelled in two places.

/// A setting with a fixed set of named values.
pub trait Named: Sized + Copy + 'static {
    /// Every value, in the order front ends list them.
    const ALL: &'static [Self];

    /// The value's name.
    fn name(self) -> &'static str;

    /// The value called `name`.
    fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|v| v.name() == name)
    }

    /// Every name, comma-separated (for messages).
    fn names() -> String {
        Self::ALL
            .iter()
            .map(|v| v.name())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// [`Named::from_name`] with a one-line error naming the valid values.
    fn parse_named(what: &str, name: &str) -> Result<Self, String> {
        Self::from_name(name)
            .ok_or_else(|| format!("unknown {what} {name}; available: {}", Self::names()))
    }
}

/// Implements [`Named`] for a fieldless enum from `Variant => "name"` pairs.
#[macro_export]
macro_rules! named {
    ($ty:ty { $($variant:ident => $name:literal),+ $(,)? }) => {
        impl $crate::named::Named for $ty {
            const ALL: &'static [Self] = &[$(<$ty>::$variant),+];

            fn name(self) -> &'static str {
                match self {
                    $(<$ty>::$variant => $name),+
                }
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exemplar::{ExemplarFilter, FeatureMethod};
    use crate::methods::erosion::{Falloff, Orientation, Placement, WeightMode};
    use crate::methods::registry::MethodKind;

    fn round_trip<T: Named + PartialEq + std::fmt::Debug>() {
        for &v in T::ALL {
            assert_eq!(T::from_name(v.name()), Some(v));
        }
        let mut names: Vec<_> = T::ALL.iter().map(|v| v.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), T::ALL.len(), "names are unique");
        assert_eq!(T::from_name("no-such-value"), None);
    }

    #[test]
    fn every_name_parses_back_to_its_value() {
        round_trip::<MethodKind>();
        round_trip::<Placement>();
        round_trip::<WeightMode>();
        round_trip::<Falloff>();
        round_trip::<Orientation>();
        round_trip::<FeatureMethod>();
        round_trip::<ExemplarFilter>();
        round_trip::<crate::methods::optimization::Histogram>();
    }

    #[test]
    fn a_bad_name_gets_a_message_listing_the_valid_ones() {
        let err = Placement::parse_named("placement", "everywhere").expect_err("unknown");
        assert_eq!(
            err,
            "unknown placement everywhere; available: local, global"
        );
    }

    #[test]
    fn serde_names_are_the_command_line_names() {
        // Config files and flags must accept the same words.
        for &m in MethodKind::ALL {
            assert_eq!(
                serde_json::to_string(&m).expect("serialize"),
                format!("\"{}\"", m.name())
            );
        }
        for &p in Placement::ALL {
            assert_eq!(
                serde_json::to_string(&p).expect("serialize"),
                format!("\"{}\"", p.name())
            );
        }
    }
}
