//! Fault injection, as SQLite tests it: the k-th write, seek or sync of the writer fails (k = 1,
//! 2, … until a run succeeds), the k-th read of the reader's source fails; every run must fail
//! cleanly — an `IO` error, no file under the final name (or the old file there unchanged), no
//! temporary file left, never garbage data or a bogus verify report.

use crate::common;

use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use common::{deep, fixture, fixtures, open_bytes, read_all_blocks, TestResult};
use oocfmt::verify::{verify, Report};
use oocfmt::writer::OutputFile;
use oocfmt::{ByteSource, Code, ReadOptions, Reader, WriteOptions, WriteSummary, Writer};

// ---------------------------------------------------------------------------------------------
// Writer faults

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Fault {
    /// The k-th `write` fails.
    Write,
    /// The k-th `write` writes half its bytes (a legal short write); the next `write` fails.
    ShortThenFail,
    /// The k-th `write` is interrupted (`ErrorKind::Interrupted`): `write_all` retries, so the
    /// operation must succeed.
    Interrupted,
    /// The k-th `seek` fails.
    Seek,
    /// The k-th `sync` fails.
    Sync,
}

/// An output file that fails its k-th operation of one kind.
struct Failing<W> {
    inner: W,
    fault: Fault,
    k: usize,
    /// Operations of the faulty kind so far, shared with the test.
    seen: Arc<AtomicUsize>,
    broken: bool,
}

impl<W> Failing<W> {
    fn new(inner: W, fault: Fault, k: usize, seen: Arc<AtomicUsize>) -> Self {
        Failing {
            inner,
            fault,
            k,
            seen,
            broken: false,
        }
    }

    /// Counts an operation of kind `f`; true when it is the k-th.
    fn hit(&mut self, f: Fault) -> bool {
        let kind = match self.fault {
            Fault::ShortThenFail | Fault::Interrupted => Fault::Write,
            other => other,
        };
        kind == f && self.seen.fetch_add(1, Ordering::SeqCst) + 1 == self.k
    }
}

fn injected(what: &str) -> io::Error {
    io::Error::other(format!("injected {what} fault"))
}

impl<W: Write> Write for Failing<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.broken {
            return Err(injected("write after a short write"));
        }
        if self.hit(Fault::Write) {
            match self.fault {
                Fault::ShortThenFail if buf.len() > 1 => {
                    self.broken = true;
                    return self.inner.write(&buf[..buf.len() / 2]);
                }
                Fault::Interrupted => return Err(io::Error::from(io::ErrorKind::Interrupted)),
                _ => return Err(injected("write")),
            }
        }
        self.inner.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

impl<W: Seek> Seek for Failing<W> {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        if self.hit(Fault::Seek) {
            return Err(injected("seek"));
        }
        self.inner.seek(pos)
    }
}

impl<W: OutputFile> OutputFile for Failing<W> {
    fn sync(&mut self) -> io::Result<()> {
        if self.hit(Fault::Sync) {
            return Err(injected("sync"));
        }
        self.inner.sync()
    }
}

/// Writes the blocks and metadata of `src` again through a writer over `wrap`.
fn rewrite<F: OutputFile>(
    src: &Reader,
    path: &Path,
    wrap: impl FnOnce(File) -> io::Result<F>,
) -> oocfmt::Result<WriteSummary> {
    let codec = src
        .entries()
        .iter()
        .find(|e| e.codec != oocfmt::CodecId::None)
        .map_or(oocfmt::Codec::None, |e| match e.codec {
            oocfmt::CodecId::Zstd => oocfmt::Codec::Zstd(3),
            _ => oocfmt::Codec::Lz4,
        });
    let opts = WriteOptions {
        block_size_log2: src.header().block_size_log2,
        codec,
        lod: src.lod_kinds(),
    };
    let mut w = Writer::create_with(path, opts, wrap)?;
    for id in 0..src.header().sections.block_count {
        let b = src.read_block(id)?;
        w.write_block(b.entry.kind, b.entry.level, b.entry.item_count, &b.data)?;
    }
    w.finish(src.metadata())
}

/// The names in `dir`, sorted.
fn listing(dir: &Path) -> TestResult<Vec<String>> {
    let mut v: Vec<String> = std::fs::read_dir(dir)?
        .map(|e| e.map(|e| e.file_name().to_string_lossy().into_owned()))
        .collect::<Result<_, _>>()?;
    v.sort();
    Ok(v)
}

/// Runs `rewrite` with fault `fault` at k = 1, 2, … until a run succeeds, checking every failed
/// run; `old` is the content already under the final name, if any. Returns the number of runs.
fn fault_loop(src_bytes: &[u8], fault: Fault, old: Option<&[u8]>) -> TestResult<usize> {
    let src = open_bytes(src_bytes, ReadOptions::default())?;
    for k in 1..10_000 {
        let dir = tempfile::tempdir()?;
        let path = dir.path().join("out.oocf");
        if let Some(old) = old {
            std::fs::write(&path, old)?;
        }
        let seen = Arc::new(AtomicUsize::new(0));
        let s2 = Arc::clone(&seen);
        let result = rewrite(&src, &path, move |f| {
            Ok(Failing::new(BufWriter::new(f), fault, k, s2))
        });
        let names = listing(dir.path())?;
        let fired = seen.load(Ordering::SeqCst) >= k;
        match result {
            Ok(_) => {
                assert!(
                    !fired || fault == Fault::Interrupted,
                    "{fault:?} k={k}: the fault fired but the write succeeded"
                );
                assert_eq!(names, vec!["out.oocf".to_string()], "{fault:?} k={k}");
                assert_eq!(
                    std::fs::read(&path)?,
                    src_bytes,
                    "{fault:?} k={k}: the rewritten file differs"
                );
                if fault == Fault::Interrupted && fired {
                    continue;
                }
                return Ok(k);
            }
            Err(e) => {
                assert!(fired, "{fault:?} k={k}: failed without the fault: {e}");
                assert_ne!(
                    fault,
                    Fault::Interrupted,
                    "k={k}: an interrupted write must be retried: {e}"
                );
                assert_eq!(e.code(), Code::Io, "{fault:?} k={k}: {e}");
                match old {
                    Some(old) => {
                        assert_eq!(
                            names,
                            vec!["out.oocf".to_string()],
                            "{fault:?} k={k}: left {names:?}"
                        );
                        assert_eq!(
                            std::fs::read(&path)?,
                            old,
                            "{fault:?} k={k}: the old file changed"
                        );
                    }
                    None => assert!(names.is_empty(), "{fault:?} k={k}: left {names:?}"),
                }
            }
        }
    }
    Err(format!("{fault:?}: never succeeded").into())
}

#[test]
fn every_write_fault_fails_cleanly() -> TestResult {
    for f in fixtures()? {
        for fault in [Fault::Write, Fault::ShortThenFail, Fault::Seek, Fault::Sync] {
            for old in [None, Some(&b"an older file that must survive"[..])] {
                let runs = fault_loop(&f.bytes, fault, old)?;
                // Blocks + directory + metadata + trailer + header: the loop really went through.
                if matches!(fault, Fault::Write | Fault::ShortThenFail) {
                    assert!(runs >= 5, "{}: {fault:?}: only {runs} writes", f.name);
                }
            }
        }
    }
    Ok(())
}

#[test]
fn interrupted_writes_are_retried() -> TestResult {
    for f in fixtures()? {
        fault_loop(&f.bytes, Fault::Interrupted, None)?;
    }
    Ok(())
}

#[test]
fn a_dropped_writer_leaves_nothing() -> TestResult {
    let src_bytes = fixture("fx-lod-lz4")?;
    let src = open_bytes(&src_bytes, ReadOptions::default())?;
    for blocks in 0..=src.header().sections.block_count {
        for old in [None, Some(&b"old"[..])] {
            let dir = tempfile::tempdir()?;
            let path = dir.path().join("out.oocf");
            if let Some(old) = old {
                std::fs::write(&path, old)?;
            }
            let mut w = Writer::create(&path, WriteOptions::default())?;
            let temp = w.temp_path().to_path_buf();
            assert!(temp.exists(), "the writer writes a temporary file");
            let name = temp
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            assert!(
                name.starts_with(".out.oocf.") && name.ends_with(".partial"),
                "{name}"
            );
            for id in 0..blocks {
                let b = src.read_block(id)?;
                w.write_block(b.entry.kind, b.entry.level, b.entry.item_count, &b.data)?;
            }
            drop(w);
            let expect: Vec<String> = old.iter().map(|_| "out.oocf".to_string()).collect();
            assert_eq!(listing(dir.path())?, expect, "after {blocks} blocks");
            if let Some(old) = old {
                assert_eq!(std::fs::read(&path)?, old);
            }
        }
    }
    Ok(())
}

#[test]
fn a_writer_error_closes_the_writer() -> TestResult {
    let src_bytes = fixture("fx-deep-zstd")?;
    let src = open_bytes(&src_bytes, ReadOptions::default())?;
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("out.oocf");
    let seen = Arc::new(AtomicUsize::new(0));
    let s2 = Arc::clone(&seen);
    let mut w = Writer::create_with(&path, WriteOptions::default(), move |f| {
        Ok(Failing::new(BufWriter::new(f), Fault::Write, 3, s2))
    })?;
    let b = src.read_block(0)?;
    assert!(w
        .write_block(b.entry.kind, b.entry.level, b.entry.item_count, &b.data)
        .is_ok());
    let e = w
        .write_block(b.entry.kind, b.entry.level, b.entry.item_count, &b.data)
        .err()
        .map(|e| e.code());
    assert_eq!(e, Some(Code::Io));
    assert!(
        listing(dir.path())?.is_empty(),
        "the temporary file is removed at the failure"
    );
    // Later calls fail without touching the disk, and finish fails.
    assert!(w
        .write_block(b.entry.kind, b.entry.level, b.entry.item_count, &b.data)
        .is_err());
    assert!(w.finish(src.metadata()).is_err());
    assert!(listing(dir.path())?.is_empty());
    Ok(())
}

#[test]
fn a_writer_into_a_missing_directory_fails_cleanly() -> TestResult {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("missing").join("out.oocf");
    let e = Writer::create(&path, WriteOptions::default())
        .err()
        .map(|e| e.code());
    assert_eq!(e, Some(Code::Io));
    assert!(listing(dir.path())?.is_empty());
    // A bad block size is refused before anything is created.
    let e = Writer::create(
        &dir.path().join("x.oocf"),
        WriteOptions {
            block_size_log2: 21,
            ..WriteOptions::default()
        },
    )
    .err()
    .map(|e| e.code());
    assert_eq!(e, Some(Code::InvalidParameter));
    assert!(listing(dir.path())?.is_empty());
    Ok(())
}

/// `create_with` used to leak its temporary file when the wrap closure or the placeholder header
/// write failed (the `Drop` guard was not armed yet).
#[test]
fn a_failed_first_write_leaves_nothing() -> TestResult {
    let src = open_bytes(&fixture("fx-quad-none")?, ReadOptions::default())?;
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("out.oocf");
    // The first write is the placeholder header inside `create_with`.
    let seen = Arc::new(AtomicUsize::new(0));
    let s2 = Arc::clone(&seen);
    let r = rewrite(&src, &path, move |f| {
        Ok(Failing::new(BufWriter::new(f), Fault::Write, 1, s2))
    });
    assert_eq!(r.err().map(|e| e.code()), Some(Code::Io));
    assert_eq!(
        listing(dir.path())?,
        Vec::<String>::new(),
        "a failed create_with must not leave its temporary file"
    );
    // The wrap closure failing: same.
    let r = Writer::<BufWriter<File>>::create_with(&path, WriteOptions::default(), |_| {
        Err(injected("wrap"))
    });
    assert_eq!(r.err().map(|e| e.code()), Some(Code::Io));
    assert_eq!(
        listing(dir.path())?,
        Vec::<String>::new(),
        "a failed wrap must not leave the temporary file"
    );
    Ok(())
}

/// `write_encoded` used to trust an `EncodedBlock`'s codec, lengths and CRC and write a file its
/// own reader refuses; it must refuse such a block and stay usable.
#[test]
fn write_encoded_refuses_an_inconsistent_block() -> TestResult {
    use oocfmt::checksum::crc32c;
    use oocfmt::{BlockKind, CodecId, EncodedBlock};
    let raw = vec![7u8; 100];
    let block = |codec, stored: Vec<u8>, crc| EncodedBlock {
        kind: BlockKind::Triangle,
        level: 0,
        item_count: 1,
        raw_length: 100,
        codec,
        crc,
        stored,
    };
    let bad = [
        (
            "compressed but not smaller",
            block(CodecId::Lz4, raw.clone(), crc32c(&raw)),
        ),
        (
            "uncompressed but short",
            block(CodecId::None, raw[..50].to_vec(), crc32c(&raw[..50])),
        ),
        (
            "nothing stored",
            block(CodecId::Zstd, Vec::new(), crc32c(&[])),
        ),
        (
            "a wrong CRC",
            block(CodecId::None, raw.clone(), crc32c(&raw) ^ 1),
        ),
    ];
    let src = open_bytes(&fixture("fx-quad-none")?, ReadOptions::default())?;
    for (what, b) in bad {
        let dir = tempfile::tempdir()?;
        let path = dir.path().join("out.oocf");
        let mut w = Writer::create(
            &path,
            WriteOptions {
                block_size_log2: 12,
                codec: oocfmt::Codec::None,
                ..WriteOptions::default()
            },
        )?;
        let e = w.write_encoded(b).err().map(|e| e.code());
        assert_eq!(e, Some(Code::InvalidParameter), "{what}");
        // The writer is still usable and writes a valid file.
        for id in 0..src.header().sections.block_count {
            let b = src.read_block(id)?;
            w.write_block(b.entry.kind, b.entry.level, b.entry.item_count, &b.data)?;
        }
        w.finish(src.metadata())?;
        let r = common::verify_bytes(&std::fs::read(&path)?, &deep())?;
        assert!(r.valid && r.issues.is_empty(), "{what}: {:?}", r.issues);
    }
    Ok(())
}

/// The writer refuses metadata its reader would refuse (non-finite or inverted scene box).
#[test]
fn the_writer_refuses_metadata_the_reader_refuses() -> TestResult {
    let src = open_bytes(&fixture("fx-quad-none")?, ReadOptions::default())?;
    type MetaEdit = fn(&mut oocfmt::Metadata);
    let edits: [MetaEdit; 3] = [
        |m| m.scene.bounds_max[0] = f32::NAN,
        |m| m.scene.bounds_min[1] = 5.0,
        |m| m.build.treelet_height = 0,
    ];
    for (i, edit) in edits.into_iter().enumerate() {
        let dir = tempfile::tempdir()?;
        let path = dir.path().join("out.oocf");
        let mut meta = src.metadata().clone();
        edit(&mut meta);
        let w = Writer::create(&path, WriteOptions::default())?;
        assert_eq!(
            w.finish(&meta).err().map(|e| e.code()),
            Some(Code::InvalidParameter),
            "case {i}"
        );
        assert!(
            listing(dir.path())?.is_empty(),
            "case {i}: {:?}",
            listing(dir.path())
        );
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Reader faults

/// A source whose k-th read fails after scribbling over the caller's buffer.
struct FailingSource {
    data: Vec<u8>,
    k: usize,
    reads: AtomicUsize,
}

impl FailingSource {
    fn new(data: Vec<u8>, k: usize) -> Self {
        FailingSource {
            data,
            k,
            reads: AtomicUsize::new(0),
        }
    }
}

impl ByteSource for FailingSource {
    fn len(&self) -> u64 {
        self.data.len() as u64
    }

    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        if self.reads.fetch_add(1, Ordering::SeqCst) + 1 == self.k {
            buf.fill(0xa5);
            return Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                "injected read fault",
            ));
        }
        self.data.read_exact_at(offset, buf)
    }
    // No `as_slice`: every byte goes through `read_exact_at`.
}

/// Opens through a source failing its k-th read and reads everything; the blocks' data.
fn read_through(bytes: &[u8], k: usize) -> (oocfmt::Result<Vec<Vec<u8>>>, usize) {
    let src = Arc::new(FailingSource::new(bytes.to_vec(), k));
    struct Shared(Arc<FailingSource>);
    impl ByteSource for Shared {
        fn len(&self) -> u64 {
            self.0.len()
        }
        fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
            self.0.read_exact_at(offset, buf)
        }
    }
    let run = || -> oocfmt::Result<Vec<Vec<u8>>> {
        let r = Reader::from_source(
            Box::new(Shared(Arc::clone(&src))),
            Arc::from("faulty"),
            ReadOptions::default(),
        )?;
        read_all_blocks(&r)?;
        let mut out = Vec::new();
        for id in 0..r.header().sections.block_count {
            out.push(r.read_block(id)?.data);
        }
        out.push(format!("{:?}", r.proxies()).into_bytes());
        Ok(out)
    };
    let result = run();
    (result, src.reads.load(Ordering::SeqCst))
}

#[test]
fn every_read_fault_is_an_io_error() -> TestResult {
    for f in fixtures()? {
        let (clean, reads) = read_through(&f.bytes, 0);
        let clean = clean?;
        assert!(reads >= 4, "{}: only {reads} reads", f.name);
        for k in 1..=reads {
            let (r, _) = read_through(&f.bytes, k);
            let got = r
                .as_ref()
                .map(|data| data == &clean)
                .map_err(|e| (e.code(), e.to_string()));
            assert!(got.is_err(), "{}: read {k} of {reads} failed but the reader returned data (same as clean: {got:?})", f.name);
            assert_eq!(
                got.err().map(|e| e.0),
                Some(Code::Io),
                "{}: read {k}: {:?}",
                f.name,
                r.err().map(|e| e.to_string())
            );
        }
        let (r, _) = read_through(&f.bytes, reads + 1);
        assert_eq!(r?, clean, "{}", f.name);
    }
    Ok(())
}

fn verify_through(bytes: &[u8], k: usize) -> (oocfmt::Result<Report>, usize) {
    let src = FailingSource::new(bytes.to_vec(), k);
    let r = verify(&src, "faulty", &deep(), &|_| {});
    (r, src.reads.load(Ordering::SeqCst))
}

#[test]
fn every_read_fault_stops_verify_with_an_io_error() -> TestResult {
    for f in fixtures()? {
        let (clean, reads) = verify_through(&f.bytes, 0);
        let clean = clean?;
        assert!(clean.valid, "{}", f.name);
        for k in 1..=reads {
            let r = verify_through(&f.bytes, k).0;
            let report = r.as_ref().ok().map(|r| (r.valid, r.issues.clone()));
            assert!(
                report.is_none(),
                "{}: read {k} of {reads} failed but verify reported {report:?}",
                f.name
            );
            assert_eq!(
                r.err().map(|e| e.code()),
                Some(Code::Io),
                "{}: read {k}",
                f.name
            );
        }
        let (again, _) = verify_through(&f.bytes, reads + 1);
        assert_eq!(again?, clean, "{}", f.name);
    }
    Ok(())
}

#[test]
fn a_reader_on_a_vanished_file_is_an_io_error() -> TestResult {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("nope.oocf");
    assert_eq!(
        Reader::open(&path, ReadOptions::default())
            .err()
            .map(|e| e.code()),
        Some(Code::Io)
    );
    assert_eq!(
        Reader::open_mmap(&path, ReadOptions::default())
            .err()
            .map(|e| e.code()),
        Some(Code::Io)
    );
    // A file that shrinks after it was opened: pread sees the end early.
    let bytes = fixture("fx-lod-lz4")?;
    std::fs::write(&path, &bytes)?;
    let r = Reader::open(&path, ReadOptions::default())?;
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)?
        .set_len(100)?;
    let e = read_all_blocks(&r).err().map(|e| e.code());
    assert_eq!(e, Some(Code::Io));
    Ok(())
}
