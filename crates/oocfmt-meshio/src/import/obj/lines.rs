//! Logical lines of an OBJ or MTL file, read with a cap on their length so that a file without
//! newlines cannot make us buffer all of it. CRLF endings, `\` continuations, `#` comments and
//! surrounding whitespace are dealt with here, so the statement parsers see clean text.

use std::io::{self, BufRead, Read};

pub(super) enum LineError {
    Io(io::Error),
    /// The logical line is longer than the cap (in bytes, without its line ending).
    TooLong,
}

/// A read failure and the number of the physical line it happened on.
pub(super) struct LineFailure {
    pub line: u64,
    pub error: LineError,
}

pub(super) struct Lines<R> {
    reader: R,
    buf: Vec<u8>,
    /// Physical lines consumed so far.
    read: u64,
    max_len: usize,
}

impl<R: BufRead> Lines<R> {
    pub(super) fn new(reader: R, max_len: usize) -> Lines<R> {
        Lines {
            reader,
            buf: Vec::new(),
            read: 0,
            max_len,
        }
    }

    /// The next logical line, comment removed and trimmed (possibly empty), with the number of
    /// its first physical line; `None` at the end of the input. Bytes that are not UTF-8 are
    /// replaced rather than refused: they can only matter inside names.
    pub(super) fn next_line(&mut self) -> Result<Option<(u64, &str)>, LineFailure> {
        Ok(self.next_with_comment()?.map(|(n, text, _)| (n, text)))
    }

    /// [`Lines::next_line`], and the comment cut off it: from its `#` to the end of the line,
    /// untrimmed (empty when the line has none). The part table `oocfmt export` writes lives
    /// in comments.
    pub(super) fn next_with_comment(&mut self) -> Result<Option<(u64, &str, &str)>, LineFailure> {
        self.buf.clear();
        let first = self.read + 1;
        let mut any = false;
        loop {
            let start = self.buf.len();
            // Room for what the cap still allows, a CR, an LF, and one byte to detect excess.
            let room = (self.max_len.saturating_sub(start) as u64).saturating_add(3);
            let n = (&mut self.reader)
                .take(room)
                .read_until(b'\n', &mut self.buf)
                .map_err(|e| LineFailure {
                    line: self.read + 1,
                    error: LineError::Io(e),
                })?;
            if n == 0 {
                break;
            }
            any = true;
            self.read += 1;
            if self.buf.last() == Some(&b'\n') {
                self.buf.pop();
                if self.buf.last() == Some(&b'\r') {
                    self.buf.pop();
                }
            }
            if self.buf.len() > self.max_len {
                return Err(LineFailure {
                    line: self.read,
                    error: LineError::TooLong,
                });
            }
            match self.buf.last_mut() {
                Some(last) if *last == b'\\' => *last = b' ',
                _ => break,
            }
        }
        if !any {
            return Ok(None);
        }
        // ASCII (nearly every line) is checked several times faster than UTF-8. Replacing
        // bytes never touches an ASCII `#`, so the comment is found after.
        if !self.buf.is_ascii() && std::str::from_utf8(&self.buf).is_err() {
            self.buf = String::from_utf8_lossy(&self.buf).into_owned().into_bytes();
        }
        let line = std::str::from_utf8(&self.buf).unwrap_or_default();
        let (text, comment) = line.split_at(comment_start(line.as_bytes()));
        Ok(Some((first, text.trim(), comment)))
    }
}

/// Where the comment starts: at a `#` that starts a word, so `v 1 2 3 # note` works but a
/// material named `steel#2` keeps its name; the line's length when it has none.
fn comment_start(line: &[u8]) -> usize {
    // Most lines have no `#`: one memchr pass finds that.
    if !line.contains(&b'#') {
        return line.len();
    }
    line.iter()
        .enumerate()
        .find(|&(i, &b)| b == b'#' && (i == 0 || line[i - 1].is_ascii_whitespace()))
        .map_or(line.len(), |(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all(text: &[u8], max: usize) -> Vec<Result<(u64, String), (u64, bool)>> {
        let mut lines = Lines::new(text, max);
        let mut out = Vec::new();
        loop {
            match lines.next_line() {
                Ok(Some((n, t))) => out.push(Ok((n, t.to_string()))),
                Ok(None) => break,
                Err(f) => {
                    out.push(Err((f.line, matches!(f.error, LineError::TooLong))));
                    break;
                }
            }
        }
        out
    }

    #[test]
    fn endings_comments_and_continuations() {
        let got = all(
            b"v 1 2 3 # c\r\n\r\nf 1 \\\n 2 3\n# all comment\nusemtl a#b\t \nlast",
            64,
        );
        let want: Vec<Result<(u64, String), (u64, bool)>> = vec![
            Ok((1, "v 1 2 3".into())),
            Ok((2, String::new())),
            Ok((3, "f 1   2 3".into())),
            Ok((5, String::new())),
            Ok((6, "usemtl a#b".into())),
            Ok((7, "last".into())),
        ];
        assert_eq!(got, want);
    }

    #[test]
    fn the_cap_counts_content_not_line_endings() {
        assert_eq!(all(b"abcd\r\nabcd", 4).len(), 2);
        assert_eq!(all(b"abcde\n", 4), vec![Err((1, true))]);
        assert_eq!(all(b"ok\nabcdefghijklmnop", 4)[1], Err((2, true)));
        // A continuation counts towards the cap of its logical line.
        assert_eq!(all(b"ab\\\ncd\\\nef\n", 4), vec![Err((2, true))]);
    }

    #[test]
    fn the_comment_comes_back_as_written() {
        let mut lines = Lines::new(&b"v 1 2 3 # note  \n# part 0 -1 a #b \\\nsteel#2\n"[..], 64);
        let mut got = Vec::new();
        while let Ok(Some((n, text, comment))) = lines.next_with_comment() {
            got.push((n, text.to_string(), comment.to_string()));
        }
        let line = |n, t: &str, c: &str| (n, t.to_string(), c.to_string());
        assert_eq!(
            got,
            [
                line(1, "v 1 2 3", "# note  "),
                // A continuation joins the next line into the comment.
                line(2, "", "# part 0 -1 a #b  steel#2"),
            ]
        );
    }

    #[test]
    fn invalid_utf8_is_replaced() {
        let got = all(b"usemtl caf\xe9\n", 64);
        assert_eq!(got, vec![Ok((1, "usemtl caf\u{fffd}".into()))]);
    }
}
