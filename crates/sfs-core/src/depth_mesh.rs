//! The one triangulation of a depth map, shared by the 3-D view and the mesh
//! exporters (PLY, OBJ): which pixels become vertices, which grid cells
//! become triangles, and where the surface is cut. Pure functions over
//! [`Grid`] and [`LevelGeometry`]; no GPU, no files.
//!
//! # The rule
//!
//! - A pixel (sampled every `stride` pixels) with finite depth `z > 0` is a
//!   vertex, back-projected through the level's camera
//!   ([`LevelGeometry::back_project`], camera space: x right, y down, z
//!   forward). Every other pixel is "no surface": off the object (the solver
//!   writes NaN there), a hole, or a NaN region.
//! - A triangle joins three vertices of one 2x2 cell `a b / c d` only when
//!   its depths are *connected*: `max z - min z <= max_step_footprints *
//!   footprint(min z)`, the footprint being the size of one sampling step at
//!   that depth (`z * stride * spacing / f`). So no triangle crosses the
//!   silhouette, a hole or a depth jump.
//! - Each cell gives the two triangles `a c b` and `b c d` (diagonal b-c) when
//!   both are connected; else `a c d` and `a d b` (diagonal a-d) when both
//!   are; else the first connected one of those four (a cell at the
//!   silhouette or at a jump with three corners on one side), or nothing.
//!   Triangles never overlap.
//! - Triangles wind counter-clockwise as seen from the camera: their normal
//!   `(v1 - v0) x (v2 - v0)` points towards it (negative z in camera space
//!   for a plane facing the camera).

use glam::DVec3;

use crate::grid::Grid;
use crate::model::LevelGeometry;

/// Default of [`MeshOptions::max_step_footprints`]: a cell is cut when its
/// depths differ by more than ten pixel footprints (a slope of about 84
/// degrees to the image plane).
pub const DEFAULT_MAX_STEP_FOOTPRINTS: f64 = 10.0;

/// Most vertices a mesh may have: its indices must fit a PLY `int`.
pub const MAX_VERTICES: usize = i32::MAX as usize;

/// Marks a sample without a vertex.
const NO_VERTEX: u32 = u32::MAX;

/// How a depth map is sampled and cut.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshOptions {
    /// Use every `stride`-th pixel along rows and columns (1: every pixel;
    /// larger strides keep a display mesh small).
    pub stride: usize,
    /// The depth-jump rule (see the module docs), in pixel footprints (>= 0;
    /// infinity never cuts).
    pub max_step_footprints: f64,
}

impl Default for MeshOptions {
    /// Every pixel, [`DEFAULT_MAX_STEP_FOOTPRINTS`].
    fn default() -> Self {
        Self {
            stride: 1,
            max_step_footprints: DEFAULT_MAX_STEP_FOOTPRINTS,
        }
    }
}

/// Why a depth map cannot be triangulated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// The depth map and the geometry disagree on the size.
    #[error(
        "the depth map is {}x{} but its level geometry is {}x{}",
        depth.0, depth.1, geometry.0, geometry.1
    )]
    SizeMismatch {
        /// Depth map `(width, height)`.
        depth: (usize, usize),
        /// Geometry `(width, height)`.
        geometry: (usize, usize),
    },
    /// The camera's focal length is not finite and positive.
    #[error("the focal length {0} px is not finite and positive")]
    InvalidFocal(f64),
    /// A stride of 0 or a negative or NaN step rule.
    #[error("invalid mesh options: {0}")]
    InvalidOptions(String),
    /// More vertices than [`MAX_VERTICES`].
    #[error("{0} vertices are more than a mesh may have ({MAX_VERTICES})")]
    TooManyVertices(usize),
}

/// Edges of a cell used by its triangles (bit flags).
const TOP: u8 = 1;
const LEFT: u8 = 2;
const BOTTOM: u8 = 4;
const RIGHT: u8 = 8;

/// A depth map's vertices, triangles and grid edges.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DepthMesh {
    grid_size: (usize, usize),
    vertex_pixels: Vec<(usize, usize)>,
    positions_camera: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    edges: Vec<[u32; 2]>,
}

impl DepthMesh {
    /// Every pixel of `depth` with [`MeshOptions::default`].
    pub fn new(depth: &Grid<f64>, geometry: &LevelGeometry) -> Result<Self, MeshError> {
        Self::with_options(depth, geometry, MeshOptions::default())
    }

    /// Triangulates `depth` (at the size of `geometry`) by the rule of the
    /// module docs.
    pub fn with_options(
        depth: &Grid<f64>,
        geometry: &LevelGeometry,
        options: MeshOptions,
    ) -> Result<Self, MeshError> {
        Self::build(depth, geometry, options, true)
    }

    /// [`Self::new`]'s vertices and triangles without the outline
    /// ([`Self::edges`] empty): what the exporters write, without the
    /// edges' memory (about 17 bytes per pixel of a full-resolution mesh,
    /// the largest part of writing a solve's files).
    pub fn surface(depth: &Grid<f64>, geometry: &LevelGeometry) -> Result<Self, MeshError> {
        Self::build(depth, geometry, MeshOptions::default(), false)
    }

    /// The triangulation, with the outline's edges where `outline`.
    fn build(
        depth: &Grid<f64>,
        geometry: &LevelGeometry,
        options: MeshOptions,
        outline: bool,
    ) -> Result<Self, MeshError> {
        let (width, height) = depth.size();
        if (width, height) != (geometry.width, geometry.height) {
            return Err(MeshError::SizeMismatch {
                depth: (width, height),
                geometry: (geometry.width, geometry.height),
            });
        }
        let focal_px = geometry.camera.focal_px;
        if !(focal_px.is_finite() && focal_px > 0.0) {
            return Err(MeshError::InvalidFocal(focal_px));
        }
        let MeshOptions {
            stride,
            max_step_footprints,
        } = options;
        let step_is_valid = max_step_footprints >= 0.0; // false for NaN
        if stride == 0 || !step_is_valid {
            return Err(MeshError::InvalidOptions(format!(
                "stride {stride}, max step {max_step_footprints} footprints"
            )));
        }
        let (samples_x, samples_y) = (width.div_ceil(stride), height.div_ceil(stride));
        let spacing_px = geometry.spacing.x.max(geometry.spacing.y);
        let step_per_depth = max_step_footprints * stride as f64 * spacing_px / focal_px;

        // Vertices, row-major over the samples.
        let mut mesh = Self {
            grid_size: (width, height),
            ..Self::default()
        };
        let mut vertex_of_sample = vec![NO_VERTEX; samples_x * samples_y];
        for sample_row in 0..samples_y {
            for sample_column in 0..samples_x {
                let (column, row) = (sample_column * stride, sample_row * stride);
                let z = *depth.at(column, row);
                if !(z.is_finite() && z > 0.0) {
                    continue;
                }
                let index = mesh.vertex_pixels.len();
                if index >= MAX_VERTICES {
                    return Err(MeshError::TooManyVertices(index + 1));
                }
                vertex_of_sample[sample_row * samples_x + sample_column] = index as u32;
                mesh.vertex_pixels.push((column, row));
                mesh.positions_camera
                    .push(geometry.back_project(column, row, z));
            }
        }

        // Triangles per cell, and the grid edges each cell uses.
        let cells_x = samples_x.saturating_sub(1);
        let cells_y = samples_y.saturating_sub(1);
        let mut cell_edges = vec![0u8; if outline { cells_x * cells_y } else { 0 }];
        let mut no_edges = 0u8;
        let depth_of = |v: u32| mesh.positions_camera[v as usize][2];
        let connected = |corners: [u32; 3]| {
            let z = corners.map(depth_of);
            let lo = z[0].min(z[1]).min(z[2]);
            let hi = z[0].max(z[1]).max(z[2]);
            hi - lo <= step_per_depth * lo
        };
        let mut triangles = Vec::new();
        let mut diagonals = Vec::new();
        for cell_row in 0..cells_y {
            for cell_column in 0..cells_x {
                let sample = |dc: usize, dr: usize| {
                    let v = vertex_of_sample[(cell_row + dr) * samples_x + cell_column + dc];
                    (v != NO_VERTEX).then_some(v)
                };
                let (a, b, c, d) = (sample(0, 0), sample(1, 0), sample(0, 1), sample(1, 1));
                let triangle = |corners: [Option<u32>; 3]| {
                    let corners = [corners[0]?, corners[1]?, corners[2]?];
                    connected(corners).then_some(corners)
                };
                let acb = triangle([a, c, b]);
                let bcd = triangle([b, c, d]);
                let acd = triangle([a, c, d]);
                let adb = triangle([a, d, b]);
                let edges = match outline {
                    true => &mut cell_edges[cell_row * cells_x + cell_column],
                    false => &mut no_edges,
                };
                match (acb, bcd, acd, adb) {
                    (Some(t), Some(u), _, _) | (_, _, Some(t), Some(u)) => {
                        triangles.extend([t, u]);
                        *edges = TOP | LEFT | BOTTOM | RIGHT;
                    }
                    (Some(t), ..) => {
                        triangles.push(t);
                        *edges = TOP | LEFT;
                        diagonals.push([t[2], t[1]]);
                    }
                    (None, Some(t), ..) => {
                        triangles.push(t);
                        *edges = BOTTOM | RIGHT;
                        diagonals.push([t[0], t[1]]);
                    }
                    (None, None, Some(t), None) => {
                        triangles.push(t);
                        *edges = LEFT | BOTTOM;
                        diagonals.push([t[0], t[2]]);
                    }
                    (None, None, None, Some(t)) => {
                        triangles.push(t);
                        *edges = TOP | RIGHT;
                        diagonals.push([t[0], t[1]]);
                    }
                    (None, None, None, None) => {}
                }
            }
        }
        mesh.triangles = triangles;
        if !outline {
            return Ok(mesh);
        }

        // Grid edges, each once: a row edge is the bottom of the cell above
        // or the top of the cell below, a column edge the right of the cell
        // to its left or the left of the cell to its right.
        let vertex = |column: usize, row: usize| vertex_of_sample[row * samples_x + column];
        let uses = |column: usize, row: usize, edge: u8| {
            column < cells_x && row < cells_y && cell_edges[row * cells_x + column] & edge != 0
        };
        for row in 0..samples_y {
            for column in 0..cells_x {
                if (row > 0 && uses(column, row - 1, BOTTOM)) || uses(column, row, TOP) {
                    mesh.edges
                        .push([vertex(column, row), vertex(column + 1, row)]);
                }
            }
        }
        for row in 0..cells_y {
            for column in 0..samples_x {
                if (column > 0 && uses(column - 1, row, RIGHT)) || uses(column, row, LEFT) {
                    mesh.edges
                        .push([vertex(column, row), vertex(column, row + 1)]);
                }
            }
        }
        // The diagonal of a lone triangle is an outline too.
        mesh.edges.extend(diagonals);
        Ok(mesh)
    }

    /// `(width, height)` of the depth map (the level's grid), whatever the
    /// stride.
    pub fn grid_size(&self) -> (usize, usize) {
        self.grid_size
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions_camera.len()
    }

    /// The level pixel `(column, row)` of each vertex (row-major order).
    pub fn vertex_pixels(&self) -> &[(usize, usize)] {
        &self.vertex_pixels
    }

    /// Each vertex in camera space (x right, y down, z forward; depth units).
    pub fn positions_camera(&self) -> &[[f64; 3]] {
        &self.positions_camera
    }

    /// Triangles as vertex indices, counter-clockwise seen from the camera.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The outline of the surface's grid: the sides of the cells drawn as
    /// triangles, not the diagonal inside a cell of two triangles, each edge
    /// once (for a wireframe).
    pub fn edges(&self) -> &[[u32; 2]] {
        &self.edges
    }

    /// True when there is no triangle.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Unit vertex normals in camera space, facing the camera: the
    /// area-weighted sum of the normals of the vertex's triangles; a vertex
    /// without a triangle faces the camera's centre.
    pub fn normals_camera(&self) -> Vec<[f64; 3]> {
        let mut sums = vec![DVec3::ZERO; self.positions_camera.len()];
        let p = |v: u32| DVec3::from_array(self.positions_camera[v as usize]);
        for &[i, j, k] in &self.triangles {
            let (a, b, c) = (p(i), p(j), p(k));
            let n = (b - a).cross(c - a);
            for v in [i, j, k] {
                sums[v as usize] += n;
            }
        }
        // Divided by the length rather than `try_normalize`'s multiplication
        // by its reciprocal, which rounds differently.
        let unit = |v: DVec3| {
            let length = v.length();
            (length.is_finite() && length > 0.0).then(|| v / length)
        };
        sums.iter()
            .zip(&self.positions_camera)
            .map(|(&sum, &position)| {
                unit(sum)
                    .or_else(|| unit(-DVec3::from_array(position)))
                    .unwrap_or(DVec3::NEG_Z)
                    .to_array()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;

    fn full(width: usize, height: usize, focal_px: f64) -> LevelGeometry {
        LevelGeometry::new(
            width,
            height,
            width,
            height,
            Intrinsics::centred(focal_px, width, height),
        )
    }

    fn mesh(depth: &Grid<f64>, focal_px: f64) -> DepthMesh {
        let (w, h) = depth.size();
        match DepthMesh::new(depth, &full(w, h, focal_px)) {
            Ok(m) => m,
            Err(e) => panic!("{e}"),
        }
    }

    /// Triangles as sorted pixel triples.
    fn pixel_triangles(mesh: &DepthMesh) -> Vec<[(usize, usize); 3]> {
        let mut t: Vec<_> = mesh
            .triangles()
            .iter()
            .map(|t| {
                let mut p = t.map(|v| mesh.vertex_pixels()[v as usize]);
                p.sort_unstable();
                p
            })
            .collect();
        t.sort_unstable();
        t
    }

    #[test]
    fn plane_gives_two_triangles_per_cell_facing_the_camera() {
        let depth = Grid::filled(5, 4, 3.0);
        let m = mesh(&depth, 20.0);
        assert_eq!(m.vertex_count(), 20);
        assert_eq!(m.triangles().len(), 2 * 4 * 3);
        // Outline of a 4x3 grid of cells: 5*3 column edges + 4*4 row edges.
        assert_eq!(m.edges().len(), 5 * 3 + 4 * 4);
        let p = |v: u32| DVec3::from_array(m.positions_camera()[v as usize]);
        for &[a, b, c] in m.triangles() {
            let n = (p(b) - p(a)).cross(p(c) - p(a));
            assert!(n.z < 0.0, "{n:?}");
        }
        for n in m.normals_camera() {
            assert!((n[2] + 1.0).abs() < 1e-12 && n[0].abs() < 1e-12, "{n:?}");
        }
        // Pixel (0, 0) at x = (0 - 2) * 3 / 20.
        assert_eq!(m.positions_camera()[0], [-0.3, -0.225, 3.0]);
    }

    #[test]
    fn silhouette_cells_keep_one_triangle_and_holes_none() {
        // 9x7, a 3x2 hole of zeros, a NaN corner.
        let depth = Grid::from_fn(9, 7, |c, r| {
            if (3..=5).contains(&c) && (2..=3).contains(&r) {
                0.0
            } else if (c, r) == (0, 6) {
                f64::NAN
            } else {
                5.0
            }
        });
        let m = mesh(&depth, 50.0);
        assert_eq!(m.vertex_count(), 63 - 7);
        // 8x6 cells; the 12 touching the hole lose their two triangles, the
        // 4 at its corners keep one; the cell at the NaN corner keeps one.
        assert_eq!(m.triangles().len(), 2 * (48 - 13) + 4 + 1);
        for t in pixel_triangles(&m) {
            for (c, r) in t {
                assert!(*depth.at(c, r) > 0.0);
            }
        }
        // Every edge once, and every triangle side is an edge or an inner
        // diagonal.
        let key = |e: [u32; 2]| (e[0].min(e[1]), e[0].max(e[1]));
        let mut edges: Vec<_> = m.edges().iter().map(|&e| key(e)).collect();
        let count = edges.len();
        edges.sort_unstable();
        edges.dedup();
        assert_eq!(edges.len(), count);
    }

    #[test]
    fn the_surface_is_the_mesh_without_its_outline() {
        let depth = Grid::from_fn(9, 7, |c, r| {
            if (3..=5).contains(&c) && (2..=3).contains(&r) {
                0.0
            } else if c > 6 {
                9.0
            } else {
                5.0 + 0.01 * (c * r) as f64
            }
        });
        let geometry = LevelGeometry::new(9, 7, 9, 7, Intrinsics::centred(50.0, 9, 7));
        let full = DepthMesh::new(&depth, &geometry).expect("a mesh");
        let surface = DepthMesh::surface(&depth, &geometry).expect("a mesh");
        assert!(!full.edges().is_empty());
        assert!(surface.edges().is_empty());
        assert_eq!(surface.vertex_pixels(), full.vertex_pixels());
        assert_eq!(surface.positions_camera(), full.positions_camera());
        assert_eq!(surface.triangles(), full.triangles());
    }

    #[test]
    fn depth_jump_cuts_between_the_two_sides() {
        // Footprint at depth 10 is 10 / 50 = 0.2: a step of 5 is 25 footprints.
        let depth = Grid::from_fn(10, 6, |c, _| if c < 5 { 10.0 } else { 15.0 });
        let (w, h) = depth.size();
        let m = mesh(&depth, 50.0);
        let left = |v: u32| m.vertex_pixels()[v as usize].0 < 5;
        for t in m.triangles() {
            assert!(t.iter().all(|&v| left(v)) || t.iter().all(|&v| !left(v)));
        }
        for e in m.edges() {
            assert_eq!(left(e[0]), left(e[1]));
        }
        assert_eq!(m.triangles().len(), 2 * 8 * 5);
        let options = MeshOptions {
            max_step_footprints: 30.0,
            ..MeshOptions::default()
        };
        let joined = DepthMesh::with_options(&depth, &full(w, h, 50.0), options);
        assert_eq!(joined.map(|m| m.triangles().len()), Ok(2 * 9 * 5));
    }

    #[test]
    fn a_diagonal_step_keeps_the_triangle_on_each_side() {
        // Far corner b alone: a c d stays (diagonal a-d), nothing crosses.
        let Some(depth) = Grid::from_vec(2, 2, vec![1.0, 5.0, 1.0, 1.0]) else {
            panic!("2x2 grid")
        };
        let mesh = mesh(&depth, 10.0);
        assert_eq!(pixel_triangles(&mesh), vec![[(0, 0), (0, 1), (1, 1)]]);
        assert_eq!(mesh.edges().len(), 3);
    }

    #[test]
    fn stride_samples_pixels_and_back_projects_them_exactly() {
        let (w, h) = (41, 23);
        // A level at half size of an 82x46 image: its geometry, not a
        // rebuilt camera, places the vertices.
        let geometry = LevelGeometry::new(w, h, 82, 46, Intrinsics::centred(80.0, 82, 46));
        let depth = Grid::from_fn(w, h, |c, r| 2.0 + (c + r) as f64 * 1e-3);
        let options = MeshOptions {
            stride: 4,
            ..MeshOptions::default()
        };
        let Ok(m) = DepthMesh::with_options(&depth, &geometry, options) else {
            panic!("mesh")
        };
        assert_eq!(m.vertex_count(), 11 * 6);
        assert_eq!(m.triangles().len(), 2 * 10 * 5);
        for (&(c, r), &p) in m.vertex_pixels().iter().zip(m.positions_camera()) {
            assert_eq!((c % 4, r % 4), (0, 0));
            assert_eq!(p, geometry.back_project(c, r, *depth.at(c, r)));
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let depth = Grid::filled(4, 4, 1.0);
        assert!(matches!(
            DepthMesh::new(&depth, &full(3, 4, 10.0)),
            Err(MeshError::SizeMismatch { .. })
        ));
        assert!(matches!(
            DepthMesh::new(&depth, &full(4, 4, 0.0)),
            Err(MeshError::InvalidFocal(_))
        ));
        for options in [
            MeshOptions {
                stride: 0,
                ..MeshOptions::default()
            },
            MeshOptions {
                max_step_footprints: f64::NAN,
                ..MeshOptions::default()
            },
        ] {
            assert!(matches!(
                DepthMesh::with_options(&depth, &full(4, 4, 10.0), options),
                Err(MeshError::InvalidOptions(_))
            ));
        }
        for empty in [Grid::filled(0, 0, 1.0), Grid::filled(1, 1, 1.0)] {
            let (w, h) = empty.size();
            let m = DepthMesh::new(&empty, &full(w, h, 10.0));
            assert!(m.is_ok_and(|m| m.is_empty()));
        }
    }
}
