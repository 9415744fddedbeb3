//! The number of distinct triangles and their total area under every node, in one pass over
//! the leaves instead of one walk per LOD node (which costs a pass over the whole tree per LOD
//! level).
//!
//! A triangle straddling several leaves must count once per subtree. Visiting the leaves in
//! depth-first order, each reference adds the triangle to its leaf and takes it away again at
//! the lowest common ancestor of this leaf and the triangle's previous leaf: the leaves of a
//! subtree are consecutive in that order, so a subtree holding `k` of a triangle's leaves also
//! holds the `k − 1` ancestors of consecutive pairs among them, and the triangle sums to one.

use crate::kdtree::{KdNode, KdTree, NodeId};

/// Per node (indexed by [`NodeId::index`]): distinct triangles and their summed area.
pub(crate) struct Totals {
    pub count: Vec<i64>,
    pub area: Vec<f64>,
}

impl Totals {
    pub fn of(&self, id: NodeId) -> (usize, f64) {
        let count = self.count.get(id.index()).copied().unwrap_or(0);
        let area = self.area.get(id.index()).copied().unwrap_or(0.0);
        (usize::try_from(count).unwrap_or(0), area.max(0.0))
    }
}

const NONE: u32 = u32::MAX;

/// The totals of every node reached from the root; `areas` holds each mesh triangle's area.
pub(super) fn totals(tree: &KdTree, areas: &[f64]) -> Totals {
    let n = tree.nodes().len();
    let mut count = vec![0i64; n];
    let mut area = vec![0.0f64; n];
    let mut parent = vec![NONE; n];
    let mut depth = vec![0u32; n];
    let mut order: Vec<u32> = Vec::with_capacity(n);
    let mut last = vec![NONE; areas.len()];
    let mut stack: Vec<u32> = tree.root().map(|r| r.0).into_iter().collect();
    while let Some(id) = stack.pop() {
        order.push(id);
        match tree.node(NodeId(id)) {
            Some(KdNode::Inner { children, .. }) => {
                let d = depth.get(id as usize).copied().unwrap_or(0) + 1;
                // Right first so that the left subtree is visited first.
                for c in children.iter().rev().flatten() {
                    if let (Some(p), Some(cd)) =
                        (parent.get_mut(c.index()), depth.get_mut(c.index()))
                    {
                        *p = id;
                        *cd = d;
                        stack.push(c.0);
                    }
                }
            }
            Some(KdNode::Leaf { triangles }) => {
                for &t in triangles {
                    let a = areas.get(t as usize).copied().unwrap_or(0.0);
                    add(&mut count, &mut area, id, 1, a);
                    if let Some(prev) = last.get_mut(t as usize) {
                        if *prev != NONE {
                            let l = ancestor(&parent, &depth, *prev, id);
                            add(&mut count, &mut area, l, -1, -a);
                        }
                        *prev = id;
                    }
                }
            }
            None => {}
        }
    }
    for &id in order.iter().rev() {
        let p = parent.get(id as usize).copied().unwrap_or(NONE);
        if p == NONE {
            continue;
        }
        let (c, a) = (
            count.get(id as usize).copied().unwrap_or(0),
            area.get(id as usize).copied().unwrap_or(0.0),
        );
        add(&mut count, &mut area, p, c, a);
    }
    Totals { count, area }
}

fn add(count: &mut [i64], area: &mut [f64], id: u32, c: i64, a: f64) {
    if let (Some(k), Some(s)) = (count.get_mut(id as usize), area.get_mut(id as usize)) {
        *k += c;
        *s += a;
    }
}

/// The lowest common ancestor of `a` and `b` (nodes of one tree, with their parents and
/// depths).
fn ancestor(parent: &[u32], depth: &[u32], mut a: u32, mut b: u32) -> u32 {
    let d = |x: u32| depth.get(x as usize).copied().unwrap_or(0);
    let up = |x: u32| parent.get(x as usize).copied().unwrap_or(NONE);
    while d(a) > d(b) {
        a = up(a);
    }
    while d(b) > d(a) {
        b = up(b);
    }
    while a != b && a != NONE && b != NONE {
        a = up(a);
        b = up(b);
    }
    a
}
