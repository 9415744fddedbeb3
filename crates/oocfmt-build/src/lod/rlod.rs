//! R-LOD planes (Yoon et al. 2006, §4.4; spec §6.4): the triangles of a LOD node's subtree,
//! clipped to the node's cell, are summarised by the plane of their area-weighted principal
//! components, their area-weighted mean colour and the largest distance of the clipped surface
//! from that plane. Everything is computed in f64, relative to the cell's centre, one node at a
//! time, so the result does not depend on the thread count.

use oocfmt::records::Rlod;

use super::{material_colour, vertex_colour};
use crate::mesh::{Bounds, Mesh};
use crate::raycast::{cross, dot, normalise, sub};

/// Expansion past the cell on top of the deviation, in node radii: neighbouring coplanar
/// planes meet at the shared face only up to rounding, and this covers it (spec §6.4).
pub const EXPANSION_SLACK: f64 = 1.0 / 128.0;

/// Sweeps of the cyclic Jacobi method: 3×3 matrices converge in well under ten.
const JACOBI_SWEEPS: usize = 32;

/// A plane fitted in f64, before it is rounded into a record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneFit {
    /// Unit normal.
    pub normal: [f64; 3],
    /// A point of the plane: the area-weighted centroid of the clipped triangles.
    pub point: [f64; 3],
    /// Largest distance of a clipped vertex from the plane.
    pub deviation: f64,
    /// The same from the plane as stored ([`PlaneFit::stored_plane`]: f32 normal and offset).
    pub stored_deviation: f64,
    /// Area-weighted mean linear RGB.
    pub colour: [f64; 3],
    /// Area of the clipped triangles.
    pub area: f64,
}

/// Sums over clipped polygons, relative to the cell's centre.
#[derive(Default)]
struct Moments {
    area: f64,
    /// ∫ x dA.
    first: [f64; 3],
    /// ∫ x xᵀ dA (upper triangle: xx, xy, xz, yy, yz, zz).
    second: [f64; 6],
    /// Σ area vectors (orientation of the mesh).
    oriented: [f64; 3],
    colour: [f64; 3],
    colour_weight: f64,
    /// Clipped vertices, for the degenerate case.
    vertex_sum: [f64; 3],
    vertices: f64,
}

impl Moments {
    fn add_polygon(&mut self, poly: &[[f64; 3]], colour: [f64; 3]) {
        let Some(&a) = poly.first() else { return };
        let mut poly_area = 0.0;
        for w in poly.windows(2).skip(1) {
            let (b, c) = (w[0], w[1]);
            let n = cross(sub(b, a), sub(c, a));
            let area = 0.5 * dot(n, n).sqrt();
            for k in 0..3 {
                self.oriented[k] += 0.5 * n[k];
            }
            if area == 0.0 {
                continue;
            }
            poly_area += area;
            self.area += area;
            let s = [a[0] + b[0] + c[0], a[1] + b[1] + c[1], a[2] + b[2] + c[2]];
            for k in 0..3 {
                self.first[k] += area * s[k] / 3.0;
            }
            // Exact second moment of a triangle: A/12 (Σ vᵢvᵢᵀ + s sᵀ).
            let mut i = 0;
            for r in 0..3 {
                for q in r..3 {
                    let vv = a[r] * a[q] + b[r] * b[q] + c[r] * c[q];
                    self.second[i] += area / 12.0 * (vv + s[r] * s[q]);
                    i += 1;
                }
            }
        }
        // Degenerate triangles still lend their colour, as in the voxels' fallback.
        let w = poly_area + 1e-30;
        for k in 0..3 {
            self.colour[k] += w * colour[k];
        }
        self.colour_weight += w;
        for v in poly {
            for k in 0..3 {
                self.vertex_sum[k] += v[k];
            }
            self.vertices += 1.0;
        }
    }
}

/// Fits the R-LOD plane of the triangles `tris` of `mesh` clipped to `cell`.
pub fn fit(mesh: &Mesh, tris: &[u32], cell: Bounds) -> PlaneFit {
    let centre: [f64; 3] =
        std::array::from_fn(|k| (f64::from(cell.min[k]) + f64::from(cell.max[k])) / 2.0);
    let lo: [f64; 3] = std::array::from_fn(|k| f64::from(cell.min[k]) - centre[k]);
    let hi: [f64; 3] = std::array::from_fn(|k| f64::from(cell.max[k]) - centre[k]);
    let mut m = Moments::default();
    let mut scratch = Clip::default();
    let clipped = |t: u32, scratch: &mut Clip| -> bool {
        let Some(c) = mesh.corners(t as usize) else {
            return false;
        };
        let p = c.map(|v| std::array::from_fn(|k| f64::from(v[k]) - centre[k]));
        scratch.clip(p, lo, hi);
        !scratch.out.is_empty()
    };
    for &t in tris {
        if !clipped(t, &mut scratch) {
            continue;
        }
        let colour = mesh
            .triangles
            .get(t as usize)
            .and_then(|idx| vertex_colour(mesh, idx))
            .unwrap_or_else(|| material_colour(mesh, t as usize));
        m.add_polygon(&scratch.out, colour);
    }
    let colour = if m.colour_weight > 0.0 {
        m.colour.map(|c| c / m.colour_weight)
    } else {
        [1.0; 3]
    };
    let (point, normal) = if m.area > 0.0 {
        let mean = m.first.map(|f| f / m.area);
        let s = m.second.map(|x| x / m.area);
        let cov = [
            [
                s[0] - mean[0] * mean[0],
                s[1] - mean[0] * mean[1],
                s[2] - mean[0] * mean[2],
            ],
            [
                s[1] - mean[0] * mean[1],
                s[3] - mean[1] * mean[1],
                s[4] - mean[1] * mean[2],
            ],
            [
                s[2] - mean[0] * mean[2],
                s[4] - mean[1] * mean[2],
                s[5] - mean[2] * mean[2],
            ],
        ];
        (mean, smallest_eigenvector(cov))
    } else {
        let point = if m.vertices > 0.0 {
            m.vertex_sum.map(|x| x / m.vertices)
        } else {
            [0.0; 3]
        };
        (point, unit_or_z(m.oriented))
    };
    // Face the way the mesh's triangles do; a tie picks a positive major component.
    let along = dot(normal, m.oriented);
    let major = (0..3).fold(0, |b, k| {
        if normal[k].abs() > normal[b].abs() {
            k
        } else {
            b
        }
    });
    let flip = along < 0.0 || (along == 0.0 && normal[major] < 0.0);
    let normal = if flip { normal.map(|c| -c) } else { normal };
    let mut plane = PlaneFit {
        normal,
        point: std::array::from_fn(|k| point[k] + centre[k]),
        deviation: 0.0,
        stored_deviation: 0.0,
        colour,
        area: m.area,
    };
    // Distance from the stored plane, relative to the centre: n·(v + c) − d.
    let (sn, sd) = plane.stored_plane();
    let sn = sn.map(f64::from);
    let shift = dot(sn, centre) - f64::from(sd);
    for &t in tris {
        if clipped(t, &mut scratch) {
            for v in &scratch.out {
                plane.deviation = plane.deviation.max(dot(normal, sub(*v, point)).abs());
                plane.stored_deviation = plane.stored_deviation.max((dot(sn, *v) + shift).abs());
            }
        }
    }
    plane
}

impl PlaneFit {
    /// The record of this plane for a LOD node of enclosing radius `radius`. Its deviation
    /// bound holds for the plane as stored.
    pub fn record(&self, radius: f32) -> Rlod {
        let (normal, offset) = self.stored_plane();
        let r = f64::from(radius);
        let deviation = self.deviation.max(self.stored_deviation);
        Rlod {
            normal,
            offset,
            colour: self
                .colour
                .map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8),
            deviation_code: Rlod::code_for(deviation, r),
            expansion_code: Rlod::code_for(deviation + EXPANSION_SLACK * r, r),
        }
    }

    /// The plane as it is stored: f32 unit normal and f32 offset (+z through the origin if
    /// either would not be finite, which only a scene beyond f32 range could cause).
    pub fn stored_plane(&self) -> ([f32; 3], f32) {
        let normal = self.normal.map(|c| c as f32);
        let offset = dot(self.normal, self.point) as f32;
        if normal.iter().all(|c| c.is_finite()) && offset.is_finite() {
            (normal, offset)
        } else {
            ([0.0, 0.0, 1.0], 0.0)
        }
    }
}

/// Sutherland–Hodgman clipping of a triangle against a box, reusing its buffers.
#[derive(Default)]
struct Clip {
    out: Vec<[f64; 3]>,
    tmp: Vec<[f64; 3]>,
}

impl Clip {
    fn clip(&mut self, tri: [[f64; 3]; 3], lo: [f64; 3], hi: [f64; 3]) {
        self.out.clear();
        self.out.extend_from_slice(&tri);
        for k in 0..3 {
            for (bound, keep_below) in [(lo[k], false), (hi[k], true)] {
                std::mem::swap(&mut self.out, &mut self.tmp);
                self.out.clear();
                let n = self.tmp.len();
                for i in 0..n {
                    let (p, q) = (self.tmp[i], self.tmp[(i + 1) % n]);
                    let inside = |v: [f64; 3]| {
                        if keep_below {
                            v[k] <= bound
                        } else {
                            v[k] >= bound
                        }
                    };
                    let (pin, qin) = (inside(p), inside(q));
                    if pin {
                        self.out.push(p);
                    }
                    if pin != qin {
                        let s = (bound - p[k]) / (q[k] - p[k]);
                        let mut x: [f64; 3] = std::array::from_fn(|j| p[j] + s * (q[j] - p[j]));
                        x[k] = bound;
                        self.out.push(x);
                    }
                }
                if self.out.is_empty() {
                    return;
                }
            }
        }
    }
}

/// The unit eigenvector of the smallest eigenvalue of a symmetric 3×3 matrix, by cyclic Jacobi
/// rotations: deterministic, and defined (an axis) even when eigenvalues repeat.
pub fn smallest_eigenvector(a: [[f64; 3]; 3]) -> [f64; 3] {
    let mut a = a;
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..JACOBI_SWEEPS {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        let diag = a[0][0].abs() + a[1][1].abs() + a[2][2].abs();
        if off <= diag * 1e-18 || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A ← Jᵀ A J, V ← V J.
            for k in 0..3 {
                let (akp, akq) = (a[k][p], a[k][q]);
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for k in 0..3 {
                let (apk, aqk) = (a[p][k], a[q][k]);
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let k = (0..3).fold(0, |b, k| if a[k][k] < a[b][b] { k } else { b });
    unit_or_z([v[0][k], v[1][k], v[2][k]])
}

/// `a` normalised, +z for a zero or non-finite vector.
fn unit_or_z(a: [f64; 3]) -> [f64; 3] {
    let n = normalise(a);
    if n == [0.0; 3] {
        [0.0, 0.0, 1.0]
    } else {
        n
    }
}
