//! Triangulation of one polygon face by ear clipping.
//!
//! A fan is only right for convex polygons, and CAD exports are full of concave ones (L-shaped
//! brackets, slotted plates). The polygon is projected onto the coordinate plane most
//! perpendicular to its Newell normal, which is exact (a coordinate is dropped, nothing is
//! rounded) and keeps non-planar faces as faithful as any projection can. Every polygon of n
//! corners yields exactly n − 2 triangles, so counts stay predictable: a corner collinear with
//! its neighbours is clipped as a zero-area ear, and the sink reports that triangle as dropped.
//!
//! Ears are searched starting at corner 1 and continuing after each clipped ear, so a convex
//! polygon comes out as the fan (0, i, i + 1), the same triangles every fan triangulator
//! produces.

/// How a polygon was triangulated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::import) enum Outcome {
    /// Ear clipping succeeded (or the polygon was a triangle).
    Clipped,
    /// No usable plane: non-finite or coincident/collinear corners. Fanned; every triangle
    /// that comes out degenerate is the sink's to drop.
    Degenerate,
    /// Ear clipping found no ear (a self-intersecting polygon, or one that ran out of its work
    /// budget), so the rest was fanned; worth a warning.
    Fallback,
}

/// Reusable buffers, so faces cost no allocation once the largest has been seen.
#[derive(Default)]
pub(in crate::import) struct Triangulator {
    pts: Vec<[f64; 2]>,
    prev: Vec<usize>,
    next: Vec<usize>,
    reflex: Vec<bool>,
    out: Vec<[usize; 3]>,
}

impl Triangulator {
    /// The triangles of the last call, as corner indices into the polygon given.
    pub(in crate::import) fn triangles(&self) -> &[[usize; 3]] {
        &self.out
    }

    /// Triangulates `poly` (at least 3 corners) into `poly.len() - 2` triangles.
    pub(in crate::import) fn triangulate(&mut self, poly: &[[f32; 3]]) -> Outcome {
        self.out.clear();
        let n = poly.len();
        if n < 3 {
            return Outcome::Degenerate;
        }
        if n == 3 {
            self.out.push([0, 1, 2]);
            return Outcome::Clipped;
        }
        if !poly.iter().flatten().all(|c| c.is_finite()) {
            self.fan(n);
            return Outcome::Degenerate;
        }
        if !self.project(poly) {
            self.fan(n);
            return if has_area(poly) {
                Outcome::Fallback
            } else {
                Outcome::Degenerate
            };
        }
        self.clip(n)
    }

    fn fan(&mut self, n: usize) {
        self.out
            .extend((1..n.saturating_sub(1)).map(|i| [0, i, i + 1]));
    }

    /// Fills `pts` with the polygon in the plane of its Newell normal, wound counter-clockwise.
    /// False when the normal is zero.
    fn project(&mut self, poly: &[[f32; 3]]) -> bool {
        let Some(&origin) = poly.first() else {
            return false;
        };
        let rel = |p: &[f32; 3]| -> [f64; 3] {
            [0, 1, 2].map(|a| f64::from(p[a]) - f64::from(origin[a]))
        };
        let mut normal = [0.0f64; 3];
        for (i, p) in poly.iter().enumerate() {
            let (a, b) = (rel(p), rel(&poly[(i + 1) % poly.len()]));
            normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
            normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
            normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
        }
        let mut axis = 0;
        for a in 1..3 {
            if normal[a].abs() > normal[axis].abs() {
                axis = a;
            }
        }
        if normal[axis] == 0.0 || !normal[axis].is_finite() {
            return false;
        }
        // (axis+1, axis+2) is the right-handed pair, whose area has the sign of normal[axis];
        // swapping the pair mirrors a clockwise projection into a counter-clockwise one.
        let (mut u, mut v) = ((axis + 1) % 3, (axis + 2) % 3);
        if normal[axis] < 0.0 {
            std::mem::swap(&mut u, &mut v);
        }
        self.pts.clear();
        self.pts.extend(poly.iter().map(|p| {
            let r = rel(p);
            [r[u], r[v]]
        }));
        true
    }

    fn clip(&mut self, n: usize) -> Outcome {
        self.prev.clear();
        self.prev.extend((0..n).map(|i| (i + n - 1) % n));
        self.next.clear();
        self.next.extend((0..n).map(|i| (i + 1) % n));
        self.reflex.clear();
        for i in 0..n {
            let r = self.turn(self.prev[i], i, self.next[i]) <= 0.0;
            self.reflex.push(r);
        }
        let mut reflex_count = self.reflex.iter().filter(|&&r| r).count();
        // Generous for real polygons (roughly n × reflex corners steps), but bounded so that
        // a crafted spiral cannot take cubic time.
        let mut budget = 16 * (n as u64) * (n as u64) + 1024;
        let mut remaining = n;
        let mut cur = 1;
        let mut misses = 0;
        while remaining > 3 {
            let (p, q) = (self.prev[cur], self.next[cur]);
            match self.is_ear(p, cur, q, reflex_count, &mut budget) {
                Some(true) => {
                    self.out.push([p, cur, q]);
                    self.next[p] = q;
                    self.prev[q] = p;
                    remaining -= 1;
                    for k in [p, q] {
                        let r = self.turn(self.prev[k], k, self.next[k]) <= 0.0;
                        if r != self.reflex[k] {
                            self.reflex[k] = r;
                            if r {
                                reflex_count += 1;
                            } else {
                                reflex_count -= 1;
                            }
                        }
                    }
                    if self.reflex[cur] {
                        reflex_count -= 1;
                        self.reflex[cur] = false;
                    }
                    misses = 0;
                    cur = q;
                }
                Some(false) => {
                    misses += 1;
                    cur = q;
                    if misses > remaining {
                        return self.fan_rest(cur, remaining);
                    }
                }
                None => return self.fan_rest(cur, remaining),
            }
        }
        self.out.push([self.prev[cur], cur, self.next[cur]]);
        Outcome::Clipped
    }

    /// Fans the corners still in the ring from `start`.
    fn fan_rest(&mut self, start: usize, remaining: usize) -> Outcome {
        let mut a = self.next[start];
        for _ in 2..remaining {
            let b = self.next[a];
            self.out.push([start, a, b]);
            a = b;
        }
        Outcome::Fallback
    }

    /// Twice the signed area of (a, b, c): positive for a left turn.
    fn turn(&self, a: usize, b: usize, c: usize) -> f64 {
        cross(self.pts[a], self.pts[b], self.pts[c])
    }

    /// Whether (p, c, q) can be cut off; `None` when the work budget is spent.
    fn is_ear(
        &self,
        p: usize,
        c: usize,
        q: usize,
        reflex_count: usize,
        budget: &mut u64,
    ) -> Option<bool> {
        let t = self.turn(p, c, q);
        if t < 0.0 {
            return Some(false);
        }
        // A zero-area corner can always go: cutting it changes neither the area nor the shape.
        if t == 0.0 || reflex_count == 0 {
            return Some(true);
        }
        let (a, b, d) = (self.pts[p], self.pts[c], self.pts[q]);
        // Only reflex corners can lie inside an ear of a simple polygon. Corners coinciding
        // with the ear's own (the two ends of a bridge to a hole) do not block it.
        let mut k = self.next[q];
        while k != p {
            *budget = budget.checked_sub(1)?;
            let x = self.pts[k];
            if self.reflex[k] && x != a && x != b && x != d && inside(a, b, d, x) {
                return Some(false);
            }
            k = self.next[k];
        }
        Some(true)
    }
}

fn cross(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Whether `x` lies in the counter-clockwise triangle (a, b, c) or on its boundary.
fn inside(a: [f64; 2], b: [f64; 2], c: [f64; 2], x: [f64; 2]) -> bool {
    cross(a, b, x) >= 0.0 && cross(b, c, x) >= 0.0 && cross(c, a, x) >= 0.0
}

/// Whether any fan triangle of the polygon has a non-zero area in 3D.
fn has_area(poly: &[[f32; 3]]) -> bool {
    let Some(&o) = poly.first() else {
        return false;
    };
    let rel = |p: [f32; 3]| [0, 1, 2].map(|a| f64::from(p[a]) - f64::from(o[a]));
    poly.windows(2).skip(1).any(|w| {
        let (u, v) = (rel(w[0]), rel(w[1]));
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        n != [0.0; 3]
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area2d(poly: &[[f32; 3]], tris: &[[usize; 3]]) -> f64 {
        tris.iter()
            .map(|t| {
                let p = t.map(|i| [f64::from(poly[i][0]), f64::from(poly[i][1])]);
                0.5 * cross(p[0], p[1], p[2])
            })
            .sum()
    }

    fn shoelace(poly: &[[f32; 3]]) -> f64 {
        let n = poly.len();
        (0..n)
            .map(|i| {
                let (a, b) = (poly[i], poly[(i + 1) % n]);
                0.5 * (f64::from(a[0]) * f64::from(b[1]) - f64::from(b[0]) * f64::from(a[1]))
            })
            .sum()
    }

    fn xy(points: &[[f32; 2]]) -> Vec<[f32; 3]> {
        points.iter().map(|p| [p[0], p[1], 0.0]).collect()
    }

    #[test]
    fn convex_polygons_come_out_as_the_fan_from_corner_0() {
        let hexagon: Vec<[f32; 3]> = (0..6)
            .map(|i| {
                let a = i as f32 * std::f32::consts::PI / 3.0;
                [a.cos(), a.sin(), 0.5]
            })
            .collect();
        let mut t = Triangulator::default();
        assert_eq!(t.triangulate(&hexagon), Outcome::Clipped);
        assert_eq!(t.triangles(), &[[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]]);
    }

    #[test]
    fn concave_polygons_keep_their_area_in_either_winding() {
        let l_shape = xy(&[
            [0.0, 0.0],
            [2.0, 0.0],
            [2.0, 1.0],
            [1.0, 1.0],
            [1.0, 2.0],
            [0.0, 2.0],
        ]);
        let star: Vec<[f32; 2]> = (0..10)
            .map(|i| {
                let a = i as f32 * std::f32::consts::PI / 5.0;
                let r = if i % 2 == 0 { 1.0 } else { 0.4 };
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        // Corner 1 is reflex in this one, so a fan from corner 0 would overlap itself.
        let arrow = xy(&[[0.0, 0.0], [1.0, 1.0], [2.0, 0.0], [1.0, 3.0]]);
        for poly in [l_shape, xy(&star), arrow] {
            for reversed in [false, true] {
                let mut p = poly.clone();
                if reversed {
                    p.reverse();
                }
                let mut t = Triangulator::default();
                assert_eq!(t.triangulate(&p), Outcome::Clipped);
                assert_eq!(t.triangles().len(), p.len() - 2);
                let (want, got) = (shoelace(&p), area2d(&p, t.triangles()));
                assert!((want - got).abs() < 1e-9, "{want} vs {got}");
                // Every triangle keeps the polygon's winding, so none is flipped or overlapping.
                for tri in t.triangles() {
                    assert!(area2d(&p, &[*tri]) * want > 0.0, "{tri:?} in {p:?}");
                }
            }
        }
    }

    #[test]
    fn collinear_and_duplicate_corners_are_clipped_as_zero_area_ears() {
        let p = xy(&[
            [0.0, 0.0],
            [1.0, 0.0],
            [2.0, 0.0],
            [2.0, 0.0],
            [2.0, 2.0],
            [1.0, 1.0],
            [0.0, 2.0],
        ]);
        let mut t = Triangulator::default();
        assert_eq!(t.triangulate(&p), Outcome::Clipped);
        assert_eq!(t.triangles().len(), 5);
        assert!((area2d(&p, t.triangles()) - shoelace(&p)).abs() < 1e-9);
    }

    #[test]
    fn a_hole_joined_by_a_bridge_is_respected() {
        // A 4×4 square with a 2×2 hole, joined along the bridge (0,0)-(1,1).
        let p = xy(&[
            [0.0, 0.0],
            [4.0, 0.0],
            [4.0, 4.0],
            [0.0, 4.0],
            [0.0, 0.0],
            [1.0, 1.0],
            [1.0, 3.0],
            [3.0, 3.0],
            [3.0, 1.0],
            [1.0, 1.0],
        ]);
        let mut t = Triangulator::default();
        assert_eq!(t.triangulate(&p), Outcome::Clipped);
        assert!((area2d(&p, t.triangles()) - 12.0).abs() < 1e-9);
    }

    #[test]
    fn planes_other_than_xy_and_mirrored_ones_work() {
        // The L-shape in the plane x = 3, seen from -x, so the projection has to mirror it.
        let l = [
            [0.0, 0.0],
            [2.0, 0.0],
            [2.0, 1.0],
            [1.0, 1.0],
            [1.0, 2.0],
            [0.0, 2.0],
        ];
        let p: Vec<[f32; 3]> = l.iter().map(|q| [3.0, q[1], q[0]]).collect();
        let mut t = Triangulator::default();
        assert_eq!(t.triangulate(&p), Outcome::Clipped);
        let area: f64 = t
            .triangles()
            .iter()
            .map(|tri| {
                let q = tri.map(|i| [f64::from(p[i][2]), f64::from(p[i][1])]);
                0.5 * cross(q[0], q[1], q[2])
            })
            .sum();
        assert!((area - 3.0).abs() < 1e-9, "{area}");
    }

    #[test]
    fn self_intersecting_and_degenerate_polygons_fall_back_to_a_fan() {
        let mut t = Triangulator::default();
        let bowtie = xy(&[[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]);
        assert_eq!(t.triangulate(&bowtie), Outcome::Fallback);
        assert_eq!(t.triangles().len(), 2);
        // An asymmetric self-intersecting pentagon: the Newell normal is not zero.
        let tangled = xy(&[[0.0, 0.0], [4.0, 0.0], [0.0, 3.0], [3.0, 3.0], [3.0, -1.0]]);
        let outcome = t.triangulate(&tangled);
        assert_eq!(t.triangles().len(), 3);
        assert_ne!(outcome, Outcome::Degenerate);
        let line = xy(&[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]]);
        assert_eq!(t.triangulate(&line), Outcome::Degenerate);
        assert_eq!(t.triangles().len(), 2);
        let nan = xy(&[[0.0, 0.0], [1.0, 0.0], [f32::NAN, 1.0], [0.0, 1.0]]);
        assert_eq!(t.triangulate(&nan), Outcome::Degenerate);
        assert_eq!(t.triangles().len(), 2);
    }

    #[test]
    fn a_long_comb_is_clipped_within_its_budget() {
        // A comb of 2000 teeth: most corners reflex, the classic slow case for ear clipping.
        let mut p = Vec::new();
        let teeth = 2000;
        for i in 0..teeth {
            let x = i as f32 * 2.0;
            p.extend([[x, 0.0], [x + 1.0, 0.0], [x + 1.0, -10.0]].map(|q| [q[0], q[1], 0.0]));
        }
        p.push([teeth as f32 * 2.0, -10.0, 0.0]);
        p.push([teeth as f32 * 2.0, 1.0, 0.0]);
        p.push([0.0, 1.0, 0.0]);
        p.reverse();
        let mut t = Triangulator::default();
        assert_eq!(t.triangulate(&p), Outcome::Clipped);
        assert_eq!(t.triangles().len(), p.len() - 2);
        assert!((area2d(&p, t.triangles()) - shoelace(&p)).abs() < 1e-6);
    }
}
