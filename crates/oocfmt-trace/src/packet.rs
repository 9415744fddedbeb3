//! Coherent rays traced together: a packet of `N` rays whose direction components have the same
//! signs (and none is ±0 or so tiny that its reciprocal overflows) and whose watertight kernels
//! share an axis permutation walks the kd-tree once for all of them (Wald 2004, §3: kd-tree
//! packet traversal). Every ray keeps its own interval and nearest hit; a mask says which rays
//! are on the path being walked. At an inner node each ray makes the decision it makes alone
//! ([`Tracer::trace`]), and the packet goes where any ray goes: near child first, the far child
//! stacked for the rays that want it. Leaves test each triangle against all the packet's rays
//! at once ([`RayLanes`]). LOD stops, missing blocks, proxies and R-LOD planes end a ray on the
//! current path exactly as alone. The per-ray loops have fixed lengths and no early exits, so
//! the compiler makes them SIMD.
//!
//! Every ray visits the same nodes in the same order as alone, with the same nearest distance
//! at each (the near/far order depends only on the direction's signs), and a stacked subtree
//! is skipped for a ray only where the single-ray path pops and skips it, so the hits are the
//! same, bit for bit, and so is the count of nodes visited. The blocks the rays wanted and did
//! not get are logged under each ray's key ([`Memo::release_deferred`]), so that the caller can
//! replay them in the single-ray order. Rays that cannot form a packet are traced alone.
//!
//! [`Tracer::trace_packet_layers`] walks the same way, each ray also keeping the translucent
//! LOD entries it goes on behind ([`Tracer::trace_layers`]): they do not end it, so it walks
//! on as alone, and collects the same layers.
//!
//! Under a part filter each ray asks the filter's grid at the nodes where it asks alone, with
//! its own interval, and leaves the packet's path where its stretch meets no visible part's
//! box ([`Tracer::with_parts`]), so this too is as alone.

// Lane loops index several arrays by the same lane, which is what the compiler vectorizes.
#![allow(clippy::needless_range_loop)]

use arrayvec::ArrayVec;

use oocfmt::records::MAX_TREE_DEPTH;

use crate::blocks::{NodeView, TreeletData, NONE};
use crate::intersect::{ray_box, Ray};
use crate::lanes::RayLanes;
use crate::parts::{BlockMask, Cover, VisibilityGrid};
use crate::traverse::{
    clamp_mid, grid_due, opaque, proxy_sample, push_last, shown, visible_entries, Best, Collected,
    Hit, Layers, Memo, Tracer, NO_GRID,
};

/// Which rays of a packet (bit i: ray i).
type Mask = u32;

/// A subtree waiting on the packet's stack: each ray's interval, which rays visit it, and for
/// which of them it is a far child stacked by their own decision (the rays that went there
/// alone, without visiting the near side, do not test it against their nearest hit when it is
/// popped: alone they never stacked it).
#[derive(Clone, Copy)]
struct Entry<'m, const N: usize> {
    data: &'m TreeletData,
    node: u32,
    lods: u8,
    active: Mask,
    check: Mask,
    /// Nodes on the path before the part filter's grid is asked again (as alone).
    due: u8,
    /// The rays for which the grid need not be asked below (as alone).
    full: Mask,
    t0: [f32; N],
    t1: [f32; N],
}

impl<'m, const N: usize> Entry<'m, N> {
    /// The far side `far` of a split, stacked below `lods` LOD nodes of the path; `check`: the
    /// rays that stacked it by their own decision.
    #[inline(always)]
    fn far(far: At<'m, N>, lods: u8, check: Mask) -> Entry<'m, N> {
        Entry {
            data: far.data,
            node: far.node,
            lods,
            active: far.active,
            check,
            due: far.due,
            full: far.full,
            t0: far.t0,
            t1: far.t1,
        }
    }
}

/// A LOD node on the packet's path, with each ray's interval in its cell.
#[derive(Clone, Copy)]
struct LastVoxels<'m, const N: usize> {
    data: &'m TreeletData,
    lod: u32,
    radius: f32,
    t: [f32; N],
    t1: [f32; N],
}

/// The per-ray state of the split decisions (structure of arrays) and the direction signs the
/// rays share.
struct Lanes<const N: usize> {
    org: [[f32; N]; 3],
    inv: [[f32; N]; 3],
    /// `eps · |inv|` per axis, as [`Tracer::trace`] computes it.
    tol: [[f32; N]; 3],
    eps: [f32; N],
    left_first: [bool; 3],
}

impl<const N: usize> Lanes<N> {
    /// None when the rays cannot walk together: a direction component is ±0 or has no finite
    /// reciprocal (the ray is parallel to that axis's planes), the signs differ, or there are
    /// more rays than bits in a [`Mask`].
    fn new(rays: &[Ray; N], eps: [f32; N]) -> Option<Lanes<N>> {
        let first = rays.first()?;
        if N > Mask::BITS as usize {
            return None;
        }
        let left_first = first.dir.map(|d| d > 0.0);
        for r in rays {
            for k in 0..3 {
                if r.dir[k] == 0.0 || !r.inv[k].is_finite() || (r.dir[k] > 0.0) != left_first[k] {
                    return None;
                }
            }
        }
        let inv = [0, 1, 2].map(|k| std::array::from_fn(|i| rays[i].inv[k]));
        Some(Lanes {
            org: [0, 1, 2].map(|k| std::array::from_fn(|i| rays[i].org[k])),
            tol: [0, 1, 2].map(|k| std::array::from_fn(|i| eps[i] * inv[k][i].abs())),
            inv,
            eps,
            left_first,
        })
    }

    /// The children `left` and `right` of a split of axis `a` in the order the rays meet
    /// them.
    #[inline(always)]
    fn in_order(&self, a: u8, left: u32, right: u32) -> (u32, u32) {
        if self.left_first[usize::from(a.min(2))] {
            (left, right)
        } else {
            (right, left)
        }
    }
}

/// The decisions of every ray at a split plane: which rays visit the side they meet first and
/// which the second, and the crossing clamped to each ray's interval.
struct Split<const N: usize> {
    before: Mask,
    after: Mask,
    mid: [f32; N],
}

/// Where the packet is: the node, each ray's interval in its cell, and which rays are on this
/// path.
#[derive(Clone, Copy)]
struct At<'m, const N: usize> {
    data: &'m TreeletData,
    node: u32,
    active: Mask,
    /// Nodes on the path before the part filter's grid is asked again ([`grid_due`]).
    due: u8,
    /// The rays whose stretch in an ancestor's cell the grid found full of visible parts'
    /// cells ([`Cover::Full`]): they are not asked again below.
    full: Mask,
    t0: [f32; N],
    t1: [f32; N],
}

impl<'m, const N: usize> At<'m, N> {
    /// Where the packet goes on from popped entry `e`: with the rays of `e` that still visit
    /// it (a ray that stacked it itself skips it when it starts beyond its nearest hit at
    /// `best_t`, with tolerance `eps`). None when no ray does.
    #[inline(always)]
    fn resume(e: &Entry<'m, N>, best_t: &[f32; N], eps: &[f32; N]) -> Option<At<'m, N>> {
        let mut beyond: Mask = 0;
        for i in 0..N {
            beyond |= Mask::from(e.t0[i] > best_t[i] + eps[i]) << i;
        }
        let active = e.active & !(e.check & beyond);
        (active != 0).then_some(At {
            data: e.data,
            node: e.node,
            active,
            due: e.due,
            full: e.full,
            t0: e.t0,
            t1: e.t1,
        })
    }

    /// Each ray's decision at a split plane of axis `a` at `split`, between the child met
    /// first and the second one ([`NONE`]: no child), for the rays of `active`.
    #[inline(always)]
    fn split(
        &self,
        lanes: &Lanes<N>,
        active: Mask,
        a: u8,
        split: f32,
        first: u32,
        second: u32,
    ) -> Split<N> {
        let k = usize::from(a.min(2));
        let (org, inv, tol) = (&lanes.org[k], &lanes.inv[k], &lanes.tol[k]);
        let (t0, t1) = (&self.t0, &self.t1);
        let mut s = Split {
            before: 0,
            after: 0,
            mid: [0.0; N],
        };
        for i in 0..N {
            let ts = (split - org[i]) * inv[i];
            s.before |= Mask::from(ts + tol[i] >= t0[i]) << i;
            s.after |= Mask::from(ts - tol[i] <= t1[i]) << i;
            s.mid[i] = clamp_mid(ts, t0[i], t1[i]);
        }
        let has = |c: u32| if c != NONE { active } else { 0 };
        s.before &= has(first);
        s.after &= has(second);
        s
    }

    /// Goes on after a split into `data`, as each ray alone does: both sides, the near one
    /// now and the far one returned to be stacked; one side, that one now. None: no ray goes
    /// on.
    #[inline(always)]
    fn step(
        &mut self,
        s: &Split<N>,
        data: &'m TreeletData,
        first: u32,
        second: u32,
    ) -> Option<Option<At<'m, N>>> {
        self.data = data;
        match (s.before != 0, s.after != 0) {
            (true, far) => {
                let far = far.then_some(At {
                    data,
                    node: second,
                    active: s.after,
                    due: self.due,
                    full: self.full,
                    t0: s.mid,
                    t1: self.t1,
                });
                self.node = first;
                self.active = s.before;
                self.t1 = s.mid;
                Some(far)
            }
            (false, true) => {
                self.node = second;
                self.active = s.after;
                self.t0 = s.mid;
                Some(None)
            }
            (false, false) => None,
        }
    }
}

/// How many rays `m` (of a packet of `N`) holds: by nibbles from a table, a fixed number of
/// steps, as the baseline x86-64 target has no `popcnt` instruction.
#[inline(always)]
fn rays_in<const N: usize>(m: Mask) -> u64 {
    // Bits set in each 4-bit value, one per nibble.
    const NIBBLES: u64 = 0x4332_3221_3221_2110;
    (0..N.div_ceil(4)).fold(0, |n, k| n + (NIBBLES >> (4 * (m >> (4 * k) & 15)) & 15))
}

/// Drops from `at` the rays whose stretch in its cell meets no visible part's box in `grid`,
/// and marks as full those whose stretch the grid finds full ([`Cover::Full`]): the decision
/// each ray not full yet makes alone ([`VisibilityGrid::cover_segment`] with its tolerance
/// `eps`). (Asking once for the box around all the stretches first saved nothing on the CAD
/// scene: near visible parts the rays mostly need their own answers.)
#[inline(always)]
fn showing<const N: usize>(
    grid: &VisibilityGrid,
    rays: &[Ray; N],
    at: &mut At<'_, N>,
    eps: &[f32; N],
) {
    let ask = at.active & !at.full;
    for (i, ray) in rays.iter().enumerate() {
        if ask >> i & 1 != 0 {
            match grid.cover_segment(ray, at.t0[i], at.t1[i], eps[i]) {
                Cover::None => at.active &= !(1 << i),
                Cover::Some => {}
                Cover::Full => at.full |= 1 << i,
            }
        }
    }
}

/// The rays of `m`, in order.
fn rays_of(m: Mask) -> impl Iterator<Item = usize> {
    (0..Mask::BITS as usize).filter(move |&i| m >> i & 1 != 0)
}

impl Tracer<'_> {
    /// [`Tracer::trace`] of each of `rays`, walking the tree once for all of them where they
    /// can form a packet (see the module comment), ray by ray otherwise. The blocks a ray
    /// wanted are logged under its key in `keys` (see [`Memo::release_deferred`]).
    pub fn trace_packet<const N: usize>(
        &self,
        rays: &[Ray; N],
        keys: &[u32; N],
        memo: &Memo,
    ) -> [Option<Hit>; N] {
        let mut near = Nearest::new([f32::INFINITY; N], Ending);
        match self.walk_packet(rays, keys, memo, &mut near) {
            Some(()) => {
                let mut ends = near.best.into_iter().zip(near.best_t);
                std::array::from_fn(|_| ends.next().and_then(|(b, t)| b.hit(t)))
            }
            None => {
                let mut out = [const { None }; N];
                for ((o, ray), &key) in out.iter_mut().zip(rays).zip(keys) {
                    memo.defer_wants(Some(key));
                    *o = self.trace(ray, memo);
                }
                memo.defer_wants(None);
                out
            }
        }
    }

    /// [`Tracer::trace_layers`] of each of `rays` closer than its `t_max`, into `out`,
    /// walking the tree once for all of them where they can form a packet, as
    /// [`Tracer::trace_packet`] does: each ray collects the same layers as alone, and none is
    /// walked again to find them. (`out` is written in place: a packet's layers take
    /// kilobytes, and moving them cost more than the walk on full-detail views.)
    pub fn trace_packet_layers<const N: usize>(
        &self,
        rays: &[Ray; N],
        keys: &[u32; N],
        t_max: [f32; N],
        memo: &Memo,
        out: &mut [Layers; N],
    ) {
        let t_max = t_max.map(|t| if t.is_nan() { f32::INFINITY } else { t });
        let layers: [Collected<'_>; N] = std::array::from_fn(|_| Collected::new());
        let mut near = Nearest::new(t_max, layers);
        if self.walk_packet(rays, keys, memo, &mut near).is_some() {
            let ends = near.best.into_iter().zip(near.best_t);
            for ((l, o), (best, t)) in near.layers.iter_mut().zip(out.iter_mut()).zip(ends) {
                l.finish(t, best, o);
            }
            return;
        }
        for (((o, ray), &key), t) in out.iter_mut().zip(rays).zip(keys).zip(t_max) {
            memo.defer_wants(Some(key));
            *o = self.trace_layers(ray, t, memo);
        }
        memo.defer_wants(None);
    }

    /// The packet walk of `rays`, from and into `near` (each ray's farthest distance, and
    /// where it keeps layers); None when the rays cannot form a packet.
    fn walk_packet<'m, const N: usize, L: Layering<'m>>(
        &self,
        rays: &[Ray; N],
        keys: &[u32; N],
        memo: &'m Memo,
        near: &mut Nearest<'m, N, L>,
    ) -> Option<()> {
        let eps = std::array::from_fn(|i| self.ray_eps(&rays[i]));
        let (lanes, kernel) = (Lanes::new(rays, eps)?, RayLanes::new(rays)?);
        let p = Packet {
            rays,
            keys,
            lanes: &lanes,
            kernel: &kernel,
            memo,
        };
        // Two copies of the walk, as alone ([`Tracer::trace`]): without a grid, not even its
        // branch in the node loop.
        match self.grid {
            Some(g) => self.walk::<N, true, L>(&p, g, near),
            None => self.walk::<N, false, L>(&p, &NO_GRID, near),
        }
        Some(())
    }

    /// The packet's walk from `near`, asking `grid` where `GRID`: each ray's nearest surface
    /// (and, when collecting, the layers in front of it).
    fn walk<'m, const N: usize, const GRID: bool, L: Layering<'m>>(
        &self,
        p: &Packet<'_, 'm, N>,
        grid: &VisibilityGrid,
        near: &mut Nearest<'m, N, L>,
    ) {
        let (rays, lanes, memo) = (p.rays, p.lanes, p.memo);
        let mut lasts = LastsN::new();
        let Some(root) = self.packet_root(p, &near.best_t) else {
            return;
        };
        let mut stack = ArrayVec::<Entry<'m, N>, { MAX_TREE_DEPTH as usize }>::new();
        stack.push(root);
        let mut visited = 0u64;
        // Nodes the packet visited, held to the tracer's bound as a single ray's are.
        let mut steps = 0u64;
        'packet: while let Some(e) = stack.pop() {
            let Some(mut at) = At::resume(&e, &near.best_t, &lanes.eps) else {
                continue;
            };
            let mut lods = e.lods;
            lasts.truncate(usize::from(lods));
            while let Some(n) = at.data.node(at.node) {
                visited += rays_in::<N>(at.active);
                steps += 1;
                if steps > self.max_visits {
                    break 'packet;
                }
                // As alone: a ray whose stretch in this cell meets no visible part's box
                // skips the subtree.
                if GRID {
                    let lod = matches!(n, NodeView::Lod { .. });
                    if grid_due(&mut at.due, lod) && at.active & !at.full != 0 {
                        showing(grid, rays, &mut at, &lanes.eps);
                        if at.active == 0 {
                            break;
                        }
                    }
                }
                let (s, first, second, next) = match n {
                    NodeView::Inner {
                        axis: a,
                        split,
                        left,
                        right,
                    } => {
                        let (first, second) = lanes.in_order(a, left, right);
                        let s = at.split(lanes, at.active, a, split, first, second);
                        (s, first, second, at.data)
                    }
                    NodeView::Lod {
                        axis: a,
                        split,
                        lod,
                    } => match self.packet_lod_step(
                        p,
                        &at,
                        &mut lods,
                        &mut lasts,
                        near,
                        (a, split, lod),
                    ) {
                        Some(next) => next,
                        None => break,
                    },
                    NodeView::Leaf {
                        first,
                        count,
                        block,
                    } => {
                        self.packet_leaf_step(p, &at, &lasts, near, (first, count), block);
                        break;
                    }
                };
                match at.step(&s, next, first, second) {
                    None => break,
                    Some(None) => {}
                    Some(Some(far)) => {
                        let _ = stack.try_push(Entry::far(far, lods, s.before & s.after));
                    }
                }
            }
        }
        memo.visited.set(memo.visited.get() + visited);
    }

    /// The stack entry the packet starts from: the root treelet, for the rays that meet the
    /// scene's box closer than their `t_max`. None when no ray does, or the root block is not
    /// available (then each ray wants it).
    fn packet_root<'m, const N: usize>(
        &self,
        w: &Packet<'_, 'm, N>,
        t_max: &[f32; N],
    ) -> Option<Entry<'m, N>> {
        let (mut t0, mut t1) = ([0f32; N], [0f32; N]);
        let mut live: Mask = 0;
        for ((i, ray), &t_max) in w.rays.iter().enumerate().zip(t_max) {
            let eps = w.lanes.eps[i];
            if let Some((a, b)) = ray_box(ray, self.lo, self.hi, eps, 0.0, t_max) {
                (t0[i], t1[i]) = (a, b);
                live |= 1 << i;
            }
        }
        if live == 0 {
            return None;
        }
        let (root_block, root_treelet) = self.root?;
        let Some(root_data) = w.memo.treelets(self.cache, root_block) else {
            for i in rays_of(live) {
                w.memo
                    .want_later(w.keys[i], root_block, f32::INFINITY, t0[i]);
            }
            return None;
        };
        let &root = root_data.roots.get(root_treelet as usize)?;
        Some(Entry {
            data: root_data,
            node: root,
            lods: 0,
            active: live,
            check: live,
            due: 0,
            full: 0,
            t0,
            t1,
        })
    }

    /// The LOD step of the packet walk, at the LOD node of `at` with split `(axis, split)`
    /// and LOD entry `lod`: the node becomes the last voxel of the path (`lasts`, `lods` of
    /// them); the rays the LOD metric stops end on it, and all of them do when the child block
    /// is not available, each as alone. Returns the split of the rays going on into the child
    /// treelets, as [`At::step`] takes it; None where no ray goes on.
    #[inline(always)]
    fn packet_lod_step<'m, const N: usize, L: Layering<'m>>(
        &self,
        w: &Packet<'_, 'm, N>,
        at: &At<'m, N>,
        lods: &mut u8,
        lasts: &mut LastsN<'m, N>,
        near: &mut Nearest<'m, N, L>,
        (a, split, lod): (u8, f32, u32),
    ) -> Option<(Split<N>, u32, u32, &'m TreeletData)> {
        let data = at.data;
        let l = data.lods.get(lod as usize)?;
        *lods = push_last(
            lasts,
            LastVoxels {
                data,
                lod,
                radius: l.radius,
                t: at.t0,
                t1: at.t1,
            },
        );
        let hidden = self.hides_lod(data, lod);
        let mut stop: Mask = 0;
        if self.lod_c > 0.0 && !hidden {
            for i in 0..N {
                stop |= Mask::from(l.radius <= at.t0[i] * self.lod_c) << i;
            }
        }
        stop &= at.active;
        let go = at.active & !stop;
        let child = if go != 0 {
            w.memo.treelets(self.cache, l.child_block)
        } else {
            None
        };
        if hidden && child.is_none() {
            // As alone: a hidden entry stands in for nothing; each ray passes the cell.
            for i in rays_of(at.active) {
                w.memo
                    .want_later(w.keys[i], l.child_block, l.radius, at.t0[i]);
            }
            return None;
        }
        // The rays that end here: those that stop, and, without the child block, all of
        // them. Without the node's look they just end.
        let look = (stop != 0 || child.is_none()).then(|| data.look(lod));
        if let Some(Some((look, proxy))) = look {
            let proxy = proxy.and_then(|p| self.proxies.get(p as usize));
            let ends = if child.is_some() { stop } else { at.active };
            for (i, ray) in w.rays.iter().enumerate() {
                if ends >> i & 1 == 0 {
                    continue;
                }
                let (t0, t1) = (at.t0[i], at.t1[i]);
                let own = || shown(&look, ray, t0, t1, l.radius, data.lod_part(lod));
                let found = if stop >> i & 1 != 0 {
                    own()
                } else {
                    w.memo.want_later(w.keys[i], l.child_block, l.radius, t0);
                    // A proxy that sees nothing in the ray's direction skips the subtree.
                    match proxy {
                        Some(p) => Some(proxy_sample(&p.samples, ray))
                            .filter(|s| !s.is_empty())
                            .map(|s| (t0, Best::Proxy(s, l.radius))),
                        None => opaque(own()),
                    }
                };
                near.offer(i, found);
            }
        }
        let child = child?;
        let root = |t: u32| {
            child
                .roots
                .get(t as usize)
                .copied()
                .filter(|&r| t != NONE && r != NONE)
                .unwrap_or(NONE)
        };
        let (left, right) = (root(l.left), root(l.right));
        let (first, second) = w.lanes.in_order(a, left, right);
        let s = at.split(w.lanes, go, a, split, first, second);
        Some((s, first, second, child))
    }

    /// The leaf step of the packet walk, at a leaf of `(first, count)` list entries in
    /// triangle block `block`: each active ray's nearest of its triangles, all tested at once,
    /// or, when the block is not available, each ray's last voxel on the path (`lasts`; the
    /// block is wanted either way).
    #[inline(always)]
    fn packet_leaf_step<'m, const N: usize, L: Layering<'m>>(
        &self,
        w: &Packet<'_, 'm, N>,
        at: &At<'m, N>,
        lasts: &LastsN<'m, N>,
        near: &mut Nearest<'m, N, L>,
        (first, count): (u16, u16),
        block: u32,
    ) {
        let (td, mask) = match self.parts {
            None => (w.memo.triangles(self.cache, block), BlockMask::NoneHidden),
            Some(f) => match w.memo.masked(self.cache, block, f) {
                Some((td, mask)) => (Some(td), mask),
                None => (None, BlockMask::NoneHidden),
            },
        };
        match td {
            Some(td) => {
                let first = usize::from(first);
                let list = td.list.get(first..first + usize::from(count));
                let list = list.unwrap_or(&[]);
                let mut visible;
                let list = match (mask, self.parts) {
                    (BlockMask::NoneHidden, _) | (_, None) => list,
                    (BlockMask::AllHidden, _) => &[],
                    (BlockMask::Mixed, Some(f)) => {
                        visible = w.memo.visible.borrow_mut();
                        visible_entries(list, td, f, &mut visible);
                        &visible[..]
                    }
                };
                let h = w
                    .kernel
                    .nearest(at.active, list, &td.positions, &mut near.best_t);
                for (i, b) in near.best.iter_mut().enumerate() {
                    if h.hit >> i & 1 != 0 {
                        *b = Best::Triangle {
                            data: td,
                            triangle: u32::from(h.triangle[i]),
                            bary: [h.bary[0][i], h.bary[1][i], h.bary[2][i]],
                        };
                    }
                }
            }
            None => {
                for (i, ray) in w.rays.iter().enumerate() {
                    if at.active >> i & 1 == 0 {
                        continue;
                    }
                    match lasts.last() {
                        Some(lv) => {
                            let (t, t1) = (lv.t[i], lv.t1[i]);
                            w.memo.want_later(w.keys[i], block, lv.radius, t);
                            if self.hides_lod(lv.data, lv.lod) {
                                continue;
                            }
                            let part = lv.data.lod_part(lv.lod);
                            let found = lv
                                .data
                                .look(lv.lod)
                                .and_then(|(look, _)| shown(&look, ray, t, t1, lv.radius, part));
                            near.offer(i, opaque(found));
                        }
                        None => {
                            let t = at.t0[i];
                            w.memo.want_later(w.keys[i], block, f32::INFINITY, t);
                        }
                    }
                }
            }
        }
    }
}

/// What the steps of a packet's walk read: its rays, their keys and lanes, the leaf kernel,
/// and the memo.
struct Packet<'r, 'm, const N: usize> {
    rays: &'r [Ray; N],
    keys: &'r [u32; N],
    lanes: &'r Lanes<N>,
    kernel: &'r RayLanes<N>,
    memo: &'m Memo,
}

/// The LOD nodes on the packet's path, outermost first.
type LastsN<'m, const N: usize> = ArrayVec<LastVoxels<'m, N>, { MAX_TREE_DEPTH as usize }>;

/// Each ray's nearest surface so far, at `best_t`, and where the rays keep the translucent
/// surfaces in front of it (`L`). Kept apart from the rest of the walk's state: the leaf
/// kernel writes `best_t` through a pointer, and a struct holding the rays' references too
/// would then be read back from memory after every leaf.
struct Nearest<'m, const N: usize, L> {
    best: [Best<'m>; N],
    best_t: [f32; N],
    layers: L,
}

impl<'m, const N: usize, L: Layering<'m>> Nearest<'m, N, L> {
    /// Nothing found yet closer than `t_max`, translucent surfaces kept in `layers`.
    fn new(t_max: [f32; N], layers: L) -> Nearest<'m, N, L> {
        Nearest {
            best: [Best::None; N],
            best_t: t_max,
            layers,
        }
    }

    /// Ray `i`, which found `found` on the current path, keeps it when it is nearer: as a
    /// layer it goes on behind where `L` keeps it, else as its nearest.
    #[inline(always)]
    fn offer(&mut self, i: usize, found: Option<(f32, Best<'m>)>) {
        if let (Some((t, s)), Some(bt), Some(b)) =
            (found, self.best_t.get_mut(i), self.best.get_mut(i))
        {
            if t < *bt && !self.layers.keep(i, t, s) {
                *bt = t;
                *b = s;
            }
        }
    }
}

/// Where the rays of a packet keep the translucent surfaces they go on behind.
trait Layering<'m> {
    /// Whether ray `i` keeps surface `s` at `t` as a layer and goes on behind it.
    fn keep(&mut self, i: usize, t: f32, s: Best<'m>) -> bool;
}

/// Nowhere ([`Tracer::trace_packet`]): the nearest surface ends a ray, translucent or not.
struct Ending;

impl<'m> Layering<'m> for Ending {
    #[inline(always)]
    fn keep(&mut self, _: usize, _: f32, _: Best<'m>) -> bool {
        false
    }
}

/// Each ray's own layers, as alone ([`Collected::keep`]; [`Tracer::trace_packet_layers`]).
impl<'m, const N: usize> Layering<'m> for [Collected<'m>; N] {
    #[inline(always)]
    fn keep(&mut self, i: usize, t: f32, s: Best<'m>) -> bool {
        self.get_mut(i).is_some_and(|l| l.keep(t, s))
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn rays_in_counts_the_bits_of_a_mask() {
        for m in [0u32, 1, 0b1011, 0xff, 0xf0f0, 0x8000_0001, u32::MAX] {
            assert_eq!(super::rays_in::<32>(m), u64::from(m.count_ones()), "{m:#x}");
            assert_eq!(
                super::rays_in::<4>(m & 15),
                u64::from((m & 15).count_ones())
            );
        }
    }
}
