//! The asynchronous cache (Áfra 2012 §5, Wald et al. 2004 §4): render threads never wait on
//! the disk. A lookup of a block that is not resident returns None at once and the traversal
//! falls back on the last voxel or the proxy of the missing subtree; the rays' wishes are
//! gathered as requests with priorities. Fetcher threads read, check and decode requested
//! blocks in the background. Between frames one step, [`BlockCache::end_frame`], publishes
//! what the fetchers finished, evicts blocks the frame did not touch (least recently used, or
//! by a second-chance sweep: [`policy`]) and hands the fetchers the new requests ranked by
//! priority (Áfra's or Wald's). Look-ahead prefetching (Correa et al. 2002,
//! [`crate::cache::prefetch`]) adds a second queue, served only when no demand fetch waits and
//! only up to a per-frame budget. Fetching while a frame renders shares a per-frame budget of CPU
//! time, a share of the last frame's duration ([`AsyncOptions::fetch_share`]), so that a burst
//! of requests arrives over several frames instead of slowing one down; between frames, once
//! the caller says it will not render for a while ([`AsyncCache::idle`]), the fetchers work
//! without that limit.
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
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering::Relaxed};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError, RwLock};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use rustc_hash::FxHashMap as HashMap;

use super::policy::{self, Clock, Eviction, FetchOrder, Range, Verdict, HIGH_WATER};
use super::waits::Waits;
use super::{BlockCache, CacheStats, Data, MissingBlock, Wish};
use crate::blocks::{TreeletData, TriangleData};
use crate::scene::Scene;

/// Request maps, so that tiles finishing together rarely meet on one lock.
const SHARDS: usize = 16;

/// How many block levels below a block a ray asked for the fetchers read ahead by default
/// (the child blocks of each treelet block they decode, and theirs): rays reach one level
/// further per frame at most, so without reading ahead a cold view fills in a level every
/// frame or two.
pub const DEFAULT_READ_AHEAD: u8 = 2;

/// How an asynchronous cache fetches, evicts and prefetches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AsyncOptions {
    /// Fetcher threads (at least one is started).
    pub fetchers: usize,
    /// Block levels read ahead below each block a ray asked for, into free room only (while
    /// less than half the budget is held); 0 reads nothing ahead.
    pub read_ahead: u8,
    /// The order the fetchers serve a frame's requests in.
    pub fetch_order: FetchOrder,
    /// How room is made for new blocks.
    pub eviction: Eviction,
    /// How many nice levels below the thread that creates the cache the fetchers run (Linux
    /// only; elsewhere they keep the render threads' priority): above 0 the render threads get
    /// the CPU first, so decoding a burst of blocks slows a frame down less, and blocks arrive
    /// later.
    pub fetcher_nice: u8,
    /// CPU time the fetchers may spend reading and decoding blocks while a frame renders, as a
    /// share of the last frame's duration (from its start, [`BlockCache::begin_frame`], to the
    /// step after it): a fetcher starts a block only while less was spent since the last step,
    /// so a burst of requests is spread over frames instead of slowing one down (a frame may go
    /// over by a block per fetcher). Blocks started while the caller is idle
    /// ([`AsyncCache::idle`]) do not count. `f64::INFINITY`: no limit.
    pub fetch_share: f64,
    /// Decoded bytes look-ahead prefetching may load per frame ([`AsyncCache::prefetch`]); a
    /// fetcher starts a prefetch only while less than this was loaded since the last call, so
    /// a frame may go over by a block per fetcher.
    pub prefetch_bytes: u64,
}

impl Default for AsyncOptions {
    fn default() -> Self {
        AsyncOptions {
            fetchers: 2,
            read_ahead: DEFAULT_READ_AHEAD,
            fetch_order: FetchOrder::Afra,
            eviction: Eviction::Lru,
            fetcher_nice: DEFAULT_FETCHER_NICE,
            fetch_share: DEFAULT_FETCH_SHARE,
            prefetch_bytes: 0,
        }
    }
}

/// How many nice levels below the render threads the fetchers run by default: about a tenth of
/// a core while 2 cores render, and all the time left between frames (at 19 a 10M walkthrough
/// never converged; docs/notes/2026-12-01-fetch-share.md).
pub const DEFAULT_FETCHER_NICE: u8 = 10;

/// The fetchers' default CPU time per frame, as a share of the last frame's duration. In-frame
/// fetching takes its CPU from the render threads, so with R threads a frame of warm time W
/// takes W / (1 − s/R) once the budget is spent: 1.08 W at 0.15 on 2 cores, which still reaches
/// full detail as fast as larger shares (docs/notes/2026-12-01-fetch-share.md).
pub const DEFAULT_FETCH_SHARE: f64 = 0.15;

/// CPU time the calling thread has used, where the system tells (Linux); else `None`, and
/// fetch budgets count wall time instead.
#[cfg(target_os = "linux")]
fn thread_cpu_time() -> Option<Duration> {
    let t = rustix::time::clock_gettime(rustix::time::ClockId::ThreadCPUTime);
    Some(Duration::new(
        u64::try_from(t.tv_sec).ok()?,
        u32::try_from(t.tv_nsec).ok()?,
    ))
}

#[cfg(not(target_os = "linux"))]
fn thread_cpu_time() -> Option<Duration> {
    None
}

/// Lowers the calling thread's priority by `levels` nice levels (to 19 at most); false where
/// the system refused or cannot. On Linux the nice value belongs to the thread, not the
/// process, and a new thread starts at its creator's: counting from there keeps the fetchers
/// the same distance below the render threads when the whole process runs at another priority
/// (`nice -n -10 oocfmt render ...` gives the render threads the CPU before the system's own
/// threads, and the fetchers still get a tenth of a core against each).
#[cfg(target_os = "linux")]
fn lower_this_thread(levels: u8) -> bool {
    let tid = rustix::thread::gettid();
    let Ok(now) = rustix::process::getpriority_process(Some(tid)) else {
        return false;
    };
    rustix::process::setpriority_process(Some(tid), (now + i32::from(levels)).min(19)).is_ok()
}

/// Elsewhere `setpriority` renices the whole process: fetchers keep the render threads'
/// priority.
#[cfg(not(target_os = "linux"))]
fn lower_this_thread(_levels: u8) -> bool {
    false
}

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
    /// The second-chance bit: set by the first use in a frame, cleared by the clock hand.
    referenced: AtomicBool,
    /// Loaded by prefetching and not used since.
    prefetched: AtomicBool,
}

/// Work for the fetchers.
#[derive(Default)]
struct Queue {
    /// Block ids, lowest priority first: fetchers pop from the end.
    ids: Vec<u32>,
    /// Prefetch requests, lowest priority first: served when `ids` is empty, within the
    /// per-frame prefetch budget.
    prefetch: Vec<u32>,
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

/// Why a block was fetched.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Why {
    /// A ray asked for it.
    Demand,
    /// A child of a block a fetcher decoded (kept in free room only).
    ReadAhead,
    /// A predicted view would want it.
    Prefetch,
}

/// A block a fetcher read: its id, the outcome, and why it was read.
type Fetched = (u32, Outcome, Why);

/// What the cache and its fetchers share.
struct Shared {
    scene: Arc<Scene>,
    queue: Mutex<Queue>,
    /// Signalled when work arrives or the cache closes.
    work: Condvar,
    /// Signalled when a fetcher finishes a block.
    finished: Condvar,
    /// Blocks fetched since the last publication, or why they could not be, and why they were
    /// fetched.
    done: Mutex<Vec<Fetched>>,
    /// Decoded bytes held: published plus fetched and waiting for publication. Never above
    /// `budget`: fetchers reserve before they hand a block over. Look-ahead reads stop at half.
    held: AtomicU64,
    /// The most `held` has been.
    peak: AtomicU64,
    budget: u64,
    /// Levels read ahead below each block a ray asked for (0: none).
    read_ahead: u8,
    /// The per-frame prefetch budget and the decoded bytes prefetched since the last
    /// [`AsyncCache::prefetch`].
    prefetch_bytes: u64,
    prefetch_spent: AtomicU64,
    /// The fetchers' share of a frame ([`AsyncOptions::fetch_share`]), the nanoseconds of
    /// fetching it allows until the next step (`u64::MAX`: no limit) and those spent since.
    fetch_share: f64,
    fetch_allowed_ns: AtomicU64,
    fetch_spent_ns: AtomicU64,
    /// Set by [`AsyncCache::idle`], cleared when the next frame begins. While it
    /// is set no frame is rendering, so fetching slows none down.
    idle: AtomicBool,
    /// When the frame being rendered started (its beginning after an idle spell, else the
    /// step before it), in nanoseconds since `epoch`.
    frame_start_ns: AtomicU64,
    epoch: Instant,
    /// Every nanosecond of fetching since the cache opened.
    fetch_total_ns: AtomicU64,
    /// Fetchers whose lower priority the system refused.
    refused: AtomicUsize,
    /// Block reads made on render threads: none, by design (the fetchers read); counted so
    /// that a test holds the design to it.
    waits: Waits,
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
    prefetched: u64,
    dropped: u64,
    wanted_last_frame: u64,
    /// Handed to the fetchers and not yet published.
    fetching: rustc_hash::FxHashSet<u32>,
    missing: BTreeMap<u32, String>,
    /// The second-chance ring (second-chance eviction only).
    clock: Clock,
    /// The range of the last frame's Wald priorities.
    wald_range: Option<Range>,
}

/// The asynchronous cache: render threads only look blocks up; background fetcher threads
/// load what the frames asked for, published between frames ([`BlockCache::end_frame`]).
pub struct AsyncCache {
    shared: Arc<Shared>,
    fetchers: Vec<JoinHandle<()>>,
    budget: usize,
    fetch_order: FetchOrder,
    eviction: Eviction,
    fetcher_nice: u8,
    table: RwLock<HashMap<u32, Arc<Resident>>>,
    /// The frame being rendered; blocks used by it are not evicted.
    frame: AtomicU64,
    requests: Vec<Mutex<HashMap<u32, Wish>>>,
    book: Mutex<Book>,
    lookups: AtomicU64,
    hits: AtomicU64,
    prefetch_used: AtomicU64,
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
        let opts = AsyncOptions {
            fetchers,
            read_ahead: levels,
            ..AsyncOptions::default()
        };
        AsyncCache::with_options(scene, budget_bytes, &opts)
    }

    /// A cache of `budget_bytes` decoded bytes that fetches, evicts and prefetches as `opts`
    /// says.
    pub fn with_options(scene: Arc<Scene>, budget_bytes: usize, opts: &AsyncOptions) -> AsyncCache {
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
            read_ahead: opts.read_ahead,
            prefetch_bytes: opts.prefetch_bytes,
            prefetch_spent: AtomicU64::new(0),
            fetch_share: opts.fetch_share,
            fetch_allowed_ns: AtomicU64::new(u64::MAX),
            fetch_spent_ns: AtomicU64::new(0),
            idle: AtomicBool::new(false),
            frame_start_ns: AtomicU64::new(0),
            epoch: Instant::now(),
            fetch_total_ns: AtomicU64::new(0),
            refused: AtomicUsize::new(0),
            waits: Waits::default(),
        });
        let nice = opts.fetcher_nice;
        let handles = (0..opts.fetchers.max(1))
            .map(|_| {
                let s = Arc::clone(&shared);
                std::thread::spawn(move || {
                    // Where the system refuses, the fetcher runs at normal priority and the
                    // stats say so.
                    if nice > 0 && !lower_this_thread(nice) {
                        s.refused.fetch_add(1, Relaxed);
                    }
                    fetch_loop(&s)
                })
            })
            .collect();
        let cache = AsyncCache {
            shared,
            fetchers: handles,
            fetcher_nice: opts.fetcher_nice,
            budget: budget_bytes,
            fetch_order: opts.fetch_order,
            eviction: opts.eviction,
            table: RwLock::new(HashMap::default()),
            frame: AtomicU64::new(0),
            requests: (0..SHARDS)
                .map(|_| Mutex::new(HashMap::default()))
                .collect(),
            book: Mutex::new(Book::default()),
            lookups: AtomicU64::new(0),
            hits: AtomicU64::new(0),
            prefetch_used: AtomicU64::new(0),
        };
        if let Some(r) = root {
            let outcome = cache.shared.load(r, Why::Demand);
            lock(&cache.shared.done).push((r, outcome, Why::Demand));
            let mut book = lock(&cache.book);
            cache.publish(&mut book, 0);
        }
        cache
            .shared
            .frame_start_ns
            .store(cache.shared.now_ns(), Relaxed);
        cache
    }

    /// The scene the fetchers load blocks from.
    pub fn scene(&self) -> &Arc<Scene> {
        &self.shared.scene
    }

    /// Waits until the fetchers have nothing queued or in flight. For callers between frames
    /// that want a still image to converge (tests, a single-frame render); render threads
    /// never call it.
    pub fn wait_for_fetchers(&self) {
        let mut q = lock(&self.shared.queue);
        // A caller that waits wants every block now: no per-frame limit until the next step.
        // Lifted under the queue's lock, which a fetcher holds from finding no room until it
        // waits for work: lifted outside it, the wake-up could come before that wait, and the
        // fetcher would sleep through it while this waits for it for ever.
        self.shared.fetch_allowed_ns.store(u64::MAX, Relaxed);
        self.shared.work.notify_all();
        while !q.shutdown && (!q.ids.is_empty() || q.in_flight > 0 || self.prefetch_waits(&q)) {
            q = self
                .shared
                .finished
                .wait(q)
                .unwrap_or_else(PoisonError::into_inner);
        }
    }

    /// Says that the caller will not render until its next frame (it writes an image, waits
    /// for the display, reads input): until that frame begins the fetchers work without the
    /// per-frame limit, and what they spend does not count against the frame. Render threads
    /// never call it; a walkthrough calls it after each step.
    pub fn idle(&self) {
        // Under the queue's lock, as in `wait_for_fetchers`: a fetcher that found no room must
        // not miss the wake-up (it would sleep through the idle spell).
        let _q = lock(&self.shared.queue);
        self.shared.idle.store(true, Relaxed);
        self.shared.work.notify_all();
    }

    fn lookup(&self, id: u32) -> Option<Data> {
        self.lookups.fetch_add(1, Relaxed);
        let table = self.table.read().unwrap_or_else(PoisonError::into_inner);
        let r = table.get(&id)?;
        let frame = self.frame.load(Relaxed);
        // A load first: most lookups of a frame find the mark already set and leave the
        // cache line shared. The first use in a frame also sets the second-chance bit (the
        // hand clears it between frames only).
        if r.last_used.load(Relaxed) != frame {
            r.last_used.store(frame, Relaxed);
            r.referenced.store(true, Relaxed);
            if r.prefetched.swap(false, Relaxed) {
                self.prefetch_used.fetch_add(1, Relaxed);
            }
        }
        self.hits.fetch_add(1, Relaxed);
        Some(r.data.clone())
    }

    /// A resident block, without counting a lookup or marking it used: what look-ahead probes
    /// see (a guess must not change what is evicted).
    pub(super) fn peek(&self, id: u32) -> Option<Data> {
        let table = self.table.read().unwrap_or_else(PoisonError::into_inner);
        table.get(&id).map(|r| r.data.clone())
    }

    /// Whether a prefetch is queued that the fetchers will still start (within the budget).
    fn prefetch_waits(&self, q: &Queue) -> bool {
        !q.prefetch.is_empty() && self.shared.prefetch_room()
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

    /// Queues look-ahead prefetch requests (see [`crate::cache::prefetch`]), replacing those
    /// not started yet: the blocks of `wanted` not resident, missing or being fetched, in the
    /// fetch order, as many of the highest-priority ones as the per-frame prefetch budget
    /// allows by their estimated size. Room is made for them by evicting blocks the frame
    /// just rendered did not use; the fetchers serve them only when no demand fetch waits.
    /// Returns how many were queued; 0 when the cache has no prefetch budget.
    pub fn prefetch(&self, mut wanted: Vec<(u32, Wish)>) -> usize {
        let allowed = self.shared.prefetch_bytes;
        if allowed == 0 {
            return 0;
        }
        let mut book = lock(&self.book);
        {
            let table = self.table.read().unwrap_or_else(PoisonError::into_inner);
            wanted.retain(|(id, _)| {
                !table.contains_key(id)
                    && !book.fetching.contains(id)
                    && !book.missing.contains_key(id)
            });
        }
        let (ranked, _) = policy::rank(wanted, self.fetch_order, book.wald_range, None);
        // The highest-priority requests (at the end) that the budget allows.
        let mut bytes = 0u64;
        let first = ranked
            .iter()
            .rev()
            .take_while(|&&id| {
                bytes += self.shared.estimate(id);
                bytes <= allowed
            })
            .count();
        let kept = ranked.get(ranked.len() - first..).unwrap_or(&[]).to_vec();
        let bytes: u64 = kept.iter().map(|&id| self.shared.estimate(id)).sum();
        // The step after frame f has set the frame counter to f + 1: the blocks f used stay.
        let just_rendered = self.frame.load(Relaxed).saturating_sub(1);
        self.make_room(&mut book, just_rendered, bytes.min(self.shared.budget / 2));
        let mut q = lock(&self.shared.queue);
        for id in q.prefetch.drain(..) {
            book.fetching.remove(&id);
        }
        book.fetching.extend(kept.iter().copied());
        q.seen_ahead.extend(kept.iter().copied());
        q.prefetch = kept;
        let n = q.prefetch.len();
        self.shared.prefetch_spent.store(0, Relaxed);
        drop(q);
        self.shared.work.notify_all();
        n
    }

    /// Publishes the fetched blocks (their room is reserved already).
    fn publish(&self, book: &mut Book, frame: u64) {
        let done = std::mem::take(&mut *lock(&self.shared.done));
        if done.is_empty() {
            return;
        }
        let mut table = self.table.write().unwrap_or_else(PoisonError::into_inner);
        for (id, outcome, why) in done {
            book.fetching.remove(&id);
            let data = match outcome {
                Outcome::Loaded(d) => d,
                Outcome::Failed(e) => {
                    book.missing.entry(id).or_insert(e);
                    continue;
                }
                Outcome::NoRoom => {
                    if why == Why::Demand {
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
            // A block read ahead is unused so far: the first to go when room is needed. A
            // prefetched one counts as used by the frame that predicted it (the one before):
            // evicting it before the predicted view comes would waste the read.
            let (last_used, referenced) = match why {
                Why::Demand => (frame, true),
                Why::ReadAhead => {
                    book.looked_ahead += 1;
                    (0, false)
                }
                Why::Prefetch => {
                    book.prefetched += 1;
                    (frame.saturating_sub(1), true)
                }
            };
            table.insert(
                id,
                Arc::new(Resident {
                    data,
                    bytes,
                    last_used: AtomicU64::new(last_used),
                    referenced: AtomicBool::new(referenced),
                    prefetched: AtomicBool::new(why == Why::Prefetch),
                }),
            );
            if self.eviction == Eviction::SecondChance {
                book.clock.insert(id);
            }
        }
    }

    /// Makes room for `wanted` more bytes by evicting blocks that frame `frame` (or a later
    /// one) did not use, as the eviction policy says: least recently used first until they
    /// fit; or, second chance, a sweep until they fit and the cache is at most at its
    /// high-water mark. Stops when nothing more can go.
    fn make_room(&self, book: &mut Book, frame: u64, wanted: u64) {
        let held = || self.shared.held.load(Relaxed);
        let budget = self.shared.budget;
        let target = match self.eviction {
            Eviction::Lru => budget.saturating_sub(wanted),
            Eviction::SecondChance => budget
                .saturating_sub(wanted)
                .min((budget as f64 * HIGH_WATER) as u64),
        };
        if held() <= target {
            return;
        }
        let mut table = self.table.write().unwrap_or_else(PoisonError::into_inner);
        let evict = |table: &mut HashMap<u32, Arc<Resident>>, book: &mut Book, id: u32| {
            if let Some(r) = table.remove(&id) {
                book.resident_bytes -= r.bytes;
                book.evicted += 1;
                self.shared.held.fetch_sub(r.bytes as u64, Relaxed);
            }
        };
        match self.eviction {
            Eviction::Lru => {
                // Least recently used first (ties by id, for repeatable runs).
                let mut victims: Vec<(u64, u32)> = table
                    .iter()
                    .map(|(&id, r)| (r.last_used.load(Relaxed), id))
                    .filter(|&(used, _)| used < frame)
                    .collect();
                victims.sort_unstable();
                for (_, victim) in victims {
                    if held() <= target {
                        break;
                    }
                    evict(&mut table, book, victim);
                }
            }
            Eviction::SecondChance => {
                let mut clock = std::mem::take(&mut book.clock);
                clock.sweep(
                    |id| {
                        let Some(r) = table.get(&id) else {
                            return Verdict::Remove;
                        };
                        if r.last_used.load(Relaxed) >= frame || r.referenced.swap(false, Relaxed) {
                            return Verdict::Keep;
                        }
                        evict(&mut table, book, id);
                        Verdict::Remove
                    },
                    || held() <= target,
                );
                book.clock = clock;
            }
        }
    }
}

impl Shared {
    /// Reads and decodes block `id` and reserves room for it.
    fn load(&self, id: u32, why: Why) -> Outcome {
        let data = match self.waits.read(|| Data::load(&self.scene, id)) {
            Ok(d) => d,
            Err(e) => return Outcome::Failed(e),
        };
        let bytes = data.bytes() as u64;
        if bytes > self.budget && why == Why::Demand {
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

    /// Whether this frame's fetch budget allows starting another block. The first block after
    /// a step always may, so every frame brings something however short it was; while the
    /// caller is idle, any may.
    fn fetch_room(&self) -> bool {
        let spent = self.fetch_spent_ns.load(Relaxed);
        spent == 0 || spent < self.fetch_allowed_ns.load(Relaxed) || self.idle.load(Relaxed)
    }

    fn now_ns(&self) -> u64 {
        u64::try_from(self.epoch.elapsed().as_nanos()).unwrap_or(u64::MAX)
    }

    /// Whether this frame's prefetch budget allows starting another prefetch.
    fn prefetch_room(&self) -> bool {
        self.prefetch_spent.load(Relaxed) < self.prefetch_bytes
    }
}

fn fetch_loop(s: &Shared) {
    loop {
        let (id, levels, why) = {
            let mut q = lock(&s.queue);
            loop {
                if q.shutdown {
                    return;
                }
                // Within the frame's fetch budget: demand first, then prefetches within their
                // own budget, then reading ahead into free room. The budget is checked and
                // waited on under the queue's lock, so whoever lifts it (`wait_for_fetchers`,
                // `idle`, the step between frames) must take that lock after the change and
                // before the wake-up, or a fetcher between its check and its wait misses it.
                if !s.fetch_room() {
                    q = s.work.wait(q).unwrap_or_else(PoisonError::into_inner);
                    continue;
                }
                if let Some(id) = q.ids.pop() {
                    q.in_flight += 1;
                    break (id, s.read_ahead, Why::Demand);
                }
                if s.prefetch_room() {
                    if let Some(id) = q.prefetch.pop() {
                        q.in_flight += 1;
                        break (id, 0, Why::Prefetch);
                    }
                }
                let room = s.held.load(Relaxed) < s.budget / 2;
                if let Some((id, levels)) = q.ahead.pop().filter(|_| room) {
                    q.in_flight += 1;
                    break (id, levels, Why::ReadAhead);
                }
                q = s.work.wait(q).unwrap_or_else(PoisonError::into_inner);
            }
        };
        let (wall, cpu) = (Instant::now(), thread_cpu_time());
        // A block started while the caller is idle costs no frame.
        let during_frame = !s.idle.load(Relaxed);
        let outcome = s.load(id, why);
        let spent = match (thread_cpu_time(), cpu) {
            (Some(after), Some(before)) => after.saturating_sub(before),
            _ => wall.elapsed(),
        };
        let spent = u64::try_from(spent.as_nanos()).unwrap_or(u64::MAX);
        if during_frame {
            s.fetch_spent_ns.fetch_add(spent, Relaxed);
        }
        s.fetch_total_ns.fetch_add(spent, Relaxed);
        if let (Why::Prefetch, Outcome::Loaded(d)) = (why, &outcome) {
            s.prefetch_spent.fetch_add(d.bytes() as u64, Relaxed);
        }
        let children: Vec<u32> = match &outcome {
            Outcome::Loaded(Data::Treelets(d)) if levels > 0 => {
                d.lods.iter().map(|l| l.child_block).collect()
            }
            _ => Vec::new(),
        };
        lock(&s.done).push((id, outcome, why));
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

    fn request(&self, wanted: &[(u32, Wish)]) {
        for (id, w) in wanted {
            let mut shard = lock(&self.requests[*id as usize % SHARDS]);
            shard.entry(*id).or_default().merge(w);
        }
    }

    fn begin_frame(&self) {
        if self.shared.idle.swap(false, Relaxed) {
            self.shared
                .frame_start_ns
                .store(self.shared.now_ns(), Relaxed);
        }
    }

    fn end_frame(&self) {
        let mut book = lock(&self.book);
        let frame = self.frame.load(Relaxed);
        // The next frame's fetch budget, from this one's duration. A caller that never idles
        // starts its next frame at this step.
        let now = self.shared.now_ns();
        let start = self.shared.frame_start_ns.swap(now, Relaxed);
        self.shared.idle.store(false, Relaxed);
        let allowed = self.shared.fetch_share * now.saturating_sub(start) as f64;
        self.shared.fetch_spent_ns.store(0, Relaxed);
        // A share of infinity (or NaN) lifts the limit.
        self.shared.fetch_allowed_ns.store(
            if allowed < u64::MAX as f64 {
                allowed as u64
            } else {
                u64::MAX
            },
            Relaxed,
        );
        let root = self.shared.scene.metadata().root.map(|r| r.block);
        // What the frame wanted, before publishing: a block that arrived during the frame
        // still counts as wanted by it.
        let mut wanted: Vec<(u32, Wish)> = Vec::new();
        for shard in &self.requests {
            wanted.extend(
                lock(shard)
                    .drain()
                    .filter(|(id, _)| !book.missing.contains_key(id)),
            );
        }
        book.wanted_last_frame = wanted.len() as u64;
        self.publish(&mut book, frame);
        {
            // Blocks queued and not started yet are taken back before this frame's requests
            // are filtered, so that one still wanted is queued again at its new priority (and
            // one no longer wanted is forgotten). Prefetches too: the next prediction remakes
            // that list, and a block this frame asks for must wait as demand, not as a guess.
            let mut q = lock(&self.shared.queue);
            let queued = std::mem::take(&mut q.ids);
            for id in queued.into_iter().chain(q.prefetch.drain(..)) {
                book.fetching.remove(&id);
            }
        }
        {
            let table = self.table.read().unwrap_or_else(PoisonError::into_inner);
            wanted.retain(|(id, _)| !table.contains_key(id) && !book.fetching.contains(id));
        }
        // Room for what is asked, up to half the budget: the rest of the requests fetch into
        // room that later steps make.
        let bytes: u64 = wanted.iter().map(|&(id, _)| self.shared.estimate(id)).sum();
        self.make_room(&mut book, frame, bytes.min(self.shared.budget / 2));
        let (ranked, range) = policy::rank(wanted, self.fetch_order, book.wald_range, root);
        if range.is_some() {
            book.wald_range = range;
        }
        book.requested += ranked.len() as u64;
        {
            let mut q = lock(&self.shared.queue);
            // Reading ahead follows the blocks rays asked for; a new frame starts it afresh,
            // skipping what is resident or asked for.
            q.ahead.clear();
            q.seen_ahead.clear();
            let table = self.table.read().unwrap_or_else(PoisonError::into_inner);
            q.seen_ahead.extend(table.keys().copied());
            q.seen_ahead.extend(ranked.iter().copied());
            book.fetching.extend(ranked.iter().copied());
            q.ids = ranked;
        }
        self.shared.work.notify_all();
        self.frame.store(frame + 1, Relaxed);
    }

    fn stats(&self) -> CacheStats {
        let b = lock(&self.book);
        let pending = {
            let q = lock(&self.shared.queue);
            q.ids.len() + q.prefetch.len() + q.in_flight
        };
        CacheStats {
            mode: "async",
            io: self.shared.scene.reader().io_mode().name(),
            render_waits: self.shared.waits.count(),
            fetch_order: self.fetch_order.name(),
            eviction: self.eviction.name(),
            fetcher_nice: (self.fetcher_nice > 0 && self.shared.refused.load(Relaxed) == 0)
                .then_some(i32::from(self.fetcher_nice)),
            budget_bytes: self.budget as u64,
            bytes_resident: b.resident_bytes as u64,
            peak_bytes_resident: self.shared.peak.load(Relaxed),
            lookups: self.lookups.load(Relaxed),
            hits: self.hits.load(Relaxed),
            blocks_loaded: b.loaded,
            blocks_evicted: b.evicted,
            blocks_requested: b.requested,
            blocks_looked_ahead: b.looked_ahead,
            blocks_prefetched: b.prefetched,
            blocks_prefetch_used: self.prefetch_used.load(Relaxed),
            blocks_pending: pending as u64,
            blocks_dropped: b.dropped,
            blocks_wanted_last_frame: b.wanted_last_frame,
            fetch_cpu_ms: self.shared.fetch_total_ns.load(Relaxed) as f64 / 1e6,
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

    fn render_waits(&self) -> u64 {
        self.shared.waits.count()
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
