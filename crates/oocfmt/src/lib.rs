//! `oocfmt`: the `.oocf` out-of-core ray tracing container. This crate knows bytes and records,
//! never geometry algorithms; `spec/oocfmt.md` is the contract it implements.
//!
//! - [`Writer`] streams blocks into a temporary file and renames it into place when complete.
//! - [`Reader`] validates header, trailer, directory and metadata at open, loads the proxies,
//!   and reads blocks by id (positioned reads, through the page cache or past it
//!   ([`direct`]), or a memory map).
//! - [`records`] holds the hot fixed-layout records and their zero-copy views.
//! - [`verify`] checks a file at three depths and reports every problem with a stable code.
//!
//! ```
//! use oocfmt::{BlockKind, ReadOptions, Reader};
//!
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec/vectors/quad.oocf");
//! let reader = Reader::open(std::path::Path::new(path), ReadOptions::default())?;
//! assert_eq!(reader.metadata().counts.triangles, 2);
//! let id = reader.entries().iter().position(|e| e.kind == BlockKind::Triangle).unwrap_or(0);
//! let block = reader.read_block(id as u32)?;
//! let triangles = block.triangles(reader.metadata().triangle_attributes())?;
//! assert_eq!(triangles.primary_count(), 2);
//! # Ok::<(), oocfmt::Error>(())
//! ```

#![deny(missing_docs)]

mod bytes;
pub mod checksum;
pub mod codec;
pub mod direct;
pub mod directory;
pub mod error;
pub mod header;
pub mod metadata;
mod mmap;
pub mod reader;
pub mod records;
pub mod source;
pub mod summary;
pub mod trailer;
pub mod verify;
pub mod writer;

pub use codec::Codec;
#[cfg(target_os = "linux")]
pub use direct::DirectSource;
pub use direct::{Io, IoMode};
pub use directory::{BlockEntry, BlockKind, CodecId};
pub use error::{Code, Error, ErrorKind, Result, Severity};
pub use header::Header;
pub use metadata::Metadata;
pub use mmap::MmapSource;
pub use reader::{Block, Checksums, Limits, ReadOptions, Reader};
pub use source::{ByteSource, FileSource};
pub use trailer::Trailer;
pub use writer::{EncodedBlock, WriteOptions, WriteSummary, Writer};

#[cfg(doctest)]
#[doc = include_str!("../../../docs/library.md")]
pub struct LibraryDoctests;
