//! `oocfmt`: inspect, verify and build `.oocf` containers.
//!
//! Exit status: 0 success (for `verify`: the file is valid); 1 the file is invalid or a format
//! error stopped the command; 2 the command could not run (bad usage, I/O error).

#![forbid(unsafe_code)]

mod accuracy;
mod convert;
mod curve;
mod demo;
mod error;
mod export;
mod gen;
mod hexdump;
mod inspect;
mod inspect_block;
mod out;
mod progress;
mod render;
mod verify;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "oocfmt",
    version,
    about = "Out-of-core ray tracing containers (.oocf): inspect, verify, build"
)]
#[command(
    after_help = "Exit status: 0 success (verify: valid), 1 invalid file, 2 could not run (usage, I/O)."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Summarise a container: header, per-LOD-level table, residency, tree statistics, metadata
    Inspect(inspect::Args),
    /// Check a container and report every problem with a stable issue code
    Verify(verify::Args),
    /// Convert OBJ and glTF files into one container
    Convert(convert::Args),
    /// Write the full-detail triangles of a container back out as OBJ or PLY
    Export(export::Args),
    /// Generate a test scene as OBJ (streaming, any size)
    Gen(gen::Args),
    /// Build a container from the built-in demo scene, then inspect and verify it
    Demo(demo::Args),
    /// Ray trace one frame of a container to PNG (LOD by pixels of error)
    Render(render::Args),
    /// Speed against error: render a view at a list of PoEs, compare each with full detail
    Curve(curve::Args),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    let result = match cli.command {
        Command::Inspect(a) => inspect::run(&a),
        Command::Verify(a) => verify::run(&a),
        Command::Convert(a) => convert::run(&a),
        Command::Export(a) => export::run(&a),
        Command::Gen(a) => gen::run(&a),
        Command::Demo(a) => demo::run(&a),
        Command::Render(a) => render::run(&a),
        Command::Curve(a) => curve::run(&a),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("oocfmt: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
