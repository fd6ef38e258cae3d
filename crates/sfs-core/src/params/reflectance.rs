//! The reflectance in [`SolverParams`], read through the models' table
//! ([`crate::material::MODELS`]) and the parameter table: which material the
//! parameters ask for, parameters set to a material, and which parameters
//! the chosen model uses. No model is named here.

use super::settings::{AlbedoChoice, SolverParams};
use super::table::{ParamValue, spec};
use crate::material::{Material, ModelParam, model_of_param};

impl SolverParams {
    /// A model parameter's value here (its entry in the parameter table);
    /// its default if the table lacks it (a test keeps every one there).
    fn model_param(&self, param: &ModelParam) -> f64 {
        match spec(param.name).map(|s| (s.get)(self)) {
            Some(ParamValue::Real(v)) => v,
            _ => param.default,
        }
    }

    /// The material these parameters ask for; `None` for
    /// [`super::ReflectanceChoice::Auto`] (fitted by `solver::material_fit`).
    pub fn fixed_material(&self) -> Option<Material> {
        let model = self.reflectance.model()?;
        Some(model.material(|param| self.model_param(param)))
    }

    /// The material a solve uses: [`SolverParams::fixed_material`], Lambert
    /// while `auto` is unresolved (the solvers resolve it first).
    pub fn material(&self) -> Material {
        self.fixed_material().unwrap_or_default()
    }

    /// These parameters with `auto` taken as the material it solves with
    /// (Lambert) and albedo 1: for trial solves that must not compare the
    /// materials again each time, and searches whose trials must all solve
    /// one model (with `--albedo auto` deciding per trial, a known-depth
    /// search missed its distance by 6 % on a render).
    pub fn without_fit(&self) -> Self {
        let mut params = self.clone().with_material(self.material());
        params.albedo = AlbedoChoice::One;
        params
    }

    /// These parameters set to `material` (its model and parameters).
    pub fn with_material(mut self, material: Material) -> Self {
        let model = material.model();
        self.reflectance = model.choice;
        for param in model.params {
            if let Some(spec) = spec(param.name) {
                (spec.set)(&mut self, ParamValue::Real((param.get)(&material)));
            }
        }
        self
    }

    /// True when the named parameter matters for the chosen reflectance: a
    /// model's parameter ([`crate::material::Model::params`]) only with its
    /// model, everything else always. The viewer shows a model's sliders
    /// only when it is chosen.
    pub fn applies(&self, name: &str) -> bool {
        match model_of_param(name) {
            Some(owner) => owner.choice == self.reflectance,
            None => true,
        }
    }

    /// Why the named parameter, given, would do nothing whatever the image
    /// (`h-z` without numeric derivatives); `None` when it may act.
    pub fn inert(&self, name: &str) -> Option<&'static str> {
        match (name, self.derivatives) {
            ("h-z", crate::model::Derivatives::Exact) => Some(
                "--h-z is the step of numeric derivatives and the derivatives are exact                  (give --derivatives numeric with it)",
            ),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::table::PARAMS;
    use super::*;
    use crate::material::{MODELS, ReflectanceChoice};

    /// Every model round-trips name -> choice -> material -> name, and its
    /// parameters are exactly the parameter table's entries that apply only
    /// with it.
    #[test]
    fn every_model_round_trips_and_owns_exactly_its_parameters() {
        for model in MODELS {
            let choice = ReflectanceChoice::from_name(model.name).expect("a model's name parses");
            assert_eq!(choice, model.choice);
            assert_eq!(choice.name(), model.name);
            let reflectance = spec("reflectance").expect("reflectance in the table");
            let word = reflectance.parse(model.name).expect("the table accepts it");
            let mut params = SolverParams::default();
            (reflectance.set)(&mut params, word);
            assert_eq!(params.reflectance, choice);
            assert_eq!((reflectance.get)(&params), ParamValue::Choice(model.name));
            let material = params.fixed_material().expect("a model is fixed");
            assert_eq!(material.name(), model.name);
            assert_eq!(material.choice(), choice);
            assert_eq!(material, model.base, "{}: the defaults", model.name);
            assert!(material.validated().is_ok(), "{}", model.name);
            // serde spells the choice as the table does.
            assert_eq!(
                serde_json::to_value(choice).expect("serialises"),
                serde_json::json!(model.name)
            );
            // Parameters: each in the table with the model's range, and
            // the table's entries that apply only with this model are these.
            let own: Vec<&str> = PARAMS
                .iter()
                .filter(|s| {
                    params.applies(s.name)
                        && MODELS
                            .iter()
                            .filter(|other| other.name != model.name)
                            .all(|other| !params.clone().with_material(other.base).applies(s.name))
                })
                .map(|s| s.name)
                .collect();
            let listed: Vec<&str> = model.params.iter().map(|p| p.name).collect();
            assert_eq!(own, listed, "{}", model.name);
            for param in model.params {
                let entry = spec(param.name).expect("a model parameter is in the table");
                match entry.kind {
                    super::super::ParamKind::Real { min, max, .. } => {
                        assert_eq!((min, max), param.range, "{}", param.name)
                    }
                    kind => panic!("{}: {kind:?}", param.name),
                }
                assert_eq!(
                    (entry.get)(&SolverParams::default()),
                    ParamValue::Real(param.default)
                );
                // Written to and read from a material and the parameters.
                let (low, high) = param.range;
                let v = low + 0.25 * (high - low);
                let set = params.clone().with_material(
                    model.material(|p| if p.name == param.name { v } else { p.default }),
                );
                assert_eq!((entry.get)(&set), ParamValue::Real(v));
                assert_eq!(set.fixed_material().map(|m| (param.get)(&m)), Some(v));
            }
            // auto's candidates: the grid names every parameter.
            if let Some(grid) = model.fit_grid {
                assert_eq!(grid.len(), model.params.len(), "{}", model.name);
                for m in model.fit_candidates() {
                    assert_eq!(m.choice(), choice);
                    assert!(m.validated().is_ok(), "{m:?}");
                }
            }
        }
        assert_eq!(
            ReflectanceChoice::from_name("auto"),
            Some(ReflectanceChoice::Auto)
        );
        assert_eq!(ReflectanceChoice::Auto.name(), "auto");
        assert_eq!(ReflectanceChoice::from_name("glossy"), None);
    }
}
