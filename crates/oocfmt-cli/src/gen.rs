//! `oocfmt gen`: streaming scene generators for tests and benchmarks. `-o -` writes the OBJ
//! to standard output (for `oocfmt convert -`), the summary then going to stderr; a reader
//! that goes away early ends it quietly with [`EXIT_BROKEN_PIPE`].

use std::io::ErrorKind;
use std::path::{Path, PathBuf};

use oocfmt_scenes::cad::{self, CadOptions};
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};
use oocfmt_scenes::{GenError, GenReport};

use crate::error::{to_json, CliResult, EXIT_BROKEN_PIPE};
use crate::out::outln;
use crate::progress;

#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub scene: Scene,
}

#[derive(clap::Subcommand)]
pub enum Scene {
    /// The power-8 Mandelbulb isosurface (the data set of the Áfra paper)
    Mandelbulb(Common),
    /// CAD-like clutter: thin pipes, cables and bolts, jittered, with coplanar overlapping panels
    Cad(CadArgs),
}

#[derive(clap::Args)]
pub struct CadArgs {
    #[command(flatten)]
    pub common: Common,
    /// Parts (assemblies and their components, `o` and `g` lines) to name: about this many;
    /// 0 names none. Default: one assembly per group of shapes, one component per shape
    #[arg(long)]
    pub parts: Option<u64>,
}

#[derive(clap::Args)]
pub struct Common {
    /// Approximate triangle count (Mandelbulb within about 20 %, CAD exact): a whole number,
    /// or in scientific notation (`1e9`)
    #[arg(long, value_parser = crate::args::parse_count)]
    pub tris: u64,
    /// The OBJ file to write; `-` writes to standard output (CAD: without its .mtl, so
    /// materials get the default colour)
    #[arg(short, long)]
    pub output: PathBuf,
    /// Seed: the same seed and count give the same file
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Print the report as JSON
    #[arg(long)]
    pub json: bool,
    /// No progress bar
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(a: &Args) -> CliResult {
    let (name, c) = match &a.scene {
        Scene::Mandelbulb(c) => ("mandelbulb", c),
        Scene::Cad(c) => ("cad", &c.common),
    };
    let bar = progress::count(name, c.quiet || c.json);
    let mut tick = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let stream = c.output == Path::new("-");
    let result = generate(&a.scene, stream, &mut tick);
    bar.finish_and_clear();
    let report: GenReport = match result {
        Err(GenError::Write(e)) if stream && e.source.kind() == ErrorKind::BrokenPipe => {
            return Ok(EXIT_BROKEN_PIPE)
        }
        r => r?,
    };
    let summary = match c.json {
        true => to_json(&report)?,
        false => format!(
            "wrote {} ({} triangles, {} vertices, {} bytes)",
            if stream {
                STDOUT.into()
            } else {
                c.output.display().to_string()
            },
            report.triangles,
            report.vertices,
            report.bytes
        ),
    };
    // Standard output holds the model.
    if stream {
        eprintln!("{summary}");
    } else {
        outln!("{summary}")?;
    }
    Ok(0)
}

/// How standard output is named in messages.
const STDOUT: &str = "standard output";

/// Runs the generator `scene` asks for, into its file or (`stream`) standard output.
fn generate(
    scene: &Scene,
    stream: bool,
    tick: &mut dyn FnMut(u64, u64),
) -> Result<GenReport, GenError> {
    let out = || Box::new(std::io::stdout()) as Box<dyn std::io::Write>;
    match scene {
        Scene::Mandelbulb(c) => {
            let opts = MandelbulbOptions {
                triangles: c.tris,
                seed: c.seed,
                ..MandelbulbOptions::default()
            };
            match stream {
                true => mandelbulb::write_obj_stream(out(), STDOUT, &opts, tick),
                false => mandelbulb::write_obj(&c.output, &opts, tick),
            }
        }
        Scene::Cad(a) => {
            let opts = CadOptions {
                triangles: a.common.tris,
                seed: a.common.seed,
                parts: a.parts,
                ..CadOptions::default()
            };
            match stream {
                true => cad::write_obj_stream(out(), STDOUT, &opts, tick),
                false => cad::write_obj(&a.common.output, &opts, tick),
            }
        }
    }
}
