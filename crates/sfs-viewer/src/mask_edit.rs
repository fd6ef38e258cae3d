//! The mask editing model behind the image panel: the solver's two masks as
//! editable layers, brush strokes, shapes, whole-layer operations, undo/redo
//! with compact diffs, PNG load/save, crash-safe autosave and the overlay
//! texture. No UI and no egui: the app maps pointer events to these calls.
//!
//! # Coordinates
//!
//! Every position is an [`ImagePoint`] in image pixel coordinates `[x, y]`:
//! pixel `(column c, row r)` covers `[c, c + 1) x [r, r + 1)`, its centre is
//! `(c + 0.5, r + 0.5)`, and brushes and shapes test pixel centres. The app
//! maps screen positions to image coordinates with its zoom/pan transform, so
//! the masks do not depend on the zoom.
//!
//! # Layers and modes
//!
//! [`Layer::Confidence`] holds `c` in [0, 1] (1 = trusted, the default; 0 =
//! do not trust); [`Layer::Object`] holds `true` for object (surface, the
//! default) and `false` for background (no surface). [`Mode::Paint`] excludes
//! (towards `c = 0` / background), [`Mode::Erase`] restores (towards `c = 1` /
//! object).
//!
//! # Strokes
//!
//! A stroke keeps, for every pixel, the largest brush coverage it has received
//! so far (coverage falls with the distance from the pixel centre to each
//! segment, see [`Brush::coverage`]) and sets each pixel from its value at the
//! start of the stroke `c0` and that coverage `a`:
//! paint `c = min(c0, 1 - a)`, erase `c = max(c0, a)`; on the object layer a
//! pixel flips when `a >= 0.5`. A segment is covered exactly (the distance to
//! the whole segment, the limit of infinitely dense stamps), so fast mouse
//! moves leave no gaps, overlapping parts of one stroke do not compound and
//! the result does not depend on the order or direction of the segments.
//!
//! # History
//!
//! Every edit (a whole stroke, a shape, a whole-layer operation, a load) is
//! one undo step holding the bounding box of the pixels it changed with their
//! values before and after. The history keeps at most
//! [`Masks::history_limit_bytes`] of such diffs (default
//! [`DEFAULT_HISTORY_BYTES`]) and drops the oldest steps beyond it; the newest
//! step is always kept, even when it alone is larger.

use std::collections::VecDeque;
use std::fs;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};
use sfs_core::grid::Grid;
use sfs_core::io::{self, IoError};

/// A position in image pixel coordinates `[x, y]` (see the module docs).
pub type ImagePoint = [f32; 2];

/// Default bound on the undo/redo history: 256 MiB of diffs.
pub const DEFAULT_HISTORY_BYTES: usize = 256 << 20;

/// Smallest accepted brush radius. A hard brush of this radius centred on a
/// pixel centre covers exactly that pixel; radii below about 0.71 can miss
/// every pixel centre when the cursor is near a pixel corner.
pub const MIN_BRUSH_RADIUS_PX: f32 = 0.5;

/// File names inside an autosave folder.
const AUTOSAVE_JSON: &str = "autosave.json";
const AUTOSAVE_CONFIDENCE: &str = "confidence.png";
const AUTOSAVE_OBJECT: &str = "object.png";
const AUTOSAVE_FORMAT: u32 = 1;

/// Why a mask operation failed; messages name the file or parameter.
#[derive(Debug, thiserror::Error)]
pub enum MaskError {
    /// Reading or writing a file failed (the message names the file; a mask
    /// file of the wrong size is [`IoError::SizeMismatch`]).
    #[error(transparent)]
    Io(#[from] IoError),
    /// A parameter is out of range.
    #[error("invalid {name}: {reason}")]
    Parameter {
        /// The parameter, as named in the API (`radius_px`, `tolerance`, ...).
        name: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// An image or layer passed in does not have the size of the masks.
    #[error(
        "the {what} is {}x{} but the masks are {}x{}",
        found.0, found.1, expected.0, expected.1
    )]
    SizeMismatch {
        /// What was passed in (`image`, `object mask`).
        what: &'static str,
        /// Its `(width, height)`.
        found: (usize, usize),
        /// The masks' `(width, height)`.
        expected: (usize, usize),
    },
    /// An autosave folder exists but cannot be restored.
    #[error("autosave {} is unusable: {reason}", path.display())]
    Autosave {
        /// The autosave file concerned.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
}

fn parameter(name: &'static str, reason: String) -> MaskError {
    MaskError::Parameter { name, reason }
}

/// Which mask an edit applies to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Layer {
    /// The confidence mask, `c` in [0, 1], 1 = trusted.
    Confidence,
    /// The object mask, `true` = object, `false` = background.
    Object,
}

/// What an edit does to the pixels it covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Mode {
    /// Exclude: confidence towards 0, object to background.
    Paint,
    /// Restore: confidence towards 1, object to object.
    Erase,
}

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

/// Colours of [`Masks::overlay_rgba`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OverlayStyle {
    /// Colour of untrusted pixels; alpha `opacity * (1 - c)`.
    pub confidence_rgb: [u8; 3],
    /// Colour of background (non-object) pixels.
    pub background_rgb: [u8; 3],
    /// Overall opacity in [0, 1] (values outside are clamped, NaN is 0).
    pub opacity: f32,
    /// Period in pixels of the diagonal hatching of the background: half of
    /// each period at full opacity, the rest at a third of it; 0 = solid.
    pub hatch_period_px: usize,
}

impl Default for OverlayStyle {
    /// Red for untrusted, blue hatching for background, opacity 0.5,
    /// hatch period 8 pixels.
    fn default() -> Self {
        Self {
            confidence_rgb: [230, 40, 40],
            background_rgb: [40, 90, 230],
            opacity: 0.5,
            hatch_period_px: 8,
        }
    }
}

/// A pixel rectangle `[x0, x1) x [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rect {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
}

impl Rect {
    fn new(x0: usize, y0: usize, x1: usize, y1: usize) -> Self {
        Self { x0, y0, x1, y1 }
    }

    fn width(&self) -> usize {
        self.x1 - self.x0
    }

    fn area(&self) -> usize {
        self.width() * (self.y1 - self.y0)
    }

    /// The smallest rectangle holding `rect` (if any) and pixel `(c, r)`.
    fn include(rect: Option<Rect>, c: usize, r: usize) -> Rect {
        match rect {
            None => Rect::new(c, r, c + 1, r + 1),
            Some(q) => Rect::new(q.x0.min(c), q.y0.min(r), q.x1.max(c + 1), q.y1.max(r + 1)),
        }
    }

    /// The smallest rectangle holding this one and `other` (if any).
    fn union(self, other: Option<Rect>) -> Rect {
        let q = Rect::include(other, self.x0, self.y0);
        Rect::include(Some(q), self.x1 - 1, self.y1 - 1)
    }

    /// The values of this rectangle taken from `data`, the row-major values
    /// of rectangle `within` (which holds this one).
    fn gather<T: Copy>(&self, data: &[T], within: Rect) -> Vec<T> {
        let mut out = Vec::with_capacity(self.area());
        for r in self.y0..self.y1 {
            let start = (r - within.y0) * within.width() + self.x0 - within.x0;
            out.extend_from_slice(&data[start..start + self.width()]);
        }
        out
    }
}

/// The whole of `grid` as a rectangle.
fn whole<T>(grid: &Grid<T>) -> Rect {
    Rect::new(0, 0, grid.width(), grid.height())
}

/// Indices `[start, end)` of the pixels among `0..n` whose centres lie in
/// `[lo, hi]`; `None` when there are none (or a bound is NaN).
fn span(lo: f32, hi: f32, n: usize) -> Option<(usize, usize)> {
    let start = (f64::from(lo) - 0.5).ceil().max(0.0);
    let end = ((f64::from(hi) - 0.5).floor() + 1.0).min(n as f64);
    (start < end).then_some((start as usize, end as usize))
}

/// The pixels of a `size` grid whose centres lie in `[x0, x1] x [y0, y1]`.
fn rect_spanning(x: (f32, f32), y: (f32, f32), size: (usize, usize)) -> Option<Rect> {
    let (x0, x1) = span(x.0, x.1, size.0)?;
    let (y0, y1) = span(y.0, y.1, size.1)?;
    Some(Rect::new(x0, y0, x1, y1))
}

/// Distance from `p` to the segment `a`-`b`, symmetric in `a` and `b` to
/// the last bit (so a segment's direction does not matter).
fn distance_to_segment(p: ImagePoint, a: ImagePoint, b: ImagePoint) -> f32 {
    let (a, b) = if (a[0], a[1]) <= (b[0], b[1]) {
        (a, b)
    } else {
        (b, a)
    };
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let (px, py) = (p[0] - a[0], p[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        ((px * dx + py * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((px - t * dx).powi(2) + (py - t * dy).powi(2)).sqrt()
}

/// A layer's cell type.
trait Cell: Copy + PartialEq {
    /// The value of a cleared layer.
    const DEFAULT: Self;
    /// What a hard shape sets in `mode`.
    fn target(mode: Mode) -> Self;
    /// A stroke's value from the value at its start and its coverage.
    fn blend(start: Self, coverage: f32, mode: Mode) -> Self;
    /// The inverted value.
    fn inverted(self) -> Self;
}

impl Cell for f32 {
    const DEFAULT: Self = 1.0;
    fn target(mode: Mode) -> Self {
        if mode == Mode::Erase { 1.0 } else { 0.0 }
    }
    fn blend(start: Self, coverage: f32, mode: Mode) -> Self {
        match mode {
            Mode::Paint => start.min(1.0 - coverage),
            Mode::Erase => start.max(coverage),
        }
    }
    fn inverted(self) -> Self {
        1.0 - self
    }
}

impl Cell for bool {
    const DEFAULT: Self = true;
    fn target(mode: Mode) -> Self {
        mode == Mode::Erase
    }
    fn blend(start: Self, coverage: f32, mode: Mode) -> Self {
        if coverage >= 0.5 {
            Self::target(mode)
        } else {
            start
        }
    }
    fn inverted(self) -> Self {
        !self
    }
}

/// One layer's part of an undo step: the values of `rect` before and after.
#[derive(Clone, Debug)]
struct Diff<T> {
    rect: Rect,
    before: Vec<T>,
    after: Vec<T>,
}

impl<T: Copy> Diff<T> {
    fn bytes(&self) -> usize {
        size_of::<Self>() + (self.before.len() + self.after.len()) * size_of::<T>()
    }

    fn apply(&self, grid: &mut Grid<T>, forward: bool) {
        let (w, rect) = (grid.width(), self.rect);
        let values = if forward { &self.after } else { &self.before };
        for (k, r) in (rect.y0..rect.y1).enumerate() {
            grid.as_mut_slice()[r * w + rect.x0..r * w + rect.x1]
                .copy_from_slice(&values[k * rect.width()..(k + 1) * rect.width()]);
        }
    }
}

/// The diff between `before` (the values of `rect`) and `grid`, over the
/// bounding box of the pixels that differ; `None` when none does.
fn diff<T: Copy + PartialEq>(grid: &Grid<T>, before: &[T], rect: Rect) -> Option<Diff<T>> {
    let now = grid.as_slice();
    let mut changed = None;
    for r in rect.y0..rect.y1 {
        for c in rect.x0..rect.x1 {
            if now[r * grid.width() + c] != before[(r - rect.y0) * rect.width() + c - rect.x0] {
                changed = Some(Rect::include(changed, c, r));
            }
        }
    }
    let tight = changed?;
    let (before, after) = (tight.gather(before, rect), tight.gather(now, whole(grid)));
    Some(Diff {
        rect: tight,
        before,
        after,
    })
}

/// Sets every pixel of `rect` to `f(column, row, old)` and returns the diff.
fn region_edit<T: Copy + PartialEq>(
    grid: &mut Grid<T>,
    rect: Rect,
    mut f: impl FnMut(usize, usize, T) -> T,
) -> Option<Diff<T>> {
    let before = rect.gather(grid.as_slice(), whole(grid));
    for r in rect.y0..rect.y1 {
        for c in rect.x0..rect.x1 {
            let v = grid.at_mut(c, r);
            *v = f(c, r, *v);
        }
    }
    diff(grid, &before, rect)
}

/// One undo step.
#[derive(Clone, Debug)]
enum Change {
    Confidence(Diff<f32>),
    Object(Diff<bool>),
}

impl Change {
    fn bytes(&self) -> usize {
        match self {
            Change::Confidence(d) => d.bytes(),
            Change::Object(d) => d.bytes(),
        }
    }
}

/// Covers segment `from`-`to` with `brush`: raises the stroke's per-pixel
/// coverage and sets the values from the stroke's start values. Returns the
/// bounding box of the values that changed. Allocates nothing.
fn stamp<T: Cell>(
    values: &mut [T],
    start: &[T],
    coverage: &mut [f32],
    size: (usize, usize),
    brush: &Brush,
    [from, to]: [ImagePoint; 2],
) -> Option<Rect> {
    let r = brush.radius_px;
    let x = (from[0].min(to[0]) - r, from[0].max(to[0]) + r);
    let y = (from[1].min(to[1]) - r, from[1].max(to[1]) + r);
    let rect = rect_spanning(x, y, size)?;
    let mut changed = None;
    for row in rect.y0..rect.y1 {
        for col in rect.x0..rect.x1 {
            let centre = [col as f32 + 0.5, row as f32 + 0.5];
            let a = brush.coverage(distance_to_segment(centre, from, to));
            let i = row * size.0 + col;
            if a > coverage[i] {
                coverage[i] = a;
                let v = T::blend(start[i], a, brush.mode);
                if v != values[i] {
                    values[i] = v;
                    changed = Some(Rect::include(changed, col, row));
                }
            }
        }
    }
    changed
}

/// A layer's values at the start of a stroke.
#[derive(Clone, Debug)]
enum Snapshot {
    Confidence(Vec<f32>),
    Object(Vec<bool>),
}

/// A stroke in progress.
#[derive(Clone, Debug)]
struct Stroke {
    brush: Brush,
    /// Largest coverage per pixel so far (whole layer).
    coverage: Vec<f32>,
    start: Snapshot,
    /// Bounding box of the pixels changed so far.
    dirty: Option<Rect>,
}

/// A hard region operation on one layer.
enum Op<'a> {
    /// Sets the pixels for which the predicate holds to the mode's target.
    Set(Mode, &'a dyn Fn(usize, usize) -> bool),
    Clear,
    Invert,
}

impl Op<'_> {
    fn apply<T: Cell>(&self, c: usize, r: usize, v: T) -> T {
        match self {
            Op::Set(mode, inside) if inside(c, r) => T::target(*mode),
            Op::Set(..) => v,
            Op::Clear => T::DEFAULT,
            Op::Invert => v.inverted(),
        }
    }
}

/// Undo and redo stacks with their total size.
#[derive(Clone, Debug)]
struct History {
    undo: VecDeque<Change>,
    redo: Vec<Change>,
    bytes: usize,
    limit_bytes: usize,
}

impl History {
    fn push(&mut self, change: Change) {
        for c in self.redo.drain(..) {
            self.bytes -= c.bytes();
        }
        self.bytes += change.bytes();
        self.undo.push_back(change);
        self.trim();
    }

    /// Drops the oldest undo steps (keeping the newest), then the farthest
    /// redo steps, until the history fits its limit.
    fn trim(&mut self) {
        while self.bytes > self.limit_bytes && self.undo.len() > 1 {
            if let Some(c) = self.undo.pop_front() {
                self.bytes -= c.bytes();
            }
        }
        while self.bytes > self.limit_bytes && !self.redo.is_empty() {
            self.bytes -= self.redo.remove(0).bytes();
        }
    }
}

/// The two editable masks of one image, with their undo/redo history.
#[derive(Clone, Debug)]
pub struct Masks {
    confidence: Grid<f32>,
    object: Grid<bool>,
    history: History,
    stroke: Option<Stroke>,
    revision: u64,
}

/// Contents of `autosave.json`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct AutosaveInfo {
    format: u32,
    image: String,
    width: usize,
    height: usize,
    saved_unix_s: u64,
}

impl Masks {
    /// Default masks (every pixel trusted and object) for a `width` x
    /// `height` image.
    pub fn new(width: usize, height: usize) -> Self {
        let confidence = Grid::filled(width, height, 1.0);
        let object = Grid::filled(width, height, true);
        Self::with_layers(confidence, object)
    }

    fn with_layers(confidence: Grid<f32>, object: Grid<bool>) -> Self {
        let (undo, redo) = (VecDeque::new(), Vec::new());
        let limit_bytes = DEFAULT_HISTORY_BYTES;
        let history = History {
            undo,
            redo,
            bytes: 0,
            limit_bytes,
        };
        Self {
            confidence,
            object,
            history,
            stroke: None,
            revision: 0,
        }
    }

    /// Masks holding the given layers, with an empty history. Errors when the
    /// sizes differ or a confidence value is outside [0, 1].
    pub fn from_layers(confidence: Grid<f32>, object: Grid<bool>) -> Result<Self, MaskError> {
        let (found, expected) = (object.size(), confidence.size());
        if found != expected {
            return Err(MaskError::SizeMismatch {
                what: "object mask",
                found,
                expected,
            });
        }
        let values = confidence.as_slice();
        if let Some(k) = values.iter().position(|v| !(0.0..=1.0).contains(v)) {
            let (c, r) = (k % expected.0, k / expected.0);
            let reason = format!("value {} at ({c}, {r}) is outside [0, 1]", values[k]);
            return Err(parameter("confidence", reason));
        }
        Ok(Self::with_layers(confidence, object))
    }

    /// `(width, height)` of the masks.
    pub fn size(&self) -> (usize, usize) {
        self.confidence.size()
    }

    /// The confidence layer (1 = trusted).
    pub fn confidence(&self) -> &Grid<f32> {
        &self.confidence
    }

    /// The object layer (`true` = object).
    pub fn object(&self) -> &Grid<bool> {
        &self.object
    }

    /// The confidence for the solver's `Problem`: `None` when every pixel is
    /// trusted.
    pub fn confidence_for_solver(&self) -> Option<Grid<f64>> {
        let all_trusted = self.confidence.as_slice().iter().all(|&v| v == 1.0);
        (!all_trusted).then(|| self.confidence.map(|&v| f64::from(v)))
    }

    /// The object mask for the solver's `Problem`: `None` when every pixel
    /// is object.
    pub fn object_for_solver(&self) -> Option<Grid<bool>> {
        let all_object = self.object.as_slice().iter().all(|&v| v);
        (!all_object).then(|| self.object.clone())
    }

    /// A counter that changes whenever a mask value changes (during strokes
    /// too, and on undo/redo); the app re-solves and re-uploads the overlay
    /// when it differs from the value it last saw.
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// Whether [`Masks::undo`] would do something.
    pub fn can_undo(&self) -> bool {
        !self.history.undo.is_empty() || self.stroke.as_ref().is_some_and(|s| s.dirty.is_some())
    }

    /// Whether [`Masks::redo`] would do something.
    pub fn can_redo(&self) -> bool {
        !self.history.redo.is_empty()
    }

    /// Bytes held by the undo and redo steps.
    pub fn history_bytes(&self) -> usize {
        self.history.bytes
    }

    /// The history bound in bytes.
    pub fn history_limit_bytes(&self) -> usize {
        self.history.limit_bytes
    }

    /// Sets the history bound, dropping the oldest steps that no longer fit.
    pub fn set_history_limit_bytes(&mut self, limit_bytes: usize) {
        self.history.limit_bytes = limit_bytes;
        self.history.trim();
    }

    fn bump(&mut self) {
        self.revision = self.revision.wrapping_add(1);
    }

    /// Pushes `change` (if any) on the history and bumps the revision;
    /// returns whether there was a change.
    fn record(&mut self, change: Option<Change>) -> bool {
        let Some(change) = change else { return false };
        self.history.push(change);
        self.bump();
        true
    }

    fn apply(&mut self, change: &Change, forward: bool) {
        match change {
            Change::Confidence(d) => d.apply(&mut self.confidence, forward),
            Change::Object(d) => d.apply(&mut self.object, forward),
        }
        self.bump();
    }

    /// Undoes the last edit (ending a stroke in progress first); false when
    /// there is nothing to undo.
    pub fn undo(&mut self) -> bool {
        self.end_stroke();
        let Some(change) = self.history.undo.pop_back() else {
            return false;
        };
        self.apply(&change, false);
        self.history.redo.push(change);
        true
    }

    /// Redoes the last undone edit; false when there is none.
    pub fn redo(&mut self) -> bool {
        self.end_stroke();
        let Some(change) = self.history.redo.pop() else {
            return false;
        };
        self.apply(&change, true);
        self.history.undo.push_back(change);
        true
    }

    /// Starts a stroke on `layer` and covers the point `at`. A stroke in
    /// progress is ended first. Errors (changing nothing) on an invalid brush.
    pub fn begin_stroke(
        &mut self,
        layer: Layer,
        brush: Brush,
        at: ImagePoint,
    ) -> Result<(), MaskError> {
        brush.validate()?;
        self.end_stroke();
        let start = match layer {
            Layer::Confidence => Snapshot::Confidence(self.confidence.as_slice().to_vec()),
            Layer::Object => Snapshot::Object(self.object.as_slice().to_vec()),
        };
        let coverage = vec![0.0; self.confidence.len()];
        self.stroke = Some(Stroke {
            brush,
            coverage,
            start,
            dirty: None,
        });
        self.stroke_segment(at, at);
        Ok(())
    }

    /// Covers the segment `from`-`to` with the stroke's brush. Returns false
    /// (doing nothing) when no stroke is in progress or a coordinate is not
    /// finite.
    pub fn stroke_segment(&mut self, from: ImagePoint, to: ImagePoint) -> bool {
        let size = self.size();
        let Some(Stroke {
            brush,
            coverage,
            start,
            dirty,
        }) = self.stroke.as_mut()
        else {
            return false;
        };
        if !from.iter().chain(&to).all(|v| v.is_finite()) {
            return false;
        }
        let changed = match start {
            Snapshot::Confidence(s) => stamp(
                self.confidence.as_mut_slice(),
                s,
                coverage,
                size,
                brush,
                [from, to],
            ),
            Snapshot::Object(s) => stamp(
                self.object.as_mut_slice(),
                s,
                coverage,
                size,
                brush,
                [from, to],
            ),
        };
        if let Some(rect) = changed {
            *dirty = Some(rect.union(*dirty));
            self.bump();
        }
        true
    }

    /// Whether a stroke is in progress.
    pub fn is_stroking(&self) -> bool {
        self.stroke.is_some()
    }

    /// Ends the stroke in progress and returns its change, if any.
    fn take_stroke(&mut self) -> Option<Change> {
        let stroke = self.stroke.take()?;
        let rect = stroke.dirty?;
        Some(match stroke.start {
            Snapshot::Confidence(s) => {
                let before = rect.gather(&s, whole(&self.confidence));
                Change::Confidence(diff(&self.confidence, &before, rect)?)
            }
            Snapshot::Object(s) => {
                let before = rect.gather(&s, whole(&self.object));
                Change::Object(diff(&self.object, &before, rect)?)
            }
        })
    }

    /// Ends the stroke in progress and records it as one undo step; returns
    /// whether a step was recorded (false when no stroke was in progress or
    /// it changed nothing). The revision does not change here.
    pub fn end_stroke(&mut self) -> bool {
        let change = self.take_stroke();
        change.map(|c| self.history.push(c)).is_some()
    }

    /// Abandons the stroke in progress, restoring the values it changed;
    /// returns whether anything was restored.
    pub fn cancel_stroke(&mut self) -> bool {
        let change = self.take_stroke();
        change.map(|c| self.apply(&c, false)).is_some()
    }

    /// Runs `op` over `rect` of `layer` as one undo step (ending a stroke in
    /// progress first); returns whether anything changed.
    fn apply_op(&mut self, layer: Layer, rect: Rect, op: &Op) -> bool {
        self.end_stroke();
        let change = match layer {
            Layer::Confidence => {
                region_edit(&mut self.confidence, rect, |c, r, v| op.apply(c, r, v))
                    .map(Change::Confidence)
            }
            Layer::Object => {
                region_edit(&mut self.object, rect, |c, r, v| op.apply(c, r, v)).map(Change::Object)
            }
        };
        self.record(change)
    }

    /// Sets the pixels whose centres lie in the rectangle with corners `a`
    /// and `b` (edges included) to `mode`'s value (confidence 0/1, object
    /// false/true). Returns whether anything changed (one undo step if so);
    /// non-finite corners change nothing.
    pub fn fill_rect(&mut self, layer: Layer, mode: Mode, a: ImagePoint, b: ImagePoint) -> bool {
        let (x, y) = (
            (a[0].min(b[0]), a[0].max(b[0])),
            (a[1].min(b[1]), a[1].max(b[1])),
        );
        let Some(rect) = rect_spanning(x, y, self.size()) else {
            return false;
        };
        self.apply_op(layer, rect, &Op::Set(mode, &|_, _| true))
    }

    /// Sets the pixels whose centres lie inside the closed `polygon`
    /// (even-odd rule) to `mode`'s value. Fewer than 3 points or a
    /// non-finite coordinate change nothing. Returns whether anything changed.
    pub fn fill_lasso(&mut self, layer: Layer, mode: Mode, polygon: &[ImagePoint]) -> bool {
        if polygon.len() < 3 || !polygon.iter().flatten().all(|v| v.is_finite()) {
            return false;
        }
        let bounds = |k: usize| {
            let lo = polygon.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min);
            (lo, polygon.iter().map(|p| p[k]).fold(lo, f32::max))
        };
        let Some(rect) = rect_spanning(bounds(0), bounds(1), self.size()) else {
            return false;
        };
        let index = |c: usize, r: usize| (r - rect.y0) * rect.width() + c - rect.x0;
        let mut inside = vec![false; rect.area()];
        let mut crossings = Vec::new();
        for r in rect.y0..rect.y1 {
            let y = r as f32 + 0.5;
            crossings.clear();
            for (k, p) in polygon.iter().enumerate() {
                let q = polygon[(k + 1) % polygon.len()];
                if (p[1] <= y) != (q[1] <= y) {
                    crossings.push(p[0] + (y - p[1]) * (q[0] - p[0]) / (q[1] - p[1]));
                }
            }
            crossings.sort_by(f32::total_cmp);
            for pair in crossings.chunks_exact(2) {
                if let Some((c0, c1)) = span(pair[0], pair[1], rect.x1) {
                    (c0.max(rect.x0)..c1).for_each(|c| inside[index(c, r)] = true);
                }
            }
        }
        self.apply_op(layer, rect, &Op::Set(mode, &|c, r| inside[index(c, r)]))
    }

    fn check_image(&self, image: &Grid<f64>) -> Result<(), MaskError> {
        let (found, expected) = (image.size(), self.size());
        if found == expected {
            return Ok(());
        }
        Err(MaskError::SizeMismatch {
            what: "image",
            found,
            expected,
        })
    }

    /// Sets to `mode`'s value the pixels 4-connected to the pixel under
    /// `seed` through pixels whose `image` value is within `tolerance`
    /// (inclusive) of the seed pixel's. A seed outside the image changes
    /// nothing. Errors on an image of another size or a negative or
    /// non-finite tolerance. Returns whether anything changed.
    pub fn flood_fill(
        &mut self,
        layer: Layer,
        mode: Mode,
        image: &Grid<f64>,
        seed: ImagePoint,
        tolerance: f64,
    ) -> Result<bool, MaskError> {
        self.check_image(image)?;
        if !(tolerance.is_finite() && tolerance >= 0.0) {
            let reason = format!("{tolerance} (must be finite and >= 0)");
            return Err(parameter("tolerance", reason));
        }
        let (w, h) = self.size();
        let (x, y) = (seed[0].floor(), seed[1].floor());
        if !(x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h) {
            return Ok(false);
        }
        let (values, seed) = (image.as_slice(), (x as usize, y as usize));
        let seed_value = values[seed.1 * w + seed.0];
        let mut inside = vec![false; w * h];
        inside[seed.1 * w + seed.0] = true;
        let (mut stack, mut rect) = (vec![seed], None);
        while let Some((c, r)) = stack.pop() {
            rect = Some(Rect::include(rect, c, r));
            let (left, up) = (c.wrapping_sub(1), r.wrapping_sub(1));
            for (nc, nr) in [(left, r), (c + 1, r), (c, up), (c, r + 1)] {
                let i = nr.wrapping_mul(w).wrapping_add(nc);
                if nc < w && nr < h && !inside[i] && (values[i] - seed_value).abs() <= tolerance {
                    inside[i] = true;
                    stack.push((nc, nr));
                }
            }
        }
        let rect = Rect::include(rect, seed.0, seed.1);
        Ok(self.apply_op(layer, rect, &Op::Set(mode, &|c, r| inside[r * w + c])))
    }

    /// Resets `layer` to its default (confidence 1, object true). Returns
    /// whether anything changed.
    pub fn clear(&mut self, layer: Layer) -> bool {
        self.apply_op(layer, whole(&self.object), &Op::Clear)
    }

    /// Inverts `layer` (`c -> 1 - c`, object <-> background). Returns whether
    /// anything changed.
    pub fn invert(&mut self, layer: Layer) -> bool {
        self.apply_op(layer, whole(&self.object), &Op::Invert)
    }

    /// Sets the object layer to `image > threshold`: dark background pixels
    /// (and NaN) become background. Errors on an image of another size or a
    /// non-finite threshold. Returns whether anything changed.
    pub fn threshold(&mut self, image: &Grid<f64>, threshold: f64) -> Result<bool, MaskError> {
        self.check_image(image)?;
        if !threshold.is_finite() {
            return Err(parameter(
                "threshold",
                format!("{threshold} (must be finite)"),
            ));
        }
        self.end_stroke();
        let change = region_edit(&mut self.object, whole(image), |c, r, _| {
            *image.at(c, r) > threshold
        });
        Ok(self.record(change.map(Change::Object)))
    }

    /// Sets the confidence layer to `min(current, proposal)` (values clamped
    /// to [0, 1], NaN ignored) as one undo step, so a suggestion can be
    /// undone, erased or painted over; errors on another size. Returns
    /// whether anything changed.
    pub fn lower_confidence(&mut self, proposal: &Grid<f64>) -> Result<bool, MaskError> {
        self.check_image(proposal)?;
        self.end_stroke();
        let change = region_edit(&mut self.confidence, whole(proposal), |c, r, current| {
            let p = *proposal.at(c, r);
            if p.is_finite() {
                current.min(p.clamp(0.0, 1.0) as f32)
            } else {
                current
            }
        })
        .map(Change::Confidence);
        Ok(self.record(change))
    }

    /// Saves `layer` as an 8-bit grey PNG (confidence `round(255 c)`, object
    /// 255 / background 0), written to a temporary file then renamed.
    pub fn save_png(&self, layer: Layer, path: &Path) -> Result<(), MaskError> {
        match layer {
            Layer::Confidence => {
                let values = self.confidence.map(|&v| f64::from(v));
                write_atomic(path, |p| io::write_png8(p, &values))
            }
            Layer::Object => write_atomic(path, |p| io::write_mask_png(p, &self.object)),
        }
    }

    /// Loads `layer` from an image read by `sfs_core::io::read_mask`
    /// (PNG/TIFF/JPEG, 8- or 16-bit, colour as Rec. 709 luminance, alpha
    /// ignored): confidence takes the value in [0, 1], object is
    /// `value >= 0.5`. An image of another size is an error naming the file
    /// and both sizes; any error leaves the masks unchanged. A load that
    /// changes something is one undo step; returns whether it did.
    pub fn load_png(&mut self, layer: Layer, path: &Path) -> Result<bool, MaskError> {
        let values = read_sized_mask(path, self.size())?;
        self.end_stroke();
        let rect = whole(&values);
        let change = match layer {
            Layer::Confidence => region_edit(&mut self.confidence, rect, |c, r, _| {
                *values.at(c, r) as f32
            })
            .map(Change::Confidence),
            Layer::Object => region_edit(&mut self.object, rect, |c, r, _| *values.at(c, r) >= 0.5)
                .map(Change::Object),
        };
        Ok(self.record(change))
    }

    /// Writes both layers (confidence as 16-bit grey for near-exact restore,
    /// object as 8-bit) and `autosave.json` (image path, size, Unix time)
    /// into `dir`, creating it; each file is written to a temporary file in
    /// `dir` and renamed, so a crash never leaves a half-written file.
    pub fn autosave(&self, dir: &Path, image_path: &Path) -> Result<(), MaskError> {
        let create_error = |cause| IoError::CreateDir {
            path: dir.to_path_buf(),
            cause,
        };
        fs::create_dir_all(dir).map_err(create_error)?;
        let confidence = self.confidence.map(|&v| f64::from(v));
        write_atomic(&dir.join(AUTOSAVE_CONFIDENCE), |p| {
            io::write_png16(p, &confidence)
        })?;
        write_atomic(&dir.join(AUTOSAVE_OBJECT), |p| {
            io::write_mask_png(p, &self.object)
        })?;
        let ((width, height), now) = (self.size(), SystemTime::now());
        let info = AutosaveInfo {
            format: AUTOSAVE_FORMAT,
            image: image_path.display().to_string(),
            width,
            height,
            saved_unix_s: now.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs()),
        };
        write_atomic(&dir.join(AUTOSAVE_JSON), |p| io::write_json(p, &info))
    }

    /// Restores masks autosaved in `dir` for an image of `expected_size`,
    /// with an empty history. `Ok(None)` when `dir` holds no autosave; an
    /// error when its files are corrupt, missing or of another size.
    pub fn restore(dir: &Path, expected_size: (usize, usize)) -> Result<Option<Self>, MaskError> {
        let json = dir.join(AUTOSAVE_JSON);
        let text = match fs::read_to_string(&json) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(cause) => return Err(IoError::Read { path: json, cause }.into()),
        };
        let corrupt = |reason: String| MaskError::Autosave {
            path: json.clone(),
            reason,
        };
        let info: AutosaveInfo = serde_json::from_str(&text).map_err(|e| corrupt(e.to_string()))?;
        if info.format != AUTOSAVE_FORMAT {
            return Err(corrupt(format!("unknown format {}", info.format)));
        }
        let ((w, h), saved) = (expected_size, (info.width, info.height));
        if saved != expected_size {
            let reason = format!(
                "saved for a {}x{} image but the image is {w}x{h}",
                saved.0, saved.1
            );
            return Err(corrupt(reason));
        }
        let confidence = read_sized_mask(&dir.join(AUTOSAVE_CONFIDENCE), expected_size)?;
        let object = read_sized_mask(&dir.join(AUTOSAVE_OBJECT), expected_size)?;
        Self::from_layers(confidence.map(|&v| v as f32), object.map(|&v| v >= 0.5)).map(Some)
    }

    /// The overlay texture: row-major RGBA8, 4 bytes per pixel, NOT
    /// premultiplied (egui's `ColorImage::from_rgba_unmultiplied`).
    /// Untrusted pixels get `confidence_rgb` with alpha `opacity (1 - c)`,
    /// composited over the (hatched) `background_rgb` of background pixels;
    /// trusted object pixels are transparent.
    pub fn overlay_rgba(&self, style: &OverlayStyle) -> Vec<u8> {
        let opacity = if style.opacity.is_nan() {
            0.0
        } else {
            style.opacity.clamp(0.0, 1.0)
        };
        let (w, period) = (self.confidence.width().max(1), style.hatch_period_px);
        let cells = self
            .confidence
            .as_slice()
            .iter()
            .zip(self.object.as_slice());
        let mut out = Vec::with_capacity(4 * self.confidence.len());
        for (k, (&c, &object)) in cells.enumerate() {
            let a1 = opacity * (1.0 - c.clamp(0.0, 1.0));
            let a2 = match (object, period) {
                (true, _) => 0.0,
                (false, 0) => opacity,
                (false, p) if ((k % w) + (k / w)) % p < p.div_ceil(2) => opacity,
                (false, _) => opacity / 3.0,
            };
            let alpha = a1 + a2 * (1.0 - a1);
            if alpha <= 0.0 {
                out.extend_from_slice(&[0; 4]);
                continue;
            }
            for (fg, bg) in style.confidence_rgb.iter().zip(&style.background_rgb) {
                let v = (f32::from(*fg) * a1 + f32::from(*bg) * a2 * (1.0 - a1)) / alpha;
                out.push(v.round().clamp(0.0, 255.0) as u8);
            }
            out.push((alpha * 255.0).round() as u8);
        }
        out
    }
}

/// Reads a mask image and checks its size.
fn read_sized_mask(path: &Path, expected: (usize, usize)) -> Result<Grid<f64>, MaskError> {
    let values = io::read_mask(path)?;
    let (found, path) = (values.size(), path.to_path_buf());
    if found != expected {
        return Err(IoError::SizeMismatch {
            path,
            found,
            expected,
        }
        .into());
    }
    Ok(values)
}

/// [`io::write_atomic`], its failure as a mask error.
fn write_atomic(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), IoError>,
) -> Result<(), MaskError> {
    Ok(io::write_atomic(path, write)?)
}

/// 64-bit FNV-1a: a fixed hash, stable across Rust versions and platforms.
fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        hash ^= u64::from(b);
        hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
    }
    hash
}

/// The autosave folder of `image_path`:
/// `DATA_DIR/autosave/STEM-HASH`, where HASH is the 64-bit FNV-1a (hex) of
/// the image's canonical absolute path (its absolute path when it cannot be
/// canonicalised, e.g. because it no longer exists) and STEM the file stem
/// reduced to at most 32 ASCII letters, digits, `-` and `_` (`image` if
/// none is left). Remove the folder to discard an autosave.
pub fn autosave_dir(image_path: &Path, data_dir: &Path) -> PathBuf {
    let absolute = fs::canonicalize(image_path)
        .or_else(|_| std::path::absolute(image_path))
        .unwrap_or_else(|_| image_path.to_path_buf());
    let hash = fnv1a64(absolute.as_os_str().as_encoded_bytes());
    let stem = absolute.file_stem().unwrap_or_default().to_string_lossy();
    let allowed = |c: &char| c.is_ascii_alphanumeric() || *c == '-' || *c == '_';
    let mut stem: String = stem.chars().filter(allowed).take(32).collect();
    if stem.is_empty() {
        stem = "image".into();
    }
    data_dir
        .join("autosave")
        .join(format!("{stem}-{hash:016x}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use tempfile::tempdir;

    fn brush(radius_px: f32, hardness: f32, mode: Mode) -> Brush {
        Brush {
            radius_px,
            hardness,
            mode,
        }
    }

    /// Paints one stroke through `points` and ends it.
    fn stroke(m: &mut Masks, layer: Layer, b: Brush, points: &[ImagePoint]) {
        m.begin_stroke(layer, b, points[0]).unwrap();
        for p in points.windows(2) {
            assert!(m.stroke_segment(p[0], p[1]));
        }
        m.end_stroke();
    }

    fn state(m: &Masks) -> (Grid<f32>, Grid<bool>) {
        (m.confidence().clone(), m.object().clone())
    }

    /// Whether pixel `(c, r)` of `layer` is fully excluded.
    fn excluded(m: &Masks, layer: Layer, c: usize, r: usize) -> bool {
        match layer {
            Layer::Confidence => *m.confidence().at(c, r) == 0.0,
            Layer::Object => !*m.object().at(c, r),
        }
    }

    /// Distance from the centre of pixel `(c, r)` to the polyline `points`.
    fn distance(c: usize, r: usize, points: &[ImagePoint]) -> f32 {
        let p = [c as f32 + 0.5, r as f32 + 0.5];
        let segments = points
            .windows(2)
            .map(|s| distance_to_segment(p, s[0], s[1]));
        segments.fold(distance_to_segment(p, points[0], points[0]), f32::min)
    }

    #[test]
    fn brush_edges_gaps_and_erase() {
        let mut m = Masks::new(40, 40);
        stroke(
            &mut m,
            Layer::Confidence,
            brush(5.0, 1.0, Mode::Paint),
            &[[20.0, 20.0]],
        );
        let soft = brush(8.0, 0.25, Mode::Paint);
        let mut s = Masks::new(40, 40);
        stroke(&mut s, Layer::Confidence, soft, &[[20.0, 20.0]]);
        stroke(&mut s, Layer::Object, soft, &[[20.0, 20.0]]);
        let mut ramp = 0;
        for (r, c) in (0..40).flat_map(|r| (0..40).map(move |c| (r, c))) {
            let d = distance(c, r, &[[20.0, 20.0]]);
            assert_eq!(*m.confidence().at(c, r), if d <= 5.0 { 0.0 } else { 1.0 });
            let v = *s.confidence().at(c, r);
            assert_eq!(v, 1.0 - soft.coverage(d));
            assert!(
                (v == 0.0) == (d <= 2.0) && (v == 1.0) == (d >= 8.0),
                "{d} {v}"
            );
            ramp += usize::from(v > 0.0 && v < 1.0);
            assert_eq!(*s.object().at(c, r), soft.coverage(d) < 0.5, "({c}, {r})");
        }
        assert!(ramp > 100, "{ramp}");
        // Erasing with a larger hard brush restores both layers exactly.
        let erase = brush(8.5, 1.0, Mode::Erase);
        stroke(&mut s, Layer::Confidence, erase, &[[20.0, 20.0]]);
        stroke(&mut s, Layer::Object, erase, &[[20.0, 20.0]]);
        assert_eq!(state(&s), state(&Masks::new(40, 40)));

        // Two far-apart points in one segment: every pixel near it, no gaps.
        let mut m = Masks::new(100, 60);
        let points = [[2.0, 3.0], [97.0, 55.0], [3.0, 57.0]];
        stroke(
            &mut m,
            Layer::Confidence,
            brush(1.0, 1.0, Mode::Paint),
            &points,
        );
        for (r, c) in (0..60).flat_map(|r| (0..100).map(move |c| (r, c))) {
            assert_eq!(
                excluded(&m, Layer::Confidence, c, r),
                distance(c, r, &points) <= 1.0
            );
        }
        for c in 2..97 {
            assert!(
                (0..60).any(|r| excluded(&m, Layer::Confidence, c, r)),
                "gap at {c}"
            );
        }
    }

    #[test]
    fn strokes_are_order_independent_and_do_not_compound() {
        let soft = brush(6.0, 0.2, Mode::Paint);
        let points = [[10.0, 10.0], [20.0, 14.0], [13.0, 22.0], [11.0, 11.0]];
        let (mut forward, mut backward) = (Masks::new(32, 32), Masks::new(32, 32));
        stroke(&mut forward, Layer::Confidence, soft, &points);
        let reversed: Vec<_> = points.iter().rev().copied().collect();
        stroke(&mut backward, Layer::Confidence, soft, &reversed);
        assert_eq!(forward.confidence(), backward.confidence());

        let (mut once, mut many) = (Masks::new(32, 32), Masks::new(32, 32));
        stroke(&mut once, Layer::Confidence, soft, &[[16.0, 16.0]]);
        stroke(&mut many, Layer::Confidence, soft, &[[16.0, 16.0]; 5]);
        assert_eq!(once.confidence(), many.confidence());
        // A second stroke does combine with the first (min rule).
        stroke(&mut many, Layer::Confidence, soft, &[[17.0, 16.0]]);
        let pairs = many
            .confidence()
            .as_slice()
            .iter()
            .zip(once.confidence().as_slice());
        assert!(pairs.clone().all(|(a, b)| a <= b) && pairs.clone().any(|(a, b)| a < b));
    }

    #[test]
    fn invalid_brush_and_cancelled_stroke() {
        let mut m = Masks::new(8, 8);
        let e = m.begin_stroke(Layer::Confidence, brush(0.2, 1.0, Mode::Paint), [1.0, 1.0]);
        assert!(e.unwrap_err().to_string().contains("radius_px"));
        let e = m.begin_stroke(Layer::Object, brush(2.0, f32::NAN, Mode::Paint), [1.0, 1.0]);
        assert!(e.unwrap_err().to_string().contains("hardness"));
        assert!(!m.is_stroking() && !m.stroke_segment([1.0, 1.0], [2.0, 2.0]));
        m.begin_stroke(Layer::Object, brush(2.0, 1.0, Mode::Paint), [4.0, 4.0])
            .unwrap();
        assert!(excluded(&m, Layer::Object, 4, 4));
        assert!(!m.stroke_segment([f32::NAN, 1.0], [2.0, 2.0]));
        assert!(m.cancel_stroke());
        assert_eq!(state(&m), state(&Masks::new(8, 8)));
        assert!(!m.can_undo());
    }

    #[test]
    fn shapes_on_each_layer() {
        for layer in [Layer::Confidence, Layer::Object] {
            let mut m = Masks::new(12, 12);
            assert!(m.fill_rect(layer, Mode::Paint, [5.9, 6.4], [2.2, 3.0]));
            for (r, c) in (0..12).flat_map(|r| (0..12).map(move |c| (r, c))) {
                let inside = (2..=5).contains(&c) && (3..=5).contains(&r);
                assert_eq!(excluded(&m, layer, c, r), inside);
            }
            assert!(m.fill_rect(layer, Mode::Erase, [0.0, 0.0], [12.0, 12.0]));
            assert!(!m.fill_rect(layer, Mode::Erase, [0.0, 0.0], [12.0, 12.0]));
            assert!(!m.fill_rect(layer, Mode::Paint, [20.0, 0.0], [30.0, 12.0]));

            let triangle = [[0.0, 0.0], [10.2, 0.0], [0.0, 10.2]];
            assert!(m.fill_lasso(layer, Mode::Paint, &triangle));
            for (r, c) in (0..12).flat_map(|r| (0..12).map(move |c| (r, c))) {
                assert_eq!(excluded(&m, layer, c, r), c + r <= 9, "({c}, {r})");
            }
            assert!(m.fill_lasso(layer, Mode::Erase, &triangle));
            assert_eq!(state(&m), state(&Masks::new(12, 12)));
            assert!(!m.fill_lasso(layer, Mode::Paint, &triangle[..2]));
        }
    }

    /// Dark background 0.05, a bright textured square at columns and rows
    /// 5..15 and a detached bright square at columns 20..24, rows 2..6.
    fn scene() -> Grid<f64> {
        Grid::from_fn(30, 20, |c, r| {
            let big = (5..15).contains(&c) && (5..15).contains(&r);
            let small = (20..24).contains(&c) && (2..6).contains(&r);
            if big || small {
                0.7 + 0.01 * ((c + r) % 3) as f64
            } else {
                0.05
            }
        })
    }

    #[test]
    fn flood_fill_stops_at_image_edges() {
        let image = scene();
        for layer in [Layer::Confidence, Layer::Object] {
            let mut m = Masks::new(30, 20);
            assert!(
                m.flood_fill(layer, Mode::Paint, &image, [7.3, 9.9], 0.05)
                    .unwrap()
            );
            for (r, c) in (0..20).flat_map(|r| (0..30).map(move |c| (r, c))) {
                let big = (5..15).contains(&c) && (5..15).contains(&r);
                assert_eq!(excluded(&m, layer, c, r), big, "({c}, {r})");
            }
            assert!(
                !m.flood_fill(layer, Mode::Paint, &image, [-1.0, 3.0], 0.05)
                    .unwrap()
            );
            assert!(
                !m.flood_fill(layer, Mode::Paint, &image, [30.0, 3.0], 0.05)
                    .unwrap()
            );
        }
        let mut m = Masks::new(30, 20);
        assert!(
            m.flood_fill(Layer::Object, Mode::Paint, &image, [0.5, 0.5], 0.0)
                .unwrap()
        );
        assert_eq!(
            m.object().as_slice().iter().filter(|&&o| !o).count(),
            600 - 100 - 16
        );
        let small = Grid::filled(3, 3, 0.0);
        let e = m.flood_fill(Layer::Object, Mode::Paint, &small, [0.0, 0.0], 0.1);
        assert!(e.unwrap_err().to_string().contains("3x3"));
        let e = m.flood_fill(Layer::Object, Mode::Paint, &image, [0.0, 0.0], -1.0);
        assert!(e.unwrap_err().to_string().contains("tolerance"));
    }

    #[test]
    fn threshold_clear_and_invert() {
        let image = scene();
        let mut m = Masks::new(30, 20);
        assert!(m.threshold(&image, 0.1).unwrap());
        assert_eq!(*m.object(), image.map(|&v| v > 0.1));
        assert_eq!(m.object_for_solver().as_ref(), Some(m.object()));
        assert!(
            m.threshold(&image, f64::NAN)
                .unwrap_err()
                .to_string()
                .contains("threshold")
        );
        assert!(m.invert(Layer::Object));
        assert_eq!(*m.object(), image.map(|&v| v <= 0.1));
        m.fill_rect(Layer::Confidence, Mode::Paint, [0.0, 0.0], [3.0, 3.0]);
        assert!(m.invert(Layer::Confidence));
        assert_eq!(
            m.confidence()
                .as_slice()
                .iter()
                .filter(|&&v| v == 1.0)
                .count(),
            9
        );
        assert!(m.clear(Layer::Confidence) && m.clear(Layer::Object) && !m.clear(Layer::Object));
        assert_eq!(state(&m), state(&Masks::new(30, 20)));
        assert!(m.confidence_for_solver().is_none() && m.object_for_solver().is_none());
    }

    #[test]
    fn undo_and_redo_every_kind_of_edit() {
        let dir = tempdir().unwrap();
        let png = dir.path().join("loaded.png");
        io::write_png8(&png, &Grid::from_fn(30, 20, |c, _| c as f64 / 29.0)).unwrap();
        let (image, soft, hard) = (
            scene(),
            brush(4.0, 0.3, Mode::Paint),
            brush(3.0, 1.0, Mode::Paint),
        );
        let (c, o) = (Layer::Confidence, Layer::Object);
        type Edit<'a> = Box<dyn Fn(&mut Masks) -> bool + 'a>;
        let edits: Vec<Edit> = vec![
            Box::new(|m| {
                stroke(m, c, soft, &[[3.0, 3.0], [25.0, 12.0]]);
                true
            }),
            Box::new(|m| {
                stroke(m, o, hard, &[[20.0, 3.0], [6.0, 15.0]]);
                true
            }),
            Box::new(|m| m.fill_rect(c, Mode::Erase, [4.0, 4.0], [9.0, 7.0])),
            Box::new(|m| m.fill_lasso(o, Mode::Erase, &[[0.0, 0.0], [30.0, 0.0], [0.0, 20.0]])),
            Box::new(|m| {
                m.flood_fill(c, Mode::Paint, &image, [8.0, 8.0], 0.1)
                    .unwrap()
            }),
            Box::new(|m| m.invert(c)),
            Box::new(|m| m.threshold(&image, 0.1).unwrap()),
            Box::new(|m| m.clear(o)),
            Box::new(|m| m.load_png(c, &png).unwrap()),
        ];
        let mut m = Masks::new(30, 20);
        let mut states = vec![state(&m)];
        for edit in &edits {
            assert!(edit(&mut m));
            assert_ne!(state(&m), *states.last().unwrap());
            states.push(state(&m));
        }
        for expected in states.iter().rev().skip(1) {
            let before = m.revision();
            assert!(m.undo());
            assert_ne!(m.revision(), before);
            assert_eq!(state(&m), *expected);
        }
        assert!(!m.undo() && m.can_redo());
        for expected in &states[1..] {
            assert!(m.redo());
            assert_eq!(state(&m), *expected);
        }
        assert!(!m.redo());
        // A new edit clears the redo stack.
        assert!(m.undo() && m.undo() && m.can_redo());
        assert!(m.fill_rect(o, Mode::Erase, [0.0, 0.0], [2.0, 2.0]));
        assert!(!m.can_redo() && !m.redo());
        assert!(m.undo());
        assert_eq!(state(&m), states[states.len() - 3]);
        // Undo in the middle of a stroke undoes that stroke.
        m.begin_stroke(c, hard, [1.0, 1.0]).unwrap();
        assert!(m.can_undo() && m.undo());
        assert_eq!(state(&m), states[states.len() - 3]);
    }

    #[test]
    fn history_is_bounded() {
        let mut m = Masks::new(64, 8);
        let square = |m: &mut Masks, k: usize| {
            let x = 4.0 * k as f32;
            assert!(m.fill_rect(Layer::Confidence, Mode::Paint, [x, 0.0], [x + 4.0, 4.0]));
            state(m)
        };
        square(&mut m, 0);
        let step = m.history_bytes();
        assert!((2 * 16 * 4..2 * 16 * 4 + 200).contains(&step), "{step}");
        m.set_history_limit_bytes(3 * step);
        let states: Vec<_> = (1..10).map(|k| square(&mut m, k)).collect();
        assert_eq!(m.history_bytes(), 3 * step);
        assert!(m.undo() && m.undo() && m.undo() && !m.undo());
        assert_eq!(state(&m), states[5]);
        // The newest step is kept even when alone it exceeds the limit.
        m.set_history_limit_bytes(1);
        assert_eq!(m.history_bytes(), 0);
        assert!(m.clear(Layer::Confidence) && m.history_bytes() > 1);
        assert!(m.undo() && !m.undo());
        assert_eq!(state(&m), states[5]);
    }

    #[test]
    fn png_round_trip_and_wrong_size_load() {
        let dir = tempdir().unwrap();
        let (cp, op) = (dir.path().join("conf.png"), dir.path().join("obj.png"));
        let mut m = Masks::new(20, 12);
        stroke(
            &mut m,
            Layer::Confidence,
            brush(5.0, 0.3, Mode::Paint),
            &[[4.0, 4.0], [15.0, 8.0]],
        );
        stroke(
            &mut m,
            Layer::Object,
            brush(3.0, 1.0, Mode::Paint),
            &[[10.0, 2.0], [10.0, 10.0]],
        );
        m.save_png(Layer::Confidence, &cp).unwrap();
        m.save_png(Layer::Object, &op).unwrap();
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2);

        let mut n = Masks::new(20, 12);
        assert!(n.load_png(Layer::Confidence, &cp).unwrap());
        assert!(n.load_png(Layer::Object, &op).unwrap());
        assert_eq!(n.object(), m.object());
        for (a, b) in n
            .confidence()
            .as_slice()
            .iter()
            .zip(m.confidence().as_slice())
        {
            assert!((a - b).abs() <= 0.5 / 255.0 + 1e-6, "{a} {b}");
        }
        assert!(n.undo() && n.undo());
        assert_eq!(state(&n), state(&Masks::new(20, 12)));

        let mut wrong = Masks::new(21, 12);
        wrong.fill_rect(Layer::Object, Mode::Paint, [0.0, 0.0], [3.0, 3.0]);
        let (before, revision) = (state(&wrong), wrong.revision());
        let e = wrong.load_png(Layer::Object, &op).unwrap_err().to_string();
        let op_name = op.display().to_string();
        assert!(
            e.contains(&op_name) && e.contains("20x12") && e.contains("21x12"),
            "{e}"
        );
        assert_eq!((state(&wrong), wrong.revision()), (before, revision));
        assert!(wrong.undo() && !wrong.undo());
        let e = n
            .load_png(Layer::Object, &dir.path().join("missing.png"))
            .unwrap_err();
        assert!(e.to_string().contains("missing.png"), "{e}");
    }

    #[test]
    fn autosave_round_trip_missing_and_corrupt() {
        let data = tempdir().unwrap();
        let image = data.path().join("vase.png");
        fs::write(&image, "x").unwrap();
        let dir = autosave_dir(&image, data.path());
        assert!(Masks::restore(&dir, (20, 12)).unwrap().is_none());

        let mut m = Masks::new(20, 12);
        stroke(
            &mut m,
            Layer::Confidence,
            brush(5.0, 0.3, Mode::Paint),
            &[[4.0, 4.0], [15.0, 8.0]],
        );
        m.fill_rect(Layer::Object, Mode::Paint, [0.0, 0.0], [6.0, 12.0]);
        m.autosave(&dir, &image).unwrap();
        m.autosave(&dir, &image).unwrap();
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 3);
        let json = fs::read_to_string(dir.join(AUTOSAVE_JSON)).unwrap();
        assert!(
            json.contains("vase.png") && json.contains("\"width\": 20"),
            "{json}"
        );

        let r = Masks::restore(&dir, (20, 12)).unwrap().unwrap();
        assert_eq!(r.object(), m.object());
        for (a, b) in r
            .confidence()
            .as_slice()
            .iter()
            .zip(m.confidence().as_slice())
        {
            assert!((a - b).abs() <= 1.0 / 65535.0, "{a} {b}");
        }
        assert!(!r.can_undo());

        let e = Masks::restore(&dir, (21, 12)).unwrap_err().to_string();
        assert!(e.contains("20x12") && e.contains("21x12"), "{e}");
        fs::write(dir.join(AUTOSAVE_OBJECT), "garbage").unwrap();
        let e = Masks::restore(&dir, (20, 12)).unwrap_err().to_string();
        assert!(e.contains(AUTOSAVE_OBJECT), "{e}");
        fs::write(dir.join(AUTOSAVE_JSON), "{\"format\": 1").unwrap();
        let e = Masks::restore(&dir, (20, 12)).unwrap_err().to_string();
        assert!(e.contains(AUTOSAVE_JSON), "{e}");
    }

    #[test]
    fn autosave_dir_is_stable_and_distinct() {
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
        let data = tempdir().unwrap();
        let (a, b) = (data.path().join("a b.png"), data.path().join("b.png"));
        fs::write(&a, "x").unwrap();
        fs::write(&b, "x").unwrap();
        let dir = autosave_dir(&a, data.path());
        assert_eq!(
            dir,
            autosave_dir(&data.path().join(".").join("a b.png"), data.path())
        );
        assert_ne!(dir, autosave_dir(&b, data.path()));
        assert!(dir.starts_with(data.path().join("autosave")));
        let name = dir.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with("ab-") && name.len() == 3 + 16, "{name}");
    }

    #[test]
    fn revision_changes_with_every_change_only() {
        let mut m = Masks::new(10, 10);
        let r0 = m.revision();
        assert!(!m.fill_rect(Layer::Confidence, Mode::Erase, [0.0, 0.0], [10.0, 10.0]));
        assert_eq!(m.revision(), r0);
        m.begin_stroke(Layer::Confidence, brush(1.0, 1.0, Mode::Paint), [2.0, 2.0])
            .unwrap();
        let r1 = m.revision();
        assert_ne!(r1, r0);
        m.stroke_segment([2.0, 2.0], [8.0, 2.0]);
        let r2 = m.revision();
        assert_ne!(r2, r1);
        m.stroke_segment([8.0, 2.0], [2.0, 2.0]);
        assert!(m.end_stroke());
        assert_eq!(m.revision(), r2);
        assert!(m.undo());
        assert_ne!(m.revision(), r2);
    }

    #[test]
    fn overlay_colours_untrusted_and_background() {
        let mut m = Masks::new(3, 1);
        m.fill_rect(Layer::Confidence, Mode::Paint, [0.0, 0.0], [1.0, 1.0]);
        m.fill_rect(Layer::Object, Mode::Paint, [1.0, 0.0], [2.0, 1.0]);
        let style = OverlayStyle {
            hatch_period_px: 0,
            ..OverlayStyle::default()
        };
        let rgba = m.overlay_rgba(&style);
        assert_eq!(rgba, [230, 40, 40, 128, 40, 90, 230, 128, 0, 0, 0, 0]);
        let hatched = m.overlay_rgba(&OverlayStyle {
            hatch_period_px: 2,
            ..style
        });
        assert_eq!(hatched[4..8], [40, 90, 230, 43]);
    }
}
