//! The tracer's error type: every failure of opening, rendering or writing names the file or
//! the setting at fault.

use std::path::PathBuf;

/// Why a tracer operation failed.
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    /// The container could not be read or failed its checks (the format crate's error).
    #[error(transparent)]
    Format(#[from] oocfmt::Error),
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file the operation was on.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The PNG encoder refused the image or failed to write it.
    #[error("{path}: cannot encode the PNG: {source}")]
    Png {
        /// The PNG file being written.
        path: PathBuf,
        /// The encoder's error.
        source: png::EncodingError,
    },
    /// The camera cannot make rays; the text says why (an empty image, a field of view outside
    /// 0..180 degrees, a non-finite vector, the eye on the look-at point, a degenerate up).
    #[error("camera: {0}")]
    Camera(String),
    /// A render or cache setting is out of range; the text names the setting and its limits.
    #[error("render options: {0}")]
    Options(String),
    /// The file's LOD nodes do not carry the LOD kind asked for.
    #[error("{path}: its LOD nodes carry no {asked} (the file holds {holds}); convert it with --lod {asked} or --lod both")]
    LodKind {
        /// The container's path, as it was opened.
        path: String,
        /// The LOD kind asked for (`voxel` or `rlod`).
        asked: &'static str,
        /// The LOD kinds the file's nodes do carry (`voxel`, `rlod` or `voxel+rlod`).
        holds: &'static str,
    },
    /// A walkthrough camera path file is malformed.
    #[error("{path}: {message}")]
    Path {
        /// The camera path file.
        path: PathBuf,
        /// What is wrong and where in the file (line and column, or camera index).
        message: String,
    },
}

impl TraceError {
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        TraceError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}
