//! `oocfmt curve`: speed against error. Renders one view (or a walkthrough) at a list of
//! pixels-of-error values with each asked-for cache, warm, and compares every image with the
//! true picture: full detail supersampled (PoE 0, `--reference-spp` rays per pixel, blocking
//! cache of `--reference-mb`), on the model's pixels and on the whole image. Full detail at one
//! ray per pixel is measured against it too: the floor that aliasing sets. A table, JSON, a
//! plot of error against frame time and a contact sheet of the images with zoomed crops.

mod plot;
mod sheet;
mod text;
mod touched;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

use oocfmt_trace::blocks::LodKind;
use oocfmt_trace::cache::asynchronous::AsyncOptions;
use oocfmt_trace::compare::{Accumulator, ImageError};
use oocfmt_trace::render::Endings;
use oocfmt_trace::session::{self, frame, Cache, CacheKind};
use oocfmt_trace::{BlockingCache, Camera, Image, RenderOptions, Scene};

use crate::accuracy::{self, db, reference_options};
use crate::args::{self, budget_bytes, use_threads, CacheArg, IoArg, LodArg, View};
use crate::error::{CliError, CliResult};
use crate::out::outln;
use crate::render::{settle, warn_missing, write_json};
use touched::Touched;

/// The JSON schema of `--json`.
pub const SCHEMA: &str = "oocfmt-curve/3";
/// `--reference-mb` unless given: a full-detail view of 10M triangles takes 333 MiB of blocks.
pub const DEFAULT_REFERENCE_MB: u64 = 8192;

#[derive(clap::Args)]
pub struct Args {
    /// The container
    pub model: PathBuf,
    /// Pixels-of-error values to measure, comma-separated, each finite, >= 0 and listed once
    #[arg(long, default_value = "0,0.5,1,2,4,8,16", value_parser = parse_poes, allow_hyphen_values = true)]
    pub poe: PoeList,
    /// Caches to measure, comma-separated (one series each): async, blocking, mmap (mmap
    /// needs a container converted with `--codec none`)
    #[arg(long, value_enum, default_value = "async", value_delimiter = ',')]
    pub cache: Vec<CacheArg>,
    /// How the async and blocking caches read blocks (as for `render`): `buffered` or `direct`
    /// (past the page cache); not with mmap
    #[arg(long, value_enum, default_value = "buffered")]
    pub io: IoArg,
    /// LOD representations to compare, comma-separated (one series each with every cache):
    /// voxel, rlod; each must be in the file (`convert --lod both` holds both). Default: the
    /// one `render` stops on (rlod when the file has R-LODs, else voxel)
    #[arg(long, value_enum, value_delimiter = ',')]
    pub lod: Vec<LodArg>,
    #[command(flatten)]
    pub view: View,
    /// A walkthrough (as for `render --path`) instead of one view: every figure is over all
    /// its frames (times per frame, the error as of one image, SSIM the frames' mean); the
    /// contact sheet shows the first frame. Every frame's images are kept in memory.
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Timed frames (walkthrough: passes) per PoE once the cache is warm; the median is
    /// reported
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub repeat: u32,
    /// A pixel is "within tolerance" when its three channels all differ from the reference's
    /// by at most this many levels of 255
    #[arg(long, default_value_t = 8)]
    pub tolerance: u8,
    /// Rays per pixel of the reference (full detail, at the stratified points of `render
    /// --spp`); the aliasing floor is full detail at one
    #[arg(long, default_value_t = accuracy::DEFAULT_REFERENCE_SPP, value_parser = clap::value_parser!(u32).range(1..=i64::from(accuracy::MAX_REFERENCE_SPP)))]
    pub reference_spp: u32,
    /// Memory for decoded blocks per cache, in MiB
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u64).range(1..=1 << 30))]
    pub cache_mb: u64,
    /// Memory for the full-detail renders' decoded blocks, in MiB: a model larger than memory
    /// is measured too, a reference that cannot keep its view's blocks only reading them again
    /// (time, never accuracy)
    #[arg(long, default_value_t = DEFAULT_REFERENCE_MB, value_parser = clap::value_parser!(u64).range(1..=1 << 30))]
    pub reference_mb: u64,
    /// Light with a point light and one shadow ray per hit (as `render --shadows`), every
    /// image and the reference alike
    #[arg(long)]
    pub shadows: bool,
    /// The point light of --shadows, X,Y,Z in world coordinates (default: as for `render`)
    #[arg(long, value_parser = args::parse_vec3, allow_hyphen_values = true, requires = "shadows")]
    pub light: Option<[f64; 3]>,
    /// Ambient occlusion with N rays per hit (as `render --ao`), every image and the reference
    /// alike
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=i64::from(oocfmt_trace::render::MAX_SAMPLES)))]
    pub ao: Option<u32>,
    /// How far ambient-occlusion rays look, in world units (default: as for `render`)
    #[arg(long, value_parser = args::parse_distance, allow_hyphen_values = true, requires = "ao")]
    pub ao_distance: Option<f32>,
    /// Fetcher threads of the async cache (default: half the cores, at least one)
    #[arg(long, default_value_t = args::default_fetchers(), value_parser = clap::value_parser!(u64).range(1..=64))]
    pub fetchers: u64,
    /// Async cache: block levels read ahead (as for `render`)
    #[arg(long, default_value_t = oocfmt_trace::cache::asynchronous::DEFAULT_READ_AHEAD, value_parser = clap::value_parser!(u8).range(0..=16))]
    pub read_ahead: u8,
    /// Write the figures as JSON (schema `oocfmt-curve/3`, docs/cli.md) to this file
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Plot the RMSE on the model's pixels against frame time, one point per PoE and one series
    /// per cache, the aliasing floor a horizontal line: FILE.svg or FILE.png
    #[arg(long, value_parser = parse_plot_path)]
    pub plot: Option<PathBuf>,
    /// Write a contact sheet PNG: the reference, the aliasing floor and every PoE's image side
    /// by side, labelled, each over a 4x crop of one region at the model's centre; one row per
    /// cache
    #[arg(long)]
    pub sheet: Option<PathBuf>,
    /// Render threads (default: all cores)
    #[arg(long)]
    pub threads: Option<usize>,
    /// Show every LOD entry opaque, coverage aside (spec §5.1): a little faster on rough
    /// surfaces, while thin parts swell to their cells. By default an entry that covers part
    /// of its cell (pre-filtered files) is translucent, composited over what lies behind
    #[arg(long)]
    pub opaque_lod: bool,
}

/// The PoE values of `--poe`.
#[derive(Clone, Debug)]
pub struct PoeList(pub Vec<f32>);

fn parse_poes(s: &str) -> Result<PoeList, String> {
    if s.trim().is_empty() {
        return Err("expected a comma-separated list of PoEs, e.g. 0,1,4".to_string());
    }
    let mut v: Vec<f32> = Vec::new();
    for part in s.split(',') {
        let p = part.trim();
        let x: f32 = p
            .parse()
            .map_err(|_| format!("`{p}`: expected a number (a comma-separated list of PoEs)"))?;
        if !(x.is_finite() && x >= 0.0) {
            return Err(format!("`{p}`: a PoE is a finite number >= 0"));
        }
        // -0 is 0, listed and written as such.
        let x = if x == 0.0 { 0.0 } else { x };
        if v.contains(&x) {
            return Err(format!("`{p}` is listed twice"));
        }
        v.push(x);
    }
    Ok(PoeList(v))
}

fn parse_plot_path(s: &str) -> Result<PathBuf, String> {
    let p = PathBuf::from(s);
    match plot::Format::of(&p) {
        Some(_) => Ok(p),
        None => Err(format!(
            "`{s}`: expected a file name ending in .svg or .png"
        )),
    }
}

/// One (LOD kind, cache, PoE) measurement.
#[derive(Serialize)]
pub struct Row {
    pub cache: String,
    pub lod: &'static str,
    pub poe: f32,
    /// How the cache's reads met the page cache: `buffered`, `direct` or `dontneed`.
    pub io: &'static str,
    /// Frames rendered before the timed ones: until the view (every camera) found every
    /// block it wants.
    pub settle_frames: u32,
    /// Times a render thread waited on I/O in those frames (the cold ones): every block read
    /// with the blocking and mmap caches, none with the async cache.
    pub settle_waits: u64,
    /// Times a render thread waited on I/O in the timed frames, all of them.
    pub waits: u64,
    /// Median over the timed repeats of the time per frame.
    pub ms: f64,
    pub rays_per_second: f64,
    pub nodes_per_ray: f64,
    /// Decoded bytes resident after the last timed frame.
    pub working_set_mb: f64,
    /// Distinct blocks one warm frame (walkthrough: one pass) looked up.
    pub blocks_touched: u64,
    /// How primary rays ended, over the frames of one pass.
    pub primary: Endings,
    pub error: ImageError,
}

#[derive(Serialize)]
struct Curve<'a> {
    schema: &'static str,
    model: String,
    width: u32,
    height: u32,
    /// Cameras per measurement: 1, or the walkthrough's frames.
    frames: usize,
    repeat: u32,
    threads: usize,
    cache_mb: u64,
    /// Lit by a point light with shadow rays (`--shadows`), else by the headlight.
    shadows: bool,
    /// Ambient-occlusion rays per hit (`--ao`), 0 for none.
    ao: u32,
    /// The tolerance of every `within_tolerance`.
    tolerance: u8,
    /// The reference: PoE 0, `spp` rays per pixel, blocking cache of `--reference-mb`.
    reference: Reference,
    /// Full detail at one ray per pixel against the reference: the aliasing floor.
    floor: Floor,
    rows: &'a [Row],
}

/// How a full-detail image was rendered (once per camera, cold, blocking cache).
#[derive(Serialize)]
struct Reference {
    cache: &'static str,
    poe: f32,
    spp: u32,
    /// Time per camera of the cold frame.
    ms: f64,
    /// How the centre rays ended.
    primary: Endings,
}

#[derive(Serialize)]
struct Floor {
    #[serde(flatten)]
    render: Reference,
    error: ImageError,
}

/// A measurement's images of the first camera, for the sheet.
pub struct Shot {
    /// The series: cache, and the LOD kind when several are compared.
    pub cache: String,
    pub poe: f32,
    pub ms: f64,
    /// The RMSE on the model's pixels.
    pub rmse: f64,
    pub image: Image,
}

pub fn run(a: &Args) -> CliResult {
    use_threads(a.threads)?;
    let kinds = listed_once("--cache", &a.cache, |k| CacheKind::from(k).name())?;
    let (w, h) = a.view.size;
    let path_cameras = match &a.path {
        Some(p) => Some(oocfmt_trace::walk::read_path(p, w, h)?),
        None => None,
    };
    let lods = listed_once("--lod", &a.lod, |l| LodKind::from(l).name())?;
    // Every kind is checked before anything is rendered. The reference does not depend on the
    // kind: PoE 0 never stops on a LOD node.
    let scenes = if lods.is_empty() {
        let scene = args::open_scene(&a.model, None, a.io)?;
        vec![(scene.lod(), Arc::new(scene))]
    } else {
        lods.iter()
            .map(|&l| {
                let l = LodKind::from(l);
                Ok((l, Arc::new(args::open_scene(&a.model, Some(l), a.io)?)))
            })
            .collect::<Result<Vec<_>, CliError>>()?
    };
    let Some((_, scene)) = scenes.first() else {
        return Err(CliError::Usage(
            "--lod: expected at least one kind".to_string(),
        ));
    };
    let scene = Arc::clone(scene);
    let cameras = match path_cameras {
        Some(c) => session::stored_cameras(&scene, c),
        None => vec![a.view.camera(&scene)],
    };
    if kinds.contains(&CacheArg::Mmap) {
        args::check_io(CacheKind::Mmap, a.io)?;
        // A container mmap cannot map is refused before any rendering.
        open_cache(a, None, CacheKind::Mmap, None)?;
    }
    let base = RenderOptions {
        shadows: a.shadows,
        light: a.light.map(|l| session::stored_point(&scene, l)),
        ao: a.ao.unwrap_or(0),
        ao_distance: a.ao_distance,
        ..RenderOptions::default()
    };
    let full = render_full_detail(
        (&scene, &cameras),
        &base,
        budget_bytes(a.reference_mb),
        (a.reference_spp, a.tolerance),
    )?;
    let references = &full.references;
    let mut rows = Vec::new();
    let mut shots = Vec::new();
    for (lod, lod_scene) in &scenes {
        for &kind in &kinds {
            for &poe in &a.poe.0 {
                // A fresh cache per measurement, so each working set is the PoE's own.
                let kind = CacheKind::from(kind);
                let (scene, cache) = open_cache(a, Some(Arc::clone(lod_scene)), kind, Some(*lod))?;
                let opts = RenderOptions {
                    poe,
                    translucent: !a.opaque_lod,
                    ..base
                };
                let (row, image) =
                    measure(a, &scene, &cache, (kind, *lod), &opts, &cameras, references)?;
                shots.push(Shot {
                    cache: if scenes.len() > 1 {
                        format!("{} {}", row.cache, row.lod)
                    } else {
                        row.cache.clone()
                    },
                    poe,
                    ms: row.ms,
                    rmse: row.error.model.rmse,
                    image,
                });
                rows.push(row);
            }
        }
    }
    print_table(a, &cameras, &full, &rows)?;
    let first_floor = full.first_floor;
    let first_reference = full.references.into_iter().next();
    let curve = Curve {
        schema: SCHEMA,
        model: a.model.display().to_string(),
        width: w,
        height: h,
        frames: cameras.len(),
        repeat: a.repeat,
        threads: rayon::current_num_threads(),
        cache_mb: a.cache_mb,
        shadows: a.shadows,
        ao: a.ao.unwrap_or(0),
        tolerance: a.tolerance,
        reference: full.reference,
        floor: full.floor,
        rows: &rows,
    };
    let sheet = match (first_reference, first_floor) {
        (Some(reference), Some(floor)) => Some(sheet::Fixed { reference, floor }),
        _ => None,
    };
    write_files(a, &curve, sheet.as_ref(), &shots)?;
    Ok(0)
}

/// The items of a comma-separated list flag, refused when one is listed twice.
fn listed_once<T: Copy + PartialEq>(
    flag: &str,
    items: &[T],
    name: impl Fn(T) -> &'static str,
) -> Result<Vec<T>, CliError> {
    let mut once: Vec<T> = Vec::with_capacity(items.len());
    for &item in items {
        if once.contains(&item) {
            return Err(CliError::Usage(format!(
                "{flag}: `{}` is listed twice",
                name(item)
            )));
        }
        once.push(item);
    }
    Ok(once)
}

/// A cache of `kind` with the flags' budget and async options, over `scene` (or the container
/// opened anew).
fn open_cache(
    a: &Args,
    scene: Option<Arc<Scene>>,
    kind: CacheKind,
    lod: Option<LodKind>,
) -> Result<(Arc<Scene>, Cache), CliError> {
    let opts = AsyncOptions {
        fetchers: usize::try_from(a.fetchers).unwrap_or(1),
        read_ahead: a.read_ahead,
        ..AsyncOptions::default()
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

/// `--json`, `--plot` and `--sheet`.
fn write_files(
    a: &Args,
    curve: &Curve<'_>,
    fixed: Option<&sheet::Fixed>,
    shots: &[Shot],
) -> Result<(), CliError> {
    if let Some(p) = &a.json {
        write_json(p, curve)?;
    }
    if let Some(p) = &a.plot {
        plot::write(p, &a.model, curve.rows, curve.floor.error.model.rmse)?;
    }
    if let (Some(p), Some(f)) = (&a.sheet, fixed) {
        sheet::write(
            p,
            f,
            (curve.reference.spp, curve.floor.error.model.rmse),
            shots,
        )?;
    }
    Ok(())
}

/// The full-detail renders of the cameras: the references and the floor's figures.
struct FullDetail {
    /// Per camera, the reference image.
    references: Vec<Image>,
    reference: Reference,
    floor: Floor,
    /// The first camera's floor image, for the sheet.
    first_floor: Option<Image>,
}

/// Renders each camera at full detail with `base`'s lighting through a blocking cache of
/// `budget` bytes: the reference at `spp` rays per pixel, and at one ray per pixel the floor,
/// measured against it at once (only the first camera's floor image is kept).
fn render_full_detail(
    (scene, cameras): (&Arc<Scene>, &[Camera]),
    base: &RenderOptions,
    budget: usize,
    (spp, tolerance): (u32, u8),
) -> Result<FullDetail, CliError> {
    let cache = BlockingCache::new(Arc::clone(scene), budget);
    let floor_opts = RenderOptions {
        poe: 0.0,
        spp: 1,
        ..*base
    };
    let reference_opts = reference_options(&floor_opts, spp);
    let blank = |spp| Reference {
        cache: "blocking",
        poe: 0.0,
        spp,
        ms: 0.0,
        primary: Endings::default(),
    };
    let (mut reference, mut floor) = (blank(spp), blank(floor_opts.spp));
    let mut references = Vec::with_capacity(cameras.len());
    let mut first_floor = None;
    let mut acc = Accumulator::new(tolerance);
    for camera in cameras {
        let r = frame(scene, &cache, camera, &reference_opts)?;
        add_endings(&mut reference.primary, &r.stats.primary);
        reference.ms += r.stats.ms;
        let f = frame(scene, &cache, camera, &floor_opts)?;
        add_endings(&mut floor.primary, &f.stats.primary);
        floor.ms += f.stats.ms;
        acc.add(&r.image, &f.image)?;
        references.push(r.image);
        if first_floor.is_none() {
            first_floor = Some(f.image);
        }
    }
    let n = cameras.len().max(1) as f64;
    reference.ms /= n;
    floor.ms /= n;
    Ok(FullDetail {
        references,
        reference,
        floor: Floor {
            render: floor,
            error: acc.finish(),
        },
        first_floor,
    })
}

fn add_endings(sum: &mut Endings, e: &Endings) {
    sum.triangle += e.triangle;
    sum.voxel += e.voxel;
    sum.rlod += e.rlod;
    sum.proxy += e.proxy;
    sum.miss += e.miss;
}

/// Warms `cache` on every camera with `opts`, renders one recorded pass for the blocks
/// touched, then `repeat` timed passes; returns the figures and the first camera's last image.
fn measure(
    a: &Args,
    scene: &Scene,
    cache: &Cache,
    (kind, lod): (CacheKind, LodKind),
    opts: &RenderOptions,
    cameras: &[Camera],
    references: &[Image],
) -> Result<(Row, Image), CliError> {
    let (opts, poe) = (*opts, opts.poe);
    let mut settle_frames = 0;
    let cold = cache.get().render_waits();
    for camera in cameras {
        settle_frames += settle(scene, cache, camera, &opts)?.frames;
    }
    let settle_waits = cache.get().render_waits().saturating_sub(cold);
    let touched = Touched::new(cache.get());
    for camera in cameras {
        frame(scene, &touched, camera, &opts)?;
    }
    let blocks_touched = touched.count();
    let mut pass_ms = Vec::with_capacity(a.repeat as usize);
    let mut last = Vec::new();
    let (mut rays, mut nodes, mut primary) = (0u64, 0u64, Endings::default());
    let (mut bytes_resident, mut waits) = (0, 0);
    for _ in 0..a.repeat {
        let (mut ms, mut images) = (0.0, Vec::with_capacity(cameras.len()));
        (rays, nodes, primary) = (0, 0, Endings::default());
        for camera in cameras {
            let session::Frame { image, stats, .. } = frame(scene, cache.get(), camera, &opts)?;
            ms += stats.ms;
            rays += stats.rays;
            nodes += stats.nodes_visited;
            add_endings(&mut primary, &stats.primary);
            bytes_resident = stats.cache.bytes_resident;
            waits += stats.waits;
            images.push(image);
        }
        pass_ms.push(ms);
        last = images;
    }
    warn_missing(&cache.get().stats().missing_blocks);
    let mut acc = Accumulator::new(a.tolerance);
    for (r, t) in references.iter().zip(&last) {
        acc.add(r, t)?;
    }
    pass_ms.sort_by(f64::total_cmp);
    let median_pass = oocfmt_trace::compare::median_sorted(&pass_ms);
    let frames = cameras.len().max(1) as f64;
    let row = Row {
        cache: kind.name().to_string(),
        lod: lod.name(),
        poe,
        io: cache.get().stats().io,
        settle_frames,
        settle_waits,
        waits,
        ms: median_pass / frames,
        rays_per_second: rays as f64 / (median_pass / 1e3).max(1e-9),
        nodes_per_ray: nodes as f64 / rays.max(1) as f64,
        working_set_mb: bytes_resident as f64 / 1048576.0,
        blocks_touched,
        primary,
        error: acc.finish(),
    };
    let first = last
        .into_iter()
        .next()
        .ok_or_else(|| CliError::Usage("the walkthrough has no frames".to_string()))?;
    Ok((row, first))
}

/// The speed columns of the table, and the width they take.
const SPEED_HEADER: [&str; 13] = [
    "cache",
    "lod",
    "poe",
    "ms",
    "Mrays/s",
    "nodes/ray",
    "WS MiB",
    "blocks",
    "tri%",
    "voxel%",
    "rlod%",
    "proxy%",
    "miss%",
];

fn speed_header() -> String {
    let [c, l, p, ms, mr, n, ws, b, t, v, r, x, m] = SPEED_HEADER;
    format!("{c:<8} {l:<5} {p:>5} {ms:>9} {mr:>8} {n:>9} {ws:>8} {b:>7} {t:>6} {v:>6} {r:>6} {x:>6} {m:>6}")
}

fn speed_columns(r: &Row) -> String {
    let p = &r.primary;
    let n = (p.triangle + p.voxel + p.rlod + p.proxy + p.miss).max(1) as f64;
    let pct = |x: u64| 100.0 * x as f64 / n;
    format!(
        "{:<8} {:<5} {:>5} {:>9.2} {:>8.2} {:>9.1} {:>8.1} {:>7} {:>6.1} {:>6.1} {:>6.1} {:>6.1} {:>6.1}",
        r.cache,
        r.lod,
        r.poe,
        r.ms,
        r.rays_per_second / 1e6,
        r.nodes_per_ray,
        r.working_set_mb,
        r.blocks_touched,
        pct(p.triangle),
        pct(p.voxel),
        pct(p.rlod),
        pct(p.proxy),
        pct(p.miss),
    )
}

fn error_header(tolerance: u8) -> String {
    format!(
        "{:>7} {:>6} {:>7} {:>7} {:>6} {:>8} {:>8} {:>8} {:>9} {:>9}",
        "RMSE",
        "PSNR",
        "SSIM",
        format!("<={tolerance}%"),
        "bias",
        "all RMSE",
        "all PSNR",
        "hit/miss",
        "depth med",
        "depth max"
    )
}

fn error_columns(e: &ImageError) -> String {
    let (m, w) = (&e.model, &e.whole);
    format!(
        "{:>7.3} {:>6} {:>7.4} {:>7.2} {:>+6.2} {:>8.3} {:>8} {:>8} {:>9.2e} {:>9.2e}",
        m.rmse,
        db(m.psnr_db),
        m.ssim,
        100.0 * m.within_tolerance,
        m.bias,
        w.rmse,
        db(w.psnr_db),
        e.depth.hit_miss_differ,
        e.depth.median_relative,
        e.depth.max_relative,
    )
}

fn print_table(
    a: &Args,
    cameras: &[Camera],
    full: &FullDetail,
    rows: &[Row],
) -> Result<(), CliError> {
    let (w, h) = a.view.size;
    let model_pixels = full.floor.error.model.pixels;
    outln!(
        "{}: {w}x{h}, {} camera(s), {} threads, {}; warm caches, median of {} timed frame(s)",
        a.model.display(),
        cameras.len(),
        rayon::current_num_threads(),
        lighting(a),
        a.repeat,
    )?;
    outln!(
        "error against full detail at {} rays per pixel (PoE 0, blocking cache, {:.1} ms cold) \
         on the model's pixels (hit in either image: {model_pixels} for the floor); \"all\": the \
         whole image",
        full.reference.spp,
        full.reference.ms,
    )?;
    let speed = speed_header();
    outln!("{speed} {}", error_header(a.tolerance))?;
    let floor = format!(
        "aliasing floor: PoE 0, 1 ray per pixel, blocking ({:.2} ms cold)",
        full.floor.render.ms
    );
    outln!(
        "{floor:<width$} {}",
        error_columns(&full.floor.error),
        width = speed.len()
    )?;
    for r in rows {
        outln!("{} {}", speed_columns(r), error_columns(&r.error))?;
    }
    Ok(())
}

/// The file name of `model` for titles.
fn model_name(model: &Path) -> String {
    model
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| model.display().to_string())
}

/// How the images are lit, in words.
fn lighting(a: &Args) -> String {
    let light = match a.shadows {
        true => "point light with shadow rays",
        false => "headlight",
    };
    match a.ao {
        Some(n) => format!("{light}, ambient occlusion with {n} rays per hit"),
        None => light.to_string(),
    }
}
