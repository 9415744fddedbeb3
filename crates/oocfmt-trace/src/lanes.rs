//! The watertight ray/triangle kernel of [`crate::intersect`] over a packet of `N` rays that
//! share one axis permutation: each triangle is tested against every ray of the packet at once,
//! lane by lane, in loops without early exits that the compiler turns into SIMD instructions.
//! Every lane computes exactly what [`Ray::triangle`] computes for its ray, operation for
//! operation (no fused multiply-adds, the same order of additions, the same f64 recomputation
//! of an edge function that rounds to zero), so a packet finds the same hits, bit for bit.

// Lane loops index several arrays by the same lane, which is what the compiler vectorizes.
#![allow(clippy::needless_range_loop)]

use crate::intersect::Ray;

/// `N` rays with one axis permutation, by component (structure of arrays).
#[derive(Clone, Copy, Debug)]
pub struct RayLanes<const N: usize> {
    org: [[f32; N]; 3],
    sx: [f32; N],
    sy: [f32; N],
    sz: [f32; N],
    kx: usize,
    kz: usize,
}

/// The nearest hits a leaf gave the lanes: which lanes found a nearer triangle, its index and
/// its barycentric weights.
pub struct LaneHits<const N: usize> {
    /// Bit i: lane i found a nearer triangle.
    pub hit: u32,
    /// Per lane, the id (from `ids`) of the nearer triangle found; meaningful only where `hit`
    /// has the lane's bit.
    pub triangle: [u16; N],
    /// Per vertex a, b, c, then per lane, the barycentric weights of that lane's hit.
    pub bary: [[f32; N]; 3],
}

impl<const N: usize> RayLanes<N> {
    /// The lanes of `rays`; None when their axis permutations differ or there are more than
    /// 32 (a lane mask is a `u32`).
    pub fn new(rays: &[Ray; N]) -> Option<RayLanes<N>> {
        if N > 32 {
            return None;
        }
        let first = rays.first()?;
        if rays.iter().any(|r| r.kx != first.kx || r.kz != first.kz) {
            return None;
        }
        Some(RayLanes {
            org: [0, 1, 2].map(|k| std::array::from_fn(|i| rays[i].org[k])),
            sx: std::array::from_fn(|i| rays[i].sx),
            sy: std::array::from_fn(|i| rays[i].sy),
            sz: std::array::from_fn(|i| rays[i].sz),
            kx: first.kx,
            kz: first.kz,
        })
    }

    /// For each lane in `active` (bit i: lane i), the nearest hit closer than its `t_max` among the triangles
    /// `ids` of `positions` (the first of equal distances; ids past `positions` are skipped),
    /// as [`Ray::nearest`] gives it; `t_max` is lowered to the hits found.
    pub fn nearest(
        &self,
        active: u32,
        ids: &[u16],
        positions: &[[[f32; 3]; 3]],
        t_max: &mut [f32; N],
    ) -> LaneHits<N> {
        match (self.kz, self.kx) {
            (0, 1) => self.nearest_in::<1, 2, 0>(active, ids, positions, t_max),
            (0, _) => self.nearest_in::<2, 1, 0>(active, ids, positions, t_max),
            (1, 2) => self.nearest_in::<2, 0, 1>(active, ids, positions, t_max),
            (1, _) => self.nearest_in::<0, 2, 1>(active, ids, positions, t_max),
            (_, 0) => self.nearest_in::<0, 1, 2>(active, ids, positions, t_max),
            (_, _) => self.nearest_in::<1, 0, 2>(active, ids, positions, t_max),
        }
    }

    #[inline(always)]
    fn nearest_in<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        active: u32,
        ids: &[u16],
        positions: &[[[f32; 3]; 3]],
        t_max: &mut [f32; N],
    ) -> LaneHits<N> {
        let mut out = LaneHits {
            hit: 0,
            triangle: [0; N],
            bary: [[0.0; N]; 3],
        };
        let [ox, oy, oz] = [&self.org[KX], &self.org[KY], &self.org[KZ]];
        let (sx, sy, sz) = (&self.sx, &self.sy, &self.sz);
        let mut act = [0u32; N];
        for i in 0..N {
            act[i] = all(active >> i & 1 != 0);
        }
        for &ti in ids {
            let Some([a, b, c]) = positions.get(usize::from(ti)) else {
                continue;
            };
            // The sheared, projected vertices relative to each lane's origin.
            let (ak, bk, ck) = (from(a[KZ], oz), from(b[KZ], oz), from(c[KZ], oz));
            let ax = sub(&from(a[KX], ox), &mul(sx, &ak));
            let ay = sub(&from(a[KY], oy), &mul(sy, &ak));
            let bx = sub(&from(b[KX], ox), &mul(sx, &bk));
            let by = sub(&from(b[KY], oy), &mul(sy, &bk));
            let cx = sub(&from(c[KX], ox), &mul(sx, &ck));
            let cy = sub(&from(c[KY], oy), &mul(sy, &ck));
            let mut u = sub(&mul(&cx, &by), &mul(&cy, &bx));
            let mut v = sub(&mul(&ax, &cy), &mul(&ay, &cx));
            let mut w = sub(&mul(&bx, &ay), &mul(&by, &ax));
            let mut zero = [0u32; N];
            for i in 0..N {
                zero[i] = all(u[i] == 0.0) | all(v[i] == 0.0) | all(w[i] == 0.0);
            }
            if any(&zero) {
                // Rare: an edge function rounded to zero in some lane; that lane recomputes
                // all three in f64, as the single-ray kernel does.
                for i in 0..N {
                    if zero[i] != 0 {
                        let f = |x: &[f32; N]| f64::from(x[i]);
                        let (ax, ay, bx, by, cx, cy) =
                            (f(&ax), f(&ay), f(&bx), f(&by), f(&cx), f(&cy));
                        u[i] = (cx * by - cy * bx) as f32;
                        v[i] = (ax * cy - ay * cx) as f32;
                        w[i] = (bx * ay - by * ax) as f32;
                    }
                }
            }
            // Inside: no edge function of either sign against the others.
            let mut inside = [0u32; N];
            for i in 0..N {
                let (u, v, w) = (u[i], v[i], w[i]);
                let neg = all(u < 0.0) | all(v < 0.0) | all(w < 0.0);
                let pos = all(u > 0.0) | all(v > 0.0) | all(w > 0.0);
                inside[i] = act[i] & !(neg & pos);
            }
            if !any(&inside) {
                continue;
            }
            let det = add(&add(&u, &v), &w);
            let (az, bz, cz) = (mul(sz, &ak), mul(sz, &bk), mul(sz, &ck));
            let t_scaled = add(&add(&mul(&u, &az), &mul(&v, &bz)), &mul(&w, &cz));
            let mut rcp = [0f32; N];
            for i in 0..N {
                rcp[i] = 1.0 / det[i];
            }
            let t = mul(&t_scaled, &rcp);
            let mut take = [0u32; N];
            for i in 0..N {
                let (d, ts) = (det[i], t_scaled[i]);
                let behind = (all(d > 0.0) & all(ts <= 0.0)) | (all(d < 0.0) & all(ts >= 0.0));
                let ok = all(d != 0.0)
                    & all(d.is_finite())
                    & !behind
                    & all(t[i].is_finite())
                    & all(t[i] < t_max[i]);
                take[i] = inside[i] & ok;
            }
            if !any(&take) {
                continue;
            }
            let bary = [mul(&u, &rcp), mul(&v, &rcp), mul(&w, &rcp)];
            for i in 0..N {
                if take[i] != 0 {
                    t_max[i] = t[i];
                    out.hit |= 1 << i;
                    out.triangle[i] = ti;
                    for k in 0..3 {
                        out.bary[k][i] = bary[k][i];
                    }
                }
            }
        }
        out
    }
}

/// A lane mask: all bits set for true, none for false (what a SIMD comparison gives).
#[inline(always)]
fn all(b: bool) -> u32 {
    u32::from(b).wrapping_neg()
}

/// Whether some lane of `m` is set.
#[inline(always)]
fn any<const N: usize>(m: &[u32; N]) -> bool {
    m.iter().fold(0, |a, &b| a | b) != 0
}

/// p − o per lane.
#[inline(always)]
fn from<const N: usize>(p: f32, o: &[f32; N]) -> [f32; N] {
    let mut r = [0.0; N];
    for i in 0..N {
        r[i] = p - o[i];
    }
    r
}

#[inline(always)]
fn add<const N: usize>(a: &[f32; N], b: &[f32; N]) -> [f32; N] {
    let mut r = [0.0; N];
    for i in 0..N {
        r[i] = a[i] + b[i];
    }
    r
}

#[inline(always)]
fn sub<const N: usize>(a: &[f32; N], b: &[f32; N]) -> [f32; N] {
    let mut r = [0.0; N];
    for i in 0..N {
        r[i] = a[i] - b[i];
    }
    r
}

#[inline(always)]
fn mul<const N: usize>(a: &[f32; N], b: &[f32; N]) -> [f32; N] {
    let mut r = [0.0; N];
    for i in 0..N {
        r[i] = a[i] * b[i];
    }
    r
}
