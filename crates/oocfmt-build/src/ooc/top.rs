//! The top of an out-of-core tree: the median-split nodes above the chunks plus each chunk's
//! top treelet, assembled into one small tree that the ordinary planner lays out.
//!
//! The LOD nodes among the median-split nodes cannot be sampled against a subtree in memory.
//! Their rays are fixed in advance (the most rays on every face and direction), traced through
//! every chunk below them as each chunk is built, and the nearest hit of each is kept: the
//! same first-hit sampling an in-core node gets, done in pieces.

use std::collections::BTreeMap;

use super::chunk::{ChunkOut, PendingRay, UpperNode};
use super::split::{TopNode, TopTree};
use crate::kdtree::{KdNode, KdTree, NodeId};
use crate::layout::plan::is_lod_depth;
use crate::layout::triangles::LeafRef;
use crate::layout::LayoutError;
use crate::lod::{sample_cell, LodData};
use oocfmt::records::Rlod;
use oocfmt_meshio::mesh::Bounds;

/// A LOD node among the median-split nodes, with its rays.
pub struct TopLod {
    pub node: usize,
    pub cell: Bounds,
    pub rays: Vec<PendingRay>,
}

/// Finds the median-split nodes that are LOD nodes ([`is_lod_depth`]) and records the rays
/// that will sample them.
pub fn top_lod_nodes(top: &TopTree, bounds: Bounds, height: u8, threshold: f32) -> Vec<TopLod> {
    let mut out = Vec::new();
    let mut stack = vec![(0usize, bounds, 0u32)];
    while let Some((id, cell, depth)) = stack.pop() {
        let Some(&TopNode::Inner {
            axis,
            split,
            children,
        }) = top.nodes.get(id)
        else {
            continue;
        };
        if is_lod_depth(depth, height) {
            out.push(TopLod {
                node: id,
                cell,
                rays: record_rays(cell, threshold),
            });
        }
        let (lo, hi) = cell.split(usize::from(axis), split);
        for (c, cc) in children.into_iter().zip([lo, hi]) {
            if let Some(c) = c {
                stack.push((c, cc, depth + 1));
            }
        }
    }
    out.sort_by_key(|t| t.node);
    out
}

/// The rays that sample `cell`, in the order [`sample_cell`] casts them, not yet answered.
pub fn record_rays(cell: Bounds, threshold: f32) -> Vec<PendingRay> {
    let mut rays = Vec::new();
    sample_cell(cell, threshold, 0.0, 0, &mut |ray, t1, eps| {
        rays.push(PendingRay {
            ray: *ray,
            t1,
            eps,
            best: None,
        });
        None
    });
    rays
}

/// The LOD data of a top LOD node from its answered rays: its part the one most face rays
/// hit, as in core, or `fallback_part` when none hit.
pub fn finish_top_lod(lod: &TopLod, threshold: f32, area: f64, fallback_part: u32) -> LodData {
    let mut answers = lod.rays.iter();
    sample_cell(lod.cell, threshold, area, fallback_part, &mut |_, _, _| {
        answers.next().and_then(|r| r.best.map(|(_, s)| s))
    })
}

/// The top tree ready for the planner: a skeleton whose leaves carry no triangles (their
/// references are in `leaves`) and whose frontier LOD nodes have placeholder children.
pub struct Skeleton {
    pub tree: KdTree,
    pub lod: BTreeMap<NodeId, (LodData, Option<Rlod>)>,
    /// Frontier LOD nodes: (chunk, chunk-local child block, child treelet).
    pub frontier: BTreeMap<NodeId, (usize, u32, u32)>,
    /// Leaves of chunk top treelets: (chunk, reference with a chunk-local triangle block).
    pub leaves: BTreeMap<NodeId, (usize, LeafRef)>,
}

pub fn skeleton(
    top: &TopTree,
    chunks: &[ChunkOut],
    top_lod: &BTreeMap<usize, (LodData, Option<Rlod>)>,
    bounds: Bounds,
) -> Result<Skeleton, LayoutError> {
    let mut s = Builder {
        nodes: Vec::new(),
        lod: BTreeMap::new(),
        frontier: BTreeMap::new(),
        leaves: BTreeMap::new(),
        top,
        chunks,
        top_lod,
    };
    let root = s.top_node(0)?;
    Ok(Skeleton {
        tree: KdTree::skeleton(s.nodes, root, bounds),
        lod: s.lod,
        frontier: s.frontier,
        leaves: s.leaves,
    })
}

struct Builder<'a> {
    nodes: Vec<KdNode>,
    lod: BTreeMap<NodeId, (LodData, Option<Rlod>)>,
    frontier: BTreeMap<NodeId, (usize, u32, u32)>,
    leaves: BTreeMap<NodeId, (usize, LeafRef)>,
    top: &'a TopTree,
    chunks: &'a [ChunkOut],
    top_lod: &'a BTreeMap<usize, (LodData, Option<Rlod>)>,
}

impl Builder<'_> {
    fn push(&mut self, node: KdNode) -> Result<NodeId, LayoutError> {
        let id = u32::try_from(self.nodes.len()).map_err(|_| LayoutError::TooMany("nodes"))?;
        self.nodes.push(node);
        Ok(NodeId(id))
    }

    /// Adds a node and its subtree; the tree is shallow (median splits are at most 48 deep).
    fn top_node(&mut self, k: usize) -> Result<NodeId, LayoutError> {
        match self.top.nodes.get(k) {
            Some(&TopNode::Inner {
                axis,
                split,
                children,
            }) => {
                let id = self.push(KdNode::Leaf {
                    triangles: Vec::new(),
                })?;
                if let Some(d) = self.top_lod.get(&k) {
                    self.lod.insert(id, *d);
                }
                self.inner(id, axis, split, children, &mut |b, c| b.top_node(c))?;
                Ok(id)
            }
            Some(&TopNode::Chunk(c)) => self.upper(c, 0),
            None => Err(LayoutError::Internal("a top node is missing")),
        }
    }

    /// Makes node `id` an inner node whose children `add` places (`children` names them in
    /// whatever numbering `add` reads).
    fn inner(
        &mut self,
        id: NodeId,
        axis: u8,
        split: f32,
        children: [Option<usize>; 2],
        add: &mut dyn FnMut(&mut Self, usize) -> Result<NodeId, LayoutError>,
    ) -> Result<(), LayoutError> {
        let mut kids = [None, None];
        for (slot, c) in kids.iter_mut().zip(children) {
            if let Some(c) = c {
                *slot = Some(add(self, c)?);
            }
        }
        if let Some(slot) = self.nodes.get_mut(id.index()) {
            *slot = KdNode::Inner {
                axis,
                split,
                children: kids,
            };
        }
        Ok(())
    }

    fn upper(&mut self, chunk: usize, k: usize) -> Result<NodeId, LayoutError> {
        let node = self
            .chunks
            .get(chunk)
            .and_then(|c| c.upper.get(k))
            .cloned()
            .ok_or(LayoutError::Internal(
                "a chunk's top treelet is missing a node",
            ))?;
        let placeholder = || KdNode::Leaf {
            triangles: Vec::new(),
        };
        let id = self.push(placeholder())?;
        match node {
            UpperNode::Leaf(r) => {
                self.leaves.insert(id, (chunk, r));
            }
            UpperNode::Basic {
                axis,
                split,
                children,
            } => {
                self.inner(id, axis, split, children, &mut |b, c| b.upper(chunk, c))?;
            }
            UpperNode::Frontier {
                axis,
                split,
                present,
                child_block,
                child_treelet,
                lod,
                rlod,
            } => {
                // Placeholders only carry which children exist: the children live in the
                // chunk's own blocks.
                let children = present.map(|p| p.then_some(0));
                self.inner(id, axis, split, children, &mut |b, _| b.push(placeholder()))?;
                self.lod.insert(id, (lod, rlod));
                self.frontier
                    .insert(id, (chunk, child_block, child_treelet));
            }
        }
        Ok(id)
    }
}
