//! Block caches: where the traversal gets decoded blocks. The traversal only sees the
//! [`BlockCache`] trait, so the blocking, asynchronous and mmap caches are interchangeable.

pub mod asynchronous;
pub mod blocking;
pub mod mmap;
pub mod policy;
pub mod prefetch;
mod waits;

use std::sync::Arc;

use serde::Serialize;

use crate::blocks::{TreeletData, TriangleData};
use crate::scene::Scene;

pub use asynchronous::AsyncCache;
pub use blocking::BlockingCache;
pub use mmap::MmapCache;
pub use policy::{Eviction, FetchOrder};

/// Where the traversal gets decoded treelet and triangle blocks, by block id; shared by all
/// render threads of a frame.
pub trait BlockCache: Send + Sync {
    /// Treelet block `id`, or None when it is not available: missing for good (it failed to
    /// read or decode), or, in an asynchronous cache, not loaded yet.
    fn treelets(&self, id: u32) -> Option<Arc<TreeletData>>;
    /// Triangle block `id`, or None when it is not available, as for [`BlockCache::treelets`].
    fn triangles(&self, id: u32) -> Option<Arc<TriangleData>>;
    /// Blocks the rays of one tile wanted and did not get, each with what the rays made of its
    /// priority. A cache that loads on demand ignores it.
    fn request(&self, _wanted: &[(u32, Wish)]) {}
    /// A frame starts: render calls it once, before its first ray. An asynchronous cache ends
    /// an idle spell here ([`AsyncCache::idle`]) and times the frame's fetch budget from it.
    fn begin_frame(&self) {}
    /// The step between two frames: an asynchronous cache publishes what its fetchers loaded,
    /// evicts and hands the fetchers the new requests. Render threads must not be inside a
    /// frame while it runs (it is correct then too, only less useful).
    fn end_frame(&self) {}
    /// The cache's counters so far (over all frames since it was made).
    fn stats(&self) -> CacheStats;
    /// Block reads made on render threads so far, each a wait on I/O
    /// ([`CacheStats::render_waits`]); cheap, so a frame reads it before and after itself. A
    /// cache that never reads on a render thread keeps the default, 0.
    fn render_waits(&self) -> u64 {
        0
    }
}

/// What the rays that wanted a block make of its priority, under either fetch order
/// ([`policy::FetchOrder`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Wish {
    /// Áfra: the sum over the rays of 1 plus the region's angular size (radius over distance,
    /// at most 1): many rays, and big, near regions first.
    pub weight: f32,
    /// Wald: the region's size over its distance, the largest over the rays (the nearest ray's);
    /// +inf for a region the ray starts in or a block wanted without a region (the root).
    pub size: f32,
}

impl Wish {
    /// One more ray wanted the block of a region of `radius` it enters at distance `t`.
    pub fn add(&mut self, radius: f32, t: f32) {
        let size = if t > 0.0 && radius.is_finite() {
            radius / t
        } else {
            f32::INFINITY
        };
        self.weight += 1.0 + size.min(1.0);
        self.size = self.size.max(size);
    }

    /// Both rays' wishes.
    pub fn merge(&mut self, other: &Wish) {
        self.weight += other.weight;
        self.size = self.size.max(other.size);
    }
}

/// A cache's counters, part of each frame's [`crate::render::FrameStats`]. Counts run over all
/// frames since the cache was made; the fields only the asynchronous cache fills stay 0 in the
/// others.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct CacheStats {
    /// Which cache: `blocking`, `async` or `mmap`.
    pub mode: &'static str,
    /// How the cache's reads meet the operating system's page cache: `buffered`, `direct`
    /// (`O_DIRECT`) or `dontneed` (buffered, each range dropped after it was read), as
    /// [`oocfmt::IoMode::name`]; the mmap cache's map is `buffered`.
    pub io: &'static str,
    /// Asynchronous cache: the fetch order and the eviction policy (empty for the others).
    pub fetch_order: &'static str,
    /// Asynchronous cache: the eviction policy, `lru` or `second-chance` (empty for the others).
    pub eviction: &'static str,
    /// Asynchronous cache: how many nice levels below the render threads the fetchers were asked
    /// to run (up to nice 19), when the system took it (`None`: they run at the render threads'
    /// priority).
    pub fetcher_nice: Option<i32>,
    /// The byte budget the cache was made with, in decoded bytes.
    pub budget_bytes: u64,
    /// Decoded bytes of the blocks resident now.
    pub bytes_resident: u64,
    /// The most decoded bytes held at once; in the asynchronous cache that counts blocks
    /// fetched and waiting for publication too.
    pub peak_bytes_resident: u64,
    /// Requests for a block by the traversal ([`BlockCache::treelets`], [`BlockCache::triangles`]).
    pub lookups: u64,
    /// Of those, the ones that found the block resident.
    pub hits: u64,
    /// Blocks read and decoded into the cache (in the asynchronous cache: published).
    pub blocks_loaded: u64,
    /// Blocks dropped from the cache to stay within the budget.
    pub blocks_evicted: u64,
    /// Asynchronous cache: distinct blocks handed to the fetchers, over all frames.
    pub blocks_requested: u64,
    /// Asynchronous cache: of those, look-ahead requests (child blocks of the treelet blocks a
    /// frame used, fetched into free room at the lowest priority).
    pub blocks_looked_ahead: u64,
    /// Asynchronous cache: blocks loaded by look-ahead prefetching (predicted views), over all
    /// frames; and of those, the ones a frame has used since.
    pub blocks_prefetched: u64,
    /// Asynchronous cache: of the prefetched blocks, those a frame has looked up since.
    pub blocks_prefetch_used: u64,
    /// Asynchronous cache: blocks queued or being fetched now.
    pub blocks_pending: u64,
    /// Asynchronous cache: blocks fetched but not kept, because every resident block was in
    /// use by the frame and there was no room.
    pub blocks_dropped: u64,
    /// Asynchronous cache: distinct blocks the last frame wanted and did not find resident
    /// (blocks missing for good aside). 0: the frame showed everything it asked for.
    pub blocks_wanted_last_frame: u64,
    /// Asynchronous cache: the fetchers' CPU time spent reading and decoding blocks so far, in
    /// milliseconds (wall time where the system has no per-thread clock).
    pub fetch_cpu_ms: f64,
    /// Block reads made on render threads (the rayon pool frames are traced on), each one a
    /// render thread waiting on I/O: every miss of the blocking and mmap caches, and never one
    /// in the asynchronous cache, whose fetchers read.
    pub render_waits: u64,
    /// Blocks that could not be read or decoded, by id, with the reason; never retried.
    pub missing_blocks: Vec<MissingBlock>,
}

/// A block that could not be read or decoded; the cache never tries it again and reports it
/// as not available from then on.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
pub struct MissingBlock {
    /// The block's id (its index in the container's directory).
    pub id: u32,
    /// Why it failed: the reader's or decoder's error, or a block of the wrong kind.
    pub error: String,
}

/// A decoded block of either kind.
#[derive(Clone)]
pub(crate) enum Data {
    Treelets(Arc<TreeletData>),
    Triangles(Arc<TriangleData>),
}

impl Data {
    pub(crate) fn bytes(&self) -> usize {
        match self {
            Data::Treelets(d) => d.bytes(),
            Data::Triangles(d) => d.bytes(),
        }
    }

    /// Reads and decodes block `id` as the kind its directory entry names.
    pub(crate) fn load(scene: &Scene, id: u32) -> Result<Data, String> {
        let kind = scene.reader().entry(id).map_err(|e| e.to_string())?.kind;
        match kind {
            oocfmt::BlockKind::Treelet => scene
                .load_treelets(id)
                .map(|d| Data::Treelets(Arc::new(d)))
                .map_err(|e| e.to_string()),
            oocfmt::BlockKind::Triangle => scene
                .load_triangles(id)
                .map(|d| Data::Triangles(Arc::new(d)))
                .map_err(|e| e.to_string()),
            k => Err(format!(
                "a {k:?} block referenced as a treelet or triangle block"
            )),
        }
    }
}
