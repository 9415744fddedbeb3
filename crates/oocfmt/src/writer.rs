//! The streaming, atomic writer: blocks are appended as they come; directory, metadata and
//! trailer follow at the end; the file appears under its final name only once complete.

use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::checksum::{crc32c, Crc32c};
use crate::codec::Codec;
use crate::directory::{BlockEntry, BlockKind, CodecId};
use crate::error::{Error, Result};
use crate::header::{
    Header, SectionTable, COMPAT_LOD_VOXELS, COMPAT_PROXIES, DEFAULT_BLOCK_SIZE_LOG2, HEADER_LEN,
    INCOMPAT_PART_IDS, MAX_BLOCK_SIZE_LOG2, MIN_BLOCK_SIZE_LOG2, OFF_HEADER_CRC,
};
use crate::metadata::Metadata;
use crate::records::LodKinds;
use crate::trailer::Trailer;

/// The file under construction. `sync` must make everything written durable.
pub trait OutputFile: Write + Seek {
    /// Flushes buffers and makes every byte written durable (fsync).
    fn sync(&mut self) -> io::Result<()>;
}

impl OutputFile for BufWriter<File> {
    fn sync(&mut self) -> io::Result<()> {
        self.flush()?;
        self.get_ref().sync_all()
    }
}

/// How a [`Writer`] lays out and compresses a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WriteOptions {
    /// Log2 of the block size in bytes, 12 ..= 20 (default 16: 64 KiB).
    pub block_size_log2: u8,
    /// The codec blocks are compressed with; a block it does not shrink is stored raw.
    pub codec: Codec,
    /// What the LOD nodes carry: the header's LOD feature bits and the minor version
    /// ([`LodKinds::minor_version`]). Pre-filtered voxels by default. The `PART_IDS` bit and
    /// minor 3 also follow from the metadata's part table at [`Writer::finish`] (the blocks
    /// must then carry part ids and part words), which refuses `parts` set here without two or
    /// more parts.
    pub lod: LodKinds,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            block_size_log2: DEFAULT_BLOCK_SIZE_LOG2,
            codec: Codec::default(),
            lod: LodKinds::VOXEL.filtered(),
        }
    }
}

impl WriteOptions {
    /// Block size in bytes, which must be a power of two in 4 KiB ..= 1 MiB.
    pub fn with_block_size(mut self, bytes: u64) -> Result<Self> {
        let log2 = bytes.trailing_zeros();
        if !bytes.is_power_of_two()
            || !(u32::from(MIN_BLOCK_SIZE_LOG2)..=u32::from(MAX_BLOCK_SIZE_LOG2)).contains(&log2)
        {
            return Err(Error::parameter(format!(
                "block size {bytes}: expected a power of two from 4096 to 1048576"
            )));
        }
        self.block_size_log2 = log2 as u8;
        Ok(self)
    }
}

/// A block compressed and checksummed, ready to append. Building these is the expensive part,
/// so callers may do it on many threads and append in order.
#[derive(Clone, Debug)]
pub struct EncodedBlock {
    /// What the block holds.
    pub kind: BlockKind,
    /// LOD level of a treelet block; zero for other kinds.
    pub level: u16,
    /// Treelets, triangles or proxies in the block.
    pub item_count: u32,
    /// Bytes before compression.
    pub raw_length: u32,
    /// The codec the stored bytes are in: [`CodecId::None`] when compressing did not shrink them.
    pub codec: CodecId,
    /// CRC-32C of `stored`.
    pub crc: u32,
    /// The bytes to store in the file.
    pub stored: Vec<u8>,
}

impl EncodedBlock {
    /// Compresses `raw` with `codec` (raw when that does not make it smaller) and checksums the
    /// result; it needs no [`Writer`], so it can run on any thread.
    pub fn encode(
        codec: Codec,
        kind: BlockKind,
        level: u16,
        item_count: u32,
        raw: &[u8],
    ) -> Result<Self> {
        let (codec, stored) = codec.encode(raw)?;
        Ok(EncodedBlock {
            kind,
            level,
            item_count,
            raw_length: u32::try_from(raw.len())
                .map_err(|_| Error::parameter("block over 4 GiB"))?,
            codec,
            crc: crc32c(&stored),
            stored,
        })
    }
}

/// What a finished write produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WriteSummary {
    /// Length of the finished file in bytes.
    pub file_length: u64,
    /// Blocks written.
    pub block_count: u32,
    /// The file's root checksum (spec §10).
    pub identity: u32,
}

/// Writes an `.oocf` file: blocks are appended in order to a temporary file beside the
/// target, which [`Writer::finish`] completes and renames into place; dropping the writer
/// unfinished removes the temporary file.
pub struct Writer<F: OutputFile = BufWriter<File>> {
    out: Option<F>,
    temp: PathBuf,
    target: PathBuf,
    header: Header,
    codec: Codec,
    entries: Vec<BlockEntry>,
    pos: u64,
    last_level: u16,
}

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

impl Writer {
    /// Starts writing `path`. Nothing appears under that name (and an existing file there is
    /// untouched) until [`Writer::finish`] succeeds.
    pub fn create(path: &Path, opts: WriteOptions) -> Result<Self> {
        Self::create_with(path, opts, |f| Ok(BufWriter::with_capacity(1 << 20, f)))
    }
}

impl<F: OutputFile> Writer<F> {
    /// Like [`Writer::create`], wrapping the temporary file (used to inject faults in tests).
    pub fn create_with(
        path: &Path,
        opts: WriteOptions,
        wrap: impl FnOnce(File) -> io::Result<F>,
    ) -> Result<Self> {
        if !(MIN_BLOCK_SIZE_LOG2..=MAX_BLOCK_SIZE_LOG2).contains(&opts.block_size_log2) {
            return Err(Error::parameter(format!(
                "block size 2^{} is outside 2^12 ..= 2^20",
                opts.block_size_log2
            )));
        }
        let temp = temp_path(path)?;
        let file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp)
            .map_err(|e| {
                Error::io(e, 0).in_file(&std::sync::Arc::from(temp.display().to_string()))
            })?;
        let mut w = Writer {
            out: None,
            temp,
            target: path.to_path_buf(),
            header: {
                let mut h = Header::new(opts.block_size_log2);
                h.incompatible_features = opts.lod.incompatible_bits();
                h.minor = opts.lod.minor_version();
                h
            },
            codec: opts.codec,
            entries: Vec::new(),
            pos: HEADER_LEN as u64,
            last_level: 0,
        };
        // A placeholder header; the real one is written by `finish`.
        let started =
            wrap(file).and_then(|mut out| out.write_all(&[0u8; HEADER_LEN]).map(|()| out));
        match started {
            Ok(out) => {
                w.out = Some(out);
                Ok(w)
            }
            Err(e) => {
                w.discard();
                Err(Error::io(e, 0))
            }
        }
    }

    /// The block size in bytes: the most raw bytes a block may hold.
    pub fn block_size(&self) -> u32 {
        self.header.block_size()
    }

    /// Blocks written so far; the next block gets this id.
    pub fn block_count(&self) -> u32 {
        self.entries.len() as u32
    }

    /// The codec blocks written through [`Writer::write_block`] are compressed with.
    pub fn codec(&self) -> Codec {
        self.codec
    }

    /// Compresses and appends one block; returns its id.
    pub fn write_block(
        &mut self,
        kind: BlockKind,
        level: u16,
        item_count: u32,
        raw: &[u8],
    ) -> Result<u32> {
        self.check_block(kind, level, item_count, raw.len())?;
        let block = EncodedBlock::encode(self.codec, kind, level, item_count, raw)?;
        self.write_encoded(block)
    }

    /// Appends a block encoded elsewhere; returns its id.
    pub fn write_encoded(&mut self, b: EncodedBlock) -> Result<u32> {
        self.check_block(b.kind, b.level, b.item_count, b.raw_length as usize)?;
        // The block may come from anywhere: check the rules of spec §4 so this writer never
        // produces a file its reader refuses.
        let stored = b.stored.len();
        let fits = match b.codec {
            CodecId::None => stored == b.raw_length as usize,
            CodecId::Lz4 | CodecId::Zstd => stored >= 1 && stored < b.raw_length as usize,
        };
        if !fits || crc32c(&b.stored) != b.crc {
            return Err(Error::parameter(format!(
                "encoded block: {stored} stored bytes, raw length {}, codec {}, crc {:#010x} are inconsistent",
                b.raw_length,
                b.codec.name(),
                b.crc
            )));
        }
        let id = u32::try_from(self.entries.len())
            .ok()
            .filter(|&id| id < u32::MAX)
            .ok_or_else(|| Error::parameter("too many blocks"))?;
        let entry = BlockEntry {
            offset: self.pos,
            stored_length: b.stored.len() as u32,
            raw_length: b.raw_length,
            crc: b.crc,
            kind: b.kind,
            codec: b.codec,
            level: b.level,
            item_count: b.item_count,
        };
        let pos = self.pos;
        if let Err(e) = self.out_mut()?.write_all(&b.stored) {
            self.discard();
            return Err(Error::io(e, pos).in_block(id));
        }
        self.pos += b.stored.len() as u64;
        if b.kind == BlockKind::Treelet {
            self.last_level = b.level;
        }
        self.entries.push(entry);
        Ok(id)
    }

    fn check_block(
        &self,
        kind: BlockKind,
        level: u16,
        item_count: u32,
        raw_len: usize,
    ) -> Result<()> {
        let bs = self.block_size() as usize;
        if raw_len == 0 || raw_len > bs {
            return Err(Error::parameter(format!(
                "a {}-byte block does not fit the block size {bs}",
                raw_len
            )));
        }
        if item_count == 0 {
            return Err(Error::parameter("a block must hold at least one item"));
        }
        if kind != BlockKind::Treelet && level != 0 {
            return Err(Error::parameter("only treelet blocks have a level"));
        }
        if kind == BlockKind::Treelet && level < self.last_level {
            return Err(Error::parameter(format!(
                "treelet level {level} after level {}",
                self.last_level
            )));
        }
        Ok(())
    }

    fn out_mut(&mut self) -> Result<&mut F> {
        self.out
            .as_mut()
            .ok_or_else(|| Error::parameter("the writer failed earlier and is closed"))
    }

    /// Writes directory, metadata, trailer and header, makes the file durable and renames it
    /// into place.
    pub fn finish(mut self, metadata: &Metadata) -> Result<WriteSummary> {
        let result = self.finish_inner(metadata);
        if result.is_err() {
            self.discard();
        }
        result
    }

    fn finish_inner(&mut self, metadata: &Metadata) -> Result<WriteSummary> {
        let mut dir = Vec::with_capacity(self.entries.len() * crate::directory::ENTRY_LEN);
        for e in &self.entries {
            e.encode_into(&mut dir);
        }
        // Never write metadata that the reader would refuse.
        metadata
            .check()
            .map_err(|e| Error::parameter(e.kind.to_string()))?;
        let meta = metadata.encode()?;
        let metadata_length =
            u32::try_from(meta.len()).map_err(|_| Error::parameter("metadata over 4 GiB"))?;
        let sections = SectionTable {
            directory_offset: self.pos,
            block_count: self.block_count(),
            metadata_offset: self.pos + dir.len() as u64,
            metadata_length,
        };
        self.header.sections = sections;
        if self.entries.iter().any(|e| e.kind == BlockKind::Proxy) {
            self.header.compatible_features |= COMPAT_PROXIES;
        }
        if metadata.counts.lod_nodes > 0 {
            self.header.compatible_features |= COMPAT_LOD_VOXELS;
        }
        // The part table decides the part ids' bit and the minor (spec §3, §9).
        let part_ids = metadata.parts.len() >= 2;
        if self.header.incompatible_features & INCOMPAT_PART_IDS != 0 && !part_ids {
            return Err(Error::parameter(format!(
                "the LOD entries were announced with part words, but the part table has {} parts (part ids need two or more)",
                metadata.parts.len()
            )));
        }
        if part_ids {
            self.header.incompatible_features |= INCOMPAT_PART_IDS;
        }
        self.header.minor = self.header.minor.max(metadata.minor_version());
        let header = self.header.encode();
        let mut root = Crc32c::new();
        root.update(&header[..OFF_HEADER_CRC]);
        root.update(&dir);
        root.update(&meta);
        let trailer = Trailer {
            sections,
            directory_crc: crc32c(&dir),
            metadata_crc: crc32c(&meta),
            root_checksum: root.finish(),
        };
        let tail_at = self.pos;
        let out = self.out_mut()?;
        let io = |e| Error::io(e, tail_at);
        out.write_all(&dir).map_err(io)?;
        out.write_all(&meta).map_err(io)?;
        out.write_all(&trailer.encode()).map_err(io)?;
        out.seek(SeekFrom::Start(0)).map_err(|e| Error::io(e, 0))?;
        out.write_all(&header).map_err(|e| Error::io(e, 0))?;
        out.sync().map_err(|e| Error::io(e, 0))?;
        drop(self.out.take());
        std::fs::rename(&self.temp, &self.target).map_err(|e| Error::io(e, 0))?;
        sync_parent(&self.target);
        Ok(WriteSummary {
            file_length: sections.trailer_offset().unwrap_or(0)
                + crate::trailer::TRAILER_LEN as u64,
            block_count: sections.block_count,
            identity: trailer.root_checksum,
        })
    }

    fn discard(&mut self) {
        drop(self.out.take());
        let _ = std::fs::remove_file(&self.temp);
    }

    /// The temporary file being written (for tests).
    pub fn temp_path(&self) -> &Path {
        &self.temp
    }
}

impl<F: OutputFile> Drop for Writer<F> {
    fn drop(&mut self) {
        if self.out.is_some() {
            self.discard();
        }
    }
}

fn temp_path(target: &Path) -> Result<PathBuf> {
    let name = target
        .file_name()
        .ok_or_else(|| Error::parameter(format!("{}: not a file path", target.display())))?;
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let temp_name = format!(
        ".{}.{}-{n}.partial",
        name.to_string_lossy(),
        std::process::id()
    );
    Ok(target.with_file_name(temp_name))
}

/// Makes the rename durable where the platform allows it.
fn sync_parent(target: &Path) {
    #[cfg(unix)]
    if let Some(dir) = target.parent() {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
    }
    #[cfg(not(unix))]
    let _ = target;
}
