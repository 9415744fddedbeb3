//! CAD-like clutter in the manner of the Boeing 777 data: pipes routed along the axes, bundles
//! of thin cables along curves, bolts, and panels, some duplicated exactly in their plane or a
//! hair above it, all interleaved in one box, with slightly jittered vertices. It stresses
//! what real CAD exports stress: thin long triangles, overlapping coplanar surfaces, dense
//! small parts and many materials.
//!
//! Parts are made and written one at a time (memory is one part, a few thousand triangles),
//! from a seeded splitmix64 stream in a fixed order, so the same options give the same file.
//!
//! The file is an assembly two levels deep, as CAD exports are: each group of shapes made
//! together (a pipe run with its flanges, a cable bundle, a panel with its twin and bolts, a
//! row of bolts) is an object `o assembly-K`, and each shape in it a group `g KIND-N` under it
//! (the importer's part tree: assemblies of components). [`CadOptions::parts`] asks for
//! another number of parts: components are then cut or merged, never the geometry.

use std::f64::consts::TAU;
use std::path::Path;
#[cfg(test)]
use std::path::PathBuf;

use crate::rng::Rng;
pub use crate::{GenError, GenReport};
use oocfmt_meshio::obj_writer::{mtl_beside, write_mtl, AtomicFile, ObjWriter};

/// The materials, by name and diffuse colour.
pub const MATERIALS: [(&str, [f32; 3]); 8] = [
    ("pipe_steel", [0.62, 0.64, 0.66]),
    ("pipe_copper", [0.72, 0.45, 0.2]),
    ("cable_yellow", [0.9, 0.78, 0.1]),
    ("cable_red", [0.8, 0.12, 0.1]),
    ("cable_black", [0.08, 0.08, 0.08]),
    ("bolt_zinc", [0.75, 0.75, 0.7]),
    ("panel_green", [0.3, 0.55, 0.35]),
    ("panel_grey", [0.5, 0.5, 0.52]),
];
const PIPE_STEEL: usize = 0;
const CABLE_YELLOW: usize = 2;
const BOLT_ZINC: usize = 5;
const PANEL_GREEN: usize = 6;

/// Triangles per cubic unit: the box grows with the target so the clutter stays as dense.
const DENSITY: f64 = 8000.0;
/// Vertex jitter as a fraction of a part's radius (or of a panel cell, in its plane only).
const JITTER: f64 = 0.01;

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CadOptions {
    /// The exact triangle count written (the last part is cut short).
    pub triangles: u64,
    pub seed: u64,
    /// Write a normal per vertex (`vn`), as CAD exports do.
    pub normals: bool,
    /// How many parts (assemblies and components together) the file names: `None` the
    /// natural ones (one assembly per group of shapes, one component per shape), `Some(0)`
    /// none at all (no `o`/`g` lines: a scene without parts), `Some(1)` one assembly holding
    /// everything, more: about that many (exactly, unless there are fewer triangles than
    /// components asked for). The geometry is the same whatever the value.
    pub parts: Option<u64>,
}

impl Default for CadOptions {
    fn default() -> Self {
        CadOptions {
            triangles: 1_000_000,
            seed: 0,
            normals: true,
            parts: None,
        }
    }
}

/// Writes the scene to `path` and its materials to the `.mtl` beside it (both atomically).
/// `progress` gets (triangles written, triangles wanted).
pub fn write_obj(
    path: &Path,
    opts: &CadOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<GenReport, GenError> {
    generate(path, opts, progress).map(|(report, _)| report)
}

/// Writes the scene as OBJ to the stream `out` (standard output, say), named `name` in
/// errors. A stream has no folder for the `.mtl`, so it names no library: its `usemtl`
/// materials keep their names and get a reader's default colour. `progress` gets (triangles
/// written, triangles wanted).
pub fn write_obj_stream(
    out: Box<dyn std::io::Write>,
    name: &str,
    opts: &CadOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<GenReport, GenError> {
    check(opts)?;
    let obj = ObjWriter::stream(out, name);
    generate_into(obj, None, opts, progress).map(|(report, _)| report)
}

fn check(opts: &CadOptions) -> Result<(), GenError> {
    match opts.triangles {
        0 => Err(GenError::Option("a scene needs at least 1 triangle".into())),
        _ => Ok(()),
    }
}

/// [`write_obj`], also returning the most triangles one part held.
fn generate(
    path: &Path,
    opts: &CadOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(GenReport, usize), GenError> {
    check(opts)?;
    let (mtl_path, mtl_name) = mtl_beside(path)?;
    let mtl = write_mtl(&mtl_path, MATERIALS.iter().map(|&(n, c)| (n, c)))?;
    let obj = ObjWriter::create(path)?;
    generate_into(obj, Some((mtl, &mtl_name)), opts, progress)
}

/// Writes the scene to `obj`, naming the material library `mtl` (committed at the end) if any.
fn generate_into(
    mut obj: ObjWriter,
    mtl: Option<(AtomicFile, &str)>,
    opts: &CadOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(GenReport, usize), GenError> {
    obj.comment(&format!(
        "CAD-like clutter: pipes, cables, bolts and panels; {} triangles, seed {}\n\
         generated by oocfmt-build",
        opts.triangles, opts.seed
    ))?;
    if let Some((_, name)) = &mtl {
        obj.mtllib(name)?;
    }
    let labels = match opts.parts {
        None => Labels::Natural,
        Some(0) => Labels::Planned(Vec::new().into_iter().peekable()),
        Some(n) => Labels::Planned(plan_parts(&dry_run(opts)?, n).into_iter().peekable()),
    };
    let mut out = Emitter::new(Some(&mut obj), opts, labels);
    let mut scene = Scene::new(opts);
    while out.triangles < out.target {
        out.begin_group();
        scene.next_group(&mut out)?;
        progress(out.triangles, out.target);
    }
    let (triangles, peak) = (out.triangles, out.peak);
    if let Some((mtl, _)) = mtl {
        mtl.commit()?;
    }
    let stats = obj.finish()?;
    Ok((
        GenReport {
            triangles,
            vertices: stats.vertices,
            bytes: stats.bytes,
        },
        peak,
    ))
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    a.map(|c| c * s)
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn normalise(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    if l > 0.0 {
        scale(a, 1.0 / l)
    } else {
        [0.0, 0.0, 1.0]
    }
}

fn axis(a: usize) -> [f64; 3] {
    let mut v = [0.0; 3];
    if let Some(c) = v.get_mut(a) {
        *c = 1.0;
    }
    v
}

/// A unit vector perpendicular to `d`, and `d × u`: (u, v, d) is right-handed, so a ring
/// u·cos θ + v·sin θ runs counter-clockwise seen from the tip of `d`.
fn frame(d: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let least = (0..3)
        .min_by(|&a, &b| d[a].abs().total_cmp(&d[b].abs()))
        .unwrap_or(0);
    let u = normalise(cross(d, axis(least)));
    (u, cross(d, u))
}

/// One part's mesh before it is written: positions, outward normals, faces wound
/// counter-clockwise seen from outside.
struct Part {
    name: &'static str,
    material: usize,
    positions: Vec<[f64; 3]>,
    normals: Vec<[f64; 3]>,
    faces: Vec<[u32; 3]>,
    /// Jitter amplitude, and an axis left unjittered (a panel's plane stays exact).
    jitter: f64,
    exact_axis: Option<usize>,
}

impl Part {
    fn new(name: &'static str, material: usize, jitter: f64) -> Part {
        Part {
            name,
            material,
            positions: Vec::new(),
            normals: Vec::new(),
            faces: Vec::new(),
            jitter,
            exact_axis: None,
        }
    }

    fn vertex(&mut self, p: [f64; 3], n: [f64; 3]) -> u32 {
        self.positions.push(p);
        self.normals.push(n);
        (self.positions.len() - 1) as u32
    }

    /// A ring of `sides` vertices around `c` in the plane of (u, v); returns the first index.
    fn ring(&mut self, c: [f64; 3], (u, v): ([f64; 3], [f64; 3]), r: f64, sides: u32) -> u32 {
        let first = self.positions.len() as u32;
        for k in 0..sides {
            let a = TAU * f64::from(k) / f64::from(sides);
            let n = add(scale(u, a.cos()), scale(v, a.sin()));
            self.vertex(add(c, scale(n, r)), n);
        }
        first
    }

    /// The side wall between two rings, the second further along the axis.
    fn wall(&mut self, a: u32, b: u32, sides: u32) {
        for k in 0..sides {
            let k1 = (k + 1) % sides;
            self.faces.push([a + k, a + k1, b + k1]);
            self.faces.push([a + k, b + k1, b + k]);
        }
    }

    /// A flat fan closing the ring at `first` with its own vertices (a sharp edge), facing
    /// `n`; `forward` says whether `n` points along the ring's axis.
    fn cap(&mut self, c: [f64; 3], first: u32, sides: u32, n: [f64; 3], forward: bool) {
        let centre = self.vertex(c, n);
        let rim = self.positions.len() as u32;
        for k in 0..sides {
            let p = self
                .positions
                .get((first + k) as usize)
                .copied()
                .unwrap_or(c);
            self.vertex(p, n);
        }
        for k in 0..sides {
            let k1 = (k + 1) % sides;
            self.faces.push(if forward {
                [centre, rim + k, rim + k1]
            } else {
                [centre, rim + k1, rim + k]
            });
        }
    }

    /// A tube through `centres` with the given frames (tangent, u, v per ring).
    fn tube(&mut self, rings: &[([f64; 3], [f64; 3], [f64; 3])], r: f64, sides: u32, caps: bool) {
        let mut prev: Option<u32> = None;
        let mut first_ring = 0;
        for &(c, u, v) in rings {
            let ring = self.ring(c, (u, v), r, sides);
            match prev {
                Some(p) => self.wall(p, ring, sides),
                None => first_ring = ring,
            }
            prev = Some(ring);
        }
        if let (true, Some(last), Some(&(c0, u0, v0)), Some(&(c1, u1, v1))) =
            (caps, prev, rings.first(), rings.last())
        {
            self.cap(c0, first_ring, sides, scale(cross(u0, v0), -1.0), false);
            self.cap(c1, last, sides, cross(u1, v1), true);
        }
    }

    /// A straight cylinder from `a` to `b`, with rings every `step` or closer.
    fn cylinder(&mut self, a: [f64; 3], b: [f64; 3], r: f64, sides: u32, step: f64, caps: bool) {
        let d = sub(b, a);
        let len = dot(d, d).sqrt();
        let dir = normalise(d);
        let (u, v) = frame(dir);
        let sections = ((len / step).ceil() as u32).clamp(1, 16);
        let rings: Vec<_> = (0..=sections)
            .map(|s| (add(a, scale(d, f64::from(s) / f64::from(sections))), u, v))
            .collect();
        self.tube(&rings, r, sides, caps);
    }

    /// A hexagonal prism (a bolt head or nut) on `base` along unit `d`: flat faces with
    /// their own vertices.
    fn hex_prism(&mut self, base: [f64; 3], d: [f64; 3], r: f64, height: f64) {
        let frame = frame(d);
        let top = add(base, scale(d, height));
        for k in 0..6 {
            let corner = |k: u32| {
                let a = TAU * f64::from(k) / 6.0;
                scale(add(scale(frame.0, a.cos()), scale(frame.1, a.sin())), r)
            };
            let mid = TAU * (f64::from(k) + 0.5) / 6.0;
            let n = add(scale(frame.0, mid.cos()), scale(frame.1, mid.sin()));
            let (c0, c1) = (corner(k), corner(k + 1));
            let a = self.vertex(add(base, c0), n);
            self.vertex(add(base, c1), n);
            self.vertex(add(top, c1), n);
            self.vertex(add(top, c0), n);
            self.faces.push([a, a + 1, a + 2]);
            self.faces.push([a, a + 2, a + 3]);
        }
        let bottom = self.ring(base, frame, r, 6);
        self.cap(base, bottom, 6, scale(d, -1.0), false);
        let upper = self.ring(top, frame, r, 6);
        self.cap(top, upper, 6, d, true);
    }

    /// A grid of `m1 × m2` quads on the rectangle `o + [0, s1]·a1 + [0, s2]·a2` of the plane
    /// normal to world axis `normal_axis`, facing `sign` along it.
    fn panel(&mut self, o: [f64; 3], normal_axis: usize, sign: f64, s: [f64; 2], m: [u32; 2]) {
        let (a1, a2) = (axis((normal_axis + 1) % 3), axis((normal_axis + 2) % 3));
        let n = scale(axis(normal_axis), sign);
        let first = self.positions.len() as u32;
        for j in 0..=m[1] {
            for i in 0..=m[0] {
                let p = add(
                    add(o, scale(a1, s[0] * f64::from(i) / f64::from(m[0]))),
                    scale(a2, s[1] * f64::from(j) / f64::from(m[1])),
                );
                self.vertex(p, n);
            }
        }
        let at = |i: u32, j: u32| first + j * (m[0] + 1) + i;
        for j in 0..m[1] {
            for i in 0..m[0] {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                // a1 × a2 is +normal_axis.
                if sign > 0.0 {
                    self.faces.push([a, b, c]);
                    self.faces.push([a, c, d]);
                } else {
                    self.faces.push([a, c, b]);
                    self.faces.push([a, d, c]);
                }
            }
        }
        self.exact_axis = Some(normal_axis);
    }
}

/// A shape as written: the group of shapes it was made with, its kind and the faces kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Shape {
    group: u64,
    kind: &'static str,
    faces: u64,
}

/// A part line to write before face `face` of shape `shape` (both counted among the shapes
/// written): `o assembly-K` and/or `g KIND-N`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Cut {
    shape: u64,
    face: u64,
    assembly: Option<u64>,
    component: Option<(&'static str, u64)>,
}

/// Where the part lines go.
enum Labels {
    /// One assembly per group of shapes, one component per shape.
    Natural,
    /// At the cuts [`plan_parts`] chose, in order.
    Planned(std::iter::Peekable<std::vec::IntoIter<Cut>>),
}

/// Writes shapes (or, without a writer, only counts them) and keeps the counts.
struct Emitter<'a> {
    obj: Option<&'a mut ObjWriter>,
    normals: bool,
    material: Option<usize>,
    labels: Labels,
    /// Groups begun, and the group whose assembly line was written last (natural labels).
    groups: u64,
    labelled_group: u64,
    /// Shapes written: the number of the next component under natural labels.
    shapes: u64,
    /// What a dry run saw, shape by shape.
    seen: Vec<Shape>,
    triangles: u64,
    target: u64,
    peak: usize,
}

impl<'a> Emitter<'a> {
    fn new(obj: Option<&'a mut ObjWriter>, opts: &CadOptions, labels: Labels) -> Emitter<'a> {
        Emitter {
            obj,
            normals: opts.normals,
            material: None,
            labels,
            groups: 0,
            labelled_group: 0,
            shapes: 0,
            seen: Vec::new(),
            triangles: 0,
            target: opts.triangles,
            peak: 0,
        }
    }

    /// The shapes emitted next were made together: one assembly under natural labels.
    fn begin_group(&mut self) {
        self.groups += 1;
    }

    /// The part lines due before face `face` of the shape being written.
    fn labels_at(&mut self, face: u64, kind: &'static str) -> Result<(), GenError> {
        let (assembly, component) = match &mut self.labels {
            Labels::Natural if face == 0 => {
                let new = self.labelled_group != self.groups;
                self.labelled_group = self.groups;
                (new.then_some(self.groups), Some((kind, self.shapes)))
            }
            Labels::Natural => (None, None),
            Labels::Planned(cuts) => {
                match cuts.next_if(|c| c.shape + 1 == self.shapes && c.face == face) {
                    Some(c) => (c.assembly, c.component),
                    None => (None, None),
                }
            }
        };
        let Some(obj) = self.obj.as_deref_mut() else {
            return Ok(());
        };
        if let Some(k) = assembly {
            obj.object(&format!("assembly-{k}"))?;
        }
        if let Some((kind, n)) = component {
            obj.group(&format!("{kind}-{n}"))?;
        }
        Ok(())
    }

    /// Writes `part`, cut short if it would pass the target; jitters vertices from `rng`.
    fn emit(&mut self, part: &Part, rng: &mut Rng) -> Result<(), GenError> {
        let room = self.target.saturating_sub(self.triangles);
        let keep = part
            .faces
            .len()
            .min(usize::try_from(room).unwrap_or(usize::MAX));
        let faces = part.faces.get(..keep).unwrap_or_default();
        let Some(used) = faces.iter().flatten().max().map(|&m| m as usize + 1) else {
            return Ok(());
        };
        self.peak = self.peak.max(part.faces.len());
        self.shapes += 1;
        self.seen.push(Shape {
            group: self.groups,
            kind: part.name,
            faces: keep as u64,
        });
        self.labels_at(0, part.name)?;
        let change = self.material != Some(part.material);
        self.material = Some(part.material);
        let base = self.obj.as_deref().map_or(0, ObjWriter::vertex_count) + 1;
        if let (true, Some(obj)) = (change, self.obj.as_deref_mut()) {
            obj.usemtl(MATERIALS.get(part.material).map_or("", |m| m.0))?;
        }
        for p in part.positions.iter().take(used) {
            let mut q = *p;
            for (a, c) in q.iter_mut().enumerate() {
                if part.exact_axis != Some(a) {
                    *c += part.jitter * rng.range(-1.0, 1.0);
                }
            }
            if let Some(obj) = self.obj.as_deref_mut() {
                obj.vertex(q.map(|c| c as f32))?;
            }
        }
        if let (true, Some(obj)) = (self.normals, self.obj.as_deref_mut()) {
            for n in part.normals.iter().take(used) {
                obj.normal(n.map(|c| c as f32))?;
            }
        }
        for (k, f) in faces.iter().enumerate() {
            if k > 0 {
                self.labels_at(k as u64, part.name)?;
            }
            let Some(obj) = self.obj.as_deref_mut() else {
                continue;
            };
            let v = f.map(|i| base + u64::from(i));
            if self.normals {
                obj.face_normals(v, v)?;
            } else {
                obj.face(v)?;
            }
        }
        self.triangles += keep as u64;
        Ok(())
    }
}

/// The shapes the scene of `opts` writes, generated without writing them.
fn dry_run(opts: &CadOptions) -> Result<Vec<Shape>, GenError> {
    let mut out = Emitter::new(None, opts, Labels::Natural);
    let mut scene = Scene::new(opts);
    while out.triangles < out.target {
        out.begin_group();
        scene.next_group(&mut out)?;
    }
    Ok(out.seen)
}

/// The cuts that give `parts` ≥ 1 parts over `shapes`: as many assemblies as the natural
/// share of them (at least one, each with a component), the rest components. Fewer components
/// than shapes merge consecutive shapes; more cut the shapes with the most faces per piece
/// first, assemblies then staying the natural ones. Part names stay unique: assemblies and
/// components are numbered in file order.
fn plan_parts(shapes: &[Shape], parts: u64) -> Vec<Cut> {
    let c = shapes.len() as u64;
    let mut groups: Vec<u64> = shapes.iter().map(|s| s.group).collect();
    groups.dedup();
    let a = groups.len() as u64;
    let faces: u64 = shapes.iter().map(|s| s.faces).sum();
    if c == 0 {
        return Vec::new();
    }
    if parts == 1 {
        return vec![Cut {
            shape: 0,
            face: 0,
            assembly: Some(1),
            component: None,
        }];
    }
    if parts >= a + c {
        split_shapes(shapes, (parts - a).min(faces))
    } else {
        // The natural share of assemblies, leaving each at least one component.
        let share = (parts as f64 * a as f64 / (a + c) as f64).round() as u64;
        let assemblies = share.clamp(1, parts / 2);
        merge_shapes(shapes, assemblies, parts - assemblies)
    }
}

/// `components` ≥ shapes: every group of shapes its assembly, every shape at least one
/// component; the extra pieces go one at a time to the shape whose pieces are largest (ties:
/// the first), and a shape's pieces split its faces evenly.
fn split_shapes(shapes: &[Shape], components: u64) -> Vec<Cut> {
    use std::cmp::Ordering;
    use std::collections::BinaryHeap;

    /// A shape by its faces per piece, largest first, then the lower index.
    struct Load {
        faces: u64,
        pieces: u64,
        index: usize,
    }
    impl PartialEq for Load {
        fn eq(&self, o: &Self) -> bool {
            self.cmp(o) == Ordering::Equal
        }
    }
    impl Eq for Load {}
    impl PartialOrd for Load {
        fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
            Some(self.cmp(o))
        }
    }
    impl Ord for Load {
        fn cmp(&self, o: &Self) -> Ordering {
            // faces / pieces compared without division.
            (u128::from(self.faces) * u128::from(o.pieces))
                .cmp(&(u128::from(o.faces) * u128::from(self.pieces)))
                .then(o.index.cmp(&self.index))
        }
    }
    let mut pieces = vec![1u64; shapes.len()];
    let mut heap: BinaryHeap<Load> = shapes
        .iter()
        .enumerate()
        .filter(|(_, s)| s.faces > 1)
        .map(|(index, s)| Load {
            faces: s.faces,
            pieces: 1,
            index,
        })
        .collect();
    let mut extra = components.saturating_sub(shapes.len() as u64);
    while extra > 0 {
        let Some(mut top) = heap.pop() else { break };
        top.pieces += 1;
        if let Some(p) = pieces.get_mut(top.index) {
            *p = top.pieces;
        }
        if top.pieces < top.faces {
            heap.push(top);
        }
        extra -= 1;
    }
    let mut cuts = Vec::new();
    let (mut group, mut assembly, mut component) = (None, 0, 0);
    for (i, (s, &n)) in shapes.iter().zip(&pieces).enumerate() {
        for p in 0..n {
            let new_group = p == 0 && group != Some(s.group);
            if new_group {
                group = Some(s.group);
                assembly += 1;
            }
            component += 1;
            cuts.push(Cut {
                shape: i as u64,
                face: p * s.faces / n,
                assembly: new_group.then_some(assembly),
                component: Some((s.kind, component)),
            });
        }
    }
    cuts
}

/// `components` < shapes: component j takes the shapes `⌊j·C/c⌋ ..`, assembly k the
/// components `⌊k·c/a⌋ ..` (consecutive runs of nearly equal length).
fn merge_shapes(shapes: &[Shape], assemblies: u64, components: u64) -> Vec<Cut> {
    let c = shapes.len() as u64;
    let start = |j: u64, of: u64, over: u64| -> u64 {
        (u128::from(j) * u128::from(of) / u128::from(over.max(1))) as u64
    };
    let mut cuts = Vec::new();
    let mut assembly = 0;
    for j in 0..components {
        let shape = start(j, c, components);
        let new_assembly = assembly < assemblies && start(assembly, components, assemblies) == j;
        if new_assembly {
            assembly += 1;
        }
        cuts.push(Cut {
            shape,
            face: 0,
            assembly: new_assembly.then_some(assembly),
            component: Some((shapes.get(shape as usize).map_or("part", |s| s.kind), j + 1)),
        });
    }
    cuts
}

/// The box the parts fill, and where the last parts went, so new parts crowd around old
/// ones as routed systems do.
struct Scene {
    rng: Rng,
    size: [f64; 3],
    anchors: [[f64; 3]; 8],
    next_anchor: usize,
}

impl Scene {
    fn new(opts: &CadOptions) -> Scene {
        let s = (opts.triangles as f64 / (2.0 * DENSITY)).cbrt().max(1.0);
        let size = [2.0 * s, s, s];
        let mut rng = Rng(opts.seed);
        let anchors = [0; 8].map(|_| [0, 1, 2].map(|a| rng.range(0.0, size[a])));
        Scene {
            rng,
            size,
            anchors,
            next_anchor: 0,
        }
    }

    fn clamp(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| p[a].clamp(0.0, self.size[a]))
    }

    /// A start point: near an earlier part more often than not.
    fn start(&mut self) -> [f64; 3] {
        let p = if self.rng.chance(0.7) {
            let i = self.rng.int(0, 7) as usize;
            let a = self.anchors.get(i).copied().unwrap_or_default();
            add(a, scale(self.rng.direction(), self.rng.range(0.02, 0.3)))
        } else {
            [0, 1, 2].map(|a| self.rng.range(0.0, self.size[a]))
        };
        self.clamp(p)
    }

    fn remember(&mut self, p: [f64; 3]) {
        if let Some(slot) = self.anchors.get_mut(self.next_anchor % 8) {
            *slot = p;
        }
        self.next_anchor += 1;
    }

    fn next_group(&mut self, out: &mut Emitter<'_>) -> Result<(), GenError> {
        let pick = self.rng.unit();
        if pick < 0.35 {
            self.pipe(out)
        } else if pick < 0.65 {
            self.cable_bundle(out)
        } else if pick < 0.9 {
            self.panel(out)
        } else {
            self.bolt_row(out)
        }
    }

    /// An axis-aligned pipe run with open overlapping segments, flanges at some bends.
    fn pipe(&mut self, out: &mut Emitter<'_>) -> Result<(), GenError> {
        let r = self.rng.range(0.01, 0.05);
        let sides = [8, 12, 16][self.rng.int(0, 2) as usize % 3];
        let material = PIPE_STEEL + self.rng.int(0, 1) as usize;
        let mut part = Part::new("pipe", material, JITTER * r);
        let mut flanges = Part::new("flange", BOLT_ZINC, JITTER * r);
        let mut p = self.start();
        let mut last_axis = 3;
        for s in 0..self.rng.int(2, 6) {
            let mut a = self.rng.int(0, 2) as usize;
            if a == last_axis {
                a = (a + 1) % 3;
            }
            last_axis = a;
            let len = self.rng.range(0.2, 1.5);
            let mut q = add(p, scale(axis(a), len * self.rng.sign()));
            if q.get(a).is_none_or(|&c| c < 0.0 || c > self.size[a]) {
                // Turn back into the box.
                q = self.clamp(sub(scale(p, 2.0), q));
            }
            if dot(sub(q, p), sub(q, p)) < r * r {
                continue;
            }
            part.cylinder(p, q, r, sides, 8.0 * r, false);
            if s > 0 && self.rng.chance(0.4) {
                let d = normalise(sub(q, p));
                flanges.cylinder(
                    sub(p, scale(d, 0.3 * r)),
                    add(p, scale(d, 0.3 * r)),
                    1.6 * r,
                    sides,
                    r,
                    true,
                );
            }
            p = q;
        }
        self.remember(p);
        out.emit(&part, &mut self.rng)?;
        out.emit(&flanges, &mut self.rng)
    }

    /// Thin cables along one smooth curve, side by side.
    fn cable_bundle(&mut self, out: &mut Emitter<'_>) -> Result<(), GenError> {
        let r = self.rng.range(0.003, 0.01);
        let count = self.rng.int(1, 6);
        let start = self.start();
        let centre = scale(self.size, 0.5);
        // Steps shrink in a small box, so a cable's length stays within the box's size.
        let reach = (self.size[1] / 4.0).min(1.0);
        let mut heading = normalise(add(
            normalise(sub(centre, start)),
            scale(self.rng.direction(), 0.8),
        ));
        let mut controls = vec![start];
        for _ in 0..self.rng.int(3, 6) {
            let last = controls.last().copied().unwrap_or_default();
            // Steer gently (at most about 55° per step, steps of similar length) and away
            // from the walls: sharp corners, or points bunched up against a wall, would
            // make cusps tighter than the cable, whose rings would then cut each other.
            // So points are not clamped either; the pull keeps them near the box.
            let margin = 0.7 * reach;
            let near_wall = (0..3).any(|a| last[a] < margin || last[a] > self.size[a] - margin);
            let pull = if near_wall {
                scale(normalise(sub(centre, last)), 0.4)
            } else {
                [0.0; 3]
            };
            let turn = scale(self.rng.direction(), 0.4);
            heading = normalise(add(heading, add(turn, pull)));
            let step = reach * self.rng.range(0.5, 0.7);
            controls.push(add(last, scale(heading, step)));
        }
        let path = catmull_rom(&controls, 10);
        let frames = transport_frames(&path);
        for c in 0..count {
            let colour = CABLE_YELLOW + self.rng.int(0, 2) as usize;
            let mut part = Part::new("cable", colour, JITTER * r);
            // Neighbours in a bundle touch: offsets of one diameter around the first.
            let angle = TAU * f64::from(c) / 6.0;
            let (ou, ov) = if c == 0 {
                (0.0, 0.0)
            } else {
                (2.0 * r * angle.cos(), 2.0 * r * angle.sin())
            };
            let rings: Vec<_> = path
                .iter()
                .zip(&frames)
                .map(|(&p, &(u, v))| (add(p, add(scale(u, ou), scale(v, ov))), u, v))
                .collect();
            part.tube(&rings, r, 6, true);
            out.emit(&part, &mut self.rng)?;
        }
        if let Some(&end) = path.last() {
            self.remember(end);
        }
        Ok(())
    }

    /// A panel, often a duplicate in the same plane or a hair off it, bolted along two edges.
    fn panel(&mut self, out: &mut Emitter<'_>) -> Result<(), GenError> {
        let mut o = self.start();
        let normal_axis = self.rng.int(0, 2) as usize;
        let sign = self.rng.sign();
        let s = [self.rng.range(0.2, 1.2), self.rng.range(0.2, 1.2)];
        // Keep the panel inside the box.
        for (k, len) in s.iter().enumerate() {
            let a = (normal_axis + 1 + k) % 3;
            if let (Some(c), Some(&size)) = (o.get_mut(a), self.size.get(a)) {
                *c = c.min(size - len).max(0.0);
            }
        }
        let m = [self.rng.int(2, 6), self.rng.int(2, 6)];
        let material = PANEL_GREEN + self.rng.int(0, 1) as usize;
        let mut part = Part::new("panel", material, 0.1 * JITTER * s[0] / f64::from(m[0]));
        part.panel(o, normal_axis, sign, s, m);
        out.emit(&part, &mut self.rng)?;
        if self.rng.chance(0.6) {
            let offset = [0.0, 1e-6, 1e-4][self.rng.int(0, 2) as usize % 3] * sign;
            let shift = [
                self.rng.range(-0.3, 0.3) * s[0],
                self.rng.range(-0.3, 0.3) * s[1],
            ];
            let o2 = add(
                add(o, scale(axis(normal_axis), offset)),
                add(
                    scale(axis((normal_axis + 1) % 3), shift[0]),
                    scale(axis((normal_axis + 2) % 3), shift[1]),
                ),
            );
            let m2 = [self.rng.int(1, 5), self.rng.int(1, 5)];
            let mut twin = Part::new("panel", (material + 1 - PANEL_GREEN) % 2 + PANEL_GREEN, 0.0);
            twin.panel(o2, normal_axis, sign, s, m2);
            out.emit(&twin, &mut self.rng)?;
        }
        // Bolt heads sit on the face (coplanar with it), shanks pass through.
        let n = scale(axis(normal_axis), sign);
        let (a1, a2) = (axis((normal_axis + 1) % 3), axis((normal_axis + 2) % 3));
        let head = self.rng.range(0.005, 0.015);
        for edge in 0..2 {
            let count = self.rng.int(2, 6);
            for b in 0..count {
                let t = (f64::from(b) + 0.5) / f64::from(count);
                let inset = 3.0 * head;
                let at = if edge == 0 {
                    add(add(o, scale(a1, t * s[0])), scale(a2, inset))
                } else {
                    add(add(o, scale(a1, inset)), scale(a2, t * s[1]))
                };
                self.bolt(out, at, n, head)?;
            }
        }
        self.remember(add(add(o, scale(a1, s[0])), scale(a2, s[1])));
        Ok(())
    }

    /// Bolts in a row through thin air, as where a bracket was left out of the export.
    fn bolt_row(&mut self, out: &mut Emitter<'_>) -> Result<(), GenError> {
        let start = self.start();
        let step = scale(self.rng.direction(), self.rng.range(0.02, 0.08));
        let d = axis(self.rng.int(0, 2) as usize);
        let head = self.rng.range(0.005, 0.015);
        for b in 0..self.rng.int(3, 10) {
            let at = self.clamp(add(start, scale(step, f64::from(b))));
            self.bolt(out, at, d, head)?;
        }
        self.remember(start);
        Ok(())
    }

    /// A hexagonal head on `at` facing `d` and a round shank behind it.
    fn bolt(
        &mut self,
        out: &mut Emitter<'_>,
        at: [f64; 3],
        d: [f64; 3],
        head: f64,
    ) -> Result<(), GenError> {
        let mut part = Part::new("bolt", BOLT_ZINC, JITTER * head);
        part.hex_prism(at, d, head, 0.6 * head);
        let length = self.rng.range(2.0, 4.0) * head;
        part.cylinder(at, sub(at, scale(d, length)), 0.5 * head, 8, length, true);
        out.emit(&part, &mut self.rng)
    }
}

/// Points along a Catmull-Rom spline through `controls`, `per_span` per span.
fn catmull_rom(controls: &[[f64; 3]], per_span: u32) -> Vec<[f64; 3]> {
    let n = controls.len();
    let at = |i: isize| {
        let i = i.clamp(0, n as isize - 1) as usize;
        controls.get(i).copied().unwrap_or_default()
    };
    let mut out = Vec::new();
    for span in 0..n.saturating_sub(1) as isize {
        let (p0, p1, p2, p3) = (at(span - 1), at(span), at(span + 1), at(span + 2));
        for s in 0..per_span {
            let t = f64::from(s) / f64::from(per_span);
            let (t2, t3) = (t * t, t * t * t);
            out.push([0, 1, 2].map(|a| {
                0.5 * (2.0 * p1[a]
                    + (p2[a] - p0[a]) * t
                    + (2.0 * p0[a] - 5.0 * p1[a] + 4.0 * p2[a] - p3[a]) * t2
                    + (3.0 * p1[a] - p0[a] - 3.0 * p2[a] + p3[a]) * t3)
            }));
        }
    }
    out.push(at(n as isize - 1));
    // Clamped control points can coincide: drop repeats so every segment has a direction.
    out.dedup_by(|a, b| {
        let d = sub(*a, *b);
        dot(d, d) < 1e-12
    });
    out
}

/// Frames that turn as little as possible along a path (parallel transport), so a tube's
/// rings do not twist.
fn transport_frames(path: &[[f64; 3]]) -> Vec<([f64; 3], [f64; 3])> {
    let tangent = |i: usize| {
        let a = path.get(i.saturating_sub(1)).copied().unwrap_or_default();
        let b = path
            .get((i + 1).min(path.len().saturating_sub(1)))
            .copied()
            .unwrap_or_default();
        normalise(sub(b, a))
    };
    let mut frames = Vec::with_capacity(path.len());
    let (mut u, _) = frame(tangent(0));
    for i in 0..path.len() {
        let t = tangent(i);
        let projected = sub(u, scale(t, dot(u, t)));
        u = if dot(projected, projected) > 1e-12 {
            normalise(projected)
        } else {
            frame(t).0
        };
        frames.push((u, cross(t, u)));
    }
    frames
}

#[cfg(test)]
mod tests {
    use super::*;

    fn face_normal(p: &Part, f: [u32; 3]) -> [f64; 3] {
        let q = f.map(|i| p.positions[i as usize]);
        cross(sub(q[1], q[0]), sub(q[2], q[0]))
    }

    /// Every face's winding agrees with the normals of its corners.
    fn assert_outward(p: &Part) {
        for &f in &p.faces {
            let g = face_normal(p, f);
            for i in f {
                assert!(dot(g, p.normals[i as usize]) > 0.0, "{} face {f:?}", p.name);
            }
        }
    }

    #[test]
    fn each_shape_faces_the_way_its_normals_say() {
        let mut p = Part::new("cylinder", 0, 0.0);
        p.cylinder([0.1, 0.2, 0.3], [0.1, 1.2, 0.4], 0.05, 12, 0.1, true);
        assert_eq!(p.faces.len(), 11 * 12 * 2 + 2 * 12);
        assert_outward(&p);
        let mut p = Part::new("bolt", 0, 0.0);
        p.hex_prism([0.0; 3], normalise([0.3, -1.0, 0.2]), 0.01, 0.006);
        assert_eq!(p.faces.len(), 24);
        assert_outward(&p);
        for sign in [1.0, -1.0] {
            for a in 0..3 {
                let mut p = Part::new("panel", 0, 0.0);
                p.panel([0.0; 3], a, sign, [1.0, 0.5], [3, 2]);
                assert_eq!(p.faces.len(), 12);
                assert_outward(&p);
            }
        }
        let path = catmull_rom(
            &[[0.0; 3], [1.0, 0.0, 0.0], [1.5, 1.0, 0.2], [1.0, 2.0, 0.0]],
            8,
        );
        let frames = transport_frames(&path);
        let rings: Vec<_> = path
            .iter()
            .zip(&frames)
            .map(|(&c, &(u, v))| (c, u, v))
            .collect();
        let mut p = Part::new("cable", 0, 0.0);
        p.tube(&rings, 0.01, 6, true);
        assert_outward(&p);
    }

    #[test]
    fn transported_frames_stay_orthonormal() {
        let mut rng = Rng(3);
        let controls: Vec<_> = (0..6).map(|_| rng.direction()).collect();
        let path = catmull_rom(&controls, 10);
        for (i, (u, v)) in transport_frames(&path).into_iter().enumerate() {
            assert!((dot(u, u) - 1.0).abs() < 1e-9 && (dot(v, v) - 1.0).abs() < 1e-9);
            assert!(dot(u, v).abs() < 1e-9, "frame {i}");
        }
    }

    #[test]
    fn parts_are_small_and_the_count_is_exact() -> Result<(), String> {
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        for target in [1, 7, 5000, 40_000] {
            let path = dir.path().join(format!("c{target}.obj"));
            let opts = CadOptions {
                triangles: target,
                ..CadOptions::default()
            };
            let mut last = 0;
            let (report, peak) = generate(&path, &opts, &mut |done, total| {
                assert!(done >= last && total == target);
                last = done;
            })
            .map_err(|e| e.to_string())?;
            assert_eq!(report.triangles, target);
            assert_eq!(last, target);
            // A part is a few thousand triangles at most, whatever the target.
            assert!(peak <= 6000, "{peak}");
        }
        Ok(())
    }

    /// The parts a cut list names: (assemblies, components).
    fn counted(cuts: &[Cut]) -> (u64, u64) {
        let a = cuts.iter().filter(|c| c.assembly.is_some()).count() as u64;
        let c = cuts.iter().filter(|c| c.component.is_some()).count() as u64;
        (a, c)
    }

    #[test]
    fn planned_parts_come_to_the_count_asked_for() -> Result<(), GenError> {
        let opts = CadOptions {
            triangles: 40_000,
            seed: 4,
            ..CadOptions::default()
        };
        let shapes = dry_run(&opts)?;
        let mut groups: Vec<u64> = shapes.iter().map(|s| s.group).collect();
        groups.dedup();
        let natural = (groups.len() + shapes.len()) as u64;
        assert!(shapes.len() > 100, "{} shapes", shapes.len());
        assert_eq!(shapes.iter().map(|s| s.faces).sum::<u64>(), 40_000);
        for parts in [1, 2, 3, 10, natural - 1, natural, natural + 1, 5 * natural] {
            let cuts = plan_parts(&shapes, parts);
            let (a, c) = counted(&cuts);
            assert_eq!(a + c, parts, "{parts}: {a} assemblies, {c} components");
            // In file order, starting at the first face with an assembly, inside the shapes.
            assert!(cuts.first().is_some_and(|c| (c.shape, c.face) == (0, 0)));
            assert!(cuts.first().is_some_and(|c| c.assembly.is_some()));
            assert!(cuts
                .windows(2)
                .all(|w| (w[0].shape, w[0].face) < (w[1].shape, w[1].face)));
            for cut in &cuts {
                let shape = shapes.get(cut.shape as usize);
                assert!(shape.is_some_and(|s| cut.face < s.faces), "{cut:?}");
            }
            // Every assembly holds a component (one part asked for: the assembly alone), and
            // names are unique: numbered in order.
            if parts > 1 {
                assert!(cuts.iter().all(|c| c.component.is_some()));
            }
            let numbers: Vec<u64> = cuts
                .iter()
                .filter_map(|c| c.component)
                .map(|c| c.1)
                .collect();
            assert!(numbers.iter().copied().eq(1..=c), "{parts}");
            let numbers: Vec<u64> = cuts.iter().filter_map(|c| c.assembly).collect();
            assert!(numbers.iter().copied().eq(1..=a), "{parts}");
            // More parts than natural keep the natural assemblies.
            if parts >= natural {
                assert_eq!(a, groups.len() as u64);
            }
        }
        Ok(())
    }

    #[test]
    fn the_million_triangle_scene_has_thousands_of_natural_parts() -> Result<(), GenError> {
        let shapes = dry_run(&CadOptions::default())?;
        let mut groups: Vec<u64> = shapes.iter().map(|s| s.group).collect();
        groups.dedup();
        let parts = groups.len() + shapes.len();
        assert!((2000..100_000).contains(&parts), "{parts} parts");
        Ok(())
    }

    /// The OBJ text without its part lines.
    fn geometry(path: &Path) -> Result<String, String> {
        let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
        Ok(text
            .lines()
            .filter(|l| !l.starts_with("o ") && !l.starts_with("g "))
            .collect::<Vec<_>>()
            .join("\n"))
    }

    #[test]
    fn parts_change_only_the_part_lines() -> Result<(), String> {
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        let write = |parts: Option<u64>, name: &str| -> Result<(PathBuf, String), String> {
            // The same file name everywhere: the `mtllib` line names it.
            let sub = dir.path().join(name);
            std::fs::create_dir_all(&sub).map_err(|e| e.to_string())?;
            let path = sub.join("cad.obj");
            let opts = CadOptions {
                triangles: 20_000,
                seed: 2,
                parts,
                ..CadOptions::default()
            };
            generate(&path, &opts, &mut |_, _| {}).map_err(|e| e.to_string())?;
            let text = std::fs::read_to_string(&path).map_err(|e| e.to_string())?;
            Ok((path, text))
        };
        let (natural, text) = write(None, "natural")?;
        let lines = |t: &str, p: &str| t.lines().filter(|l| l.starts_with(p)).count();
        let (o, g) = (lines(&text, "o "), lines(&text, "g "));
        assert!(o > 10 && g > o, "{o} assemblies, {g} components");
        assert!(text.lines().any(|l| l == "o assembly-1"), "{text:.300}");
        let want = geometry(&natural)?;
        for (parts, name) in [(Some(0), "none"), (Some(1), "one"), (Some(9), "nine")] {
            let (path, text) = write(parts, name)?;
            assert!(geometry(&path)? == want, "{parts:?} changed the geometry");
            let n = (lines(&text, "o ") + lines(&text, "g ")) as u64;
            assert_eq!(n, parts.unwrap_or_default(), "{parts:?}");
        }
        let many = 3 * (o + g) as u64;
        let (path, text) = write(Some(many), "many")?;
        assert!(geometry(&path)? == want);
        assert_eq!((lines(&text, "o ") + lines(&text, "g ")) as u64, many);
        // Deterministic.
        assert!(write(Some(many), "again")?.1 == text);
        Ok(())
    }

    #[test]
    fn an_empty_scene_is_refused() {
        let r = generate(
            Path::new("unused.obj"),
            &CadOptions {
                triangles: 0,
                ..CadOptions::default()
            },
            &mut |_, _| {},
        );
        assert!(matches!(r, Err(GenError::Option(_))));
    }
}
