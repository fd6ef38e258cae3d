//! Parameters from the options a user typed (`--kappa 10`, Python's
//! `kappa=10`), checked in the user's terms once for every front: each
//! value by its table entry, then what the values mean together — a
//! parameter that would do nothing whatever the image, a model's
//! parameter without its model, `kappa` above `kappa-max` named by the
//! option the user gave.
//!
//! Uses: `params::table` (the entries), `material` (whose parameter each
//! is).

use super::settings::SolverParams;
use super::table::{ParamError, ParamSpec, params_from};

/// The options given, as typed: each table entry with its text, in the
/// table's order.
pub type Given = [(&'static ParamSpec, String)];

/// Parameters from the options given over the defaults of the chosen
/// `--units` (the defaults of lambda and dz-limit depend on them). The
/// error names the first bad option.
pub fn params_from_given(given: &Given) -> Result<SolverParams, ParamError> {
    let mut values = Vec::with_capacity(given.len());
    for (spec, text) in given {
        values.push((*spec, spec.parse(text)?));
    }
    let params = params_from(values);
    refuse_unused(&params, given)?;
    refuse_kappa_above_kappa_max(&params, given)?;
    Ok(params)
}

/// Refuses a parameter that would do nothing whatever the image (`--h-z`
/// with exact derivatives) and a model's parameter given without its model
/// (`--roughness` without oren-nayar, `--specular` or `--shininess` without
/// blinn-phong; the models' table says whose each is): either would be
/// silently unused.
pub fn refuse_unused(params: &SolverParams, given: &Given) -> Result<(), ParamError> {
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
                crate::material::model_of_param(spec.name).map_or("", |m| m.name)
            ),
        }),
        None => Ok(()),
    }
}

/// `kappa > kappa-max`, named by the option the user gave: `--kappa 10`
/// alone exceeds kappa-max's default (5), which the user never set.
fn refuse_kappa_above_kappa_max(params: &SolverParams, given: &Given) -> Result<(), ParamError> {
    if params.kappa <= params.kappa_max {
        return Ok(());
    }
    let typed = |name: &str| given.iter().find(|(spec, _)| spec.name == name);
    let (kappa, kappa_max) = (params.kappa, params.kappa_max);
    match (typed("kappa"), typed("kappa-max")) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::table::spec;

    fn given(pairs: &[(&str, &str)]) -> Vec<(&'static ParamSpec, String)> {
        pairs
            .iter()
            .map(|(name, text)| (spec(name).expect("a table entry"), (*text).to_owned()))
            .collect()
    }

    /// A model's parameter without its model is refused by name.
    #[test]
    fn a_models_parameter_without_its_model_is_refused() {
        let err = params_from_given(&given(&[("roughness", "0.5")])).expect_err("no oren-nayar");
        assert!(err.to_string().contains("oren-nayar"), "{err}");
        assert!(
            params_from_given(&given(&[("reflectance", "oren-nayar"), ("shininess", "9")]))
                .is_err()
        );
        let p = params_from_given(&given(&[
            ("reflectance", "blinn-phong"),
            ("specular", "0.5"),
            ("shininess", "40"),
        ]))
        .expect("params");
        assert_eq!(
            p.fixed_material(),
            Some(crate::material::Material::BlinnPhong {
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
        let err = |pairs: &[(&str, &str)]| {
            params_from_given(&given(pairs))
                .expect_err("refused")
                .to_string()
        };
        let kappa = err(&[("kappa", "10")]);
        assert!(kappa.contains("kappa = 10"), "{kappa}");
        assert!(
            kappa.contains("kappa-max's value 5 (the default"),
            "{kappa}"
        );
        assert!(kappa.contains("--kappa-max 10"), "{kappa}");
        let kappa_max = err(&[("kappa-max", "3")]);
        assert!(kappa_max.contains("kappa-max = 3"), "{kappa_max}");
        assert!(
            kappa_max.contains("kappa's value 5 (the default"),
            "{kappa_max}"
        );
        assert!(params_from_given(&given(&[("kappa", "10"), ("kappa-max", "12")])).is_ok());
    }

    /// Values over the units' defaults; a bad value names its option.
    #[test]
    fn options_come_from_the_table_and_units_set_the_defaults() {
        let p = params_from_given(&given(&[("alpha", "3e-7"), ("kappa", "3")])).expect("params");
        assert_eq!(p.alpha, crate::params::Alpha::Value(3e-7));
        assert_eq!(p.kappa, 3);
        assert_eq!(p.lambda, SolverParams::default().lambda);
        let p = params_from_given(&given(&[("units", "paper")])).expect("params");
        assert_eq!((p.lambda, p.dz_limit), (1e-3, 0.01));
        assert_eq!(
            params_from_given(&given(&[("eta", "1.5")])).map_err(|e| e.name),
            Err("eta")
        );
        assert_eq!(
            params_from_given(&given(&[("alpha", "-1")])).map_err(|e| e.name),
            Err("alpha")
        );
    }
}
