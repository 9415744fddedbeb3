//! An open container: the reader, its metadata and the resident proxies.

use std::path::Path;

use oocfmt::metadata::Metadata;
use oocfmt::records::ProxyRecord;
use oocfmt::{ReadOptions, Reader};

use crate::blocks::{TreeletData, TriangleData};
use crate::error::TraceError;

pub struct Scene {
    reader: Reader,
    attrs: u16,
    /// Loaded at open (the reader does it): a missing subtree always has something to show.
    proxies: Vec<ProxyRecord>,
}

impl Scene {
    pub fn open(path: &Path) -> Result<Scene, TraceError> {
        Ok(Self::from_reader(Reader::open(
            path,
            ReadOptions::default(),
        )?))
    }

    pub fn from_reader(reader: Reader) -> Scene {
        let attrs = reader.metadata().schema.triangle_attributes();
        let proxies = reader.proxies().to_vec();
        Scene {
            reader,
            attrs,
            proxies,
        }
    }

    pub fn metadata(&self) -> &Metadata {
        self.reader.metadata()
    }

    pub fn reader(&self) -> &Reader {
        &self.reader
    }

    pub fn proxies(&self) -> &[ProxyRecord] {
        &self.proxies
    }

    pub fn block_count(&self) -> usize {
        self.reader.entries().len()
    }

    /// Reads, checks and decodes treelet block `id`.
    pub fn load_treelets(&self, id: u32) -> oocfmt::Result<TreeletData> {
        TreeletData::decode(&self.reader.read_block(id)?)
    }

    /// Reads, checks and decodes triangle block `id`.
    pub fn load_triangles(&self, id: u32) -> oocfmt::Result<TriangleData> {
        TriangleData::decode(&self.reader.read_block(id)?, self.attrs)
    }
}
