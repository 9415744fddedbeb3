//! Where a reader's bytes come from: positioned reads of a file, memory, or a memory map.

use std::fs::File;
use std::io;
use std::path::Path;

use crate::direct::IoMode;

/// Random-access bytes of known length.
pub trait ByteSource: Send + Sync {
    /// Length of the source in bytes.
    fn len(&self) -> u64;

    /// Whether the source holds no bytes.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Fills `buf` from `offset`, or fails; never returns short data.
    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()>;

    /// The whole source as memory, where it is memory (a map or a buffer): zero-copy access.
    fn as_slice(&self) -> Option<&[u8]> {
        None
    }

    /// How the source's reads meet the operating system's page cache: through it, unless
    /// the source reads past it ([`crate::direct`]).
    fn io_mode(&self) -> IoMode {
        IoMode::Buffered
    }
}

/// Positioned reads (pread) of an open file; its length is fixed when opened.
pub struct FileSource {
    file: File,
    len: u64,
}

impl FileSource {
    /// Opens the file at `path` and fixes its length.
    pub fn open(path: &Path) -> io::Result<Self> {
        let file = File::open(path)?;
        let len = file.metadata()?.len();
        Ok(FileSource { file, len })
    }
}

impl ByteSource for FileSource {
    fn len(&self) -> u64 {
        self.len
    }

    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        check_range(self.len, offset, buf.len())?;
        read_at(&self.file, offset, buf)
    }
}

#[cfg(unix)]
fn read_at(file: &File, offset: u64, buf: &mut [u8]) -> io::Result<()> {
    std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
}

#[cfg(windows)]
fn read_at(file: &File, mut offset: u64, mut buf: &mut [u8]) -> io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !buf.is_empty() {
        match file.seek_read(buf, offset) {
            Ok(0) => return Err(io::Error::from(io::ErrorKind::UnexpectedEof)),
            Ok(n) => {
                buf = &mut buf[n..];
                offset += n as u64;
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

pub(crate) fn check_range(len: u64, offset: u64, n: usize) -> io::Result<()> {
    match offset.checked_add(n as u64) {
        Some(end) if end <= len => Ok(()),
        _ => Err(io::Error::new(
            io::ErrorKind::UnexpectedEof,
            format!("read of {n} bytes at {offset} passes the end ({len} bytes)"),
        )),
    }
}

/// Bytes in memory (tests, fuzzing, small files).
impl ByteSource for Vec<u8> {
    fn len(&self) -> u64 {
        self.as_slice().len() as u64
    }

    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        slice_read(self, offset, buf)
    }

    fn as_slice(&self) -> Option<&[u8]> {
        Some(self)
    }
}

pub(crate) fn slice_read(data: &[u8], offset: u64, buf: &mut [u8]) -> io::Result<()> {
    check_range(data.len() as u64, offset, buf.len())?;
    let at = offset as usize;
    buf.copy_from_slice(&data[at..at + buf.len()]);
    Ok(())
}
