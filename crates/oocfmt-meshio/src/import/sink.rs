//! An in-memory sink: triangles become a de-duplicated [`Mesh`], degenerate ones are dropped
//! and counted (or refused under `strict`).

use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};

use oocfmt::metadata::Material;

use super::placement::Placement;
use super::{
    DropReason, ImportError, ImportReport, InputTriangle, Location, PartDef, Skipped, TriangleSink,
};
use crate::mesh::Mesh;

/// Material indices in triangle blocks are 16-bit (spec §8).
const MAX_MATERIALS: usize = 1 << 16;

/// The most parts a scene may declare (spec §12).
pub const MAX_PARTS: u32 = 1 << 24;

/// The name of the part given to triangles that the input put in no part, in a scene that
/// has parts.
pub const UNNAMED_PART: &str = "(no part)";

/// The grey given to triangles without a material when others have one.
const DEFAULT_MATERIAL: [f32; 3] = [0.8, 0.8, 0.8];

/// A vertex under construction: the attributes the input gave.
#[derive(Clone, Copy)]
struct Vert {
    position: [f32; 3],
    normal: Option<[f32; 3]>,
    colour: Option<[u8; 4]>,
}

impl Vert {
    /// What makes two vertices one: every attribute, bit for bit.
    fn key(&self) -> [u32; 8] {
        let n = self.normal.map_or([u32::MAX; 3], |n| n.map(f32::to_bits));
        let c = self.colour.map_or(u32::MAX, u32::from_le_bytes);
        [
            self.position[0].to_bits(),
            self.position[1].to_bits(),
            self.position[2].to_bits(),
            n[0],
            n[1],
            n[2],
            c,
            u32::from(self.colour.is_some()),
        ]
    }
}

/// What a mesh holding a chunk of a scene must store because the whole scene has it, so every
/// chunk's triangle blocks carry the same attributes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChunkSchema {
    /// The scene has vertex normals: the chunk's mesh gets them even if its triangles have none.
    pub normals: bool,
    /// The scene has vertex colours: the chunk's mesh gets them (white where the input gave
    /// none).
    pub colours: bool,
    /// The scene's material table; triangles then give indices into it as their material, and
    /// the table is kept as it is instead of being compacted to what the chunk uses.
    pub materials: Option<Vec<Material>>,
    /// The scene has more than one part: the chunk's mesh keeps a part id per triangle (the
    /// scene-wide ids its triangles give).
    pub part_ids: bool,
}

/// What a sink does with the triangles the policy admits.
pub trait Store {
    /// Keeps one admitted triangle: finite, not degenerate, within the format's limits.
    fn store(&mut self, t: InputTriangle, at: &Location) -> Result<(), ImportError>;
    /// [`TriangleSink::charge_disk`], for a store that counts disk use.
    fn charge_disk(&mut self, _bytes: u64) -> std::io::Result<()> {
        Ok(())
    }
    /// [`TriangleSink::release_disk`].
    fn release_disk(&mut self, _bytes: u64) {}
}

/// A sink: the bad-input policy and the import report, shared by every kind of sink, in front
/// of a [`Store`]. It judges each triangle (dropping and counting, or refusing under
/// `strict`), checks the format's limits where the input's place is still known, numbers
/// materials, and places positions relative to the scene origin.
pub struct Intake<S> {
    strict: bool,
    placement: Placement,
    used: HashSet<Option<u32>>,
    /// The materials triangles use (`None`: no material), in order of first use.
    used_order: Vec<Option<u32>>,
    /// Materials as the importers added them.
    table: Vec<Material>,
    /// Parts as the importers (and [`Intake::with_file_parts`]) declared them.
    parts: Vec<PartDef>,
    /// Each input file becomes a part above the parts it declares.
    file_parts: bool,
    /// The part of the file being read, under `file_parts`.
    file_part: Option<u32>,
    /// Some triangle was stored without a part.
    unparted: bool,
    report: ImportReport,
    store: S,
}

/// What an [`Intake`] knows once the import is over.
pub struct Intaken<S> {
    /// The store, holding every admitted triangle.
    pub store: S,
    /// The materials as the importers added them, indexed by [`InputTriangle::material`].
    pub table: Vec<Material>,
    /// The materials triangles use (`None`: no material), in order of first use.
    pub used_order: Vec<Option<u32>>,
    /// The parts as declared, parents before children; empty when the input named none. Every
    /// triangle stored has a part index below its length when it is not empty.
    pub parts: Vec<PartDef>,
    /// The import report, its placement figures filled in.
    pub report: ImportReport,
}

impl<S> Intake<S> {
    /// `strict`: refuse the first degenerate or broken triangle instead of dropping it.
    pub fn with_store(strict: bool, store: S) -> Intake<S> {
        Intake {
            strict,
            placement: Placement::new([0.0; 3]),
            used: HashSet::default(),
            used_order: Vec::new(),
            table: Vec::new(),
            parts: Vec::new(),
            file_parts: false,
            file_part: None,
            unparted: false,
            report: ImportReport::default(),
            store,
        }
    }

    /// Makes each input file a part (named by its file name) above the parts it
    /// declares, and the part of its triangles that declare none: for imports of several files.
    pub fn with_file_parts(self, on: bool) -> Intake<S> {
        Intake {
            file_parts: on,
            ..self
        }
    }

    /// The store behind the intake.
    pub fn store_mut(&mut self) -> &mut S {
        &mut self.store
    }

    /// The parts declared so far.
    pub fn parts(&self) -> &[PartDef] {
        &self.parts
    }

    /// Stores positions relative to `origin` (world = origin + stored).
    pub fn with_origin(self, origin: [f64; 3]) -> Intake<S> {
        Intake {
            placement: Placement::new(origin),
            ..self
        }
    }

    /// The report so far (its placement figures are filled in only by
    /// [`Intake::finish_intake`]).
    pub fn report(&self) -> &ImportReport {
        &self.report
    }

    /// Ends the import; fails when no triangle was kept. When parts were declared and some
    /// triangles have none, a last top-level part [`UNNAMED_PART`] is added for them.
    pub fn finish_intake(mut self) -> Result<Intaken<S>, ImportError> {
        if !self.parts.is_empty() && self.unparted {
            self.file_part = None;
            self.declare_part(PartDef::new(UNNAMED_PART, None))?;
        }
        let mut report = self.report;
        report.placement = self.placement.report();
        if report.triangles_out == 0 {
            return Err(ImportError::Empty {
                dropped: report.dropped_total(),
            });
        }
        Ok(Intaken {
            store: self.store,
            table: self.table,
            used_order: self.used_order,
            parts: self.parts,
            report,
        })
    }

    /// [`TriangleSink::add_part`], for any store.
    fn declare_part(&mut self, mut part: PartDef) -> Result<u32, ImportError> {
        let next = self.parts.len();
        if part.parent.is_some_and(|p| p as usize >= next) {
            return Err(ImportError::Parse {
                at: Location::default(),
                message: format!(
                    "part {:?} names parent {:?}, which is not a part declared before it",
                    part.name, part.parent
                ),
            });
        }
        let index =
            u32::try_from(next)
                .ok()
                .filter(|&p| p < MAX_PARTS)
                .ok_or(ImportError::Limit {
                    at: Location::default(),
                    what: "parts".into(),
                    limit: u64::from(MAX_PARTS),
                })?;
        part.parent = part.parent.or(self.file_part);
        part.source = self.report.files.len().checked_sub(1).map(|f| f as u32);
        self.parts.push(part);
        Ok(index)
    }

    fn drop_or_fail(&mut self, reason: DropReason, at: &Location) -> Result<(), ImportError> {
        if self.strict {
            return Err(ImportError::Strict {
                at: at.clone(),
                reason,
            });
        }
        self.report.triangles_in += 1;
        *self.report.dropped.entry(reason).or_default() += 1;
        Ok(())
    }
}

impl<S: Store> TriangleSink for Intake<S> {
    fn add_material(&mut self, material: Material) -> Result<u32, ImportError> {
        self.table.push(material);
        u32::try_from(self.table.len() - 1)
            .ok()
            .filter(|&m| m != u32::MAX)
            .ok_or(ImportError::Limit {
                at: Location::default(),
                what: "materials".into(),
                limit: u64::from(u32::MAX),
            })
    }

    fn add_part(&mut self, part: PartDef) -> Result<u32, ImportError> {
        self.declare_part(part)
    }

    fn push(&mut self, mut t: InputTriangle, at: &Location) -> Result<(), ImportError> {
        t.part = t.part.or(self.file_part);
        if let Some(reason) = DropReason::classify(&t.positions) {
            return self.drop_or_fail(reason, at);
        }
        if self.report.triangles_out >= u64::from(u32::MAX) {
            return Err(ImportError::Limit {
                at: at.clone(),
                what: "triangles".into(),
                limit: u64::from(u32::MAX),
            });
        }
        // The format's material indices are 16 bits: refuse the triangle that needs one more,
        // where its place is still known.
        if self.used.insert(t.material) {
            if self.used.len() > MAX_MATERIALS {
                return Err(ImportError::Limit {
                    at: at.clone(),
                    what: "distinct materials used by triangles".into(),
                    limit: MAX_MATERIALS as u64,
                });
            }
            self.used_order.push(t.material);
        }
        self.unparted |= t.part.is_none();
        self.store.store(t, at)?;
        self.report.triangles_in += 1;
        self.report.triangles_out += 1;
        Ok(())
    }

    fn reject(&mut self, reason: DropReason, at: &Location) -> Result<(), ImportError> {
        self.drop_or_fail(reason, at)
    }

    fn skip(&mut self, what: Skipped, count: u64) {
        *self.report.skipped.entry(what).or_default() += count;
    }

    fn warn(&mut self, at: &Location, message: String) {
        self.report.warnings.push(format!("{at}: {message}"));
    }

    fn begin_file(&mut self, path: &str) {
        self.report.files.push(path.to_string());
        self.file_part = None;
        if self.file_parts {
            // Named by its file name: a `/` in a part's name would blur the paths that
            // `render --hide a/b` matches; the whole path is the part's `source`.
            let name = std::path::Path::new(path)
                .file_name()
                .map_or_else(|| path.to_string(), |n| n.to_string_lossy().into_owned());
            self.file_part = self.declare_part(PartDef::new(name, None)).ok();
        }
    }

    fn place(&mut self, exact: [f64; 3]) -> [f32; 3] {
        self.placement.place(exact)
    }

    fn charge_disk(&mut self, bytes: u64) -> std::io::Result<()> {
        self.store.charge_disk(bytes)
    }

    fn release_disk(&mut self, bytes: u64) {
        self.store.release_disk(bytes);
    }
}

/// Keeps admitted triangles as a de-duplicated in-memory mesh.
#[derive(Default)]
pub struct MeshStore {
    part: Option<ChunkSchema>,
    verts: Vec<Vert>,
    index: HashMap<[u32; 8], u32>,
    /// By importer vertex number ([`InputTriangle::hint`]): the mesh vertex it last became.
    /// Corners repeat the importer's vertices, and this answers most of them without a
    /// probe into `index` (a cache miss each).
    by_hint: Vec<u32>,
    triangles: Vec<[u32; 3]>,
    materials: Vec<Option<u32>>,
    /// Each triangle's part as the importer gave it (`None`: none).
    parts: Vec<Option<u32>>,
}

/// The in-memory sink.
pub type MeshSink = Intake<MeshStore>;

impl Intake<MeshStore> {
    /// `strict`: refuse the first degenerate or broken triangle instead of dropping it.
    pub fn new(strict: bool) -> MeshSink {
        Intake::with_store(strict, MeshStore::default())
    }

    /// A sink for part of a scene whose attributes are fixed by `schema`.
    pub fn for_chunk(schema: ChunkSchema) -> MeshSink {
        Intake::with_store(
            false,
            MeshStore {
                part: Some(schema),
                ..MeshStore::default()
            },
        )
    }

    /// The mesh and the report. Fails on an empty result or on counts past the format's limits.
    pub fn finish(self) -> Result<(Mesh, ImportReport), ImportError> {
        let Intaken {
            store,
            table,
            parts,
            report,
            ..
        } = self.finish_intake()?;
        Ok((store.into_mesh(table, parts)?, report))
    }
}

impl MeshStore {
    /// The mesh vertex of `v`: an existing one with the same key, else a new one. `hint`,
    /// the importer's number for it, is checked first against the vertex it led to last time.
    fn vertex(&mut self, v: Vert, hint: Option<u32>) -> u32 {
        let key = v.key();
        let slot = hint.map(|h| h as usize);
        if let Some(&id) = slot.and_then(|h| self.by_hint.get(h)) {
            if self
                .verts
                .get(id as usize)
                .is_some_and(|known| known.key() == key)
            {
                return id;
            }
        }
        let next = self.verts.len() as u32;
        let id = *self.index.entry(key).or_insert_with(|| {
            self.verts.push(v);
            next
        });
        // A hint far beyond what the triangles so far could use is not followed, so the
        // table stays within 64 MiB plus 32 bytes per triangle whatever a caller passes.
        let cap = (1 << 24) + 8 * self.triangles.len();
        if let Some(h) = slot.filter(|&h| h < cap) {
            if h >= self.by_hint.len() {
                self.by_hint.resize(h + 1, u32::MAX);
            }
            if let Some(s) = self.by_hint.get_mut(h) {
                *s = id;
            }
        }
        id
    }

    /// Triangles stored so far.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The indexed mesh of what was stored, with `table` as its materials and `parts` as its
    /// parts (from [`Intaken::parts`]: triangles without a part get the last one).
    pub fn into_mesh(self, table: Vec<Material>, parts: Vec<PartDef>) -> Result<Mesh, ImportError> {
        let part = self.part.unwrap_or_default();
        let unnamed = parts.len().saturating_sub(1) as u32;
        let part_ids = (part.part_ids || parts.len() > 1).then(|| {
            self.parts
                .iter()
                .map(|p| p.unwrap_or(unnamed))
                .collect::<Vec<u32>>()
        });
        let any_normals = part.normals || self.verts.iter().any(|v| v.normal.is_some());
        let any_colours = part.colours || self.verts.iter().any(|v| v.colour.is_some());
        let any_materials = self.materials.iter().any(Option::is_some);
        let mut mesh = Mesh::new(
            self.verts.iter().map(|v| v.position).collect(),
            self.triangles,
        );
        if any_normals {
            // A vertex the input gave no normal takes the geometric normal of the first
            // triangle that used it (computed only now: most scenes have no normals at all).
            let mut normals: Vec<Option<[f32; 3]>> = self.verts.iter().map(|v| v.normal).collect();
            for tri in &mesh.triangles {
                let corners = tri.map(|v| normals.get(v as usize).copied().flatten());
                if corners.iter().all(Option::is_some) {
                    continue;
                }
                let p = tri.map(|v| mesh.positions.get(v as usize).copied().unwrap_or_default());
                let n = geometric_normal(&p);
                for (v, c) in tri.iter().zip(corners) {
                    if let (None, Some(slot)) = (c, normals.get_mut(*v as usize)) {
                        *slot = Some(n);
                    }
                }
            }
            mesh.normals = Some(normals.into_iter().map(Option::unwrap_or_default).collect());
        }
        if any_colours {
            mesh.colours = Some(
                self.verts
                    .iter()
                    .map(|v| v.colour.unwrap_or([255; 4]))
                    .collect(),
            );
        }
        if let Some(table) = part.materials {
            let materials = self
                .materials
                .iter()
                .map(|m| m.and_then(|k| u16::try_from(k).ok()).unwrap_or(0))
                .collect();
            mesh.materials = Some(materials);
            mesh.material_table = table;
        } else if any_materials {
            let (materials, table) = compact_materials(&self.materials, table)?;
            mesh.materials = Some(materials);
            mesh.material_table = table;
        }
        mesh.part_ids = part_ids;
        mesh.parts = parts;
        Ok(mesh)
    }
}

/// Keeps the materials that triangles use, in order of first use, plus a default for
/// triangles without one; indices must fit the format's 16 bits.
pub fn compact_materials(
    used: &[Option<u32>],
    table: Vec<Material>,
) -> Result<(Vec<u16>, Vec<Material>), ImportError> {
    let mut remap: HashMap<Option<u32>, u16> = HashMap::default();
    let mut out = Vec::new();
    let mut indices = Vec::with_capacity(used.len());
    for m in used {
        let next = out.len();
        let idx = match remap.get(m) {
            Some(&i) => i,
            None => {
                let i = u16::try_from(next).map_err(|_| ImportError::Limit {
                    at: Location::default(),
                    what: "materials used by triangles".into(),
                    limit: u64::from(u16::MAX) + 1,
                })?;
                let material = m
                    .and_then(|k| table.get(k as usize).cloned())
                    .unwrap_or_else(|| Material {
                        name: "default".into(),
                        diffuse: DEFAULT_MATERIAL,
                    });
                out.push(material);
                remap.insert(*m, i);
                i
            }
        };
        indices.push(idx);
    }
    Ok((indices, out))
}

fn geometric_normal(p: &[[f32; 3]; 3]) -> [f32; 3] {
    let n = super::edge_cross(p);
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if len > 0.0 {
        [
            (n[0] / len) as f32,
            (n[1] / len) as f32,
            (n[2] / len) as f32,
        ]
    } else {
        [0.0, 0.0, 1.0]
    }
}

impl Store for MeshStore {
    fn store(&mut self, t: InputTriangle, _at: &Location) -> Result<(), ImportError> {
        let mut tri = [0u32; 3];
        for (k, slot) in tri.iter_mut().enumerate() {
            let v = Vert {
                position: t.positions[k],
                normal: t
                    .normals
                    .map(|n| n[k])
                    .filter(|n| n.iter().all(|c| c.is_finite())),
                colour: t.colours.map(|c| c[k]),
            };
            *slot = self.vertex(v, t.hint.map(|h| h[k]));
        }
        self.triangles.push(tri);
        self.materials.push(t.material);
        self.parts.push(t.part);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(p: [[f32; 3]; 3]) -> InputTriangle {
        InputTriangle::new(p)
    }

    #[test]
    fn vertices_without_normals_take_their_first_triangles_normal() -> Result<(), ImportError> {
        let at = Location::line("t.obj", 1);
        let mut s = MeshSink::new(false);
        // Corner 0 is met first by a triangle facing +z, then by one facing −z.
        s.push(tri([[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), &at)?;
        s.push(tri([[0.0; 3], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]), &at)?;
        let mut lit = tri([[5.0, 0.0, 0.0], [6.0, 0.0, 0.0], [5.0, 0.0, 1.0]]);
        lit.normals = Some([[1.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        s.push(lit, &at)?;
        let (mesh, _) = s.finish()?;
        let normals = mesh.normals.clone().unwrap_or_default();
        let normal_at = |p: [f32; 3]| {
            let v = mesh.positions.iter().position(|q| *q == p);
            v.and_then(|v| normals.get(v).copied())
        };
        assert_eq!(normal_at([0.0; 3]), Some([0.0, 0.0, 1.0]));
        assert_eq!(normal_at([0.0, -1.0, 0.0]), Some([0.0, 0.0, -1.0]));
        assert_eq!(normal_at([5.0, 0.0, 0.0]), Some([1.0, 0.0, 0.0]));
        // The corner whose normal was not finite: the geometric normal of its triangle.
        assert_eq!(normal_at([6.0, 0.0, 0.0]), Some([0.0, -1.0, 0.0]));
        assert_eq!(normal_at([5.0, 0.0, 1.0]), Some([0.0, 1.0, 0.0]));
        Ok(())
    }

    #[test]
    fn importer_hints_never_change_the_mesh() -> Result<(), ImportError> {
        // Corners on a small lattice, some with colours: the same position recurs with
        // different attributes, and the hints are absent, right, misleading or absurd.
        let mesh_with = |mode: u32| {
            let mut s = MeshSink::new(false);
            let mut rng = oocfmt_scenes::rng::Rng(5);
            let at = Location::line("t.obj", 1);
            for i in 0..3000u32 {
                let ids: [u32; 3] = std::array::from_fn(|_| rng.int(0, 63));
                let mut t =
                    tri(ids.map(|v| [(v % 4) as f32, ((v / 4) % 4) as f32, (v / 16) as f32]));
                if i % 4 == 0 {
                    t.colours = Some(ids.map(|v| [v as u8, 0, 0, 255]));
                }
                t.hint = match mode {
                    0 => None,
                    1 => Some(ids),
                    2 => Some(ids.map(|v| (v * 7 + i) % 50)),
                    _ => Some([u32::MAX, 1 << 31, ids[0]]),
                };
                s.push(t, &at)?;
            }
            Ok::<Mesh, ImportError>(s.finish()?.0)
        };
        let plain = mesh_with(0)?;
        assert!(
            plain.positions.len() > 64 && plain.triangles.len() > 1500,
            "{} {}",
            plain.positions.len(),
            plain.triangles.len()
        );
        for mode in 1..4 {
            assert!(
                mesh_with(mode)? == plain,
                "hint mode {mode} changed the mesh"
            );
        }
        Ok(())
    }

    #[test]
    fn degenerate_triangles_are_dropped_and_counted() -> Result<(), ImportError> {
        let at = Location::line("t.obj", 1);
        let mut s = MeshSink::new(false);
        s.push(
            tri([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
            &at,
        )?;
        s.push(
            tri([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
            &at,
        )?;
        s.push(
            tri([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]),
            &at,
        )?;
        s.push(
            tri([[f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
            &at,
        )?;
        s.reject(DropReason::IndexOutOfRange, &at)?;
        let (mesh, r) = s.finish()?;
        assert_eq!(mesh.triangles.len(), 1);
        assert_eq!(mesh.positions.len(), 3);
        assert_eq!(
            (r.triangles_in, r.triangles_out, r.dropped_total()),
            (5, 1, 4)
        );
        for reason in [
            DropReason::ZeroArea,
            DropReason::Collinear,
            DropReason::NonFinite,
            DropReason::IndexOutOfRange,
        ] {
            assert_eq!(r.dropped.get(&reason), Some(&1), "{reason:?}");
        }
        Ok(())
    }

    #[test]
    fn strict_refuses_with_the_place() {
        let mut s = MeshSink::new(true);
        let e = s.push(
            tri([[0.0; 3], [0.0; 3], [1.0; 3]]),
            &Location::line("m.obj", 42),
        );
        let msg = e.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(
            msg.contains("m.obj:42") && msg.contains("zero area"),
            "{msg}"
        );
    }

    #[test]
    fn positions_are_stored_relative_to_the_origin_and_the_error_reported(
    ) -> Result<(), ImportError> {
        let mut s = MeshSink::new(false).with_origin([1e7, 0.0, 0.0]);
        let at = Location::default();
        let p = [
            [1e7 + 0.25, 0.0, 0.0],
            [1e7 + 1.5, 0.0, 0.0],
            [1e7, 1.0, 0.0],
        ];
        let positions = p.map(|q| s.place(q));
        s.push(tri(positions), &at)?;
        let (mesh, r) = s.finish()?;
        assert_eq!(mesh.positions[0], [0.25, 0.0, 0.0]);
        assert_eq!(r.placement.origin, [1e7, 0.0, 0.0]);
        assert_eq!(r.placement.max_abs_error, 0.0);
        // Without the origin, 1e7 + 0.25 rounds to 1e7 (f32 spacing 1 there).
        assert_eq!(r.placement.max_abs_error_without_origin, 0.5);
        Ok(())
    }

    #[test]
    fn an_empty_result_is_an_error() {
        let s = MeshSink::new(false);
        assert!(matches!(s.finish(), Err(ImportError::Empty { .. })));
    }

    #[test]
    fn attributes_exist_only_when_given_and_vertices_are_shared() -> Result<(), ImportError> {
        let at = Location::default();
        let mut s = MeshSink::new(false);
        let m = s.add_material(Material {
            name: "red".into(),
            diffuse: [1.0, 0.0, 0.0],
        })?;
        let mut a = tri([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        a.material = Some(m);
        s.push(a, &at)?;
        s.push(
            tri([[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]),
            &at,
        )?;
        let (mesh, _) = s.finish()?;
        assert_eq!(mesh.positions.len(), 4);
        assert!(mesh.normals.is_none() && mesh.colours.is_none());
        assert_eq!(mesh.materials, Some(vec![0, 1]));
        assert_eq!(mesh.material_table.len(), 2);
        assert_eq!(mesh.material_table[1].name, "default");
        Ok(())
    }
}
