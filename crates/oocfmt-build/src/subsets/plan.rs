//! The plan of a build split into subsets (spec §16.1): the top median cuts, fixed from a
//! sample of the scene, and the R-LOD planes of the LOD nodes among them, fitted over every
//! triangle. Two streaming passes over the inputs: the first keeps the bounds and a sample of
//! centroids, the second routes every triangle down the cuts as the out-of-core split would.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::cells::{CellKind, CellTree};
use super::SubsetError;
use crate::lod::rlod::PlaneFit;
use crate::ooc::split::{Start, TopNode, TopTree, MAX_SPLIT_DEPTH};
use oocfmt_meshio::mesh::Bounds;

/// The `format` of a plan file.
pub const PLAN_FORMAT: &str = "oocfmt-plan";
/// The version of the plan's layout this build writes and reads.
pub const PLAN_VERSION: u32 = 1;
/// Most subsets a plan may have.
pub const MAX_SUBSETS: u32 = 4096;

/// A plan: what `oocfmt plan` writes and every subset build and merge reads. Floats are kept
/// as their IEEE bits so that every process sees the very same values, and the identity is a
/// checksum of text made of integers and strings alone.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plan {
    /// Always [`PLAN_FORMAT`].
    pub format: String,
    /// Always [`PLAN_VERSION`].
    pub version: u32,
    /// 8 hex digits: CRC-32C of this plan's JSON with this field empty ([`Plan::seal`]).
    pub identity: String,
    /// Subsets, numbered 0 to `subsets - 1`: the non-empty cells, left to right.
    pub subsets: u32,
    /// The inputs, in order, with what they held when planned.
    pub inputs: Vec<PlanInput>,
    /// The build settings, as `oocfmt convert` flags: every subset and the merge use them.
    pub settings: Vec<String>,
    /// The scene origin positions are stored relative to, as f64 bits.
    pub origin_bits: [u64; 3],
    /// Triangles the import keeps.
    pub triangles: u64,
    /// The scene's bounds as f32 bits.
    pub bounds_bits: [[u32; 3]; 2],
    /// 8 hex digits: CRC-32C of the scene's tables (spec §16.1): what every subset
    /// numbers materials and parts by.
    pub tables: String,
    /// The cut tree in preorder: node 0 is the scene root.
    pub nodes: Vec<PlanNode>,
    /// The R-LOD planes of the LOD nodes among the cuts (none without R-LODs).
    pub planes: Vec<PlanPlane>,
    /// Subsets whose files, built from an earlier plan, this plan takes as they are
    /// (`plan --update`): no input that reaches them changed, nor a plane above them.
    pub reuse: Vec<PlanReuse>,
}

/// A subset an updated plan takes from an earlier plan's build.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanReuse {
    /// The subset.
    pub index: u32,
    /// The identity of the plan its file was built from.
    pub plan: String,
}

/// One input as planned.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanInput {
    /// The path as given to `oocfmt plan`.
    pub path: String,
    /// Its length in bytes.
    pub bytes: u64,
    /// CRC-32C of its bytes, 8 hex digits.
    pub crc32c: String,
    /// The subsets its triangles reach, in order.
    pub subsets: Vec<u32>,
}

/// A node of the cut tree.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
pub enum PlanNode {
    /// A median cut: `axis` (0 x, 1 y, 2 z) at the f32 whose bits are `split_bits`; each
    /// child a later node, or none where no triangle reaches that side.
    Cut {
        /// 0 x, 1 y, 2 z: the cell's longest axis.
        axis: u8,
        /// The f32 bits of the cut's position: the middle of the cell on `axis`.
        split_bits: u32,
        /// The nodes of the two halves, low side first.
        children: [Option<u32>; 2],
    },
    /// A cell built as one subset.
    Subset {
        /// The subset's number.
        index: u32,
        /// Triangle records that reach the cell (straddling triangles count in each cell).
        records: u64,
    },
}

/// The R-LOD plane of a LOD node among the cuts, fitted to every triangle reaching its cell;
/// its deviation is measured by the subsets.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanPlane {
    /// The node.
    pub node: u32,
    /// The fit's f64 fields as bits: normal (3), point (3), colour (3), area, section.
    pub fit_bits: [u64; 11],
    /// The part of the largest clipped area.
    pub part: u32,
}

impl PlanPlane {
    /// The record of `fit` at `node` (its deviation and sums are 0: the subsets measure them).
    pub fn of(node: u32, fit: &PlaneFit) -> PlanPlane {
        let [n0, n1, n2] = fit.normal.map(f64::to_bits);
        let [p0, p1, p2] = fit.point.map(f64::to_bits);
        let [c0, c1, c2] = fit.colour.map(f64::to_bits);
        PlanPlane {
            node,
            fit_bits: [
                n0,
                n1,
                n2,
                p0,
                p1,
                p2,
                c0,
                c1,
                c2,
                fit.area.to_bits(),
                fit.section.to_bits(),
            ],
            part: fit.part,
        }
    }

    /// The plane as fitted, nothing measured against it yet.
    pub fn fit(&self) -> PlaneFit {
        let b = self.fit_bits.map(f64::from_bits);
        PlaneFit {
            normal: [b[0], b[1], b[2]],
            point: [b[3], b[4], b[5]],
            deviation: 0.0,
            stored_deviation: 0.0,
            colour: [b[6], b[7], b[8]],
            area: b[9],
            section: b[10],
            projected: 0.0,
            facing: 0.0,
            cosine_weighted: 0.0,
            part: self.part,
        }
    }
}

/// Where one subset's cell sits among the cuts.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct SubsetCell {
    /// Its node in the plan (and in every subset's and the merge's top tree).
    pub node: usize,
    pub cell: Bounds,
    pub depth: u32,
    /// The cut nodes above it, root first.
    pub ancestors: Vec<usize>,
    /// The side of each ancestor's cut it lies on (true: low).
    pub sides: Vec<bool>,
}

impl SubsetCell {
    /// Where the out-of-core split of this cell starts.
    pub fn start(&self) -> Start {
        Start {
            node: self.node,
            cell: self.cell,
            depth: self.depth,
            ancestors: self.ancestors.clone(),
        }
    }
}

/// The plan's cut tree as the out-of-core build's top tree (its subsets' nodes placeholders),
/// and each subset's cell, by index.
pub(crate) struct PlanTop {
    pub tree: TopTree,
    pub cells: Vec<SubsetCell>,
    /// Nodes of the plan: every node a subset adds comes after these.
    pub plan_nodes: usize,
}

impl Plan {
    /// The scene's bounds.
    pub fn scene_bounds(&self) -> Bounds {
        let [lo, hi] = self.bounds_bits;
        Bounds {
            min: lo.map(f32::from_bits),
            max: hi.map(f32::from_bits),
        }
    }

    /// The scene origin.
    pub fn origin(&self) -> [f64; 3] {
        self.origin_bits.map(f64::from_bits)
    }

    /// The identity of the plan the file of subset `index` must be built from: this plan's,
    /// or an earlier one's that this plan reuses.
    pub fn identity_for(&self, index: u32) -> &str {
        self.reuse
            .iter()
            .find(|r| r.index == index)
            .map_or(self.identity.as_str(), |r| r.plan.as_str())
    }

    /// Whether a file of subset `index` built from the plan `identity` belongs to this plan:
    /// built from it, or from the earlier plan it takes that subset from.
    pub fn takes(&self, index: u32, identity: &str) -> bool {
        identity == self.identity || identity == self.identity_for(index)
    }

    /// Whether `other` has this plan's cuts, subsets, bounds, inputs and settings (what its
    /// counts, checksums and planes say aside).
    pub fn same_cuts(&self, other: &Plan) -> bool {
        let shape = |p: &Plan| -> Vec<PlanNode> {
            p.nodes
                .iter()
                .map(|n| match n {
                    PlanNode::Subset { index, .. } => PlanNode::Subset {
                        index: *index,
                        records: 0,
                    },
                    cut => cut.clone(),
                })
                .collect()
        };
        let paths = |p: &Plan| -> Vec<String> { p.inputs.iter().map(|i| i.path.clone()).collect() };
        self.subsets == other.subsets
            && self.bounds_bits == other.bounds_bits
            && self.origin_bits == other.origin_bits
            && self.settings == other.settings
            && self.tables == other.tables
            && paths(self) == paths(other)
            && shape(self) == shape(other)
    }

    /// The identity as a number.
    pub fn identity_number(&self) -> Result<u32, SubsetError> {
        u32::from_str_radix(&self.identity, 16)
            .map_err(|_| self.bad("identity is not 8 hex digits"))
    }

    /// Fills in `identity` from the rest.
    pub fn seal(&mut self) -> Result<(), SubsetError> {
        self.identity = format!("{:08x}", self.compute_identity()?);
        Ok(())
    }

    fn compute_identity(&self) -> Result<u32, SubsetError> {
        let unsealed = Plan {
            identity: String::new(),
            ..self.clone()
        };
        let json = serde_json::to_vec(&unsealed).map_err(|e| SubsetError::Json(e.to_string()))?;
        Ok(crc32c::crc32c(&json))
    }

    /// The plan as a file's text.
    pub fn to_json(&self) -> Result<String, SubsetError> {
        serde_json::to_string_pretty(self).map_err(|e| SubsetError::Json(e.to_string()))
    }

    /// Reads and checks a plan file; `name` is what errors call it.
    pub fn parse(text: &str, name: &str) -> Result<Plan, SubsetError> {
        let plan: Plan = serde_json::from_str(text).map_err(|e| SubsetError::Plan {
            path: name.to_string(),
            what: e.to_string(),
        })?;
        plan.check().map_err(|e| match e {
            SubsetError::Plan { what, .. } => SubsetError::Plan {
                path: name.to_string(),
                what,
            },
            other => other,
        })?;
        Ok(plan)
    }

    /// Writes the plan to `path` under a temporary name in its folder, then renames it into
    /// place: a failure leaves no file under `path` and an existing one untouched.
    pub fn write(&self, path: &Path) -> Result<(), SubsetError> {
        use std::io::Write;
        let io = |source| SubsetError::Io {
            path: path.display().to_string(),
            source,
        };
        let mut tmp = super::file::temp_beside(path).map_err(io)?;
        let text = self.to_json()?;
        tmp.write_all(text.as_bytes()).map_err(io)?;
        tmp.write_all(b"\n").map_err(io)?;
        tmp.as_file().sync_all().map_err(io)?;
        tmp.persist(path).map_err(|e| io(e.error))?;
        Ok(())
    }

    /// Reads and checks the plan file at `path`.
    pub fn read(path: &Path) -> Result<Plan, SubsetError> {
        let text = std::fs::read_to_string(path).map_err(|source| SubsetError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Plan::parse(&text, &path.display().to_string())
    }

    fn bad(&self, what: &str) -> SubsetError {
        SubsetError::Plan {
            path: "plan".into(),
            what: what.to_string(),
        }
    }

    /// Checks the format, the identity and the cut tree.
    pub fn check(&self) -> Result<(), SubsetError> {
        if self.format != PLAN_FORMAT {
            return Err(self.bad("not an oocfmt plan (format is not \"oocfmt-plan\")"));
        }
        if self.version != PLAN_VERSION {
            return Err(SubsetError::Plan {
                path: "plan".into(),
                what: format!("version {} (this build reads {PLAN_VERSION})", self.version),
            });
        }
        if self.identity_number()? != self.compute_identity()? {
            return Err(self.bad("its identity does not match its contents (edited?)"));
        }
        if self.subsets == 0 || self.subsets > MAX_SUBSETS {
            return Err(self.bad("subsets out of range"));
        }
        let mut reused = std::collections::BTreeSet::new();
        for r in &self.reuse {
            let hex = r.plan.len() == 8 && r.plan.bytes().all(|b| b.is_ascii_hexdigit());
            if r.index >= self.subsets || !reused.insert(r.index) || !hex {
                return Err(self.bad("a reused subset is out of range, repeated or unnamed"));
            }
        }
        self.top().map(|_| ())
    }

    /// The cut tree as a top tree, with every subset's cell; checks the tree's shape.
    pub(crate) fn top(&self) -> Result<PlanTop, SubsetError> {
        let n = self.nodes.len();
        let mut tree = TopTree {
            nodes: vec![TopNode::Chunk(usize::MAX); n],
            ..TopTree::default()
        };
        let mut cells: Vec<Option<SubsetCell>> = vec![None; self.subsets as usize];
        let mut seen = vec![false; n];
        let root = SubsetCell {
            node: 0,
            cell: self.scene_bounds(),
            depth: 0,
            ancestors: Vec::new(),
            sides: Vec::new(),
        };
        let mut stack = vec![root];
        while let Some(c) = stack.pop() {
            let node = self
                .nodes
                .get(c.node)
                .ok_or_else(|| self.bad("a child is missing"))?;
            match seen.get_mut(c.node) {
                Some(s) if !*s => *s = true,
                _ => return Err(self.bad("a node is reached twice")),
            }
            match *node {
                PlanNode::Cut {
                    axis,
                    split_bits,
                    children,
                } => {
                    if axis > 2 || c.depth >= MAX_SPLIT_DEPTH {
                        return Err(self.bad("a cut's axis or depth is out of range"));
                    }
                    let split = f32::from_bits(split_bits);
                    let halves = c.cell.split(usize::from(axis), split);
                    let mut kids = [None, None];
                    for (k, (child, cell)) in
                        children.into_iter().zip([halves.0, halves.1]).enumerate()
                    {
                        let Some(child) = child else { continue };
                        let child = child as usize;
                        if child <= c.node {
                            return Err(self.bad("a child comes before its parent"));
                        }
                        kids[k] = Some(child);
                        let mut ancestors = c.ancestors.clone();
                        ancestors.push(c.node);
                        let mut sides = c.sides.clone();
                        sides.push(k == 0);
                        stack.push(SubsetCell {
                            node: child,
                            cell,
                            depth: c.depth + 1,
                            ancestors,
                            sides,
                        });
                    }
                    if let Some(slot) = tree.nodes.get_mut(c.node) {
                        *slot = TopNode::Inner {
                            axis,
                            split,
                            children: kids,
                        };
                    }
                }
                PlanNode::Subset { index, .. } => match cells.get_mut(index as usize) {
                    Some(slot @ None) => *slot = Some(c),
                    _ => return Err(self.bad("a subset index is repeated or out of range")),
                },
            }
        }
        if seen.iter().any(|s| !s) {
            return Err(self.bad("a node is not reached from the root"));
        }
        for p in &self.planes {
            match self.nodes.get(p.node as usize) {
                Some(PlanNode::Cut { .. }) => {
                    tree.planes.insert(p.node as usize, p.fit());
                }
                _ => return Err(self.bad("a plane's node is not a cut")),
            }
        }
        let cells = cells
            .into_iter()
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| self.bad("a subset index is missing"))?;
        Ok(PlanTop {
            tree,
            cells,
            plan_nodes: n,
        })
    }
}

/// The plan's nodes, in preorder, from the grown and counted cell tree: empty cells dropped,
/// the rest numbered left to right.
pub(super) struct Emitted {
    pub nodes: Vec<PlanNode>,
    pub planes: Vec<PlanPlane>,
    pub subsets: u32,
    /// The subset of each cell of the tree that became one.
    pub subset_of: std::collections::BTreeMap<usize, u32>,
}

pub(super) fn plan_nodes(tree: &CellTree) -> Result<Emitted, SubsetError> {
    let mut e = Emitted {
        nodes: Vec::new(),
        planes: Vec::new(),
        subsets: 0,
        subset_of: std::collections::BTreeMap::new(),
    };
    emit(tree, 0, &mut e)?;
    Ok(e)
}

/// Appends cell `k`'s subtree in preorder; returns its node, or `None` for an empty one.
fn emit(tree: &CellTree, k: usize, e: &mut Emitted) -> Result<Option<u32>, SubsetError> {
    if tree.records_below(k) == 0 {
        return Ok(None);
    }
    let id = u32::try_from(e.nodes.len()).map_err(|_| SubsetError::TooManySubsets)?;
    let Some(cell) = tree.nodes.get(k) else {
        return Ok(None);
    };
    match &cell.kind {
        CellKind::Leaf { records } => {
            e.nodes.push(PlanNode::Subset {
                index: e.subsets,
                records: *records,
            });
            e.subset_of.insert(k, e.subsets);
            e.subsets += 1;
        }
        CellKind::Inner { cut, children, fit } => {
            e.nodes.push(PlanNode::Cut {
                axis: cut.axis as u8,
                split_bits: cut.mid.to_bits(),
                children: [None, None],
            });
            if let Some(f) = fit {
                e.planes.push(PlanPlane::of(id, f));
            }
            let mut kids = [None, None];
            for (slot, &c) in kids.iter_mut().zip(children) {
                *slot = emit(tree, c, e)?;
            }
            if let Some(PlanNode::Cut { children, .. }) = e.nodes.get_mut(id as usize) {
                *children = kids;
            }
        }
    }
    Ok(Some(id))
}

/// CRC-32C of what every subset numbers materials and parts by, and the attributes the scene
/// has: a plan's `tables`.
pub(super) fn tables_digest(scene: &crate::ooc::SceneInfo) -> Result<String, SubsetError> {
    let tables = (
        &scene.materials,
        &scene.used_materials,
        &scene.parts,
        scene.normals,
        scene.colours,
    );
    let bytes = postcard::to_stdvec(&tables).map_err(|e| SubsetError::Json(e.to_string()))?;
    Ok(format!("{:08x}", crc32c::crc32c(&bytes)))
}
