//! `oocfmt`: inspect, verify, build and render `.oocf` containers. A thin layer over the
//! library crates: each subcommand's module reads its flags, calls the library and prints or
//! writes what it returns (docs/cli.md is the reference).
//!
//! Exit status, decided in one place ([`error::CliError::exit_code`]):
//! - 0: success (for `verify`: the file is valid; `--help` and `--version` too);
//! - 1: an input is invalid: `verify` found errors, or a container cannot be read as one, or
//!   a model cannot be imported or built into one;
//! - 2: the command could not run: bad usage (an unknown flag, a bad value, a LOD kind the
//!   file lacks, a bad camera path) or an I/O error (a missing input, an unwritable output);
//! - 3: an internal error, a bug in oocfmt (a report that cannot be written as JSON, a broken
//!   invariant of the builder);
//! - 130, 143: `convert` interrupted by SIGINT or SIGTERM (128 + the signal), cleaned up;
//! - 141: `gen -o -` found standard output closed (128 + SIGPIPE).

#![forbid(unsafe_code)]

mod accuracy;
mod args;
mod build_args;
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
mod subsets;
mod verify;
mod view;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "oocfmt",
    version,
    about = "Out-of-core ray tracing containers (.oocf): inspect, verify, build"
)]
#[command(
    after_help = "Exit status: 0 success (verify: valid), 1 invalid input, 2 could not run (usage, I/O), 3 internal error, 130/143 convert interrupted (SIGINT/SIGTERM), 141 gen -o - into a closed pipe."
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
    /// Convert OBJ, glTF, STL and PLY files (or standard input) into one container
    Convert(convert::Args),
    /// Plan a build split into subsets, for separate processes or a batch engine's tasks
    Plan(subsets::PlanArgs),
    /// Merge the subset files of a plan into one container
    Merge(subsets::MergeArgs),
    /// Write the full-detail triangles of a container back out as OBJ or PLY
    Export(export::Args),
    /// Generate a test scene as OBJ (streaming, any size; `-o -`: to standard output)
    Gen(gen::Args),
    /// Build a container from the built-in demo scene, then inspect and verify it
    Demo(demo::Args),
    /// Ray trace one frame of a container to PNG (LOD by pixels of error)
    Render(render::Args),
    /// Speed against error: render a view at a list of PoEs, compare each with full detail
    Curve(curve::Args),
    /// Fly through a container live in the browser: a local server, its URL printed first
    View(view::Args),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let code = if e.use_stderr() { error::EXIT_USAGE } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    let result = match cli.command {
        Command::Inspect(a) => inspect::run(&a),
        Command::Verify(a) => verify::run(&a),
        Command::Convert(a) => convert::run(&a),
        Command::Plan(a) => subsets::run_plan(&a),
        Command::Merge(a) => subsets::run_merge(&a),
        Command::Export(a) => export::run(&a),
        Command::Gen(a) => gen::run(&a),
        Command::Demo(a) => demo::run(&a),
        Command::Render(a) => render::run(&a),
        Command::Curve(a) => curve::run(&a),
        Command::View(a) => view::run(&a),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("oocfmt: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
