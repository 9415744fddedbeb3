//! Ray sampling of one LOD node: rays from outside its cell, through its faces, against its
//! own subtree; the first hit of each ray is what a viewer on that side sees.

use oocfmt::records::{Footprint, Sample, Voxel, PROXY_DIRECTIONS};

use super::sequence;
use crate::kdtree::NodeId;
use crate::raycast::{
    clip_to_box, cross, dot, first_hit_of, normalise, sub, Hit, Prepared, Ray, Tracer, PACKET_MAX,
};
use oocfmt_meshio::mesh::{Bounds, Mesh};

/// Rays per voxel face: one per `TRIANGLES_PER_FACE_RAY` subtree triangles, clamped to
/// `MIN ..= BASE`, then four times as many, up to `MAX`, while the rays so far leave the
/// face's sample uncertain: a standard error of its mean normal, colour or coverage above half
/// the one-sample threshold. Coverage counts: a comb of strips looks the same on every hit.
/// Small subtrees get few rays: the lowest LOD levels hold most LOD nodes, and a handful of
/// triangles shows little detail anyway.
pub const FACE_RAYS_MIN: usize = 4;
/// The most rays per face in the first round; a face whose mean is still uncertain after them
/// gets more, up to [`FACE_RAYS_MAX`].
pub const FACE_RAYS_BASE: usize = 16;
/// The most rays per face in all: uncertain faces, and every face of an out-of-core node,
/// whose ray sequence must be fixed before any ray is answered. A coverage of ½ measured by
/// this many unstratified rays has a standard error of 1/32.
pub const FACE_RAYS_MAX: usize = 256;
/// Subtree triangles per face ray in the first round (see [`FACE_RAYS_MIN`]).
pub const TRIANGLES_PER_FACE_RAY: usize = 8;
/// Rays per diagonal proxy direction: one per `TRIANGLES_PER_DIAGONAL_RAY` subtree triangles,
/// at most `MAX`. Subtrees too small for `MIN` rays blend the samples of the two or three
/// faces the direction looks through instead, weighted by their visible projected areas. The
/// six axis directions always reuse the face rays.
pub const DIAGONAL_RAYS_MIN: usize = 2;
/// The most rays per diagonal proxy direction.
pub const DIAGONAL_RAYS_MAX: usize = 16;
/// Subtree triangles per diagonal ray (see [`DIAGONAL_RAYS_MIN`]).
pub const TRIANGLES_PER_DIAGONAL_RAY: usize = 24;

/// What a ray sees: the normal turned to face it, the mesh's own normal, and the colour.
pub type Shade = ([f64; 3], [f64; 3], [f64; 3]);

/// What a ray sees and the part of the triangle it hits (0 in a scene without part ids).
pub type Seen = (Shade, u32);

/// Answers a ray `(ray, t1, eps)` from elsewhere: the shaded first hit in `0 ..= t1`, and its
/// part.
pub type Oracle<'t> = &'t mut dyn FnMut(&Ray, f64, f64) -> Option<Seen>;

/// What the rays of one node are tested against.
pub(super) enum Target<'t> {
    /// A small subtree's triangles, each tested: cheaper than traversing the subtree.
    Each(&'t [Prepared]),
    /// The subtree under this node, traversed.
    Subtree(NodeId),
    /// A subtree not in memory (out-of-core builds): its rays are recorded, traced part by
    /// part, and answered afterwards.
    Oracle(Oracle<'t>),
}

/// What the hits of one face or direction add up to.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Acc {
    rays: u32,
    hits: u32,
    /// Unit normals turned to face the ray, summed.
    facing: [f64; 3],
    /// Unit normals as the mesh orients them, summed.
    raw: [f64; 3],
    colour: [f64; 3],
    /// Squares of the facing normals' and colours' components, summed (for the spread).
    squares: [f64; 6],
}

impl Acc {
    fn add(&mut self, facing: [f64; 3], raw: [f64; 3], colour: [f64; 3]) {
        self.hits += 1;
        for a in 0..3 {
            self.facing[a] += facing[a];
            self.raw[a] += raw[a];
            self.colour[a] += colour[a];
            self.squares[a] += facing[a] * facing[a];
            self.squares[3 + a] += colour[a] * colour[a];
        }
    }

    /// The largest standard deviation of a facing-normal component or colour channel.
    fn spread(&self) -> f64 {
        if self.hits < 2 {
            return 0.0;
        }
        let h = f64::from(self.hits);
        let means = [self.facing, self.colour].concat();
        means
            .iter()
            .zip(&self.squares)
            .map(|(&s, &q)| (q / h - (s / h) * (s / h)).max(0.0).sqrt())
            .fold(0.0, f64::max)
    }

    /// The largest standard error of the sample's means (normal and colour, over the hits)
    /// and of its coverage (a share of the rays).
    fn standard_error(&self) -> f64 {
        let c = self.coverage();
        let of_means = self.spread() / f64::from(self.hits.max(1)).sqrt();
        let of_coverage = (c * (1.0 - c)).sqrt() / f64::from(self.rays.max(1)).sqrt();
        of_means.max(of_coverage)
    }

    fn mean_colour(&self) -> [f32; 3] {
        let h = f64::from(self.hits.max(1));
        self.colour.map(|c| (c / h) as f32)
    }

    /// The sample as seen along the rays, or `None` without hits.
    fn facing_sample(&self) -> Option<Sample> {
        (self.hits > 0).then(|| Sample::pack(self.facing.map(|c| c as f32), self.mean_colour()))
    }

    /// σ: the length of the mean facing unit normal (spec §5.1), 1 without hits.
    fn shade(&self) -> f64 {
        if self.hits == 0 {
            return 1.0;
        }
        dot(self.facing, self.facing).sqrt() / f64::from(self.hits)
    }

    /// α: the share of the rays that hit (0 when none were cast).
    fn coverage(&self) -> f64 {
        f64::from(self.hits) / f64::from(self.rays.max(1))
    }
}

/// Ray tracing state for one LOD node.
pub(super) struct NodeSampler<'a, 'b> {
    pub mesh: &'a Mesh,
    pub tracer: &'b mut Tracer<'a>,
    pub target: Target<'b>,
    pub cell: Bounds,
    /// Distinct triangles in the subtree: sets the ray counts.
    pub triangles: usize,
    pub threshold: f32,
    /// Whether to sample the twelve diagonal proxy directions (only proxied nodes need them).
    pub diagonals: bool,
    /// Cast the most rays everywhere, whatever the hits say: the ray sequence is then fixed in
    /// advance, as an [`Target::Oracle`] that records rays before answering them needs.
    pub force_max: bool,
    /// Cast more face rays where a face's standard error is above half the voxel threshold.
    /// Voxels want it; a file without voxels samples faces only for proxies, which stand in
    /// until their block arrives and keep the base count, as their diagonals do.
    pub refine: bool,
    /// Count the parts the face rays hit (the mesh's part ids, or the oracle's answers): the
    /// entry's part word is the one hit most.
    pub count_parts: bool,
}

/// Where a node's rays start: the cell's low corner and extent in f64, and the tolerance of
/// hits behind a ray's start.
struct Frame {
    lo: [f64; 3],
    ext: [f64; 3],
    eps: f64,
    /// Each face's scramble of the ray pattern ([`sequence::seed`]).
    seeds: [u64; 6],
}

impl Frame {
    /// The area of face `f` (faces in pairs per axis).
    fn face_area(&self, f: usize) -> f64 {
        let a = f / 2;
        self.ext[(a + 1) % 3] * self.ext[(a + 2) % 3]
    }
}

/// The voxel (`None` when no ray hit anything), the 18 proxy samples of a node, and the part
/// most face rays hit (`None` without hits or without counting).
pub(super) struct Sampled {
    pub voxel: Option<Voxel>,
    pub proxy: [Sample; 18],
    pub part: Option<u32>,
}

/// The part most often named in `votes` (ties: the lowest id); `None` for no votes. Sorting
/// makes it independent of the order the hits came in.
pub(crate) fn majority(votes: &mut [u32]) -> Option<u32> {
    votes.sort_unstable();
    let mut best: Option<(u32, usize)> = None;
    for run in votes.chunk_by(|a, b| a == b) {
        if let Some(&part) = run.first() {
            if best.is_none_or(|(_, n)| run.len() > n) {
                best = Some((part, run.len()));
            }
        }
    }
    best.map(|(part, _)| part)
}

impl NodeSampler<'_, '_> {
    pub fn run(&mut self) -> Sampled {
        let lo = self.cell.min.map(f64::from);
        let ext: [f64; 3] = std::array::from_fn(|a| f64::from(self.cell.max[a]) - lo[a]);
        let diag = dot(ext, ext).sqrt();
        let scale = self
            .cell
            .min
            .iter()
            .chain(&self.cell.max)
            .fold(0.0f64, |m, &c| m.max(f64::from(c).abs()));
        // Rays start on the cell's boundary, often on a surface lying in it: allow hits a
        // rounding error behind the start.
        let eps = 1e-9 * (diag + scale);
        let seeds = std::array::from_fn(|f| sequence::seed(f, self.cell.min, self.cell.max));
        let frame = Frame {
            lo,
            ext,
            eps,
            seeds,
        };
        let face_area = |f: usize| frame.face_area(f);

        let mut faces = [Acc::default(); 6];
        let mut votes = Vec::new();
        let base = if self.force_max {
            FACE_RAYS_MAX
        } else {
            (self.triangles / TRIANGLES_PER_FACE_RAY).clamp(FACE_RAYS_MIN, FACE_RAYS_BASE)
        };
        for (f, acc) in faces.iter_mut().enumerate() {
            if face_area(f) <= 0.0 {
                continue;
            }
            let a = f / 2;
            let mut dir = [0.0; 3];
            dir[a] = if f % 2 == 0 { 1.0 } else { -1.0 };
            self.cast_face(acc, f, dir, 0..base, &frame, &mut votes);
            // More rays where the standard error could move the sample by half the one-sample
            // threshold.
            let mut cast = base;
            while self.refine
                && (FACE_RAYS_BASE..FACE_RAYS_MAX).contains(&cast)
                && acc.standard_error() > f64::from(self.threshold) / 2.0
            {
                let more = (4 * cast).min(FACE_RAYS_MAX);
                self.cast_face(acc, f, dir, cast..more, &frame, &mut votes);
                cast = more;
            }
        }
        let areas: [f64; 6] = std::array::from_fn(face_area);

        let mut proxy = [Sample::EMPTY; 18];
        for (p, acc) in proxy.iter_mut().zip(&faces) {
            *p = acc.facing_sample().unwrap_or(Sample::EMPTY);
        }
        let rays = if self.force_max {
            DIAGONAL_RAYS_MAX
        } else {
            (self.triangles / TRIANGLES_PER_DIAGONAL_RAY).min(DIAGONAL_RAYS_MAX)
        };
        let diagonals = if self.diagonals { 12 } else { 0 };
        for (p, d) in proxy
            .iter_mut()
            .zip(PROXY_DIRECTIONS)
            .skip(6)
            .take(diagonals)
        {
            let dir = normalise(d.map(f64::from));
            *p = if rays < DIAGONAL_RAYS_MIN {
                blend(&faces, &areas, dir)
            } else {
                let acc = self.cast_direction(dir, rays, &frame);
                acc.facing_sample().unwrap_or(Sample::EMPTY)
            };
        }

        Sampled {
            voxel: voxel(&faces, &areas, self.threshold),
            proxy,
            part: majority(&mut votes),
        }
    }

    /// Casts rays `range` of face `f`'s sequence ([`sequence`]) straight through the cell;
    /// the part of each hit goes to `votes` when parts are counted.
    fn cast_face(
        &mut self,
        acc: &mut Acc,
        f: usize,
        dir: [f64; 3],
        range: std::ops::Range<usize>,
        frame: &Frame,
        votes: &mut Vec<u32>,
    ) {
        let (ext, eps) = (&frame.ext, frame.eps);
        if let Target::Subtree(node) = self.target {
            // A face's rays share their direction and starting plane: traced together.
            for part in range.clone().step_by(PACKET_MAX) {
                let end = (part + PACKET_MAX).min(range.end);
                let mut rays = [Ray::new([0.0; 3], dir); PACKET_MAX];
                let mut hits = [None; PACKET_MAX];
                let n = end - part;
                for (ray, i) in rays.iter_mut().zip(part..end) {
                    *ray = Ray::new(face_point(f, i, frame), dir);
                }
                let (rays, hits) = (&rays[..n], &mut hits[..n]);
                self.tracer
                    .first_hits_along(node, rays, ext[f / 2], eps, hits);
                for hit in hits.iter() {
                    acc.rays += 1;
                    let Some(h) = hit else { continue };
                    if let Some((facing, raw, colour)) = self.shade(h, dir) {
                        acc.add(facing, raw, colour);
                        if self.count_parts {
                            votes.push(self.part_of(h.triangle));
                        }
                    }
                }
            }
            return;
        }
        for i in range {
            let origin = face_point(f, i, frame);
            let ray = Ray::new(origin, dir);
            acc.rays += 1;
            if let (Some(part), true) = (self.trace(acc, &ray, ext[f / 2], eps), self.count_parts) {
                votes.push(part);
            }
        }
    }

    /// The part of mesh triangle `t` (0 without part ids).
    fn part_of(&self, t: u32) -> u32 {
        self.mesh
            .part_ids
            .as_ref()
            .and_then(|ids| ids.get(t as usize))
            .copied()
            .unwrap_or(0)
    }

    /// Casts `rays` rays along `dir` from the faces it enters through, spread over them in
    /// proportion to their projected areas, so they cover the cell's silhouette evenly.
    fn cast_direction(&mut self, dir: [f64; 3], rays: usize, frame: &Frame) -> Acc {
        let eps = frame.eps;
        let mut acc = Acc::default();
        // Face f's outward normal is −axis for even f, +axis for odd f; it is entered by a
        // ray whose direction points against that normal.
        let weights: [f64; 6] = std::array::from_fn(|f| {
            let facing = -outward(f) * dir[f / 2];
            if facing > 0.0 {
                frame.face_area(f) * facing
            } else {
                0.0
            }
        });
        let total: f64 = weights.iter().sum();
        if total <= 0.0 {
            return acc;
        }
        let mut used = [0usize; 6];
        for i in 0..rays {
            let target = (i as f64 + 0.5) / rays as f64 * total;
            let mut f = 5;
            let mut cumulative = 0.0;
            for (k, w) in weights.iter().enumerate() {
                cumulative += w;
                if *w > 0.0 && target < cumulative {
                    f = k;
                    break;
                }
            }
            let Some(n) = used.get_mut(f) else { continue };
            let origin = face_point(f, *n, frame);
            *n += 1;
            let ray = Ray::new(origin, dir);
            acc.rays += 1;
            let cell = self.cell;
            let Some((_, t1)) = clip_to_box(&ray, &cell) else {
                continue;
            };
            self.trace(&mut acc, &ray, t1.max(0.0), eps);
        }
        acc
    }

    /// What a ray along `dir` sees at `hit`, the corners taken from the tracer's table.
    fn shade(&self, hit: &Hit, dir: [f64; 3]) -> Option<Shade> {
        shade_at(self.mesh, hit, self.tracer.corners(hit.triangle)?, dir)
    }

    /// Traces one ray into `acc`; returns the part of what it hit.
    fn trace(&mut self, acc: &mut Acc, ray: &Ray, t1: f64, eps: f64) -> Option<u32> {
        let seen = match &mut self.target {
            Target::Each(triangles) => first_hit_of(triangles, ray, 0.0, t1, eps)
                .and_then(|hit| Some((self.shade(&hit, ray.dir)?, self.part_of(hit.triangle)))),
            Target::Subtree(node) => {
                let hit = self.tracer.first_hit(*node, ray, 0.0, t1, eps);
                hit.and_then(|hit| Some((self.shade(&hit, ray.dir)?, self.part_of(hit.triangle))))
            }
            Target::Oracle(answer) => answer(ray, t1, eps),
        };
        let ((facing, raw, colour), part) = seen?;
        acc.add(facing, raw, colour);
        Some(part)
    }
}

/// Face `f`'s outward normal component along its axis: −1 for even `f`, +1 for odd.
fn outward(f: usize) -> f64 {
    if f % 2 == 0 {
        -1.0
    } else {
        1.0
    }
}

/// What a ray along `dir` sees, from the samples of the faces it enters through: their mean
/// normals and colours weighted by each face's projected area times the share of its rays
/// that hit. [`Sample::EMPTY`] when none of those faces saw anything.
fn blend(faces: &[Acc; 6], areas: &[f64; 6], dir: [f64; 3]) -> Sample {
    let (mut normal, mut colour, mut total) = ([0.0f64; 3], [0.0f64; 3], 0.0f64);
    for (f, acc) in faces.iter().enumerate() {
        let facing = -outward(f) * dir[f / 2];
        if facing <= 0.0 || acc.hits == 0 {
            continue;
        }
        let w = areas[f] * facing * f64::from(acc.hits) / f64::from(acc.rays.max(1));
        let n = normalise(acc.facing);
        let c = acc.mean_colour();
        for a in 0..3 {
            normal[a] += w * n[a];
            colour[a] += w * f64::from(c[a]);
        }
        total += w;
    }
    if total <= 0.0 {
        return Sample::EMPTY;
    }
    Sample::pack(normal.map(|c| c as f32), colour.map(|c| (c / total) as f32))
}

/// Point `i` of face `f`'s scrambled sequence on the frame's cell `lo + [0, ext]`.
fn face_point(f: usize, i: usize, frame: &Frame) -> [f64; 3] {
    let (lo, ext) = (&frame.lo, &frame.ext);
    let a = f / 2;
    let (u, v) = ((a + 1) % 3, (a + 2) % 3);
    let seed = frame.seeds.get(f).copied().unwrap_or(0);
    let [hu, hv] = sequence::point(i as u64, seed);
    let mut o = *lo;
    if f % 2 == 1 {
        o[a] += ext[a];
    }
    o[u] += hu * ext[u];
    o[v] += hv * ext[v];
    o
}

/// The normal turned to face a ray along `dir`, the mesh's own normal, and the colour at a hit.
/// Normals are the interpolated vertex normals when the mesh has them, else the geometric one.
pub(crate) fn shade(mesh: &Mesh, hit: &Hit, dir: [f64; 3]) -> Option<Shade> {
    shade_at(mesh, hit, mesh.corners(hit.triangle as usize)?, dir)
}

/// [`shade`] given the hit triangle's corners, which a tracer has at hand: the mesh's own
/// vertex arrays are then read only for normals and colours.
fn shade_at(mesh: &Mesh, hit: &Hit, corners: [[f32; 3]; 3], dir: [f64; 3]) -> Option<Shade> {
    let t = hit.triangle as usize;
    let p = corners.map(|c| c.map(f64::from));
    let w = [1.0 - hit.u - hit.v, hit.u, hit.v];
    let geometric = normalise(cross(sub(p[1], p[0]), sub(p[2], p[0])));
    let idx = match (&mesh.normals, &mesh.colours) {
        (None, None) => [0; 3],
        _ => *mesh.triangles.get(t)?,
    };
    let interpolated = mesh.normals.as_ref().map(|ns| {
        let mut sum = [0.0; 3];
        for (&v, &wk) in idx.iter().zip(&w) {
            if let Some(n) = ns.get(v as usize) {
                for a in 0..3 {
                    sum[a] += wk * f64::from(n[a]);
                }
            }
        }
        normalise(sum)
    });
    let raw = match interpolated {
        Some(n) if dot(n, n) > 0.0 => n,
        _ => geometric,
    };
    let facing = if dot(raw, dir) > 0.0 {
        raw.map(|c| -c)
    } else {
        raw
    };
    let colour = match &mesh.colours {
        Some(cs) => {
            let mut sum = [0.0; 3];
            for (&v, &wk) in idx.iter().zip(&w) {
                if let Some(c) = cs.get(v as usize) {
                    for a in 0..3 {
                        sum[a] += wk * f64::from(c[a]) / 255.0;
                    }
                }
            }
            sum
        }
        None => super::material_colour(mesh, t),
    };
    Some((facing, raw, colour))
}

/// The voxel from the six faces' hits, `None` when no face saw anything.
///
/// Each face's sample shows the surface turned towards that face's rays, with its footprint:
/// the share of the rays that hit and the length of their mean normal (spec §5.1). Whether one
/// sample will do is decided on the normals brought to one orientation first: a flat patch
/// looks the same from its front and its back, and a renderer turns the normal towards the
/// viewer anyway; only with all six agreeing (shade and coverage included) is it stored once,
/// oriented as the mesh orients it.
fn voxel(faces: &[Acc; 6], areas: &[f64; 6], threshold: f32) -> Option<Voxel> {
    let hits: u32 = faces.iter().map(|f| f.hits).sum();
    if hits == 0 {
        return None;
    }
    let units: [[f64; 3]; 6] = std::array::from_fn(|f| normalise(faces[f].facing));
    let raw: [f64; 3] = std::array::from_fn(|a| faces.iter().map(|f| f.raw[a]).sum());
    // Visible area through each face: its area times the share of its rays that hit.
    let weights: [f64; 6] = std::array::from_fn(|f| areas[f] * faces[f].coverage());
    let heaviest = (0..6).fold(0, |b, f| if weights[f] > weights[b] { f } else { b });
    let reference = if dot(raw, raw).sqrt() > 1e-9 * f64::from(hits) {
        raw
    } else {
        units[heaviest]
    };
    let aligned: [[f64; 3]; 6] = std::array::from_fn(|f| {
        if dot(units[f], reference) < 0.0 {
            units[f].map(|c| -c)
        } else {
            units[f]
        }
    });
    let weight_sum: f64 = weights.iter().sum();
    let (mut normal, mut colour, mut shade) = ([0.0f64; 3], [0.0f64; 3], 0.0f64);
    for f in 0..6 {
        let acc = &faces[f];
        if acc.hits == 0 {
            continue;
        }
        // Flat cells have faces of zero area; count hits then.
        let w = if weight_sum > 0.0 {
            weights[f] / weight_sum
        } else {
            f64::from(acc.hits) / f64::from(hits)
        };
        let c = acc.mean_colour();
        for a in 0..3 {
            normal[a] += w * aligned[f][a];
            colour[a] += w * f64::from(c[a]);
        }
        shade += w * acc.shade();
    }
    // The cell's coverage seen from everywhere: the faces' coverages weighted by their areas.
    let area_sum: f64 = (0..6)
        .filter(|&f| faces[f].rays > 0)
        .map(|f| areas[f])
        .sum();
    let coverage = if area_sum > 0.0 {
        (0..6)
            .filter(|&f| faces[f].rays > 0)
            .map(|f| areas[f] * faces[f].coverage())
            .sum::<f64>()
            / area_sum
    } else {
        1.0
    };
    let mean = Sample::pack(normal.map(|c| c as f32), colour.map(|c| c as f32));
    let mean_foot = Footprint::new(shade, coverage);
    let t = f64::from(threshold);
    let agree = (0..6).filter(|&f| faces[f].rays > 0).all(|f| {
        let acc = &faces[f];
        let covered = (acc.coverage() - coverage).abs() <= t;
        covered
            && (acc.hits == 0 || {
                let s = Sample::pack(aligned[f].map(|c| c as f32), acc.mean_colour());
                super::difference(s, mean) <= threshold && (acc.shade() - shade).abs() <= t
            })
    });
    Some(if agree {
        Voxel::Single(mean, mean_foot)
    } else {
        Voxel::Six(
            std::array::from_fn(|f| faces[f].facing_sample().unwrap_or(mean)),
            std::array::from_fn(|f| {
                let acc = &faces[f];
                if acc.rays == 0 {
                    // A face of zero area casts no rays: what the others see stands for it.
                    mean_foot
                } else {
                    Footprint::new(acc.shade(), acc.coverage())
                }
            }),
        )
    })
}
