//! Triangle soup: the spill files of the out-of-core build, runs of segment files
//! (`segments`) of the self-contained records of `record`.

use std::path::Path;
use std::sync::Arc;

use super::disk::SpillDisk;
pub use super::record::SoupTriangle;
use super::record::MAX_RECORD_LEN;
use super::segments::{Run, SegmentReader, SegmentWriter};
use super::tee::MeshTee;
use super::OocError;
use super::SceneInfo;
use oocfmt_meshio::import::{
    ImportError, ImportReport, InputTriangle, Intake, Intaken, Location, MeshSink, Store,
    TriangleSink,
};
use oocfmt_meshio::mesh::{Bounds, Mesh};

/// Appends triangle records to a spill run.
pub struct SoupWriter {
    out: SegmentWriter,
}

impl SoupWriter {
    /// A run whose segments are named after `base` (nothing is created before the first
    /// record), accounted on `disk`.
    pub fn create(base: &Path, disk: Arc<SpillDisk>) -> SoupWriter {
        SoupWriter {
            out: SegmentWriter::new(base, disk),
        }
    }

    /// The name the run's segments are numbered after.
    pub fn base(&self) -> &Path {
        self.out.base()
    }

    /// Appends one record (buffered: an I/O error may surface only later).
    pub fn push(&mut self, t: &SoupTriangle) -> Result<(), OocError> {
        let mut record = [0u8; MAX_RECORD_LEN];
        let len = t.encode(&mut record);
        self.out.push(record.get(..len).unwrap_or(&record))
    }

    /// Flushes the last segment; returns the run.
    pub fn finish(self) -> Result<Run, OocError> {
        self.out.finish()
    }
}

/// Streams the records of a run written by [`SoupWriter`], deleting each segment once read when
/// it consumes the run.
pub struct SoupReader {
    input: SegmentReader,
    left: u64,
}

impl SoupReader {
    /// Starts reading `run`; with `consume` its segments are deleted as they are finished, the
    /// last one once its last record is taken.
    pub fn open(run: &Run, consume: bool, disk: Arc<SpillDisk>) -> SoupReader {
        SoupReader {
            input: SegmentReader::new(run, consume, disk),
            left: run.count,
        }
    }

    fn next_record(&mut self) -> Result<SoupTriangle, OocError> {
        let decoded = self.input.peek(MAX_RECORD_LEN)?.map(SoupTriangle::decode);
        let path = self.input.path();
        match decoded {
            Some(Ok((t, len))) => {
                self.input.advance(len);
                Ok(t)
            }
            Some(Err(e)) => Err(OocError::corrupt(path, e.describe())),
            None => Err(OocError::corrupt(path, "fewer records than written")),
        }
    }
}

impl Iterator for SoupReader {
    type Item = Result<SoupTriangle, OocError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.left == 0 {
            return None;
        }
        self.left -= 1;
        let r = self.next_record();
        if r.is_err() {
            self.left = 0;
            return Some(r);
        }
        if self.left == 0 {
            // The end of the run: its last segment is checked, and deleted when consuming.
            if let Err(e) = self.input.finish() {
                return Some(Err(e));
            }
        }
        Some(r)
    }
}

/// The imported scene as a spill run, with what the whole scene has.
pub struct Soup {
    /// The spill run holding every kept triangle, all primary.
    pub run: Run,
    /// What the scene has: its bounds, its triangle count (the records in the run), its
    /// material and part tables (materials in the order the in-memory sink numbers them, so
    /// both paths give the same table).
    pub scene: SceneInfo,
    /// What the import read, dropped and warned about.
    pub report: ImportReport,
    /// What this conversion's spill files take on disk.
    pub disk: Arc<SpillDisk>,
    /// The mesh built beside the import, when one was asked for and the scene fitted.
    tee: Option<MeshTee>,
}

impl Soup {
    /// The whole scene as one in-memory mesh, numbered exactly as if it had been imported into
    /// a [`MeshSink`] directly: the one built during the import when there is one, else read
    /// back from the spill run. Either way the spill run is deleted.
    pub fn into_mesh(mut self) -> Result<Mesh, OocError> {
        let (materials, parts) = (&self.scene.materials, &self.scene.parts);
        if let Some(mesh) = self
            .tee
            .take()
            .and_then(|t| t.finish(materials.clone(), parts.clone()))
        {
            self.run.remove(&self.disk)?;
            return Ok(mesh?);
        }
        let mut sink = MeshSink::new(false);
        for m in materials {
            sink.add_material(m.clone())?;
        }
        let at = Location::file("import spill");
        for r in SoupReader::open(&self.run, true, self.disk.clone()) {
            sink.push(r?.triangle, &at)?;
        }
        let store = sink.finish_intake()?.store;
        Ok(store.into_mesh(materials.clone(), parts.clone())?)
    }

    /// Spill bytes per triangle of the import's run: what the scene's records take.
    pub fn bytes_per_triangle(&self) -> f64 {
        self.run.bytes() as f64 / self.scene.count.max(1) as f64
    }
}

/// Streams admitted triangles to a spill run, noting what the scene has.
pub struct SoupStore {
    writer: SoupWriter,
    disk: Arc<SpillDisk>,
    tee: Option<MeshTee>,
    tally: Tally,
}

/// What a store learns of the scene besides its triangles, as it takes them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tally {
    /// The box of every corner taken.
    pub bounds: Bounds,
    /// Triangles taken.
    pub count: u64,
    /// Some triangle has vertex normals.
    pub normals: bool,
    /// Some triangle has vertex colours.
    pub colours: bool,
}

impl Default for Tally {
    fn default() -> Self {
        Tally {
            bounds: Bounds::EMPTY,
            count: 0,
            normals: false,
            colours: false,
        }
    }
}

impl Tally {
    /// Takes one triangle.
    pub fn add(&mut self, t: &InputTriangle) {
        for p in t.positions {
            self.bounds.extend(p);
        }
        self.count += 1;
        self.normals |= t.normals.is_some();
        self.colours |= t.colours.is_some();
    }

    /// The scene: this tally with the intake's material and part tables.
    pub fn scene<S>(&self, intaken: &Intaken<S>) -> SceneInfo {
        SceneInfo {
            bounds: self.bounds,
            count: self.count,
            materials: intaken.table.clone(),
            used_materials: intaken.used_order.clone(),
            parts: intaken.parts.clone(),
            normals: self.normals,
            colours: self.colours,
        }
    }
}

impl Store for SoupStore {
    fn store(&mut self, t: InputTriangle, _at: &Location) -> Result<(), ImportError> {
        let record = SoupTriangle {
            triangle: t,
            primary: true,
        };
        self.writer.push(&record).map_err(|e| ImportError::Io {
            path: self.writer.base().display().to_string(),
            // The kind stays (a full disk is still `StorageFull` to the caller).
            source: std::io::Error::new(e.io_kind(), e.to_string()),
        })?;
        if let Some(tee) = &mut self.tee {
            tee.push(t);
        }
        self.tally.add(&t);
        Ok(())
    }

    fn charge_disk(&mut self, bytes: u64) -> std::io::Result<()> {
        self.disk.charge(bytes)
    }

    fn release_disk(&mut self, bytes: u64) {
        self.disk.release(bytes);
    }
}

/// The sink of `oocfmt convert`: the shared bad-input policy in front of a spill run.
pub type SoupSink = Intake<SoupStore>;

/// A sink that spills every admitted triangle to a new run named after `base` (accounted on a
/// new [`SpillDisk`]), under the bad-input policy `strict` (refuse the first bad triangle, else
/// drop and count it). With `mesh_limit` it also builds the in-memory mesh on a second thread,
/// for a scene of at most that many triangles, so that an in-core build need not read the
/// spill back.
pub fn soup_sink(base: &Path, strict: bool, mesh_limit: Option<u64>) -> Result<SoupSink, OocError> {
    let disk = Arc::new(SpillDisk::new());
    let store = SoupStore {
        writer: SoupWriter::create(base, disk.clone()),
        disk,
        tee: mesh_limit.map(MeshTee::spawn),
        tally: Tally::default(),
    };
    Ok(Intake::with_store(strict, store))
}

/// Ends the import into `sink` and flushes its spill run. Fails on an empty result, like the
/// in-memory sink.
pub fn finish_soup(sink: SoupSink) -> Result<Soup, OocError> {
    let intaken = sink.finish_intake()?;
    let scene = intaken.store.tally.scene(&intaken);
    let Intaken { store, report, .. } = intaken;
    Ok(Soup {
        tee: store.tee,
        run: store.writer.finish()?,
        scene,
        report,
        disk: store.disk,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(x: f32) -> SoupTriangle {
        SoupTriangle {
            triangle: InputTriangle::new([[x, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
            primary: x > 0.0,
        }
    }

    #[test]
    fn a_run_reads_back_in_order_across_segments() -> Result<(), OocError> {
        let dir = tempfile::tempdir().map_err(|e| OocError::spill(Path::new("."), e))?;
        // Two 37-byte records a segment.
        let disk = Arc::new(SpillDisk::with_segments(80, None));
        let mut w = SoupWriter::create(&dir.path().join("s"), disk.clone());
        let input: Vec<SoupTriangle> = (0..5).map(|k| tri(k as f32)).collect();
        for t in &input {
            w.push(t)?;
        }
        let run = w.finish()?;
        assert_eq!((run.segments.len(), run.bytes()), (3, 5 * 37));
        let back: Vec<SoupTriangle> =
            SoupReader::open(&run, false, disk.clone()).collect::<Result<_, _>>()?;
        assert_eq!(back, input);
        let back: Vec<SoupTriangle> =
            SoupReader::open(&run, true, disk.clone()).collect::<Result<_, _>>()?;
        assert_eq!(back, input);
        assert!(run.segments.iter().all(|s| !s.path.exists()));
        assert_eq!(disk.spill_bytes(), 0);
        Ok(())
    }

    #[test]
    fn a_run_with_a_record_missing_or_spare_is_refused() -> Result<(), OocError> {
        let dir = tempfile::tempdir().map_err(|e| OocError::spill(Path::new("."), e))?;
        let disk = Arc::new(SpillDisk::with_segments(1 << 20, None));
        let mut w = SoupWriter::create(&dir.path().join("s.soup"), disk.clone());
        w.push(&tri(1.0))?;
        w.push(&tri(2.0))?;
        let run = w.finish()?;
        for (count, records) in [(1, 2), (3, 2), (2, 3)] {
            let mut wrong = run.clone();
            wrong.count = count;
            if let Some(s) = wrong.segments.first_mut() {
                s.records = records;
            }
            let read: Result<Vec<_>, _> = SoupReader::open(&wrong, false, disk.clone()).collect();
            let e = read.err().map(|e| e.to_string());
            assert!(
                e.is_some_and(|m| m.contains("s.soup.0")),
                "{count} {records}"
            );
        }
        Ok(())
    }
}
