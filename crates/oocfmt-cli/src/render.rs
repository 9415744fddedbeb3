//! `oocfmt render`: one frame, or a walkthrough, of a container with the reference CPU ray
//! tracer; or a pick of one pixel (`--pick`). The frames are rendered by
//! [`oocfmt_trace::session`], the parts chosen by [`oocfmt_trace::parts`] and picks made by
//! [`oocfmt_trace::pick`]; this module reads the flags, writes the images and prints the
//! figures.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

use oocfmt_trace::affinity;
use oocfmt_trace::cache::asynchronous::AsyncOptions;
use oocfmt_trace::cache::prefetch::DEFAULT_FRAMES_AHEAD;
use oocfmt_trace::cache::MissingBlock;
use oocfmt_trace::compare::median_sorted;
use oocfmt_trace::output::{write_pfm, write_png};
use oocfmt_trace::parts::{PartFilter, PartSelection};
use oocfmt_trace::pick::{pick, Pick};
use oocfmt_trace::render::{FrameStats, Image};
use oocfmt_trace::session::{
    self, Cache, CacheKind, FrameFigures, Settled, WalkFrame, Walkthrough,
};
use oocfmt_trace::{walk, Camera, RenderOptions, Scene, Section};

use crate::accuracy::{self, Accuracy};
use crate::args::{
    self, budget_bytes, use_threads, CacheArg, EvictionArg, FetchOrderArg, IoArg, LodArg, Switch,
    View,
};
use crate::error::{to_json, CliError, CliResult};
use crate::out::outln;

#[derive(clap::Args)]
pub struct Args {
    /// The container to render
    pub model: PathBuf,
    /// The PNG to write; may be left out with --pick, which then renders nothing
    #[arg(short, long, required_unless_present = "pick")]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub view: View,
    /// Pixels of error: a ray stops on a LOD voxel whose radius is at most this many pixels;
    /// 0 renders full detail
    #[arg(long, default_value_t = 1.0)]
    pub poe: f32,
    /// LOD representation to stop on: voxel (Áfra 2012) or rlod (planes, Yoon et al. 2006);
    /// default: rlod when the file has R-LODs, else voxel. A kind the file lacks is an error
    #[arg(long, value_enum)]
    pub lod: Option<LodArg>,
    /// Block cache: `async` (fetcher threads load blocks in the background, rays never wait
    /// and show coarser levels meanwhile; a single frame is rendered until every block it
    /// wants is loaded, or with a warning once 16 frames in a row had to evict blocks without
    /// getting closer: a --cache-mb too small for the view), `blocking` (a ray waits for every block it needs: the exact
    /// reference), `mmap` (the container mapped into memory and paged by the operating system;
    /// needs a container converted with `--codec none`)
    #[arg(long, value_enum, default_value = "async")]
    pub cache: CacheArg,
    /// How the async and blocking caches read blocks: `buffered` (through the operating
    /// system's page cache, which then holds the file's bytes beside the decoded blocks) or
    /// `direct` (past it: O_DIRECT, or where the file system refuses that, buffered reads each
    /// dropped from the page cache after it); the figures say which was in effect. Not with
    /// --cache mmap, whose map is the page cache
    #[arg(long, value_enum, default_value = "buffered")]
    pub io: IoArg,
    /// Fetcher threads of the async cache (default: half the cores, at least one: reading,
    /// decompressing and decoding blocks takes CPU time from the render threads)
    #[arg(long, default_value_t = args::default_fetchers(), value_parser = clap::value_parser!(u64).range(1..=64))]
    pub fetchers: u64,
    /// Async cache: block levels the fetchers read ahead below each block a ray asked for, into
    /// free room only (less than half the budget in use); 0 reads only what rays ask for
    #[arg(long, default_value_t = oocfmt_trace::cache::asynchronous::DEFAULT_READ_AHEAD, value_parser = clap::value_parser!(u8).range(0..=16))]
    pub read_ahead: u8,
    /// Async cache: the order fetchers serve requests in: `afra` (by the rays that wanted a
    /// block, each weighted by the region's angular size) or `wald` (by region size over
    /// distance alone, in 8 discrete queues spread linearly between the last frame's extremes,
    /// after Wald et al. 2004)
    #[arg(long, value_enum, default_value = "afra")]
    pub fetch_order: FetchOrderArg,
    /// Async cache: what makes room: `lru` (the least recently used blocks the frame did not
    /// touch, when fetches need room) or `second-chance` (a clock sweep that spares a block
    /// used since the hand last passed, running once more than 80 % of --cache-mb is held,
    /// after Wald et al. 2004); neither evicts a block the current frame touched
    #[arg(long, value_enum, default_value = "lru")]
    pub eviction: EvictionArg,
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
    #[arg(long, default_value_t = oocfmt_trace::cache::asynchronous::DEFAULT_FETCH_SHARE, value_parser = args::parse_share)]
    pub fetch_share: f64,
    /// Walkthroughs with the async cache: look-ahead prefetching (after iWalk): after each
    /// frame, predict the next cameras from the linear and angular speed of the last two,
    /// trace a coarse grid of probe rays from them against the resident blocks, and fetch the
    /// blocks they miss after every demand fetch, within --prefetch-mb per frame
    #[arg(long, value_enum, default_value = "off")]
    pub prefetch: Switch,
    /// Decoded MiB that look-ahead prefetching may load per frame
    #[arg(long, default_value_t = 4.0, value_parser = args::parse_mb)]
    pub prefetch_mb: f64,
    /// Frames ahead that look-ahead prefetching predicts and probes (each one)
    #[arg(long, default_value_t = DEFAULT_FRAMES_AHEAD, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub prefetch_frames: u32,
    /// Walkthroughs: measure each frame against the true picture, the same camera at full
    /// detail with --reference-spp rays per pixel (--cache blocking --poe 0, rendered after
    /// the walkthrough so its time does not help the walkthrough's fetchers): RMSE, PSNR,
    /// SSIM, share within --accuracy-tolerance and luma bias on the model's pixels (those
    /// that hit in either image) and on the whole image; beside it the aliasing floor (full
    /// detail at the frames' own --spp against the same reference) and the share of pixels
    /// equal to that full-detail image
    #[arg(long, requires = "path")]
    pub accuracy: bool,
    /// Levels of 255 each channel may differ by for a pixel to count as within tolerance
    #[arg(long, default_value_t = 8)]
    pub accuracy_tolerance: u8,
    /// Rays per pixel of the --accuracy reference, at the stratified points of --spp
    #[arg(long, default_value_t = accuracy::DEFAULT_REFERENCE_SPP, value_parser = clap::value_parser!(u32).range(1..=i64::from(accuracy::MAX_REFERENCE_SPP)), requires = "accuracy")]
    pub reference_spp: u32,
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
    /// fetcher. Cold frames lose less time to loading and warm frames gain a little, but where
    /// the system stalls a core now and then, a render thread cannot leave it
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
    #[arg(long, value_parser = args::parse_vec3, allow_hyphen_values = true, requires = "shadows")]
    pub light: Option<[f64; 3]>,
    /// Ambient occlusion: N rays per primary hit, cosine-weighted over the hemisphere; with
    /// --poe > 0 a LOD entry whose radius is at most t·√(2/N) (the ray's cone of 2π/N
    /// steradians) stands for what the ray meets there and lets 1 − its coverage through
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=i64::from(oocfmt_trace::render::MAX_SAMPLES)))]
    pub ao: Option<u32>,
    /// How far ambient-occlusion rays look, in world units (default: 0.1 × the model's box
    /// diagonal)
    #[arg(long, value_parser = args::parse_distance, allow_hyphen_values = true, requires = "ao")]
    pub ao_distance: Option<f32>,
    /// Show every LOD entry opaque, coverage aside (spec §5.1): a little faster on rough
    /// surfaces, while thin parts swell to their cells. By default an entry that covers part
    /// of its cell (pre-filtered files) is translucent, composited over what lies behind
    #[arg(long)]
    pub opaque_lod: bool,
    /// Hide the parts whose name matches GLOB (a GLOB with `/` matches paths of names from the
    /// top: `assembly-3/bolt-*`), with everything under them; repeatable. `*` and `?` match
    /// within a name, `**` across `/`. A GLOB that matches no part is a usage error
    #[arg(long, value_name = "GLOB")]
    pub hide: Vec<String>,
    /// Show only the parts GLOB matches, with everything under them (every other part hidden);
    /// repeatable, as --hide
    #[arg(long, value_name = "GLOB")]
    pub isolate: Vec<String>,
    /// Tint the parts GLOB matches, with everything under them, half way to orange (at full
    /// detail by each triangle's part, at a LOD entry by its part word); repeatable, as --hide
    #[arg(long, value_name = "GLOB")]
    pub highlight: Vec<String>,
    /// Cut the model open with a section plane (world coordinates): `x=V` (or y, z) keeps
    /// where that coordinate is >= V, `-x=V` where it is <= V, `X,Y,Z,NX,NY,NZ` the side of
    /// the plane through the point that the normal points to. Clips primary rays and --pick;
    /// shadow and ambient-occlusion rays still see the whole model
    #[arg(long, value_name = "PLANE", value_parser = Section::parse, allow_hyphen_values = true)]
    pub section: Option<Section>,
    /// Pick pixel X,Y (0,0 the top left) of the view at --poe: print the distance, point,
    /// normal, triangle and part its centre ray meets first, reading any block it needs even
    /// with the async cache; renders nothing unless --output is given too (then after the
    /// frame). Honours --hide and --isolate
    #[arg(long, value_name = "X,Y", value_parser = args::parse_pixel, conflicts_with = "path")]
    pub pick: Option<(u32, u32)>,
    /// With --pick: print the pick as JSON (schema `oocfmt-pick/1`, docs/cli.md) and nothing
    /// else on stdout
    #[arg(long, requires = "pick")]
    pub json: bool,
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
        Some(p) => Some(walk::read_path(p, w, h)?),
        None => None,
    };
    if a.prefetch.is_on() && (a.cache != CacheArg::Async || a.path.is_none()) {
        return Err(CliError::Usage(
            "--prefetch on predicts the cameras of a walkthrough: it needs --path and --cache \
             async"
                .into(),
        ));
    }
    let (scene, cache) = open_cache(a)?;
    if let (Some(note), false) = (args::io_note(a.io, &scene), a.json) {
        outln!("{note}")?;
    }
    choose_parts(a, &scene)?;
    scene.set_section(a.section);
    let opts = RenderOptions {
        poe: a.poe,
        spp: a.spp,
        shadows: a.shadows,
        light: a.light.map(|l| session::stored_point(&scene, l)),
        ao: a.ao.unwrap_or(0),
        ao_distance: a.ao_distance,
        translucent: !a.opaque_lod,
        ..RenderOptions::default()
    };
    match (path_cameras, &a.output) {
        (Some(cameras), Some(output)) => {
            let cameras = session::stored_cameras(&scene, cameras);
            walkthrough(a, output, &scene, &cache, &cameras, opts, &pinned_cores)
        }
        (None, Some(output)) => {
            still(a, output, &scene, &cache, &opts, &pinned_cores)?;
            print_pick(a, &scene, &cache)
        }
        // clap requires --output without --pick, and --pick conflicts with --path.
        (_, None) => print_pick(a, &scene, &cache),
    }
}

/// `--hide`, `--isolate`, `--highlight`: resolved against the file's part table and set on
/// the scene, so that every frame and pick follows them. A glob that matches nothing (or any
/// glob on a file without parts) is a usage error naming the closest parts.
fn choose_parts(a: &Args, scene: &Scene) -> Result<(), CliError> {
    let sel = PartSelection {
        hide: a.hide.clone(),
        isolate: a.isolate.clone(),
        highlight: a.highlight.clone(),
    };
    if sel.is_empty() {
        return Ok(());
    }
    let parts = &scene.metadata().parts;
    let filter = PartFilter::new(parts, &sel).map_err(|e| CliError::Usage(e.to_string()))?;
    if !a.json {
        outln!(
            "parts: {} of {} hidden, {} highlighted",
            filter.hidden(),
            parts.len(),
            filter.highlighted()
        )?;
    }
    scene.set_parts(filter);
    Ok(())
}

/// `--pick`: one ray through the pixel's centre, at --poe, printed as a line or as JSON.
fn print_pick(a: &Args, scene: &Scene, cache: &Cache) -> CliResult {
    let Some(at) = a.pick else {
        return Ok(0);
    };
    let camera = a.view.camera(scene);
    let found = pick(scene, cache.get(), &camera, at, a.poe)?;
    if a.json {
        let record = PickRecord {
            schema: "oocfmt-pick/1",
            pixel: [at.0, at.1],
            poe: a.poe,
            hit: found.as_ref(),
        };
        outln!("{}", to_json(&record)?)?;
        return Ok(0);
    }
    outln!("{}", pick_line(at, a.poe, found.as_ref()))?;
    Ok(0)
}

/// `render --pick --json`: what a pick found (docs/cli.md, "The pick JSON").
#[derive(Serialize)]
struct PickRecord<'a> {
    schema: &'static str,
    pixel: [u32; 2],
    poe: f32,
    hit: Option<&'a Pick>,
}

/// A pick as a line for people.
fn pick_line((x, y): (u32, u32), poe: f32, p: Option<&Pick>) -> String {
    let Some(p) = p else {
        return format!("pick {x},{y} (--poe {poe}): nothing, the background");
    };
    let part = match (p.part, &p.part_name, &p.part_path) {
        (Some(id), Some(name), Some(path)) => format!("part {id} `{name}` ({path})"),
        (Some(id), _, _) => format!("part {id}"),
        _ => "no part (the file has none)".to_string(),
    };
    let what = match p.triangle {
        Some(t) => format!("triangle {} of block {}", t.index, t.block),
        None => "a LOD entry (its part covers most of its cell)".to_string(),
    };
    let v = |c: &[f64; 3]| format!("{:.6}, {:.6}, {:.6}", c[0], c[1], c[2]);
    let n = p.normal;
    format!(
        "pick {x},{y} (--poe {poe}): {part}, {what}, distance {:.6}, point {}, normal {:.4}, {:.4}, {:.4}",
        p.distance,
        v(&p.point),
        n[0],
        n[1],
        n[2]
    )
}

/// The scene and the cache `--cache` asks for, with the async cache's flags.
fn open_cache(a: &Args) -> Result<(Arc<Scene>, Cache), CliError> {
    let kind = CacheKind::from(a.cache);
    let lod = a.lod.map(Into::into);
    let scene = args::scene_for(&a.model, kind, lod, a.io)?;
    let opts = AsyncOptions {
        fetchers: usize::try_from(a.fetchers).unwrap_or(1),
        read_ahead: a.read_ahead,
        fetch_order: a.fetch_order.into(),
        eviction: a.eviction.into(),
        fetcher_nice: a.fetcher_nice,
        fetch_share: a.fetch_share,
        prefetch_bytes: if a.prefetch.is_on() {
            (a.prefetch_mb * 1048576.0) as u64
        } else {
            0
        },
    };
    Ok(Cache::open(
        &a.model,
        scene,
        kind,
        budget_bytes(a.cache_mb),
        &opts,
        lod,
    )?)
}

/// A still view: rendered until it has what it wants, then `--repeat` more times.
fn still(
    a: &Args,
    output: &Path,
    scene: &Scene,
    cache: &Cache,
    opts: &RenderOptions,
    pinned_cores: &[usize],
) -> CliResult {
    let camera = a.view.camera(scene);
    let settled = settle(scene, cache, &camera, opts)?;
    let mut last = settled.frame;
    for _ in 1..a.repeat {
        last = session::frame(scene, cache.get(), &camera, opts)?;
    }
    let (image, stats) = (last.image, last.stats);
    write_png(output, image.width, image.height, &image.rgb)?;
    if let Some(d) = &a.depth_out {
        write_pfm(d, image.width, image.height, &image.depth)?;
    }
    if let Some(s) = &a.stats_json {
        write_json(
            s,
            &StillFigures {
                stats: &stats,
                pinned_cores,
            },
        )?;
    }
    if !a.json {
        print_still(
            a,
            output,
            &image,
            &stats,
            settled.frames,
            !pinned_cores.is_empty(),
        )?;
    }
    warn_missing(&stats.cache.missing_blocks);
    Ok(0)
}

/// The lines `render` prints for a still view.
fn print_still(
    a: &Args,
    output: &Path,
    image: &Image,
    stats: &FrameStats,
    settle_frames: u32,
    pinned: bool,
) -> Result<(), CliError> {
    let p = &stats.primary;
    outln!(
        "wrote {} ({}x{}, --poe {}): {:.1} ms, {:.2} Mrays/s on {} threads{}",
        output.display(),
        image.width,
        image.height,
        stats.poe,
        stats.ms,
        stats.rays_per_second / 1e6,
        stats.threads,
        if pinned { ", one per core" } else { "" }
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
        "blocks: {} loaded, {} evicted, {:.1} MiB resident (peak {:.1} MiB of {} MiB); {} \
         render-thread waits on I/O in this frame",
        c.blocks_loaded,
        c.blocks_evicted,
        c.bytes_resident as f64 / 1048576.0,
        c.peak_bytes_resident as f64 / 1048576.0,
        a.cache_mb,
        stats.waits
    )
}

/// Renders `cameras` in order with one cache ([`Walkthrough`]), writing numbered PNGs and a
/// line of figures per frame; with --accuracy, compares every frame with its full-detail
/// reference at the end.
fn walkthrough(
    a: &Args,
    output: &Path,
    scene: &Arc<Scene>,
    cache: &Cache,
    cameras: &[Camera],
    opts: RenderOptions,
    pinned_cores: &[usize],
) -> CliResult {
    let prefetch = a.prefetch.is_on().then_some(a.prefetch_frames);
    let mut walk = Walkthrough::new(scene, cache, opts, prefetch)?;
    let mut records = Vec::with_capacity(cameras.len());
    let mut kept = Vec::new();
    for camera in cameras {
        let f = walk.frame(camera)?;
        let file = walk::frame_file(output, f.index);
        write_png(&file, f.image.width, f.image.height, &f.image.rgb)?;
        if let Some(d) = &a.depth_out {
            let dfile = walk::frame_file(d, f.index);
            write_pfm(&dfile, f.image.width, f.image.height, &f.image.depth)?;
        }
        warn_missing(&f.new_missing);
        if a.accuracy {
            kept.push(accuracy::Kept::new(&f.image, &file));
        }
        let record = FrameRecord::new(f, &file, pinned_cores);
        print_frame(&record, walk.prefetching())?;
        records.push(record);
    }
    if a.accuracy {
        report_accuracy(a, scene, cameras, &kept, &opts, &mut records)?;
    }
    if let Some(s) = &a.stats_json {
        write_json(s, &records)?;
    }
    Ok(0)
}

/// A walkthrough frame's line of figures.
fn print_frame(r: &FrameRecord, prefetching: bool) -> Result<(), CliError> {
    let f = &r.figures;
    let p = &f.primary;
    let prefetched = if prefetching {
        format!(
            " ({} prefetched, +{:.1} ms look-ahead)",
            f.blocks_prefetched, f.prefetch_ms
        )
    } else {
        String::new()
    };
    outln!("frame {:4}: {:8.1} ms (+{:.1} ms step) {:7.2} Mrays/s | tri {} voxel {} proxy {} miss {} | blocks \
         +{} requested +{} loaded{prefetched} +{} evicted {} pending {} missed | {:.1} MiB | hit {:.1}% | waits {} | {}",
        r.frame,
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
        f.waits,
        r.file
    )
}

/// `--accuracy`: each frame against the supersampled reference, a line per frame and the
/// medians; the figures go into `records`.
fn report_accuracy(
    a: &Args,
    scene: &Arc<Scene>,
    cameras: &[Camera],
    kept: &[accuracy::Kept],
    opts: &RenderOptions,
    records: &mut [FrameRecord],
) -> Result<(), CliError> {
    let tolerance = a.accuracy_tolerance;
    let measured = accuracy::measure(
        scene,
        cameras,
        kept,
        opts,
        budget_bytes(a.cache_mb),
        accuracy::Against {
            reference_spp: a.reference_spp,
            tolerance,
        },
    )?;
    outln!(
        "accuracy against full detail at {} rays per pixel (PoE 0, blocking cache); model: the \
         pixels that hit in either image; floor: full detail at --spp {} against the same \
         reference",
        a.reference_spp,
        opts.spp
    )?;
    for (f, m) in records.iter_mut().zip(measured) {
        let e = &m.error;
        outln!(
            "accuracy {:4}: model {} px: {}; whole image RMSE {:.2}, PSNR {} dB; floor RMSE \
             {:.2} on the model; {} hit/miss differ; {:.2} % equal to full detail",
            f.frame,
            e.model.pixels,
            accuracy::region_line(&e.model, tolerance),
            e.whole.rmse,
            accuracy::db(e.whole.psnr_db),
            m.floor.model.rmse,
            e.hit_miss_differ,
            100.0 * m.exact
        )?;
        f.accuracy = Some(m);
    }
    let median = |k: fn(&Accuracy) -> f64| {
        let mut v: Vec<f64> = records
            .iter()
            .filter_map(|f| f.accuracy.as_ref().map(k))
            .collect();
        v.sort_by(f64::total_cmp);
        (median_sorted(&v), v.first().copied())
    };
    if let (rmse, Some(_)) = median(|m| m.error.model.rmse) {
        let (floor, _) = median(|m| m.floor.model.rmse);
        let (bias, _) = median(|m| m.error.model.bias);
        let (ssim, _) = median(|m| m.error.model.ssim);
        let (exact, min_exact) = median(|m| m.exact);
        outln!(
            "accuracy: medians over the frames on the model: RMSE {rmse:.2} (aliasing floor \
             {floor:.2}), SSIM {ssim:.4}, bias {bias:+.2}; {:.2} % of pixels equal to full \
             detail (minimum {:.2} %)",
            100.0 * exact,
            100.0 * min_exact.unwrap_or(0.0)
        )?;
    }
    Ok(())
}

/// One walkthrough frame in `--stats-json`: where it was written, the session's figures, and
/// what the CLI adds.
#[derive(Serialize)]
struct FrameRecord {
    frame: usize,
    file: String,
    #[serde(flatten)]
    figures: FrameFigures,
    /// With --accuracy: the error against the supersampled reference, and the floor's.
    #[serde(skip_serializing_if = "Option::is_none")]
    accuracy: Option<Accuracy>,
    missing_blocks: usize,
    /// The cores the render threads are bound to with --pin, in the pool's order; empty when
    /// the system places them.
    pinned_cores: Vec<usize>,
    stats: FrameStats,
}

impl FrameRecord {
    fn new(f: WalkFrame, file: &Path, pinned_cores: &[usize]) -> FrameRecord {
        FrameRecord {
            frame: f.index,
            file: file.display().to_string(),
            figures: f.figures,
            accuracy: None,
            missing_blocks: f.stats.cache.missing_blocks.len(),
            pinned_cores: pinned_cores.to_vec(),
            stats: f.stats,
        }
    }
}

/// A still image's figures: the frame's, and where its render threads ran.
#[derive(Serialize)]
struct StillFigures<'a> {
    #[serde(flatten)]
    stats: &'a FrameStats,
    /// As in [`FrameRecord`].
    pinned_cores: &'a [usize],
}

/// Warns about blocks that could not be read; the frames are coarser where they are needed.
pub(crate) fn warn_missing(blocks: &[MissingBlock]) {
    for b in blocks {
        eprintln!("oocfmt: warning: block {} is missing: {}", b.id, b.error);
    }
}

/// [`session::settle`], warning when the view still wants blocks after the most frames it
/// may take.
pub(crate) fn settle(
    scene: &Scene,
    cache: &Cache,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<Settled, CliError> {
    let settled = session::settle(scene, cache, camera, opts)?;
    if !settled.complete {
        eprintln!(
            "oocfmt: warning: after {} frames the view still wants blocks \
             (is --cache-mb too small for it?); the image is coarser where they are missing",
            settled.frames
        );
    }
    Ok(settled)
}

pub(crate) fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), CliError> {
    let json = to_json(value)?;
    std::fs::write(path, json + "\n").map_err(|source| CliError::Io {
        path: path.display().to_string(),
        source,
    })
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
