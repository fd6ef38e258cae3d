//! Reading and writing the files sfs-studio works with, one module per
//! format: [`image`] (grey images and masks: PNG, TIFF with integer or float
//! samples, JPEG), [`npy`] (NumPy arrays), [`mesh`] (PLY and OBJ meshes of a
//! depth map), [`json`] (any serde value), [`atomic`] (a file replaced
//! all at once) and [`ground_truth`] (a `synth` folder's truth). The camera file is [`crate::camera_file`]'s.
//!
//! Every error names the file (or folder) it concerns.

pub mod atomic;
mod error;
pub mod ground_truth;
pub mod image;
pub mod json;
pub mod mesh;
pub mod npy;

pub use self::image::{
    DecodedPhoto, FloatSamples, SrgbMode, depth_range, exif_orientation, image_size, photo_size,
    read_image, read_mask, read_photo, srgb_decision, write_depth_png16, write_mask_png,
    write_png8, write_png16, write_rgb_png8,
};
pub use atomic::write_atomic;
pub use error::IoError;
pub use json::write_json;
pub use mesh::{write_depth_obj, write_depth_ply};
pub use npy::{read_npy, read_npy_vec3, write_npy_f32, write_npy_f32_vec3, write_npy_f64};
