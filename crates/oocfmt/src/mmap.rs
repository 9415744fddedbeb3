//! The memory-mapped source: the crate's only `unsafe`, fenced here.
//!
//! Opting in is explicit (`Reader::open_mmap`). The risk it carries: if another process
//! truncates or rewrites the file while it is mapped, reads of the lost pages fault (SIGBUS)
//! or see changing bytes. oocfmt never modifies a finished file (writers rename a new one into
//! place), so the risk is limited to outside tools.
#![allow(unsafe_code)]

use std::fs::File;
use std::io;
use std::path::Path;

use crate::source::{slice_read, ByteSource};

/// A read-only memory map of a whole file, read without copies through
/// [`ByteSource::as_slice`]; its length is fixed when mapped.
pub struct MmapSource {
    map: memmap2::Mmap,
}

impl MmapSource {
    /// Opens and maps the file at `path`; see the module documentation for the risk.
    pub fn open(path: &Path) -> io::Result<Self> {
        let file = File::open(path)?;
        // SAFETY: the map is read-only and private to this process. The bytes may change only
        // if another process modifies the file, which the module documentation warns about;
        // every read through the map is bounds-checked against the length fixed at map time.
        let map = unsafe { memmap2::Mmap::map(&file)? };
        Ok(MmapSource { map })
    }
}

impl ByteSource for MmapSource {
    fn len(&self) -> u64 {
        self.map.len() as u64
    }

    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        slice_read(&self.map, offset, buf)
    }

    fn as_slice(&self) -> Option<&[u8]> {
        Some(&self.map)
    }
}
