//! The out-of-core median split (Áfra et al. 2012, §4.1): while a cell holds more triangles
//! than fit in memory, cut it at the middle of its longest axis in one streaming pass over its
//! spill file. A triangle reaching both halves goes to both (its copy on the side away from its
//! centroid is marked as not primary); a triangle is placed by the bounds of its part inside
//! the cell, so thin diagonal triangles are not copied where they do not reach.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use rayon::prelude::*;

use super::disk::SpillDisk;
use super::record::SoupTriangle;
use super::segments::Run;
use super::soup::{SoupReader, SoupWriter};
use super::OocError;
use crate::kdtree::clip_triangle;
use crate::layout::plan::is_lod_depth;
use crate::lod::rlod::{PlaneFit, PlaneMoments};
use crate::progress::Progress;
use oocfmt_meshio::import::InputTriangle;
use oocfmt_meshio::mesh::Bounds;

/// The top of the tree, above the chunks: inner nodes from median splits, in preorder.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum TopNode {
    Inner {
        axis: u8,
        split: f32,
        children: [Option<usize>; 2],
    },
    Chunk(usize),
}

/// A cell small enough to build in memory: its spill run, its place in the tree.
#[derive(Clone, Debug, PartialEq)]
pub struct Chunk {
    /// Its triangles (consumed, so gone from the disk, once the chunk is built).
    pub run: Run,
    pub count: u64,
    pub cell: Bounds,
    /// Node level of the chunk's root below the scene root (0 for the root itself).
    pub depth: u32,
    /// The top nodes above it, root first.
    pub ancestors: Vec<usize>,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct TopTree {
    pub nodes: Vec<TopNode>,
    pub chunks: Vec<Chunk>,
    /// Cells that could not be split further (every triangle reaches both halves, or the depth
    /// limit) and stay over the budget.
    pub oversized: Vec<usize>,
    /// With [`RlodMoments`]: the R-LOD planes of the inner nodes that are LOD nodes, by node,
    /// fitted to the moments gathered in their split pass. Their deviation is still 0: the
    /// chunks below measure it.
    pub planes: BTreeMap<usize, PlaneFit>,
}

/// Asks the split to gather R-LOD moments: the pass that splits a LOD node
/// ([`is_lod_depth`]) reads every triangle of its cell once anyway.
pub struct RlodMoments<'a> {
    pub treelet_height: u8,
    pub colour: TriangleColour<'a>,
    /// Each triangle's scene part id (`None` without part ids): the plane keeps the part of
    /// the largest clipped area, an R-LOD-only entry's part word.
    pub part: TrianglePart<'a>,
}

/// A triangle's linear RGB, as the in-core fit sees it.
pub type TriangleColour<'a> = &'a (dyn Fn(&InputTriangle) -> [f64; 3] + Sync);

/// A triangle's scene part id, as the in-core mesh numbers it.
pub type TrianglePart<'a> = &'a (dyn Fn(&InputTriangle) -> Option<u32> + Sync);

/// Records a split pass reads before placing them, while another thread adds them to the
/// R-LOD moments.
const SPLIT_BATCH: usize = 1 << 15;

/// Deepest median split: leaves the in-core builds room under the format's 128 levels.
pub const MAX_SPLIT_DEPTH: u32 = 48;

/// Where a split writes its spill runs and what it charges them to.
pub struct SpillTo<'a> {
    pub dir: &'a Path,
    pub disk: &'a Arc<SpillDisk>,
}

/// Where a split starts: the top node its cell fills, the cell, the cell's depth below the
/// scene root and the top nodes above it, root first.
#[derive(Clone, Debug, PartialEq)]
pub struct Start {
    pub node: usize,
    pub cell: Bounds,
    pub depth: u32,
    pub ancestors: Vec<usize>,
}

impl Start {
    /// The whole scene, `cell`, as node 0.
    pub fn root(cell: Bounds) -> Start {
        Start {
            node: 0,
            cell,
            depth: 0,
            ancestors: Vec::new(),
        }
    }
}

/// Splits the soup `run` over `cell` until every chunk holds at most `budget` triangles.
#[cfg(test)]
pub fn split(
    run: Run,
    cell: Bounds,
    budget: u64,
    to: &SpillTo,
    rlods: Option<&RlodMoments>,
    progress: &mut dyn Progress,
) -> Result<TopTree, OocError> {
    let start = Start::root(cell);
    split_from(run, TopTree::default(), start, budget, to, rlods, progress)
}

/// Splits `run`, the triangles of `start`'s cell, until every chunk holds at most `budget`
/// triangles, adding the nodes below `start.node` to `top` (which may already hold the nodes
/// above it). Chunks come out left to right; their runs replace the input's, which each pass
/// consumes as it reads it.
pub fn split_from(
    run: Run,
    mut top: TopTree,
    start: Start,
    budget: u64,
    to: &SpillTo,
    rlods: Option<&RlodMoments>,
    progress: &mut dyn Progress,
) -> Result<TopTree, OocError> {
    let mut done = 0u64;
    // Names each pass's runs: a top node id can come back after a pass that made no progress.
    let mut pass = 0usize;
    let count = run.count;
    progress.phase("split", Some(count));
    while top.nodes.len() <= start.node {
        top.nodes.push(TopNode::Chunk(usize::MAX));
    }
    let mut stack = vec![Pending {
        node: start.node,
        run,
        cell: start.cell,
        depth: start.depth,
        ancestors: start.ancestors,
    }];
    while let Some(mut p) = stack.pop() {
        let cut = Cut::middle(&p.cell);
        let n = p.run.count;
        let splittable = n > budget && p.depth < MAX_SPLIT_DEPTH && cut.inside();
        let mut moments = rlods
            .filter(|r| splittable && is_lod_depth(p.depth, r.treelet_height))
            .map(|r| (PlaneMoments::new(p.cell), r));
        let halves = if splittable {
            pass += 1;
            Some(split_run(&p, &cut, to, pass, moments.as_mut())?)
        } else {
            None
        };
        match halves {
            // Some triangles stayed on one side only: the split made progress.
            Some([l, r]) if l.count < n || r.count < n => {
                let plane = moments.map(|(m, _)| m.plane());
                top.divide(p, &cut, [l, r], plane, to.disk, &mut stack)?;
            }
            other => {
                if let Some([l, r]) = other {
                    // The pass consumed the input: every triangle went to both halves, which
                    // together give it back.
                    p.run = merge_halves(&l, &r, to, pass)?;
                }
                done += n;
                top.finish_chunk(p, budget);
                progress.advance(done.min(count));
            }
        }
    }
    progress.finish_phase();
    Ok(top)
}

/// A cell waiting to be split or kept: the top node to fill, its spill run, its bounds, its
/// depth and the top nodes above it.
struct Pending {
    node: usize,
    run: Run,
    cell: Bounds,
    depth: u32,
    ancestors: Vec<usize>,
}

/// A cell's median cut: the middle of its longest axis.
pub(crate) struct Cut {
    pub cell: Bounds,
    pub axis: usize,
    pub mid: f32,
}

impl Cut {
    pub fn middle(cell: &Bounds) -> Cut {
        let axis = cell.longest_axis();
        let (lo, hi) = (cell.min[axis], cell.max[axis]);
        Cut {
            cell: *cell,
            axis,
            mid: (lo + (hi - lo) * 0.5).clamp(lo, hi),
        }
    }

    /// The cut leaves room on both sides.
    pub fn inside(&self) -> bool {
        let (lo, hi) = (self.cell.min[self.axis], self.cell.max[self.axis]);
        lo < self.mid && self.mid < hi
    }
}

impl TopTree {
    /// Makes `p`'s node an inner node cut at `cut` over the non-empty `halves`, with the R-LOD
    /// `plane` fitted on the way, and stacks the halves, left on top. The input run was
    /// consumed by the pass; an empty half's run has no segments.
    fn divide(
        &mut self,
        p: Pending,
        cut: &Cut,
        halves: [Run; 2],
        plane: Option<PlaneFit>,
        disk: &SpillDisk,
        stack: &mut Vec<Pending>,
    ) -> Result<(), OocError> {
        let (lc, rc) = p.cell.split(cut.axis, cut.mid);
        let mut children = [None, None];
        let mut path_down = p.ancestors;
        path_down.push(p.node);
        // Pushed right first so the left subtree is numbered and finished first.
        let mut pending = Vec::new();
        for (slot, (run, cc)) in children.iter_mut().zip(halves.into_iter().zip([lc, rc])) {
            if run.count == 0 {
                run.remove(disk)?;
                continue;
            }
            let id = self.nodes.len();
            // Filled in when the child's own turn comes.
            self.nodes.push(TopNode::Chunk(usize::MAX));
            *slot = Some(id);
            pending.push((id, run, cc));
        }
        if let Some(plane) = plane {
            self.planes.insert(p.node, plane);
        }
        if let Some(n) = self.nodes.get_mut(p.node) {
            *n = TopNode::Inner {
                axis: cut.axis as u8,
                split: cut.mid,
                children,
            };
        }
        for (node, run, cell) in pending.into_iter().rev() {
            stack.push(Pending {
                node,
                run,
                cell,
                depth: p.depth + 1,
                ancestors: path_down.clone(),
            });
        }
        Ok(())
    }

    /// Keeps `p` as a chunk (an oversized one when it is over the `budget`).
    fn finish_chunk(&mut self, p: Pending, budget: u64) {
        if p.run.count > budget {
            self.oversized.push(self.chunks.len());
        }
        if let Some(slot) = self.nodes.get_mut(p.node) {
            *slot = TopNode::Chunk(self.chunks.len());
        }
        self.chunks.push(Chunk {
            count: p.run.count,
            run: p.run,
            cell: p.cell,
            depth: p.depth,
            ancestors: p.ancestors,
        });
    }
}

/// Records one task of a split pass places at a time.
const SIDES_RUN: usize = 1 << 12;

/// The sides of a cut a record's part inside the cell reaches, and the side of its centroid.
pub(crate) struct Sides {
    pub left: bool,
    pub right: bool,
    pub owner_left: bool,
}

impl Sides {
    pub fn of(t: &SoupTriangle, cut: &Cut) -> Sides {
        let (axis, mid) = (cut.axis, cut.mid);
        let part = clip_triangle(t.triangle.positions, &cut.cell);
        let (pmin, pmax) = (part.min[axis], part.max[axis]);
        let in_plane = pmin == mid && pmax == mid;
        Sides {
            left: pmin < mid || in_plane,
            right: pmax > mid || in_plane,
            owner_left: t.centroid()[axis] <= mid,
        }
    }

    /// `t`'s copy on the left side (or the right), or `None` when its part does not reach
    /// that side: primary when `t` is and the side holds its centroid, or it reaches only
    /// that side.
    pub fn copy(&self, t: &SoupTriangle, left: bool) -> Option<SoupTriangle> {
        let (reach, owner, other) = match left {
            true => (self.left, self.owner_left, self.right),
            false => (self.right, !self.owner_left, self.left),
        };
        reach.then_some(SoupTriangle {
            primary: t.primary && (owner || !other),
            ..*t
        })
    }
}

/// One streaming pass, consuming `p`'s run: every record to the side(s) of the `cut` its
/// clipped part reaches, and into `moments` when given. The sides' runs are named after pass
/// `id`.
fn split_run(
    p: &Pending,
    cut: &Cut,
    to: &SpillTo,
    id: usize,
    mut moments: Option<&mut (PlaneMoments, &RlodMoments)>,
) -> Result<[Run; 2], OocError> {
    let mut left = SoupWriter::create(&to.dir.join(format!("p{id}-l.soup")), to.disk.clone());
    let mut right = SoupWriter::create(&to.dir.join(format!("p{id}-r.soup")), to.disk.clone());
    let mut reader = SoupReader::open(&p.run, true, to.disk.clone());
    let mut batch = Vec::with_capacity(SPLIT_BATCH);
    loop {
        batch.clear();
        for record in reader.by_ref().take(SPLIT_BATCH) {
            batch.push(record?);
        }
        if batch.is_empty() {
            break;
        }
        // Where each record goes, decided in parallel: clipping is most of a pass's work.
        let sides = || -> Vec<Sides> {
            batch
                .par_chunks(SIDES_RUN)
                .flat_map_iter(|run| run.iter().map(|t| Sides::of(t, cut)))
                .collect()
        };
        // The moments take the batch in order on another thread meanwhile: the same sums,
        // bit for bit, as one thread gives.
        let sides = match moments.as_deref_mut() {
            Some((m, r)) => {
                let add = || {
                    for t in &batch {
                        m.add(t.triangle.positions, (r.part)(&t.triangle), || {
                            (r.colour)(&t.triangle)
                        });
                    }
                };
                rayon::join(add, sides).1
            }
            None => sides(),
        };
        for (t, s) in batch.iter().zip(&sides) {
            if let Some(c) = s.copy(t, true) {
                left.push(&c)?;
            }
            if let Some(c) = s.copy(t, false) {
                right.push(&c)?;
            }
        }
    }
    Ok([left.finish()?, right.finish()?])
}

/// The run a split that made no progress consumed, from its two halves: each holds every
/// record in the input's order, primary on the side of its centroid. Consumes both halves;
/// the result is named after pass `id`.
fn merge_halves(l: &Run, r: &Run, to: &SpillTo, id: usize) -> Result<Run, OocError> {
    let mut out = SoupWriter::create(&to.dir.join(format!("p{id}-m.soup")), to.disk.clone());
    let rights = SoupReader::open(r, true, to.disk.clone());
    for (a, b) in SoupReader::open(l, true, to.disk.clone()).zip(rights) {
        let (mut a, b) = (a?, b?);
        a.primary |= b.primary;
        out.push(&a)?;
    }
    out.finish()
}

#[cfg(test)]
mod tests {
    use super::super::soup::SoupTriangle;
    use super::*;
    use crate::progress::NoProgress;
    use oocfmt_meshio::import::InputTriangle;

    fn tri(x: f32, w: f32) -> SoupTriangle {
        SoupTriangle {
            triangle: InputTriangle::new([[x, 0.0, 0.0], [x + w, 0.0, 0.0], [x, 1.0, 0.0]]),
            primary: true,
        }
    }

    /// A run of `input` in `dir`, in segments of about three records.
    fn spill(dir: &Path, input: &[SoupTriangle]) -> Result<(Run, Arc<SpillDisk>), OocError> {
        let disk = Arc::new(SpillDisk::with_segments(3 * 37, None));
        let mut w = SoupWriter::create(&dir.join("all.soup"), disk.clone());
        for t in input {
            w.push(t)?;
        }
        Ok((w.finish()?, disk))
    }

    fn files_in(dir: &Path) -> Result<usize, OocError> {
        Ok(std::fs::read_dir(dir)
            .map_err(|e| OocError::spill(dir, e))?
            .count())
    }

    #[test]
    fn every_triangle_keeps_exactly_one_primary_copy() -> Result<(), OocError> {
        let dir = tempfile::tempdir().map_err(|e| OocError::spill(Path::new("."), e))?;
        // 64 small triangles along x, and 8 wide ones that straddle many cuts.
        let mut input = Vec::new();
        for k in 0..64 {
            input.push(tri(k as f32, 0.5));
        }
        for k in 0..8 {
            input.push(tri(k as f32 * 8.0 + 0.25, 20.0));
        }
        let (run, disk) = spill(dir.path(), &input)?;
        let cell = Bounds {
            min: [0.0; 3],
            max: [84.25, 1.0, 0.0],
        };
        let to = SpillTo {
            dir: dir.path(),
            disk: &disk,
        };
        let top = split(run, cell, 10, &to, None, &mut NoProgress)?;
        assert!(top.chunks.len() >= 8, "{} chunks", top.chunks.len());
        assert!(top.oversized.is_empty());
        let mut primaries = Vec::new();
        let mut copies = 0;
        let mut segments = 0;
        for c in &top.chunks {
            assert!(c.count <= 10);
            segments += c.run.segments.len();
            for r in SoupReader::open(&c.run, false, disk.clone()) {
                let r = r?;
                let b = Bounds::of_points(&r.triangle.positions);
                assert!(b.min[0] <= c.cell.max[0] && b.max[0] >= c.cell.min[0]);
                if r.primary {
                    primaries.push(r.triangle.positions[0][0].to_bits());
                } else {
                    copies += 1;
                }
            }
        }
        primaries.sort_unstable();
        let mut expected: Vec<u32> = input
            .iter()
            .map(|t| t.triangle.positions[0][0].to_bits())
            .collect();
        expected.sort_unstable();
        assert_eq!(primaries, expected);
        assert!(copies > 0);
        // Only the chunks' segments are left, and they are what the disk holds.
        assert_eq!(files_in(dir.path())?, segments);
        let left: u64 = top.chunks.iter().map(|c| c.run.bytes()).sum();
        assert_eq!(disk.spill_bytes(), left);
        // Each pass freed its input as it went: the disk never held much more than one copy
        // of the data (the copies, and a segment per run being written or read).
        let most = (input.len() + copies) as u64 * 37 + 3 * 3 * 37;
        assert!(disk.peak() <= most, "{} > {most}", disk.peak());
        Ok(())
    }

    #[test]
    fn a_cell_every_triangle_crosses_stays_one_oversized_chunk() -> Result<(), OocError> {
        let dir = tempfile::tempdir().map_err(|e| OocError::spill(Path::new("."), e))?;
        // Every triangle spans the cell; every other one has its centroid on the right.
        let mut input: Vec<SoupTriangle> = (0..20)
            .map(|k| match k % 2 {
                0 => tri(0.0, 10.0),
                _ => SoupTriangle {
                    triangle: InputTriangle::new([
                        [10.0, 0.0, 0.0],
                        [0.0, 0.0, 0.0],
                        [10.0, 1.0, 0.0],
                    ]),
                    primary: true,
                },
            })
            .collect();
        input[3].primary = false;
        let (run, disk) = spill(dir.path(), &input)?;
        let cell = Bounds {
            min: [0.0; 3],
            max: [10.0, 1.0, 0.0],
        };
        let to = SpillTo {
            dir: dir.path(),
            disk: &disk,
        };
        let top = split(run, cell, 4, &to, None, &mut NoProgress)?;
        assert_eq!(top.chunks.len(), 1);
        assert_eq!(top.oversized, vec![0]);
        assert_eq!(top.nodes, vec![TopNode::Chunk(0)]);
        // The pass consumed the input; the chunk's run, merged from the halves, is the input.
        let run = &top.chunks[0].run;
        let back: Vec<SoupTriangle> =
            SoupReader::open(run, true, disk.clone()).collect::<Result<_, _>>()?;
        assert_eq!(back, input);
        assert_eq!((files_in(dir.path())?, disk.spill_bytes()), (0, 0));
        Ok(())
    }
}
