//! The power-8 Mandelbulb (the data set of the Áfra paper) as a streamed OBJ file.
//!
//! The surface is the level set `DE(p) = ISO_CELLS × h` of the distance estimate over a grid
//! of cell size `h`: an offset surface that resolves the fractal down to the grid and no
//! further, so finer grids show more detail instead of aliasing. It is extracted one slab of
//! cells at a time with marching tetrahedra (six Kuhn tetrahedra per cube, all sharing the
//! main diagonal, so neighbouring cubes cut their common faces the same way and the surface is
//! closed). Vertices live on grid edges and are written once: an edge's vertex is remembered
//! while the slabs on both sides of it are being cut, so memory is two planes of the grid,
//! never the model.
//!
//! The field of a plane is evaluated in parallel, everything else in a fixed order, and each
//! field value depends only on its point: the same options give the same bytes whatever the
//! thread count.

use std::path::Path;

use rayon::prelude::*;

pub use crate::{GenError, GenReport};
use oocfmt_meshio::obj_writer::ObjWriter;

/// A cube around the bulb (whose surfaces lie within ±1.13), centred on the origin.
const BULB_HALF_EXTENT: f64 = 1.25;
/// Cells of grid beyond that cube on each side: room for the iso-level offset and the seed's
/// shift, so the surface never reaches the edge of the grid and is always closed.
const MARGIN_CELLS: u32 = 2;
/// The iso-level in cells: far enough from the set that the offset surface is smooth at the
/// scale of a cell, close enough to keep the bulb's detail.
const ISO_CELLS: f64 = 0.5;
const MAX_ITERATIONS: u32 = 10;
const BAILOUT_SQUARED: f64 = 256.0;
/// The slab state is 48 bytes per grid column (two planes of f32 field values, ten of u32
/// edge vertices): 3.2 GB at this resolution, which makes some 10^10 triangles.
pub const MAX_RESOLUTION: u32 = 8192;
const MIN_RESOLUTION: u32 = 8;

/// Measured triangle counts by resolution (cells per axis), seed 0; other seeds differ by
/// under 1%. The count grows like n^2.1 at coarse grids and n^2.5 at fine ones: each finer
/// grid resolves more of the fractal. [`resolution_for`] interpolates between them in log-log
/// space and extends the last segment's slope beyond.
const CALIBRATION: [(u32, u64); 15] = [
    (8, 660),
    (12, 1_908),
    (16, 3_856),
    (24, 10_064),
    (32, 19_204),
    (48, 46_644),
    (64, 88_160),
    (96, 218_444),
    (128, 419_676),
    (192, 1_088_452),
    (256, 2_202_928),
    (384, 5_925_888),
    (512, 11_826_528),
    (768, 31_939_368),
    (1024, 65_968_888),
];

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MandelbulbOptions {
    /// The approximate triangle count wanted (within ±20% from 100,000 up).
    pub triangles: u64,
    /// Shifts the grid by a fraction of a cell: another tessellation of the same surface.
    pub seed: u64,
    /// Cells per axis; when set, `triangles` is ignored.
    pub resolution: Option<u32>,
}

impl Default for MandelbulbOptions {
    fn default() -> Self {
        MandelbulbOptions {
            triangles: 1_000_000,
            seed: 0,
            resolution: None,
        }
    }
}

/// The grid resolution whose surface has about `triangles` triangles.
pub fn resolution_for(triangles: u64) -> u32 {
    let t = (triangles.max(1)) as f64;
    let mut seg = [CALIBRATION[0], CALIBRATION[1]];
    for w in CALIBRATION.windows(2) {
        if let [a, b] = *w {
            seg = [a, b];
            if t <= b.1 as f64 {
                break;
            }
        }
    }
    let [(n0, t0), (n1, t1)] = seg;
    let slope = ((n1 as f64).ln() - (n0 as f64).ln()) / ((t1 as f64).ln() - (t0 as f64).ln());
    let n = (n0 as f64).ln() + slope * (t.ln() - (t0 as f64).ln());
    (n.exp().round() as u32).clamp(MIN_RESOLUTION, MAX_RESOLUTION)
}

/// Writes the Mandelbulb surface to `path` (atomically). `progress` gets (slabs done, slabs).
pub fn write_obj(
    path: &Path,
    opts: &MandelbulbOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<GenReport, GenError> {
    generate(path, opts, progress).map(|(report, _)| report)
}

/// Writes the Mandelbulb surface as OBJ to the stream `out` (standard output, say), named
/// `name` in errors. `progress` gets (slabs done, slabs).
pub fn write_obj_stream(
    out: Box<dyn std::io::Write>,
    name: &str,
    opts: &MandelbulbOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<GenReport, GenError> {
    let open = || Ok(ObjWriter::stream(out, name));
    generate_into(open, opts, progress).map(|(report, _)| report)
}

/// [`write_obj`], also returning the most vertices and faces one slab held at once.
fn generate(
    path: &Path,
    opts: &MandelbulbOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(GenReport, usize), GenError> {
    generate_into(|| Ok(ObjWriter::create(path)?), opts, progress)
}

/// [`generate`] into the writer `open` makes once the options are checked.
fn generate_into(
    open: impl FnOnce() -> Result<ObjWriter, GenError>,
    opts: &MandelbulbOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(GenReport, usize), GenError> {
    let n = opts
        .resolution
        .unwrap_or_else(|| resolution_for(opts.triangles));
    if !(MIN_RESOLUTION..=MAX_RESOLUTION).contains(&n) {
        return Err(GenError::Option(format!(
            "resolution {n}: expected {MIN_RESOLUTION} ..= {MAX_RESOLUTION} cells per axis"
        )));
    }
    let grid = Grid::new(n, opts.seed);
    let mut obj = open()?;
    obj.comment(&format!(
        "power-8 Mandelbulb, distance-estimate level set at {ISO_CELLS} cells\n\
         grid {n}^3 cells, seed {}, generated by oocfmt-build",
        opts.seed
    ))?;
    let points = grid.points;
    let mut lo = vec![0f32; points * points];
    let mut hi = vec![0f32; points * points];
    grid.eval_plane(0, &mut lo);
    let mut cutter = SlabCutter::new(points);
    let mut triangles = 0u64;
    for k in 0..n {
        grid.eval_plane(k + 1, &mut hi);
        triangles += cutter.cut(&grid, k, &lo, &hi, &mut obj)?;
        std::mem::swap(&mut lo, &mut hi);
        progress(u64::from(k) + 1, u64::from(n));
    }
    let stats = obj.finish()?;
    let report = GenReport {
        triangles,
        vertices: stats.vertices,
        bytes: stats.bytes,
    };
    Ok((report, cutter.peak))
}

/// The sampling grid: point `(i, j, k)` sits at `origin + (i, j, k) × h`.
struct Grid {
    points: usize,
    h: f64,
    origin: [f64; 3],
    iso: f64,
}

impl Grid {
    /// `cells` must exceed `2 × MARGIN_CELLS`.
    fn new(cells: u32, seed: u64) -> Grid {
        let h = 2.0 * BULB_HALF_EXTENT / f64::from(cells - 2 * MARGIN_CELLS);
        let mut state = seed;
        let margin = f64::from(MARGIN_CELLS) * h;
        // Shifted by up to a cell, so at least `MARGIN_CELLS - 1` cells remain on each side.
        let origin = [0; 3].map(|_| -BULB_HALF_EXTENT - margin - h * unit(splitmix64(&mut state)));
        Grid {
            points: cells as usize + 1,
            h,
            origin,
            iso: ISO_CELLS * h,
        }
    }

    fn point(&self, i: usize, j: usize, k: u32) -> [f64; 3] {
        [
            self.origin[0] + i as f64 * self.h,
            self.origin[1] + j as f64 * self.h,
            self.origin[2] + f64::from(k) * self.h,
        ]
    }

    /// The field over plane `k`, row by row; negative inside the surface.
    fn eval_plane(&self, k: u32, out: &mut [f32]) {
        out.par_chunks_mut(self.points)
            .enumerate()
            .for_each(|(j, row)| {
                for (i, v) in row.iter_mut().enumerate() {
                    *v = (distance_estimate(self.point(i, j, k)) - self.iso) as f32;
                }
            });
    }
}

/// The Mandelbulb distance estimate `0.5 · ln r · r / dr`, 0 for points that stay bounded.
///
/// The power-8 step `w ← w⁸ + c` uses Quílez's polynomial form of the spherical formula
/// (polar axis y): correctly rounded IEEE operations instead of trigonometry, so the only
/// platform-dependent step is the final `ln` of the math library.
fn distance_estimate(c: [f64; 3]) -> f64 {
    let [mut x, mut y, mut z] = c;
    let mut r2 = x * x + y * y + z * z;
    let mut dr = 1.0;
    for _ in 0..MAX_ITERATIONS {
        if r2 > BAILOUT_SQUARED {
            break;
        }
        let r = r2.sqrt();
        dr = 8.0 * r2 * r2 * r2 * r * dr + 1.0;
        let (x2, y2, z2) = (x * x, y * y, z * z);
        let (x4, y4, z4) = (x2 * x2, y2 * y2, z2 * z2);
        let k3 = x2 + z2;
        let k1 = x4 + y4 + z4 - 6.0 * y2 * z2 - 6.0 * x2 * y2 + 2.0 * z2 * x2;
        let k4 = x2 - y2 + z2;
        let ny = c[1] - 16.0 * y2 * k3 * k4 * k4 + k1 * k1;
        // On the polar axis the x and z terms vanish (they are O(√k3)), but the formula
        // divides by k3^3.5 there.
        let (nx, nz) = if k3 > 1e-40 {
            let k2 = 1.0 / (k3 * k3 * k3 * k3 * k3 * k3 * k3).sqrt();
            (
                c[0] + 64.0 * x * y * z * (x2 - z2) * k4 * (x4 - 6.0 * x2 * z2 + z4) * k1 * k2,
                c[2] - 8.0
                    * y
                    * k4
                    * (x4 * x4 - 28.0 * x4 * x2 * z2 + 70.0 * x4 * z4 - 28.0 * x2 * z2 * z4
                        + z4 * z4)
                    * k1
                    * k2,
            )
        } else {
            (c[0], c[2])
        };
        (x, y, z) = (nx, ny, nz);
        r2 = x * x + y * y + z * z;
    }
    if r2 <= BAILOUT_SQUARED || !r2.is_finite() {
        return 0.0;
    }
    let r = r2.sqrt();
    0.5 * r.ln() * r / dr
}

fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A value in [0, 1) from the top 53 bits.
fn unit(bits: u64) -> f64 {
    (bits >> 11) as f64 / (1u64 << 53) as f64
}

/// The six tetrahedra of a cube, by corner (bit 0: +x, bit 1: +y, bit 2: +z): the monotone
/// paths from corner 0 to corner 7, each listed in positive orientation. Every edge joins a
/// corner to a superset corner, so it is a grid edge from its lower end in direction 1 ..= 7.
pub(crate) const TETRAHEDRA: [[u8; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 5, 1, 7],
    [0, 6, 4, 7],
    [0, 3, 2, 7],
];

const NO_VERTEX: u32 = u32::MAX;

/// The triangles of one tetrahedron, as pairs of tetrahedron-local corners whose edges they
/// cut, wound so the normal points to the outside (field ≥ 0). `inside` has bit `c` set when
/// corner `c` is inside. Orientation follows from the tetrahedron's: for a positive
/// tetrahedron (a, b, c, d), any even permutation is positive, and (i, i^1, i^2, i^3) is one
/// for every i, so the triangle cut around a lone inside corner i is (i-i^1, i-i^2, i-i^3).
pub(crate) fn tetrahedron_cut(inside: u8) -> ([[(u8, u8); 3]; 2], usize) {
    let none = [[(0, 0); 3]; 2];
    let lone = |i: u8, flip: bool| {
        let t = [(i, i ^ 1), (i, i ^ 2), (i, i ^ 3)];
        if flip {
            [t[0], t[2], t[1]]
        } else {
            t
        }
    };
    match inside.count_ones() {
        1 => ([lone(inside.trailing_zeros() as u8, false), none[1]], 1),
        3 => (
            [lone((!inside & 15).trailing_zeros() as u8, true), none[1]],
            1,
        ),
        2 => {
            let i = inside.trailing_zeros() as u8;
            let j = (inside & !(1 << i)).trailing_zeros() as u8;
            // (i, j, k, l) is an even permutation; the quad i-k, i-l, j-l, j-k then faces
            // from {i, j} towards {k, l}.
            let next = |m: u8| m % 3 + 1;
            let m = i ^ j;
            let (k, l) = (i ^ next(m), i ^ next(next(m)));
            let (ik, il, jl, jk) = ((i, k), (i, l), (j, l), (j, k));
            ([[ik, il, jl], [ik, jl, jk]], 2)
        }
        _ => (none, 0),
    }
}

/// Cuts slabs of cells and remembers the vertices on the grid edges of the plane between the
/// current slab and the next.
struct SlabCutter {
    points: usize,
    /// Vertices on the in-plane edges (directions x, y, x+y) of the slab's lower plane,
    /// relative to `base_lo`, and of its upper plane, relative to `base_hi`.
    lo_edges: [Vec<u32>; 3],
    hi_edges: [Vec<u32>; 3],
    /// Vertices on the edges from the lower to the upper plane (z, x+z, y+z, x+y+z),
    /// relative to `base_hi`.
    cross: [Vec<u32>; 4],
    base_lo: u64,
    base_hi: u64,
    /// The slab's new vertices in index order, and its faces.
    vertices: Vec<[f32; 3]>,
    faces: Vec<[u64; 3]>,
    /// The most vertices plus faces held for one slab.
    peak: usize,
}

impl SlabCutter {
    fn new(points: usize) -> SlabCutter {
        let plane = || vec![NO_VERTEX; points * points];
        SlabCutter {
            points,
            lo_edges: [plane(), plane(), plane()],
            hi_edges: [plane(), plane(), plane()],
            cross: [plane(), plane(), plane(), plane()],
            base_lo: 1,
            base_hi: 1,
            vertices: Vec::new(),
            faces: Vec::new(),
            peak: 0,
        }
    }

    /// Cuts the cells between planes `k` and `k + 1` and writes their vertices and faces.
    fn cut(
        &mut self,
        grid: &Grid,
        k: u32,
        lo: &[f32],
        hi: &[f32],
        obj: &mut ObjWriter,
    ) -> Result<u64, GenError> {
        if k > 0 {
            std::mem::swap(&mut self.lo_edges, &mut self.hi_edges);
            for e in self.hi_edges.iter_mut().chain(&mut self.cross) {
                e.fill(NO_VERTEX);
            }
            self.base_lo = self.base_hi;
        }
        self.base_hi = obj.vertex_count() + 1;
        let p = self.points;
        let cells = p - 1;
        let field = |corner: u8, x: usize, y: usize| -> f32 {
            let at = (y + usize::from(corner >> 1 & 1)) * p + x + usize::from(corner & 1);
            let plane = if corner & 4 == 0 { lo } else { hi };
            plane.get(at).copied().unwrap_or(0.0)
        };
        for y in 0..cells {
            for x in 0..cells {
                let values: [f32; 8] = std::array::from_fn(|c| field(c as u8, x, y));
                let inside = values.iter().filter(|v| **v < 0.0).count();
                if inside == 0 || inside == 8 {
                    continue;
                }
                let cell = Cell {
                    grid,
                    k,
                    x,
                    y,
                    values: &values,
                };
                for tet in TETRAHEDRA {
                    let mut mask = 0u8;
                    for (bit, &c) in tet.iter().enumerate() {
                        if values.get(usize::from(c)).is_some_and(|v| *v < 0.0) {
                            mask |= 1 << bit;
                        }
                    }
                    let (tris, count) = tetrahedron_cut(mask);
                    for tri in tris.iter().take(count) {
                        let mut face = [0u64; 3];
                        for (slot, &(a, b)) in face.iter_mut().zip(tri) {
                            let (ca, cb) = (tet[usize::from(a)], tet[usize::from(b)]);
                            *slot = self.edge_vertex(&cell, ca & cb, ca ^ cb)?;
                        }
                        self.faces.push(face);
                    }
                }
            }
        }
        self.peak = self.peak.max(self.vertices.len() + self.faces.len());
        for v in self.vertices.drain(..) {
            obj.vertex(v)?;
        }
        let faces = self.faces.len() as u64;
        for f in self.faces.drain(..) {
            obj.face(f)?;
        }
        Ok(faces)
    }

    /// The index of the vertex on the edge of `cell` from its corner `from` in direction
    /// `dir`, created on first use.
    fn edge_vertex(&mut self, cell: &Cell, from: u8, dir: u8) -> Result<u64, GenError> {
        let Cell {
            grid,
            k,
            x,
            y,
            values,
        } = *cell;
        let (gx, gy) = (x + usize::from(from & 1), y + usize::from(from >> 1 & 1));
        let at = gy * self.points + gx;
        let (slot, base) = if dir & 4 != 0 {
            (
                self.cross
                    .get_mut(usize::from(dir - 4))
                    .and_then(|e| e.get_mut(at)),
                self.base_hi,
            )
        } else if from & 4 == 0 {
            (
                self.lo_edges
                    .get_mut(usize::from(dir.wrapping_sub(1)))
                    .and_then(|e| e.get_mut(at)),
                self.base_lo,
            )
        } else {
            (
                self.hi_edges
                    .get_mut(usize::from(dir.wrapping_sub(1)))
                    .and_then(|e| e.get_mut(at)),
                self.base_hi,
            )
        };
        let slot =
            slot.ok_or_else(|| GenError::TooLarge("internal: a grid edge out of range".into()))?;
        if *slot != NO_VERTEX {
            return Ok(base + u64::from(*slot));
        }
        let index = self.base_hi + self.vertices.len() as u64;
        *slot = u32::try_from(index - base)
            .ok()
            .filter(|&r| r != NO_VERTEX)
            .ok_or_else(|| {
                GenError::TooLarge("over 4 billion vertices in two slabs of the grid".into())
            })?;
        let value = |c: u8| f64::from(values.get(usize::from(c)).copied().unwrap_or(0.0));
        let (f0, f1) = (value(from), value(from | dir));
        let t = f0 / (f0 - f1);
        let gz = k + u32::from(from >> 2 & 1);
        let p0 = grid.point(gx, gy, gz);
        let step = [dir & 1, dir >> 1 & 1, dir >> 2 & 1].map(|b| f64::from(b) * grid.h);
        self.vertices
            .push([0, 1, 2].map(|a| (p0[a] + t * step[a]) as f32));
        Ok(index)
    }
}

/// A grid cell being cut: the cell at (`x`, `y`) between planes `k` and `k + 1`, and the field
/// at its eight corners (bit 0 x, bit 1 y, bit 2 z).
#[derive(Clone, Copy)]
struct Cell<'a> {
    grid: &'a Grid,
    k: u32,
    x: usize,
    y: usize,
    values: &'a [f32; 8],
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }

    fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }

    fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    fn corner(c: u8) -> [f64; 3] {
        [c & 1, c >> 1 & 1, c >> 2 & 1].map(f64::from)
    }

    #[test]
    fn the_tetrahedra_are_positive_and_fill_the_cube() {
        let mut volume = 0.0;
        for t in TETRAHEDRA {
            let p = t.map(corner);
            let det = dot(sub(p[1], p[0]), cross(sub(p[2], p[0]), sub(p[3], p[0])));
            // Each is a sixth of the unit cube: determinant 1.
            assert_eq!(det, 1.0, "{t:?}");
            volume += det;
            for a in 0..4 {
                for b in 0..4 {
                    // Every edge joins a corner to a superset corner: a grid edge.
                    let (ca, cb) = (t[a], t[b]);
                    assert!(ca & cb == ca || ca & cb == cb, "{t:?}");
                }
            }
        }
        assert_eq!(volume, 6.0);
    }

    #[test]
    fn every_cut_faces_the_outside() {
        // A positive tetrahedron and values of every sign pattern at several magnitudes.
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        for mask in 0u8..16 {
            for scale in [0.1, 1.0, 7.0] {
                let f: [f64; 4] = std::array::from_fn(|c| {
                    let m = scale * (1.0 + c as f64 * 0.37);
                    if mask >> c & 1 == 1 {
                        -m
                    } else {
                        m
                    }
                });
                let (tris, count) = tetrahedron_cut(mask);
                let expected = match mask.count_ones() {
                    0 | 4 => 0,
                    2 => 2,
                    _ => 1,
                };
                assert_eq!(count, expected, "mask {mask:04b}");
                let at = |(a, b): (u8, u8)| {
                    let (a, b) = (usize::from(a), usize::from(b));
                    assert!((f[a] < 0.0) != (f[b] < 0.0), "mask {mask:04b} edge {a}-{b}");
                    let t = f[a] / (f[a] - f[b]);
                    [0, 1, 2].map(|k| p[a][k] + t * (p[b][k] - p[a][k]))
                };
                let centroid = |inside: bool| {
                    let pts: Vec<[f64; 3]> = (0..4)
                        .filter(|&c| (f[c] < 0.0) == inside)
                        .map(|c| p[c])
                        .collect();
                    let n = pts.len() as f64;
                    [0, 1, 2].map(|k| pts.iter().map(|q| q[k]).sum::<f64>() / n)
                };
                if count == 0 {
                    continue;
                }
                let out = sub(centroid(false), centroid(true));
                for tri in tris.iter().take(count) {
                    let q = tri.map(at);
                    let n = cross(sub(q[1], q[0]), sub(q[2], q[0]));
                    assert!(dot(n, out) > 0.0, "mask {mask:04b} {tri:?}");
                }
            }
        }
    }

    #[test]
    fn the_field_is_negative_inside_and_positive_far_away() {
        let grid = Grid::new(64, 0);
        assert!(distance_estimate([0.0, 0.0, 0.0]) - grid.iso < 0.0);
        assert!(distance_estimate([0.0, 0.3, 0.0]) - grid.iso < 0.0);
        for p in [
            [1.3, 0.0, 0.0],
            [0.0, -1.3, 0.0],
            [0.8, 0.8, 0.8],
            [0.0, 0.0, 0.0001],
        ] {
            let d = distance_estimate(p);
            assert!(
                d.is_finite() && (p == [0.0, 0.0, 0.0001] || d > grid.iso),
                "{p:?}: {d}"
            );
        }
        // The polar axis, where the polynomial step would divide by zero.
        assert!(distance_estimate([0.0, 1.1, 0.0]).is_finite());
        assert!(distance_estimate([0.0, 2.0, 0.0]) > 0.0);
    }

    #[test]
    fn the_calibration_is_monotonic_and_reproduces_its_table() {
        for (n, t) in CALIBRATION {
            assert_eq!(resolution_for(t), n);
        }
        let mut last = 0;
        for t in (0..40).map(|e| 1u64 << e) {
            let n = resolution_for(t);
            assert!(n >= last, "{t}: {n} < {last}");
            last = n;
        }
        assert_eq!(resolution_for(0), MIN_RESOLUTION);
        assert_eq!(resolution_for(u64::MAX), MAX_RESOLUTION);
    }

    #[test]
    fn a_slab_holds_only_its_own_vertices_and_faces() -> Result<(), String> {
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        let path = dir.path().join("m.obj");
        let opts = MandelbulbOptions {
            resolution: Some(48),
            ..MandelbulbOptions::default()
        };
        let mut calls = Vec::new();
        let (report, peak) =
            generate(&path, &opts, &mut |d, t| calls.push((d, t))).map_err(|e| e.to_string())?;
        assert_eq!(calls.len(), 48);
        assert_eq!(calls.last(), Some(&(48, 48)));
        // One slab of 48 holds a small share of the model; the whole model would be 1.5× the
        // triangle count.
        let whole = (report.vertices + report.triangles) as usize;
        assert!(peak > 0 && peak * 10 < whole, "peak {peak}, whole {whole}");
        Ok(())
    }

    #[test]
    fn bad_resolutions_are_refused() {
        let dir = tempfile::tempdir();
        let Ok(dir) = dir else { return };
        for n in [0, 3, MIN_RESOLUTION - 1, MAX_RESOLUTION + 1] {
            let opts = MandelbulbOptions {
                resolution: Some(n),
                ..MandelbulbOptions::default()
            };
            let r = write_obj(&dir.path().join("x.obj"), &opts, &mut |_, _| {});
            assert!(matches!(r, Err(GenError::Option(_))), "{n}");
        }
        assert!(!dir.path().join("x.obj").exists());
    }
}
