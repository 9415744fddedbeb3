//! Block caches: where the traversal gets decoded blocks. The traversal only sees the
//! [`BlockCache`] trait, so the blocking cache here and the asynchronous and mmap caches to come
//! are interchangeable.

pub mod blocking;

use std::sync::Arc;

use serde::Serialize;

use crate::blocks::{TreeletData, TriangleData};

pub use blocking::BlockingCache;

pub trait BlockCache: Send + Sync {
    /// Treelet block `id`, or None when it is not available (a blocking cache: it failed to
    /// read or decode and is missing for good).
    fn treelets(&self, id: u32) -> Option<Arc<TreeletData>>;
    fn triangles(&self, id: u32) -> Option<Arc<TriangleData>>;
    fn stats(&self) -> CacheStats;
}

#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct CacheStats {
    pub mode: &'static str,
    pub budget_bytes: u64,
    pub bytes_resident: u64,
    pub peak_bytes_resident: u64,
    pub lookups: u64,
    pub hits: u64,
    pub blocks_loaded: u64,
    pub blocks_evicted: u64,
    /// Blocks that could not be read or decoded, by id, with the reason; never retried.
    pub missing_blocks: Vec<MissingBlock>,
}

#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
pub struct MissingBlock {
    pub id: u32,
    pub error: String,
}
