//! `oocfmt export`: the full-detail triangles of a container back out as OBJ or PLY.

use std::path::PathBuf;

use oocfmt_meshio::export::{write_obj, write_ply, ExportOptions};

use crate::error::{to_json, CliError, CliResult};
use crate::out::outln;
use crate::progress;

#[derive(clap::Args)]
pub struct Args {
    /// The container to read
    pub file: PathBuf,
    /// The file to write: .obj (with an .mtl beside it when the scene has materials) or .ply
    #[arg(short, long)]
    pub output: PathBuf,
    /// Write stored coordinates bit-exact, without adding the container's origin
    #[arg(long)]
    pub stored_coordinates: bool,
    /// Print the export report as JSON
    #[arg(long)]
    pub json: bool,
    /// No progress bar
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(a: &Args) -> CliResult {
    let ext = a
        .output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let opts = ExportOptions {
        world_coordinates: !a.stored_coordinates,
        ..ExportOptions::default()
    };
    let bar = progress::count("export", a.quiet || a.json);
    let mut tick = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let result = match ext.as_deref() {
        Some("obj") => write_obj(&a.file, &a.output, &opts, &mut tick),
        Some("ply") => write_ply(&a.file, &a.output, &opts, &mut tick),
        _ => {
            return Err(CliError::Usage(format!(
                "{}: the output must end in .obj or .ply",
                a.output.display()
            )))
        }
    };
    bar.finish_and_clear();
    let report = result?;
    if a.json {
        outln!("{}", to_json(&report)?)?;
    } else {
        outln!(
            "wrote {} ({} triangles, {} vertices, {} bytes){}",
            a.output.display(),
            report.triangles,
            report.vertices,
            report.bytes,
            if report.bit_exact {
                String::new()
            } else {
                format!(
                    "; origin added, largest rounding error {:e}",
                    report.max_abs_error
                )
            }
        )?;
    }
    Ok(0)
}
