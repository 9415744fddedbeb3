//! `oocfmt convert`: OBJ, glTF, STL and PLY files (or standard input) into one container.
//! Ctrl-C and SIGTERM stop the build at its next check, which then removes its spill folder
//! and temporary output; a second one ends the process at once.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use oocfmt::records::LodKinds;
use oocfmt::{Codec, WriteOptions};
use oocfmt_build::convert::{convert, ConvertError, ConvertOptions, InputFormat, MIN_MEM_LIMIT};
use oocfmt_build::kdtree::KdBuildOptions;
use oocfmt_build::layout::LayoutOptions;
use oocfmt_build::report::{total_memory, ConvertReport};
use oocfmt_build::Interrupt;
use oocfmt_meshio::import::gltf::GltfOptions;
use oocfmt_meshio::import::obj::ObjOptions;
use oocfmt_meshio::import::{Recentre, Skipped};

use crate::args::{self, use_threads, LodKindsArg};
use crate::error::{to_json, CliError, CliResult};
use crate::out::out;
use crate::progress::Phases;

#[derive(clap::Args)]
pub struct Args {
    /// Input files (.obj, .gltf, .glb, .stl, .ply); several become one scene. `-` reads
    /// standard input, which needs --format
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// The inputs' format, whatever their names (standard input has none): obj, ply, stl or
    /// gltf (not from standard input)
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// The container to write
    #[arg(short, long)]
    pub output: PathBuf,
    /// Block codec: none, lz4, zstd or zstd:LEVEL (none is what a memory-mapped reader wants)
    #[arg(long, default_value = "lz4", value_parser = args::parse_codec)]
    pub codec: Codec,
    /// Block size in bytes: a power of two from 4096 to 1048576
    #[arg(long, default_value_t = 65536)]
    pub block_size: u64,
    /// Most triangles per kd-tree leaf (1..=4095)
    #[arg(long, default_value_t = 8)]
    pub max_leaf: u32,
    /// Node levels per treelet; every this-many levels holds the LOD voxels
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..=8))]
    pub treelet_height: u8,
    /// LOD representations to store in the LOD nodes: rlod (planes, Yoon et al. 2006), voxel
    /// (Áfra 2012) or both, in core or out of core alike
    #[arg(long, value_enum, default_value = "rlod")]
    pub lod: LodKindsArg,
    /// Write opaque, unfiltered LOD records as version 1.1 did (no shade or coverage, spec
    /// §5.1): for 1.1 readers, and to measure what pre-filtering gains
    #[arg(long)]
    pub unfiltered: bool,
    /// Refuse the first bad triangle (NaN, out-of-range index, zero area) instead of dropping it
    #[arg(long)]
    pub strict: bool,
    /// Memory the build may use, e.g. 2G, 512M, at least 16M (default: half the physical
    /// memory). A larger scene is built out of core, in chunks that fit
    #[arg(long, value_parser = parse_mem_limit)]
    pub mem_limit: Option<u64>,
    /// Store positions relative to an origin: none (positions exactly as read), auto (near
    /// the centre of the input's bounds; one more pass over the input, so not with `-`) or
    /// X,Y,Z. For models far from zero, where f32 positions would lose precision; the report
    /// gives the error
    #[arg(
        long,
        default_value = "none",
        value_name = "auto|none|X,Y,Z",
        allow_hyphen_values = true
    )]
    pub recentre: Recentre,
    /// glTF: import every scene, not only the default one
    #[arg(long)]
    pub all_scenes: bool,
    /// Also write the report as JSON to this file
    #[arg(long)]
    pub report_json: Option<PathBuf>,
    /// Folder for the spill files of the import and the out-of-core build (default: next to
    /// the output). They take about 37 bytes a triangle, more with normals or colours
    #[arg(long, value_name = "DIR")]
    pub tmp_dir: Option<PathBuf>,
    /// Worker threads (default: all cores)
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bars
    #[arg(long)]
    pub quiet: bool,
}

/// `--format`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FormatArg {
    Obj,
    Ply,
    Stl,
    Gltf,
}

impl From<FormatArg> for InputFormat {
    fn from(f: FormatArg) -> InputFormat {
        match f {
            FormatArg::Obj => InputFormat::Obj,
            FormatArg::Ply => InputFormat::Ply,
            FormatArg::Stl => InputFormat::Stl,
            FormatArg::Gltf => InputFormat::Gltf,
        }
    }
}

/// A `--mem-limit`: a size of at least [`MIN_MEM_LIMIT`].
fn parse_mem_limit(s: &str) -> Result<u64, String> {
    let v = args::parse_byte_size(s)?;
    if v < MIN_MEM_LIMIT {
        return Err(format!(
            "`{s}`: below the minimum of {}M (the importers and one chunk of the out-of-core build need that much)",
            MIN_MEM_LIMIT >> 20
        ));
    }
    Ok(v)
}

pub fn run(a: &Args) -> CliResult {
    use_threads(a.threads)?;
    let write = WriteOptions {
        codec: a.codec,
        lod: if a.unfiltered {
            LodKinds::from(a.lod)
        } else {
            LodKinds::from(a.lod).filtered()
        },
        ..WriteOptions::default()
    }
    .with_block_size(a.block_size)?;
    let opts = ConvertOptions {
        layout: LayoutOptions {
            write,
            treelet_height: a.treelet_height,
            ..LayoutOptions::default()
        },
        kd: KdBuildOptions {
            max_leaf_triangles: a.max_leaf,
            ..KdBuildOptions::default()
        },
        strict: a.strict,
        mem_limit: a
            .mem_limit
            .unwrap_or_else(|| total_memory().map_or(4 << 30, |m| m / 2)),
        obj: ObjOptions::default(),
        gltf: GltfOptions {
            all_scenes: a.all_scenes,
            ..GltfOptions::default()
        },
        recentre: a.recentre,
        tmp_dir: a.tmp_dir.clone(),
        format: a.format.map(InputFormat::from),
        interrupt: Interrupt::new(),
    };
    let signal = on_signals(&opts.interrupt)?;
    let mut progress = Phases::new(a.quiet);
    let report = match convert(&a.inputs, &a.output, &opts, &mut progress) {
        Ok(report) => report,
        Err(e @ ConvertError::Interrupted { .. }) => {
            use oocfmt_build::progress::Progress;
            progress.finish_phase();
            return Err(match u8::try_from(signal.load(Ordering::Relaxed)) {
                Ok(n @ 1..=127) => CliError::Interrupted {
                    code: 128 + n,
                    source: e,
                },
                _ => e.into(),
            });
        }
        Err(e) => return Err(e.into()),
    };
    if let Some(path) = &a.report_json {
        std::fs::write(path, to_json(&report)?).map_err(|e| CliError::Io {
            path: path.display().to_string(),
            source: e,
        })?;
    }
    out!("{}", render(&report))?;
    Ok(0)
}

/// Makes SIGINT and SIGTERM request `interrupt` (the build then stops and cleans up), and a
/// second one end the process at once with 128 + its number. Returns where the number of the
/// last signal received is kept (0: none).
fn on_signals(interrupt: &Interrupt) -> Result<Arc<AtomicUsize>, CliError> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    use signal_hook::flag;
    let received = Arc::new(AtomicUsize::new(0));
    let io = |source| CliError::Io {
        path: "signal handler".into(),
        source,
    };
    for signal in [SIGINT, SIGTERM] {
        // In this order: the second signal finds the flag the first one set.
        flag::register_conditional_shutdown(signal, 128 + signal, Arc::clone(interrupt.flag()))
            .map_err(io)?;
        flag::register_usize(signal, Arc::clone(&received), signal as usize).map_err(io)?;
        flag::register(signal, Arc::clone(interrupt.flag())).map_err(io)?;
    }
    Ok(received)
}

fn render(r: &ConvertReport) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let i = &r.import;
    let _ = writeln!(
        o,
        "wrote      {} ({} bytes, identity {})",
        r.output, r.file_bytes, r.identity
    );
    let _ = writeln!(o, "inputs     {}", i.files.join(", "));
    let _ = writeln!(
        o,
        "triangles  {} in, {} out, {} dropped",
        i.triangles_in,
        i.triangles_out,
        i.dropped_total()
    );
    for (reason, n) in &i.dropped {
        let _ = writeln!(o, "           dropped {n}: {}", reason.describe());
    }
    for (what, n) in &i.skipped {
        let what = match what {
            Skipped::Lines => "line segments",
            Skipped::Points => "points",
            Skipped::NonTrianglePrimitives => "non-triangle glTF primitives",
        };
        let _ = writeln!(o, "           skipped {n} {what}");
    }
    for w in &i.warnings {
        let _ = writeln!(o, "warning    {w}");
    }
    let p = &i.placement;
    let _ = writeln!(
        o,
        "positions  origin {} {} {}: largest coordinate error {:.3e} ({:.3e} without an origin)",
        p.origin[0], p.origin[1], p.origin[2], p.max_abs_error, p.max_abs_error_without_origin
    );
    let _ = writeln!(
        o,
        "tree       {} basic + {} LOD nodes, {} leaves, depth {}",
        r.basic_nodes, r.lod_nodes, r.leaves, r.depth
    );
    let _ = writeln!(o, "LOD        {}: {}", r.lod_kinds, lod_line(r));
    for (kind, b) in &r.blocks {
        let _ = writeln!(
            o,
            "blocks     {kind:<9} {:>7} blocks, {:>12} raw, {:>12} stored bytes",
            b.blocks, b.raw_bytes, b.stored_bytes
        );
    }
    if let Some(c) = &r.out_of_core {
        let _ = writeln!(
            o,
            "out of core {} chunks of at most {} triangles (largest {}, {} over), {} copies of straddling triangles, {} LOD nodes above the chunks",
            c.chunks,
            c.chunk_budget_triangles,
            c.largest_chunk_triangles,
            c.oversized_chunks,
            c.split_copies,
            c.top_lod_nodes
        );
    }
    let phases: Vec<String> = r
        .phases
        .iter()
        .map(|p| format!("{} {:.2} s", p.phase, p.seconds))
        .collect();
    let _ = writeln!(
        o,
        "time       {:.2} s ({}): {:.0} triangles/s",
        r.seconds,
        phases.join(", "),
        r.triangles_per_second
    );
    if let Some(peak) = r.peak_memory_bytes {
        let _ = writeln!(
            o,
            "memory     peak {:.1} MiB (limit {:.1} MiB)",
            peak as f64 / 1048576.0,
            r.mem_limit_bytes as f64 / 1048576.0
        );
    }
    let estimate = match r.disk_estimate_bytes {
        Some(e) => format!("estimated {:.1} MiB", e as f64 / 1048576.0),
        None => "no estimate: an input's size was unknown".to_string(),
    };
    let _ = writeln!(
        o,
        "disk       peak {:.1} MiB ({estimate}), spill {:.1} bytes/triangle",
        r.peak_disk_bytes as f64 / 1048576.0,
        r.spill_bytes_per_triangle
    );
    o
}

/// The LOD records a conversion wrote: voxels by sample count and R-LODs (one per LOD node
/// when the file holds them), then the proxies.
fn lod_line(r: &ConvertReport) -> String {
    let mut parts = Vec::new();
    if r.lod_kinds.contains("voxel") {
        parts.push(format!(
            "{} one-sample + {} six-sample voxels",
            r.voxels_single, r.voxels_six
        ));
    }
    if r.lod_kinds.contains("rlod") {
        parts.push(format!("{} R-LODs", r.lod_nodes));
    }
    parts.push(format!("{} proxies", r.proxies));
    parts.join(", ")
}

#[cfg(test)]
mod tests {
    use super::lod_line;
    use oocfmt_build::report::ConvertReport;

    fn report(kinds: &str) -> ConvertReport {
        ConvertReport {
            lod_kinds: kinds.to_owned(),
            lod_nodes: 7,
            voxels_single: 3,
            voxels_six: 4,
            proxies: 2,
            ..ConvertReport::default()
        }
    }

    #[test]
    fn the_lod_line_names_what_the_file_holds() {
        assert_eq!(lod_line(&report("rlod")), "7 R-LODs, 2 proxies");
        assert_eq!(
            lod_line(&report("voxel")),
            "3 one-sample + 4 six-sample voxels, 2 proxies"
        );
        assert_eq!(
            lod_line(&report("voxel+rlod")),
            "3 one-sample + 4 six-sample voxels, 7 R-LODs, 2 proxies"
        );
    }
}
