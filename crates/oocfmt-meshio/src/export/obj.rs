//! Export to Wavefront OBJ: `v x y z [r g b]`, `vn` when the container has normals, `usemtl`
//! per material run with an `.mtl` beside the file. Alpha has no place in OBJ and is dropped.
//!
//! Parts: the part table goes into comments (`# oocfmt parts N`, then `# part ID PARENT
//! NAME`, see [`crate::import::obj`]), and each part's run of faces starts with `# part ID`
//! and `g PATH` (its names from the root, joined by `/`): our importer rebuilds the exact tree
//! from the comments, other readers see one group per part. With two parts or more every
//! vertex comes first, then the faces part by part.

use std::path::Path;

use oocfmt::metadata::Part;
use oocfmt::records::triangle::{oct_decode, Vertex};

use super::parts::{path, walk_in_part_order, PartOrder};
use super::{
    material_names, Container, ExportError, ExportOptions, ExportReport, Face, Placement,
    PrimarySink,
};
use crate::import::obj::part_table;
use crate::obj_writer::{mtl_beside, write_mtl, ObjWriter};

/// Writes the primaries of `container` to `out` (and its materials to the `.mtl` beside it),
/// atomically. `progress` gets (block reads done, block reads): one pass over the triangle
/// blocks, or with two parts or more one for the vertices and one per
/// [`ExportOptions::faces_per_pass`] faces.
pub fn write_obj(
    container: &Path,
    out: &Path,
    opts: &ExportOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<ExportReport, ExportError> {
    let c = Container::open(container)?;
    let meta = c.meta();
    let names = material_names(&meta.materials);
    let mtl = if names.is_empty() {
        None
    } else {
        let (path, name) = mtl_beside(out)?;
        let colours = meta.materials.iter().map(|m| m.diffuse);
        let file = write_mtl(&path, names.iter().map(String::as_str).zip(colours))?;
        Some((file, path, name))
    };
    let mut obj = ObjWriter::create(out)?;
    let origin = meta.scene.origin;
    obj.comment(&format!(
        "exported by oocfmt-build from {}: {} triangles (primaries only)",
        c.name(),
        meta.counts.triangles
    ))?;
    let placement = Placement::new(meta, opts);
    if placement.origin.is_none() && origin != [0.0; 3] {
        obj.comment(&format!(
            "positions are relative to the scene origin {} {} {}",
            origin[0], origin[1], origin[2]
        ))?;
    }
    if !meta.parts.is_empty() {
        obj.comment(&format!(
            "{} {}",
            part_table::TABLE_HEADER,
            meta.parts.len()
        ))?;
        for (id, p) in (0u32..).zip(&meta.parts) {
            let entry = part_table::format_entry(id, p.parent, &p.name);
            obj.comment(&format!("{} {entry}", part_table::PART))?;
        }
    }
    if let Some((_, _, name)) = &mtl {
        obj.mtllib(name)?;
    }
    let grouped = meta.parts.len() > 1;
    let mut sink = ObjSink {
        obj,
        placement,
        names,
        material: None,
        normals: meta.schema.vertex_normals,
        parts: &meta.parts,
        part: None,
        faces: !grouped,
    };
    let blocks = c.blocks.len() as u64;
    let passes = if grouped {
        1 + PartOrder::new(meta).passes(opts.faces_per_pass)
    } else {
        1
    };
    let total = blocks * passes;
    let walked = c.walk(&mut sink, progress, 0, total)?;
    if grouped {
        sink.faces = true;
        walk_in_part_order(&c, &mut sink, opts.faces_per_pass, progress, blocks, total)?;
    }
    let mut report = ExportReport {
        triangles: walked.triangles,
        vertices: walked.vertices,
        triangle_blocks: blocks,
        materials: sink.names.len(),
        parts: meta.parts.len(),
        ..ExportReport::default()
    };
    sink.placement.report(&mut report);
    if let Some((file, path, _)) = mtl {
        file.commit()?;
        report.mtl = Some(path);
    }
    report.bytes = sink.obj.finish()?.bytes;
    Ok(report)
}

struct ObjSink<'a> {
    obj: ObjWriter,
    placement: Placement,
    names: Vec<String>,
    material: Option<u16>,
    normals: bool,
    parts: &'a [Part],
    /// The part of the faces written last.
    part: Option<u32>,
    /// Faces are written (off in the vertex pass of a file in part order).
    faces: bool,
}

impl PrimarySink for ObjSink<'_> {
    fn vertex(&mut self, _index: u64, v: &Vertex) -> Result<(), ExportError> {
        let rgb = v
            .colour
            .map(|c| [c[0], c[1], c[2]].map(|b| f32::from(b) / 255.0));
        match (self.placement.origin, rgb) {
            (None, None) => self.obj.vertex(v.position)?,
            (None, Some(rgb)) => self.obj.vertex_rgb(v.position, rgb)?,
            (Some(o), None) => {
                let p = self.placement.world(o, v.position);
                self.obj.vertex(p)?
            }
            (Some(o), Some(rgb)) => {
                let p = self.placement.world(o, v.position);
                self.obj.vertex_rgb(p, rgb)?
            }
        };
        if self.normals {
            self.obj.normal(oct_decode(v.normal.unwrap_or([0, 0])))?;
        }
        Ok(())
    }

    fn triangle(&mut self, face: Face, _rank: u64) -> Result<(), ExportError> {
        if !self.faces {
            return Ok(());
        }
        let Face {
            corners,
            material,
            part,
        } = face;
        if let Some(p) = part.filter(|&p| self.part != Some(p)) {
            self.obj.comment(&format!("{} {p}", part_table::PART))?;
            self.obj.group(&path(self.parts, p))?;
            self.part = Some(p);
        }
        if let Some(m) = material.filter(|&m| self.material != Some(m)) {
            let name = self.names.get(usize::from(m)).map_or("", String::as_str);
            self.obj.usemtl(name)?;
            self.material = Some(m);
        }
        // OBJ counts from 1; normals are written one per vertex, so they share its number.
        let v = corners.map(|i| i + 1);
        if self.normals {
            self.obj.face_normals(v, v)?;
        } else {
            self.obj.face(v)?;
        }
        Ok(())
    }
}
