//! The body of a PLY file, read one value at a time: [`Binary`] (either byte order) and
//! [`Ascii`] (whitespace-separated words, records usually one per line) behind one trait, so
//! the element readers are written once. Every list length is checked against the bytes left
//! in the file before anything is read or skipped for it, and skips step over bytes without
//! holding them.

use std::fmt::Write as _;
use std::io::{self, BufRead, ErrorKind, Read, Seek, SeekFrom};

use super::header::{Element, Kind};
use super::scalar::Scalar;
use crate::import::stl::lines::{LineError, Lines};
use crate::import::{ImportError, Location, TriangleSink};

/// Skips shorter than this are read through (keeping the read buffer); longer ones seek.
const SEEK_FROM: u64 = 1 << 16;

/// A source of property values.
pub(super) trait Body {
    /// The records of `element` follow.
    fn enter(&mut self, element: &Element);
    /// Record `index` of the element entered starts.
    fn record(&mut self, index: u64);
    /// One scalar of type `ty`, for the property named `property`.
    fn scalar(&mut self, ty: Scalar, property: &str) -> Result<f64, ImportError>;
    /// A list's length, checked against the bytes left for that many `item`s.
    fn list_len(&mut self, count: Scalar, item: Scalar, property: &str)
        -> Result<u64, ImportError>;
    /// Steps over one property's value.
    fn skip_property(&mut self, kind: Kind, property: &str) -> Result<(), ImportError>;
    /// Steps over every record of `element` (entered).
    fn skip_element(&mut self, element: &Element) -> Result<(), ImportError>;
    /// Where the current record is, for the sink.
    fn location(&mut self) -> &Location;
    /// Back to the first byte of the body, for a second pass.
    fn rewind(&mut self) -> Result<(), ImportError>;
    /// The end of a pass over every element: warns about what follows the last one.
    fn end(&mut self, sink: &mut dyn TriangleSink);
}

/// The file's bytes, little- or big-endian.
pub(super) struct Binary<R> {
    input: R,
    file: String,
    /// Where the body starts, the next byte to read, the file's length (`None`: a stream).
    start: u64,
    pos: u64,
    len: Option<u64>,
    big_endian: bool,
    element: String,
    record: u64,
    record_pos: u64,
    at: Location,
    at_fresh: bool,
}

impl<R: BufRead + Seek> Binary<R> {
    /// The body of `file` in `input`, which stands at byte `start` of a file of `len` bytes
    /// (`None`: a stream of unknown length).
    pub(super) fn new(
        input: R,
        file: &str,
        start: u64,
        len: Option<u64>,
        big_endian: bool,
    ) -> Binary<R> {
        Binary {
            input,
            file: file.to_string(),
            start,
            pos: start,
            len,
            big_endian,
            element: String::new(),
            record: 0,
            record_pos: start,
            at: Location::item(file, String::new()),
            at_fresh: false,
        }
    }

    /// Bytes left in the file; as many as can be for a stream.
    fn left(&self) -> u64 {
        self.len.map_or(u64::MAX, |l| l.saturating_sub(self.pos))
    }

    fn error(&mut self, message: String) -> ImportError {
        ImportError::Parse {
            at: self.location().clone(),
            message,
        }
    }

    fn read_error(&mut self, e: io::Error, property: &str) -> ImportError {
        if e.kind() == ErrorKind::UnexpectedEof {
            let message = match self.len {
                Some(len) => format!("the file ends at byte {len} inside property `{property}`"),
                None => format!(
                    "the stream ends inside property `{property}` (after byte {})",
                    self.pos
                ),
            };
            return self.error(message);
        }
        ImportError::Io {
            path: self.location().to_string(),
            source: e,
        }
    }

    /// Steps over `n` bytes, known to be there.
    fn skip_bytes(&mut self, n: u64, what: &str) -> Result<(), ImportError> {
        if n > self.left() {
            let message = format!(
                "{what} takes {n} bytes, but only {} are left in the file",
                self.left()
            );
            return Err(self.error(message));
        }
        let mut small = [0u8; 16];
        let result = if let Some(buf) = usize::try_from(n).ok().and_then(|n| small.get_mut(..n)) {
            // A property's value: as cheap as reading it.
            self.input.read_exact(buf)
        } else if n < SEEK_FROM {
            io::copy(&mut (&mut self.input).take(n), &mut io::sink()).and_then(|done| {
                if done == n {
                    Ok(())
                } else {
                    Err(ErrorKind::UnexpectedEof.into())
                }
            })
        } else {
            i64::try_from(n)
                .map_err(|_| io::Error::from(ErrorKind::InvalidInput))
                .and_then(|d| self.input.seek(SeekFrom::Current(d)).map(|_| ()))
        };
        result.map_err(|e| self.read_error(e, what))?;
        self.pos += n;
        Ok(())
    }
}

impl<R: BufRead + Seek> Body for Binary<R> {
    fn enter(&mut self, element: &Element) {
        self.element.clone_from(&element.name);
        self.record(0);
    }

    fn record(&mut self, index: u64) {
        self.record = index;
        self.record_pos = self.pos;
        self.at_fresh = false;
    }

    fn scalar(&mut self, ty: Scalar, property: &str) -> Result<f64, ImportError> {
        let mut bytes = [0u8; 8];
        let n = ty.size() as usize;
        let slot = bytes.get_mut(..n).unwrap_or_default();
        if let Err(e) = self.input.read_exact(slot) {
            return Err(self.read_error(e, property));
        }
        self.pos += n as u64;
        Ok(ty.decode(bytes, self.big_endian))
    }

    fn list_len(
        &mut self,
        count: Scalar,
        item: Scalar,
        property: &str,
    ) -> Result<u64, ImportError> {
        let n = self.scalar(count, property)?;
        if n < 0.0 {
            return Err(self.error(format!("list `{property}` has a negative length {n}")));
        }
        // An integer type's value: whole and below 2^32.
        let n = n as u64;
        let bytes = n.saturating_mul(item.size());
        if bytes > self.left() {
            let message = format!(
                "list `{property}` of {n} items ({bytes} bytes) runs past the end of the file \
                 ({} bytes left)",
                self.left()
            );
            return Err(self.error(message));
        }
        Ok(n)
    }

    fn skip_property(&mut self, kind: Kind, property: &str) -> Result<(), ImportError> {
        match kind {
            Kind::Scalar(s) => self.skip_bytes(s.size(), property),
            Kind::List { count, item } => {
                let n = self.list_len(count, item, property)?;
                self.skip_bytes(n * item.size(), property)
            }
        }
    }

    fn skip_element(&mut self, element: &Element) -> Result<(), ImportError> {
        if let Some(size) = element.fixed_record_bytes() {
            let what = format!("element `{}` ({} records)", element.name, element.count);
            return self.skip_bytes(element.count.saturating_mul(size), &what);
        }
        for r in 0..element.count {
            self.record(r);
            for p in &element.properties {
                self.skip_property(p.kind, &p.name)?;
            }
        }
        Ok(())
    }

    fn location(&mut self) -> &Location {
        if !self.at_fresh {
            if let Some(item) = self.at.item.as_mut() {
                item.clear();
                // Writing to a String cannot fail.
                let _ = write!(
                    item,
                    "{} {} at byte {}",
                    self.element, self.record, self.record_pos
                );
            }
            self.at_fresh = true;
        }
        &self.at
    }

    fn rewind(&mut self) -> Result<(), ImportError> {
        self.input
            .seek(SeekFrom::Start(self.start))
            .map_err(|source| ImportError::Io {
                path: self.file.clone(),
                source,
            })?;
        self.pos = self.start;
        Ok(())
    }

    fn end(&mut self, sink: &mut dyn TriangleSink) {
        let at = Location::item(&self.file, format!("byte {}", self.pos));
        match self.len {
            Some(_) if self.left() > 0 => sink.warn(
                &at,
                format!("{} bytes after the last element were ignored", self.left()),
            ),
            None if self.input.fill_buf().is_ok_and(|b| !b.is_empty()) => sink.warn(
                &at,
                "the stream goes on after the last element; the rest was not read".into(),
            ),
            _ => {}
        }
    }
}

/// The file's text after the header: values are words separated by whitespace.
pub(super) struct Ascii<R> {
    lines: Lines<R>,
    file: String,
    /// The line and byte where the body starts; the file's length (`None`: a stream).
    start: (u64, u64),
    len: Option<u64>,
    /// Where the current line starts in the file, and how far it has been read.
    line_start: u64,
    cursor: usize,
    max_line: usize,
    element: String,
    record: u64,
    at: Location,
}

impl<R: BufRead + Seek> Ascii<R> {
    /// The body of `file`, read from `lines` (which stand at its start) in a file of `len`
    /// bytes (`None`: a stream of unknown length).
    pub(super) fn new(lines: Lines<R>, file: &str, len: Option<u64>, max_line: usize) -> Ascii<R> {
        Ascii {
            max_line,
            start: (lines.line(), lines.offset()),
            // The header's last line is read to its end: what is left starts at the offset.
            line_start: lines.offset().saturating_sub(lines.text().len() as u64),
            cursor: lines.text().len(),
            lines,
            file: file.to_string(),
            len,
            element: String::new(),
            record: 0,
            at: Location::line(file, 0),
        }
    }

    fn error(&mut self, message: String) -> ImportError {
        let at = self.location().clone();
        ImportError::Parse {
            at,
            message: format!(
                "{message} (element `{}` record {})",
                self.element, self.record
            ),
        }
    }

    /// Bytes not read yet: the rest of the current line and of the file; as many as can be
    /// for a stream.
    fn left(&self) -> u64 {
        let read = self.line_start.saturating_add(self.cursor as u64);
        self.len.map_or(u64::MAX, |l| l.saturating_sub(read))
    }

    /// The next word.
    fn word(&mut self, property: &str) -> Result<&str, ImportError> {
        loop {
            let text = self.lines.text();
            let rest = text.get(self.cursor..).unwrap_or_default();
            if let Some(start) = rest.find(|c: char| !c.is_ascii_whitespace()) {
                let from = self.cursor + start;
                let tail = text.get(from..).unwrap_or_default();
                let len = tail
                    .find(|c: char| c.is_ascii_whitespace())
                    .unwrap_or(tail.len());
                self.cursor = from + len;
                return Ok(self.lines.text().get(from..from + len).unwrap_or_default());
            }
            let line_start = self.lines.offset();
            match self.lines.next_line() {
                Ok(Some(_)) => {
                    self.line_start = line_start;
                    self.cursor = 0;
                }
                Ok(None) => {
                    return Err(self.error(format!("the file ends inside property `{property}`")))
                }
                Err(LineError::Io(source)) => {
                    return Err(ImportError::Io {
                        path: format!("{}:{}", self.file, self.lines.line()),
                        source,
                    })
                }
                Err(LineError::TooLong) => {
                    return Err(ImportError::Limit {
                        at: Location::line(&self.file, self.lines.line()),
                        what: "line length in bytes".into(),
                        limit: self.max_line as u64,
                    })
                }
            }
        }
    }
}

impl<R: BufRead + Seek> Body for Ascii<R> {
    fn enter(&mut self, element: &Element) {
        self.element.clone_from(&element.name);
        self.record = 0;
    }

    fn record(&mut self, index: u64) {
        self.record = index;
    }

    fn scalar(&mut self, _ty: Scalar, property: &str) -> Result<f64, ImportError> {
        let word = self.word(property)?;
        match word.parse::<f64>() {
            Ok(v) => Ok(v),
            Err(_) => {
                let message = format!("`{word}` is not a number (property `{property}`)");
                Err(self.error(message))
            }
        }
    }

    fn list_len(
        &mut self,
        count: Scalar,
        _item: Scalar,
        property: &str,
    ) -> Result<u64, ImportError> {
        let n = self.scalar(count, property)?;
        if !(n >= 0.0 && n.fract() == 0.0 && n < 2f64.powi(63)) {
            return Err(self.error(format!(
                "list `{property}` has length {n}, not a whole number"
            )));
        }
        let n = n as u64;
        // Each item takes a character and a separator (but the file's last).
        let bytes = n.saturating_mul(2).saturating_sub(1);
        if bytes > self.left() {
            let message = format!(
                "list `{property}` of {n} items (at least {bytes} bytes) runs past the end of the \
                 file ({} bytes left)",
                self.left()
            );
            return Err(self.error(message));
        }
        Ok(n)
    }

    fn skip_property(&mut self, kind: Kind, property: &str) -> Result<(), ImportError> {
        match kind {
            Kind::Scalar(_) => self.word(property).map(|_| ()),
            Kind::List { count, item } => {
                for _ in 0..self.list_len(count, item, property)? {
                    self.word(property)?;
                }
                Ok(())
            }
        }
    }

    fn skip_element(&mut self, element: &Element) -> Result<(), ImportError> {
        if element.properties.is_empty() {
            return Ok(());
        }
        for r in 0..element.count {
            self.record(r);
            for p in &element.properties {
                self.skip_property(p.kind, &p.name)?;
            }
        }
        Ok(())
    }

    fn location(&mut self) -> &Location {
        self.at.line = Some(self.lines.line());
        &self.at
    }

    fn rewind(&mut self) -> Result<(), ImportError> {
        let (line, offset) = self.start;
        self.lines
            .rewind(line, offset)
            .map_err(|source| ImportError::Io {
                path: self.file.clone(),
                source,
            })?;
        self.line_start = offset;
        self.cursor = 0;
        Ok(())
    }

    fn end(&mut self, _sink: &mut dyn TriangleSink) {}
}
