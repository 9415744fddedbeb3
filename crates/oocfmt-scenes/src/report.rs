//! What a generator reports, and how it fails.

use oocfmt_meshio::obj_writer::WriteError;

/// What a generator made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct GenReport {
    pub triangles: u64,
    pub vertices: u64,
    /// Size of the OBJ file (without the `.mtl` beside it).
    pub bytes: u64,
}

#[derive(Debug, thiserror::Error)]
pub enum GenError {
    #[error(transparent)]
    Write(#[from] WriteError),
    #[error("invalid generator option: {0}")]
    Option(String),
    #[error("the model is too large: {0}")]
    TooLarge(String),
}
