//! R-LOD planes (Yoon et al. 2006, §4.4; spec §6.4): the triangles of a LOD node's subtree,
//! clipped to the node's cell, are summarised by the plane of their area-weighted principal
//! components, their area-weighted mean colour and the largest distance of the clipped surface
//! from that plane. Everything is computed in f64, relative to the cell's centre, one node at a
//! time, so the result does not depend on the thread count.

use oocfmt::records::Rlod;

use super::{material_colour, vertex_colour};
use crate::raycast::{cross, dot, normalise, sub};
use oocfmt_meshio::mesh::{Bounds, Mesh};

/// Expansion past the cell on top of the deviation, in node radii: neighbouring coplanar
/// planes meet at the shared face only up to rounding, and this covers it (spec §6.4).
pub const EXPANSION_SLACK: f64 = 1.0 / 128.0;

/// Sweeps of the cyclic Jacobi method: 3×3 matrices converge in well under ten.
const JACOBI_SWEEPS: usize = 32;

/// A plane fitted in f64, before it is rounded into a record.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
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
    /// Area of the plane's part inside the cell: what the coverage is a share of.
    pub section: f64,
    /// Σ over the clipped polygons measured so far ([`Deviation`]) of their area projected on
    /// the plane, |A · n|.
    pub projected: f64,
    /// Σ of the same, signed: A · n, the area facing along the normal less the area facing
    /// against it.
    pub facing: f64,
    /// Σ of their projected areas times their cosine to the normal, (A · n)² / |A|.
    pub cosine_weighted: f64,
    /// The part with the largest clipped area (ties: the lowest id); 0 when the triangles
    /// were given no parts.
    pub part: u32,
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
    /// Clipped vertices, for the degenerate case: their sum, their products (as `second`) and
    /// their count.
    vertex_sum: [f64; 3],
    vertex_second: [f64; 6],
    vertices: f64,
}

impl Moments {
    /// Adds a clipped polygon; returns its area.
    fn add_polygon(&mut self, poly: &[[f64; 3]], colour: [f64; 3]) -> f64 {
        let Some(&a) = poly.first() else { return 0.0 };
        let mut poly_area = 0.0;
        for w in poly.windows(2).skip(1) {
            let (b, c) = (w[0], w[1]);
            let n = cross(sub(b, a), sub(c, a));
            let area = 0.5 * dot(n, n).sqrt();
            for (o, n) in self.oriented.iter_mut().zip(n) {
                *o += 0.5 * n;
            }
            if area == 0.0 {
                continue;
            }
            poly_area += area;
            self.area += area;
            let s = [a[0] + b[0] + c[0], a[1] + b[1] + c[1], a[2] + b[2] + c[2]];
            for (f, s) in self.first.iter_mut().zip(s) {
                *f += area * s / 3.0;
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
        for (c, x) in self.colour.iter_mut().zip(colour) {
            *c += w * x;
        }
        self.colour_weight += w;
        for v in poly {
            let mut i = 0;
            for r in 0..3 {
                self.vertex_sum[r] += v[r];
                for q in r..3 {
                    self.vertex_second[i] += v[r] * v[q];
                    i += 1;
                }
            }
            self.vertices += 1.0;
        }
        poly_area
    }
}

/// Fits the R-LOD plane of the triangles `tris` of `mesh` clipped to `cell`.
pub fn fit(mesh: &Mesh, tris: &[u32], cell: Bounds) -> PlaneFit {
    let mut moments = PlaneMoments::new(cell);
    let part = |t: u32| Some(*mesh.part_ids.as_ref()?.get(t as usize)?);
    for &t in tris {
        if let Some(c) = mesh.corners(t as usize) {
            moments.add(c, part(t), || {
                mesh.triangles
                    .get(t as usize)
                    .and_then(|idx| vertex_colour(mesh, idx))
                    .unwrap_or_else(|| material_colour(mesh, t as usize))
            });
        }
    }
    let mut deviation = moments.deviation();
    for &t in tris {
        if let Some(c) = mesh.corners(t as usize) {
            deviation.add(c);
        }
    }
    deviation.finish()
}

/// A cell in f64, relative to its centre: sums stay small and exact where the scene is far
/// from the origin.
#[derive(Clone, Copy)]
struct Frame {
    centre: [f64; 3],
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Frame {
    fn new(cell: Bounds) -> Frame {
        let centre: [f64; 3] =
            std::array::from_fn(|k| (f64::from(cell.min[k]) + f64::from(cell.max[k])) / 2.0);
        Frame {
            centre,
            lo: std::array::from_fn(|k| f64::from(cell.min[k]) - centre[k]),
            hi: std::array::from_fn(|k| f64::from(cell.max[k]) - centre[k]),
        }
    }

    /// Clips a triangle to the cell into `scratch.out`; false when nothing is left.
    fn clip(&self, corners: [[f32; 3]; 3], scratch: &mut Clip) -> bool {
        let p = corners.map(|v| std::array::from_fn(|k| f64::from(v[k]) - self.centre[k]));
        scratch.clip(p, self.lo, self.hi);
        !scratch.out.is_empty()
    }
}

/// The first pass of a fit: the moments of the triangles clipped to a cell, fed one triangle
/// at a time, so the triangles may come from memory or stream from a spill file. The integrals
/// are additive: triangles clipped to the cells of a partition sum to the same moments.
pub struct PlaneMoments {
    frame: Frame,
    moments: Moments,
    scratch: Clip,
    /// Clipped area by part, for the triangles given one (summed in the order they come).
    part_areas: std::collections::BTreeMap<u32, f64>,
}

impl PlaneMoments {
    /// Starts a fit of the triangles clipped to `cell`; sums are kept relative to its centre.
    pub fn new(cell: Bounds) -> PlaneMoments {
        PlaneMoments {
            frame: Frame::new(cell),
            moments: Moments::default(),
            scratch: Clip::default(),
            part_areas: std::collections::BTreeMap::new(),
        }
    }

    /// Adds one triangle of `part` (`None`: the scene has no part ids); `colour` (linear RGB)
    /// is asked only when the triangle reaches the cell.
    pub fn add(
        &mut self,
        corners: [[f32; 3]; 3],
        part: Option<u32>,
        colour: impl FnOnce() -> [f64; 3],
    ) {
        if self.frame.clip(corners, &mut self.scratch) {
            let area = self.moments.add_polygon(&self.scratch.out, colour());
            if let Some(p) = part {
                *self.part_areas.entry(p).or_insert(0.0) += area;
            }
        }
    }

    /// The part with the largest clipped area so far (ties: the lowest id), 0 for none.
    fn largest_part(&self) -> u32 {
        let mut best: Option<(u32, f64)> = None;
        for (&p, &a) in &self.part_areas {
            if best.is_none_or(|(_, b)| a > b) {
                best = Some((p, a));
            }
        }
        best.map_or(0, |(p, _)| p)
    }

    /// The plane and its point relative to the cell's centre, as fitted (no rounding through
    /// the absolute point).
    fn plane_and_local_point(&self) -> (PlaneFit, [f64; 3]) {
        let m = &self.moments;
        let colour = if m.colour_weight > 0.0 {
            m.colour.map(|c| c / m.colour_weight)
        } else {
            super::default_albedo()
        };
        let (point, normal) = if m.area > 0.0 {
            let (mean, normal, _) = principal(m.first, m.second, m.area);
            (mean, normal)
        } else if m.vertices > 0.0 {
            // No area (degenerate triangles, or only edges on the cell's faces): the same fit
            // over the clipped vertices, each of weight one. Collinear vertices leave a choice
            // of normals (any one perpendicular to their line), which Jacobi makes
            // deterministically; a single point falls back on the triangles' orientation.
            let (mean, normal, spread) = principal(m.vertex_sum, m.vertex_second, m.vertices);
            (
                mean,
                if spread > 0.0 {
                    normal
                } else {
                    unit_or_z(m.oriented)
                },
            )
        } else {
            ([0.0; 3], [0.0, 0.0, 1.0])
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
        let plane = PlaneFit {
            normal,
            point: std::array::from_fn(|k| point[k] + self.frame.centre[k]),
            deviation: 0.0,
            stored_deviation: 0.0,
            colour,
            area: m.area,
            section: section_area(&self.frame, normal, point),
            projected: 0.0,
            facing: 0.0,
            cosine_weighted: 0.0,
            part: self.largest_part(),
        };
        (plane, point)
    }

    /// The plane of the moments so far, with no deviation yet ([`Deviation`] measures it).
    pub fn plane(&self) -> PlaneFit {
        self.plane_and_local_point().0
    }

    /// The second pass over the same cell.
    pub fn deviation(&self) -> Deviation {
        let (plane, point) = self.plane_and_local_point();
        Deviation::in_frame(&plane, self.frame, point)
    }
}

/// The second pass of a fit: the largest distance of the clipped triangles from a plane
/// already fitted, both as fitted and as stored. Fed one triangle at a time like
/// [`PlaneMoments`]; the triangles may be clipped to any cell inside the fit's cell (the pieces
/// of a partition have the same largest distance as the whole), and [`PlaneFit::widen`]
/// combines the pieces.
pub struct Deviation {
    plane: PlaneFit,
    frame: Frame,
    /// The fitted plane's point relative to the frame's centre.
    point: [f64; 3],
    stored_normal: [f64; 3],
    /// n·c − d of the stored plane at the frame's centre.
    shift: f64,
    scratch: Clip,
}

impl Deviation {
    /// Measures against `plane` the triangles clipped to `cell`.
    pub fn new(plane: &PlaneFit, cell: Bounds) -> Deviation {
        let frame = Frame::new(cell);
        let point = std::array::from_fn(|k| plane.point[k] - frame.centre[k]);
        Deviation::in_frame(plane, frame, point)
    }

    fn in_frame(plane: &PlaneFit, frame: Frame, point: [f64; 3]) -> Deviation {
        let (sn, sd) = plane.stored_plane();
        let stored_normal = sn.map(f64::from);
        Deviation {
            // This piece's own sums: the plane may carry those of pieces measured before.
            plane: PlaneFit {
                projected: 0.0,
                facing: 0.0,
                cosine_weighted: 0.0,
                ..*plane
            },
            point,
            stored_normal,
            shift: dot(stored_normal, frame.centre) - f64::from(sd),
            frame,
            scratch: Clip::default(),
        }
    }

    /// Measures one triangle's clipped part; one outside the cell changes nothing.
    pub fn add(&mut self, corners: [[f32; 3]; 3]) {
        if !self.frame.clip(corners, &mut self.scratch) {
            return;
        }
        let p = &mut self.plane;
        for v in &self.scratch.out {
            p.deviation = p.deviation.max(dot(p.normal, sub(*v, self.point)).abs());
            p.stored_deviation = p
                .stored_deviation
                .max((dot(self.stored_normal, *v) + self.shift).abs());
        }
        let area = area_vector(&self.scratch.out);
        let (along, len) = (dot(area, p.normal), dot(area, area).sqrt());
        p.projected += along.abs();
        p.facing += along;
        if len > 0.0 {
            p.cosine_weighted += along * along / len;
        }
    }

    /// The plane with the largest deviations found, as fitted and as stored.
    pub fn finish(self) -> PlaneFit {
        self.plane
    }
}

impl PlaneFit {
    /// Folds in the deviations another piece of the same node measured against this plane.
    /// Its projected and measured areas add up: the pieces of a partition are disjoint.
    pub fn widen(&mut self, piece: &PlaneFit) {
        self.deviation = self.deviation.max(piece.deviation);
        self.stored_deviation = self.stored_deviation.max(piece.stored_deviation);
        self.projected += piece.projected;
        self.facing += piece.facing;
        self.cosine_weighted += piece.cosine_weighted;
    }

    /// The share of the plane's part in the cell the triangles cover, seen along the normal,
    /// at most 1 (1 when the plane has no part in the cell to cover): the larger of the areas
    /// facing along and against the normal, (|A · n| summed + |Σ A · n|) / 2, so that a closed
    /// part (a pipe, a plate with two faces), whose two sides both project onto the plane,
    /// counts its shadow once and not twice.
    pub fn coverage(&self) -> f64 {
        if self.section > 0.0 {
            ((self.projected + self.facing.abs()) / 2.0 / self.section).min(1.0)
        } else {
            1.0
        }
    }

    /// The mean, over the plane's covered area, of the cosine between the triangles' normals
    /// and the plane's: the mean shade of the surface seen along the normal under a headlight
    /// (1 without area).
    pub fn shade(&self) -> f64 {
        if self.projected > 0.0 {
            (self.cosine_weighted / self.projected).min(1.0)
        } else {
            1.0
        }
    }

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
            coverage: share_code(self.coverage()),
            shade: share_code(self.shade()),
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

/// The mean, the smallest principal axis and the total variance (the covariance's trace) of a
/// distribution of total weight `weight`, first moments `first` and second moments `second`
/// (xx, xy, xz, yy, yz, zz).
fn principal(first: [f64; 3], second: [f64; 6], weight: f64) -> ([f64; 3], [f64; 3], f64) {
    let m = first.map(|f| f / weight);
    let s = second.map(|x| x / weight);
    let cov = [
        [s[0] - m[0] * m[0], s[1] - m[0] * m[1], s[2] - m[0] * m[2]],
        [s[1] - m[0] * m[1], s[3] - m[1] * m[1], s[4] - m[1] * m[2]],
        [s[2] - m[0] * m[2], s[4] - m[1] * m[2], s[5] - m[2] * m[2]],
    ];
    let trace = cov[0][0] + cov[1][1] + cov[2][2];
    (m, smallest_eigenvector(cov), trace)
}

/// A share in 0..=1 as a code of value / 255, rounded to nearest.
fn share_code(x: f64) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// The area vector of a planar polygon (half the sum of its fan's cross products).
fn area_vector(poly: &[[f64; 3]]) -> [f64; 3] {
    let mut sum = [0.0; 3];
    if let Some(&a) = poly.first() {
        for w in poly.windows(2).skip(1) {
            let n = cross(sub(w[0], a), sub(w[1], a));
            for (s, n) in sum.iter_mut().zip(n) {
                *s += 0.5 * n;
            }
        }
    }
    sum
}

/// The area of the plane through `point` with unit normal `normal` inside the frame's cell
/// (all relative to the cell's centre): a square on the plane larger than the cell, clipped
/// to it.
fn section_area(frame: &Frame, normal: [f64; 3], point: [f64; 3]) -> f64 {
    let half = dot(sub(frame.hi, frame.lo), sub(frame.hi, frame.lo)).sqrt();
    // The point of the plane nearest the centre, and two unit vectors spanning the plane.
    let centre: [f64; 3] = std::array::from_fn(|k| dot(normal, point) * normal[k]);
    let helper = if normal[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = normalise(cross(normal, helper));
    let v = cross(normal, u);
    let corner = |a: f64, b: f64| -> [f64; 3] {
        std::array::from_fn(|k| centre[k] + half * (a * u[k] + b * v[k]))
    };
    let (p, q, r, t) = (
        corner(-1.0, -1.0),
        corner(1.0, -1.0),
        corner(1.0, 1.0),
        corner(-1.0, 1.0),
    );
    let mut clip = Clip::default();
    let mut area = 0.0;
    for tri in [[p, q, r], [p, r, t]] {
        clip.clip(tri, frame.lo, frame.hi);
        let a = area_vector(&clip.out);
        area += dot(a, a).sqrt();
    }
    area
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
        // A triangle inside the box would come out of every pass as it went in, vertex for
        // vertex and in order: most of a cell's triangles, so the passes are skipped.
        let inside = |v: &[f64; 3]| (0..3).all(|k| v[k] >= lo[k] && v[k] <= hi[k]);
        if !tri.iter().all(inside) {
            self.passes(lo, hi);
        }
    }

    /// The six Sutherland–Hodgman passes over `out`, one per face of the box.
    fn passes(&mut self, lo: [f64; 3], hi: [f64; 3]) {
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
            for row in &mut a {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (rp, rq) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * rp[k] - s * rq[k];
                a[q][k] = s * rp[k] + c * rq[k];
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

#[cfg(test)]
mod tests {
    use super::*;
    use oocfmt_scenes::rng::Rng;

    fn cell(lo: f32, hi: f32) -> Bounds {
        Bounds {
            min: [lo; 3],
            max: [hi; 3],
        }
    }

    /// A grid of `n`×`n` squares over [-1, 1]² lifted by `z(x, y)`.
    fn patch(n: usize, z: impl Fn(f64, f64) -> f64) -> Mesh {
        let mut positions = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (
                    -1.0 + 2.0 * i as f64 / n as f64,
                    -1.0 + 2.0 * j as f64 / n as f64,
                );
                positions.push([x as f32, y as f32, z(x, y) as f32]);
            }
        }
        let mut triangles = Vec::new();
        let at = |i: usize, j: usize| (j * (n + 1) + i) as u32;
        for j in 0..n {
            for i in 0..n {
                triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        Mesh::new(positions, triangles)
    }

    fn all(mesh: &Mesh) -> Vec<u32> {
        (0..mesh.triangles.len() as u32).collect()
    }

    /// The reference: area-weighted covariance of the (unclipped) triangles by the
    /// edge-midpoint rule (exact for quadratics, a different formula from the fit's), and the
    /// smallest eigenvector from the closed-form eigenvalue of the characteristic cubic.
    fn reference_normal(mesh: &Mesh) -> [f64; 3] {
        let (mut area, mut first, mut second) = (0.0, [0.0; 3], [[0.0; 3]; 3]);
        for t in 0..mesh.triangles.len() {
            let Some(c) = mesh.corners(t) else { continue };
            let p = c.map(|v| v.map(f64::from));
            let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            let a = 0.5 * dot(n, n).sqrt();
            area += a;
            for (u, v) in [(0, 1), (1, 2), (2, 0)] {
                let m: [f64; 3] = std::array::from_fn(|k| (p[u][k] + p[v][k]) / 2.0);
                for r in 0..3 {
                    first[r] += a / 3.0 * m[r];
                    for q in 0..3 {
                        second[r][q] += a / 3.0 * m[r] * m[q];
                    }
                }
            }
        }
        let mean = first.map(|f| f / area);
        let c: [[f64; 3]; 3] = std::array::from_fn(|r| {
            std::array::from_fn(|q| second[r][q] / area - mean[r] * mean[q])
        });
        // Smallest eigenvalue of a symmetric 3×3 matrix (trigonometric method).
        let p1 = c[0][1].powi(2) + c[0][2].powi(2) + c[1][2].powi(2);
        let q = (c[0][0] + c[1][1] + c[2][2]) / 3.0;
        let p2 = (c[0][0] - q).powi(2) + (c[1][1] - q).powi(2) + (c[2][2] - q).powi(2) + 2.0 * p1;
        let p = (p2 / 6.0).sqrt();
        let b: [[f64; 3]; 3] = std::array::from_fn(|r| {
            std::array::from_fn(|s| (c[r][s] - if r == s { q } else { 0.0 }) / p)
        });
        let det = b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1])
            - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0])
            + b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]);
        let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
        let smallest = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
        let m: [[f64; 3]; 3] = std::array::from_fn(|r| {
            std::array::from_fn(|s| c[r][s] - if r == s { smallest } else { 0.0 })
        });
        // The null vector: the largest cross product of two rows.
        let candidates = [cross(m[0], m[1]), cross(m[0], m[2]), cross(m[1], m[2])];
        let best = candidates
            .into_iter()
            .fold([0.0; 3], |b, x| if dot(x, x) > dot(b, b) { x } else { b });
        normalise(best)
    }

    #[test]
    fn a_flat_patch_gives_its_exact_plane_and_no_deviation() {
        // z = 0.3 x − 0.2 y + 0.1: normal ∝ (−0.3, 0.2, 1).
        let mesh = patch(8, |x, y| 0.3 * x - 0.2 * y + 0.1);
        let fit = fit(&mesh, &all(&mesh), cell(-2.0, 2.0));
        let want = normalise([-0.3, 0.2, 1.0]);
        assert!(dot(fit.normal, want) > 1.0 - 1e-12, "{:?}", fit.normal);
        let on_plane = fit.point[2] - (0.3 * fit.point[0] - 0.2 * fit.point[1] + 0.1);
        assert!(on_plane.abs() < 1e-6, "{on_plane}");
        // The f32 vertices lie on the plane up to their rounding.
        assert!(fit.deviation < 1e-6, "{}", fit.deviation);
        assert!((fit.area - 4.0 * (1.0f64 + 0.09 + 0.04).sqrt()).abs() < 1e-5);
        let r = fit.record(2.0 * 3f32.sqrt());
        assert!(r.deviation_code <= 1 && r.expansion_code >= 1, "{r:?}");
    }

    #[test]
    fn a_curved_patch_matches_the_double_precision_reference() {
        let mesh = patch(12, |x, y| {
            0.2 * x * x + 0.1 * x * y - 0.3 * y + 0.05 * y * y
        });
        let fit = fit(&mesh, &all(&mesh), cell(-4.0, 4.0));
        let want = reference_normal(&mesh);
        assert!(
            dot(fit.normal, want).abs() > 1.0 - 1e-9,
            "{:?} vs {want:?}",
            fit.normal
        );
        assert!(fit.normal[2] > 0.0, "faces the way the triangles do");
    }

    /// The shortcut for a triangle inside the box gives the passes' own output, bit for bit:
    /// checked on triangles inside (hundreds of them), straddling and outside, corners on faces.
    #[test]
    fn clipping_a_triangle_inside_the_box_without_the_passes_gives_their_result() {
        let (lo, hi) = ([-1.0, -0.5, 0.0], [1.0, 0.5, 2.0]);
        let mut rng = Rng(11);
        let mut kept = 0;
        for n in 0..2000 {
            let spread = [0.9, 1.3, 3.0][n % 3];
            let tri: [[f64; 3]; 3] = std::array::from_fn(|_| {
                std::array::from_fn(|k| {
                    let c = (lo[k] + hi[k]) / 2.0;
                    let h = (hi[k] - lo[k]) / 2.0 * spread;
                    if rng.chance(0.05) {
                        if rng.chance(0.5) {
                            lo[k]
                        } else {
                            hi[k]
                        }
                    } else {
                        c + rng.range(-h, h)
                    }
                })
            });
            let mut fast = Clip::default();
            fast.clip(tri, lo, hi);
            let mut slow = Clip::default();
            slow.out.extend_from_slice(&tri);
            slow.passes(lo, hi);
            assert_eq!(fast.out, slow.out, "triangle {n}: {tri:?}");
            kept += usize::from(fast.out[..] == tri[..]);
        }
        assert!(
            kept > 300,
            "{kept} triangles inside: the shortcut was hardly tried"
        );
    }

    #[test]
    fn a_noisy_patch_has_a_bounded_deviation() {
        let amp = 0.01;
        let mut rng = Rng(7);
        let mut noise = move || rng.range(-amp, amp);
        let heights: Vec<f64> = (0..33 * 33).map(|_| noise()).collect();
        let mesh = patch(32, |x, y| {
            let (i, j) = (
                ((x + 1.0) * 16.0).round() as usize,
                ((y + 1.0) * 16.0).round() as usize,
            );
            heights[j * 33 + i]
        });
        let fit = fit(&mesh, &all(&mesh), cell(-2.0, 2.0));
        assert!(fit.normal[2] > 1.0 - 1e-3, "{:?}", fit.normal);
        // Every vertex is within `amp` of z = 0 and the plane is within about `amp` of z = 0
        // over the patch, so no vertex is farther than about 2·amp from the plane.
        assert!(fit.deviation <= 2.5 * amp, "{}", fit.deviation);
        assert!(fit.deviation >= 0.5 * amp, "{}", fit.deviation);
        let radius = 2.0 * 3f32.sqrt();
        let r = fit.record(radius);
        assert!(f64::from(r.deviation(radius)) >= fit.deviation.max(fit.stored_deviation));
        assert!(r.error_radius(radius) > radius);
    }

    #[test]
    fn only_the_part_inside_the_cell_counts() {
        // One triangle, half of it beyond x = 0, which bounds the cell.
        let mesh = Mesh::new(
            vec![[-1.0, -1.0, 0.5], [1.0, -1.0, 0.5], [-1.0, 1.0, 0.5]],
            vec![[0, 1, 2]],
        );
        let c = Bounds {
            min: [-1.0, -1.0, -1.0],
            max: [0.0, 1.0, 1.0],
        };
        let fit = fit(&mesh, &[0], c);
        // Inside: the triangle minus the corner x > 0 (a right triangle of legs 1): 2 − 0.5.
        assert!((fit.area - 1.5).abs() < 1e-12, "{}", fit.area);
        assert!(fit.point[0] < 0.0 && (fit.point[2] - 0.5).abs() < 1e-12);
        assert_eq!(fit.normal, [0.0, 0.0, 1.0]);
    }

    #[test]
    fn degenerate_nodes_get_a_defined_plane() {
        // Collinear corners (zero area), a repeated vertex, nothing at all, nothing inside.
        let mesh = Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [0.5, 0.5, 0.5],
                [1.0, 1.0, 1.0],
                [5.0, 5.0, 5.0],
                [6.0, 5.0, 5.0],
                [5.0, 6.0, 5.0],
            ],
            vec![[0, 1, 2], [0, 0, 2], [3, 4, 5]],
        );
        let c = cell(-1.0, 2.0);
        for tris in [vec![0], vec![0, 1], vec![], vec![2]] {
            let fit = fit(&mesh, &tris, c);
            let all_finite = fit
                .normal
                .iter()
                .chain(&fit.point)
                .chain(&fit.colour)
                .all(|x| x.is_finite())
                && fit.deviation.is_finite();
            assert!(all_finite, "{tris:?}: {fit:?}");
            assert!(
                (dot(fit.normal, fit.normal) - 1.0).abs() < 1e-12,
                "{tris:?}"
            );
            let r = fit.record(2.6);
            let bytes = {
                let mut v = Vec::new();
                r.encode_into(&mut v, true);
                v
            };
            assert!(Rlod::decode(&bytes, 0, true).is_ok(), "{tris:?}: {r:?}");
        }
        // The collinear triangle's points all lie in the plane through their centroid.
        let fit = fit(&mesh, &[0], c);
        assert!(fit.deviation < 1e-12, "{fit:?}");
    }

    #[test]
    fn jacobi_finds_the_smallest_axis_of_a_rotated_diagonal() {
        // R diag(3, 2, 0.5) Rᵀ with R a rotation about (1, 1, 1).
        let (s, c) = (0.7f64.sin(), 0.7f64.cos());
        let k = normalise([1.0, 1.0, 1.0]);
        let rot: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let id = if i == j { 1.0 } else { 0.0 };
                let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
                c * id + s * kx[i][j] + (1.0 - c) * k[i] * k[j]
            })
        });
        let d = [3.0, 2.0, 0.5];
        let m: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..3).map(|q| rot[i][q] * d[q] * rot[j][q]).sum())
        });
        let v = smallest_eigenvector(m);
        let want = [rot[0][2], rot[1][2], rot[2][2]];
        assert!(dot(v, want).abs() > 1.0 - 1e-12, "{v:?} vs {want:?}");
        // Repeated eigenvalues still give a unit vector.
        let v = smallest_eigenvector([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        assert!((dot(v, v) - 1.0).abs() < 1e-12);
    }
}
