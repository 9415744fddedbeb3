//! Treelet blocks (spec §6.2): a table of treelet starts, a node area and a LOD area (voxels
//! and, in files with R-LODs, R-LOD records; in files with `PART_IDS`, a part word closing each
//! entry).

use std::ops::Range;

use super::node::{Node, MAX_CHILD_UNITS};
use super::rlod::{LodKinds, Rlod};
use super::sample::Voxel;
use crate::bytes::{u32_at, PutLe};
use crate::error::{bad, Code, Error, Result};

const HEAD_LEN: usize = 16;

/// A zero-copy view of a treelet block's raw bytes, with its framing checked.
#[derive(Clone, Copy, Debug)]
pub struct TreeletBlock<'a> {
    starts: &'a [u8],
    nodes: &'a [u8],
    voxels: &'a [u8],
    kinds: LodKinds,
}

/// A LOD node's entry in the LOD area, as [`TreeletBlock::walk_lods`] decoded it: what the
/// file's LOD kinds put there.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LodEntry {
    /// The node's voxel; `None` for a non-LOD node or a file without voxels.
    pub voxel: Option<Voxel>,
    /// The node's R-LOD record; `None` for a non-LOD node or a file without R-LODs.
    pub rlod: Option<Rlod>,
    /// Bytes the voxel takes in the LOD area as stored (0 without one): the entry's length
    /// follows from it, not from the decoded voxel (spec §5.1).
    pub voxel_len: usize,
    /// The part that covers most of the node's cell as seen from outside (spec §6.2), what
    /// picking at this level answers; `None` for a non-LOD node or a file without `PART_IDS`.
    pub part: Option<u32>,
}

impl LodEntry {
    /// Bytes the entry takes in the LOD area: its voxel, R-LOD record and part word.
    pub fn byte_len(&self) -> usize {
        self.voxel_len
            + self.rlod.map_or(0, |_| super::rlod::RLOD_LEN)
            + self.part.map_or(0, |_| PART_WORD_LEN)
    }
}

/// Bytes of the part word that ends each LOD entry of a file with `PART_IDS`.
pub const PART_WORD_LEN: usize = 4;

/// What one pass over a treelet block found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TreeletSummary {
    /// Treelets in the block.
    pub treelets: u64,
    /// Basic (inner, same-treelet) nodes visited.
    pub basic_nodes: u64,
    /// LOD nodes visited.
    pub lod_nodes: u64,
    /// Leaves visited.
    pub leaves: u64,
    /// 1-sample voxels decoded.
    pub voxels_single: u64,
    /// 6-sample voxels decoded.
    pub voxels_six: u64,
    /// R-LOD records decoded.
    pub rlods: u64,
}

impl<'a> TreeletBlock<'a> {
    /// Checks the header, the section sizes and the treelet start table of a block whose LOD
    /// nodes carry voxels only (every 1.0 file).
    pub fn parse(raw: &'a [u8]) -> Result<Self> {
        Self::parse_with(raw, LodKinds::VOXEL)
    }

    /// Like [`TreeletBlock::parse`], for a file whose LOD nodes carry `kinds`.
    pub fn parse_with(raw: &'a [u8], kinds: LodKinds) -> Result<Self> {
        let c = Code::TreeletLayout;
        let count = u32_at(raw, 0, c)? as usize;
        let node_bytes = u32_at(raw, 4, c)? as usize;
        let voxel_bytes = u32_at(raw, 8, c)? as usize;
        if u32_at(raw, 12, c)? != 0 {
            return bad(c, "reserved treelet block field is not zero");
        }
        let expected =
            (HEAD_LEN as u64) + 4 * count as u64 + node_bytes as u64 + voxel_bytes as u64;
        if count == 0 || node_bytes % 8 != 0 || voxel_bytes % 4 != 0 || expected != raw.len() as u64
        {
            return bad(
                c,
                format!(
                    "{count} treelets, {node_bytes} node bytes and {voxel_bytes} voxel bytes do not frame a {}-byte block",
                    raw.len()
                ),
            );
        }
        let nodes_at = HEAD_LEN + 4 * count;
        let block = TreeletBlock {
            starts: &raw[HEAD_LEN..nodes_at],
            nodes: &raw[nodes_at..nodes_at + node_bytes],
            voxels: &raw[nodes_at + node_bytes..],
            kinds,
        };
        let mut prev: Option<u32> = None;
        for t in 0..count {
            let s = u32_at(block.starts, 4 * t, c)?;
            let ok = match prev {
                None => s == 0,
                Some(p) => s > p,
            };
            if !ok || s % 8 != 0 || s as usize >= node_bytes {
                return bad(c, format!("treelet {t} starts at {s}: not aligned, increasing and inside the node area"));
            }
            prev = Some(s);
        }
        Ok(block)
    }

    /// Number of treelets in the block (≥ 1).
    pub fn treelet_count(&self) -> usize {
        self.starts.len() / 4
    }

    /// The node area: every treelet's nodes, in preorder, back to back.
    pub fn node_area(&self) -> &'a [u8] {
        self.nodes
    }

    /// The LOD area (spec §6.2; named for the voxels it held alone in 1.0).
    pub fn voxel_area(&self) -> &'a [u8] {
        self.voxels
    }

    /// The LOD kinds the block was parsed with: the layout of its LOD area.
    pub fn lod_kinds(&self) -> LodKinds {
        self.kinds
    }

    /// The node-area byte range of treelet `t`.
    pub fn treelet_span(&self, t: usize) -> Result<Range<usize>> {
        let start = u32_at(self.starts, 4 * t, Code::TreeReference).map_err(|_| {
            Error::malformed(
                Code::TreeReference,
                format!("treelet {t} of {}", self.treelet_count()),
            )
        })?;
        let end = match u32_at(self.starts, 4 * (t + 1), Code::TreeletLayout) {
            Ok(e) => e as usize,
            Err(_) => self.nodes.len(),
        };
        Ok(start as usize..end)
    }

    /// The node at byte `pos` of the node area.
    #[inline]
    pub fn node(&self, pos: usize) -> Result<Node> {
        Node::decode(self.nodes, pos)
    }

    /// The voxel of a LOD node, whose LOD entry starts at `voxel_offset`.
    #[inline]
    pub fn voxel(&self, voxel_offset: u32) -> Result<Voxel> {
        if !self.kinds.voxel {
            return bad(Code::Voxel, "this file's LOD nodes carry no voxels");
        }
        Voxel::decode(self.voxels, voxel_offset as usize, self.kinds.filtered)
    }

    /// The R-LOD record of a LOD node whose LOD entry starts at `voxel_offset`: after the voxel
    /// in a file with both kinds (spec §6.4).
    pub fn rlod(&self, voxel_offset: u32) -> Result<Rlod> {
        if !self.kinds.rlod {
            return bad(Code::Rlod, "this file's LOD nodes carry no R-LODs");
        }
        let skip = if self.kinds.voxel {
            let off = voxel_offset as usize;
            Voxel::decode_sized(self.voxels, off, self.kinds.filtered)?.1
        } else {
            0
        };
        Rlod::decode(
            self.voxels,
            voxel_offset as usize + skip,
            self.kinds.filtered,
        )
    }

    /// Byte position of a child, from its parent's position and the stored offset.
    pub fn child_pos(pos: usize, units: u16) -> usize {
        pos + 8 * usize::from(units)
    }

    /// Walks every treelet in preorder and checks that its nodes are well formed, that children
    /// are forward and inside the treelet, that the nodes cover the treelet's bytes exactly once,
    /// and that every voxel decodes. Calls `visit(treelet, pos, node)` for each node.
    pub fn walk(
        &self,
        mut visit: impl FnMut(usize, usize, &Node) -> Result<()>,
    ) -> Result<TreeletSummary> {
        self.walk_lods(|t, pos, node, _| visit(t, pos, node))
    }

    /// [`TreeletBlock::walk`], handing `visit` the LOD entry it decoded and checked for each
    /// LOD node (empty for the other nodes), so that a reader that keeps them decodes each once.
    ///
    /// The preorder check makes a basic node's left child, when present, the node visited right
    /// after it.
    pub fn walk_lods(
        &self,
        mut visit: impl FnMut(usize, usize, &Node, &LodEntry) -> Result<()>,
    ) -> Result<TreeletSummary> {
        let mut sum = TreeletSummary {
            treelets: self.treelet_count() as u64,
            ..TreeletSummary::default()
        };
        let mut stack = Vec::with_capacity(16);
        for t in 0..self.treelet_count() {
            let span = self.treelet_span(t)?;
            self.walk_treelet(t, span, &mut stack, &mut sum, &mut visit)?;
        }
        Ok(sum)
    }

    /// Treelet `t` of [`TreeletBlock::walk_lods`], whose nodes span `span`: a preorder walk on
    /// `stack` in which each node must start where the previous one ended.
    #[inline]
    fn walk_treelet(
        &self,
        t: usize,
        span: Range<usize>,
        stack: &mut Vec<usize>,
        sum: &mut TreeletSummary,
        visit: &mut impl FnMut(usize, usize, &Node, &LodEntry) -> Result<()>,
    ) -> Result<()> {
        let mut cursor = span.start;
        stack.clear();
        stack.push(span.start);
        while let Some(pos) = stack.pop() {
            preorder(t, pos, cursor)?;
            let node = self.node(pos)?;
            cursor += node.byte_len();
            if cursor > span.end {
                return Err(Error::malformed(
                    Code::NodeOverlap,
                    format!(
                        "treelet {t}: node at {pos} runs past the treelet's end {}",
                        span.end
                    ),
                )
                .at(pos as u64));
            }
            let entry = match node {
                Node::Basic { left, right, .. } => {
                    sum.basic_nodes += 1;
                    push_children(t, pos, [left, right], &span, stack)?;
                    LodEntry::default()
                }
                Node::Lod { voxel_offset, .. } => {
                    sum.lod_nodes += 1;
                    self.lod_entry(voxel_offset, sum)
                        .map_err(|e| e.at(pos as u64))?
                }
                Node::Leaf { .. } => {
                    sum.leaves += 1;
                    LodEntry::default()
                }
            };
            visit(t, pos, &node, &entry)?;
        }
        if cursor != span.end {
            return Err(Error::malformed(
                Code::NodeOverlap,
                format!(
                    "treelet {t}: nodes end at {cursor}, the treelet at {}",
                    span.end
                ),
            )
            .at(cursor as u64));
        }
        Ok(())
    }

    /// Decodes the LOD entry at `voxel_offset`, the file's LOD kinds in order, counting what it
    /// holds in `sum`.
    #[inline]
    fn lod_entry(&self, voxel_offset: u32, sum: &mut TreeletSummary) -> Result<LodEntry> {
        let mut entry = LodEntry::default();
        if self.kinds.voxel {
            let (v, len) =
                Voxel::decode_sized(self.voxels, voxel_offset as usize, self.kinds.filtered)?;
            entry.voxel_len = len;
            match v {
                Voxel::Single(..) => sum.voxels_single += 1,
                Voxel::Six(..) => sum.voxels_six += 1,
            }
            entry.voxel = Some(v);
        }
        if self.kinds.rlod {
            let filtered = self.kinds.filtered;
            let at = voxel_offset as usize + entry.voxel_len;
            entry.rlod = Some(Rlod::decode(self.voxels, at, filtered)?);
            sum.rlods += 1;
        }
        if self.kinds.parts {
            let at = voxel_offset as usize + entry.byte_len();
            entry.part = Some(u32_at(self.voxels, at, Code::LodArea).map_err(|_| {
                Error::malformed(
                    Code::LodArea,
                    format!(
                        "the part word of the LOD entry at {voxel_offset} would be at {at}, past the {}-byte LOD area",
                        self.voxels.len()
                    ),
                )
            })?);
        }
        Ok(entry)
    }
}

/// Checks that the node at `pos` of treelet `t` is where preorder puts the next one, `cursor`
/// (spec §6.2): past it is a layout in another order (`NODE_ORDER`); before it, the node
/// overlaps one already walked.
#[inline]
fn preorder(t: usize, pos: usize, cursor: usize) -> Result<()> {
    if pos == cursor {
        return Ok(());
    }
    let code = if pos > cursor {
        Code::NodeOrder
    } else {
        Code::NodeOverlap
    };
    Err(Error::malformed(
        code,
        format!("treelet {t}: node at {pos} but preorder puts the next node at {cursor}"),
    )
    .at(pos as u64))
}

/// Pushes a basic node's children, given as `[left, right]` offsets (0: none), right first so
/// that the left one is walked next; checks that the right one comes after the left and that
/// both are inside the treelet's `span`.
#[inline]
fn push_children(
    t: usize,
    pos: usize,
    [left, right]: [u16; 2],
    span: &Range<usize>,
    stack: &mut Vec<usize>,
) -> Result<()> {
    if left != 0 && right != 0 && right <= left {
        return Err(Error::malformed(
            Code::NodeChild,
            format!("node at {pos}: right child before left"),
        )
        .at(pos as u64));
    }
    for units in [right, left] {
        if units == 0 {
            continue;
        }
        let child = TreeletBlock::child_pos(pos, units);
        if child >= span.end {
            return Err(Error::malformed(
                Code::NodeChild,
                format!(
                    "node at {pos}: child at {child} outside treelet {t} ({}..{})",
                    span.start, span.end
                ),
            )
            .at(pos as u64));
        }
        stack.push(child);
    }
    Ok(())
}

/// Encodes a treelet block record by record. The caller lays the tree out; this only writes
/// what it is given, in order.
#[derive(Clone, Debug, Default)]
pub struct TreeletBlockWriter {
    starts: Vec<u32>,
    nodes: Vec<u8>,
    voxels: Vec<u8>,
}

impl TreeletBlockWriter {
    /// An empty block with no treelets.
    pub fn new() -> Self {
        Self::default()
    }

    /// Starts a new treelet; returns its index in the block.
    pub fn begin_treelet(&mut self) -> u32 {
        self.starts.push(self.nodes.len() as u32);
        (self.starts.len() - 1) as u32
    }

    /// Byte position the next node will get in the node area.
    pub fn next_node_pos(&self) -> usize {
        self.nodes.len()
    }

    /// Appends a node at [`TreeletBlockWriter::next_node_pos`] of the current treelet.
    pub fn push_node(&mut self, node: &Node) {
        node.encode_into(&mut self.nodes);
    }

    /// Rewrites a node already pushed at `pos` (to fill in child offsets once known).
    pub fn patch_node(&mut self, pos: usize, node: &Node) -> Result<()> {
        let mut bytes = Vec::with_capacity(node.byte_len());
        node.encode_into(&mut bytes);
        let slot = self
            .nodes
            .get_mut(pos..pos + bytes.len())
            .ok_or_else(|| Error::parameter(format!("no node at {pos} to patch")))?;
        slot.copy_from_slice(&bytes);
        Ok(())
    }

    /// Appends a voxel, with its footprints in a `filtered` file (spec §5.1); returns the
    /// offset a LOD node stores for it.
    pub fn push_voxel(&mut self, voxel: &Voxel, filtered: bool) -> u32 {
        let off = self.voxels.len() as u32;
        voxel.encode_into(&mut self.voxels, filtered);
        off
    }

    /// Appends an R-LOD record; returns its offset in the LOD area. In a file with both kinds
    /// it goes right after its node's voxel, and the node stores the voxel's offset.
    pub fn push_rlod(&mut self, rlod: &Rlod, filtered: bool) -> u32 {
        let off = self.voxels.len() as u32;
        rlod.encode_into(&mut self.voxels, filtered);
        off
    }

    /// Appends the part word that ends a LOD entry in a file with `PART_IDS` (spec §6.2): call
    /// it right after the entry's voxel and R-LOD record.
    pub fn push_lod_part(&mut self, part: u32) {
        self.voxels.put_u32(part);
    }

    /// Treelets begun so far.
    pub fn treelet_count(&self) -> usize {
        self.starts.len()
    }

    /// The raw length the block will have.
    pub fn raw_len(&self) -> usize {
        Self::raw_len_for(self.starts.len(), self.nodes.len(), self.voxels.len())
    }

    /// The raw length of a block of `treelets` treelets with these node and voxel bytes.
    pub fn raw_len_for(treelets: usize, node_bytes: usize, voxel_bytes: usize) -> usize {
        HEAD_LEN + 4 * treelets + node_bytes + voxel_bytes
    }

    /// Raw bytes for the next node offset in 8-byte units, checked against the 12-bit field.
    pub fn units_between(parent: usize, child: usize) -> Result<u16> {
        let units = child.checked_sub(parent).map(|d| d / 8).unwrap_or(0);
        if units == 0 || units > usize::from(MAX_CHILD_UNITS) || (child - parent) % 8 != 0 {
            return Err(Error::parameter(format!(
                "child at {child} cannot be addressed from node at {parent}"
            )));
        }
        Ok(units as u16)
    }

    /// The block's raw bytes: header, treelet starts, node area, LOD area.
    pub fn finish(self) -> Vec<u8> {
        let mut v = Vec::with_capacity(self.raw_len());
        v.put_u32(self.starts.len() as u32);
        v.put_u32(self.nodes.len() as u32);
        v.put_u32(self.voxels.len() as u32);
        v.put_u32(0);
        for s in &self.starts {
            v.put_u32(*s);
        }
        v.extend_from_slice(&self.nodes);
        v.extend_from_slice(&self.voxels);
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::records::sample::{Footprint, Sample};

    fn two_leaf_treelet() -> Vec<u8> {
        let mut w = TreeletBlockWriter::new();
        w.begin_treelet();
        w.push_node(&Node::Basic {
            axis: 0,
            split: 0.5,
            left: 1,
            right: 2,
        });
        w.push_node(&Node::Leaf {
            count: 1,
            first: 0,
            block: 1,
        });
        w.push_node(&Node::Leaf {
            count: 1,
            first: 1,
            block: 1,
        });
        w.begin_treelet();
        let vox = w.push_voxel(
            &Voxel::single(Sample::pack([0.0, 0.0, 1.0], [1.0; 3])),
            false,
        );
        w.push_node(&Node::Lod {
            axis: 1,
            split: 0.0,
            radius: 1.0,
            left_present: true,
            right_present: true,
            child_treelet: 0,
            child_block: 2,
            voxel_offset: vox,
            proxy: 0,
        });
        w.finish()
    }

    #[test]
    fn walk_counts_nodes() {
        let raw = two_leaf_treelet();
        let b = TreeletBlock::parse(&raw).map_err(|e| e.to_string());
        let sum = b.and_then(|b| b.walk(|_, _, _| Ok(())).map_err(|e| e.to_string()));
        assert_eq!(
            sum,
            Ok(TreeletSummary {
                treelets: 2,
                basic_nodes: 1,
                lod_nodes: 1,
                leaves: 2,
                voxels_single: 1,
                voxels_six: 0,
                rlods: 0,
            })
        );
    }

    #[test]
    fn lod_entries_hold_a_voxel_then_an_r_lod() {
        let rlod = Rlod {
            normal: [0.0, 1.0, 0.0],
            offset: 0.25,
            colour: [1, 2, 3],
            deviation_code: 4,
            expansion_code: 5,
            coverage: 255,
            shade: 255,
        };
        let kinds_all = [LodKinds::RLOD, LodKinds::BOTH];
        for kinds in kinds_all
            .into_iter()
            .chain(kinds_all.map(LodKinds::filtered))
        {
            let f = kinds.filtered;
            // Filtered: a voxel with a footprint word (8 bytes) the R-LOD must be found after.
            let (rlod, foot) = if f {
                let r = Rlod {
                    coverage: 100,
                    shade: 200,
                    ..rlod
                };
                (r, Footprint::new(0.5, 0.25))
            } else {
                (rlod, Footprint::FULL)
            };
            let mut w = TreeletBlockWriter::new();
            w.begin_treelet();
            let at = if kinds.voxel {
                let s = Sample::pack([0.0, 0.0, 1.0], [1.0; 3]);
                let at = w.push_voxel(&Voxel::Single(s, foot), f);
                w.push_rlod(&rlod, f);
                at
            } else {
                w.push_rlod(&rlod, f)
            };
            w.push_node(&Node::Lod {
                axis: 1,
                split: 0.0,
                radius: 1.0,
                left_present: true,
                right_present: false,
                child_treelet: 0,
                child_block: 2,
                voxel_offset: at,
                proxy: 0,
            });
            let raw = w.finish();
            let b = TreeletBlock::parse_with(&raw, kinds).map_err(|e| e.to_string());
            let got = b.as_ref().map(|b| b.rlod(at).ok());
            assert_eq!(got, Ok(Some(rlod)), "{kinds:?}");
            if kinds.voxel {
                let v = b.as_ref().map(|b| b.voxel(at).ok());
                let s = Sample::pack([0.0, 0.0, 1.0], [1.0; 3]);
                assert_eq!(v, Ok(Some(Voxel::Single(s, foot))), "{kinds:?}");
            }
            let sum = b.and_then(|b| b.walk(|_, _, _| Ok(())).map_err(|e| e.to_string()));
            assert_eq!(
                sum.map(|s| (s.rlods, s.voxels_single)),
                Ok((1, u64::from(kinds.voxel)))
            );
            if !kinds.voxel {
                // R-LOD bytes read as a voxel and a record run past the area: refused.
                let e = TreeletBlock::parse_with(&raw, LodKinds::BOTH)
                    .and_then(|b| b.walk(|_, _, _| Ok(())));
                assert!(e.is_err());
            }
        }
    }

    #[test]
    fn a_child_pointing_backwards_or_outside_is_refused() {
        let mut raw = two_leaf_treelet();
        // Right child offset 2 -> 3: now it points at the next treelet's LOD node.
        let at = 16 + 8;
        raw[at + 2] = (raw[at + 2] & 0x0f) | 0x30;
        let e = TreeletBlock::parse(&raw).and_then(|b| b.walk(|_, _, _| Ok(())));
        assert!(matches!(
            e.err().map(|e| e.code()),
            Some(Code::NodeChild | Code::NodeOverlap)
        ));
    }

    #[test]
    fn a_lod_entry_ends_with_its_part_word() -> Result<()> {
        let kinds = LodKinds::BOTH.filtered().with_parts(true);
        let mut w = TreeletBlockWriter::new();
        w.begin_treelet();
        let vox = w.push_voxel(
            &Voxel::single(Sample::pack([0.0, 0.0, 1.0], [1.0; 3])),
            true,
        );
        let rlod = crate::records::Rlod {
            normal: [0.0, 0.0, 1.0],
            offset: 0.0,
            colour: [1, 2, 3],
            deviation_code: 0,
            expansion_code: 0,
            coverage: 255,
            shade: 255,
        };
        w.push_rlod(&rlod, true);
        w.push_lod_part(77);
        w.push_node(&Node::Lod {
            axis: 0,
            split: 0.0,
            radius: 1.0,
            left_present: true,
            right_present: false,
            child_treelet: 0,
            child_block: 1,
            voxel_offset: vox,
            proxy: 0,
        });
        let raw = w.finish();
        let b = TreeletBlock::parse_with(&raw, kinds)?;
        let mut entries = Vec::new();
        b.walk_lods(|_, _, _, e| {
            entries.push(*e);
            Ok(())
        })?;
        assert_eq!(entries.len(), 1);
        assert_eq!(entries[0].part, Some(77));
        assert_eq!(entries[0].byte_len(), 4 + 24 + PART_WORD_LEN);
        assert_eq!(entries[0].byte_len(), b.voxel_area().len());
        assert_eq!(b.rlod(vox)?, rlod);
        // Read without part words, the entry is shorter and the word unnamed.
        let b = TreeletBlock::parse_with(&raw, kinds.with_parts(false))?;
        b.walk_lods(|_, _, _, e| {
            assert_eq!((e.part, e.byte_len()), (None, 28));
            Ok(())
        })?;
        // An entry whose part word would pass the area's end is refused.
        let mut short = raw.clone();
        short.truncate(raw.len() - 4);
        let lod_bytes = u32::from_le_bytes([short[8], short[9], short[10], short[11]]) - 4;
        short[8..12].copy_from_slice(&lod_bytes.to_le_bytes());
        let e = TreeletBlock::parse_with(&short, kinds).and_then(|b| b.walk(|_, _, _| Ok(())));
        assert_eq!(e.err().map(|e| e.code()), Some(Code::LodArea));
        Ok(())
    }
}
