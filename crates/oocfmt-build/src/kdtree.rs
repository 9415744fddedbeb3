//! An in-core kd-tree over a [`Mesh`]: spatial-median splits of the longest cell axis.
//!
//! The tree is an arena of nodes so that later builders (out-of-core, SAH) can produce the same
//! representation and reuse the layout stage unchanged.

use crate::mesh::{Bounds, Mesh, MeshError};

/// The spec's limit on triangles per leaf (a 12-bit field).
pub const MAX_LEAF_TRIANGLES: u32 = oocfmt::records::MAX_LEAF_TRIANGLES as u32;
pub use oocfmt::records::MAX_TREE_DEPTH;

/// Index of a node in [`KdTree::nodes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(pub u32);

impl NodeId {
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum KdNode {
    /// Splits its cell by the plane `axis = split`; `children[0]` is the low side. An empty side
    /// is `None`.
    Inner {
        axis: u8,
        split: f32,
        children: [Option<NodeId>; 2],
    },
    /// Mesh triangle ids whose boxes overlap the leaf's cell.
    Leaf { triangles: Vec<u32> },
}

#[derive(Clone, Debug, PartialEq)]
pub struct KdBuildOptions {
    /// Stop splitting at this many triangles (1 ..= 4095).
    pub max_leaf_triangles: u32,
    /// Most node levels on a path, root and leaf included (1 ..= 128).
    pub max_depth: u32,
    /// Most splits on a path that leave one side with every triangle while copying some to
    /// the other side. Such splits can still pay off a level later, but a run of them (cells
    /// creeping along the edge where two surfaces meet) only multiplies references.
    pub max_bad_splits: u32,
}

impl Default for KdBuildOptions {
    fn default() -> Self {
        KdBuildOptions {
            max_leaf_triangles: 8,
            max_depth: 48,
            max_bad_splits: 2,
        }
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KdError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error("max_leaf_triangles {0} is outside 1 ..= {MAX_LEAF_TRIANGLES}")]
    MaxLeafTriangles(u32),
    #[error("max_depth {0} is outside 1 ..= {MAX_TREE_DEPTH}")]
    MaxDepth(u32),
    #[error("a leaf at depth {depth} needs {triangles} triangles, over the limit of {MAX_LEAF_TRIANGLES}: they cannot be separated by spatial-median splits")]
    LeafTooLarge { triangles: usize, depth: u32 },
    #[error("node {node} is out of range ({nodes} nodes)")]
    NodeOutOfRange { node: u32, nodes: usize },
    #[error("node {node} is reached twice or is unreachable from the root")]
    NotATree { node: u32 },
    #[error("node {node} is an inner node without children")]
    NoChildren { node: u32 },
    #[error("node {node} has an invalid axis {axis} or split {split} outside its cell")]
    BadSplit { node: u32, axis: u8, split: f32 },
    #[error("leaf {node} has {triangles} triangles: expected 1 ..= {MAX_LEAF_TRIANGLES}")]
    LeafSize { node: u32, triangles: usize },
    #[error("leaf {node} names triangle {triangle}, but the mesh has {triangles}")]
    TriangleOutOfRange {
        node: u32,
        triangle: u32,
        triangles: usize,
    },
    #[error("the tree is {depth} node levels deep, over the limit of {MAX_TREE_DEPTH}")]
    TooDeep { depth: u32 },
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

    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    pub fn node(&self, id: NodeId) -> Option<&KdNode> {
        self.nodes.get(id.index())
    }

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
        let mut seen = vec![false; n];
        let mut stack = vec![(root, self.bounds, 1u32)];
        while let Some((id, cell, depth)) = stack.pop() {
            let node = self.node(id).ok_or(KdError::NodeOutOfRange {
                node: id.0,
                nodes: n,
            })?;
            match seen.get_mut(id.index()) {
                Some(s) if !*s => *s = true,
                _ => return Err(KdError::NotATree { node: id.0 }),
            }
            if depth > MAX_TREE_DEPTH {
                return Err(KdError::TooDeep { depth });
            }
            match node {
                KdNode::Leaf { triangles } => {
                    if triangles.is_empty() || triangles.len() > MAX_LEAF_TRIANGLES as usize {
                        return Err(KdError::LeafSize {
                            node: id.0,
                            triangles: triangles.len(),
                        });
                    }
                    if let Some(&t) = triangles
                        .iter()
                        .find(|&&t| t as usize >= mesh.triangles.len())
                    {
                        return Err(KdError::TriangleOutOfRange {
                            node: id.0,
                            triangle: t,
                            triangles: mesh.triangles.len(),
                        });
                    }
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
                    for (child, c) in children.into_iter().zip([lo, hi]) {
                        if let Some(child) = child {
                            stack.push((child, c, depth + 1));
                        }
                    }
                }
            }
        }
        match seen.iter().position(|s| !s) {
            Some(i) => Err(KdError::NotATree { node: i as u32 }),
            None => Ok(()),
        }
    }
}

/// Builds a kd-tree: each cell is split at the spatial median of its longest axis; a triangle
/// goes to every side its box overlaps. Splitting stops at `max_leaf_triangles`, when every
/// triangle straddles the plane (the split would not separate anything), after
/// `max_bad_splits` splits that kept every triangle on one side, when the cell is too thin to
/// split, or at `max_depth`. Deterministic: the same mesh gives the same tree.
pub fn build(mesh: &Mesh, opts: &KdBuildOptions) -> Result<KdTree, KdError> {
    mesh.validate()?;
    if !(1..=MAX_LEAF_TRIANGLES).contains(&opts.max_leaf_triangles) {
        return Err(KdError::MaxLeafTriangles(opts.max_leaf_triangles));
    }
    if !(1..=MAX_TREE_DEPTH).contains(&opts.max_depth) {
        return Err(KdError::MaxDepth(opts.max_depth));
    }
    let bounds = mesh.bounds();
    let params = vec![
        ("kd_split".to_string(), "spatial-median".to_string()),
        ("kd_max_depth".to_string(), opts.max_depth.to_string()),
        (
            "kd_max_bad_splits".to_string(),
            opts.max_bad_splits.to_string(),
        ),
    ];
    let mut b = Builder {
        boxes: (0..mesh.triangles.len())
            .map(|t| mesh.triangle_bounds(t))
            .collect(),
        opts,
        nodes: Vec::new(),
    };
    let root = if mesh.triangles.is_empty() {
        None
    } else {
        let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
        Some(b.node(all, bounds, 1, 0)?)
    };
    Ok(KdTree {
        nodes: b.nodes,
        root,
        bounds,
        max_leaf_triangles: opts.max_leaf_triangles,
        params,
    })
}

struct Builder<'a> {
    boxes: Vec<Bounds>,
    opts: &'a KdBuildOptions,
    nodes: Vec<KdNode>,
}

impl Builder<'_> {
    /// Builds the subtree for `tris` in `cell` at node level `depth`, `bad` bad splits below the
    /// root; nodes land in preorder.
    fn node(
        &mut self,
        tris: Vec<u32>,
        cell: Bounds,
        depth: u32,
        bad: u32,
    ) -> Result<NodeId, KdError> {
        let id = NodeId(self.nodes.len() as u32);
        let Some((axis, split, left, right)) = self.try_split(&tris, &cell, depth) else {
            return self.leaf(id, tris, depth);
        };
        let n = tris.len();
        let is_bad =
            (left.len() == n && !right.is_empty()) || (right.len() == n && !left.is_empty());
        let bad = bad + u32::from(is_bad);
        if bad > self.opts.max_bad_splits {
            return self.leaf(id, tris, depth);
        }
        drop(tris);
        self.nodes.push(KdNode::Inner {
            axis: axis as u8,
            split,
            children: [None, None],
        });
        let (lo, hi) = cell.split(axis, split);
        let l = if left.is_empty() {
            None
        } else {
            Some(self.node(left, lo, depth + 1, bad)?)
        };
        let r = if right.is_empty() {
            None
        } else {
            Some(self.node(right, hi, depth + 1, bad)?)
        };
        if let Some(KdNode::Inner { children, .. }) = self.nodes.get_mut(id.index()) {
            *children = [l, r];
        }
        Ok(id)
    }

    fn leaf(&mut self, id: NodeId, tris: Vec<u32>, depth: u32) -> Result<NodeId, KdError> {
        if tris.len() > MAX_LEAF_TRIANGLES as usize {
            return Err(KdError::LeafTooLarge {
                triangles: tris.len(),
                depth,
            });
        }
        self.nodes.push(KdNode::Leaf { triangles: tris });
        Ok(id)
    }

    /// The split of `cell` and the two triangle lists, or `None` when this should be a leaf.
    fn try_split(
        &self,
        tris: &[u32],
        cell: &Bounds,
        depth: u32,
    ) -> Option<(usize, f32, Vec<u32>, Vec<u32>)> {
        if tris.len() <= self.opts.max_leaf_triangles as usize || depth >= self.opts.max_depth {
            return None;
        }
        let axis = cell.longest_axis();
        let (lo, hi) = (cell.min.get(axis).copied()?, cell.max.get(axis).copied()?);
        // Halving each bound separately cannot overflow, and rounding keeps it inside [lo, hi].
        let split = 0.5 * lo + 0.5 * hi;
        if !(lo < split && split < hi) {
            return None;
        }
        let (mut left, mut right) = (Vec::new(), Vec::new());
        for &t in tris {
            let b = self.boxes.get(t as usize).copied().unwrap_or(Bounds::EMPTY);
            let (min, max) = (b.min.get(axis).copied()?, b.max.get(axis).copied()?);
            // A triangle lying in the plane is on both sides; one touching it from one side is
            // only on that side.
            let in_plane = min == split && max == split;
            if min < split || in_plane {
                left.push(t);
            }
            if max > split || in_plane {
                right.push(t);
            }
        }
        if left.len() == tris.len() && right.len() == tris.len() {
            return None;
        }
        Some((axis, split, left, right))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row of `n` unit squares along x, two triangles each.
    fn strip(n: u32) -> Mesh {
        let mut positions = Vec::new();
        for i in 0..=n {
            positions.push([i as f32, 0.0, 0.0]);
            positions.push([i as f32, 1.0, 0.0]);
        }
        let triangles = (0..n)
            .flat_map(|i| [[2 * i, 2 * i + 2, 2 * i + 3], [2 * i, 2 * i + 3, 2 * i + 1]])
            .collect();
        Mesh::new(positions, triangles)
    }

    fn leaf_sets(tree: &KdTree) -> Vec<Vec<u32>> {
        tree.leaves_depth_first()
            .into_iter()
            .filter_map(|id| match tree.node(id) {
                Some(KdNode::Leaf { triangles }) => Some(triangles.clone()),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn splits_separate_a_strip_and_cover_every_triangle() {
        let mesh = strip(8);
        let tree = build(
            &mesh,
            &KdBuildOptions {
                max_leaf_triangles: 2,
                ..KdBuildOptions::default()
            },
        );
        let Ok(tree) = tree else { panic!("{tree:?}") };
        let leaves = leaf_sets(&tree);
        assert_eq!(leaves.len(), 8);
        assert!(leaves.iter().all(|l| l.len() == 2));
        let mut all: Vec<u32> = leaves.concat();
        all.sort_unstable();
        assert_eq!(all, (0..16).collect::<Vec<_>>());
        assert_eq!(tree.depth(), 4);
        assert_eq!(
            tree.node(NodeId(0)),
            Some(&KdNode::Inner {
                axis: 0,
                split: 4.0,
                children: [Some(NodeId(1)), Some(NodeId(8))]
            })
        );
    }

    #[test]
    fn straddlers_go_both_ways_and_unsplittable_sets_stop() {
        // Both triangles of a square span the whole square: no split separates them.
        let tree = build(
            &strip(1),
            &KdBuildOptions {
                max_leaf_triangles: 1,
                ..KdBuildOptions::default()
            },
        );
        assert_eq!(tree.map(|t| leaf_sets(&t)), Ok(vec![vec![0, 1]]));
    }

    #[test]
    fn the_build_is_deterministic_and_passes_its_own_checks() {
        let mesh = strip(37);
        let opts = KdBuildOptions {
            max_leaf_triangles: 3,
            max_depth: 20,
            ..KdBuildOptions::default()
        };
        let a = build(&mesh, &opts);
        assert_eq!(a, build(&mesh, &opts));
        let Ok(a) = a else { panic!("{a:?}") };
        let again = KdTree::from_parts(&mesh, a.nodes().to_vec(), a.root(), a.bounds(), Vec::new());
        assert!(again.is_ok(), "{again:?}");
        assert!(a.depth() <= 20);
    }

    #[test]
    fn an_empty_mesh_gives_an_empty_tree() {
        let tree = build(&Mesh::default(), &KdBuildOptions::default());
        assert_eq!(tree.as_ref().map(|t| (t.root(), t.depth())), Ok((None, 0)));
    }

    #[test]
    fn bad_parts_are_refused() {
        let mesh = strip(1);
        let bounds = mesh.bounds();
        let leaf = KdNode::Leaf {
            triangles: vec![0, 1],
        };
        let shared = vec![
            KdNode::Inner {
                axis: 0,
                split: 0.5,
                children: [Some(NodeId(1)), Some(NodeId(1))],
            },
            leaf.clone(),
        ];
        assert_eq!(
            KdTree::from_parts(&mesh, shared, Some(NodeId(0)), bounds, Vec::new()),
            Err(KdError::NotATree { node: 1 })
        );
        let outside = vec![
            KdNode::Inner {
                axis: 0,
                split: 2.0,
                children: [Some(NodeId(1)), None],
            },
            leaf.clone(),
        ];
        assert!(matches!(
            KdTree::from_parts(&mesh, outside, Some(NodeId(0)), bounds, Vec::new()),
            Err(KdError::BadSplit { .. })
        ));
        let bad_tri = vec![KdNode::Leaf { triangles: vec![2] }];
        assert!(matches!(
            KdTree::from_parts(&mesh, bad_tri, Some(NodeId(0)), bounds, Vec::new()),
            Err(KdError::TriangleOutOfRange { .. })
        ));
        assert!(matches!(
            build(
                &mesh,
                &KdBuildOptions {
                    max_leaf_triangles: 0,
                    max_depth: 4,
                    ..KdBuildOptions::default()
                }
            ),
            Err(KdError::MaxLeafTriangles(0))
        ));
    }
}
