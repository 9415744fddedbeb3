//! Importers read model files and stream triangles into a [`TriangleSink`]; the sink owns the
//! bad-input policy (drop and count, or fail under `--strict`), so every importer applies the
//! same rules and the report adds up: triangles out = triangles in − triangles dropped.

mod forward;
pub mod gltf;
pub mod obj;
pub mod placement;
pub mod ply;
mod sink;
pub mod spill_table;
pub mod stl;

use std::collections::BTreeMap;
use std::fmt;

use serde::Serialize;

pub use crate::mesh::PartDef;
pub use forward::STDIN_NAME;
pub use placement::{PlacementReport, Recentre};
pub use sink::{
    compact_materials, ChunkSchema, Intake, Intaken, MeshSink, MeshStore, Store, MAX_PARTS,
    UNNAMED_PART,
};

use oocfmt::metadata::Material;

/// Where in the input something was found: file, and a line (text formats) or an item path
/// (e.g. `mesh 3 primitive 1 triangle 17`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Location {
    /// The input file, as its path displays (empty where no file applies).
    pub file: String,
    /// The 1-based line, in a text format.
    pub line: Option<u64>,
    /// The path to the element inside the file, in a structured format.
    pub item: Option<String>,
}

impl Location {
    /// The whole of `file`.
    pub fn file(file: impl Into<String>) -> Location {
        Location {
            file: file.into(),
            line: None,
            item: None,
        }
    }

    /// Line `line` (1-based) of `file`.
    pub fn line(file: impl Into<String>, line: u64) -> Location {
        Location {
            file: file.into(),
            line: Some(line),
            item: None,
        }
    }

    /// The element `item` (e.g. `mesh 3 primitive 1`) of `file`.
    pub fn item(file: impl Into<String>, item: impl Into<String>) -> Location {
        Location {
            file: file.into(),
            line: None,
            item: Some(item.into()),
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.file)?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        if let Some(i) = &self.item {
            write!(f, " ({i})")?;
        }
        Ok(())
    }
}

/// One triangle as an importer produces it, in world space. Normals and colours are per
/// corner and present only when the input has them; `material` indexes the materials added
/// to the same sink.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InputTriangle {
    /// The three corners, as placed by [`TriangleSink::place`] (relative to the scene origin).
    pub positions: [[f32; 3]; 3],
    /// The corners' normals, as the input gives them.
    pub normals: Option<[[f32; 3]; 3]>,
    /// The corners' RGBA colours, value / 255.
    pub colours: Option<[[u8; 4]; 3]>,
    /// The index [`TriangleSink::add_material`] returned for the triangle's material.
    pub material: Option<u32>,
    /// The index [`TriangleSink::add_part`] returned for the part (assembly node) the triangle
    /// belongs to; `None`: the part of the file being read, if any.
    pub part: Option<u32>,
    /// The importer's own numbers of the corners' vertices, when it has them: a hint that
    /// spares the in-memory sink a hash lookup for a vertex met before. It never changes
    /// which vertex a corner becomes, and spill files do not keep it.
    pub hint: Option<[u32; 3]>,
}

impl InputTriangle {
    /// A triangle with positions only: no normals, colours, material or hint.
    pub fn new(positions: [[f32; 3]; 3]) -> InputTriangle {
        InputTriangle {
            positions,
            normals: None,
            colours: None,
            material: None,
            part: None,
            hint: None,
        }
    }
}

/// Why a triangle was dropped. Ordered as reported.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DropReason {
    /// A position coordinate is NaN or infinite.
    NonFinite,
    /// A vertex index points outside the vertex data.
    IndexOutOfRange,
    /// Two corners coincide: the triangle has zero area.
    ZeroArea,
    /// Three distinct corners on one line: zero area too, but a different defect in the input.
    Collinear,
}

impl DropReason {
    /// The reason in words, for messages (`--strict` errors, the import report).
    pub fn describe(self) -> &'static str {
        match self {
            DropReason::NonFinite => "a coordinate is NaN or infinite",
            DropReason::IndexOutOfRange => "a vertex index is out of range",
            DropReason::ZeroArea => "two corners coincide (zero area)",
            DropReason::Collinear => "the corners are collinear (zero area)",
        }
    }

    /// The reason a triangle must be dropped for, if any, judged on its positions alone.
    /// Exact arithmetic in f64: the cross product of two f32 edge vectors is exact enough that
    /// only truly degenerate triangles are zero.
    pub fn classify(p: &[[f32; 3]; 3]) -> Option<DropReason> {
        if !p.iter().flatten().all(|c| c.is_finite()) {
            return Some(DropReason::NonFinite);
        }
        if p[0] == p[1] || p[1] == p[2] || p[0] == p[2] {
            return Some(DropReason::ZeroArea);
        }
        if edge_cross(p) == [0.0; 3] {
            return Some(DropReason::Collinear);
        }
        None
    }
}

/// The cross product of a triangle's two edges from its first corner, in f64: twice its area
/// vector. For corners of similar magnitude the f32 edge differences and their products are
/// exact in f64, so only a degenerate triangle gives zero.
pub(crate) fn edge_cross(p: &[[f32; 3]; 3]) -> [f64; 3] {
    let d = |a: [f32; 3], b: [f32; 3]| {
        std::array::from_fn::<f64, 3, _>(|k| f64::from(b[k]) - f64::from(a[k]))
    };
    let (u, v) = (d(p[0], p[1]), d(p[0], p[2]));
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

/// Elements of the input that are not triangles and are skipped on purpose, but counted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Skipped {
    /// Line segments: one per pair of consecutive vertices of an OBJ `l` element, and OBJ
    /// faces of two corners.
    Lines,
    /// Points: one per vertex of an OBJ `p` element, and OBJ faces of one corner.
    Points,
    /// glTF primitives of a mode other than the triangle modes.
    NonTrianglePrimitives,
}

/// What the import saw, for the final report.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ImportReport {
    /// The model files imported, in order, as their paths display (not the `.mtl` or buffer
    /// files they name).
    pub files: Vec<String>,
    /// Triangles offered: kept plus dropped.
    pub triangles_in: u64,
    /// Triangles kept: `triangles_in` − [`ImportReport::dropped_total`].
    pub triangles_out: u64,
    /// Triangles dropped, by reason.
    pub dropped: BTreeMap<DropReason, u64>,
    /// Non-triangle elements skipped, by kind.
    pub skipped: BTreeMap<Skipped, u64>,
    /// Messages that did not stop the import, each prefixed with its [`Location`].
    pub warnings: Vec<String>,
    /// The scene origin and the rounding error of the stored positions.
    pub placement: PlacementReport,
}

impl ImportReport {
    /// Triangles dropped, every reason together.
    pub fn dropped_total(&self) -> u64 {
        self.dropped.values().sum()
    }
}

/// Why an import failed, with where in the input.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// An input file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The failure.
        source: std::io::Error,
    },
    /// The input is not well-formed.
    #[error("{at}: {message}")]
    Parse {
        /// Where.
        at: Location,
        /// What is wrong.
        message: String,
    },
    /// The input is valid but uses something the importer does not read.
    #[error("{at}: unsupported: {what}")]
    Unsupported {
        /// Where.
        at: Location,
        /// What is not supported.
        what: String,
    },
    /// A count or size is past what the importer or the format allows.
    #[error("{at}: {what} exceeds the limit of {limit}")]
    Limit {
        /// Where ([`Location::default`] where no place applies).
        at: Location,
        /// What is counted, e.g. `triangles` or `distinct materials used by triangles`.
        what: String,
        /// The most allowed.
        limit: u64,
    },
    /// A triangle that would be dropped, refused because the import is strict.
    #[error("{at}: triangle refused under --strict: {}", reason.describe())]
    Strict {
        /// Where the triangle is.
        at: Location,
        /// Why it would be dropped.
        reason: DropReason,
    },
    /// No triangle was kept.
    #[error("the input holds no usable triangle ({dropped} dropped)")]
    Empty {
        /// How many triangles were dropped.
        dropped: u64,
    },
    /// The caller asked the import to stop (a sink returns it; Ctrl-C in `oocfmt convert`).
    #[error("{at}: the import was interrupted")]
    Interrupted {
        /// Where the import stood.
        at: Location,
    },
}

/// Opens `path` for a streaming importer: its name as displayed, and a 64 KiB buffered reader.
pub(crate) fn open_buffered(
    path: &std::path::Path,
) -> Result<(String, std::io::BufReader<std::fs::File>), ImportError> {
    let name = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|source| ImportError::Io {
        path: name.clone(),
        source,
    })?;
    Ok((name, std::io::BufReader::with_capacity(1 << 16, file)))
}

/// Starts reading `input` (a whole file, named `name`) into `sink`: records the file and
/// returns its length, the reader back at its start.
pub(crate) fn begin_seekable<R: std::io::Seek>(
    input: &mut R,
    name: &str,
    sink: &mut dyn TriangleSink,
) -> Result<u64, ImportError> {
    sink.begin_file(name);
    let io = |source| ImportError::Io {
        path: name.to_string(),
        source,
    };
    let len = input.seek(std::io::SeekFrom::End(0)).map_err(io)?;
    input.seek(std::io::SeekFrom::Start(0)).map_err(io)?;
    Ok(len)
}

/// Receives an importer's output.
pub trait TriangleSink {
    /// Adds a material; returns the index that triangles give as `material`.
    fn add_material(&mut self, material: Material) -> Result<u32, ImportError>;
    /// Declares a part; returns the index that triangles give as `part` and children as
    /// `parent`. A parent that is not an index returned before is an error.
    fn add_part(&mut self, part: PartDef) -> Result<u32, ImportError>;
    /// One triangle. The sink drops (and counts) or refuses degenerate ones.
    fn push(&mut self, triangle: InputTriangle, at: &Location) -> Result<(), ImportError>;
    /// A triangle the importer could not even form (an index out of range, say).
    fn reject(&mut self, reason: DropReason, at: &Location) -> Result<(), ImportError>;
    /// Elements skipped on purpose.
    fn skip(&mut self, what: Skipped, count: u64);
    /// Something worth telling the user that does not stop the import (a missing .mtl, say).
    fn warn(&mut self, at: &Location, message: String);
    /// Records an input file (for provenance).
    fn begin_file(&mut self, path: &str);
    /// A world position, as exact as the input gives it (f64), to the f32 position stored:
    /// relative to the scene origin, rounded once. Importers call it for every position.
    fn place(&mut self, exact: [f64; 3]) -> [f32; 3];
    /// True when the sink only wants positions placed (the bounds pass of `--recentre auto`):
    /// an importer may then skip faces, materials and other attributes.
    fn positions_only(&self) -> bool {
        false
    }
    /// The importer's own temporary files (vertex tables larger than memory) grew by `bytes`:
    /// a sink that counts disk use charges them, refusing as a full disk would.
    fn charge_disk(&mut self, _bytes: u64) -> std::io::Result<()> {
        Ok(())
    }
    /// The importer's temporary files of `bytes` in all were deleted.
    fn release_disk(&mut self, _bytes: u64) {}
}
