//! An in-core kd-tree over a [`Mesh`]: binned SAH splits with aggressive empty-space cutting
//! (Áfra et al. 2012, §4.1), built in parallel and identical whatever the thread count.
//!
//! The tree is an arena of nodes in preorder so that other builders (out-of-core, by hand) can
//! produce the same representation and reuse the layout stage unchanged.

mod sah;

pub(crate) use sah::clip_triangle;

use std::sync::atomic::{AtomicBool, Ordering};

use oocfmt_meshio::mesh::{Bounds, Mesh, MeshError};

/// The spec's limit on triangles per leaf (a 12-bit field).
pub const MAX_LEAF_TRIANGLES: u32 = oocfmt::records::MAX_LEAF_TRIANGLES as u32;
pub use oocfmt::records::MAX_TREE_DEPTH;

/// Index of a node in [`KdTree::nodes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(pub u32);

impl NodeId {
    /// The id as a position in [`KdTree::nodes`].
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// One node of a [`KdTree`]: a split plane with up to two children, or a leaf.
#[derive(Clone, Debug, PartialEq)]
pub enum KdNode {
    /// Splits its cell by the plane `axis = split`; `children[0]` is the low side. An empty side
    /// is `None`.
    Inner {
        /// The axis the plane is normal to: 0 = x, 1 = y, 2 = z.
        axis: u8,
        /// The plane's coordinate on `axis`, in mesh units; inside the node's cell.
        split: f32,
        /// The children below and above the plane, each None when its side is empty; never both.
        children: [Option<NodeId>; 2],
    },
    /// Mesh triangle ids whose boxes overlap the leaf's cell.
    Leaf {
        /// Indices into the mesh's triangles, 1 ..= [`MAX_LEAF_TRIANGLES`] of them.
        triangles: Vec<u32>,
    },
}

/// How [`build`] and [`build_cell`] split nodes; [`KdBuildOptions::check`] gives each field's
/// range.
#[derive(Clone, Debug, PartialEq)]
pub struct KdBuildOptions {
    /// A node of at most this many triangles becomes a leaf (1 ..= 4095); a larger one is
    /// split, by the SAH where a plane pays off and at the spatial median where none does.
    /// Larger leaves only where no plane separates the triangles (see [`build_cell`]).
    pub max_leaf_triangles: u32,
    /// Most node levels on a path, root and leaf included (1 ..= 128).
    pub max_depth: u32,
    /// Most splits on a path that leave one side with every triangle while copying some to
    /// the other side. Such splits can still pay off a level later, but a run of them (cells
    /// creeping along the edge where two surfaces meet) only multiplies references.
    pub max_bad_splits: u32,
    /// Candidate planes per axis are the inner boundaries of this many equal bins (2 ..= 256).
    pub sah_bins: u32,
    /// SAH cost of visiting an inner node (> 0, finite).
    pub traversal_cost: f32,
    /// SAH cost of intersecting one triangle (> 0, finite).
    pub intersection_cost: f32,
    /// An empty slab on one side of a cell thicker than this fraction of the cell is cut off
    /// first, as a split with an empty child (0 < f ≤ 1; 1 turns cutting off).
    pub empty_cut: f32,
}

/// The default cost of a ray-triangle test relative to a traversal step.
pub const DEFAULT_INTERSECTION_COST: f32 = 1.5;
/// The default empty-space cutting threshold: Áfra used 10–20 % of the cell volume.
pub const DEFAULT_EMPTY_CUT: f32 = 0.15;

impl Default for KdBuildOptions {
    fn default() -> Self {
        KdBuildOptions {
            max_leaf_triangles: 8,
            // Empty-space cuts take levels of their own, so leave room beyond log2(n).
            max_depth: 64,
            max_bad_splits: 2,
            sah_bins: 32,
            traversal_cost: 1.0,
            intersection_cost: DEFAULT_INTERSECTION_COST,
            empty_cut: DEFAULT_EMPTY_CUT,
        }
    }
}

impl KdBuildOptions {
    /// Checks every field against its documented range.
    pub fn check(&self) -> Result<(), KdError> {
        if !(1..=MAX_LEAF_TRIANGLES).contains(&self.max_leaf_triangles) {
            return Err(KdError::MaxLeafTriangles(self.max_leaf_triangles));
        }
        if !(1..=MAX_TREE_DEPTH).contains(&self.max_depth) {
            return Err(KdError::MaxDepth(self.max_depth));
        }
        if !(2..=256).contains(&self.sah_bins) {
            return Err(KdError::BadOption {
                option: "sah_bins",
                value: self.sah_bins.to_string(),
                expected: "2 ..= 256",
            });
        }
        for (option, v) in [
            ("traversal_cost", self.traversal_cost),
            ("intersection_cost", self.intersection_cost),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(KdError::BadOption {
                    option,
                    value: v.to_string(),
                    expected: "a finite number > 0",
                });
            }
        }
        if !(self.empty_cut > 0.0 && self.empty_cut <= 1.0) {
            return Err(KdError::BadOption {
                option: "empty_cut",
                value: self.empty_cut.to_string(),
                expected: "0 < f ≤ 1",
            });
        }
        Ok(())
    }

    /// How a tree was built with these options, as `(key, value)` pairs for the metadata
    /// (the leaf size has a field of its own there).
    pub fn params(&self) -> Vec<(String, String)> {
        [
            ("kd_split", "binned-sah".to_string()),
            ("kd_sah_bins", self.sah_bins.to_string()),
            ("kd_traversal_cost", self.traversal_cost.to_string()),
            ("kd_intersection_cost", self.intersection_cost.to_string()),
            ("kd_empty_cut", self.empty_cut.to_string()),
            ("kd_max_depth", self.max_depth.to_string()),
            ("kd_max_bad_splits", self.max_bad_splits.to_string()),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }
}

/// Why a kd-tree could not be built or is not a proper tree. Node ids are positions in the
/// node list being built or checked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KdError {
    /// The mesh itself is invalid (an index out of range, a non-finite position).
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// [`KdBuildOptions::max_leaf_triangles`] is outside its range; holds the value given.
    #[error("max_leaf_triangles {0} is outside 1 ..= {MAX_LEAF_TRIANGLES}")]
    MaxLeafTriangles(u32),
    /// [`KdBuildOptions::max_depth`] is outside its range; holds the value given.
    #[error("max_depth {0} is outside 1 ..= {MAX_TREE_DEPTH}")]
    MaxDepth(u32),
    /// Another [`KdBuildOptions`] field is outside its range.
    #[error("{option} {value}: expected {expected}")]
    BadOption {
        /// The field's name.
        option: &'static str,
        /// The value given, as text.
        value: String,
        /// The range it must lie in.
        expected: &'static str,
    },
    /// A node that must become a leaf holds more triangles than a leaf may.
    #[error("a leaf at depth {depth} needs {triangles} triangles, over the limit of {MAX_LEAF_TRIANGLES}: no axis-aligned plane separates them (they overlap in one place, or the depth limit was reached)")]
    LeafTooLarge {
        /// Triangles the leaf would hold.
        triangles: usize,
        /// Its node level (the root is 1).
        depth: u32,
    },
    /// The tree would need more nodes than a u32 id can name.
    #[error("the tree needs more than {max} nodes", max = u32::MAX)]
    TooManyNodes,
    /// A child id names no node.
    #[error("node {node} is out of range ({nodes} nodes)")]
    NodeOutOfRange {
        /// The id named.
        node: u32,
        /// Nodes in the list.
        nodes: usize,
    },
    /// A node is reached from two parents, or from none.
    #[error("node {node} is reached twice or is unreachable from the root")]
    NotATree {
        /// The node's id.
        node: u32,
    },
    /// An inner node has neither child.
    #[error("node {node} is an inner node without children")]
    NoChildren {
        /// The node's id.
        node: u32,
    },
    /// An inner node's axis is over 2 or its plane lies outside its cell.
    #[error("node {node} has an invalid axis {axis} or split {split} outside its cell")]
    BadSplit {
        /// The node's id.
        node: u32,
        /// Its axis.
        axis: u8,
        /// Its plane's coordinate.
        split: f32,
    },
    /// A leaf holds no triangles or more than [`MAX_LEAF_TRIANGLES`].
    #[error("leaf {node} has {triangles} triangles: expected 1 ..= {MAX_LEAF_TRIANGLES}")]
    LeafSize {
        /// The leaf's id.
        node: u32,
        /// Triangles it holds.
        triangles: usize,
    },
    /// A leaf (or the list given to [`build_cell`], as node 0) names a triangle the mesh lacks.
    #[error("leaf {node} names triangle {triangle}, but the mesh has {triangles}")]
    TriangleOutOfRange {
        /// The leaf's id.
        node: u32,
        /// The triangle id named.
        triangle: u32,
        /// Triangles in the mesh.
        triangles: usize,
    },
    /// A path from the root has more than [`MAX_TREE_DEPTH`] node levels.
    #[error("the tree is {depth} node levels deep, over the limit of {MAX_TREE_DEPTH}")]
    TooDeep {
        /// The level reached.
        depth: u32,
    },
    /// The root cell (or a cell given to [`build_cell`]) is empty or has a non-finite bound.
    #[error("the scene bounds {0:?} are empty or not finite")]
    BadBounds(Bounds),
}

/// A kd-tree whose root cell is `bounds`. Constructed only through [`build`] or
/// [`KdTree::from_parts`], both of which check it is a proper tree over its mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct KdTree {
    nodes: Vec<KdNode>,
    root: Option<NodeId>,
    bounds: Bounds,
    max_leaf_triangles: u32,
    params: Vec<(String, String)>,
}

impl KdTree {
    /// Assembles a tree built elsewhere (by hand, or by another builder) and checks it against
    /// `mesh`: every node reached exactly once from `root`, splits inside their cells, leaves of
    /// 1 ..= 4095 valid triangle ids, depth ≤ 128. `params` describe how it was built and go
    /// into the container's build metadata.
    pub fn from_parts(
        mesh: &Mesh,
        nodes: Vec<KdNode>,
        root: Option<NodeId>,
        bounds: Bounds,
        params: Vec<(String, String)>,
    ) -> Result<KdTree, KdError> {
        let max_leaf = nodes
            .iter()
            .map(|n| match n {
                KdNode::Leaf { triangles } => triangles.len(),
                KdNode::Inner { .. } => 0,
            })
            .max()
            .unwrap_or(0);
        let tree = KdTree {
            nodes,
            root,
            bounds,
            max_leaf_triangles: u32::try_from(max_leaf).unwrap_or(u32::MAX),
            params,
        };
        tree.validate(mesh)?;
        Ok(tree)
    }

    /// A tree without nodes.
    pub fn empty() -> KdTree {
        KdTree {
            nodes: Vec::new(),
            root: None,
            bounds: Bounds::EMPTY,
            max_leaf_triangles: 0,
            params: Vec::new(),
        }
    }

    /// A tree assembled from parts of other trees, checked for shape only: its leaves' triangle
    /// lists may be empty, because their triangles are laid out elsewhere (the top of an
    /// out-of-core build).
    pub(crate) fn skeleton(nodes: Vec<KdNode>, root: NodeId, bounds: Bounds) -> KdTree {
        KdTree {
            nodes,
            root: Some(root),
            bounds,
            max_leaf_triangles: 0,
            params: Vec::new(),
        }
    }

    /// Every node, indexed by [`NodeId`]; the root comes first in a built tree.
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// The node `id`, or None when out of range.
    pub fn node(&self, id: NodeId) -> Option<&KdNode> {
        self.nodes.get(id.index())
    }

    /// The root node; None for a tree without triangles.
    pub fn root(&self) -> Option<NodeId> {
        self.root
    }

    /// The root cell: the scene box.
    pub fn bounds(&self) -> Bounds {
        self.bounds
    }

    /// The leaf-size parameter of the build (for a tree given in parts, its largest leaf).
    pub fn max_leaf_triangles(&self) -> u32 {
        self.max_leaf_triangles
    }

    /// How the tree was built, as `(key, value)` pairs for the container's metadata.
    pub fn params(&self) -> &[(String, String)] {
        &self.params
    }

    /// The low and high child of `id`; both None for a leaf or an id out of range.
    pub fn children(&self, id: NodeId) -> [Option<NodeId>; 2] {
        match self.node(id) {
            Some(KdNode::Inner { children, .. }) => *children,
            _ => [None, None],
        }
    }

    /// Node levels on the longest root-to-leaf path (a lone leaf is 1, an empty tree 0).
    pub fn depth(&self) -> u32 {
        let mut deepest = 0;
        let mut stack: Vec<(NodeId, u32)> = self.root.map(|r| (r, 1)).into_iter().collect();
        while let Some((id, d)) = stack.pop() {
            deepest = deepest.max(d);
            stack.extend(self.children(id).into_iter().flatten().map(|c| (c, d + 1)));
        }
        deepest
    }

    /// Leaves in depth-first order, left before right.
    pub fn leaves_depth_first(&self) -> Vec<NodeId> {
        let mut out = Vec::new();
        let mut stack: Vec<NodeId> = self.root.into_iter().collect();
        while let Some(id) = stack.pop() {
            match self.node(id) {
                Some(KdNode::Leaf { .. }) => out.push(id),
                Some(KdNode::Inner {
                    children: [l, r], ..
                }) => {
                    stack.extend(r.iter());
                    stack.extend(l.iter());
                }
                None => {}
            }
        }
        out
    }

    /// Checks that this is a proper tree over `mesh`: every node reached exactly once from the
    /// root, splits inside their cells, leaves of 1 ..= 4095 valid triangle ids, depth ≤ 128.
    pub fn validate(&self, mesh: &Mesh) -> Result<(), KdError> {
        mesh.validate()?;
        let n = self.nodes.len();
        let Some(root) = self.root else {
            return match self.nodes.first() {
                Some(_) => Err(KdError::NotATree { node: 0 }),
                None => Ok(()),
            };
        };
        if self.bounds.is_empty()
            || !self
                .bounds
                .min
                .iter()
                .chain(&self.bounds.max)
                .all(|c| c.is_finite())
        {
            return Err(KdError::BadBounds(self.bounds));
        }
        let seen: Vec<AtomicBool> = (0..n).map(|_| AtomicBool::new(false)).collect();
        self.check_subtree(mesh.triangles.len(), &seen, (root, self.bounds, 1))?;
        match seen.iter().position(|s| !s.load(Ordering::Relaxed)) {
            Some(i) => Err(KdError::NotATree { node: i as u32 }),
            None => Ok(()),
        }
    }

    /// Checks the subtree under `start` (node, cell, level), marking its nodes in `seen`: the
    /// two sides of the top levels in parallel, the rest depth first.
    fn check_subtree(
        &self,
        triangles: usize,
        seen: &[AtomicBool],
        start: Visit,
    ) -> Result<(), KdError> {
        // 2^10 parallel subtrees keep any number of cores busy.
        const PARALLEL_LEVELS: u32 = 10;
        if start.2 <= PARALLEL_LEVELS {
            let [l, r] = self.check_node(triangles, seen, start)?;
            let side = |s: Option<Visit>| match s {
                Some(s) => self.check_subtree(triangles, seen, s),
                None => Ok(()),
            };
            let (l, r) = rayon::join(|| side(l), || side(r));
            return l.and(r);
        }
        let mut stack = vec![start];
        while let Some(next) = stack.pop() {
            stack.extend(
                self.check_node(triangles, seen, next)?
                    .into_iter()
                    .flatten(),
            );
        }
        Ok(())
    }

    /// Checks one node (node, cell, level) of a tree over `triangles` triangles and marks it in
    /// `seen`; returns its children with their cells and levels.
    fn check_node(
        &self,
        triangles: usize,
        seen: &[AtomicBool],
        (id, cell, depth): Visit,
    ) -> Result<[Option<Visit>; 2], KdError> {
        let node = self.node(id).ok_or(KdError::NodeOutOfRange {
            node: id.0,
            nodes: self.nodes.len(),
        })?;
        match seen.get(id.index()) {
            Some(s) if !s.swap(true, Ordering::Relaxed) => {}
            _ => return Err(KdError::NotATree { node: id.0 }),
        }
        if depth > MAX_TREE_DEPTH {
            return Err(KdError::TooDeep { depth });
        }
        match node {
            KdNode::Leaf { triangles: list } => {
                if list.is_empty() || list.len() > MAX_LEAF_TRIANGLES as usize {
                    return Err(KdError::LeafSize {
                        node: id.0,
                        triangles: list.len(),
                    });
                }
                if let Some(&t) = list.iter().find(|&&t| t as usize >= triangles) {
                    return Err(KdError::TriangleOutOfRange {
                        node: id.0,
                        triangle: t,
                        triangles,
                    });
                }
                Ok([None, None])
            }
            &KdNode::Inner {
                axis,
                split,
                children,
            } => {
                let a = usize::from(axis);
                let inside = matches!((cell.min.get(a), cell.max.get(a)), (Some(&lo), Some(&hi)) if lo <= split && split <= hi);
                if !inside {
                    return Err(KdError::BadSplit {
                        node: id.0,
                        axis,
                        split,
                    });
                }
                if children == [None, None] {
                    return Err(KdError::NoChildren { node: id.0 });
                }
                let (lo, hi) = cell.split(a, split);
                let [l, r] = children;
                Ok([l.map(|l| (l, lo, depth + 1)), r.map(|r| (r, hi, depth + 1))])
            }
        }
    }
}

/// A node to check, with its cell and level (the root 1).
type Visit = (NodeId, Bounds, u32);

/// Builds a kd-tree over every triangle of `mesh`, its root cell the scene box. See
/// [`build_cell`] for how nodes are split. Deterministic: the same mesh and options give the
/// same tree whatever the number of threads.
pub fn build(mesh: &Mesh, opts: &KdBuildOptions) -> Result<KdTree, KdError> {
    mesh.validate()?;
    opts.check()?;
    let bounds = mesh.bounds();
    let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
    let nodes = if all.is_empty() {
        Vec::new()
    } else {
        build_cell(mesh, all, bounds, 1, opts)?
    };
    Ok(KdTree {
        root: (!nodes.is_empty()).then_some(NodeId(0)),
        nodes,
        bounds,
        max_leaf_triangles: opts.max_leaf_triangles,
        params: opts.params(),
    })
}

/// Builds the subtree over `triangles` (mesh triangle ids whose boxes touch `cell`) whose
/// root sits at node level `depth` (the tree's root is level 1), for builders that place
/// subtrees themselves (out of core). Returns its nodes in preorder with ids relative to the
/// first, the subtree's root; an empty list gives no nodes.
///
/// Every triangle is tracked by the exact bounds of its part inside the current cell. A node
/// of at most `max_leaf_triangles` becomes a leaf. A larger one first cuts off an empty slab
/// thicker than `empty_cut` of its cell, if there is one (a split with an empty child);
/// otherwise it takes the cheapest binned-SAH plane if that beats intersecting all its
/// triangles, else the spatial median of the occupied part of its longest axis. A triangle
/// goes to every side it reaches (one lying in the plane to both). A split that keeps every
/// triangle on one side while copying some to the other is "bad"; after `max_bad_splits` of
/// them on a path, or at `max_depth`, the node becomes a leaf (an error beyond 4095).
pub fn build_cell(
    mesh: &Mesh,
    triangles: Vec<u32>,
    cell: Bounds,
    depth: u32,
    opts: &KdBuildOptions,
) -> Result<Vec<KdNode>, KdError> {
    opts.check()?;
    if let Some(&t) = triangles
        .iter()
        .find(|&&t| t as usize >= mesh.triangles.len())
    {
        return Err(KdError::TriangleOutOfRange {
            node: 0,
            triangle: t,
            triangles: mesh.triangles.len(),
        });
    }
    if triangles.is_empty() {
        return Ok(Vec::new());
    }
    if cell.is_empty() || !cell.min.iter().chain(&cell.max).all(|c| c.is_finite()) {
        return Err(KdError::BadBounds(cell));
    }
    sah::Builder::new(mesh, opts).subtree(triangles, cell, depth)
}
#[cfg(test)]
mod tests;
