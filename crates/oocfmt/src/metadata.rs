//! The metadata section: serde + postcard (spec §9).

use serde::{Deserialize, Serialize};

use crate::error::{Code, Error, Result};

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
    /// ones [`Metadata::decode`] accepts.
    pub fn encode(&self) -> Result<Vec<u8>> {
        postcard::to_stdvec(self)
            .map_err(|e| Error::parameter(format!("metadata cannot be encoded: {e}")))
    }

    /// Decodes metadata. Trailing bytes are fields of a newer minor version: allowed only when
    /// `newer_minor` says the file is newer than this reader (spec §11).
    ///
    /// The value's bytes MUST be its canonical encoding, the one [`Metadata::encode`] writes
    /// (spec §9): postcard also accepts over-long varints, and a value with two encodings
    /// would give one content two file identities.
    pub fn decode(bytes: &[u8], newer_minor: bool) -> Result<Metadata> {
        let (meta, rest) = postcard::take_from_bytes::<Metadata>(bytes)
            .map_err(|e| Error::malformed(Code::MetadataDecode, format!("metadata: {e}")))?;
        if !rest.is_empty() && !newer_minor {
            return Err(Error::malformed(
                Code::MetadataDecode,
                format!("{} bytes after the metadata value", rest.len()),
            ));
        }
        let used = bytes.get(..bytes.len() - rest.len()).unwrap_or(bytes);
        let canonical = meta.encode()?;
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
        Ok(())
    }
}
