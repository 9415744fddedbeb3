//! A block cache that records which blocks a frame looked up, around any other cache: the
//! "blocks touched" of a frame. It costs a lock per lookup, so curve renders one recorded frame
//! apart from the timed ones.

use std::sync::{Arc, Mutex, PoisonError};

use rustc_hash::FxHashSet;

use oocfmt_trace::blocks::{TreeletData, TriangleData};
use oocfmt_trace::cache::Wish;
use oocfmt_trace::{BlockCache, CacheStats};

pub struct Touched<'a> {
    inner: &'a dyn BlockCache,
    ids: Mutex<FxHashSet<u32>>,
}

impl<'a> Touched<'a> {
    pub fn new(inner: &'a dyn BlockCache) -> Touched<'a> {
        Touched {
            inner,
            ids: Mutex::default(),
        }
    }

    fn note(&self, id: u32) {
        self.ids
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(id);
    }

    /// Distinct blocks looked up so far, found or not.
    pub fn count(&self) -> u64 {
        self.ids
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .len() as u64
    }
}

impl BlockCache for Touched<'_> {
    fn treelets(&self, id: u32) -> Option<Arc<TreeletData>> {
        self.note(id);
        self.inner.treelets(id)
    }

    fn triangles(&self, id: u32) -> Option<Arc<TriangleData>> {
        self.note(id);
        self.inner.triangles(id)
    }

    fn request(&self, wanted: &[(u32, Wish)]) {
        self.inner.request(wanted);
    }

    fn begin_frame(&self) {
        self.inner.begin_frame();
    }

    fn end_frame(&self) {
        self.inner.end_frame();
    }

    fn stats(&self) -> CacheStats {
        self.inner.stats()
    }

    fn render_waits(&self) -> u64 {
        self.inner.render_waits()
    }
}
