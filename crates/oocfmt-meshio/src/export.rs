//! `oocfmt export`: writes the full-detail triangles of a container back out (OBJ or binary
//! PLY), so a round trip can prove nothing was lost.
//!
//! Only primaries are written (spec §8: the first `primary_count` triangles of each triangle
//! block), so every input triangle comes out exactly once however many leaves share it.
//! Positions are the stored f32 values printed so they parse back bit for bit; a container
//! with a non-zero `scene.origin` is exported in world coordinates (`origin + stored`, in
//! f64), which is no longer bit-exact, and the report says so and gives the largest rounding
//! error. Vertices are written once per block, only those the primaries use.
//!
//! A container with parts gets its part table back (OBJ: comments and `g` lines; PLY: header
//! comments and a face property), and its faces grouped by part in the table's order, each
//! part's in file order (`export/parts.rs`).

mod obj;
mod parts;
mod ply;

use std::path::{Path, PathBuf};

use oocfmt::metadata::{Material, Metadata};
use oocfmt::records::triangle::Vertex;
use oocfmt::{BlockKind, ReadOptions, Reader};

pub use crate::obj_writer::WriteError;
pub use obj::write_obj;
pub use ply::write_ply;

/// How [`write_obj`] and [`write_ply`] place positions and order faces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExportOptions {
    /// Add the container's `scene.origin` to positions when it is not zero (then written as
    /// f64, not bit-exact). Off, positions are the stored ones and the origin is only noted.
    pub world_coordinates: bool,
    /// Most faces held in memory to put a container with parts in part order: each pass over
    /// the triangle blocks collects this many (40 bytes each), so memory stays bounded
    /// whatever the model's size.
    pub faces_per_pass: u64,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            world_coordinates: true,
            // 256 MiB of faces: a 100M-triangle model takes 12 passes.
            faces_per_pass: 1 << 23,
        }
    }
}

/// What an export wrote (printed by `oocfmt export`, as JSON with `--json`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ExportReport {
    /// Triangles written: the container's primaries, each input triangle once.
    pub triangles: u64,
    /// Vertices written: those the primaries use, once per triangle block (a vertex that two
    /// blocks share is written twice).
    pub vertices: u64,
    /// Triangle blocks read.
    pub triangle_blocks: u64,
    /// Size of the model file (without the `.mtl` beside an OBJ).
    pub bytes: u64,
    /// Materials written (to the `.mtl` for OBJ, as header comments for PLY).
    pub materials: usize,
    /// Parts written (the container's part table; 0 when it has none).
    pub parts: usize,
    /// The `.mtl` written beside an OBJ, when the container has materials.
    pub mtl: Option<PathBuf>,
    /// The origin added to every position (zero when none was).
    pub origin: [f64; 3],
    /// Whether every position is written exactly as stored.
    pub bit_exact: bool,
    /// The largest difference between a written coordinate and the exact `origin + stored`.
    pub max_abs_error: f64,
}

/// Why an export failed, naming the container (and the block or triangle where one is at
/// fault).
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The container could not be opened or read, or a block is malformed.
    #[error(transparent)]
    Format(#[from] oocfmt::Error),
    /// The model or `.mtl` file could not be written.
    #[error(transparent)]
    Write(#[from] WriteError),
    /// The primaries in the triangle blocks do not add up to the metadata's triangle count.
    #[error("{file}: the metadata counts {expected} triangles, but the triangle blocks hold {found} primaries")]
    CountMismatch {
        /// The container's name.
        file: String,
        /// The triangle count in the metadata.
        expected: u64,
        /// The primaries the triangle blocks hold.
        found: u64,
    },
    /// A triangle names a material past the metadata's material table.
    #[error("{file}: block {block}: triangle {triangle} uses material {material}, but the metadata lists {materials}")]
    MaterialOutOfRange {
        /// The container's name.
        file: String,
        /// The id of the triangle block.
        block: u32,
        /// The triangle's index in its block.
        triangle: usize,
        /// The material index it names.
        material: u16,
        /// How many materials the metadata lists.
        materials: usize,
    },
    /// A PLY export would need vertex indices past `u32::MAX`.
    #[error("{file}: {vertices} vertices, more than the 32-bit indices of PLY can address")]
    TooManyVertices {
        /// The container's name.
        file: String,
        /// The vertices the export would write.
        vertices: u64,
    },
    /// A part holds another number of primaries than the metadata's part table says.
    #[error("{file}: the part table counts {expected} triangles in part {part}, but the triangle blocks hold {found}")]
    PartCountMismatch {
        /// The container's name.
        file: String,
        /// The part's index in the table.
        part: usize,
        /// The triangle count in the table.
        expected: u64,
        /// The primaries the triangle blocks give that part.
        found: u64,
    },
    /// The export's passes (vertices, then faces) found different counts.
    #[error("{file}: the container changed while it was being exported")]
    Changed {
        /// The container's name.
        file: String,
    },
}

/// A primary triangle as the exporters write it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Face {
    /// Its vertices' export numbers (from 0).
    corners: [u64; 3],
    material: Option<u16>,
    /// Its part: the id stored with it, 0 in a file of one part, `None` without parts.
    part: Option<u32>,
}

/// Receives the primaries of a container: vertices numbered from 0 in the order of first use
/// (per block), then the triangles that use them.
trait PrimarySink {
    fn vertex(&mut self, index: u64, v: &Vertex) -> Result<(), ExportError>;
    /// `rank`: how many faces of the same part came before this one in the walk.
    fn triangle(&mut self, face: Face, rank: u64) -> Result<(), ExportError>;
}

/// An open container and its triangle blocks in file order.
struct Container {
    reader: Reader,
    attrs: u16,
    blocks: Vec<u32>,
}

/// What one walk over the primaries produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Walked {
    triangles: u64,
    vertices: u64,
}

impl Container {
    fn open(path: &Path) -> Result<Container, ExportError> {
        let reader = Reader::open(path, ReadOptions::default())?;
        let attrs = reader.metadata().triangle_attributes();
        let blocks = reader
            .entries()
            .iter()
            .zip(0u32..)
            .filter(|(e, _)| e.kind == BlockKind::Triangle)
            .map(|(_, id)| id)
            .collect();
        Ok(Container {
            reader,
            attrs,
            blocks,
        })
    }

    fn meta(&self) -> &Metadata {
        self.reader.metadata()
    }

    fn name(&self) -> String {
        self.reader.name().to_string()
    }

    /// Feeds every primary to `sink`, block by block. `progress` gets (`done_before` + blocks
    /// done, `total`).
    fn walk(
        &self,
        sink: &mut dyn PrimarySink,
        progress: &mut dyn FnMut(u64, u64),
        done_before: u64,
        total: u64,
    ) -> Result<Walked, ExportError> {
        let materials = self.meta().materials.len();
        let parts = self.meta().parts.len();
        let mut walked = Walked {
            triangles: 0,
            vertices: 0,
        };
        // Faces so far per part (one counter for all in a file without parts or with one).
        let mut ranks: Vec<u64> = vec![0; parts.max(1)];
        let mut local: Vec<Option<u64>> = Vec::new();
        for (done, &id) in (1u64..).zip(&self.blocks) {
            let block = self.reader.read_block(id)?;
            let in_block = |e: oocfmt::Error| e.in_block(id).in_file(self.reader.name());
            let tb = block.triangles(self.attrs).map_err(in_block)?;
            tb.check_contents().map_err(in_block)?;
            tb.check_parts(parts).map_err(in_block)?;
            local.clear();
            local.resize(tb.vertex_count(), None);
            for t in 0..tb.primary_count() {
                let tri = tb.triangle(t).map_err(in_block)?;
                if let Some(m) = tri.material.filter(|&m| usize::from(m) >= materials) {
                    return Err(ExportError::MaterialOutOfRange {
                        file: self.name(),
                        block: id,
                        triangle: t,
                        material: m,
                        materials,
                    });
                }
                let mut corners = [0u64; 3];
                for (corner, &v) in corners.iter_mut().zip(&tri.v) {
                    let slot = local.get_mut(usize::from(v)).ok_or_else(|| {
                        in_block(oocfmt::Error::malformed(
                            oocfmt::Code::TriangleIndex,
                            format!("triangle {t} names vertex {v}"),
                        ))
                    })?;
                    *corner = match *slot {
                        Some(global) => global,
                        None => {
                            let global = walked.vertices;
                            sink.vertex(global, &tb.vertex(usize::from(v)).map_err(in_block)?)?;
                            walked.vertices += 1;
                            *slot = Some(global);
                            global
                        }
                    };
                }
                let part = tri.part.or((parts > 0).then_some(0));
                let counter = ranks.get_mut(part.unwrap_or(0) as usize);
                let rank = counter.as_deref().copied().unwrap_or(0);
                if let Some(c) = counter {
                    *c += 1;
                }
                let face = Face {
                    corners,
                    material: tri.material,
                    part,
                };
                sink.triangle(face, rank)?;
                walked.triangles += 1;
            }
            progress(done_before + done, total);
        }
        let expected = self.meta().counts.triangles;
        if walked.triangles != expected {
            return Err(ExportError::CountMismatch {
                file: self.name(),
                expected,
                found: walked.triangles,
            });
        }
        if parts > 1 {
            let table = self.meta().parts.iter().map(|p| p.triangles);
            if let Some((part, (expected, found))) = table
                .zip(ranks)
                .enumerate()
                .find(|(_, (want, got))| want != got)
            {
                return Err(ExportError::PartCountMismatch {
                    file: self.name(),
                    part,
                    expected,
                    found,
                });
            }
        }
        Ok(walked)
    }
}

/// Positions as written: stored, or moved by the origin in f64 with the rounding tracked.
struct Placement {
    origin: Option<[f64; 3]>,
    max_abs_error: f64,
}

impl Placement {
    fn new(meta: &Metadata, opts: &ExportOptions) -> Placement {
        let origin = meta.scene.origin;
        Placement {
            origin: (opts.world_coordinates && origin != [0.0; 3]).then_some(origin),
            max_abs_error: 0.0,
        }
    }

    /// `origin + p` rounded to f64, noting the exact rounding error (Knuth's two-sum).
    fn world(&mut self, origin: [f64; 3], p: [f32; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| {
            let (x, y) = (origin[a], f64::from(p[a]));
            let s = x + y;
            let bp = s - x;
            let err = (x - (s - bp)) + (y - bp);
            self.max_abs_error = self.max_abs_error.max(err.abs());
            s
        })
    }

    fn report(&self, report: &mut ExportReport) {
        report.origin = self.origin.unwrap_or([0.0; 3]);
        report.bit_exact = self.origin.is_none();
        report.max_abs_error = self.max_abs_error;
    }
}

/// Material names usable on an OBJ `usemtl` line and unique: whitespace and `\` (which would
/// continue the line) become `_`, an empty name becomes `material_N`, and a repeated name
/// gets `_N` appended.
fn material_names(materials: &[Material]) -> Vec<String> {
    let mut seen = std::collections::HashSet::new();
    materials
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let mut name: String = m
                .name
                .chars()
                .map(|c| {
                    if c.is_whitespace() || c.is_control() || c == '\\' {
                        '_'
                    } else {
                        c
                    }
                })
                .collect();
            if name.is_empty() {
                name = format!("material_{i}");
            }
            while !seen.insert(name.clone()) {
                name = format!("{name}_{i}");
            }
            name
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn material_names_are_single_words_and_unique() {
        let m = |name: &str| Material {
            name: name.into(),
            diffuse: [0.5; 3],
        };
        let names = material_names(&[
            m("steel"),
            m("red paint"),
            m(""),
            m("steel"),
            m("a\tb"),
            m("c\\"),
        ]);
        assert_eq!(
            names,
            ["steel", "red_paint", "material_2", "steel_3", "a_b", "c_"]
        );
    }

    #[test]
    fn the_origin_is_added_in_f64_with_its_exact_error() {
        let mut meta = Metadata::default();
        meta.scene.origin = [1.0e9, 0.0, -0.1];
        let mut p = Placement::new(&meta, &ExportOptions::default());
        let origin = p.origin.unwrap_or_default();
        let w = p.world(origin, [0.1, 2.5, 0.1]);
        assert_eq!(w[1], 2.5);
        assert_eq!(w[0], 1.0e9 + f64::from(0.1f32));
        assert!(p.max_abs_error > 0.0 && p.max_abs_error < 1e-7);
        let mut r = ExportReport::default();
        p.report(&mut r);
        assert!(!r.bit_exact);
        let off = Placement::new(
            &meta,
            &ExportOptions {
                world_coordinates: false,
                ..ExportOptions::default()
            },
        );
        assert!(off.origin.is_none());
        assert!(
            Placement::new(&Metadata::default(), &ExportOptions::default())
                .origin
                .is_none()
        );
    }
}
