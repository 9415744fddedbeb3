//! The asynchronous cache (Áfra 2012 §5, Wald et al. 2004 §4): render threads never wait on
//! the disk. A lookup of a block that is not resident returns None at once and the traversal
//! falls back on the last voxel or the proxy of the missing subtree; the rays' wishes are
//! gathered as requests with priorities. Fetcher threads read, check and decode requested
//! blocks in the background. Between frames one step, [`BlockCache::end_frame`], publishes
//! what the fetchers finished, evicts least-recently-used blocks the frame did not touch when
//! room is needed, and hands the fetchers the new requests ranked by priority.
//!
//! During a frame the table of resident blocks is only read: render threads take a shared
//! read lock (no writer is ever waiting during a frame) and mark the blocks they use with the
//! frame number in an atomic. Requests go to sharded maps, once per block per tile. The budget
//! bounds every decoded byte the cache holds: the blocks in the table plus the blocks fetched
//! and waiting for publication. A fetcher reserves room for a block before handing it over;
//! the step between frames makes room for the requests it queues by evicting blocks the frame
//! did not use, and a block that still finds no room (every resident block in use by the
//! frame) is dropped and asked for again later.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError, RwLock};
use std::thread::JoinHandle;

use rustc_hash::FxHashMap as HashMap;

use super::{BlockCache, CacheStats, Data, MissingBlock};
use crate::blocks::{TreeletData, TriangleData};
use crate::scene::Scene;

/// Request maps, so that tiles finishing together rarely meet on one lock.
const SHARDS: usize = 16;

/// Priority of the root block: nothing shows without it.
const ROOT_PRIORITY: f32 = 1e9;

/// How many block levels below a block a ray asked for the fetchers read ahead by default
/// (the child blocks of each treelet block they decode, and theirs): rays reach one level
/// further per frame at most, so without reading ahead a cold view fills in a level every
/// frame or two.
pub const DEFAULT_READ_AHEAD: u8 = 2;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // Every update under these locks is a few field writes or a container operation: a panic
    // elsewhere cannot leave them half done in a way that matters.
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

struct Resident {
    data: Data,
    bytes: usize,
    /// The last frame that used the block.
    last_used: AtomicU64,
}

/// Work for the fetchers.
#[derive(Default)]
struct Queue {
    /// Block ids, lowest priority first: fetchers pop from the end.
    ids: Vec<u32>,
    /// Look-ahead work, served only when `ids` is empty and the cache has free room: block ids
    /// with how many more levels to read ahead below them.
    ahead: Vec<(u32, u8)>,
    /// Blocks queued or fetched ahead since the last step between frames.
    seen_ahead: rustc_hash::FxHashSet<u32>,
    in_flight: usize,
    shutdown: bool,
}

/// What a fetcher made of a block.
enum Outcome {
    /// Decoded, its bytes reserved in [`Shared::held`].
    Loaded(Data),
    /// Unreadable or undecodable: missing for good.
    Failed(String),
    /// Decoded but no room could be reserved: dropped, to be asked for again.
    NoRoom,
}

/// A block a fetcher read: its id, the outcome, and whether it was read ahead.
type Fetched = (u32, Outcome, bool);

/// What the cache and its fetchers share.
struct Shared {
    scene: Arc<Scene>,
    queue: Mutex<Queue>,
    /// Signalled when work arrives or the cache closes.
    work: Condvar,
    /// Signalled when a fetcher finishes a block.
    finished: Condvar,
    /// Blocks fetched since the last publication, or why they could not be, and whether they
    /// were read ahead (kept only in free room, never evicting for them).
    done: Mutex<Vec<Fetched>>,
    /// Decoded bytes held: published plus fetched and waiting for publication. Never above
    /// `budget`: fetchers reserve before they hand a block over. Look-ahead reads stop at half.
    held: AtomicU64,
    /// The most `held` has been.
    peak: AtomicU64,
    budget: u64,
    /// Levels read ahead below each block a ray asked for (0: none).
    read_ahead: u8,
}

/// What only the step between frames changes.
#[derive(Default)]
struct Book {
    resident_bytes: usize,
    loaded: u64,
    evicted: u64,
    requested: u64,
    /// Look-ahead requests among `requested`.
    looked_ahead: u64,
    dropped: u64,
    wanted_last_frame: u64,
    /// Handed to the fetchers and not yet published.
    fetching: rustc_hash::FxHashSet<u32>,
    missing: BTreeMap<u32, String>,
}

pub struct AsyncCache {
    shared: Arc<Shared>,
    fetchers: Vec<JoinHandle<()>>,
    budget: usize,
    table: RwLock<HashMap<u32, Arc<Resident>>>,
    /// The frame being rendered; blocks used by it are not evicted.
    frame: AtomicU64,
    requests: Vec<Mutex<HashMap<u32, f32>>>,
    book: Mutex<Book>,
    lookups: AtomicU64,
    hits: AtomicU64,
}

impl AsyncCache {
    /// A cache of `budget_bytes` decoded bytes with `fetchers` background threads (at least
    /// one). The root treelet block is loaded here, as the proxies are at open, so that the
    /// first frame has the root's voxels and proxies to show.
    pub fn new(scene: Arc<Scene>, budget_bytes: usize, fetchers: usize) -> AsyncCache {
        AsyncCache::with_read_ahead(scene, budget_bytes, fetchers, DEFAULT_READ_AHEAD)
    }

    /// [`AsyncCache::new`] reading `levels` block levels ahead of the blocks rays ask for, into
    /// free room only (while less than half the budget is resident); 0 reads nothing ahead.
    pub fn with_read_ahead(
        scene: Arc<Scene>,
        budget_bytes: usize,
        fetchers: usize,
        levels: u8,
    ) -> AsyncCache {
        let root = scene.metadata().root.map(|r| r.block);
        let shared = Arc::new(Shared {
            scene,
            queue: Mutex::new(Queue::default()),
            work: Condvar::new(),
            finished: Condvar::new(),
            done: Mutex::new(Vec::new()),
            held: AtomicU64::new(0),
            peak: AtomicU64::new(0),
            budget: budget_bytes as u64,
            read_ahead: levels,
        });
        let handles = (0..fetchers.max(1))
            .map(|_| {
                let s = Arc::clone(&shared);
                std::thread::spawn(move || fetch_loop(&s))
            })
            .collect();
        let cache = AsyncCache {
            shared,
            fetchers: handles,
            budget: budget_bytes,
            table: RwLock::new(HashMap::default()),
            frame: AtomicU64::new(0),
            requests: (0..SHARDS)
                .map(|_| Mutex::new(HashMap::default()))
                .collect(),
            book: Mutex::new(Book::default()),
            lookups: AtomicU64::new(0),
            hits: AtomicU64::new(0),
        };
        if let Some(r) = root {
            let outcome = cache.shared.load(r, false);
            lock(&cache.shared.done).push((r, outcome, false));
            let mut book = lock(&cache.book);
            cache.publish(&mut book, 0);
        }
        cache
    }

    pub fn scene(&self) -> &Arc<Scene> {
        &self.shared.scene
    }

    /// Waits until the fetchers have nothing queued or in flight. For callers between frames
    /// that want a still image to converge (tests, a single-frame render); render threads
    /// never call it.
    pub fn wait_for_fetchers(&self) {
        let mut q = lock(&self.shared.queue);
        while !q.shutdown && (!q.ids.is_empty() || q.in_flight > 0) {
            q = self
                .shared
                .finished
                .wait(q)
                .unwrap_or_else(PoisonError::into_inner);
        }
    }

    fn lookup(&self, id: u32) -> Option<Data> {
        self.lookups.fetch_add(1, Relaxed);
        let table = self.table.read().unwrap_or_else(PoisonError::into_inner);
        let r = table.get(&id)?;
        let frame = self.frame.load(Relaxed);
        // A load first: most lookups of a frame find the mark already set and leave the
        // cache line shared.
        if r.last_used.load(Relaxed) != frame {
            r.last_used.store(frame, Relaxed);
        }
        self.hits.fetch_add(1, Relaxed);
        Some(r.data.clone())
    }

    /// A block referenced as one kind and stored as another: the file is malformed there, and
    /// the block is missing for good for both uses.
    fn wrong_kind<T>(&self, id: u32, is: &str, wanted: &str) -> Option<T> {
        lock(&self.book)
            .missing
            .entry(id)
            .or_insert_with(|| format!("a {is} block where a {wanted} block was expected"));
        None
    }

    /// Publishes the fetched blocks (their room is reserved already).
    fn publish(&self, book: &mut Book, frame: u64) {
        let done = std::mem::take(&mut *lock(&self.shared.done));
        if done.is_empty() {
            return;
        }
        let mut table = self.table.write().unwrap_or_else(PoisonError::into_inner);
        for (id, outcome, ahead) in done {
            book.fetching.remove(&id);
            let data = match outcome {
                Outcome::Loaded(d) => d,
                Outcome::Failed(e) => {
                    book.missing.entry(id).or_insert(e);
                    continue;
                }
                Outcome::NoRoom => {
                    if !ahead {
                        book.dropped += 1;
                    }
                    continue;
                }
            };
            let bytes = data.bytes();
            // Read ahead and asked for at once, or asked for again while it was in flight: the
            // same block, kept once.
            if table.contains_key(&id) {
                self.shared.held.fetch_sub(bytes as u64, Relaxed);
                continue;
            }
            book.resident_bytes += bytes;
            book.loaded += 1;
            if ahead {
                book.looked_ahead += 1;
            }
            table.insert(
                id,
                Arc::new(Resident {
                    data,
                    bytes,
                    // A block read ahead is unused so far: the first to go when room is needed.
                    last_used: AtomicU64::new(if ahead { 0 } else { frame }),
                }),
            );
        }
    }

    /// Evicts least-recently-used blocks that frame `frame` did not use until `wanted` more
    /// bytes fit the budget, or nothing is left to evict.
    fn make_room(&self, book: &mut Book, frame: u64, wanted: u64) {
        let held = |s: &Shared| s.held.load(Relaxed);
        if held(&self.shared) + wanted <= self.shared.budget {
            return;
        }
        let mut table = self.table.write().unwrap_or_else(PoisonError::into_inner);
        // Least recently used first (ties by id, for repeatable runs).
        let mut victims: Vec<(u64, u32)> = table
            .iter()
            .map(|(&id, r)| (r.last_used.load(Relaxed), id))
            .filter(|&(used, _)| used < frame)
            .collect();
        victims.sort_unstable();
        for (_, victim) in victims {
            if held(&self.shared) + wanted <= self.shared.budget {
                break;
            }
            if let Some(r) = table.remove(&victim) {
                book.resident_bytes -= r.bytes;
                book.evicted += 1;
                self.shared.held.fetch_sub(r.bytes as u64, Relaxed);
            }
        }
    }
}

impl Shared {
    /// Reads and decodes block `id` and reserves room for it.
    fn load(&self, id: u32, ahead: bool) -> Outcome {
        let data = match Data::load(&self.scene, id) {
            Ok(d) => d,
            Err(e) => return Outcome::Failed(e),
        };
        let bytes = data.bytes() as u64;
        if bytes > self.budget && !ahead {
            return Outcome::Failed(format!(
                "the decoded block needs {bytes} bytes, over the cache budget of {}",
                self.budget
            ));
        }
        let reserved = self.held.fetch_update(Relaxed, Relaxed, |h| {
            (h + bytes <= self.budget).then_some(h + bytes)
        });
        match reserved {
            Ok(before) => {
                self.peak.fetch_max(before + bytes, Relaxed);
                Outcome::Loaded(data)
            }
            Err(_) => Outcome::NoRoom,
        }
    }

    /// Decoded bytes a block is expected to take, from its directory entry, for making room
    /// before it is fetched. Three times the raw bytes is an estimate (16-byte decoded nodes
    /// for 8-byte stored ones, 36 bytes of corners for a triangle's indices and shared
    /// vertices), not a bound: a block that finds too little room is dropped and asked for
    /// again, never kept over the budget.
    fn estimate(&self, id: u32) -> u64 {
        self.scene
            .reader()
            .entry(id)
            .map_or(0, |e| 3 * u64::from(e.raw_length))
    }
}

fn fetch_loop(s: &Shared) {
    loop {
        let (id, levels, ahead) = {
            let mut q = lock(&s.queue);
            loop {
                if q.shutdown {
                    return;
                }
                if let Some(id) = q.ids.pop() {
                    q.in_flight += 1;
                    break (id, s.read_ahead, false);
                }
                let room = s.held.load(Relaxed) < s.budget / 2;
                if let Some((id, levels)) = q.ahead.pop().filter(|_| room) {
                    q.in_flight += 1;
                    break (id, levels, true);
                }
                q = s.work.wait(q).unwrap_or_else(PoisonError::into_inner);
            }
        };
        let outcome = s.load(id, ahead);
        let children: Vec<u32> = match &outcome {
            Outcome::Loaded(Data::Treelets(d)) if levels > 0 => {
                d.lods.iter().map(|l| l.child_block).collect()
            }
            _ => Vec::new(),
        };
        lock(&s.done).push((id, outcome, ahead));
        let mut q = lock(&s.queue);
        q.in_flight -= 1;
        for c in children {
            if q.seen_ahead.insert(c) {
                q.ahead.push((c, levels - 1));
            }
        }
        drop(q);
        s.work.notify_all();
        s.finished.notify_all();
    }
}

impl BlockCache for AsyncCache {
    fn treelets(&self, id: u32) -> Option<Arc<TreeletData>> {
        match self.lookup(id)? {
            Data::Treelets(d) => Some(d),
            Data::Triangles(_) => self.wrong_kind(id, "triangle", "treelet"),
        }
    }

    fn triangles(&self, id: u32) -> Option<Arc<TriangleData>> {
        match self.lookup(id)? {
            Data::Triangles(d) => Some(d),
            Data::Treelets(_) => self.wrong_kind(id, "treelet", "triangle"),
        }
    }

    fn request(&self, wanted: &[(u32, f32)]) {
        for &(id, p) in wanted {
            let mut shard = lock(&self.requests[id as usize % SHARDS]);
            *shard.entry(id).or_insert(0.0) += p;
        }
    }

    fn end_frame(&self) {
        let mut book = lock(&self.book);
        let frame = self.frame.load(Relaxed);
        let root = self.shared.scene.metadata().root.map(|r| r.block);
        // What the frame wanted, before publishing: a block that arrived during the frame
        // still counts as wanted by it.
        let mut ranked: Vec<(f32, u32)> = Vec::new();
        for shard in &self.requests {
            for (id, p) in lock(shard).drain() {
                if !book.missing.contains_key(&id) {
                    let p = if Some(id) == root { ROOT_PRIORITY } else { p };
                    ranked.push((p, id));
                }
            }
        }
        book.wanted_last_frame = ranked.len() as u64;
        self.publish(&mut book, frame);
        {
            let table = self.table.read().unwrap_or_else(PoisonError::into_inner);
            ranked.retain(|(_, id)| !table.contains_key(id) && !book.fetching.contains(id));
        }
        // Room for what is asked, up to half the budget: the rest of the requests fetch into
        // room that later steps make.
        let wanted: u64 = ranked.iter().map(|&(_, id)| self.shared.estimate(id)).sum();
        self.make_room(&mut book, frame, wanted.min(self.shared.budget / 2));
        // Lowest first, as the fetchers pop from the end.
        ranked.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)));
        book.requested += ranked.len() as u64;
        {
            let mut q = lock(&self.shared.queue);
            // Blocks queued for the last frame and not wanted by this one are forgotten; the
            // ones still wanted are among this frame's requests.
            for id in q.ids.drain(..) {
                book.fetching.remove(&id);
            }
            // Reading ahead follows the blocks rays asked for; a new frame starts it afresh,
            // skipping what is resident or asked for.
            q.ahead.clear();
            q.seen_ahead.clear();
            let table = self.table.read().unwrap_or_else(PoisonError::into_inner);
            q.seen_ahead.extend(table.keys().copied());
            q.seen_ahead.extend(ranked.iter().map(|&(_, id)| id));
            for &(_, id) in &ranked {
                book.fetching.insert(id);
            }
            q.ids = ranked.into_iter().map(|(_, id)| id).collect();
        }
        self.shared.work.notify_all();
        self.frame.store(frame + 1, Relaxed);
    }

    fn stats(&self) -> CacheStats {
        let b = lock(&self.book);
        let pending = {
            let q = lock(&self.shared.queue);
            q.ids.len() + q.in_flight
        };
        CacheStats {
            mode: "async",
            budget_bytes: self.budget as u64,
            bytes_resident: b.resident_bytes as u64,
            peak_bytes_resident: self.shared.peak.load(Relaxed),
            lookups: self.lookups.load(Relaxed),
            hits: self.hits.load(Relaxed),
            blocks_loaded: b.loaded,
            blocks_evicted: b.evicted,
            blocks_requested: b.requested,
            blocks_looked_ahead: b.looked_ahead,
            blocks_pending: pending as u64,
            blocks_dropped: b.dropped,
            blocks_wanted_last_frame: b.wanted_last_frame,
            missing_blocks: b
                .missing
                .iter()
                .map(|(&id, e)| MissingBlock {
                    id,
                    error: e.clone(),
                })
                .collect(),
        }
    }
}

impl Drop for AsyncCache {
    fn drop(&mut self) {
        lock(&self.shared.queue).shutdown = true;
        self.shared.work.notify_all();
        self.shared.finished.notify_all();
        for h in self.fetchers.drain(..) {
            // A fetcher that panicked has nothing left to clean up.
            let _ = h.join();
        }
    }
}
