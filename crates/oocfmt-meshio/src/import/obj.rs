//! The Wavefront OBJ importer.
//!
//! It streams: the file is read line by line and each face goes to the sink as it is read, so
//! only the vertex attributes (positions, normals, colours) stay in memory, never the faces.
//! That is why it is not built on tobj, which holds whole files, fans concave polygons,
//! cannot count lines and points, and panics on some malformed material libraries; tobj
//! remains the reference our tests compare against.
//!
//! Faces may only use vertices defined above them (what every exporter writes; tobj also
//! accepts later ones). An index that does not resolve, zero included, makes the face's
//! triangles rejected as [`DropReason::IndexOutOfRange`], not the file. Texture coordinates
//! are ignored, and so is the `w` of `v x y z w`, which only weighs rational curves.
//!
//! Positions are read as f64 and stored through [`TriangleSink::place`], which subtracts the
//! scene origin before rounding to f32 (see the parser's `coordinate` for why that is still
//! bit-exact without an origin).
//!
//! Input may be a pipe ([`import_from`]): one forward pass reads it all. Material libraries
//! are then looked up in the folder the caller names; for standard input that is the current
//! folder, so `mtllib scene.mtl` finds the `scene.mtl` a shell user sees beside them.
//!
//! Objects and groups become parts: `o NAME` a top-level part, `g NAME…` a part under the
//! current object (the names of `g a b` joined by a space, `g` alone `default`), a name met
//! again under the same parent continuing its part (`obj/parts.rs`). A file `oocfmt export`
//! wrote carries its exact part table in comments instead, which then decides:
//!
//! ```text
//! # oocfmt parts 3            the table follows: 3 parts
//! # part 0 -1 engine          part 0, top level (parent -1), named "engine"
//! # part 1 0 turbine blade    part 1 under part 0
//! # part 2 0 50%25 scale      `%`, `\`, control characters and surrounding whitespace
//! …                           are written %XX (per UTF-8 byte), so any name fits a line
//! # part 1                    the faces below belong to part 1
//! g engine/turbine blade      (for other readers; ignored once a table was read)
//! ```

mod lines;
mod materials;
mod mtl;
mod notes;
pub(crate) mod part_table;
mod parts;
pub(in crate::import) mod polygon;

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::num::IntErrorKind;
use std::path::{Path, PathBuf};
use std::str::SplitWhitespace;

use lines::{LineError, LineFailure, Lines};
use materials::Materials;
use notes::{Kind, Notes};
use parts::Parts;
use polygon::{Outcome, Triangulator};

use super::spill_table::{SpillTable, VertexSpill};
use super::{DropReason, ImportError, InputTriangle, Location, Skipped, TriangleSink};

/// Bounds on what one file can make the importer hold or do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ObjOptions {
    /// Longest logical line, in bytes (continuations joined, line ending not counted).
    pub max_line_bytes: usize,
    /// Most vertex positions (`v`) held in memory; the same bound applies to normals (`vn`).
    pub max_vertices: usize,
    /// Where vertex attributes beyond a memory budget go, and the bound on vertices then;
    /// `None`: all in memory, at most `max_vertices`.
    pub spill: Option<VertexSpill>,
    /// Most corners of one face.
    pub max_face_corners: usize,
    /// Largest material library read, in bytes.
    pub max_mtl_bytes: u64,
}

impl Default for ObjOptions {
    fn default() -> ObjOptions {
        ObjOptions {
            max_line_bytes: 1 << 20,
            // 3 GiB of positions: beyond any model that reasonably comes as one OBJ file.
            max_vertices: 1 << 28,
            max_face_corners: 1 << 16,
            max_mtl_bytes: 64 << 20,
            spill: None,
        }
    }
}

/// Reads the OBJ file at `path` (and the material libraries it names) into `sink`.
pub fn import(
    path: &Path,
    sink: &mut dyn TriangleSink,
    opts: &ObjOptions,
) -> Result<(), ImportError> {
    let name = path.display().to_string();
    let file = File::open(path).map_err(|source| ImportError::Io {
        path: name.clone(),
        source,
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let input = BufReader::with_capacity(1 << 16, file);
    import_from(input, &name, dir, sink, opts)
}

/// Reads OBJ text from `input` into `sink`, reporting places in it as `name`; `mtllib` names
/// are looked up in `dir` (and may not leave it). OBJ is read in one forward pass, so `input`
/// may be a pipe: standard input passes [`super::STDIN_NAME`] and the current folder.
pub fn import_from<R: BufRead>(
    input: R,
    name: &str,
    dir: &Path,
    sink: &mut dyn TriangleSink,
    opts: &ObjOptions,
) -> Result<(), ImportError> {
    sink.begin_file(name);
    let mut lines = Lines::new(input, opts.max_line_bytes);
    let mut obj = Obj::new(name.to_string(), dir.to_path_buf(), opts);
    obj.positions_only = sink.positions_only();
    loop {
        let line = lines.next_with_comment().map_err(|f| obj.line_error(f))?;
        let Some((n, text, comment)) = line else {
            break;
        };
        if text.is_empty() && !comment.is_empty() && !obj.positions_only {
            obj.at.line = Some(n);
            obj.parts.comment(comment, &obj.at, sink)?;
        } else {
            obj.statement(n, text, sink)?;
        }
    }
    obj.finish(sink)
}

/// One corner of a face: its vertex, and its normal if it names one.
#[derive(Clone, Copy)]
struct Corner {
    vertex: usize,
    normal: Option<usize>,
}

struct Obj<'o> {
    opts: &'o ObjOptions,
    /// The place of the statement being read; faces report with it.
    at: Location,
    positions: SpillTable<[f32; 3]>,
    normals: SpillTable<[f32; 3]>,
    /// Per vertex; empty until the first coloured vertex, so colourless files pay nothing.
    colours: SpillTable<Option<[u8; 4]>>,
    /// The bytes of the tables' files the sink was charged for.
    charged: u64,
    corners: Vec<Corner>,
    polygon: Vec<[f32; 3]>,
    triangulator: Triangulator,
    materials: Materials,
    parts: Parts,
    notes: Notes,
    lines: u64,
    points: u64,
    /// The sink wants positions only (a bounds pass): every other statement is skipped.
    positions_only: bool,
}

impl<'o> Obj<'o> {
    fn new(file: String, dir: PathBuf, opts: &'o ObjOptions) -> Obj<'o> {
        Obj {
            opts,
            at: Location::file(file),
            positions: SpillTable::new(opts.spill.as_ref().map(|s| s.to.clone())),
            normals: SpillTable::new(opts.spill.as_ref().map(|s| s.to.clone())),
            colours: SpillTable::new(opts.spill.as_ref().map(|s| s.to.clone())),
            charged: 0,
            corners: Vec::new(),
            polygon: Vec::new(),
            triangulator: Triangulator::default(),
            materials: Materials::new(dir),
            parts: Parts::default(),
            notes: Notes::default(),
            lines: 0,
            points: 0,
            positions_only: false,
        }
    }

    fn parse_error(&self, message: String) -> ImportError {
        ImportError::Parse {
            at: self.at.clone(),
            message,
        }
    }

    fn line_error(&self, f: LineFailure) -> ImportError {
        match f.error {
            LineError::Io(source) => ImportError::Io {
                path: format!("{}:{}", self.at.file, f.line),
                source,
            },
            LineError::TooLong => ImportError::Limit {
                at: Location::line(self.at.file.clone(), f.line),
                what: "line length in bytes".into(),
                limit: self.opts.max_line_bytes as u64,
            },
        }
    }

    fn statement(
        &mut self,
        n: u64,
        text: &str,
        sink: &mut dyn TriangleSink,
    ) -> Result<(), ImportError> {
        self.at.line = Some(n);
        let mut words = text.split_whitespace();
        let Some(keyword) = words.next() else {
            return Ok(());
        };
        if self.positions_only && keyword != "v" {
            return Ok(());
        }
        match keyword {
            "v" => self.vertex(words, sink),
            "vn" => {
                self.normal(words)?;
                self.charge_moved(sink)
            }
            // `fo` is the face statement of old versions of the format.
            "f" | "fo" => self.face(words, sink),
            "l" => {
                self.lines += (words.count() as u64).saturating_sub(1);
                Ok(())
            }
            "p" => {
                self.points += words.count() as u64;
                Ok(())
            }
            "usemtl" => {
                self.materials.select(mtl::rest_after(text, keyword), n);
                Ok(())
            }
            "mtllib" => {
                let args = mtl::rest_after(text, keyword);
                self.materials
                    .load(args, &self.at, self.opts, sink, &mut self.notes);
                Ok(())
            }
            "o" => {
                self.parts.object(mtl::rest_after(text, keyword));
                Ok(())
            }
            "g" => {
                self.parts.group(mtl::rest_after(text, keyword));
                Ok(())
            }
            // Texture coordinates, smoothing and display attributes do not reach the
            // container; `vp` and the free-form settings only matter to the free-form
            // statements, which are warned about.
            "vt" | "vp" | "s" | "mg" | "bevel" | "c_interp" | "d_interp" | "lod" | "usemap"
            | "maplib" | "shadow_obj" | "trace_obj" | "ctech" | "stech" | "cstype" | "deg"
            | "bmat" | "step" => Ok(()),
            other => {
                self.notes.unsupported(other, n);
                Ok(())
            }
        }
    }

    fn number(&self, word: &str, what: &str) -> Result<f32, ImportError> {
        // Rust's parser also takes `nan` and `inf`: such vertices are the sink's to drop.
        word.parse::<f32>()
            .map_err(|_| self.parse_error(format!("`{word}` is not a number (in `{what}`)")))
    }

    /// A position coordinate, in f64 so that the origin is subtracted before rounding to f32.
    /// Rounding the f64 to f32 gives the f32 nearest the text except where the f64 lies
    /// exactly halfway between two f32s and the text does not (it has more digits than f64
    /// keeps): there the f64 is moved one f64 step towards the f32 nearest the text, so that
    /// without an origin the stored value is exactly `word.parse::<f32>()`, as it always was.
    fn coordinate(&self, word: &str) -> Result<f64, ImportError> {
        let bad = || self.parse_error(format!("`{word}` is not a number (in `v`)"));
        let x: f64 = word.parse().map_err(|_| bad())?;
        if !maybe_f32_tie(x) {
            return Ok(x);
        }
        let nearest: f32 = word.parse().map_err(|_| bad())?;
        Ok(if nearest == x as f32 {
            x
        } else {
            step_towards(x, f64::from(nearest))
        })
    }

    fn vertex(
        &mut self,
        words: SplitWhitespace<'_>,
        sink: &mut dyn TriangleSink,
    ) -> Result<(), ImportError> {
        let mut xyz = [0.0f64; 3];
        let mut vals = [0.0f32; 3];
        let mut count = 0;
        for w in words {
            if let Some(slot) = xyz.get_mut(count) {
                *slot = self.coordinate(w)?;
            } else {
                let slot = vals.get_mut(count - 3).ok_or_else(|| {
                    self.parse_error(
                        "`v` has more than 6 numbers (x y z [w] or x y z r g b)".into(),
                    )
                })?;
                *slot = self.number(w, "v")?;
            }
            count += 1;
        }
        let colour = match count {
            3 | 4 => None,
            6 => Some(vals),
            k => {
                return Err(self.parse_error(format!(
                    "`v` has {k} numbers, expected x y z [w] or x y z r g b"
                )))
            }
        };
        if self.positions_only {
            sink.place(xyz);
            return Ok(());
        }
        if self.positions.len() >= self.max_vertices() {
            return Err(self.limit("vertex positions (`v`)", self.max_vertices()));
        }
        let p = sink.place(xyz);
        self.positions.push(p).map_err(|e| self.spill_error(e))?;
        match colour {
            Some(rgb) => {
                if !rgb.iter().all(|c| (0.0..=1.0).contains(c)) {
                    self.notes.warn(sink, Kind::Colour, &self.at, || {
                        format!("vertex colour {rgb:?} is outside 0..1 and is clamped")
                    });
                }
                // NaN clamps to NaN, which converts to 0.
                let c = rgb.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
                if self.colours.is_empty() {
                    let before = self.positions.len() - 1;
                    self.colours
                        .extend_default(before)
                        .map_err(|e| self.spill_error(e))?;
                }
                let c = Some([c[0], c[1], c[2], 255]);
                self.colours.push(c).map_err(|e| self.spill_error(e))?;
            }
            None if !self.colours.is_empty() => {
                self.colours.push(None).map_err(|e| self.spill_error(e))?
            }
            None => {}
        }
        self.charge_moved(sink)
    }

    /// The bound on vertices: in memory, or with a spill.
    fn max_vertices(&self) -> usize {
        self.opts
            .spill
            .as_ref()
            .map_or(self.opts.max_vertices, |s| s.max_vertices)
    }

    /// Tells the sink of the tables' file bytes since the last call.
    fn charge_moved(&mut self, sink: &mut dyn TriangleSink) -> Result<(), ImportError> {
        let now =
            self.positions.file_bytes() + self.normals.file_bytes() + self.colours.file_bytes();
        if now > self.charged {
            sink.charge_disk(now - self.charged)
                .map_err(|e| self.spill_error(e))?;
            self.charged = now;
        }
        Ok(())
    }

    /// A failure of the vertex tables' file, named by the input and the folder.
    fn spill_error(&self, source: std::io::Error) -> ImportError {
        let dir = self
            .opts
            .spill
            .as_ref()
            .map(|s| s.to.dir.display().to_string());
        ImportError::Io {
            path: format!(
                "{} (vertices moved to a temporary file in {})",
                self.at.file,
                dir.unwrap_or_default()
            ),
            source,
        }
    }

    fn normal(&mut self, words: SplitWhitespace<'_>) -> Result<(), ImportError> {
        let mut vals = [0.0f32; 3];
        let mut count = 0;
        for w in words {
            let slot = vals
                .get_mut(count)
                .ok_or_else(|| self.parse_error("`vn` has more than 3 numbers".into()))?;
            *slot = self.number(w, "vn")?;
            count += 1;
        }
        if count != 3 {
            return Err(self.parse_error(format!("`vn` has {count} numbers, expected 3")));
        }
        if self.normals.len() >= self.max_vertices() {
            return Err(self.limit("vertex normals (`vn`)", self.max_vertices()));
        }
        self.normals.push(vals).map_err(|e| self.spill_error(e))
    }

    fn limit(&self, what: &str, limit: usize) -> ImportError {
        ImportError::Limit {
            at: self.at.clone(),
            what: what.into(),
            limit: limit as u64,
        }
    }

    fn face(
        &mut self,
        words: SplitWhitespace<'_>,
        sink: &mut dyn TriangleSink,
    ) -> Result<(), ImportError> {
        self.corners.clear();
        self.polygon.clear();
        let mut unresolved = false;
        for w in words {
            if self.corners.len() >= self.opts.max_face_corners {
                return Err(self.limit("corners of one face", self.opts.max_face_corners));
            }
            let (v, vn) = parse_corner(w).ok_or_else(|| {
                self.parse_error(format!(
                    "bad face corner `{w}`: expected v, v/vt, v//vn or v/vt/vn with whole-number \
                     indices"
                ))
            })?;
            let vertex = match resolve(v, self.positions.len()) {
                Some(i) => self
                    .positions
                    .get(i)
                    .map_err(|e| self.spill_error(e))?
                    .map(|p| (i, p)),
                None => None,
            };
            let normal = vn.map(|i| resolve(i, self.normals.len()));
            match (vertex, normal) {
                (Some((i, p)), None | Some(Some(_))) => {
                    self.polygon.push(p);
                    self.corners.push(Corner {
                        vertex: i,
                        normal: normal.flatten(),
                    });
                }
                _ => {
                    unresolved = true;
                    self.corners.push(Corner {
                        vertex: 0,
                        normal: None,
                    });
                }
            }
        }
        match self.corners.len() {
            0 => return Err(self.parse_error("face without corners".into())),
            // tobj reads these as a point and a line; so do we, and count them with the rest.
            1 => self.points += 1,
            2 => self.lines += 1,
            n if unresolved => {
                for _ in 2..n {
                    sink.reject(DropReason::IndexOutOfRange, &self.at)?;
                }
            }
            _ => self.emit(sink)?,
        }
        Ok(())
    }

    /// Triangulates the face in `corners`/`polygon` and pushes its triangles.
    fn emit(&mut self, sink: &mut dyn TriangleSink) -> Result<(), ImportError> {
        if self.triangulator.triangulate(&self.polygon) == Outcome::Fallback {
            let corners = self.polygon.len();
            self.notes.warn(sink, Kind::Fallback, &self.at, || {
                format!(
                    "polygon of {corners} corners could not be ear-clipped (self-intersecting?) \
                     and was fan-triangulated"
                )
            });
        }
        let material = self
            .materials
            .current(sink, &mut self.notes, &self.at.file)?;
        let part = self.parts.current(&self.at, sink)?;
        for t in self.triangulator.triangles() {
            let corners = t.map(|i| self.corners[i]);
            let looked_up = corner_normals(&mut self.normals, corners)
                .and_then(|n| Ok((n, corner_colours(&mut self.colours, corners)?)));
            let (normals, colours) = match looked_up {
                Ok(v) => v,
                Err(e) => return Err(self.spill_error(e)),
            };
            let colours = colours
                .iter()
                .any(Option::is_some)
                .then(|| colours.map(|c| c.unwrap_or([255; 4])));
            let triangle = InputTriangle {
                positions: t.map(|i| self.polygon[i]),
                normals,
                colours,
                material,
                part,
                hint: match corners.map(|c| u32::try_from(c.vertex).ok()) {
                    [Some(a), Some(b), Some(c)] => Some([a, b, c]),
                    _ => None,
                },
            };
            sink.push(triangle, &self.at)?;
        }
        Ok(())
    }

    fn finish(&mut self, sink: &mut dyn TriangleSink) -> Result<(), ImportError> {
        if self.lines > 0 {
            sink.skip(Skipped::Lines, self.lines);
        }
        if self.points > 0 {
            sink.skip(Skipped::Points, self.points);
        }
        self.notes.finish(sink, &self.at.file);
        // The tables' file goes with them.
        sink.release_disk(std::mem::take(&mut self.charged));
        self.parts.finish(&Location::file(self.at.file.clone()))
    }
}

/// The normals of a triangle's corners, when all three name one.
fn corner_normals(
    normals: &mut SpillTable<[f32; 3]>,
    corners: [Corner; 3],
) -> std::io::Result<Option<[[f32; 3]; 3]>> {
    let mut out = [[0.0; 3]; 3];
    for (o, c) in out.iter_mut().zip(corners) {
        match c.normal.map(|n| normals.get(n)).transpose()?.flatten() {
            Some(n) => *o = n,
            None => return Ok(None),
        }
    }
    Ok(Some(out))
}

/// The colours of a triangle's corners (none where the table has none).
fn corner_colours(
    colours: &mut SpillTable<Option<[u8; 4]>>,
    corners: [Corner; 3],
) -> std::io::Result<[Option<[u8; 4]>; 3]> {
    let mut out = [None; 3];
    for (o, c) in out.iter_mut().zip(corners) {
        *o = colours.get(c.vertex)?.flatten();
    }
    Ok(out)
}

/// Whether rounding `x` to f32 may be a tie (exactly halfway between two f32s). Exact for
/// f32's normal range, where the 29 low fraction bits that f32 drops are then exactly one
/// half; outside it (subnormal, overflowing) always yes, as those are rare and the caller
/// then checks against the f32 parse.
fn maybe_f32_tie(x: f64) -> bool {
    let a = x.abs();
    if !a.is_finite() || a == 0.0 {
        return false;
    }
    if a < f64::from(f32::MIN_POSITIVE) || a > f64::from(f32::MAX) {
        return true;
    }
    x.to_bits() & ((1 << 29) - 1) == 1 << 28
}

/// The f64 next to `x` (finite, not zero) in the direction of `target`.
fn step_towards(x: f64, target: f64) -> f64 {
    let away_from_zero = (target > x) == (x > 0.0);
    let bits = x.to_bits();
    f64::from_bits(if away_from_zero { bits + 1 } else { bits - 1 })
}

/// `v`, `v/vt`, `v//vn` or `v/vt/vn` → the raw vertex and normal indices. Texture indices are
/// checked for form only.
fn parse_corner(word: &str) -> Option<(i64, Option<i64>)> {
    let mut parts = word.split('/');
    let v = index(parts.next()?)?;
    let vt = parts.next();
    let vn = parts.next();
    if parts.next().is_some() {
        return None;
    }
    match vt {
        Some(t) if !t.is_empty() => {
            index(t)?;
        }
        _ => {}
    }
    let vn = match vn {
        Some(n) if !n.is_empty() => Some(index(n)?),
        _ => None,
    };
    Some((v, vn))
}

/// A whole number; one too large for i64 is still an index (just out of range).
fn index(word: &str) -> Option<i64> {
    match word.parse::<i64>() {
        Ok(i) => Some(i),
        Err(e) => match e.kind() {
            IntErrorKind::PosOverflow => Some(i64::MAX),
            IntErrorKind::NegOverflow => Some(i64::MIN),
            _ => None,
        },
    }
}

/// A 1-based (or, negative, counted back from the latest) OBJ index → a 0-based one, if it
/// names one of the `count` elements defined so far.
fn resolve(raw: i64, count: usize) -> Option<usize> {
    let count = count as u64;
    let i = if raw > 0 {
        raw.unsigned_abs() - 1
    } else {
        count.checked_sub(raw.unsigned_abs())?
    };
    // Zero falls out here too: count − 0 is never below count.
    (i < count).then_some(i as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_in_every_form() {
        assert_eq!(parse_corner("3"), Some((3, None)));
        assert_eq!(parse_corner("3/7"), Some((3, None)));
        assert_eq!(parse_corner("3//-2"), Some((3, Some(-2))));
        assert_eq!(parse_corner("-1/7/2"), Some((-1, Some(2))));
        assert_eq!(parse_corner("3/"), Some((3, None)));
        assert_eq!(parse_corner("99999999999999999999"), Some((i64::MAX, None)));
        for bad in ["", "/1", "a", "1/x", "1//y", "1/2/3/4", "1.5", "1 2"] {
            assert_eq!(parse_corner(bad), None, "{bad}");
        }
    }

    #[test]
    fn coordinates_round_to_the_f32_nearest_their_text() {
        let opts = ObjOptions::default();
        let obj = Obj::new("t.obj".into(), PathBuf::from("."), &opts);
        // 1 + 2^-24 is halfway between the f32s 1 and 1 + 2^-23. These texts are just above
        // (17 digits) or below it, or exactly it; the nearest f64 of the first two is the
        // halfway point itself, which rounds to even (1.0) when converted.
        for text in [
            "1.0000000596046448",
            "1.00000005960464477",
            "1.000000059604644775390625",
            "-1.0000000596046448",
            "16777217.000000001",
            "16777217",
            "1e-45",
            "7e-46",
            "3.4028235677973366e38",
            "3.40282357e38",
            "0.1",
            "-0",
            "1e7",
        ] {
            let x = obj.coordinate(text).unwrap_or(f64::NAN);
            let want: f32 = text.parse().unwrap_or(f32::NAN);
            assert_eq!((x as f32).to_bits(), want.to_bits(), "{text}: {x:e}");
            let exact: f64 = text.parse().unwrap_or(f64::NAN);
            assert!(x == exact || step_towards(exact, x) == x, "{text}");
        }
        assert!(f64::from(1.0f32) + 2f64.powi(-24) != 1.0);
        assert!(maybe_f32_tie(1.0 + 2f64.powi(-24)));
        assert!(!maybe_f32_tie(1.0 + 2f64.powi(-23)));
        assert!(!maybe_f32_tie(0.1));
    }

    #[test]
    fn a_stream_reads_in_one_pass_with_libraries_from_the_folder_given() -> Result<(), String> {
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 1 0 0\n")
            .map_err(|e| e.to_string())?;
        let text = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\nf 1 2 9\n";
        let mut sink = crate::import::MeshSink::new(false);
        import_from(
            text.as_bytes(),
            crate::import::STDIN_NAME,
            dir.path(),
            &mut sink,
            &ObjOptions::default(),
        )
        .map_err(|e| e.to_string())?;
        let (mesh, report) = sink.finish().map_err(|e| e.to_string())?;
        assert_eq!(mesh.triangles.len(), 1);
        let red = mesh.material_table.iter().find(|m| m.name == "red");
        assert_eq!(red.map(|m| m.diffuse), Some([1.0, 0.0, 0.0]));
        assert_eq!(report.files, vec!["<stdin>".to_string()]);
        assert_eq!(report.dropped.get(&DropReason::IndexOutOfRange), Some(&1));
        Ok(())
    }

    #[test]
    fn indices_resolve_forwards_and_backwards() {
        assert_eq!(resolve(1, 3), Some(0));
        assert_eq!(resolve(3, 3), Some(2));
        assert_eq!(resolve(4, 3), None);
        assert_eq!(resolve(-1, 3), Some(2));
        assert_eq!(resolve(-3, 3), Some(0));
        assert_eq!(resolve(-4, 3), None);
        assert_eq!(resolve(0, 3), None);
        assert_eq!(resolve(i64::MIN, 3), None);
    }
}
