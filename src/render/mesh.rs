//! Depth map to triangle mesh (CPU only).

use crate::camera::Intrinsics;
use crate::grid::Grid;
use glam::Vec3;

/// Vertex value meaning "no colour value here" (the colour grid was not
/// finite at that pixel); the shader draws such vertices grey in
/// [`ColourMode::Error`](super::ColourMode::Error).
pub const NO_VALUE: f32 = f32::MAX;

/// Marks a pixel without a vertex in the pixel-to-vertex table.
const NO_VERTEX: u32 = u32::MAX;

/// One mesh vertex as uploaded to the GPU. Keep in sync with `VertexIn` in
/// surface.wgsl and `SurfaceRenderer`'s vertex layout.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SurfaceVertex {
    /// Position in world space (see the module docs; depth = `-z`).
    pub position_world: [f32; 3],
    /// Unit normal in world space, on the side facing the photo's camera.
    pub normal_world: [f32; 3],
    /// Scalar for colour mapping: the depth, or the given colour value, or
    /// [`NO_VALUE`].
    pub value: f32,
}

/// A bounding box and sphere of a mesh, for framing the camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Corner with the smallest coordinates, world space.
    pub min_world: Vec3,
    /// Corner with the largest coordinates, world space.
    pub max_world: Vec3,
    /// Centre of the box, world space.
    pub centre_world: Vec3,
    /// Radius of the sphere about `centre_world` through the box's corners,
    /// so it holds every vertex (world units, > 0).
    pub radius: f32,
}

impl Default for Bounds {
    /// The unit sphere one unit in front of the photo's camera.
    fn default() -> Self {
        let centre_world = Vec3::new(0.0, 0.0, -1.0);
        Self {
            min_world: centre_world - Vec3::ONE,
            max_world: centre_world + Vec3::ONE,
            centre_world,
            radius: 1.0,
        }
    }
}

/// A triangle mesh of a depth map, ready for [`SurfaceRenderer::upload`](super::SurfaceRenderer::upload).
#[derive(Clone, Debug, Default)]
pub struct SurfaceMesh {
    vertices: Vec<SurfaceVertex>,
    triangle_indices: Vec<u32>,
    line_indices: Vec<u32>,
    bounds: Bounds,
    depth_range: Option<[f32; 2]>,
    value_range: Option<[f32; 2]>,
}

impl SurfaceMesh {
    /// Default of the depth-discontinuity rule of [`Self::from_depth_with_max_step`]:
    /// a 2x2 block is cut when its depths differ by more than this many pixel
    /// footprints (a slope of about 84 degrees to the image plane).
    pub const DEFAULT_MAX_STEP_FOOTPRINTS: f64 = 10.0;

    /// [`Self::from_depth_with_max_step`] with [`Self::DEFAULT_MAX_STEP_FOOTPRINTS`].
    pub fn from_depth(
        depth: &Grid<f64>,
        camera: &Intrinsics,
        colour_values: Option<&Grid<f64>>,
    ) -> Self {
        Self::from_depth_with_max_step(
            depth,
            camera,
            colour_values,
            Self::DEFAULT_MAX_STEP_FOOTPRINTS,
        )
    }

    /// Builds the mesh of a depth map seen through `camera` (intrinsics at the
    /// depth map's resolution).
    ///
    /// - Every pixel centre with finite, positive depth becomes one vertex
    ///   (back-projected, then converted to world space); other pixels are
    ///   "no surface" (e.g. outside the object's mask).
    /// - Each 2x2 block of valid pixels becomes two triangles, unless it spans
    ///   a depth discontinuity: `max z - min z > max_step_footprints * min z / f`,
    ///   where `min z / f` is the footprint of one pixel at the block's nearest
    ///   depth. So no triangle crosses the silhouette or a depth step.
    /// - Normals are smooth: the cross product of central differences over the
    ///   4-neighbours (one-sided where a neighbour is missing or across a
    ///   step, which uses the same rule pairwise); an isolated vertex faces
    ///   the photo's camera.
    /// - `colour_values` (same size as `depth`, else ignored) gives each
    ///   vertex its [`SurfaceVertex::value`]; without it the value is the
    ///   depth. Non-finite colour values become [`NO_VALUE`].
    ///
    /// A non-positive or non-finite focal length gives an empty mesh.
    pub fn from_depth_with_max_step(
        depth: &Grid<f64>,
        camera: &Intrinsics,
        colour_values: Option<&Grid<f64>>,
        max_step_footprints: f64,
    ) -> Self {
        let mut mesh = Self::default();
        mesh.rebuild(depth, camera, colour_values, max_step_footprints);
        mesh
    }

    /// [`Self::from_depth_with_max_step`] into `self`, reusing its allocations
    /// (cheaper when meshes of similar size follow each other).
    pub fn rebuild(
        &mut self,
        depth: &Grid<f64>,
        camera: &Intrinsics,
        colour_values: Option<&Grid<f64>>,
        max_step_footprints: f64,
    ) {
        self.vertices.clear();
        self.triangle_indices.clear();
        self.line_indices.clear();
        self.bounds = Bounds::default();
        (self.depth_range, self.value_range) = (None, None);
        let focal_px = camera.focal_px;
        if !(focal_px.is_finite() && focal_px > 0.0) {
            return;
        }
        let (width, height) = depth.size();
        let depths = depth.as_slice();
        let colours = colour_values
            .filter(|c| c.size() == depth.size())
            .map(|c| c.as_slice());
        let inverse_focal = 1.0 / focal_px;
        let step_per_depth = max_step_footprints * inverse_focal;
        let is_valid = |z: f64| z.is_finite() && z > 0.0;
        let connected = |za: f64, zb: f64| (za - zb).abs() <= step_per_depth * za.min(zb);
        // `camera.back_project` with the divisions hoisted, then to world space.
        let x_over_f: Vec<f64> = (0..width)
            .map(|column| camera.image_xy(column as f64, 0.0).0 * inverse_focal)
            .collect();
        let world = |column: usize, row: usize, z: f64| {
            let y_over_f = camera.image_xy(0.0, row as f64).1 * inverse_focal;
            Vec3::new(
                (z * x_over_f[column]) as f32,
                (-z * y_over_f) as f32,
                -z as f32,
            )
        };

        // One pass over the rows; reserving is virtual memory only until used.
        let quads_x = width.saturating_sub(1);
        let quad_count = quads_x * height.saturating_sub(1);
        self.vertices.reserve(depths.len());
        self.triangle_indices.reserve(6 * quad_count);
        self.line_indices
            .reserve(4 * quad_count + 2 * (width + height));
        // Vertex index (or NO_VERTEX) of each pixel of the previous and current
        // rows; validity of the 2x2 blocks of the previous and current block rows.
        let (mut vertices_above, mut vertices_here) =
            (vec![NO_VERTEX; width], vec![NO_VERTEX; width]);
        let (mut quads_above, mut quads_here) = (vec![false; quads_x], vec![false; quads_x]);
        let (mut min_world, mut max_world) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        let mut values_seen = [f32::MAX, f32::MIN];
        let row_of = |row: usize| &depths[row * width..(row + 1) * width];
        for row in 0..height {
            let (depths_here, depths_above) = (row_of(row), row.checked_sub(1).map(row_of));
            let depths_below = (row + 1 < height).then(|| row_of(row + 1));
            for (column, &z) in depths_here.iter().enumerate() {
                vertices_here[column] = NO_VERTEX;
                if !is_valid(z) {
                    continue;
                }
                let here = world(column, row, z);
                // Smooth normal: central differences over connected 4-neighbours,
                // one-sided where one is missing.
                let neighbour = |column: usize, row: usize, other: f64| {
                    (is_valid(other) && connected(z, other)).then(|| world(column, row, other))
                };
                let left = column
                    .checked_sub(1)
                    .and_then(|c| neighbour(c, row, depths_here[c]));
                let right = depths_here
                    .get(column + 1)
                    .and_then(|&o| neighbour(column + 1, row, o));
                let up = depths_above.and_then(|d| neighbour(column, row - 1, d[column]));
                let down = depths_below.and_then(|d| neighbour(column, row + 1, d[column]));
                let difference = |plus: Option<Vec3>, minus: Option<Vec3>| match (plus, minus) {
                    (None, None) => None,
                    (plus, minus) => Some(plus.unwrap_or(here) - minus.unwrap_or(here)),
                };
                // World x follows the columns, world -y the rows: (down - up) x
                // (right - left) points towards the photo's camera.
                let normal = difference(down, up)
                    .zip(difference(right, left))
                    .and_then(|(along_rows, along_x)| along_rows.cross(along_x).try_normalize())
                    .or_else(|| (-here).try_normalize())
                    .unwrap_or(Vec3::Z);
                let pixel = row * width + column;
                let value = match colours {
                    Some(c) if c[pixel].is_finite() => c[pixel] as f32,
                    Some(_) => NO_VALUE,
                    None => z as f32,
                };
                if value != NO_VALUE {
                    values_seen = [values_seen[0].min(value), values_seen[1].max(value)];
                }
                min_world = min_world.min(here);
                max_world = max_world.max(here);
                vertices_here[column] = self.vertices.len() as u32;
                self.vertices.push(SurfaceVertex {
                    position_world: here.to_array(),
                    normal_world: normal.to_array(),
                    value,
                });
            }

            // The 2x2 blocks between the previous row and this one.
            if let Some(depths_above) = depths_above {
                for column in 0..quads_x {
                    let (a, b) = (vertices_above[column], vertices_above[column + 1]);
                    let (c, d) = (vertices_here[column], vertices_here[column + 1]);
                    let corners = [
                        depths_above[column],
                        depths_above[column + 1],
                        depths_here[column],
                        depths_here[column + 1],
                    ];
                    let (lo, hi) = corners
                        .iter()
                        .fold((f64::MAX, f64::MIN), |(lo, hi), &z| (lo.min(z), hi.max(z)));
                    let valid = [a, b, c, d].iter().all(|&v| v != NO_VERTEX)
                        && hi - lo <= step_per_depth * lo;
                    quads_here[column] = valid;
                    if !valid {
                        continue;
                    }
                    // Counter-clockwise as seen from the photo's camera.
                    self.triangle_indices.extend_from_slice(&[a, c, b, b, c, d]);
                    // The block's outline (not its diagonal): bottom and right
                    // edges always, top and left ones where no block drew them.
                    self.line_indices.extend_from_slice(&[c, d, b, d]);
                    if !quads_above[column] {
                        self.line_indices.extend_from_slice(&[a, b]);
                    }
                    if column == 0 || !quads_here[column - 1] {
                        self.line_indices.extend_from_slice(&[a, c]);
                    }
                }
                std::mem::swap(&mut quads_above, &mut quads_here);
            }
            std::mem::swap(&mut vertices_above, &mut vertices_here);
        }

        if !self.vertices.is_empty() {
            let centre_world = 0.5 * (min_world + max_world);
            let radius = 0.5 * (max_world - min_world).length();
            self.bounds = Bounds {
                min_world,
                max_world,
                centre_world,
                radius: if radius > 0.0 {
                    radius
                } else {
                    1e-3 * centre_world.length().max(1.0)
                },
            };
        }
        let seen = |r: [f32; 2]| (r[0] <= r[1]).then_some(r);
        self.depth_range = seen([-max_world.z, -min_world.z]);
        self.value_range = seen(values_seen);
    }

    /// The vertices, one per valid pixel in row-major order.
    pub fn vertices(&self) -> &[SurfaceVertex] {
        &self.vertices
    }

    /// Triangle list (three vertex indices per triangle, counter-clockwise as
    /// seen from the photo's camera).
    pub fn triangle_indices(&self) -> &[u32] {
        &self.triangle_indices
    }

    /// Line list of the grid edges: the outlines of the 2x2 blocks drawn as
    /// triangles, without their diagonals (two vertex indices per edge, each
    /// edge once).
    pub fn line_indices(&self) -> &[u32] {
        &self.line_indices
    }

    /// Bounding box and sphere ([`Bounds::default`] for an empty mesh).
    pub fn bounds(&self) -> Bounds {
        self.bounds
    }

    /// `[min, max]` depth over the vertices, `None` when empty.
    pub fn depth_range(&self) -> Option<[f32; 2]> {
        self.depth_range
    }

    /// `[min, max]` vertex value (excluding [`NO_VALUE`]), `None` when there is none.
    pub fn value_range(&self) -> Option<[f32; 2]> {
        self.value_range
    }

    /// True when the mesh has no triangles.
    pub fn is_empty(&self) -> bool {
        self.triangle_indices.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(width: usize, height: usize) -> Intrinsics {
        Intrinsics::centred(50.0, width, height)
    }

    fn triangles(mesh: &SurfaceMesh) -> impl Iterator<Item = [u32; 3]> + '_ {
        mesh.triangle_indices()
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
    }

    /// Pixel (column, row) of each vertex, from the row-major vertex order.
    fn vertex_pixels(depth: &Grid<f64>) -> Vec<(usize, usize)> {
        (0..depth.len())
            .filter(|&p| depth.as_slice()[p].is_finite())
            .map(|p| (p % depth.width(), p / depth.width()))
            .collect()
    }

    #[test]
    fn nan_hole_has_no_triangle_and_one_vertex_per_finite_pixel() {
        let depth = Grid::from_fn(9, 7, |c, r| {
            if (3..=5).contains(&c) && (2..=3).contains(&r) || (c, r) == (0, 6) {
                f64::NAN
            } else {
                5.0
            }
        });
        let mesh = SurfaceMesh::from_depth(&depth, &camera(9, 7), None);
        let finite = depth.as_slice().iter().filter(|z| z.is_finite()).count();
        assert_eq!(mesh.vertices().len(), finite);
        let pixels = vertex_pixels(&depth);
        for triangle in triangles(&mesh) {
            for v in triangle {
                let (c, r) = pixels[v as usize];
                assert!(depth.at(c, r).is_finite());
            }
            let columns: Vec<usize> = triangle.iter().map(|&v| pixels[v as usize].0).collect();
            let rows: Vec<usize> = triangle.iter().map(|&v| pixels[v as usize].1).collect();
            let span = |v: &[usize]| v.iter().max().unwrap() - v.iter().min().unwrap();
            assert!(span(&columns) <= 1 && span(&rows) <= 1);
        }
        // 8x6 blocks, minus the 4x3 touching the hole and the 1 at the corner.
        assert_eq!(mesh.triangle_indices().len(), 3 * 2 * (8 * 6 - 4 * 3 - 1));
        // Edges of a grid of blocks: each drawn once.
        let mut edges: Vec<(u32, u32)> = mesh
            .line_indices()
            .chunks_exact(2)
            .map(|e| (e[0].min(e[1]), e[0].max(e[1])))
            .collect();
        let count = edges.len();
        edges.sort_unstable();
        edges.dedup();
        assert_eq!(edges.len(), count);
    }

    #[test]
    fn plane_facing_the_camera_has_normals_towards_it() {
        let depth = Grid::filled(12, 10, 4.0);
        let mesh = SurfaceMesh::from_depth(&depth, &camera(12, 10), None);
        assert_eq!(mesh.vertices().len(), 120);
        assert_eq!(mesh.triangle_indices().len(), 6 * 11 * 9);
        for v in mesh.vertices() {
            let n = Vec3::from_array(v.normal_world);
            assert!((n - Vec3::Z).length() < 1e-5, "{n}");
            assert!((v.position_world[2] + 4.0).abs() < 1e-6);
            assert_eq!(v.value, 4.0);
        }
        // Every triangle is counter-clockwise seen from +z (the camera).
        let p = |i: u32| Vec3::from_array(mesh.vertices()[i as usize].position_world);
        for [a, b, c] in triangles(&mesh) {
            assert!((p(b) - p(a)).cross(p(c) - p(a)).z > 0.0);
        }
    }

    #[test]
    fn tilted_plane_normal_matches_geometry() {
        // Plane z_camera = 5 + 0.5 x_camera: normal (in camera space) ~ (0.5, 0, -1),
        // i.e. (0.5, 0, 1) in world space after the y/z flip.
        let cam = camera(15, 15);
        let depth = Grid::from_fn(15, 15, |c, r| {
            let (x, _) = cam.image_xy(c as f64, r as f64);
            5.0 / (1.0 - 0.5 * x / cam.focal_px)
        });
        let mesh = SurfaceMesh::from_depth(&depth, &cam, None);
        let expected = Vec3::new(0.5, 0.0, 1.0).normalize();
        for v in mesh.vertices() {
            assert!((Vec3::from_array(v.normal_world) - expected).length() < 1e-3);
        }
    }

    #[test]
    fn depth_step_cuts_the_mesh() {
        let cam = camera(10, 6);
        // Footprint at depth 10 is 10 / 50 = 0.2, so a step of 5 is 25 footprints.
        let depth = Grid::from_fn(10, 6, |c, _| if c < 5 { 10.0 } else { 15.0 });
        let mesh = SurfaceMesh::from_depth(&depth, &cam, None);
        let pixels = vertex_pixels(&depth);
        let side = |v: u32| pixels[v as usize].0 < 5;
        for t in triangles(&mesh) {
            assert!(t.iter().all(|&v| side(v)) || t.iter().all(|&v| !side(v)));
        }
        for e in mesh.line_indices().chunks_exact(2) {
            assert_eq!(side(e[0]), side(e[1]));
        }
        assert_eq!(mesh.triangle_indices().len(), 6 * (9 - 1) * 5);
        // A gentler rule keeps the step.
        let joined = SurfaceMesh::from_depth_with_max_step(&depth, &cam, None, 30.0);
        assert_eq!(joined.triangle_indices().len(), 6 * 9 * 5);
    }

    #[test]
    fn bounds_ranges_and_colour_values() {
        let cam = camera(5, 5);
        let depth = Grid::from_fn(5, 5, |c, _| 2.0 + 0.01 * c as f64);
        let colours = Grid::from_fn(5, 5, |c, r| if r == 0 { f64::NAN } else { c as f64 });
        let mesh = SurfaceMesh::from_depth(&depth, &cam, Some(&colours));
        let b = mesh.bounds();
        for v in mesh.vertices() {
            let p = Vec3::from_array(v.position_world);
            assert!(p.distance(b.centre_world) <= b.radius * (1.0 + 1e-5));
            assert!(p.cmpge(b.min_world).all() && p.cmple(b.max_world).all());
        }
        assert!((b.centre_world.z + 2.02).abs() < 1e-5);
        assert_eq!(mesh.depth_range(), Some([2.0, 2.04]));
        assert_eq!(mesh.value_range(), Some([0.0, 4.0]));
        assert_eq!(mesh.vertices()[0].value, NO_VALUE);
        // A colour grid of the wrong size is ignored.
        let wrong = Grid::filled(3, 3, 1.0);
        let mesh = SurfaceMesh::from_depth(&depth, &cam, Some(&wrong));
        assert_eq!(mesh.value_range(), Some([2.0, 2.04]));
        // Degenerate inputs.
        let empty = SurfaceMesh::from_depth(&Grid::filled(4, 4, f64::NAN), &cam, None);
        assert!(empty.is_empty() && empty.vertices().is_empty());
        assert_eq!(empty.bounds(), Bounds::default());
        assert!(SurfaceMesh::from_depth(&Grid::filled(1, 1, 1.0), &cam, None).is_empty());
        assert!(SurfaceMesh::from_depth(&Grid::filled(0, 0, 1.0), &cam, None).is_empty());
    }
}
