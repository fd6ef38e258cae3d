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
    /// The names of the table's options given on the command line (the
    /// table's options have no default on the command line: given means
    /// typed), in the table's order.
    pub fn given_names(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.given.iter().map(|(spec, _)| spec.name)
    }

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
        self.refuse_kappa_above_kappa_max(&params)?;
        Ok(params)
    }

    /// `kappa > kappa-max`, named by the option the user gave: `--kappa 10`
    /// alone exceeds kappa-max's default (5), which the user never set.
    fn refuse_kappa_above_kappa_max(&self, params: &SolverParams) -> Result<(), ParamError> {
        if params.kappa <= params.kappa_max {
            return Ok(());
        }
        let given = |name: &str| self.given.iter().find(|(spec, _)| spec.name == name);
        let (kappa, kappa_max) = (params.kappa, params.kappa_max);
        match (given("kappa"), given("kappa-max")) {
            (Some((_, text)), None) => Err(ParamError {
                name: "kappa",
                value: text.clone(),
                reason: format!(
                    "exceeds kappa-max's value {kappa_max} (the default; kappa-max is the most \
                     outer iterations per level and must be at least kappa): raise it with \
                     --kappa-max {kappa} or more"
                ),
            }),
            (None, Some((_, text))) => Err(ParamError {
                name: "kappa-max",
                value: text.clone(),
                reason: format!(
                    "is below kappa's value {kappa} (the default; kappa-max must be at least \
                     kappa): give --kappa-max {kappa} or more, or lower --kappa with it"
                ),
            }),
            _ => Ok(()), // both given, or neither: validate names kappa-max
        }
    }
}

/// Refuses a parameter that would do nothing whatever the image (`--h-z`
/// with exact derivatives) and a model's parameter given without its model
/// (`--roughness` without oren-nayar, `--specular` or `--shininess` without
/// blinn-phong; the models' table says whose each is): either would be
/// silently unused. `given`: the options as typed.
pub fn refuse_unused(
    params: &SolverParams,
    given: &[(&'static ParamSpec, String)],
) -> Result<(), ParamError> {
    if let Some((spec, text, why)) = given
        .iter()
        .find_map(|(spec, text)| params.inert(spec.name).map(|why| (spec, text, why)))
    {
        return Err(ParamError {
            name: spec.name,
            value: text.clone(),
            reason: why.to_owned(),
        });
    }
    match given.iter().find(|(spec, _)| !params.applies(spec.name)) {
        Some((spec, text)) => Err(ParamError {
            name: spec.name,
            value: text.clone(),
            reason: format!(
                "--{} belongs to --reflectance {} (the chosen reflectance does not use it)",
                spec.name,
                sfs_core::material::model_of_param(spec.name).map_or("", |m| m.name)
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

    /// `--kappa 10` alone blamed kappa-max's default ("kappa-max = 5: must
    /// be at least kappa"): the option given is named, with kappa-max's
    /// default and how to raise it.
    #[test]
    fn kappa_above_kappa_max_names_the_option_given() {
        let err = |args: &[&str]| {
            let probe = Probe::try_parse_from(args).expect("parse");
            probe.params.to_params().expect_err("refused").to_string()
        };
        let kappa = err(&["x", "--kappa", "10"]);
        assert!(kappa.contains("kappa = 10"), "{kappa}");
        assert!(
            kappa.contains("kappa-max's value 5 (the default"),
            "{kappa}"
        );
        assert!(kappa.contains("--kappa-max 10"), "{kappa}");
        let kappa_max = err(&["x", "--kappa-max", "3"]);
        assert!(kappa_max.contains("kappa-max = 3"), "{kappa_max}");
        assert!(
            kappa_max.contains("kappa's value 5 (the default"),
            "{kappa_max}"
        );
        let both =
            Probe::try_parse_from(["x", "--kappa", "10", "--kappa-max", "12"]).expect("parse");
        assert!(both.params.to_params().is_ok());
    }

    #[test]
    fn options_come_from_the_table_and_units_set_the_defaults() {
        let probe = Probe::try_parse_from(["x", "--alpha", "3e-7", "--kappa", "3"]).expect("parse");
        let p = probe.params.to_params().expect("params");
        assert_eq!(p.alpha, sfs_core::params::Alpha::Value(3e-7));
        assert_eq!(p.kappa, 3);
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
