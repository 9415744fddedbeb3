//! The blocking cache: a render thread that needs a block not in memory reads and decodes it
//! itself and waits for it. The exact reference: every ray sees full detail where it asks for it.
//!
//! One mutex guards the table. It is never held across a read: two threads that miss on the
//! same block may both decode it, and the second one's copy is dropped. Residency is bounded
//! by a byte budget with least-recently-used eviction; blocks in use by a ray stay alive through
//! their `Arc` after eviction, so the budget bounds the table, not short-lived borrows.

use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex, MutexGuard};

use super::waits::Waits;
use super::{BlockCache, CacheStats, Data, MissingBlock};
use crate::blocks::{TreeletData, TriangleData};
use crate::scene::Scene;

struct Slot {
    data: Data,
    bytes: usize,
    stamp: u64,
}

#[derive(Default)]
struct Table {
    slots: HashMap<u32, Slot>,
    /// Block id by last-use stamp, oldest first.
    lru: BTreeMap<u64, u32>,
    clock: u64,
    resident: usize,
    peak: usize,
    lookups: u64,
    hits: u64,
    loaded: u64,
    evicted: u64,
    missing: BTreeMap<u32, String>,
}

/// The blocking cache: misses are read and decoded on the render thread that met them, within
/// a byte budget with least-recently-used eviction.
pub struct BlockingCache {
    scene: Arc<Scene>,
    budget: usize,
    mode: &'static str,
    table: Mutex<Table>,
    /// Misses read on render threads: each a wait on I/O.
    waits: Waits,
}

impl BlockingCache {
    /// A cache over `scene` holding up to `budget_bytes` decoded bytes (the block just loaded
    /// stays even when it alone is over the budget).
    pub fn new(scene: Arc<Scene>, budget_bytes: usize) -> BlockingCache {
        Self::with_mode(scene, budget_bytes, "blocking")
    }

    /// The mmap cache is this cache over a mapped file; only the name in the stats differs.
    pub(crate) fn with_mode(scene: Arc<Scene>, budget_bytes: usize, mode: &'static str) -> Self {
        BlockingCache {
            scene,
            budget: budget_bytes,
            mode,
            table: Mutex::new(Table::default()),
            waits: Waits::default(),
        }
    }

    /// The scene the cache loads blocks from.
    pub fn scene(&self) -> &Arc<Scene> {
        &self.scene
    }

    fn lock(&self) -> MutexGuard<'_, Table> {
        // A panic elsewhere cannot leave the table half-updated in a way that matters here:
        // every update is a few field writes.
        self.table.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn get(&self, id: u32, load: impl FnOnce(&Scene) -> oocfmt::Result<Data>) -> Option<Data> {
        {
            let mut t = self.lock();
            t.lookups += 1;
            if t.missing.contains_key(&id) {
                return None;
            }
            let stamp = t.clock + 1;
            if let Some(slot) = t.slots.get_mut(&id) {
                let (old, data) = (slot.stamp, slot.data.clone());
                slot.stamp = stamp;
                t.clock = stamp;
                t.hits += 1;
                t.lru.remove(&old);
                t.lru.insert(stamp, id);
                return Some(data);
            }
        }
        let loaded = self.waits.read(|| load(&self.scene));
        let mut t = self.lock();
        let data = match loaded {
            Ok(d) => d,
            Err(e) => {
                t.missing.insert(id, e.to_string());
                return None;
            }
        };
        if let Some(slot) = t.slots.get(&id) {
            return Some(slot.data.clone());
        }
        let bytes = data.bytes();
        t.clock += 1;
        let stamp = t.clock;
        t.slots.insert(
            id,
            Slot {
                data: data.clone(),
                bytes,
                stamp,
            },
        );
        t.lru.insert(stamp, id);
        t.resident += bytes;
        t.loaded += 1;
        while t.resident > self.budget {
            let Some((&old, &victim)) = t.lru.iter().next() else {
                break;
            };
            if victim == id {
                break; // the block just loaded stays, even when it alone is over the budget
            }
            t.lru.remove(&old);
            if let Some(s) = t.slots.remove(&victim) {
                t.resident -= s.bytes;
                t.evicted += 1;
            }
        }
        t.peak = t.peak.max(t.resident);
        Some(data)
    }
}

impl BlockingCache {
    /// A block referenced as one kind after it was loaded as another: the file is malformed
    /// there, and the block is missing for good for both uses.
    fn wrong_kind<T>(&self, id: u32, is: &str, wanted: &str) -> Option<T> {
        let mut t = self.lock();
        t.missing
            .entry(id)
            .or_insert_with(|| format!("a {is} block where a {wanted} block was expected"));
        None
    }
}

impl BlockCache for BlockingCache {
    fn treelets(&self, id: u32) -> Option<Arc<TreeletData>> {
        match self.get(id, |s| {
            s.load_treelets(id).map(|d| Data::Treelets(Arc::new(d)))
        })? {
            Data::Treelets(d) => Some(d),
            Data::Triangles(_) => self.wrong_kind(id, "triangle", "treelet"),
        }
    }

    fn triangles(&self, id: u32) -> Option<Arc<TriangleData>> {
        match self.get(id, |s| {
            s.load_triangles(id).map(|d| Data::Triangles(Arc::new(d)))
        })? {
            Data::Triangles(d) => Some(d),
            Data::Treelets(_) => self.wrong_kind(id, "treelet", "triangle"),
        }
    }

    fn stats(&self) -> CacheStats {
        let t = self.lock();
        CacheStats {
            mode: self.mode,
            io: self.scene.reader().io_mode().name(),
            render_waits: self.waits.count(),
            budget_bytes: self.budget as u64,
            bytes_resident: t.resident as u64,
            peak_bytes_resident: t.peak as u64,
            lookups: t.lookups,
            hits: t.hits,
            blocks_loaded: t.loaded,
            blocks_evicted: t.evicted,
            missing_blocks: t
                .missing
                .iter()
                .map(|(&id, e)| MissingBlock {
                    id,
                    error: e.clone(),
                })
                .collect(),
            // What only the asynchronous cache does stays 0.
            ..CacheStats::default()
        }
    }

    fn render_waits(&self) -> u64 {
        self.waits.count()
    }
}
