//! `oocfmt convert`: OBJ, glTF, STL and PLY files (or standard input) into one container.
//! Ctrl-C and SIGTERM stop the build at its next check, which then removes its spill folder
//! and temporary output; a second one ends the process at once.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use oocfmt_build::convert::{convert, ConvertError};
use oocfmt_build::report::ConvertReport;
use oocfmt_build::Interrupt;
use oocfmt_meshio::import::Skipped;

use crate::args::use_threads;
use crate::build_args::BuildArgs;
use crate::error::{to_json, CliError, CliResult};
use crate::out::out;
use crate::progress::Phases;

#[derive(clap::Args)]
pub struct Args {
    /// Input files (.obj, .gltf, .glb, .stl, .ply); several become one scene. `-` reads
    /// standard input, which needs --format
    #[arg(required_unless_present = "plan", conflicts_with = "plan")]
    pub inputs: Vec<PathBuf>,
    /// Build from a plan (`oocfmt plan`): its inputs, with its settings. With --subset, only
    /// that subset, into a subset file for `oocfmt merge`; without, every subset and the
    /// merge in this process
    #[arg(long, value_name = "PLAN")]
    pub plan: Option<PathBuf>,
    /// With --plan: the subset to build (0 to the plan's subsets - 1)
    #[arg(long, requires = "plan", value_name = "I")]
    pub subset: Option<u32>,
    /// The container to write (with --subset: the subset file, .oocfp)
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub build: BuildArgs,
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

pub fn run(a: &Args) -> CliResult {
    use_threads(a.threads)?;
    if let Some(plan) = &a.plan {
        return crate::subsets::convert_planned(a, plan);
    }
    let opts = a.build.options(a.tmp_dir.clone())?;
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
    write_report_json(a.report_json.as_deref(), &report)?;
    out!("{}", render(&report))?;
    Ok(0)
}

/// Writes `report` as JSON to `path`, when one is given.
pub fn write_report_json<T: serde::Serialize>(
    path: Option<&std::path::Path>,
    report: &T,
) -> Result<(), CliError> {
    if let Some(path) = path {
        std::fs::write(path, to_json(report)?).map_err(|e| CliError::Io {
            path: path.display().to_string(),
            source: e,
        })?;
    }
    Ok(())
}

/// Makes SIGINT and SIGTERM request `interrupt` (the build then stops and cleans up), and a
/// second one end the process at once with 128 + its number. Returns where the number of the
/// last signal received is kept (0: none).
pub fn on_signals(interrupt: &Interrupt) -> Result<Arc<AtomicUsize>, CliError> {
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

pub fn render(r: &ConvertReport) -> String {
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
