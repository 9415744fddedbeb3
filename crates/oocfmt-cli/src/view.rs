//! `oocfmt view`: flies through a container live in the browser. This module reads the flags,
//! opens the scene and its cache, starts the render thread ([`oocfmt_trace::live::Viewer`]) and
//! the server ([`oocfmt_view::run`]), and prints the page's URL, token included, as the first
//! line on standard output. Ctrl-C stops it.

use std::net::IpAddr;
use std::path::PathBuf;

use oocfmt_trace::cache::asynchronous::AsyncOptions;
use oocfmt_trace::live::{LiveOptions, Quality, Viewer};
use oocfmt_trace::session::{Cache, CacheKind};
use oocfmt_trace::RenderOptions;
use oocfmt_view::{ViewConfig, ViewError};

use crate::args::{self, budget_bytes, use_threads, CacheArg, IoArg, LodArg};
use crate::error::{CliError, CliResult};
use crate::out::outln;

#[derive(clap::Args)]
pub struct Args {
    /// The container to view
    pub model: PathBuf,
    /// Port to listen on; 0 takes any free one (the URL printed says which)
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    /// Address to listen on. The default serves this machine only; another address (0.0.0.0 or
    /// `::`: every interface, and the URL names this machine) lets anyone who can reach it and
    /// has the URL's token drive the viewer
    #[arg(long, default_value = "127.0.0.1")]
    pub bind: IpAddr,
    /// Also open the page in the system's browser (xdg-open, or open on macOS)
    #[arg(long)]
    pub open: bool,
    /// Milliseconds a frame may take while the camera moves: the resolution, then the PoE, are
    /// lowered to hold it
    #[arg(long, default_value_t = LiveOptions::DEFAULT.target_ms, value_parser = parse_target_ms)]
    pub target_ms: f64,
    /// Pixels of error of the still image, once the camera stops (0: full detail); the page
    /// can change it
    #[arg(long, default_value_t = 1.0, value_parser = parse_poe)]
    pub poe: f32,
    /// Samples per pixel the still image accumulates, one pass at a time through the points
    /// `render --spp` takes; the page can change it
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=i64::from(oocfmt_trace::render::MAX_SAMPLES)))]
    pub spp: u32,
    /// Memory for decoded blocks, in MiB
    #[arg(long, alias = "cache-mib", default_value_t = 1024, value_parser = clap::value_parser!(u64).range(1..=1 << 30))]
    pub cache_mb: u64,
    /// Block cache: `async` (rays never wait; frames show coarser levels where blocks are still
    /// loading and sharpen as they arrive), `blocking` (every frame waits for its blocks: moving
    /// frames stall) or `mmap` (needs a container converted with `--codec none`)
    #[arg(long, value_enum, default_value = "async")]
    pub cache: CacheArg,
    /// How the async and blocking caches read blocks (as for `render`): `buffered` or `direct`
    /// (past the page cache); not with mmap
    #[arg(long, value_enum, default_value = "buffered")]
    pub io: IoArg,
    /// LOD representation to stop on (default: rlod when the file has R-LODs, else voxel)
    #[arg(long, value_enum)]
    pub lod: Option<LodArg>,
    /// Fetcher threads of the async cache (default: half the cores, at least one)
    #[arg(long, default_value_t = args::default_fetchers(), value_parser = clap::value_parser!(u64).range(1..=64))]
    pub fetchers: u64,
    /// Render threads (default: all cores)
    #[arg(long)]
    pub threads: Option<usize>,
}

/// A frame time in milliseconds: 1 to 10000.
fn parse_target_ms(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if (1.0..=10_000.0).contains(&v) => Ok(v),
        _ => Err(format!("`{s}`: expected milliseconds, 1 to 10000")),
    }
}

/// Pixels of error within the live view's range.
fn parse_poe(s: &str) -> Result<f32, String> {
    let max = oocfmt_trace::live::view::MAX_POE;
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && (0.0..=max).contains(&v) => Ok(v),
        _ => Err(format!("`{s}`: expected pixels of error, 0 to {max}")),
    }
}

fn view_error(e: ViewError) -> CliError {
    match e {
        ViewError::Trace(t) => CliError::Trace(t),
        ViewError::Bind { addr, source } => CliError::Io {
            path: format!("listening on {addr}"),
            source,
        },
        ViewError::Runtime(source) | ViewError::Serve(source) | ViewError::Signal(source) => {
            CliError::Io {
                path: "the viewer's server".into(),
                source,
            }
        }
        ViewError::Random(why) => CliError::Io {
            path: "the token's random source".into(),
            source: std::io::Error::other(why),
        },
    }
}

/// Starts the system's browser on `url`, in the background; a failure is only a warning (the
/// URL is printed anyway).
fn open_browser(url: &str) {
    let program = if cfg!(target_os = "macos") {
        "open"
    } else {
        "xdg-open"
    };
    let spawned = std::process::Command::new(program)
        .arg(url)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn();
    if let Err(e) = spawned {
        eprintln!("oocfmt: warning: --open: cannot start {program}: {e}");
    }
}

pub fn run(a: &Args) -> CliResult {
    use_threads(a.threads)?;
    let kind = CacheKind::from(a.cache);
    let lod = a.lod.map(Into::into);
    let scene = args::scene_for(&a.model, kind, lod, a.io)?;
    let opts = AsyncOptions {
        fetchers: usize::try_from(a.fetchers).unwrap_or(1),
        ..AsyncOptions::default()
    };
    let (scene, cache) = Cache::open(&a.model, scene, kind, budget_bytes(a.cache_mb), &opts, lod)?;
    if let Some(note) = args::io_note(a.io, &scene) {
        eprintln!("oocfmt: {note}");
    }
    let live = LiveOptions {
        target_ms: a.target_ms,
        still_ms: (3.0 * a.target_ms).max(LiveOptions::DEFAULT.still_ms),
        ..LiveOptions::DEFAULT
    };
    let viewer = Viewer::start(scene, cache, RenderOptions::DEFAULT, live)?;
    let name = a.model.file_name().map_or_else(
        || a.model.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let config = ViewConfig {
        bind: a.bind,
        port: a.port,
        quality: Quality {
            poe: a.poe,
            spp: a.spp,
        },
        name,
    };
    if !a.bind.is_loopback() {
        eprintln!(
            "oocfmt: warning: --bind {}: anyone who can reach this address and has the URL's \
             token can drive the viewer",
            a.bind
        );
    }
    let mut printed = Ok(());
    oocfmt_view::run(viewer, &config, |running| {
        printed = outln!("{}", running.url());
        if running.addr().ip().is_unspecified() {
            eprintln!(
                "oocfmt: listening on all interfaces ({}); the URL names this machine as `{}`: \
                 where that name does not reach it, put one of its addresses in its place",
                running.addr(),
                running.host()
            );
        }
        eprintln!("oocfmt: viewing {}; Ctrl-C stops", a.model.display());
        if a.open {
            open_browser(running.url());
        }
    })
    .map_err(view_error)?;
    printed?;
    Ok(0)
}
