//! How well the model explains an image, said plainly: the model-fit summary
//! after a solve (RIE over trusted pixels, share of badly explained,
//! near-black and saturated pixels, warnings), the residual map, the
//! darkness check before a solve, and the suggested confidence (saturated
//! highlights, near-black and cast-shadow pixels, the silhouette band).
//!
//! One photograph is saturated where its own value is (nearly) at the top
//! of the range; a sum of photographs is saturated exactly where one of
//! them was ([`Photographs`]), whatever the sum's value.
//!
//! Occluding contours are said plainly too ([`occlusion_edges`]): where the
//! solved surface grazes the view beside a much brighter pixel, a surface
//! lies behind a contour, and its distance is not fixed by its shading
//! unless it faces the light somewhere (docs/occlusion-edges.md).

use serde::Serialize;

use crate::camera::Intrinsics;
use crate::grid::Grid;
use crate::model::{LevelGeometry, neighbourhood};

/// Linear values below this are near-black: an 8-bit sRGB value of about 3,
/// where one quantisation step is more than a quarter of the value.
pub const NEAR_BLACK: f64 = 0.001;

/// Linear values at or above this are (nearly) saturated.
pub const NEAR_SATURATED: f64 = 0.98;

/// A pixel is badly explained when `|I - R|` exceeds this fraction of
/// `max(I, I_ref / 10)`.
pub const POOR_RESIDUAL: f64 = 0.15;

/// The RIE over trusted pixels above which the fit is called poor.
pub const POOR_RIE: f64 = 0.15;

/// The share of badly explained trusted pixels above which the fit is called
/// poor.
pub const POOR_SHARE: f64 = 0.2;
/// The brightest share of trusted object pixels checked for highlights.
pub const HIGHLIGHT_SHARE: f64 = 0.02;
/// Highlights are named when at least this share of the brightest pixels is
/// brighter than the model explains, and at least twice the share of badly
/// explained pixels overall: the misfit is concentrated where a glossy
/// surface would shine.
pub const HIGHLIGHT_POOR_SHARE: f64 = 0.3;

/// An object pixel is on an occluding contour when the solved surface meets
/// its viewing ray at a cosine below this (more than about 73 degrees off
/// facing the camera)...
pub const GRAZING_COSINE: f64 = 0.3;
/// ...beside a 4-neighbour at least this many times brighter in the image:
/// a step in brightness, not a slope turning away (a continuous surface
/// darkens gradually towards its rim; the surface behind a contour starts
/// at its own brightness).
pub const EDGE_BRIGHTNESS_STEP: f64 = 2.0;
/// Occluding contours are named when at least this share of the object's
/// pixels lies on them.
pub const EDGE_WARNING_SHARE: f64 = 0.002;

/// The median object brightness (linear, full range 1) below which an image
/// is too dark to carry shape: half the object near-black (an ambient frame
/// has median 0 on the face; the LED photographs of near_ps_human1, dark as
/// they are, 0.002).
pub const TOO_DARK_MEDIAN: f64 = NEAR_BLACK;

/// The model-fit summary of a solve.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ModelFit {
    /// `sqrt(sum c (I - R)^2 / sum c I^2)` over trusted object pixels.
    pub rie_trusted: f64,
    /// Share of trusted object pixels whose residual exceeds
    /// [`POOR_RESIDUAL`].
    pub poor_share: f64,
    /// Share of object pixels below [`NEAR_BLACK`].
    pub near_black_share: f64,
    /// Share of object pixels at or above [`NEAR_SATURATED`].
    pub saturated_share: f64,
    /// Median linear brightness of the object pixels.
    pub median_brightness: f64,
    /// Share of the brightest [`HIGHLIGHT_SHARE`] of trusted object pixels
    /// that are brighter than the model explains by more than
    /// [`POOR_RESIDUAL`]: highlights a matte model cannot show.
    pub highlight_poor_share: f64,
    /// Share of the object's pixels on occluding contours
    /// ([`occlusion_edges`]; 0 until [`ModelFit::with_occlusion_edges`]).
    pub occlusion_edge_share: f64,
    /// Plain-language warnings (empty when the fit is good).
    pub warnings: Vec<String>,
}

impl ModelFit {
    /// The fit with the share of object pixels (`depth` finite) on the
    /// occluding contours `edges`, and a warning when it reaches
    /// [`EDGE_WARNING_SHARE`].
    #[must_use]
    pub fn with_occlusion_edges(mut self, edges: &Grid<bool>, depth: &Grid<f64>) -> Self {
        let object = depth.as_slice().iter().filter(|z| z.is_finite()).count();
        let on_edges = edges.as_slice().iter().filter(|&&e| e).count();
        self.occlusion_edge_share = on_edges as f64 / object.max(1) as f64;
        if self.occlusion_edge_share >= EDGE_WARNING_SHARE {
            self.warnings.push(format!(
                "{:.1} % of the object was solved as grazing the view beside a much brighter \
                 pixel: an occluding contour (what lies behind it was joined to it, and its \
                 distance is not fixed by its shading unless it faces the light somewhere) or a \
                 dark mark on the surface (albedo) read as a slope",
                100.0 * self.occlusion_edge_share
            ));
        }
        self
    }
}

/// The object pixels (`depth` finite, all four neighbours too: the
/// silhouette is left out) on an occluding contour: the solved
/// surface meets the viewing ray at a cosine below [`GRAZING_COSINE`] (its
/// upwind gradient, the solver's own) beside a 4-neighbour on the object at
/// least [`EDGE_BRIGHTNESS_STEP`] times brighter in `image`. `camera` is the
/// camera of `depth`'s grid. Geometry only: the same for any light and
/// material.
pub fn occlusion_edges(image: &Grid<f64>, depth: &Grid<f64>, camera: Intrinsics) -> Grid<bool> {
    let (w, h) = depth.size();
    let geometry = LevelGeometry::new(w, h, w, h, camera);
    let domain = depth.map(|z| z.is_finite() && *z > 0.0);
    let f = camera.focal_px;
    Grid::from_fn(w, h, |c, r| {
        // On the object, and not on its silhouette (what lies behind the
        // silhouette is the background, nothing solved).
        let on_object = |cc: Option<usize>, rr: Option<usize>| match (cc, rr) {
            (Some(cc), Some(rr)) if cc < w && rr < h => *domain.at(cc, rr),
            _ => false,
        };
        if !*domain.at(c, r)
            || image.size() != (w, h)
            || !(on_object(c.checked_sub(1), Some(r))
                && on_object(Some(c + 1), Some(r))
                && on_object(Some(c), r.checked_sub(1))
                && on_object(Some(c), Some(r + 1)))
        {
            return false;
        }
        let nb = neighbourhood(depth, &domain, c, r);
        let (_, gx, gy) = nb.upwind(geometry.spacing);
        let ray = geometry.ray(c, r);
        let z = nb.centre;
        let along = gx * ray.x_px + gy * ray.y_px + z;
        let root = (f * f * (gx * gx + gy * gy) + along * along).sqrt();
        let cosine = ray.q() * z / root;
        // A NaN cosine (a degenerate neighbourhood) is no contour.
        if cosine.is_nan() || cosine >= GRAZING_COSINE {
            return false;
        }
        let here = image.at(c, r).max(0.0);
        let brighter = |cc: usize, rr: usize| *image.at(cc, rr) > EDGE_BRIGHTNESS_STEP * here;
        brighter(c - 1, r) || brighter(c + 1, r) || brighter(c, r - 1) || brighter(c, r + 1)
    })
}

/// What the fit summary and the suggested confidence need to know of the
/// photographs behind an image: where they were saturated, and on what
/// scale the image holds their values.
#[derive(Clone, Copy, Debug)]
pub struct Photographs<'a> {
    /// The pixels where a photograph was saturated (a sum of photographs:
    /// where any of them was, as `photo::PreparedPhoto::clipped` records
    /// it). `None`: where the image itself is at or above
    /// [`NEAR_SATURATED`] (one photograph).
    pub saturated: Option<&'a Grid<bool>>,
    /// The photographs' values are the image's times this: 1, or the power
    /// of two a sum was divided by (`photo::PhotoReport::sum_divisor`). The
    /// brightness thresholds ([`NEAR_BLACK`], [`TOO_DARK_MEDIAN`]) and the
    /// reported median apply to the values times this.
    pub scale: f64,
}

impl Photographs<'static> {
    /// One photograph: saturated where its value is, on its own scale.
    pub const ONE: Photographs<'static> = Photographs {
        saturated: None,
        scale: 1.0,
    };
}

impl Photographs<'_> {
    /// Whether pixel `q` (row-major index) of `image` is saturated.
    fn saturated_at(&self, image: &Grid<f64>, q: usize) -> bool {
        match self.saturated {
            Some(mask) => mask.as_slice()[q],
            None => image.as_slice()[q] >= NEAR_SATURATED,
        }
    }
}

fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let middle = values.len() / 2;
    *values.select_nth_unstable_by(middle, f64::total_cmp).1
}

/// The values of `image` on the object (every pixel without a mask).
fn object_values(image: &Grid<f64>, object: Option<&Grid<bool>>) -> Vec<f64> {
    image
        .as_slice()
        .iter()
        .enumerate()
        .filter(|(q, _)| object.is_none_or(|o| o.as_slice()[*q]))
        .map(|(_, v)| *v)
        .collect()
}

/// Why an image cannot be solved at all because it holds no usable light:
/// black on every object pixel, or dark (brightest object pixel below 1 %
/// of full range) with fewer than [`MIN_GREY_LEVELS`] distinct values, i.e.
/// a few quantisation steps of noise and no shading (a lens-cap frame, an
/// 8-bit photograph with the light off). A dark 16-bit image keeps its
/// hundreds of levels and is solved (with the darkness warning). `None`
/// when there is light to work with.
pub fn too_dark_to_solve(image: &Grid<f64>, object: Option<&Grid<bool>>) -> Option<String> {
    let values = object_values(image, object);
    let brightest = values.iter().copied().fold(0.0, f64::max);
    if brightest <= 0.0 {
        return Some(
            "the image is black on every object pixel: there is no shading to explain".into(),
        );
    }
    if brightest >= DARK_BRIGHTEST {
        return None;
    }
    let mut levels: Vec<u64> = values.iter().map(|v| v.to_bits()).collect();
    levels.sort_unstable();
    levels.dedup();
    (levels.len() < MIN_GREY_LEVELS).then(|| {
        format!(
            "the image holds no usable light: its brightest object pixel is {:.3} % of full \
             range and it has only {} grey level(s); a lit photograph or a longer exposure is \
             needed",
            100.0 * brightest,
            levels.len()
        )
    })
}

/// Brightest object value (fraction of full range) below which an image
/// is checked for [`MIN_GREY_LEVELS`].
const DARK_BRIGHTEST: f64 = 0.01;
/// Fewest distinct grey values a dark image needs to carry any shading.
pub const MIN_GREY_LEVELS: usize = 8;

/// The warning for an image too dark to carry shape (before a solve), from
/// the object pixels' brightness; `None` when it is bright enough.
pub fn darkness_warning(image: &Grid<f64>, object: Option<&Grid<bool>>) -> Option<String> {
    let values = object_values(image, object);
    let brightest = values.iter().copied().fold(0.0, f64::max);
    let median = median(values);
    (median < TOO_DARK_MEDIAN).then(|| {
        format!(
            "the image is too dark to carry shape: the object's median brightness is {:.2} % of \
             full range (brightest {:.2} %); a lit photograph, a longer exposure or an ambient \
             frame that is not the photograph itself is needed",
            100.0 * median,
            100.0 * brightest
        )
    })
}

/// The residual map `(I - R) / I_ref` on `domain` (NaN elsewhere): positive
/// where the image is brighter than the model explains.
pub fn residual_map(
    image: &Grid<f64>,
    reprojection: &Grid<f64>,
    domain: &Grid<bool>,
    intensity_ref: f64,
) -> Grid<f64> {
    Grid::from_fn(image.width(), image.height(), |c, r| {
        if *domain.at(c, r) {
            (image.at(c, r) - reprojection.at(c, r)) / intensity_ref
        } else {
            f64::NAN
        }
    })
}

/// Measures the fit of `reprojection` to `image` over the object (`domain`)
/// with the solver's confidence (0 = not trusted), `intensity_ref` the
/// problem's brightness scale; the image is one photograph
/// ([`measure_photographs`] with [`Photographs::ONE`]).
pub fn measure(
    image: &Grid<f64>,
    reprojection: &Grid<f64>,
    domain: &Grid<bool>,
    confidence: Option<&Grid<f64>>,
    intensity_ref: f64,
) -> ModelFit {
    measure_photographs(
        image,
        reprojection,
        domain,
        confidence,
        intensity_ref,
        Photographs::ONE,
    )
}

/// [`measure`] for an image made of `photographs` (a sum: saturated where
/// one of them was; on a scale of its own): the saturated share and its
/// warning follow `photographs.saturated`, the near-black share and the
/// median the photographs' scale.
pub fn measure_photographs(
    image: &Grid<f64>,
    reprojection: &Grid<f64>,
    domain: &Grid<bool>,
    confidence: Option<&Grid<f64>>,
    intensity_ref: f64,
    photographs: Photographs<'_>,
) -> ModelFit {
    let (mut num, mut den, mut trusted, mut poor) = (0.0, 0.0, 0usize, 0usize);
    let (mut object, mut black, mut saturated) = (0usize, 0usize, 0usize);
    let mut values = Vec::new();
    let scale = photographs.scale;
    // The smallest brightness a residual is measured against; an unusable
    // reference (a degenerate solve's scales) must not call every residual
    // small (RIE 1 with 0 % badly explained, the probe's tiny focal length).
    let floor = if intensity_ref.is_finite() {
        0.1 * intensity_ref
    } else {
        0.0
    };
    for q in 0..image.len() {
        if !domain.as_slice()[q] {
            continue;
        }
        let (i, r) = (image.as_slice()[q], reprojection.as_slice()[q]);
        object += 1;
        values.push(i * scale);
        black += usize::from(i * scale < NEAR_BLACK);
        saturated += usize::from(photographs.saturated_at(image, q));
        let c = confidence.map_or(1.0, |c| c.as_slice()[q]);
        if c > 0.0 && r.is_finite() {
            num += c * (i - r) * (i - r);
            den += c * i * i;
            trusted += 1;
            poor += usize::from((i - r).abs() > POOR_RESIDUAL * i.max(floor));
        }
    }
    let share = |n: usize, of: usize| n as f64 / of.max(1) as f64;
    // The brightest trusted pixels (at or above the brightness of the
    // HIGHLIGHT_SHARE-th from the top, found without a copy of the image)
    // and how many of them the model leaves darker than they are.
    let trusted_at = |q: usize| {
        domain.as_slice()[q]
            && confidence.map_or(1.0, |c| c.as_slice()[q]) > 0.0
            && reprojection.as_slice()[q].is_finite()
    };
    let width = image.width().max(1);
    let brightest = ((trusted as f64 * HIGHLIGHT_SHARE).ceil() as usize).min(trusted);
    let threshold = crate::selection::kth_smallest(
        image.height(),
        |r, out| {
            out.extend(
                (r * width..(r + 1) * width)
                    .filter(|&q| trusted_at(q))
                    .map(|q| image.as_slice()[q].max(0.0)),
            )
        },
        |count| count.saturating_sub(brightest.max(1)),
        crate::cancel::Cancel::NEVER,
    )
    .ok()
    .flatten();
    let highlight_poor_share = match threshold {
        Some(threshold) if brightest > 0 => {
            let (mut among, mut poor_among) = (0usize, 0usize);
            for q in (0..image.len()).filter(|&q| trusted_at(q)) {
                let (i, r) = (image.as_slice()[q], reprojection.as_slice()[q]);
                if i.max(0.0) >= threshold {
                    among += 1;
                    poor_among += usize::from(i - r > POOR_RESIDUAL * i.max(floor));
                }
            }
            share(poor_among, among)
        }
        _ => 0.0,
    };
    let mut fit = ModelFit {
        rie_trusted: if den > 0.0 {
            (num / den).sqrt()
        } else {
            f64::NAN
        },
        poor_share: share(poor, trusted),
        near_black_share: share(black, object),
        saturated_share: share(saturated, object),
        median_brightness: median(values),
        highlight_poor_share,
        occlusion_edge_share: 0.0,
        warnings: Vec::new(),
    };
    if fit.median_brightness < TOO_DARK_MEDIAN {
        fit.warnings.push(format!(
            "the image is too dark to carry shape (median {:.2} % of full range)",
            100.0 * fit.median_brightness
        ));
    }
    if fit.rie_trusted.is_nan() || fit.rie_trusted > POOR_RIE || fit.poor_share > POOR_SHARE {
        fit.warnings.push(format!(
            "the model does not fit this image: RIE {:.3} over trusted pixels, {:.0} % of them \
             off by more than {:.0} % (the light's position, albedo, shadows or highlights?); \
             see the residual map and mask what the model cannot explain",
            fit.rie_trusted,
            100.0 * fit.poor_share,
            100.0 * POOR_RESIDUAL
        ));
    }
    if fit.highlight_poor_share >= HIGHLIGHT_POOR_SHARE
        && fit.highlight_poor_share >= 2.0 * fit.poor_share
    {
        fit.warnings.push(format!(
            "the brightest pixels are brighter than the model explains ({:.0} % of the \
             brightest {:.0} % by more than {:.0} %): a glossy surface? Solve with \
             --reflectance blinn-phong, or lower their confidence (--auto-confidence, the \
             viewer's brush)",
            100.0 * fit.highlight_poor_share,
            100.0 * HIGHLIGHT_SHARE,
            100.0 * POOR_RESIDUAL
        ));
    }
    if fit.near_black_share > 0.1 {
        fit.warnings.push(format!(
            "{:.0} % of the object is near-black (below {:.1} % of full range): no shape there",
            100.0 * fit.near_black_share,
            100.0 * NEAR_BLACK
        ));
    }
    if fit.saturated_share > 0.02 {
        fit.warnings.push(format!(
            "{:.1} % of the object is saturated{} (not trusted)",
            100.0 * fit.saturated_share,
            if photographs.saturated.is_some() {
                " in a photograph"
            } else {
                ""
            }
        ));
    }
    fit
}

/// Why [`suggest_confidence`] lowered a pixel's confidence: counts of object
/// pixels per reason (a pixel counts under every reason that applies).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Suggestion {
    /// Saturated highlights (and their 1-pixel rim).
    pub saturated: usize,
    /// Near-black pixels.
    pub near_black: usize,
    /// Cast shadows: much darker than the model predicts, or than their
    /// surroundings without a model.
    pub shadow: usize,
    /// The band along the object's silhouette.
    pub silhouette: usize,
}

/// Confidence of the silhouette band.
const SILHOUETTE_CONFIDENCE: f64 = 0.3;

/// Proposes a confidence in [0, 1] (1 = trusted) for `image` on `object`:
/// 0 on saturated highlights (with a 1-pixel rim), near-black pixels and
/// cast shadows, 0.3 on the silhouette band (1 % of the object's size, at
/// least 2 pixels). Cast shadows are pixels darker than half the model's
/// prediction where a `reprojection` is given, else darker than 30 % of the
/// local mean brightness of the object (a box of 20 % of its size). Off the
/// object the confidence is 0. The image is one photograph
/// ([`suggest_confidence_photographs`] with [`Photographs::ONE`]).
pub fn suggest_confidence(
    image: &Grid<f64>,
    object: &Grid<bool>,
    reprojection: Option<&Grid<f64>>,
) -> (Grid<f64>, Suggestion) {
    suggest_confidence_photographs(image, object, reprojection, Photographs::ONE)
}

/// [`suggest_confidence`] for an image made of `photographs`: highlights
/// are where `photographs.saturated` says (a sum: where one photograph was
/// saturated), near-black is judged on the photographs' scale.
pub fn suggest_confidence_photographs(
    image: &Grid<f64>,
    object: &Grid<bool>,
    reprojection: Option<&Grid<f64>>,
    photographs: Photographs<'_>,
) -> (Grid<f64>, Suggestion) {
    let (w, h) = image.size();
    let on = |c: usize, r: usize| *object.at(c, r);
    let (mut min_c, mut max_c, mut min_r, mut max_r) = (w, 0, h, 0);
    for r in 0..h {
        for c in 0..w {
            if on(c, r) {
                min_c = min_c.min(c);
                max_c = max_c.max(c);
                min_r = min_r.min(r);
                max_r = max_r.max(r);
            }
        }
    }
    let size = if max_c >= min_c && max_r >= min_r {
        ((max_c - min_c + 1) as f64).hypot((max_r - min_r + 1) as f64)
    } else {
        0.0
    };
    let band = ((0.01 * size).round() as usize).max(2);
    let distance = distance_to_background(object);
    let local_mean = match reprojection {
        Some(_) => None,
        None => Some(box_mean_on(image, object, ((0.1 * size) as usize).max(4))),
    };
    let mut count = Suggestion::default();
    let confidence = Grid::from_fn(w, h, |c, r| {
        if !on(c, r) {
            return 0.0;
        }
        let i = *image.at(c, r);
        let mut conf: f64 = 1.0;
        let near_saturated = (r.saturating_sub(1)..(r + 2).min(h)).any(|rr| {
            (c.saturating_sub(1)..(c + 2).min(w))
                .any(|cc| photographs.saturated_at(image, rr * w + cc))
        });
        if near_saturated {
            conf = 0.0;
            count.saturated += 1;
        }
        if i * photographs.scale < NEAR_BLACK {
            conf = 0.0;
            count.near_black += 1;
        }
        let shadow = match (reprojection, &local_mean) {
            (Some(model), _) => {
                let predicted = *model.at(c, r);
                predicted * photographs.scale > NEAR_BLACK && i < 0.5 * predicted
            }
            (None, Some(mean)) => i < 0.3 * mean.at(c, r),
            (None, None) => false,
        };
        if shadow {
            conf = 0.0;
            count.shadow += 1;
        }
        if *distance.at(c, r) <= band {
            conf = conf.min(SILHOUETTE_CONFIDENCE);
            count.silhouette += 1;
        }
        conf
    });
    (confidence, count)
}

/// City-block distance (pixels) of each object pixel to the nearest
/// background pixel or image border (two-pass chamfer); 0 off the object.
fn distance_to_background(object: &Grid<bool>) -> Grid<usize> {
    let (w, h) = object.size();
    let far = w + h;
    let mut d = Grid::from_fn(w, h, |c, r| {
        if !*object.at(c, r) {
            0
        } else {
            // The image border counts as background.
            (c + 1).min(r + 1).min(w - c).min(h - r)
        }
    });
    for r in 0..h {
        for c in 0..w {
            if *d.at(c, r) == 0 {
                continue;
            }
            let mut v = (*d.at(c, r)).min(far);
            if c > 0 {
                v = v.min(d.at(c - 1, r) + 1);
            }
            if r > 0 {
                v = v.min(d.at(c, r - 1) + 1);
            }
            *d.at_mut(c, r) = v;
        }
    }
    for r in (0..h).rev() {
        for c in (0..w).rev() {
            if *d.at(c, r) == 0 {
                continue;
            }
            let mut v = *d.at(c, r);
            if c + 1 < w {
                v = v.min(d.at(c + 1, r) + 1);
            }
            if r + 1 < h {
                v = v.min(d.at(c, r + 1) + 1);
            }
            *d.at_mut(c, r) = v;
        }
    }
    d
}

/// The mean of `image` over object pixels in a `(2 radius + 1)^2` box, by
/// summed-area tables.
fn box_mean_on(image: &Grid<f64>, object: &Grid<bool>, radius: usize) -> Grid<f64> {
    let (w, h) = image.size();
    let mut sum = vec![0.0; (w + 1) * (h + 1)];
    let mut count = vec![0.0; (w + 1) * (h + 1)];
    for r in 0..h {
        for c in 0..w {
            let (v, n) = if *object.at(c, r) {
                (*image.at(c, r), 1.0)
            } else {
                (0.0, 0.0)
            };
            let q = (r + 1) * (w + 1) + c + 1;
            sum[q] = v + sum[q - 1] + sum[q - w - 1] - sum[q - w - 2];
            count[q] = n + count[q - 1] + count[q - w - 1] - count[q - w - 2];
        }
    }
    let rect = |t: &[f64], c0: usize, r0: usize, c1: usize, r1: usize| {
        t[r1 * (w + 1) + c1] - t[r0 * (w + 1) + c1] - t[r1 * (w + 1) + c0] + t[r0 * (w + 1) + c0]
    };
    Grid::from_fn(w, h, |c, r| {
        let (c0, r0) = (c.saturating_sub(radius), r.saturating_sub(radius));
        let (c1, r1) = ((c + radius + 1).min(w), (r + radius + 1).min(h));
        let n = rect(&count, c0, r0, c1, r1);
        if n > 0.0 {
            rect(&sum, c0, r0, c1, r1) / n
        } else {
            0.0
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sphere of radius 0.4 at distance 2 on the axis, in front of a plane
    /// at depth `plane_z` (`None`: nothing behind, background), lit from the
    /// optical centre, `s = 1`, rendered in closed form (exact normals):
    /// image, depth (NaN on the background) and the camera.
    fn sphere_scene(plane_z: Option<f64>, side: usize) -> (Grid<f64>, Grid<f64>, Intrinsics) {
        let camera = Intrinsics::centred(side as f64, side, side);
        let (centre, radius) = (glam::DVec3::new(0.05, -0.03, 2.0), 0.4);
        let mut image = Grid::filled(side, side, 0.0);
        let mut depth = Grid::filled(side, side, f64::NAN);
        for r in 0..side {
            for c in 0..side {
                let (x, y) = camera.image_xy(c as f64, r as f64);
                let ray =
                    glam::DVec3::new(x / camera.focal_px, y / camera.focal_px, 1.0).normalize();
                // Nearest hit of the sphere, else the plane.
                let b = ray.dot(centre);
                let disc = b * b - (centre.length_squared() - radius * radius);
                let hit = if disc >= 0.0 {
                    let t = b - disc.sqrt();
                    let normal = (ray * t - centre) / radius;
                    Some((t, (-normal.dot(ray)).max(0.0), ray.z * t))
                } else {
                    plane_z.map(|z| {
                        let t = z / ray.z;
                        (t, ray.z, z)
                    })
                };
                if let Some((t, cosine, z)) = hit {
                    *image.at_mut(c, r) = cosine / (t * t);
                    *depth.at_mut(c, r) = z;
                }
            }
        }
        (image, depth, camera)
    }

    #[test]
    fn occlusion_edges_lie_on_a_contour_over_a_surface_and_nowhere_else() {
        let side = 128;
        let (image, depth, camera) = sphere_scene(Some(3.0), side);
        let edges = occlusion_edges(&image, &depth, camera);
        let on: Vec<(usize, usize)> = (0..side)
            .flat_map(|r| (0..side).map(move |c| (c, r)))
            .filter(|&(c, r)| *edges.at(c, r))
            .collect();
        // The sphere's contour over the plane is about 2 pi 0.4 / 2 * 128
        // = 161 pixels around; most of it is found.
        assert!(on.len() > 80, "{} contour pixels", on.len());
        // Every one is on the sphere, beside the plane (a depth jump).
        for &(c, r) in &on {
            let z = *depth.at(c, r);
            assert!(z < 2.5, "({c}, {r}) at depth {z} is not on the sphere");
            let behind = [(c - 1, r), (c + 1, r), (c, r - 1), (c, r + 1)]
                .iter()
                .any(|&(cc, rr)| *depth.at(cc, rr) > 2.9);
            assert!(behind, "({c}, {r}) is not beside the plane");
        }
        let fit = ModelFit::default().with_occlusion_edges(&edges, &depth);
        assert!((fit.occlusion_edge_share - on.len() as f64 / (side * side) as f64).abs() < 1e-12);
        assert!(
            fit.warnings
                .iter()
                .any(|w| w.contains("an occluding contour"))
        );

        // The same sphere against the background: its silhouette is no
        // occluding contour over anything solved.
        let (alone, alone_depth, camera) = sphere_scene(None, side);
        let none = occlusion_edges(&alone, &alone_depth, camera);
        assert!(!none.as_slice().iter().any(|&e| e));
        let quiet = ModelFit::default().with_occlusion_edges(&none, &alone_depth);
        assert!(quiet.warnings.is_empty() && quiet.occlusion_edge_share == 0.0);

        // A smooth surface turning steeply (the Sombrero) has none.
        let sombrero = crate::scene::sombrero::sombrero(side, side);
        let smooth = occlusion_edges(&sombrero.image, &sombrero.depth_gt, sombrero.camera);
        assert!(!smooth.as_slice().iter().any(|&e| e));
    }

    #[test]
    fn occlusion_edges_do_not_depend_on_exposure_or_the_depth_unit() {
        let (image, depth, camera) = sphere_scene(Some(3.0), 96);
        let edges = occlusion_edges(&image, &depth, camera);
        assert!(edges.as_slice().iter().any(|&e| e));
        // Exposure x 0.25 and depth in units a thousand times smaller.
        let dimmed = occlusion_edges(&image.map(|v| 0.25 * v), &depth, camera);
        let rescaled = occlusion_edges(&image, &depth.map(|z| 1000.0 * z), camera);
        assert_eq!(edges, dimmed);
        assert_eq!(edges, rescaled);
    }

    #[test]
    fn a_dark_image_is_called_dark_and_a_lit_one_is_not() {
        let dark = Grid::filled(20, 20, 0.0005);
        assert!(darkness_warning(&dark, None).unwrap().contains("too dark"));
        let lit = Grid::filled(20, 20, 0.2);
        assert!(darkness_warning(&lit, None).is_none());
        let domain = Grid::filled(20, 20, true);
        let fit = measure(&dark, &dark, &domain, None, 0.0005);
        assert!(
            fit.warnings.iter().any(|w| w.contains("too dark")),
            "{fit:?}"
        );
    }

    #[test]
    fn a_perfect_fit_has_no_warning_and_a_wrong_one_has() {
        let image = Grid::from_fn(30, 30, |c, _| 0.2 + 0.01 * c as f64);
        let domain = Grid::filled(30, 30, true);
        let good = measure(&image, &image, &domain, None, 0.3);
        assert_eq!(good.rie_trusted, 0.0);
        assert!(good.warnings.is_empty(), "{good:?}");
        let wrong = image.map(|v| 0.5 * v);
        let bad = measure(&image, &wrong, &domain, None, 0.3);
        assert!((bad.rie_trusted - 0.5).abs() < 1e-12);
        assert_eq!(bad.poor_share, 1.0);
        assert!(bad.warnings.iter().any(|w| w.contains("does not fit")));
        // Untrusted pixels do not count.
        let zero = Grid::filled(30, 30, 0.0);
        let ignored = measure(&image, &wrong, &domain, Some(&zero), 0.3);
        assert_eq!(ignored.poor_share, 0.0);
        // A black reprojection against an unusable reference is all badly
        // explained, consistent with its RIE of 1.
        let black = measure(&image, &zero, &domain, None, f64::INFINITY);
        assert!((black.rie_trusted - 1.0).abs() < 1e-12);
        assert_eq!(black.poor_share, 1.0);
    }

    #[test]
    fn highlights_the_model_cannot_show_are_named() {
        // A matte reprojection of an image with a glossy spot: the
        // brightest pixels are the badly explained ones.
        let matte = Grid::from_fn(50, 50, |c, r| 0.2 + 0.002 * (c + r) as f64);
        let mut glossy = matte.clone();
        // 64 pixels: more than the brightest 2 % of 2500.
        for r in 20..28 {
            for c in 20..28 {
                *glossy.at_mut(c, r) = 0.9;
            }
        }
        let domain = Grid::filled(50, 50, true);
        let fit = measure(&glossy, &matte, &domain, None, 0.4);
        assert_eq!(fit.highlight_poor_share, 1.0);
        assert!(fit.warnings.iter().any(|w| w.contains("glossy")), "{fit:?}");
        // The same misfit spread evenly (a darker model everywhere) is no
        // highlight.
        let darker = glossy.map(|v| 0.7 * v);
        let even = measure(&glossy, &darker, &domain, None, 0.4);
        assert!(
            !even.warnings.iter().any(|w| w.contains("glossy")),
            "{even:?}"
        );
        // Brightest pixels explained: nothing.
        let exact = measure(&glossy, &glossy, &domain, None, 0.4);
        assert_eq!(exact.highlight_poor_share, 0.0);
    }

    #[test]
    fn suggestions_mark_highlights_black_shadows_and_the_rim() {
        let mut image = Grid::filled(40, 40, 0.3);
        *image.at_mut(20, 20) = 1.0; // highlight
        *image.at_mut(10, 10) = 0.001; // near-black
        for r in 25..30 {
            for c in 25..30 {
                *image.at_mut(c, r) = 0.05; // a cast shadow
            }
        }
        let object = Grid::from_fn(40, 40, |c, r| (3..37).contains(&c) && (3..37).contains(&r));
        let (conf, count) = suggest_confidence(&image, &object, None);
        assert_eq!(*conf.at(20, 20), 0.0);
        assert_eq!(*conf.at(21, 21), 0.0, "the rim of a highlight");
        assert_eq!(*conf.at(10, 10), 0.0);
        assert_eq!(*conf.at(27, 27), 0.0, "shadow");
        assert_eq!(*conf.at(3, 20), SILHOUETTE_CONFIDENCE);
        assert_eq!(*conf.at(15, 15), 1.0);
        assert_eq!(*conf.at(0, 0), 0.0, "off the object");
        assert_eq!(count.saturated, 9);
        // The 5x5 shadow and the near-black pixel, darker than their surroundings.
        assert_eq!(count.shadow, 26);
        // With a model, a pixel darker than half its prediction is a shadow.
        let model = Grid::filled(40, 40, 0.3);
        let (conf, _) = suggest_confidence(&image, &object, Some(&model));
        assert_eq!(*conf.at(27, 27), 0.0);
        assert_eq!(*conf.at(15, 15), 1.0);
    }
}
