//! The GPU form of a depth map's mesh (CPU only): the triangulation is
//! [`sfs_core::depth_mesh`]'s, shared with the exporters; this module adds
//! world-space positions, normals and per-vertex colour values.

use glam::Vec3;
use sfs_core::camera::Intrinsics;
use sfs_core::depth_mesh::DepthMesh;
use sfs_core::grid::Grid;
use sfs_core::model::LevelGeometry;

/// Vertex value meaning "no colour value here" (the colour grid was not
/// finite at that pixel); the shader draws such vertices grey in
/// [`ColourMode::Error`](super::ColourMode::Error).
pub const NO_VALUE: f32 = f32::MAX;

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
    /// The photograph's linear grey at this vertex (for
    /// [`ColourMode::Photo`](super::ColourMode::Photo)), or [`NO_VALUE`].
    pub photo: f32,
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
    /// The mesh of a full-resolution depth map seen through `camera`, by the
    /// one triangulation ([`DepthMesh::new`]); a depth map it refuses (a bad
    /// focal length) gives an empty mesh. `colour_values` as in
    /// [`Self::from_depth_mesh`]; no photograph.
    pub fn from_depth(
        depth: &Grid<f64>,
        camera: &Intrinsics,
        colour_values: Option<&Grid<f64>>,
    ) -> Self {
        let (width, height) = depth.size();
        let geometry = LevelGeometry::new(width, height, width, height, *camera);
        match DepthMesh::new(depth, &geometry) {
            Ok(mesh) => Self::from_depth_mesh(&mesh, colour_values, None),
            Err(_) => Self::default(),
        }
    }

    /// The GPU mesh of a [`DepthMesh`]: its vertices converted to world space
    /// (see the module docs), its area-weighted normals, its triangles and
    /// its grid edges for the wireframe.
    ///
    /// - `colour_values` (a grid at the depth map's size, indexed by each
    ///   vertex's level pixel; another size is ignored) gives each vertex its
    ///   [`SurfaceVertex::value`]; without it the value is the depth.
    ///   Non-finite colour values become [`NO_VALUE`].
    /// - `photo` (likewise) gives [`SurfaceVertex::photo`], the photograph's
    ///   linear grey at the vertex; without it, or where it is not finite,
    ///   [`NO_VALUE`].
    pub fn from_depth_mesh(
        mesh: &DepthMesh,
        colour_values: Option<&Grid<f64>>,
        photo: Option<&Grid<f64>>,
    ) -> Self {
        let world = |p: [f64; 3]| Vec3::new(p[0] as f32, -p[1] as f32, -p[2] as f32);
        let lookup = |grid: Option<&Grid<f64>>, (column, row): (usize, usize)| {
            grid.map(|g| {
                let v = *g.at(column, row);
                if v.is_finite() { v as f32 } else { NO_VALUE }
            })
        };
        // A grid of another size cannot be the level's.
        let fits = |g: &&Grid<f64>| g.size() == mesh.grid_size();
        let colour_values = colour_values.filter(fits);
        let photo = photo.filter(fits);

        let normals = mesh.normals_camera();
        let (mut min_world, mut max_world) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        let mut values_seen = [f32::MAX, f32::MIN];
        let vertices: Vec<SurfaceVertex> = mesh
            .positions_camera()
            .iter()
            .zip(&normals)
            .zip(mesh.vertex_pixels())
            .map(|((&position, &normal), &pixel)| {
                let here = world(position);
                min_world = min_world.min(here);
                max_world = max_world.max(here);
                let value = lookup(colour_values, pixel).unwrap_or(position[2] as f32);
                if value != NO_VALUE {
                    values_seen = [values_seen[0].min(value), values_seen[1].max(value)];
                }
                SurfaceVertex {
                    position_world: here.to_array(),
                    normal_world: world(normal).to_array(),
                    value,
                    photo: lookup(photo, pixel).unwrap_or(NO_VALUE),
                }
            })
            .collect();

        let bounds = if vertices.is_empty() {
            Bounds::default()
        } else {
            let centre_world = 0.5 * (min_world + max_world);
            let radius = 0.5 * (max_world - min_world).length();
            Bounds {
                min_world,
                max_world,
                centre_world,
                radius: if radius > 0.0 {
                    radius
                } else {
                    1e-3 * centre_world.length().max(1.0)
                },
            }
        };
        let seen = |r: [f32; 2]| (r[0] <= r[1]).then_some(r);
        Self {
            vertices,
            triangle_indices: mesh.triangles().as_flattened().to_vec(),
            line_indices: mesh.edges().as_flattened().to_vec(),
            bounds,
            depth_range: seen([-max_world.z, -min_world.z]),
            value_range: seen(values_seen),
        }
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
            assert_eq!(v.photo, NO_VALUE);
        }
        // Every triangle is counter-clockwise seen from +z (the camera).
        let p = |i: u32| Vec3::from_array(mesh.vertices()[i as usize].position_world);
        for t in mesh.triangle_indices().chunks_exact(3) {
            assert!((p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).z > 0.0);
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
    fn bounds_ranges_colour_values_and_photo() {
        let cam = camera(5, 5);
        let depth = Grid::from_fn(5, 5, |c, _| 2.0 + 0.01 * c as f64);
        let colours = Grid::from_fn(5, 5, |c, r| if r == 0 { f64::NAN } else { c as f64 });
        let photo = Grid::from_fn(5, 5, |c, r| 0.1 * (c + r) as f64);
        let geometry = LevelGeometry::new(5, 5, 5, 5, cam);
        let Ok(topology) = DepthMesh::new(&depth, &geometry) else {
            panic!("mesh")
        };
        let mesh = SurfaceMesh::from_depth_mesh(&topology, Some(&colours), Some(&photo));
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
        assert_eq!(mesh.vertices()[7].photo, 0.3);
        // Grids of the wrong size are ignored.
        let wrong = Grid::filled(3, 3, 1.0);
        let mesh = SurfaceMesh::from_depth_mesh(&topology, Some(&wrong), Some(&wrong));
        assert_eq!(mesh.value_range(), Some([2.0, 2.04]));
        assert!(mesh.vertices().iter().all(|v| v.photo == NO_VALUE));
        // Degenerate inputs.
        let empty = SurfaceMesh::from_depth(&Grid::filled(4, 4, f64::NAN), &cam, None);
        assert!(empty.is_empty() && empty.vertices().is_empty());
        assert_eq!(empty.bounds(), Bounds::default());
        assert!(SurfaceMesh::from_depth(&Grid::filled(1, 1, 1.0), &cam, None).is_empty());
        assert!(SurfaceMesh::from_depth(&Grid::filled(0, 0, 1.0), &cam, None).is_empty());
        let no_focal = Intrinsics::centred(0.0, 4, 4);
        assert!(SurfaceMesh::from_depth(&Grid::filled(4, 4, 1.0), &no_focal, None).is_empty());
    }

    /// The view's mesh and the exported PLY and OBJ hold the same vertices
    /// and the same triangles, for a depth map with a hole (depth 0), a NaN
    /// region at the border and a depth jump.
    #[test]
    fn view_mesh_and_exports_have_the_same_triangles() {
        let (w, h) = (14, 11);
        let cam = Intrinsics::centred(40.0, w, h);
        let depth = Grid::from_fn(w, h, |c, r| {
            if (4..=6).contains(&c) && (3..=4).contains(&r) {
                0.0 // a hole
            } else if c + r < 3 || (c == 13 && r > 7) {
                f64::NAN // a NaN region
            } else if c >= 9 {
                4.0 + 0.01 * r as f64 // behind a depth jump
            } else {
                2.0 + 0.01 * (c * r) as f64
            }
        });
        let view = SurfaceMesh::from_depth(&depth, &cam, None);
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let (ply, obj) = (dir.path().join("m.ply"), dir.path().join("m.obj"));
        sfs_core::io::write_depth_ply(&ply, &depth, &cam, None).unwrap_or_else(|e| panic!("{e}"));
        sfs_core::io::write_depth_obj(&obj, &depth, &cam).unwrap_or_else(|e| panic!("{e}"));

        // The three meshes number their vertices alike (row-major pixels):
        // triangles as sets of index triples, each rotated to start at its
        // smallest index (which keeps the winding).
        let triangle_set = |triangles: &[[u32; 3]]| {
            let mut set: Vec<[u32; 3]> = triangles
                .iter()
                .map(|t| {
                    let mut t = *t;
                    let first = (0..3).min_by_key(|&i| t[i]).unwrap_or(0);
                    t.rotate_left(first);
                    t
                })
                .collect();
            set.sort_unstable();
            set
        };
        let same_positions = |a: &[[f64; 3]], b: &[[f64; 3]]| {
            a.len() == b.len()
                && a.iter()
                    .zip(b)
                    .all(|(p, q)| (0..3).all(|i| (p[i] - q[i]).abs() <= 1e-5 * p[i].abs().max(1.0)))
        };
        let view_positions: Vec<[f64; 3]> = view
            .vertices()
            .iter()
            .map(|v| {
                let p = v.position_world.map(f64::from);
                [p[0], -p[1], -p[2]]
            })
            .collect();
        let view_triangles: Vec<[u32; 3]> = view
            .triangle_indices()
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        let from_view = triangle_set(&view_triangles);

        let text = std::fs::read_to_string(&obj).unwrap_or_else(|e| panic!("{e}"));
        let (mut obj_positions, mut obj_triangles) = (Vec::new(), Vec::new());
        for line in text.lines() {
            let fields: Vec<&str> = line.split_whitespace().collect();
            let numbers = |kind: &str| -> Vec<f64> {
                fields[1..]
                    .iter()
                    .map(|x| x.parse().unwrap_or_else(|e| panic!("{kind} {x}: {e}")))
                    .collect()
            };
            match fields.first() {
                Some(&"v") => {
                    let v = numbers("vertex");
                    obj_positions.push([v[0], v[1], v[2]]);
                }
                Some(&"f") => {
                    let f = numbers("face");
                    obj_triangles.push([f[0] as u32 - 1, f[1] as u32 - 1, f[2] as u32 - 1]);
                }
                _ => {}
            }
        }
        let from_obj = triangle_set(&obj_triangles);

        let bytes = std::fs::read(&ply).unwrap_or_else(|e| panic!("{e}"));
        let end = b"end_header\n";
        let Some(body) = bytes.windows(end.len()).position(|w| w == end) else {
            panic!("no PLY header")
        };
        let header = String::from_utf8_lossy(&bytes[..body]).to_string();
        let count = |prefix: &str| -> usize {
            header
                .lines()
                .find_map(|l| l.strip_prefix(prefix))
                .and_then(|n| n.parse().ok())
                .unwrap_or_else(|| panic!("no {prefix}"))
        };
        let (vertex_count, face_count) = (count("element vertex "), count("element face "));
        let mut at = body + end.len();
        let word = |at: &mut usize| {
            let w = [bytes[*at], bytes[*at + 1], bytes[*at + 2], bytes[*at + 3]];
            *at += 4;
            w
        };
        let ply_positions: Vec<[f64; 3]> = (0..vertex_count)
            .map(|_| [(); 3].map(|_| f64::from(f32::from_le_bytes(word(&mut at)))))
            .collect();
        let mut ply_triangles = Vec::new();
        for _ in 0..face_count {
            assert_eq!(bytes[at], 3);
            at += 1;
            ply_triangles.push([(); 3].map(|_| i32::from_le_bytes(word(&mut at)) as u32));
        }
        assert_eq!(at, bytes.len());
        let from_ply = triangle_set(&ply_triangles);

        assert!(from_view.len() > 50, "{} triangles", from_view.len());
        assert_eq!(from_view, from_obj);
        assert_eq!(from_view, from_ply);
        assert!(same_positions(&view_positions, &obj_positions));
        assert!(same_positions(&view_positions, &ply_positions));
        // Nothing crosses the jump, the hole or the NaN region.
        for t in &from_view {
            let z = t.map(|v| obj_positions[v as usize][2]);
            assert!(
                z.iter().all(|&z| z < 3.5) || z.iter().all(|&z| z > 3.5),
                "{z:?}"
            );
            for v in t {
                let [x, y, z] = obj_positions[*v as usize];
                let (c, r) = (x * 40.0 / z + 6.5, y * 40.0 / z + 5.0);
                let (c, r) = (c.round() as usize, r.round() as usize);
                assert!(*depth.at(c, r) > 0.0, "vertex at ({c}, {r})");
            }
        }
    }
}
