//! Synthetic scenes with ground truth: the analytic Sombrero (METHOD.md
//! section 7) and OBJ meshes rendered in perspective, plus noise and
//! inpainting regions.

use crate::camera::Intrinsics;
use crate::grid::Grid;

pub mod mesh;
pub mod photometric;
pub mod shading;
pub mod shadow;
pub mod sombrero;

/// A synthetic scene: a noise-free linear image with its exact depth.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Short name, e.g. `sombrero` or the mesh file stem.
    pub name: String,
    /// Camera intrinsics at full resolution.
    pub camera: Intrinsics,
    /// Intensity scale `s` (albedo times light power) used to render the image.
    pub intensity_scale: f64,
    /// Linear image values `I` in [0, 1]; 0 on the background.
    pub image: Grid<f64>,
    /// Ground-truth Cartesian depth along the optical axis; NaN on the background.
    pub depth_gt: Grid<f64>,
    /// True where the pixel sees the object.
    pub object_mask: Grid<bool>,
    /// The unit normal each pixel was shaded with (camera frame, towards
    /// the camera; NaN on the background), where the renderer knows it.
    pub normals: Option<Grid<[f64; 3]>>,
    /// The lights it was rendered with (empty: one at the optical centre).
    pub lights: Vec<crate::light::PointLight>,
    /// The material it was rendered with (METHOD.md section 10).
    pub material: crate::material::Material,
}

impl Scene {
    /// RSE and RIE of `depth` against this scene's truth, reprojected as
    /// [`crate::metrics::errors`] does: Lambertian, the light at the optical
    /// centre (the Table 1 scenes; a scene with other lights or a material
    /// needs [`crate::metrics::errors_with_model`]).
    ///
    /// # Errors
    /// As [`crate::metrics::errors`].
    pub fn centred_errors(
        &self,
        depth: &Grid<f64>,
    ) -> Result<crate::metrics::Errors, crate::metrics::MetricsError> {
        crate::metrics::errors(
            depth,
            &self.depth_gt,
            &self.image,
            self.camera,
            self.intensity_scale,
        )
    }
}

/// Adds Gaussian noise of standard deviation `sigma_255` (on the 0..255 scale)
/// to a linear image, seeded for reproducibility, and quantises the result to
/// 8 bits in [0, 1] (what `noisy8.png` stores). Background pixels get noise too,
/// as a camera would.
pub fn add_noise(image: &Grid<f64>, sigma_255: f64, seed: u64) -> Grid<f64> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    image.map(|&v| {
        let noisy = v * 255.0 + sigma_255 * rng.sample::<f64, _>(rand_distr::StandardNormal);
        noisy.round().clamp(0.0, 255.0) / 255.0
    })
}

/// A disc-shaped inpainting region for the paper's Fig. 3 case: confidence 0
/// inside the disc, 1 elsewhere. Centre and radius are fractions of the image
/// width and height (`centre_x`, `centre_y`) and of the smaller side (`radius`).
pub fn disc_confidence(
    width: usize,
    height: usize,
    centre_x: f64,
    centre_y: f64,
    radius: f64,
) -> Grid<f64> {
    let (cx, cy) = (centre_x * width as f64, centre_y * height as f64);
    let r = radius * width.min(height) as f64;
    Grid::from_fn(width, height, |c, row| {
        let (dx, dy) = (c as f64 + 0.5 - cx, row as f64 + 0.5 - cy);
        if dx * dx + dy * dy < r * r { 0.0 } else { 1.0 }
    })
}

/// A horizontal band of confidence 0 (the rest 1): `height_share` of the
/// image height, centred at `centre_y` (a fraction of the height).
pub fn band_confidence(width: usize, height: usize, centre_y: f64, height_share: f64) -> Grid<f64> {
    let centre = centre_y * height as f64;
    let half = 0.5 * height_share * height as f64;
    Grid::from_fn(width, height, |_, r| {
        let y = r as f64 + 0.5;
        if (y - centre).abs() < half { 0.0 } else { 1.0 }
    })
}

/// Confidence 0 on the object's pixels within `width_px` pixels (city-block
/// steps) of the background or the image border, 1 elsewhere: the
/// silhouette band, where a photograph's edge pixels are least trusted.
pub fn silhouette_band_confidence(object: &Grid<bool>, width_px: usize) -> Grid<f64> {
    let (w, h) = object.size();
    // Distance to the nearest non-object pixel (or the border), two passes.
    let mut distance = Grid::from_fn(w, h, |c, r| {
        if *object.at(c, r) && c > 0 && r > 0 && c + 1 < w && r + 1 < h {
            usize::MAX
        } else if *object.at(c, r) {
            1
        } else {
            0
        }
    });
    for r in 0..h {
        for c in 0..w {
            let mut d = *distance.at(c, r);
            if c > 0 {
                d = d.min(distance.at(c - 1, r).saturating_add(1));
            }
            if r > 0 {
                d = d.min(distance.at(c, r - 1).saturating_add(1));
            }
            *distance.at_mut(c, r) = d;
        }
    }
    for r in (0..h).rev() {
        for c in (0..w).rev() {
            let mut d = *distance.at(c, r);
            if c + 1 < w {
                d = d.min(distance.at(c + 1, r).saturating_add(1));
            }
            if r + 1 < h {
                d = d.min(distance.at(c, r + 1).saturating_add(1));
            }
            *distance.at_mut(c, r) = d;
        }
    }
    distance.map(|&d| if d >= 1 && d <= width_px { 0.0 } else { 1.0 })
}

/// Random discs of confidence 0 over the object until they cover `share` of
/// its pixels (seeded; radii 2-8 % of the smaller side), 1 elsewhere.
pub fn blob_confidence(object: &Grid<bool>, share: f64, seed: u64) -> Grid<f64> {
    use rand::{Rng, SeedableRng};
    let (w, h) = object.size();
    let mut confidence = Grid::filled(w, h, 1.0);
    let on_object = object.as_slice().iter().filter(|&&o| o).count();
    let wanted = (share.clamp(0.0, 1.0) * on_object as f64).round() as usize;
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let side = w.min(h) as f64;
    let mut covered = 0;
    // Enough tries for any share below 1; a share no disc can reach stops.
    for _ in 0..10_000 {
        if covered >= wanted {
            break;
        }
        let (cx, cy) = (
            rng.random::<f64>() * w as f64,
            rng.random::<f64>() * h as f64,
        );
        let radius = side * rng.random_range(0.02..0.08);
        let rows =
            ((cy - radius).floor().max(0.0) as usize)..((cy + radius).ceil() as usize).min(h);
        for r in rows {
            let cols =
                ((cx - radius).floor().max(0.0) as usize)..((cx + radius).ceil() as usize).min(w);
            for c in cols {
                let (dx, dy) = (c as f64 + 0.5 - cx, r as f64 + 0.5 - cy);
                if dx * dx + dy * dy < radius * radius
                    && *object.at(c, r)
                    && *confidence.at(c, r) == 1.0
                {
                    *confidence.at_mut(c, r) = 0.0;
                    covered += 1;
                }
            }
        }
    }
    confidence
}

/// The harmonic (Laplace) fill of `depth` across the object pixels that are
/// not `known`: each unknown pixel the mean of its object neighbours, the
/// known ones fixed (Dirichlet), the background a wall (Neumann). The
/// reference a hole's solve is measured against ("a plain smooth
/// continuation"); solved by SOR to a relative change below 1e-12. Unknown
/// pixels with no known pixel in their component keep the known pixels'
/// mean.
pub fn harmonic_fill(depth: &Grid<f64>, known: &Grid<bool>) -> Grid<f64> {
    let (w, h) = depth.size();
    let on = |c: usize, r: usize| depth.at(c, r).is_finite();
    let known_values: Vec<f64> = (0..h)
        .flat_map(|r| (0..w).map(move |c| (c, r)))
        .filter(|&(c, r)| on(c, r) && *known.at(c, r))
        .map(|(c, r)| *depth.at(c, r))
        .collect();
    let mean = known_values.iter().sum::<f64>() / known_values.len().max(1) as f64;
    let mut filled = Grid::from_fn(w, h, |c, r| {
        let z = *depth.at(c, r);
        if on(c, r) && !*known.at(c, r) {
            mean
        } else {
            z
        }
    });
    let unknown: Vec<(usize, usize)> = (0..h)
        .flat_map(|r| (0..w).map(move |c| (c, r)))
        .filter(|&(c, r)| on(c, r) && !*known.at(c, r))
        .collect();
    const OMEGA: f64 = 1.9;
    for _ in 0..200_000 {
        let mut largest = 0.0f64;
        for &(c, r) in &unknown {
            let mut sum = 0.0;
            let mut count = 0.0;
            let neighbours = [
                (c.wrapping_sub(1), r),
                (c + 1, r),
                (c, r.wrapping_sub(1)),
                (c, r + 1),
            ];
            for (nc, nr) in neighbours {
                if nc < w && nr < h && on(nc, nr) {
                    sum += *filled.at(nc, nr);
                    count += 1.0;
                }
            }
            if count > 0.0 {
                let old = *filled.at(c, r);
                let new = old + OMEGA * (sum / count - old);
                largest = largest.max((new - old).abs() / old.abs().max(f64::MIN_POSITIVE));
                *filled.at_mut(c, r) = new;
            }
        }
        if largest < 1e-12 {
            break;
        }
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_seeded_and_has_the_requested_spread() {
        let image = Grid::filled(200, 200, 0.5);
        let a = add_noise(&image, 20.0, 7);
        assert_eq!(a, add_noise(&image, 20.0, 7));
        assert_ne!(a, add_noise(&image, 20.0, 8));
        let n = a.len() as f64;
        let mean = a.as_slice().iter().sum::<f64>() / n;
        let sd = (a.as_slice().iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt() * 255.0;
        assert!(
            (mean - 0.5).abs() < 0.005 && (sd - 20.0).abs() < 0.5,
            "{mean} {sd}"
        );
    }

    #[test]
    fn the_hole_shapes_cover_what_they_say() {
        let band = band_confidence(50, 100, 0.45, 0.1);
        let rows: Vec<usize> = (0..100).filter(|&r| *band.at(3, r) == 0.0).collect();
        assert_eq!(rows.len(), 10);
        assert_eq!((rows[0], rows[9]), (40, 49));
        let object = Grid::from_fn(40, 40, |c, r| {
            (10..30).contains(&c) && (10..30).contains(&r)
        });
        let silhouette = silhouette_band_confidence(&object, 3);
        let zeros = silhouette.as_slice().iter().filter(|&&v| v == 0.0).count();
        assert_eq!(zeros, 20 * 20 - 14 * 14, "a 3-pixel ring inside the square");
        assert_eq!(
            *silhouette.at(5, 5),
            1.0,
            "the background is not in the band"
        );
        let blobs = blob_confidence(&object, 0.2, 3);
        let covered = blobs.as_slice().iter().filter(|&&v| v == 0.0).count() as f64;
        assert!((covered / 400.0 - 0.2).abs() < 0.1, "{covered}");
        assert_eq!(blobs, blob_confidence(&object, 0.2, 3), "seeded");
        assert!(
            (0..40).all(|r| (0..40).all(|c| *object.at(c, r) || *blobs.at(c, r) == 1.0)),
            "only object pixels are covered"
        );
    }

    #[test]
    fn the_harmonic_fill_continues_a_plane_exactly_and_leaves_known_pixels() {
        // A plane is harmonic: its fill across any hole is the plane itself.
        let plane = Grid::from_fn(30, 20, |c, r| 2.0 + 0.01 * c as f64 - 0.02 * r as f64);
        let known = disc_confidence(30, 20, 0.5, 0.5, 0.3).map(|&v| v > 0.5);
        let filled = harmonic_fill(&plane, &known);
        for (a, b) in filled.as_slice().iter().zip(plane.as_slice()) {
            assert!((a - b).abs() < 1e-9, "{a} vs {b}");
        }
        // A bump is not: the fill is the smooth guess under it, not the bump.
        let bump = Grid::from_fn(30, 20, |c, r| {
            let (dx, dy) = (c as f64 - 15.0, r as f64 - 10.0);
            2.0 - 0.3 * (-(dx * dx + dy * dy) / 8.0).exp()
        });
        let filled = harmonic_fill(&bump, &known);
        assert!(*filled.at(15, 10) > 1.95, "{}", filled.at(15, 10));
        assert_eq!(filled.at(0, 0), bump.at(0, 0));
    }

    #[test]
    fn disc_covers_its_area() {
        let c = disc_confidence(100, 100, 0.5, 0.5, 0.2);
        let holes = c.as_slice().iter().filter(|&&v| v == 0.0).count() as f64;
        assert!(
            (holes - std::f64::consts::PI * 400.0).abs() < 40.0,
            "{holes}"
        );
    }
}
