//! The methods' parameter flags as clap arguments (`fluidtex run` flattens
//! [`MethodFlags`] into its own), built from the declarations
//! ([`MethodParams::flags`]) rather than written in the CLI: a parameter
//! added to a method's `params!` list gets its flag, its `--help` line and
//! its value check with no line elsewhere. It lives in the library so that
//! the registry's tests parse a test-only method's flag with the very
//! parser the CLI uses.

use super::params::ParamFlag;
use super::registry::MethodParams;
use clap::builder::{PossibleValuesParser, ValueParser};
use clap::{Arg, ArgAction, ArgMatches, Args, Command, FromArgMatches};

/// The method flags given on a command line, in declaration order, each
/// with its text (a switch: the text it writes).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MethodFlags {
    pub set: Vec<(&'static str, String)>,
}

/// Every method flag once, with its section: a flag several sections
/// declare (`--substeps`) is one argument, described by its first
/// section's help.
pub fn unique_flags() -> Vec<(&'static str, &'static ParamFlag)> {
    let mut seen = std::collections::BTreeSet::new();
    MethodParams::flags()
        .filter(|(_, f)| seen.insert(f.flag))
        .collect()
}

/// `--help` lists each section's flags under its own heading.
fn argument(section: &str, spec: &'static ParamFlag) -> Arg {
    let arg = Arg::new(spec.flag)
        .long(spec.flag)
        .help(spec.help)
        .help_heading(format!("Method parameters [{section}]"));
    if spec.switch.is_some() {
        return arg.action(ArgAction::SetTrue);
    }
    let value_name = spec.flag.to_uppercase().replace('-', "_");
    let arg = arg
        .action(ArgAction::Set)
        .value_name(value_name)
        .allow_hyphen_values(spec.list);
    match (spec.names)() {
        Some(names) => arg.value_parser(PossibleValuesParser::new(names)),
        None => {
            let check = spec.check;
            arg.value_parser(ValueParser::new(move |text: &str| {
                check(text).map(|()| text.to_owned())
            }))
        }
    }
}

impl Args for MethodFlags {
    fn augment_args(cmd: Command) -> Command {
        unique_flags()
            .into_iter()
            .fold(cmd, |cmd, (section, spec)| cmd.arg(argument(section, spec)))
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}

impl FromArgMatches for MethodFlags {
    fn from_arg_matches(matches: &ArgMatches) -> Result<Self, clap::Error> {
        let mut set = Vec::new();
        for (_, spec) in unique_flags() {
            match spec.switch {
                Some(text) => {
                    if matches.get_flag(spec.flag) {
                        set.push((spec.flag, text.to_owned()));
                    }
                }
                None => {
                    if let Some(text) = matches.get_one::<String>(spec.flag) {
                        set.push((spec.flag, text.clone()));
                    }
                }
            }
        }
        Ok(MethodFlags { set })
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(matches)?;
        Ok(())
    }
}

impl MethodFlags {
    /// Sets every given flag in `params` (in each section that declares it).
    pub fn apply(&self, params: &mut MethodParams) -> Result<(), String> {
        for (flag, text) in &self.set {
            params
                .set_flag(flag, text)
                .map_err(|e| format!("--{flag} {text}: {e}"))?;
        }
        Ok(())
    }
}
