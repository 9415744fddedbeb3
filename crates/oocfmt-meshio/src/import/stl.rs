//! The STL importer, ASCII and binary.
//!
//! The kind is told from the content, not from the 80-byte header (binary files often start
//! with `solid` too): a file is binary exactly when its size is 84 + 50 × the facet count at
//! byte 80, else it must parse as ASCII (`solid` … `endsolid`), else the error says why it is
//! neither. Both are streamed facet by facet; nothing grows with the file.
//!
//! - **Parts.** Each `solid` of an ASCII file with several becomes a part, named by its name or
//!   `solid N` (1-based) when unnamed; a lone solid is a part only when it is named, so its name
//!   survives. Telling whether an unnamed first solid is alone takes a quick scan ahead for
//!   another `solid` line. Binary files have no parts.
//! - **Normals.** Facet normals are not stored (they are face normals; the sink takes vertex
//!   normals). Each stored normal that is finite, not zero and points against the winding's
//!   normal (negative dot product) is counted, and one warning per file gives the count: the
//!   winding wins, as in every CAD reader.
//! - **Colours** (binary only; [`StlOptions::colours`]). With `COLOR=` and four bytes R, G, B,
//!   A in the header, the Materialise Magics convention: that is the default colour, and a
//!   facet whose attribute word has bit 15 clear has its own colour, red in bits 0–4, green
//!   5–9, blue 10–14. Otherwise the VisCAM/SolidView convention: bit 15 set marks a valid
//!   colour, blue in bits 0–4, green 5–9, red 10–14 (the bit order of VisCAM's own
//!   description; the two conventions are mirror images). Five bits become eight by
//!   repeating the top bits (31 → 255). Facets without a colour in a file where some have one
//!   are white. Any other use of the attribute word is ignored.
//! - **Polygons.** ASCII loops of more than three vertices (written by a few exporters) are
//!   triangulated like OBJ polygons.
//!
//! Positions are read as f64 and stored through [`TriangleSink::place`]; degenerate facets
//! are the sink's to drop and count.

mod ascii;
mod binary;
mod colour;
mod facet;
pub(in crate::import) mod lines;

use std::io::{BufRead, Seek, SeekFrom};
use std::path::Path;

use super::{ImportError, TriangleSink};

/// Bounds and choices of the STL importer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StlOptions {
    /// Longest line of an ASCII file, in bytes (line ending not counted).
    pub max_line_bytes: usize,
    /// Most vertices in one ASCII `outer loop`.
    pub max_loop_vertices: usize,
    /// Read facet colours from binary attribute words (the conventions in the module
    /// documentation); off, the attribute words are ignored.
    pub colours: bool,
}

impl Default for StlOptions {
    fn default() -> StlOptions {
        StlOptions {
            max_line_bytes: 1 << 20,
            max_loop_vertices: 1 << 16,
            colours: true,
        }
    }
}

/// The bytes before the first facet of a binary STL: header and facet count.
const BINARY_HEAD: u64 = 84;
/// The bytes of one binary facet: normal, three corners, attribute word.
const BINARY_FACET: u64 = 50;

/// Reads the STL file at `path` into `sink`.
pub fn import(
    path: &Path,
    sink: &mut dyn TriangleSink,
    opts: &StlOptions,
) -> Result<(), ImportError> {
    let (name, input) = super::open_buffered(path)?;
    import_from(input, &name, sink, opts)
}

/// Reads an STL file from `input` (at its start), reporting places in it as `name`: what
/// [`import`] does once the file is open, for input that is not a file (the fuzz targets).
pub fn import_from<R: BufRead + Seek>(
    mut input: R,
    name: &str,
    sink: &mut dyn TriangleSink,
    opts: &StlOptions,
) -> Result<(), ImportError> {
    let len = super::begin_seekable(&mut input, name, sink)?;
    let io = |source| ImportError::Io {
        path: name.to_string(),
        source,
    };
    let mut head = [0u8; BINARY_HEAD as usize];
    if len < BINARY_HEAD {
        let note = format!(
            "it is too short for binary STL ({len} bytes, under the {BINARY_HEAD} of the header \
             and facet count)"
        );
        return ascii::read(input, name, sink, opts, &note);
    }
    input.read_exact(&mut head).map_err(io)?;
    let (header, count) = head.split_at(80);
    let count = u32::from_le_bytes(count.try_into().unwrap_or_default());
    let expected = BINARY_HEAD + BINARY_FACET * u64::from(count);
    if len == expected {
        let header: [u8; 80] = header.try_into().unwrap_or([0; 80]);
        return binary::read(input, name, &header, count, sink, opts);
    }
    input.seek(SeekFrom::Start(0)).map_err(io)?;
    let note = format!(
        "as binary STL its header declares {count} facets, which take 84 + 50 × {count} = \
         {expected} bytes, but the file has {len} bytes"
    );
    ascii::read(input, name, sink, opts, &note)
}
