//! kd-tree nodes inside a treelet (spec §6.3): basic 8 bytes, LOD 24 bytes, leaf 8 bytes.
//!
//! Word 0, bits 0–1: type. Basic: axis 2–3, empty flags 4–5, child offsets 8–19 / 20–31
//! (8-byte units from this node), split f32. LOD: axis, empty flags, child treelet 8–31, split,
//! radius, child block, voxel offset, proxy id. Leaf: count 4–15, first list entry 16–31,
//! triangle block id.

use crate::bytes::{f32_at, u32_at, PutLe};
use crate::error::{bad, Code, Result};

/// Bytes of a basic (inner) node.
pub const NODE_BASIC_LEN: usize = 8;
/// Bytes of a LOD node.
pub const NODE_LOD_LEN: usize = 24;
/// Bytes of a leaf node.
pub const NODE_LEAF_LEN: usize = 8;
/// The proxy id of a LOD node without a proxy.
pub const NO_PROXY: u32 = u32::MAX;
/// The largest child offset, in 8-byte units (12 bits).
pub const MAX_CHILD_UNITS: u16 = 0xfff;
/// The largest leaf triangle count (12 bits).
pub const MAX_LEAF_TRIANGLES: u16 = 0xfff;
/// The most node levels on a root-to-leaf path (spec §12): a traversal stack of this many
/// entries never overflows.
pub const MAX_TREE_DEPTH: u32 = 128;
/// The largest child treelet index (24 bits).
pub const MAX_CHILD_TREELET: u32 = 0x00ff_ffff;

const TYPE_BASIC: u32 = 0;
const TYPE_LOD: u32 = 1;
const TYPE_LEAF: u32 = 2;

/// One decoded node. Child offsets are as stored: 8-byte units from this node, 0 = empty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Node {
    /// An inner node whose children lie in the same treelet.
    Basic {
        /// Split axis: 0 x, 1 y, 2 z.
        axis: u8,
        /// Position of the split plane on `axis`, in stored coordinates.
        split: f32,
        /// Offset of the left child in 8-byte units from this node, at most
        /// [`MAX_CHILD_UNITS`]; 0 when the left child is empty.
        left: u16,
        /// Offset of the right child, as `left`; above `left` when both are present.
        right: u16,
    },
    /// An inner node at the bottom of a treelet: its children are treelet roots in a block of
    /// the next LOD level, and it carries a LOD entry (voxel and/or R-LOD) and maybe a proxy.
    Lod {
        /// Split axis: 0 x, 1 y, 2 z.
        axis: u8,
        /// Position of the split plane on `axis`, in stored coordinates.
        split: f32,
        /// Radius of the sphere enclosing the node's cell (half its diagonal, rounded up to
        /// the next f32); never larger than an ancestor LOD node's.
        radius: f32,
        /// Whether the left child exists.
        left_present: bool,
        /// Whether the right child exists.
        right_present: bool,
        /// Index of the first present child's treelet in `child_block`.
        child_treelet: u32,
        /// Id of the treelet block (of the next level) holding the children's treelets.
        child_block: u32,
        /// Byte offset of the node's LOD entry in its block's LOD area, a multiple of 4
        /// (called the voxel offset in 1.0).
        voxel_offset: u32,
        /// Proxy id standing for the node's subtree, or [`NO_PROXY`].
        proxy: u32,
    },
    /// A leaf: a run of entries in a triangle block's list section.
    Leaf {
        /// Number of triangles, 1 ..= [`MAX_LEAF_TRIANGLES`].
        count: u16,
        /// First entry of the run in the triangle block's list section.
        first: u16,
        /// Id of the triangle block holding the triangles.
        block: u32,
    },
}

/// The treelets of a LOD node's children in its child block, left and right (spec §6.3): the
/// stored index names the first present child's treelet, and with two children the right one
/// is the next. `None` for an empty child.
pub fn lod_child_treelets(first: u32, present: [bool; 2]) -> [Option<u32>; 2] {
    let right = first.saturating_add(u32::from(present[0]));
    [present[0].then_some(first), present[1].then_some(right)]
}

impl Node {
    /// Bytes the node takes in the node area: [`NODE_BASIC_LEN`], [`NODE_LOD_LEN`] or
    /// [`NODE_LEAF_LEN`].
    pub fn byte_len(&self) -> usize {
        match self {
            Node::Basic { .. } => NODE_BASIC_LEN,
            Node::Lod { .. } => NODE_LOD_LEN,
            Node::Leaf { .. } => NODE_LEAF_LEN,
        }
    }

    /// Appends the node's bytes. Out-of-range fields are the caller's bug; they are masked so
    /// the output always decodes, and [`Node::check`] on the decoded value reports them.
    pub fn encode_into(&self, v: &mut Vec<u8>) {
        match *self {
            Node::Basic {
                axis,
                split,
                left,
                right,
            } => {
                let w = TYPE_BASIC
                    | (u32::from(axis & 3) << 2)
                    | (u32::from(left == 0) << 4)
                    | (u32::from(right == 0) << 5)
                    | (u32::from(left & MAX_CHILD_UNITS) << 8)
                    | (u32::from(right & MAX_CHILD_UNITS) << 20);
                v.put_u32(w);
                v.put_f32(split);
            }
            Node::Lod {
                axis,
                split,
                radius,
                left_present,
                right_present,
                child_treelet,
                child_block,
                voxel_offset,
                proxy,
            } => {
                let w = TYPE_LOD
                    | (u32::from(axis & 3) << 2)
                    | (u32::from(!left_present) << 4)
                    | (u32::from(!right_present) << 5)
                    | ((child_treelet & MAX_CHILD_TREELET) << 8);
                v.put_u32(w);
                v.put_f32(split);
                v.put_f32(radius);
                v.put_u32(child_block);
                v.put_u32(voxel_offset);
                v.put_u32(proxy);
            }
            Node::Leaf {
                count,
                first,
                block,
            } => {
                let w = TYPE_LEAF
                    | (u32::from(count & MAX_LEAF_TRIANGLES) << 4)
                    | (u32::from(first) << 16);
                v.put_u32(w);
                v.put_u32(block);
            }
        }
    }

    /// Decodes the node at byte `pos` of a node area, checking every field it holds alone.
    #[inline]
    pub fn decode(area: &[u8], pos: usize) -> Result<Node> {
        let w = u32_at(area, pos, Code::NodeChild)?;
        let axis = ((w >> 2) & 3) as u8;
        let node = match w & 3 {
            TYPE_BASIC => {
                let left = ((w >> 8) & 0xfff) as u16;
                let right = ((w >> 20) & 0xfff) as u16;
                if (w >> 4) & 1 != u32::from(left == 0) || (w >> 5) & 1 != u32::from(right == 0) {
                    return bad(
                        Code::NodeChild,
                        format!("node at {pos}: empty flags disagree with child offsets"),
                    );
                }
                if w & 0xc0 != 0 {
                    return bad(Code::NodeField, format!("node at {pos}: reserved bits set"));
                }
                Node::Basic {
                    axis,
                    split: f32_at(area, pos + 4, Code::NodeChild)?,
                    left,
                    right,
                }
            }
            TYPE_LOD => {
                if w & 0xc0 != 0 {
                    return bad(Code::NodeField, format!("node at {pos}: reserved bits set"));
                }
                let at = |k: usize| u32_at(area, pos + k, Code::NodeChild);
                Node::Lod {
                    axis,
                    split: f32_at(area, pos + 4, Code::NodeChild)?,
                    radius: f32_at(area, pos + 8, Code::NodeChild)?,
                    left_present: (w >> 4) & 1 == 0,
                    right_present: (w >> 5) & 1 == 0,
                    child_treelet: w >> 8,
                    child_block: at(12)?,
                    voxel_offset: at(16)?,
                    proxy: at(20)?,
                }
            }
            TYPE_LEAF => {
                if w & 0xc != 0 {
                    return bad(Code::NodeField, format!("leaf at {pos}: reserved bits set"));
                }
                Node::Leaf {
                    count: ((w >> 4) & 0xfff) as u16,
                    first: (w >> 16) as u16,
                    block: u32_at(area, pos + 4, Code::NodeChild)?,
                }
            }
            _ => return bad(Code::NodeType, format!("node at {pos}: type 3 is invalid")),
        };
        node.check().map_err(|e| e.at(pos as u64))?;
        Ok(node)
    }

    /// Field rules that need no context: axis, finiteness, non-empty.
    #[inline]
    pub fn check(&self) -> Result<()> {
        let (axis, split) = match *self {
            Node::Basic {
                axis,
                split,
                left,
                right,
            } => {
                if left == 0 && right == 0 {
                    return bad(Code::NodeField, "inner node with two empty children");
                }
                (axis, split)
            }
            Node::Lod {
                axis,
                split,
                radius,
                left_present,
                right_present,
                ..
            } => {
                if !left_present && !right_present {
                    return bad(Code::NodeField, "LOD node with two empty children");
                }
                if !(radius.is_finite() && radius >= 0.0) {
                    return bad(
                        Code::NodeField,
                        format!("LOD radius {radius} is not a finite non-negative number"),
                    );
                }
                (axis, split)
            }
            Node::Leaf { count, .. } => {
                if count == 0 {
                    return bad(Code::NodeField, "leaf with zero triangles");
                }
                return Ok(());
            }
        };
        if axis > 2 {
            return bad(Code::NodeField, "split axis 3");
        }
        if !split.is_finite() {
            return bad(
                Code::NodeField,
                format!("split position {split} is not finite"),
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_node_kind_round_trips() {
        let nodes = [
            Node::Basic {
                axis: 2,
                split: -1.5,
                left: 1,
                right: 0xfff,
            },
            Node::Basic {
                axis: 0,
                split: 0.0,
                left: 0,
                right: 3,
            },
            Node::Lod {
                axis: 1,
                split: 2.0,
                radius: 0.25,
                left_present: true,
                right_present: false,
                child_treelet: MAX_CHILD_TREELET,
                child_block: 9,
                voxel_offset: 40,
                proxy: NO_PROXY,
            },
            Node::Leaf {
                count: 4095,
                first: 65535,
                block: u32::MAX,
            },
        ];
        for n in nodes {
            let mut v = Vec::new();
            n.encode_into(&mut v);
            assert_eq!(v.len(), n.byte_len());
            assert_eq!(Node::decode(&v, 0).ok(), Some(n));
        }
    }

    #[test]
    fn bad_fields_are_refused() {
        let mut v = Vec::new();
        Node::Basic {
            axis: 3,
            split: 1.0,
            left: 1,
            right: 2,
        }
        .encode_into(&mut v);
        assert_eq!(
            Node::decode(&v, 0).err().map(|e| e.code()),
            Some(Code::NodeField)
        );
        let v = 3u32.to_le_bytes().repeat(2);
        assert_eq!(
            Node::decode(&v, 0).err().map(|e| e.code()),
            Some(Code::NodeType)
        );
        assert!(Node::decode(&[0, 0, 0], 0).is_err());
    }
}
