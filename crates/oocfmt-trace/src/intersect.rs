//! Ray/triangle and ray/box kernels.
//!
//! The triangle test is the watertight one of Woop, Benthin and Wald (JCGT 2013): the ray is
//! turned into the +z axis of a sheared space, where the three edge functions of a triangle are
//! 2D cross products of the same transformed vertices for every triangle sharing an edge. An
//! edge function that rounds to exactly zero is recomputed in f64, so a ray through a shared
//! edge or vertex is counted by at least one of the triangles around it: no cracks.

/// A ray with its watertight precomputation (shear constants and axis permutation).
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// The origin, in the container's stored coordinates.
    pub org: [f32; 3],
    /// The direction as given (not normalised here); hit distances are in multiples of it.
    pub dir: [f32; 3],
    /// 1 / dir per axis; ±inf for a ±0 component.
    pub inv: [f32; 3],
    pub(crate) kx: usize,
    pub(crate) kz: usize,
    pub(crate) sx: f32,
    pub(crate) sy: f32,
    pub(crate) sz: f32,
}

/// A triangle hit: distance along the ray direction and barycentric weights of the three
/// vertices (a, b, c), summing to one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    /// The hit's distance in multiples of the ray's direction (the length along a unit one).
    pub t: f32,
    /// The weights of vertices a, b and c at the hit point.
    pub bary: [f32; 3],
}

impl Ray {
    /// A ray; `dir` need not be normalised but must have a non-zero finite component.
    #[inline]
    pub fn new(org: [f32; 3], dir: [f32; 3]) -> Ray {
        let kz = major_axis(dir);
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keeps the winding of the sheared triangle, so the sign of the edge functions means
        // the same for every ray.
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let inv = dir.map(|d| 1.0 / d);
        Ray {
            org,
            dir,
            inv,
            kx,
            kz,
            sx: dir[kx] / dir[kz],
            sy: dir[ky] / dir[kz],
            // 1 / dir[kz], the same division.
            sz: inv[kz],
        }
    }

    /// The watertight test of triangle (a, b, c), both sides, for hits with 0 < t.
    /// Returns the hit whatever its distance: callers keep the nearest.
    #[inline]
    pub fn triangle(&self, a: &[f32; 3], b: &[f32; 3], c: &[f32; 3]) -> Option<TriHit> {
        // One copy of the kernel per axis permutation: the components are picked by constant
        // indices, in registers, instead of through the stack by the ray's indices. The branch
        // goes the same way for every triangle of a ray.
        match (self.kz, self.kx) {
            (0, 1) => self.triangle_in::<1, 2, 0>(a, b, c),
            (0, _) => self.triangle_in::<2, 1, 0>(a, b, c),
            (1, 2) => self.triangle_in::<2, 0, 1>(a, b, c),
            (1, _) => self.triangle_in::<0, 2, 1>(a, b, c),
            (_, 0) => self.triangle_in::<0, 1, 2>(a, b, c),
            (_, _) => self.triangle_in::<1, 0, 2>(a, b, c),
        }
    }

    /// The nearest hit closer than `t_max` among the triangles `ids` of `positions` (the
    /// first of equal distances; ids past `positions` are skipped): what testing them one by
    /// one with [`Ray::triangle`] keeps, with the permutation picked once for the list.
    #[inline]
    pub fn nearest(
        &self,
        ids: &[u16],
        positions: &[[[f32; 3]; 3]],
        t_max: f32,
    ) -> Option<(u16, TriHit)> {
        match (self.kz, self.kx) {
            (0, 1) => self.nearest_in::<1, 2, 0>(ids, positions, t_max),
            (0, _) => self.nearest_in::<2, 1, 0>(ids, positions, t_max),
            (1, 2) => self.nearest_in::<2, 0, 1>(ids, positions, t_max),
            (1, _) => self.nearest_in::<0, 2, 1>(ids, positions, t_max),
            (_, 0) => self.nearest_in::<0, 1, 2>(ids, positions, t_max),
            (_, _) => self.nearest_in::<1, 0, 2>(ids, positions, t_max),
        }
    }

    #[inline(always)]
    fn nearest_in<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        ids: &[u16],
        positions: &[[[f32; 3]; 3]],
        mut t_max: f32,
    ) -> Option<(u16, TriHit)> {
        let mut best = None;
        for &ti in ids {
            let Some([a, b, c]) = positions.get(usize::from(ti)) else {
                continue;
            };
            if let Some(h) = self.triangle_in::<KX, KY, KZ>(a, b, c) {
                if h.t < t_max {
                    t_max = h.t;
                    best = Some((ti, h));
                }
            }
        }
        best
    }

    /// [`Ray::triangle`] for the ray's permutation (`KX`, `KY`, `KZ`).
    #[inline(always)]
    fn triangle_in<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        a: &[f32; 3],
        b: &[f32; 3],
        c: &[f32; 3],
    ) -> Option<TriHit> {
        let (kx, ky, kz) = (KX, KY, KZ);
        let o = &self.org;
        let a = [a[0] - o[0], a[1] - o[1], a[2] - o[2]];
        let b = [b[0] - o[0], b[1] - o[1], b[2] - o[2]];
        let c = [c[0] - o[0], c[1] - o[1], c[2] - o[2]];
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            let f = f64::from;
            u = (f(cx) * f(by) - f(cy) * f(bx)) as f32;
            v = (f(ax) * f(cy) - f(ay) * f(cx)) as f32;
            w = (f(bx) * f(ay) - f(by) * f(ax)) as f32;
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let az = self.sz * a[kz];
        let bz = self.sz * b[kz];
        let cz = self.sz * c[kz];
        let t_scaled = u * az + v * bz + w * cz;
        // t > 0 with the sign of det, without a division.
        if (det > 0.0 && t_scaled <= 0.0) || (det < 0.0 && t_scaled >= 0.0) {
            return None;
        }
        let rcp = 1.0 / det;
        let t = t_scaled * rcp;
        if !t.is_finite() {
            return None;
        }
        Some(TriHit {
            t,
            bary: [u * rcp, v * rcp, w * rcp],
        })
    }
}

/// The axis of the largest |component| (the lowest such axis on ties).
#[inline]
pub fn major_axis(d: [f32; 3]) -> usize {
    let a = d.map(f32::abs);
    if a[0] >= a[1] && a[0] >= a[2] {
        0
    } else if a[1] >= a[2] {
        1
    } else {
        2
    }
}

/// The part of the ray inside the box [lo, hi] grown by `pad` on every side, within
/// [t0, t1]: `(entry, exit)`. A component of ±0, or one so tiny that its reciprocal
/// overflows, makes the ray parallel to that slab: it is inside or outside for all t, and no
/// 0 × inf product (NaN) is ever formed.
pub fn ray_box(
    ray: &Ray,
    lo: [f32; 3],
    hi: [f32; 3],
    pad: f32,
    t0: f32,
    t1: f32,
) -> Option<(f32, f32)> {
    let (mut near, mut far) = (t0, t1);
    for k in 0..3 {
        let (l, h) = (lo[k] - pad, hi[k] + pad);
        let o = ray.org[k];
        let inv = ray.inv[k];
        if ray.dir[k] == 0.0 || !inv.is_finite() {
            if o < l || o > h {
                return None;
            }
            continue;
        }
        let (mut a, mut b) = ((l - o) * inv, (h - o) * inv);
        if a > b {
            std::mem::swap(&mut a, &mut b);
        }
        if a > near {
            near = a;
        }
        if b < far {
            far = b;
        }
    }
    (near <= far).then_some((near, far))
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: [f32; 3] = [0.0, 0.0, 0.0];
    const B: [f32; 3] = [1.0, 0.0, 0.0];
    const C: [f32; 3] = [0.0, 1.0, 0.0];

    #[test]
    fn a_ray_through_the_inside_hits_with_the_right_distance_and_weights() {
        let r = Ray::new([0.25, 0.25, 2.0], [0.0, 0.0, -1.0]);
        let h = r.triangle(&A, &B, &C).map(|h| (h.t, h.bary));
        assert_eq!(h, Some((2.0, [0.5, 0.25, 0.25])));
        // Both sides count.
        let r = Ray::new([0.25, 0.25, -3.0], [0.0, 0.0, 1.0]);
        assert_eq!(r.triangle(&A, &B, &C).map(|h| h.t), Some(3.0));
    }

    #[test]
    fn misses_behind_outside_and_parallel() {
        let behind = Ray::new([0.25, 0.25, 2.0], [0.0, 0.0, 1.0]);
        assert!(behind.triangle(&A, &B, &C).is_none());
        let outside = Ray::new([0.75, 0.75, 2.0], [0.0, 0.0, -1.0]);
        assert!(outside.triangle(&A, &B, &C).is_none());
        let parallel = Ray::new([0.25, 0.25, 0.0], [1.0, 0.0, 0.0]);
        assert!(parallel.triangle(&A, &B, &C).is_none());
        let degenerate = Ray::new([0.25, 0.0, 1.0], [0.0, 0.0, -1.0]);
        assert!(degenerate.triangle(&A, &B, &[2.0, 0.0, 0.0]).is_none());
    }

    #[test]
    fn negative_zero_components_are_handled() {
        let r = Ray::new([0.25, 0.25, 2.0], [-0.0, 0.0, -1.0]);
        assert_eq!(r.triangle(&A, &B, &C).map(|h| h.t), Some(2.0));
        assert_eq!(r.inv[0], f32::NEG_INFINITY);
        let b = ray_box(&r, [0.0; 3], [1.0; 3], 0.0, 0.0, f32::INFINITY);
        assert_eq!(b, Some((1.0, 2.0)));
        let outside = Ray::new([1.5, 0.25, 2.0], [-0.0, 0.0, -1.0]);
        assert!(ray_box(&outside, [0.0; 3], [1.0; 3], 0.0, 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn a_ray_on_a_box_face_plane_is_inside_not_nan() {
        // Origin exactly on the x = 0 slab with a zero x direction: (0 - 0) * inf would be NaN.
        let r = Ray::new([0.0, 0.5, -1.0], [0.0, 0.0, 1.0]);
        let b = ray_box(&r, [0.0; 3], [1.0; 3], 0.0, 0.0, f32::INFINITY);
        assert_eq!(b, Some((1.0, 2.0)));
        // A subnormal component: its reciprocal overflows, the slab is treated as parallel.
        let r = Ray::new([0.5, 0.5, -1.0], [1e-45, 0.0, 1.0]);
        assert!(ray_box(&r, [0.0; 3], [1.0; 3], 0.0, 0.0, f32::INFINITY).is_some());
    }

    #[test]
    fn a_flat_box_is_hit() {
        let r = Ray::new([0.5, 0.5, -1.0], [0.0, 0.0, 1.0]);
        let b = ray_box(
            &r,
            [0.0, 0.0, 0.5],
            [1.0, 1.0, 0.5],
            0.0,
            0.0,
            f32::INFINITY,
        );
        assert_eq!(b, Some((1.5, 1.5)));
    }
}
