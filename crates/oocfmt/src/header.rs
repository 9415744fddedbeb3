//! The 64-byte file header (spec §3).

use crate::bytes::{u16_at, u32_at, u64_at, PutLe};
use crate::checksum::crc32c;
use crate::error::{bad, Code, Error, ErrorKind, Result};

/// The first 8 bytes of every file, `\x89OCF\r\n\x1a\n`: built like PNG's so 7-bit and
/// line-ending conversions break it visibly (spec §3).
pub const MAGIC: [u8; 8] = [0x89, b'O', b'C', b'F', b'\r', b'\n', 0x1a, b'\n'];
/// The major version this crate reads and writes.
pub const VERSION_MAJOR: u16 = 1;
/// The newest minor version this crate knows; it reads every minor of [`VERSION_MAJOR`]. It
/// writes [`VERSION_MINOR_BASE`] for files that use nothing added since (unfiltered voxel-only
/// files stay byte-identical to 1.0 ones), [`VERSION_MINOR_RLODS`] for unfiltered files with
/// R-LODs, [`VERSION_MINOR_FILTERED`] for pre-filtered files and this for files with a part
/// table.
pub const VERSION_MINOR: u16 = VERSION_MINOR_PARTS;
/// The minor version that added the metadata's part table and per-triangle part ids.
pub const VERSION_MINOR_PARTS: u16 = 3;
/// The minor version that added pre-filtered LOD records (`LOD_FILTERED`).
pub const VERSION_MINOR_FILTERED: u16 = 2;
/// The minor version that added R-LODs.
pub const VERSION_MINOR_RLODS: u16 = 1;
/// The minor version of files that use no feature added after 1.0.
pub const VERSION_MINOR_BASE: u16 = 0;
/// Smallest allowed `block_size_log2`: blocks of 4 KiB.
pub const MIN_BLOCK_SIZE_LOG2: u8 = 12;
/// Largest allowed `block_size_log2`: blocks of 1 MiB, which bounds every block allocation.
pub const MAX_BLOCK_SIZE_LOG2: u8 = 20;
/// The `block_size_log2` writers use unless told otherwise: 64 KiB blocks.
pub const DEFAULT_BLOCK_SIZE_LOG2: u8 = 16;

/// Compatible feature bit: the file has at least one proxy block.
pub const COMPAT_PROXIES: u64 = 1 << 0;
/// Compatible feature bit: the tree has at least one LOD node.
pub const COMPAT_LOD_VOXELS: u64 = 1 << 1;
/// Compatible feature bits defined by this version.
pub const KNOWN_COMPAT: u64 = COMPAT_PROXIES | COMPAT_LOD_VOXELS;
/// LOD nodes carry an R-LOD record after their voxel (spec §6.4); since 1.1.
pub const INCOMPAT_LOD_RLODS: u64 = 1 << 0;
/// LOD nodes carry no voxel (only with [`INCOMPAT_LOD_RLODS`]); since 1.1.
pub const INCOMPAT_LOD_NO_VOXELS: u64 = 1 << 1;
/// Voxel samples may carry footprints and R-LOD records a shade and a coverage (spec §5.1);
/// since 1.2.
pub const INCOMPAT_LOD_FILTERED: u64 = 1 << 2;
/// Triangle blocks carry a part id per triangle and every LOD entry ends with a part word
/// (spec §6.2, §8); set exactly when the metadata's part table has two or more parts. Since 1.3.
pub const INCOMPAT_PART_IDS: u64 = 1 << 3;
/// Incompatible feature bits defined by this version.
pub const KNOWN_INCOMPAT: u64 =
    INCOMPAT_LOD_RLODS | INCOMPAT_LOD_NO_VOXELS | INCOMPAT_LOD_FILTERED | INCOMPAT_PART_IDS;

// Field offsets, each built from the one before so prose and code cannot drift apart.
/// Byte offset in the header of [`MAGIC`].
pub const OFF_MAGIC: usize = 0;
/// Byte offset in the header of the `u16` major version.
pub const OFF_MAJOR: usize = OFF_MAGIC + 8;
/// Byte offset in the header of the `u16` minor version.
pub const OFF_MINOR: usize = OFF_MAJOR + 2;
/// Byte offset in the header of the `u8` log2 of the block size.
pub const OFF_BLOCK_SIZE_LOG2: usize = OFF_MINOR + 2;
/// Byte offset in the header of 3 reserved bytes that must be zero.
pub const OFF_RESERVED_A: usize = OFF_BLOCK_SIZE_LOG2 + 1;
/// Byte offset in the header of the `u64` incompatible feature bits.
pub const OFF_INCOMPAT: usize = OFF_RESERVED_A + 3;
/// Byte offset in the header of the `u64` compatible feature bits.
pub const OFF_COMPAT: usize = OFF_INCOMPAT + 8;
/// Byte offset in the header of the `u64` file offset of the directory.
pub const OFF_DIRECTORY_OFFSET: usize = OFF_COMPAT + 8;
/// Byte offset in the header of the `u32` number of blocks (directory entries).
pub const OFF_BLOCK_COUNT: usize = OFF_DIRECTORY_OFFSET + 8;
/// Byte offset in the header of the `u32` length of the metadata in bytes.
pub const OFF_METADATA_LENGTH: usize = OFF_BLOCK_COUNT + 4;
/// Byte offset in the header of the `u64` file offset of the metadata.
pub const OFF_METADATA_OFFSET: usize = OFF_METADATA_LENGTH + 4;
/// Byte offset in the header of a reserved `u32` that must be zero.
pub const OFF_RESERVED_B: usize = OFF_METADATA_OFFSET + 8;
/// Byte offset in the header of the CRC-32C of header bytes `0..OFF_HEADER_CRC`.
pub const OFF_HEADER_CRC: usize = OFF_RESERVED_B + 4;
/// Length of the header in bytes (64); the first block starts here.
pub const HEADER_LEN: usize = OFF_HEADER_CRC + 4;

/// Where the sections after the blocks lie; the header and the trailer both carry it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct SectionTable {
    /// File offset of the directory: the end of the last block, or 64 without blocks.
    pub directory_offset: u64,
    /// Number of blocks and directory entries; block ids are `0..block_count`.
    pub block_count: u32,
    /// File offset of the metadata: `directory_offset + 32 × block_count`.
    pub metadata_offset: u64,
    /// Length of the postcard-encoded metadata in bytes.
    pub metadata_length: u32,
}

impl SectionTable {
    /// Offset of the trailer that must follow the metadata.
    pub fn trailer_offset(&self) -> Option<u64> {
        self.metadata_offset
            .checked_add(u64::from(self.metadata_length))
    }

    /// Checks that directory, metadata and trailer tile a file of `file_len` bytes (spec §2).
    pub fn check_tiling(&self, file_len: u64) -> Result<()> {
        let dir_len = u64::from(self.block_count) * crate::directory::ENTRY_LEN as u64;
        let dir_end = self.directory_offset.checked_add(dir_len);
        let end = self
            .trailer_offset()
            .and_then(|t| t.checked_add(crate::trailer::TRAILER_LEN as u64));
        if self.directory_offset < HEADER_LEN as u64 {
            return bad(
                Code::Layout,
                format!(
                    "directory offset {} lies inside the header",
                    self.directory_offset
                ),
            );
        }
        if dir_end != Some(self.metadata_offset) {
            return bad(
                Code::Layout,
                format!(
                    "metadata offset {} is not directory offset {} + 32 × {} blocks",
                    self.metadata_offset, self.directory_offset, self.block_count
                ),
            );
        }
        if end != Some(file_len) {
            return bad(
                Code::Layout,
                format!(
                    "metadata at {} + {} bytes + 48-byte trailer does not end at the file length {file_len}",
                    self.metadata_offset, self.metadata_length
                ),
            );
        }
        Ok(())
    }
}

/// The decoded header: version, block size, feature bits and where the sections lie.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Header {
    /// Major version; a reader refuses any other than [`VERSION_MAJOR`].
    pub major: u16,
    /// Minor version; newer than [`VERSION_MINOR`] is read, ignoring what it adds.
    pub minor: u16,
    /// Log2 of the block size in bytes, in
    /// [`MIN_BLOCK_SIZE_LOG2`]`..=`[`MAX_BLOCK_SIZE_LOG2`] once validated.
    pub block_size_log2: u8,
    /// Feature bits a reader must know to read the file ([`KNOWN_INCOMPAT`]).
    pub incompatible_features: u64,
    /// Feature bits a reader may ignore ([`KNOWN_COMPAT`]).
    pub compatible_features: u64,
    /// Where the directory and metadata lie; must equal the trailer's copy.
    pub sections: SectionTable,
}

impl Header {
    /// A header of version 1.0 with no feature bits and an empty section table, for a writer to
    /// fill in.
    pub fn new(block_size_log2: u8) -> Self {
        Header {
            major: VERSION_MAJOR,
            minor: VERSION_MINOR_BASE,
            block_size_log2,
            incompatible_features: 0,
            compatible_features: 0,
            sections: SectionTable::default(),
        }
    }

    /// The block size in bytes: the most raw bytes one block may hold.
    pub fn block_size(&self) -> u32 {
        1u32 << self.block_size_log2.min(31)
    }

    /// The 64 header bytes, reserved bytes zero and the header CRC computed.
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut v = Vec::with_capacity(HEADER_LEN);
        v.extend_from_slice(&MAGIC);
        v.put_u16(self.major);
        v.put_u16(self.minor);
        v.push(self.block_size_log2);
        v.extend_from_slice(&[0; 3]);
        v.put_u64(self.incompatible_features);
        v.put_u64(self.compatible_features);
        v.put_u64(self.sections.directory_offset);
        v.put_u32(self.sections.block_count);
        v.put_u32(self.sections.metadata_length);
        v.put_u64(self.sections.metadata_offset);
        v.put_u32(0);
        let crc = crc32c(&v);
        v.put_u32(crc);
        let mut out = [0u8; HEADER_LEN];
        out.copy_from_slice(&v);
        out
    }

    /// Decodes and validates a header. Checks run in the order of spec §11: magic, major
    /// version, checksum, then the fields.
    pub fn decode(b: &[u8]) -> Result<Header> {
        let h = Self::decode_unchecked(b)?;
        let stored = u32_at(b, OFF_HEADER_CRC, Code::HeaderChecksum)?;
        let computed = crc32c(&b[..OFF_HEADER_CRC]);
        if stored != computed {
            return Err(Error::new(ErrorKind::Checksum {
                code: Code::HeaderChecksum,
                what: "header",
                stored,
                computed,
            })
            .at(OFF_HEADER_CRC as u64));
        }
        if b[OFF_RESERVED_A..OFF_INCOMPAT].iter().any(|&x| x != 0)
            || u32_at(b, OFF_RESERVED_B, Code::HeaderReserved)? != 0
        {
            return Err(Error::malformed(
                Code::HeaderReserved,
                "reserved header bytes are not zero",
            )
            .at(OFF_RESERVED_A as u64));
        }
        if !(MIN_BLOCK_SIZE_LOG2..=MAX_BLOCK_SIZE_LOG2).contains(&h.block_size_log2) {
            return Err(Error::malformed(
                Code::HeaderBlockSize,
                format!(
                    "block size 2^{} is outside 2^12 ..= 2^20",
                    h.block_size_log2
                ),
            )
            .at(OFF_BLOCK_SIZE_LOG2 as u64));
        }
        let unknown = h.incompatible_features & !KNOWN_INCOMPAT;
        if unknown != 0 {
            return Err(Error::new(ErrorKind::Unsupported {
                code: Code::HeaderFeatureUnsupported,
                detail: format!(
                    "incompatible feature bits {unknown:#x} are not known to this reader"
                ),
            })
            .at(OFF_INCOMPAT as u64));
        }
        if h.incompatible_features & INCOMPAT_LOD_NO_VOXELS != 0
            && h.incompatible_features & INCOMPAT_LOD_RLODS == 0
        {
            return Err(Error::malformed(
                Code::HeaderFeatureUnsupported,
                "feature LOD_NO_VOXELS without LOD_RLODS leaves LOD nodes with nothing to show",
            )
            .at(OFF_INCOMPAT as u64));
        }
        Ok(h)
    }

    /// Reads the fields after checking only the magic and the major version: for `verify`,
    /// which goes on past a bad checksum to find more problems.
    pub fn decode_unchecked(b: &[u8]) -> Result<Header> {
        let b = b.get(..HEADER_LEN).ok_or_else(|| {
            Error::malformed(
                Code::FileTooSmall,
                format!("{} bytes, shorter than the 64-byte header", b.len()),
            )
        })?;
        check_magic(b)?;
        let c = Code::HeaderMagic;
        let major = u16_at(b, OFF_MAJOR, c)?;
        let minor = u16_at(b, OFF_MINOR, c)?;
        if major != VERSION_MAJOR {
            return Err(Error::new(ErrorKind::Unsupported {
                code: Code::HeaderVersionUnsupported,
                detail: format!(
                    "format version {major}.{minor}; this reader implements {VERSION_MAJOR}.x"
                ),
            })
            .at(OFF_MAJOR as u64));
        }
        Ok(Header {
            major,
            minor,
            block_size_log2: b[OFF_BLOCK_SIZE_LOG2],
            incompatible_features: u64_at(b, OFF_INCOMPAT, c)?,
            compatible_features: u64_at(b, OFF_COMPAT, c)?,
            sections: SectionTable {
                directory_offset: u64_at(b, OFF_DIRECTORY_OFFSET, c)?,
                block_count: u32_at(b, OFF_BLOCK_COUNT, c)?,
                metadata_length: u32_at(b, OFF_METADATA_LENGTH, c)?,
                metadata_offset: u64_at(b, OFF_METADATA_OFFSET, c)?,
            },
        })
    }
}

fn check_magic(b: &[u8]) -> Result<()> {
    let got = &b[..MAGIC.len()];
    if got == MAGIC {
        return Ok(());
    }
    let detail = if got[..4] == MAGIC[..4] {
        "the file starts like an .oocf file but its magic is mangled: it went through a text-mode (line-ending) conversion".to_string()
    } else if got[1..4] == MAGIC[1..4] && got[0] == 0x09 {
        "the magic's high bit was stripped: the file went through a 7-bit transfer".to_string()
    } else {
        format!("not an .oocf file: magic is {got:02x?}")
    };
    Err(Error::malformed(Code::HeaderMagic, detail).at(0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let mut h = Header::new(16);
        h.compatible_features = COMPAT_PROXIES;
        h.sections = SectionTable {
            directory_offset: 1 << 40,
            block_count: 7,
            metadata_offset: (1 << 40) + 224,
            metadata_length: 99,
        };
        assert_eq!(Header::decode(&h.encode()).ok(), Some(h));
    }

    #[test]
    fn text_mode_mangling_is_named() {
        let mut b = Header::new(16).encode().to_vec();
        b.remove(4); // CRLF -> LF drops the '\r'
        b.push(0);
        let e = Header::decode(&b)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.contains("text-mode"), "{e}");
    }
}
