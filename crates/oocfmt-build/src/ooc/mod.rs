//! The out-of-core build (Áfra et al. 2012, §4.1; Correa et al. 2002, §3): the imported scene
//! lives in a spill file, cells too large for memory are split at their spatial median in
//! streaming passes ([`split`]), and each chunk that fits is built, sampled and laid out in
//! memory on its own ([`chunk`]), its deeper blocks spilled. The median-split nodes and the
//! chunks' top treelets form a small tree laid out last ([`top`]), and [`assemble`] writes
//! everything in the order the spec requires. Memory holds one chunk at a time, plus the top.

mod assemble;
mod chunk;
pub mod soup;
mod split;
mod tee;
mod top;

#[cfg(test)]
mod tests;

use std::collections::BTreeMap;
use std::path::Path;

use rustc_hash::FxHashMap;

use oocfmt::metadata::{Build, Counts, Provenance, Scene, Schema, TreeletRef};
use oocfmt::{BlockKind, Metadata, WriteSummary};

use crate::kdtree::{KdBuildOptions, KdError, NodeId};
use crate::layout::lod_params;
use crate::layout::plan::{plan_tree_with, LodSource, PlanSpec};
use crate::layout::treelets::encode_treelets;
use crate::layout::triangles::LeafRef;
use crate::layout::{LayoutError, LayoutOptions, RawBlock};
use crate::lod::rlod::PlaneFit;
use crate::progress::Progress;
use chunk::{build_chunk, BlockSpill, ChunkCounts, ChunkOut, SceneFacts};
use oocfmt_meshio::import::{compact_materials, InputTriangle, PartSchema};
use soup::Soup;

#[derive(Debug, thiserror::Error)]
pub enum OocError {
    #[error("spill file {path}: {source}")]
    Spill {
        path: String,
        source: std::io::Error,
    },
    #[error("spill file {path}: {len} bytes, expected {count} records")]
    SpillLength { path: String, len: u64, count: u64 },
    #[error(transparent)]
    Import(#[from] oocfmt_meshio::import::ImportError),
    #[error(transparent)]
    Tree(#[from] KdError),
    #[error(transparent)]
    Layout(#[from] LayoutError),
    #[error(transparent)]
    Format(#[from] oocfmt::Error),
}

impl OocError {
    pub fn spill(path: &Path, source: std::io::Error) -> OocError {
        OocError::Spill {
            path: path.display().to_string(),
            source,
        }
    }
}

/// What the out-of-core build did, for the report.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct OocStats {
    pub chunks: u64,
    pub chunk_budget_triangles: u64,
    pub largest_chunk_triangles: u64,
    /// Chunks that could not be split down to the budget.
    pub oversized_chunks: u64,
    /// Triangle records in the chunks over triangles imported: the copies splits made.
    pub split_copies: u64,
    pub top_lod_nodes: u64,
}

/// Builds the container at `output` from the spill file of `soup`, holding at most about
/// `chunk_triangles` triangles in memory at once. Spill files go to `dir`.
pub fn build(
    soup: Soup,
    output: &Path,
    kd: &KdBuildOptions,
    layout: &LayoutOptions,
    chunk_triangles: u64,
    dir: &Path,
    progress: &mut dyn Progress,
) -> Result<(WriteSummary, OocStats), OocError> {
    kd.check()?;
    let block_size = 1usize << layout.write.block_size_log2.min(20);
    oocfmt::WriteOptions::default()
        .with_block_size(1u64 << layout.write.block_size_log2.min(63))?;
    let budget = chunk_triangles.max(1);
    let bounds = soup.bounds;
    let materials = soup.used_materials.iter().any(Option::is_some);
    let (_, table) = compact_materials(&soup.used_materials, soup.materials.clone())?;
    let schema = Schema {
        vertex_normals: soup.normals,
        vertex_colours: soup.colours,
        triangle_materials: materials,
        six_sample_voxels: false,
    };
    let facts = SceneFacts {
        schema: PartSchema {
            normals: soup.normals,
            colours: soup.colours,
            materials: materials.then(|| table.clone()),
        },
        material_index: materials.then(|| {
            soup.used_materials
                .iter()
                .enumerate()
                .map(|(i, &m)| (m, i as u32))
                .collect::<FxHashMap<_, _>>()
        }),
        attrs: schema.triangle_attributes(),
        block_size,
    };
    let colour = |t: &InputTriangle| facts.colour(t);
    let rlods = layout.write.lod.rlod.then_some(split::RlodMoments {
        treelet_height: layout.treelet_height,
        colour: &colour,
    });
    let mut tree = split::split(
        &soup.path,
        soup.count,
        bounds,
        budget,
        dir,
        rlods.as_ref(),
        progress,
    )?;
    let mut planes: BTreeMap<usize, PlaneFit> = std::mem::take(&mut tree.planes);

    let mut top_lod =
        top::top_lod_nodes(&tree, bounds, layout.treelet_height, layout.voxel_threshold);
    let mut spill = BlockSpill::create(&dir.join("blocks.spill"))?;
    let mut outs: Vec<ChunkOut> = Vec::with_capacity(tree.chunks.len());
    let mut chunk_proxies = Vec::new();
    let mut proxy_count = 0u32;
    progress.phase("chunks", Some(tree.chunks.len() as u64));
    for (i, c) in tree.chunks.iter().enumerate() {
        let mut rays: Vec<&mut [chunk::PendingRay]> = top_lod
            .iter_mut()
            .filter(|t| c.ancestors.contains(&t.node))
            .map(|t| t.rays.as_mut_slice())
            .collect();
        let above: Vec<(usize, PlaneFit)> = c
            .ancestors
            .iter()
            .filter_map(|a| planes.get(a).map(|p| (*a, *p)))
            .collect();
        let mut out = build_chunk(
            c,
            &facts,
            kd,
            layout,
            proxy_count,
            &mut rays,
            &above,
            &mut spill,
        )?;
        for (node, piece) in &out.plane_pieces {
            if let Some(p) = planes.get_mut(node) {
                p.widen(piece);
            }
        }
        std::fs::remove_file(&c.path).map_err(|e| OocError::spill(&c.path, e))?;
        let n = u32::try_from(out.proxies.len() / oocfmt::records::PROXY_LEN)
            .map_err(|_| LayoutError::TooMany("proxies"))?;
        proxy_count = proxy_count
            .checked_add(n)
            .ok_or(LayoutError::TooMany("proxies"))?;
        chunk_proxies.push(std::mem::take(&mut out.proxies));
        outs.push(out);
        progress.advance(i as u64 + 1);
    }
    progress.finish_phase();

    // The top: LOD data of the median-split LOD nodes, then the skeleton's plan.
    let mut given = BTreeMap::new();
    for t in &top_lod {
        let area: f64 = tree
            .chunks
            .iter()
            .zip(&outs)
            .filter(|(c, _)| c.ancestors.contains(&t.node))
            .map(|(_, o)| o.area)
            .sum();
        let rlod = match planes.get(&t.node) {
            Some(p) => Some(p.record(t.cell.half_diagonal_up().unwrap_or(f32::MAX))),
            None if layout.write.lod.rlod => {
                return Err(LayoutError::Internal("a top LOD node has no R-LOD plane").into())
            }
            None => None,
        };
        given.insert(
            t.node,
            (top::finish_top_lod(t, layout.voxel_threshold, area), rlod),
        );
    }
    let skel = top::skeleton(&tree, &outs, &given, bounds)?;
    let external: BTreeMap<NodeId, (u32, u32)> = skel
        .frontier
        .iter()
        .map(|(&id, &(_, block, treelet))| (id, (block, treelet)))
        .collect();
    let lod_of = |id: NodeId| skel.lod.get(&id).copied();
    let mut plan = plan_tree_with(
        &skel.tree,
        &PlanSpec {
            treelet_height: layout.treelet_height,
            block_size,
            max_proxies: usize::MAX,
            depth_offset: 0,
            proxy_base: proxy_count,
            detach_root: false,
            first_level: 0,
            lod: LodSource::Given {
                data: &lod_of,
                kinds: layout.write.lod,
            },
            external: &external,
        },
    )?;
    let top_levels: Vec<u16> = plan.blocks.iter().map(|b| b.level).collect();
    let order = assemble::order(&top_levels, &outs)?;

    // Final ids into the top plan, then encode it.
    let top_block = |local: u32| {
        order
            .top
            .get(local as usize)
            .copied()
            .ok_or(LayoutError::Internal("a top block id is out of range"))
    };
    for k in 0..plan.info.len() {
        let id = NodeId(k as u32);
        let info = plan.info(id);
        let block = top_block(info.block).unwrap_or(info.block);
        let child_block = match skel.frontier.get(&id) {
            Some(&(chunk, local, _)) => order
                .chunk_treelets
                .get(chunk)
                .and_then(|m| m.get(local as usize))
                .copied()
                .ok_or(LayoutError::Internal(
                    "a frontier node's child block is missing",
                ))?,
            None if info.role == crate::layout::plan::Role::Lod => top_block(info.child_block)?,
            None => info.child_block,
        };
        if let Some(slot) = plan.info.get_mut(k) {
            slot.block = block;
            slot.child_block = child_block;
        }
    }
    let mut leaves: Vec<Option<LeafRef>> = vec![None; skel.tree.nodes().len()];
    for (&id, &(chunk, r)) in &skel.leaves {
        let block = order
            .chunk_triangles
            .get(chunk)
            .and_then(|m| m.get(r.block as usize))
            .copied()
            .ok_or(LayoutError::Internal("a leaf's triangle block is missing"))?;
        if let Some(slot) = leaves.get_mut(id.index()) {
            *slot = Some(LeafRef { block, ..r });
        }
    }
    let top_raw: Vec<RawBlock> = plan
        .blocks
        .iter()
        .map(|b| {
            Ok(RawBlock {
                kind: BlockKind::Treelet,
                level: b.level,
                item_count: u32::try_from(b.treelets.len())
                    .map_err(|_| LayoutError::TooMany("treelets"))?,
                raw: encode_treelets(b, &skel.tree, &plan, &leaves, 0)?,
            })
        })
        .collect::<Result<_, LayoutError>>()?;

    let mut proxies = Vec::new();
    for (i, mut records) in chunk_proxies.into_iter().enumerate() {
        order.patch_proxies(i, &mut records)?;
        proxies.extend_from_slice(&records);
    }
    for &n in &plan.lod_order {
        let data = plan
            .lod_data(n)
            .ok_or(LayoutError::Internal("a LOD node has no LOD data"))?;
        data.proxy(plan.info(n).block).encode_into(&mut proxies);
    }

    let mut counts = ChunkCounts::default();
    for b in &plan.blocks {
        for &t in &b.treelets {
            chunk::count_treelet(&plan, t, &mut counts);
        }
    }
    let mut stats = OocStats {
        chunks: outs.len() as u64,
        chunk_budget_triangles: budget,
        oversized_chunks: tree.oversized.len() as u64,
        top_lod_nodes: top_lod.len() as u64,
        ..OocStats::default()
    };
    for (c, o) in tree.chunks.iter().zip(&outs) {
        add_counts(&mut counts, &o.counts);
        stats.largest_chunk_triangles = stats.largest_chunk_triangles.max(c.count);
        stats.split_copies += c.count;
    }
    stats.split_copies = stats.split_copies.saturating_sub(soup.count);
    let metadata = metadata(
        &counts,
        &order,
        proxies.len(),
        schema,
        table,
        kd,
        layout,
        &stats,
        bounds,
    );
    let summary = assemble::write(
        output,
        layout.write,
        &assemble::Parts {
            order: &order,
            top: &top_raw,
            spill: spill.path(),
            proxies: &proxies,
        },
        &metadata,
        progress,
    )?;
    Ok((summary, stats))
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

#[allow(clippy::too_many_arguments)]
fn metadata(
    counts: &ChunkCounts,
    order: &assemble::Order,
    proxy_bytes: usize,
    mut schema: Schema,
    materials: Vec<oocfmt::metadata::Material>,
    kd: &KdBuildOptions,
    layout: &LayoutOptions,
    stats: &OocStats,
    bounds: oocfmt_meshio::mesh::Bounds,
) -> Metadata {
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
        materials,
        build: Build {
            treelet_height: layout.treelet_height,
            max_leaf_triangles: kd.max_leaf_triangles,
            params,
        },
        provenance: Provenance {
            generator: layout.generator.clone(),
            sources: layout.sources.clone(),
        },
    }
}
