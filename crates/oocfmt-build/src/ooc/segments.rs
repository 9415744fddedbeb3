//! Segmented spill files: a spill "file" is a run of segment files of at most
//! [`SpillDisk::segment_limit`] each, written in order and read in order. A pass that consumes
//! its input deletes each segment as soon as it has read it, so a pass needs about one copy
//! of the data on disk, not two. Records never straddle segments.

use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::disk::SpillDisk;
use super::OocError;

/// Bytes buffered before a write, and read at a time.
const IO_BYTES: usize = 1 << 20;

/// One segment file of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct Segment {
    pub path: PathBuf,
    pub bytes: u64,
    pub records: u64,
}

/// The segments of one spill "file", in order, and the records they hold.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Run {
    pub segments: Vec<Segment>,
    pub count: u64,
}

impl Run {
    /// Bytes the run's segments hold.
    pub fn bytes(&self) -> u64 {
        self.segments.iter().map(|s| s.bytes).sum()
    }

    /// Deletes whatever segments of the run are still on disk.
    pub fn remove(&self, disk: &SpillDisk) -> Result<(), OocError> {
        for s in &self.segments {
            remove_segment(s, disk)?;
        }
        Ok(())
    }
}

/// Deletes one segment file, if it is still there, and credits its bytes back.
fn remove_segment(s: &Segment, disk: &SpillDisk) -> Result<(), OocError> {
    match std::fs::remove_file(&s.path) {
        Ok(()) => {
            disk.release(s.bytes);
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(OocError::spill(&s.path, e)),
    }
}

/// Appends records to a run of segment files named `BASE.0`, `BASE.1`, …
pub struct SegmentWriter {
    base: PathBuf,
    disk: Arc<SpillDisk>,
    /// The open segment (opened at its first record) and its path.
    file: Option<(File, PathBuf)>,
    buf: Vec<u8>,
    /// Bytes and records of the open segment, buffered ones included.
    seg_bytes: u64,
    seg_records: u64,
    /// Bytes that reached the disk in this run so far.
    written: u64,
    run: Run,
}

impl SegmentWriter {
    /// A writer of segments named after `base`; nothing is created before the first record.
    pub fn new(base: &Path, disk: Arc<SpillDisk>) -> SegmentWriter {
        SegmentWriter {
            base: base.to_path_buf(),
            disk,
            file: None,
            buf: Vec::with_capacity(IO_BYTES),
            seg_bytes: 0,
            seg_records: 0,
            written: 0,
            run: Run::default(),
        }
    }

    /// The name the segments are numbered after.
    pub fn base(&self) -> &Path {
        &self.base
    }

    /// Appends one record of at most a segment's size (buffered: an I/O error may surface on a
    /// later push or at [`SegmentWriter::finish`]).
    pub fn push(&mut self, record: &[u8]) -> Result<(), OocError> {
        let len = record.len() as u64;
        let limit = self
            .disk
            .segment_limit(self.written + self.buf.len() as u64);
        if self.seg_records > 0 && self.seg_bytes + len > limit {
            self.close_segment()?;
        }
        if self.file.is_none() {
            let path = segment_path(&self.base, self.run.segments.len());
            let file = File::create(&path).map_err(|e| OocError::spill(&path, e))?;
            self.file = Some((file, path));
        }
        self.buf.extend_from_slice(record);
        self.seg_bytes += len;
        self.seg_records += 1;
        self.run.count += 1;
        if self.buf.len() >= IO_BYTES {
            self.flush()?;
        }
        Ok(())
    }

    /// Writes the buffer to the open segment, charging the disk first.
    fn flush(&mut self) -> Result<(), OocError> {
        let Some((file, path)) = self.file.as_mut() else {
            return Ok(());
        };
        let n = self.buf.len() as u64;
        let wrote = self.disk.charge(n).and_then(|()| file.write_all(&self.buf));
        wrote.map_err(|source| OocError::SpillWrite {
            path: path.display().to_string(),
            written: self.written,
            source,
        })?;
        self.written += n;
        self.buf.clear();
        Ok(())
    }

    /// Flushes and closes the open segment, adding it to the run.
    fn close_segment(&mut self) -> Result<(), OocError> {
        self.flush()?;
        if let Some((_, path)) = self.file.take() {
            self.run.segments.push(Segment {
                path,
                bytes: self.seg_bytes,
                records: self.seg_records,
            });
        }
        self.seg_bytes = 0;
        self.seg_records = 0;
        Ok(())
    }

    /// Flushes the last segment; returns the run.
    pub fn finish(mut self) -> Result<Run, OocError> {
        self.close_segment()?;
        Ok(std::mem::take(&mut self.run))
    }
}

fn segment_path(base: &Path, k: usize) -> PathBuf {
    let mut name = base.as_os_str().to_owned();
    name.push(format!(".{k}"));
    PathBuf::from(name)
}

/// Reads the records of a run in order, segment by segment, deleting each segment once read
/// when it consumes the run. Each segment's length and record count are checked.
pub struct SegmentReader {
    segments: std::vec::IntoIter<Segment>,
    consume: bool,
    disk: Arc<SpillDisk>,
    /// The segment being read, its file, its bytes not yet in the buffer, its records not yet
    /// taken.
    open: Option<(Segment, File, u64, u64)>,
    buf: Vec<u8>,
    pos: usize,
    /// The segment open now or last, for errors.
    path: PathBuf,
}

impl SegmentReader {
    /// Starts reading `run`; with `consume`, segments are deleted as they are finished.
    pub fn new(run: &Run, consume: bool, disk: Arc<SpillDisk>) -> SegmentReader {
        SegmentReader {
            segments: run.segments.clone().into_iter(),
            consume,
            disk,
            open: None,
            buf: Vec::with_capacity(IO_BYTES),
            pos: 0,
            path: run
                .segments
                .first()
                .map(|s| s.path.clone())
                .unwrap_or_default(),
        }
    }

    /// At least `want` bytes of the open segment (fewer only at its end), the start of the next
    /// record; `None` once every segment is read. Opens the next segment when one is finished.
    pub fn peek(&mut self, want: usize) -> Result<Option<&[u8]>, OocError> {
        loop {
            let Some((seg, file, unread, _)) = self.open.as_mut() else {
                if !self.open_next()? {
                    return Ok(None);
                }
                continue;
            };
            let have = self.buf.len() - self.pos;
            if have < want && *unread > 0 {
                self.buf.drain(..self.pos);
                self.pos = 0;
                let room = (IO_BYTES.max(want) - self.buf.len()) as u64;
                let take = room.min(*unread);
                let start = self.buf.len();
                self.buf.resize(start + take as usize, 0);
                file.read_exact(&mut self.buf[start..])
                    .map_err(|e| OocError::spill(&seg.path, e))?;
                *unread -= take;
            }
            if self.pos < self.buf.len() {
                return Ok(self.buf.get(self.pos..));
            }
            self.close_open()?;
        }
    }

    /// Takes the `len` bytes of one record, peeked before.
    pub fn advance(&mut self, len: usize) {
        self.pos = (self.pos + len).min(self.buf.len());
        if let Some((_, _, _, left)) = self.open.as_mut() {
            *left = left.saturating_sub(1);
        }
    }

    /// The path of the segment open now or last, for errors.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn open_next(&mut self) -> Result<bool, OocError> {
        let Some(seg) = self.segments.next() else {
            return Ok(false);
        };
        self.path.clone_from(&seg.path);
        let file = File::open(&seg.path).map_err(|e| OocError::spill(&seg.path, e))?;
        let len = file
            .metadata()
            .map_err(|e| OocError::spill(&seg.path, e))?
            .len();
        if len != seg.bytes {
            return Err(OocError::SpillLength {
                path: seg.path.display().to_string(),
                len,
                expected: seg.bytes,
            });
        }
        let (bytes, records) = (seg.bytes, seg.records);
        self.open = Some((seg, file, bytes, records));
        self.buf.clear();
        self.pos = 0;
        Ok(true)
    }

    /// Ends the open segment: every record taken, then deleted when consuming.
    fn close_open(&mut self) -> Result<(), OocError> {
        let Some((seg, file, _, left)) = self.open.take() else {
            return Ok(());
        };
        drop(file);
        if left != 0 {
            return Err(OocError::corrupt(&seg.path, "fewer records than written"));
        }
        if self.consume {
            remove_segment(&seg, &self.disk)?;
        }
        Ok(())
    }

    /// Ends the read: the last segment is checked and closed (and deleted when consuming).
    pub fn finish(&mut self) -> Result<(), OocError> {
        match self.peek(1)? {
            Some(_) => Err(OocError::corrupt(
                self.path(),
                "bytes after its last record",
            )),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_all(run: &Run, consume: bool, disk: &Arc<SpillDisk>) -> Vec<Vec<u8>> {
        let mut r = SegmentReader::new(run, consume, disk.clone());
        let mut out = Vec::new();
        while let Some(b) = r.peek(8).unwrap_or_else(|e| panic!("{e}")) {
            let len = usize::from(b[0]);
            out.push(b[..len].to_vec());
            r.advance(len);
        }
        r.finish().unwrap_or_else(|e| panic!("{e}"));
        out
    }

    #[test]
    fn records_roll_over_segments_and_a_consuming_read_frees_them() -> Result<(), OocError> {
        let dir = tempfile::tempdir().map_err(|e| OocError::spill(Path::new("."), e))?;
        let disk = Arc::new(SpillDisk::with_segments(20, None));
        let mut w = SegmentWriter::new(&dir.path().join("s"), disk.clone());
        let records: Vec<Vec<u8>> = (1..=8u8).map(|n| vec![n; usize::from(n)]).collect();
        for r in &records {
            w.push(r)?;
        }
        let run = w.finish()?;
        // 1+2+…+5 = 15 fits in 20, 6 does not: segments of 15, 13 (6+7) and 8 bytes.
        let sizes: Vec<u64> = run.segments.iter().map(|s| s.bytes).collect();
        assert_eq!((sizes, run.count), (vec![15, 13, 8], 8));
        assert_eq!(disk.spill_bytes(), 36);
        assert_eq!(read_all(&run, false, &disk), records);
        assert_eq!(read_all(&run, true, &disk), records);
        assert_eq!(disk.spill_bytes(), 0);
        let left = std::fs::read_dir(dir.path())
            .map_err(|e| OocError::spill(dir.path(), e))?
            .count();
        assert_eq!(left, 0);
        Ok(())
    }

    #[test]
    fn a_segment_of_the_wrong_length_is_refused() -> Result<(), OocError> {
        let dir = tempfile::tempdir().map_err(|e| OocError::spill(Path::new("."), e))?;
        let disk = Arc::new(SpillDisk::with_segments(1 << 20, None));
        let mut w = SegmentWriter::new(&dir.path().join("s"), disk.clone());
        w.push(&[3, 3, 3])?;
        let mut run = w.finish()?;
        if let Some(s) = run.segments.first_mut() {
            s.bytes += 1;
        }
        let mut r = SegmentReader::new(&run, false, disk);
        let e = r.peek(3).err().map(|e| e.to_string());
        assert!(e.is_some_and(|m| m.contains("s.0")));
        Ok(())
    }
}
