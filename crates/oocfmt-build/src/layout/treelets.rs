//! Encodes planned treelet blocks: each treelet's nodes in preorder, LOD voxels in the order
//! their nodes are written.

use oocfmt::records::{Node, TreeletBlockWriter};

use super::plan::{NodeInfo, PlannedBlock, Role, TreePlan, Treelet};
use super::triangles::LeafRef;
use super::LayoutError;
use crate::kdtree::{KdNode, KdTree, NodeId};

/// Encodes one planned treelet block. `leaves` are the triangle references by node id, and
/// `first_triangle_block` the block id of triangle block 0.
pub(crate) fn encode_treelets(
    block: &PlannedBlock,
    tree: &KdTree,
    plan: &TreePlan,
    leaves: &[Option<LeafRef>],
    first_triangle_block: u32,
) -> Result<Vec<u8>, LayoutError> {
    let mut w = TreeletBlockWriter::new();
    for &t in &block.treelets {
        let treelet = plan
            .treelets
            .get(t)
            .ok_or(LayoutError::Internal("a planned treelet is missing"))?;
        let mut enc = Encoder {
            w,
            tree,
            plan,
            treelet,
            at: 0,
            leaves,
            first_triangle_block,
        };
        enc.w.begin_treelet();
        enc.node(treelet.root)?;
        w = enc.w;
    }
    Ok(w.finish())
}

struct Encoder<'a> {
    w: TreeletBlockWriter,
    tree: &'a KdTree,
    plan: &'a TreePlan,
    /// The treelet being written, and the index in its preorder `nodes` of the next node.
    treelet: &'a Treelet,
    at: usize,
    leaves: &'a [Option<LeafRef>],
    first_triangle_block: u32,
}

impl Encoder<'_> {
    /// Writes `id` and, for a basic node, its subtree; recursion is bounded by the treelet
    /// height.
    fn node(&mut self, id: NodeId) -> Result<(), LayoutError> {
        // Nodes are written in the preorder the plan listed them in, so a basic node's low
        // child is the next one and its span is known.
        let k = self.at;
        if self.treelet.nodes.get(k) != Some(&id) {
            return Err(LayoutError::Internal(
                "a treelet's nodes are written out of their planned order",
            ));
        }
        self.at += 1;
        let info = self.plan.info(id);
        match (info.role, self.tree.node(id)) {
            (Role::Leaf, Some(KdNode::Leaf { .. })) => self.leaf(id),
            (
                Role::Lod,
                Some(&KdNode::Inner {
                    axis,
                    split,
                    children,
                }),
            ) => self.lod(id, &info, (axis, split), children),
            (
                Role::Basic,
                Some(&KdNode::Inner {
                    axis,
                    split,
                    children,
                }),
            ) => self.basic(k, (axis, split), children),
            _ => Err(LayoutError::Internal(
                "a node's role does not match its kind",
            )),
        }
    }

    /// Writes leaf `id`, pointing at its triangles.
    fn leaf(&mut self, id: NodeId) -> Result<(), LayoutError> {
        let leaf = self
            .leaves
            .get(id.index())
            .copied()
            .flatten()
            .ok_or(LayoutError::Internal("a leaf has no triangle block"))?;
        let block = self
            .first_triangle_block
            .checked_add(leaf.block)
            .ok_or(LayoutError::TooMany("blocks"))?;
        self.w.push_node(&Node::Leaf {
            count: leaf.count,
            first: leaf.first,
            block,
        });
        Ok(())
    }

    /// Writes LOD node `id` (split `(axis, split)`, children `[l, r]`) after its LOD entry;
    /// its children are in the child treelets the plan gave it.
    fn lod(
        &mut self,
        id: NodeId,
        info: &NodeInfo,
        (axis, split): (u8, f32),
        [l, r]: [Option<NodeId>; 2],
    ) -> Result<(), LayoutError> {
        let data = self
            .plan
            .lod_data(id)
            .ok_or(LayoutError::Internal("a LOD node has no LOD data"))?;
        let radius = info
            .cell
            .half_diagonal_up()
            .ok_or(LayoutError::SceneTooLarge)?;
        // The LOD entry (spec §3): the voxel, then the R-LOD, as the file has them, then the
        // part word.
        let voxel_at = match (self.plan.kinds.voxel, &data.voxel) {
            (false, _) => None,
            (true, Some(v)) => Some(self.w.push_voxel(v, self.plan.kinds.filtered)),
            (true, None) => return Err(LayoutError::Internal("a LOD node has no voxel")),
        };
        let rlod_at = match self.plan.kinds.rlod {
            true => Some(
                self.w.push_rlod(
                    self.plan
                        .rlod(id)
                        .ok_or(LayoutError::Internal("a LOD node has no R-LOD"))?,
                    self.plan.kinds.filtered,
                ),
            ),
            false => None,
        };
        // The part word closes the entry in a file with `PART_IDS`.
        if self.plan.kinds.parts {
            self.w.push_lod_part(data.part);
        }
        let voxel_offset = voxel_at
            .or(rlod_at)
            .ok_or(LayoutError::Internal("a LOD node has an empty LOD entry"))?;
        self.w.push_node(&Node::Lod {
            axis,
            split,
            radius,
            left_present: l.is_some(),
            right_present: r.is_some(),
            child_treelet: info.child_treelet,
            child_block: info.child_block,
            voxel_offset,
            proxy: info.proxy,
        });
        Ok(())
    }

    /// Writes the basic node at index `k` of the treelet's preorder (split `(axis, split)`,
    /// children `[l, r]`), then its children's subtrees at the offsets its spans give.
    fn basic(
        &mut self,
        k: usize,
        (axis, split): (u8, f32),
        [l, r]: [Option<NodeId>; 2],
    ) -> Result<(), LayoutError> {
        let pos = self.w.next_node_pos();
        let left_at = pos + oocfmt::records::NODE_BASIC_LEN;
        let left_span = match l {
            Some(_) => self
                .treelet
                .spans
                .get(k + 1)
                .copied()
                .ok_or(LayoutError::Internal("a child is outside its treelet"))?,
            None => 0,
        };
        let right_at = left_at + left_span;
        let units = |present: bool, at: usize| -> Result<u16, LayoutError> {
            if present {
                TreeletBlockWriter::units_between(pos, at)
                    .map_err(|_| LayoutError::TreeletSpan { bytes: at - pos })
            } else {
                Ok(0)
            }
        };
        let left = units(l.is_some(), left_at)?;
        let right = units(r.is_some(), right_at)?;
        self.w.push_node(&Node::Basic {
            axis,
            split,
            left,
            right,
        });
        for (child, at) in [(l, left_at), (r, right_at)] {
            if let Some(c) = child {
                if self.w.next_node_pos() != at {
                    return Err(LayoutError::Internal(
                        "a child landed away from its planned offset",
                    ));
                }
                self.node(c)?;
            }
        }
        Ok(())
    }
}
