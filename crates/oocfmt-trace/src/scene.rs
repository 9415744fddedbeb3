//! An open container: the reader, its metadata and the resident proxies.

use std::path::Path;
use std::sync::{Arc, RwLock};

use oocfmt::metadata::Metadata;
use oocfmt::records::ProxyRecord;
use oocfmt::{BlockKind, ReadOptions, Reader};

use crate::blocks::{LodKind, TreeletData, TriangleData};
use crate::error::TraceError;
use crate::parts::PartFilter;
use crate::section::Section;

/// An open container ready to trace: its reader (metadata, directory, proxies resident), the
/// LOD kind the traversal stops on, and which parts it shows. Shared by the caches and the
/// render threads.
pub struct Scene {
    reader: Reader,
    attrs: u16,
    /// The length of the part table (part ids are checked against it at decode).
    part_count: usize,
    /// See [`Scene::set_parts`].
    parts: RwLock<Arc<PartFilter>>,
    /// See [`Scene::set_section`].
    section: RwLock<Option<Section>>,
    /// The LOD representation the traversal stops on.
    lod: LodKind,
    /// See [`Scene::node_bound`].
    node_bound: u64,
}

impl Scene {
    /// Opens the container at `path` with the default read options (default limits, block CRCs
    /// checked), stopping on voxels when the file has them, else on R-LODs.
    pub fn open(path: &Path) -> Result<Scene, TraceError> {
        Ok(Self::from_reader(Reader::open(
            path,
            ReadOptions::default(),
        )?))
    }

    /// A scene that stops on voxels when the file has them, else on R-LODs.
    pub fn from_reader(reader: Reader) -> Scene {
        let attrs = reader.metadata().triangle_attributes();
        let part_count = reader.metadata().parts.len();
        // R-LODs where the file has them: on the measurements of `docs/benchmarks.md` their
        // images are the closer to the true picture.
        let lod = if reader.lod_kinds().rlod {
            LodKind::Rlod
        } else {
            LodKind::Voxel
        };
        let node_bound = reader
            .entries()
            .iter()
            .filter(|e| e.kind == BlockKind::Treelet)
            .map(|e| u64::from(e.raw_length) / 8)
            .sum();
        Scene {
            reader,
            attrs,
            part_count,
            parts: RwLock::new(Arc::new(PartFilter::none())),
            section: RwLock::new(None),
            lod,
            node_bound,
        }
    }

    /// How many nodes the file's treelet blocks can hold (8 bytes is the smallest node): the
    /// most a ray meets in a well-formed tree, where it meets each node once at most. The
    /// traversal ends a ray there, so that a file whose treelets are shared cannot make one
    /// ray's work grow without bound (spec §12, "Following LOD links").
    pub fn node_bound(&self) -> u64 {
        self.node_bound
    }

    /// Stops on `lod`; an error when the file's LOD nodes do not carry it. Set it before any
    /// block is loaded: blocks are decoded for one kind.
    pub fn with_lod(mut self, lod: LodKind) -> Result<Scene, TraceError> {
        let kinds = self.reader.lod_kinds();
        let has = match lod {
            LodKind::Voxel => kinds.voxel,
            LodKind::Rlod => kinds.rlod,
        };
        if !has {
            return Err(TraceError::LodKind {
                path: self.reader.name().to_string(),
                asked: lod.name(),
                holds: kinds.name(),
            });
        }
        self.lod = lod;
        Ok(self)
    }

    /// The LOD representation the traversal stops on.
    pub fn lod(&self) -> LodKind {
        self.lod
    }

    /// Which parts frames show from now on (hidden, highlighted; [`crate::parts`]): made for
    /// this file's part table ([`PartFilter::new`] of [`Scene::metadata`]'s parts). A frame
    /// reads it once, at its start, and every ray of the frame (primary, shadow, occlusion)
    /// and every pick honours it; a frame already running keeps the filter it started with.
    pub fn set_parts(&self, filter: PartFilter) {
        let mut at = self.parts.write().unwrap_or_else(|e| e.into_inner());
        *at = Arc::new(filter);
    }

    /// [`Scene::set_parts`] with a filter already shared: a live view keeps its own and sets
    /// it before each of its frames without copying it.
    pub fn set_shared_parts(&self, filter: Arc<PartFilter>) {
        let mut at = self.parts.write().unwrap_or_else(|e| e.into_inner());
        *at = filter;
    }

    /// The part filter frames use now ([`Scene::set_parts`]; none at open).
    pub fn parts(&self) -> Arc<PartFilter> {
        let at = self.parts.read().unwrap_or_else(|e| e.into_inner());
        Arc::clone(&at)
    }

    /// The section plane frames clip their primary rays with from now on (world
    /// coordinates; None: no cut; [`crate::section`]). Read once at a frame's start, like the
    /// part filter; every pick honours it too.
    pub fn set_section(&self, section: Option<Section>) {
        let mut at = self.section.write().unwrap_or_else(|e| e.into_inner());
        *at = section;
    }

    /// The section plane frames use now ([`Scene::set_section`]; none at open).
    pub fn section(&self) -> Option<Section> {
        *self.section.read().unwrap_or_else(|e| e.into_inner())
    }

    /// The section plane in stored coordinates, as the rays are ([`Section::in_stored`]).
    pub fn stored_section(&self) -> Option<Section> {
        self.section()
            .map(|s| s.in_stored(self.metadata().scene.origin))
    }

    /// The container's metadata: the scene's bounds and origin, the schema, the root.
    pub fn metadata(&self) -> &Metadata {
        self.reader.metadata()
    }

    /// The container's reader, for the blocks and the directory.
    pub fn reader(&self) -> &Reader {
        &self.reader
    }

    /// The reader's proxies, loaded at open: a missing subtree always has something to show.
    pub fn proxies(&self) -> &[ProxyRecord] {
        self.reader.proxies()
    }

    /// How many blocks the container's directory lists (block ids run below it).
    pub fn block_count(&self) -> usize {
        self.reader.entries().len()
    }

    /// Reads, checks and decodes treelet block `id`.
    pub fn load_treelets(&self, id: u32) -> oocfmt::Result<TreeletData> {
        TreeletData::decode_as(
            &self.reader.read_block(id)?,
            self.lod,
            self.reader.entries(),
            self.part_count,
        )
    }

    /// Reads, checks and decodes triangle block `id`.
    pub fn load_triangles(&self, id: u32) -> oocfmt::Result<TriangleData> {
        TriangleData::decode(&self.reader.read_block(id)?, self.attrs, self.part_count)
    }
}
