//! `oocfmt render`: one frame of a container with the reference CPU ray tracer.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

use oocfmt_trace::output::{write_pfm, write_png};
use oocfmt_trace::{render, BlockingCache, Camera, RenderOptions, Scene, TraceError};

use crate::error::{to_json, CliError, CliResult};

#[derive(clap::Args)]
pub struct Args {
    /// The container to render
    pub model: PathBuf,
    /// The PNG to write
    #[arg(short, long)]
    pub output: PathBuf,
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
    /// Pixels of error: a ray stops on a LOD voxel whose radius is at most this many pixels;
    /// 0 renders full detail
    #[arg(long, default_value_t = 1.0)]
    pub poe: f32,
    /// Block cache: only `blocking` for now (every block is read when a ray needs it: the exact
    /// reference); the asynchronous and mmap caches are yet to come
    #[arg(long, default_value = "blocking", value_parser = ["blocking"])]
    pub cache: String,
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
}

/// `WIDTHxHEIGHT`, each 1 ..= 16384.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
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
fn parse_vec3(s: &str) -> Result<[f64; 3], String> {
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
        e @ (TraceError::Camera(_) | TraceError::Options(_)) => CliError::Usage(e.to_string()),
    }
}

pub fn run(a: &Args) -> CliResult {
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| CliError::Usage(format!("--threads {n}: {e}")))?;
    }
    let scene = Arc::new(Scene::open(&a.model).map_err(cli_error)?);
    let m = scene.metadata();
    let origin = m.scene.origin;
    let stored = |p: [f64; 3]| [0, 1, 2].map(|k| p[k] - origin[k]);
    let (w, h) = a.size;
    let mut camera = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, w, h);
    if let Some(e) = a.eye {
        camera.eye = stored(e);
    }
    if let Some(l) = a.look_at {
        camera.look_at = stored(l);
    }
    if let Some(u) = a.up {
        camera.up = u;
    }
    camera.fov_y = a.fov_y;
    let budget = usize::try_from(a.cache_mb << 20).unwrap_or(usize::MAX);
    let cache = BlockingCache::new(Arc::clone(&scene), budget);
    let opts = RenderOptions {
        poe: a.poe,
        ..RenderOptions::default()
    };
    let mut frame = render(&scene, &cache, &camera, &opts).map_err(cli_error)?;
    for _ in 1..a.repeat {
        frame = render(&scene, &cache, &camera, &opts).map_err(cli_error)?;
    }
    let (image, stats) = frame;
    write_png(&a.output, image.width, image.height, &image.rgb).map_err(cli_error)?;
    if let Some(d) = &a.depth_out {
        write_pfm(d, image.width, image.height, &image.depth).map_err(cli_error)?;
    }
    if let Some(s) = &a.stats_json {
        let json = to_json(&stats)?;
        std::fs::write(s, json + "\n").map_err(|source| CliError::Io {
            path: s.display().to_string(),
            source,
        })?;
    }
    let p = &stats.primary;
    // A closed stdout (`| head`) is not an error of the render: the files are written.
    let mut out = std::io::stdout().lock();
    let _ = writeln!(
        out,
        "wrote {} ({}x{}, --poe {}): {:.1} ms, {:.2} Mrays/s on {} threads",
        a.output.display(),
        image.width,
        image.height,
        stats.poe,
        stats.ms,
        stats.rays_per_second / 1e6,
        stats.threads
    );
    let _ = writeln!(
        out,
        "primary rays: {} triangle, {} voxel, {} proxy, {} miss",
        p.triangle, p.voxel, p.proxy, p.miss
    );
    let c = &stats.cache;
    let _ = writeln!(
        out,
        "blocks: {} loaded, {} evicted, {:.1} MiB resident (peak {:.1} MiB of {} MiB)",
        c.blocks_loaded,
        c.blocks_evicted,
        c.bytes_resident as f64 / 1048576.0,
        c.peak_bytes_resident as f64 / 1048576.0,
        a.cache_mb
    );
    for b in &c.missing_blocks {
        eprintln!("oocfmt: warning: block {} is missing: {}", b.id, b.error);
    }
    Ok(0)
}
