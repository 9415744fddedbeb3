//! The metadata section: serde + postcard (spec §9).

use serde::{Deserialize, Serialize};

use crate::error::{Code, Error, Result};
use crate::header::{VERSION_MINOR, VERSION_MINOR_BASE, VERSION_MINOR_PARTS};
use crate::records::triangle::{part_id_width, ATTR_PART_WIDTH_SHIFT};

/// Most parts a part table may hold (spec §12): ids then fit 24 bits, and a table this long
/// already needs far more metadata than the default limit allows.
pub const MAX_PARTS: usize = 1 << 24;

/// The file's metadata value (spec §9). Field order is the wire order: new fields may only be
/// appended, in a new minor version (spec §11).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Metadata {
    /// The scene's box and coordinate origin.
    pub scene: Scene,
    /// The treelet holding the tree's root, in a level-0 treelet block; `None` only for a file
    /// with no geometry.
    pub root: Option<TreeletRef>,
    /// What the stored tree holds; deep verify compares each count with the tree.
    pub counts: Counts,
    /// Which optional attributes the scene stores.
    pub schema: Schema,
    /// The materials that triangles' material indices point into.
    pub materials: Vec<Material>,
    /// The build parameters the file was made with.
    pub build: Build,
    /// What made the file and from which inputs.
    pub provenance: Provenance,
    /// The scene's parts (CAD assembly nodes), parents first; since 1.3, and only files of
    /// minor 3 or later store the field. Empty when the input named no parts; with two or more,
    /// triangles and LOD entries carry part ids (`PART_IDS`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub parts: Vec<Part>,
}

/// One part of the scene: a named node of the assembly forest (spec §9). Its counts and bounds
/// cover its own triangles only, so a viewer can size and frame it without reading a block.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Part {
    /// The name the input gave it (for people and glob selection; no rule reads it).
    pub name: String,
    /// Index of the parent part, below this part's own index; `None` for a top-level part.
    pub parent: Option<u32>,
    /// Index into [`Provenance::sources`] of the input file the part came from, when known.
    pub source: Option<u32>,
    /// Primary triangles whose part id is this part (not counting its descendants').
    pub triangles: u64,
    /// Low corner of those triangles' corners, in stored coordinates; zero without triangles.
    pub bounds_min: [f32; 3],
    /// High corner of those triangles' corners, in stored coordinates; zero without triangles.
    pub bounds_max: [f32; 3],
}

/// Refuses a part table whose length, the varint `bytes` start with, is over [`MAX_PARTS`]
/// (`PART_TABLE`, spec §12), before any part is decoded. A malformed varint is left to the
/// decoder, which names it.
fn check_part_count(bytes: &[u8]) -> Result<()> {
    let mut n = 0u64;
    for (i, &b) in bytes.iter().take(10).enumerate() {
        n |= u64::from(b & 0x7f) << (7 * i);
        if b & 0x80 == 0 {
            if n > MAX_PARTS as u64 {
                return Err(Error::malformed(
                    Code::PartTable,
                    format!("the part table holds {n} parts, over the limit of {MAX_PARTS}"),
                ));
            }
            break;
        }
    }
    Ok(())
}

/// The fields of metadata up to 1.2, borrowed: what a writer encodes first, so a file without
/// parts keeps the bytes of a 1.2 writer's value.
#[derive(Serialize)]
struct Until12Ref<'a> {
    scene: &'a Scene,
    root: &'a Option<TreeletRef>,
    counts: &'a Counts,
    schema: &'a Schema,
    materials: &'a Vec<Material>,
    build: &'a Build,
    provenance: &'a Provenance,
}

/// The fields of metadata up to 1.2, owned: what a reader decodes first at every minor.
#[derive(Deserialize)]
struct Until12 {
    scene: Scene,
    root: Option<TreeletRef>,
    counts: Counts,
    schema: Schema,
    materials: Vec<Material>,
    build: Build,
    provenance: Provenance,
}

/// The scene's extent. Every value is finite; with a root, `bounds_min <= bounds_max` on every
/// axis (the root's cell).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    /// Low corner of the scene box, in stored coordinates (x, y, z).
    pub bounds_min: [f32; 3],
    /// High corner of the scene box, in stored coordinates (x, y, z).
    pub bounds_max: [f32; 3],
    /// World coordinates are `origin + stored` (in f64).
    pub origin: [f64; 3],
}

/// A treelet: its block and its index in that block.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize,
)]
pub struct TreeletRef {
    /// Id of the treelet block holding it.
    pub block: u32,
    /// Index of the treelet among that block's treelets.
    pub treelet: u32,
}

/// What the tree holds as stored (spec §9). Block sums are over all triangle blocks; node
/// counts are over the nodes reachable from the root, through LOD links.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counts {
    /// Input triangles: the sum of the blocks' primary counts (copies not counted).
    pub triangles: u64,
    /// Triangle records stored, copies of straddling triangles included.
    pub triangle_records: u64,
    /// Vertex records stored, summed over the triangle blocks.
    pub vertices: u64,
    /// Reachable inner nodes without LOD data.
    pub basic_nodes: u64,
    /// Reachable LOD nodes (inner nodes with a voxel and/or an R-LOD, linking to child treelets).
    pub lod_nodes: u64,
    /// Reachable leaves.
    pub leaves: u64,
    /// Voxels with one shading sample.
    pub voxels_single: u64,
    /// Voxels with six shading samples, one per cell face (−x, +x, −y, +y, −z, +z).
    pub voxels_six: u64,
    /// Proxy records over all proxy blocks.
    pub proxies: u64,
    /// Treelets reached from the root.
    pub treelets: u64,
    /// Node levels on the longest root-to-leaf path; a lone leaf has depth 1.
    pub depth: u32,
    /// One more than the highest treelet block level; 0 without treelet blocks.
    pub lod_levels: u32,
}

/// Which optional attributes the scene has; each costs nothing when absent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Schema {
    /// Vertices carry an octahedral normal (two i16).
    pub vertex_normals: bool,
    /// Vertices carry a linear RGBA colour (four u8).
    pub vertex_colours: bool,
    /// Triangles carry a u16 material index into [`Metadata::materials`].
    pub triangle_materials: bool,
    /// True exactly when some voxel has six shading samples.
    pub six_sample_voxels: bool,
}

impl Schema {
    /// The attribute bits of a triangle block (spec §8).
    pub fn triangle_attributes(&self) -> u16 {
        u16::from(self.vertex_normals)
            | (u16::from(self.vertex_colours) << 1)
            | (u16::from(self.triangle_materials) << 2)
    }
}

/// A surface material, named by triangles' material indices.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// The name the input gave it (for people and exporters; no rule reads it).
    pub name: String,
    /// Diffuse colour, linear RGB, normally in 0 ..= 1; only finiteness is checked.
    pub diffuse: [f32; 3],
}

/// How the builder was set up. Recorded only: no reader or verifier rule relies on these values
/// beyond `treelet_height >= 1`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Build {
    /// Node levels per treelet the builder aimed at (at least 1); the tree need not keep to it.
    pub treelet_height: u8,
    /// The builder's leaf-size parameter: a node of at most this many triangles became a leaf
    /// (larger leaves remain where no plane separates their triangles).
    pub max_leaf_triangles: u32,
    /// Other build options as (name, value) pairs, in the order the builder wrote them.
    pub params: Vec<(String, String)>,
}

impl Default for Build {
    fn default() -> Self {
        Build {
            treelet_height: 3,
            max_leaf_triangles: 16,
            params: Vec::new(),
        }
    }
}

/// Where the file came from. It must not hold anything that differs between runs (such as a
/// timestamp): the same input and options give a byte-identical file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The program that wrote the file, with its version (the builder writes `oocfmt-build`
    /// and its crate version).
    pub generator: String,
    /// The input files it was built from, as the caller named them; empty when the geometry
    /// was generated rather than read.
    pub sources: Vec<String>,
}

impl Metadata {
    /// The canonical postcard encoding of the value: the bytes a writer stores and the only
    /// ones [`Metadata::decode`] accepts. The part table is written only when it is non-empty,
    /// which is when a writer makes the file 1.3 ([`Metadata::minor_version`]).
    pub fn encode(&self) -> Result<Vec<u8>> {
        self.encode_for(!self.parts.is_empty())
    }

    /// The encoding with the 1.3 part-table field (`with_parts`, even when empty) or without
    /// it (only for an empty table). Postcard lays a struct out as its fields in order, so the
    /// 1.2 fields then the table are the encoding of the whole value.
    fn encode_for(&self, with_parts: bool) -> Result<Vec<u8>> {
        let fail =
            |e: postcard::Error| Error::parameter(format!("metadata cannot be encoded: {e}"));
        if !with_parts && !self.parts.is_empty() {
            return Err(Error::parameter(format!(
                "a part table of {} parts needs format 1.3",
                self.parts.len()
            )));
        }
        let mut out = postcard::to_stdvec(&Until12Ref {
            scene: &self.scene,
            root: &self.root,
            counts: &self.counts,
            schema: &self.schema,
            materials: &self.materials,
            build: &self.build,
            provenance: &self.provenance,
        })
        .map_err(fail)?;
        if with_parts {
            out.extend(postcard::to_stdvec(&self.parts).map_err(fail)?);
        }
        Ok(out)
    }

    /// The lowest minor version whose metadata holds this value: 1.3 with a part table, else 0
    /// (the LOD kinds may ask for more, spec §11).
    pub fn minor_version(&self) -> u16 {
        if self.parts.is_empty() {
            VERSION_MINOR_BASE
        } else {
            VERSION_MINOR_PARTS
        }
    }

    /// The attribute bits every triangle block of the file carries (spec §8): the schema's,
    /// with the part-id width the part table asks for in bits 3–4.
    pub fn triangle_attributes(&self) -> u16 {
        self.schema.triangle_attributes()
            | (part_id_width(self.parts.len()) << ATTR_PART_WIDTH_SHIFT)
    }

    /// Decodes the metadata of a file of minor version `minor`: the fields of 1.2, then the
    /// part table where `minor` is 3 or more. Trailing bytes are fields of a newer minor
    /// version: allowed only when the file is newer than this reader (spec §11).
    ///
    /// The value's bytes MUST be its canonical encoding, the one a writer of that minor writes
    /// (spec §9): postcard also accepts over-long varints, and a value with two encodings
    /// would give one content two file identities.
    pub fn decode(bytes: &[u8], minor: u16) -> Result<Metadata> {
        let undecodable =
            |e: postcard::Error| Error::malformed(Code::MetadataDecode, format!("metadata: {e}"));
        let (base, rest) = postcard::take_from_bytes::<Until12>(bytes).map_err(undecodable)?;
        let with_parts = minor >= VERSION_MINOR_PARTS;
        let (parts, rest) = if with_parts {
            check_part_count(rest)?;
            postcard::take_from_bytes::<Vec<Part>>(rest).map_err(|e| {
                Error::malformed(Code::MetadataDecode, format!("metadata part table: {e}"))
            })?
        } else {
            (Vec::new(), rest)
        };
        if !rest.is_empty() && minor <= VERSION_MINOR {
            return Err(Error::malformed(
                Code::MetadataDecode,
                format!("{} bytes after the metadata value", rest.len()),
            ));
        }
        let meta = Metadata {
            scene: base.scene,
            root: base.root,
            counts: base.counts,
            schema: base.schema,
            materials: base.materials,
            build: base.build,
            provenance: base.provenance,
            parts,
        };
        let used = bytes.get(..bytes.len() - rest.len()).unwrap_or(bytes);
        let canonical = meta.encode_for(with_parts)?;
        if canonical != used {
            let at = canonical
                .iter()
                .zip(used)
                .position(|(a, b)| a != b)
                .unwrap_or(canonical.len().min(used.len()));
            return Err(Error::malformed(
                Code::MetadataNonCanonical,
                format!(
                    "the value's {} bytes are not its canonical {}-byte encoding (first difference at byte {at})",
                    used.len(),
                    canonical.len()
                ),
            ));
        }
        meta.check()?;
        Ok(meta)
    }

    /// Rules on values that postcard cannot express; the writer checks them too, so it never
    /// writes a file its reader refuses.
    pub fn check(&self) -> Result<()> {
        let bad = |detail: String| Err(Error::malformed(Code::MetadataDecode, detail));
        if self.build.treelet_height == 0 {
            return bad("treelet height is zero".into());
        }
        let s = &self.scene;
        let finite = s
            .bounds_min
            .iter()
            .chain(&s.bounds_max)
            .all(|c| c.is_finite())
            && s.origin.iter().all(|c| c.is_finite());
        if !finite {
            return bad(format!(
                "scene bounds {:?} .. {:?} or origin {:?} not finite",
                s.bounds_min, s.bounds_max, s.origin
            ));
        }
        if self.root.is_some() && (0..3).any(|a| s.bounds_min[a] > s.bounds_max[a]) {
            return bad(format!(
                "scene bounds {:?} .. {:?} are inverted",
                s.bounds_min, s.bounds_max
            ));
        }
        if let Some(m) = self
            .materials
            .iter()
            .find(|m| !m.diffuse.iter().all(|c| c.is_finite()))
        {
            return bad(format!(
                "material `{}` has a non-finite colour {:?}",
                m.name, m.diffuse
            ));
        }
        self.check_parts()
    }

    /// The part table's rules (spec §9, `PART_TABLE`): a forest listed parents first, sources
    /// that exist, finite bounds, at most [`MAX_PARTS`] parts.
    pub fn check_parts(&self) -> Result<()> {
        let bad = |detail: String| Err(Error::malformed(Code::PartTable, detail));
        if self.parts.len() > MAX_PARTS {
            return bad(format!(
                "{} parts, over the limit of {MAX_PARTS}",
                self.parts.len()
            ));
        }
        let sources = self.provenance.sources.len();
        for (i, p) in self.parts.iter().enumerate() {
            if let Some(parent) = p.parent.filter(|&q| q as usize >= i) {
                return bad(format!(
                    "part {i} `{}` has parent {parent}, not an earlier part",
                    p.name
                ));
            }
            if let Some(source) = p.source.filter(|&s| s as usize >= sources) {
                return bad(format!(
                    "part {i} `{}` names source {source} of {sources}",
                    p.name
                ));
            }
            if !p
                .bounds_min
                .iter()
                .chain(&p.bounds_max)
                .all(|c| c.is_finite())
            {
                return bad(format!(
                    "part {i} `{}` has bounds {:?} .. {:?}, not finite",
                    p.name, p.bounds_min, p.bounds_max
                ));
            }
        }
        Ok(())
    }
}
