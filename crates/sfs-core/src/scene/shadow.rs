//! Cast shadows for synthetic scenes: a scene rendered with the shadows
//! [`cast_shadow`] finds, so that every shadow case has ground truth. Attached shadows (`N . L <= 0`) are
//! already black in the local shading; these are the others.

use crate::grid::Grid;
use crate::light::PointLight;
use crate::occlusion::cast_shadow;

use super::Scene;

/// A scene lit by `lights` with cast shadows, from a renderer of the local
/// shading (`render(lights)`, e.g. [`super::sombrero::sombrero_lit`] or
/// [`super::mesh::render_lit`]): each light's image is rendered alone,
/// darkened where [`cast_shadow`] hides its light, and the lights summed at
/// the exposure of the full render. Returns the scene and, per pixel, true
/// where no light reaches the object (cast or attached shadow of every
/// light). With no lights (one at the optical centre) nothing is hidden.
pub fn with_cast_shadows<E>(
    render: impl Fn(&[PointLight]) -> Result<Scene, E>,
    lights: &[PointLight],
) -> Result<(Scene, Grid<bool>), E> {
    let mut scene = render(lights)?;
    let (w, h) = scene.image.size();
    let mut lit = Grid::filled(w, h, false);
    if lights.is_empty() {
        for (l, (&i, &o)) in lit.as_mut_slice().iter_mut().zip(
            scene
                .image
                .as_slice()
                .iter()
                .zip(scene.object_mask.as_slice()),
        ) {
            *l = o && i > 0.0;
        }
    } else {
        let mut image = Grid::filled(w, h, 0.0);
        for light in lights {
            let alone = render(std::slice::from_ref(light))?;
            let hidden = cast_shadow(&scene.depth_gt, scene.camera, light.position);
            // This light's share at the full render's exposure.
            let k = scene.intensity_scale / alone.intensity_scale;
            for q in 0..w * h {
                let value = alone.image.as_slice()[q];
                if !hidden.as_slice()[q] && value > 0.0 {
                    image.as_mut_slice()[q] += k * value;
                    lit.as_mut_slice()[q] = true;
                }
            }
        }
        scene.image = image;
    }
    let shadow = Grid::from_fn(w, h, |c, r| *scene.object_mask.at(c, r) && !*lit.at(c, r));
    Ok((scene, shadow))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;

    #[test]
    fn a_step_casts_a_shadow_away_from_the_light_and_none_towards_it() {
        // A floor at depth 2 with a raised block (depth 1.6) in the middle
        // columns; a light to the left, nearer the camera: the floor just
        // right of the block is hidden, the floor left of it, the block's
        // top and the floor far right (the ray passes in front) are lit.
        let (w, h) = (64, 16);
        let camera = Intrinsics::centred(64.0, w, h);
        let depth = Grid::from_fn(w, h, |c, _| if (28..36).contains(&c) { 1.6 } else { 2.0 });
        let hidden = cast_shadow(&depth, camera, [-1.0, 0.0, 0.5]);
        let row = 8;
        assert!(*hidden.at(38, row), "just right of the block");
        assert!(!*hidden.at(20, row), "left of the block");
        assert!(!*hidden.at(32, row), "on the block");
        assert!(!*hidden.at(60, row), "far right: the shadow ends");
    }

    #[test]
    fn a_light_at_the_optical_centre_casts_no_shadow() {
        let (w, h) = (32, 32);
        let camera = Intrinsics::centred(32.0, w, h);
        let depth = Grid::from_fn(w, h, |c, r| {
            2.0 + 0.3 * ((c as f64) * 0.7).sin() * (r as f64 * 0.5).cos()
        });
        let hidden = cast_shadow(&depth, camera, [0.0, 0.0, 0.0]);
        assert!(hidden.as_slice().iter().all(|&s| !s));
    }
}
