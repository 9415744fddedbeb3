//! Input that can only be read forwards (standard input, a pipe), behind the `Seek` the
//! seekable readers are written against: a seek ahead reads through, a seek back fails with
//! [`io::ErrorKind::Unsupported`]. The importers never seek back on such input (they check
//! first and say why not), so the error is a guard, not a path.

use std::io::{self, BufRead, Read, Seek, SeekFrom};

/// The name places in standard input are reported under.
pub const STDIN_NAME: &str = "<stdin>";

/// `R`, read forwards only; counts the bytes consumed so that a position can be asked for.
pub(in crate::import) struct Forward<R> {
    inner: R,
    pos: u64,
}

impl<R: BufRead> Forward<R> {
    /// `inner`, standing at what is called byte 0.
    pub(in crate::import) fn new(inner: R) -> Forward<R> {
        Forward { inner, pos: 0 }
    }

    /// Whether any byte is left.
    pub(in crate::import) fn at_end(&mut self) -> io::Result<bool> {
        Ok(self.fill_buf()?.is_empty())
    }

    /// Reads and drops `n` bytes; fewer when the input ends first.
    fn skip(&mut self, n: u64) -> io::Result<u64> {
        io::copy(&mut self.take(n), &mut io::sink())
    }
}

impl<R: BufRead> Read for Forward<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.pos += n as u64;
        Ok(n)
    }
}

impl<R: BufRead> BufRead for Forward<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        self.inner.fill_buf()
    }

    fn consume(&mut self, amt: usize) {
        self.inner.consume(amt);
        self.pos += amt as u64;
    }
}

impl<R: BufRead> Seek for Forward<R> {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        let target = match to {
            SeekFrom::Start(t) => Some(t),
            SeekFrom::Current(d) => self.pos.checked_add_signed(d),
            SeekFrom::End(_) => None,
        };
        match target {
            Some(t) if t >= self.pos => {
                let want = t - self.pos;
                if self.skip(want)? < want {
                    return Err(io::ErrorKind::UnexpectedEof.into());
                }
                Ok(self.pos)
            }
            _ => Err(io::Error::new(
                io::ErrorKind::Unsupported,
                "a stream can only be read forwards",
            )),
        }
    }

    fn stream_position(&mut self) -> io::Result<u64> {
        Ok(self.pos)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeks_ahead_read_through_and_seeks_back_fail() {
        let mut f = Forward::new(&b"0123456789"[..]);
        let mut two = [0u8; 2];
        assert!(f.read_exact(&mut two).is_ok());
        assert_eq!(f.seek(SeekFrom::Current(3)).ok(), Some(5));
        assert!(f.read_exact(&mut two).is_ok());
        assert_eq!(&two, b"56");
        assert_eq!(f.seek(SeekFrom::Start(7)).ok(), Some(7));
        for back in [SeekFrom::Start(1), SeekFrom::Current(-1), SeekFrom::End(0)] {
            let e = f.seek(back).err().map(|e| e.kind());
            assert_eq!(e, Some(io::ErrorKind::Unsupported));
        }
        assert_eq!(
            f.seek(SeekFrom::Current(9)).err().map(|e| e.kind()),
            Some(io::ErrorKind::UnexpectedEof)
        );
        assert!(matches!(f.at_end(), Ok(true)));
    }
}
