//! The block spill: the chunks' encoded blocks, waiting for the file order. Blocks go to one
//! stream per treelet level and one for triangle blocks, each a series of segment files. The
//! file order takes each stream in the order it was written (level by level, chunk by chunk),
//! so a segment is deleted as soon as its last block is read: while the output grows, the
//! spill shrinks.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Write;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use oocfmt::BlockKind;

use super::disk::SpillDisk;
use super::OocError;

/// A block written to the spill, by place.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct SpilledBlock {
    pub kind: BlockKind,
    pub level: u16,
    pub item_count: u32,
    /// The segment (an index into the spill's list) and the block's place in it.
    pub segment: u32,
    pub offset: u64,
    pub len: u64,
    /// CRC-32C of its raw bytes, checked when it is read back.
    pub crc: u32,
}

/// One segment file of the block spill.
struct BlockSegment {
    path: PathBuf,
    bytes: u64,
    /// Blocks written to it and not yet read back.
    unread: u32,
    /// Open for writing while its stream appends to it; for reading once read from.
    file: Option<File>,
}

/// Spills raw blocks to per-stream segment files in `dir`.
pub struct BlockSpill {
    dir: PathBuf,
    disk: Arc<SpillDisk>,
    segments: Vec<BlockSegment>,
    /// The segment each stream appends to and the bytes the stream holds: by treelet level,
    /// `None` for triangle blocks.
    open: BTreeMap<Option<u16>, (u32, u64)>,
}

impl BlockSpill {
    /// An empty spill in `dir`; nothing is created before the first block.
    pub fn new(dir: &Path, disk: Arc<SpillDisk>) -> BlockSpill {
        BlockSpill {
            dir: dir.to_path_buf(),
            disk,
            segments: Vec::new(),
            open: BTreeMap::new(),
        }
    }

    /// Appends one block to its stream.
    pub fn push(
        &mut self,
        kind: BlockKind,
        level: u16,
        item_count: u32,
        raw: &[u8],
    ) -> Result<SpilledBlock, OocError> {
        let stream = (kind == BlockKind::Treelet).then_some(level);
        let len = raw.len() as u64;
        let k = self.segment_for(stream, len)?;
        if let Some((_, bytes)) = self.open.get_mut(&stream) {
            *bytes += len;
        }
        let seg = self
            .segments
            .get_mut(k as usize)
            .ok_or_else(|| OocError::corrupt(&self.dir, "a block segment is missing"))?;
        let offset = seg.bytes;
        let wrote = match seg.file.as_mut() {
            Some(f) => self.disk.charge(len).and_then(|()| f.write_all(raw)),
            None => Err(std::io::Error::other("the segment is closed")),
        };
        wrote.map_err(|source| OocError::SpillWrite {
            path: seg.path.display().to_string(),
            written: offset,
            source,
        })?;
        seg.bytes += len;
        seg.unread += 1;
        Ok(SpilledBlock {
            kind,
            level,
            item_count,
            segment: k,
            offset,
            len,
            crc: crc32c::crc32c(raw),
        })
    }

    /// The segment `stream` appends a block of `len` bytes to: its open one, or a new one when
    /// that would pass the segment size.
    fn segment_for(&mut self, stream: Option<u16>, len: u64) -> Result<u32, OocError> {
        let (open, stream_bytes) = match self.open.get(&stream) {
            Some(&(k, bytes)) => (Some(k), bytes),
            None => (None, 0),
        };
        if let Some(k) = open {
            let limit = self.disk.segment_limit(stream_bytes);
            match self.segments.get_mut(k as usize) {
                Some(s) if s.bytes + len <= limit => return Ok(k),
                Some(s) => s.file = None,
                None => {}
            }
        }
        let k = u32::try_from(self.segments.len())
            .map_err(|_| OocError::corrupt(&self.dir, "too many block segments"))?;
        let name = match stream {
            Some(level) => format!("blocks-t{level}.{k}"),
            None => format!("blocks-x.{k}"),
        };
        let path = self.dir.join(name);
        let file = File::create(&path).map_err(|e| OocError::spill(&path, e))?;
        self.segments.push(BlockSegment {
            path,
            bytes: 0,
            unread: 0,
            file: Some(file),
        });
        self.open.insert(stream, (k, stream_bytes));
        Ok(k)
    }

    /// Ends writing: every segment is closed, to be opened for reading when first read.
    pub fn close(&mut self) {
        self.open.clear();
        for s in &mut self.segments {
            s.file = None;
        }
    }

    /// Reads block `b` back; its segment is deleted once every block in it has been read.
    pub fn read(&mut self, b: &SpilledBlock) -> Result<Vec<u8>, OocError> {
        let seg = self
            .segments
            .get_mut(b.segment as usize)
            .filter(|s| s.unread > 0 && b.offset + b.len <= s.bytes)
            .ok_or_else(|| {
                OocError::corrupt(&self.dir, "a block is read twice or lies past its segment")
            })?;
        if seg.file.is_none() {
            let f = File::open(&seg.path).map_err(|e| OocError::spill(&seg.path, e))?;
            seg.file = Some(f);
        }
        let mut raw = vec![0u8; usize::try_from(b.len).unwrap_or(usize::MAX)];
        if let Some(f) = &seg.file {
            f.read_exact_at(&mut raw, b.offset)
                .map_err(|e| OocError::spill(&seg.path, e))?;
        }
        if crc32c::crc32c(&raw) != b.crc {
            return Err(OocError::corrupt(
                &seg.path,
                "a spilled block fails its checksum",
            ));
        }
        seg.unread -= 1;
        if seg.unread == 0 {
            seg.file = None;
            std::fs::remove_file(&seg.path).map_err(|e| OocError::spill(&seg.path, e))?;
            self.disk.release(seg.bytes);
        }
        Ok(raw)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_freed_segment_by_segment_as_they_are_read() -> Result<(), OocError> {
        let dir = tempfile::tempdir().map_err(|e| OocError::spill(Path::new("."), e))?;
        let disk = Arc::new(SpillDisk::with_segments(100, None));
        let mut spill = BlockSpill::new(dir.path(), disk.clone());
        let mut blocks = Vec::new();
        // Two chunks, each with level-1 and level-2 treelet blocks and triangle blocks.
        for chunk in 0..2u8 {
            for (kind, level) in [
                (BlockKind::Treelet, 1),
                (BlockKind::Treelet, 2),
                (BlockKind::Triangle, 0),
                (BlockKind::Triangle, 0),
            ] {
                let raw = vec![chunk * 16 + blocks.len() as u8; 40];
                blocks.push((spill.push(kind, level, 1, &raw)?, raw));
            }
        }
        spill.close();
        assert_eq!(disk.spill_bytes(), 8 * 40);
        // The file order: level 1, level 2, then triangle blocks, each in chunk order.
        let mut order: Vec<&(SpilledBlock, Vec<u8>)> = blocks.iter().collect();
        order.sort_by_key(|(b, _)| (b.kind == BlockKind::Triangle, b.level));
        let mut freed = Vec::new();
        for (b, raw) in order {
            assert_eq!(&spill.read(b)?, raw);
            freed.push(disk.spill_bytes());
        }
        // Two 40-byte blocks fit a 100-byte segment: each stream's segment goes once both of
        // its blocks are read, and the spill is empty after the last.
        assert_eq!(freed, [320, 240, 240, 160, 160, 80, 80, 0]);
        assert!(spill.read(&blocks[0].0).is_err());
        let left = std::fs::read_dir(dir.path())
            .map_err(|e| OocError::spill(dir.path(), e))?
            .count();
        assert_eq!(left, 0);
        Ok(())
    }
}
