//! The node-splitting rules of [`super::build_cell`] and the parallel recursion over them.
//!
//! Subtrees are built as separate preorder arrays and concatenated parent, left, right, so the
//! arena is the same as a sequential depth-first build would make, whatever the thread count.
//! Every per-node computation is either sequential or an order-independent reduction (integer
//! bin counts, min/max bounds, chunks concatenated in order), so it too is thread-count
//! independent.

use rayon::prelude::*;

use super::{KdBuildOptions, KdError, KdNode, NodeId, MAX_LEAF_TRIANGLES};
use oocfmt_meshio::mesh::{Bounds, Mesh};

/// Subtrees of at least this many references build their two sides in parallel; below it the
/// cost of a task and of copying the subtree's nodes into the parent's array would dominate.
const PARALLEL_SUBTREE: usize = 4096;
/// Nodes with at least this many references bin and partition them in parallel chunks: near
/// the root these passes are the sequential bottleneck of the build.
const PARALLEL_PASS: usize = 1 << 16;
const PASS_CHUNK: usize = 1 << 14;
/// Nodes with at most this many references evaluate every reference's bounds as a candidate
/// plane instead of bin boundaries: near the leaves bins are coarse next to the triangles,
/// and on axis-aligned models (CAD, grids) the planes that matter are exactly the faces'.
const EXACT_SAH_MAX: usize = 64;

/// A triangle in a node: its id and the exact bounds of its part inside the node's cell (the
/// triangle clipped to the cell, not its box clipped to the cell: a long diagonal triangle's
/// box would fill every cell it crosses and defeat both the SAH and the empty-space cuts).
#[derive(Clone, Copy, Debug)]
struct Ref {
    tri: u32,
    b: Bounds,
}

/// A node to build: its references, its cell, and the box around the references.
struct Job {
    refs: Vec<Ref>,
    cell: Bounds,
    occupied: Bounds,
    depth: u32,
    /// One-sided splits on the path from the root (see `max_bad_splits`).
    bad: u32,
}

/// What to do with one node.
enum Step {
    Leaf(Vec<Ref>),
    /// Either side may be empty (no references): then that child is absent.
    Split {
        axis: usize,
        split: f32,
        left: Job,
        right: Job,
    },
}

/// A candidate plane and its SAH cost.
#[derive(Clone, Copy)]
struct Plane {
    axis: usize,
    split: f32,
    cost: f64,
}

pub(super) struct Builder<'a> {
    mesh: &'a Mesh,
    opts: &'a KdBuildOptions,
}

impl<'a> Builder<'a> {
    pub(super) fn new(mesh: &'a Mesh, opts: &'a KdBuildOptions) -> Builder<'a> {
        Builder { mesh, opts }
    }

    /// The subtree over `tris` in `cell`, root at level `depth`, in preorder with local ids.
    pub(super) fn subtree(
        &self,
        tris: Vec<u32>,
        cell: Bounds,
        depth: u32,
    ) -> Result<Vec<KdNode>, KdError> {
        let refs: Vec<Ref> = tris
            .par_iter()
            .map(|&tri| Ref {
                tri,
                b: self.clip(tri, &cell),
            })
            .collect();
        drop(tris);
        let occupied = occupied(&refs);
        let piece = self.parallel(Job {
            refs,
            cell,
            occupied,
            depth,
            bad: 0,
        })?;
        let mut out = Vec::with_capacity(piece.len());
        piece.flatten_into(&mut out);
        Ok(out)
    }

    /// The bounds of triangle `tri` clipped to the box `to`.
    fn clip(&self, tri: u32, to: &Bounds) -> Bounds {
        let Some(c) = self.mesh.corners(tri as usize) else {
            return *to;
        };
        clip_triangle(c, to)
    }

    /// The subtree of `job` as pieces: the parallel part is joined once, at the end, instead
    /// of copying every subtree's nodes into its parent's array at each parallel level (about
    /// a dozen copies of the whole tree, each into freshly faulted pages, at 10M triangles).
    fn parallel(&self, job: Job) -> Result<Piece, KdError> {
        if job.refs.len() < PARALLEL_SUBTREE {
            let mut out = Vec::new();
            self.sequential(job, &mut out)?;
            return Ok(Piece::Nodes(out));
        }
        match self.step(job)? {
            Step::Leaf(refs) => Ok(Piece::Nodes(vec![leaf_node(refs)])),
            Step::Split {
                axis,
                split,
                left,
                right,
            } => {
                let side = |job: Job| {
                    if job.refs.is_empty() {
                        Ok(None)
                    } else {
                        self.parallel(job).map(Some)
                    }
                };
                let (l, r) = rayon::join(|| side(left), || side(right));
                // The left error first, so a failing build reports the same error every time.
                let (l, r) = (l?, r?);
                let len = 1 + l.as_ref().map_or(0, Piece::len) + r.as_ref().map_or(0, Piece::len);
                if u32::try_from(len).is_err() {
                    return Err(KdError::TooManyNodes);
                }
                Ok(Piece::Split {
                    axis: axis as u8,
                    split,
                    children: Box::new([l, r]),
                    len,
                })
            }
        }
    }

    /// Builds depth first into `out`, ids being positions in `out`; returns the subtree root.
    fn sequential(&self, job: Job, out: &mut Vec<KdNode>) -> Result<NodeId, KdError> {
        let id = NodeId(u32::try_from(out.len()).map_err(|_| KdError::TooManyNodes)?);
        match self.step(job)? {
            Step::Leaf(refs) => out.push(leaf_node(refs)),
            Step::Split {
                axis,
                split,
                left,
                right,
            } => {
                out.push(KdNode::Inner {
                    axis: axis as u8,
                    split,
                    children: [None, None],
                });
                let l = if left.refs.is_empty() {
                    None
                } else {
                    Some(self.sequential(left, out)?)
                };
                let r = if right.refs.is_empty() {
                    None
                } else {
                    Some(self.sequential(right, out)?)
                };
                if let Some(KdNode::Inner { children, .. }) = out.get_mut(id.index()) {
                    *children = [l, r];
                }
            }
        }
        Ok(id)
    }

    /// Decides how to treat one node (see [`super::build_cell`]).
    fn step(&self, job: Job) -> Result<Step, KdError> {
        let n = job.refs.len();
        if job.depth >= self.opts.max_depth {
            return leaf(job);
        }
        // Small enough: a leaf. Empty-space cuts come before splits only; cutting around
        // leaves too would add about one node per leaf for a little less empty space.
        if n <= self.opts.max_leaf_triangles as usize {
            return leaf(job);
        }
        if let Some((axis, split, empty_low)) = self.empty_cut(&job.cell, &job.occupied) {
            let (lo, hi) = job.cell.split(axis, split);
            let child = |cell: Bounds, refs: Vec<Ref>| Job {
                refs,
                cell,
                occupied: job.occupied,
                depth: job.depth + 1,
                bad: job.bad,
            };
            let (left, right) = if empty_low {
                (child(lo, Vec::new()), child(hi, job.refs))
            } else {
                (child(lo, job.refs), child(hi, Vec::new()))
            };
            return Ok(Step::Split {
                axis,
                split,
                left,
                right,
            });
        }
        let leaf_cost = f64::from(self.opts.intersection_cost) * n as f64;
        let sah = if n <= EXACT_SAH_MAX {
            self.best_exact(&job.refs, &job.cell, &job.occupied)
        } else {
            self.best_sah(&job.refs, &job.cell, &job.occupied)
        };
        // The SAH's plane where it pays off, else (or if it separates nothing) the median.
        let planes = [sah.filter(|p| p.cost < leaf_cost), median(&job.occupied)];
        for p in planes.into_iter().flatten() {
            let (lo, hi) = job.cell.split(p.axis, p.split);
            let (left, right) = self.partition(&job.refs, p.axis, p.split, &lo, &hi);
            let (nl, nr) = (left.0.len(), right.0.len());
            if nl == n && nr == n {
                continue;
            }
            let one_sided = (nl == n && nr > 0) || (nr == n && nl > 0);
            let bad = job.bad + u32::from(one_sided);
            if bad > self.opts.max_bad_splits && n <= MAX_LEAF_TRIANGLES as usize {
                break;
            }
            let child = |cell: Bounds, (refs, occupied): (Vec<Ref>, Bounds)| Job {
                refs,
                cell,
                occupied,
                depth: job.depth + 1,
                bad,
            };
            return Ok(Step::Split {
                axis: p.axis,
                split: p.split,
                left: child(lo, left),
                right: child(hi, right),
            });
        }
        leaf(job)
    }

    /// The thickest empty slab between the cell's boundary and the occupied box, when it is
    /// more than `empty_cut` of the cell: `(axis, plane, whether the empty side is the low one)`.
    fn empty_cut(&self, cell: &Bounds, occupied: &Bounds) -> Option<(usize, f32, bool)> {
        let threshold = f64::from(self.opts.empty_cut);
        let mut best: Option<(f64, usize, f32, bool)> = None;
        for a in 0..3 {
            let ext = f64::from(cell.max[a]) - f64::from(cell.min[a]);
            if ext <= 0.0 {
                continue;
            }
            let low = (f64::from(occupied.min[a]) - f64::from(cell.min[a])) / ext;
            let high = (f64::from(cell.max[a]) - f64::from(occupied.max[a])) / ext;
            for (frac, split, empty_low) in
                [(low, occupied.min[a], true), (high, occupied.max[a], false)]
            {
                if frac > threshold && best.is_none_or(|b| frac > b.0) {
                    best = Some((frac, a, split, empty_low));
                }
            }
        }
        best.map(|(_, a, s, low)| (a, s, low))
    }

    /// The cheapest bin-boundary plane inside the occupied box, by the surface area heuristic.
    fn best_sah(&self, refs: &[Ref], cell: &Bounds, occupied: &Bounds) -> Option<Plane> {
        let bins = self.opts.sah_bins as usize;
        let lo = occupied.min.map(f64::from);
        let ext: [f64; 3] = std::array::from_fn(|a| f64::from(occupied.max[a]) - lo[a]);
        let scale = ext.map(|e| if e > 0.0 { bins as f64 / e } else { 0.0 });
        // Per axis, how many references start and end in each bin: [axis][start/end][bin].
        let count = |chunk: &[Ref]| {
            let mut c = vec![0u32; 6 * bins];
            for r in chunk {
                for a in 0..3 {
                    if scale[a] > 0.0 {
                        let bin =
                            |x: f32| (((f64::from(x) - lo[a]) * scale[a]) as usize).min(bins - 1);
                        if let Some(s) = c.get_mut(2 * a * bins + bin(r.b.min[a])) {
                            *s += 1;
                        }
                        if let Some(e) = c.get_mut((2 * a + 1) * bins + bin(r.b.max[a])) {
                            *e += 1;
                        }
                    }
                }
            }
            c
        };
        let counts = if refs.len() >= PARALLEL_PASS {
            refs.par_chunks(PASS_CHUNK).map(count).reduce(
                || vec![0u32; 6 * bins],
                |mut a, b| {
                    for (x, y) in a.iter_mut().zip(b) {
                        *x += y;
                    }
                    a
                },
            )
        } else {
            count(refs)
        };
        let model = CostModel::new(cell, self.opts)?;
        let n = refs.len() as f64;
        let mut best: Option<Plane> = None;
        for a in 0..3 {
            if scale[a] <= 0.0 {
                continue;
            }
            let starts = counts.get(2 * a * bins..(2 * a + 1) * bins).unwrap_or(&[]);
            let ends = counts
                .get((2 * a + 1) * bins..(2 * a + 2) * bins)
                .unwrap_or(&[]);
            let (mut left, mut ended) = (0f64, 0f64);
            for i in 1..bins {
                left += f64::from(starts.get(i - 1).copied().unwrap_or(0));
                ended += f64::from(ends.get(i - 1).copied().unwrap_or(0));
                let split = (lo[a] + ext[a] * i as f64 / bins as f64) as f32;
                if !(occupied.min[a] < split && split < occupied.max[a]) {
                    continue;
                }
                model.offer(&mut best, a, split, left, n - ended);
            }
        }
        best
    }

    /// The cheapest plane at a reference's bound inside the occupied box, by the SAH with the
    /// exact counts of [`Builder::partition`] (a reference lying in the plane counts on both
    /// sides).
    fn best_exact(&self, refs: &[Ref], cell: &Bounds, occupied: &Bounds) -> Option<Plane> {
        let model = CostModel::new(cell, self.opts)?;
        let mut best: Option<Plane> = None;
        let n = refs.len().min(EXACT_SAH_MAX);
        let refs = refs.get(..n).unwrap_or(refs);
        let (mut mins, mut maxs, mut flat) = (
            [0f32; EXACT_SAH_MAX],
            [0f32; EXACT_SAH_MAX],
            [0f32; EXACT_SAH_MAX],
        );
        for a in 0..3 {
            if occupied.min[a] >= occupied.max[a] {
                continue;
            }
            let mut flats = 0;
            for ((r, lo), hi) in refs.iter().zip(&mut mins).zip(&mut maxs) {
                (*lo, *hi) = (r.b.min[a], r.b.max[a]);
                if r.b.min[a] == r.b.max[a] {
                    if let Some(f) = flat.get_mut(flats) {
                        *f = r.b.min[a];
                        flats += 1;
                    }
                }
            }
            let (mins, maxs, flat) = (&mut mins[..n], &mut maxs[..n], &mut flat[..flats]);
            sort_small(mins);
            sort_small(maxs);
            sort_small(flat);
            // Sweep the candidates in order, counting as the plane moves: references starting
            // below it (`lt`), starting at or below it (`le`, which moves the sweep on), ending
            // at or below it (`ended`), and lying in it (`flat_le - flat_lt`).
            let (mut lt, mut le, mut ended, mut flat_lt, mut flat_le) = (0, 0, 0, 0, 0);
            loop {
                let split = match (mins.get(le), maxs.get(ended)) {
                    (Some(&x), Some(&y)) => x.min(y),
                    (Some(&x), None) => x,
                    (None, Some(&y)) => y,
                    (None, None) => break,
                };
                let advance = |v: &[f32], k: &mut usize, inclusive: bool| {
                    while v
                        .get(*k)
                        .is_some_and(|&x| x < split || (inclusive && x == split))
                    {
                        *k += 1;
                    }
                };
                advance(mins, &mut lt, false);
                advance(mins, &mut le, true);
                advance(maxs, &mut ended, true);
                advance(flat, &mut flat_lt, false);
                advance(flat, &mut flat_le, true);
                if !(occupied.min[a] < split && split < occupied.max[a]) {
                    continue;
                }
                let in_plane = flat_le - flat_lt;
                let (left, right) = (lt + in_plane, n - ended + in_plane);
                model.offer(&mut best, a, split, left as f64, right as f64);
            }
        }
        best
    }

    /// The references on each side of the plane, in their original order, with the box around
    /// each side's; a straddler is clipped again to either side.
    fn partition(
        &self,
        refs: &[Ref],
        axis: usize,
        split: f32,
        lo: &Bounds,
        hi: &Bounds,
    ) -> ((Vec<Ref>, Bounds), (Vec<Ref>, Bounds)) {
        let run = |chunk: &[Ref]| {
            let mut left = (Vec::with_capacity(chunk.len()), Bounds::EMPTY);
            let mut right = (Vec::with_capacity(chunk.len()), Bounds::EMPTY);
            let push = |side: &mut (Vec<Ref>, Bounds), r: Ref| {
                side.1.extend(r.b.min);
                side.1.extend(r.b.max);
                side.0.push(r);
            };
            for r in chunk {
                let (min, max) = (r.b.min[axis], r.b.max[axis]);
                // A triangle lying in the plane is on both sides; one touching it from one side
                // is only on that side.
                if min == split && max == split {
                    push(&mut left, *r);
                    push(&mut right, *r);
                } else if max <= split {
                    push(&mut left, *r);
                } else if min >= split {
                    push(&mut right, *r);
                } else {
                    // The triangle's part inside this side: clipping it to the reference's box
                    // cut at the plane gives exactly that, as the box holds its part in the cell.
                    for (side, child) in [(&mut left, lo), (&mut right, hi)] {
                        let mut to = r.b;
                        to.min[axis] = to.min[axis].max(child.min[axis]);
                        to.max[axis] = to.max[axis].min(child.max[axis]);
                        let b = match self.mesh.corners(r.tri as usize) {
                            Some(c) => clip_triangle(c, &to),
                            None => to,
                        };
                        push(side, Ref { tri: r.tri, b });
                    }
                }
            }
            (left, right)
        };
        if refs.len() < PARALLEL_PASS {
            let (mut left, mut right) = run(refs);
            // Each side was given room for every reference; give back what a big one left over.
            for side in [&mut left.0, &mut right.0] {
                if side.len() >= PARALLEL_SUBTREE && side.capacity() > side.len() + side.len() / 4 {
                    side.shrink_to_fit();
                }
            }
            return (left, right);
        }
        let parts: Vec<_> = refs.par_chunks(PASS_CHUNK).map(run).collect();
        let count = |f: fn(&(_, _)) -> usize| parts.iter().map(f).sum::<usize>();
        let mut left = (
            Vec::with_capacity(count(|p: &((Vec<Ref>, Bounds), _)| p.0 .0.len())),
            Bounds::EMPTY,
        );
        let mut right = (
            Vec::with_capacity(count(|p: &(_, (Vec<Ref>, Bounds))| p.1 .0.len())),
            Bounds::EMPTY,
        );
        for ((l, lb), (r, rb)) in parts {
            left.0.extend(l);
            left.1 = union(left.1, lb);
            right.0.extend(r);
            right.1 = union(right.1, rb);
        }
        (left, right)
    }
}

/// Sorts at most [`EXACT_SAH_MAX`] floats in [`f32::total_cmp`] order (a longer slice only
/// in its first part), as integers: the exact search sorts six such runs per node, and integer
/// comparisons are several times cheaper than `total_cmp`'s.
fn sort_small(v: &mut [f32]) {
    let mut keys = [0u32; EXACT_SAH_MAX];
    let n = v.len().min(EXACT_SAH_MAX);
    for (k, &x) in keys.iter_mut().zip(v.iter()) {
        *k = order_key(x);
    }
    let keys = keys.get_mut(..n).unwrap_or(&mut []);
    keys.sort_unstable();
    for (x, &k) in v.iter_mut().zip(keys.iter()) {
        *x = from_order_key(k);
    }
}

/// A key whose unsigned order is [`f32::total_cmp`]'s order of the floats.
fn order_key(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | 0x8000_0000
    }
}

fn from_order_key(k: u32) -> f32 {
    f32::from_bits(if k >> 31 == 1 { k & 0x7fff_ffff } else { !k })
}

fn leaf_node(refs: Vec<Ref>) -> KdNode {
    KdNode::Leaf {
        triangles: refs.into_iter().map(|r| r.tri).collect(),
    }
}

fn leaf(job: Job) -> Result<Step, KdError> {
    if job.refs.len() > MAX_LEAF_TRIANGLES as usize {
        return Err(KdError::LeafTooLarge {
            triangles: job.refs.len(),
            depth: job.depth,
        });
    }
    Ok(Step::Leaf(job.refs))
}

/// The box around the references' bounds.
fn occupied(refs: &[Ref]) -> Bounds {
    let part = |chunk: &[Ref]| {
        let mut o = Bounds::EMPTY;
        for r in chunk {
            o.extend(r.b.min);
            o.extend(r.b.max);
        }
        o
    };
    refs.par_chunks(PASS_CHUNK)
        .map(part)
        .reduce(|| Bounds::EMPTY, union)
}

/// The middle of the occupied box's longest axis, when that lies strictly inside it.
fn median(occupied: &Bounds) -> Option<Plane> {
    let axis = occupied.longest_axis();
    let (lo, hi) = (occupied.min[axis], occupied.max[axis]);
    // Halving each bound separately cannot overflow, and rounding keeps it inside [lo, hi].
    let split = 0.5 * lo + 0.5 * hi;
    (lo < split && split < hi).then_some(Plane {
        axis,
        split,
        cost: f64::INFINITY,
    })
}

/// Most vertices a triangle clipped by six planes can have.
const MAX_CLIPPED: usize = 9;

/// The bounds of a triangle clipped to the box `to` (Sutherland–Hodgman in f64 against its six
/// planes), rounded outwards to f32 and kept inside the box. A triangle that only touches the
/// box, or vanishes under rounding, gets the part of its own box inside `to` instead: never an
/// empty box, so a reference is never lost.
pub(crate) fn clip_triangle(c: [[f32; 3]; 3], to: &Bounds) -> Bounds {
    // Inside the box, no plane cuts it and the passes would give its own box back: the
    // common case of the out-of-core split passes, which place every triangle of a cell.
    let own = Bounds::of_points(&c);
    if (0..3).all(|a| to.min[a] <= own.min[a] && own.max[a] <= to.max[a]) {
        return own;
    }
    clip_passes(c, to)
}

/// [`clip_triangle`] by its six Sutherland–Hodgman passes, whatever the triangle.
fn clip_passes(c: [[f32; 3]; 3], to: &Bounds) -> Bounds {
    let mut poly = [[0.0f64; 3]; MAX_CLIPPED];
    for (slot, p) in poly.iter_mut().zip(&c) {
        *slot = p.map(f64::from);
    }
    let mut len = 3;
    for a in 0..3 {
        for (plane, keep_below) in [(to.min[a], false), (to.max[a], true)] {
            let plane = f64::from(plane);
            let inside = |p: &[f64; 3]| {
                if keep_below {
                    p[a] <= plane
                } else {
                    p[a] >= plane
                }
            };
            let current = poly.get(..len).unwrap_or(&[]);
            if current.iter().all(inside) {
                continue;
            }
            let mut next = [[0.0f64; 3]; MAX_CLIPPED];
            let mut n = 0;
            let mut emit = |x: [f64; 3]| {
                if let Some(slot) = next.get_mut(n) {
                    *slot = x;
                    n += 1;
                }
            };
            for (i, p) in current.iter().enumerate() {
                let q = current.get((i + 1) % len).unwrap_or(p);
                let (pin, qin) = (inside(p), inside(q));
                if pin {
                    emit(*p);
                }
                if pin != qin {
                    let t = (plane - p[a]) / (q[a] - p[a]);
                    let mut x: [f64; 3] = std::array::from_fn(|k| p[k] + t * (q[k] - p[k]));
                    x[a] = plane;
                    emit(x);
                }
            }
            poly = next;
            len = n;
        }
    }
    let mut out = Bounds::EMPTY;
    for p in poly.get(..len).unwrap_or(&[]) {
        for ((lo, hi), &x) in out.min.iter_mut().zip(&mut out.max).zip(p) {
            *lo = lo.min(down(x));
            *hi = hi.max(up(x));
        }
    }
    if out.is_empty() {
        out = Bounds::of_points(&c);
    }
    for a in 0..3 {
        out.min[a] = out.min[a].max(to.min[a]).min(to.max[a]);
        out.max[a] = out.max[a].min(to.max[a]).max(out.min[a]);
    }
    out
}

/// The largest f32 ≤ `x` (`x` within the f32 range, as clipped coordinates are).
fn down(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x {
        -next_up(-f)
    } else {
        f
    }
}

/// The smallest f32 ≥ `x`.
fn up(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x {
        next_up(f)
    } else {
        f
    }
}

/// The next f32 above a finite `x` (`f32::next_up` needs Rust 1.86).
fn next_up(x: f32) -> f32 {
    if x == 0.0 {
        f32::from_bits(1)
    } else if x > 0.0 {
        f32::from_bits(x.to_bits() + 1)
    } else {
        f32::from_bits(x.to_bits() - 1)
    }
}

fn union(mut a: Bounds, b: Bounds) -> Bounds {
    if !b.is_empty() {
        a.extend(b.min);
        a.extend(b.max);
    }
    a
}

/// The SAH cost of the planes of one cell, shared by the binned and the exact search.
struct CostModel {
    min: [f32; 3],
    max: [f32; 3],
    dims: [f64; 3],
    parent: f64,
    traversal: f64,
    intersection: f64,
}

impl CostModel {
    /// None for a cell without a finite positive surface area (no plane can be judged).
    fn new(cell: &Bounds, opts: &KdBuildOptions) -> Option<CostModel> {
        let dims: [f64; 3] =
            std::array::from_fn(|a| f64::from(cell.max[a]) - f64::from(cell.min[a]));
        let parent = area(dims);
        (parent > 0.0 && parent.is_finite()).then_some(CostModel {
            min: cell.min,
            max: cell.max,
            dims,
            parent,
            traversal: f64::from(opts.traversal_cost),
            intersection: f64::from(opts.intersection_cost),
        })
    }

    /// Keeps the plane at `split` on axis `a`, with `left` and `right` references, in `best`
    /// when it is the cheapest so far.
    fn offer(&self, best: &mut Option<Plane>, a: usize, split: f32, left: f64, right: f64) {
        let (mut l, mut r) = (self.dims, self.dims);
        l[a] = f64::from(split) - f64::from(self.min[a]);
        r[a] = f64::from(self.max[a]) - f64::from(split);
        let cost =
            self.traversal + self.intersection * (area(l) * left + area(r) * right) / self.parent;
        if best.is_none_or(|b| cost < b.cost) {
            *best = Some(Plane {
                axis: a,
                split,
                cost,
            });
        }
    }
}

/// Surface area of a box with these extents.
fn area(d: [f64; 3]) -> f64 {
    2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
}

/// A subtree built in parallel, not yet in one array: the sides of a split are pieces built by
/// separate tasks.
enum Piece {
    /// A subtree in preorder with ids local to it.
    Nodes(Vec<KdNode>),
    Split {
        axis: u8,
        split: f32,
        /// Low and high side; an empty side is `None`.
        children: Box<[Option<Piece>; 2]>,
        /// Nodes in the subtree (checked to fit a `u32`).
        len: usize,
    },
}

impl Piece {
    fn len(&self) -> usize {
        match self {
            Piece::Nodes(nodes) => nodes.len(),
            Piece::Split { len, .. } => *len,
        }
    }

    /// Appends the subtree in preorder, parent, low side, high side, with ids shifted to its
    /// place in `out`: the array a sequential depth-first build would make.
    fn flatten_into(self, out: &mut Vec<KdNode>) {
        let base = out.len() as u32;
        match self {
            Piece::Nodes(nodes) => append_shifted(out, nodes, base),
            Piece::Split {
                axis,
                split,
                children,
                ..
            } => {
                let [l, r] = *children;
                let right_at = 1 + l.as_ref().map_or(0, Piece::len) as u32;
                out.push(KdNode::Inner {
                    axis,
                    split,
                    children: [
                        l.is_some().then_some(NodeId(base + 1)),
                        r.is_some().then_some(NodeId(base + right_at)),
                    ],
                });
                for side in [l, r].into_iter().flatten() {
                    side.flatten_into(out);
                }
            }
        }
    }
}

/// Appends a subtree built with local ids, renumbering its child links by `offset`.
fn append_shifted(out: &mut Vec<KdNode>, nodes: Vec<KdNode>, offset: u32) {
    out.extend(nodes.into_iter().map(|mut n| {
        if let KdNode::Inner { children, .. } = &mut n {
            for c in children.iter_mut().flatten() {
                c.0 += offset;
            }
        }
        n
    }));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_small_sort_is_total_cmp_order() {
        let mut v = vec![
            3.5,
            -0.0,
            0.0,
            f32::NEG_INFINITY,
            -2.0,
            f32::INFINITY,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1e-45,
            f32::NAN,
            -f32::NAN,
            2.0,
            -3.5,
        ];
        let mut expected = v.clone();
        expected.sort_unstable_by(f32::total_cmp);
        sort_small(&mut v);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&v), bits(&expected));
    }

    #[test]
    fn clipping_gives_the_exact_part_inside() {
        // A right triangle with legs 4 along x and y: inside x ≤ 1 it spans y up to 4, inside
        // y ≥ 3 it spans x up to 1.
        let c = [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]];
        let to = |min: [f32; 3], max: [f32; 3]| Bounds { min, max };
        let b = clip_triangle(c, &to([0.0, 0.0, -1.0], [1.0, 4.0, 1.0]));
        assert_eq!((b.min, b.max), ([0.0; 3], [1.0, 4.0, 0.0]));
        let b = clip_triangle(c, &to([0.0, 3.0, -1.0], [4.0, 4.0, 1.0]));
        assert_eq!((b.min, b.max), ([0.0, 3.0, 0.0], [1.0, 4.0, 0.0]));
        // Only touching the box at a corner: the box's part of the triangle's box.
        let b = clip_triangle(c, &to([4.0, 0.0, 0.0], [5.0, 1.0, 1.0]));
        assert!(!b.is_empty());
        // Non-representable crossings round outwards.
        let c = [[0.0, 0.0, 0.0], [3.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let b = clip_triangle(c, &to([1.0, 0.0, -1.0], [3.0, 1.0, 1.0]));
        assert!(f64::from(b.min[1]) <= 1.0 / 3.0 && f64::from(b.min[1]) > 0.3333);
    }

    #[test]
    fn a_triangle_inside_the_box_gets_the_bounds_the_passes_give() {
        // A small linear congruential generator: the same triangles every run.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut unit = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let to = Bounds {
            min: [-1.0, -0.5, 0.0],
            max: [1.0, 0.5, 2.0],
        };
        let mut inside = 0;
        for n in 0..3000 {
            let spread = [0.9f32, 1.3, 3.0][n % 3];
            let c: [[f32; 3]; 3] = std::array::from_fn(|_| {
                std::array::from_fn(|k| {
                    let (lo, hi) = (to.min[k], to.max[k]);
                    match unit() {
                        u if u < 0.03 => lo,
                        u if u < 0.06 => hi,
                        _ => (lo + hi) / 2.0 + (unit() - 0.5) * (hi - lo) * spread,
                    }
                })
            });
            let (fast, slow) = (clip_triangle(c, &to), clip_passes(c, &to));
            assert_eq!(
                (fast.min, fast.max),
                (slow.min, slow.max),
                "triangle {n}: {c:?}"
            );
            inside += usize::from(fast == Bounds::of_points(&c));
        }
        assert!(
            inside > 400,
            "{inside} triangles inside: the shortcut was hardly tried"
        );
    }
}
