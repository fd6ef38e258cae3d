//! OBJ triangle meshes rendered in perspective with exact ground-truth depth.
//!
//! Conventions (METHOD.md section 1): pinhole camera at the origin looking
//! along +Z; pixel (column `i`, row `j`) has image-plane coordinates
//! `x = i - cx`, `y = j - cy` (rows go down, so camera +Y is image-down); the
//! ray through a pixel centre is `d = (x/f, y/f, 1)` and depth is the Cartesian
//! `Z` of the surface point. A point light sits at the camera centre with
//! `1/r^2` fall-off and the surface is Lambertian:
//! `I = s * max(N . L, 0) / r^2` with `r = |P|`, `L = -P/r` and `N` the unit
//! normal turned to face the camera. The background has image 0, depth NaN and
//! mask false.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use crate::camera::Intrinsics;
use crate::grid::Grid;
use crate::light::PointLight;
use crate::material::Material;
use crate::scene::Scene;

/// Rows per band of the parallel rasteriser (triangles are binned per band).
const BAND_ROWS: usize = 8;

/// Slack in pixels added to the screen-space bounding box of a triangle so a
/// pixel centre lying exactly on an edge is never missed by rounding of the
/// projection; the inclusion test itself is exact in 3-D.
const BBOX_SLACK_PX: f64 = 1e-6;

/// Errors from loading or rendering a mesh.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be read or parsed as OBJ.
    #[error("cannot load OBJ file {}: {message}", path.display())]
    Load {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The mesh has no vertices or no triangles.
    #[error("mesh {mesh}: no vertices or no triangles")]
    Empty {
        /// The mesh: the file path for [`load_obj`], the scene name for [`render`].
        mesh: String,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "mesh {mesh}: triangle {triangle} refers to vertex {vertex} but there are only {vertex_count} vertices"
    )]
    InvalidIndex {
        /// The mesh: the file path for [`load_obj`], the scene name for [`render`].
        mesh: String,
        /// Index of the offending triangle.
        triangle: usize,
        /// The out-of-range vertex index (0-based).
        vertex: u32,
        /// Number of vertices in the mesh.
        vertex_count: usize,
    },
    /// Non-finite coordinates, a zero-size bounding box or a geometry that
    /// cannot be framed by the camera.
    #[error("mesh {mesh} is degenerate: {reason}")]
    Degenerate {
        /// The mesh: the file path for [`load_obj`], the scene name for [`render`].
        mesh: String,
        /// What is degenerate.
        reason: String,
    },
    /// Invalid image size or placement parameters.
    #[error("invalid render input: {message}")]
    InvalidInput {
        /// What is invalid.
        message: String,
    },
    /// The rendered mesh covers no pixel centre.
    #[error("mesh {mesh} is not visible: no pixel centre hits a triangle")]
    Misses {
        /// The scene name.
        mesh: String,
    },
    /// Every visible pixel has zero intensity (all surfaces seen edge-on).
    #[error("mesh {mesh} renders completely dark: every visible surface is edge-on to the light")]
    Unlit {
        /// The scene name.
        mesh: String,
    },
}

/// A triangle mesh in model space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions (model units).
    pub positions: Vec<[f64; 3]>,
    /// Triangles as 0-based indices into `positions`. The winding is used only
    /// for smooth normals; each normal is turned to face the camera anyway.
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// Checks the mesh (non-empty, indices in range, all coordinates finite,
    /// non-zero bounding box) and returns the bounding box `(min, max)` of the
    /// vertices referenced by triangles. `label` names the mesh in errors.
    fn validated_bounds(&self, label: &str) -> Result<([f64; 3], [f64; 3]), MeshError> {
        if self.positions.is_empty() || self.triangles.is_empty() {
            return Err(MeshError::Empty {
                mesh: label.to_owned(),
            });
        }
        if let Some(k) = self
            .positions
            .iter()
            .position(|p| p.iter().any(|c| !c.is_finite()))
        {
            return Err(MeshError::Degenerate {
                mesh: label.to_owned(),
                reason: format!("vertex {k} has a non-finite coordinate"),
            });
        }
        let vertex_count = self.positions.len();
        let mut min = [f64::INFINITY; 3];
        let mut max = [f64::NEG_INFINITY; 3];
        for (triangle, tri) in self.triangles.iter().enumerate() {
            for &vertex in tri {
                let Some(p) = self.positions.get(vertex as usize) else {
                    return Err(MeshError::InvalidIndex {
                        mesh: label.to_owned(),
                        triangle,
                        vertex,
                        vertex_count,
                    });
                };
                for axis in 0..3 {
                    min[axis] = min[axis].min(p[axis]);
                    max[axis] = max[axis].max(p[axis]);
                }
            }
        }
        let largest_side = (0..3).map(|a| max[a] - min[a]).fold(0.0, f64::max);
        if !(largest_side.is_finite() && largest_side > 0.0) {
            return Err(MeshError::Degenerate {
                mesh: label.to_owned(),
                reason: format!("bounding box largest side is {largest_side}"),
            });
        }
        Ok((min, max))
    }
}

/// Loads an OBJ file as one triangle mesh.
///
/// Triangles and polygons (fan-triangulated by `tobj`) with any `v`, `v/vt`,
/// `v//vn` or `v/vt/vn` index form are accepted; all objects and groups in the
/// file are merged; points, lines, texture coordinates, normals and materials
/// are ignored (the `mtllib` file is never opened). Coordinates are read as
/// `f32` by `tobj` and widened to `f64`.
///
/// # Errors
/// [`MeshError::Load`] when the file cannot be read or parsed (including
/// out-of-range face indices); [`MeshError::Empty`], [`MeshError::Degenerate`]
/// (non-finite coordinates, zero-size bounding box) for unusable content. Every
/// error names the file.
pub fn load_obj(path: &Path) -> Result<TriangleMesh, MeshError> {
    let load_error = |message: String| MeshError::Load {
        path: path.to_path_buf(),
        message,
    };
    let file = File::open(path).map_err(|e| load_error(e.to_string()))?;
    let mut reader = BufReader::new(file);
    // Triangulated, points and lines dropped (as in GPU_LOAD_OPTIONS), but
    // positions keep their own index (no duplication per normal/texcoord).
    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: true,
        ..tobj::GPU_LOAD_OPTIONS
    };
    // tobj can overflow index arithmetic on hostile relative indices (a panic
    // with overflow checks on); turn that into an error as well.
    let parsed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut reader, &options, |_| {
            Err(tobj::LoadError::GenericFailure)
        })
    }))
    .map_err(|_| load_error("the OBJ parser failed on malformed input".to_owned()))?;
    let (models, _materials) = parsed.map_err(|e| load_error(e.to_string()))?;

    let mut mesh = TriangleMesh::default();
    for model in &models {
        let m = &model.mesh;
        if m.positions.len() % 3 != 0 || m.indices.len() % 3 != 0 {
            return Err(load_error(format!(
                "object `{}` is not a triangle list after triangulation",
                model.name
            )));
        }
        let offset = u32::try_from(mesh.positions.len())
            .map_err(|_| load_error("too many vertices".to_owned()))?;
        let model_vertices = m.positions.len() / 3;
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]),
        );
        for tri in m.indices.chunks_exact(3) {
            let mut out = [0u32; 3];
            for (o, &i) in out.iter_mut().zip(tri) {
                if i as usize >= model_vertices {
                    return Err(load_error(format!(
                        "object `{}` refers to vertex {i} of {model_vertices}",
                        model.name
                    )));
                }
                *o = offset
                    .checked_add(i)
                    .ok_or_else(|| load_error("too many vertices".to_owned()))?;
            }
            mesh.triangles.push(out);
        }
    }
    mesh.validated_bounds(&path.display().to_string())?;
    Ok(mesh)
}

/// Placement of a mesh in front of the camera, and the exposure.
///
/// The mesh's bounding box (of the vertices used by triangles) is centred at
/// the origin, the mesh is scaled so the largest bounding-box side is 1, rotated
/// by [`rotation_deg`](Placement::rotation_deg) and translated to
/// `(0, 0, distance)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// Rotation of the centred model as Euler angles in degrees `[a_x, a_y,
    /// a_z]`: first about the camera X axis by `a_x`, then about the (fixed)
    /// camera Y axis by `a_y`, then about the camera Z axis by `a_z`, i.e.
    /// `R = Rz(a_z) Ry(a_y) Rx(a_x)` acting on column vectors, each a
    /// right-handed rotation. Default `(180, 0, 0)`: turns the usual OBJ
    /// convention (Y up, front facing +Z) into the camera convention (Y down,
    /// camera looking along +Z, the front facing the camera), without mirroring.
    pub rotation_deg: [f64; 3],
    /// Distance from the camera centre to the bounding-box centre, in units of
    /// the model's largest bounding-box side. Must exceed `sqrt(3)/2` so the
    /// whole model lies in front of the camera. Default 2.0.
    pub distance: f64,
    /// Fraction of the image, in each direction, that the projected object may
    /// fill, in (0, 1]; sets the focal length. Default 0.9.
    pub fill: f64,
    /// Value of the brightest pixel, in (0, 1]; the intensity scale `s` is
    /// chosen to reach it. Default 0.9.
    pub brightest: f64,
}

impl Default for Placement {
    fn default() -> Self {
        Self {
            rotation_deg: [180.0, 0.0, 0.0],
            distance: 2.0,
            fill: 0.9,
            brightest: 0.9,
        }
    }
}

impl Placement {
    /// Checks every field; see the field docs for the ranges.
    fn validate(&self) -> Result<(), MeshError> {
        let invalid = |message: String| Err(MeshError::InvalidInput { message });
        if self.rotation_deg.iter().any(|a| !a.is_finite()) {
            return invalid(format!(
                "rotation_deg {:?} must be finite",
                self.rotation_deg
            ));
        }
        let min_distance = 3f64.sqrt() / 2.0;
        if !(self.distance.is_finite() && self.distance > min_distance) {
            return invalid(format!(
                "distance {} must be finite and greater than sqrt(3)/2",
                self.distance
            ));
        }
        if !(self.fill > 0.0 && self.fill <= 1.0) {
            return invalid(format!("fill {} must lie in (0, 1]", self.fill));
        }
        if !(self.brightest > 0.0 && self.brightest <= 1.0) {
            return invalid(format!("brightest {} must lie in (0, 1]", self.brightest));
        }
        Ok(())
    }
}

/// Renders `mesh` as a synthetic scene of `width` x `height` pixels.
///
/// The mesh is placed as described in [`Placement`]. The focal length `f`
/// (pixels) is the largest for which every vertex used by a triangle projects
/// inside `fill` of the image in both directions with the default principal
/// point `((w-1)/2, (h-1)/2)`:
/// `f = min(fill (w-1)/2 / max|X/Z|, fill (h-1)/2 / max|Y/Z|)`.
///
/// A z-buffer rasteriser then finds, for every pixel centre, the nearest
/// triangle the ray `d = (x/f, y/f, 1)` hits (exact 3-D inclusion test with
/// signed volumes, watertight along shared edges; candidate pixels from the
/// screen-space bounding box) and takes the exact ray-plane intersection `Z` as
/// depth; ties go to the lower triangle index. Shading uses smooth vertex
/// normals (sum of the unnormalised face cross products at each vertex, i.e.
/// area-weighted) interpolated with the barycentric coordinates of the 3-D hit
/// point, normalised and turned to face the camera; the face normal is used
/// where the interpolated normal vanishes. The image is rendered with `s = 1`
/// and then scaled so the brightest pixel equals `placement.brightest`; that
/// `s` is stored as [`Scene::intensity_scale`]. Triangles with a vertex at
/// `Z <= 0` are skipped (the placement rules them out).
///
/// # Errors
/// [`MeshError::InvalidInput`] for a size below 2 x 2 or invalid placement;
/// [`MeshError::Empty`], [`MeshError::InvalidIndex`] or
/// [`MeshError::Degenerate`] for an unusable mesh; [`MeshError::Misses`] when no
/// pixel centre hits the mesh and [`MeshError::Unlit`] when all hits are dark.
pub fn render(
    mesh: &TriangleMesh,
    width: usize,
    height: usize,
    placement: &Placement,
    name: &str,
) -> Result<Scene, MeshError> {
    render_lit(mesh, width, height, placement, &[], name)
}

/// [`render`] lit by `lights` (camera frame, in units of the placed model,
/// whose largest side is 1; empty: one light at the optical centre). Cast
/// shadows are not traced: the image is the model's local shading.
pub fn render_lit(
    mesh: &TriangleMesh,
    width: usize,
    height: usize,
    placement: &Placement,
    lights: &[PointLight],
    name: &str,
) -> Result<Scene, MeshError> {
    render_shaded(
        mesh,
        width,
        height,
        placement,
        lights,
        Material::Lambert,
        name,
    )
}

/// [`render_lit`] for a surface of `material` (METHOD.md section 10),
/// shaded with the true normal and the direction to the camera; Lambert
/// renders exactly as [`render_lit`].
pub fn render_shaded(
    mesh: &TriangleMesh,
    width: usize,
    height: usize,
    placement: &Placement,
    lights: &[PointLight],
    material: Material,
    name: &str,
) -> Result<Scene, MeshError> {
    let material = material
        .validated()
        .map_err(|message| MeshError::InvalidInput { message })?;
    for (k, light) in lights.iter().enumerate() {
        light
            .validated(k + 1)
            .map_err(|message| MeshError::InvalidInput { message })?;
    }
    if width < 2 || height < 2 {
        return Err(MeshError::InvalidInput {
            message: format!("image size {width} x {height}: both sides must be at least 2 pixels"),
        });
    }
    let pixel_count = width
        .checked_mul(height)
        .ok_or_else(|| MeshError::InvalidInput {
            message: format!("image size {width} x {height} is too large"),
        })?;
    placement.validate()?;
    let bounds = mesh.validated_bounds(name)?;
    let camera_points = place_vertices(mesh, bounds, placement);
    let focal_px = fit_focal_px(mesh, &camera_points, width, height, placement.fill, name)?;
    let camera = Intrinsics::centred(focal_px, width, height);

    let vertex_normals = vertex_normals(&camera_points, &mesh.triangles);
    let triangles = prepare_triangles(mesh, &camera_points, &camera, width, height);
    let bins = bin_by_band(&triangles, height);

    // Ray directions per column and per row: d = (x/f, y/f, 1).
    let ray_x: Vec<f64> = (0..width)
        .map(|i| camera.image_xy(i as f64, 0.0).0 / focal_px)
        .collect();
    let ray_y: Vec<f64> = (0..height)
        .map(|j| camera.image_xy(0.0, j as f64).1 / focal_px)
        .collect();

    let mut image = vec![0.0; pixel_count];
    let mut depth = vec![f64::NAN; pixel_count];
    let mut mask = vec![false; pixel_count];
    let mut normals = vec![[f64::NAN; 3]; pixel_count];
    let band_len = BAND_ROWS * width;
    depth
        .par_chunks_mut(band_len)
        .zip(image.par_chunks_mut(band_len))
        .zip(mask.par_chunks_mut(band_len))
        .zip(normals.par_chunks_mut(band_len))
        .zip(bins.par_iter())
        .enumerate()
        .for_each(|(band, ((((depth, image), mask), normals), bin))| {
            let band = Band {
                first_row: band * BAND_ROWS,
                width,
                ray_x: &ray_x,
                ray_y: &ray_y,
            };
            band.render(
                bin,
                &triangles,
                &vertex_normals,
                (lights, material),
                depth,
                image,
                (mask, normals),
            );
        });

    if !mask.iter().any(|&m| m) {
        return Err(MeshError::Misses {
            mesh: name.to_owned(),
        });
    }
    let brightest_raw = image.iter().copied().fold(0.0, f64::max);
    let intensity_scale = placement.brightest / brightest_raw;
    if !(brightest_raw > 0.0 && intensity_scale.is_finite()) {
        return Err(MeshError::Unlit {
            mesh: name.to_owned(),
        });
    }
    image.par_iter_mut().for_each(|v| *v *= intensity_scale);

    let grid_error = || MeshError::InvalidInput {
        message: "internal: grid size mismatch".to_owned(),
    };
    Ok(Scene {
        name: name.to_owned(),
        camera,
        intensity_scale,
        image: Grid::from_vec(width, height, image).ok_or_else(grid_error)?,
        depth_gt: Grid::from_vec(width, height, depth).ok_or_else(grid_error)?,
        object_mask: Grid::from_vec(width, height, mask).ok_or_else(grid_error)?,
        normals: Some(Grid::from_vec(width, height, normals).ok_or_else(grid_error)?),
        lights: lights.to_vec(),
        material,
    })
}

/// A triangle ready for rasterising, in camera space.
struct PreparedTriangle {
    /// The vertex indices `A, B, C` into the mesh's vertex list.
    vertices: [u32; 3],
    /// `A x B`, `B x C`, `C x A` for the vertices `A, B, C`: the signed volumes
    /// `d . (A x B)` etc. are the unnormalised barycentrics of `C`, `A`, `B`.
    edge_cross: [DVec3; 3],
    /// Face normal `(B - A) x (C - A)` (unnormalised).
    normal: DVec3,
    /// `normal . A`: the plane is `normal . P = plane_offset`.
    plane_offset: f64,
    /// Inclusive pixel column range of candidate pixel centres.
    columns: (usize, usize),
    /// Inclusive pixel row range of candidate pixel centres.
    rows: (usize, usize),
}

impl PreparedTriangle {
    /// Intersects the ray `d` with the triangle: `Some((depth, barycentrics of
    /// A, B, C))` when the ray passes through it (edges included) in front of
    /// the camera.
    #[inline]
    fn hit(&self, d: DVec3) -> Option<(f64, [f64; 3])> {
        let w_c = d.dot(self.edge_cross[0]);
        let w_a = d.dot(self.edge_cross[1]);
        let w_b = d.dot(self.edge_cross[2]);
        let inside =
            (w_a >= 0.0 && w_b >= 0.0 && w_c >= 0.0) || (w_a <= 0.0 && w_b <= 0.0 && w_c <= 0.0);
        let sum = w_a + w_b + w_c;
        if !inside || sum == 0.0 {
            return None;
        }
        let depth = self.plane_offset / self.normal.dot(d);
        if !(depth.is_finite() && depth > 0.0) {
            return None;
        }
        Some((depth, [w_a / sum, w_b / sum, w_c / sum]))
    }
}

/// One horizontal band of the image, rendered by one task.
struct Band<'a> {
    first_row: usize,
    width: usize,
    ray_x: &'a [f64],
    ray_y: &'a [f64],
}

impl Band<'_> {
    /// Z-buffers the triangles of `bin` into this band and shades it with
    /// `s = 1`. The slices are the band's rows of the full image.
    #[allow(clippy::too_many_arguments)]
    fn render(
        &self,
        bin: &[u32],
        triangles: &[PreparedTriangle],
        vertex_normals: &[DVec3],
        (lights, material): (&[PointLight], Material),
        depth: &mut [f64],
        image: &mut [f64],
        (mask, normals): (&mut [bool], &mut [[f64; 3]]),
    ) {
        let rows_here = depth.len() / self.width;
        let last_row = self.first_row + rows_here - 1;
        let mut nearest = vec![f64::INFINITY; depth.len()];
        let mut winner = vec![u32::MAX; depth.len()];
        for &t in bin {
            let tri = &triangles[t as usize];
            let row_start = tri.rows.0.max(self.first_row);
            let row_end = tri.rows.1.min(last_row);
            for row in row_start..=row_end {
                let local = (row - self.first_row) * self.width;
                for column in tri.columns.0..=tri.columns.1 {
                    let d = DVec3::new(self.ray_x[column], self.ray_y[row], 1.0);
                    if let Some((z, _)) = tri.hit(d)
                        && z < nearest[local + column]
                    {
                        nearest[local + column] = z;
                        winner[local + column] = t;
                    }
                }
            }
        }
        for (k, &t) in winner.iter().enumerate() {
            let Some(tri) = triangles.get(t as usize) else {
                continue;
            };
            let d = DVec3::new(
                self.ray_x[k % self.width],
                self.ray_y[self.first_row + k / self.width],
                1.0,
            );
            let Some((z, bary)) = tri.hit(d) else {
                continue;
            };
            let point = d * z;
            let normal = shading_normal(tri, bary, vertex_normals);
            // The normal turned to face the camera (N . P <= 0).
            let facing = if normal.dot(point) > 0.0 {
                -normal
            } else {
                normal
            };
            let intensity = crate::light::irradiance_with_material(
                lights,
                material,
                point.to_array(),
                facing.to_array(),
            );
            depth[k] = z;
            mask[k] = true;
            normals[k] = facing.to_array();
            image[k] = if intensity.is_finite() {
                intensity
            } else {
                0.0
            };
        }
    }
}

/// Unit shading normal at barycentrics `bary` of `tri` (orientation not yet
/// turned to the camera): interpolated smooth vertex normals, or the face
/// normal where they cancel.
fn shading_normal(tri: &PreparedTriangle, bary: [f64; 3], vertex_normals: &[DVec3]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for (&vertex, weight) in tri.vertices.iter().zip(bary) {
        n += weight * vertex_normals[vertex as usize];
    }
    // Both branches multiply by the reciprocal of the length, as `normalize`
    // does (the face normal of a prepared triangle is never zero).
    let length = n.length();
    if length.is_finite() && length > 0.0 {
        n * (1.0 / length)
    } else {
        tri.normal.normalize()
    }
}

/// Centres, scales, rotates and translates the vertices into camera space.
fn place_vertices(
    mesh: &TriangleMesh,
    (min, max): ([f64; 3], [f64; 3]),
    placement: &Placement,
) -> Vec<DVec3> {
    let (min, max) = (DVec3::from_array(min), DVec3::from_array(max));
    let centre = 0.5 * (min + max);
    let largest_side = (max - min).to_array().into_iter().fold(0.0, f64::max);
    let unit = 1.0 / largest_side;
    let rotation = rotation_matrix(placement.rotation_deg);
    mesh.positions
        .iter()
        .map(|&p| {
            let mut out = rotation * ((DVec3::from_array(p) - centre) * unit);
            out.z += placement.distance;
            out
        })
        .collect()
}

/// `R = Rz(a_z) Ry(a_y) Rx(a_x)` for `[a_x, a_y, a_z]` in degrees.
fn rotation_matrix(rotation_deg: [f64; 3]) -> DMat3 {
    let (cx, sx) = cos_sin_deg(rotation_deg[0]);
    let (cy, sy) = cos_sin_deg(rotation_deg[1]);
    let (cz, sz) = cos_sin_deg(rotation_deg[2]);
    let rows = |r0: [f64; 3], r1: [f64; 3], r2: [f64; 3]| {
        DMat3::from_rows(
            DVec3::from_array(r0),
            DVec3::from_array(r1),
            DVec3::from_array(r2),
        )
    };
    let rx = rows([1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]);
    let ry = rows([cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]);
    let rz = rows([cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]);
    rz * (ry * rx)
}

/// Cosine and sine of an angle in degrees, exact at multiples of 90 degrees.
fn cos_sin_deg(angle_deg: f64) -> (f64, f64) {
    let reduced = angle_deg.rem_euclid(360.0);
    if reduced == 0.0 {
        (1.0, 0.0)
    } else if reduced == 90.0 {
        (0.0, 1.0)
    } else if reduced == 180.0 {
        (-1.0, 0.0)
    } else if reduced == 270.0 {
        (0.0, -1.0)
    } else {
        let radians = reduced.to_radians();
        (radians.cos(), radians.sin())
    }
}

/// The focal length (pixels) that fits every used vertex into `fill` of the
/// image with the default principal point.
fn fit_focal_px(
    mesh: &TriangleMesh,
    camera_points: &[DVec3],
    width: usize,
    height: usize,
    fill: f64,
    name: &str,
) -> Result<f64, MeshError> {
    let mut max_tan_x: f64 = 0.0;
    let mut max_tan_y: f64 = 0.0;
    for tri in &mesh.triangles {
        for &v in tri {
            let p = camera_points[v as usize];
            if p.z > 0.0 {
                max_tan_x = max_tan_x.max((p.x / p.z).abs());
                max_tan_y = max_tan_y.max((p.y / p.z).abs());
            }
        }
    }
    let half_x_px = fill * (width as f64 - 1.0) / 2.0;
    let half_y_px = fill * (height as f64 - 1.0) / 2.0;
    let focal_px = (half_x_px / max_tan_x).min(half_y_px / max_tan_y);
    if focal_px.is_finite() && focal_px > 0.0 {
        Ok(focal_px)
    } else {
        Err(MeshError::Degenerate {
            mesh: name.to_owned(),
            reason: format!("cannot frame the mesh: focal length would be {focal_px} px"),
        })
    }
}

/// Area-weighted vertex normals: the sum of the unnormalised face cross
/// products `(B - A) x (C - A)` of the triangles at each vertex.
fn vertex_normals(camera_points: &[DVec3], triangles: &[[u32; 3]]) -> Vec<DVec3> {
    let mut normals = vec![DVec3::ZERO; camera_points.len()];
    for tri in triangles {
        let [a, b, c] = tri.map(|v| camera_points[v as usize]);
        let n = (b - a).cross(c - a);
        for &v in tri {
            normals[v as usize] += n;
        }
    }
    normals
}

/// Builds the rasteriser's triangles, dropping those behind the camera,
/// degenerate ones and those whose screen bounding box holds no pixel centre.
fn prepare_triangles(
    mesh: &TriangleMesh,
    camera_points: &[DVec3],
    camera: &Intrinsics,
    width: usize,
    height: usize,
) -> Vec<PreparedTriangle> {
    let f = camera.focal_px;
    let mut prepared = Vec::with_capacity(mesh.triangles.len());
    for tri in &mesh.triangles {
        let [a, b, c] = tri.map(|v| camera_points[v as usize]);
        if a.z <= 0.0 || b.z <= 0.0 || c.z <= 0.0 {
            continue;
        }
        let normal = (b - a).cross(c - a);
        if normal == DVec3::ZERO {
            continue;
        }
        let us = [a, b, c].map(|p| camera.principal_x_px + f * p.x / p.z);
        let vs = [a, b, c].map(|p| camera.principal_y_px + f * p.y / p.z);
        let Some(columns) = pixel_range(&us, width) else {
            continue;
        };
        let Some(rows) = pixel_range(&vs, height) else {
            continue;
        };
        prepared.push(PreparedTriangle {
            vertices: *tri,
            edge_cross: [a.cross(b), b.cross(c), c.cross(a)],
            normal,
            plane_offset: normal.dot(a),
            columns,
            rows,
        });
    }
    prepared
}

/// Inclusive range of integer pixel centres within `[min, max]` of `coords`
/// (plus slack), clipped to `0..size`; `None` when empty.
fn pixel_range(coords: &[f64; 3], size: usize) -> Option<(usize, usize)> {
    let lo = coords.iter().copied().fold(f64::INFINITY, f64::min) - BBOX_SLACK_PX;
    let hi = coords.iter().copied().fold(f64::NEG_INFINITY, f64::max) + BBOX_SLACK_PX;
    let first = lo.ceil().max(0.0);
    let last = hi.floor().min(size as f64 - 1.0);
    (first <= last).then_some((first as usize, last as usize))
}

/// Lists, per band of [`BAND_ROWS`] rows, the prepared triangles (their
/// positions in `triangles`, ascending) whose row range meets the band.
fn bin_by_band(triangles: &[PreparedTriangle], height: usize) -> Vec<Vec<u32>> {
    let band_count = height.div_ceil(BAND_ROWS);
    let mut bins = vec![Vec::new(); band_count];
    for (k, tri) in triangles.iter().enumerate() {
        for bin in &mut bins[tri.rows.0 / BAND_ROWS..=tri.rows.1 / BAND_ROWS] {
            bin.push(k as u32);
        }
    }
    bins
}

#[cfg(test)]
mod tests;
