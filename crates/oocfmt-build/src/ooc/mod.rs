//! The out-of-core build (Áfra et al. 2012, §4.1; Correa et al. 2002, §3): the imported scene
//! lives in a spill run (`soup`), cells too large for memory are split at their spatial median in
//! streaming passes (`split`), and each chunk that fits is built, sampled and laid out in
//! memory on its own (`chunk`), its deeper blocks spilled. The median-split nodes and the
//! chunks' top treelets form a small tree laid out last (`top`), and `assemble` writes
//! everything in the order the spec requires. Memory holds two chunks at a time (each in half the
//! budget), plus the top.

pub(crate) mod assemble;
pub(crate) mod blocks;
pub(crate) mod chunk;
pub mod disk;
mod record;
pub(crate) mod segments;
pub mod soup;
pub mod space;
pub(crate) mod split;
mod tee;
pub(crate) mod top;

#[cfg(test)]
mod at_once;
#[cfg(test)]
mod full_disk;
#[cfg(test)]
mod tests;

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use rayon::prelude::*;
use rustc_hash::FxHashMap;

use oocfmt::metadata::{Build, Counts, Provenance, Scene, Schema, TreeletRef};
use oocfmt::records::Rlod;
use oocfmt::{BlockKind, Metadata, WriteSummary};

use crate::kdtree::{KdBuildOptions, KdError, NodeId};
use crate::layout::lod_params;
use crate::layout::parts::{self, PartTotals};
use crate::layout::plan::{plan_tree_with, LodSource, PlanSpec, Role, TreePlan};
use crate::layout::treelets::encode_treelets;
use crate::layout::triangles::LeafRef;
use crate::layout::{LayoutError, LayoutOptions, RawBlock};
use crate::lod::rlod::PlaneFit;
use crate::lod::LodData;
use crate::progress::Progress;
use crate::report::PhaseClock;
use chunk::{BlockSpill, ChunkBuilder, ChunkCounts, ChunkOut, SceneFacts};
use disk::SpillDisk;
use oocfmt_meshio::import::{compact_materials, ChunkSchema, InputTriangle};
use oocfmt_meshio::mesh::Bounds;
use soup::Soup;
pub(crate) use split::TopTree;

/// Why the out-of-core build, or the spill files it and the importer use, failed.
#[derive(Debug, thiserror::Error)]
pub enum OocError {
    /// Creating, reading, writing or removing a spill file failed.
    #[error("spill file {path}: {source}")]
    Spill {
        /// The spill file (or the folder it was to be made in).
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Writing a spill file failed, most likely for want of space (see the message).
    #[error(
        "writing spill file {path} failed after {written} bytes of it{}: {source}",
        space_hint(source)
    )]
    SpillWrite {
        /// The spill segment being written.
        path: String,
        /// Bytes of its run that had reached the disk.
        written: u64,
        /// The I/O error (`StorageFull` when the disk is full).
        source: std::io::Error,
    },
    /// A block read back from a subset file failed its checks (a merge).
    #[error("{0}")]
    BlockFile(String),
    /// A spill file's length is not what was written to it.
    #[error("spill file {path}: {len} bytes, expected {expected}")]
    SpillLength {
        /// The spill file.
        path: String,
        /// Its length in bytes.
        len: u64,
        /// Bytes written to it.
        expected: u64,
    },
    /// A spill file does not hold the records written to it.
    #[error("spill file {path}: {what}")]
    SpillCorrupt {
        /// The spill file.
        path: String,
        /// What is wrong.
        what: &'static str,
    },
    /// The free space cannot hold what the conversion is estimated to need: refused before
    /// any work.
    #[error(transparent)]
    NoSpace(#[from] space::NoSpace),
    /// The import kept no triangle, or turning the spilled import back into an in-memory mesh
    /// failed.
    #[error(transparent)]
    Import(#[from] oocfmt_meshio::import::ImportError),
    /// A chunk's kd-tree build failed.
    #[error(transparent)]
    Tree(#[from] KdError),
    /// Laying out a chunk or the top of the tree failed.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// Encoding or writing the container failed.
    #[error(transparent)]
    Format(#[from] oocfmt::Error),
}

impl OocError {
    /// A [`OocError::Spill`] for `path`.
    pub fn spill(path: &Path, source: std::io::Error) -> OocError {
        OocError::Spill {
            path: path.display().to_string(),
            source,
        }
    }

    /// A [`OocError::SpillCorrupt`] for `path`.
    pub fn corrupt(path: &Path, what: &'static str) -> OocError {
        OocError::SpillCorrupt {
            path: path.display().to_string(),
            what,
        }
    }

    /// The I/O error kind behind a spill failure (`Other` for the rest), so that a full disk
    /// stays recognisable through layers that keep only a message.
    pub fn io_kind(&self) -> std::io::ErrorKind {
        match self {
            OocError::Spill { source, .. } | OocError::SpillWrite { source, .. } => source.kind(),
            _ => std::io::ErrorKind::Other,
        }
    }
}

/// A hint for a write that failed for want of space.
fn space_hint(e: &std::io::Error) -> &'static str {
    match e.kind() {
        std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded => {
            " (out of disk space: free some, or put spill files elsewhere with --tmp-dir)"
        }
        _ => "",
    }
}

/// What the out-of-core build did, for the report.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct OocStats {
    /// Chunks built, each in memory on its own.
    pub chunks: u64,
    /// Most triangles a chunk was meant to hold: the memory limit over the per-triangle cost.
    pub chunk_budget_triangles: u64,
    /// Triangles (copies included) in the largest chunk.
    pub largest_chunk_triangles: u64,
    /// Chunks that could not be split down to the budget.
    pub oversized_chunks: u64,
    /// Triangle records in the chunks over triangles imported: the copies splits made.
    pub split_copies: u64,
    /// LOD nodes among the median-split nodes above the chunks.
    pub top_lod_nodes: u64,
}

/// Chunks built at once, each in an equal share of the memory budget: while one chunk's
/// serial parts run (its load and vertex de-duplication, its block encoding), the other's
/// parallel parts keep the workers busy. A constant, not the thread count, so that the chunks,
/// and the bytes, are the same on every machine.
pub(crate) const CHUNKS_AT_ONCE: usize = 2;

/// How an out-of-core build cuts and spills the scene.
pub(crate) struct Chunking<'a> {
    /// Most triangles (about) held in memory at once: the chunks built at once hold this
    /// many together.
    pub chunk_triangles: u64,
    /// Chunks built at once: [`CHUNKS_AT_ONCE`], except in the test that compares it with 1.
    pub at_once: usize,
    /// The folder of the spill files.
    pub dir: &'a Path,
}

impl<'a> Chunking<'a> {
    /// `chunk_triangles` in memory, [`CHUNKS_AT_ONCE`] chunks at once, spill files in `dir`.
    pub(crate) fn new(chunk_triangles: u64, dir: &'a Path) -> Chunking<'a> {
        Chunking {
            chunk_triangles,
            at_once: CHUNKS_AT_ONCE,
            dir,
        }
    }
}

/// Builds the container at `output` from the spill run of `soup`, as `chunking` says. Each
/// pass frees its input as it reads it, and `soup.disk` counts what the spill files take.
/// `clock` times the phases.
pub(crate) fn build(
    soup: Soup,
    output: &Path,
    kd: &KdBuildOptions,
    layout: &LayoutOptions,
    chunking: Chunking,
    clock: &mut PhaseClock,
    progress: &mut dyn Progress,
) -> Result<(WriteSummary, OocStats), OocError> {
    let scene = &soup.scene;
    let b = OocBuild::new(scene, &soup.disk, kd, layout, &chunking)?;
    let start = split::Start::root(scene.bounds);
    // The split consumes the import's run.
    let mut tree = b.split(soup.run.clone(), TopTree::default(), start, progress)?;
    clock.done("split");
    let planes = std::mem::take(&mut tree.planes);
    let top_lod = b.top_lod_nodes(&tree);
    let (chunks, mut spill) = b.build_chunks(&tree, planes, top_lod, progress)?;
    clock.done("chunks");
    b.finish(&tree, chunks, &mut spill, output, clock, progress)
}

/// One out-of-core build: its inputs and the scene-wide facts every phase reads. [`build`]
/// runs the phases in data-flow order, each on what the one before produced.
pub(crate) struct OocBuild<'a> {
    scene: &'a SceneInfo,
    disk: &'a Arc<SpillDisk>,
    kd: &'a KdBuildOptions,
    layout: &'a LayoutOptions,
    /// Most triangles a chunk holds (at least 1).
    budget: u64,
    /// Chunks built at once (at least 1).
    at_once: usize,
    dir: &'a Path,
    block_size: usize,
    schema: Schema,
    /// The scene's material table, compacted to the materials triangles use.
    materials: Vec<oocfmt::metadata::Material>,
    facts: SceneFacts,
}

/// The chunks, built and spilled.
pub(crate) struct Chunks {
    pub outs: Vec<ChunkOut>,
    /// Each chunk's proxy records (node blocks chunk-local), taken out of its [`ChunkOut`].
    pub proxies: Vec<Vec<u8>>,
    /// Proxies of all chunks: the top's proxy ids start here.
    pub proxy_count: u32,
    /// What each chunk's treelet blocks add to the proxy ids they hold: 0 when the chunks
    /// were numbered as one series, the proxies of the subsets before when merged.
    pub proxy_shift: Vec<u32>,
    pub top_lod: Vec<top::TopLod>,
    /// The R-LOD planes of the top LOD nodes, their deviations widened by every chunk below.
    pub planes: BTreeMap<usize, PlaneFit>,
}

/// What the whole scene has, as the import found it: what every chunk and the top are built
/// with, whichever subset of the scene a process builds.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SceneInfo {
    /// The box of every kept triangle's corners, positions relative to the scene origin.
    pub bounds: Bounds,
    /// Triangles kept.
    pub count: u64,
    /// Materials as the importers added them.
    pub materials: Vec<oocfmt::metadata::Material>,
    /// The materials triangles use (`None`: no material), in order of first use.
    pub used_materials: Vec<Option<u32>>,
    /// The parts as the importers declared them.
    pub parts: Vec<oocfmt_meshio::import::PartDef>,
    /// Some triangle has vertex normals.
    pub normals: bool,
    /// Some triangle has vertex colours.
    pub colours: bool,
}

/// The top of the tree, planned, and the file order of every block.
struct TopPlan {
    skel: top::Skeleton,
    plan: TreePlan,
    order: assemble::Order,
}

impl<'a> OocBuild<'a> {
    /// Checks the options and gathers the scene-wide facts: schema, material table, block size.
    pub(crate) fn new(
        scene: &'a SceneInfo,
        disk: &'a Arc<SpillDisk>,
        kd: &'a KdBuildOptions,
        layout: &'a LayoutOptions,
        chunking: &Chunking<'a>,
    ) -> Result<OocBuild<'a>, OocError> {
        kd.check()?;
        let block_size = 1usize << layout.write.block_size_log2.min(20);
        oocfmt::WriteOptions::default()
            .with_block_size(1u64 << layout.write.block_size_log2.min(63))?;
        let materials = scene.used_materials.iter().any(Option::is_some);
        let (_, table) = compact_materials(&scene.used_materials, scene.materials.clone())?;
        let schema = Schema {
            vertex_normals: scene.normals,
            vertex_colours: scene.colours,
            triangle_materials: materials,
            six_sample_voxels: false,
        };
        let facts = SceneFacts {
            schema: ChunkSchema {
                normals: scene.normals,
                colours: scene.colours,
                materials: materials.then(|| table.clone()),
                part_ids: scene.parts.len() > 1,
            },
            material_index: materials.then(|| {
                scene
                    .used_materials
                    .iter()
                    .enumerate()
                    .map(|(i, &m)| (m, i as u32))
                    .collect::<FxHashMap<_, _>>()
            }),
            attrs: parts::triangle_attributes(schema.triangle_attributes(), scene.parts.len()),
            block_size,
            kinds: layout.write.lod.with_parts(scene.parts.len() >= 2),
            parts: scene.parts.clone(),
            unnamed: scene.parts.len().checked_sub(1).map(|p| p as u32),
        };
        Ok(OocBuild {
            scene,
            disk,
            kd,
            layout,
            budget: (chunking.chunk_triangles / chunking.at_once.max(1) as u64).max(1),
            at_once: chunking.at_once.max(1),
            dir: chunking.dir,
            block_size,
            schema,
            materials: table,
            facts,
        })
    }

    /// The scene-wide facts every chunk is built with.
    pub(crate) fn facts(&self) -> &SceneFacts {
        &self.facts
    }

    /// Median-splits `run`, the triangles of `start`'s cell, into chunks within the budget,
    /// below the nodes `top` already holds, fitting the R-LOD planes of the split nodes that
    /// are LOD nodes on the way when the build makes R-LODs. Consumes the run.
    pub(crate) fn split(
        &self,
        run: segments::Run,
        top: TopTree,
        start: split::Start,
        progress: &mut dyn Progress,
    ) -> Result<TopTree, OocError> {
        let colour = |t: &InputTriangle| self.facts.colour(t);
        let part = |t: &InputTriangle| self.facts.part(t);
        let rlods = self.layout.write.lod.rlod.then_some(split::RlodMoments {
            treelet_height: self.layout.treelet_height,
            colour: &colour,
            part: &part,
        });
        let to = split::SpillTo {
            dir: self.dir,
            disk: self.disk,
        };
        split::split_from(run, top, start, self.budget, &to, rlods.as_ref(), progress)
    }

    /// The LOD nodes among `tree`'s median-split nodes, with the rays that will sample them.
    pub(crate) fn top_lod_nodes(&self, tree: &TopTree) -> Vec<top::TopLod> {
        top::top_lod_nodes(
            tree,
            self.scene.bounds,
            self.layout.treelet_height,
            self.layout.voxel_threshold,
        )
    }

    /// Builds the chunks several at a time (`at_once`) and spills their blocks in chunk order;
    /// each chunk answers the rays of the `top_lod` nodes above it and widens their R-LOD
    /// `planes` by its deviation. The bytes do not depend on how many are built at once.
    pub(crate) fn build_chunks(
        &self,
        tree: &TopTree,
        mut planes: BTreeMap<usize, PlaneFit>,
        mut top_lod: Vec<top::TopLod>,
        progress: &mut dyn Progress,
    ) -> Result<(Chunks, BlockSpill), OocError> {
        let builder = ChunkBuilder {
            facts: &self.facts,
            kd: self.kd,
            layout: self.layout,
            disk: self.disk,
        };
        let mut spill = BlockSpill::new(self.dir, self.disk.clone());
        let mut outs: Vec<ChunkOut> = Vec::with_capacity(tree.chunks.len());
        let mut chunk_proxies = Vec::new();
        let mut proxy_count = 0u32;
        // A chunk measures its deviation from the planes as fitted; the pieces are widened in.
        let fitted = planes.clone();
        progress.phase("chunks", Some(tree.chunks.len() as u64));
        for window in tree.chunks.chunks(self.at_once) {
            let built: Vec<Result<chunk::BuiltChunk, OocError>> = window
                .par_iter()
                .map(|c| {
                    let rays: Vec<&[chunk::PendingRay]> = top_lod
                        .iter()
                        .filter(|t| c.ancestors.contains(&t.node))
                        .map(|t| t.rays.as_slice())
                        .collect();
                    let above: Vec<(usize, PlaneFit)> = c
                        .ancestors
                        .iter()
                        .filter_map(|a| fitted.get(a).map(|p| (*a, *p)))
                        .collect();
                    builder.build(c, &rays, &above)
                })
                .collect();
            for (c, b) in window.iter().zip(built) {
                let mut rays: Vec<&mut [chunk::PendingRay]> = top_lod
                    .iter_mut()
                    .filter(|t| c.ancestors.contains(&t.node))
                    .map(|t| t.rays.as_mut_slice())
                    .collect();
                let mut out = b?.spill(&mut spill, proxy_count, &mut rays)?;
                for (node, piece) in &out.plane_pieces {
                    if let Some(p) = planes.get_mut(node) {
                        p.widen(piece);
                    }
                }
                let n = u32::try_from(out.proxies.len() / oocfmt::records::PROXY_LEN)
                    .map_err(|_| LayoutError::TooMany("proxies"))?;
                proxy_count = proxy_count
                    .checked_add(n)
                    .ok_or(LayoutError::TooMany("proxies"))?;
                chunk_proxies.push(std::mem::take(&mut out.proxies));
                outs.push(out);
                progress.advance(outs.len() as u64);
            }
        }
        progress.finish_phase();
        let chunks = Chunks {
            proxy_shift: vec![0; outs.len()],
            outs,
            proxies: chunk_proxies,
            proxy_count,
            top_lod,
            planes,
        };
        Ok((chunks, spill))
    }

    /// Lays out the top over the built `chunks`, whose blocks `blocks` holds, and writes the
    /// container at `output`.
    pub(crate) fn finish(
        &self,
        tree: &TopTree,
        mut chunks: Chunks,
        blocks: &mut dyn assemble::BlockSource,
        output: &Path,
        clock: &mut PhaseClock,
        progress: &mut dyn Progress,
    ) -> Result<(WriteSummary, OocStats), OocError> {
        let given = self.top_lod_data(tree, &chunks)?;
        let mut top = self.plan_top(tree, &chunks, &given)?;
        top.order.proxy_shift = std::mem::take(&mut chunks.proxy_shift);
        top.assign_final_ids()?;
        let top_raw = top.encode()?;
        let proxies = self.gather_proxies(std::mem::take(&mut chunks.proxies), &top)?;
        let (counts, stats) = self.tally(tree, &chunks, &top);
        let mut metadata = self.metadata(&counts, &top.order, proxies.len(), &stats);
        metadata.parts = self.part_table(&chunks);
        clock.done("top");
        let summary = assemble::write(
            output,
            self.layout.write,
            &assemble::Parts {
                order: &top.order,
                top: &top_raw,
                proxies: &proxies,
                lod: self.facts.kinds,
            },
            blocks,
            self.disk,
            &metadata,
            progress,
        )?;
        clock.done("write");
        Ok((summary, stats))
    }

    /// The LOD data (and R-LOD) of each top LOD node, from its answered rays and the area of
    /// the chunks below it.
    fn top_lod_data(
        &self,
        tree: &split::TopTree,
        chunks: &Chunks,
    ) -> Result<BTreeMap<usize, (LodData, Option<Rlod>)>, OocError> {
        let mut given = BTreeMap::new();
        let kinds = self.facts.kinds;
        for t in &chunks.top_lod {
            let below = || {
                tree.chunks
                    .iter()
                    .zip(&chunks.outs)
                    .filter(|(c, _)| c.ancestors.contains(&t.node))
                    .map(|(_, o)| o)
            };
            let area: f64 = below().map(|o| o.area).sum();
            let plane = chunks.planes.get(&t.node);
            let rlod = match plane {
                Some(p) => Some(p.record(t.cell.half_diagonal_up().unwrap_or(f32::MAX))),
                None if kinds.rlod => {
                    return Err(LayoutError::Internal("a top LOD node has no R-LOD plane").into())
                }
                None => None,
            };
            // A cell no ray hit: the part of the largest area in the chunks below.
            let fallback = match kinds.parts {
                true => parts::largest_by_area(below().map(|o| o.parts.as_slice())),
                false => 0,
            };
            let mut data = top::finish_top_lod(t, self.layout.voxel_threshold, area, fallback);
            // R-LOD only: the part of the largest area clipped to the cell, as in core.
            if let (false, true, Some(p)) = (kinds.voxel, kinds.parts, plane) {
                data.part = p.part;
            }
            given.insert(t.node, (data, rlod));
        }
        Ok(given)
    }

    /// Plans the top: the median-split nodes and the chunks' top treelets as one skeleton,
    /// laid out by the ordinary planner, then the file order of every block.
    fn plan_top(
        &self,
        tree: &split::TopTree,
        chunks: &Chunks,
        given: &BTreeMap<usize, (LodData, Option<Rlod>)>,
    ) -> Result<TopPlan, OocError> {
        let skel = top::skeleton(tree, &chunks.outs, given, self.scene.bounds)?;
        let external: BTreeMap<NodeId, (u32, u32)> = skel
            .frontier
            .iter()
            .map(|(&id, &(_, block, treelet))| (id, (block, treelet)))
            .collect();
        let lod_of = |id: NodeId| skel.lod.get(&id).copied();
        let plan = plan_tree_with(
            &skel.tree,
            &PlanSpec {
                treelet_height: self.layout.treelet_height,
                block_size: self.block_size,
                max_proxies: usize::MAX,
                depth_offset: 0,
                proxy_base: chunks.proxy_count,
                detach_root: false,
                first_level: 0,
                lod: LodSource::Given {
                    data: &lod_of,
                    kinds: self.facts.kinds,
                },
                external: &external,
            },
        )?;
        let top_levels: Vec<u16> = plan.blocks.iter().map(|b| b.level).collect();
        let order = assemble::order(&top_levels, &chunks.outs)?;
        Ok(TopPlan { skel, plan, order })
    }

    /// The proxy records in id order: each chunk's, their node blocks made final, then the
    /// top's.
    fn gather_proxies(
        &self,
        chunk_proxies: Vec<Vec<u8>>,
        top: &TopPlan,
    ) -> Result<Vec<u8>, OocError> {
        let mut proxies = Vec::new();
        for (i, mut records) in chunk_proxies.into_iter().enumerate() {
            top.order.patch_proxies(i, &mut records)?;
            proxies.extend_from_slice(&records);
        }
        chunk::proxy_records(&top.plan, &mut proxies)?;
        Ok(proxies)
    }

    /// The part table: every chunk's primaries tallied by part.
    fn part_table(&self, chunks: &Chunks) -> Vec<oocfmt::metadata::Part> {
        let mut totals = PartTotals::new(self.scene.parts.len());
        for o in &chunks.outs {
            totals.add(&o.parts);
        }
        totals.table(&self.scene.parts)
    }

    /// The counts of the whole tree (the top's treelets and every chunk's) and the build's
    /// statistics.
    fn tally(
        &self,
        tree: &split::TopTree,
        chunks: &Chunks,
        top: &TopPlan,
    ) -> (ChunkCounts, OocStats) {
        let mut counts = ChunkCounts::default();
        for b in &top.plan.blocks {
            for &t in &b.treelets {
                chunk::count_treelet(&top.plan, t, &mut counts);
            }
        }
        let mut stats = OocStats {
            chunks: chunks.outs.len() as u64,
            chunk_budget_triangles: self.budget,
            oversized_chunks: tree.oversized.len() as u64,
            top_lod_nodes: chunks.top_lod.len() as u64,
            ..OocStats::default()
        };
        for (c, o) in tree.chunks.iter().zip(&chunks.outs) {
            add_counts(&mut counts, &o.counts);
            stats.largest_chunk_triangles = stats.largest_chunk_triangles.max(c.count);
            stats.split_copies += c.count;
        }
        stats.split_copies = stats.split_copies.saturating_sub(self.scene.count);
        (counts, stats)
    }

    /// The container's metadata.
    fn metadata(
        &self,
        counts: &ChunkCounts,
        order: &assemble::Order,
        proxy_bytes: usize,
        stats: &OocStats,
    ) -> Metadata {
        let (kd, layout, bounds) = (self.kd, self.layout, self.scene.bounds);
        let mut schema = self.schema;
        schema.six_sample_voxels = counts.voxels_six > 0;
        let mut params = kd.params();
        params.extend(lod_params(layout.write.lod, layout.voxel_threshold));
        params.push((
            "triangles_per_proxy".into(),
            layout.triangles_per_proxy.to_string(),
        ));
        params.push((
            "out_of_core".into(),
            format!(
                "{} chunks of at most {} triangles; median-split LOD nodes sampled with {} rays per face",
                stats.chunks,
                stats.chunk_budget_triangles,
                crate::lod::FACE_RAYS_MAX
            ),
        ));
        params.extend(layout.params.iter().cloned());
        Metadata {
            scene: Scene {
                bounds_min: bounds.min,
                bounds_max: bounds.max,
                origin: layout.origin,
            },
            root: Some(TreeletRef {
                block: order.top.first().copied().unwrap_or(0),
                treelet: 0,
            }),
            counts: Counts {
                triangles: counts.triangles.primaries,
                triangle_records: counts.triangles.triangles,
                vertices: counts.triangles.vertices,
                basic_nodes: counts.basic_nodes,
                lod_nodes: counts.lod_nodes,
                leaves: counts.leaves,
                voxels_single: counts.voxels_single,
                voxels_six: counts.voxels_six,
                proxies: (proxy_bytes / oocfmt::records::PROXY_LEN) as u64,
                treelets: counts.treelets,
                depth: counts.depth,
                lod_levels: order.levels,
            },
            schema,
            materials: self.materials.clone(),
            build: Build {
                treelet_height: layout.treelet_height,
                max_leaf_triangles: kd.max_leaf_triangles,
                params,
            },
            provenance: Provenance {
                generator: layout.generator.clone(),
                sources: layout.sources.clone(),
            },
            parts: Vec::new(),
        }
    }
}

impl TopPlan {
    /// Gives the top plan's nodes their final block ids: their own block, and the block of
    /// their children (a chunk's block below a frontier node, a top block below another LOD
    /// node).
    fn assign_final_ids(&mut self) -> Result<(), LayoutError> {
        let order = &self.order;
        let top_block = |local: u32| {
            order
                .top
                .get(local as usize)
                .copied()
                .ok_or(LayoutError::Internal("a top block id is out of range"))
        };
        for k in 0..self.plan.info.len() {
            let id = NodeId(k as u32);
            let info = self.plan.info(id);
            let block = top_block(info.block)?;
            let child_block = match self.skel.frontier.get(&id) {
                Some(&(chunk, local, _)) => order
                    .chunk_treelets
                    .get(chunk)
                    .and_then(|m| m.get(local as usize))
                    .copied()
                    .ok_or(LayoutError::Internal(
                        "a frontier node's child block is missing",
                    ))?,
                None if info.role == Role::Lod => top_block(info.child_block)?,
                None => info.child_block,
            };
            if let Some(slot) = self.plan.info.get_mut(k) {
                slot.block = block;
                slot.child_block = child_block;
            }
        }
        Ok(())
    }

    /// The top's treelet blocks, encoded with final ids: the leaves of the chunks' top
    /// treelets pointing at their final triangle blocks.
    fn encode(&self) -> Result<Vec<RawBlock>, LayoutError> {
        let mut leaves: Vec<Option<LeafRef>> = vec![None; self.skel.tree.nodes().len()];
        for (&id, &(chunk, r)) in &self.skel.leaves {
            let block = self
                .order
                .chunk_triangles
                .get(chunk)
                .and_then(|m| m.get(r.block as usize))
                .copied()
                .ok_or(LayoutError::Internal("a leaf's triangle block is missing"))?;
            if let Some(slot) = leaves.get_mut(id.index()) {
                *slot = Some(LeafRef { block, ..r });
            }
        }
        self.plan
            .blocks
            .iter()
            .map(|b| {
                Ok(RawBlock {
                    kind: BlockKind::Treelet,
                    level: b.level,
                    item_count: u32::try_from(b.treelets.len())
                        .map_err(|_| LayoutError::TooMany("treelets"))?,
                    raw: encode_treelets(b, &self.skel.tree, &self.plan, &leaves, 0)?,
                })
            })
            .collect()
    }
}

fn add_counts(total: &mut ChunkCounts, c: &ChunkCounts) {
    total.basic_nodes += c.basic_nodes;
    total.lod_nodes += c.lod_nodes;
    total.leaves += c.leaves;
    total.voxels_single += c.voxels_single;
    total.voxels_six += c.voxels_six;
    total.treelets += c.treelets;
    total.depth = total.depth.max(c.depth);
    total.triangles.primaries += c.triangles.primaries;
    total.triangles.triangles += c.triangles.triangles;
    total.triangles.vertices += c.triangles.vertices;
}
