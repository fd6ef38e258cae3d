//! The solver parameters on the command line, generated from the one table
//! [`sfs_core::params::PARAMS`]: one `--NAME VALUE` option per entry, with the
//! entry's help; values are parsed and range-checked by the table.

use clap::{Arg, ArgMatches, Args, Command, FromArgMatches};

use sfs_core::params::{PARAMS, ParamError, ParamSpec, SolverParams};

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
    /// Parameters from the given options over the defaults of the chosen
    /// `--units` (the defaults of lambda and dz-limit depend on them). The
    /// error names the first bad option.
    pub fn to_params(&self) -> Result<SolverParams, ParamError> {
        let mut values = Vec::with_capacity(self.given.len());
        for (spec, text) in &self.given {
            values.push((*spec, spec.parse(text)?));
        }
        let params = sfs_core::params::table::params_from(values);
        refuse_unused(&params, &self.given)?;
        Ok(params)
    }
}

/// Refuses a model's parameter given without its model (`--roughness`
/// without oren-nayar, `--specular` or `--shininess` without blinn-phong):
/// it would be silently unused. `given`: the options as typed.
pub fn refuse_unused(
    params: &SolverParams,
    given: &[(&'static ParamSpec, String)],
) -> Result<(), ParamError> {
    match given.iter().find(|(spec, _)| !params.applies(spec.name)) {
        Some((spec, text)) => Err(ParamError {
            name: spec.name,
            value: text.clone(),
            reason: format!(
                "--{} belongs to --reflectance {} (the chosen reflectance does not use it)",
                spec.name,
                if spec.name == "roughness" {
                    "oren-nayar"
                } else {
                    "blinn-phong"
                }
            ),
        }),
        None => Ok(()),
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

    #[test]
    fn a_models_parameter_without_its_model_is_refused() {
        let probe = Probe::try_parse_from(["x", "--roughness", "0.5"]).expect("parse");
        let err = probe.params.to_params().expect_err("no oren-nayar");
        assert!(err.to_string().contains("oren-nayar"), "{err}");
        let probe = Probe::try_parse_from(["x", "--reflectance", "oren-nayar", "--shininess", "9"])
            .expect("parse");
        assert!(probe.params.to_params().is_err());
        let probe = Probe::try_parse_from([
            "x",
            "--reflectance",
            "blinn-phong",
            "--specular",
            "0.5",
            "--shininess",
            "40",
        ])
        .expect("parse");
        let p = probe.params.to_params().expect("params");
        assert_eq!(
            p.fixed_material(),
            Some(sfs_core::material::Material::BlinnPhong {
                specular: 0.5,
                shininess: 40.0
            })
        );
    }

    #[test]
    fn options_come_from_the_table_and_units_set_the_defaults() {
        let probe = Probe::try_parse_from(["x", "--alpha", "3e-7", "--kappa", "7"]).expect("parse");
        let p = probe.params.to_params().expect("params");
        assert_eq!(p.alpha, sfs_core::params::Alpha::Value(3e-7));
        assert_eq!(p.kappa, 7);
        assert_eq!(p.lambda, SolverParams::default().lambda);
        let paper = Probe::try_parse_from(["x", "--units", "paper"]).expect("parse");
        let p = paper.params.to_params().expect("params");
        assert_eq!((p.lambda, p.dz_limit), (1e-3, 0.01));
        let bad = Probe::try_parse_from(["x", "--eta", "1.5"]).expect("parse");
        assert_eq!(bad.params.to_params().map_err(|e| e.name), Err("eta"));
        let negative = Probe::try_parse_from(["x", "--alpha", "-1"]).expect("parse");
        assert_eq!(
            negative.params.to_params().map_err(|e| e.name),
            Err("alpha")
        );
    }
}
