//! Corrupted files: truncations, every single-bit flip, huge length fields (under a counting
//! allocator), misplaced blocks, versions and feature bits, targeted structural damage, and
//! random damage (proptest) — run over the spec vectors and the fixtures of `tests/common`.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};

use common::*;
use oocfmt::metadata::TreeletRef;
use oocfmt::verify::{verify, Depth, VerifyOptions};
use oocfmt::{
    directory, header, trailer, Checksums, Code, Limits, Metadata, ReadOptions, Reader, Severity,
};
use proptest::prelude::*;
use proptest::sample::Index;

// ---------------------------------------------------------------------------------------------
// A global allocator that remembers the largest single allocation.

struct Counting;

static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is forwarded unchanged to the system allocator; the only addition is an
// atomic maximum of the requested size.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        PEAK.fetch_max(layout.size(), Ordering::Relaxed);
        // SAFETY: the caller's contract is passed on unchanged.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        PEAK.fetch_max(layout.size(), Ordering::Relaxed);
        // SAFETY: as above.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        PEAK.fetch_max(new_size, Ordering::Relaxed);
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Serialises the tests that read `PEAK`. The other tests of this binary never allocate more
/// than a block (≤ 1 MiB) or a file at once, so they cannot push the peak past the bound either.
static PEAK_LOCK: Mutex<()> = Mutex::new(());

// ---------------------------------------------------------------------------------------------

fn files() -> &'static [NamedFile] {
    static FILES: OnceLock<Vec<NamedFile>> = OnceLock::new();
    FILES.get_or_init(|| {
        let r = all_files();
        assert!(
            r.is_ok(),
            "cannot build the fixtures: {:?}",
            r.as_ref().err().map(|e| e.to_string())
        );
        r.unwrap_or_default()
    })
}

fn file(name: &str) -> TestResult<Vec<u8>> {
    files()
        .iter()
        .find(|f| f.name == name)
        .map(|f| f.bytes.clone())
        .ok_or_else(|| format!("no file {name}").into())
}

fn full() -> VerifyOptions {
    VerifyOptions::default()
}

/// The reader's verdict on the whole file: open, then read and decode every block.
fn read_whole(b: &[u8], opts: ReadOptions) -> oocfmt::Result<()> {
    open_bytes(b, opts).and_then(|r| read_all_blocks(&r))
}

fn reader_code(b: &[u8]) -> Option<Code> {
    read_whole(b, ReadOptions::default())
        .err()
        .map(|e| e.code())
}

fn workers() -> usize {
    std::thread::available_parallelism()
        .map_or(2, |n| n.get())
        .clamp(1, 4)
}

// ---------------------------------------------------------------------------------------------
// Truncation

#[test]
fn every_truncation_is_rejected_in_memory() -> TestResult {
    for f in files() {
        for len in 0..f.bytes.len() {
            let cut = &f.bytes[..len];
            assert!(
                open_bytes(cut, ReadOptions::default()).is_err(),
                "{}: open accepted the first {len} bytes",
                f.name
            );
            let r = verify_bytes(cut, &full())?;
            assert!(
                has_error(&r),
                "{}: verify accepted the first {len} bytes: {:?}",
                f.name,
                r.issues
            );
        }
    }
    Ok(())
}

#[test]
fn every_truncation_is_rejected_on_disk_by_both_sources() -> TestResult {
    let dir = tempfile::tempdir()?;
    for f in files() {
        let path = dir.path().join(&f.name);
        std::fs::write(&path, &f.bytes)?;
        let handle = std::fs::OpenOptions::new().write(true).open(&path)?;
        for len in (0..f.bytes.len()).rev() {
            handle.set_len(len as u64)?;
            assert!(
                Reader::open(&path, ReadOptions::default()).is_err(),
                "{}: pread accepted {len} bytes",
                f.name
            );
            assert!(
                Reader::open_mmap(&path, ReadOptions::default()).is_err(),
                "{}: mmap accepted {len} bytes",
                f.name
            );
        }
    }
    Ok(())
}

#[test]
fn the_whole_file_is_accepted_by_both_sources() -> TestResult {
    let dir = tempfile::tempdir()?;
    for f in files() {
        let path = dir.path().join(&f.name);
        std::fs::write(&path, &f.bytes)?;
        read_all_blocks(&Reader::open(&path, ReadOptions::default())?)?;
        read_all_blocks(&Reader::open_mmap(&path, ReadOptions::default())?)?;
    }
    Ok(())
}

#[test]
fn appended_bytes_are_rejected() -> TestResult {
    for f in files() {
        for extra in [&[0u8][..], b"\n", b"OCFEND\r\n"] {
            let mut b = f.bytes.clone();
            b.extend_from_slice(extra);
            assert!(
                open_bytes(&b, ReadOptions::default()).is_err(),
                "{}",
                f.name
            );
            assert!(has_error(&verify_bytes(&b, &full())?), "{}", f.name);
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Single-bit flips

/// What is wrong with flipping `bit` of `b` (restored on return), if anything.
fn check_flip(b: &mut [u8], bit: usize) -> Option<String> {
    b[bit / 8] ^= 1 << (bit % 8);
    let owned = b.to_vec();
    let verdict = match verify(&owned, "flip", &full(), &|_| {}) {
        Ok(r) if r.valid => Some(format!("bit {bit}: verify says valid ({:?})", r.issues)),
        Ok(r) if r.errors == 0 => Some(format!("bit {bit}: invalid report without an error")),
        Ok(_) => None,
        Err(e) => Some(format!("bit {bit}: verify failed to run: {e}")),
    };
    let verdict = verdict.or_else(|| {
        read_whole(&owned, ReadOptions::default())
            .is_ok()
            .then(|| format!("bit {bit}: the reader accepts the file and every block"))
    });
    b[bit / 8] ^= 1 << (bit % 8);
    verdict
}

#[test]
fn every_single_bit_flip_is_detected() -> TestResult {
    let n = workers();
    for f in files() {
        let bits = f.bytes.len() * 8;
        let problems: Vec<String> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..n)
                .map(|t| {
                    s.spawn(move || {
                        let mut b = f.bytes.clone();
                        (t..bits)
                            .step_by(n)
                            .filter_map(|bit| check_flip(&mut b, bit))
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            handles
                .into_iter()
                .flat_map(|h| {
                    h.join()
                        .unwrap_or_else(|_| vec!["a worker panicked".to_string()])
                })
                .collect()
        });
        assert!(
            problems.is_empty(),
            "{}: {} undetected flips, e.g. {:?}",
            f.name,
            problems.len(),
            &problems[..problems.len().min(8)]
        );
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Huge length fields

/// Runs the reader (memory and pread) and verify over `b`, which must be refused, and checks
/// that no single allocation exceeded 1 MiB + the file's size.
fn refused_without_allocating(what: &str, b: &[u8], expect: &[Code]) -> TestResult {
    let _guard = PEAK_LOCK.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("huge.oocf");
    std::fs::write(&path, b)?;
    let limit = (1 << 20) + b.len();
    PEAK.store(0, Ordering::SeqCst);
    let mem = read_whole(b, ReadOptions::default());
    let pread = Reader::open(&path, ReadOptions::default()).and_then(|r| read_all_blocks(&r));
    let skip = read_whole(
        b,
        ReadOptions {
            checksums: Checksums::Skip,
            ..ReadOptions::default()
        },
    );
    let report = verify_bytes(b, &deep())?;
    let peak = PEAK.load(Ordering::SeqCst);
    assert!(
        peak <= limit,
        "{what}: an allocation of {peak} bytes (limit {limit})"
    );
    for r in [&mem, &pread, &skip] {
        let code = r.as_ref().err().map(|e| e.code());
        assert!(
            code.is_some_and(|c| expect.contains(&c)),
            "{what}: reader gave {code:?}, expected one of {expect:?}"
        );
    }
    assert!(has_error(&report), "{what}: verify says valid");
    assert!(
        report.issues.iter().any(|i| expect.contains(&i.code)),
        "{what}: verify found {:?}",
        codes(&report)
    );
    Ok(())
}

const HUGE: u64 = 1 << 60;

#[test]
fn huge_section_fields_are_refused_without_allocating() -> TestResult {
    use header as h;
    use trailer as t;
    for f in files() {
        let cases: [(&str, usize, usize, u64, bool); 6] = [
            (
                "directory_offset",
                h::OFF_DIRECTORY_OFFSET,
                t::OFF_DIRECTORY_OFFSET,
                HUGE,
                true,
            ),
            (
                "metadata_offset",
                h::OFF_METADATA_OFFSET,
                t::OFF_METADATA_OFFSET,
                HUGE,
                true,
            ),
            (
                "block_count",
                h::OFF_BLOCK_COUNT,
                t::OFF_BLOCK_COUNT,
                u64::from(u32::MAX),
                false,
            ),
            (
                "metadata_length",
                h::OFF_METADATA_LENGTH,
                t::OFF_METADATA_LENGTH,
                u64::from(u32::MAX),
                false,
            ),
            (
                "directory_offset at the end",
                h::OFF_DIRECTORY_OFFSET,
                t::OFF_DIRECTORY_OFFSET,
                u64::MAX - 7,
                true,
            ),
            (
                "metadata_offset at the end",
                h::OFF_METADATA_OFFSET,
                t::OFF_METADATA_OFFSET,
                u64::MAX - 7,
                true,
            ),
        ];
        for (what, hat, tat, v, wide) in cases {
            // Header and trailer agree (so only the layout rule can refuse it), then only one.
            for tat in [Some(tat), None] {
                let mut b = f.bytes.clone();
                if wide {
                    set_section_u64(&mut b, hat, tat, v);
                } else {
                    set_section_u32(&mut b, hat, tat, u32::try_from(v)?);
                }
                let b = reseal(&b)?;
                refused_without_allocating(
                    &format!(
                        "{}: {what} = {v:#x} (trailer too: {})",
                        f.name,
                        tat.is_some()
                    ),
                    &b,
                    &[Code::Layout],
                )?;
            }
        }
    }
    Ok(())
}

#[test]
fn huge_directory_entry_fields_are_refused_without_allocating() -> TestResult {
    use directory as d;
    for f in files() {
        let (dir, count) = directory_of(&f.bytes);
        for i in 0..count {
            let at = dir + i * d::ENTRY_LEN;
            let cases: [(&str, usize, u64, bool, &[Code]); 6] = [
                ("offset", d::OFF_OFFSET, HUGE, true, &[Code::EntryOffset]),
                (
                    "offset past the file",
                    d::OFF_OFFSET,
                    f.bytes.len() as u64,
                    true,
                    &[Code::EntryOffset],
                ),
                (
                    "stored_length",
                    d::OFF_STORED_LENGTH,
                    u64::from(u32::MAX),
                    false,
                    &[Code::EntryLength],
                ),
                (
                    "raw_length",
                    d::OFF_RAW_LENGTH,
                    u64::from(u32::MAX),
                    false,
                    &[Code::EntryLength],
                ),
                (
                    "raw_length 2 MiB",
                    d::OFF_RAW_LENGTH,
                    2 << 20,
                    false,
                    &[Code::EntryLength],
                ),
                (
                    "item_count",
                    d::OFF_ITEM_COUNT,
                    u64::from(u32::MAX),
                    false,
                    &[Code::EntryItemCount, Code::ProxyLayout],
                ),
            ];
            for (what, off, v, wide, expect) in cases {
                let mut b = f.bytes.clone();
                if wide {
                    put_u64(&mut b, at + off, v);
                } else {
                    put_u32(&mut b, at + off, u32::try_from(v)?);
                }
                let b = reseal(&b)?;
                let what = format!("{}: block {i} {what} = {v:#x}", f.name);
                if off == d::OFF_ITEM_COUNT {
                    // The directory alone cannot know the count: open succeeds, the block is refused
                    // by verify; the reader's decoders return what the block holds.
                    let _guard = PEAK_LOCK.lock().unwrap_or_else(|p| p.into_inner());
                    PEAK.store(0, Ordering::SeqCst);
                    let _ = read_whole(&b, ReadOptions::default());
                    let report = verify_bytes(&b, &deep())?;
                    assert!(PEAK.load(Ordering::SeqCst) <= (1 << 20) + b.len(), "{what}");
                    assert!(
                        report.issues.iter().any(|i| expect.contains(&i.code)),
                        "{what}: {:?}",
                        codes(&report)
                    );
                } else {
                    refused_without_allocating(&what, &b, expect)?;
                }
            }
        }
    }
    Ok(())
}

/// The varint of 2^60 in postcard's encoding (LEB128).
const VARINT_2_60: [u8; 9] = [0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x10];

/// The index of the first byte where the encodings of two metadata values differ.
fn first_difference(a: &Metadata, b: &Metadata) -> TestResult<usize> {
    let (x, y) = (a.encode()?, b.encode()?);
    x.iter()
        .zip(&y)
        .position(|(p, q)| p != q)
        .ok_or_else(|| "encodings do not differ".into())
}

#[test]
fn huge_metadata_lengths_are_refused_without_allocating() -> TestResult {
    let b = file("fx-lod-lz4")?;
    let meta = Metadata::decode(metadata_bytes(&b), minor_of(&b))?;
    let bytes = meta.encode()?;
    let mut variants: Vec<(&str, Metadata)> = Vec::new();
    let mut m = meta.clone();
    m.materials.clear();
    variants.push(("materials", m));
    let mut m = meta.clone();
    m.build.params.clear();
    variants.push(("build.params", m));
    let mut m = meta.clone();
    m.provenance.generator = "x".repeat(200);
    variants.push(("provenance.generator", m));
    let mut m = meta.clone();
    m.provenance.sources.clear();
    variants.push(("provenance.sources", m));
    let mut m = meta.clone();
    m.materials[0].name = "y".repeat(300);
    variants.push(("materials[0].name", m));
    for (what, other) in variants {
        let at = first_difference(&meta, &other)?;
        let mut evil = bytes[..at].to_vec();
        evil.extend_from_slice(&VARINT_2_60);
        evil.extend_from_slice(&bytes[at + 1..]);
        let file = with_metadata(&b, &evil)?;
        refused_without_allocating(
            &format!("metadata {what} length 2^60"),
            &file,
            &[Code::MetadataDecode],
        )?;
    }
    // A metadata length over the configured limit is refused before it is read.
    let small = Limits {
        max_metadata_bytes: 16,
        ..Limits::default()
    };
    let e = open_bytes(
        &b,
        ReadOptions {
            limits: small,
            ..ReadOptions::default()
        },
    )
    .err()
    .map(|e| e.code());
    assert_eq!(e, Some(Code::MetadataLimit));
    let r = verify_bytes(
        &b,
        &VerifyOptions {
            limits: small,
            ..VerifyOptions::default()
        },
    )?;
    assert!(r.has(Code::MetadataLimit) && !r.valid, "{:?}", r.issues);
    Ok(())
}

#[test]
fn huge_counts_inside_uncompressed_blocks_are_refused_without_allocating() -> TestResult {
    let b = file("fx-quad-none")?;
    let r = open_bytes(&b, ReadOptions::default())?;
    let entries = r.entries().to_vec();
    drop(r);
    for e in entries {
        let at = usize::try_from(e.offset)?;
        let fields: &[(usize, Code)] = match e.kind {
            // treelet_count, node_bytes, voxel_bytes
            oocfmt::BlockKind::Treelet => &[
                (0, Code::TreeletLayout),
                (4, Code::TreeletLayout),
                (8, Code::TreeletLayout),
            ],
            // list_count, triangle_count, vertex_count
            oocfmt::BlockKind::Triangle => &[
                (0, Code::TriangleLayout),
                (4, Code::TriangleLayout),
                (8, Code::TriangleLayout),
            ],
            oocfmt::BlockKind::Proxy => &[],
        };
        for &(off, code) in fields {
            for v in [u32::MAX, 1 << 30, 0xffff] {
                let mut m = b.clone();
                put_u32(&mut m, at + off, v);
                let m = props::reseal_with_blocks(&m).ok_or("reseal")?;
                refused_without_allocating(
                    &format!("{:?} block field {off} = {v:#x}", e.kind),
                    &m,
                    &[code],
                )?;
            }
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Block placement

#[test]
fn overlapping_gapped_and_outside_blocks_are_refused() -> TestResult {
    for f in files() {
        let (dir, count) = directory_of(&f.bytes);
        let entry = |i: usize| dir + i * directory::ENTRY_LEN;
        let offset_of = |i: usize| get_u64(&f.bytes, entry(i));
        let mut cases: Vec<(String, Vec<(usize, u64)>)> = Vec::new();
        for i in 0..count {
            let o = offset_of(i);
            cases.push((format!("block {i} one byte late"), vec![(i, o + 1)]));
            cases.push((format!("block {i} one byte early"), vec![(i, o - 1)]));
            cases.push((format!("block {i} at the directory"), vec![(i, dir as u64)]));
            cases.push((
                format!("block {i} past the end"),
                vec![(i, f.bytes.len() as u64 + 64)],
            ));
            cases.push((format!("block {i} inside the header"), vec![(i, 0)]));
            if i > 0 {
                cases.push((
                    format!("block {i} overlaps block {}", i - 1),
                    vec![(i, offset_of(i - 1))],
                ));
                cases.push((
                    format!("blocks {} and {i} swapped", i - 1),
                    vec![(i - 1, o), (i, offset_of(i - 1))],
                ));
            }
        }
        for (what, edits) in cases {
            let mut b = f.bytes.clone();
            for (i, v) in edits {
                put_u64(&mut b, entry(i) + directory::OFF_OFFSET, v);
            }
            let b = reseal(&b)?;
            let code = reader_code(&b);
            assert!(
                matches!(code, Some(Code::EntryOffset | Code::Layout)),
                "{}: {what}: reader gave {code:?}",
                f.name
            );
            let r = verify_bytes(&b, &full())?;
            assert!(
                r.has(Code::EntryOffset) || r.has(Code::Layout),
                "{}: {what}: {:?}",
                f.name,
                codes(&r)
            );
            assert!(
                !r.has(Code::DirectoryChecksum) && !r.has(Code::RootChecksum),
                "{}: {what}: re-seal failed",
                f.name
            );
        }
        // The directory itself one byte off: header and trailer agree, the regions do not tile.
        if count > 0 {
            let mut b = f.bytes.clone();
            let d = get_u64(&b, header::OFF_DIRECTORY_OFFSET);
            set_section_u64(
                &mut b,
                header::OFF_DIRECTORY_OFFSET,
                Some(trailer::OFF_DIRECTORY_OFFSET),
                d - 1,
            );
            let b = reseal(&b)?;
            assert!(
                matches!(reader_code(&b), Some(Code::Layout | Code::EntryOffset)),
                "{}",
                f.name
            );
        }
    }
    Ok(())
}

#[test]
fn header_and_trailer_that_disagree_are_refused() -> TestResult {
    for f in files() {
        let mut b = f.bytes.clone();
        let base = b.len() - trailer::TRAILER_LEN;
        let c = get_u32(&b, base + trailer::OFF_BLOCK_COUNT);
        put_u32(&mut b, base + trailer::OFF_BLOCK_COUNT, c + 1);
        let b = reseal(&b)?;
        assert_eq!(reader_code(&b), Some(Code::Layout), "{}", f.name);
        assert!(verify_bytes(&b, &full())?.has(Code::Layout), "{}", f.name);
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Versions and feature bits

#[test]
fn an_unknown_incompatible_feature_is_refused() -> TestResult {
    for f in files() {
        // Bit 4 is the lowest undefined one in 1.3 (spec §3); set beside the file's own bits.
        for bit in [4u32, 5, 63] {
            let mut b = f.bytes.clone();
            let known = get_u64(&b, header::OFF_INCOMPAT);
            put_u64(&mut b, header::OFF_INCOMPAT, known | 1u64 << bit);
            let b = reseal(&b)?;
            assert_eq!(
                reader_code(&b),
                Some(Code::HeaderFeatureUnsupported),
                "{} bit {bit}",
                f.name
            );
            let r = verify_bytes(&b, &deep())?;
            assert!(
                r.has(Code::HeaderFeatureUnsupported) && !r.valid,
                "{}: {:?}",
                f.name,
                r.issues
            );
        }
    }
    Ok(())
}

#[test]
fn an_unknown_compatible_feature_is_only_noted() -> TestResult {
    for f in files() {
        let mut b = f.bytes.clone();
        let c = get_u64(&b, header::OFF_COMPAT);
        put_u64(&mut b, header::OFF_COMPAT, c | (1 << 40));
        let b = reseal(&b)?;
        let r = open_bytes(&b, ReadOptions::default())?;
        read_all_blocks(&r)?;
        let rep = verify_bytes(&b, &deep())?;
        assert!(rep.valid, "{}: {:?}", f.name, rep.issues);
        let i = rep
            .issues
            .iter()
            .find(|i| i.code == Code::HeaderFeatureUnknown);
        assert!(
            i.is_some_and(|i| i.severity == Severity::Info),
            "{}: {:?}",
            f.name,
            rep.issues
        );
    }
    Ok(())
}

#[test]
fn a_newer_major_version_is_refused_and_named() -> TestResult {
    for f in files() {
        for (major, sealed) in [(2u16, true), (2, false), (0, true), (0xffff, false)] {
            let mut b = f.bytes.clone();
            put_u16(&mut b, header::OFF_MAJOR, major);
            // Unsealed, the header CRC is wrong too: the version must be reported first.
            let b = if sealed { reseal(&b)? } else { b };
            let e = read_whole(&b, ReadOptions::default()).err();
            assert_eq!(
                e.as_ref().map(|e| e.code()),
                Some(Code::HeaderVersionUnsupported),
                "{} major {major}",
                f.name
            );
            let msg = e.map(|e| e.to_string()).unwrap_or_default();
            let minor = get_u32(&b, header::OFF_MINOR) & 0xffff;
            assert!(
                msg.contains(&format!("{major}.{minor}")),
                "{}: message does not name version {major}.{minor}: {msg}",
                f.name
            );
            let r = verify_bytes(&b, &deep())?;
            assert!(!r.valid, "{}", f.name);
            assert_eq!(
                codes(&r),
                vec![Code::HeaderVersionUnsupported],
                "{}: {:?}",
                f.name,
                r.issues
            );
            assert!(
                r.issues
                    .iter()
                    .all(|i| i.message.contains(&format!("{major}.{minor}"))),
                "{}",
                f.name
            );
        }
    }
    Ok(())
}

#[test]
fn a_newer_minor_version_with_trailing_metadata_still_reads() -> TestResult {
    for f in files() {
        let meta = metadata_bytes(&f.bytes).to_vec();
        let original = Metadata::decode(&meta, minor_of(&f.bytes))?;
        let mut longer = meta.clone();
        // Metadata of 1.3 and later always has the part table: an empty one is a zero length.
        if minor_of(&f.bytes) < header::VERSION_MINOR_PARTS {
            longer.push(0);
        }
        longer.extend_from_slice(&[7, 1, 2, 3, 0xff, 0]);
        let base = with_metadata(&f.bytes, &longer)?;

        let mut newer = base.clone();
        put_u16(&mut newer, header::OFF_MINOR, 7);
        let newer = reseal(&newer)?;
        let r = open_bytes(&newer, ReadOptions::default())?;
        assert_eq!(r.metadata(), &original, "{}", f.name);
        assert_eq!((r.header().major, r.header().minor), (1, 7));
        read_all_blocks(&r)?;
        let rep = verify_bytes(&newer, &deep())?;
        assert!(rep.valid, "{}: {:?}", f.name, rep.issues);
        let i = rep.issues.iter().find(|i| i.code == Code::HeaderMinorNewer);
        assert!(
            i.is_some_and(|i| i.severity == Severity::Info),
            "{}: {:?}",
            f.name,
            rep.issues
        );

        // The same trailing bytes at minor 0 are an error.
        assert_eq!(reader_code(&base), Some(Code::MetadataDecode), "{}", f.name);
        let rep = verify_bytes(&base, &full())?;
        assert!(
            rep.has(Code::MetadataDecode) && !rep.valid,
            "{}: {:?}",
            f.name,
            rep.issues
        );
        assert!(
            !rep.has(Code::MetadataChecksum) && !rep.has(Code::RootChecksum),
            "{}: re-seal failed",
            f.name
        );

        // And another minor without trailing bytes is fine too (for a file without a part
        // table, whose metadata is the same at every minor below 3).
        if minor_of(&f.bytes) < header::VERSION_MINOR_PARTS {
            let mut plain = f.bytes.clone();
            put_u16(&mut plain, header::OFF_MINOR, 1);
            let plain = reseal(&plain)?;
            read_whole(&plain, ReadOptions::default())?;
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Targeted structural damage, re-sealed so the structural rule (not a checksum) must catch it.

type Edit = Box<dyn Fn(&mut Vec<u8>)>;

fn entry_at(b: &[u8], i: usize) -> usize {
    directory_of(b).0 + i * directory::ENTRY_LEN
}

/// Applies `edit` to `name`, re-seals every checksum (blocks included) and checks that both the
/// reader and verify (at `depth`) report `code`.
fn expect_code(
    name: &str,
    what: &str,
    edit: Edit,
    code: Code,
    depth: Depth,
    reader_too: bool,
) -> TestResult {
    let mut b = file(name)?;
    edit(&mut b);
    let b = props::reseal_with_blocks(&b).ok_or("reseal")?;
    let r = verify_bytes(
        &b,
        &VerifyOptions {
            depth,
            ..VerifyOptions::default()
        },
    )?;
    assert!(
        r.has(code),
        "{name}: {what}: verify found {:?}, not {code}",
        r.issues
    );
    if code.severity() == Severity::Error {
        assert!(!r.valid, "{name}: {what}");
    }
    if reader_too {
        let got = reader_code(&b);
        assert_eq!(got, Some(code), "{name}: {what}: reader");
    }
    Ok(())
}

#[test]
fn header_and_directory_rules_hold_on_their_own() -> TestResult {
    let q = "fx-quad-none";
    let d = "fx-deep-zstd";
    let cases: Vec<(&str, &str, Edit, Code)> = vec![
        (
            q,
            "reserved header byte 13",
            Box::new(|b: &mut Vec<u8>| b[header::OFF_RESERVED_A] = 1),
            Code::HeaderReserved,
        ),
        (
            q,
            "reserved header byte 15",
            Box::new(|b: &mut Vec<u8>| b[header::OFF_RESERVED_A + 2] = 0x80),
            Code::HeaderReserved,
        ),
        (
            q,
            "reserved header word",
            Box::new(|b: &mut Vec<u8>| put_u32(b, header::OFF_RESERVED_B, 1)),
            Code::HeaderReserved,
        ),
        (
            q,
            "block size 2^21",
            Box::new(|b: &mut Vec<u8>| b[header::OFF_BLOCK_SIZE_LOG2] = 21),
            Code::HeaderBlockSize,
        ),
        (
            q,
            "block size 2^11",
            Box::new(|b: &mut Vec<u8>| b[header::OFF_BLOCK_SIZE_LOG2] = 11),
            Code::HeaderBlockSize,
        ),
        (
            q,
            "magic",
            Box::new(|b: &mut Vec<u8>| b[1] = b'o'),
            Code::HeaderMagic,
        ),
        (
            q,
            "end magic",
            Box::new(|b: &mut Vec<u8>| {
                let n = b.len();
                b[n - 1] = b'\r'
            }),
            Code::TrailerMagic,
        ),
        (
            q,
            "unknown kind",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 1);
                b[e + directory::OFF_KIND] = 4
            }),
            Code::EntryKind,
        ),
        (
            q,
            "kind 0",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 0);
                b[e + directory::OFF_KIND] = 0
            }),
            Code::EntryKind,
        ),
        (
            q,
            "unknown codec",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 1);
                b[e + directory::OFF_CODEC] = 3
            }),
            Code::EntryCodec,
        ),
        (
            q,
            "reserved entry word",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 0);
                put_u32(b, e + directory::OFF_RESERVED, 1 << 31)
            }),
            Code::EntryReserved,
        ),
        (
            q,
            "raw over the block size",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 0);
                put_u32(b, e + directory::OFF_RAW_LENGTH, 4097)
            }),
            Code::EntryLength,
        ),
        (
            q,
            "codec none with stored != raw",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 0);
                let r = get_u32(b, e + directory::OFF_RAW_LENGTH);
                put_u32(b, e + directory::OFF_RAW_LENGTH, r + 1)
            }),
            Code::EntryLength,
        ),
        (
            q,
            "raw length 0",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 0);
                put_u32(b, e + directory::OFF_RAW_LENGTH, 0)
            }),
            Code::EntryLength,
        ),
        (
            q,
            "codec lz4 with stored == raw",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 0);
                b[e + directory::OFF_CODEC] = 1
            }),
            Code::EntryLength,
        ),
        (
            q,
            "level on a triangle block",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 1);
                put_u16(b, e + directory::OFF_LEVEL, 1)
            }),
            Code::EntryLevel,
        ),
        (
            d,
            "level on a proxy block",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 2);
                put_u16(b, e + directory::OFF_LEVEL, 3)
            }),
            Code::EntryLevel,
        ),
        (
            d,
            "treelet levels out of order",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 5);
                put_u16(b, e + directory::OFF_LEVEL, 0)
            }),
            Code::EntryLevel,
        ),
        (
            q,
            "item count 0",
            Box::new(|b: &mut Vec<u8>| {
                let e = entry_at(b, 1);
                put_u32(b, e + directory::OFF_ITEM_COUNT, 0)
            }),
            Code::EntryItemCount,
        ),
        // Byte 48 of the metadata is the tag of `root: Option<_>`, after the 48-byte scene.
        (
            q,
            "metadata option tag 7",
            Box::new(|b: &mut Vec<u8>| {
                let at = get_u64(b, header::OFF_METADATA_OFFSET) as usize;
                b[at + 48] = 7
            }),
            Code::MetadataDecode,
        ),
    ];
    for (name, what, edit, code) in cases {
        expect_code(name, what, edit, code, Depth::Quick, true)?;
    }
    Ok(())
}

/// Offsets inside the uncompressed fixture: block 0 (treelet) and block 1 (triangles).
fn quad_blocks(b: &[u8]) -> (usize, usize) {
    let e0 = entry_at(b, 0);
    let e1 = entry_at(b, 1);
    (get_u64(b, e0) as usize, get_u64(b, e1) as usize)
}

#[test]
fn block_rules_hold_on_their_own() -> TestResult {
    let q = "fx-quad-none";
    // Treelet block: 16-byte head, 1 start, nodes at +20 (basic, leaf, leaf).
    // Triangle block: 16-byte head, list (2 × u16), triangles (2 × 6 bytes), 4 vertices.
    let cases: Vec<(&str, Edit, Code)> = vec![
        (
            "treelet reserved",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                b[t + 12] = 1
            }),
            Code::TreeletLayout,
        ),
        (
            "treelet count 2",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                b[t] = 2
            }),
            Code::TreeletLayout,
        ),
        (
            "treelet start 8",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                b[t + 16] = 8
            }),
            Code::TreeletLayout,
        ),
        (
            "node type 3",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                b[t + 28] |= 3
            }),
            Code::NodeType,
        ),
        (
            "split axis 3",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                b[t + 20] |= 0b1100
            }),
            Code::NodeField,
        ),
        (
            "basic reserved bits",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                b[t + 20] |= 0x40
            }),
            Code::NodeField,
        ),
        (
            "NaN split",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                put_u32(b, t + 24, 0x7fc0_0000)
            }),
            Code::NodeField,
        ),
        (
            "empty flag with an offset",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                b[t + 20] |= 0x10
            }),
            Code::NodeChild,
        ),
        (
            "leaf with no triangles",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                b[t + 28] &= 0x0f;
                b[t + 29] &= 0xf0
            }),
            Code::NodeField,
        ),
        (
            "right child before left",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                let w = get_u32(b, t + 20);
                put_u32(b, t + 20, (w & 0xff) | (2 << 8) | (1 << 20))
            }),
            Code::NodeChild,
        ),
        (
            "child outside the treelet",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                let w = get_u32(b, t + 20);
                put_u32(b, t + 20, (w & 0xfffff) | (3 << 20))
            }),
            Code::NodeChild,
        ),
        (
            "a node reached twice",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                let w = get_u32(b, t + 20);
                put_u32(b, t + 20, (w & 0xfffff) | (1 << 20))
            }),
            Code::NodeChild,
        ),
        (
            "triangle attributes",
            Box::new(|b: &mut Vec<u8>| {
                let (_, r) = quad_blocks(b);
                b[r + 12] = 1
            }),
            Code::TriangleAttributes,
        ),
        (
            "reserved attribute bit",
            Box::new(|b: &mut Vec<u8>| {
                let (_, r) = quad_blocks(b);
                b[r + 13] = 0x80
            }),
            Code::TriangleLayout,
        ),
        (
            "primaries over triangles",
            Box::new(|b: &mut Vec<u8>| {
                let (_, r) = quad_blocks(b);
                put_u16(b, r + 14, 3)
            }),
            Code::TriangleLayout,
        ),
        (
            "list entry past the triangles",
            Box::new(|b: &mut Vec<u8>| {
                let (_, r) = quad_blocks(b);
                put_u16(b, r + 16, 2)
            }),
            Code::TriangleIndex,
        ),
        (
            "vertex index past the vertices",
            Box::new(|b: &mut Vec<u8>| {
                let (_, r) = quad_blocks(b);
                put_u16(b, r + 20, 4)
            }),
            Code::TriangleIndex,
        ),
        (
            "vertex not finite",
            Box::new(|b: &mut Vec<u8>| {
                let (_, r) = quad_blocks(b);
                put_u32(b, r + 32 + 4, 0x7f80_0000)
            }),
            Code::VertexNotFinite,
        ),
    ];
    for (what, edit, code) in cases {
        expect_code(q, what, edit, code, Depth::Full, true)?;
    }
    // References are checked by deep verify only. The leaves are at +28 and +36.
    let deep_cases: Vec<(&str, Edit, Code)> = vec![
        (
            "leaf names a treelet block",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                put_u32(b, t + 32, 0)
            }),
            Code::TreeReference,
        ),
        (
            "leaf names a missing block",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                put_u32(b, t + 40, 7)
            }),
            Code::TreeReference,
        ),
        (
            "leaf entries past the list",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                put_u32(b, t + 36, 2 | (1 << 4) | (2 << 16))
            }),
            Code::TreeReference,
        ),
        (
            "leaf with more triangles",
            Box::new(|b: &mut Vec<u8>| {
                let (t, _) = quad_blocks(b);
                put_u32(b, t + 28, 2 | (3 << 4))
            }),
            Code::TreeReference,
        ),
    ];
    for (what, edit, code) in deep_cases {
        expect_code(q, what, edit, code, Depth::Deep, false)?;
    }
    Ok(())
}

fn edit_metadata(name: &str, edit: impl Fn(&mut Metadata)) -> TestResult<Vec<u8>> {
    let b = file(name)?;
    let mut m = Metadata::decode(metadata_bytes(&b), minor_of(&b))?;
    edit(&mut m);
    with_metadata(&b, &m.encode()?)
}

#[test]
fn tree_rules_hold_on_their_own() -> TestResult {
    type MetaEdit = fn(&mut Metadata);
    let cases: [(&str, &str, MetaEdit, Code); 11] = [
        (
            "fx-deep-zstd",
            "root in a level-1 block",
            |m| {
                m.root = Some(TreeletRef {
                    block: 3,
                    treelet: 0,
                })
            },
            Code::TreeRoot,
        ),
        (
            "fx-deep-zstd",
            "root in a triangle block",
            |m| {
                m.root = Some(TreeletRef {
                    block: 0,
                    treelet: 0,
                })
            },
            Code::TreeRoot,
        ),
        (
            "fx-deep-zstd",
            "root treelet out of range",
            |m| {
                m.root = Some(TreeletRef {
                    block: 1,
                    treelet: 1,
                })
            },
            Code::TreeRoot,
        ),
        ("fx-deep-zstd", "no root", |m| m.root = None, Code::TreeRoot),
        (
            "fx-deep-zstd",
            "counts.leaves",
            |m| m.counts.leaves += 1,
            Code::TreeCounts,
        ),
        (
            "fx-deep-zstd",
            "counts.depth",
            |m| m.counts.depth = 4,
            Code::TreeCounts,
        ),
        (
            "fx-lod-lz4",
            "six_sample_voxels",
            |m| m.schema.six_sample_voxels = false,
            Code::TreeCounts,
        ),
        (
            "fx-lod-lz4",
            "materials",
            |m| m.materials.truncate(1),
            Code::TreeMaterial,
        ),
        (
            "fx-lod-lz4",
            "a box too small for the split",
            |m| m.scene.bounds_max[0] = 0.9,
            Code::TreeSplit,
        ),
        (
            "fx-lod-lz4",
            "a box too big for the radius",
            |m| m.scene.bounds_max[2] = 3.0,
            Code::TreeLodRadius,
        ),
        (
            "fx-deep-zstd",
            "schema attributes",
            |m| m.schema.vertex_colours = true,
            Code::TriangleAttributes,
        ),
    ];
    for (name, what, edit, code) in cases {
        let b = edit_metadata(name, edit)?;
        let r = verify_bytes(&b, &deep())?;
        assert!(r.has(code) && !r.valid, "{name}: {what}: {:?}", r.issues);
        let full_report = verify_bytes(&b, &full())?;
        assert!(
            !full_report.has(Code::MetadataChecksum),
            "{name}: {what}: re-seal failed"
        );
    }
    // A wrong feature bit is a warning only.
    let mut b = file("fx-lod-lz4")?;
    put_u64(&mut b, header::OFF_COMPAT, header::COMPAT_LOD_VOXELS);
    let b = reseal(&b)?;
    let r = verify_bytes(&b, &deep())?;
    assert!(
        r.valid && r.has(Code::HeaderFeatureMismatch),
        "{:?}",
        r.issues
    );
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Random damage

#[derive(Clone, Debug)]
enum Damage {
    Overwrite(Index, Vec<u8>),
    Insert(Index, Vec<u8>),
    Delete(Index, usize),
    Flip(Index, u8),
    /// A little-endian u32 at a 4-aligned position (fields are aligned).
    Word(Index, u32),
}

fn damage() -> impl Strategy<Value = Damage> {
    prop_oneof![
        3 => (any::<Index>(), prop::collection::vec(any::<u8>(), 1..8)).prop_map(|(i, v)| Damage::Overwrite(i, v)),
        1 => (any::<Index>(), prop::collection::vec(any::<u8>(), 1..16)).prop_map(|(i, v)| Damage::Insert(i, v)),
        1 => (any::<Index>(), 1usize..32).prop_map(|(i, n)| Damage::Delete(i, n)),
        3 => (any::<Index>(), 0u8..8).prop_map(|(i, bit)| Damage::Flip(i, bit)),
        2 => (any::<Index>(), prop_oneof![Just(0u32), Just(1), Just(u32::MAX), Just(0x8000_0000), Just(0xffff), any::<u32>()])
            .prop_map(|(i, v)| Damage::Word(i, v)),
    ]
}

fn apply(b: &mut Vec<u8>, d: &Damage) {
    if b.is_empty() {
        return;
    }
    match d {
        Damage::Overwrite(i, v) => {
            let at = i.index(b.len());
            let n = v.len().min(b.len() - at);
            b[at..at + n].copy_from_slice(&v[..n]);
        }
        Damage::Insert(i, v) => {
            let at = i.index(b.len() + 1);
            b.splice(at..at, v.iter().copied());
        }
        Damage::Delete(i, n) => {
            let at = i.index(b.len());
            let end = (at + n).min(b.len());
            b.drain(at..end);
        }
        Damage::Flip(i, bit) => {
            let at = i.index(b.len());
            b[at] ^= 1 << bit;
        }
        Damage::Word(i, v) => {
            if b.len() >= 4 {
                let at = i.index(b.len() / 4) * 4;
                put_u32(b, at, *v);
            }
        }
    }
}

/// Everything a reader and verify do with `b`, with checksums on; must not panic.
fn survive(b: &[u8]) -> TestResult {
    if let Ok(r) = open_bytes(b, ReadOptions::default()) {
        let _ = read_all_blocks(&r);
        let _ = oocfmt::summary::summarize(&r);
    }
    let report = verify_bytes(b, &deep())?;
    assert_eq!(report.valid, report.errors == 0);
    Ok(())
}

proptest! {
    #![proptest_config(proptest_config(256))]

    #[test]
    fn random_damage_never_panics(file in any::<Index>(), ops in prop::collection::vec(damage(), 1..6)) {
        let f = &files()[file.index(files().len())];
        let mut b = f.bytes.clone();
        for d in &ops {
            apply(&mut b, d);
        }
        prop_assert!(survive(&b).is_ok());
        // The same damage behind valid checksums reaches the structural checks.
        if let Some(sealed) = props::reseal_with_blocks(&b) {
            prop_assert!(survive(&sealed).is_ok());
        }
        // And with checksums skipped, through the fuzz property (which also cross-checks the
        // reader against verify).
        props::open_verify(&b);
    }

    #[test]
    fn damaged_block_bytes_with_checksums_skipped_never_panic(
        file in any::<Index>(),
        ops in prop::collection::vec((any::<Index>(), any::<u8>(), 0u8..3), 1..12),
    ) {
        let f = &files()[file.index(files().len())];
        let mut b = f.bytes.clone();
        let (dir, _) = directory_of(&b);
        let blocks = dir - header::HEADER_LEN;
        if blocks > 0 {
            for (i, v, how) in &ops {
                let at = header::HEADER_LEN + i.index(blocks);
                match how {
                    0 => b[at] = *v,
                    1 => b[at] ^= 1 << (v % 8),
                    _ => b[at] = b[at].wrapping_add(*v),
                }
            }
        }
        let skip = ReadOptions { checksums: Checksums::Skip, ..ReadOptions::default() };
        if let Ok(r) = open_bytes(&b, skip) {
            let _ = read_all_blocks(&r);
        }
        let rep = verify_bytes(&b, &VerifyOptions { depth: Depth::Deep, checksums: Checksums::Skip, ..VerifyOptions::default() });
        prop_assert!(rep.is_ok());
        // With checksums on, the damage is always seen (a block CRC).
        if b != f.bytes {
            let rep = verify_bytes(&b, &full());
            prop_assert!(rep.is_ok_and(|r| !r.valid));
        }
        props::exercise_file(b);
    }
}

#[test]
fn the_counting_allocator_sees_large_allocations() {
    let _guard = PEAK_LOCK.lock().unwrap_or_else(|p| p.into_inner());
    PEAK.store(0, Ordering::SeqCst);
    let v = std::hint::black_box(vec![1u8; 3 << 20]);
    assert!(PEAK.load(Ordering::SeqCst) >= 3 << 20);
    drop(v);
}

// ---------------------------------------------------------------------------------------------
// Regressions: bugs these tests found in crates/oocfmt/src, fixed since.

#[test]
/// `BlockEntry::end()` used to overflow (a panic in debug builds) in `check_placement`.
fn an_entry_offset_near_u64_max_is_refused_without_panic() -> TestResult {
    for f in files() {
        let (dir, count) = directory_of(&f.bytes);
        for i in 0..count {
            let mut b = f.bytes.clone();
            put_u64(
                &mut b,
                dir + i * directory::ENTRY_LEN + directory::OFF_OFFSET,
                u64::MAX,
            );
            let b = reseal(&b)?;
            let caught = std::panic::catch_unwind(|| {
                (
                    reader_code(&b),
                    verify_bytes(&b, &full()).map(|r| r.has(Code::EntryOffset)),
                )
            });
            let (code, flagged) = caught.map_err(|_| {
                format!(
                    "{}: block {i} at offset u64::MAX: the reader or verify panicked",
                    f.name
                )
            })?;
            assert_eq!(code, Some(Code::EntryOffset), "{}: block {i}", f.name);
            assert!(flagged?, "{}: block {i}", f.name);
        }
    }
    Ok(())
}

#[test]
/// Deep verify used to panic in `split_cell` (`f64::clamp` with a NaN bound) on NaN scene bounds;
/// found by the `open_verify` fuzzer within seconds.
fn nan_scene_bounds_do_not_panic_deep_verify() -> TestResult {
    for (name, axis, max) in [
        ("fx-quad-none", 0, false),
        ("fx-lod-lz4", 1, true),
        ("fx-deep-zstd", 2, false),
    ] {
        let b = edit_metadata(name, |m| {
            if max {
                m.scene.bounds_max[axis] = f32::NAN;
            } else {
                m.scene.bounds_min[axis] = f32::NAN;
            }
        })?;
        let r = std::panic::catch_unwind(|| verify_bytes(&b, &deep()));
        let r = r.map_err(|_| format!("{name}: deep verify panicked on NaN scene bounds"))?;
        assert!(
            !r?.valid,
            "{name}: NaN scene bounds must make the file invalid (spec §1: f32 fields are finite)"
        );
    }
    // The file the fuzzer found (fuzz/regressions/open_verify/).
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fuzz/regressions/open_verify/nan-scene-bounds-deep-verify-panics"
    );
    let data = std::fs::read(path)?;
    assert!(
        std::panic::catch_unwind(|| props::open_verify(&data)).is_ok(),
        "the fuzz regression still panics"
    );
    Ok(())
}

#[test]
/// `Metadata::decode` used to accept non-finite floats (spec §1: every f32 is finite).
fn non_finite_metadata_floats_are_refused() -> TestResult {
    type MetaEdit = fn(&mut oocfmt::Metadata);
    let cases: [(&str, MetaEdit); 6] = [
        ("bounds_min = NaN", |m| m.scene.bounds_min[0] = f32::NAN),
        ("origin = NaN", |m| m.scene.origin[1] = f64::NAN),
        ("an inverted box", |m| m.scene.bounds_min[0] = 2.5),
        ("bounds_max = +inf", |m| {
            m.scene.bounds_max[1] = f32::INFINITY
        }),
        ("bounds_min = -inf", |m| {
            m.scene.bounds_min[2] = f32::NEG_INFINITY
        }),
        ("diffuse = NaN", |m| m.materials[0].diffuse[1] = f32::NAN),
    ];
    for (what, edit) in cases {
        let b = edit_metadata("fx-lod-lz4", edit)?;
        assert_eq!(
            reader_code(&b),
            Some(Code::MetadataDecode),
            "{what}: the reader"
        );
        let r = std::panic::catch_unwind(|| verify_bytes(&b, &full()));
        let r = r.map_err(|_| format!("{what}: verify panicked"))?;
        assert!(!r?.valid, "{what}: verify (default depth) says valid");
    }
    Ok(())
}

#[test]
/// Verify used to ignore `Limits::max_resident_bytes` and call valid a file the reader refuses.
fn verify_enforces_the_resident_proxy_limit() -> TestResult {
    let b = file("fx-deep-zstd")?; // one proxy block of 2 × 80 bytes
    let limits = Limits {
        max_resident_bytes: 100,
        ..Limits::default()
    };
    let e = open_bytes(
        &b,
        ReadOptions {
            limits,
            ..ReadOptions::default()
        },
    )
    .err()
    .map(|e| e.code());
    assert_eq!(e, Some(Code::LimitExceeded));
    let r = verify_bytes(
        &b,
        &VerifyOptions {
            limits,
            ..VerifyOptions::default()
        },
    )?;
    assert!(
        r.has(Code::LimitExceeded) && !r.valid,
        "verify with the same limits: {:?}",
        r.issues
    );
    Ok(())
}

/// A file of `n` proxy blocks, each one stored byte claiming 1 MiB raw under LZ4 (1 MiB blocks):
/// every rule the directory alone can check holds, and it is about 32 bytes per block.
fn proxy_bomb(n: u32) -> TestResult<Vec<u8>> {
    let meta = Metadata::default().encode()?;
    let mut h = oocfmt::Header::new(20);
    let blocks_end = header::HEADER_LEN as u64 + u64::from(n);
    h.sections = header::SectionTable {
        directory_offset: blocks_end,
        block_count: n,
        metadata_offset: blocks_end + u64::from(n) * directory::ENTRY_LEN as u64,
        metadata_length: u32::try_from(meta.len())?,
    };
    h.compatible_features = header::COMPAT_PROXIES;
    let mut b = h.encode().to_vec();
    b.extend(std::iter::repeat_n(0u8, n as usize));
    for i in 0..n {
        let e = oocfmt::BlockEntry {
            offset: header::HEADER_LEN as u64 + u64::from(i),
            stored_length: 1,
            raw_length: 1 << 20,
            crc: oocfmt::checksum::crc32c(&[0]),
            kind: oocfmt::BlockKind::Proxy,
            codec: oocfmt::CodecId::Lz4,
            level: 0,
            item_count: 13107,
        };
        e.encode_into(&mut b);
    }
    b.extend_from_slice(&meta);
    let t = oocfmt::Trailer {
        sections: h.sections,
        directory_crc: 0,
        metadata_crc: 0,
        root_checksum: 0,
    };
    b.extend_from_slice(&t.encode());
    reseal(&b)
}

#[test]
fn opening_a_proxy_bomb_allocates_little() -> TestResult {
    let b = proxy_bomb(64)?;
    assert!(b.len() < 4096);
    let _guard = PEAK_LOCK.lock().unwrap_or_else(|p| p.into_inner());
    PEAK.store(0, Ordering::SeqCst);
    let r = open_bytes(&b, ReadOptions::default());
    let peak = PEAK.load(Ordering::SeqCst);
    assert!(r.is_err(), "the blocks do not decompress");
    assert!(
        peak <= (1 << 20) + b.len(),
        "Reader::open of a {}-byte file allocated {peak} bytes at once",
        b.len()
    );
    Ok(())
}

#[test]
fn a_proxy_bomb_is_refused_by_reader_and_verify() -> TestResult {
    let b = proxy_bomb(64)?;
    let e = open_bytes(&b, ReadOptions::default())
        .err()
        .map(|e| e.code());
    assert_eq!(e, Some(Code::BlockDecompress));
    let skip = ReadOptions {
        checksums: Checksums::Skip,
        ..ReadOptions::default()
    };
    assert_eq!(
        open_bytes(&b, skip).err().map(|e| e.code()),
        Some(Code::BlockDecompress)
    );
    let r = verify_bytes(&b, &deep())?;
    assert!(r.has(Code::BlockDecompress) && !r.valid, "{:?}", codes(&r));
    let tight = Limits {
        max_resident_bytes: 32 << 20,
        ..Limits::default()
    };
    let e = open_bytes(
        &b,
        ReadOptions {
            limits: tight,
            ..ReadOptions::default()
        },
    )
    .err()
    .map(|e| e.code());
    assert_eq!(e, Some(Code::LimitExceeded));
    Ok(())
}

#[test]
fn a_short_file_of_another_major_version_is_named_as_such() -> TestResult {
    let mut head = oocfmt::Header::new(16).encode().to_vec();
    head[oocfmt::header::OFF_MAJOR] = 2;
    for len in [12, 40, 64, 100] {
        let b = &head
            .iter()
            .copied()
            .chain(std::iter::repeat(0))
            .take(len)
            .collect::<Vec<u8>>();
        let e = open_bytes(b, ReadOptions::default())
            .err()
            .map(|e| e.code());
        assert_eq!(e, Some(Code::HeaderVersionUnsupported), "{len} bytes");
        assert!(
            verify_bytes(b, &VerifyOptions::default())?.has(Code::HeaderVersionUnsupported),
            "{len} bytes"
        );
    }
    let e = open_bytes(&head[..11], ReadOptions::default())
        .err()
        .map(|e| e.code());
    assert_eq!(e, Some(Code::FileTooSmall), "too short to hold the version");
    Ok(())
}

/// Byte offset of the first R-LOD record of block 0 of `lod-rlod.oocf` (uncompressed, both LOD
/// kinds: the record follows its node's voxel).
fn first_rlod(b: &[u8]) -> usize {
    let t = get_u64(b, entry_at(b, 0)) as usize;
    let (count, nodes, lod) = (
        get_u32(b, t) as usize,
        get_u32(b, t + 4) as usize,
        get_u32(b, t + 8) as usize,
    );
    assert!(lod > 0, "block 0 has no LOD entries");
    let area = t + 16 + 4 * count + nodes;
    let voxel = if get_u32(b, area) >> 31 == 1 { 4 } else { 24 };
    area + voxel
}

#[test]
fn bad_r_lod_records_are_refused() -> TestResult {
    let v = "lod-rlod.oocf";
    let at = first_rlod(&file(v)?);
    let cases: Vec<(&str, Edit, Code, Depth)> = vec![
        (
            "NaN normal",
            Box::new(move |b: &mut Vec<u8>| put_u32(b, at, f32::NAN.to_bits())),
            Code::Rlod,
            Depth::Full,
        ),
        (
            "infinite offset",
            Box::new(move |b: &mut Vec<u8>| put_u32(b, at + 12, f32::INFINITY.to_bits())),
            Code::Rlod,
            Depth::Full,
        ),
        (
            "normal of length 2",
            Box::new(move |b: &mut Vec<u8>| {
                for k in 0..3 {
                    let c = f32::from_bits(get_u32(b, at + 4 * k));
                    put_u32(b, at + 4 * k, (2.0 * c).to_bits());
                }
            }),
            Code::Rlod,
            Depth::Full,
        ),
        (
            "reserved byte",
            Box::new(move |b: &mut Vec<u8>| b[at + 19] = 1),
            Code::Rlod,
            Depth::Full,
        ),
        (
            "reserved tail",
            Box::new(move |b: &mut Vec<u8>| b[at + 23] = 1),
            Code::Rlod,
            Depth::Full,
        ),
        (
            "plane far from its cell",
            Box::new(move |b: &mut Vec<u8>| put_u32(b, at + 12, 1.0e6f32.to_bits())),
            Code::Rlod,
            Depth::Deep,
        ),
        (
            "NO_VOXELS without RLODS",
            Box::new(|b: &mut Vec<u8>| {
                put_u64(b, header::OFF_INCOMPAT, header::INCOMPAT_LOD_NO_VOXELS)
            }),
            Code::HeaderFeatureUnsupported,
            Depth::Quick,
        ),
    ];
    for (what, edit, code, depth) in cases {
        expect_code(v, what, edit, code, depth, false)?;
    }
    Ok(())
}
