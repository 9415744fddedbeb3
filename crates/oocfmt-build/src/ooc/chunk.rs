//! One chunk of an out-of-core build, in memory: its mesh from its spill file, its kd-subtree
//! (binned SAH), its LOD data and its blocks. The blocks below the chunk's top treelet are
//! encoded with chunk-local block ids and spilled; the top treelet goes back to the caller,
//! which lays it out with the top of the scene.

use std::sync::Arc;

use oocfmt::BlockKind;

pub use super::blocks::{BlockSpill, SpilledBlock};
use super::disk::SpillDisk;
use super::soup::SoupReader;
use super::split::Chunk;
use super::OocError;
use crate::kdtree::{build_cell, KdBuildOptions, KdNode, KdTree, NodeId};
use crate::layout::parts::{self, PartStat};
use crate::layout::plan::{plan_tree_with, LodSource, PlanSpec, Role, TreePlan};
use crate::layout::treelets::encode_treelets;
use crate::layout::triangles::{
    encode_triangles, plan_triangles_with, LeafRef, TriangleCounts, VertexTable,
};
use crate::layout::{LayoutError, LayoutOptions};
use crate::lod::rlod::{Deviation, PlaneFit};
use crate::lod::{mean_vertex_colour, shade, triangle_area, LodData, Seen};
use crate::raycast::{clip_to_box, Ray, Tracer};
use oocfmt::records::LodKinds;
use oocfmt_meshio::import::{
    ChunkSchema, InputTriangle, Location, MeshSink, PartDef, TriangleSink,
};
use oocfmt_meshio::mesh::{Bounds, Mesh};
use std::collections::BTreeMap;

use oocfmt::records::{Rlod, Voxel};
use rayon::prelude::*;

/// The scene-wide facts every chunk is built with.
pub struct SceneFacts {
    pub schema: ChunkSchema,
    /// Scene material index of each importer material (`None`: no material), when the scene
    /// has materials.
    pub material_index: Option<rustc_hash::FxHashMap<Option<u32>, u32>>,
    /// Triangle block attributes, the part-id width included.
    pub attrs: u16,
    pub block_size: usize,
    /// What the LOD entries hold, the part word included.
    pub kinds: LodKinds,
    /// The scene's part table (a chunk's mesh is checked against it).
    pub parts: Vec<PartDef>,
    /// The part of triangles the input put in none: the table's last ("(no part)", added by
    /// the import exactly when such triangles exist); `None` without parts.
    pub unnamed: Option<u32>,
}

impl SceneFacts {
    /// A triangle's linear RGB as the in-core LOD code reads it from a chunk's mesh: its
    /// vertices' mean colour when the scene has vertex colours, else its material's diffuse
    /// colour, else white.
    pub fn colour(&self, t: &InputTriangle) -> [f64; 3] {
        if self.schema.colours {
            // The mesh sink gives a vertex without a colour white.
            return mean_vertex_colour(t.colours.unwrap_or([[255; 4]; 3]));
        }
        let index = self
            .material_index
            .as_ref()
            .map(|map| map.get(&t.material).copied().unwrap_or(0));
        index
            .and_then(|i| self.schema.materials.as_ref()?.get(i as usize))
            .map_or([1.0; 3], |m| m.diffuse.map(f64::from))
    }

    /// A spilled triangle's scene part id, as the in-core mesh numbers it: `None` when the
    /// scene has no part ids (fewer than two parts).
    pub fn part(&self, t: &InputTriangle) -> Option<u32> {
        self.schema
            .part_ids
            .then(|| t.part.or(self.unnamed))
            .flatten()
    }
}

/// A node of a chunk's top treelet, for the top layout.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub enum UpperNode {
    Basic {
        axis: u8,
        split: f32,
        children: [Option<usize>; 2],
    },
    /// A LOD node at the bottom of the treelet: its children are in the chunk's own blocks.
    Frontier {
        axis: u8,
        split: f32,
        present: [bool; 2],
        child_block: u32,
        child_treelet: u32,
        lod: LodData,
        rlod: Option<Rlod>,
    },
    Leaf(LeafRef),
}

/// What a chunk hands back once its blocks are spilled.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct ChunkOut {
    /// Its top treelet in preorder, children as indices into this list.
    pub upper: Vec<UpperNode>,
    /// Treelet blocks then triangle blocks, in chunk-local id order within each kind.
    pub treelet_blocks: Vec<SpilledBlock>,
    pub triangle_blocks: Vec<SpilledBlock>,
    /// Proxy records (80 bytes each, node block chunk-local) in proxy-id order.
    pub proxies: Vec<u8>,
    pub counts: ChunkCounts,
    /// Area of the chunk's primary triangles.
    pub area: f64,
    /// The R-LOD planes of the top LOD nodes above, as given, with the deviation of this
    /// chunk's part of the surface.
    pub plane_pieces: Vec<(usize, PlaneFit)>,
    /// The chunk's primaries by part (empty in a scene without parts).
    pub parts: Vec<(u32, PartStat)>,
}

#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct ChunkCounts {
    pub basic_nodes: u64,
    pub lod_nodes: u64,
    pub leaves: u64,
    pub voxels_single: u64,
    pub voxels_six: u64,
    pub treelets: u64,
    pub depth: u32,
    pub triangles: TriangleCounts,
}

/// A ray of a top LOD node, waiting for its first hit: the segment `0 ..= t1`, the tolerance,
/// and the nearest hit found so far (its parameter, shade and part).
pub struct PendingRay {
    pub ray: Ray,
    pub t1: f64,
    pub eps: f64,
    pub best: Option<(f64, Seen)>,
}

/// Loads a chunk's spill run as a mesh in the scene's schema, consuming the run; returns the
/// mesh with, for each triangle, whether this is its primary copy.
fn load_mesh(
    chunk: &Chunk,
    facts: &SceneFacts,
    disk: &Arc<SpillDisk>,
) -> Result<(Mesh, Vec<bool>), OocError> {
    let mut sink = MeshSink::for_chunk(facts.schema.clone());
    let mut primary = Vec::with_capacity(usize::try_from(chunk.count).unwrap_or(0));
    let at = Location::file("chunk spill");
    for record in SoupReader::open(&chunk.run, true, disk.clone()) {
        let r = record?;
        let material = facts
            .material_index
            .as_ref()
            .map(|map| map.get(&r.triangle.material).copied().unwrap_or(0));
        // The chunk's sink has no part table: it keeps the ids given, so the scene's
        // "(no part)" is given here, as the in-core mesh gives it.
        let part = facts.part(&r.triangle);
        sink.push(
            InputTriangle {
                material,
                part,
                ..r.triangle
            },
            &at,
        )?;
        primary.push(r.primary);
    }
    let (mut mesh, _) = sink.finish()?;
    mesh.parts.clone_from(&facts.parts);
    Ok((mesh, primary))
}

/// What every chunk of one build is built with, and the spill their blocks go to.
pub struct ChunkBuilder<'a> {
    pub facts: &'a SceneFacts,
    pub kd: &'a KdBuildOptions,
    pub layout: &'a LayoutOptions,
    pub spill: BlockSpill,
    /// Where the chunks' runs are accounted (reading one deletes it).
    pub disk: &'a Arc<SpillDisk>,
}

impl ChunkBuilder<'_> {
    /// Builds chunk `chunk`, answers the pending rays of the top LOD nodes above it, measures
    /// its surface against their R-LOD `planes`, and spills its blocks. `proxy_base` is the id
    /// of its first proxy.
    pub fn build(
        &mut self,
        chunk: &Chunk,
        proxy_base: u32,
        rays: &mut [&mut [PendingRay]],
        planes: &[(usize, PlaneFit)],
    ) -> Result<ChunkOut, OocError> {
        let (mesh, primary) = load_mesh(chunk, self.facts, self.disk)?;
        let plane_pieces = plane_pieces(&mesh, chunk, planes);
        let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
        let kd = self.kd;
        let nodes = build_cell(&mesh, all, chunk.cell, chunk.depth + 1, kd)?;
        let tree = KdTree::from_parts(&mesh, nodes, Some(NodeId(0)), chunk.cell, kd.params())?;
        answer_rays(&mesh, &tree, &chunk.cell, rays);

        let plan = self.plan(&mesh, &tree, chunk, proxy_base)?;
        let vertices = VertexTable::new(&mesh);
        let stored_elsewhere: Vec<bool> = primary.iter().map(|p| !p).collect();
        let (attrs, block_size) = (self.facts.attrs, self.facts.block_size);
        let tri_plan =
            plan_triangles_with(&mesh, &tree, &vertices, attrs, block_size, stored_elsewhere)?;

        let mut counts = ChunkCounts {
            depth: chunk.depth + plan.depth,
            ..ChunkCounts::default()
        };
        let mut treelet_blocks = Vec::with_capacity(plan.blocks.len());
        for b in &plan.blocks {
            let raw = encode_treelets(b, &tree, &plan, &tri_plan.leaves, 0)?;
            let n =
                u32::try_from(b.treelets.len()).map_err(|_| LayoutError::TooMany("treelets"))?;
            treelet_blocks.push(self.spill.push(BlockKind::Treelet, b.level, n, &raw)?);
            for &t in &b.treelets {
                count_treelet(&plan, t, &mut counts);
            }
        }
        let mut triangle_blocks = Vec::with_capacity(tri_plan.blocks.len());
        for b in &tri_plan.blocks {
            let (raw, c) = encode_triangles(b, &mesh, &vertices, attrs)?;
            let n = u32::try_from(c.triangles).map_err(|_| LayoutError::TooMany("triangles"))?;
            triangle_blocks.push(self.spill.push(BlockKind::Triangle, 0, n, &raw)?);
            counts.triangles.primaries += c.primaries;
            counts.triangles.triangles += c.triangles;
            counts.triangles.vertices += c.vertices;
        }
        let mut proxies = Vec::with_capacity(plan.lod_order.len() * oocfmt::records::PROXY_LEN);
        proxy_records(&plan, &mut proxies)?;
        let is_primary = |t: usize| primary.get(t).copied().unwrap_or(false);
        let area = (0..mesh.triangles.len())
            .filter(|&t| is_primary(t))
            .map(|t| triangle_area(&mesh, t))
            .sum();
        let part_stats = match mesh.parts.is_empty() {
            true => Vec::new(),
            false => parts::tally(&mesh, is_primary),
        };
        Ok(ChunkOut {
            upper: upper_nodes(&tree, &plan, &tri_plan.leaves)?,
            treelet_blocks,
            triangle_blocks,
            proxies,
            counts,
            area,
            plane_pieces,
            parts: part_stats,
        })
    }

    /// Plans the chunk's treelet blocks: its top treelet detached for the top layout, its LOD
    /// levels numbered on from the depth of its root, its proxies from `proxy_base`.
    fn plan(
        &self,
        mesh: &Mesh,
        tree: &KdTree,
        chunk: &Chunk,
        proxy_base: u32,
    ) -> Result<TreePlan, LayoutError> {
        let layout = self.layout;
        let h = u32::from(layout.treelet_height.max(1));
        let first_level =
            u16::try_from(chunk.depth / h + 1).map_err(|_| LayoutError::TooMany("LOD levels"))?;
        let max_proxies = match layout.triangles_per_proxy {
            0 => usize::MAX,
            n => (chunk.count as usize)
                .div_ceil(n as usize)
                .max(1 << (h - 1).min(16)),
        };
        let external = BTreeMap::new();
        plan_tree_with(
            tree,
            &PlanSpec {
                treelet_height: layout.treelet_height,
                block_size: self.facts.block_size,
                max_proxies,
                depth_offset: chunk.depth,
                proxy_base,
                detach_root: true,
                first_level,
                lod: LodSource::Sample {
                    mesh,
                    threshold: layout.voxel_threshold,
                    kinds: self.facts.kinds,
                },
                external: &external,
            },
        )
    }
}

/// Triangles a worker measures against a plane at a time in [`plane_pieces`]: a fixed size, so
/// the pieces and the order they are combined in do not depend on the thread count.
const DEVIATION_RUN: usize = 1 << 14;

/// The deviation of the chunk's surface from each R-LOD plane of the top LOD nodes above it.
/// The chunk's cell lies inside each top node's cell, and the chunks partition it. The
/// triangles are measured in runs in parallel (a chunk has one to a few such planes) and the
/// runs' pieces combined in order.
fn plane_pieces(
    mesh: &Mesh,
    chunk: &Chunk,
    planes: &[(usize, PlaneFit)],
) -> Vec<(usize, PlaneFit)> {
    let n = mesh.triangles.len();
    let starts: Vec<usize> = (0..n).step_by(DEVIATION_RUN).collect();
    planes
        .iter()
        .map(|(node, plane)| {
            let measure = |&start: &usize| {
                let mut d = Deviation::new(plane, chunk.cell);
                for t in start..(start + DEVIATION_RUN).min(n) {
                    if let Some(c) = mesh.corners(t) {
                        d.add(c);
                    }
                }
                d.finish()
            };
            let runs: Vec<PlaneFit> = starts.par_iter().map(measure).collect();
            let mut whole = Deviation::new(plane, chunk.cell).finish();
            for r in &runs {
                whole.widen(r);
            }
            (*node, whole)
        })
        .collect()
}

/// Appends the proxy records of `plan`'s proxied LOD nodes, in proxy-id order.
pub(super) fn proxy_records(plan: &TreePlan, out: &mut Vec<u8>) -> Result<(), LayoutError> {
    for &n in &plan.lod_order {
        let data = plan
            .lod_data(n)
            .ok_or(LayoutError::Internal("a LOD node has no LOD data"))?;
        data.proxy(plan.info(n).block).encode_into(out);
    }
    Ok(())
}

pub(super) fn count_treelet(plan: &TreePlan, t: usize, counts: &mut ChunkCounts) {
    let Some(treelet) = plan.treelets.get(t) else {
        return;
    };
    counts.treelets += 1;
    for &n in &treelet.nodes {
        match plan.info(n).role {
            Role::Basic => counts.basic_nodes += 1,
            Role::Leaf => counts.leaves += 1,
            Role::Lod => {
                counts.lod_nodes += 1;
                match plan.lod_data(n).and_then(|d| d.voxel) {
                    _ if !plan.kinds.voxel => {}
                    Some(Voxel::Six(..)) => counts.voxels_six += 1,
                    Some(Voxel::Single(..)) => counts.voxels_single += 1,
                    None => {}
                }
            }
        }
    }
}

/// The chunk's detached top treelet, as the top layout needs it.
fn upper_nodes(
    tree: &KdTree,
    plan: &TreePlan,
    leaves: &[Option<LeafRef>],
) -> Result<Vec<UpperNode>, OocError> {
    let nodes = plan
        .detached
        .and_then(|t| plan.treelets.get(t))
        .map(|t| t.nodes.clone())
        .ok_or(LayoutError::Internal("a chunk has no top treelet"))?;
    let index = |id: NodeId| nodes.iter().position(|&n| n == id);
    nodes
        .iter()
        .map(|&id| {
            let info = plan.info(id);
            Ok(match (info.role, tree.node(id)) {
                (Role::Leaf, _) => UpperNode::Leaf(
                    leaves
                        .get(id.index())
                        .copied()
                        .flatten()
                        .ok_or(LayoutError::Internal("a leaf has no triangle block"))?,
                ),
                (
                    Role::Basic,
                    Some(&KdNode::Inner {
                        axis,
                        split,
                        children,
                    }),
                ) => UpperNode::Basic {
                    axis,
                    split,
                    children: children.map(|c| c.and_then(index)),
                },
                (
                    Role::Lod,
                    Some(&KdNode::Inner {
                        axis,
                        split,
                        children,
                    }),
                ) => UpperNode::Frontier {
                    axis,
                    split,
                    present: children.map(|c| c.is_some()),
                    child_block: info.child_block,
                    child_treelet: info.child_treelet,
                    lod: *plan
                        .lod_data(id)
                        .ok_or(LayoutError::Internal("a LOD node has no LOD data"))?,
                    rlod: plan.rlod(id).copied(),
                },
                _ => {
                    return Err(
                        LayoutError::Internal("a node's role does not match its kind").into(),
                    )
                }
            })
        })
        .collect()
}

/// Traces the pending rays through this chunk: the part of each ray inside the chunk's cell,
/// against the chunk's triangles; a nearer hit replaces the one found so far.
pub(super) fn answer_rays(
    mesh: &Mesh,
    tree: &KdTree,
    cell: &Bounds,
    rays: &mut [&mut [PendingRay]],
) {
    let Some(root) = tree.root() else { return };
    let mut tracer = Tracer::new(mesh, tree);
    for r in rays.iter_mut().flat_map(|list| list.iter_mut()) {
        let Some((c0, c1)) = clip_to_box(&r.ray, cell) else {
            continue;
        };
        let (t0, t1) = (c0.max(0.0), c1.min(r.t1));
        if t0 > t1 + r.eps {
            continue;
        }
        let Some(hit) = tracer.first_hit(root, &r.ray, t0, t1, r.eps) else {
            continue;
        };
        if r.best.is_some_and(|(t, _)| t <= hit.t) {
            continue;
        }
        if let Some(s) = shade(mesh, &hit, r.ray.dir) {
            r.best = Some((hit.t, (s, parts::part_of(mesh, hit.triangle as usize))));
        }
    }
}
