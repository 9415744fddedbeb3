//! Rays against the in-memory [`KdTree`], for sampling what a subtree looks like from outside:
//! a front-to-back traversal of one subtree and a double-precision Möller–Trumbore test.
//!
//! Triangles straddle leaves, so a hit found in one leaf may lie beyond it; the traversal keeps
//! the nearest hit over every leaf it visits and stops once that hit is no farther than the end
//! of the current leaf's stretch of the ray, which no later leaf can undercut.

mod packet;

use crate::kdtree::{KdNode, KdTree, NodeId};
use oocfmt_meshio::mesh::{Bounds, Mesh};
pub use packet::PACKET_MAX;

/// A ray `origin + t · dir`, with the reciprocals of the direction's components (infinite for
/// zero ones) so that slab tests multiply instead of divide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Where the ray starts (`t = 0`), in mesh units.
    pub origin: [f64; 3],
    /// Its direction; need not be unit length (`t` is in multiples of it).
    pub dir: [f64; 3],
    inv: [f64; 3],
}

impl Ray {
    /// The ray from `origin` along `dir`.
    pub fn new(origin: [f64; 3], dir: [f64; 3]) -> Ray {
        Ray {
            origin,
            dir,
            inv: dir.map(|d| 1.0 / d),
        }
    }
}

/// Where a ray meets a triangle: its parameter, the mesh triangle, and the barycentric weights
/// of corners 1 and 2 (corner 0 has `1 − u − v`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// The ray parameter of the hit: the point is `origin + t · dir`.
    pub t: f64,
    /// The mesh triangle hit.
    pub triangle: u32,
    /// Barycentric weight of corner 1.
    pub u: f64,
    /// Barycentric weight of corner 2.
    pub v: f64,
}

/// Keeps `hit` in `best` when it lies in `t0 ..= t1` widened by `eps` and is strictly nearer:
/// of equally near hits the first one tested stays, which is why every walk over the same
/// triangles in the same order finds the same hit.
#[inline]
pub(crate) fn keep_nearer(best: &mut Option<Hit>, hit: Hit, t0: f64, t1: f64, eps: f64) {
    if hit.t >= t0 - eps && hit.t <= t1 + eps && best.is_none_or(|b| hit.t < b.t) {
        *best = Some(hit);
    }
}

/// The box of a triangle's corners, `(low, high)`.
#[inline]
pub(crate) fn corner_box(c: &[[f32; 3]; 3]) -> ([f32; 3], [f32; 3]) {
    (
        std::array::from_fn(|a| c[0][a].min(c[1][a]).min(c[2][a])),
        std::array::from_fn(|a| c[0][a].max(c[1][a]).max(c[2][a])),
    )
}

/// Möller–Trumbore in f64: `(t, u, v)` where the ray's line meets the triangle, edges
/// included, or `None` when it misses or runs parallel to its plane. `t` may be negative.
pub fn intersect_triangle(ray: &Ray, p: [[f64; 3]; 3]) -> Option<(f64, f64, f64)> {
    moller_trumbore(ray, p[0], sub(p[1], p[0]), sub(p[2], p[0]))
}

/// The test of [`intersect_triangle`] on a triangle given by a corner and the edges from it.
#[inline(always)]
fn moller_trumbore(ray: &Ray, v0: [f64; 3], e1: [f64; 3], e2: [f64; 3]) -> Option<(f64, f64, f64)> {
    let pv = cross(ray.dir, e2);
    let det = dot(e1, pv);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let tv = sub(ray.origin, v0);
    let u = dot(tv, pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = cross(tv, e1);
    let v = dot(ray.dir, qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some((dot(e2, qv) * inv, u, v))
}

/// A triangle with its edges and box precomputed, for testing many rays against few
/// triangles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prepared {
    /// The mesh triangle it was made from.
    pub triangle: u32,
    v0: [f64; 3],
    e1: [f64; 3],
    e2: [f64; 3],
    /// The triangle's box, padded by a rounding margin: a cheap first test.
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Prepared {
    /// Prepares mesh triangle `triangle` with corners `p`.
    pub fn new(triangle: u32, p: [[f64; 3]; 3]) -> Prepared {
        let lo: [f64; 3] = std::array::from_fn(|a| p[0][a].min(p[1][a]).min(p[2][a]));
        let hi: [f64; 3] = std::array::from_fn(|a| p[0][a].max(p[1][a]).max(p[2][a]));
        let pad = 1e-9 * (0..3).fold(0.0f64, |m, a| m.max(lo[a].abs()).max(hi[a].abs()));
        Prepared {
            triangle,
            v0: p[0],
            e1: sub(p[1], p[0]),
            e2: sub(p[2], p[0]),
            lo: lo.map(|c| c - pad),
            hi: hi.map(|c| c + pad),
        }
    }

    /// Whether the ray can meet the triangle's box with `t` in `t0 ..= t1`.
    fn box_reachable(&self, ray: &Ray, t0: f64, t1: f64) -> bool {
        let (mut near, mut far) = (t0, t1);
        for a in 0..3 {
            let (o, d) = (ray.origin[a], ray.dir[a]);
            if d == 0.0 {
                if o < self.lo[a] || o > self.hi[a] {
                    return false;
                }
                continue;
            }
            let inv = ray.inv[a];
            let (ta, tb) = ((self.lo[a] - o) * inv, (self.hi[a] - o) * inv);
            near = near.max(ta.min(tb));
            far = far.min(ta.max(tb));
        }
        near <= far
    }

    /// See [`intersect_triangle`].
    pub fn intersect(&self, ray: &Ray) -> Option<(f64, f64, f64)> {
        moller_trumbore(ray, self.v0, self.e1, self.e2)
    }
}

/// The nearest hit with `t` in `t0 ..= t1` (widened by `eps`) among `triangles`, testing each.
pub fn first_hit_of(triangles: &[Prepared], ray: &Ray, t0: f64, t1: f64, eps: f64) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    let flat = ray.dir.map(|d| d == 0.0);
    for p in triangles {
        // Face rays run parallel to two axes: their boxes' sides there settle most misses.
        if (flat[0] && (ray.origin[0] < p.lo[0] || ray.origin[0] > p.hi[0]))
            || (flat[1] && (ray.origin[1] < p.lo[1] || ray.origin[1] > p.hi[1]))
            || (flat[2] && (ray.origin[2] < p.lo[2] || ray.origin[2] > p.hi[2]))
        {
            continue;
        }
        let limit = best.map_or(t1, |b| b.t) + eps;
        if !p.box_reachable(ray, t0 - eps, limit) {
            continue;
        }
        if let Some((t, u, v)) = p.intersect(ray) {
            let triangle = p.triangle;
            keep_nearer(&mut best, Hit { t, triangle, u, v }, t0, t1, eps);
        }
    }
    best
}

/// The parameter interval in which the ray is inside `cell` (slab test), or `None` when it
/// misses the box.
pub fn clip_to_box(ray: &Ray, cell: &Bounds) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..3 {
        let (lo, hi) = (f64::from(cell.min[a]), f64::from(cell.max[a]));
        let (o, d) = (ray.origin[a], ray.dir[a]);
        if d == 0.0 {
            if o < lo || o > hi {
                return None;
            }
            continue;
        }
        let (ta, tb) = ((lo - o) * ray.inv[a], (hi - o) * ray.inv[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Per axis, the span a triangle's box must overlap for the ray to possibly hit it: around
/// the origin on axes the ray runs parallel to (face rays have two), everything elsewhere. It
/// is widened far beyond rounding in the ray test (by `eps` and a relative margin, then
/// outwards to f32), so checking it never loses a hit; it spares most misses the full test.
fn flat_reach(ray: &Ray, eps: f64) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::NEG_INFINITY; 3];
    let mut hi = [f32::INFINITY; 3];
    for a in 0..3 {
        if ray.dir[a] == 0.0 {
            let o = ray.origin[a];
            let pad = eps.abs() + 1e-7 * o.abs() + 1e-30;
            let (l, h) = ((o - pad) as f32, (o + pad) as f32);
            // Rounding to f32 may move each bound inwards by half a unit; step it outwards.
            lo[a] = l - l.abs() * 1e-6 - f32::MIN_POSITIVE;
            hi[a] = h + h.abs() * 1e-6 + f32::MIN_POSITIVE;
            if lo[a].is_nan() || hi[a].is_nan() || lo[a] > hi[a] {
                // NaN or overflow: keep everything.
                (lo[a], hi[a]) = (f32::NEG_INFINITY, f32::INFINITY);
            }
        }
    }
    (lo, hi)
}

/// The corners of every mesh triangle side by side, indexed by triangle: one memory access per
/// triangle test instead of an index lookup and three scattered positions.
pub fn triangle_corners(mesh: &Mesh) -> Vec<[[f32; 3]; 3]> {
    use rayon::prelude::*;
    (0..mesh.triangles.len())
        .into_par_iter()
        .map(|t| mesh.corners(t).unwrap_or([[f32::NAN; 3]; 3]))
        .collect()
}

/// Traces rays through subtrees of one tree; keeps its traversal stack between rays.
pub struct Tracer<'a> {
    mesh: &'a Mesh,
    tree: &'a KdTree,
    /// [`triangle_corners`] of the mesh, when the caller made them.
    corners: Option<&'a [[[f32; 3]; 3]]>,
    stack: Vec<(NodeId, f64, f64)>,
    /// The stack of [`Tracer::first_hits_along`]: node, ray interval, rays still wanting it.
    packet_stack: Vec<(NodeId, f64, f64, u64)>,
}

impl<'a> Tracer<'a> {
    /// A tracer over `tree`, whose leaves name triangles of `mesh`.
    pub fn new(mesh: &'a Mesh, tree: &'a KdTree) -> Tracer<'a> {
        Tracer {
            mesh,
            tree,
            corners: None,
            stack: Vec::with_capacity(64),
            packet_stack: Vec::with_capacity(64),
        }
    }

    /// A tracer reading triangles from `corners`, which must be [`triangle_corners`] of `mesh`
    /// (shared between tracers): the same hits as [`Tracer::new`], found faster.
    pub fn with_corners(
        mesh: &'a Mesh,
        tree: &'a KdTree,
        corners: &'a [[[f32; 3]; 3]],
    ) -> Tracer<'a> {
        Tracer {
            corners: Some(corners),
            ..Tracer::new(mesh, tree)
        }
    }

    /// Triangle `t`'s corners, from the copied table when the tracer has one.
    #[inline]
    pub fn corners(&self, t: u32) -> Option<[[f32; 3]; 3]> {
        match self.corners {
            Some(cs) => cs.get(t as usize).copied(),
            None => self.mesh.corners(t as usize),
        }
    }

    /// The nearest hit with `t` in `t0 ..= t1` (widened by `eps` for rays that start on a
    /// surface) among the triangles of the subtree under `root`, whose cell the segment must
    /// lie in.
    pub fn first_hit(
        &mut self,
        root: NodeId,
        ray: &Ray,
        t0: f64,
        t1: f64,
        eps: f64,
    ) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let (reach_lo, reach_hi) = flat_reach(ray, eps);
        self.stack.clear();
        self.stack.push((root, t0, t1));
        while let Some((mut id, tmin, mut tmax)) = self.stack.pop() {
            loop {
                match self.tree.node(id) {
                    Some(&KdNode::Inner {
                        axis,
                        split,
                        children: [l, r],
                    }) => {
                        let a = usize::from(axis).min(2);
                        let (o, d, s) = (ray.origin[a], ray.dir[a], f64::from(split));
                        let near = if d == 0.0 {
                            // Parallel to the plane: only the side holding the ray, both when
                            // the ray runs in the plane itself.
                            if o < s {
                                l
                            } else if o > s {
                                r
                            } else {
                                if let Some(f) = r {
                                    self.stack.push((f, tmin, tmax));
                                }
                                l
                            }
                        } else {
                            let ts = (s - o) * ray.inv[a];
                            let (near, far) = if d > 0.0 { (l, r) } else { (r, l) };
                            if ts > tmax {
                                near
                            } else if ts < tmin {
                                far
                            } else {
                                if let Some(f) = far {
                                    self.stack.push((f, ts, tmax));
                                }
                                tmax = ts;
                                near
                            }
                        };
                        match near {
                            Some(n) => id = n,
                            None => break,
                        }
                    }
                    Some(KdNode::Leaf { triangles }) => {
                        for &t in triangles {
                            let Some(c) = self.corners(t) else {
                                continue;
                            };
                            let (lo, hi) = corner_box(&c);
                            if !(0..3).all(|a| hi[a] >= reach_lo[a] && lo[a] <= reach_hi[a]) {
                                continue;
                            }
                            let p = c.map(|p| p.map(f64::from));
                            let Some((th, u, v)) =
                                moller_trumbore(ray, p[0], sub(p[1], p[0]), sub(p[2], p[0]))
                            else {
                                continue;
                            };
                            let hit = Hit {
                                t: th,
                                triangle: t,
                                u,
                                v,
                            };
                            keep_nearer(&mut best, hit, t0, t1, eps);
                        }
                        if best.is_some_and(|b| b.t <= tmax + eps) {
                            return best;
                        }
                        break;
                    }
                    None => break,
                }
            }
        }
        best
    }
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `v` scaled to unit length, or zero.
pub(crate) fn normalise(v: [f64; 3]) -> [f64; 3] {
    let len = dot(v, v).sqrt();
    if len > 0.0 && len.is_finite() {
        v.map(|c| c / len)
    } else {
        [0.0; 3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kdtree::{build, KdBuildOptions};

    fn ray(o: [f64; 3], d: [f64; 3]) -> Ray {
        Ray::new(o, d)
    }

    #[test]
    fn the_triangle_test_finds_inside_points_and_edges_and_misses_outside() {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let h = intersect_triangle(&ray([0.25, 0.25, 2.0], [0.0, 0.0, -1.0]), p);
        assert_eq!(h, Some((2.0, 0.25, 0.25)));
        assert!(intersect_triangle(&ray([0.5, 0.5, 1.0], [0.0, 0.0, -1.0]), p).is_some());
        assert!(intersect_triangle(&ray([0.6, 0.6, 1.0], [0.0, 0.0, -1.0]), p).is_none());
        assert!(intersect_triangle(&ray([0.2, 0.2, 1.0], [1.0, 0.0, 0.0]), p).is_none());
        let behind = intersect_triangle(&ray([0.2, 0.2, -1.0], [0.0, 0.0, -1.0]), p);
        assert_eq!(behind.map(|h| h.0), Some(-1.0));
    }

    #[test]
    fn the_slab_test_clips_to_the_box() {
        let cell = Bounds {
            min: [0.0; 3],
            max: [2.0, 1.0, 1.0],
        };
        assert_eq!(
            clip_to_box(&ray([-1.0, 0.5, 0.5], [1.0, 0.0, 0.0]), &cell),
            Some((1.0, 3.0))
        );
        assert_eq!(
            clip_to_box(&ray([-1.0, 2.5, 0.5], [1.0, 0.0, 0.0]), &cell),
            None
        );
    }

    /// A stack of `n` unit squares at z = 0, 1, ..., each facing +z.
    fn plates(n: u32) -> Mesh {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for k in 0..n {
            let z = k as f32;
            let b = positions.len() as u32;
            positions.extend([[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]]);
            triangles.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
        }
        Mesh::new(positions, triangles)
    }

    #[test]
    fn the_first_hit_is_the_nearest_plate_from_either_side() {
        let mesh = plates(9);
        let opts = KdBuildOptions {
            max_leaf_triangles: 2,
            ..KdBuildOptions::default()
        };
        let Ok(tree) = build(&mesh, &opts) else {
            panic!("build failed")
        };
        assert!(tree.nodes().len() > 5);
        let root = tree.root().unwrap_or(NodeId(0));
        let mut tracer = Tracer::new(&mesh, &tree);
        let up = ray([0.3, 0.6, -1.0], [0.0, 0.0, 1.0]);
        let hit = tracer.first_hit(root, &up, 0.0, 20.0, 1e-9);
        assert_eq!(hit.map(|h| (h.t, h.triangle / 2)), Some((1.0, 0)));
        let down = ray([0.3, 0.6, 8.0], [0.0, 0.0, -1.0]);
        let hit = tracer.first_hit(root, &down, 0.0, 20.0, 1e-9);
        assert_eq!(hit.map(|h| (h.t, h.triangle / 2)), Some((0.0, 8)));
        // Starting between plates 4 and 5 and limited to one unit: plate 5 only.
        let mid = ray([0.3, 0.6, 4.5], [0.0, 0.0, 1.0]);
        let hit = tracer.first_hit(root, &mid, 0.0, 1.0, 1e-9);
        assert_eq!(hit.map(|h| (h.t, h.triangle / 2)), Some((0.5, 5)));
        assert_eq!(tracer.first_hit(root, &mid, 0.0, 0.4, 1e-9), None);
        // A diagonal ray crossing many cells still meets the first plate in its path.
        let slant = ray([0.05, 0.05, 2.5], [0.3, 0.3, 1.0]);
        let hit = tracer.first_hit(root, &slant, 0.0, 3.0, 1e-9);
        assert_eq!(hit.map(|h| h.triangle / 2), Some(3));
        // Parallel to the plates, in between them: nothing.
        let flat = ray([-1.0, 0.5, 3.5], [1.0, 0.0, 0.0]);
        assert_eq!(tracer.first_hit(root, &flat, 0.0, 5.0, 1e-9), None);
    }
}
