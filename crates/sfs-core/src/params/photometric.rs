//! The photometric-stereo parameters a user sets (`--ps-*`, the viewer's
//! set panel): one entry each with its one rule, which the command line's
//! parsing and messages, the viewer's control and
//! `PhotometricParams::validate` all apply. The values live in
//! `solver::photometric::PhotometricParams` (above this table: it names no
//! solver type).

use super::table::ParamError;

/// Which numbers a parameter accepts (besides `auto`, always accepted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PsRule {
    /// Finite and at least 0.
    NonNegative,
    /// Finite and above 0 (the value divides something).
    Positive,
}

/// One photometric-stereo parameter: `auto` (`None`) or a number.
#[derive(Clone, Copy, Debug)]
pub struct PsParamSpec {
    /// Name on the command line (`--NAME`) and in errors.
    pub name: &'static str,
    /// What it does.
    pub help: &'static str,
    /// The numbers it accepts.
    pub rule: PsRule,
    /// The viewer's control range, inside the rule (a logarithmic slider);
    /// `None`: not in the viewer.
    pub slider: Option<(f64, f64)>,
}

impl PsParamSpec {
    /// What a valid value is, in words: ``must be `auto` or …``.
    pub fn accepted(&self) -> &'static str {
        match self.rule {
            PsRule::NonNegative => "must be `auto` or a non-negative number",
            PsRule::Positive => "must be `auto` or a positive number (above 0)",
        }
    }

    /// True when the number fits the rule.
    pub fn admits(&self, value: f64) -> bool {
        value.is_finite()
            && match self.rule {
                PsRule::NonNegative => value >= 0.0,
                PsRule::Positive => value > 0.0,
            }
    }

    fn error(&self, value: impl ToString) -> ParamError {
        ParamError {
            name: self.name,
            value: value.to_string(),
            reason: self.accepted().to_owned(),
        }
    }

    /// Checks a value (`None`: auto).
    pub fn check(&self, value: Option<f64>) -> Result<(), ParamError> {
        match value {
            Some(v) if !self.admits(v) => Err(self.error(v)),
            _ => Ok(()),
        }
    }

    /// Parses and checks a value written as text: `auto` (any case) is
    /// `None`.
    pub fn parse(&self, text: &str) -> Result<Option<f64>, ParamError> {
        let trimmed = text.trim();
        if trimmed.eq_ignore_ascii_case("auto") {
            return Ok(None);
        }
        match trimmed.parse::<f64>() {
            Ok(v) if self.admits(v) => Ok(Some(v)),
            _ => Err(self.error(text)),
        }
    }

    /// Reads `--NAME TEXT` as a user typed it: `auto` (`None`) or a
    /// number under the rule, else the message the command line gives
    /// (`--ps-robust-scale -1: ...` with what is accepted).
    pub fn read_option(&self, text: &str) -> Result<Option<f64>, String> {
        self.parse(text)
            .map_err(|_| format!("--{} {text}: {}", self.name, self.accepted()))
    }

    /// A stored value as the viewer keeps it: inside the rule and the
    /// slider's range, else auto (`None`).
    pub fn in_slider(&self, value: Option<f64>) -> Option<f64> {
        let (low, high) = self.slider?;
        value.filter(|&v| self.admits(v) && (low..=high).contains(&v))
    }
}

/// The smoothness weight of a set (relative), `PhotometricParams::alpha`.
pub const PS_SMOOTHNESS: PsParamSpec = PsParamSpec {
    name: "ps-smoothness",
    help: "The set's smoothness weight (relative: the log-depth's second derivatives times \
           f^2), or `auto` (default): from the photographs' noise.",
    rule: PsRule::NonNegative,
    slider: Some((1e-9, 1e-1)),
};

/// The Cauchy scale of a set's residuals relative to the brightness,
/// `PhotometricParams::robust_scale`: it divides the residuals.
pub const PS_ROBUST_SCALE: PsParamSpec = PsParamSpec {
    name: "ps-robust-scale",
    help: "The Cauchy scale of the residuals relative to the brightness, or `auto` \
           (default): from the residuals' median.",
    rule: PsRule::Positive,
    slider: None,
};

/// Every photometric-stereo parameter a user sets.
pub const PS_PARAMS: &[PsParamSpec] = &[PS_SMOOTHNESS, PS_ROBUST_SCALE];

/// The photometric-stereo entry called `name`.
pub fn ps_spec(name: &str) -> Option<&'static PsParamSpec> {
    PS_PARAMS.iter().find(|s| s.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_rule_per_parameter_and_the_slider_inside_it() {
        assert_eq!(
            PS_ROBUST_SCALE.parse("-1").unwrap_err().name,
            "ps-robust-scale"
        );
        assert!(PS_ROBUST_SCALE.parse("0").is_err());
        assert_eq!(PS_ROBUST_SCALE.parse(" AUTO ").ok(), Some(None));
        assert_eq!(PS_SMOOTHNESS.parse("0").ok(), Some(Some(0.0)));
        assert!(PS_SMOOTHNESS.check(Some(f64::NAN)).is_err());
        for spec in PS_PARAMS {
            assert_eq!(ps_spec(spec.name).map(|s| s.name), Some(spec.name));
            if let Some((low, high)) = spec.slider {
                assert!(
                    low < high && spec.admits(low) && spec.admits(high),
                    "{}",
                    spec.name
                );
                assert_eq!(spec.in_slider(Some(-1.0)), None);
            }
        }
    }
}
