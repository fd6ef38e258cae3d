//! The two ways a synthetic scene's image is shaded (METHOD.md section 12):
//! from the renderer's own normals (a mesh's interpolated normals, the
//! Sombrero's exact gradient), or from the ground-truth depth map through
//! the solver's image formation (the model's upwind derivatives over object
//! neighbours only), under which the true depth explains the image exactly.

use super::Scene;
use crate::cancel::{Cancel, Uncancelled};
use crate::light::LightModel;
use crate::model::{self, LevelGeometry};

/// How a scene's image is computed from its geometry.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Shading {
    /// The renderer's own normals: a mesh's interpolated vertex normals,
    /// the Sombrero's exact gradient. Physically closer to a photograph; at
    /// occlusion edges and creases the image and the depth map disagree.
    #[default]
    Mesh,
    /// The depth map through the solver's model (METHOD.md Eq. 5 and its
    /// generalisations to lights anywhere and other materials) with the
    /// upwind derivatives of section 3, object neighbours only: the true
    /// depth has zero data residual (the paper's Table 1 convention).
    DepthMap,
}

impl Shading {
    /// Every shading with its name on the command line.
    pub const NAMES: [(&'static str, Shading); 2] =
        [("mesh", Shading::Mesh), ("depth-map", Shading::DepthMap)];

    /// The shading called `name` (`mesh` or `depth-map`).
    pub fn from_name(name: &str) -> Option<Shading> {
        Self::NAMES
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, shading)| *shading)
    }

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Shading::Mesh => "mesh",
            Shading::DepthMap => "depth-map",
        }
    }

    /// `scene` shaded this way: itself for [`Shading::Mesh`] (renderers
    /// shade with their normals), [`shade_from_depth`] for
    /// [`Shading::DepthMap`].
    pub fn apply(self, scene: Scene) -> Scene {
        match self {
            Shading::Mesh => scene,
            Shading::DepthMap => shade_from_depth(&scene),
        }
    }
}

/// `scene` with its image recomputed from its ground-truth depth by the
/// solver's own image formation: the reflectance the solver would use for
/// the scene's intensity scale, lights and material
/// ([`LightModel::with_material`]), evaluated by [`model::reproject`] with
/// the upwind derivatives over the object's pixels only. Everything else
/// (depth, mask, camera, lights, material, intensity scale) is kept, so the
/// two shadings of one scene differ in their image alone, except where the
/// image would exceed 1: then image and scale are scaled down together to
/// the scene's own brightest value. The normals are
/// dropped (the image was not shaded with them). A pixel whose value is not
/// finite gets 0, as the solver's reprojection does.
pub fn shade_from_depth(scene: &Scene) -> Scene {
    let (w, h) = scene.depth_gt.size();
    let model = LightModel::with_material(scene.intensity_scale, &scene.lights, scene.material);
    let geometry = LevelGeometry::new(w, h, w, h, scene.camera);
    let image = model::reproject(
        &model,
        &geometry,
        &scene.object_mask,
        &scene.depth_gt,
        Cancel::NEVER,
    )
    .uncancelled();
    // The same intensity scale as the scene's own shading, so both images
    // compare pixel for pixel; where the depth's upwind slopes would make a
    // pixel brighter than 1 (a highlight the interpolated normals spread
    // out), the image and the scale are brought down together so the
    // brightest pixel is the scene's own brightest (a saturated file would
    // no longer follow the model).
    let brightest = image.as_slice().iter().copied().fold(0.0, f64::max);
    let own_brightest = scene.image.as_slice().iter().copied().fold(0.0, f64::max);
    let (image, intensity_scale) = if brightest > 1.0 && own_brightest > 0.0 {
        let k = own_brightest.min(1.0) / brightest;
        (image.map(|v| v * k), scene.intensity_scale * k)
    } else {
        (image, scene.intensity_scale)
    };
    Scene {
        image,
        intensity_scale,
        normals: None,
        ..scene.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;
    use crate::model::energy;
    use crate::params::{InitialDepth, SolverParams};
    use crate::scene::sombrero::sombrero;
    use crate::solver::{Problem, solve};

    fn problem(scene: &Scene) -> Problem {
        Problem {
            image: scene.image.clone(),
            camera: scene.camera,
            intensity_scale: scene.intensity_scale,
            object_mask: Some(scene.object_mask.clone()),
            confidence: None,
            lights: Vec::new(),
        }
    }

    /// The data energy of `depth` against `scene`'s image, per object pixel.
    fn data_per_pixel(scene: &Scene, depth: &Grid<f64>) -> f64 {
        let (w, h) = scene.image.size();
        let model = LightModel::with_material(scene.intensity_scale, &scene.lights, scene.material);
        let geometry = LevelGeometry::new(w, h, w, h, scene.camera);
        let e = energy(
            &model,
            &geometry,
            &scene.image,
            &Grid::filled(w, h, 1.0),
            &scene.object_mask,
            depth,
            0.0,
            1e-3,
            Cancel::NEVER,
        )
        .uncancelled();
        let pixels = scene.object_mask.as_slice().iter().filter(|&&o| o).count();
        e.data / pixels as f64
    }

    #[test]
    fn the_names_round_trip_and_mesh_is_the_default() {
        for (name, shading) in Shading::NAMES {
            assert_eq!(Shading::from_name(name), Some(shading));
            assert_eq!(shading.name(), name);
        }
        assert_eq!(Shading::from_name("normals"), None);
        assert_eq!(Shading::default(), Shading::Mesh);
    }

    #[test]
    fn h13_the_truth_explains_a_depth_map_render_and_stays_put_when_solved() {
        let mesh_shaded = sombrero(64, 64);
        let scene = Shading::DepthMap.apply(mesh_shaded.clone());
        assert_eq!(scene.depth_gt, mesh_shaded.depth_gt);
        assert!(scene.normals.is_none());
        // The analytic gradient's image differs from the upwind one's (the
        // Sombrero's rings are where they part), so the test below could
        // not pass on the default shading.
        let truth_on_mesh = data_per_pixel(&mesh_shaded, &mesh_shaded.depth_gt);
        assert!(truth_on_mesh > 1e-6, "{truth_on_mesh}");
        assert!(data_per_pixel(&scene, &scene.depth_gt) < 1e-28);
        // Started from the truth, the solver at its defaults keeps a
        // (near) zero data residual and the true depth.
        let params = SolverParams {
            initial_depth: InitialDepth::Map(scene.depth_gt.clone()),
            ..SolverParams::default()
        };
        let solution = solve(&problem(&scene), &params, &mut ()).expect("solved");
        let data = data_per_pixel(&scene, &solution.depth);
        assert!(data < 1e-9, "{data}");
        let rse = crate::metrics::rse(&solution.depth, &scene.depth_gt).expect("rse");
        assert!(rse < 1e-3, "{rse}");
    }

    #[test]
    fn h13_the_defaults_recover_the_sombrero_from_a_depth_map_render_within_the_papers_rse() {
        // The paper's Table 1: RSE 0.00768 on its 256x256 Sombrero.
        let scene = Shading::DepthMap.apply(sombrero(256, 256));
        let solution = solve(&problem(&scene), &SolverParams::default(), &mut ()).expect("solved");
        let rse = crate::metrics::rse(&solution.depth, &scene.depth_gt).expect("rse");
        assert!(rse <= 0.00768, "RSE {rse}");
    }
}
