//! Export to Wavefront OBJ: `v x y z [r g b]`, `vn` when the container has normals, `usemtl`
//! per material run with an `.mtl` beside the file. Alpha has no place in OBJ and is dropped.

use std::path::Path;

use oocfmt::records::triangle::{oct_decode, Vertex};

use super::{
    material_names, Container, ExportError, ExportOptions, ExportReport, Placement, PrimarySink,
};
use crate::obj_writer::{mtl_beside, write_mtl, ObjWriter};

/// Writes the primaries of `container` to `out` (and its materials to the `.mtl` beside it),
/// atomically. `progress` gets (triangle blocks done, triangle blocks).
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
    if let Some((_, _, name)) = &mtl {
        obj.mtllib(name)?;
    }
    let mut sink = ObjSink {
        obj,
        placement,
        names,
        material: None,
        normals: meta.schema.vertex_normals,
    };
    let total = c.blocks.len() as u64;
    let walked = c.walk(&mut sink, progress, 0, total)?;
    let mut report = ExportReport {
        triangles: walked.triangles,
        vertices: walked.vertices,
        triangle_blocks: total,
        materials: sink.names.len(),
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

struct ObjSink {
    obj: ObjWriter,
    placement: Placement,
    names: Vec<String>,
    material: Option<u16>,
    normals: bool,
}

impl PrimarySink for ObjSink {
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

    fn triangle(&mut self, corners: [u64; 3], material: Option<u16>) -> Result<(), ExportError> {
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
