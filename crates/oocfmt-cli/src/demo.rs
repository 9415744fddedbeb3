//! `oocfmt demo`: the README's first command. Generates the built-in scene, builds a container
//! from it, then inspects and deep-verifies the result, printing where it is and what it cost.

use std::path::PathBuf;
use std::time::Instant;

use oocfmt::verify::{verify, Depth, VerifyOptions};
use oocfmt::{Codec, FileSource, ReadOptions, Reader, WriteOptions};
use oocfmt_build::gen::demo::demo_scene;
use oocfmt_build::kdtree::{self, KdBuildOptions};
use oocfmt_build::layout::{write_container, LayoutOptions};

use crate::error::{CliError, CliResult};
use crate::{inspect, progress};

#[derive(clap::Args)]
pub struct Args {
    /// Folder for the output (created if missing)
    #[arg(long, default_value = "oocfmt-demo")]
    pub out: PathBuf,
    /// Approximate triangle count of the generated scene
    #[arg(long, default_value_t = 200_000, value_parser = clap::value_parser!(u64).range(16..=20_000_000))]
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
}

pub fn parse_codec(s: &str) -> Result<Codec, String> {
    Codec::parse(s).map_err(|e| e.to_string())
}

pub fn run(a: &Args) -> CliResult {
    let write = WriteOptions {
        codec: a.codec,
        ..WriteOptions::default()
    }
    .with_block_size(a.block_size)?;
    std::fs::create_dir_all(&a.out).map_err(|e| CliError::Io {
        path: a.out.display().to_string(),
        source: e,
    })?;
    let path = a.out.join("demo.oocf");

    let spin = progress::spinner("generating the demo scene");
    let t = Instant::now();
    let mesh = demo_scene(a.triangles as usize);
    spin.finish_and_clear();
    println!(
        "scene      {} triangles, {} vertices in {:.2} s",
        mesh.triangles.len(),
        mesh.positions.len(),
        t.elapsed().as_secs_f64()
    );

    let spin = progress::spinner("building the kd-tree");
    let t = Instant::now();
    let tree = kdtree::build(
        &mesh,
        &KdBuildOptions {
            max_leaf_triangles: a.max_leaf,
            ..KdBuildOptions::default()
        },
    )
    .map_err(|e| CliError::Build(e.to_string()))?;
    spin.finish_and_clear();
    println!(
        "kd-tree    {} nodes, depth {} in {:.2} s",
        tree.nodes().len(),
        tree.depth(),
        t.elapsed().as_secs_f64()
    );

    let spin = progress::spinner("laying out and writing the container");
    let t = Instant::now();
    let opts = LayoutOptions {
        write,
        sources: vec!["built-in demo scene".to_string()],
        ..LayoutOptions::default()
    };
    let (written, _) =
        write_container(&path, &mesh, &tree, &opts).map_err(|e| CliError::Build(e.to_string()))?;
    spin.finish_and_clear();
    let secs = t.elapsed().as_secs_f64();
    println!(
        "written    {} ({} bytes, {} blocks) in {secs:.2} s: {:.0} triangles/s",
        path.display(),
        written.file_length,
        written.block_count,
        mesh.triangles.len() as f64 / secs.max(1e-9)
    );

    let reader = Reader::open(&path, ReadOptions::default())?;
    println!();
    print!("{}", inspect::render(&oocfmt::summary::summarize(&reader)?));
    println!();

    let src = FileSource::open(&path).map_err(|e| CliError::Io {
        path: path.display().to_string(),
        source: e,
    })?;
    let bar = progress::bytes(written.file_length, "verify --deep", false);
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
        println!("{issue}");
    }
    println!(
        "verify     --deep: {} ({} errors, {} warnings) in {secs:.3} s, {:.0} MB/s",
        if report.valid { "valid" } else { "INVALID" },
        report.errors,
        report.warnings,
        written.file_length as f64 / secs.max(1e-9) / 1e6
    );
    println!(
        "\nnext: oocfmt inspect {0} --block 0; oocfmt verify --deep {0}",
        path.display()
    );
    Ok(if report.valid { 0 } else { 1 })
}
