//! Lays a kd-tree out as an `.oocf` container (spec §6–§9): treelets packed into blocks level
//! by level, triangle blocks, proxy blocks and the metadata.
//!
//! Everything is planned before anything is encoded, because references point forward (a LOD
//! node names its children's block, a leaf its triangle block). Block order in the file:
//! treelet blocks by level, then triangle blocks, then proxy blocks.

pub(crate) mod parts;
#[cfg(test)]
mod parts_tests;
pub(crate) mod plan;
#[cfg(test)]
pub(crate) mod tests;
pub(crate) mod treelets;
pub(crate) mod triangles;

use std::path::Path;

use oocfmt::metadata::{Build, Counts, Provenance, Scene, Schema, TreeletRef};
use oocfmt::records::{LodKinds, Voxel, PROXY_LEN};
use oocfmt::{BlockKind, EncodedBlock, Metadata, WriteOptions, WriteSummary, Writer};
use rayon::prelude::*;

use crate::kdtree::{KdError, KdTree};
use crate::lod::{DEFAULT_VOXEL_THRESHOLD, LOD_SAMPLING, LOD_SAMPLING_PROXIES, RLOD_FIT};
use oocfmt_meshio::mesh::{Mesh, MeshError};
use plan::{Role, TreePlan};
use triangles::{LeafRef, TriangleCounts, VertexTable};

/// Blocks compressed at once before they are appended: bounds the memory held by compressed
/// blocks waiting for their turn.
pub(crate) const ENCODE_BATCH: usize = 256;

/// How a tree is laid out into blocks, and what the metadata records about the build.
#[derive(Clone, Debug, PartialEq)]
pub struct LayoutOptions {
    /// Block size, codec, LOD kinds and the other writer settings.
    pub write: WriteOptions,
    /// Node levels per treelet (≥ 1); every `treelet_height`-th level holds the LOD nodes.
    pub treelet_height: u8,
    /// See [`crate::lod::DEFAULT_VOXEL_THRESHOLD`].
    pub voxel_threshold: f32,
    /// At most one proxy per this many triangles (at least [`MIN_PROXIES`]), given to the
    /// coarsest LOD nodes first; 0 gives every LOD node a proxy. Proxies are resident (read at
    /// open), so this bounds what a reader must hold: 64 triangles per 80-byte proxy is
    /// 1.25 bytes per triangle. Wald et al. kept about one proxy per 300 triangles.
    pub triangles_per_proxy: u32,
    /// The program that wrote the file (metadata `provenance.generator`).
    pub generator: String,
    /// The input files the scene came from (metadata `provenance.sources`).
    pub sources: Vec<String>,
    /// Extra `(key, value)` build parameters, appended after the ones the builder records.
    pub params: Vec<(String, String)>,
    /// The scene origin the mesh positions are relative to (metadata `scene.origin`).
    pub origin: [f64; 3],
}

impl Default for LayoutOptions {
    fn default() -> Self {
        LayoutOptions {
            write: WriteOptions::default(),
            treelet_height: 3,
            voxel_threshold: DEFAULT_VOXEL_THRESHOLD,
            triangles_per_proxy: DEFAULT_TRIANGLES_PER_PROXY,
            generator: concat!("oocfmt-build ", env!("CARGO_PKG_VERSION")).to_string(),
            sources: Vec::new(),
            params: Vec::new(),
            origin: [0.0; 3],
        }
    }
}

/// See [`LayoutOptions::triangles_per_proxy`].
pub const DEFAULT_TRIANGLES_PER_PROXY: u32 = 64;
/// Small scenes keep proxies for up to this many LOD nodes whatever the ratio.
pub const MIN_PROXIES: usize = 64;

impl LayoutOptions {
    /// How many LOD nodes get a proxy in a scene of `triangles` triangles.
    pub fn max_proxies(&self, triangles: usize) -> usize {
        match self.triangles_per_proxy {
            0 => usize::MAX,
            n => triangles.div_ceil(n as usize).max(MIN_PROXIES),
        }
    }
}

/// Why a tree could not be laid out or written.
#[derive(Debug, thiserror::Error)]
pub enum LayoutError {
    /// The writer refused an option or failed to write.
    #[error(transparent)]
    Format(#[from] oocfmt::Error),
    /// The mesh is invalid.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// The tree is not a proper tree over the mesh.
    #[error(transparent)]
    Tree(#[from] KdError),
    /// [`LayoutOptions::treelet_height`] is 0; holds the value given.
    #[error("treelet height {0}: expected at least 1")]
    TreeletHeight(u8),
    /// [`LayoutOptions::voxel_threshold`] is negative or not finite; holds the value given.
    #[error("voxel threshold {0}: expected a finite number ≥ 0")]
    VoxelThreshold(f32),
    /// The treelets under one LOD node, which must share a block, do not fit in one.
    #[error("the child treelets of a LOD node need {bytes} bytes, more than a {block_size}-byte block: lower the treelet height or raise the block size")]
    TreeletsTooLarge {
        /// Bytes the treelets need together.
        bytes: usize,
        /// The block size in bytes.
        block_size: usize,
    },
    /// A treelet's nodes span more bytes than a child offset can reach.
    #[error("a treelet spans {bytes} node bytes, beyond the 32 KiB reach of child offsets: lower the treelet height")]
    TreeletSpan {
        /// Node bytes spanned.
        bytes: usize,
    },
    /// One leaf's triangles and vertices do not fit in one triangle block.
    #[error("a leaf of {triangles} triangles needs {bytes} bytes, more than a {block_size}-byte triangle block: lower max_leaf_triangles or raise the block size")]
    LeafTooLarge {
        /// Triangles in the leaf.
        triangles: usize,
        /// Bytes of a triangle block holding this leaf alone.
        bytes: usize,
        /// The block size in bytes.
        block_size: usize,
    },
    /// A LOD node's cell has a half-diagonal too large for an f32 radius.
    #[error("the scene is too large for f32 LOD radii")]
    SceneTooLarge,
    /// More of something (named: blocks, treelets, triangles in a leaf, …) than the format's
    /// count or index fields hold.
    #[error("too many {0} for the format's fields")]
    TooMany(&'static str),
    /// A broken invariant between the layout's planning and encoding stages: a bug, not bad
    /// input; names what was missing.
    #[error("internal layout error: {0}")]
    Internal(&'static str),
}

/// One block before compression.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RawBlock {
    /// What the block holds.
    pub kind: BlockKind,
    /// LOD level of a treelet block; zero for other kinds.
    pub level: u16,
    /// Treelets, triangles or proxies in the block.
    pub item_count: u32,
    /// The block's bytes, uncompressed.
    pub raw: Vec<u8>,
}

/// Every block of a container, in file order, and its metadata.
#[derive(Clone, Debug, PartialEq)]
pub struct Container {
    /// Treelet blocks by level, then triangle blocks, then proxy blocks; a block's position is
    /// its id.
    pub blocks: Vec<RawBlock>,
    /// The metadata written after the blocks.
    pub metadata: Metadata,
}

/// Lays out `tree` over `mesh` and writes the container to `path` (atomically: nothing appears
/// there unless the write completes). The output depends only on the inputs, never on the
/// thread count.
pub fn write_container(
    path: &Path,
    mesh: &Mesh,
    tree: &KdTree,
    opts: &LayoutOptions,
) -> Result<(WriteSummary, Metadata), LayoutError> {
    let container = build_blocks(mesh, tree, opts)?;
    let summary = write_blocks(path, &container, opts.write, &mut |_| {})?;
    Ok((summary, container.metadata))
}

/// Compresses the blocks of `container` (in parallel, in batches) and writes them in order with
/// its metadata; `progress` gets the number of blocks written so far.
pub fn write_blocks(
    path: &Path,
    container: &Container,
    write: WriteOptions,
    progress: &mut dyn FnMut(u64),
) -> Result<WriteSummary, LayoutError> {
    let mut writer = Writer::create(path, write)?;
    let mut appender = Appender::new(&mut writer, write.codec);
    let mut done = 0u64;
    for batch in container.blocks.chunks(ENCODE_BATCH) {
        appender.push(batch)?;
        done += batch.len() as u64;
        progress(done);
    }
    appender.finish()?;
    Ok(writer.finish(&container.metadata)?)
}

/// Compresses batches of at most [`ENCODE_BATCH`] blocks in parallel and appends them in
/// order. A batch is written while the next one is compressed, so the cores are not left
/// waiting on the writer; at most two batches of compressed blocks wait in memory.
pub(crate) struct Appender<'w> {
    writer: &'w mut Writer,
    codec: oocfmt::Codec,
    pending: Vec<EncodedBlock>,
}

impl<'w> Appender<'w> {
    pub(crate) fn new(writer: &'w mut Writer, codec: oocfmt::Codec) -> Appender<'w> {
        Appender {
            writer,
            codec,
            pending: Vec::new(),
        }
    }

    pub(crate) fn push(&mut self, blocks: &[RawBlock]) -> Result<(), oocfmt::Error> {
        let codec = self.codec;
        let pending = std::mem::take(&mut self.pending);
        let writer = &mut *self.writer;
        let (encoded, written) = rayon::join(
            || {
                blocks
                    .par_iter()
                    .map(|b| EncodedBlock::encode(codec, b.kind, b.level, b.item_count, &b.raw))
                    .collect::<Result<Vec<_>, _>>()
            },
            || write_all(writer, pending),
        );
        // The earlier batch's failure first.
        written?;
        self.pending = encoded?;
        Ok(())
    }

    /// Writes the last batch.
    pub(crate) fn finish(self) -> Result<(), oocfmt::Error> {
        write_all(self.writer, self.pending)
    }
}

fn write_all(writer: &mut Writer, blocks: Vec<EncodedBlock>) -> Result<(), oocfmt::Error> {
    for b in blocks {
        writer.write_encoded(b)?;
    }
    Ok(())
}

/// Plans and encodes every block (uncompressed) and fills the metadata.
pub fn build_blocks(
    mesh: &Mesh,
    tree: &KdTree,
    opts: &LayoutOptions,
) -> Result<Container, LayoutError> {
    if opts.treelet_height == 0 {
        return Err(LayoutError::TreeletHeight(opts.treelet_height));
    }
    if !(opts.voxel_threshold.is_finite() && opts.voxel_threshold >= 0.0) {
        return Err(LayoutError::VoxelThreshold(opts.voxel_threshold));
    }
    // Checked here too, so a bad block size fails before the expensive planning.
    let block_size = 1usize << opts.write.block_size_log2.min(20);
    WriteOptions::default().with_block_size(1u64 << opts.write.block_size_log2.min(63))?;
    tree.validate(mesh)?;
    let schema = Schema {
        vertex_normals: mesh.has_normals(),
        vertex_colours: mesh.has_colours(),
        triangle_materials: mesh.has_materials(),
        six_sample_voxels: false,
    };
    // Ids per triangle and a part word per LOD entry only with two or more parts: a scene of
    // one part (or none) writes what it wrote before parts existed.
    let attrs = parts::triangle_attributes(schema.triangle_attributes(), mesh.parts.len());
    let kinds = opts.write.lod.with_parts(mesh.parts.len() >= 2);

    // The triangle blocks do not depend on the LOD data: their serial planning runs beside
    // the treelet plan's serial passes, and the sampling keeps every core busy after both.
    let (tree_plan, triangle_side) = rayon::join(
        || {
            plan::plan_tree(
                mesh,
                tree,
                opts.treelet_height,
                opts.voxel_threshold,
                kinds,
                block_size,
                opts.max_proxies(mesh.triangles.len()),
            )
        },
        || triangle_blocks(mesh, tree, attrs, block_size),
    );
    let tree_plan = tree_plan?;
    let (leaves, triangle_raw): TriangleBlocks = triangle_side?;
    let treelet_blocks =
        u32::try_from(tree_plan.blocks.len()).map_err(|_| LayoutError::TooMany("blocks"))?;
    let treelet_raw: Vec<RawBlock> = tree_plan
        .blocks
        .par_iter()
        .map(|b| {
            let raw = treelets::encode_treelets(b, tree, &tree_plan, &leaves, treelet_blocks)?;
            let item_count =
                u32::try_from(b.treelets.len()).map_err(|_| LayoutError::TooMany("treelets"))?;
            Ok(RawBlock {
                kind: BlockKind::Treelet,
                level: b.level,
                item_count,
                raw,
            })
        })
        .collect::<Result<_, LayoutError>>()?;
    let proxy_raw = proxy_blocks(&tree_plan, block_size)?;

    let metadata = metadata(mesh, tree, opts, &tree_plan, &triangle_raw, schema)?;
    let mut blocks = treelet_raw;
    blocks.extend(triangle_raw.into_iter().map(|(b, _)| b));
    blocks.extend(proxy_raw);
    u32::try_from(blocks.len()).map_err(|_| LayoutError::TooMany("blocks"))?;
    Ok(Container { blocks, metadata })
}

/// Where every leaf's list entries went (by node id), and the triangle blocks, encoded, with
/// what each holds.
type TriangleBlocks = (Vec<Option<LeafRef>>, Vec<(RawBlock, TriangleCounts)>);

/// Plans and encodes the triangle blocks.
fn triangle_blocks(
    mesh: &Mesh,
    tree: &KdTree,
    attrs: u16,
    block_size: usize,
) -> Result<TriangleBlocks, LayoutError> {
    let vertices = VertexTable::new(mesh);
    let plan = triangles::plan_triangles(mesh, tree, &vertices, attrs, block_size)?;
    let blocks = plan
        .blocks
        .par_iter()
        .map(|b| {
            let (raw, counts) = triangles::encode_triangles(b, mesh, &vertices, attrs)?;
            let item_count =
                u32::try_from(counts.triangles).map_err(|_| LayoutError::TooMany("triangles"))?;
            Ok((
                RawBlock {
                    kind: BlockKind::Triangle,
                    level: 0,
                    item_count,
                    raw,
                },
                counts,
            ))
        })
        .collect::<Result<_, LayoutError>>()?;
    Ok((plan.leaves, blocks))
}

/// Proxy records in proxy-id order (the order LOD nodes appear in the file), as many per block
/// as fit.
fn proxy_blocks(plan: &TreePlan, block_size: usize) -> Result<Vec<RawBlock>, LayoutError> {
    let per_block = (block_size / PROXY_LEN).max(1);
    plan.lod_order
        .chunks(per_block)
        .map(|chunk| {
            let mut raw = Vec::with_capacity(chunk.len() * PROXY_LEN);
            for &n in chunk {
                let data = plan
                    .lod_data(n)
                    .ok_or(LayoutError::Internal("a LOD node has no LOD data"))?;
                data.proxy(plan.info(n).block).encode_into(&mut raw);
            }
            let item_count =
                u32::try_from(chunk.len()).map_err(|_| LayoutError::TooMany("proxies"))?;
            Ok(RawBlock {
                kind: BlockKind::Proxy,
                level: 0,
                item_count,
                raw,
            })
        })
        .collect()
}

fn metadata(
    mesh: &Mesh,
    tree: &KdTree,
    opts: &LayoutOptions,
    plan: &TreePlan,
    triangle_blocks: &[(RawBlock, TriangleCounts)],
    mut schema: Schema,
) -> Result<Metadata, LayoutError> {
    let mut counts = Counts {
        treelets: plan.treelets.len() as u64,
        proxies: plan.lod_order.len() as u64,
        depth: plan.depth,
        lod_levels: plan.lod_levels,
        ..Counts::default()
    };
    for &n in plan.treelets.iter().flat_map(|t| &t.nodes) {
        match plan.info(n).role {
            Role::Basic => counts.basic_nodes += 1,
            Role::Lod => counts.lod_nodes += 1,
            Role::Leaf => counts.leaves += 1,
        }
    }
    for d in plan.lod.iter().filter(|_| plan.kinds.voxel) {
        match d.voxel {
            Some(Voxel::Single(..)) => counts.voxels_single += 1,
            Some(Voxel::Six(..)) => counts.voxels_six += 1,
            None => {}
        }
    }
    for (_, c) in triangle_blocks {
        counts.triangles += c.primaries;
        counts.triangle_records += c.triangles;
        counts.vertices += c.vertices;
    }
    schema.six_sample_voxels = counts.voxels_six > 0;
    let bounds = tree.bounds();
    let scene = if tree.root().is_some() {
        Scene {
            bounds_min: bounds.min,
            bounds_max: bounds.max,
            origin: opts.origin,
        }
    } else {
        Scene::default()
    };
    let mut params: Vec<(String, String)> = tree.params().to_vec();
    params.extend(lod_params(plan.kinds, opts.voxel_threshold));
    let mut totals = parts::PartTotals::new(mesh.parts.len());
    if !mesh.parts.is_empty() {
        totals.add(&parts::tally(mesh, |_| true));
    }
    params.push((
        "triangles_per_proxy".into(),
        opts.triangles_per_proxy.to_string(),
    ));
    params.extend(opts.params.iter().cloned());
    Ok(Metadata {
        scene,
        root: tree.root().map(|_| TreeletRef {
            block: 0,
            treelet: 0,
        }),
        counts,
        schema,
        materials: mesh.material_table.clone(),
        build: Build {
            treelet_height: opts.treelet_height,
            max_leaf_triangles: tree.max_leaf_triangles(),
            params,
        },
        provenance: Provenance {
            generator: opts.generator.clone(),
            sources: opts.sources.clone(),
        },
        parts: totals.table(&mesh.parts),
    })
}

/// The build parameters that say how the LOD data was made (part words aside: the header
/// says whether entries have them).
pub(crate) fn lod_params(kinds: LodKinds, voxel_threshold: f32) -> Vec<(String, String)> {
    let kinds = kinds.with_parts(false);
    let sampling = match kinds.voxel {
        true => LOD_SAMPLING,
        false => LOD_SAMPLING_PROXIES,
    };
    let mut params = vec![
        ("lod_sampling".into(), sampling.into()),
        ("voxel_threshold".into(), voxel_threshold.to_string()),
    ];
    // Recorded only off the default, so voxel-only files stay as they were.
    if kinds != LodKinds::VOXEL {
        params.push(("lod_kinds".into(), kinds.name().into()));
        params.push(("rlod_fit".into(), RLOD_FIT.into()));
    }
    params
}
