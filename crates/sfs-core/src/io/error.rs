//! The one error type of file input and output ([`IoError`]), below every
//! format's module so that they share it without importing the folder's
//! module (which re-exports them); re-exported as `io::IoError`.

use std::path::{Path, PathBuf};

use ::image::ImageError;

/// An input/output failure; its message always names the file concerned.
///
/// The cause is part of the message (`Display`), so the variants do not
/// expose it again as an error `source`.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// A file could not be opened or read.
    #[error("cannot read {}: {cause}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        cause: std::io::Error,
    },
    /// An image file could not be opened or read (missing, a folder,
    /// unreadable, truncated, too large for the decoder's limits).
    #[error("cannot read image {}: {cause}", path.display())]
    ReadImage {
        /// The image file.
        path: PathBuf,
        /// What went wrong.
        cause: ImageError,
    },
    /// The file was read but is not an image in a supported format
    /// (PNG, TIFF, JPEG).
    #[error("{} is not an image ({cause})", path.display())]
    NotAnImage {
        /// The file.
        path: PathBuf,
        /// The decoder's complaint.
        cause: ImageError,
    },
    /// The image decoded but its content cannot be used (empty, NaN values).
    #[error("{} is not a usable image: {reason}", path.display())]
    BadImage {
        /// The image file.
        path: PathBuf,
        /// Why it cannot be used.
        reason: String,
    },
    /// An image-like input does not have the size it must have.
    #[error(
        "{} is {}x{} but the image is {}x{}",
        path.display(), found.0, found.1, expected.0, expected.1
    )]
    SizeMismatch {
        /// The file whose size is wrong.
        path: PathBuf,
        /// Its `(width, height)`.
        found: (usize, usize),
        /// The `(width, height)` it must have.
        expected: (usize, usize),
    },
    /// A `.npy` file is malformed or does not hold a 2-D numeric array.
    #[error("{} is not a usable .npy array: {reason}", path.display())]
    Npy {
        /// The `.npy` file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The camera/scene file is malformed, has missing or unknown keys, or
    /// holds invalid values.
    #[error("camera file {}: {reason}", path.display())]
    Camera {
        /// The camera file.
        path: PathBuf,
        /// What is wrong with it (names the key concerned).
        reason: String,
    },
    /// A file could not be written.
    #[error("cannot write {}: {cause}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        cause: Box<dyn std::error::Error + Send + Sync>,
    },
    /// An output folder could not be created.
    #[error("cannot create folder {}: {cause}", path.display())]
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// What went wrong.
        cause: std::io::Error,
    },
    /// A staged output could not be moved to its final name.
    #[error("cannot move {} to {}: {cause}", from.display(), to.display())]
    Rename {
        /// The temporary file.
        from: PathBuf,
        /// The final name.
        to: PathBuf,
        /// What went wrong.
        cause: std::io::Error,
    },
    /// Another run holds the output folder's lock.
    #[error(
        "{} is being written by another sfs-studio run; wait for it to finish or choose another output folder",
        path.display()
    )]
    Busy {
        /// The output folder.
        path: PathBuf,
    },
}

pub(super) fn write_error(
    path: &Path,
    cause: impl Into<Box<dyn std::error::Error + Send + Sync>>,
) -> IoError {
    IoError::Write {
        path: path.to_path_buf(),
        cause: cause.into(),
    }
}
