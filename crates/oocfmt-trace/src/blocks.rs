//! Blocks decoded once into the shapes the traversal reads: nodes with child indices instead
//! of byte offsets, voxels unpacked, triangles as three positions each. Decoding validates
//! every reference inside the block, so the traversal indexes with `get` and never fails on a
//! block that decoded.

use oocfmt::records::triangle::{
    oct_decode, Vertex, ATTR_COLOURS, ATTR_MATERIALS, ATTR_NORMALS, ATTR_PART_WIDTH,
    ATTR_PART_WIDTH_SHIFT,
};
use oocfmt::records::{
    lod_child_treelets, Footprint, LodEntry, Node, Sample, TreeletBlock, TriangleBlock, Voxel,
    NODE_BASIC_LEN, NO_PROXY,
};
use oocfmt::{Block, BlockEntry, BlockKind, Code, Error, Result};

/// No child in [`NodeView::Inner`], no treelet in [`Lod`].
pub const NONE: u32 = u32::MAX;

/// A decoded node in 8 bytes, so that eight share a cache line and a treelet block holds
/// about half the memory the 16-byte nodes took (every byte a fetcher writes is a fresh page
/// to fault in: README). Read through [`TreeletData::node`].
///
/// `split` holds the split plane's bits, or a leaf's triangle block. `word`: bits 0–1 the
/// axis, 3 for a leaf; for an inner node bit 2 clear, bit 3 set when the left child is present
/// (it is the next node, [`TreeletBlock::walk_lods`]), bits 4–31 the right child's index + 1
/// (0: none); for a LOD node bit 2 set and bits 3–31 the index in [`TreeletData::lods`]; for a
/// leaf bits 2–17 its first list entry and bits 18–31 its count, or [`SPILLED`] there and the
/// leaf in [`TreeletData::spilled`] at the index `split` holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct DNode {
    split: u32,
    word: u32,
}

const LEAF_AXIS: u32 = 3;
const LOD_BIT: u32 = 1 << 2;
const LEFT_BIT: u32 = 1 << 3;
/// A leaf's count field saying that the leaf lies in [`TreeletData::spilled`]: the format
/// allows up to 65535 list entries, the node holds up to 16382.
const SPILLED: u32 = (1 << 14) - 1;

impl DNode {
    /// An inner node; its right child is set later ([`DNode::set_right`]).
    fn inner(axis: u8, split: f32, has_left: bool) -> DNode {
        DNode {
            split: split.to_bits(),
            word: u32::from(axis & 3) | if has_left { LEFT_BIT } else { 0 },
        }
    }

    fn set_right(&mut self, right: u32) {
        self.word = self.word & 0xF | (right + 1) << 4;
    }

    fn lod(axis: u8, split: f32, lod: u32) -> DNode {
        DNode {
            split: split.to_bits(),
            word: u32::from(axis & 3) | LOD_BIT | lod << 3,
        }
    }

    /// A leaf, in the node when its count fits, else appended to `spilled`.
    fn leaf(leaf: Leaf, spilled: &mut Vec<Leaf>) -> DNode {
        if u32::from(leaf.count) < SPILLED {
            DNode {
                split: leaf.block,
                word: LEAF_AXIS | u32::from(leaf.first) << 2 | u32::from(leaf.count) << 18,
            }
        } else {
            spilled.push(leaf);
            DNode {
                // At most one leaf per 8 bytes of a block: the index fits.
                split: (spilled.len() - 1) as u32,
                word: LEAF_AXIS | SPILLED << 18,
            }
        }
    }
}

/// The largest index each kind of node can hold: far above the nodes a 1 MiB block can have
/// (131072), checked all the same.
const MAX_RIGHT: usize = (1 << 28) - 2;
const MAX_LOD: usize = (1 << 29) - 1;

/// A node as the traversal matches on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NodeView {
    /// A kd-tree split with up to two children in the same block.
    Inner {
        /// The split plane's axis: 0 x, 1 y, 2 z.
        axis: u8,
        /// The split plane's coordinate on `axis`, in stored coordinates.
        split: f32,
        /// Node indices in the same block, [`NONE`] for an empty child.
        left: u32,
        /// Like `left`, for the child above the split.
        right: u32,
    },
    /// The LOD fields live in [`TreeletData::lods`] and [`TreeletData::look`].
    Lod {
        /// The split plane's axis: 0 x, 1 y, 2 z.
        axis: u8,
        /// The split plane's coordinate on `axis`, in stored coordinates.
        split: f32,
        /// Index in [`TreeletData::lods`].
        lod: u32,
    },
    /// A leaf: `count` entries of triangle block `block`'s list, from entry `first`.
    Leaf {
        /// The first entry in the triangle block's list ([`TriangleData::list`]).
        first: u16,
        /// How many list entries the leaf holds.
        count: u16,
        /// The id of the triangle block holding the leaf's triangles.
        block: u32,
    },
}

/// A leaf's triangles: `count` list entries from `first` in triangle block `block`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Leaf {
    block: u32,
    first: u16,
    count: u16,
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
    /// The kind's name in messages and on the command line: `voxel` or `rlod`.
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
    /// The plane's unit normal.
    pub normal: [f32; 3],
    /// The plane's offset in stored coordinates: its points x have `normal · x = offset`.
    pub offset: f32,
    /// The node's triangles' mean colour, linear RGB in 0..=1.
    pub colour: [f32; 3],
    /// How far past the node's cell the plane still counts, in scene units (spec §6.4).
    pub expansion: f32,
    /// δ: the bound on the node's triangles' distance from the plane, in scene units.
    pub deviation: f32,
    /// α: the share of what a ray shows that is this plane (spec §6.4; 1 when unfiltered).
    pub coverage: f32,
    /// σ: the factor on the light's cosine (1 when unfiltered).
    pub shade: f32,
}

/// What a LOD node shows.
#[derive(Clone, Copy, Debug)]
pub enum Shown {
    /// The node's voxel: one sample, or one per cell face.
    Voxel(Voxel),
    /// The node's R-LOD plane.
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
    /// Like `left`, for the child above the split.
    pub right: u32,
    /// The id of the treelet block, one level finer, that holds the node's children.
    pub child_block: u32,
}

/// Where a LOD node's look lies, read only when a ray stops there: 8 bytes, the samples and
/// planes apart ([`TreeletData::look`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct LookAt {
    /// Voxels: the first sample's index in `samples`, [`SIX`] set for six samples. R-LODs: the
    /// index in `planes`.
    at: u32,
    /// The proxy's id, [`NO_PROXY`] for none.
    proxy: u32,
}

/// In [`LookAt::at`]: the voxel has six samples.
const SIX: u32 = 1 << 31;

/// A decoded treelet block.
#[derive(Debug)]
pub struct TreeletData {
    nodes: Vec<DNode>,
    /// Leaves whose count the node cannot hold.
    spilled: Vec<Leaf>,
    /// The LOD nodes' hot fields, by the index [`NodeView::Lod`] carries.
    pub lods: Vec<Lod>,
    /// Same index as `lods`.
    looks: Vec<LookAt>,
    samples: Vec<Sample>,
    /// The samples' footprints, same index; empty when every one is [`Footprint::FULL`] (an
    /// unfiltered file, or a block of opaque flat voxels).
    feet: Vec<Footprint>,
    planes: Vec<Plane>,
    /// Each LOD node's part word (the part covering most of its cell, spec §6.2), same index
    /// as `lods`; empty in a file without `PART_IDS`.
    lod_parts: Vec<u32>,
    /// The file has exactly one part: every LOD node is of part 0.
    one_part: bool,
    /// Node index of each treelet's root.
    pub roots: Vec<u32>,
}

/// What a LOD node's links are checked against while decoding: the file's directory, the
/// level of the block being decoded, and the LOD kind the traversal reads.
struct Links<'a> {
    directory: &'a [BlockEntry],
    level: u16,
    kind: LodKind,
    /// Every LOD entry ends with a part word (`PART_IDS`).
    part_words: bool,
    /// The length of the file's part table: each part word is below it.
    parts: usize,
}

/// A thread's working arrays for decoding blocks, kept between blocks: a fetcher decodes block
/// after block, and fresh pages are dear (the kernel zeroes each on first touch; page faults
/// were half of a fetcher's profile in a cold walkthrough, README). A treelet block is built
/// here and copied out into arrays of exactly its size. Outside the cache budget: for 64 KiB
/// blocks under 250 KiB per thread for treelet blocks (most of it the right-children list of a
/// block of inner nodes only) and 24 bytes per vertex for triangle blocks.
#[derive(Default)]
struct Scratch {
    /// Node index by 8-byte unit of the node area.
    index: Vec<u32>,
    /// Inner nodes' right children to resolve once every node has its index: (node, child's
    /// byte position).
    rights: Vec<(u32, usize)>,
    nodes: Vec<DNode>,
    spilled: Vec<Leaf>,
    lods: Vec<Lod>,
    looks: Vec<LookAt>,
    samples: Vec<Sample>,
    feet: Vec<Footprint>,
    planes: Vec<Plane>,
    lod_parts: Vec<u32>,
    vertices: Vec<Vertex>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::default();
}

impl Scratch {
    /// Decodes the node at byte `pos` (with its LOD `entry`) as the next node. A right child
    /// is noted to be linked once every node has its index.
    #[inline]
    fn push_node(
        &mut self,
        links: &Links,
        pos: usize,
        node: &Node,
        entry: &LodEntry,
    ) -> Result<()> {
        let i = self.nodes.len();
        if let Some(slot) = self.index.get_mut(pos / 8) {
            *slot = i as u32;
        }
        let node = match *node {
            Node::Basic {
                axis,
                split,
                left,
                right,
            } => {
                // The walk's preorder check puts the left child right after its parent; the
                // traversal relies on it, so it is checked here too.
                if left != 0 && left as usize * 8 != NODE_BASIC_LEN {
                    return Err(not_a_node(i, "left", TreeletBlock::child_pos(pos, left)));
                }
                if right != 0 {
                    self.rights
                        .push((i as u32, TreeletBlock::child_pos(pos, right)));
                }
                DNode::inner(axis, split, left != 0)
            }
            Node::Lod {
                axis,
                split,
                radius,
                left_present,
                right_present,
                child_treelet,
                child_block,
                voxel_offset: _,
                proxy,
            } => {
                check_link(links.directory, links.level, child_block, pos)?;
                let lod = self.lods.len();
                let (radius, at) = look(links.kind, entry, radius, self, pos)?;
                let [left, right] =
                    lod_child_treelets(child_treelet, [left_present, right_present])
                        .map(|t| t.unwrap_or(NONE));
                self.lods.push(Lod {
                    radius,
                    left,
                    right,
                    child_block,
                });
                self.looks.push(LookAt { at, proxy });
                if links.part_words {
                    let part = entry.part.unwrap_or(NONE);
                    if part as usize >= links.parts {
                        return Err(Error::malformed(
                            Code::PartId,
                            format!(
                                "LOD node {i}: part word {part} of a table of {} parts",
                                links.parts
                            ),
                        )
                        .at(pos as u64));
                    }
                    self.lod_parts.push(part);
                }
                DNode::lod(axis, split, index_within(lod, MAX_LOD, pos)?)
            }
            Node::Leaf {
                count,
                first,
                block,
            } => DNode::leaf(
                Leaf {
                    block,
                    first,
                    count,
                },
                &mut self.spilled,
            ),
        };
        self.nodes.push(node);
        Ok(())
    }

    /// Gives each inner node noted with a right child that child's index (an error in block
    /// `block` where no node starts at the child's byte).
    fn link_rights(&mut self, block: u32) -> Result<()> {
        for &(node, child) in &self.rights {
            let at = self.index.get(child / 8).copied().unwrap_or(NONE);
            let bad = || not_a_node(node as usize, "right", child).in_block(block);
            if at == NONE {
                return Err(bad());
            }
            let right =
                index_within(at as usize, MAX_RIGHT, child).map_err(|e| e.in_block(block))?;
            match self.nodes.get_mut(node as usize) {
                Some(n) => n.set_right(right),
                None => return Err(bad()),
            }
        }
        Ok(())
    }
    /// Empties the treelet arrays for a block of `slots` 8-byte node units.
    fn reset(&mut self, slots: usize) {
        self.index.clear();
        self.index.resize(slots, NONE);
        self.rights.clear();
        self.nodes.clear();
        self.spilled.clear();
        self.lods.clear();
        self.looks.clear();
        self.samples.clear();
        self.feet.clear();
        self.planes.clear();
        self.lod_parts.clear();
    }
}

impl TreeletData {
    /// Decodes for voxels when the block's file has them, else for R-LODs. `directory` is the
    /// file's: each LOD node's child block must be a treelet block of the next level there;
    /// `parts` the length of its part table, which every part word must be below.
    pub fn decode(block: &Block, directory: &[BlockEntry], parts: usize) -> Result<TreeletData> {
        let kind = if block.lod.voxel {
            LodKind::Voxel
        } else {
            LodKind::Rlod
        };
        Self::decode_as(block, kind, directory, parts)
    }

    /// Decodes the LOD nodes' `kind` (an error when the file lacks it).
    pub fn decode_as(
        block: &Block,
        kind: LodKind,
        directory: &[BlockEntry],
        parts: usize,
    ) -> Result<TreeletData> {
        SCRATCH.with(|scratch| match scratch.try_borrow_mut() {
            Ok(mut s) => Self::decode_with(block, kind, directory, parts, &mut s),
            // Only a decode inside a decode would find it taken; none does.
            Err(_) => Self::decode_with(block, kind, directory, parts, &mut Scratch::default()),
        })
    }

    /// One walk over the block builds every array; the right children, which preorder puts
    /// after their subtree's left half, are filled in after it.
    fn decode_with(
        block: &Block,
        kind: LodKind,
        directory: &[BlockEntry],
        parts: usize,
        s: &mut Scratch,
    ) -> Result<TreeletData> {
        let tb = block.treelets()?;
        s.reset(tb.node_area().len() / 8);
        let links = Links {
            directory,
            level: block.entry.level,
            kind,
            part_words: block.lod.parts,
            parts,
        };
        tb.walk_lods(|_, pos, node, entry| s.push_node(&links, pos, node, entry))
            .map_err(|e| e.in_block(block.id))?;
        s.link_rights(block.id)?;
        let roots = (0..tb.treelet_count())
            .map(|t| {
                let span = tb.treelet_span(t)?;
                Ok(s.index.get(span.start / 8).copied().unwrap_or(NONE))
            })
            .collect::<Result<Vec<_>>>()
            .map_err(|e| e.in_block(block.id))?;
        // Copied out sized exactly: these stay in the cache, and growing them by doubling
        // would touch fresh pages for every copy.
        Ok(TreeletData {
            nodes: s.nodes.clone(),
            spilled: s.spilled.clone(),
            lods: s.lods.clone(),
            looks: s.looks.clone(),
            samples: s.samples.clone(),
            feet: if s.feet.iter().all(|f| f.is_full()) {
                Vec::new()
            } else {
                s.feet.clone()
            },
            planes: s.planes.clone(),
            lod_parts: s.lod_parts.clone(),
            one_part: parts == 1,
            roots,
        })
    }

    /// Node `i`, None past the end.
    #[inline]
    pub fn node(&self, i: u32) -> Option<NodeView> {
        let n = *self.nodes.get(i as usize)?;
        let axis = (n.word & 3) as u8;
        let split = f32::from_bits(n.split);
        Some(if u32::from(axis) == LEAF_AXIS {
            let count = n.word >> 18;
            if count == SPILLED {
                let leaf = *self.spilled.get(n.split as usize)?;
                NodeView::Leaf {
                    first: leaf.first,
                    count: leaf.count,
                    block: leaf.block,
                }
            } else {
                NodeView::Leaf {
                    first: (n.word >> 2) as u16,
                    count: count as u16,
                    block: n.split,
                }
            }
        } else if n.word & LOD_BIT != 0 {
            NodeView::Lod {
                axis,
                split,
                lod: n.word >> 3,
            }
        } else {
            NodeView::Inner {
                axis,
                split,
                left: if n.word & LEFT_BIT != 0 { i + 1 } else { NONE },
                right: (n.word >> 4).wrapping_sub(1),
            }
        })
    }

    /// How many nodes the block holds, every treelet's together.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Every node, in index order (the file's preorder).
    pub fn nodes(&self) -> impl Iterator<Item = NodeView> + '_ {
        (0..self.nodes.len() as u32).filter_map(|i| self.node(i))
    }

    /// What LOD node `lod` shows, and its proxy.
    #[inline]
    pub fn look(&self, lod: u32) -> Option<(Shown, Option<u32>)> {
        let l = *self.looks.get(lod as usize)?;
        let shown = if self.planes.is_empty() {
            let at = (l.at & !SIX) as usize;
            Shown::Voxel(if l.at & SIX != 0 {
                let feet = match self.feet.get(at..at + 6) {
                    Some(f) => f.try_into().ok()?,
                    None => [Footprint::FULL; 6],
                };
                Voxel::Six(self.samples.get(at..at + 6)?.try_into().ok()?, feet)
            } else {
                let foot = self.feet.get(at).copied().unwrap_or(Footprint::FULL);
                Voxel::Single(*self.samples.get(at)?, foot)
            })
        } else {
            Shown::Plane(*self.planes.get(l.at as usize)?)
        };
        Some((shown, (l.proxy != NO_PROXY).then_some(l.proxy)))
    }

    /// The part LOD node `lod` shows most of (its part word; 0 in a file of one part), what
    /// picking there answers; None in a file without parts.
    #[inline]
    pub fn lod_part(&self, lod: u32) -> Option<u32> {
        match self.lod_parts.get(lod as usize) {
            Some(&p) => (p != NONE).then_some(p),
            None => self.one_part.then_some(0),
        }
    }

    /// Bytes this block holds in memory, for the cache budget.
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.nodes.capacity() * std::mem::size_of::<DNode>()
            + self.spilled.capacity() * std::mem::size_of::<Leaf>()
            + self.lods.capacity() * std::mem::size_of::<Lod>()
            + self.looks.capacity() * std::mem::size_of::<LookAt>()
            + self.samples.capacity() * std::mem::size_of::<Sample>()
            + self.feet.capacity() * std::mem::size_of::<Footprint>()
            + self.planes.capacity() * std::mem::size_of::<Plane>()
            + self.lod_parts.capacity() * 4
            + self.roots.capacity() * 4
    }

    /// Whether every array holds exactly its length (what the cache budget counts).
    pub fn is_exactly_sized(&self) -> bool {
        self.nodes.capacity() == self.nodes.len()
            && self.spilled.capacity() == self.spilled.len()
            && self.lods.capacity() == self.lods.len()
            && self.looks.capacity() == self.looks.len()
            && self.samples.capacity() == self.samples.len()
            && self.feet.capacity() == self.feet.len()
            && self.planes.capacity() == self.planes.len()
            && self.lod_parts.capacity() == self.lod_parts.len()
    }
}

/// The radius for the metric of the LOD node at byte `pos` and where its look goes, appended
/// to `s`'s samples or planes.
fn look(
    kind: LodKind,
    entry: &LodEntry,
    radius: f32,
    s: &mut Scratch,
    pos: usize,
) -> Result<(f32, u32)> {
    let lacks = |code, what: &str| {
        Error::malformed(code, format!("this file's LOD nodes carry no {what}")).at(pos as u64)
    };
    match kind {
        LodKind::Voxel => {
            let v = entry.voxel.ok_or_else(|| lacks(Code::Voxel, "voxels"))?;
            let at = index_within(s.samples.len(), (SIX - 1) as usize, pos)?;
            Ok(match v {
                Voxel::Single(x, f) => {
                    s.samples.push(x);
                    s.feet.push(f);
                    (radius, at)
                }
                Voxel::Six(xs, fs) => {
                    s.samples.extend(xs);
                    s.feet.extend(fs);
                    (radius, at | SIX)
                }
            })
        }
        LodKind::Rlod => {
            let r = entry.rlod.ok_or_else(|| lacks(Code::Rlod, "R-LODs"))?;
            let at = index_within(s.planes.len(), u32::MAX as usize - 1, pos)?;
            s.planes.push(Plane {
                normal: r.normal,
                offset: r.offset,
                colour: r.colour_f32(),
                expansion: r.expansion(radius),
                deviation: r.deviation(radius),
                coverage: r.coverage_f32(),
                shade: r.shade_f32(),
            });
            Ok((r.error_radius(radius), at))
        }
    }
}

/// The rule that ends every path of LOD links (spec §12, "Following LOD links"): the child
/// block of a LOD node at byte `pos` of a block of `level` is a treelet block of `level` + 1.
/// Without it a link back into the same level is a cycle, and a ray would descend for ever.
fn check_link(directory: &[BlockEntry], level: u16, child_block: u32, pos: usize) -> Result<()> {
    let Some(child) = directory
        .get(child_block as usize)
        .filter(|c| c.kind == BlockKind::Treelet)
    else {
        return Err(Error::malformed(
            Code::TreeReference,
            format!("a LOD node's child block {child_block} is not a treelet block"),
        )
        .at(pos as u64));
    };
    if u32::from(child.level) != u32::from(level) + 1 {
        return Err(Error::malformed(
            Code::TreeLevel,
            format!(
                "a LOD node's child block {child_block} has level {}, not {}",
                child.level,
                u32::from(level) + 1
            ),
        )
        .at(pos as u64));
    }
    Ok(())
}

fn not_a_node(node: usize, which: &str, child: usize) -> Error {
    Error::malformed(
        Code::NodeChild,
        format!("node {node}: {which} child at byte {child} is not a node"),
    )
    .at(child as u64)
}

/// `i` as a u32 when it is at most `max`, else an error at byte `pos`.
fn index_within(i: usize, max: usize, pos: usize) -> Result<u32> {
    match u32::try_from(i) {
        Ok(v) if i <= max => Ok(v),
        _ => Err(Error::malformed(
            Code::NodeChild,
            format!("node at {pos}: index {i} is past what a decoded node holds ({max})"),
        )
        .at(pos as u64)),
    }
}

/// A decoded triangle block.
#[derive(Debug)]
pub struct TriangleData {
    /// The block's id in the file's directory (what picking reports).
    pub block: u32,
    /// Triangle index by list entry, each < the triangle count.
    pub list: Vec<u16>,
    /// Each triangle's three corners, in stored coordinates (world = the scene origin + these).
    pub positions: Vec<[[f32; 3]; 3]>,
    /// Per corner, when the scene has vertex normals.
    pub normals: Option<Vec<[[f32; 3]; 3]>>,
    /// Per corner, linear RGB in 0..=1, when the scene has vertex colours.
    pub colours: Option<Vec<[[f32; 3]; 3]>>,
    /// Each triangle's material index, when the scene has materials.
    pub materials: Option<Vec<u16>>,
    /// Each triangle's part, at the width the file stores.
    parts: PartIds,
    /// The distinct parts of the block's triangles, ascending: what a part filter makes of the
    /// whole block is decided from these ([`crate::parts::PartFilter::block_mask`]).
    present: Vec<u32>,
}

/// The part id of each triangle of a block, kept at the file's width (a scene of at most 256
/// parts pays a byte per triangle).
#[derive(Debug)]
enum PartIds {
    /// The file has no parts.
    None,
    /// The file has one part: every triangle is of part 0, and no id is stored.
    One,
    U8(Vec<u8>),
    U16(Vec<u16>),
    U32(Vec<u32>),
}

impl PartIds {
    /// Ids for `n` triangles of a block whose attributes carry `width` (spec §8), in a file of
    /// `parts` parts.
    fn with_capacity(width: u16, n: usize, parts: usize) -> PartIds {
        match width {
            0 if parts == 1 => PartIds::One,
            0 => PartIds::None,
            1 => PartIds::U8(Vec::with_capacity(n)),
            2 => PartIds::U16(Vec::with_capacity(n)),
            _ => PartIds::U32(Vec::with_capacity(n)),
        }
    }

    /// Appends `id` (already checked against the table); the width held it when it was written.
    fn push(&mut self, id: u32) {
        match self {
            PartIds::None | PartIds::One => {}
            PartIds::U8(v) => v.push(id as u8),
            PartIds::U16(v) => v.push(id as u16),
            PartIds::U32(v) => v.push(id),
        }
    }

    #[inline(always)]
    fn get(&self, i: usize) -> Option<u32> {
        match self {
            PartIds::None => None,
            PartIds::One => Some(0),
            PartIds::U8(v) => v.get(i).map(|&p| u32::from(p)),
            PartIds::U16(v) => v.get(i).map(|&p| u32::from(p)),
            PartIds::U32(v) => v.get(i).copied(),
        }
    }

    fn bytes(&self) -> usize {
        match self {
            PartIds::None | PartIds::One => 0,
            PartIds::U8(v) => v.capacity(),
            PartIds::U16(v) => v.capacity() * 2,
            PartIds::U32(v) => v.capacity() * 4,
        }
    }
}

impl TriangleData {
    /// Decodes and checks `block`, whose attribute bits must equal `attrs` (the metadata's,
    /// [`oocfmt::Metadata::triangle_attributes`]) in a file of `parts` parts: every part id
    /// must be below it (`PART_ID`).
    pub fn decode(block: &Block, attrs: u16, parts: usize) -> Result<TriangleData> {
        SCRATCH.with(|scratch| match scratch.try_borrow_mut() {
            Ok(mut s) => Self::decode_with(block, attrs, parts, &mut s.vertices),
            // Only a decode inside a decode would find it taken; none does.
            Err(_) => Self::decode_with(block, attrs, parts, &mut Vec::new()),
        })
    }

    /// One pass over each section with the bulk readers, after `check_contents` has checked
    /// every index (the list entries among them) and position. A fetcher decodes block after
    /// block, and on the 100M-triangle Mandelbulb this takes 0.55 of the time a `Result` per
    /// field read took (README).
    fn decode_with(
        block: &Block,
        attrs: u16,
        parts: usize,
        vertices: &mut Vec<Vertex>,
    ) -> Result<TriangleData> {
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
        let width = (tb.attributes() & ATTR_PART_WIDTH) >> ATTR_PART_WIDTH_SHIFT;
        let mut ids = PartIds::with_capacity(width, n, parts);
        let mut present = Vec::new();
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
            if let Some(p) = t.part {
                if p as usize >= parts {
                    return Err(Error::malformed(
                        Code::PartId,
                        format!("triangle {i}: part {p} of a table of {parts} parts"),
                    )
                    .in_block(block.id));
                }
                ids.push(p);
                // Triangles come in runs of one part: most repeats end here.
                if present.last() != Some(&p) {
                    present.push(p);
                }
            }
        }
        if let PartIds::One = ids {
            present.push(0);
        }
        present.sort_unstable();
        present.dedup();
        present.shrink_to_fit();
        Ok(TriangleData {
            block: block.id,
            list,
            positions,
            normals,
            colours,
            materials,
            parts: ids,
            present,
        })
    }

    /// Triangle `triangle`'s part (0 in a file of one part); None in a file without parts or
    /// past the block.
    #[inline(always)]
    pub fn part(&self, triangle: u32) -> Option<u32> {
        self.parts.get(triangle as usize)
    }

    /// The distinct parts of the block's triangles, ascending (empty without parts).
    pub fn parts_present(&self) -> &[u32] {
        &self.present
    }

    /// Bytes this block holds in memory, for the cache budget.
    pub fn bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.list.capacity() * 2
            + self.positions.capacity() * 36
            + self.normals.as_ref().map_or(0, |v| v.capacity() * 36)
            + self.colours.as_ref().map_or(0, |v| v.capacity() * 36)
            + self.materials.as_ref().map_or(0, |v| v.capacity() * 2)
            + self.parts.bytes()
            + self.present.capacity() * 4
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_node_is_8_bytes_and_the_hot_part_of_a_lod_node_16() {
        assert_eq!(std::mem::size_of::<super::DNode>(), 8);
        assert_eq!(std::mem::size_of::<super::Lod>(), 16);
        assert_eq!(std::mem::size_of::<super::LookAt>(), 8);
    }

    #[test]
    fn a_leaf_keeps_its_fields_in_the_node_or_spilled() {
        use super::*;
        let mut spilled = Vec::new();
        let leaves = [(7, 0, 1), (u32::MAX, u16::MAX, SPILLED as u16 - 1)]
            .into_iter()
            .chain([SPILLED as u16, u16::MAX].map(|count| (9, 65000, count)))
            .map(|(block, first, count)| Leaf {
                block,
                first,
                count,
            });
        let nodes: Vec<DNode> = leaves
            .clone()
            .map(|l| DNode::leaf(l, &mut spilled))
            .collect();
        assert_eq!(spilled.len(), 2);
        let d = TreeletData {
            nodes,
            spilled,
            lods: Vec::new(),
            looks: Vec::new(),
            samples: Vec::new(),
            feet: Vec::new(),
            planes: Vec::new(),
            lod_parts: Vec::new(),
            one_part: false,
            roots: Vec::new(),
        };
        let views: Vec<NodeView> = d.nodes().collect();
        let want: Vec<NodeView> = leaves
            .map(|l| NodeView::Leaf {
                first: l.first,
                count: l.count,
                block: l.block,
            })
            .collect();
        assert_eq!(views, want);
    }
}
