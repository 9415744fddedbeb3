//! The mmap cache, the baseline of Wald et al. (2004) and Yoon et al. (2006): the container is
//! mapped into memory and the operating system pages its bytes in on first touch; blocks are
//! decoded from the mapped bytes the first time a ray needs them, and the ray waits. Only an
//! uncompressed container can be paged this way: compressed blocks would be decompressed into
//! copies, which is the blocking cache again.

use std::path::Path;
use std::sync::Arc;

use oocfmt::{BlockKind, CodecId, ReadOptions, Reader};

use super::{BlockCache, BlockingCache, CacheStats};
use crate::blocks::{TreeletData, TriangleData};
use crate::error::TraceError;
use crate::scene::Scene;

/// The mmap cache: a [`BlockingCache`] over a memory-mapped, uncompressed container; its stats
/// say `mmap`.
pub struct MmapCache {
    inner: BlockingCache,
}

impl MmapCache {
    /// Maps `path` and checks that its treelet and triangle blocks are stored uncompressed.
    /// Decoded blocks are kept up to `budget_bytes`, least recently used evicted beyond.
    pub fn open(path: &Path, budget_bytes: usize) -> Result<MmapCache, TraceError> {
        Self::open_as(path, budget_bytes, None)
    }

    /// Like [`MmapCache::open`], stopping on `lod` (None: the scene's default).
    pub fn open_as(
        path: &Path,
        budget_bytes: usize,
        lod: Option<crate::blocks::LodKind>,
    ) -> Result<MmapCache, TraceError> {
        let reader = Reader::open_mmap(path, ReadOptions::default())?;
        let compressed = reader
            .entries()
            .iter()
            .filter(|e| matches!(e.kind, BlockKind::Treelet | BlockKind::Triangle))
            .filter(|e| e.codec != CodecId::None)
            .count();
        if compressed > 0 {
            return Err(TraceError::Options(format!(
                "--cache mmap needs an uncompressed container, and {} has {compressed} \
                 compressed blocks; convert it with `--codec none` (or use --cache async or \
                 --cache blocking)",
                path.display()
            )));
        }
        let scene = Scene::from_reader(reader);
        let scene = Arc::new(match lod {
            Some(l) => scene.with_lod(l)?,
            None => scene,
        });
        Ok(MmapCache {
            inner: BlockingCache::with_mode(scene, budget_bytes, "mmap"),
        })
    }

    /// The scene opened over the mapped file.
    pub fn scene(&self) -> &Arc<Scene> {
        self.inner.scene()
    }
}

impl BlockCache for MmapCache {
    fn treelets(&self, id: u32) -> Option<Arc<TreeletData>> {
        self.inner.treelets(id)
    }

    fn triangles(&self, id: u32) -> Option<Arc<TriangleData>> {
        self.inner.triangles(id)
    }

    fn stats(&self) -> CacheStats {
        self.inner.stats()
    }

    fn render_waits(&self) -> u64 {
        self.inner.render_waits()
    }
}
