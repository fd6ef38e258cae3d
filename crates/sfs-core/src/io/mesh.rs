//! PLY and OBJ meshes of a depth map: [`crate::depth_mesh`]'s triangulation
//! back-projected through the camera, optionally shaded.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::Path;

use super::error::{IoError, write_error};
use super::image::quantise;
use crate::camera::Intrinsics;
use crate::depth_mesh::DepthMesh;
use crate::grid::Grid;
use crate::model::LevelGeometry;

/// Writes a triangle mesh of a depth map as a binary little-endian PLY.
///
/// The mesh is [`DepthMesh::new`]'s, the one the 3-D view draws: every
/// pixel with finite depth `z > 0` becomes the vertex
/// `((i - cx) z / f, (j - cy) z / f, z)` (column `i`, row `j`); triangles
/// join neighbouring pixels but never cross a missing pixel or a depth jump
/// (see [`crate::depth_mesh`]). Triangles wind counter-clockwise as seen
/// from the camera, so their normals `(v1 - v0) x (v2 - v0)` point towards it
/// (negative z for a fronto-parallel plane). With `shade` (same size as
/// `depth`, values in [0, 1], NaN as 0) each vertex gets grey
/// `red`/`green`/`blue` uchar properties.
pub fn write_depth_ply(
    path: &Path,
    depth: &Grid<f64>,
    camera: &Intrinsics,
    shade: Option<&Grid<f64>>,
) -> Result<(), IoError> {
    let (w, h) = depth.size();
    if let Some(s) = shade
        && s.size() != depth.size()
    {
        return Err(write_error(
            path,
            format!(
                "the shading is {}x{} but the depth map is {w}x{h}",
                s.width(),
                s.height()
            ),
        ));
    }
    let mesh = full_resolution_mesh(path, depth, camera)?;

    let err = |e: std::io::Error| write_error(path, e);
    let file = fs::File::create(path).map_err(err)?;
    let mut out = BufWriter::new(file);
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment sfs-studio depth mesh\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        mesh.vertex_count()
    );
    if shade.is_some() {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    header.push_str(&format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.triangles().len()
    ));
    out.write_all(header.as_bytes()).map_err(err)?;
    for (&(i, j), position) in mesh.vertex_pixels().iter().zip(mesh.positions_camera()) {
        for &v in position {
            out.write_all(&(v as f32).to_le_bytes()).map_err(err)?;
        }
        if let Some(s) = shade {
            let g = quantise(*s.at(i, j), 255.0) as u8;
            out.write_all(&[g, g, g]).map_err(err)?;
        }
    }
    for triangle in mesh.triangles() {
        out.write_all(&[3u8]).map_err(err)?;
        for &v in triangle {
            // Fits: the mesh has at most `depth_mesh::MAX_VERTICES` = i32::MAX.
            out.write_all(&(v as i32).to_le_bytes()).map_err(err)?;
        }
    }
    out.flush().map_err(err)
}

/// The mesh of a full-resolution depth map seen through `camera`.
fn full_resolution_mesh(
    path: &Path,
    depth: &Grid<f64>,
    camera: &Intrinsics,
) -> Result<DepthMesh, IoError> {
    let (w, h) = depth.size();
    let geometry = LevelGeometry::new(w, h, w, h, *camera);
    DepthMesh::surface(depth, &geometry).map_err(|e| write_error(path, e))
}

/// Writes the depth map as a Wavefront OBJ triangle mesh (camera
/// coordinates: x right, y down, z forward, in depth units), the same mesh
/// as [`write_depth_ply`].
pub fn write_depth_obj(path: &Path, depth: &Grid<f64>, camera: &Intrinsics) -> Result<(), IoError> {
    let mesh = full_resolution_mesh(path, depth, camera)?;
    let err = |e: std::io::Error| write_error(path, e);
    let file = fs::File::create(path).map_err(err)?;
    let mut out = BufWriter::new(file);
    writeln!(
        out,
        "# sfs-studio depth mesh, camera coordinates (x right, y down, z forward)"
    )
    .map_err(err)?;
    for [px, py, pz] in mesh.positions_camera() {
        writeln!(out, "v {px} {py} {pz}").map_err(err)?;
    }
    for [a, b, c] in mesh.triangles() {
        writeln!(out, "f {} {} {}", a + 1, b + 1, c + 1).map_err(err)?;
    }
    out.flush().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;
    use tempfile::tempdir;

    /// Parses the PLY written by `write_depth_ply`: header lines, vertices
    /// (x, y, z) and faces.
    fn parse_ply(bytes: &[u8], colour: bool) -> (Vec<String>, Vec<[f32; 3]>, Vec<[i32; 3]>) {
        let end = b"end_header\n";
        let pos = bytes.windows(end.len()).position(|w| w == end).unwrap() + end.len();
        let header: Vec<String> = std::str::from_utf8(&bytes[..pos])
            .unwrap()
            .lines()
            .map(String::from)
            .collect();
        let count = |prefix: &str| -> usize {
            header
                .iter()
                .find_map(|l| l.strip_prefix(prefix))
                .unwrap()
                .parse()
                .unwrap()
        };
        let (nv, nf) = (count("element vertex "), count("element face "));
        let stride = if colour { 15 } else { 12 };
        let mut k = pos;
        let f32_at = |k: usize| f32::from_le_bytes(bytes[k..k + 4].try_into().unwrap());
        let mut vertices = Vec::new();
        for _ in 0..nv {
            vertices.push([f32_at(k), f32_at(k + 4), f32_at(k + 8)]);
            k += stride;
        }
        let mut faces = Vec::new();
        for _ in 0..nf {
            assert_eq!(bytes[k], 3);
            let i = |o: usize| i32::from_le_bytes(bytes[k + o..k + o + 4].try_into().unwrap());
            faces.push([i(1), i(5), i(9)]);
            k += 13;
        }
        assert_eq!(k, bytes.len());
        (header, vertices, faces)
    }

    #[test]
    fn ply_of_a_plane_faces_the_camera() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("plane.ply");
        let depth = Grid::filled(3, 3, 2.0);
        let cam = Intrinsics::centred(10.0, 3, 3);
        write_depth_ply(&p, &depth, &cam, Some(&Grid::filled(3, 3, 0.5))).unwrap();
        let (header, v, f) = parse_ply(&fs::read(&p).unwrap(), true);
        assert_eq!(header[0], "ply");
        assert_eq!(header[1], "format binary_little_endian 1.0");
        assert!(header.contains(&"element vertex 9".to_string()));
        assert!(header.contains(&"element face 8".to_string()));
        assert!(header.contains(&"property uchar red".to_string()));
        assert!(header.contains(&"property list uchar int vertex_indices".to_string()));
        assert_eq!(header.last().unwrap(), "end_header");
        assert_eq!((v.len(), f.len()), (9, 8));
        // Pixel (0, 0) is at x = (0 - 1) * 2 / 10.
        assert_eq!(v[0], [-0.2, -0.2, 2.0]);
        for face in &f {
            let [a, b, c] = face.map(|i| v[i as usize]);
            let e1 = [b[0] - a[0], b[1] - a[1]];
            let e2 = [c[0] - a[0], c[1] - a[1]];
            let nz = e1[0] * e2[1] - e1[1] * e2[0];
            assert!(nz < 0.0, "face {face:?} has normal z {nz}");
        }
    }

    #[test]
    fn ply_skips_missing_pixels() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("hole.ply");
        let mut depth = Grid::filled(3, 3, 2.0);
        *depth.at_mut(0, 0) = f64::NAN;
        let cam = Intrinsics::centred(10.0, 3, 3);
        write_depth_ply(&p, &depth, &cam, None).unwrap();
        let (header, v, f) = parse_ply(&fs::read(&p).unwrap(), false);
        assert!(!header.iter().any(|l| l.contains("red")));
        assert_eq!((v.len(), f.len()), (8, 7));
        // With the centre missing too, the top-left block has two valid
        // pixels (no face) and the other three blocks three (one face each).
        *depth.at_mut(1, 1) = 0.0;
        write_depth_ply(&p, &depth, &cam, None).unwrap();
        let (_, v, f) = parse_ply(&fs::read(&p).unwrap(), false);
        assert_eq!((v.len(), f.len()), (7, 3));
        let e = write_depth_ply(&p, &depth, &cam, Some(&Grid::filled(2, 2, 0.0)));
        assert!(e.unwrap_err().to_string().contains("hole.ply"));
    }
}
