//! The rays of one cell face traced together. They all run along one axis, in one direction,
//! from one plane across it, so every node's stretch of the ray is the same for all of them:
//! a split across the axis sends them all the same way, and a split along it only sorts them
//! by their origins. One walk of the subtree then serves every ray, each node visited once for
//! the rays that reach it instead of once per ray, and each ray still meets the same
//! triangles in the same order as [`Tracer::first_hit`] alone, so it finds the same hit.

use super::{corner_box, flat_reach, keep_nearer, moller_trumbore, sub, Hit, Ray, Tracer};
use crate::kdtree::{KdNode, NodeId};

/// The most rays one call takes: one bit each in a mask.
pub const PACKET_MAX: usize = 64;

impl Tracer<'_> {
    /// Writes to `hits[k]` what [`Tracer::first_hit`]`(root, rays[k], 0, t1, eps)` returns.
    /// Rays that do not all run along one axis in one direction from one plane across it, or
    /// more than [`PACKET_MAX`] of them, are traced one by one.
    pub fn first_hits_along(
        &mut self,
        root: NodeId,
        rays: &[Ray],
        t1: f64,
        eps: f64,
        hits: &mut [Option<Hit>],
    ) {
        let Some(axis) = shared_axis(rays).filter(|_| rays.len() <= PACKET_MAX) else {
            for (hit, ray) in hits.iter_mut().zip(rays) {
                *hit = self.first_hit(root, ray, 0.0, t1, eps);
            }
            return;
        };
        let n = rays.len().min(hits.len());
        hits.iter_mut().for_each(|h| *h = None);
        let mut reach = [([0.0f32; 3], [0.0f32; 3]); PACKET_MAX];
        for (r, ray) in reach.iter_mut().zip(rays) {
            *r = flat_reach(ray, eps);
        }
        let Some(first) = rays.first() else { return };
        let face = FaceRays {
            rays,
            reach,
            axis,
            origin: first.origin[axis],
            inv: first.inv[axis],
            forward: first.dir[axis] > 0.0,
            t1,
            eps,
        };
        let mut done = 0u64;
        let all = if n == PACKET_MAX {
            u64::MAX
        } else {
            (1u64 << n) - 1
        };
        self.packet_stack.clear();
        self.packet_stack.push((root, 0.0, t1, all));
        while let Some((mut id, tmin, tmax, mask)) = self.packet_stack.pop() {
            let mut span = Span {
                tmin,
                tmax,
                mask: mask & !done,
            };
            while span.mask != 0 {
                match self.tree.node(id) {
                    Some(&KdNode::Inner {
                        axis: split_axis,
                        split,
                        children,
                    }) => {
                        let a = usize::from(split_axis).min(2);
                        let s = f64::from(split);
                        let next = if a == face.axis {
                            self.split_across(&face, s, children, &mut span)
                        } else {
                            self.split_along(&face, (a, s), children, &mut span)
                        };
                        match next {
                            Some(c) => id = c,
                            None => break,
                        }
                    }
                    Some(KdNode::Leaf { triangles }) => {
                        for &t in triangles {
                            self.test_triangle(&face, t, span.mask, hits);
                        }
                        for k in bits(span.mask) {
                            if hits
                                .get(k)
                                .is_some_and(|h| h.is_some_and(|b| b.t <= span.tmax + eps))
                            {
                                done |= 1 << k;
                            }
                        }
                        break;
                    }
                    None => break,
                }
            }
        }
    }

    /// At a split across the rays' axis at `s`, crossed by every ray at the same distance:
    /// the child to visit now, the far one stacked when the span reaches it (the span then
    /// ends at the crossing).
    #[inline]
    fn split_across(
        &mut self,
        face: &FaceRays,
        s: f64,
        [l, r]: [Option<NodeId>; 2],
        span: &mut Span,
    ) -> Option<NodeId> {
        let ts = (s - face.origin) * face.inv;
        let (near, far) = if face.forward { (l, r) } else { (r, l) };
        if ts > span.tmax {
            near
        } else if ts < span.tmin {
            far
        } else {
            if let Some(f) = far {
                self.packet_stack.push((f, ts, span.tmax, span.mask));
            }
            span.tmax = ts;
            near
        }
    }

    /// At a split of axis `a` at `s`, parallel to the rays: each ray takes the side holding
    /// it, both (the low one first) when it runs in the plane. Returns the child to visit now,
    /// the span's rays cut to those going there; the high side is stacked for its rays when
    /// both are visited.
    #[inline]
    fn split_along(
        &mut self,
        face: &FaceRays,
        (a, s): (usize, f64),
        [l, r]: [Option<NodeId>; 2],
        span: &mut Span,
    ) -> Option<NodeId> {
        let (mut low, mut high) = (0u64, 0u64);
        for k in bits(span.mask) {
            let ok = face.rays.get(k).map_or(s, |r| r.origin[a]);
            low |= u64::from(ok <= s) << k;
            high |= u64::from(ok >= s) << k;
        }
        let (l, r) = (l.filter(|_| low != 0), r.filter(|_| high != 0));
        match (l, r) {
            (Some(l), Some(r)) => {
                self.packet_stack.push((r, span.tmin, span.tmax, high));
                span.mask = low;
                Some(l)
            }
            (Some(l), None) => {
                span.mask = low;
                Some(l)
            }
            (None, Some(r)) => {
                span.mask = high;
                Some(r)
            }
            (None, None) => None,
        }
    }

    /// Tests triangle `t` of a leaf against the rays of `mask` whose reach meets its box,
    /// keeping each ray's nearest hit in `hits`.
    #[inline]
    fn test_triangle(&self, face: &FaceRays, t: u32, mask: u64, hits: &mut [Option<Hit>]) {
        let Some(c) = self.corners(t) else {
            return;
        };
        let (lo, hi) = corner_box(&c);
        // Most triangles of a leaf lie beside every ray: find the rays whose reach meets the
        // triangle's box before any f64 work.
        let mut near = 0u64;
        for k in bits(mask) {
            if let Some((rlo, rhi)) = face.reach.get(k) {
                let meets = (0..3).all(|a| hi[a] >= rlo[a] && lo[a] <= rhi[a]);
                near |= u64::from(meets) << k;
            }
        }
        if near == 0 {
            return;
        }
        let p = c.map(|p| p.map(f64::from));
        let (e1, e2) = (sub(p[1], p[0]), sub(p[2], p[0]));
        for k in bits(near) {
            let (Some(ray), Some(best)) = (face.rays.get(k), hits.get_mut(k)) else {
                continue;
            };
            let Some((th, u, v)) = moller_trumbore(ray, p[0], e1, e2) else {
                continue;
            };
            let hit = Hit {
                t: th,
                triangle: t,
                u,
                v,
            };
            keep_nearer(best, hit, 0.0, face.t1, face.eps);
        }
    }
}

/// One face's rays, as the packet walk reads them: each ray's reach (the box its segment
/// sweeps, widened by the tolerance), the axis they run along with the first ray's origin and
/// reciprocal direction on it, whether they run forward, and the interval [0, `t1`] of every
/// ray with its tolerance `eps`.
struct FaceRays<'r> {
    rays: &'r [Ray],
    reach: [([f32; 3], [f32; 3]); PACKET_MAX],
    axis: usize,
    origin: f64,
    inv: f64,
    forward: bool,
    t1: f64,
    eps: f64,
}

/// A node's stretch of the rays, [`tmin`, `tmax`], and the rays (bit k: ray k) visiting it.
struct Span {
    tmin: f64,
    tmax: f64,
    mask: u64,
}

/// The axis all `rays` run along, in one direction, from one plane across it; `None` when
/// they do not (or there are none).
fn shared_axis(rays: &[Ray]) -> Option<usize> {
    let first = rays.first()?;
    let axis = (0..3).find(|&a| first.dir[a] != 0.0)?;
    let along = |r: &Ray| {
        (0..3).all(|a| (a == axis) == (r.dir[a] != 0.0))
            && r.dir[axis].is_sign_positive() == first.dir[axis].is_sign_positive()
            && r.dir[axis] == first.dir[axis]
            && r.origin[axis] == first.origin[axis]
    };
    (first.dir[axis].is_finite() && rays.iter().all(along)).then_some(axis)
}

/// The indices of the set bits of `mask`, lowest first.
fn bits(mut mask: u64) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let k = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            k
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kdtree::{build, KdBuildOptions};
    use oocfmt_meshio::mesh::Mesh;
    use oocfmt_scenes::demo::demo_scene;
    use oocfmt_scenes::rng::Rng;

    /// The demo scene plus a jittered grid of coplanar, overlapping squares: shared edges,
    /// triangles in split planes, ties between equally near hits.
    fn scene() -> Mesh {
        let mut mesh = demo_scene(3000);
        let mut rng = Rng(7);
        for i in 0..12u32 {
            for j in 0..12u32 {
                let b = mesh.positions.len() as u32;
                let (x, y) = (i as f32 * 0.1 - 0.6, j as f32 * 0.1 - 0.6);
                let z = if rng.chance(0.5) {
                    0.0
                } else {
                    rng.range(-1e-6, 1e-6) as f32
                };
                mesh.positions.extend([
                    [x, y, z],
                    [x + 0.15, y, z],
                    [x + 0.15, y + 0.15, z],
                    [x, y + 0.15, z],
                ]);
                mesh.triangles
                    .extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
            }
        }
        Mesh::new(mesh.positions, mesh.triangles)
    }

    #[test]
    fn a_face_packet_finds_what_each_ray_finds_alone() {
        let mesh = scene();
        let tree = match build(
            &mesh,
            &KdBuildOptions {
                max_leaf_triangles: 3,
                ..KdBuildOptions::default()
            },
        ) {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        };
        // Lateral coordinates that lie exactly on split planes and on vertices.
        let mut special: [Vec<f64>; 3] = Default::default();
        for n in tree.nodes() {
            if let KdNode::Inner { axis, split, .. } = n {
                special[usize::from(*axis).min(2)].push(f64::from(*split));
            }
        }
        for p in mesh.positions.iter().step_by(7) {
            for a in 0..3 {
                special[a].push(f64::from(p[a]));
            }
        }
        let mut rng = Rng(11);
        let mut single = Tracer::new(&mesh, &tree);
        let mut packed = Tracer::new(&mesh, &tree);
        let (mut rays_traced, mut hits_found) = (0, 0);
        let all: Vec<NodeId> = (0..tree.nodes().len() as u32).map(NodeId).collect();
        for (id, cell) in crate::lod::cells_of(&tree, &all).into_iter().step_by(5) {
            let lo = cell.min.map(f64::from);
            let hi = cell.max.map(f64::from);
            for f in 0..6 {
                let a = f / 2;
                let mut dir = [0.0; 3];
                dir[a] = if f % 2 == 0 { 1.0 } else { -1.0 };
                let n = [1, 16, 48, 64][rng.int(0, 3) as usize];
                let rays: Vec<Ray> = (0..n)
                    .map(|_| {
                        let mut o = [0.0; 3];
                        o[a] = if f % 2 == 0 { lo[a] } else { hi[a] };
                        for b in (0..3).filter(|&b| b != a) {
                            let pick = &special[b];
                            o[b] = if rng.chance(0.4) && !pick.is_empty() {
                                pick[rng.int(0, pick.len() as u32 - 1) as usize].clamp(lo[b], hi[b])
                            } else {
                                rng.range(lo[b], hi[b])
                            };
                        }
                        Ray::new(o, dir)
                    })
                    .collect();
                let t1 = hi[a] - lo[a];
                let eps = 1e-9 * (t1 + 1.0);
                let mut hits = vec![None; n];
                packed.first_hits_along(id, &rays, t1, eps, &mut hits);
                for (ray, hit) in rays.iter().zip(&hits) {
                    assert_eq!(*hit, single.first_hit(id, ray, 0.0, t1, eps), "{ray:?}");
                    rays_traced += 1;
                    hits_found += usize::from(hit.is_some());
                }
            }
        }
        assert!(rays_traced > 20_000 && hits_found > rays_traced / 10);
    }

    #[test]
    fn rays_that_do_not_share_an_axis_are_traced_one_by_one() {
        let mesh = scene();
        let tree = match build(&mesh, &KdBuildOptions::default()) {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        };
        let root = tree.root().unwrap_or(NodeId(0));
        let mut single = Tracer::new(&mesh, &tree);
        let mut packed = Tracer::new(&mesh, &tree);
        let mixed = [
            Ray::new([0.01, 0.02, -5.0], [0.0, 0.0, 1.0]),
            Ray::new([0.03, 0.01, 5.0], [0.0, 0.0, -1.0]),
            Ray::new([-5.0, 0.02, 0.0], [1.0, 0.0, 0.0]),
            Ray::new([0.02, 0.03, -4.0], [0.0, 0.0, 1.0]),
            Ray::new([0.1, 0.1, -5.0], [0.1, 0.0, 1.0]),
        ];
        assert_eq!(shared_axis(&mixed), None);
        assert_eq!(shared_axis(&mixed[..1]), Some(2));
        let mut hits = [None; 5];
        packed.first_hits_along(root, &mixed, 20.0, 1e-9, &mut hits);
        for (ray, hit) in mixed.iter().zip(&hits) {
            assert_eq!(*hit, single.first_hit(root, ray, 0.0, 20.0, 1e-9));
        }
        assert!(hits.iter().filter(|h| h.is_some()).count() >= 3);
    }
}
