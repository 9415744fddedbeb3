//! The block directory: one 32-byte entry per block (spec §4).

use crate::bytes::{u16_at, u32_at, u64_at, PutLe};
use crate::error::{bad, Code, Error, Result};
use crate::header::HEADER_LEN;

/// Byte offset in a directory entry of the `u64` file offset of the block's stored bytes.
pub const OFF_OFFSET: usize = 0;
/// Byte offset in a directory entry of the `u32` number of bytes stored in the file.
pub const OFF_STORED_LENGTH: usize = OFF_OFFSET + 8;
/// Byte offset in a directory entry of the `u32` number of bytes after decompression.
pub const OFF_RAW_LENGTH: usize = OFF_STORED_LENGTH + 4;
/// Byte offset in a directory entry of the CRC-32C of the stored bytes.
pub const OFF_CRC: usize = OFF_RAW_LENGTH + 4;
/// Byte offset in a directory entry of the `u8` [`BlockKind`].
pub const OFF_KIND: usize = OFF_CRC + 4;
/// Byte offset in a directory entry of the `u8` [`CodecId`].
pub const OFF_CODEC: usize = OFF_KIND + 1;
/// Byte offset in a directory entry of the `u16` LOD level (treelet blocks; zero otherwise).
pub const OFF_LEVEL: usize = OFF_CODEC + 1;
/// Byte offset in a directory entry of the `u32` count of treelets, triangles or proxies.
pub const OFF_ITEM_COUNT: usize = OFF_LEVEL + 2;
/// Byte offset in a directory entry of a reserved `u32` that must be zero.
pub const OFF_RESERVED: usize = OFF_ITEM_COUNT + 4;
/// Length of one directory entry in bytes (32).
pub const ENTRY_LEN: usize = OFF_RESERVED + 4;

/// What a block holds.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum BlockKind {
    /// Treelets of the kd-tree of one LOD level, with their LOD entries (spec §6).
    Treelet = 1,
    /// Triangles, their vertices and the leaves' index lists (spec §8).
    Triangle = 2,
    /// 80-byte directional proxies, loaded when the file opens (spec §7).
    Proxy = 3,
}

impl BlockKind {
    /// The kind stored as `v` in a directory entry, or `None` for an unknown kind.
    pub fn from_u8(v: u8) -> Option<Self> {
        match v {
            1 => Some(BlockKind::Treelet),
            2 => Some(BlockKind::Triangle),
            3 => Some(BlockKind::Proxy),
            _ => None,
        }
    }

    /// Lowercase name, as in messages and JSON output.
    pub fn name(self) -> &'static str {
        match self {
            BlockKind::Treelet => "treelet",
            BlockKind::Triangle => "triangle",
            BlockKind::Proxy => "proxy",
        }
    }
}

/// How a block's stored bytes encode its raw bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CodecId {
    /// Stored bytes are the raw bytes.
    None = 0,
    /// One raw LZ4 block, without frame header or size prefix.
    Lz4 = 1,
    /// One zstd frame (RFC 8878).
    Zstd = 2,
}

impl CodecId {
    /// The codec stored as `v` in a directory entry, or `None` for an unknown codec.
    pub fn from_u8(v: u8) -> Option<Self> {
        match v {
            0 => Some(CodecId::None),
            1 => Some(CodecId::Lz4),
            2 => Some(CodecId::Zstd),
            _ => None,
        }
    }

    /// Lowercase name, as in messages and JSON output.
    pub fn name(self) -> &'static str {
        match self {
            CodecId::None => "none",
            CodecId::Lz4 => "lz4",
            CodecId::Zstd => "zstd",
        }
    }
}

/// One directory entry: where a block lies, how it is stored and what it holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockEntry {
    /// File offset of the block's stored bytes (64 for block 0, then packed back to back).
    pub offset: u64,
    /// Bytes the block takes in the file; below `raw_length` when compressed.
    pub stored_length: u32,
    /// Bytes after decompression, `1..=` the block size: the exact size of the decode buffer.
    pub raw_length: u32,
    /// CRC-32C of the stored bytes.
    pub crc: u32,
    /// What the block holds.
    pub kind: BlockKind,
    /// How the stored bytes encode the raw bytes.
    pub codec: CodecId,
    /// LOD level of a treelet block (never decreasing in block order); zero for other kinds.
    pub level: u16,
    /// Treelets, triangles or proxies in the block; at least 1.
    pub item_count: u32,
}

impl BlockEntry {
    /// Appends the entry's 32 bytes to `v`.
    pub fn encode_into(&self, v: &mut Vec<u8>) {
        v.put_u64(self.offset);
        v.put_u32(self.stored_length);
        v.put_u32(self.raw_length);
        v.put_u32(self.crc);
        v.push(self.kind as u8);
        v.push(self.codec as u8);
        v.put_u16(self.level);
        v.put_u32(self.item_count);
        v.put_u32(0);
    }

    /// Decodes one entry and checks what it can alone: kind, codec, reserved bytes and lengths.
    pub fn decode(b: &[u8], block_size: u32) -> Result<BlockEntry> {
        let kind_byte = *b
            .get(OFF_KIND)
            .ok_or_else(|| Error::malformed(Code::Layout, "short directory entry"))?;
        let codec_byte = *b
            .get(OFF_CODEC)
            .ok_or_else(|| Error::malformed(Code::Layout, "short directory entry"))?;
        let kind = BlockKind::from_u8(kind_byte).ok_or_else(|| {
            Error::malformed(Code::EntryKind, format!("unknown block kind {kind_byte}"))
        })?;
        let codec = CodecId::from_u8(codec_byte).ok_or_else(|| {
            Error::malformed(Code::EntryCodec, format!("unknown codec {codec_byte}"))
        })?;
        if u32_at(b, OFF_RESERVED, Code::EntryReserved)? != 0 {
            return bad(Code::EntryReserved, "reserved directory bytes are not zero");
        }
        let e = BlockEntry {
            offset: u64_at(b, OFF_OFFSET, Code::Layout)?,
            stored_length: u32_at(b, OFF_STORED_LENGTH, Code::Layout)?,
            raw_length: u32_at(b, OFF_RAW_LENGTH, Code::Layout)?,
            crc: u32_at(b, OFF_CRC, Code::Layout)?,
            kind,
            codec,
            level: u16_at(b, OFF_LEVEL, Code::Layout)?,
            item_count: u32_at(b, OFF_ITEM_COUNT, Code::Layout)?,
        };
        e.check_lengths(block_size)?;
        if e.offset.checked_add(u64::from(e.stored_length)).is_none() {
            return bad(
                Code::EntryOffset,
                format!(
                    "block at {} + {} bytes passes 2^64",
                    e.offset, e.stored_length
                ),
            );
        }
        if e.kind != BlockKind::Treelet && e.level != 0 {
            return bad(
                Code::EntryLevel,
                format!("a {} block has level {}, not 0", kind.name(), e.level),
            );
        }
        // Every item costs bytes, so the raw length bounds the count before anything trusts it:
        // a treelet at least a 4-byte start and an 8-byte node, a triangle 6 bytes, a proxy 80.
        let most = match e.kind {
            BlockKind::Treelet => e.raw_length.saturating_sub(16) / 12,
            BlockKind::Triangle => e.raw_length.saturating_sub(16) / 6,
            BlockKind::Proxy => e.raw_length / 80,
        };
        if e.item_count == 0 || e.item_count > most {
            return bad(
                Code::EntryItemCount,
                format!(
                    "{} items cannot fit a {}-byte {} block",
                    e.item_count,
                    e.raw_length,
                    kind.name()
                ),
            );
        }
        Ok(e)
    }

    fn check_lengths(&self, block_size: u32) -> Result<()> {
        if self.raw_length == 0 || self.raw_length > block_size {
            return bad(
                Code::EntryLength,
                format!(
                    "raw length {} is outside 1 ..= block size {block_size}",
                    self.raw_length
                ),
            );
        }
        let ok = match self.codec {
            CodecId::None => self.stored_length == self.raw_length,
            CodecId::Lz4 | CodecId::Zstd => {
                self.stored_length >= 1 && self.stored_length < self.raw_length
            }
        };
        if !ok {
            return bad(
                Code::EntryLength,
                format!(
                    "stored length {} does not fit raw length {} under codec {}",
                    self.stored_length,
                    self.raw_length,
                    self.codec.name()
                ),
            );
        }
        Ok(())
    }

    /// The first byte after the block (saturating: decode refuses entries that overflow).
    pub fn end(&self) -> u64 {
        self.offset.saturating_add(u64::from(self.stored_length))
    }
}

/// Checks the rules between entries: blocks packed back to back from byte 64 up to the
/// directory, and treelet levels in order. Returns every problem, block by block.
pub fn check_placement(entries: &[BlockEntry], directory_offset: u64) -> Vec<(u32, Error)> {
    let mut problems = Vec::new();
    let mut expected = HEADER_LEN as u64;
    let mut last_level = 0u16;
    for (id, e) in (0u32..).zip(entries) {
        if e.offset != expected {
            problems.push((
                id,
                Error::malformed(
                    Code::EntryOffset,
                    format!(
                        "block starts at byte {} but the previous one ends at {expected}",
                        e.offset
                    ),
                ),
            ));
        }
        expected = e.end();
        if e.kind == BlockKind::Treelet {
            if e.level < last_level {
                problems.push((
                    id,
                    Error::malformed(
                        Code::EntryLevel,
                        format!(
                            "treelet block of level {} after one of level {last_level}",
                            e.level
                        ),
                    ),
                ));
            }
            last_level = last_level.max(e.level);
        }
    }
    if expected != directory_offset {
        let id = u32::try_from(entries.len().saturating_sub(1)).unwrap_or(u32::MAX);
        problems.push((
            id,
            Error::malformed(
                Code::EntryOffset,
                format!(
                    "blocks end at byte {expected} but the directory starts at {directory_offset}"
                ),
            ),
        ));
    }
    problems
}
