//! Deep verification: the meaning of the tree. Walks every treelet from the root with the cell,
//! depth and ancestor LOD radius it inherits, and checks every reference.

use std::collections::HashMap;

use super::{Index, Verifier};
use crate::directory::{BlockEntry, BlockKind};
use crate::error::{Code, Result};
use crate::header::{COMPAT_LOD_VOXELS, COMPAT_PROXIES};
use crate::metadata::{Counts, Metadata, TreeletRef};
use crate::reader::{read_block_data, ReadOptions};
use crate::records::LodKinds;
use crate::records::{
    lod_child_treelets, Node, Rlod, TreeletBlock, Voxel, MAX_TREE_DEPTH as MAX_DEPTH, NO_PROXY,
};
use crate::summary::{BlockFacts, PartFacts};

/// What a treelet root inherits from its parent LOD node.
#[derive(Clone, Copy)]
struct Inherit {
    cell: [[f64; 3]; 2],
    depth: u32,
    max_radius: f32,
}

/// Where a node is: in the file (its block and the block's level, its byte position in the
/// node area) and in space (its cell). Every report names its block and position.
#[derive(Clone, Copy)]
struct At {
    id: u32,
    level: u16,
    pos: usize,
    cell: [[f64; 3]; 2],
}

/// Where a treelet stands in the walk.
#[derive(Clone, Copy)]
enum Slot {
    Unseen,
    Pending(Inherit),
}

/// Treelet states, one vector per block that has been referenced but not yet walked: a hash
/// lookup per block rather than per treelet, and memory for about one LOD level at a time. A
/// block's vector is dropped once walked; a later reference to it would need a child block
/// before its parent, which `ENTRY_LEVEL` and `TREE_LEVEL` already report.
#[derive(Default)]
struct Slots {
    by_block: HashMap<u32, Vec<Slot>>,
    reached: u64,
}

impl Slots {
    /// Marks treelet `r` (of a block of `count` treelets) as pending; false if it was already
    /// pending or walked, i.e. reached twice.
    fn await_treelet(&mut self, r: TreeletRef, count: u32, inh: Inherit) -> bool {
        let slots = self
            .by_block
            .entry(r.block)
            .or_insert_with(|| vec![Slot::Unseen; count as usize]);
        match slots.get_mut(r.treelet as usize) {
            Some(slot @ Slot::Unseen) => {
                *slot = Slot::Pending(inh);
                true
            }
            _ => false,
        }
    }

    /// Takes the states of a block's treelets for walking it.
    fn take(&mut self, block: u32, count: usize) -> Vec<Slot> {
        let mut v = self.by_block.remove(&block).unwrap_or_default();
        v.resize(count, Slot::Unseen);
        v
    }
}

struct Walk<'a> {
    entries: &'a [Option<BlockEntry>],
    facts: &'a [Option<BlockFacts>],
    proxy_blocks: Vec<u32>,
    slots: Slots,
    stack: Vec<(usize, [[f64; 3]; 2], u32)>,
    counts: Counts,
}

pub(super) fn check(
    v: &mut Verifier<'_>,
    index: &Index,
    facts: &[Option<BlockFacts>],
) -> Result<()> {
    let Some(meta) = &index.metadata else {
        return Ok(());
    };
    let proxy_blocks = facts
        .iter()
        .flat_map(|f| match f {
            Some(BlockFacts::Proxy { node_blocks }) => node_blocks.clone(),
            _ => Vec::new(),
        })
        .collect();
    let mut w = Walk {
        entries: &index.entries,
        facts,
        proxy_blocks,
        slots: Slots::default(),
        stack: Vec::with_capacity(64),
        counts: Counts::default(),
    };
    w.seed_root(v, index, meta);
    let ropts = ReadOptions {
        limits: v.opts.limits,
        checksums: v.opts.checksums,
    };
    for (id, e) in (0u32..).zip(&index.entries) {
        let Some(e) = (*e).filter(|e| e.kind == BlockKind::Treelet) else {
            continue;
        };
        if !matches!(facts.get(id as usize), Some(Some(_))) {
            continue; // already reported by the block pass
        }
        let raw = match read_block_data(v.src, &e, &ropts) {
            Ok(r) => r,
            Err(err) => {
                v.note(err.in_block(id))?;
                continue;
            }
        };
        let Ok(block) = TreeletBlock::parse_with(&raw, LodKinds::of_header(&index.header)) else {
            continue;
        };
        lod_area(v, id, &block);
        w.block(v, id, &e, &block);
    }
    w.totals(v, index);
    Ok(())
}

impl Walk<'_> {
    /// Marks the root treelet as pending, with the scene's box for its cell; reports a file
    /// with no root, or a root that is not a treelet of a level-0 treelet block.
    fn seed_root(&mut self, v: &mut Verifier<'_>, index: &Index, meta: &Metadata) {
        let Some(root) = meta.root else {
            if index.entries.is_empty() {
                v.note_code(Code::TreeEmpty, "the file holds no geometry".into(), None);
            } else {
                v.note_code(Code::TreeRoot, "blocks but no root".into(), None);
            }
            return;
        };
        let ok = matches!(self.entry(root.block), Some(e) if e.kind == BlockKind::Treelet && e.level == 0 && root.treelet < e.item_count);
        if !ok {
            v.note_code(
                Code::TreeRoot,
                format!("root {root:?} is not a treelet of a level-0 treelet block"),
                None,
            );
            return;
        }
        let cell = [
            meta.scene.bounds_min.map(f64::from),
            meta.scene.bounds_max.map(f64::from),
        ];
        let count = self.treelet_count(root.block);
        self.slots.await_treelet(
            root,
            count,
            Inherit {
                cell,
                depth: 0,
                max_radius: f32::INFINITY,
            },
        );
    }

    fn entry(&self, id: u32) -> Option<BlockEntry> {
        self.entries.get(id as usize).copied().flatten()
    }

    /// Treelets in block `id` as its decoded contents showed (0 for a block that failed).
    fn treelet_count(&self, id: u32) -> u32 {
        match self.facts.get(id as usize) {
            Some(Some(BlockFacts::Treelet { nodes, .. })) => nodes.treelets as u32,
            _ => 0,
        }
    }

    fn block(&mut self, v: &mut Verifier<'_>, id: u32, e: &BlockEntry, block: &TreeletBlock<'_>) {
        self.counts.lod_levels = self.counts.lod_levels.max(u32::from(e.level) + 1);
        let slots = self.slots.take(id, block.treelet_count());
        for (t, slot) in slots.into_iter().enumerate() {
            let Slot::Pending(inh) = slot else {
                v.note_code(
                    Code::TreeUnreachable,
                    format!("treelet {t} is not reached from the root"),
                    Some(id),
                );
                continue;
            };
            self.slots.reached += 1;
            if let Ok(span) = block.treelet_span(t) {
                self.treelet(v, id, e, block, span.start, inh);
            }
        }
    }

    /// Walks one treelet from its root node at `root`, checking each node it reaches.
    fn treelet(
        &mut self,
        v: &mut Verifier<'_>,
        id: u32,
        e: &BlockEntry,
        block: &TreeletBlock<'_>,
        root: usize,
        inh: Inherit,
    ) {
        let mut stack = std::mem::take(&mut self.stack);
        stack.clear();
        stack.push((root, inh.cell, inh.depth + 1));
        while let Some((pos, cell, depth)) = stack.pop() {
            if depth > MAX_DEPTH {
                v.note_code(
                    Code::TreeDepth,
                    format!("node at {pos} is at depth {depth}, over {MAX_DEPTH}"),
                    Some(id),
                );
                continue;
            }
            self.counts.depth = self.counts.depth.max(depth);
            let Ok(node) = block.node(pos) else { continue };
            let at = At {
                id,
                level: e.level,
                pos,
                cell,
            };
            match node {
                Node::Basic {
                    axis,
                    split,
                    left,
                    right,
                } => {
                    self.counts.basic_nodes += 1;
                    let (lc, rc) = split_cell(v, at, axis, split);
                    if right != 0 {
                        stack.push((TreeletBlock::child_pos(pos, right), rc, depth + 1));
                    }
                    if left != 0 {
                        stack.push((TreeletBlock::child_pos(pos, left), lc, depth + 1));
                    }
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
                    self.counts.lod_nodes += 1;
                    self.count_voxel(block, voxel_offset);
                    lod_radius(v, at, radius, inh.max_radius);
                    if let Ok(r) = block.rlod(voxel_offset) {
                        rlod_plane(v, at, radius, &r);
                    }
                    let (lc, rc) = split_cell(v, at, axis, split);
                    let inherit = |cell| Inherit {
                        cell,
                        depth,
                        max_radius: radius,
                    };
                    let children = [(left_present, inherit(lc)), (right_present, inherit(rc))];
                    self.lod_children(v, at, child_block, child_treelet, children);
                    self.proxy(v, at, proxy);
                }
                Node::Leaf {
                    count,
                    first,
                    block: tb,
                } => self.leaf(v, at, tb, first, count),
            }
        }
        self.stack = stack;
    }

    /// Counts the voxel of the LOD entry at `voxel_offset`, by its kind (none in a file
    /// without voxels).
    fn count_voxel(&mut self, block: &TreeletBlock<'_>, voxel_offset: u32) {
        match block.voxel(voxel_offset) {
            Ok(Voxel::Single(..)) => self.counts.voxels_single += 1,
            Ok(Voxel::Six(..)) => self.counts.voxels_six += 1,
            Err(_) => {}
        }
    }

    /// Counts a leaf; reports one whose `count` entries from `first` are not all in triangle
    /// block `tb`.
    fn leaf(&mut self, v: &mut Verifier<'_>, at: At, tb: u32, first: u16, count: u16) {
        self.counts.leaves += 1;
        let list = match (self.entry(tb), self.facts.get(tb as usize)) {
            (Some(te), Some(Some(BlockFacts::Triangle { list, .. })))
                if te.kind == BlockKind::Triangle =>
            {
                Some(*list)
            }
            _ => None,
        };
        let pos = at.pos;
        match list {
            Some(l) if u32::from(first) + u32::from(count) <= l => {}
            Some(l) => v.note_code(
                Code::TreeReference,
                format!(
                    "leaf at {pos}: entries {first}+{count} pass the {l} of triangle block {tb}"
                ),
                Some(at.id),
            ),
            None => v.note_code(
                Code::TreeReference,
                format!("leaf at {pos}: block {tb} is not a valid triangle block"),
                Some(at.id),
            ),
        }
    }

    /// Marks the treelets a LOD node points to as pending, each present child of `children`
    /// with what it inherits: treelets from `first` of block `child_block`, which must be a
    /// treelet block one level below the node's. Reports a treelet reached twice.
    fn lod_children(
        &mut self,
        v: &mut Verifier<'_>,
        at: At,
        child_block: u32,
        first: u32,
        children: [(bool, Inherit); 2],
    ) {
        let pos = at.pos;
        let Some(ce) = self
            .entry(child_block)
            .filter(|c| c.kind == BlockKind::Treelet)
        else {
            v.note_code(
                Code::TreeReference,
                format!("LOD node at {pos}: child block {child_block} is not a treelet block"),
                Some(at.id),
            );
            return;
        };
        if u32::from(ce.level) != u32::from(at.level) + 1 {
            v.note_code(
                Code::TreeLevel,
                format!(
                    "LOD node at {pos}: child block {child_block} has level {}, not {}",
                    ce.level,
                    at.level + 1
                ),
                Some(at.id),
            );
            return;
        }
        let present = children.map(|(p, _)| p);
        for (index, (_, inherit)) in lod_child_treelets(first, present).into_iter().zip(children) {
            let Some(index) = index else { continue };
            if index >= ce.item_count {
                v.note_code(
                    Code::TreeReference,
                    format!(
                        "LOD node at {pos}: treelet {index} of block {child_block}, which has {}",
                        ce.item_count
                    ),
                    Some(at.id),
                );
                return;
            }
            let key = TreeletRef {
                block: child_block,
                treelet: index,
            };
            if !self
                .slots
                .await_treelet(key, self.treelet_count(child_block), inherit)
            {
                v.note_code(Code::TreeShared, format!("LOD node at {pos}: treelet {index} of block {child_block} is reached twice"), Some(at.id));
            }
        }
    }

    /// Reports a LOD node's proxy that is not the one standing for the node's block.
    fn proxy(&self, v: &mut Verifier<'_>, at: At, proxy: u32) {
        if proxy == NO_PROXY {
            return;
        }
        let (id, pos) = (at.id, at.pos);
        match self.proxy_blocks.get(proxy as usize) {
            Some(&b) if b == id => {}
            Some(&b) => v.note_code(
                Code::TreeReference,
                format!("LOD node at {pos}: proxy {proxy} stands for block {b}, not this one"),
                Some(id),
            ),
            None => v.note_code(
                Code::TreeReference,
                format!(
                    "LOD node at {pos}: proxy {proxy} of {}",
                    self.proxy_blocks.len()
                ),
                Some(id),
            ),
        }
    }

    /// Compares what the walk counted with the metadata, the schema and the feature bits.
    fn totals(&mut self, v: &mut Verifier<'_>, index: &Index) {
        let Some(meta) = &index.metadata else { return };
        let mut c = self.counts;
        c.treelets = self.slots.reached;
        c.proxies = self.proxy_blocks.len() as u64;
        let mut max_material: Option<u16> = None;
        let mut parts: Vec<Option<PartFacts>> = vec![None; meta.parts.len()];
        for (id, f) in (0u32..).zip(self.facts) {
            if let Some(BlockFacts::Triangle {
                triangles,
                vertices,
                primaries,
                max_material: mm,
                parts: block_parts,
                ..
            }) = f
            {
                for bp in block_parts {
                    if let Some(slot) = parts.get_mut(bp.part as usize) {
                        match slot {
                            Some(p) => p.merge(bp),
                            None => *slot = Some(*bp),
                        }
                    }
                }
                c.triangles += u64::from(*primaries);
                c.triangle_records += u64::from(*triangles);
                c.vertices += u64::from(*vertices);
                if let Some(m) = *mm {
                    if usize::from(m) >= meta.materials.len() {
                        v.note_code(
                            Code::TreeMaterial,
                            format!("material {m} of {}", meta.materials.len()),
                            Some(id),
                        );
                    }
                    max_material = max_material.max(Some(m));
                }
            }
        }
        let m = meta.counts;
        let fields: [(&str, u64, u64); 12] = [
            ("triangles", m.triangles, c.triangles),
            ("triangle_records", m.triangle_records, c.triangle_records),
            ("vertices", m.vertices, c.vertices),
            ("basic_nodes", m.basic_nodes, c.basic_nodes),
            ("lod_nodes", m.lod_nodes, c.lod_nodes),
            ("leaves", m.leaves, c.leaves),
            ("voxels_single", m.voxels_single, c.voxels_single),
            ("voxels_six", m.voxels_six, c.voxels_six),
            ("proxies", m.proxies, c.proxies),
            ("treelets", m.treelets, c.treelets),
            ("depth", u64::from(m.depth), u64::from(c.depth)),
            (
                "lod_levels",
                u64::from(m.lod_levels),
                u64::from(c.lod_levels),
            ),
        ];
        for (name, said, found) in fields {
            if said != found {
                v.note_code(
                    Code::TreeCounts,
                    format!("metadata counts.{name} = {said}, the tree has {found}"),
                    None,
                );
            }
        }
        if meta.schema.six_sample_voxels != (c.voxels_six > 0) {
            v.note_code(
                Code::TreeCounts,
                format!(
                    "schema.six_sample_voxels = {}, the tree has {} six-sample voxels",
                    meta.schema.six_sample_voxels, c.voxels_six
                ),
                None,
            );
        }
        part_totals(v, meta, &parts);
        let features = index.header.compatible_features;
        let has_proxy_blocks = index
            .entries
            .iter()
            .flatten()
            .any(|e| e.kind == BlockKind::Proxy);
        if (features & COMPAT_PROXIES != 0) != has_proxy_blocks
            || (features & COMPAT_LOD_VOXELS != 0) != (c.lod_nodes > 0)
        {
            v.note_code(
                Code::HeaderFeatureMismatch,
                format!("compatible features {features:#x} do not match the content"),
                None,
            );
        }
    }
}

/// Compares each part's triangles and bounds with what the triangle blocks hold (`found`, by
/// part id; spec §9): the counts exactly (`PART_COUNTS`), the bounds as the exact box of the
/// corners, all zero for a part without triangles (`PART_BOUNDS`).
fn part_totals(v: &mut Verifier<'_>, meta: &Metadata, found: &[Option<PartFacts>]) {
    for (i, (part, f)) in meta.parts.iter().zip(found).enumerate() {
        let (triangles, lo, hi) = match f {
            Some(f) => (f.triangles, f.bounds_min, f.bounds_max),
            None => (0, [0.0; 3], [0.0; 3]),
        };
        if part.triangles != triangles {
            v.note_code(
                Code::PartCounts,
                format!(
                    "part {i} `{}` says {} triangles, the blocks hold {triangles}",
                    part.name, part.triangles
                ),
                None,
            );
        }
        // Equal as numbers (the bounds are exact; -0 and +0 are one corner).
        let same = |a: [f32; 3], b: [f32; 3]| a == b;
        if !same(part.bounds_min, lo) || !same(part.bounds_max, hi) {
            v.note_code(
                Code::PartBounds,
                format!(
                    "part {i} `{}` has bounds {:?} .. {:?}, its triangles {lo:?} .. {hi:?}",
                    part.name, part.bounds_min, part.bounds_max
                ),
                None,
            );
        }
    }
}

/// Reports a LOD area that its LOD nodes' entries do not tile (spec §6.2): taken in node order
/// (treelets in order, each in preorder, which is address order), every entry starts where the
/// previous one ended, the first at 0, and the last ends at the area's end. So no byte of the
/// area is unreferenced and no two LOD nodes share an entry.
fn lod_area(v: &mut Verifier<'_>, id: u32, block: &TreeletBlock<'_>) {
    let mut next = 0usize;
    let mut first_problem = None;
    let walked = block.walk_lods(|_, pos, node, entry| {
        if let Node::Lod { voxel_offset, .. } = node {
            let at = *voxel_offset as usize;
            if at != next && first_problem.is_none() {
                first_problem = Some(format!(
                    "LOD node at {pos}: its LOD entry is at {at}, the previous one ends at {next}"
                ));
            }
            next = at.saturating_add(entry.byte_len());
        }
        Ok(())
    });
    if walked.is_err() {
        return; // the block pass has reported it
    }
    let area = block.voxel_area().len();
    let problem = first_problem.or_else(|| {
        (next != area).then(|| format!("LOD entries end at {next}, the LOD area at {area}"))
    });
    if let Some(msg) = problem {
        v.note_code(Code::LodArea, msg, Some(id));
    }
}

/// Reports a LOD node whose radius exceeds its `ancestor`'s (the nearest LOD node above it) or
/// falls short of its cell's half diagonal.
fn lod_radius(v: &mut Verifier<'_>, at: At, radius: f32, ancestor: f32) {
    let (id, pos, cell) = (at.id, at.pos, at.cell);
    if radius > ancestor {
        v.note_code(
            Code::TreeLodRadius,
            format!("LOD node at {pos}: radius {radius} exceeds its ancestor's {ancestor}"),
            Some(id),
        );
    }
    let half_diag = (0..3)
        .map(|a| (cell[1][a] - cell[0][a]).powi(2))
        .sum::<f64>()
        .sqrt()
        / 2.0;
    if f64::from(radius) < half_diag * (1.0 - 1e-6) {
        v.note_code(
            Code::TreeLodRadius,
            format!(
                "LOD node at {pos}: radius {radius} is below its cell's half diagonal {half_diag}"
            ),
            Some(id),
        );
    }
}

/// Reports an R-LOD plane that misses its node's enclosing sphere: the plane is fitted through
/// the centroid of the node's clipped triangles, which lies in the cell.
fn rlod_plane(v: &mut Verifier<'_>, at: At, radius: f32, r: &Rlod) {
    let (id, pos, cell) = (at.id, at.pos, at.cell);
    let centre_distance = (0..3)
        .map(|a| f64::from(r.normal[a]) * (cell[0][a] + cell[1][a]) / 2.0)
        .sum::<f64>()
        - f64::from(r.offset);
    let reach = f64::from(radius) * (1.0 + 1e-3) + 1e-30;
    if centre_distance.abs() > reach {
        v.note_code(
            Code::Rlod,
            format!(
                "LOD node at {pos}: its R-LOD plane lies {:.3e} from the cell's centre, beyond the radius {radius}",
                centre_distance.abs()
            ),
            Some(id),
        );
    }
}

/// The two child cells of a split; reports a split plane outside the cell.
fn split_cell(
    v: &mut Verifier<'_>,
    at: At,
    axis: u8,
    split: f32,
) -> ([[f64; 3]; 2], [[f64; 3]; 2]) {
    let (id, pos, cell) = (at.id, at.pos, at.cell);
    let a = usize::from(axis.min(2));
    let s = f64::from(split);
    if !(cell[0][a] <= s && s <= cell[1][a]) {
        v.note_code(
            Code::TreeSplit,
            format!(
                "node at {pos}: split {split} on axis {a} outside the cell {}..{}",
                cell[0][a], cell[1][a]
            ),
            Some(id),
        );
    }
    // max/min rather than clamp: they cannot panic, whatever the bounds hold.
    let s = s.max(cell[0][a]).min(cell[1][a]);
    let (mut l, mut r) = (cell, cell);
    l[1][a] = s;
    r[0][a] = s;
    (l, r)
}
