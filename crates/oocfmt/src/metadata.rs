//! The metadata section: serde + postcard (spec §9).

use serde::{Deserialize, Serialize};

use crate::error::{Code, Error, Result};

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Metadata {
    pub scene: Scene,
    pub root: Option<TreeletRef>,
    pub counts: Counts,
    pub schema: Schema,
    pub materials: Vec<Material>,
    pub build: Build,
    pub provenance: Provenance,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    /// World coordinates are `origin + stored` (in f64).
    pub origin: [f64; 3],
}

/// A treelet: its block and its index in that block.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize,
)]
pub struct TreeletRef {
    pub block: u32,
    pub treelet: u32,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counts {
    pub triangles: u64,
    pub triangle_records: u64,
    pub vertices: u64,
    pub basic_nodes: u64,
    pub lod_nodes: u64,
    pub leaves: u64,
    pub voxels_single: u64,
    pub voxels_six: u64,
    pub proxies: u64,
    pub treelets: u64,
    pub depth: u32,
    pub lod_levels: u32,
}

/// Which optional attributes the scene has; each costs nothing when absent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Schema {
    pub vertex_normals: bool,
    pub vertex_colours: bool,
    pub triangle_materials: bool,
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

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Material {
    pub name: String,
    pub diffuse: [f32; 3],
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Build {
    pub treelet_height: u8,
    pub max_leaf_triangles: u32,
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

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    pub generator: String,
    pub sources: Vec<String>,
}

impl Metadata {
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
