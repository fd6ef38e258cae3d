//! The light options shared by `solve`, `synth` and `view`: `--light X,Y,Z`
//! (repeatable) with its direction, anisotropy and intensity in the same
//! order, and `--light-index K` for the lights of a camera file.

use anyhow::{Result, bail};
use clap::Args;

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

/// One value per light from a list given once (for all) or once per light.
fn per_light<T: Copy>(values: &[T], lights: usize, name: &str) -> Result<Vec<Option<T>>> {
    match values.len() {
        0 => Ok(vec![None; lights]),
        1 => Ok(vec![Some(values[0]); lights]),
        n if n == lights => Ok(values.iter().map(|&v| Some(v)).collect()),
        n => bail!(
            "--{name} is given {n} times for {lights} --light: give it once or once per light"
        ),
    }
}

impl LightArgs {
    /// The lights of `--light` and its companions (validated), or `None`
    /// without `--light`.
    pub fn lights(&self) -> Result<Option<Vec<PointLight>>> {
        if self.positions.is_empty() {
            if !(self.directions.is_empty() && self.mus.is_empty() && self.intensities.is_empty()) {
                bail!("--light-dir, --light-mu and --light-intensity need --light X,Y,Z");
            }
            return Ok(None);
        }
        let n = self.positions.len();
        let directions = per_light(&self.directions, n, "light-dir")?;
        let mus = per_light(&self.mus, n, "light-mu")?;
        let intensities = per_light(&self.intensities, n, "light-intensity")?;
        let mut lights = Vec::with_capacity(n);
        for k in 0..n {
            let light = PointLight {
                position: self.positions[k],
                direction: directions[k],
                mu: mus[k].unwrap_or(0.0),
                intensity: intensities[k].unwrap_or(1.0),
            };
            if light.mu > 0.0 && light.direction.is_none() {
                bail!(
                    "--light-mu {} for light {} needs --light-dir",
                    light.mu,
                    k + 1
                );
            }
            lights.push(
                light
                    .validated(k + 1)
                    .map_err(|e| anyhow::anyhow!("--light: {e}"))?,
            );
        }
        Ok(Some(lights))
    }
}

/// The material of a rendered or evaluated surface (METHOD.md section 10):
/// `synth` renders with it, `eval` measures with it. The names are those of
/// `solve`'s parameters of the same meaning.
#[derive(Debug, Clone, Args)]
pub struct MaterialArgs {
    /// Reflectance model: lambert, oren-nayar or blinn-phong.
    #[arg(long, value_name = "MODEL", value_parser = ["lambert", "oren-nayar", "blinn-phong"])]
    pub reflectance: Option<String>,
    /// Oren-Nayar roughness sigma, radians [default: 0.3].
    #[arg(long, value_name = "SIGMA")]
    pub roughness: Option<f64>,
    /// Blinn-Phong specular weight k_s [default: 0.3].
    #[arg(long, value_name = "KS")]
    pub specular: Option<f64>,
    /// Blinn-Phong shininess n [default: 20].
    #[arg(long, value_name = "N")]
    pub shininess: Option<f64>,
}

impl MaterialArgs {
    /// The material asked for, read and checked by the parameter table's
    /// entries of the same names (ranges, a model's parameter only with its
    /// model); `None` when no option is given.
    pub fn material(&self) -> Result<Option<Material>> {
        let typed = [
            ("reflectance", self.reflectance.clone()),
            ("roughness", self.roughness.map(|v| v.to_string())),
            ("specular", self.specular.map(|v| v.to_string())),
            ("shininess", self.shininess.map(|v| v.to_string())),
        ];
        let mut given = Vec::new();
        for (name, text) in typed {
            if let (Some(spec), Some(text)) = (sfs_core::params::table::spec(name), text) {
                given.push((spec, text));
            }
        }
        if given.is_empty() {
            return Ok(None);
        }
        let mut params = sfs_core::params::SolverParams::default();
        for (spec, text) in &given {
            (spec.set)(&mut params, spec.parse(text)?);
        }
        super::params::refuse_unused(&params, &given)?;
        Ok(params.fixed_material())
    }
}
