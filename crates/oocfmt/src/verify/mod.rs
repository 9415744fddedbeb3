//! `verify`: checks a file at three depths and reports every problem found, each with a stable
//! code (spec §13). Only I/O failures stop it early; malformed bytes become issues.

mod report;
mod tree;

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

pub use report::{Depth, Issue, Report, REPORT_SCHEMA};

use crate::directory::{check_placement, BlockEntry, BlockKind, ENTRY_LEN};
use crate::error::{Code, Error, Result};
use crate::header::{
    Header, SectionTable, HEADER_LEN, KNOWN_COMPAT, MAX_BLOCK_SIZE_LOG2, VERSION_MINOR,
};
use crate::metadata::Metadata;
use crate::reader::{
    read_block_data, read_metadata, read_trailer, read_vec, root_checksum, short_file_error,
    Limits, ReadOptions,
};
use crate::records::LodKinds;
use crate::source::ByteSource;
use crate::summary::{survey_block, BlockFacts, BlockSchema};
use crate::trailer::{Trailer, TRAILER_LEN};
use crate::Checksums;

/// How [`verify`] checks a file. The default is [`Depth::Full`], 1000 issues, the reader's
/// default limits, and block CRCs checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VerifyOptions {
    /// How much of the file to check.
    pub depth: Depth,
    /// Issues kept in the report; the rest are only counted.
    pub max_issues: usize,
    /// The reader limits the file must keep; a size over one is an issue (`LIMIT_EXCEEDED`,
    /// `METADATA_LIMIT`), not a refusal.
    pub limits: Limits,
    /// Whether block CRCs are checked ([`Checksums::Skip`] is for fuzzing).
    pub checksums: Checksums,
}

impl Default for VerifyOptions {
    fn default() -> Self {
        VerifyOptions {
            depth: Depth::Full,
            max_issues: 1000,
            limits: Limits::default(),
            checksums: Checksums::Verify,
        }
    }
}

/// Verifies `src`. `progress` receives stored bytes checked so far (from any thread). Returns
/// `Err` only when the source cannot be read; everything else is in the report.
pub fn verify(
    src: &dyn ByteSource,
    name: &str,
    opts: &VerifyOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Report> {
    let mut v = Verifier {
        src,
        opts,
        report: Report::new(name, opts.depth),
    };
    v.run(progress)?;
    Ok(v.report)
}

struct Verifier<'a> {
    src: &'a dyn ByteSource,
    opts: &'a VerifyOptions,
    report: Report,
}

/// What the quick phase found usable.
struct Index {
    header: Header,
    entries: Vec<Option<BlockEntry>>,
    metadata: Option<Metadata>,
}

impl Verifier<'_> {
    /// Records a problem; an I/O error aborts the run instead.
    fn note(&mut self, e: Error) -> Result<()> {
        if e.code() == Code::Io {
            return Err(e);
        }
        self.report
            .push(Issue::from_error(&e), self.opts.max_issues);
        Ok(())
    }

    fn note_code(&mut self, code: Code, msg: String, block: Option<u32>) {
        let issue = Issue {
            code,
            severity: code.severity(),
            message: msg,
            block,
            offset: None,
        };
        self.report.push(issue, self.opts.max_issues);
    }

    fn run(&mut self, progress: &(dyn Fn(u64) + Sync)) -> Result<()> {
        let Some(index) = self.quick()? else {
            return Ok(());
        };
        if self.opts.depth == Depth::Quick {
            return Ok(());
        }
        let facts = self.blocks(&index, progress)?;
        if self.opts.depth == Depth::Deep {
            tree::check(self, &index, &facts)?;
        }
        Ok(())
    }

    /// The quick depth: the header, the trailer, the section table, the directory and the
    /// metadata, with the root checksum over them. None when nothing past them can be trusted.
    fn quick(&mut self) -> Result<Option<Index>> {
        let min = (HEADER_LEN + TRAILER_LEN) as u64;
        if self.src.len() < min {
            let e = short_file_error(self.src)?;
            self.note(e)?;
            return Ok(None);
        }
        let header_bytes = read_vec(self.src, 0, HEADER_LEN as u64)?;
        let Some((mut header, header_ok)) = self.header(&header_bytes)? else {
            return Ok(None);
        };
        let trailer = match read_trailer(self.src) {
            Ok(t) => Some(t),
            Err(e) => {
                self.note(e)?;
                None
            }
        };
        let Some(sections) = self.choose_sections(&header, header_ok, trailer.as_ref())? else {
            return Ok(None);
        };
        header.sections = sections;
        self.report.identity = trailer.map(|t| format!("{:08x}", t.root_checksum));
        let dir_len = u64::from(sections.block_count) * ENTRY_LEN as u64;
        let dir_bytes = read_vec(self.src, sections.directory_offset, dir_len)?;
        let entries = self.directory(&header, &dir_bytes, trailer.as_ref())?;
        self.resident(&entries)?;
        let metadata = match &trailer {
            Some(t) => self.metadata(&header, t, &header_bytes, &dir_bytes)?,
            None => None,
        };
        Ok(Some(Index {
            header,
            entries,
            metadata,
        }))
    }

    /// Decodes the header and reports what it says wrong or new. Returns it with whether it
    /// passed the full decode (its section table is then a candidate); None when it cannot be
    /// decoded at all or needs a feature this reader lacks.
    fn header(&mut self, bytes: &[u8]) -> Result<Option<(Header, bool)>> {
        let mut header = match Header::decode_unchecked(bytes) {
            Ok(h) => h,
            Err(e) => {
                self.note(e)?;
                return Ok(None);
            }
        };
        let header_ok = match Header::decode(bytes) {
            Ok(_) => true,
            Err(e) => {
                let fatal = e.code() == Code::HeaderFeatureUnsupported;
                self.note(e)?;
                if fatal {
                    return Ok(None);
                }
                false
            }
        };
        if header.minor > VERSION_MINOR {
            self.note_code(
                Code::HeaderMinorNewer,
                format!(
                    "file version 1.{}: fields added after 1.{VERSION_MINOR} are ignored",
                    header.minor
                ),
                None,
            );
        }
        let unknown = header.compatible_features & !KNOWN_COMPAT;
        if unknown != 0 {
            self.note_code(
                Code::HeaderFeatureUnknown,
                format!("compatible feature bits {unknown:#x} are not known"),
                None,
            );
        }
        header.block_size_log2 = header.block_size_log2.min(MAX_BLOCK_SIZE_LOG2);
        Ok(Some((header, header_ok)))
    }

    /// Reports proxies that together pass the resident limit (a reader keeps them all loaded).
    fn resident(&mut self, entries: &[Option<BlockEntry>]) -> Result<()> {
        let resident: u64 = entries
            .iter()
            .flatten()
            .filter(|e| e.kind == BlockKind::Proxy)
            .map(|e| u64::from(e.raw_length))
            .sum();
        let limit = self.opts.limits.max_resident_bytes;
        if resident > limit {
            self.note(Error::limit("resident proxies", resident, limit))?;
        }
        Ok(())
    }

    /// Reads the metadata the trailer points to and checks the root checksum over the header's,
    /// the directory's and the metadata's bytes; None when the metadata cannot be read.
    fn metadata(
        &mut self,
        header: &Header,
        trailer: &Trailer,
        header_bytes: &[u8],
        dir_bytes: &[u8],
    ) -> Result<Option<Metadata>> {
        let (metadata, meta_bytes) =
            match read_metadata(self.src, header, trailer, &self.opts.limits) {
                Ok(m) => m,
                Err(e) => {
                    self.note(e)?;
                    return Ok(None);
                }
            };
        let computed = root_checksum(header_bytes, dir_bytes, &meta_bytes);
        if computed != trailer.root_checksum {
            self.note_code(
                Code::RootChecksum,
                format!(
                    "root checksum: stored {:#010x}, computed {computed:#010x}",
                    trailer.root_checksum
                ),
                None,
            );
        }
        Ok(Some(metadata))
    }

    /// Picks the section table to trust: the header's and trailer's must agree and tile the file.
    fn choose_sections(
        &mut self,
        header: &Header,
        header_ok: bool,
        trailer: Option<&Trailer>,
    ) -> Result<Option<SectionTable>> {
        let len = self.src.len();
        let mut candidates = Vec::new();
        if let Some(t) = trailer {
            candidates.push(t.sections);
        }
        if header_ok || trailer.is_none() {
            candidates.push(header.sections);
        }
        if let (Some(t), true) = (trailer, header_ok) {
            if t.sections != header.sections {
                self.note_code(
                    Code::Layout,
                    format!(
                        "header says {:?}, trailer says {:?}",
                        header.sections, t.sections
                    ),
                    None,
                );
            }
        }
        let mut first_err = None;
        for s in candidates {
            match s.check_tiling(len) {
                Ok(()) => return Ok(Some(s)),
                Err(e) => {
                    first_err.get_or_insert(e);
                }
            }
        }
        if let Some(e) = first_err {
            self.note(e)?;
        }
        Ok(None)
    }

    fn directory(
        &mut self,
        header: &Header,
        bytes: &[u8],
        trailer: Option<&Trailer>,
    ) -> Result<Vec<Option<BlockEntry>>> {
        let at = header.sections.directory_offset;
        if let Some(t) = trailer {
            let computed = crate::checksum::crc32c(bytes);
            if computed != t.directory_crc {
                self.note_code(
                    Code::DirectoryChecksum,
                    format!(
                        "directory checksum: stored {:#010x}, computed {computed:#010x}",
                        t.directory_crc
                    ),
                    None,
                );
            }
        }
        let mut entries = Vec::with_capacity(bytes.len() / ENTRY_LEN);
        for (chunk, id) in bytes.chunks_exact(ENTRY_LEN).zip(0u32..) {
            match BlockEntry::decode(chunk, header.block_size()) {
                Ok(e) => entries.push(Some(e)),
                Err(e) => {
                    self.note(e.in_block(id).at(at + u64::from(id) * ENTRY_LEN as u64))?;
                    entries.push(None);
                }
            }
        }
        if entries.iter().all(Option::is_some) {
            let valid: Vec<BlockEntry> = entries.iter().flatten().copied().collect();
            for (id, e) in check_placement(&valid, at) {
                self.note(e.in_block(id))?;
            }
        }
        Ok(entries)
    }

    /// Reads, checks and surveys every block, in parallel, keeping results in block order.
    fn blocks(
        &mut self,
        index: &Index,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Option<BlockFacts>>> {
        let ropts = ReadOptions {
            limits: self.opts.limits,
            checksums: self.opts.checksums,
        };
        let schema = index.metadata.as_ref().map(BlockSchema::of);
        let lod = LodKinds::of_header(&index.header);
        let done = AtomicU64::new(0);
        let src = self.src;
        let results: Vec<Option<Result<BlockFacts>>> = index
            .entries
            .par_iter()
            .map(|e| {
                let e = e.as_ref().filter(|e| e.stored_length > 0)?;
                let r = read_block_data(src, e, &ropts)
                    .and_then(|raw| survey_block(e, &raw, schema, lod));
                progress(
                    done.fetch_add(u64::from(e.stored_length), Ordering::Relaxed)
                        + u64::from(e.stored_length),
                );
                Some(r)
            })
            .collect();
        let mut facts = Vec::with_capacity(results.len());
        for ((r, e), id) in results.into_iter().zip(&index.entries).zip(0u32..) {
            match r {
                Some(Ok(f)) => {
                    if let Some(e) = e {
                        self.report.blocks_checked += 1;
                        self.report.stored_bytes_checked += u64::from(e.stored_length);
                        self.report.raw_bytes_checked += u64::from(e.raw_length);
                    }
                    facts.push(Some(f));
                }
                Some(Err(err)) => {
                    let off = e.map(|e| e.offset).unwrap_or(0);
                    self.note(err.in_block(id).at(off))?;
                    facts.push(None);
                }
                None => facts.push(None),
            }
        }
        Ok(facts)
    }
}
