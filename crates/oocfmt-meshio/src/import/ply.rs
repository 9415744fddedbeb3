//! The PLY importer: `ascii`, `binary_little_endian` and `binary_big_endian`, elements in any
//! order, properties of any scalar type (`char` … `double` and the `int8` … `float64` names).
//!
//! - **Vertices** (`vertex`): `x`, `y`, `z`, optionally `nx`, `ny`, `nz` and `red`, `green`,
//!   `blue` with optional `alpha` (or their `diffuse_` names). Colours of an integer type are
//!   0..255, of a float type 0..1; either is clamped.
//! - **Faces** (`face`): the list `vertex_indices` (or `vertex_index`), any count and index
//!   type, triangulated like OBJ polygons (ear clipping, the same degenerate handling); faces
//!   of one or two corners are counted as points and lines, an index out of range rejects
//!   the face's triangles. `tristrips` with `-1` restarts are read too (a strip's part and
//!   material are the ones its record gives before the list).
//! - **Parts**: an integer property `part` (or `part_id`) on faces. Its ids are named by
//!   header comments `comment part <id> <parent id or -1> <name>` (as `oocfmt export` writes
//!   them, the name escaped as in its OBJ part table; a parent must have a smaller id), else
//!   `part <id>`. **Materials**: `material_index`
//!   on faces, named by `comment material <index> <name> <r> <g> <b>`. A file written with
//!   `comment positions are relative to the scene origin <x> <y> <z>` has that origin added
//!   back. Every other element, property and comment is stepped over.
//!
//! It streams: only the vertex table is held (its count checked against the file's size
//! before it is reserved), faces go to the sink as they are read. Faces stored before the
//! vertices are read in a second pass over the file. Every element count and list length is
//! checked against the bytes left in the file before anything is reserved or skipped for it.
//!
//! A stream (standard input, [`import_stream`]) has no size to check against: counts are then
//! held to the limits of [`PlyOptions`] alone, the vertex table grows as it is read instead of
//! being reserved, and faces stored before the vertices are refused (no second pass).

mod body;
mod faces;
mod header;
mod scalar;
#[cfg(test)]
mod stream_tests;
mod vertices;

use std::io::{BufRead, Seek};
use std::path::Path;

use body::{Ascii, Binary, Body};
use faces::{FacePlan, Faces};
use header::{Encoding, Header};
use vertices::{Table, VertexPlan};

use super::forward::Forward;
use super::spill_table::VertexSpill;
use super::stl::lines::Lines;
use super::{ImportError, Location, TriangleSink};

/// Bounds on what one file can make the importer hold or do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlyOptions {
    /// Longest line of the header or of an ASCII body, in bytes.
    pub max_line_bytes: usize,
    /// Largest header, in bytes.
    pub max_header_bytes: u64,
    /// Most vertices held in memory.
    pub max_vertices: u64,
    /// Where vertex attributes beyond a memory budget go, and the bound on vertices then;
    /// `None`: all in memory, at most `max_vertices`.
    pub spill: Option<VertexSpill>,
    /// Most corners of one face.
    pub max_face_corners: usize,
}

impl Default for PlyOptions {
    fn default() -> PlyOptions {
        PlyOptions {
            max_line_bytes: 1 << 20,
            max_header_bytes: 64 << 20,
            // As for OBJ: 3 GiB of positions.
            max_vertices: 1 << 28,
            spill: None,
            max_face_corners: 1 << 16,
        }
    }
}

impl PlyOptions {
    /// The bound on vertices: in memory, or with a spill.
    pub fn vertex_bound(&self) -> u64 {
        self.spill
            .as_ref()
            .map_or(self.max_vertices, |s| s.max_vertices as u64)
    }
}

/// Reads the PLY file at `path` into `sink`.
pub fn import(
    path: &Path,
    sink: &mut dyn TriangleSink,
    opts: &PlyOptions,
) -> Result<(), ImportError> {
    let (name, input) = super::open_buffered(path)?;
    import_from(input, &name, sink, opts)
}

/// Reads a PLY file from `input` (at its start), reporting places in it as `name`: what
/// [`import`] does once the file is open, for input that is not a file (the fuzz targets).
pub fn import_from<R: BufRead + Seek>(
    mut input: R,
    name: &str,
    sink: &mut dyn TriangleSink,
    opts: &PlyOptions,
) -> Result<(), ImportError> {
    let len = super::begin_seekable(&mut input, name, sink)?;
    read(input, name, Some(len), sink, opts)
}

/// Reads a PLY stream (standard input, a pipe: no size, no seeking) from `input` into `sink`,
/// reporting places in it as `name`. Without a size, counts are held only to
/// [`PlyOptions::vertex_bound`] and the vertex table grows as it is read; faces stored before
/// the vertices, which need a second pass, are refused.
pub fn import_stream<R: BufRead>(
    input: R,
    name: &str,
    sink: &mut dyn TriangleSink,
    opts: &PlyOptions,
) -> Result<(), ImportError> {
    sink.begin_file(name);
    read(Forward::new(input), name, None, sink, opts)
}

/// Reads `input` (at its start), a file of `len` bytes or a stream (`None`), into `sink`.
fn read<R: BufRead + Seek>(
    input: R,
    name: &str,
    len: Option<u64>,
    sink: &mut dyn TriangleSink,
    opts: &PlyOptions,
) -> Result<(), ImportError> {
    let mut lines = Lines::new(input, opts.max_line_bytes, 0, 0);
    let mut header = header::read(&mut lines, name, opts)?;
    let start = lines.offset();
    let body_bytes = len.map(|l| l.saturating_sub(start));
    check_sizes(&header, body_bytes, name, opts)?;
    for (line, text) in std::mem::take(&mut header.bad_comments) {
        sink.warn(
            &Location::line(name, line),
            format!("comment `{text}` looks like an oocfmt comment but does not parse; ignored"),
        );
    }
    let plan = Plan::new(&header, name, sink)?;
    if len.is_none() && !sink.positions_only() {
        plan.check_one_pass(&header, name)?;
    }
    match header.encoding {
        Encoding::Ascii => {
            let body = Ascii::new(lines, name, len, opts.max_line_bytes);
            plan.run(body, header, name, sink, opts)
        }
        Encoding::Binary(big_endian) => {
            let body = Binary::new(lines.into_inner(), name, start, len, big_endian);
            plan.run(body, header, name, sink, opts)
        }
    }
}

/// Refuses counts the file cannot hold: every element's records take at least
/// [`header::Element::min_record_bytes`] each, so the sum cannot pass the `body_bytes` after
/// the header (unknown for a stream). The vertex count is also held to
/// [`PlyOptions::vertex_bound`].
fn check_sizes(
    header: &Header,
    body_bytes: Option<u64>,
    file: &str,
    opts: &PlyOptions,
) -> Result<(), ImportError> {
    // An ASCII file's last value needs no separator.
    let slack = u128::from(header.encoding == Encoding::Ascii);
    let mut need = 0u128;
    for e in &header.elements {
        let min = e.min_record_bytes(header.encoding);
        need += u128::from(e.count) * u128::from(min);
        if let Some(body_bytes) = body_bytes.filter(|&b| need > u128::from(b) + slack) {
            return Err(ImportError::Parse {
                at: Location::line(file, e.line),
                message: format!(
                    "element `{}` declares {} records of at least {min} bytes each, more than the \
                     {body_bytes} bytes after the header hold (with the elements before it)",
                    e.name, e.count
                ),
            });
        }
        if e.name == "vertex" && e.count > opts.vertex_bound() {
            return Err(ImportError::Limit {
                at: Location::line(file, e.line),
                what: "vertices".into(),
                limit: opts.vertex_bound(),
            });
        }
    }
    Ok(())
}

/// What to do with each element.
struct Plan {
    /// The vertex element (the first one named `vertex`) and how to read it.
    vertex: Option<(usize, VertexPlan)>,
    /// Per element: how to read it when it holds faces.
    faces: Vec<Option<FacePlan>>,
}

impl Plan {
    fn new(header: &Header, file: &str, sink: &mut dyn TriangleSink) -> Result<Plan, ImportError> {
        let mut vertex = None;
        let mut faces = Vec::with_capacity(header.elements.len());
        for (i, e) in header.elements.iter().enumerate() {
            let at = Location::line(file, e.line);
            if e.name == "vertex" {
                if vertex.is_none() {
                    vertex = Some((i, VertexPlan::new(e, file)?));
                } else {
                    sink.warn(&at, "a second `vertex` element was skipped".into());
                }
            }
            faces.push(match FacePlan::new(e) {
                Ok(plan) => plan,
                Err(why) => {
                    sink.warn(&at, format!("{why}: skipped"));
                    None
                }
            });
        }
        let any_faces = faces.iter().any(Option::is_some);
        match &vertex {
            None if any_faces => {
                return Err(ImportError::Parse {
                    at: Location::file(file),
                    message: "the file has faces but no `vertex` element".into(),
                })
            }
            Some((i, _)) if !any_faces => {
                let count = header.elements.get(*i).map_or(0, |e| e.count);
                sink.warn(
                    &Location::file(file),
                    format!(
                        "no `face` or `tristrips` element: the {count} vertices (a point cloud?) \
                         make no triangles"
                    ),
                );
            }
            _ => {}
        }
        Ok(Plan { vertex, faces })
    }

    /// Refuses faces stored before the vertices: reading them takes a second pass, which a
    /// stream cannot give.
    fn check_one_pass(&self, header: &Header, file: &str) -> Result<(), ImportError> {
        let first_vertex = self.vertex.as_ref().map_or(usize::MAX, |(v, _)| *v);
        let early = self
            .faces
            .iter()
            .take(first_vertex)
            .position(Option::is_some);
        match early.and_then(|i| header.elements.get(i)) {
            Some(e) => Err(ImportError::Unsupported {
                at: Location::line(file, e.line),
                what: format!(
                    "element `{}` comes before the vertices, which takes a second pass over the \
                     input, and a stream can be read only once: save it to a file first",
                    e.name
                ),
            }),
            None => Ok(()),
        }
    }

    /// Reads the body: vertices and the faces after them in one pass; faces stored before the
    /// vertices in a second.
    fn run<B: Body>(
        &self,
        mut body: B,
        header: Header,
        file: &str,
        sink: &mut dyn TriangleSink,
        opts: &PlyOptions,
    ) -> Result<(), ImportError> {
        let origin = header.origin.unwrap_or_default();
        let keep = !sink.positions_only();
        let mut faces = Faces::new(file, opts.max_face_corners, header.parts, header.materials);
        let mut table: Option<Table> = None;
        let mut deferred = Vec::new();
        for (i, e) in header.elements.iter().enumerate() {
            body.enter(e);
            if let Some((_, plan)) = self.vertex.as_ref().filter(|(v, _)| *v == i) {
                let spill = opts.spill.as_ref().map(|s| &s.to);
                table = Some(vertices::read(
                    &mut body, e, plan, origin, sink, keep, spill,
                )?);
                continue;
            }
            match (self.faces.get(i).and_then(Option::as_ref), &mut table) {
                (Some(plan), Some(t)) if keep => faces.read(&mut body, e, plan, t, sink)?,
                (Some(_), None) if keep => {
                    deferred.push(i);
                    body.skip_element(e)?;
                }
                _ => body.skip_element(e)?,
            }
        }
        body.end(sink);
        if let (Some(&last), Some(t)) = (deferred.last(), &mut table) {
            body.rewind()?;
            for (i, e) in header.elements.iter().enumerate().take(last + 1) {
                body.enter(e);
                match self.faces.get(i).and_then(Option::as_ref) {
                    Some(plan) if deferred.contains(&i) => {
                        faces.read(&mut body, e, plan, t, sink)?
                    }
                    _ => body.skip_element(e)?,
                }
            }
        }
        faces.finish(sink);
        if let Some(t) = table.as_mut() {
            t.release(sink);
        }
        Ok(())
    }
}
