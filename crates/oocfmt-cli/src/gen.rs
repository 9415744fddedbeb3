//! `oocfmt gen`: streaming scene generators for tests and benchmarks.

use std::path::PathBuf;

use oocfmt_scenes::cad::{self, CadOptions};
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};
use oocfmt_scenes::GenReport;

use crate::error::{to_json, CliResult};
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
    /// Approximate triangle count (Mandelbulb within about 20 %, CAD exact)
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub tris: u64,
    /// The OBJ file to write
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
    let result = match &a.scene {
        Scene::Mandelbulb(c) => mandelbulb::write_obj(
            &c.output,
            &MandelbulbOptions {
                triangles: c.tris,
                seed: c.seed,
                ..MandelbulbOptions::default()
            },
            &mut tick,
        ),
        Scene::Cad(a) => cad::write_obj(
            &a.common.output,
            &CadOptions {
                triangles: a.common.tris,
                seed: a.common.seed,
                parts: a.parts,
                ..CadOptions::default()
            },
            &mut tick,
        ),
    };
    bar.finish_and_clear();
    let report: GenReport = result?;
    if c.json {
        outln!("{}", to_json(&report)?)?;
    } else {
        outln!(
            "wrote {} ({} triangles, {} vertices, {} bytes)",
            c.output.display(),
            report.triangles,
            report.vertices,
            report.bytes
        )?;
    }
    Ok(0)
}
