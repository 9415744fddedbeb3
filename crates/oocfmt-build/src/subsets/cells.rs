//! The plan's cells: grown from a sample of centroids by median cuts, then counted and fitted
//! by routing every triangle down the cuts as the out-of-core split routes it.

use super::plan::{Plan, PlanNode};
use super::SubsetError;
use crate::layout::plan::is_lod_depth;
use crate::lod::rlod::{PlaneFit, PlaneMoments};
use crate::ooc::chunk::SceneFacts;
use crate::ooc::soup::{SoupTriangle, Tally};
use crate::ooc::split::{Cut, Sides, MAX_SPLIT_DEPTH};
use oocfmt_meshio::import::{ImportError, InputTriangle, Location, Store};
use oocfmt_meshio::mesh::Bounds;

/// Centroids the first pass keeps: enough to place a few thousand cuts.
pub(super) const SAMPLE_SIZE: usize = 1 << 18;

/// A cell of the plan.
pub(super) struct Cell {
    pub cell: Bounds,
    pub depth: u32,
    pub kind: CellKind,
}

pub(super) enum CellKind {
    /// A subset's cell and the records routed to it.
    Leaf { records: u64 },
    /// A median cut, its halves, and its R-LOD plane once fitted.
    Inner {
        cut: Cut,
        children: [usize; 2],
        fit: Option<PlaneFit>,
    },
}

/// The cut tree; node 0 is the scene.
pub(super) struct CellTree {
    pub nodes: Vec<Cell>,
}

impl CellTree {
    /// Cuts the scene `bounds` at medians, always the cell holding the most `sample`
    /// centroids (ties: the first made), until there are `n` cells or none can be cut.
    pub fn grow(bounds: Bounds, sample: &[[f32; 3]], n: u32) -> CellTree {
        let mut nodes = vec![Cell {
            cell: bounds,
            depth: 0,
            kind: CellKind::Leaf { records: 0 },
        }];
        let mut points: Vec<Vec<[f32; 3]>> = vec![sample.to_vec()];
        let mut leaves = 1u32;
        while leaves < n {
            let pick = (0..nodes.len())
                .filter(|&k| splittable(&nodes[k]))
                .max_by(|&a, &b| points[a].len().cmp(&points[b].len()).then(b.cmp(&a)));
            let Some(k) = pick else { break };
            let cut = Cut::middle(&nodes[k].cell);
            let (lo, hi) = nodes[k].cell.split(cut.axis, cut.mid);
            let (l, r): (Vec<_>, Vec<_>) = std::mem::take(&mut points[k])
                .into_iter()
                .partition(|p| p[cut.axis] <= cut.mid);
            let depth = nodes[k].depth + 1;
            let first = nodes.len();
            for cell in [lo, hi] {
                nodes.push(Cell {
                    cell,
                    depth,
                    kind: CellKind::Leaf { records: 0 },
                });
            }
            points.push(l);
            points.push(r);
            nodes[k].kind = CellKind::Inner {
                cut,
                children: [first, first + 1],
                fit: None,
            };
            leaves += 1;
        }
        CellTree { nodes }
    }

    /// The cut tree of `plan`, its counts cleared, for routing again: a side the plan has no
    /// node for becomes an empty cell, which a routed triangle may fill.
    pub fn from_plan(plan: &Plan) -> Result<CellTree, SubsetError> {
        let mut tree = CellTree { nodes: Vec::new() };
        tree.add(plan, Some(0), plan.scene_bounds(), 0)?;
        Ok(tree)
    }

    /// Adds plan node `node` (none: an empty cell) with its subtree; returns its index.
    fn add(
        &mut self,
        plan: &Plan,
        node: Option<u32>,
        cell: Bounds,
        depth: u32,
    ) -> Result<usize, SubsetError> {
        let k = self.nodes.len();
        self.nodes.push(Cell {
            cell,
            depth,
            kind: CellKind::Leaf { records: 0 },
        });
        let Some(n) = node else { return Ok(k) };
        let bad = || SubsetError::Internal("a checked plan's node is missing");
        if let PlanNode::Cut {
            axis,
            split_bits,
            children,
        } = *plan.nodes.get(n as usize).ok_or_else(bad)?
        {
            let cut = Cut {
                cell,
                axis: usize::from(axis),
                mid: f32::from_bits(split_bits),
            };
            let (lo, hi) = cell.split(cut.axis, cut.mid);
            let l = self.add(plan, children[0], lo, depth + 1)?;
            let r = self.add(plan, children[1], hi, depth + 1)?;
            let slot = self.nodes.get_mut(k).ok_or_else(bad)?;
            slot.kind = CellKind::Inner {
                cut,
                children: [l, r],
                fit: None,
            };
        }
        Ok(k)
    }

    /// Records routed to the cells below node `k`.
    pub fn records_below(&self, k: usize) -> u64 {
        let mut total = 0;
        let mut stack = vec![k];
        while let Some(k) = stack.pop() {
            match self.nodes.get(k).map(|c| &c.kind) {
                Some(CellKind::Leaf { records }) => total += records,
                Some(CellKind::Inner { children, .. }) => stack.extend(children),
                None => {}
            }
        }
        total
    }
}

/// A leaf that may be cut: room on both sides of its median, and depth to spare.
fn splittable(c: &Cell) -> bool {
    matches!(c.kind, CellKind::Leaf { .. })
        && c.depth < MAX_SPLIT_DEPTH
        && Cut::middle(&c.cell).inside()
}

/// The first pass's store: the scene's tally and a uniform sample of centroids (reservoir
/// sampling with a fixed seed, so a plan is reproducible).
pub(super) struct SampleStore {
    pub tally: Tally,
    pub sample: Vec<[f32; 3]>,
    rng: u64,
}

impl SampleStore {
    pub fn new() -> SampleStore {
        SampleStore {
            tally: Tally::default(),
            sample: Vec::new(),
            rng: 0x9E37_79B9_7F4A_7C15,
        }
    }

    /// splitmix64.
    fn next(&mut self) -> u64 {
        self.rng = self.rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

impl Store for SampleStore {
    fn store(&mut self, t: InputTriangle, _at: &Location) -> Result<(), ImportError> {
        let seen = self.tally.count;
        self.tally.add(&t);
        let c = SoupTriangle {
            triangle: t,
            primary: true,
        }
        .centroid();
        if self.sample.len() < SAMPLE_SIZE {
            self.sample.push(c);
        } else {
            let j = self.next() % (seen + 1);
            if let Some(slot) = self.sample.get_mut(j as usize) {
                *slot = c;
            }
        }
        Ok(())
    }
}

/// What the second pass found: the tree counted and fitted, the scene's tally, and the
/// leaves each input reached.
pub(super) struct Routed {
    pub tree: CellTree,
    pub tally: Tally,
    pub reach: Vec<std::collections::BTreeSet<usize>>,
}

/// The second pass's store: every triangle routed down the cuts, its copies counted in the
/// leaves and added to the R-LOD moments of the LOD nodes among the cuts, in input order.
pub(super) struct RouteStore<'a> {
    pub tree: CellTree,
    pub tally: Tally,
    /// The input being read, and the leaves each input's triangles reached.
    pub input: usize,
    pub reach: Vec<std::collections::BTreeSet<usize>>,
    moments: Vec<Option<PlaneMoments>>,
    facts: &'a SceneFacts,
    stack: Vec<(usize, SoupTriangle)>,
}

impl<'a> RouteStore<'a> {
    /// Routes into `tree`; with `rlod_height` (the treelet height, when the build makes
    /// R-LODs) the cuts at LOD depths gather moments.
    pub fn new(tree: CellTree, rlod_height: Option<u8>, facts: &'a SceneFacts) -> RouteStore<'a> {
        let moments = tree
            .nodes
            .iter()
            .map(|c| match (&c.kind, rlod_height) {
                (CellKind::Inner { .. }, Some(h)) if is_lod_depth(c.depth, h) => {
                    Some(PlaneMoments::new(c.cell))
                }
                _ => None,
            })
            .collect();
        RouteStore {
            tree,
            tally: Tally::default(),
            input: 0,
            reach: Vec::new(),
            moments,
            facts,
            stack: Vec::new(),
        }
    }

    /// The tree with every LOD cut's plane fitted.
    pub fn finish(mut self) -> Routed {
        for (cell, m) in self.tree.nodes.iter_mut().zip(&self.moments) {
            if let (CellKind::Inner { fit, .. }, Some(m)) = (&mut cell.kind, m) {
                *fit = Some(m.plane());
            }
        }
        Routed {
            tree: self.tree,
            tally: self.tally,
            reach: self.reach,
        }
    }
}

impl Store for RouteStore<'_> {
    fn store(&mut self, t: InputTriangle, _at: &Location) -> Result<(), ImportError> {
        self.tally.add(&t);
        let facts = self.facts;
        self.stack.push((
            0,
            SoupTriangle {
                triangle: t,
                primary: true,
            },
        ));
        while let Some((k, t)) = self.stack.pop() {
            let Some(cell) = self.tree.nodes.get_mut(k) else {
                continue;
            };
            match &mut cell.kind {
                CellKind::Leaf { records } => {
                    *records += 1;
                    if self.reach.len() <= self.input {
                        self.reach.resize_with(self.input + 1, Default::default);
                    }
                    if let Some(r) = self.reach.get_mut(self.input) {
                        r.insert(k);
                    }
                }
                CellKind::Inner { cut, children, .. } => {
                    if let Some(Some(m)) = self.moments.get_mut(k) {
                        let tri = &t.triangle;
                        m.add(tri.positions, facts.part(tri), || facts.colour(tri));
                    }
                    let sides = Sides::of(&t, cut);
                    for (low, &child) in [true, false].into_iter().zip(children.iter()) {
                        if let Some(c) = sides.copy(&t, low) {
                            self.stack.push((child, c));
                        }
                    }
                }
            }
        }
        Ok(())
    }
}
