//! Elements that make triangles: `face` (a list `vertex_indices` or `vertex_index` per
//! record, triangulated like OBJ polygons) and `tristrips` (strips with `-1` restarts), with
//! the optional `part`/`part_id` and `material_index` properties our exporter writes.
//!
//! Part ids map to parts named by the header's `comment part` lines, else `part N`, declared
//! when first used (comment parts all at once, parents first). Material indices map the same
//! way to `comment material` lines, else to a grey `material N`.

use rustc_hash::FxHashMap as HashMap;

use oocfmt::metadata::Material;

use super::body::Body;
use super::header::{CommentPart, Element, Kind};
use super::scalar::Scalar;
use super::vertices::Table;
use crate::import::obj::polygon::{Outcome, Triangulator};
use crate::import::{DropReason, ImportError, Location, PartDef, Skipped, TriangleSink};

/// The colour of a material a face names but no comment describes.
const UNDESCRIBED_MATERIAL: [f32; 3] = [0.8, 0.8, 0.8];

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Shape {
    Polygons,
    Strips,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Indices { count: Scalar, item: Scalar },
    Part(Scalar),
    Material(Scalar),
    Skip(Kind),
}

/// How the records of one face-like element are read.
pub(super) struct FacePlan {
    shape: Shape,
    roles: Vec<Role>,
    parts: bool,
    materials: bool,
}

impl FacePlan {
    /// The plan for `element` when it is `face` or `tristrips`; `Err` with a reason when it
    /// is one of them but has no index list, `Ok(None)` when it is something else.
    pub(super) fn new(element: &Element) -> Result<Option<FacePlan>, String> {
        let shape = match element.name.as_str() {
            "face" => Shape::Polygons,
            "tristrips" => Shape::Strips,
            _ => return Ok(None),
        };
        let mut indices = false;
        let roles: Vec<Role> = element
            .properties
            .iter()
            .map(|p| match (p.name.as_str(), p.kind) {
                ("vertex_indices" | "vertex_index", Kind::List { count, item }) if !indices => {
                    indices = true;
                    Role::Indices { count, item }
                }
                ("part" | "part_id", Kind::Scalar(s)) => Role::Part(s),
                ("material_index", Kind::Scalar(s)) => Role::Material(s),
                (_, kind) => Role::Skip(kind),
            })
            .collect();
        if !indices {
            return Err(format!(
                "element `{}` has no list property `vertex_indices` or `vertex_index`",
                element.name
            ));
        }
        let has = |f: fn(&Role) -> bool| roles.iter().any(f);
        Ok(Some(FacePlan {
            shape,
            parts: has(|r| matches!(r, Role::Part(_))),
            materials: has(|r| matches!(r, Role::Material(_))),
            roles,
        }))
    }
}

/// A strip's last two corners (`None` inside: an index out of range) and whether the next
/// triangle is odd (its first two corners swapped, so every triangle keeps the winding).
#[derive(Default)]
struct Strip {
    a: Option<Option<u32>>,
    b: Option<Option<u32>>,
    odd: bool,
}

/// What the face elements of one file share: the part and material numbering, buffers, and
/// counts for the warnings at the end.
pub(super) struct Faces {
    file: String,
    max_corners: usize,
    part_comments: Vec<CommentPart>,
    material_comments: Vec<(u32, Material)>,
    parts: Option<HashMap<u32, u32>>,
    materials: Option<HashMap<u32, u32>>,
    corners: Vec<Option<u32>>,
    polygon: Vec<[f32; 3]>,
    triangulator: Triangulator,
    points: u64,
    lines: u64,
    empty: u64,
    fans: u64,
    bad_parts: u64,
    bad_materials: u64,
    bad_part_comments: u64,
}

impl Faces {
    pub(super) fn new(
        file: &str,
        max_corners: usize,
        part_comments: Vec<CommentPart>,
        material_comments: Vec<(u32, Material)>,
    ) -> Faces {
        Faces {
            file: file.to_string(),
            max_corners,
            part_comments,
            material_comments,
            parts: None,
            materials: None,
            corners: Vec::new(),
            polygon: Vec::new(),
            triangulator: Triangulator::default(),
            points: 0,
            lines: 0,
            empty: 0,
            fans: 0,
            bad_parts: 0,
            bad_materials: 0,
            bad_part_comments: 0,
        }
    }

    /// Reads every record of the (entered) `element` and pushes its triangles.
    pub(super) fn read<B: Body>(
        &mut self,
        body: &mut B,
        element: &Element,
        plan: &FacePlan,
        table: &mut Table,
        sink: &mut dyn TriangleSink,
    ) -> Result<(), ImportError> {
        if plan.parts {
            self.declare_parts(sink)?;
        }
        if plan.materials {
            self.declare_materials(sink)?;
        }
        let vertices = table.len() as f64;
        let resolve = |v: f64| (v >= 0.0 && v < vertices && v.fract() == 0.0).then_some(v as u32);
        for r in 0..element.count {
            body.record(r);
            self.corners.clear();
            let (mut part, mut material) = (None, None);
            for (prop, role) in element.properties.iter().zip(&plan.roles) {
                match *role {
                    Role::Indices { count, item } => {
                        let n = body.list_len(count, item, &prop.name)?;
                        if plan.shape == Shape::Strips {
                            let mut strip = Strip::default();
                            for _ in 0..n {
                                let v = body.scalar(item, &prop.name)?;
                                let corner = (v != -1.0).then(|| resolve(v));
                                self.strip(
                                    &mut strip,
                                    corner,
                                    table,
                                    [part, material],
                                    body,
                                    sink,
                                )?;
                            }
                            continue;
                        }
                        if n > self.max_corners as u64 {
                            return Err(ImportError::Limit {
                                at: body.location().clone(),
                                what: "corners of one face".into(),
                                limit: self.max_corners as u64,
                            });
                        }
                        for _ in 0..n {
                            let v = body.scalar(item, &prop.name)?;
                            self.corners.push(resolve(v));
                        }
                    }
                    Role::Part(ty) => {
                        let v = body.scalar(ty, &prop.name)?;
                        part = self.part(v, sink)?;
                    }
                    Role::Material(ty) => {
                        let v = body.scalar(ty, &prop.name)?;
                        material = self.material(v, sink)?;
                    }
                    Role::Skip(kind) => body.skip_property(kind, &prop.name)?,
                }
            }
            if plan.shape == Shape::Polygons {
                self.polygon(table, part, material, body, sink)?;
            }
        }
        Ok(())
    }

    /// The face in `corners`: triangulated, rejected (an index out of range) or counted as a
    /// point or line.
    fn polygon<B: Body>(
        &mut self,
        table: &mut Table,
        part: Option<u32>,
        material: Option<u32>,
        body: &mut B,
        sink: &mut dyn TriangleSink,
    ) -> Result<(), ImportError> {
        let n = self.corners.len();
        match n {
            0 => self.empty += 1,
            1 => self.points += 1,
            2 => self.lines += 1,
            _ if self.corners.contains(&None) => {
                for _ in 2..n {
                    sink.reject(DropReason::IndexOutOfRange, body.location())?;
                }
            }
            _ => {
                self.polygon.clear();
                for c in &self.corners {
                    let p = match *c {
                        Some(i) => table.position(i)?,
                        None => None,
                    };
                    self.polygon.push(p.unwrap_or_default());
                }
                if self.triangulator.triangulate(&self.polygon) == Outcome::Fallback {
                    self.fans += 1;
                }
                for t in self.triangulator.triangles() {
                    let v = t.map(|i| self.corners.get(i).copied().flatten().unwrap_or(0));
                    sink.push(table.triangle(v, part, material)?, body.location())?;
                }
            }
        }
        Ok(())
    }

    /// One index of a strip (`None`: a restart).
    fn strip<B: Body>(
        &mut self,
        strip: &mut Strip,
        corner: Option<Option<u32>>,
        table: &mut Table,
        [part, material]: [Option<u32>; 2],
        body: &mut B,
        sink: &mut dyn TriangleSink,
    ) -> Result<(), ImportError> {
        let Some(c) = corner else {
            *strip = Strip::default();
            return Ok(());
        };
        if let (Some(a), Some(b)) = (strip.a, strip.b) {
            let (a, b) = if strip.odd { (b, a) } else { (a, b) };
            strip.odd = !strip.odd;
            match (a, b, c) {
                (Some(a), Some(b), Some(c)) => {
                    sink.push(table.triangle([a, b, c], part, material)?, body.location())?
                }
                _ => sink.reject(DropReason::IndexOutOfRange, body.location())?,
            }
        }
        strip.a = strip.b;
        strip.b = Some(c);
        Ok(())
    }

    /// The comment parts, once, in id order: a parent must have a smaller id.
    fn declare_parts(&mut self, sink: &mut dyn TriangleSink) -> Result<(), ImportError> {
        if self.parts.is_some() {
            return Ok(());
        }
        let mut map = HashMap::default();
        let mut comments = std::mem::take(&mut self.part_comments);
        comments.sort_by_key(|c| c.id);
        for c in comments {
            if map.contains_key(&c.id) {
                self.bad_part_comments += 1;
                continue;
            }
            let parent = match c.parent {
                None => None,
                Some(p) => {
                    let found = map.get(&p).copied().filter(|_| p < c.id);
                    if found.is_none() {
                        self.bad_part_comments += 1;
                    }
                    found
                }
            };
            map.insert(c.id, sink.add_part(PartDef::new(c.name, parent))?);
        }
        self.parts = Some(map);
        Ok(())
    }

    /// The part of a face whose part property is `v`.
    fn part(&mut self, v: f64, sink: &mut dyn TriangleSink) -> Result<Option<u32>, ImportError> {
        let Some(id) = whole_u32(v) else {
            self.bad_parts += 1;
            return Ok(None);
        };
        let map = self.parts.get_or_insert_with(HashMap::default);
        if let Some(&p) = map.get(&id) {
            return Ok(Some(p));
        }
        let p = sink.add_part(PartDef::new(format!("part {id}"), None))?;
        map.insert(id, p);
        Ok(Some(p))
    }

    /// The comment materials, once, in index order.
    fn declare_materials(&mut self, sink: &mut dyn TriangleSink) -> Result<(), ImportError> {
        if self.materials.is_some() {
            return Ok(());
        }
        let mut map = HashMap::default();
        let mut comments = std::mem::take(&mut self.material_comments);
        comments.sort_by_key(|c| c.0);
        for (index, m) in comments {
            if let std::collections::hash_map::Entry::Vacant(e) = map.entry(index) {
                e.insert(sink.add_material(m)?);
            }
        }
        self.materials = Some(map);
        Ok(())
    }

    /// The material of a face whose material property is `v`.
    fn material(
        &mut self,
        v: f64,
        sink: &mut dyn TriangleSink,
    ) -> Result<Option<u32>, ImportError> {
        let Some(index) = whole_u32(v) else {
            self.bad_materials += 1;
            return Ok(None);
        };
        let map = self.materials.get_or_insert_with(HashMap::default);
        if let Some(&m) = map.get(&index) {
            return Ok(Some(m));
        }
        let m = sink.add_material(Material {
            name: format!("material {index}"),
            diffuse: UNDESCRIBED_MATERIAL,
        })?;
        map.insert(index, m);
        Ok(Some(m))
    }

    /// The counts and warnings of the whole file.
    pub(super) fn finish(&self, sink: &mut dyn TriangleSink) {
        if self.points > 0 {
            sink.skip(Skipped::Points, self.points);
        }
        if self.lines > 0 {
            sink.skip(Skipped::Lines, self.lines);
        }
        let at = Location::file(&self.file);
        let notes = [
            (self.empty, "faces without corners were ignored"),
            (
                self.fans,
                "faces could not be ear-clipped (self-intersecting?) and were fan-triangulated",
            ),
            (
                self.bad_parts,
                "faces have a part that is not a whole number from 0 to 2^32 - 1: they have no part",
            ),
            (
                self.bad_materials,
                "faces have a material index that is not a whole number from 0 to 2^32 - 1: they \
                 have no material",
            ),
            (
                self.bad_part_comments,
                "`comment part` lines repeat an id or name a parent without a smaller id: \
                 repeats were ignored, such parts are top level",
            ),
        ];
        for (count, what) in notes {
            if count > 0 {
                sink.warn(&at, format!("{count} {what}"));
            }
        }
    }
}

/// `v` as a u32, when it is one exactly.
fn whole_u32(v: f64) -> Option<u32> {
    (v >= 0.0 && v <= f64::from(u32::MAX) && v.fract() == 0.0).then_some(v as u32)
}
