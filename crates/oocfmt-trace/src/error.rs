use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    #[error(transparent)]
    Format(#[from] oocfmt::Error),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: cannot encode the PNG: {source}")]
    Png {
        path: PathBuf,
        source: png::EncodingError,
    },
    #[error("camera: {0}")]
    Camera(String),
    #[error("render options: {0}")]
    Options(String),
    /// The file's LOD nodes do not carry the LOD kind asked for.
    #[error("{path}: its LOD nodes carry no {asked} (the file holds {holds}); convert it with --lod {asked} or --lod both")]
    LodKind {
        path: String,
        asked: &'static str,
        holds: &'static str,
    },
    #[error("{path}: {message}")]
    Path { path: PathBuf, message: String },
}

impl TraceError {
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        TraceError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}
