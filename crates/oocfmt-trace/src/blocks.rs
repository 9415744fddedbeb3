//! Blocks decoded once into the shapes the traversal reads: nodes with child indices instead
//! of byte offsets, voxels unpacked, triangles as three positions each. Decoding validates
//! every reference inside the block, so the traversal indexes with `get` and never fails on a
//! block that decoded.

use oocfmt::records::triangle::{oct_decode, Vertex, ATTR_COLOURS, ATTR_MATERIALS, ATTR_NORMALS};
use oocfmt::records::{
    lod_child_treelets, Node, Rlod, TreeletBlock, TriangleBlock, Voxel, NO_PROXY,
};
use oocfmt::{Block, Code, Error, Result};

/// No child in [`DNode::Inner`].
pub const NONE: u32 = u32::MAX;

#[derive(Clone, Copy, Debug)]
pub enum DNode {
    Inner {
        axis: u8,
        split: f32,
        /// Node indices in the same block, [`NONE`] for an empty child.
        left: u32,
        right: u32,
    },
    /// The LOD fields live in [`TreeletData::lods`], so every node fits 16 bytes: the inner
    /// nodes the traversal mostly reads pack four to a cache line.
    Lod {
        axis: u8,
        split: f32,
        /// Index in [`TreeletData::lods`].
        lod: u32,
    },
    Leaf {
        first: u16,
        count: u16,
        block: u32,
    },
}

/// The LOD representation a traversal stops on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LodKind {
    /// Áfra's voxels: the ray ends on the node's cell.
    Voxel,
    /// Yoon's R-LODs: the ray meets the node's plane, or skips the node.
    Rlod,
}

impl LodKind {
    pub fn name(self) -> &'static str {
        match self {
            LodKind::Voxel => "voxel",
            LodKind::Rlod => "rlod",
        }
    }
}

/// An R-LOD decoded for the traversal: the plane `normal · x = offset`, its colour, and how
/// far past the cell it still counts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    pub normal: [f32; 3],
    pub offset: f32,
    pub colour: [f32; 3],
    pub expansion: f32,
}

/// What a LOD node shows.
#[derive(Clone, Copy, Debug)]
pub enum Shown {
    Voxel(Voxel),
    Plane(Plane),
}

/// The rest of a LOD node, the part every ray crossing it reads: 16 bytes, four to a cache
/// line.
#[derive(Clone, Copy, Debug)]
pub struct Lod {
    /// The radius the LOD metric compares with t · C: the cell's enclosing radius for a voxel,
    /// the R-LOD's error radius (spec §6.4) for a plane.
    pub radius: f32,
    /// Treelet indices in `child_block`, [`NONE`] for an empty child.
    pub left: u32,
    pub right: u32,
    pub child_block: u32,
}

/// What a LOD node shows when a ray stops there: read only then, so kept apart from [`Lod`].
#[derive(Clone, Copy, Debug)]
pub struct LodLook {
    pub shown: Shown,
    pub proxy: Option<u32>,
}

/// A decoded treelet block.
#[derive(Debug)]
pub struct TreeletData {
    pub nodes: Vec<DNode>,
    pub lods: Vec<Lod>,
    /// Same index as `lods`.
    pub looks: Vec<LodLook>,
    /// Node index of each treelet's root.
    pub roots: Vec<u32>,
}

/// A thread's working arrays for decoding blocks, kept between blocks: a fetcher decodes block
/// after block, and fresh pages are dear (the kernel zeroes each on first touch; page faults
/// were half of a fetcher's profile in a cold walkthrough, README). Outside the cache budget:
/// for treelet blocks 44 bytes per 8-byte node unit of the largest block decoded (352 KiB per
/// thread for 64 KiB blocks), for triangle blocks 24 bytes per vertex.
#[derive(Default)]
struct Scratch {
    index: Vec<u32>,
    order: Vec<(usize, Node)>,
    vertices: Vec<Vertex>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::default();
}

impl TreeletData {
    /// Decodes for voxels when the block's file has them, else for R-LODs.
    pub fn decode(block: &Block) -> Result<TreeletData> {
        let kind = if block.lod.voxel {
            LodKind::Voxel
        } else {
            LodKind::Rlod
        };
        Self::decode_as(block, kind)
    }

    /// Decodes the LOD nodes' `kind` (an error when the file lacks it).
    pub fn decode_as(block: &Block, kind: LodKind) -> Result<TreeletData> {
        SCRATCH.with(|scratch| match scratch.try_borrow_mut() {
            Ok(mut s) => {
                let Scratch { index, order, .. } = &mut *s;
                Self::decode_with(block, kind, index, order)
            }
            // Only a decode inside a decode would find it taken; none does.
            Err(_) => Self::decode_with(block, kind, &mut Vec::new(), &mut Vec::new()),
        })
    }

    fn decode_with(
        block: &Block,
        kind: LodKind,
        index: &mut Vec<u32>,
        order: &mut Vec<(usize, Node)>,
    ) -> Result<TreeletData> {
        let tb = block.treelets()?;
        let slots = tb.node_area().len() / 8;
        // Node index by 8-byte unit; `walk` checks the preorder layout, so every child offset
        // lands on a node of the same treelet.
        index.clear();
        index.resize(slots, NONE);
        order.clear();
        let mut lod_nodes = 0;
        tb.walk(|_, pos, node| {
            if let Some(slot) = index.get_mut(pos / 8) {
                *slot = order.len() as u32;
            }
            lod_nodes += usize::from(matches!(node, Node::Lod { .. }));
            order.push((pos, *node));
            Ok(())
        })
        .map_err(|e| e.in_block(block.id))?;
        let child = |pos: usize, units: u16| -> Result<u32> {
            if units == 0 {
                return Ok(NONE);
            }
            let at = TreeletBlock::child_pos(pos, units) / 8;
            match index.get(at) {
                Some(&i) if i != NONE => Ok(i),
                _ => Err(Error::malformed(
                    Code::NodeChild,
                    format!("node at {pos}: child at unit {at} is not a node"),
                )
                .in_block(block.id)),
            }
        };
        // Sized exactly: these stay in the cache, and growing them by doubling would touch
        // fresh pages for every copy.
        let mut nodes = Vec::with_capacity(order.len());
        let mut lods = Vec::with_capacity(lod_nodes);
        let mut looks = Vec::with_capacity(lod_nodes);
        for &(pos, node) in order.iter() {
            nodes.push(match node {
                Node::Basic {
                    axis,
                    split,
                    left,
                    right,
                } => DNode::Inner {
                    axis,
                    split,
                    left: child(pos, left)?,
                    right: child(pos, right)?,
                },
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
                    let [left, right] =
                        lod_child_treelets(child_treelet, [left_present, right_present])
                            .map(|t| t.unwrap_or(NONE));
                    let in_block = |e: Error| e.at(pos as u64).in_block(block.id);
                    let (radius, shown) = match kind {
                        LodKind::Voxel => (
                            radius,
                            Shown::Voxel(tb.voxel(voxel_offset).map_err(in_block)?),
                        ),
                        LodKind::Rlod => {
                            let r: Rlod = tb.rlod(voxel_offset).map_err(in_block)?;
                            let plane = Plane {
                                normal: r.normal,
                                offset: r.offset,
                                colour: r.colour_f32(),
                                expansion: r.expansion(radius),
                            };
                            (r.error_radius(radius), Shown::Plane(plane))
                        }
                    };
                    lods.push(Lod {
                        radius,
                        left,
                        right,
                        child_block,
                    });
                    looks.push(LodLook {
                        shown,
                        proxy: (proxy != NO_PROXY).then_some(proxy),
                    });
                    DNode::Lod {
                        axis,
                        split,
                        lod: (lods.len() - 1) as u32,
                    }
                }
                Node::Leaf {
                    count,
                    first,
                    block,
                } => DNode::Leaf {
                    first,
                    count,
                    block,
                },
            });
        }
        let roots = (0..tb.treelet_count())
            .map(|t| {
                let span = tb.treelet_span(t)?;
                Ok(index.get(span.start / 8).copied().unwrap_or(NONE))
            })
            .collect::<Result<Vec<_>>>()
            .map_err(|e| e.in_block(block.id))?;
        Ok(TreeletData {
            nodes,
            lods,
            looks,
            roots,
        })
    }

    /// Bytes this block holds in memory, for the cache budget.
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.nodes.capacity() * std::mem::size_of::<DNode>()
            + self.lods.capacity() * std::mem::size_of::<Lod>()
            + self.looks.capacity() * std::mem::size_of::<LodLook>()
            + self.roots.capacity() * 4
    }
}

/// A decoded triangle block.
#[derive(Debug)]
pub struct TriangleData {
    /// Triangle index by list entry, each < the triangle count.
    pub list: Vec<u16>,
    pub positions: Vec<[[f32; 3]; 3]>,
    /// Per corner, when the scene has vertex normals.
    pub normals: Option<Vec<[[f32; 3]; 3]>>,
    /// Per corner, linear RGB in 0..=1, when the scene has vertex colours.
    pub colours: Option<Vec<[[f32; 3]; 3]>>,
    pub materials: Option<Vec<u16>>,
}

impl TriangleData {
    pub fn decode(block: &Block, attrs: u16) -> Result<TriangleData> {
        SCRATCH.with(|scratch| match scratch.try_borrow_mut() {
            Ok(mut s) => Self::decode_with(block, attrs, &mut s.vertices),
            // Only a decode inside a decode would find it taken; none does.
            Err(_) => Self::decode_with(block, attrs, &mut Vec::new()),
        })
    }

    /// One pass over each section with the bulk readers, after `check_contents` has checked
    /// every index (the list entries among them) and position. A fetcher decodes block after
    /// block, and on the 100M-triangle Mandelbulb this takes 0.55 of the time a `Result` per
    /// field read took (README).
    fn decode_with(block: &Block, attrs: u16, vertices: &mut Vec<Vertex>) -> Result<TriangleData> {
        let tb: TriangleBlock<'_> = block.triangles(attrs)?;
        tb.check_contents().map_err(|e| e.in_block(block.id))?;
        vertices.clear();
        vertices.extend(tb.all_vertices());
        // Sized exactly: these stay in the cache, and growing them by doubling would touch
        // fresh pages for every copy.
        let mut list = Vec::with_capacity(tb.list_count());
        list.extend(tb.list_entries());
        let n = tb.triangle_count();
        let mut positions = Vec::with_capacity(n);
        let has = |attr: u16| tb.attributes() & attr != 0;
        let mut normals = has(ATTR_NORMALS).then(|| Vec::with_capacity(n));
        let mut colours = has(ATTR_COLOURS).then(|| Vec::with_capacity(n));
        let mut materials = has(ATTR_MATERIALS).then(|| Vec::with_capacity(n));
        for (i, t) in tb.all_triangles().enumerate() {
            let corner = |k: usize| {
                vertices.get(usize::from(t.v[k])).ok_or_else(|| {
                    Error::malformed(
                        Code::TriangleIndex,
                        format!("triangle {i}: vertex {} of {}", t.v[k], vertices.len()),
                    )
                    .in_block(block.id)
                })
            };
            let vs = [corner(0)?, corner(1)?, corner(2)?];
            positions.push(vs.map(|v| v.position));
            if let Some(ns) = normals.as_mut() {
                ns.push(vs.map(|v| v.normal.map(oct_decode).unwrap_or([0.0, 0.0, 1.0])));
            }
            if let Some(cs) = colours.as_mut() {
                cs.push(vs.map(|v| {
                    let c = v.colour.unwrap_or([255; 4]);
                    [c[0], c[1], c[2]].map(|x| f32::from(x) / 255.0)
                }));
            }
            if let (Some(ms), Some(m)) = (materials.as_mut(), t.material) {
                ms.push(m);
            }
        }
        Ok(TriangleData {
            list,
            positions,
            normals,
            colours,
            materials,
        })
    }

    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.list.capacity() * 2
            + self.positions.capacity() * 36
            + self.normals.as_ref().map_or(0, |v| v.capacity() * 36)
            + self.colours.as_ref().map_or(0, |v| v.capacity() * 36)
            + self.materials.as_ref().map_or(0, |v| v.capacity() * 2)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_node_and_the_hot_part_of_a_lod_node_are_16_bytes() {
        assert_eq!(std::mem::size_of::<super::DNode>(), 16);
        assert_eq!(std::mem::size_of::<super::Lod>(), 16);
    }
}
