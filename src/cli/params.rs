//! The solver parameters on the command line, generated from the one table
//! [`sfs_core::params::PARAMS`]: one `--NAME VALUE` option per entry, with the
//! entry's help; values are parsed and range-checked by the table.

use clap::{Arg, ArgMatches, Args, Command, FromArgMatches};

use sfs_core::params::{PARAMS, ParamSpec};

/// The parameter options given on the command line, as written.
#[derive(Clone, Debug, Default)]
pub struct ParamArgs {
    given: Vec<(&'static ParamSpec, String)>,
}

impl Args for ParamArgs {
    fn augment_args(cmd: Command) -> Command {
        PARAMS.iter().fold(cmd, |cmd, spec| {
            cmd.arg(
                Arg::new(spec.name)
                    .long(spec.name)
                    .value_name("VALUE")
                    .allow_negative_numbers(true)
                    .help(spec.help)
                    .help_heading("Solver parameters"),
            )
        })
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}

impl FromArgMatches for ParamArgs {
    fn from_arg_matches(matches: &ArgMatches) -> Result<Self, clap::Error> {
        let given = PARAMS
            .iter()
            .filter_map(|spec| {
                matches
                    .get_one::<String>(spec.name)
                    .map(|text| (spec, text.clone()))
            })
            .collect();
        Ok(Self { given })
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(matches)?;
        Ok(())
    }
}

impl ParamArgs {
    /// The names of the table's options given on the command line (the
    /// table's options have no default on the command line: given means
    /// typed), in the table's order.
    pub fn given_names(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.given.iter().map(|(spec, _)| spec.name)
    }

    /// The table's options given, as typed, in the table's order.
    pub fn given(&self) -> &[(&'static ParamSpec, String)] {
        &self.given
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Probe {
        #[command(flatten)]
        params: ParamArgs,
    }

    /// Each table entry is an option; what is typed reaches the core's
    /// checks (whose own tests cover them) by name.
    #[test]
    fn options_come_from_the_table() {
        let probe = Probe::try_parse_from(["x", "--alpha", "3e-7", "--kappa", "3"]).expect("parse");
        let p = sfs_core::params::given::params_from_given(probe.params.given()).expect("params");
        assert_eq!(p.alpha, sfs_core::params::Alpha::Value(3e-7));
        assert_eq!(p.kappa, 3);
        let names: Vec<&str> = probe.params.given_names().collect();
        assert!(
            names.contains(&"kappa") && names.contains(&"alpha"),
            "{names:?}"
        );
        let bad = Probe::try_parse_from(["x", "--kappa", "10"]).expect("parse");
        assert_eq!(
            sfs_core::params::given::params_from_given(bad.params.given()).map_err(|e| e.name),
            Err("kappa")
        );
    }
}
