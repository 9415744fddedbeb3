//! The in-memory mesh, built on a second thread while the import writes the spill file. Whether
//! a scene fits `--mem-limit` is known only once the import ends; building the mesh beside the
//! import, instead of reading the spill file back afterwards, overlaps the de-duplication of
//! vertices with the parsing (they take about as long). A scene that outgrows the limit stops
//! the thread and goes out of core from the spill file as before.

use std::sync::mpsc::{sync_channel, SyncSender};
use std::thread::JoinHandle;

use oocfmt::metadata::Material;

use oocfmt_meshio::import::{ImportError, InputTriangle, Location, MeshStore, Store};
use oocfmt_meshio::mesh::Mesh;

/// Triangles handed over at a time: a few hundred kilobytes, so the threads rarely meet.
const BATCH: usize = 4096;
/// Batches in flight: the parser runs ahead of the de-duplication by at most this many.
const QUEUED: usize = 8;

/// The sending side, owned by the spill-file store.
pub struct MeshTee {
    sender: Option<SyncSender<Vec<InputTriangle>>>,
    batch: Vec<InputTriangle>,
    worker: Option<JoinHandle<MeshStore>>,
    /// The most triangles the mesh may take: past this the scene is built out of core.
    limit: u64,
    taken: u64,
}

impl MeshTee {
    /// Starts the thread; it gives up once more than `limit` triangles arrive.
    pub fn spawn(limit: u64) -> MeshTee {
        let (sender, receiver) = sync_channel::<Vec<InputTriangle>>(QUEUED);
        let worker = std::thread::Builder::new()
            .name("oocfmt-mesh".into())
            .spawn(move || {
                let mut store = MeshStore::default();
                let at = Location::default();
                for batch in receiver {
                    for t in batch {
                        // The in-memory store cannot fail; were it to, the spill file path
                        // reads the scene back and reports the error there.
                        if store.store(t, &at).is_err() {
                            return MeshStore::default();
                        }
                    }
                }
                store
            })
            .ok();
        MeshTee {
            sender: worker.is_some().then_some(sender),
            batch: Vec::with_capacity(BATCH),
            worker,
            limit,
            taken: 0,
        }
    }

    /// Hands one admitted triangle (as the spill file stores it) to the mesh.
    pub fn push(&mut self, t: InputTriangle) {
        let Some(sender) = &self.sender else {
            return;
        };
        self.taken += 1;
        if self.taken > self.limit {
            self.abandon();
            return;
        }
        self.batch.push(t);
        if self.batch.len() == BATCH {
            let full = std::mem::replace(&mut self.batch, Vec::with_capacity(BATCH));
            if sender.send(full).is_err() {
                self.abandon();
            }
        }
    }

    /// Stops building: the scene goes out of core, or the thread is gone.
    fn abandon(&mut self) {
        self.sender = None;
        self.batch = Vec::new();
        if let Some(w) = self.worker.take() {
            // What it built is not wanted; waiting frees its memory before the build starts.
            drop(w.join());
        }
    }

    /// The mesh of every triangle pushed, numbered as [`oocfmt_meshio::import::MeshSink`] numbers
    /// them, with the importers' material `table`; `None` when the thread gave up.
    pub fn finish(
        mut self,
        table: Vec<Material>,
        parts: Vec<oocfmt_meshio::import::PartDef>,
    ) -> Option<Result<Mesh, ImportError>> {
        let sender = self.sender.take()?;
        let last = std::mem::take(&mut self.batch);
        if !last.is_empty() && sender.send(last).is_err() {
            self.abandon();
            return None;
        }
        drop(sender);
        let store = self.worker.take()?.join().ok()?;
        (store.triangle_count() as u64 == self.taken).then(|| store.into_mesh(table, parts))
    }
}

impl Drop for MeshTee {
    fn drop(&mut self) {
        self.abandon();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ooc::soup::{finish_soup, soup_sink};
    use crate::ooc::OocError;
    use oocfmt_meshio::import::TriangleSink;
    use oocfmt_scenes::rng::Rng;

    /// A scene of `n` triangles on a small lattice (so vertices repeat), some with normals
    /// (one of them not finite), colours and materials.
    fn import(
        dir: &std::path::Path,
        name: &str,
        n: u32,
        limit: Option<u64>,
    ) -> Result<Mesh, OocError> {
        let mut sink = soup_sink(&dir.join(name), false, limit)?;
        let red = sink.add_material(Material {
            name: "red".into(),
            diffuse: [1.0, 0.0, 0.0],
        })?;
        let mut rng = Rng(3);
        let at = Location::default();
        for i in 0..n {
            let mut p = || [0, 1, 2].map(|_| rng.int(0, 6) as f32 * 0.5);
            let mut t = InputTriangle::new([p(), p(), p()]);
            if i % 3 == 0 {
                t.normals = Some([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [f32::NAN, 0.0, 0.0]]);
            }
            if i % 5 == 0 {
                t.colours = Some([[1, 2, 3, 255], [4, 5, 6, 255], [7, 8, 9, 255]]);
            }
            if i % 7 == 0 {
                t.material = Some(red);
            }
            sink.push(t, &at)?;
        }
        finish_soup(sink)?.into_mesh()
    }

    #[test]
    fn the_mesh_built_beside_the_import_is_the_one_read_back() -> Result<(), OocError> {
        let dir = tempfile::tempdir().map_err(|e| OocError::spill(std::path::Path::new("."), e))?;
        let n = 20_000;
        let read_back = import(dir.path(), "a.soup", n, None)?;
        assert!(read_back.triangles.len() > 15_000 && read_back.positions.len() < 5_000);
        assert!(read_back.normals.is_some() && read_back.colours.is_some());
        assert_eq!(read_back.material_table.len(), 2);
        // Batches end mid-way and exactly at the end; a limit below the count falls back to
        // the spill file.
        for (name, limit) in [
            ("b", u64::MAX),
            ("c", read_back.triangles.len() as u64),
            ("d", 1000),
        ] {
            assert_eq!(
                import(dir.path(), name, n, Some(limit))?,
                read_back,
                "{name}"
            );
        }
        Ok(())
    }

    #[test]
    fn a_tee_over_its_limit_gives_no_mesh() {
        let filled = |count: usize| {
            let mut tee = MeshTee::spawn(10);
            for _ in 0..count {
                tee.push(InputTriangle::new([
                    [0.0; 3],
                    [1.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0],
                ]));
            }
            tee
        };
        assert!(filled(11).finish(Vec::new(), Vec::new()).is_none());
        let tee = filled(10);
        let mesh = tee.finish(Vec::new(), Vec::new()).and_then(Result::ok);
        assert_eq!(
            mesh.map(|m| (m.triangles.len(), m.positions.len())),
            Some((10, 3))
        );
    }
}
