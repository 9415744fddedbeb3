//! The visibility grid of a part filter: which cells of a coarse 3D grid meet the box of some
//! part the filter leaves visible, so that the traversal can skip a subtree whose stretch of
//! the ray meets none of them (a hidden region then costs one look-up, not a walk down to its
//! leaves).
//!
//! The grid spans the union of the visible parts' boxes (the part table's exact bounds, stored
//! coordinates), at most [`MAX_CELLS`] cells along its longest axis and proportionally fewer
//! along thinner ones. A coordinate maps to its cell by one monotone function,
//! `⌊min(max((x − lo) · scale, 0), n − 1)⌋` in f32 (NaN to 0), used alike to mark the parts'
//! boxes and to query a box: monotone, so two boxes that meet map to cell ranges that meet,
//! and no outward rounding is needed. The marks are kept as an inclusive 3D summed-area table,
//! so "does this box meet a marked cell" is eight look-ups.
//!
//! The promise rests on the part table's bounds being those of the parts' triangles, which
//! `verify --deep` checks (`PART_BOUNDS`); a file whose bounds lie can lose visible triangles
//! under a filter, never more (no panic, no unbounded work).

use crate::intersect::Ray;

/// The most cells along the grid's longest axis: 64³ cells take 1.1 MB of sums, which stay in
/// a core's L2 cache. On the 1M CAD scene with 84 % hidden, 160 cells cut the nodes per ray
/// only from 7.5 to 7.2 and made the frame slower (a bigger table, little more to skip).
pub const MAX_CELLS: u32 = 64;

/// The cells that meet some visible part's box, as a summed-area table ([`VisibilityGrid::new`]).
#[derive(Clone)]
pub struct VisibilityGrid {
    /// The grid's box: the union of the visible boxes.
    lo: [f32; 3],
    hi: [f32; 3],
    /// Cells per unit of length along each axis (0 along an axis of no extent).
    scale: [f32; 3],
    /// Cells along each axis.
    cells: [u32; 3],
    /// The last cell's index along each axis (cells − 1), as the float the cell is clamped to.
    last: [f32; 3],
    /// Entries per step along axes 0 and 1 of `sums` (axis 2 is contiguous).
    stride: [usize; 2],
    /// (n₀ + 1)(n₁ + 1)(n₂ + 1) inclusive prefix sums of the marks, with a zero first layer
    /// along each axis; empty when no box is visible.
    sums: Vec<u32>,
    /// Marked cells.
    marked: u32,
}

impl VisibilityGrid {
    /// The grid of no visible box: one cell, unmarked; every box meets nothing.
    pub const EMPTY: VisibilityGrid = VisibilityGrid {
        lo: [0.0; 3],
        hi: [0.0; 3],
        scale: [0.0; 3],
        cells: [1; 3],
        last: [0.0; 3],
        stride: [0; 2],
        sums: Vec::new(),
        marked: 0,
    };

    /// The grid of `boxes` (each `(min, max)`, stored coordinates), the boxes of the parts a
    /// filter shows. None when a box is not finite or not ordered: the caller then skips
    /// nothing, which is always sound.
    pub fn new(boxes: &[([f32; 3], [f32; 3])]) -> Option<VisibilityGrid> {
        let sound = |(lo, hi): &([f32; 3], [f32; 3])| {
            (0..3).all(|k| lo[k].is_finite() && hi[k].is_finite() && lo[k] <= hi[k])
        };
        if !boxes.iter().all(sound) {
            return None;
        }
        let Some(&(first_lo, first_hi)) = boxes.first() else {
            return Some(VisibilityGrid::EMPTY);
        };
        let (mut lo, mut hi) = (first_lo, first_hi);
        for (a, b) in boxes {
            for k in 0..3 {
                lo[k] = lo[k].min(a[k]);
                hi[k] = hi[k].max(b[k]);
            }
        }
        // In f64: the extent of a box spanning most of f32's range overflows f32.
        let ext = [0, 1, 2].map(|k| f64::from(hi[k]) - f64::from(lo[k]));
        let longest = ext.iter().fold(0f64, |a, &e| a.max(e));
        let cells = ext.map(|e| {
            if longest > 0.0 && e > 0.0 {
                ((f64::from(MAX_CELLS) * e / longest).ceil() as u32).clamp(1, MAX_CELLS)
            } else {
                1
            }
        });
        let scale = [0, 1, 2].map(|k| {
            let e = ext[k];
            if e > 0.0 {
                (f64::from(cells[k]) / e).min(f64::from(f32::MAX)) as f32
            } else {
                0.0
            }
        });
        let dims = cells.map(|n| n as usize + 1);
        let stride = [dims[1] * dims[2], dims[2]];
        let mut grid = VisibilityGrid {
            lo,
            hi,
            scale,
            cells,
            last: cells.map(|n| (n - 1) as f32),
            stride,
            sums: Vec::new(),
            marked: 0,
        };
        // How many boxes cover each cell: +1 and −1 at the corners of each box's cell range
        // (a difference table), summed up along the three axes.
        let len = dims[0] * dims[1] * dims[2];
        let mut cover = vec![0i32; len];
        for (a, b) in boxes {
            let from = [0, 1, 2].map(|k| grid.cell(k, a[k]));
            let to = [0, 1, 2].map(|k| grid.cell(k, b[k]) + 1);
            for corner in 0..8 {
                let pick = |k: usize| if corner >> k & 1 == 0 { from[k] } else { to[k] };
                let sign = if (corner as u32).count_ones() % 2 == 0 {
                    1
                } else {
                    -1
                };
                if let Some(c) = cover.get_mut(grid.index(pick(0), pick(1), pick(2))) {
                    *c += sign;
                }
            }
        }
        prefix_sums(&mut cover, dims);
        // The marks shifted one cell up along each axis (the zero layers first), then summed.
        let mut sums = vec![0u32; len];
        for i in 0..dims[0] - 1 {
            for j in 0..dims[1] - 1 {
                for k in 0..dims[2] - 1 {
                    let covered = cover.get(grid.index(i, j, k)).is_some_and(|&c| c > 0);
                    if let (true, Some(s)) =
                        (covered, sums.get_mut(grid.index(i + 1, j + 1, k + 1)))
                    {
                        *s = 1;
                        grid.marked += 1;
                    }
                }
            }
        }
        prefix_sums(&mut sums, dims);
        grid.sums = sums;
        Some(grid)
    }

    /// Cells along each axis.
    pub fn cells(&self) -> [u32; 3] {
        self.cells
    }

    /// Cells marked: those meeting some visible box.
    pub fn marked(&self) -> u32 {
        self.marked
    }

    /// Whether the box `lo`..=`hi` meets a marked cell: always when it meets a visible box
    /// (the grid's promise), never when on some axis it lies more than a cell away from each of
    /// them. A box with a NaN bound, or inside out, meets one if any cell is marked.
    #[inline(always)]
    pub fn meets(&self, lo: [f32; 3], hi: [f32; 3]) -> bool {
        self.cover(lo, hi) != Cover::None
    }

    /// How the marked cells cover the cells the box `lo`..=`hi` meets: none of them, some, or
    /// all of a box inside the grid's (then every box inside it meets a marked cell too:
    /// [`Cover::Full`] promises that [`VisibilityGrid::meets`] holds for each). A NaN bound
    /// gives [`Cover::Some`] when any cell is marked.
    #[inline(always)]
    pub fn cover(&self, lo: [f32; 3], hi: [f32; 3]) -> Cover {
        let mut from = [0usize; 3];
        let mut to = [0usize; 3];
        let mut inside = true;
        for k in 0..3 {
            let (a, b) = (lo[k], hi[k]);
            if a > b || a.is_nan() || b.is_nan() {
                // Inside out or NaN: a segment's box is neither, unless its ray is NaN.
                return if self.marked > 0 {
                    Cover::Some
                } else {
                    Cover::None
                };
            }
            if b < self.lo[k] || a > self.hi[k] {
                return Cover::None;
            }
            // A box reaching past the grid is clamped to its edge cells, which a box inside it
            // but past the grid's box does not meet: only one inside may be called full.
            inside &= a >= self.lo[k] && b <= self.hi[k];
            from[k] = self.cell(k, a);
            to[k] = self.cell(k, b) + 1;
        }
        let n = self.count(from, to);
        if n == 0 {
            Cover::None
        } else if inside && n as usize == (to[0] - from[0]) * (to[1] - from[1]) * (to[2] - from[2])
        {
            Cover::Full
        } else {
            Cover::Some
        }
    }

    /// Whether the stretch of `ray` over t ∈ [`t0`, `t1`], widened by `pad` along each axis
    /// (the ray's positional tolerance), meets a marked cell ([`VisibilityGrid::meets`] of
    /// [`segment_box`]).
    #[inline(always)]
    pub fn meets_segment(&self, ray: &Ray, t0: f32, t1: f32, pad: f32) -> bool {
        let (lo, hi) = segment_box(ray, t0, t1, pad);
        self.meets(lo, hi)
    }

    /// [`VisibilityGrid::cover`] of the stretch's box, as [`VisibilityGrid::meets_segment`].
    #[inline(always)]
    pub fn cover_segment(&self, ray: &Ray, t0: f32, t1: f32, pad: f32) -> Cover {
        let (lo, hi) = segment_box(ray, t0, t1, pad);
        self.cover(lo, hi)
    }

    /// The cell coordinate `x` falls in along axis `k`: monotone in `x`, below the grid 0, past
    /// it the last cell, NaN 0.
    #[inline(always)]
    fn cell(&self, k: usize, x: f32) -> usize {
        let (lo, scale, last) = (self.lo[k], self.scale[k], self.last[k]);
        // max and min take the number over a NaN; the cast then sees 0 ..= last only.
        ((x - lo) * scale).max(0.0).min(last) as usize
    }

    /// The entry of `sums` (or of a table of the same shape) at (i, j, k).
    #[inline(always)]
    fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i * self.stride[0] + j * self.stride[1] + k
    }

    /// Marked cells in the cells `from` .. `to` (exclusive): eight look-ups of the sums
    /// (wrapping: the terms' alternating sum is the count, the partial sums may pass 0).
    #[inline(always)]
    fn count(&self, from: [usize; 3], to: [usize; 3]) -> u32 {
        let at = |i: usize| self.sums.get(i).copied().unwrap_or(0);
        let (i0, i1) = (from[0] * self.stride[0], to[0] * self.stride[0]);
        let (j0, j1) = (from[1] * self.stride[1], to[1] * self.stride[1]);
        let (k0, k1) = (from[2], to[2]);
        at(i1 + j1 + k1)
            .wrapping_sub(at(i0 + j1 + k1))
            .wrapping_sub(at(i1 + j0 + k1))
            .wrapping_sub(at(i1 + j1 + k0))
            .wrapping_add(at(i0 + j0 + k1))
            .wrapping_add(at(i0 + j1 + k0))
            .wrapping_add(at(i1 + j0 + k0))
            .wrapping_sub(at(i0 + j0 + k0))
    }
}

/// What [`VisibilityGrid::cover`] finds of a box's cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cover {
    /// None is marked: the box meets no visible part's box.
    None,
    /// Some are.
    Some,
    /// Every one is.
    Full,
}

/// The box of the stretch of `ray` over t ∈ [`t0`, `t1`], widened by `pad` along each axis.
/// An axis the ray does not move along contributes its origin alone, so an infinite `t1`
/// forms no 0 × ∞; a stretch that is a point is a box of width `2 pad`; a NaN stays NaN.
#[inline(always)]
pub fn segment_box(ray: &Ray, t0: f32, t1: f32, pad: f32) -> ([f32; 3], [f32; 3]) {
    let mut lo = [0f32; 3];
    let mut hi = [0f32; 3];
    for k in 0..3 {
        let (o, d) = (ray.org[k], ray.dir[k]);
        let (a, b) = if d == 0.0 {
            (o, o)
        } else {
            (o + t0 * d, o + t1 * d)
        };
        // Comparisons, not min/max: a NaN stays and makes the box meet.
        let (a, b) = if b < a { (b, a) } else { (a, b) };
        lo[k] = a - pad;
        hi[k] = b + pad;
    }
    (lo, hi)
}

/// Turns `table`, of `dims` entries along the three axes (the last contiguous), into its
/// inclusive prefix sums along each axis in turn.
fn prefix_sums<T: Copy + std::ops::AddAssign>(table: &mut [T], dims: [usize; 3]) {
    let strides = [dims[1] * dims[2], dims[2], 1];
    for (stride, dim) in strides.into_iter().zip(dims) {
        for block in table.chunks_exact_mut(stride * dim) {
            for j in 1..dim {
                let Some((before, from)) = block.split_at_mut_checked(j * stride) else {
                    continue;
                };
                let prev = before.get((j - 1) * stride..).unwrap_or(&[]);
                for (c, &p) in from.iter_mut().zip(prev) {
                    *c += p;
                }
            }
        }
    }
}

impl PartialEq for VisibilityGrid {
    fn eq(&self, other: &Self) -> bool {
        let bits = |v: &[f32; 3]| v.map(f32::to_bits);
        bits(&self.lo) == bits(&other.lo)
            && bits(&self.hi) == bits(&other.hi)
            && bits(&self.scale) == bits(&other.scale)
            && self.cells == other.cells
            && self.sums == other.sums
    }
}

// Floats compared by their bits: equality is reflexive.
impl Eq for VisibilityGrid {}

impl std::fmt::Debug for VisibilityGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VisibilityGrid")
            .field("lo", &self.lo)
            .field("hi", &self.hi)
            .field("cells", &self.cells())
            .field("marked", &self.marked)
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    type Aabb = ([f32; 3], [f32; 3]);

    fn overlaps(a: &Aabb, b: &Aabb) -> bool {
        (0..3).all(|k| a.0[k] <= b.1[k] && b.0[k] <= a.1[k])
    }

    /// On some axis, `q` is more than `gap[k]` away from `b`.
    fn apart(q: &Aabb, b: &Aabb, gap: [f32; 3]) -> bool {
        (0..3).any(|k| q.0[k] > b.1[k] + gap[k] || b.0[k] > q.1[k] + gap[k])
    }

    fn aabb() -> impl Strategy<Value = Aabb> {
        // Corners on a 0.01 lattice in [-10, 10]³; a third of the sizes are 0 (flat parts).
        let axis = (-1000i32..1000, prop_oneof![Just(0i32), 0i32..600]);
        [axis.clone(), axis.clone(), axis].prop_map(|a| {
            let lo = a.map(|(l, _)| l as f32 / 100.0);
            let hi = a.map(|(l, s)| (l + s) as f32 / 100.0);
            (lo, hi)
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// Against brute force over the boxes: never "none" where a visible box overlaps, and
        /// "none" where every visible box lies more than a cell away on some axis.
        #[test]
        fn the_grid_query_is_conservative_and_close(
            visible in prop::collection::vec(aabb(), 0..12),
            queries in prop::collection::vec(aabb(), 40),
        ) {
            let Some(g) = VisibilityGrid::new(&visible) else {
                return Err(TestCaseError::fail("finite boxes make a grid"));
            };
            let cell = [0, 1, 2].map(|k| {
                let ext = g.hi[k] - g.lo[k];
                if ext > 0.0 { 1.01 * ext / g.cells[k] as f32 } else { 0.0 }
            });
            for q in queries.iter().chain(&visible) {
                let exact = visible.iter().any(|b| overlaps(q, b));
                let met = g.meets(q.0, q.1);
                prop_assert!(!exact || met, "{q:?} overlaps a visible box: {g:?}");
                if visible.iter().all(|b| apart(q, b, cell)) {
                    prop_assert!(!met, "{q:?} is over a cell from every visible box: {g:?}");
                }
                // Full: every box inside meets (the packets' shortcut).
                if g.cover(q.0, q.1) == Cover::Full {
                    let mid = [0, 1, 2].map(|k| q.0[k] + (q.1[k] - q.0[k]) * 0.37);
                    prop_assert!(g.meets(mid, mid) && g.meets(q.0, mid) && g.meets(mid, q.1));
                }
                // Inside one visible box: each of its cells is marked.
                let inside = |b: &Aabb| (0..3).all(|k| b.0[k] <= q.0[k] && q.1[k] <= b.1[k]);
                if visible.iter().any(inside) {
                    prop_assert_eq!(g.cover(q.0, q.1), Cover::Full, "{:?} in a visible box", q);
                }
            }
        }
    }

    #[test]
    fn no_visible_box_meets_nothing_and_a_bad_box_gives_no_grid() -> Result<(), String> {
        let g = VisibilityGrid::new(&[]).ok_or("a grid")?;
        assert!(!g.meets([-1e30; 3], [1e30; 3]));
        assert!(!g.meets([f32::NAN; 3], [f32::NAN; 3]));
        assert_eq!(g.marked(), 0);
        assert!(VisibilityGrid::new(&[([0.0; 3], [f32::INFINITY, 1.0, 1.0])]).is_none());
        assert!(VisibilityGrid::new(&[([1.0; 3], [0.0; 3])]).is_none());
        Ok(())
    }

    #[test]
    fn thin_axes_get_fewer_cells_and_a_point_is_one_cell() -> Result<(), String> {
        let g = VisibilityGrid::new(&[([0.0; 3], [8.0, 1.0, 0.0])]).ok_or("a grid")?;
        assert_eq!(g.cells(), [64, 8, 1]);
        assert_eq!(g.marked(), 64 * 8);
        let p = VisibilityGrid::new(&[([2.0; 3], [2.0; 3])]).ok_or("a grid")?;
        assert_eq!(p.cells(), [1, 1, 1]);
        assert!(p.meets([2.0; 3], [2.0; 3]));
        assert!(!p.meets([2.5; 3], [3.0; 3]));
        Ok(())
    }

    #[test]
    fn a_segment_box_handles_axis_parallel_rays_infinite_ends_and_points() -> Result<(), String> {
        // Two unit boxes at x 0..1 and x 9..10, y and z 0..1.
        let g = VisibilityGrid::new(&[([0.0; 3], [1.0; 3]), ([9.0, 0.0, 0.0], [10.0, 1.0, 1.0])])
            .ok_or("a grid")?;
        // Along +x at y = z = 0.5: the stretch from 3 to 7 meets neither, 0..∞ both.
        let r = Ray::new([0.0, 0.5, 0.5], [1.0, 0.0, 0.0]);
        assert!(!g.meets_segment(&r, 3.0, 7.0, 1e-5));
        assert!(g.meets_segment(&r, 0.0, f32::INFINITY, 1e-5));
        assert!(g.meets_segment(&r, 9.5, 9.5, 0.0), "a point inside a box");
        assert!(!g.meets_segment(&r, 5.0, 5.0, 0.0), "a point between them");
        // Parallel to x above the boxes: y = 3 for every t, even an infinite one.
        let above = Ray::new([0.0, 3.0, 0.5], [1.0, 0.0, 0.0]);
        assert!(!g.meets_segment(&above, 0.0, f32::INFINITY, 1e-5));
        // A NaN stretch is taken as meeting.
        assert!(g.meets_segment(&r, f32::NAN, 1.0, 0.0));
        Ok(())
    }
}
