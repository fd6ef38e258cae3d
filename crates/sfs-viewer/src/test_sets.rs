//! A small synthetic photometric-stereo set written as files, for the
//! viewer's tests (the library's unit tests and `tests/viewer.rs`, which
//! includes this file by path): the Sombrero, 48x48, under 4 LEDs, each
//! photograph a 16-bit PNG named by its light in a `scene.json`, with
//! `mask.png` beside.

use std::path::{Path, PathBuf};

use sfs_core::camera_file::{CameraFile, LightEntry, write_camera};
use sfs_core::io;
use sfs_core::scene::photometric::{albedo_pattern, led_ring, render_set};
use sfs_core::scene::sombrero::sombrero_lit;

/// The set's side, pixels.
pub const SIDE: usize = 48;
/// Its photographs.
pub const PHOTOS: usize = 4;

/// Writes the set into `dir`; returns the photographs' paths in the
/// order of the camera file's lights. Panics on a write error (tests).
pub fn write_set(dir: &Path) -> Vec<PathBuf> {
    let lights = led_ring(PHOTOS, [0.0, 0.0, 2.0], 1.5, &[10.0, 25.0, 45.0], 1.0);
    let albedo = albedo_pattern(SIDE, SIDE, "patches");
    let set = render_set(
        |l| Ok::<_, ()>(sombrero_lit(SIDE, SIDE, l)),
        &lights,
        &albedo,
        true,
    )
    .unwrap_or_else(|()| panic!("the set renders"));
    let mut paths = Vec::new();
    let mut entries = Vec::new();
    for (k, (image, light)) in set.images.iter().zip(&set.lights).enumerate() {
        let name = format!("led{}.png", k + 1);
        let path = dir.join(&name);
        io::write_png16(&path, image).unwrap_or_else(|e| panic!("{e}"));
        paths.push(path);
        entries.push(LightEntry::of_light(light, Some(k as u32 + 1), Some(name)));
    }
    io::write_mask_png(&dir.join("mask.png"), &set.object_mask).unwrap_or_else(|e| panic!("{e}"));
    let camera = CameraFile {
        name: Some("sombrero set".into()),
        lights: entries,
        ..CameraFile::new(set.camera, SIDE, SIDE)
    };
    write_camera(&dir.join("scene.json"), &camera).unwrap_or_else(|e| panic!("{e}"));
    paths
}
