//! The treelet plan: which nodes are basic, LOD or leaf, how the tree is cut into treelets, and
//! which treelet block (and index in it) every treelet gets — all before anything is encoded,
//! because LOD nodes must name their children's block.

use std::collections::BTreeMap;

use oocfmt::records::{
    LodKinds, Rlod, TreeletBlockWriter, NODE_BASIC_LEN, NODE_LEAF_LEN, NODE_LOD_LEN, NO_PROXY,
    PART_WORD_LEN, RLOD_LEN,
};
use rayon::prelude::*;

use super::LayoutError;
use crate::kdtree::{KdNode, KdTree, NodeId};
use crate::lod::LodData;
use oocfmt_meshio::mesh::{Bounds, Mesh};

/// The largest node area a treelet may have: child offsets are 12-bit counts of 8-byte units.
const MAX_TREELET_NODE_BYTES: usize = 8 * 4096;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) enum Role {
    #[default]
    Basic,
    Lod,
    Leaf,
}

/// What the layout knows about one tree node.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NodeInfo {
    pub role: Role,
    pub cell: Bounds,
    /// LOD nodes: index into [`TreePlan::lod`].
    pub lod: u32,
    /// LOD nodes: proxy id, numbered in file order.
    pub proxy: u32,
    /// LOD nodes: the block of the child treelets and the index of the first one in it.
    pub child_block: u32,
    pub child_treelet: u32,
    /// The treelet block holding this node.
    pub block: u32,
}

impl Default for NodeInfo {
    fn default() -> Self {
        NodeInfo {
            role: Role::Basic,
            cell: Bounds::EMPTY,
            lod: 0,
            proxy: NO_PROXY,
            child_block: 0,
            child_treelet: 0,
            block: 0,
        }
    }
}

/// A treelet: its nodes in preorder, and the bytes it adds to a block.
#[derive(Clone, Debug)]
pub(crate) struct Treelet {
    pub root: NodeId,
    pub node_bytes: usize,
    pub voxel_bytes: usize,
    pub nodes: Vec<NodeId>,
    /// Bytes of each node and the part of its subtree inside the treelet, in `nodes` order.
    pub spans: Vec<usize>,
}

#[derive(Clone, Debug, Default)]
pub(crate) struct PlannedBlock {
    pub level: u16,
    pub treelets: Vec<usize>,
    node_bytes: usize,
    voxel_bytes: usize,
}

impl PlannedBlock {
    fn raw_len_with(
        &self,
        extra_treelets: usize,
        extra_nodes: usize,
        extra_voxels: usize,
    ) -> usize {
        TreeletBlockWriter::raw_len_for(
            self.treelets.len() + extra_treelets,
            self.node_bytes + extra_nodes,
            self.voxel_bytes + extra_voxels,
        )
    }
}

#[derive(Clone, Debug, Default)]
pub(crate) struct TreePlan {
    pub info: Vec<NodeInfo>,
    pub treelets: Vec<Treelet>,
    pub blocks: Vec<PlannedBlock>,
    /// LOD data in arena order of the LOD nodes (indexed by [`NodeInfo::lod`]).
    pub lod: Vec<LodData>,
    /// What the LOD entries hold.
    pub kinds: LodKinds,
    /// With R-LODs: the records, same index as `lod`.
    pub rlods: Vec<Rlod>,
    /// The LOD nodes that got a proxy, in file order: position = proxy id. Coarse levels come
    /// first, so a cap on proxies keeps the ones that stand for the biggest subtrees.
    pub lod_order: Vec<NodeId>,
    pub lod_levels: u32,
    /// Node levels of the tree (a lone root: 1; none: 0).
    pub depth: u32,
    /// The root's treelet, when [`PlanSpec::detach_root`] kept it out of the blocks.
    pub detached: Option<usize>,
}

impl TreePlan {
    pub fn info(&self, id: NodeId) -> NodeInfo {
        self.info.get(id.index()).copied().unwrap_or_default()
    }

    /// Renumbers the proxies as if planned with a `proxy_base` larger by `by`: a chunk is
    /// planned before the proxies of the chunks before it are counted.
    pub fn shift_proxies(&mut self, by: u32) -> Result<(), LayoutError> {
        for i in self.info.iter_mut().filter(|i| i.proxy != NO_PROXY) {
            i.proxy = i
                .proxy
                .checked_add(by)
                .filter(|&id| id != NO_PROXY)
                .ok_or(LayoutError::TooMany("LOD nodes"))?;
        }
        Ok(())
    }

    pub fn lod_data(&self, id: NodeId) -> Option<&LodData> {
        self.lod.get(self.info(id).lod as usize)
    }

    pub fn rlod(&self, id: NodeId) -> Option<&Rlod> {
        self.rlods.get(self.info(id).lod as usize)
    }

    /// Bytes of a LOD node's entry in the LOD area: voxel, R-LOD record, part word.
    pub fn lod_entry_bytes(&self, id: NodeId) -> usize {
        let voxel = if self.kinds.voxel {
            self.lod_data(id)
                .and_then(|d| d.voxel.as_ref())
                .map_or(0, |v| v.byte_len(self.kinds.filtered))
        } else {
            0
        };
        voxel
            + if self.kinds.rlod { RLOD_LEN } else { 0 }
            + if self.kinds.parts { PART_WORD_LEN } else { 0 }
    }
}

/// A LOD node and its children, the roots of its child treelets.
type ChildRoots = (NodeId, [Option<NodeId>; 2]);

/// A LOD node's present children, cut into treelets that must share a block, left first.
struct Unit {
    parent: Option<NodeId>,
    treelets: Vec<usize>,
}

/// Where a tree sits in the scene and what its layout is given instead of computing: the same
/// planner lays out a whole in-core tree, an out-of-core chunk, and the top above the chunks.
pub(crate) struct PlanSpec<'a> {
    pub treelet_height: u8,
    pub block_size: usize,
    /// At most this many LOD nodes get a proxy, the coarsest first.
    pub max_proxies: usize,
    /// Node level of the tree's root in the scene (0: the tree is the scene's).
    pub depth_offset: u32,
    /// The id this plan gives its first proxy.
    pub proxy_base: u32,
    /// Plan the root's treelet but pack it elsewhere (an out-of-core chunk's top treelet goes
    /// to the top of the scene): packing starts with the children of its LOD nodes, which get
    /// no proxy id here.
    pub detach_root: bool,
    /// The LOD level of the first blocks packed.
    pub first_level: u16,
    pub lod: LodSource<'a>,
    /// LOD nodes whose child treelets live elsewhere, with their (child block, first child
    /// treelet): nothing below them is planned.
    pub external: &'a BTreeMap<NodeId, (u32, u32)>,
}

/// Where LOD nodes' data comes from.
pub(crate) enum LodSource<'a> {
    /// Ray-sampled against the tree's own subtrees (voxels and proxies) and, when `kinds`
    /// has them, R-LOD planes fitted to them; the LOD entries hold `kinds` (an R-LOD-only
    /// entry's part word is its plane's largest part, not the rays').
    Sample {
        mesh: &'a Mesh,
        threshold: f32,
        kinds: LodKinds,
    },
    /// Computed elsewhere, by node: the LOD data and, when `kinds` has them, the R-LOD.
    Given {
        data: &'a dyn Fn(NodeId) -> Option<(LodData, Option<Rlod>)>,
        kinds: LodKinds,
    },
}

/// Plans the treelet blocks of `tree`, the scene's whole tree over `mesh`. `voxel_threshold`
/// feeds the LOD estimate, whose voxel sizes (one or six samples) the block packing needs.
pub(crate) fn plan_tree(
    mesh: &Mesh,
    tree: &KdTree,
    treelet_height: u8,
    voxel_threshold: f32,
    kinds: LodKinds,
    block_size: usize,
    max_proxies: usize,
) -> Result<TreePlan, LayoutError> {
    plan_tree_with(
        tree,
        &PlanSpec {
            treelet_height,
            block_size,
            max_proxies,
            depth_offset: 0,
            proxy_base: 0,
            detach_root: false,
            first_level: 0,
            lod: LodSource::Sample {
                mesh,
                threshold: voxel_threshold,
                kinds,
            },
            external: &BTreeMap::new(),
        },
    )
}

/// Plans the treelet blocks of `tree` as `spec` places it.
pub(crate) fn plan_tree_with(tree: &KdTree, spec: &PlanSpec) -> Result<TreePlan, LayoutError> {
    let mut plan = TreePlan {
        info: vec![NodeInfo::default(); tree.nodes().len()],
        ..TreePlan::default()
    };
    let Some(root) = tree.root() else {
        return Ok(plan);
    };
    // The subtree totals the sampling needs take a serial pass over the tree: beside the
    // serial classification.
    let (info, levels) = (&mut plan.info, &mut plan.depth);
    let (height, offset, max_proxies) = (spec.treelet_height, spec.depth_offset, spec.max_proxies);
    let sampled = match &spec.lod {
        LodSource::Sample { mesh, .. } => Some(*mesh),
        LodSource::Given { .. } => None,
    };
    let ((lod_nodes, proxied), totals) = rayon::join(
        || {
            let lod_nodes = classify(tree, root, height, offset, info, levels);
            let mut proxied = vec![false; tree.nodes().len()];
            for id in file_order_lod_nodes(tree, root, info, max_proxies) {
                if let Some(p) = proxied.get_mut(id.index()) {
                    *p = true;
                }
            }
            (lod_nodes, proxied)
        },
        || sampled.map(|mesh| crate::lod::triangle_totals(mesh, tree)),
    );
    let wants = |id: NodeId| proxied.get(id.index()).copied().unwrap_or(false);
    plan.lod = match &spec.lod {
        LodSource::Sample {
            mesh,
            threshold,
            kinds,
        } => {
            plan.kinds = *kinds;
            let mut parts = Vec::new();
            if kinds.rlod {
                (plan.rlods, parts) = crate::lod::rlods(mesh, tree, &lod_nodes)
                    .into_iter()
                    .unzip();
            }
            let totals = totals.ok_or(LayoutError::Internal("no subtree totals"))?;
            let info = &plan.info;
            let cell = |id: NodeId| info.get(id.index()).map_or(Bounds::EMPTY, |i| i.cell);
            let sample = crate::lod::Sampling {
                threshold: *threshold,
                voxels: kinds.voxel,
            };
            let mut lod =
                crate::lod::compute_in(mesh, tree, &lod_nodes, &cell, &totals, sample, &wants);
            if !kinds.voxel && mesh.part_ids.is_some() {
                for (d, &p) in lod.iter_mut().zip(&parts) {
                    d.part = p;
                }
            }
            lod
        }
        LodSource::Given { data, kinds } => {
            plan.kinds = *kinds;
            let mut lod = Vec::with_capacity(lod_nodes.len());
            for &n in &lod_nodes {
                let (d, r) = data(n).ok_or(LayoutError::Internal("a LOD node has no LOD data"))?;
                lod.push(d);
                if kinds.rlod {
                    plan.rlods
                        .push(r.ok_or(LayoutError::Internal("a LOD node has no R-LOD"))?);
                }
            }
            lod
        }
    };
    let root_treelet = make_treelet(tree, &mut plan, root);
    let mut units = if spec.detach_root {
        plan.detached = Some(root_treelet);
        let kids = expand(&mut plan, tree, root_treelet, spec, &|_| false)?;
        number_treelets(&mut plan, tree, kids)
    } else {
        vec![Unit {
            parent: None,
            treelets: vec![root_treelet],
        }]
    };
    let mut level = spec.first_level;
    while !units.is_empty() {
        let first_block = plan.blocks.len();
        pack_level(&mut plan, &units, level, spec.block_size)?;
        let mut next = Vec::new();
        for b in first_block..plan.blocks.len() {
            let treelets = plan
                .blocks
                .get(b)
                .map(|blk| blk.treelets.clone())
                .unwrap_or_default();
            for t in treelets {
                next.extend(expand(&mut plan, tree, t, spec, &wants)?);
            }
        }
        units = number_treelets(&mut plan, tree, next);
        level = level
            .checked_add(1)
            .ok_or(LayoutError::TooMany("LOD levels"))?;
    }
    plan.lod_levels = u32::from(level);
    Ok(plan)
}

/// The LOD nodes of treelet `t` with the roots of their child treelets, giving proxy ids to
/// those `wants` names on the way (numbered in the order the file stores them). LOD nodes
/// whose children live elsewhere get their references instead.
fn expand(
    plan: &mut TreePlan,
    tree: &KdTree,
    t: usize,
    spec: &PlanSpec,
    wants: &dyn Fn(NodeId) -> bool,
) -> Result<Vec<ChildRoots>, LayoutError> {
    let lods: Vec<NodeId> = plan
        .treelets
        .get(t)
        .map(|tl| {
            tl.nodes
                .iter()
                .copied()
                .filter(|&n| plan.info(n).role == Role::Lod)
                .collect()
        })
        .unwrap_or_default();
    let mut parents = Vec::new();
    for n in lods {
        if wants(n) {
            let id = u32::try_from(plan.lod_order.len())
                .ok()
                .and_then(|k| k.checked_add(spec.proxy_base))
                .filter(|&id| id != NO_PROXY)
                .ok_or(LayoutError::TooMany("LOD nodes"))?;
            if let Some(i) = plan.info.get_mut(n.index()) {
                i.proxy = id;
            }
            plan.lod_order.push(n);
        }
        if let Some(&(block, first)) = spec.external.get(&n) {
            if let Some(i) = plan.info.get_mut(n.index()) {
                i.child_block = block;
                i.child_treelet = first;
            }
            continue;
        }
        parents.push((n, tree.children(n)));
    }
    Ok(parents)
}

/// The units of child treelets under `parents`, in order: their treelets are collected in
/// parallel (they share no node), then numbered in the order a serial walk would number them.
fn number_treelets(plan: &mut TreePlan, tree: &KdTree, parents: Vec<ChildRoots>) -> Vec<Unit> {
    let roots: Vec<NodeId> = parents
        .iter()
        .flat_map(|(_, kids)| kids.iter().flatten())
        .copied()
        .collect();
    let plan_ref = &*plan;
    let collected: Vec<Treelet> = roots
        .par_iter()
        .map(|&r| collect_treelet(tree, plan_ref, r))
        .collect();
    let mut collected = collected.into_iter();
    parents
        .into_iter()
        .map(|(parent, kids)| Unit {
            parent: Some(parent),
            treelets: kids
                .iter()
                .flatten()
                .zip(collected.by_ref())
                .map(|(_, treelet)| {
                    plan.treelets.push(treelet);
                    plan.treelets.len() - 1
                })
                .collect(),
        })
        .collect()
}

/// The first `max` LOD nodes in the order the file stores them: level by level, each level in
/// its parents' order, each treelet in preorder. Depends on the tree's shape only, so the nodes
/// that will get a proxy are known before any LOD data is sampled.
fn file_order_lod_nodes(tree: &KdTree, root: NodeId, info: &[NodeInfo], max: usize) -> Vec<NodeId> {
    let role = |id: NodeId| info.get(id.index()).map_or(Role::Leaf, |i| i.role);
    let mut out = Vec::new();
    let mut roots = vec![root];
    while !roots.is_empty() && out.len() < max {
        let mut next = Vec::new();
        for r in roots {
            let mut stack = vec![r];
            while let Some(id) = stack.pop() {
                match role(id) {
                    Role::Basic => {
                        let [l, rr] = tree.children(id);
                        stack.extend(rr);
                        stack.extend(l);
                    }
                    Role::Lod => {
                        if out.len() < max {
                            out.push(id);
                        }
                        next.extend(tree.children(id).into_iter().flatten());
                    }
                    Role::Leaf => {}
                }
            }
        }
        roots = next;
    }
    out
}

/// Whether an inner node at scene depth `depth` (the root 0) is a LOD node: the last level of
/// each treelet of height `height`, `depth % H == H - 1` (spec §6).
pub(crate) fn is_lod_depth(depth: u32, height: u8) -> bool {
    let h = u32::from(height.max(1));
    depth % h == h - 1
}

/// Records every node's cell and role and the tree's node levels in `levels`; returns the LOD
/// nodes in arena order. An inner node at scene depth `d` (`offset` is the depth of this tree's
/// root) is a LOD node when [`is_lod_depth`] says so.
fn classify(
    tree: &KdTree,
    root: NodeId,
    height: u8,
    offset: u32,
    info: &mut [NodeInfo],
    levels: &mut u32,
) -> Vec<NodeId> {
    let mut stack = vec![(root, offset, tree.bounds())];
    let mut deepest = offset;
    while let Some((id, depth, cell)) = stack.pop() {
        deepest = deepest.max(depth);
        let role = match tree.node(id) {
            Some(&KdNode::Inner {
                axis,
                split,
                children,
            }) => {
                let (lo, hi) = cell.split(usize::from(axis), split);
                for (c, cc) in children.into_iter().zip([lo, hi]) {
                    if let Some(c) = c {
                        stack.push((c, depth + 1, cc));
                    }
                }
                if is_lod_depth(depth, height) {
                    Role::Lod
                } else {
                    Role::Basic
                }
            }
            _ => Role::Leaf,
        };
        if let Some(i) = info.get_mut(id.index()) {
            i.role = role;
            i.cell = cell;
        }
    }
    let mut lods = Vec::new();
    *levels = deepest - offset + 1;
    for (k, i) in info.iter_mut().enumerate() {
        if i.role == Role::Lod {
            // Fits: there are fewer LOD nodes than node ids, which are `u32`.
            i.lod = lods.len() as u32;
            lods.push(NodeId(k as u32));
        }
    }
    lods
}

/// Collects the treelet rooted at `root` and returns its index.
fn make_treelet(tree: &KdTree, plan: &mut TreePlan, root: NodeId) -> usize {
    let treelet = collect_treelet(tree, plan, root);
    plan.treelets.push(treelet);
    plan.treelets.len() - 1
}

/// The treelet rooted at `root`: its nodes in preorder, down to and including LOD nodes and
/// leaves, with their byte spans. Reads the nodes' roles and LOD sizes only, so treelets can
/// be collected in parallel.
fn collect_treelet(tree: &KdTree, plan: &TreePlan, root: NodeId) -> Treelet {
    let mut nodes = Vec::new();
    let mut stack = vec![root];
    while let Some(id) = stack.pop() {
        nodes.push(id);
        if plan.info(id).role == Role::Basic {
            let [l, r] = tree.children(id);
            stack.extend(r);
            stack.extend(l);
        }
    }
    let mut voxel_bytes = 0;
    let mut spans = vec![0; nodes.len()];
    // Reverse preorder meets a basic node right after its subtrees, high side first: the
    // spans of its children are then the last ones on `done`.
    let mut done: Vec<usize> = Vec::new();
    for (&id, slot) in nodes.iter().zip(spans.iter_mut()).rev() {
        let span = match plan.info(id).role {
            Role::Leaf => NODE_LEAF_LEN,
            Role::Lod => {
                voxel_bytes += plan.lod_entry_bytes(id);
                NODE_LOD_LEN
            }
            Role::Basic => {
                let kids = tree.children(id).iter().flatten().count();
                let below: usize = done.drain(done.len().saturating_sub(kids)..).sum();
                NODE_BASIC_LEN + below
            }
        };
        *slot = span;
        done.push(span);
    }
    Treelet {
        root,
        node_bytes: spans.first().copied().unwrap_or(0),
        voxel_bytes,
        nodes,
        spans,
    }
}

/// Packs one level's units into new blocks, consecutively, and points every parent LOD node
/// at its children's block and first treelet.
fn pack_level(
    plan: &mut TreePlan,
    units: &[Unit],
    level: u16,
    block_size: usize,
) -> Result<(), LayoutError> {
    let mut current = PlannedBlock {
        level,
        ..PlannedBlock::default()
    };
    for unit in units {
        let (mut nodes, mut voxels) = (0, 0);
        for t in unit.treelets.iter().filter_map(|&t| plan.treelets.get(t)) {
            if t.node_bytes > MAX_TREELET_NODE_BYTES {
                return Err(LayoutError::TreeletSpan {
                    bytes: t.node_bytes,
                });
            }
            nodes += t.node_bytes;
            voxels += t.voxel_bytes;
        }
        let n = unit.treelets.len();
        if current.raw_len_with(n, nodes, voxels) > block_size && !current.treelets.is_empty() {
            plan.blocks.push(std::mem::replace(
                &mut current,
                PlannedBlock {
                    level,
                    ..PlannedBlock::default()
                },
            ));
        }
        let needed = current.raw_len_with(n, nodes, voxels);
        if needed > block_size {
            return Err(LayoutError::TreeletsTooLarge {
                bytes: needed,
                block_size,
            });
        }
        let block =
            u32::try_from(plan.blocks.len()).map_err(|_| LayoutError::TooMany("treelet blocks"))?;
        let first = u32::try_from(current.treelets.len())
            .map_err(|_| LayoutError::TooMany("treelets in a block"))?;
        if let Some(p) = unit.parent.and_then(|p| plan.info.get_mut(p.index())) {
            p.child_block = block;
            p.child_treelet = first;
        }
        for &t in &unit.treelets {
            for m in plan.treelets.get(t).map_or(&[][..], |tl| &tl.nodes[..]) {
                if let Some(i) = plan.info.get_mut(m.index()) {
                    i.block = block;
                }
            }
            current.treelets.push(t);
        }
        current.node_bytes += nodes;
        current.voxel_bytes += voxels;
    }
    if !current.treelets.is_empty() {
        plan.blocks.push(current);
    }
    Ok(())
}
