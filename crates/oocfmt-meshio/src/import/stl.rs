//! The STL importer, ASCII and binary.
//!
//! The kind is told from the content, not from the 80-byte header (binary files often start
//! with `solid` too): a file is binary exactly when its size is 84 + 50 × the facet count at
//! byte 80, else it must parse as ASCII (`solid` … `endsolid`), else the error says why it is
//! neither. Both are streamed facet by facet; nothing grows with the file.
//!
//! A stream (standard input, [`import_stream`]) has no size to tell by, so its first 84 bytes
//! decide: it is ASCII when there are fewer (too short for binary) or when they start with
//! `solid` (any case, after optional whitespace) and hold no control byte other than tab, CR
//! and LF; else binary, read for exactly the facet count at byte 80. A binary header is padded
//! with NUL bytes, and the count of any model under 2^29 (536 870 912) facets has a byte
//! under 0x20, so only a binary file with a text-only header starting with `solid` and at
//! least that many facets is taken for ASCII (and then fails saying why it is neither). Bytes
//! after the declared facets are warned about, not read.
//!
//! - **Parts.** Each `solid` of an ASCII file with several becomes a part, named by its name or
//!   `solid N` (1-based) when unnamed; a lone solid is a part only when it is named, so its name
//!   survives. Telling whether an unnamed first solid is alone takes a quick scan ahead for
//!   another `solid` line; a stream cannot be scanned ahead, so there an unnamed first solid
//!   is never a part (its facets belong to the input as a whole). Binary files have no parts.
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
#[cfg(test)]
mod stream_tests;

use std::io::{BufRead, Cursor, Read, Seek, SeekFrom};
use std::path::Path;

use super::forward::Forward;
use super::{ImportError, Location, TriangleSink};

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
        return ascii::read(input, name, sink, opts, &note, true);
    }
    input.read_exact(&mut head).map_err(io)?;
    let (header, count) = split_head(&head);
    let expected = BINARY_HEAD + BINARY_FACET * u64::from(count);
    if len == expected {
        let short = "it changed while being read?";
        return binary::read(input, name, &header, count, sink, opts, short);
    }
    input.seek(SeekFrom::Start(0)).map_err(io)?;
    let note = format!(
        "as binary STL its header declares {count} facets, which take 84 + 50 × {count} = \
         {expected} bytes, but the file has {len} bytes"
    );
    ascii::read(input, name, sink, opts, &note, true)
}

/// Reads an STL stream (standard input, a pipe: no size, no seeking) from `input` into
/// `sink`, reporting places in it as `name`; binary or ASCII by its first bytes (the module
/// documentation gives the rule).
pub fn import_stream<R: BufRead>(
    input: R,
    name: &str,
    sink: &mut dyn TriangleSink,
    opts: &StlOptions,
) -> Result<(), ImportError> {
    sink.begin_file(name);
    let io = |source| ImportError::Io {
        path: name.to_string(),
        source,
    };
    let mut input = Forward::new(input);
    let mut head = Vec::with_capacity(BINARY_HEAD as usize);
    (&mut input)
        .take(BINARY_HEAD)
        .read_to_end(&mut head)
        .map_err(io)?;
    if let Some(note) = ascii_stream_note(&head) {
        let whole = Forward::new(Cursor::new(head).chain(input));
        return ascii::read(whole, name, sink, opts, &note, false);
    }
    let (header, count) = split_head(&head);
    let short = "the stream ends before the facets its header declares";
    binary::read(&mut input, name, &header, count, sink, opts, short)?;
    if !input.at_end().map_err(io)? {
        let end = BINARY_HEAD + BINARY_FACET * u64::from(count);
        sink.warn(
            &Location::item(name, format!("byte {end}")),
            format!(
                "the stream goes on after the {count} facets its header declares; the rest was \
                 not read"
            ),
        );
    }
    Ok(())
}

/// The 80-byte header and the facet count of a binary STL's first 84 bytes.
fn split_head(head: &[u8]) -> ([u8; 80], u32) {
    let (header, count) = head.split_at(head.len().min(80));
    (
        header.try_into().unwrap_or([0; 80]),
        u32::from_le_bytes(count.try_into().unwrap_or_default()),
    )
}

/// Why a stream whose first bytes are `head` (up to 84) is read as ASCII, or `None` when it
/// is read as binary.
fn ascii_stream_note(head: &[u8]) -> Option<String> {
    if head.len() < BINARY_HEAD as usize {
        return Some(format!(
            "it is too short for binary STL ({} bytes, under the {BINARY_HEAD} of the header and \
             facet count)",
            head.len()
        ));
    }
    let text = head
        .iter()
        .all(|&b| (b >= 0x20 && b != 0x7f) || matches!(b, b'\t' | b'\r' | b'\n'));
    let start = head.trim_ascii_start();
    let solid = start
        .get(..5)
        .is_some_and(|w| w.eq_ignore_ascii_case(b"solid"))
        && start.get(5).is_none_or(u8::is_ascii_whitespace);
    (text && solid).then(|| {
        "its first 84 bytes start with `solid` and are all text, which a binary header and \
         facet count (of under 2^29 facets) never are"
            .to_string()
    })
}
