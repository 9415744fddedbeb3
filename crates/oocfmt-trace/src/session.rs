//! Render sessions: one scene and one cache, frames rendered in order, the cache's step
//! between frames. This is the loop `oocfmt render` drives (a still view, or a walkthrough of
//! cameras) and an interactive viewer drives the same way: a camera in, a frame and its
//! figures out, the cache stepped and left to load while the caller shows or writes the frame.
//!
//! ```no_run
//! use std::sync::Arc;
//! use oocfmt_trace::cache::asynchronous::AsyncOptions;
//! use oocfmt_trace::session::{Cache, CacheKind, Walkthrough};
//! use oocfmt_trace::{Camera, RenderOptions};
//!
//! # fn main() -> Result<(), oocfmt_trace::TraceError> {
//! let path = std::path::Path::new("model.oocf");
//! let (scene, cache) =
//!     Cache::open(path, None, CacheKind::Async, 512 << 20, &AsyncOptions::default(), None)?;
//! let m = scene.metadata();
//! let camera = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, 640, 480);
//! let mut walk = Walkthrough::new(&scene, &cache, RenderOptions::default(), None)?;
//! let frame = walk.frame(&camera)?;
//! println!("{:.1} ms, {} blocks loaded", frame.figures.ms, frame.figures.blocks_loaded);
//! # Ok(())
//! # }
//! ```

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

use crate::blocks::LodKind;
use crate::cache::asynchronous::AsyncOptions;
use crate::cache::prefetch::{LookAhead, DEFAULT_PROBE_ROWS};
use crate::cache::MissingBlock;
use crate::render::{render, Endings, FrameStats, Image, RenderOptions};
use crate::{AsyncCache, BlockCache, BlockingCache, CacheStats, Camera, MmapCache, Scene};
use crate::{TraceError, TraceError as E};

/// The kinds of block cache a session can render with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CacheKind {
    /// Fetcher threads load blocks in the background; rays never wait and show coarser
    /// levels meanwhile ([`AsyncCache`]).
    Async,
    /// A ray waits for every block it needs: the exact reference ([`BlockingCache`]).
    Blocking,
    /// The container mapped into memory and paged by the operating system; needs
    /// uncompressed blocks ([`MmapCache`]).
    Mmap,
}

impl CacheKind {
    /// The name the command line and the figures use.
    pub fn name(self) -> &'static str {
        match self {
            CacheKind::Async => "async",
            CacheKind::Blocking => "blocking",
            CacheKind::Mmap => "mmap",
        }
    }
}

/// The cache a session renders with, kept by kind for what only one kind does (the async
/// cache's idle spells, its fetchers, look-ahead prefetching).
pub enum Cache {
    /// [`CacheKind::Async`].
    Async(AsyncCache),
    /// [`CacheKind::Blocking`].
    Blocking(BlockingCache),
    /// [`CacheKind::Mmap`].
    Mmap(MmapCache),
}

impl Cache {
    /// A cache of `kind` holding at most `budget` decoded bytes, over `scene`, or over the
    /// container at `model` opened anew (stopping on `lod`; None: the file's default) when
    /// there is no scene or the kind is [`CacheKind::Mmap`] (which maps the file). `opts`
    /// configures the async cache and is ignored by the others. Returns the scene the cache
    /// serves with it.
    pub fn open(
        model: &Path,
        scene: Option<Arc<Scene>>,
        kind: CacheKind,
        budget: usize,
        opts: &AsyncOptions,
        lod: Option<LodKind>,
    ) -> Result<(Arc<Scene>, Cache), TraceError> {
        if kind == CacheKind::Mmap {
            let c = MmapCache::open_as(model, budget, lod)?;
            return Ok((Arc::clone(c.scene()), Cache::Mmap(c)));
        }
        let scene = match scene {
            Some(s) => s,
            None => Arc::new(open_scene(model, lod)?),
        };
        let cache = if kind == CacheKind::Blocking {
            Cache::Blocking(BlockingCache::new(Arc::clone(&scene), budget))
        } else {
            Cache::Async(AsyncCache::with_options(Arc::clone(&scene), budget, opts))
        };
        Ok((scene, cache))
    }

    /// The cache as the renderer sees it.
    pub fn get(&self) -> &dyn BlockCache {
        match self {
            Cache::Async(c) => c,
            Cache::Blocking(c) => c,
            Cache::Mmap(c) => c,
        }
    }

    /// The asynchronous cache, if this is one.
    pub fn as_async(&self) -> Option<&AsyncCache> {
        match self {
            Cache::Async(c) => Some(c),
            Cache::Blocking(_) | Cache::Mmap(_) => None,
        }
    }

    /// Which kind of cache this is.
    pub fn kind(&self) -> CacheKind {
        match self {
            Cache::Async(_) => CacheKind::Async,
            Cache::Blocking(_) => CacheKind::Blocking,
            Cache::Mmap(_) => CacheKind::Mmap,
        }
    }
}

/// Opens `model` stopping on `lod` (None: the file's default).
pub fn open_scene(model: &Path, lod: Option<LodKind>) -> Result<Scene, TraceError> {
    let scene = Scene::open(model)?;
    match lod {
        Some(l) => scene.with_lod(l),
        None => Ok(scene),
    }
}

/// A point in world coordinates moved into the scene's stored coordinates (less its origin).
pub fn stored_point(scene: &Scene, p: [f64; 3]) -> [f64; 3] {
    let origin = scene.metadata().scene.origin;
    [0, 1, 2].map(|k| p[k] - origin[k])
}

/// Cameras in world coordinates (a walkthrough's, [`crate::walk::read_path`]) moved into the
/// scene's stored coordinates, which rendering uses.
pub fn stored_cameras(scene: &Scene, cameras: Vec<Camera>) -> Vec<Camera> {
    cameras
        .into_iter()
        .map(|c| Camera {
            eye: stored_point(scene, c.eye),
            look_at: stored_point(scene, c.look_at),
            ..c
        })
        .collect()
}

/// One rendered frame.
pub struct Frame {
    /// The frame's colours and depths.
    pub image: Image,
    /// The frame's figures, with the cache's figures as of after the step.
    pub stats: FrameStats,
    /// Milliseconds of the cache's step after the frame.
    pub step_ms: f64,
}

/// Renders one frame and runs the cache's step after it ([`BlockCache::end_frame`]).
pub fn frame(
    scene: &Scene,
    cache: &dyn BlockCache,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<Frame, TraceError> {
    Ok(stepped(cache, render(scene, cache, camera, opts)?))
}

/// [`frame`] through a camera's frame made already ([`crate::render::render_frame`]): a
/// live view's accumulation pass, aimed at a sample of every pixel.
pub fn frame_aimed(
    scene: &Scene,
    cache: &dyn BlockCache,
    frame: &crate::camera::Frame,
    opts: &RenderOptions,
) -> Result<Frame, TraceError> {
    Ok(stepped(
        cache,
        crate::render::render_frame(scene, cache, frame, opts)?,
    ))
}

/// A rendered frame with the cache's step after it.
fn stepped(cache: &dyn BlockCache, (image, mut stats): (Image, FrameStats)) -> Frame {
    let step = Instant::now();
    cache.end_frame();
    let step_ms = step.elapsed().as_secs_f64() * 1e3;
    stats.cache = cache.stats();
    Frame {
        image,
        stats,
        step_ms,
    }
}

/// The most frames [`settle`] renders for a still view with the async cache.
pub const MAX_SETTLE_FRAMES: u32 = 1000;
/// Frames in a row after which [`settle`] gives up when each evicted blocks and none found
/// fewer missing blocks than the best frame so far: the budget cannot hold the view, so the
/// fetchers evict what they loaded before and would go on reading the file for nothing. (While
/// the cache has room, a view descending level by level may want more blocks at each level;
/// that never counts.)
pub const SETTLE_PATIENCE: u32 = 16;

/// A still view rendered until it found what it wants.
pub struct Settled {
    /// The last frame.
    pub frame: Frame,
    /// Frames rendered, the last included.
    pub frames: u32,
    /// Whether the last frame found every block it wanted. Only the async cache can fall
    /// short, when [`MAX_SETTLE_FRAMES`] were not enough or progress stalled (a budget too
    /// small for the view); the image is then coarser where blocks are missing.
    pub complete: bool,
}

/// Renders a still view until a frame finds every block it wants: with the async cache,
/// letting the fetchers finish between frames, at most [`MAX_SETTLE_FRAMES`] frames, and
/// fewer when [`SETTLE_PATIENCE`] frames in a row make no progress; with the others (which
/// load on demand), one frame.
pub fn settle(
    scene: &Scene,
    cache: &Cache,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<Settled, TraceError> {
    let c = cache.get();
    let mut last = frame(scene, c, camera, opts)?;
    let mut frames = 1;
    let Some(ac) = cache.as_async() else {
        return Ok(Settled {
            frame: last,
            frames,
            complete: true,
        });
    };
    let (mut best, mut stalled) = (last.stats.cache.blocks_wanted_last_frame, 0);
    let mut evicted_before = no_room(&last);
    while last.stats.cache.blocks_wanted_last_frame > 0
        && frames < MAX_SETTLE_FRAMES
        && stalled < SETTLE_PATIENCE
    {
        ac.wait_for_fetchers();
        c.end_frame();
        last = frame(scene, c, camera, opts)?;
        frames += 1;
        let out = no_room(&last);
        let evicted = out > evicted_before;
        evicted_before = out;
        let wanted = last.stats.cache.blocks_wanted_last_frame;
        (best, stalled) = match (wanted < best, evicted) {
            (true, _) => (wanted, 0),
            (false, true) => (best, stalled + 1),
            (false, false) => (best, 0),
        };
    }
    let complete = last.stats.cache.blocks_wanted_last_frame == 0;
    Ok(Settled {
        frame: last,
        frames,
        complete,
    })
}

/// Blocks the cache had no room for so far: evicted, or loaded and dropped at once.
fn no_room(f: &Frame) -> u64 {
    f.stats.cache.blocks_evicted + f.stats.cache.blocks_dropped
}

/// One walkthrough frame's figures. The blocks requested, loaded and evicted, the lookups and
/// the fetchers' time are those since the previous frame's step, up to this frame's step.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FrameFigures {
    /// Milliseconds of wall time tracing and shading the frame's rays ([`FrameStats::ms`]).
    pub ms: f64,
    /// Milliseconds of the cache's step after the frame (publishing, ranking, evicting): part
    /// of the time between two frames, apart from `ms`.
    pub step_ms: f64,
    /// Rays (primary, shadow, ambient occlusion) per second of `ms`.
    pub rays_per_second: f64,
    /// How the pixels' centre rays ended.
    pub primary: Endings,
    /// Primary rays that ended on a voxel, an R-LOD or a proxy: coarser than full detail.
    pub coarse_pixels: u64,
    /// Blocks asked of the fetchers.
    pub blocks_requested: u64,
    /// Blocks made resident.
    pub blocks_loaded: u64,
    /// Blocks evicted to make room.
    pub blocks_evicted: u64,
    /// Blocks requested and not yet loaded, as of the step.
    pub blocks_pending: u64,
    /// Decoded MiB resident after the step.
    pub working_set_mb: f64,
    /// Of this frame's block lookups, the share that found the block resident.
    pub hit_rate: f64,
    /// Distinct blocks the frame wanted and did not find resident (its misses).
    pub blocks_missed: u64,
    /// Milliseconds of look-ahead prefetching after the step: predicting and probing the next
    /// cameras and queueing what they want (0 without it).
    pub prefetch_ms: f64,
    /// Of `blocks_loaded`, the ones prefetched.
    pub blocks_prefetched: u64,
    /// Prefetched blocks (loaded by any step) that this frame used for the first time.
    pub blocks_prefetch_used: u64,
    /// Milliseconds of the fetchers' CPU time reading and decoding blocks between the step
    /// before this frame and the one after it (asynchronous cache).
    pub fetch_cpu_ms: f64,
    /// Times a render thread waited on I/O during the frame ([`FrameStats::waits`]): 0 with
    /// the asynchronous cache.
    pub waits: u64,
}

impl FrameFigures {
    /// The figures of a frame whose stats (cache figures after the step) are `stats`, given
    /// the cache's figures `before` it.
    fn new(stats: &FrameStats, step_ms: f64, prefetch_ms: f64, before: &CacheStats) -> Self {
        let c = &stats.cache;
        let lookups = c.lookups.saturating_sub(before.lookups);
        let hits = c.hits.saturating_sub(before.hits);
        FrameFigures {
            ms: stats.ms,
            step_ms,
            rays_per_second: stats.rays_per_second,
            primary: stats.primary,
            coarse_pixels: stats.primary.voxel + stats.primary.rlod + stats.primary.proxy,
            blocks_requested: c.blocks_requested.saturating_sub(before.blocks_requested),
            blocks_loaded: c.blocks_loaded.saturating_sub(before.blocks_loaded),
            blocks_evicted: c.blocks_evicted.saturating_sub(before.blocks_evicted),
            blocks_pending: c.blocks_pending,
            working_set_mb: c.bytes_resident as f64 / 1048576.0,
            hit_rate: if lookups > 0 {
                hits as f64 / lookups as f64
            } else {
                1.0
            },
            blocks_missed: c.blocks_wanted_last_frame,
            prefetch_ms,
            blocks_prefetched: c.blocks_prefetched.saturating_sub(before.blocks_prefetched),
            blocks_prefetch_used: c
                .blocks_prefetch_used
                .saturating_sub(before.blocks_prefetch_used),
            fetch_cpu_ms: (c.fetch_cpu_ms - before.fetch_cpu_ms).max(0.0),
            waits: stats.waits,
        }
    }
}

/// One frame of a [`Walkthrough`].
pub struct WalkFrame {
    /// The frame's number, from 0.
    pub index: usize,
    /// The frame's colours and depths.
    pub image: Image,
    /// The figures since the previous frame.
    pub figures: FrameFigures,
    /// The frame's own figures, with the cache's as of after the step.
    pub stats: FrameStats,
    /// Blocks found missing (unreadable or corrupt) since the previous frame: each is
    /// reported once, the frame rendered coarser where it is needed.
    pub new_missing: Vec<MissingBlock>,
}

/// A walkthrough: cameras rendered in order with one cache kept across the frames. Each
/// [`Walkthrough::frame`] renders, runs the cache's step, looks ahead when prefetching, and
/// then tells an async cache that the caller renders nothing until the next frame (so its
/// fetchers work without the per-frame limit while the caller writes or shows the image).
pub struct Walkthrough<'a> {
    scene: &'a Scene,
    cache: &'a Cache,
    opts: RenderOptions,
    look_ahead: Option<LookAhead>,
    before: CacheStats,
    reported_missing: usize,
    frames: usize,
}

impl<'a> Walkthrough<'a> {
    /// A walkthrough of `scene` with `cache` and `opts`; `prefetch_frames`: look-ahead
    /// prefetching ([`LookAhead`]) predicting that many frames ahead, which needs the async
    /// cache (an error with another). The async cache's `prefetch_bytes` bounds what it loads.
    pub fn new(
        scene: &'a Scene,
        cache: &'a Cache,
        opts: RenderOptions,
        prefetch_frames: Option<u32>,
    ) -> Result<Self, TraceError> {
        let look_ahead = match (prefetch_frames, cache) {
            (None, _) => None,
            (Some(n), Cache::Async(_)) => Some(LookAhead::new(n, DEFAULT_PROBE_ROWS)),
            (Some(_), _) => {
                return Err(E::Options(format!(
                    "look-ahead prefetching needs the async cache, not {}",
                    cache.kind().name()
                )))
            }
        };
        Ok(Walkthrough {
            scene,
            cache,
            opts,
            look_ahead,
            before: cache.get().stats(),
            reported_missing: 0,
            frames: 0,
        })
    }

    /// Whether the walkthrough prefetches by look-ahead.
    pub fn prefetching(&self) -> bool {
        self.look_ahead.is_some()
    }

    /// Renders the next frame from `camera` (stored coordinates, [`stored_cameras`]).
    pub fn frame(&mut self, camera: &Camera) -> Result<WalkFrame, TraceError> {
        let Frame {
            image,
            stats,
            step_ms,
        } = frame(self.scene, self.cache.get(), camera, &self.opts)?;
        let prefetch_ms = match (&mut self.look_ahead, self.cache.as_async()) {
            (Some(la), Some(ac)) => {
                let start = Instant::now();
                la.after_frame(self.scene, ac, camera, self.opts.poe);
                start.elapsed().as_secs_f64() * 1e3
            }
            _ => 0.0,
        };
        if let Some(ac) = self.cache.as_async() {
            ac.idle();
        }
        let figures = FrameFigures::new(&stats, step_ms, prefetch_ms, &self.before);
        let missing = &stats.cache.missing_blocks;
        let new_missing = missing
            .iter()
            .skip(self.reported_missing)
            .cloned()
            .collect();
        self.reported_missing = missing.len();
        self.before = stats.cache.clone();
        let index = self.frames;
        self.frames += 1;
        Ok(WalkFrame {
            index,
            image,
            figures,
            stats,
            new_missing,
        })
    }
}
