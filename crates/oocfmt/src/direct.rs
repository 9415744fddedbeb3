//! Reading past the page cache. A renderer that keeps its own cache of decoded blocks would
//! otherwise hold the file's bytes twice: once decoded, once in the operating system's page
//! cache. [`DirectSource`] reads with `O_DIRECT` (Linux): each read fetches the aligned
//! superset of the asked range into an aligned bounce buffer and copies the asked bytes out.
//! Where the file system refuses `O_DIRECT` (EINVAL, as tmpfs did before Linux 6.6), it reads
//! through the page cache and drops the range read with `posix_fadvise(POSIX_FADV_DONTNEED)`.
//! [`DirectSource::mode`] says which is in effect.

use std::fs::File;
use std::io;
use std::path::Path;

use crate::source::{ByteSource, FileSource};

/// How reads should meet the operating system's page cache: what a caller asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Io {
    /// Positioned reads through the page cache.
    #[default]
    Buffered,
    /// Past the page cache ([`DirectSource`]): `O_DIRECT` where the file system takes it, else
    /// buffered reads whose pages are dropped after each read. Plain buffered reads outside
    /// Linux.
    Direct,
}

/// How a source's reads meet the page cache: what is in effect.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IoMode {
    /// Through the page cache (positioned reads, a memory map, or bytes in memory).
    Buffered,
    /// `O_DIRECT`: the page cache is not filled.
    Direct,
    /// Buffered reads, each range dropped from the page cache after it was read
    /// (`POSIX_FADV_DONTNEED`), where `O_DIRECT` was refused.
    DontNeed,
}

impl IoMode {
    /// The name figures and the command line use: `buffered`, `direct` or `dontneed`.
    pub fn name(self) -> &'static str {
        match self {
            IoMode::Buffered => "buffered",
            IoMode::Direct => "direct",
            IoMode::DontNeed => "dontneed",
        }
    }
}

/// Opens `path` for positioned reads as `io` asks: a [`FileSource`], or a [`DirectSource`]
/// (Linux; a [`FileSource`] elsewhere).
pub fn open_source(path: &Path, io: Io) -> io::Result<Box<dyn ByteSource>> {
    match io {
        Io::Buffered => Ok(Box::new(FileSource::open(path)?)),
        Io::Direct => open_direct(path),
    }
}

#[cfg(target_os = "linux")]
fn open_direct(path: &Path) -> io::Result<Box<dyn ByteSource>> {
    Ok(Box::new(DirectSource::open(path)?))
}

#[cfg(not(target_os = "linux"))]
fn open_direct(path: &Path) -> io::Result<Box<dyn ByteSource>> {
    Ok(Box::new(FileSource::open(path)?))
}

#[cfg(target_os = "linux")]
pub use linux::DirectSource;

#[cfg(target_os = "linux")]
mod linux {
    use std::num::NonZeroU64;
    use std::os::unix::fs::FileExt;

    use rustix::fs::{Advice, AtFlags, Mode, OFlags, StatxFlags};

    use super::*;
    use crate::source::check_range;

    /// The alignment of offsets, lengths and buffers used for `O_DIRECT` when the file system
    /// asks for less or does not say (`statx` reports it from Linux 6.1): a page, which every
    /// file system that takes `O_DIRECT` accepts.
    pub const MIN_ALIGN: u64 = 4096;

    /// The largest alignment accepted from the file system; beyond it `O_DIRECT` is not used.
    const MAX_ALIGN: u64 = 1 << 16;

    /// The largest span one direct read fetches: longer reads (the proxies at open) go in
    /// pieces, so the bounce buffer stays small.
    const CHUNK: u64 = 1 << 20;

    /// Positioned reads past the page cache; its length is fixed when opened.
    pub struct DirectSource {
        file: File,
        len: u64,
        /// Offsets, lengths and buffer addresses of direct reads are multiples of it.
        align: u64,
        mode: IoMode,
    }

    impl DirectSource {
        /// Opens `path` with `O_DIRECT`, or, where the file system refuses it, for buffered
        /// reads that drop what they read from the page cache ([`DirectSource::open_evicting`]).
        pub fn open(path: &Path) -> io::Result<DirectSource> {
            match Self::open_direct(path) {
                Ok(Some(s)) => Ok(s),
                Ok(None) => Self::open_evicting(path),
                Err(e) => Err(e),
            }
        }

        /// Opens `path` for buffered reads, each range dropped from the page cache after it
        /// was read (`POSIX_FADV_DONTNEED`): clean pages go, so the file is not held twice.
        pub fn open_evicting(path: &Path) -> io::Result<DirectSource> {
            let file = File::open(path)?;
            let len = file.metadata()?.len();
            Ok(DirectSource {
                file,
                len,
                align: MIN_ALIGN,
                mode: IoMode::DontNeed,
            })
        }

        /// How this source's reads meet the page cache.
        pub fn mode(&self) -> IoMode {
            self.mode
        }

        /// `O_DIRECT`, or None where the file system refuses it: at open, by its `statx`
        /// alignment (0: not supported for this file), or at the first read.
        fn open_direct(path: &Path) -> io::Result<Option<DirectSource>> {
            let flags = OFlags::RDONLY | OFlags::DIRECT | OFlags::CLOEXEC;
            let fd = match rustix::fs::open(path, flags, Mode::empty()) {
                Ok(fd) => fd,
                Err(e) if refused(e) => return Ok(None),
                Err(e) => return Err(e.into()),
            };
            let file = File::from(fd);
            let Some(align) = alignment(&file) else {
                return Ok(None);
            };
            let len = file.metadata()?.len();
            let source = DirectSource {
                file,
                len,
                align,
                mode: IoMode::Direct,
            };
            // Some file systems take the flag at open and refuse the reads.
            if len > 0 {
                match source.read_direct(0, &mut [0u8; 1]) {
                    Err(e) if e.raw_os_error() == Some(rustix::io::Errno::INVAL.raw_os_error()) => {
                        return Ok(None)
                    }
                    Err(e) => return Err(e),
                    Ok(()) => {}
                }
            }
            Ok(Some(source))
        }

        /// Fills `buf` from `offset` through aligned reads into a bounce buffer, at most
        /// [`CHUNK`] bytes at a time.
        fn read_direct(&self, mut offset: u64, mut buf: &mut [u8]) -> io::Result<()> {
            let align = self.align;
            let mut bounce =
                Bounce::new(align, CHUNK.min(round_up(buf.len() as u64 + align, align)));
            while !buf.is_empty() {
                let start = offset - offset % align;
                let lead = offset - start;
                // `lead` < align ≤ CHUNK / 16, so every step takes at least one byte.
                let take = (buf.len() as u64).min(CHUNK - lead);
                let window = bounce.window(round_up(lead + take, align))?;
                fill(&self.file, window, start, lead + take)?;
                let (out, rest) = std::mem::take(&mut buf).split_at_mut(take as usize);
                out.copy_from_slice(slice(window, lead, take)?);
                buf = rest;
                offset += take;
            }
            Ok(())
        }

        /// A buffered read, then the pages it covered dropped from the page cache.
        fn read_dropping(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
            self.file.read_exact_at(buf, offset)?;
            let start = offset - offset % MIN_ALIGN;
            let end = round_up(offset + buf.len() as u64, MIN_ALIGN);
            // Advice only: a refusal leaves the pages cached and the bytes read correct.
            let _ = rustix::fs::fadvise(
                &self.file,
                start,
                NonZeroU64::new(end - start),
                Advice::DontNeed,
            );
            Ok(())
        }
    }

    impl ByteSource for DirectSource {
        fn len(&self) -> u64 {
            self.len
        }

        fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
            check_range(self.len, offset, buf.len())?;
            match self.mode {
                IoMode::Direct => self.read_direct(offset, buf),
                _ => self.read_dropping(offset, buf),
            }
        }

        fn io_mode(&self) -> IoMode {
            self.mode
        }
    }

    /// Whether an open's error means the file system does not take `O_DIRECT`.
    fn refused(e: rustix::io::Errno) -> bool {
        e == rustix::io::Errno::INVAL || e == rustix::io::Errno::OPNOTSUPP
    }

    /// The alignment direct reads of `file` need: the file system's (`statx`, Linux 6.1) and
    /// at least [`MIN_ALIGN`]; None when the file system says it does not support them here, or
    /// asks for more than [`MAX_ALIGN`].
    fn alignment(file: &File) -> Option<u64> {
        let Ok(st) = rustix::fs::statx(file, "", AtFlags::EMPTY_PATH, StatxFlags::DIOALIGN) else {
            return Some(MIN_ALIGN);
        };
        if !StatxFlags::from_bits_retain(st.stx_mask).contains(StatxFlags::DIOALIGN) {
            return Some(MIN_ALIGN);
        }
        let (mem, off) = (
            u64::from(st.stx_dio_mem_align),
            u64::from(st.stx_dio_offset_align),
        );
        if mem == 0 || off == 0 {
            return None;
        }
        let align = mem.max(off).max(MIN_ALIGN).next_power_of_two();
        (align <= MAX_ALIGN).then_some(align)
    }

    /// Reads from `at` into `window` (aligned, a multiple of the alignment long) until at least
    /// `need` bytes are in. Only the end of the file reads short, and `need` lies before it.
    fn fill(file: &File, window: &mut [u8], at: u64, need: u64) -> io::Result<()> {
        let mut done = 0u64;
        while done < need {
            let rest = window.get_mut(done as usize..).unwrap_or_default();
            match file.read_at(rest, at + done) {
                Ok(0) => return Err(io::Error::from(io::ErrorKind::UnexpectedEof)),
                Ok(n) => done += n as u64,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    /// `len` bytes of `window` from `from`.
    fn slice(window: &[u8], from: u64, len: u64) -> io::Result<&[u8]> {
        window
            .get(from as usize..(from + len) as usize)
            .ok_or_else(|| io::Error::other("direct read: range outside the bounce buffer"))
    }

    fn round_up(x: u64, align: u64) -> u64 {
        x.div_ceil(align).saturating_mul(align)
    }

    /// A byte buffer with an aligned window, without `unsafe`: over-allocated by the alignment
    /// and entered at the first aligned address.
    struct Bounce {
        bytes: Vec<u8>,
        align: u64,
    }

    impl Bounce {
        fn new(align: u64, span: u64) -> Bounce {
            Bounce {
                bytes: vec![0; (span + align) as usize],
                align,
            }
        }

        /// The aligned window of `span` bytes, the buffer grown when it is too short.
        fn window(&mut self, span: u64) -> io::Result<&mut [u8]> {
            let want = (span + self.align) as usize;
            if self.bytes.len() < want {
                self.bytes.resize(want, 0);
            }
            let skip = self.bytes.as_ptr().align_offset(self.align as usize);
            self.bytes
                .get_mut(skip..skip + span as usize)
                .ok_or_else(|| io::Error::other("direct read: no aligned window in the buffer"))
        }
    }

    #[cfg(test)]
    mod tests {
        #![allow(clippy::unwrap_used)]
        use super::*;

        /// A file of `len` bytes, each a function of its offset, so any range is checkable.
        fn patterned(dir: &Path, len: usize) -> std::path::PathBuf {
            let path = dir.join("bytes.bin");
            let bytes: Vec<u8> = (0..len).map(|i| (i * 7 + i / 251) as u8).collect();
            std::fs::write(&path, bytes).unwrap();
            path
        }

        /// Reads ranges of `src` and compares them with the file's bytes read plainly.
        fn check_ranges(src: &DirectSource, path: &Path) {
            let plain = std::fs::read(path).unwrap();
            let len = plain.len() as u64;
            assert_eq!(src.len(), len);
            // Unaligned starts and ends, ranges over a chunk boundary, the file's tail.
            let ranges = [
                (0, 1),
                (1, 4095),
                (4095, 2),
                (5000, 70_000),
                (CHUNK - 1, 3),
                (3, CHUNK + 9000),
                (len - 10, 10),
            ];
            for (off, n) in ranges {
                let mut got = vec![0u8; n as usize];
                src.read_exact_at(off, &mut got).unwrap();
                assert!(
                    got == plain[off as usize..(off + n) as usize],
                    "{n} bytes at {off}"
                );
            }
            assert!(src.read_exact_at(len - 1, &mut [0u8; 2]).is_err());
        }

        #[test]
        fn direct_and_evicting_reads_return_the_bytes_buffered_reads_do() {
            let dir = tempfile::tempdir().unwrap();
            let len = (1 << 21) + 12_345;
            let path = patterned(dir.path(), len);
            let direct = DirectSource::open(&path).unwrap();
            // On a file system without O_DIRECT the fallback is what is tested twice.
            assert!(matches!(direct.mode(), IoMode::Direct | IoMode::DontNeed));
            check_ranges(&direct, &path);
            let evicting = DirectSource::open_evicting(&path).unwrap();
            assert_eq!(evicting.io_mode(), IoMode::DontNeed);
            check_ranges(&evicting, &path);
        }

        #[test]
        fn an_empty_file_opens_and_refuses_reads() {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("empty");
            std::fs::write(&path, b"").unwrap();
            let src = DirectSource::open(&path).unwrap();
            assert!(src.is_empty());
            assert!(src.read_exact_at(0, &mut [0u8; 1]).is_err());
        }
    }
}
