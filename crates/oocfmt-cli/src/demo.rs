//! `oocfmt demo`: the README's first command, the whole pipeline on a built-in scene: generate a
//! Mandelbulb, convert it, inspect and deep-verify the container, and render it at full detail
//! and at a level of detail, printing where everything is, what it cost and how far each image
//! is from the true picture (full detail supersampled), on the model's pixels and on the whole
//! image.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use oocfmt::records::LodKinds;
use oocfmt::verify::{verify, Depth, VerifyOptions};
use oocfmt::{Codec, FileSource, ReadOptions, Reader, WriteOptions};
use oocfmt_build::convert::{convert, ConvertOptions};
use oocfmt_build::kdtree::KdBuildOptions;
use oocfmt_build::layout::LayoutOptions;
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};
use oocfmt_trace::compare::{compare, ImageError};
use oocfmt_trace::output::write_png;
use oocfmt_trace::{render, BlockingCache, Camera, FrameStats, RenderOptions, Scene};

use crate::accuracy::{self, db, reference_options, region_line};
use crate::args::parse_codec;
use crate::error::{CliError, CliResult};
use crate::out::{out, outln};
use crate::{inspect, progress};

#[derive(clap::Args)]
pub struct Args {
    /// Folder for the output (created if missing)
    #[arg(long, default_value = "oocfmt-demo")]
    pub out: PathBuf,
    /// Approximate triangle count of the generated Mandelbulb
    #[arg(long, default_value_t = 1_000_000, value_parser = clap::value_parser!(u64).range(1000..=100_000_000))]
    pub triangles: u64,
    /// Block codec: none, lz4, zstd or zstd:LEVEL
    #[arg(long, default_value = "lz4", value_parser = parse_codec)]
    pub codec: Codec,
    /// Block size in bytes: a power of two from 4096 to 1048576
    #[arg(long, default_value_t = 65536)]
    pub block_size: u64,
    /// Most triangles per kd-tree leaf (1..=4095)
    #[arg(long, default_value_t = 8)]
    pub max_leaf: u32,
    /// Image width in pixels (the height is three quarters of it)
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(16..=8192))]
    pub width: u32,
    /// The pixels of error of the level-of-detail image, compared with full detail
    #[arg(long, default_value_t = 2.0)]
    pub poe: f32,
    /// Rays per pixel of the reference both images are measured against (full detail, at
    /// the stratified points of `render --spp`)
    #[arg(long, default_value_t = accuracy::DEFAULT_REFERENCE_SPP, value_parser = clap::value_parser!(u32).range(1..=i64::from(accuracy::MAX_REFERENCE_SPP)))]
    pub reference_spp: u32,
}

pub fn run(a: &Args) -> CliResult {
    if !(a.poe.is_finite() && a.poe > 0.0) {
        return Err(CliError::Usage(format!(
            "--poe {}: expected a finite number above 0",
            a.poe
        )));
    }
    // R-LODs, as `convert` stores by default.
    let write = WriteOptions {
        codec: a.codec,
        lod: LodKinds::RLOD.filtered(),
        ..WriteOptions::default()
    }
    .with_block_size(a.block_size)?;
    std::fs::create_dir_all(&a.out).map_err(|e| CliError::Io {
        path: a.out.display().to_string(),
        source: e,
    })?;
    let obj = a.out.join("mandelbulb.obj");
    let path = a.out.join("mandelbulb.oocf");
    generate(&obj, a.triangles)?;
    let file_length = build(a, &obj, &path, write)?;
    let reader = Reader::open(&path, ReadOptions::default())?;
    outln!()?;
    out!("{}", inspect::render(&oocfmt::summary::summarize(&reader)?))?;
    outln!()?;
    if !verify_deep(&path, file_length)? {
        return Ok(1);
    }
    outln!()?;
    render_both(&path, &a.out, (a.width, a.poe, a.reference_spp))?;
    outln!(
        "\nnext: oocfmt render {0} -o view.png --poe 1 --eye X,Y,Z; oocfmt inspect {0}",
        path.display()
    )?;
    Ok(0)
}

/// Writes a Mandelbulb of about `triangles` triangles to `obj`.
fn generate(obj: &Path, triangles: u64) -> Result<(), CliError> {
    let bar = progress::count("generating a Mandelbulb", false);
    let t = Instant::now();
    let gen = mandelbulb::write_obj(
        obj,
        &MandelbulbOptions {
            triangles,
            ..MandelbulbOptions::default()
        },
        &mut |done, total| {
            bar.set_length(total);
            bar.set_position(done)
        },
    )?;
    bar.finish_and_clear();
    outln!(
        "generated  {} ({} triangles, {:.1} MB) in {:.2} s",
        obj.display(),
        gen.triangles,
        gen.bytes as f64 / 1e6,
        t.elapsed().as_secs_f64()
    )
}

/// Converts `obj` into the container `path`; returns its length in bytes.
fn build(a: &Args, obj: &Path, path: &Path, write: WriteOptions) -> Result<u64, CliError> {
    let opts = ConvertOptions {
        layout: LayoutOptions {
            write,
            ..LayoutOptions::default()
        },
        kd: KdBuildOptions {
            max_leaf_triangles: a.max_leaf,
            ..KdBuildOptions::default()
        },
        ..ConvertOptions::default()
    };
    let mut phases = progress::Phases::new(false);
    let report = convert(&[obj.to_path_buf()], path, &opts, &mut phases)?;
    outln!(
        "converted  {} ({} bytes) in {:.2} s: {:.0} triangles/s, peak memory {:.0} MiB",
        path.display(),
        report.file_bytes,
        report.seconds,
        report.triangles_per_second,
        report.peak_memory_bytes.unwrap_or(0) as f64 / 1048576.0
    )?;
    Ok(report.file_bytes)
}

/// Verifies the container at `path` deeply, printing every issue and the verdict; returns
/// whether it is valid.
fn verify_deep(path: &Path, file_length: u64) -> Result<bool, CliError> {
    let src = FileSource::open(path).map_err(|e| CliError::Io {
        path: path.display().to_string(),
        source: e,
    })?;
    let bar = progress::bytes(file_length, "verify --deep", false);
    let t = Instant::now();
    let opts = VerifyOptions {
        depth: Depth::Deep,
        ..VerifyOptions::default()
    };
    let report = verify(&src, &path.display().to_string(), &opts, &|done| {
        bar.set_position(done)
    })?;
    bar.finish_and_clear();
    let secs = t.elapsed().as_secs_f64();
    for issue in &report.issues {
        outln!("{issue}")?;
    }
    outln!(
        "verify     --deep: {} ({} errors, {} warnings) in {secs:.3} s, {:.0} MB/s",
        if report.valid { "valid" } else { "INVALID" },
        report.errors,
        report.warnings,
        file_length as f64 / secs.max(1e-9) / 1e6
    )?;
    Ok(report.valid)
}

/// Renders the default view `width` pixels wide at full detail and at `poe`, writes both PNGs
/// and the reference's (full detail at `spp` rays per pixel), and prints the figures of each
/// and their error against the reference.
fn render_both(
    model: &Path,
    out: &Path,
    (width, poe, spp): (u32, f32, u32),
) -> Result<(), CliError> {
    let scene = Arc::new(Scene::open(model)?);
    let m = scene.metadata();
    let camera = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, width, width * 3 / 4);
    let mut images = Vec::new();
    for p in [0.0, poe] {
        // A fresh cache per image, so each working set is its own.
        let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
        let opts = RenderOptions {
            poe: p,
            ..RenderOptions::default()
        };
        // The first frame loads what the view needs; the second is timed warm.
        render(&scene, &cache, &camera, &opts)?;
        let (image, stats) = render(&scene, &cache, &camera, &opts)?;
        let png = out.join(format!("mandelbulb-poe{p}.png"));
        write_png(&png, image.width, image.height, &image.rgb)?;
        print_frame(&png, &stats)?;
        images.push(image);
    }
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    let opts = reference_options(&RenderOptions::default(), spp);
    let (reference, stats) = render(&scene, &cache, &camera, &opts)?;
    let png = out.join("mandelbulb-reference.png");
    write_png(&png, reference.width, reference.height, &reference.rgb)?;
    outln!(
        "reference  {} (--poe 0 --spp {spp}, cold): {:.1} ms",
        png.display(),
        stats.ms
    )?;
    if let [full, coarse] = &images[..] {
        let pixels = reference.depth.len();
        outln!(
            "error      against the reference, on the model's pixels (those that hit in either \
             image), and on all {pixels} pixels:"
        )?;
        print_error(
            "--poe 0",
            " (full detail, 1 ray per pixel: the aliasing floor)",
            &compare(&reference, full, 8)?,
        )?;
        print_error(
            &format!("--poe {poe}"),
            "",
            &compare(&reference, coarse, 8)?,
        )?;
    }
    Ok(())
}

/// One image's line of error figures.
fn print_error(name: &str, note: &str, e: &ImageError) -> Result<(), CliError> {
    outln!(
        "  {name}{note}\n    model, {} pixels: {}\n    whole image: RMSE {:.2}, PSNR {} dB; \
         {} pixels hit in one image and miss in the other",
        e.model.pixels,
        region_line(&e.model, e.tolerance),
        e.whole.rmse,
        db(e.whole.psnr_db),
        e.depth.hit_miss_differ
    )
}

fn print_frame(png: &Path, s: &FrameStats) -> Result<(), CliError> {
    let p = &s.primary;
    outln!(
        "rendered   {} (--poe {}): {:.1} ms warm, {:.2} Mrays/s; rays end on {} triangles, {} voxels, {} R-LODs, {} proxies, {} misses; working set {:.1} MiB in {} blocks",
        png.display(),
        s.poe,
        s.ms,
        s.rays_per_second / 1e6,
        p.triangle,
        p.voxel,
        p.rlod,
        p.proxy,
        p.miss,
        s.cache.bytes_resident as f64 / 1048576.0,
        s.cache.blocks_loaded
    )
}
