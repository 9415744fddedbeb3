//! `oocfmt inspect`: a summary for people, or JSON for programs; one block decoded with
//! `--block`; the part tree with `--parts` (built by [`oocfmt_trace::parts::part_tree`]).

use std::fmt::Write;
use std::path::PathBuf;

use serde::Serialize;

use oocfmt::metadata::Metadata;
use oocfmt::summary::{summarize, Summary};
use oocfmt::{ReadOptions, Reader};
use oocfmt_trace::parts::{part_tree, preorder, PartNode};

use crate::error::{to_json, CliError, CliResult};
use crate::out::{out, outln};
use crate::{hexdump, inspect_block};

#[derive(clap::Args)]
pub struct Args {
    /// The container to inspect
    pub file: PathBuf,
    /// Print JSON instead of tables
    #[arg(long)]
    pub json: bool,
    /// Decode and print one block
    #[arg(long, value_name = "ID")]
    pub block: Option<u32>,
    /// Print an annotated hex dump of the whole file (small files only)
    #[arg(long, conflicts_with = "block")]
    pub hexdump: bool,
    /// Print the part tree: each part indented under its parent, with its own and its
    /// subtree's triangle counts and bounds (with --json: schema `oocfmt-parts/1`)
    #[arg(long, conflicts_with_all = ["block", "hexdump"])]
    pub parts: bool,
}

pub fn run(a: &Args) -> CliResult {
    if a.hexdump {
        out!("{}", hexdump::annotate(&a.file)?)?;
        return Ok(0);
    }
    let reader = Reader::open(&a.file, ReadOptions::default())?;
    if a.parts {
        let m = reader.metadata();
        if a.json {
            let record = PartsRecord {
                schema: "oocfmt-parts/1",
                file: a.file.display().to_string(),
                origin: m.scene.origin,
                parts: part_tree(&m.parts),
            };
            outln!("{}", to_json(&record)?)?;
        } else {
            out!("{}", render_parts(m))?;
        }
        return Ok(0);
    }
    if let Some(id) = a.block {
        let dump = inspect_block::dump(&reader, id)?;
        if a.json {
            outln!("{}", to_json(&dump)?)?;
        } else {
            out!("{}", inspect_block::render(&dump))?;
        }
        return Ok(0);
    }
    let s = summarize(&reader)?;
    if a.json {
        outln!("{}", to_json(&s)?)?;
    } else {
        out!("{}", render(&s))?;
    }
    Ok(0)
}

fn mib(b: u64) -> String {
    if b >= 1 << 20 {
        format!("{:.1} MiB", b as f64 / f64::from(1 << 20))
    } else if b >= 1 << 10 {
        format!("{:.1} KiB", b as f64 / 1024.0)
    } else {
        format!("{b} B")
    }
}

/// The human-readable summary.
pub fn render(s: &Summary) -> String {
    let mut o = String::new();
    header(&mut o, s);
    levels(&mut o, s);
    storage_and_tree(&mut o, s);
    metadata(&mut o, s);
    o
}

/// The file, its format and features, LOD kinds and identity.
fn header(o: &mut String, s: &Summary) {
    let feats = if s.feature_names.is_empty() {
        "none".to_string()
    } else {
        s.feature_names.join(", ")
    };
    let _ = writeln!(
        o,
        "file       {} ({}, {} blocks of {})",
        s.file,
        mib(s.file_length),
        s.block_count,
        mib(u64::from(s.block_size))
    );
    let _ = writeln!(
        o,
        "format     {} features {feats} (compatible {:#x}, incompatible {:#x})",
        s.version, s.compatible_features, s.incompatible_features
    );
    let rlods: u64 = s.levels.iter().map(|r| r.rlods).sum();
    let voxels: u64 = s
        .levels
        .iter()
        .map(|r| r.voxels_single + r.voxels_six)
        .sum();
    let _ = writeln!(
        o,
        "LOD kinds  {} ({voxels} voxels, {rlods} R-LODs)",
        s.lod_kinds
    );
    let _ = writeln!(o, "identity   {}", s.identity);
    let _ = writeln!(o);
}

/// The table of LOD levels.
fn levels(o: &mut String, s: &Summary) {
    let _ = writeln!(
        o,
        "{:>9} {:>7} {:>8} {:>8} {:>7} {:>8} {:>7} {:>7} {:>10} {:>7} {:>10} {:>10} {:>6}  codecs",
        "level",
        "blocks",
        "treelets",
        "basic",
        "lod",
        "leaves",
        "vox1",
        "vox6",
        "triangles",
        "proxies",
        "raw",
        "stored",
        "ratio"
    );
    for r in &s.levels {
        let codecs: Vec<String> = r.codecs.iter().map(|(k, v)| format!("{k}:{v}")).collect();
        let _ = writeln!(
            o,
            "{:>9} {:>7} {:>8} {:>8} {:>7} {:>8} {:>7} {:>7} {:>10} {:>7} {:>10} {:>10} {:>6.2}  {}",
            r.level,
            r.blocks,
            r.treelets,
            r.basic_nodes,
            r.lod_nodes,
            r.leaves,
            r.voxels_single,
            r.voxels_six,
            r.triangles,
            r.proxies,
            mib(r.raw_bytes),
            mib(r.stored_bytes),
            r.ratio,
            codecs.join(" ")
        );
    }
    let _ = writeln!(o);
}

/// What is resident at open and what is streamed; the tree's figures.
fn storage_and_tree(o: &mut String, s: &Summary) {
    let res = &s.residency;
    let _ = writeln!(
        o,
        "resident   {} at open (header, directory, metadata, trailer, proxies; {} of proxies in memory)",
        mib(res.resident_stored_bytes),
        mib(res.proxy_raw_bytes)
    );
    let _ = writeln!(
        o,
        "streamed   {} on demand (treelet and triangle blocks)",
        mib(res.streamed_bytes)
    );
    let t = &s.tree;
    let _ = writeln!(
        o,
        "tree       depth {}, {} LOD levels, {} treelets, {} basic + {} LOD nodes, {} leaves, {:.2} triangles per leaf",
        t.depth, t.lod_levels, t.treelets, t.basic_nodes, t.lod_nodes, t.leaves, t.avg_triangles_per_leaf
    );
    let _ = writeln!(
        o,
        "triangles  {} ({:.1} bytes per triangle in the file)",
        t.triangles, t.bytes_per_triangle
    );
}

/// Bounds, schema, materials, build parameters and provenance.
fn metadata(o: &mut String, s: &Summary) {
    let m = &s.metadata;
    let _ = writeln!(
        o,
        "bounds     {:?} .. {:?}, origin {:?}",
        m.scene.bounds_min, m.scene.bounds_max, m.scene.origin
    );
    let sc = &m.schema;
    let _ = writeln!(
        o,
        "schema     vertex normals {}, vertex colours {}, triangle materials {}, 6-sample voxels {}",
        sc.vertex_normals, sc.vertex_colours, sc.triangle_materials, sc.six_sample_voxels
    );
    let _ = writeln!(o, "materials  {}", m.materials.len());
    for mat in m.materials.iter().take(16) {
        let _ = writeln!(o, "           {:<24} diffuse {:?}", mat.name, mat.diffuse);
    }
    let params: Vec<String> = m
        .build
        .params
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect();
    let _ = writeln!(
        o,
        "build      treelet height {}, max {} triangles per leaf{}{}",
        m.build.treelet_height,
        m.build.max_leaf_triangles,
        if params.is_empty() { "" } else { ", " },
        params.join(", ")
    );
    let _ = writeln!(
        o,
        "provenance {} from {}",
        m.provenance.generator,
        if m.provenance.sources.is_empty() {
            "-".to_string()
        } else {
            m.provenance.sources.join(", ")
        }
    );
}

/// `inspect --parts --json`: the part table as a tree (docs/cli.md, "The parts JSON").
#[derive(Serialize)]
struct PartsRecord {
    schema: &'static str,
    file: String,
    /// The scene origin: world = origin + the stored coordinates the bounds are in.
    origin: [f64; 3],
    /// In id order, parents first; empty for a file without parts.
    parts: Vec<PartNode>,
}

/// The part tree for people: a line per part, depth first, names indented by depth, with
/// own and subtree triangles and the subtree's bounds in world coordinates.
pub fn render_parts(m: &Metadata) -> String {
    let mut o = String::new();
    if m.parts.is_empty() {
        let _ = writeln!(
            o,
            "no parts: the input named none, so all {} triangles are one anonymous part",
            m.counts.triangles
        );
        return o;
    }
    let nodes = part_tree(&m.parts);
    let top = nodes.iter().filter(|n| n.parent.is_none()).count();
    let deepest = nodes.iter().map(|n| n.depth).max().unwrap_or(0);
    let _ = writeln!(
        o,
        "parts      {} ({top} top level, {} deep), {} triangles",
        nodes.len(),
        if deepest == 0 {
            "1 level".to_string()
        } else {
            format!("{} levels", deepest + 1)
        },
        m.counts.triangles
    );
    let _ = writeln!(
        o,
        "{:>8} {:>12} {:>12}  {:<32} bounds of the subtree (world)",
        "id", "triangles", "subtree", "name"
    );
    let world = |c: [f32; 3]| {
        let w = [0, 1, 2].map(|k| m.scene.origin[k] + f64::from(c[k]));
        format!("[{:.4}, {:.4}, {:.4}]", w[0], w[1], w[2])
    };
    for id in preorder(&m.parts) {
        let Some(n) = nodes.get(id as usize) else {
            continue;
        };
        let name = format!("{}{}", "  ".repeat(n.depth as usize), n.name);
        let bounds = if n.subtree_triangles == 0 {
            "-".to_string()
        } else {
            format!(
                "{} .. {}",
                world(n.subtree_bounds_min),
                world(n.subtree_bounds_max)
            )
        };
        let _ = writeln!(
            o,
            "{:>8} {:>12} {:>12}  {:<32} {bounds}",
            n.id, n.triangles, n.subtree_triangles, name
        );
    }
    o
}

pub fn invalid_block(id: u32, count: usize) -> CliError {
    CliError::Usage(format!("--block {id}: the file has {count} blocks"))
}
