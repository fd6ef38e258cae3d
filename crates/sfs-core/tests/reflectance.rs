//! Reflectance beyond Lambert (METHOD.md section 10): the symmetries of the
//! image formation hold for every material (exposure, depth units, image
//! size), the matched model recovers what Lambert cannot, fast marching
//! takes the materials it can and refuses the one it cannot, and
//! `--reflectance auto` reports without deciding.

mod common;
use common::{ROUND_OFF, largest_relative_difference, problem};
use sfs_core::light::PointLight;
use sfs_core::material::Material;
use sfs_core::metrics;
use sfs_core::params::{ReflectanceChoice, SolverParams};
use sfs_core::scene::sombrero::sombrero_shaded;
use sfs_core::solver::{FastMarchingParams, Method, Problem, Solution, solve, solve_method};

const ROUGH: Material = Material::OrenNayar { roughness_rad: 0.4 };
const GLOSSY: Material = Material::BlinnPhong {
    specular: 0.3,
    shininess: 30.0,
};

fn solved(problem: &Problem, material: Material) -> Solution {
    solve(
        problem,
        &SolverParams::default().with_material(material),
        &mut (),
    )
    .expect("solves")
}

#[test]
fn exposure_and_depth_units_are_symmetries_for_every_material() {
    let beside = [PointLight {
        position: [0.4, 0.0, 0.0],
        ..PointLight::CENTRED
    }];
    for material in [ROUGH, GLOSSY] {
        for lights in [&[][..], &beside[..]] {
            let scene = sombrero_shaded(40, 40, lights, material);
            let s = scene.intensity_scale;
            let base = solved(&problem(&scene, scene.image.clone(), s, lights), material);
            // The image and s times k: the same depth.
            let k = 0.37;
            let darker = solved(
                &problem(&scene, scene.image.map(|v| v * k), s * k, lights),
                material,
            );
            let same = largest_relative_difference(&darker.depth, 1.0, &base.depth);
            assert!(
                same <= ROUND_OFF,
                "{material:?} {lights:?}: exposure moved depth by {same}"
            );
            // Depth in units c times smaller (s times c^2, lights times c):
            // depth times c.
            let c = 2.5;
            let moved: Vec<PointLight> = lights
                .iter()
                .map(|l| PointLight {
                    position: l.position.map(|v| v * c),
                    ..*l
                })
                .collect();
            let units = solved(
                &problem(&scene, scene.image.clone(), s * c * c, &moved),
                material,
            );
            let scaled = largest_relative_difference(&base.depth, c, &units.depth);
            // The start's plane fit (golden sections on log z0) rounds
            // differently in other units, and the glossy solve with a light
            // beside the lens amplifies that: a 1e-9 difference in the
            // start moved its depth by 3e-4 (from the paper's plane start,
            // by 7 %: that solve has nearby minima). Everything else holds
            // to round-off.
            let tolerance = if material == GLOSSY && !lights.is_empty() {
                1e-3
            } else {
                ROUND_OFF
            };
            assert!(
                scaled <= tolerance,
                "{material:?} {lights:?}: units changed shape by {scaled}"
            );
        }
    }
}

#[test]
fn image_alone_brighter_gives_the_same_shape_nearer_for_a_centred_light() {
    // I = s m(c) / r^2 with c independent of the depth unit: the image
    // times k alone is the same shape at depth / sqrt(k).
    for material in [ROUGH, GLOSSY] {
        let scene = sombrero_shaded(40, 40, &[], material);
        let s = scene.intensity_scale;
        let base = solved(&problem(&scene, scene.image.clone(), s, &[]), material);
        let k = 0.25;
        let darker = solved(
            &problem(&scene, scene.image.map(|v| v * k), s, &[]),
            material,
        );
        let d = largest_relative_difference(&darker.depth, k.sqrt(), &base.depth);
        assert!(d <= ROUND_OFF, "{material:?}: {d}");
    }
}

#[test]
fn more_pixels_do_not_make_any_material_worse() {
    for material in [ROUGH, GLOSSY] {
        let rse = |size: usize| {
            let scene = sombrero_shaded(size, size, &[], material);
            let p = problem(&scene, scene.image.clone(), scene.intensity_scale, &[]);
            metrics::rse(&solved(&p, material).depth, &scene.depth_gt).expect("same size")
        };
        let (small, large) = (rse(48), rse(96));
        assert!(
            large <= small * 1.05,
            "{material:?}: RSE {large} at 96 px against {small} at 48 px"
        );
    }
}

#[test]
fn the_matched_model_recovers_what_lambert_cannot() {
    for material in [ROUGH, GLOSSY] {
        let scene = sombrero_shaded(128, 128, &[], material);
        let p = problem(&scene, scene.image.clone(), scene.intensity_scale, &[]);
        let rse = |m: Material| metrics::rse(&solved(&p, m).depth, &scene.depth_gt).expect("size");
        let (matched, lambert) = (rse(material), rse(Material::Lambert));
        assert!(
            matched <= 0.3 * lambert,
            "{material:?}: matched RSE {matched} against Lambert's {lambert}"
        );
    }
}

#[test]
fn fast_marching_takes_monotone_materials_and_refuses_rough_oren_nayar() {
    let scene = sombrero_shaded(128, 128, &[], GLOSSY);
    let p = problem(&scene, scene.image.clone(), scene.intensity_scale, &[]);
    let fm = Method::FastMarching(FastMarchingParams::default());
    let glossy = SolverParams::default().with_material(GLOSSY);
    let marched = solve_method(&p, &glossy, &fm, &mut ()).expect("marches");
    let rse = metrics::rse(&marched.depth, &scene.depth_gt).expect("size");
    let as_lambert = solve_method(&p, &SolverParams::default(), &fm, &mut ()).expect("marches");
    let lambert_rse = metrics::rse(&as_lambert.depth, &scene.depth_gt).expect("size");
    assert!(
        rse <= 0.3 * lambert_rse,
        "Blinn-Phong march {rse} against {lambert_rse}"
    );
    let too_rough =
        SolverParams::default().with_material(Material::OrenNayar { roughness_rad: 0.9 });
    let err = solve_method(&p, &too_rough, &fm, &mut ()).expect_err("refused");
    assert!(err.to_string().contains("fast marching"), "{err}");
    // The linearised scheme still solves it (from the constant start).
    assert!(solve(&p, &too_rough, &mut ()).is_ok());
}

#[test]
fn auto_reports_the_models_and_keeps_lambert() {
    let scene = sombrero_shaded(40, 40, &[], GLOSSY);
    let p = problem(&scene, scene.image.clone(), scene.intensity_scale, &[]);
    let params = SolverParams {
        reflectance: ReflectanceChoice::Auto,
        ..SolverParams::default()
    };
    let solution = solve(&p, &params, &mut ()).expect("solves");
    let fit = solution.material_fit.expect("a fit with auto");
    assert_eq!(solution.material, Material::Lambert);
    assert!(!fit.determined);
    assert_eq!(
        fit.trials.len(),
        sfs_core::solver::material_fit::candidates().len()
    );
    assert!(
        fit.trials
            .windows(2)
            .all(|t| t[0].relative_energy <= t[1].relative_energy)
    );
    assert!(fit.summary.contains(&format!("{} px", fit.working_side)));
    // A fixed model has no fit.
    assert!(solved(&p, GLOSSY).material_fit.is_none());
}
