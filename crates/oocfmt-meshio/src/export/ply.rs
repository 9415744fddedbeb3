//! Export to binary little-endian PLY: positions (f32, or f64 in world coordinates), normals,
//! RGBA colours and a per-face `material_index` when the container has them. Material names
//! and colours go in header comments. A container with parts gets a face property
//! `int part` (the part's index) and its table as header comments `comment part ID PARENT
//! NAME` (PARENT −1 at the top level; the name escaped as [`crate::import::obj`] says), its
//! faces grouped by part.
//!
//! PLY puts every vertex before every face and the counts in the header, so the blocks are
//! read twice: vertices first behind a header of reserved length, then faces, then the header
//! is rewritten with the counts (padded to its reserved length by a blank comment).

use std::io::Write;
use std::path::Path;

use oocfmt::records::triangle::{oct_decode, Vertex};

use super::parts::{walk_in_part_order, PartOrder};
use super::{
    material_names, Container, ExportError, ExportOptions, ExportReport, Face, Placement,
    PrimarySink, Walked,
};
use crate::import::obj::part_table;
use crate::obj_writer::{AtomicFile, WriteError};

/// Writes the primaries of `container` to `out`, atomically. `progress` gets (block reads
/// done, block reads): a pass over the triangle blocks for the vertices, then one for the
/// faces, or with two parts or more one per [`ExportOptions::faces_per_pass`] faces.
pub fn write_ply(
    container: &Path,
    out: &Path,
    opts: &ExportOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<ExportReport, ExportError> {
    let c = Container::open(container)?;
    let meta = c.meta();
    let names = material_names(&meta.materials);
    let schema = meta.schema;
    let placement = Placement::new(meta, opts);
    let header = Header {
        source: c.name(),
        materials: names
            .iter()
            .zip(&meta.materials)
            .map(|(n, m)| format!("{n} {} {} {}", m.diffuse[0], m.diffuse[1], m.diffuse[2]))
            .collect(),
        double: placement.origin.is_some(),
        normals: schema.vertex_normals,
        colours: schema.vertex_colours,
        material_index: schema.triangle_materials,
        parts: (0u32..)
            .zip(&meta.parts)
            .map(|(id, p)| part_table::format_entry(id, p.parent, &p.name))
            .collect(),
        origin: meta.scene.origin,
    };
    let reserved = header.text(u64::MAX, u64::MAX, 0).len() + PAD_MIN;
    let mut file = AtomicFile::create(out)?;
    let blank = header.text(0, 0, reserved);
    file.write_all(blank.as_bytes())
        .map_err(|e| file.error(e))?;
    let blocks = c.blocks.len() as u64;
    let grouped = meta.parts.len() > 1;
    let face_passes = if grouped {
        PartOrder::new(meta).passes(opts.faces_per_pass)
    } else {
        1
    };
    let total = blocks * (1 + face_passes);
    let mut sink = PlySink {
        out: file,
        placement,
        header: &header,
        faces: false,
    };
    let vertices = c.walk(&mut sink, progress, 0, total)?;
    if vertices.vertices > u64::from(u32::MAX) {
        return Err(ExportError::TooManyVertices {
            file: c.name(),
            vertices: vertices.vertices,
        });
    }
    sink.faces = true;
    if grouped {
        walk_in_part_order(&c, &mut sink, opts.faces_per_pass, progress, blocks, total)?;
    } else {
        let faces = c.walk(&mut sink, progress, blocks, total)?;
        if faces != vertices {
            return Err(ExportError::Changed { file: c.name() });
        }
    }
    let Walked {
        triangles,
        vertices,
    } = vertices;
    let PlySink {
        mut out, placement, ..
    } = sink;
    out.overwrite_start(header.text(vertices, triangles, reserved).as_bytes())?;
    let mut report = ExportReport {
        triangles,
        vertices,
        triangle_blocks: blocks,
        materials: names.len(),
        parts: header.parts.len(),
        ..ExportReport::default()
    };
    placement.report(&mut report);
    report.bytes = out.commit()?;
    Ok(report)
}

/// The shortest padding comment, `comment\n`.
const PAD_MIN: usize = 8;

struct Header {
    source: String,
    materials: Vec<String>,
    double: bool,
    normals: bool,
    colours: bool,
    material_index: bool,
    /// The part table's lines, `ID PARENT NAME`; empty without parts.
    parts: Vec<String>,
    origin: [f64; 3],
}

impl Header {
    /// The header for these counts, padded to `len` bytes when `len` is larger.
    fn text(&self, vertices: u64, faces: u64, len: usize) -> String {
        let mut h = String::from("ply\nformat binary_little_endian 1.0\n");
        // The source path may hold anything; a header line must not.
        let source: String = self
            .source
            .chars()
            .map(|c| if c.is_control() { '_' } else { c })
            .collect();
        h += &format!("comment exported by oocfmt-build from {source}\n");
        if !self.double && self.origin != [0.0; 3] {
            let [x, y, z] = self.origin;
            h += &format!("comment positions are relative to the scene origin {x} {y} {z}\n");
        }
        for (i, m) in self.materials.iter().enumerate() {
            h += &format!("comment material {i} {m}\n");
        }
        for p in &self.parts {
            h += &format!("comment {} {p}\n", part_table::PART);
        }
        let mut tail = format!("element vertex {vertices}\n");
        let ty = if self.double { "double" } else { "float" };
        for c in ["x", "y", "z"] {
            tail += &format!("property {ty} {c}\n");
        }
        if self.normals {
            tail += "property float nx\nproperty float ny\nproperty float nz\n";
        }
        if self.colours {
            tail += "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n";
        }
        tail += &format!("element face {faces}\nproperty list uchar uint vertex_indices\n");
        if self.material_index {
            tail += "property ushort material_index\n";
        }
        if !self.parts.is_empty() {
            tail += "property int part\n";
        }
        tail += "end_header\n";
        let pad = len.saturating_sub(h.len() + tail.len());
        if pad >= PAD_MIN {
            h += "comment";
            h.extend(std::iter::repeat_n(' ', pad - PAD_MIN));
            h += "\n";
        }
        h + &tail
    }
}

struct PlySink<'a> {
    out: AtomicFile,
    placement: Placement,
    header: &'a Header,
    /// The first pass writes vertices, the second faces.
    faces: bool,
}

impl PlySink<'_> {
    fn put(&mut self, bytes: &[u8]) -> Result<(), WriteError> {
        self.out.write_all(bytes).map_err(|e| self.out.error(e))
    }
}

impl PrimarySink for PlySink<'_> {
    fn vertex(&mut self, _index: u64, v: &Vertex) -> Result<(), ExportError> {
        if self.faces {
            return Ok(());
        }
        let mut rec = Vec::with_capacity(40);
        match self.placement.origin {
            Some(o) => {
                for c in self.placement.world(o, v.position) {
                    rec.extend_from_slice(&c.to_le_bytes());
                }
            }
            None => {
                for c in v.position {
                    rec.extend_from_slice(&c.to_le_bytes());
                }
            }
        }
        if self.header.normals {
            for c in oct_decode(v.normal.unwrap_or([0, 0])) {
                rec.extend_from_slice(&c.to_le_bytes());
            }
        }
        if self.header.colours {
            rec.extend_from_slice(&v.colour.unwrap_or([255; 4]));
        }
        Ok(self.put(&rec)?)
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
        let mut rec = Vec::with_capacity(19);
        rec.push(3u8);
        for i in corners {
            // Checked after the vertex pass: every index fits.
            rec.extend_from_slice(&(i as u32).to_le_bytes());
        }
        if self.header.material_index {
            rec.extend_from_slice(&material.unwrap_or(0).to_le_bytes());
        }
        if !self.header.parts.is_empty() {
            // Part ids are below 2^24 (spec §12): every one fits an int.
            let id = i32::try_from(part.unwrap_or(0)).unwrap_or(i32::MAX);
            rec.extend_from_slice(&id.to_le_bytes());
        }
        Ok(self.put(&rec)?)
    }
}
