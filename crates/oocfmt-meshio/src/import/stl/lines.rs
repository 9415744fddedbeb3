//! Lines of a text format read with a cap on their length, so that a binary file mistaken for
//! text (or a text file without newlines) cannot make us buffer all of it. Shared by ASCII STL
//! and by the PLY header and ASCII body, which need the byte offset where the text ends.

use std::io::{self, BufRead, Read, Seek, SeekFrom};

/// Why no line came back.
pub(in crate::import) enum LineError {
    /// Reading failed.
    Io(io::Error),
    /// The line is longer than the cap (in bytes, without its line ending).
    TooLong,
}

/// One line, as [`Lines::next_line`] gives it.
pub(in crate::import) struct Line<'a> {
    /// Its number, 1-based.
    pub number: u64,
    /// Its text without the line ending.
    pub text: &'a str,
    /// It held control bytes other than whitespace: likely not text at all.
    pub binary: bool,
}

pub(in crate::import) struct Lines<R> {
    reader: R,
    bytes: Vec<u8>,
    text: String,
    /// The number of the last line returned (1-based; 0 before the first).
    line: u64,
    /// Bytes consumed from the reader so far.
    offset: u64,
    max_len: usize,
}

impl<R: BufRead> Lines<R> {
    /// Lines of `reader`, which is at byte `offset` of its file, where line `line` ended.
    pub(in crate::import) fn new(reader: R, max_len: usize, line: u64, offset: u64) -> Lines<R> {
        Lines {
            reader,
            bytes: Vec::new(),
            text: String::new(),
            line,
            offset,
            max_len,
        }
    }

    /// The next line without its ending (LF or CRLF), `None` at the end of the input. Bytes
    /// that are not UTF-8 are replaced: they can only matter inside names.
    pub(in crate::import) fn next_line(&mut self) -> Result<Option<Line<'_>>, LineError> {
        self.bytes.clear();
        // Room for what the cap allows, a CR, an LF, and one byte to detect excess.
        let room = (self.max_len as u64).saturating_add(3);
        let n = (&mut self.reader)
            .take(room)
            .read_until(b'\n', &mut self.bytes)
            .map_err(LineError::Io)?;
        if n == 0 {
            return Ok(None);
        }
        self.offset += n as u64;
        self.line += 1;
        if self.bytes.last() == Some(&b'\n') {
            self.bytes.pop();
            if self.bytes.last() == Some(&b'\r') {
                self.bytes.pop();
            }
        }
        if self.bytes.len() > self.max_len {
            return Err(LineError::TooLong);
        }
        let binary = self
            .bytes
            .iter()
            .any(|&b| b.is_ascii_control() && !b.is_ascii_whitespace());
        self.text.clear();
        self.text.push_str(&String::from_utf8_lossy(&self.bytes));
        Ok(Some(Line {
            number: self.line,
            text: &self.text,
            binary,
        }))
    }

    /// The number of the last line returned, or of the line being read when it failed.
    pub(in crate::import) fn line(&self) -> u64 {
        self.line
    }

    /// Bytes consumed so far: where the next line starts.
    pub(in crate::import) fn offset(&self) -> u64 {
        self.offset
    }

    /// The text of the last line returned (empty before the first).
    pub(in crate::import) fn text(&self) -> &str {
        &self.text
    }

    /// The reader, positioned at [`Lines::offset`].
    pub(in crate::import) fn get_mut(&mut self) -> &mut R {
        &mut self.reader
    }

    /// The reader back, positioned at [`Lines::offset`].
    pub(in crate::import) fn into_inner(self) -> R {
        self.reader
    }
}

impl<R: BufRead + Seek> Lines<R> {
    /// Goes back to byte `offset`, where line `line` ended, to read the lines after it again.
    pub(in crate::import) fn rewind(&mut self, line: u64, offset: u64) -> io::Result<()> {
        self.reader.seek(SeekFrom::Start(offset))?;
        self.line = line;
        self.offset = offset;
        self.text.clear();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn next<R: BufRead>(l: &mut Lines<R>) -> Option<(u64, String, bool)> {
        match l.next_line() {
            Ok(Some(line)) => Some((line.number, line.text.to_string(), line.binary)),
            _ => None,
        }
    }

    #[test]
    fn lines_endings_offsets_and_the_cap() {
        let text = b"solid a\r\n  facet\n\x00\x01bin\nlast";
        let mut l = Lines::new(&text[..], 8, 0, 0);
        assert_eq!(next(&mut l), Some((1, "solid a".into(), false)));
        assert_eq!((l.line(), l.offset()), (1, 9));
        assert_eq!(next(&mut l), Some((2, "  facet".into(), false)));
        assert_eq!(next(&mut l), Some((3, "\u{0}\u{1}bin".into(), true)));
        assert_eq!(next(&mut l), Some((4, "last".into(), false)));
        assert_eq!(l.offset(), text.len() as u64);
        assert!(matches!(l.next_line(), Ok(None)));
        let mut long = Lines::new(&b"123456789\n"[..], 8, 4, 100);
        assert!(matches!(long.next_line(), Err(LineError::TooLong)));
        assert_eq!(long.line(), 5);
        let mut exact = Lines::new(&b"12345678\r\n"[..], 8, 0, 0);
        assert_eq!(next(&mut exact), Some((1, "12345678".into(), false)));
    }
}
