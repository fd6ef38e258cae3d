//! The mesh renderer's tests: exact depths of planes, a cube and a sphere against
//! ray casting, the rotation convention, invalid inputs, OBJ loading and the
//! shared meshes rendered.

use super::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A fresh file path in the system temp dir.
fn temp_path(stem: &str) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let dir =
        std::env::temp_dir().join(format!("sfs-mesh-test-{}-{nanos}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(format!("{stem}.obj"))
}

fn write_obj(stem: &str, text: &str) -> PathBuf {
    let path = temp_path(stem);
    std::fs::write(&path, text).unwrap();
    path
}

/// Square with corners `(+-0.5, +-0.5, slope * x)`.
fn square(slope: f64) -> TriangleMesh {
    let corners = [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)];
    TriangleMesh {
        positions: corners.iter().map(|&(x, y)| [x, y, slope * x]).collect(),
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

fn cube() -> TriangleMesh {
    let positions = (0..8)
        .map(|k| [0, 1, 2].map(|bit| if k >> bit & 1 == 1 { 0.5 } else { -0.5 }))
        .collect();
    // Faces as quads of corner bits (x = 1, y = 2, z = 4), outward winding.
    let quads: [[u32; 4]; 6] = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    TriangleMesh {
        positions,
        triangles,
    }
}

fn uv_sphere(radius: f64, segments: usize, rings: usize) -> TriangleMesh {
    let mut positions = vec![[0.0, 0.0, radius], [0.0, 0.0, -radius]];
    for ring in 1..rings {
        let theta = std::f64::consts::PI * ring as f64 / rings as f64;
        for seg in 0..segments {
            let phi = 2.0 * std::f64::consts::PI * seg as f64 / segments as f64;
            positions.push([
                radius * theta.sin() * phi.cos(),
                radius * theta.sin() * phi.sin(),
                radius * theta.cos(),
            ]);
        }
    }
    let at = |ring: usize, seg: usize| (2 + (ring - 1) * segments + seg % segments) as u32;
    let mut triangles = Vec::new();
    for seg in 0..segments {
        triangles.push([0, at(1, seg), at(1, seg + 1)]);
        triangles.push([1, at(rings - 1, seg + 1), at(rings - 1, seg)]);
        for ring in 1..rings - 1 {
            triangles.push([at(ring, seg), at(ring + 1, seg), at(ring + 1, seg + 1)]);
            triangles.push([at(ring, seg), at(ring + 1, seg + 1), at(ring, seg + 1)]);
        }
    }
    TriangleMesh {
        positions,
        triangles,
    }
}

/// Rotation about one axis (0 = X, 1 = Y, 2 = Z), right-handed, in degrees.
fn rotate_about(v: [f64; 3], axis: usize, angle_deg: f64) -> [f64; 3] {
    let (s, c) = angle_deg.to_radians().sin_cos();
    let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut out = v;
    out[i] = c * v[i] - s * v[j];
    out[j] = s * v[i] + c * v[j];
    out
}

/// The documented placement, implemented independently for a mesh whose
/// bounding box is already centred with largest side 1.
fn placed(p: [f64; 3], placement: &Placement) -> [f64; 3] {
    let [ax, ay, az] = placement.rotation_deg;
    let mut q = rotate_about(rotate_about(rotate_about(p, 0, ax), 1, ay), 2, az);
    q[2] += placement.distance;
    q
}

/// Every vertex of `mesh` where `placement` puts it.
fn placed_positions(mesh: &TriangleMesh, placement: &Placement) -> Vec<[f64; 3]> {
    mesh.positions
        .iter()
        .map(|&p| placed(p, placement))
        .collect()
}

fn ray(scene: &Scene, column: usize, row: usize) -> DVec3 {
    let (x, y) = scene.camera.image_xy(column as f64, row as f64);
    let f = scene.camera.focal_px;
    DVec3::new(x / f, y / f, 1.0)
}

/// Moller-Trumbore: depth `Z` of the hit and the smallest barycentric.
fn ray_triangle(d: DVec3, triangle: [[f64; 3]; 3]) -> Option<(f64, f64)> {
    let [a, b, c] = triangle.map(DVec3::from_array);
    let e1 = b - a;
    let e2 = c - a;
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-14 {
        return None;
    }
    let t_vec = -a;
    let u = t_vec.dot(p) / det;
    let q = t_vec.cross(e1);
    let v = d.dot(q) / det;
    let t = e2.dot(q) / det;
    let margin = u.min(v).min(1.0 - u - v);
    (margin >= -1e-9 && t > 0.0).then_some((t, margin))
}

#[test]
fn default_rotation_turns_y_up_into_camera_y_down() {
    let r = rotation_matrix(Placement::default().rotation_deg);
    assert_eq!(r * DVec3::new(1.0, 2.0, 3.0), DVec3::new(1.0, -2.0, -3.0));
    let angles = [20.0, -35.0, 110.0];
    let r = rotation_matrix(angles);
    let v = [0.3, -0.7, 0.2];
    let expected = rotate_about(rotate_about(rotate_about(v, 0, 20.0), 1, -35.0), 2, 110.0);
    let got = r * DVec3::from_array(v);
    for axis in 0..3 {
        assert!((got[axis] - expected[axis]).abs() < 1e-15);
    }
}

#[test]
fn fronto_parallel_square_is_exact() {
    let placement = Placement::default();
    let scene = render(&square(0.0), 65, 65, &placement, "square").unwrap();
    let f = scene.camera.focal_px;
    // max |X/Z| = 0.5 / 2; fill * (65 - 1) / 2 = 28.8 px.
    assert!((f - 28.8 / 0.25).abs() < 1e-12);
    let s = scene.intensity_scale;
    assert!((s - 0.9 * 4.0).abs() < 1e-12, "s = {s}");
    assert!((scene.image.at(32, 32) - s / 4.0).abs() < 1e-12);
    let mut covered = 0;
    for row in 0..65 {
        for column in 0..65 {
            let (x, y) = scene.camera.image_xy(column as f64, row as f64);
            let inside = x.abs() <= 28.8 && y.abs() <= 28.8;
            assert_eq!(
                *scene.object_mask.at(column, row),
                inside,
                "({column}, {row})"
            );
            let depth = *scene.depth_gt.at(column, row);
            let intensity = *scene.image.at(column, row);
            if inside {
                covered += 1;
                assert!((depth - 2.0).abs() < 1e-12);
                // Plane facing the camera: I = s Q^3 / z^2, Q = f / |(x, y, f)|.
                let q = f / (x * x + y * y + f * f).sqrt();
                let expected = s * q.powi(3) / 4.0;
                assert!(
                    (intensity - expected).abs() < 1e-12,
                    "{intensity} vs {expected}"
                );
            } else {
                assert!(depth.is_nan());
                assert_eq!(intensity, 0.0);
            }
        }
    }
    assert_eq!(covered, 57 * 57);
}

#[test]
fn tilted_plane_depth_is_the_ray_plane_intersection() {
    // Model plane z = 0.5 x; after the default rotation Z = 2 - 0.5 X.
    let placement = Placement::default();
    let scene = render(&square(0.5), 81, 61, &placement, "tilted").unwrap();
    let s = scene.intensity_scale;
    let mut covered = 0;
    for row in 0..61 {
        for column in 0..81 {
            let d = ray(&scene, column, row);
            let t = 2.0 / (1.0 + 0.5 * d[0]);
            let (x, y) = (d[0] * t, d[1] * t);
            let margin = 0.5 - x.abs().max(y.abs());
            if margin.abs() < 1e-9 {
                continue;
            }
            assert_eq!(*scene.object_mask.at(column, row), margin > 0.0);
            if margin > 0.0 {
                covered += 1;
                let depth = *scene.depth_gt.at(column, row);
                assert!((depth - t).abs() < 1e-9, "{depth} vs {t}");
                let r = t * d.length();
                let expected = s * 2.0 / (1.25f64.sqrt() * r.powi(3));
                let intensity = *scene.image.at(column, row);
                assert!((intensity - expected).abs() < 1e-9 * expected.max(1.0));
            }
        }
    }
    assert!(covered > 1000);
}

#[test]
fn rotated_plane_follows_the_euler_convention() {
    let placement = Placement {
        rotation_deg: [205.0, -30.0, 10.0],
        distance: 3.0,
        ..Placement::default()
    };
    let scene = render(&square(0.0), 70, 50, &placement, "rotated").unwrap();
    let n = placed(
        [0.0, 0.0, 1.0],
        &Placement {
            distance: 0.0,
            ..placement
        },
    );
    let corners = placed_positions(&square(0.0), &placement);
    let mut covered = 0;
    for row in 0..50 {
        for column in 0..70 {
            let d = ray(&scene, column, row);
            let t = 3.0 * n[2] / DVec3::from_array(n).dot(d);
            let hit = [
                [corners[0], corners[1], corners[2]],
                [corners[0], corners[2], corners[3]],
            ]
            .iter()
            .filter_map(|&tri| ray_triangle(d, tri))
            .map(|(_, margin)| margin)
            .fold(f64::NEG_INFINITY, f64::max);
            if hit.abs() < 1e-9 {
                continue;
            }
            assert_eq!(
                *scene.object_mask.at(column, row),
                hit > 0.0,
                "({column}, {row})"
            );
            if hit > 0.0 {
                covered += 1;
                assert!((scene.depth_gt.at(column, row) - t).abs() < 1e-9);
            }
        }
    }
    assert!(covered > 500);
}

#[test]
fn closed_cube_shows_its_front_surface() {
    let placement = Placement {
        rotation_deg: [30.0, 40.0, 15.0],
        ..Placement::default()
    };
    let mesh = cube();
    let scene = render(&mesh, 90, 70, &placement, "cube").unwrap();
    let corners = placed_positions(&mesh, &placement);
    let mut double_hits = 0;
    for row in 0..70 {
        for column in 0..90 {
            let d = ray(&scene, column, row);
            let hits: Vec<(f64, f64)> = mesh
                .triangles
                .iter()
                .filter_map(|t| ray_triangle(d, t.map(|v| corners[v as usize])))
                .collect();
            let nearest = hits.iter().map(|h| h.0).fold(f64::INFINITY, f64::min);
            let farthest = hits.iter().map(|h| h.0).fold(f64::NEG_INFINITY, f64::max);
            let robust = hits.iter().all(|h| h.1 > 1e-9);
            let depth = *scene.depth_gt.at(column, row);
            if hits.is_empty() {
                assert!(!scene.object_mask.at(column, row));
                assert!(depth.is_nan());
            } else if robust {
                assert!(*scene.object_mask.at(column, row));
                assert!((depth - nearest).abs() < 1e-9, "{depth} vs {nearest}");
                if farthest > nearest + 0.1 {
                    double_hits += 1;
                }
            }
        }
    }
    assert!(double_hits > 500);
}

#[test]
fn sphere_depth_is_the_front_hemisphere() {
    let placement = Placement::default();
    let scene = render(&uv_sphere(0.5, 96, 48), 101, 101, &placement, "sphere").unwrap();
    let mut covered = 0;
    for row in 0..101 {
        for column in 0..101 {
            let depth = *scene.depth_gt.at(column, row);
            if !scene.object_mask.at(column, row) {
                continue;
            }
            covered += 1;
            let d = ray(&scene, column, row);
            // |t d - (0, 0, 2)|^2 = 0.25, nearer root.
            let (a, b, c) = (d.length_squared(), -4.0, 4.0 - 0.25);
            let disc = (b * b - 4.0 * a * c).max(0.0);
            let t = (-b - disc.sqrt()) / (2.0 * a);
            // The inscribed polyhedron lies inside the sphere: never nearer
            // than it, and close to it away from the silhouette.
            assert!(depth >= t - 1e-9 && depth < 2.0, "{depth} vs {t}");
            let axis_distance = 2.0 * d.x.hypot(d.y) / d.length();
            if axis_distance < 0.4 {
                assert!(depth - t < 2e-3, "{depth} vs {t}");
            }
            assert!(scene.image.at(column, row).is_finite());
        }
    }
    assert!(covered > 5000);
    // The brightest pixel is near the centre, where the normal faces the light.
    assert!((scene.image.at(50, 50) - 0.9).abs() < 5e-3);
}

#[test]
fn invalid_inputs_are_errors() {
    let mesh = square(0.0);
    let ok = Placement::default();
    assert!(matches!(
        render(&mesh, 1, 10, &ok, "x"),
        Err(MeshError::InvalidInput { .. })
    ));
    for bad in [
        Placement {
            distance: 0.8,
            ..ok
        },
        Placement {
            distance: f64::NAN,
            ..ok
        },
        Placement { fill: 0.0, ..ok },
        Placement { fill: 1.5, ..ok },
        Placement {
            brightest: f64::NAN,
            ..ok
        },
        Placement {
            brightest: 0.0,
            ..ok
        },
        Placement {
            rotation_deg: [f64::INFINITY, 0.0, 0.0],
            ..ok
        },
    ] {
        assert!(matches!(
            render(&mesh, 10, 10, &bad, "x"),
            Err(MeshError::InvalidInput { .. })
        ));
    }
    let bad_index = TriangleMesh {
        triangles: vec![[0, 1, 7]],
        ..mesh.clone()
    };
    assert!(matches!(
        render(&bad_index, 10, 10, &ok, "x"),
        Err(MeshError::InvalidIndex { .. })
    ));
    let empty = TriangleMesh {
        triangles: vec![],
        ..mesh.clone()
    };
    assert!(matches!(
        render(&empty, 10, 10, &ok, "x"),
        Err(MeshError::Empty { .. })
    ));
    let point = TriangleMesh {
        positions: vec![[1.0; 3]; 3],
        triangles: vec![[0, 1, 2]],
    };
    assert!(matches!(
        render(&point, 10, 10, &ok, "x"),
        Err(MeshError::Degenerate { .. })
    ));
    let nan = TriangleMesh {
        positions: vec![[0.0, 0.0, f64::NAN]; 3],
        triangles: vec![[0, 1, 2]],
    };
    assert!(matches!(
        render(&nan, 10, 10, &ok, "x"),
        Err(MeshError::Degenerate { .. })
    ));
    let sliver = TriangleMesh {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.5, 0.0], [0.5, 0.25, 0.0]],
        triangles: vec![[0, 1, 2]],
    };
    assert!(matches!(
        render(&sliver, 10, 10, &ok, "x"),
        Err(MeshError::Misses { .. })
    ));
    // Seen exactly edge-on: the plane contains the optical axis.
    let edge_on = square(0.0);
    let side = Placement {
        rotation_deg: [0.0, 90.0, 0.0],
        ..ok
    };
    assert!(render(&edge_on, 11, 11, &side, "x").is_err());
}

#[test]
fn loads_all_face_index_forms_and_merges_objects() {
    let path = write_obj(
        "forms",
        "mtllib missing.mtl\n\
         v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
         vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n\
         usemtl nothing\n\
         f 1/1/1 2/2/1 3/3/1\n\
         f 1//1 3//1 4//1\n\
         f 1/1 2/2 3/3\n\
         f 1 2 3 4\n\
         l 1 2\n\
         o second\n\
         v 0 0 2\nv 2 0 2\nv 0 2 2\n\
         f 5 6 7\n\
         g group\n\
         f -3/-1 -2/-2 -1/-3\n",
    );
    let mesh = load_obj(&path).unwrap();
    assert_eq!(mesh.triangles.len(), 7);
    let coords = |t: usize| mesh.triangles[t].map(|v| mesh.positions[v as usize]);
    assert_eq!(
        coords(0),
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]
    );
    assert_eq!(
        coords(1),
        [[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]
    );
    let quad: Vec<[[f64; 3]; 3]> = (3..5).map(coords).collect();
    let area: f64 = quad
        .iter()
        .map(|tri| {
            let [a, b, c] = tri.map(DVec3::from_array);
            0.5 * (b - a).cross(c - a).length()
        })
        .sum();
    assert!((area - 1.0).abs() < 1e-12);
    assert_eq!(
        coords(5),
        [[0.0, 0.0, 2.0], [2.0, 0.0, 2.0], [0.0, 2.0, 2.0]]
    );
    assert_eq!(coords(6), coords(5));
    std::fs::remove_dir_all(path.parent().unwrap()).unwrap();
}

#[test]
fn malformed_obj_files_are_errors() {
    let cases = [
        ("letters", "v 1 2 x\nv 0 0 0\nv 1 1 1\nf 1 2 3\n"),
        ("short", "v 1 2\nv 0 0 0\nv 1 1 1\nf 1 2 3\n"),
        ("range", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"),
        ("negative", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -9\n"),
        ("zero", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
        (
            "texcoord",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/-5 2/-5 3/-5\n",
        ),
        (
            "normal",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//4 2//4 3//4\n",
        ),
        ("face", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a\n"),
        ("no-faces", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"),
        ("empty", ""),
        ("infinite", "v 0 0 0\nv 1e50 0 0\nv 0 1 0\nf 1 2 3\n"),
        ("nan", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n"),
        ("flat-point", "v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n"),
    ];
    for (stem, text) in cases {
        let path = write_obj(stem, text);
        let result = load_obj(&path);
        let message = match result {
            Ok(mesh) => panic!("{stem}: loaded {mesh:?}"),
            Err(e) => e.to_string(),
        };
        assert!(
            message.contains(&path.display().to_string()),
            "{stem}: {message}"
        );
        std::fs::remove_dir_all(path.parent().unwrap()).unwrap();
    }
}

#[test]
fn missing_file_error_names_the_path() {
    let path = std::env::temp_dir().join("sfs-mesh-test-does-not-exist/nothing.obj");
    let error = load_obj(&path).unwrap_err();
    assert!(matches!(error, MeshError::Load { .. }));
    assert!(error.to_string().contains(&path.display().to_string()));
}

/// Renders a shared mesh if it is present (skips otherwise).
fn check_real_mesh(stem: &str, width: usize, height: usize) {
    let path = PathBuf::from(format!(
        "{}/../../../shared/meshes/{stem}.obj",
        env!("CARGO_MANIFEST_DIR")
    ));
    if !path.exists() {
        eprintln!("skipping: {} not present", path.display());
        return;
    }
    let mesh = load_obj(&path).unwrap();
    let scene = render(&mesh, width, height, &Placement::default(), stem).unwrap();
    let brightest = scene.image.as_slice().iter().copied().fold(0.0, f64::max);
    assert!((brightest - 0.9).abs() < 1e-9);
    assert!(
        scene
            .image
            .as_slice()
            .iter()
            .all(|v| v.is_finite() && *v >= 0.0)
    );
    let object = scene.object_mask.as_slice().iter().filter(|&&m| m).count();
    assert!(object > 1000, "{stem}: {object} object pixels");
    for ((&m, &z), &i) in scene
        .object_mask
        .as_slice()
        .iter()
        .zip(scene.depth_gt.as_slice())
        .zip(scene.image.as_slice())
    {
        if m {
            assert!(z.is_finite() && z > 2.0 - 0.87 && z < 2.0 + 0.87);
        } else {
            assert!(z.is_nan());
            assert_eq!(i, 0.0);
        }
    }
}

#[test]
fn renders_stanford_bunny() {
    check_real_mesh("stanford-bunny", 256, 256);
}

#[test]
fn renders_suzanne() {
    check_real_mesh("suzanne", 512, 256);
}

#[test]
fn renders_dragon() {
    check_real_mesh("dragon", 256, 256);
}
