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

/// What every chunk of one build is built with.
pub struct ChunkBuilder<'a> {
    pub facts: &'a SceneFacts,
    pub kd: &'a KdBuildOptions,
    pub layout: &'a LayoutOptions,
    /// Where the chunks' runs are accounted (reading one deletes it).
    pub disk: &'a Arc<SpillDisk>,
}

/// The nearest shaded hit in one chunk of each ray of one top LOD node.
pub type Hits = Vec<Option<(f64, Seen)>>;

/// A chunk built in memory and waiting for its turn: chunks are built several at once, but
/// spilled in chunk order, because the proxy ids and the spill streams number them in that
/// order. Everything is encoded but the treelet blocks, which hold proxy ids.
pub struct BuiltChunk {
    tree: KdTree,
    plan: TreePlan,
    leaves: Vec<Option<LeafRef>>,
    /// Raw triangle blocks with their triangle counts.
    triangles: Vec<(u32, Vec<u8>)>,
    /// Everything but the blocks, which [`BuiltChunk::spill`] adds.
    out: ChunkOut,
    /// For each list of rays given to [`ChunkBuilder::build`], its hits in this chunk.
    hits: Vec<Hits>,
}

impl ChunkBuilder<'_> {
    /// Builds chunk `chunk` in memory with proxy ids from 0: its nearest hits of the pending
    /// `rays` of the top LOD nodes above it, and its surface measured against their R-LOD
    /// `planes` (as fitted; the pieces are widened into them in chunk order). Reads nothing
    /// another chunk writes, so chunks can be built at once.
    pub fn build(
        &self,
        chunk: &Chunk,
        rays: &[&[PendingRay]],
        planes: &[(usize, PlaneFit)],
    ) -> Result<BuiltChunk, OocError> {
        let (mesh, primary) = load_mesh(chunk, self.facts, self.disk)?;
        let plane_pieces = plane_pieces(&mesh, chunk, planes);
        let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
        let kd = self.kd;
        let nodes = build_cell(&mesh, all, chunk.cell, chunk.depth + 1, kd)?;
        let tree = KdTree::from_parts(&mesh, nodes, Some(NodeId(0)), chunk.cell, kd.params())?;
        let hits = answer_rays(&mesh, &tree, &chunk.cell, rays);

        let plan = self.plan(&mesh, &tree, chunk)?;
        let vertices = VertexTable::new(&mesh);
        let stored_elsewhere: Vec<bool> = primary.iter().map(|p| !p).collect();
        let (attrs, block_size) = (self.facts.attrs, self.facts.block_size);
        let tri_plan =
            plan_triangles_with(&mesh, &tree, &vertices, attrs, block_size, stored_elsewhere)?;

        let mut counts = ChunkCounts {
            depth: chunk.depth + plan.depth,
            ..ChunkCounts::default()
        };
        for b in &plan.blocks {
            for &t in &b.treelets {
                count_treelet(&plan, t, &mut counts);
            }
        }
        let mut triangles = Vec::with_capacity(tri_plan.blocks.len());
        for b in &tri_plan.blocks {
            let (raw, c) = encode_triangles(b, &mesh, &vertices, attrs)?;
            let n = u32::try_from(c.triangles).map_err(|_| LayoutError::TooMany("triangles"))?;
            triangles.push((n, raw));
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
        let out = ChunkOut {
            upper: upper_nodes(&tree, &plan, &tri_plan.leaves)?,
            treelet_blocks: Vec::new(),
            triangle_blocks: Vec::new(),
            proxies,
            counts,
            area,
            plane_pieces,
            parts: part_stats,
        };
        Ok(BuiltChunk {
            tree,
            plan,
            leaves: tri_plan.leaves,
            triangles,
            out,
            hits,
        })
    }

    /// Plans the chunk's treelet blocks: its top treelet detached for the top layout, its LOD
    /// levels numbered on from the depth of its root, its proxies from 0.
    fn plan(&self, mesh: &Mesh, tree: &KdTree, chunk: &Chunk) -> Result<TreePlan, LayoutError> {
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
                proxy_base: 0,
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

impl BuiltChunk {
    /// Spills the chunk's blocks, its proxy ids counted from `proxy_base` (the proxies of the
    /// chunks before it), and gives `rays` its hits where they are nearer than the ones found
    /// so far (an earlier chunk's on a tie). `rays` are the lists given to the build.
    pub fn spill(
        self,
        spill: &mut BlockSpill,
        proxy_base: u32,
        rays: &mut [&mut [PendingRay]],
    ) -> Result<ChunkOut, OocError> {
        let BuiltChunk {
            tree,
            mut plan,
            leaves,
            triangles,
            mut out,
            hits,
        } = self;
        plan.shift_proxies(proxy_base)?;
        out.treelet_blocks.reserve(plan.blocks.len());
        for b in &plan.blocks {
            let raw = encode_treelets(b, &tree, &plan, &leaves, 0)?;
            let n =
                u32::try_from(b.treelets.len()).map_err(|_| LayoutError::TooMany("treelets"))?;
            out.treelet_blocks
                .push(spill.push(BlockKind::Treelet, b.level, n, &raw)?);
        }
        out.triangle_blocks.reserve(triangles.len());
        for (n, raw) in &triangles {
            out.triangle_blocks
                .push(spill.push(BlockKind::Triangle, 0, *n, raw)?);
        }
        for (list, found) in rays.iter_mut().zip(&hits) {
            take_nearer(list, found);
        }
        Ok(out)
    }
}

/// Gives each ray its hit in one more chunk where that is nearer than the one found so far
/// (the earlier chunk's on a tie).
pub(super) fn take_nearer(rays: &mut [PendingRay], hits: &[Option<(f64, Seen)>]) {
    for (r, hit) in rays.iter_mut().zip(hits) {
        match (r.best, hit) {
            (_, None) => {}
            (Some((t, _)), Some((h, _))) if t <= *h => {}
            (_, Some(h)) => r.best = Some(*h),
        }
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
/// against the chunk's triangles. Returns, list by list, each ray's nearest shaded hit here.
pub(super) fn answer_rays(
    mesh: &Mesh,
    tree: &KdTree,
    cell: &Bounds,
    rays: &[&[PendingRay]],
) -> Vec<Hits> {
    let Some(root) = tree.root() else {
        return rays.iter().map(|list| vec![None; list.len()]).collect();
    };
    let mut tracer = Tracer::new(mesh, tree);
    let mut answer = |r: &PendingRay| {
        let (c0, c1) = clip_to_box(&r.ray, cell)?;
        let (t0, t1) = (c0.max(0.0), c1.min(r.t1));
        if t0 > t1 + r.eps {
            return None;
        }
        let hit = tracer.first_hit(root, &r.ray, t0, t1, r.eps)?;
        let s = shade(mesh, &hit, r.ray.dir)?;
        Some((hit.t, (s, parts::part_of(mesh, hit.triangle as usize))))
    };
    rays.iter()
        .map(|list| list.iter().map(&mut answer).collect())
        .collect()
}
