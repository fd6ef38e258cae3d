//! A brush and the state of a stroke in progress (what `Masks` holds); the
//! painting itself is in `stroke`.

use serde::{Deserialize, Serialize};

use super::rect::Rect;
use super::types::{MIN_BRUSH_RADIUS_PX, MaskError, Mode, parameter};

/// A round brush.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Brush {
    /// Radius in image pixels, at least [`MIN_BRUSH_RADIUS_PX`].
    pub radius_px: f32,
    /// In [0, 1]: coverage is full up to `hardness * radius_px` from the
    /// stroke and falls smoothly to 0 at `radius_px`; 1 = hard edge.
    pub hardness: f32,
    /// Paint or erase.
    pub mode: Mode,
}

impl Brush {
    /// Checks `radius_px` (finite, `>= MIN_BRUSH_RADIUS_PX`) and `hardness`
    /// (in [0, 1]); the error names the field.
    pub fn validate(&self) -> Result<(), MaskError> {
        if !(self.radius_px.is_finite() && self.radius_px >= MIN_BRUSH_RADIUS_PX) {
            let reason = format!(
                "{} (must be at least {MIN_BRUSH_RADIUS_PX})",
                self.radius_px
            );
            return Err(parameter("radius_px", reason));
        }
        if !(0.0..=1.0).contains(&self.hardness) {
            let reason = format!("{} (must lie in [0, 1])", self.hardness);
            return Err(parameter("hardness", reason));
        }
        Ok(())
    }

    /// Coverage in [0, 1] of a pixel whose centre is `distance_px` from the
    /// stroke: 1 up to `r0 = hardness * radius_px`, then the smoothstep
    /// `t^2 (3 - 2t)` with `t = (radius_px - d) / (radius_px - r0)`, 0 from
    /// `radius_px` on. With hardness 1 it is 1 for `d <= radius_px`, else 0.
    pub fn coverage(&self, distance_px: f32) -> f32 {
        let inner = self.hardness * self.radius_px;
        if distance_px <= inner {
            1.0
        } else if distance_px >= self.radius_px {
            0.0
        } else {
            let t = (self.radius_px - distance_px) / (self.radius_px - inner);
            t * t * (3.0 - 2.0 * t)
        }
    }
}

/// A layer's values at the start of a stroke.
#[derive(Clone, Debug)]
pub(super) enum Snapshot {
    Confidence(Vec<f32>),
    Object(Vec<bool>),
}

/// A stroke in progress.
#[derive(Clone, Debug)]
pub(super) struct Stroke {
    pub(super) brush: Brush,
    /// Largest coverage per pixel so far (whole layer).
    pub(super) coverage: Vec<f32>,
    pub(super) start: Snapshot,
    /// Bounding box of the pixels changed so far.
    pub(super) dirty: Option<Rect>,
}
