//! The light options shared by `solve`, `synth` and `view`: `--light X,Y,Z`
//! (repeatable) with its direction, anisotropy and intensity in the same
//! order, and `--light-index K` for the lights of a camera file.

use anyhow::Result;
use clap::{Arg, ArgMatches, Args, Command, FromArgMatches};

use sfs_core::light::PointLight;
use sfs_core::material::Material;

/// Where the lights are (camera frame: x right, y down, z forward; units of
/// depth). Without `--light` the camera file's lights are used, else one
/// light at the optical centre (the paper's).
#[derive(Clone, Debug, Default, Args)]
#[command(allow_negative_numbers = true)]
pub struct LightArgs {
    /// A point light at X,Y,Z in the camera frame, units of depth
    /// (repeatable: lights on together are summed) [default: the camera
    /// file's lights, else 0,0,0].
    #[arg(long = "light", value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = super::parse::parse_floats::<3>)]
    pub positions: Vec<[f64; 3]>,
    /// The principal direction of each --light, in the same order (one value
    /// applies to all) [default: isotropic].
    #[arg(long = "light-dir", value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = super::parse::parse_floats::<3>)]
    pub directions: Vec<[f64; 3]>,
    /// The anisotropy mu of each --light (radiance ~ cos^mu of the angle to
    /// --light-dir; 0 isotropic, 1 Lambertian LED) [default: 0].
    #[arg(long = "light-mu", value_name = "MU")]
    pub mus: Vec<f64>,
    /// The relative intensity of each --light [default: 1].
    #[arg(long = "light-intensity", value_name = "PHI")]
    pub intensities: Vec<f64>,
    /// With a camera file listing lights (a near_ps calibration.json): the
    /// light whose `led` number is K (repeatable: summed) [default: the light
    /// whose `image` is the photograph's file name].
    #[arg(long = "light-index", value_name = "K")]
    pub indices: Vec<u32>,
}

impl LightArgs {
    /// The lights of `--light` and its companions (validated), or `None`
    /// without `--light`.
    pub fn lights(&self) -> Result<Option<Vec<PointLight>>> {
        sfs_core::light::lights_from_options(
            &self.positions,
            &self.directions,
            &self.mus,
            &self.intensities,
        )
        .map_err(anyhow::Error::msg)
    }
}

/// The material of a rendered or evaluated surface (METHOD.md section 10):
/// `synth` renders with it, `eval` measures with it. The options are
/// `--reflectance MODEL` and each model's parameters, named, read and checked
/// as `solve`'s parameters of the same names (the models' table
/// [`sfs_core::material::MODELS`] lists them).
#[derive(Debug, Clone, Default)]
pub struct MaterialArgs {
    given: Vec<(&'static str, String)>,
}

/// The option names of [`MaterialArgs`]: `reflectance`, then every model's
/// parameters.
fn material_options() -> impl Iterator<Item = &'static str> {
    std::iter::once("reflectance").chain(
        sfs_core::material::MODELS
            .iter()
            .flat_map(|m| m.params.iter().map(|p| p.name)),
    )
}

impl Args for MaterialArgs {
    fn augment_args(cmd: Command) -> Command {
        let models = sfs_core::material::MODEL_NAMES;
        let cmd = cmd.arg(
            Arg::new("reflectance")
                .long("reflectance")
                .value_name("MODEL")
                .value_parser(clap::builder::PossibleValuesParser::new(models))
                .help(format!("Reflectance model: {}.", models.join(", "))),
        );
        sfs_core::material::MODELS.iter().fold(cmd, |cmd, model| {
            model.params.iter().fold(cmd, |cmd, param| {
                cmd.arg(
                    Arg::new(param.name)
                        .long(param.name)
                        .value_name("VALUE")
                        .value_parser(clap::value_parser!(f64))
                        .help(format!(
                            "With --reflectance {}: {}",
                            model.name,
                            sfs_core::params::table::spec(param.name).map_or("", |s| s.help)
                        )),
                )
            })
        })
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}

impl FromArgMatches for MaterialArgs {
    fn from_arg_matches(matches: &ArgMatches) -> Result<Self, clap::Error> {
        let given = material_options()
            .filter_map(|name| {
                let text = if name == "reflectance" {
                    matches.get_one::<String>(name).cloned()
                } else {
                    matches.get_one::<f64>(name).map(|v| v.to_string())
                };
                text.map(|text| (name, text))
            })
            .collect();
        Ok(Self { given })
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(matches)?;
        Ok(())
    }
}

impl MaterialArgs {
    /// The material asked for, read and checked by the parameter table's
    /// entries of the same names (ranges, a model's parameter only with its
    /// model); `None` when no option is given.
    pub fn material(&self) -> Result<Option<Material>> {
        let mut given = Vec::new();
        for (name, text) in &self.given {
            if let Some(spec) = sfs_core::params::table::spec(name) {
                given.push((spec, text.clone()));
            }
        }
        if given.is_empty() {
            return Ok(None);
        }
        let mut params = sfs_core::params::SolverParams::default();
        for (spec, text) in &given {
            (spec.set)(&mut params, spec.parse(text)?);
        }
        sfs_core::params::given::refuse_unused(&params, &given)?;
        Ok(params.fixed_material())
    }
}
