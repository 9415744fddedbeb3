//! The reader: `open` validates header, trailer, directory and metadata and loads the proxies;
//! blocks are then fetched by id, checksummed and decompressed on demand.

use std::path::Path;
use std::sync::Arc;

use crate::checksum::{crc32c, Crc32c};
use crate::codec::decode_into;
use crate::direct::{open_source, Io, IoMode};
use crate::directory::{check_placement, BlockEntry, BlockKind, ENTRY_LEN};
use crate::error::{Code, Error, ErrorKind, Result};
use crate::header::{Header, SectionTable, HEADER_LEN, INCOMPAT_PART_IDS, OFF_HEADER_CRC};
use crate::metadata::Metadata;
use crate::mmap::MmapSource;
use crate::records::{LodKinds, ProxyRecord, TreeletBlock, TriangleBlock};
use crate::source::{ByteSource, FileSource};
use crate::trailer::{Trailer, TRAILER_LEN};

/// Sizes a reader accepts before it allocates (spec §12).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Longest metadata section accepted, in bytes (16 MiB by default).
    pub max_metadata_bytes: u32,
    /// Most bytes of proxy blocks loaded at open, Σ `raw_length` (1 GiB by default).
    pub max_resident_bytes: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_metadata_bytes: 16 << 20,
            max_resident_bytes: 1 << 30,
        }
    }
}

/// Whether to check block CRCs. Skipping them is for fuzzing, where the fuzzer must reach the
/// structural checks that stand behind them; a `--cfg fuzzing` build (cargo-fuzz passes it)
/// forces it. A cfg, unlike a Cargo feature, cannot be switched on by another crate in the graph.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Checksums {
    /// Check every block's CRC before decompressing it.
    #[default]
    Verify,
    /// Decompress blocks without checking their CRCs.
    Skip,
}

/// How a [`Reader`] opens a file and reads its blocks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Sizes accepted before allocating.
    pub limits: Limits,
    /// Whether block CRCs are checked.
    pub checksums: Checksums,
}

impl ReadOptions {
    pub(crate) fn check_crcs(&self) -> bool {
        self.checksums == Checksums::Verify && !cfg!(fuzzing)
    }
}

/// A decoded block: its id, its directory entry and its raw bytes.
#[derive(Clone, Debug)]
pub struct Block {
    /// Block id: the index of its directory entry.
    pub id: u32,
    /// The block's directory entry.
    pub entry: BlockEntry,
    /// The decompressed bytes, exactly `entry.raw_length` of them.
    pub data: Vec<u8>,
    /// The LOD kinds of the file it came from: the layout of a treelet block's LOD area.
    pub lod: LodKinds,
}

impl Block {
    /// Parses the block as a treelet block; fails if it is of another kind or malformed.
    pub fn treelets(&self) -> Result<TreeletBlock<'_>> {
        self.check_kind(BlockKind::Treelet)?;
        TreeletBlock::parse_with(&self.data, self.lod).map_err(|e| e.in_block(self.id))
    }

    /// Parses the block as a triangle block whose attribute bits must equal `attrs` (the
    /// metadata's [`Metadata::triangle_attributes`]); fails if it is of another kind or
    /// malformed.
    pub fn triangles(&self, attrs: u16) -> Result<TriangleBlock<'_>> {
        self.check_kind(BlockKind::Triangle)?;
        TriangleBlock::parse(&self.data, Some(attrs)).map_err(|e| e.in_block(self.id))
    }

    /// Decodes the block as a proxy block; fails if it is of another kind or malformed.
    pub fn proxies(&self) -> Result<Vec<ProxyRecord>> {
        self.check_kind(BlockKind::Proxy)?;
        ProxyRecord::decode_block(&self.data, self.entry.item_count as usize)
            .map_err(|e| e.in_block(self.id))
    }

    fn check_kind(&self, kind: BlockKind) -> Result<()> {
        if self.entry.kind != kind {
            return Err(Error::malformed(
                Code::TreeReference,
                format!(
                    "a {} block where a {} block was expected",
                    self.entry.kind.name(),
                    kind.name()
                ),
            )
            .in_block(self.id));
        }
        Ok(())
    }
}

/// The parts of a file that `open` loads and checks.
#[derive(Clone, Debug)]
pub struct Index {
    /// The validated header.
    pub header: Header,
    /// The validated trailer; its section table equals the header's.
    pub trailer: Trailer,
    /// The directory, indexed by block id, with placement checked.
    pub entries: Vec<BlockEntry>,
    /// The decoded metadata.
    pub metadata: Metadata,
}

/// An open `.oocf` file whose header, trailer, directory and metadata have been checked and
/// whose proxies are loaded; blocks are read by id. Every method takes `&self` and the reader
/// is `Sync`, so threads share one.
pub struct Reader {
    source: Box<dyn ByteSource>,
    name: Arc<str>,
    opts: ReadOptions,
    index: Index,
    proxies: Vec<ProxyRecord>,
}

impl Reader {
    /// Opens a file for positioned reads.
    pub fn open(path: &Path, opts: ReadOptions) -> Result<Reader> {
        let name: Arc<str> = Arc::from(path.display().to_string());
        let src = FileSource::open(path).map_err(|e| Error::io(e, 0).in_file(&name))?;
        Self::from_source(Box::new(src), name, opts)
    }

    /// Opens a file for positioned reads through the page cache or past it, as `io` asks
    /// ([`crate::direct`]); [`Reader::io_mode`] says which is in effect.
    pub fn open_with(path: &Path, opts: ReadOptions, io: Io) -> Result<Reader> {
        let name: Arc<str> = Arc::from(path.display().to_string());
        let src = open_source(path, io).map_err(|e| Error::io(e, 0).in_file(&name))?;
        Self::from_source(src, name, opts)
    }

    /// Opens a file through a read-only memory map (see the `mmap` module for the risk).
    pub fn open_mmap(path: &Path, opts: ReadOptions) -> Result<Reader> {
        let name: Arc<str> = Arc::from(path.display().to_string());
        let src = MmapSource::open(path).map_err(|e| Error::io(e, 0).in_file(&name))?;
        Self::from_source(Box::new(src), name, opts)
    }

    /// Opens a file from any byte source; `name` labels errors (usually the path).
    pub fn from_source(
        source: Box<dyn ByteSource>,
        name: Arc<str>,
        opts: ReadOptions,
    ) -> Result<Reader> {
        let inner = || -> Result<Reader> {
            let index = read_index(source.as_ref(), &opts)?;
            let proxies = load_proxies(source.as_ref(), &index.entries, &opts)?;
            Ok(Reader {
                source,
                name: Arc::clone(&name),
                opts,
                index,
                proxies,
            })
        };
        inner().map_err(|e| e.in_file(&name))
    }

    /// The name errors carry: the path as displayed, or the name given to `from_source`.
    pub fn name(&self) -> &Arc<str> {
        &self.name
    }

    /// Which LOD representations the file's LOD nodes carry (header feature bits).
    pub fn lod_kinds(&self) -> LodKinds {
        LodKinds::of_header(&self.index.header)
    }

    /// The validated header.
    pub fn header(&self) -> &Header {
        &self.index.header
    }

    /// The validated trailer.
    pub fn trailer(&self) -> &Trailer {
        &self.index.trailer
    }

    /// The directory, indexed by block id.
    pub fn entries(&self) -> &[BlockEntry] {
        &self.index.entries
    }

    /// The directory entry of block `id`; a `TREE_REFERENCE` error if there is no such block.
    pub fn entry(&self, id: u32) -> Result<&BlockEntry> {
        self.index.entries.get(id as usize).ok_or_else(|| {
            Error::malformed(
                Code::TreeReference,
                format!("block {id} of {}", self.index.entries.len()),
            )
            .in_file(&self.name)
        })
    }

    /// The decoded metadata.
    pub fn metadata(&self) -> &Metadata {
        &self.index.metadata
    }

    /// All proxies, indexed by proxy id; loaded at open.
    pub fn proxies(&self) -> &[ProxyRecord] {
        &self.proxies
    }

    /// The file identity: the root checksum (spec §10).
    pub fn identity(&self) -> u32 {
        self.index.trailer.root_checksum
    }

    /// Length of the file in bytes.
    pub fn file_len(&self) -> u64 {
        self.source.len()
    }

    /// The bytes the reader reads from.
    pub fn source(&self) -> &dyn ByteSource {
        self.source.as_ref()
    }

    /// How the reader's reads meet the operating system's page cache.
    pub fn io_mode(&self) -> IoMode {
        self.source.io_mode()
    }

    /// Reads, checks and decompresses block `id`.
    pub fn read_block(&self, id: u32) -> Result<Block> {
        let entry = *self.entry(id)?;
        let data = read_block_data(self.source.as_ref(), &entry, &self.opts)
            .map_err(|e| e.in_block(id).in_file(&self.name))?;
        Ok(Block {
            id,
            entry,
            data,
            lod: self.lod_kinds(),
        })
    }

    /// The stored bytes of block `id` without a copy, where the source is memory (a map).
    pub fn stored_slice(&self, id: u32) -> Option<&[u8]> {
        let e = self.index.entries.get(id as usize)?;
        let all = self.source.as_slice()?;
        all.get(usize::try_from(e.offset).ok()?..usize::try_from(e.end()).ok()?)
    }
}

/// Reads one block's stored bytes, checks the CRC and decompresses into exactly `raw_length`.
pub fn read_block_data(
    src: &dyn ByteSource,
    e: &BlockEntry,
    opts: &ReadOptions,
) -> Result<Vec<u8>> {
    if e.offset
        .checked_add(u64::from(e.stored_length))
        .is_none_or(|end| end > src.len())
    {
        return Err(Error::malformed(
            Code::EntryOffset,
            format!(
                "block bytes {}+{} pass the end of the file",
                e.offset, e.stored_length
            ),
        )
        .at(e.offset));
    }
    let mut stored_buf;
    let stored: &[u8] = match src
        .as_slice()
        .and_then(|s| s.get(usize::try_from(e.offset).ok()?..usize::try_from(e.end()).ok()?))
    {
        Some(s) => s,
        None => {
            stored_buf = vec![0u8; e.stored_length as usize];
            src.read_exact_at(e.offset, &mut stored_buf)
                .map_err(|err| Error::io(err, e.offset))?;
            &stored_buf
        }
    };
    if opts.check_crcs() {
        let computed = crc32c(stored);
        if computed != e.crc {
            return Err(Error::new(ErrorKind::Checksum {
                code: Code::BlockChecksum,
                what: "block",
                stored: e.crc,
                computed,
            })
            .at(e.offset));
        }
    }
    let mut raw = vec![0u8; e.raw_length as usize];
    decode_into(e.codec, stored, &mut raw).map_err(|err| err.at(e.offset))?;
    Ok(raw)
}

/// Reads `len` bytes at `offset` after checking they lie in the source.
pub(crate) fn read_vec(src: &dyn ByteSource, offset: u64, len: u64) -> Result<Vec<u8>> {
    if offset.checked_add(len).is_none_or(|end| end > src.len()) {
        return Err(Error::malformed(
            Code::Layout,
            format!(
                "{len} bytes at {offset} pass the end of the file ({} bytes)",
                src.len()
            ),
        )
        .at(offset));
    }
    let mut v = vec![0u8; len as usize];
    src.read_exact_at(offset, &mut v)
        .map_err(|e| Error::io(e, offset))?;
    Ok(v)
}

/// Reads and checks the header (fixed 64 bytes at 0).
pub fn read_header(src: &dyn ByteSource) -> Result<(Header, Vec<u8>)> {
    let min = (HEADER_LEN + TRAILER_LEN) as u64;
    if src.len() < min {
        return Err(short_file_error(src)?);
    }
    let bytes = read_vec(src, 0, HEADER_LEN as u64)?;
    Ok((Header::decode(&bytes)?, bytes))
}

/// The error for a file too short to hold header and trailer. Spec §11 asks for a foreign
/// magic or major version to be named as such, so the first bytes are still looked at.
pub fn short_file_error(src: &dyn ByteSource) -> Result<Error> {
    let min = (HEADER_LEN + TRAILER_LEN) as u64;
    let mut head = read_vec(src, 0, src.len().min(HEADER_LEN as u64))?;
    let known = head.len() >= crate::header::OFF_MINOR + 2;
    head.resize(HEADER_LEN, 0);
    let too_small = Error::malformed(
        Code::FileTooSmall,
        format!("{} bytes, less than header and trailer ({min})", src.len()),
    );
    Ok(match Header::decode_unchecked(&head) {
        Err(e)
            if known && matches!(e.code(), Code::HeaderVersionUnsupported | Code::HeaderMagic) =>
        {
            e
        }
        _ => too_small,
    })
}

/// Reads and checks the trailer (the last 48 bytes of `src`).
pub fn read_trailer(src: &dyn ByteSource) -> Result<Trailer> {
    let at = src.len().saturating_sub(TRAILER_LEN as u64);
    let bytes = read_vec(src, at, TRAILER_LEN as u64)?;
    Trailer::decode(&bytes, at)
}

/// Reads the directory of `sections` and checks its CRC (when `crc` is given) and entries.
pub fn read_directory(
    src: &dyn ByteSource,
    sections: &SectionTable,
    block_size: u32,
    crc: Option<u32>,
) -> Result<(Vec<BlockEntry>, Vec<u8>)> {
    let len = u64::from(sections.block_count) * ENTRY_LEN as u64;
    let bytes = read_vec(src, sections.directory_offset, len)?;
    if let Some(stored) = crc {
        let computed = crc32c(&bytes);
        if computed != stored {
            return Err(Error::new(ErrorKind::Checksum {
                code: Code::DirectoryChecksum,
                what: "directory",
                stored,
                computed,
            })
            .at(sections.directory_offset));
        }
    }
    let entries = bytes
        .chunks_exact(ENTRY_LEN)
        .zip(0u32..)
        .map(|(b, id)| {
            BlockEntry::decode(b, block_size).map_err(|e| {
                e.in_block(id)
                    .at(sections.directory_offset + u64::from(id) * ENTRY_LEN as u64)
            })
        })
        .collect::<Result<Vec<_>>>()?;
    if let Some((id, e)) = check_placement(&entries, sections.directory_offset)
        .into_iter()
        .next()
    {
        return Err(e.in_block(id));
    }
    Ok((entries, bytes))
}

/// Reads and decodes the metadata, checking length limit and CRC.
pub fn read_metadata(
    src: &dyn ByteSource,
    header: &Header,
    trailer: &Trailer,
    limits: &Limits,
) -> Result<(Metadata, Vec<u8>)> {
    let s = &trailer.sections;
    if s.metadata_length > limits.max_metadata_bytes {
        return Err(Error::new(ErrorKind::Limit {
            code: Code::MetadataLimit,
            what: "metadata",
            requested: u64::from(s.metadata_length),
            limit: u64::from(limits.max_metadata_bytes),
        })
        .at(s.metadata_offset));
    }
    let bytes = read_vec(src, s.metadata_offset, u64::from(s.metadata_length))?;
    let computed = crc32c(&bytes);
    if computed != trailer.metadata_crc {
        return Err(Error::new(ErrorKind::Checksum {
            code: Code::MetadataChecksum,
            what: "metadata",
            stored: trailer.metadata_crc,
            computed,
        })
        .at(s.metadata_offset));
    }
    let meta = Metadata::decode(&bytes, header.minor).map_err(|e| e.at(s.metadata_offset))?;
    check_part_ids(header, &meta).map_err(|e| e.at(s.metadata_offset))?;
    Ok((meta, bytes))
}

/// `PART_IDS` is set exactly when the part table has two or more parts (spec §3): the bit fixes
/// the layout of every triangle block and LOD entry, the table the ids' range.
pub fn check_part_ids(header: &Header, meta: &Metadata) -> Result<()> {
    let bit = header.incompatible_features & INCOMPAT_PART_IDS != 0;
    let parts = meta.parts.len();
    if bit != (parts >= 2) {
        let said = if bit { "sets" } else { "does not set" };
        return Err(Error::malformed(
            Code::PartTable,
            format!("the header {said} PART_IDS but the part table has {parts} parts"),
        ));
    }
    Ok(())
}

/// The root checksum over header, directory and metadata bytes.
pub fn root_checksum(header: &[u8], directory: &[u8], metadata: &[u8]) -> u32 {
    let mut c = Crc32c::new();
    c.update(header.get(..OFF_HEADER_CRC).unwrap_or(header));
    c.update(directory);
    c.update(metadata);
    c.finish()
}

fn read_index(src: &dyn ByteSource, opts: &ReadOptions) -> Result<Index> {
    let (header, header_bytes) = read_header(src)?;
    let trailer = read_trailer(src)?;
    if header.sections != trailer.sections {
        return Err(Error::malformed(
            Code::Layout,
            format!(
                "header says {:?}, trailer says {:?}",
                header.sections, trailer.sections
            ),
        ));
    }
    header.sections.check_tiling(src.len())?;
    let (entries, dir_bytes) = read_directory(
        src,
        &header.sections,
        header.block_size(),
        Some(trailer.directory_crc),
    )?;
    let (metadata, meta_bytes) = read_metadata(src, &header, &trailer, &opts.limits)?;
    let computed = root_checksum(&header_bytes, &dir_bytes, &meta_bytes);
    if computed != trailer.root_checksum {
        return Err(Error::new(ErrorKind::Checksum {
            code: Code::RootChecksum,
            what: "root",
            stored: trailer.root_checksum,
            computed,
        }));
    }
    Ok(Index {
        header,
        trailer,
        entries,
        metadata,
    })
}

fn load_proxies(
    src: &dyn ByteSource,
    entries: &[BlockEntry],
    opts: &ReadOptions,
) -> Result<Vec<ProxyRecord>> {
    let resident: u64 = entries
        .iter()
        .filter(|e| e.kind == BlockKind::Proxy)
        .map(|e| u64::from(e.raw_length))
        .sum();
    if resident > opts.limits.max_resident_bytes {
        return Err(Error::limit(
            "resident proxies",
            resident,
            opts.limits.max_resident_bytes,
        ));
    }
    // Grown block by block: reserving the declared total up front would let a small file with
    // lying directory entries claim up to the whole limit before any block proves itself.
    let mut proxies = Vec::new();
    for (id, e) in (0u32..).zip(entries) {
        if e.kind == BlockKind::Proxy {
            let data = read_block_data(src, e, opts).map_err(|err| err.in_block(id))?;
            let block = ProxyRecord::decode_block(&data, e.item_count as usize)
                .map_err(|err| err.in_block(id))?;
            proxies.extend(block);
        }
    }
    Ok(proxies)
}
