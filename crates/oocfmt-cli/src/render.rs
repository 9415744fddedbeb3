//! `oocfmt render`: one frame, or a walkthrough, of a container with the reference CPU ray
//! tracer.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

use oocfmt_trace::affinity;
use oocfmt_trace::blocks::LodKind;
use oocfmt_trace::cache::asynchronous::AsyncOptions;
use oocfmt_trace::cache::prefetch::{LookAhead, DEFAULT_FRAMES_AHEAD, DEFAULT_PROBE_ROWS};
use oocfmt_trace::cache::{Eviction, FetchOrder};
use oocfmt_trace::compare::median_sorted;
use oocfmt_trace::output::{write_pfm, write_png};
use oocfmt_trace::render::{Endings, FrameStats, Image};
use oocfmt_trace::{
    render, walk, AsyncCache, BlockCache, BlockingCache, CacheStats, Camera, MmapCache,
    RenderOptions, Scene, TraceError,
};

use crate::accuracy::{self, Accuracy};
use crate::error::{to_json, CliError, CliResult};
use crate::out::outln;

#[derive(clap::Args)]
pub struct Args {
    /// The container to render
    pub model: PathBuf,
    /// The PNG to write
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub view: View,
    /// Pixels of error: a ray stops on a LOD voxel whose radius is at most this many pixels;
    /// 0 renders full detail
    #[arg(long, default_value_t = 1.0)]
    pub poe: f32,
    /// LOD representation to stop on: voxel (Áfra 2012) or rlod (planes, Yoon et al. 2006);
    /// default: voxel when the file has voxels, else rlod. A kind the file lacks is an error
    #[arg(long, value_parser = parse_lod_kind)]
    pub lod: Option<LodKind>,
    /// Block cache: `async` (fetcher threads load blocks in the background, rays never wait
    /// and show coarser levels meanwhile; a single frame is rendered until every block it
    /// wants is loaded), `blocking` (a ray waits for every block it needs: the exact
    /// reference), `mmap` (the container mapped into memory and paged by the operating system;
    /// needs a container converted with `--codec none`)
    #[arg(long, default_value = "async", value_parser = ["async", "blocking", "mmap"])]
    pub cache: String,
    /// Fetcher threads of the async cache (default: half the cores, at least one: reading,
    /// decompressing and decoding blocks takes CPU time from the render threads)
    #[arg(long, default_value_t = default_fetchers(), value_parser = clap::value_parser!(u64).range(1..=64))]
    pub fetchers: u64,
    /// Async cache: block levels the fetchers read ahead below each block a ray asked for, into
    /// free room only (less than half the budget in use); 0 reads only what rays ask for
    #[arg(long, default_value_t = oocfmt_trace::cache::asynchronous::DEFAULT_READ_AHEAD, value_parser = clap::value_parser!(u8).range(0..=16))]
    pub read_ahead: u8,
    /// Async cache: the order fetchers serve requests in: `afra` (by the rays that wanted a
    /// block, each weighted by the region's angular size) or `wald` (by region size over
    /// distance alone, in 8 discrete queues spread linearly between the last frame's extremes,
    /// after Wald et al. 2004)
    #[arg(long, default_value = "afra", value_parser = FetchOrder::NAMES)]
    pub fetch_order: String,
    /// Async cache: what makes room: `lru` (the least recently used blocks the frame did not
    /// touch, when fetches need room) or `second-chance` (a clock sweep that spares a block
    /// used since the hand last passed, running once more than 80 % of --cache-mb is held,
    /// after Wald et al. 2004); neither evicts a block the current frame touched
    #[arg(long, default_value = "lru", value_parser = Eviction::NAMES)]
    pub eviction: String,
    /// Async cache: how many nice levels below the render threads the fetcher threads run
    /// (Linux): 0 shares the CPU equally with the render threads (blocks arrive soonest, and a
    /// cold frame slows down while they decode); higher values give the render threads the CPU
    /// first (19: fetchers use only what they leave). Counted from the process's own nice value,
    /// up to 19
    #[arg(long, default_value_t = oocfmt_trace::cache::asynchronous::DEFAULT_FETCHER_NICE, value_parser = clap::value_parser!(u8).range(0..=19))]
    pub fetcher_nice: u8,
    /// Async cache: CPU time the fetchers may spend reading and decoding blocks while a frame
    /// renders, as a share of the last frame's duration (`inf`: no limit). A burst of requests
    /// then arrives over several frames instead of slowing one down: with R cores busy
    /// rendering, a frame takes at most about 1 / (1 - share / R) times its warm time, 1.08 at
    /// 0.15 on 2 cores. While a walkthrough writes a frame's files the fetchers work without
    /// this limit
    #[arg(long, default_value_t = oocfmt_trace::cache::asynchronous::DEFAULT_FETCH_SHARE, value_parser = parse_share)]
    pub fetch_share: f64,
    /// Walkthroughs with the async cache: look-ahead prefetching (after iWalk): after each
    /// frame, predict the next cameras from the linear and angular speed of the last two,
    /// trace a coarse grid of probe rays from them against the resident blocks, and fetch the
    /// blocks they miss after every demand fetch, within --prefetch-mb per frame
    #[arg(long, default_value = "off", value_parser = ["on", "off"])]
    pub prefetch: String,
    /// Decoded MiB that look-ahead prefetching may load per frame
    #[arg(long, default_value_t = 4.0, value_parser = parse_mb)]
    pub prefetch_mb: f64,
    /// Frames ahead that look-ahead prefetching predicts and probes (each one)
    #[arg(long, default_value_t = DEFAULT_FRAMES_AHEAD, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub prefetch_frames: u32,
    /// Walkthroughs: report per frame the share of pixels equal to the full-detail reference
    /// (the same camera rendered with --cache blocking --poe 0 after the walkthrough, so its
    /// time does not help the walkthrough's fetchers), exactly and within
    /// --accuracy-tolerance
    #[arg(long, requires = "path")]
    pub accuracy: bool,
    /// Levels of 255 each channel may differ by for a pixel to count as within tolerance
    #[arg(long, default_value_t = 8)]
    pub accuracy_tolerance: u8,
    /// A walkthrough: a JSON list of cameras [{"eye": [x,y,z], "look_at": [x,y,z], "up"?: ..,
    /// "fov_y"?: ..}, ...] or {"keyframes": [cameras], "frames": N}; renders numbered PNGs
    /// (out.png -> out-0000.png, ...) with one cache kept across the frames, and figures per
    /// frame (--stats-json then writes an array)
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Memory for decoded blocks, in MiB; least recently used blocks are evicted beyond it
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u64).range(1..=1 << 30))]
    pub cache_mb: u64,
    /// Also write the depth (distance along the unit ray, +inf for a miss) as a PFM image
    #[arg(long)]
    pub depth_out: Option<PathBuf>,
    /// Also write the frame's figures as JSON to this file
    #[arg(long)]
    pub stats_json: Option<PathBuf>,
    /// Render the view this many times with the same cache and report the last frame (with
    /// 2 or more: figures with a warm cache)
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub repeat: u32,
    /// Render threads (default: all cores)
    #[arg(long)]
    pub threads: Option<usize>,
    /// Bind each render thread to a core of its own (Linux), when there are as many as the
    /// cores the process may use: two then never share a core while another runs only a
    /// fetcher. Cold frames lose less time to loading and warm frames gain 2-3 %, but where the
    /// system stalls a core now and then, a render thread cannot leave it (README, "Render
    /// threads bound to their cores")
    #[arg(long)]
    pub pin: bool,
    /// Primary rays per pixel, at stratified points of the pixel (deterministic), averaged in
    /// linear RGB; 1 is the ray through the pixel centre. The depth image (--depth-out) and the
    /// primary-ray endings stay those of the centre ray, traced in addition when N > 1
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=i64::from(oocfmt_trace::render::MAX_SAMPLES)))]
    pub spp: u32,
    /// Light with a point light (Lambert, one shadow ray per hit) instead of the headlight.
    /// Shadow rays use the PoE metric carried over to the light's projection: a voxel ends one
    /// when the shadow it casts moves at most --poe pixels on the receiver
    #[arg(long)]
    pub shadows: bool,
    /// The point light of --shadows, X,Y,Z in world coordinates (default: over the camera's
    /// right shoulder, eye + D·(0.5 right + 0.7 up − 0.3 forward), D the model's box diagonal)
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, requires = "shadows")]
    pub light: Option<[f64; 3]>,
    /// Ambient occlusion: N rays per primary hit, cosine-weighted over the hemisphere; with
    /// --poe > 0 a voxel ends one when its radius is at most t·√(2/N) (the ray's cone of 2π/N
    /// steradians)
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=i64::from(oocfmt_trace::render::MAX_SAMPLES)))]
    pub ao: Option<u32>,
    /// How far ambient-occlusion rays look, in world units (default: 0.1 × the model's box
    /// diagonal)
    #[arg(long, value_parser = parse_distance, allow_hyphen_values = true, requires = "ao")]
    pub ao_distance: Option<f32>,
}

/// MiB, finite, > 0 and at most 2^30.
fn parse_mb(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(m) if m.is_finite() && m > 0.0 && m <= f64::from(1u32 << 30) => Ok(m),
        _ => Err(format!(
            "`{s}`: expected MiB, a number > 0 and at most 2^30"
        )),
    }
}

/// A share of a frame: a number > 0, or `inf`.
fn parse_share(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(x) if x > 0.0 => Ok(x),
        _ => Err(format!(
            "`{s}`: expected a share of a frame, a number > 0 or `inf`"
        )),
    }
}

/// A finite distance > 0 that fits an f32.
fn parse_distance(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(d) if d.is_finite() && d > 0.0 => Ok(d),
        _ => Err(format!("`{s}`: expected a finite distance > 0")),
    }
}

/// `WIDTHxHEIGHT`, each 1 ..= 16384.
pub(crate) fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("`{s}`: expected WIDTHxHEIGHT, each 1 to 16384, e.g. 1024x768");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
        return Err(bad());
    }
    Ok((w, h))
}

/// `X,Y,Z`, finite numbers.
pub(crate) fn parse_vec3(s: &str) -> Result<[f64; 3], String> {
    let bad = || format!("`{s}`: expected three finite numbers X,Y,Z");
    let parts: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    match parts[..] {
        [x, y, z] if parts.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => Err(bad()),
    }
}

/// A `--lod` for rendering: voxel or rlod.
pub(crate) fn parse_lod_kind(s: &str) -> Result<LodKind, String> {
    match s {
        "voxel" => Ok(LodKind::Voxel),
        "rlod" => Ok(LodKind::Rlod),
        _ => Err(format!("`{s}`: expected voxel or rlod")),
    }
}

/// Opens `model` stopping on `lod` (None: the file's default).
pub(crate) fn open_scene(model: &Path, lod: Option<LodKind>) -> Result<Scene, CliError> {
    let scene = Scene::open(model).map_err(cli_error)?;
    match lod {
        Some(l) => scene.with_lod(l).map_err(cli_error),
        None => Ok(scene),
    }
}

pub(crate) fn cli_error(e: TraceError) -> CliError {
    match e {
        TraceError::Format(e) => CliError::Format(e),
        TraceError::Io { path, source } => CliError::Io {
            path: path.display().to_string(),
            source,
        },
        TraceError::Png { path, source } => CliError::Io {
            path: path.display().to_string(),
            source: std::io::Error::other(source.to_string()),
        },
        e @ (TraceError::Camera(_)
        | TraceError::Options(_)
        | TraceError::Path { .. }
        | TraceError::LodKind { .. }) => CliError::Usage(e.to_string()),
    }
}

/// Half the cores, at least one. With as many fetchers as cores, the bursts of loads of a cold
/// walkthrough slowed frames to 2.1–2.4× the same frames warm on 2 cores (100M Mandelbulb, PoE
/// 3, `--cache-mb 512`), against 1.5–1.9× with one fetcher: the async cache never waits on the
/// disk, but decoding competes with rendering for the cores.
pub(crate) fn default_fetchers() -> u64 {
    std::thread::available_parallelism().map_or(1, |n| (n.get() as u64 / 2).max(1))
}

/// The cache a render uses, kept by kind for what only one kind does.
pub(crate) enum Cache {
    Async(AsyncCache),
    Blocking(BlockingCache),
    Mmap(MmapCache),
}

impl Cache {
    fn open(a: &Args) -> Result<(Arc<Scene>, Cache), CliError> {
        let scene = if a.cache == "mmap" {
            None
        } else {
            Some(Arc::new(open_scene(&a.model, a.lod)?))
        };
        let opts = AsyncOptions {
            fetchers: usize::try_from(a.fetchers).unwrap_or(1),
            read_ahead: a.read_ahead,
            // The value parsers allow only the names.
            fetch_order: FetchOrder::parse(&a.fetch_order).unwrap_or_default(),
            eviction: Eviction::parse(&a.eviction).unwrap_or_default(),
            fetcher_nice: a.fetcher_nice,
            fetch_share: a.fetch_share,
            prefetch_bytes: if a.prefetch == "on" {
                (a.prefetch_mb * 1048576.0) as u64
            } else {
                0
            },
        };
        Cache::with_options(
            &a.model,
            scene,
            &a.cache,
            budget_bytes(a.cache_mb),
            &opts,
            a.lod,
        )
    }

    /// A cache of `kind` (`async`, `blocking` or `mmap`) over `scene`, or over the container
    /// at `model` opened anew when there is no scene or the kind is `mmap` (which maps it).
    pub(crate) fn of_kind(
        model: &Path,
        scene: Option<Arc<Scene>>,
        kind: &str,
        budget: usize,
        fetchers: usize,
        read_ahead: u8,
        lod: Option<LodKind>,
    ) -> Result<(Arc<Scene>, Cache), CliError> {
        let opts = AsyncOptions {
            fetchers,
            read_ahead,
            ..AsyncOptions::default()
        };
        Cache::with_options(model, scene, kind, budget, &opts, lod)
    }

    /// [`Cache::of_kind`] with every option of the async cache.
    pub(crate) fn with_options(
        model: &Path,
        scene: Option<Arc<Scene>>,
        kind: &str,
        budget: usize,
        opts: &AsyncOptions,
        lod: Option<LodKind>,
    ) -> Result<(Arc<Scene>, Cache), CliError> {
        if kind == "mmap" {
            let c = MmapCache::open_as(model, budget, lod).map_err(cli_error)?;
            return Ok((Arc::clone(c.scene()), Cache::Mmap(c)));
        }
        let scene = match scene {
            Some(s) => s,
            None => Arc::new(open_scene(model, lod)?),
        };
        let cache = if kind == "blocking" {
            Cache::Blocking(BlockingCache::new(Arc::clone(&scene), budget))
        } else {
            Cache::Async(AsyncCache::with_options(Arc::clone(&scene), budget, opts))
        };
        Ok((scene, cache))
    }

    pub(crate) fn get(&self) -> &dyn BlockCache {
        match self {
            Cache::Async(c) => c,
            Cache::Blocking(c) => c,
            Cache::Mmap(c) => c,
        }
    }
}

/// One frame's figures: the blocks requested, loaded and evicted are those of the step after
/// the frame.
#[derive(Serialize)]
struct FrameFigures {
    frame: usize,
    file: String,
    /// The frame's rays.
    ms: f64,
    /// The cache's step after the frame (publishing, ranking, evicting): part of the time
    /// between two frames, apart from `ms`.
    step_ms: f64,
    rays_per_second: f64,
    primary: Endings,
    /// Primary rays that ended on a voxel, an R-LOD or a proxy: coarser than full detail.
    coarse_pixels: u64,
    blocks_requested: u64,
    blocks_loaded: u64,
    blocks_evicted: u64,
    blocks_pending: u64,
    working_set_mb: f64,
    /// Of this frame's block lookups, the share that found the block resident.
    hit_rate: f64,
    /// Distinct blocks the frame wanted and did not find resident (its misses).
    blocks_missed: u64,
    /// Look-ahead prefetching after the step: predicting and probing the next cameras and
    /// queueing what they want (0 without --prefetch).
    prefetch_ms: f64,
    /// Of `blocks_loaded`, the ones prefetched; and prefetched blocks (loaded by any step)
    /// that this frame used for the first time.
    blocks_prefetched: u64,
    blocks_prefetch_used: u64,
    /// The fetchers' CPU time reading and decoding blocks between the step before this frame
    /// and the one after it (asynchronous cache).
    fetch_cpu_ms: f64,
    /// With --accuracy: the share of pixels equal to the full-detail reference.
    #[serde(skip_serializing_if = "Option::is_none")]
    accuracy: Option<Accuracy>,
    missing_blocks: usize,
    /// The cores the render threads are bound to with --pin, in the pool's order; empty when
    /// the system places them.
    pinned_cores: Vec<usize>,
    stats: FrameStats,
}

/// A still image's figures: the frame's, and where its render threads ran.
#[derive(Serialize)]
struct StillFigures<'a> {
    #[serde(flatten)]
    stats: &'a FrameStats,
    /// As in [`FrameFigures`].
    pinned_cores: &'a [usize],
}

impl FrameFigures {
    fn new(
        frame: usize,
        file: &Path,
        (stats, step_ms): (FrameStats, f64),
        before: &CacheStats,
    ) -> FrameFigures {
        let c = &stats.cache;
        let lookups = c.lookups.saturating_sub(before.lookups);
        let hits = c.hits.saturating_sub(before.hits);
        FrameFigures {
            frame,
            file: file.display().to_string(),
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
            prefetch_ms: 0.0,
            blocks_prefetched: c.blocks_prefetched.saturating_sub(before.blocks_prefetched),
            blocks_prefetch_used: c
                .blocks_prefetch_used
                .saturating_sub(before.blocks_prefetch_used),
            fetch_cpu_ms: (c.fetch_cpu_ms - before.fetch_cpu_ms).max(0.0),
            accuracy: None,
            missing_blocks: c.missing_blocks.len(),
            pinned_cores: Vec::new(),
            stats,
        }
    }
}

/// Renders one frame and runs the cache's step after it; the stats carry the cache's figures
/// after the step.
pub(crate) fn frame(
    scene: &Scene,
    cache: &dyn BlockCache,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<(Image, FrameStats), CliError> {
    frame_and_step(scene, cache, camera, opts).map(|(image, stats, _)| (image, stats))
}

/// [`frame`], and the milliseconds of the cache's step.
fn frame_and_step(
    scene: &Scene,
    cache: &dyn BlockCache,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<(Image, FrameStats, f64), CliError> {
    let (image, mut stats) = render(scene, cache, camera, opts).map_err(cli_error)?;
    let step = std::time::Instant::now();
    cache.end_frame();
    let step_ms = step.elapsed().as_secs_f64() * 1e3;
    stats.cache = cache.stats();
    Ok((image, stats, step_ms))
}

/// Renders a still view until a frame finds every block it wants: with the async cache,
/// letting the fetchers finish between frames (at most [`MAX_SETTLE_FRAMES`], warning when
/// that was not enough); with the others, one frame. Returns the last frame and the number of
/// frames rendered.
pub(crate) fn settle(
    scene: &Scene,
    cache: &Cache,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<((Image, FrameStats), u32), CliError> {
    let c = cache.get();
    let mut result = frame(scene, c, camera, opts)?;
    let mut settle_frames = 1;
    if let Cache::Async(ac) = cache {
        while result.1.cache.blocks_wanted_last_frame > 0 && settle_frames < MAX_SETTLE_FRAMES {
            ac.wait_for_fetchers();
            c.end_frame();
            result = frame(scene, c, camera, opts)?;
            settle_frames += 1;
        }
        if result.1.cache.blocks_wanted_last_frame > 0 {
            eprintln!(
                "oocfmt: warning: after {settle_frames} frames the view still wants blocks \
                 (is --cache-mb too small for it?); the image is coarser where they are missing"
            );
        }
    }
    Ok((result, settle_frames))
}

/// The most frames a still image in async mode takes to load what it wants.
const MAX_SETTLE_FRAMES: u32 = 1000;

pub(crate) fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), CliError> {
    let json = to_json(value)?;
    std::fs::write(path, json + "\n").map_err(|source| CliError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// `--cache-mb` in bytes.
fn budget_bytes(mb: u64) -> usize {
    usize::try_from(mb << 20).unwrap_or(usize::MAX)
}

/// Sets the render threads (`--threads`; None: all cores).
pub(crate) fn use_threads(threads: Option<usize>) -> Result<(), CliError> {
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| CliError::Usage(format!("--threads {n}: {e}")))?;
    }
    Ok(())
}

/// Binds each render thread to a core of its own when there are as many as the cores the
/// process may use (`--pin`), and returns their cores in the pool's order; otherwise says why
/// not. With fewer threads, a core is left free for the fetchers and the system, and binding
/// would only tie the render threads down.
fn pin_threads() -> Result<Vec<usize>, String> {
    let threads = rayon::current_num_threads();
    let Some(cores) = affinity::usable_cores() else {
        return Err("the system does not say which cores the process may use".into());
    };
    if threads < 2 {
        return Err("one render thread shares its core with no other".into());
    }
    if cores.len() != threads {
        return Err(format!(
            "{threads} render threads on {} usable cores: they are bound only when as many",
            cores.len()
        ));
    }
    let bound = affinity::bind_pool(&cores);
    if bound.is_empty() {
        return Err("the system refused".into());
    }
    Ok(bound)
}

/// Cameras in world coordinates (a walkthrough's) moved into the scene's stored coordinates.
pub(crate) fn stored_cameras(scene: &Scene, cameras: Vec<Camera>) -> Vec<Camera> {
    let origin = scene.metadata().scene.origin;
    let stored = |p: [f64; 3]| [0, 1, 2].map(|k| p[k] - origin[k]);
    cameras
        .into_iter()
        .map(|c| Camera {
            eye: stored(c.eye),
            look_at: stored(c.look_at),
            ..c
        })
        .collect()
}

/// The view flags `render` and `curve` share.
#[derive(clap::Args, Clone, Copy)]
pub struct View {
    /// Image size, WIDTHxHEIGHT
    #[arg(long, default_value = "1024x768", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Eye position X,Y,Z in world coordinates (default: framing the whole model)
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<[f64; 3]>,
    /// The point looked at, X,Y,Z in world coordinates (default: the model's centre)
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look_at: Option<[f64; 3]>,
    /// Up direction X,Y,Z
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<[f64; 3]>,
    /// Vertical field of view in degrees
    #[arg(long, default_value_t = oocfmt_trace::camera::DEFAULT_FOV_Y)]
    pub fov_y: f64,
}

/// The camera of a still view in stored coordinates: framing the whole model, with the eye,
/// look-at point (world coordinates) and up direction given on the command line.
pub(crate) fn still_camera(scene: &Scene, v: &View) -> Camera {
    let View {
        size: (w, h),
        eye,
        look_at,
        up,
        fov_y,
    } = *v;
    let m = scene.metadata();
    let origin = m.scene.origin;
    let stored = |p: [f64; 3]| [0, 1, 2].map(|k| p[k] - origin[k]);
    let mut camera = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, w, h);
    if let Some(e) = eye {
        camera.eye = stored(e);
    }
    if let Some(l) = look_at {
        camera.look_at = stored(l);
    }
    if let Some(u) = up {
        camera.up = u;
    }
    camera.fov_y = fov_y;
    camera
}

pub fn run(a: &Args) -> CliResult {
    use_threads(a.threads)?;
    let pinned_cores = if a.pin {
        pin_threads().unwrap_or_else(|why| {
            eprintln!("oocfmt: warning: --pin: the render threads are not bound: {why}");
            Vec::new()
        })
    } else {
        Vec::new()
    };
    let (w, h) = a.view.size;
    // Read the path before the model: a bad path file is reported without loading anything.
    let path_cameras = match &a.path {
        Some(p) => Some(walk::read_path(p, w, h).map_err(cli_error)?),
        None => None,
    };
    if a.prefetch == "on" && (a.cache != "async" || a.path.is_none()) {
        return Err(CliError::Usage(
            "--prefetch on predicts the cameras of a walkthrough: it needs --path and --cache \
             async"
                .into(),
        ));
    }
    let (scene, cache) = Cache::open(a)?;
    let origin = scene.metadata().scene.origin;
    let stored = |p: [f64; 3]| [0, 1, 2].map(|k| p[k] - origin[k]);
    let opts = RenderOptions {
        poe: a.poe,
        spp: a.spp,
        shadows: a.shadows,
        light: a.light.map(stored),
        ao: a.ao.unwrap_or(0),
        ao_distance: a.ao_distance,
        ..RenderOptions::default()
    };
    if let Some(cameras) = path_cameras {
        let cameras = stored_cameras(&scene, cameras);
        return walkthrough(a, &scene, &cache, &cameras, &opts, &pinned_cores);
    }
    let camera = still_camera(&scene, &a.view);
    let c = cache.get();
    let (mut result, settle_frames) = settle(&scene, &cache, &camera, &opts)?;
    for _ in 1..a.repeat {
        result = frame(&scene, c, &camera, &opts)?;
    }
    let (image, stats) = result;
    write_png(&a.output, image.width, image.height, &image.rgb).map_err(cli_error)?;
    if let Some(d) = &a.depth_out {
        write_pfm(d, image.width, image.height, &image.depth).map_err(cli_error)?;
    }
    if let Some(s) = &a.stats_json {
        write_json(
            s,
            &StillFigures {
                stats: &stats,
                pinned_cores: &pinned_cores,
            },
        )?;
    }
    let p = &stats.primary;
    outln!(
        "wrote {} ({}x{}, --poe {}): {:.1} ms, {:.2} Mrays/s on {} threads{}",
        a.output.display(),
        image.width,
        image.height,
        stats.poe,
        stats.ms,
        stats.rays_per_second / 1e6,
        stats.threads,
        if pinned_cores.is_empty() {
            ""
        } else {
            ", one per core"
        }
    )?;
    if settle_frames > 1 {
        outln!("async cache: {settle_frames} frames to load the view's blocks")?;
    }
    outln!(
        "primary rays: {} triangle, {} voxel, {} R-LOD, {} proxy, {} miss",
        p.triangle,
        p.voxel,
        p.rlod,
        p.proxy,
        p.miss
    )?;
    if stats.rays > stats.primary_rays || stats.spp > 1 {
        outln!(
            "rays: {} primary ({} per pixel), {} shadow, {} ambient occlusion",
            stats.primary_rays,
            stats.spp,
            stats.shadow_rays,
            stats.ao_rays
        )?;
    }
    let c = &stats.cache;
    outln!(
        "blocks: {} loaded, {} evicted, {:.1} MiB resident (peak {:.1} MiB of {} MiB)",
        c.blocks_loaded,
        c.blocks_evicted,
        c.bytes_resident as f64 / 1048576.0,
        c.peak_bytes_resident as f64 / 1048576.0,
        a.cache_mb
    )?;
    for b in &c.missing_blocks {
        eprintln!("oocfmt: warning: block {} is missing: {}", b.id, b.error);
    }
    Ok(0)
}

/// Renders `cameras` in order with one cache, writing numbered PNGs and a line of figures per
/// frame; with --prefetch, looks ahead after each frame; with --accuracy, compares every frame
/// with its full-detail reference at the end.
fn walkthrough(
    a: &Args,
    scene: &Arc<Scene>,
    cache: &Cache,
    cameras: &[Camera],
    opts: &RenderOptions,
    pinned_cores: &[usize],
) -> CliResult {
    let c = cache.get();
    let mut look_ahead = match cache {
        Cache::Async(ac) if a.prefetch == "on" => {
            Some((ac, LookAhead::new(a.prefetch_frames, DEFAULT_PROBE_ROWS)))
        }
        _ => None,
    };
    let mut all = Vec::with_capacity(cameras.len());
    let mut files = Vec::with_capacity(cameras.len());
    let mut before = c.stats();
    let mut reported_missing = 0;
    for (i, camera) in cameras.iter().enumerate() {
        let (image, stats, step_ms) = frame_and_step(scene, c, camera, opts)?;
        let prefetch_ms = match &mut look_ahead {
            Some((ac, la)) => {
                let start = std::time::Instant::now();
                la.after_frame(scene, ac, camera, opts.poe);
                start.elapsed().as_secs_f64() * 1e3
            }
            None => 0.0,
        };
        // Writing the frame's files renders nothing: the fetchers may use that time freely.
        if let Cache::Async(ac) = cache {
            ac.idle();
        }
        let file = walk::frame_file(&a.output, i);
        write_png(&file, image.width, image.height, &image.rgb).map_err(cli_error)?;
        if let Some(d) = &a.depth_out {
            let dfile = walk::frame_file(d, i);
            write_pfm(&dfile, image.width, image.height, &image.depth).map_err(cli_error)?;
        }
        for b in stats.cache.missing_blocks.iter().skip(reported_missing) {
            eprintln!("oocfmt: warning: block {} is missing: {}", b.id, b.error);
        }
        reported_missing = stats.cache.missing_blocks.len();
        let next = stats.cache.clone();
        let mut f = FrameFigures::new(i, &file, (stats, step_ms), &before);
        f.prefetch_ms = prefetch_ms;
        f.pinned_cores = pinned_cores.to_vec();
        before = next;
        let p = &f.primary;
        let prefetched = if look_ahead.is_some() {
            format!(
                " ({} prefetched, +{:.1} ms look-ahead)",
                f.blocks_prefetched, f.prefetch_ms
            )
        } else {
            String::new()
        };
        outln!("frame {i:4}: {:8.1} ms (+{:.1} ms step) {:7.2} Mrays/s | tri {} voxel {} proxy {} miss {} | blocks \
             +{} requested +{} loaded{prefetched} +{} evicted {} pending {} missed | {:.1} MiB | hit {:.1}% | {}",
            f.ms,
            f.step_ms,
            f.rays_per_second / 1e6,
            p.triangle,
            p.voxel,
            p.proxy,
            p.miss,
            f.blocks_requested,
            f.blocks_loaded,
            f.blocks_evicted,
            f.blocks_pending,
            f.blocks_missed,
            f.working_set_mb,
            100.0 * f.hit_rate,
            file.display()
        )?;
        all.push(f);
        files.push(file);
    }
    if a.accuracy {
        let tolerance = a.accuracy_tolerance;
        let measured = accuracy::measure(
            scene,
            cameras,
            &files,
            opts,
            budget_bytes(a.cache_mb),
            tolerance,
        )?;
        for (f, m) in all.iter_mut().zip(measured) {
            outln!(
                "accuracy {:4}: {:6.2} % of pixels equal to the full-detail reference, {:6.2} % \
                 within {tolerance}",
                f.frame,
                100.0 * m.exact,
                100.0 * m.within_tolerance
            )?;
            f.accuracy = Some(m);
        }
        let mut exact: Vec<f64> = all
            .iter()
            .filter_map(|f| f.accuracy)
            .map(|m| m.exact)
            .collect();
        exact.sort_by(f64::total_cmp);
        if let Some(min) = exact.first() {
            outln!(
                "accuracy: median {:.2} %, minimum {:.2} % of pixels equal to the reference",
                100.0 * median_sorted(&exact),
                100.0 * min
            )?;
        }
    }
    if let Some(s) = &a.stats_json {
        write_json(s, &all)?;
    }
    Ok(0)
}
