//! The 48-byte trailer written last (spec §10).

use crate::bytes::{u32_at, u64_at, PutLe};
use crate::checksum::crc32c;
use crate::error::{Code, Error, ErrorKind, Result};
use crate::header::SectionTable;

/// The trailer's last 8 bytes, `OCFEND\r\n`: absent when a file is cut short or appended to.
pub const END_MAGIC: [u8; 8] = *b"OCFEND\r\n";

/// Byte offset in the trailer of the `u64` directory offset (a copy of the header's).
pub const OFF_DIRECTORY_OFFSET: usize = 0;
/// Byte offset in the trailer of the `u64` metadata offset (a copy of the header's).
pub const OFF_METADATA_OFFSET: usize = OFF_DIRECTORY_OFFSET + 8;
/// Byte offset in the trailer of the `u32` block count (a copy of the header's).
pub const OFF_BLOCK_COUNT: usize = OFF_METADATA_OFFSET + 8;
/// Byte offset in the trailer of the `u32` metadata length (a copy of the header's).
pub const OFF_METADATA_LENGTH: usize = OFF_BLOCK_COUNT + 4;
/// Byte offset in the trailer of the CRC-32C of the directory bytes.
pub const OFF_DIRECTORY_CRC: usize = OFF_METADATA_LENGTH + 4;
/// Byte offset in the trailer of the CRC-32C of the metadata bytes.
pub const OFF_METADATA_CRC: usize = OFF_DIRECTORY_CRC + 4;
/// Byte offset in the trailer of the root checksum (header, directory and metadata).
pub const OFF_ROOT_CHECKSUM: usize = OFF_METADATA_CRC + 4;
/// Byte offset in the trailer of the CRC-32C of trailer bytes `0..OFF_TRAILER_CRC`.
pub const OFF_TRAILER_CRC: usize = OFF_ROOT_CHECKSUM + 4;
/// Byte offset in the trailer of [`END_MAGIC`].
pub const OFF_END_MAGIC: usize = OFF_TRAILER_CRC + 4;
/// Length of the trailer in bytes (48); it ends the file.
pub const TRAILER_LEN: usize = OFF_END_MAGIC + 8;

/// The decoded trailer: the section table again, so a reader can cross-check the header, and
/// the checksums of the directory, the metadata and the whole file's identity.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Trailer {
    /// Where the directory and metadata lie; must equal the header's copy.
    pub sections: SectionTable,
    /// CRC-32C of the directory bytes.
    pub directory_crc: u32,
    /// CRC-32C of the metadata bytes.
    pub metadata_crc: u32,
    /// The file's identity (spec §10).
    pub root_checksum: u32,
}

impl Trailer {
    /// The 48 trailer bytes, with the trailer CRC computed and the end magic appended.
    pub fn encode(&self) -> [u8; TRAILER_LEN] {
        let mut v = Vec::with_capacity(TRAILER_LEN);
        v.put_u64(self.sections.directory_offset);
        v.put_u64(self.sections.metadata_offset);
        v.put_u32(self.sections.block_count);
        v.put_u32(self.sections.metadata_length);
        v.put_u32(self.directory_crc);
        v.put_u32(self.metadata_crc);
        v.put_u32(self.root_checksum);
        let crc = crc32c(&v);
        v.put_u32(crc);
        v.extend_from_slice(&END_MAGIC);
        let mut out = [0u8; TRAILER_LEN];
        out.copy_from_slice(&v);
        out
    }

    /// Decodes the last 48 bytes of a file; `base` is their file offset, for error messages.
    pub fn decode(b: &[u8], base: u64) -> Result<Trailer> {
        if b.len() != TRAILER_LEN || b[OFF_END_MAGIC..] != END_MAGIC {
            return Err(Error::malformed(
                Code::TrailerMagic,
                "no end magic: the file is truncated, was not finished, or has bytes appended",
            )
            .at(base + OFF_END_MAGIC as u64));
        }
        let stored = u32_at(b, OFF_TRAILER_CRC, Code::TrailerChecksum)?;
        let computed = crc32c(&b[..OFF_TRAILER_CRC]);
        if stored != computed {
            return Err(Error::new(ErrorKind::Checksum {
                code: Code::TrailerChecksum,
                what: "trailer",
                stored,
                computed,
            })
            .at(base + OFF_TRAILER_CRC as u64));
        }
        let c = Code::TrailerChecksum;
        Ok(Trailer {
            sections: SectionTable {
                directory_offset: u64_at(b, OFF_DIRECTORY_OFFSET, c)?,
                metadata_offset: u64_at(b, OFF_METADATA_OFFSET, c)?,
                block_count: u32_at(b, OFF_BLOCK_COUNT, c)?,
                metadata_length: u32_at(b, OFF_METADATA_LENGTH, c)?,
            },
            directory_crc: u32_at(b, OFF_DIRECTORY_CRC, c)?,
            metadata_crc: u32_at(b, OFF_METADATA_CRC, c)?,
            root_checksum: u32_at(b, OFF_ROOT_CHECKSUM, c)?,
        })
    }
}
