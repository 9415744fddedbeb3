//! Per-block facts (one pass over a decoded block) and the file summary `inspect` prints.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::directory::{BlockEntry, BlockKind};
use crate::error::{bad, Code, Result};
use crate::header::{
    COMPAT_LOD_VOXELS, COMPAT_PROXIES, INCOMPAT_LOD_FILTERED, INCOMPAT_LOD_NO_VOXELS,
    INCOMPAT_LOD_RLODS, INCOMPAT_PART_IDS,
};
use crate::metadata::Metadata;
use crate::records::triangle::ATTR_MATERIALS;
use crate::records::{LodKinds, Node, ProxyRecord, TreeletBlock, TreeletSummary, TriangleBlock};
use crate::Reader;

/// What one block holds, found by decoding it and checking its framing.
#[derive(Clone, Debug, PartialEq)]
pub enum BlockFacts {
    /// A treelet block.
    Treelet {
        /// What the walk over its treelets counted.
        nodes: TreeletSummary,
        /// Σ triangle count over its leaves: references, so a triangle in two leaves counts
        /// twice.
        leaf_triangle_refs: u64,
    },
    /// A triangle block.
    Triangle {
        /// Entries in the list section.
        list: u32,
        /// Triangle records, copies included.
        triangles: u32,
        /// Vertex records.
        vertices: u32,
        /// Primary triangles (the first `primaries` records).
        primaries: u32,
        /// Largest material index of its triangles; `None` without triangle materials.
        max_material: Option<u16>,
        /// Its primaries per part, by part id (ids below the table's length only); empty
        /// when the file has no part table or the metadata is not known.
        parts: Vec<PartFacts>,
    },
    /// A proxy block.
    Proxy {
        /// Each record's `node_block`, in record order.
        node_blocks: Vec<u32>,
    },
}

/// One part's primaries in one triangle block: what deep verify sums into the part table's
/// counts and bounds (spec §9).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PartFacts {
    /// The part id.
    pub part: u32,
    /// Primaries with that id.
    pub triangles: u64,
    /// Low corner of their corners, in stored coordinates.
    pub bounds_min: [f32; 3],
    /// High corner of their corners, in stored coordinates.
    pub bounds_max: [f32; 3],
}

impl PartFacts {
    /// Takes `other`'s triangles (of the same part) into these.
    pub fn merge(&mut self, other: &PartFacts) {
        self.triangles += other.triangles;
        for a in 0..3 {
            self.bounds_min[a] = self.bounds_min[a].min(other.bounds_min[a]);
            self.bounds_max[a] = self.bounds_max[a].max(other.bounds_max[a]);
        }
    }
}

/// What a block's checks need from the metadata, when it is known: the attribute word of every
/// triangle block and the number of parts that part ids must stay below.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockSchema {
    /// [`Metadata::triangle_attributes`]: what every triangle block's attributes must equal.
    pub triangle_attributes: u16,
    /// The part table's length (`PART_ID`: every id below it).
    pub parts: usize,
}

impl BlockSchema {
    /// The schema `m` gives every block of its file.
    pub fn of(m: &Metadata) -> BlockSchema {
        BlockSchema {
            triangle_attributes: m.triangle_attributes(),
            parts: m.parts.len(),
        }
    }
}

/// Decodes the framing of `raw` (block `id` with directory entry `e`) and checks every record
/// it can check alone. `schema` is what the metadata says, when known; `lod` the file's LOD
/// kinds (the layout of a treelet block's LOD area).
pub fn survey_block(
    e: &BlockEntry,
    raw: &[u8],
    schema: Option<BlockSchema>,
    lod: LodKinds,
) -> Result<BlockFacts> {
    let facts = match e.kind {
        BlockKind::Treelet => {
            let block = TreeletBlock::parse_with(raw, lod)?;
            let mut refs = 0u64;
            let parts = schema.map(|s| s.parts);
            let nodes = block.walk_lods(|_, pos, n, entry| {
                if let Node::Leaf { count, .. } = n {
                    refs += u64::from(*count);
                }
                lod_part(pos, entry.part, parts)
            })?;
            BlockFacts::Treelet {
                nodes,
                leaf_triangle_refs: refs,
            }
        }
        BlockKind::Triangle => {
            let b = TriangleBlock::parse(raw, schema.map(|s| s.triangle_attributes))?;
            b.check_contents()?;
            let mut max_material = None;
            if b.attributes() & ATTR_MATERIALS != 0 {
                for i in 0..b.triangle_count() {
                    max_material = max_material.max(b.triangle(i)?.material);
                }
            }
            let parts = match schema.filter(|s| s.parts > 0) {
                Some(s) => {
                    b.check_parts(s.parts)?;
                    part_facts(&b)?
                }
                None => Vec::new(),
            };
            BlockFacts::Triangle {
                list: b.list_count() as u32,
                triangles: b.triangle_count() as u32,
                vertices: b.vertex_count() as u32,
                primaries: b.primary_count() as u32,
                max_material,
                parts,
            }
        }
        BlockKind::Proxy => {
            let records = ProxyRecord::decode_block(raw, e.item_count as usize)?;
            BlockFacts::Proxy {
                node_blocks: records.iter().map(|p| p.node_block).collect(),
            }
        }
    };
    let items = facts.items();
    if items != u64::from(e.item_count) {
        return bad(
            Code::EntryItemCount,
            format!(
                "directory says {} items, the block holds {items}",
                e.item_count
            ),
        );
    }
    Ok(facts)
}

/// Checks a LOD entry's part word, at node `pos`, against the part table's length `parts`
/// when known (`PART_ID`, spec §6.2).
fn lod_part(pos: usize, part: Option<u32>, parts: Option<usize>) -> Result<()> {
    match (part, parts) {
        (Some(p), Some(n)) if p as usize >= n => Err(crate::error::Error::malformed(
            Code::PartId,
            format!("LOD node at {pos}: its entry names part {p} of {n}"),
        )
        .at(pos as u64)),
        _ => Ok(()),
    }
}

/// The primaries of block `b` per part, sorted by id: a block without ids has all of them in
/// part 0 (the one part of its table). Their corners are checked finite already.
fn part_facts(b: &TriangleBlock<'_>) -> Result<Vec<PartFacts>> {
    let mut by_part: BTreeMap<u32, PartFacts> = BTreeMap::new();
    for i in 0..b.primary_count() {
        let part = b.part(i)?.unwrap_or(0);
        let corners = b.positions(i)?;
        let f = by_part.entry(part).or_insert(PartFacts {
            part,
            triangles: 0,
            bounds_min: corners[0],
            bounds_max: corners[0],
        });
        f.merge(&PartFacts {
            part,
            triangles: 1,
            bounds_min: [0, 1, 2]
                .map(|a| corners.iter().map(|c| c[a]).fold(f32::INFINITY, f32::min)),
            bounds_max: [0, 1, 2].map(|a| {
                corners
                    .iter()
                    .map(|c| c[a])
                    .fold(f32::NEG_INFINITY, f32::max)
            }),
        });
    }
    Ok(by_part.into_values().collect())
}

impl BlockFacts {
    /// The count the directory's item_count must equal.
    pub fn items(&self) -> u64 {
        match self {
            BlockFacts::Treelet { nodes, .. } => nodes.treelets,
            BlockFacts::Triangle { triangles, .. } => u64::from(*triangles),
            BlockFacts::Proxy { node_blocks } => node_blocks.len() as u64,
        }
    }
}

/// One row of the per-level table.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct LevelRow {
    /// `0`, `1`, … for treelet levels, then `triangles` and `proxies`.
    pub level: String,
    /// Blocks in the row.
    pub blocks: u64,
    /// Treelets in the row's treelet blocks.
    pub treelets: u64,
    /// Basic nodes in the row's treelet blocks.
    pub basic_nodes: u64,
    /// LOD nodes in the row's treelet blocks.
    pub lod_nodes: u64,
    /// Leaves in the row's treelet blocks.
    pub leaves: u64,
    /// 1-sample voxels in the row's treelet blocks.
    pub voxels_single: u64,
    /// 6-sample voxels in the row's treelet blocks.
    pub voxels_six: u64,
    /// R-LOD records in the row's treelet blocks.
    pub rlods: u64,
    /// Triangle records (copies included) of the `triangles` row, from the directory.
    pub triangles: u64,
    /// Proxy records of the `proxies` row, from the directory.
    pub proxies: u64,
    /// Σ raw (decompressed) length of the row's blocks, in bytes.
    pub raw_bytes: u64,
    /// Σ stored length of the row's blocks, in bytes.
    pub stored_bytes: u64,
    /// Compression ratio `raw_bytes / stored_bytes` (0 for an empty row).
    pub ratio: f64,
    /// Blocks per codec name (`none`, `lz4`, `zstd`).
    pub codecs: BTreeMap<String, u64>,
}

/// How the file's bytes split between what a reader holds from open and what it streams.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Residency {
    /// Header, directory, metadata, trailer and proxy blocks as stored: read at open.
    pub resident_stored_bytes: u64,
    /// The proxies decoded in memory.
    pub proxy_raw_bytes: u64,
    /// Treelet and triangle blocks as stored: read on demand.
    pub streamed_bytes: u64,
}

/// Totals over the kd-tree, from the treelet blocks and the metadata.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct TreeStats {
    /// Node levels on the longest root-to-leaf path (metadata `counts.depth`).
    pub depth: u32,
    /// Number of treelet levels in the directory.
    pub lod_levels: u32,
    /// Treelets in all treelet blocks.
    pub treelets: u64,
    /// Basic nodes in all treelet blocks.
    pub basic_nodes: u64,
    /// LOD nodes in all treelet blocks.
    pub lod_nodes: u64,
    /// Leaves in all treelet blocks.
    pub leaves: u64,
    /// Σ triangle count over all leaves (a triangle in two leaves counts twice).
    pub leaf_triangle_refs: u64,
    /// `leaf_triangle_refs / leaves` (0 without leaves).
    pub avg_triangles_per_leaf: f64,
    /// Input triangles: Σ primary counts (metadata `counts.triangles`).
    pub triangles: u64,
    /// File length divided by `triangles` (0 without triangles).
    pub bytes_per_triangle: f64,
}

/// The file summary `oocfmt inspect` prints, as text or JSON.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Summary {
    /// The reader's name for the file (its path as displayed).
    pub file: String,
    /// File length in bytes.
    pub file_length: u64,
    /// Format version as `major.minor`.
    pub version: String,
    /// Block size in bytes.
    pub block_size: u32,
    /// The header's incompatible feature bits.
    pub incompatible_features: u64,
    /// The header's compatible feature bits.
    pub compatible_features: u64,
    /// Names of the known feature bits set (`PROXIES`, `LOD_VOXELS`, `LOD_RLODS`,
    /// `LOD_NO_VOXELS`, `LOD_FILTERED`, `PART_IDS`).
    pub feature_names: Vec<String>,
    /// What the LOD nodes carry: `voxel`, `rlod` or `voxel+rlod`.
    pub lod_kinds: String,
    /// The root checksum (the file's identity) as 8 lowercase hex digits.
    pub identity: String,
    /// Blocks in the directory.
    pub block_count: u32,
    /// One row per treelet level, coarse to fine, then `triangles` and `proxies` rows where
    /// the file has such blocks.
    pub levels: Vec<LevelRow>,
    /// Bytes held from open against bytes streamed.
    pub residency: Residency,
    /// Totals over the tree.
    pub tree: TreeStats,
    /// The file's metadata, as decoded.
    pub metadata: Metadata,
}

/// Summarises a file: reads and decodes every treelet block (triangle and proxy rows come from
/// the directory), so its cost is that of the tree, not of the triangles.
pub fn summarize(reader: &Reader) -> Result<Summary> {
    let mut rows: BTreeMap<(u8, u16), LevelRow> = BTreeMap::new();
    let mut leaf_refs = 0u64;
    for (id, e) in (0u32..).zip(reader.entries()) {
        let key = match e.kind {
            BlockKind::Treelet => (0, e.level),
            BlockKind::Triangle => (1, 0),
            BlockKind::Proxy => (2, 0),
        };
        let row = rows.entry(key).or_default();
        row.blocks += 1;
        row.raw_bytes += u64::from(e.raw_length);
        row.stored_bytes += u64::from(e.stored_length);
        *row.codecs.entry(e.codec.name().to_string()).or_default() += 1;
        match e.kind {
            BlockKind::Treelet => {
                let block = reader.read_block(id)?;
                let facts = survey_block(e, &block.data, None, reader.lod_kinds())
                    .map_err(|err| err.in_block(id).in_file(reader.name()))?;
                if let BlockFacts::Treelet {
                    nodes,
                    leaf_triangle_refs,
                } = facts
                {
                    row.treelets += nodes.treelets;
                    row.basic_nodes += nodes.basic_nodes;
                    row.lod_nodes += nodes.lod_nodes;
                    row.leaves += nodes.leaves;
                    row.voxels_single += nodes.voxels_single;
                    row.voxels_six += nodes.voxels_six;
                    row.rlods += nodes.rlods;
                    leaf_refs += leaf_triangle_refs;
                }
            }
            BlockKind::Triangle => row.triangles += u64::from(e.item_count),
            BlockKind::Proxy => row.proxies += u64::from(e.item_count),
        }
    }
    let levels: Vec<LevelRow> = rows
        .into_iter()
        .map(|((k, level), mut row)| {
            row.level = match k {
                0 => level.to_string(),
                1 => "triangles".to_string(),
                _ => "proxies".to_string(),
            };
            row.ratio = if row.stored_bytes == 0 {
                0.0
            } else {
                row.raw_bytes as f64 / row.stored_bytes as f64
            };
            row
        })
        .collect();
    Ok(build_summary(reader, levels, leaf_refs))
}

fn build_summary(reader: &Reader, levels: Vec<LevelRow>, leaf_refs: u64) -> Summary {
    let h = reader.header();
    let m = reader.metadata();
    let sum = |f: fn(&LevelRow) -> u64| levels.iter().map(f).sum::<u64>();
    let tree_rows = levels.iter().filter(|r| r.level.parse::<u16>().is_ok());
    let proxy_stored: u64 = levels
        .iter()
        .filter(|r| r.level == "proxies")
        .map(|r| r.stored_bytes)
        .sum();
    let proxy_raw: u64 = levels
        .iter()
        .filter(|r| r.level == "proxies")
        .map(|r| r.raw_bytes)
        .sum();
    let blocks_stored = sum(|r| r.stored_bytes);
    let leaves = sum(|r| r.leaves);
    let triangles = m.counts.triangles;
    let mut feature_names = Vec::new();
    if h.compatible_features & COMPAT_PROXIES != 0 {
        feature_names.push("PROXIES".to_string());
    }
    if h.compatible_features & COMPAT_LOD_VOXELS != 0 {
        feature_names.push("LOD_VOXELS".to_string());
    }
    if h.incompatible_features & INCOMPAT_LOD_RLODS != 0 {
        feature_names.push("LOD_RLODS".to_string());
    }
    if h.incompatible_features & INCOMPAT_LOD_NO_VOXELS != 0 {
        feature_names.push("LOD_NO_VOXELS".to_string());
    }
    if h.incompatible_features & INCOMPAT_LOD_FILTERED != 0 {
        feature_names.push("LOD_FILTERED".to_string());
    }
    if h.incompatible_features & INCOMPAT_PART_IDS != 0 {
        feature_names.push("PART_IDS".to_string());
    }
    Summary {
        file: reader.name().to_string(),
        file_length: reader.file_len(),
        version: format!("{}.{}", h.major, h.minor),
        block_size: h.block_size(),
        incompatible_features: h.incompatible_features,
        compatible_features: h.compatible_features,
        feature_names,
        lod_kinds: reader.lod_kinds().name().to_string(),
        identity: format!("{:08x}", reader.identity()),
        block_count: h.sections.block_count,
        residency: Residency {
            resident_stored_bytes: reader.file_len() - blocks_stored + proxy_stored,
            proxy_raw_bytes: proxy_raw,
            streamed_bytes: blocks_stored - proxy_stored,
        },
        tree: TreeStats {
            depth: m.counts.depth,
            lod_levels: tree_rows.count() as u32,
            treelets: sum(|r| r.treelets),
            basic_nodes: sum(|r| r.basic_nodes),
            lod_nodes: sum(|r| r.lod_nodes),
            leaves,
            leaf_triangle_refs: leaf_refs,
            avg_triangles_per_leaf: if leaves == 0 {
                0.0
            } else {
                leaf_refs as f64 / leaves as f64
            },
            triangles,
            bytes_per_triangle: if triangles == 0 {
                0.0
            } else {
                reader.file_len() as f64 / triangles as f64
            },
        },
        levels,
        metadata: m.clone(),
    }
}
