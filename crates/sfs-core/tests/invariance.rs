//! The symmetries of the image formation `I = s Q^3 / (z W)` hold for the
//! solver's result at the default settings (relative units, alpha auto):
//!
//! - the image times `k` together with the intensity scale: the same depth;
//! - the image times `k` alone: the same shape at depth `/ sqrt(k)`;
//! - depth in other units (`s` times `c^2`): depth times `c`;
//! - the same scene at another size (same field of view): RSE does not grow;
//! - a region moved m times farther with m^2 times the albedo: the same
//!   image off the region's border (the model alone, no solve).
//!
//! The first three hold with a hole of confidence 0 too (filled in depth by
//! the start's thin-plate fill, picked by energy).
//!
//! The first three are exact symmetries of the discrete problem, so the
//! results agree to round-off (the SOR works in f32); the fourth only
//! through the information in the pixels; the fifth is exact for the
//! model's image off the border.

mod common;
use common::{ROUND_OFF, largest_relative_difference};
use proptest::prelude::*;
use sfs_core::grid::Grid;
use sfs_core::metrics;
use sfs_core::params::SolverParams;
use sfs_core::scene::{Scene, add_noise, sombrero::sombrero};
use sfs_core::solver::{Problem, Solution, solve};

/// [`common::problem`] with the light at the optical centre.
fn problem(scene: &Scene, image: Grid<f64>, intensity_scale: f64) -> Problem {
    common::problem(scene, image, intensity_scale, &[])
}

/// [`problem`] with a horizontal band of confidence 0 where `hole`.
fn problem_with(scene: &Scene, image: Grid<f64>, intensity_scale: f64, hole: bool) -> Problem {
    let (w, h) = image.size();
    Problem {
        confidence: hole.then(|| sfs_core::scene::band_confidence(w, h, 0.45, 0.1)),
        ..problem(scene, image, intensity_scale)
    }
}

fn solved(problem: &Problem) -> Solution {
    solve(problem, &SolverParams::default(), &mut ()).expect("solves")
}

/// A clean or noisy (sigma 20 of 255) 40x40 Sombrero: the noisy one takes
/// the denoised fast-marching start and a larger automatic alpha.
fn scene_and_image(noisy: bool) -> (Scene, Grid<f64>) {
    let scene = sombrero(40, 40);
    let image = if noisy {
        add_noise(&scene.image, 20.0, 4)
    } else {
        scene.image.clone()
    };
    (scene, image)
}

/// The default solves of [`scene_and_image`] as it is and with its image
/// times `image_times` and its intensity scale changed by `scale` (with a
/// hole of confidence 0 in both where `hole`).
fn reference_and_changed(
    noisy: bool,
    hole: bool,
    image_times: f64,
    scale: impl FnOnce(f64) -> f64,
) -> (Solution, Solution) {
    let (scene, image) = scene_and_image(noisy);
    let s = scene.intensity_scale;
    let reference = solved(&problem_with(&scene, image.clone(), s, hole));
    let changed = image.map(|v| v * image_times);
    let changed = solved(&problem_with(&scene, changed, scale(s), hole));
    (reference, changed)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]

    #[test]
    fn image_and_intensity_scale_times_k_give_the_same_depth(
        k in 1e-3..1.0f64,
        noisy in any::<bool>(),
        hole in any::<bool>(),
    ) {
        let (reference, scaled) = reference_and_changed(noisy, hole, k, |s| s * k);
        let d = largest_relative_difference(&scaled.depth, 1.0, &reference.depth);
        prop_assert!(d < ROUND_OFF, "k {k}, hole {hole}: relative difference {d}");
        prop_assert!((scaled.alpha / reference.alpha - 1.0).abs() < 1e-9);
    }

    #[test]
    fn image_times_k_gives_the_same_shape_at_depth_over_sqrt_k(
        k in 1e-3..1.0f64,
        noisy in any::<bool>(),
        hole in any::<bool>(),
    ) {
        let (reference, dimmed) = reference_and_changed(noisy, hole, k, |s| s);
        let d = largest_relative_difference(&dimmed.depth, k.sqrt(), &reference.depth);
        prop_assert!(d < ROUND_OFF, "k {k}, hole {hole}: relative difference {d}");
    }

    #[test]
    fn depth_units_scale_the_depth_and_nothing_else(
        c in prop_oneof![1e-3..1.0f64, 1.0..1e3f64],
        noisy in any::<bool>(),
        hole in any::<bool>(),
    ) {
        // Depth in units c times smaller: z' = c z, and I = s' / z'^2 needs
        // s' = c^2 s.
        let (reference, converted) = reference_and_changed(noisy, hole, 1.0, |s| s * c * c);
        let d = largest_relative_difference(&converted.depth, 1.0 / c, &reference.depth);
        prop_assert!(d < ROUND_OFF, "c {c}, hole {hole}: relative difference {d}");
    }
}

/// RSE of the default solve of the Sombrero at `size`, clean or noisy.
fn sombrero_rse(size: usize, noisy: bool) -> f64 {
    let scene = sombrero(size, size);
    let image = if noisy {
        add_noise(&scene.image, 20.0, 1)
    } else {
        scene.image.clone()
    };
    let solution = solved(&problem(&scene, image, scene.intensity_scale));
    metrics::rse(&solution.depth, &scene.depth_gt).expect("measurable")
}

#[test]
fn the_default_does_not_get_worse_with_more_pixels() {
    // Same scene, same field of view: more pixels carry more information.
    for noisy in [false, true] {
        let rse: Vec<f64> = [48, 96, 192]
            .iter()
            .map(|&size| sombrero_rse(size, noisy))
            .collect();
        eprintln!("noisy {noisy}: RSE at 48, 96, 192 px: {rse:?}");
        for pair in rse.windows(2) {
            assert!(pair[1] <= pair[0] * 1.05, "noisy {noisy}: {rse:?}");
        }
        // And a useful surface at every size: at most three quarters of the
        // error of the best constant depth (0.0445, METHOD.md section 7);
        // measured 0.021/0.008/0.003 clean, 0.030/0.017/0.015 noisy.
        assert!(
            rse.iter().all(|&r| r < 0.75 * 0.0445),
            "noisy {noisy}: {rse:?}"
        );
    }
}

/// Lights at the optical centre act as one light of their summed
/// intensity: `s` with a centred light of intensity `phi` is `s phi` with
/// the paper's light, start included (fast marching once read `s` alone,
/// and a sum of photographs divided by two, or a light given intensity 0.5,
/// started a factor sqrt(2) too far).
#[test]
fn a_centred_light_of_intensity_phi_is_the_scale_times_phi() {
    for noisy in [false, true] {
        let (scene, image) = scene_and_image(noisy);
        let paper = solved(&problem(&scene, image.clone(), 2.0));
        for (scale, intensities) in [(4.0, vec![0.5]), (1.0, vec![0.5, 1.5])] {
            let lights = intensities
                .iter()
                .map(|&intensity| sfs_core::light::PointLight {
                    intensity,
                    ..sfs_core::light::PointLight::CENTRED
                })
                .collect();
            let with_lights = solved(&Problem {
                lights,
                ..problem(&scene, image.clone(), scale)
            });
            let difference = largest_relative_difference(&with_lights.depth, 1.0, &paper.depth);
            assert!(
                difference < ROUND_OFF,
                "noisy {noisy}, s {scale}, intensities {intensities:?}: {difference}"
            );
        }
    }
}

/// Why one photograph cannot fix the albedo of a region by its brightness
/// alone (docs/albedo.md): with the light at the
/// optical centre, a region moved `m` times farther along its rays and
/// given `m^2` times the albedo is the same image, pixel for pixel, except
/// where a pixel's upwind stencil reaches across the region's border (the
/// solver's smoothness sees that seam, the data term nowhere else). So a
/// region's albedo level is set by its edges and the surface's continuity,
/// and a shape solved with a wrong level explains the photograph about as
/// well by bending.
#[test]
fn a_region_s_albedo_level_trades_exactly_against_its_distance() {
    use sfs_core::cancel::{Cancel, Uncancelled};
    use sfs_core::model::{self, Lambertian, LevelGeometry};
    let side = 64;
    let scene = sombrero(side, side);
    let geometry = LevelGeometry::new(side, side, side, side, scene.camera);
    let model = Lambertian {
        intensity_scale: scene.intensity_scale,
    };
    let inside = Grid::from_fn(side, side, |c, r| {
        let (x, y) = (c as f64 - 40.0, r as f64 - 24.0);
        x * x + y * y < 12.0 * 12.0
    });
    // Every 5-point neighbour on the same side of the region's border.
    let one_side = |c: usize, r: usize| {
        let here = *inside.at(c, r);
        [(-1, 0), (1, 0), (0, -1), (0, 1)].iter().all(|(dc, dr)| {
            let (nc, nr) = (c as i64 + dc, r as i64 + dr);
            nc < 0
                || nr < 0
                || nc >= side as i64
                || nr >= side as i64
                || *inside.at(nc as usize, nr as usize) == here
        })
    };
    let render = |depth: &Grid<f64>| {
        model::reproject(&model, &geometry, &scene.object_mask, depth, Cancel::NEVER).uncancelled()
    };
    let original = render(&scene.depth_gt);
    for distance in [0.8, 1.25] {
        let moved = scene
            .depth_gt
            .zip_map(&inside, |z, &i| if i { z * distance } else { *z });
        // The albedo `distance^2` inside: the image the model predicts.
        let image = render(&moved).zip_map(
            &inside,
            |v, &i| {
                if i { v * distance * distance } else { *v }
            },
        );
        let (mut seam, mut largest_off_seam) = (0.0_f64, 0.0_f64);
        for r in 0..side {
            for c in 0..side {
                if !scene.object_mask.at(c, r) {
                    continue;
                }
                let (a, b) = (*image.at(c, r), *original.at(c, r));
                let difference = (a - b).abs() / b.abs().max(1e-12);
                if one_side(c, r) {
                    largest_off_seam = largest_off_seam.max(difference);
                } else {
                    seam = seam.max(difference);
                }
            }
        }
        assert!(
            largest_off_seam < 1e-12,
            "distance x{distance}: off the seam {largest_off_seam}"
        );
        assert!(seam > 1e-3, "distance x{distance}: the seam shows {seam}");
    }
}
