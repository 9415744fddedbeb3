//! Triangle soup: the spill files of the out-of-core build. Every triangle is one fixed 96-byte
//! little-endian record holding its own corners and attributes, so a file can be split, counted
//! and streamed without any index into other data.
//!
//! | bytes | field |
//! |------:|-------|
//! | 0–35  | 9 × f32 corner positions |
//! | 36–71 | 9 × f32 corner normals (zero without) |
//! | 72–83 | 3 × RGBA8 corner colours (zero without) |
//! | 84–87 | u32 material as the importer numbered it, `u32::MAX` for none |
//! | 88–91 | u32 flags: bit 0 normals, bit 1 colours, bit 2 a copy that is not the primary |
//! | 92–95 | u32 part as the importer numbered it, `u32::MAX` for none |

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use oocfmt::metadata::Material;

use super::tee::MeshTee;
use super::OocError;
use oocfmt_meshio::import::{
    ImportError, ImportReport, InputTriangle, Intake, Intaken, Location, MeshSink, PartDef, Store,
    TriangleSink,
};
use oocfmt_meshio::mesh::{Bounds, Mesh};

/// Bytes of one triangle record (the table above).
pub const RECORD_LEN: usize = 96;
const NO_MATERIAL: u32 = u32::MAX;
const NO_PART: u32 = u32::MAX;
const HAS_NORMALS: u32 = 1;
const HAS_COLOURS: u32 = 2;
const NOT_PRIMARY: u32 = 4;

/// One triangle of the soup. `primary` is false on the copies a split made of a triangle
/// reaching both sides: exactly one copy of each input triangle is primary, so the file stores
/// it once as a primary (what `export` writes back).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoupTriangle {
    /// The triangle as the importer gave it (its `hint` is not stored).
    pub triangle: InputTriangle,
    /// Whether this is the one copy of the input triangle that counts as the original.
    pub primary: bool,
}

impl SoupTriangle {
    /// The triangle's record, laid out as in the table above.
    pub fn encode(&self) -> [u8; RECORD_LEN] {
        let mut r = [0u8; RECORD_LEN];
        let t = &self.triangle;
        let floats = t
            .positions
            .iter()
            .flatten()
            .chain(t.normals.iter().flatten().flatten());
        for (k, f) in floats.enumerate() {
            r[4 * k..4 * k + 4].copy_from_slice(&f.to_le_bytes());
        }
        if let Some(c) = t.colours {
            for (k, rgba) in c.iter().enumerate() {
                r[72 + 4 * k..76 + 4 * k].copy_from_slice(rgba);
            }
        }
        r[84..88].copy_from_slice(&t.material.unwrap_or(NO_MATERIAL).to_le_bytes());
        let mut flags = 0;
        if t.normals.is_some() {
            flags |= HAS_NORMALS;
        }
        if t.colours.is_some() {
            flags |= HAS_COLOURS;
        }
        if !self.primary {
            flags |= NOT_PRIMARY;
        }
        r[88..92].copy_from_slice(&flags.to_le_bytes());
        r[92..96].copy_from_slice(&t.part.unwrap_or(NO_PART).to_le_bytes());
        r
    }

    /// The triangle a record holds; every bit pattern decodes to some triangle.
    pub fn decode(r: &[u8; RECORD_LEN]) -> SoupTriangle {
        let word = |k: usize| {
            let mut b = [0u8; 4];
            b.copy_from_slice(&r[4 * k..4 * k + 4]);
            b
        };
        let f = |k: usize| f32::from_le_bytes(word(k));
        let corners = |base: usize| -> [[f32; 3]; 3] {
            std::array::from_fn(|c| std::array::from_fn(|a| f(base + 3 * c + a)))
        };
        let flags = u32::from_le_bytes(word(22));
        let material = u32::from_le_bytes(word(21));
        let part = u32::from_le_bytes(word(23));
        SoupTriangle {
            triangle: InputTriangle {
                positions: corners(0),
                normals: (flags & HAS_NORMALS != 0).then(|| corners(9)),
                colours: (flags & HAS_COLOURS != 0).then(|| std::array::from_fn(|c| word(18 + c))),
                material: (material != NO_MATERIAL).then_some(material),
                part: (part != NO_PART).then_some(part),
                hint: None,
            },
            primary: flags & NOT_PRIMARY == 0,
        }
    }

    /// The vertex mean: inside the triangle, so inside every cell holding its primary copy.
    pub fn centroid(&self) -> [f32; 3] {
        let p = &self.triangle.positions;
        std::array::from_fn(|a| {
            ((f64::from(p[0][a]) + f64::from(p[1][a]) + f64::from(p[2][a])) / 3.0) as f32
        })
    }
}

/// Appends records to a spill file.
pub struct SoupWriter {
    path: PathBuf,
    out: BufWriter<File>,
    count: u64,
}

impl SoupWriter {
    /// Creates (or truncates) the spill file `path`.
    pub fn create(path: &Path) -> Result<SoupWriter, OocError> {
        let file = File::create(path).map_err(|e| OocError::spill(path, e))?;
        Ok(SoupWriter {
            path: path.to_path_buf(),
            out: BufWriter::with_capacity(1 << 20, file),
            count: 0,
        })
    }

    /// Appends one record (buffered: an I/O error may surface only at [`SoupWriter::finish`]).
    pub fn push(&mut self, t: &SoupTriangle) -> Result<(), OocError> {
        self.out
            .write_all(&t.encode())
            .map_err(|e| OocError::spill(&self.path, e))?;
        self.count += 1;
        Ok(())
    }

    /// Flushes the file; returns its path and record count.
    pub fn finish(mut self) -> Result<(PathBuf, u64), OocError> {
        self.out
            .flush()
            .map_err(|e| OocError::spill(&self.path, e))?;
        Ok((self.path, self.count))
    }
}

/// Streams the records of a spill file written by [`SoupWriter`].
pub struct SoupReader {
    path: PathBuf,
    input: BufReader<File>,
    left: u64,
}

impl SoupReader {
    /// Opens `path`, which must hold exactly `count` records.
    pub fn open(path: &Path, count: u64) -> Result<SoupReader, OocError> {
        let file = File::open(path).map_err(|e| OocError::spill(path, e))?;
        let len = file.metadata().map_err(|e| OocError::spill(path, e))?.len();
        if Some(len) != count.checked_mul(RECORD_LEN as u64) {
            return Err(OocError::SpillLength {
                path: path.display().to_string(),
                len,
                count,
            });
        }
        Ok(SoupReader {
            path: path.to_path_buf(),
            input: BufReader::with_capacity(1 << 20, file),
            left: count,
        })
    }
}

impl Iterator for SoupReader {
    type Item = Result<SoupTriangle, OocError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.left == 0 {
            return None;
        }
        self.left -= 1;
        let mut r = [0u8; RECORD_LEN];
        Some(
            self.input
                .read_exact(&mut r)
                .map(|()| SoupTriangle::decode(&r))
                .map_err(|e| OocError::spill(&self.path, e)),
        )
    }
}

/// The imported scene as a spill file, with what the whole scene has.
pub struct Soup {
    /// The spill file holding every kept triangle, all primary.
    pub path: PathBuf,
    /// Records in the spill file: the triangles kept.
    pub count: u64,
    /// The box of every kept triangle's corners, positions relative to the scene origin.
    pub bounds: Bounds,
    /// Materials as the importers added them.
    pub materials: Vec<Material>,
    /// The materials triangles use (`None`: no material), in order of first use: the order the
    /// in-memory sink numbers them in, so both paths give the same material table.
    pub used_materials: Vec<Option<u32>>,
    /// The parts as the importers declared them (see [`Intaken::parts`]).
    pub parts: Vec<PartDef>,
    /// Some triangle has vertex normals.
    pub normals: bool,
    /// Some triangle has vertex colours.
    pub colours: bool,
    /// What the import read, dropped and warned about.
    pub report: ImportReport,
    /// The mesh built beside the import, when one was asked for and the scene fitted.
    tee: Option<MeshTee>,
}

impl Soup {
    /// The whole scene as one in-memory mesh, numbered exactly as if it had been imported into
    /// a [`MeshSink`] directly: the one built during the import when there is one, else read
    /// back from the spill file.
    pub fn load_mesh(&mut self) -> Result<Mesh, OocError> {
        if let Some(mesh) = self
            .tee
            .take()
            .and_then(|t| t.finish(self.materials.clone(), self.parts.clone()))
        {
            return Ok(mesh?);
        }
        let mut sink = MeshSink::new(false);
        for m in &self.materials {
            sink.add_material(m.clone())?;
        }
        let at = Location::file(self.path.display().to_string());
        for r in SoupReader::open(&self.path, self.count)? {
            sink.push(r?.triangle, &at)?;
        }
        let store = sink.finish_intake()?.store;
        Ok(store.into_mesh(self.materials.clone(), self.parts.clone())?)
    }
}

/// Streams admitted triangles to a spill file, noting what the scene has.
pub struct SoupStore {
    writer: SoupWriter,
    tee: Option<MeshTee>,
    bounds: Bounds,
    normals: bool,
    colours: bool,
}

impl Store for SoupStore {
    fn store(&mut self, t: InputTriangle, _at: &Location) -> Result<(), ImportError> {
        let record = SoupTriangle {
            triangle: t,
            primary: true,
        };
        self.writer.push(&record).map_err(|e| ImportError::Io {
            path: self.writer.path.display().to_string(),
            source: std::io::Error::other(e.to_string()),
        })?;
        if let Some(tee) = &mut self.tee {
            tee.push(t);
        }
        for p in t.positions {
            self.bounds.extend(p);
        }
        self.normals |= t.normals.is_some();
        self.colours |= t.colours.is_some();
        Ok(())
    }
}

/// The sink of `oocfmt convert`: the shared bad-input policy in front of a spill file.
pub type SoupSink = Intake<SoupStore>;

/// A sink that spills every admitted triangle to a new file at `path`, under the bad-input
/// policy `strict` (refuse the first bad triangle, else drop and count it). With `mesh_limit`
/// it also builds the in-memory mesh on a second thread, for a scene of at most that many
/// triangles, so that an in-core build need not read the spill file back.
pub fn soup_sink(path: &Path, strict: bool, mesh_limit: Option<u64>) -> Result<SoupSink, OocError> {
    let store = SoupStore {
        writer: SoupWriter::create(path)?,
        tee: mesh_limit.map(MeshTee::spawn),
        bounds: Bounds::EMPTY,
        normals: false,
        colours: false,
    };
    Ok(Intake::with_store(strict, store))
}

/// Ends the import into `sink` and flushes its spill file. Fails on an empty result, like the
/// in-memory sink.
pub fn finish_soup(sink: SoupSink) -> Result<Soup, OocError> {
    let Intaken {
        store,
        table,
        used_order,
        parts,
        report,
    } = sink.finish_intake()?;
    let (path, count) = store.writer.finish()?;
    Ok(Soup {
        tee: store.tee,
        path,
        count,
        bounds: store.bounds,
        materials: table,
        used_materials: used_order,
        parts,
        normals: store.normals,
        colours: store.colours,
        report,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_with_and_without_attributes() {
        let mut t =
            InputTriangle::new([[1.0, -2.5, 3.0], [f32::MAX, 0.0, -0.0], [1e-30, 7.0, 8.0]]);
        let plain = SoupTriangle {
            triangle: t,
            primary: true,
        };
        assert_eq!(SoupTriangle::decode(&plain.encode()), plain);
        t.normals = Some([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]);
        t.colours = Some([[1, 2, 3, 4], [5, 6, 7, 8], [9, 10, 11, 12]]);
        t.material = Some(7);
        let full = SoupTriangle {
            triangle: t,
            primary: false,
        };
        assert_eq!(SoupTriangle::decode(&full.encode()), full);
    }

    #[test]
    fn a_spill_file_of_the_wrong_length_is_refused() -> Result<(), OocError> {
        let dir = tempfile::tempdir().map_err(|e| OocError::spill(Path::new("."), e))?;
        let path = dir.path().join("s.soup");
        let mut w = SoupWriter::create(&path)?;
        let t = SoupTriangle {
            triangle: InputTriangle::new([[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
            primary: true,
        };
        w.push(&t)?;
        w.push(&t)?;
        let (path, n) = w.finish()?;
        assert_eq!(n, 2);
        let back: Vec<SoupTriangle> = SoupReader::open(&path, 2)?.collect::<Result<_, _>>()?;
        assert_eq!(back, vec![t, t]);
        let e = SoupReader::open(&path, 3).err().map(|e| e.to_string());
        assert!(e.is_some_and(|m| m.contains("s.soup")));
        Ok(())
    }
}
