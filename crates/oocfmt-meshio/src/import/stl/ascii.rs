//! ASCII STL: `solid name`, then `facet normal nx ny nz` / `outer loop` / three or more
//! `vertex x y z` / `endloop` / `endfacet` per facet, then `endsolid`; several solids may
//! follow each other. Keywords are matched without regard to case (some exporters shout).

use std::io::{self, BufRead, Seek, SeekFrom};
use std::str::SplitWhitespace;

use super::facet::Facets;
use super::lines::{LineError, Lines};
use super::StlOptions;
use crate::import::{ImportError, Location, PartDef, TriangleSink};

/// Where in the grammar the parser stands.
#[derive(Clone, Copy, PartialEq, Eq)]
enum State {
    /// Before a `solid` or after an `endsolid`.
    Outside,
    /// Inside a solid, between facets.
    Solid,
    /// After `facet`, before `outer loop`.
    Facet,
    /// Inside `outer loop`.
    Loop,
    /// After `endloop`, before `endfacet`.
    Looped,
}

struct Parser<'a> {
    file: &'a str,
    opts: &'a StlOptions,
    /// Why the file is not binary STL, for errors on lines that do not look like text.
    binary_note: &'a str,
    /// Whether the input may be scanned ahead (and back): a file may, a stream may not.
    lookahead: bool,
    at: Location,
    state: State,
    solids: u64,
    part: Option<u32>,
    normal: [f64; 3],
    corners: Vec<[f64; 3]>,
    facets: Facets,
}

/// Parses the ASCII STL `input` (at its start). `binary_note` says why it is not binary STL;
/// `lookahead` says whether `input` may be scanned ahead and back (false for a stream).
pub(super) fn read<R: BufRead + Seek>(
    input: R,
    file: &str,
    sink: &mut dyn TriangleSink,
    opts: &StlOptions,
    binary_note: &str,
    lookahead: bool,
) -> Result<(), ImportError> {
    let mut lines = Lines::new(input, opts.max_line_bytes, 0, 0);
    let mut p = Parser {
        file,
        opts,
        binary_note,
        lookahead,
        at: Location::line(file, 0),
        state: State::Outside,
        solids: 0,
        part: None,
        normal: [0.0; 3],
        corners: Vec::new(),
        facets: Facets::new(file),
    };
    loop {
        let line = match lines.next_line() {
            Ok(Some(line)) => line,
            Ok(None) => break,
            Err(e) => return Err(p.line_error(e, lines.line())),
        };
        p.at.line = Some(line.number);
        let mut words = line.text.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let keyword = keyword.to_ascii_lowercase();
        if p.state == State::Outside && keyword == "solid" {
            // A binary header starting with `solid` and padded with zeros, say.
            if line.binary && p.solids == 0 {
                return Err(p.neither("its first line holds bytes that are not text"));
            }
            let name = rest_after_first_word(line.text).to_string();
            p.begin_solid(name, &mut lines, sink)?;
            continue;
        }
        let binary = line.binary;
        p.statement(&keyword, words, sink)
            .map_err(|e| p.explain(e, binary))?;
    }
    p.finish(sink)
}

impl Parser<'_> {
    fn error(&self, message: String) -> ImportError {
        ImportError::Parse {
            at: self.at.clone(),
            message,
        }
    }

    /// The error for input that is neither binary nor ASCII STL.
    fn neither(&self, why: &str) -> ImportError {
        ImportError::Parse {
            at: Location::file(self.file),
            message: format!(
                "neither binary nor ASCII STL: {}; as ASCII STL, {why}",
                self.binary_note
            ),
        }
    }

    /// On a line that does not look like text, a parse error also says why the file is not
    /// binary STL (a truncated binary file whose header starts with `solid` ends up here).
    fn explain(&self, e: ImportError, binary: bool) -> ImportError {
        match e {
            ImportError::Parse { at, message } if binary => ImportError::Parse {
                at,
                message: format!("{message} (nor is it binary STL: {})", self.binary_note),
            },
            e => e,
        }
    }

    fn line_error(&self, e: LineError, line: u64) -> ImportError {
        match e {
            LineError::Io(source) => ImportError::Io {
                path: format!("{}:{line}", self.file),
                source,
            },
            LineError::TooLong if self.solids == 0 => self.neither(&format!(
                "its first line is longer than {} bytes",
                self.opts.max_line_bytes
            )),
            LineError::TooLong => ImportError::Limit {
                at: Location::line(self.file, line),
                what: "line length in bytes".into(),
                limit: self.opts.max_line_bytes as u64,
            },
        }
    }

    /// `solid name`: a part when the file has several solids or this one is named. Without
    /// lookahead an unnamed first solid cannot know whether another follows, and is no part.
    fn begin_solid<R: BufRead + Seek>(
        &mut self,
        name: String,
        lines: &mut Lines<R>,
        sink: &mut dyn TriangleSink,
    ) -> Result<(), ImportError> {
        self.solids += 1;
        self.state = State::Solid;
        self.part = None;
        if sink.positions_only() {
            return Ok(());
        }
        let declare = !name.is_empty()
            || self.solids > 1
            || (self.lookahead && {
                let io = |source| ImportError::Io {
                    path: self.file.to_string(),
                    source,
                };
                let back = lines.offset();
                let more = another_solid(lines.get_mut()).map_err(io)?;
                lines.get_mut().seek(SeekFrom::Start(back)).map_err(io)?;
                more
            });
        if declare {
            let name = if name.is_empty() {
                format!("solid {}", self.solids)
            } else {
                name
            };
            self.part = Some(sink.add_part(PartDef::new(name, None))?);
        }
        Ok(())
    }

    fn statement(
        &mut self,
        keyword: &str,
        mut words: SplitWhitespace<'_>,
        sink: &mut dyn TriangleSink,
    ) -> Result<(), ImportError> {
        match (self.state, keyword) {
            (State::Outside, _) if self.solids == 0 => {
                Err(self.neither("its first line does not start with `solid`"))
            }
            (State::Outside, k) => Err(self.error(format!(
                "expected `solid` or the end of the file after `endsolid`, found `{k}`"
            ))),
            (State::Solid, "facet") => {
                self.normal = match words.next() {
                    None => [0.0; 3],
                    Some(w) if w.eq_ignore_ascii_case("normal") => self.numbers(words, "normal")?,
                    Some(w) => {
                        return Err(self.error(format!("expected `facet normal`, found `{w}`")))
                    }
                };
                self.corners.clear();
                self.state = State::Facet;
                Ok(())
            }
            (State::Solid, "endsolid") => {
                self.state = State::Outside;
                Ok(())
            }
            (State::Solid, k) => {
                Err(self.error(format!("expected `facet` or `endsolid`, found `{k}`")))
            }
            (State::Facet, "outer")
                if words.next().is_some_and(|w| w.eq_ignore_ascii_case("loop")) =>
            {
                self.state = State::Loop;
                Ok(())
            }
            (State::Facet, k) => Err(self.error(format!("expected `outer loop`, found `{k}`"))),
            (State::Loop, "vertex") => {
                if self.corners.len() >= self.opts.max_loop_vertices {
                    return Err(ImportError::Limit {
                        at: self.at.clone(),
                        what: "vertices of one loop".into(),
                        limit: self.opts.max_loop_vertices as u64,
                    });
                }
                let v = self.numbers(words, "vertex")?;
                self.corners.push(v);
                Ok(())
            }
            (State::Loop, "endloop") if self.corners.len() < 3 => Err(self.error(format!(
                "a loop of {} vertices: a facet needs at least 3",
                self.corners.len()
            ))),
            (State::Loop, "endloop") => {
                self.state = State::Looped;
                Ok(())
            }
            (State::Loop, k) => {
                Err(self.error(format!("expected `vertex` or `endloop`, found `{k}`")))
            }
            (State::Looped, "endfacet") => {
                self.state = State::Solid;
                let (normal, part) = (self.normal, self.part);
                self.facets
                    .emit(sink, &self.corners, normal, None, part, &self.at)
            }
            (State::Looped, k) => Err(self.error(format!("expected `endfacet`, found `{k}`"))),
        }
    }

    /// Exactly three numbers, for `what`.
    fn numbers(&self, words: SplitWhitespace<'_>, what: &str) -> Result<[f64; 3], ImportError> {
        let mut v = [0.0f64; 3];
        let mut count = 0;
        for w in words {
            let slot = v
                .get_mut(count)
                .ok_or_else(|| self.error(format!("`{what}` has more than 3 numbers")))?;
            // Rust's parser also takes `nan` and `inf`: such facets are the sink's to drop.
            *slot = w
                .parse()
                .map_err(|_| self.error(format!("`{w}` is not a number (in `{what}`)")))?;
            count += 1;
        }
        if count != 3 {
            return Err(self.error(format!("`{what}` has {count} numbers, expected 3")));
        }
        Ok(v)
    }

    fn finish(self, sink: &mut dyn TriangleSink) -> Result<(), ImportError> {
        match self.state {
            State::Outside if self.solids == 0 => return Err(self.neither("it holds no `solid`")),
            State::Outside => {}
            // Truncated exports often lose the last line only: every facet is complete.
            State::Solid => sink.warn(
                &self.at,
                "the file ends without `endsolid`; every facet was complete".into(),
            ),
            State::Facet | State::Loop | State::Looped => {
                return Err(self.error("the file ends inside a facet".into()))
            }
        }
        self.facets.finish(sink);
        Ok(())
    }
}

/// The line after its first word, trimmed: a solid's name.
fn rest_after_first_word(text: &str) -> &str {
    let t = text.trim_start();
    let end = t.find(char::is_whitespace).unwrap_or(t.len());
    t.get(end..).unwrap_or_default().trim()
}

/// Whether a later line of `input` starts with the word `solid` (any case): a quick scan, so
/// that an unnamed first solid knows whether it is alone.
fn another_solid<R: BufRead>(input: &mut R) -> io::Result<bool> {
    const WORD: &[u8] = b"solid";
    // Some(k): at a line start, k letters of the word matched; None: the rest of a line.
    let mut state = Some(0usize);
    loop {
        let buf = input.fill_buf()?;
        if buf.is_empty() {
            return Ok(state == Some(WORD.len()));
        }
        for &b in buf {
            state = match state {
                _ if b == b'\n' => {
                    if state == Some(WORD.len()) {
                        return Ok(true);
                    }
                    Some(0)
                }
                Some(k) if k == WORD.len() => {
                    if b.is_ascii_whitespace() {
                        return Ok(true);
                    }
                    None
                }
                Some(0) if b.is_ascii_whitespace() => Some(0),
                Some(k) if WORD.get(k) == Some(&b.to_ascii_lowercase()) => Some(k + 1),
                _ => None,
            };
        }
        let n = buf.len();
        input.consume(n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scan_finds_a_solid_only_at_a_line_start() {
        let scan = |t: &str| another_solid(&mut t.as_bytes()).unwrap_or(false);
        assert!(scan("  facet\nendsolid\n  SOLID b\n"));
        assert!(scan("endsolid\nsolid"));
        assert!(scan("endsolid\nsolid\r\n"));
        assert!(!scan("endsolid a\n"));
        assert!(!scan("endsolid\nsolidity\n"));
        assert!(!scan("  facet solid\n"));
        assert!(!scan(""));
        assert_eq!(rest_after_first_word("  solid  my part \t"), "my part");
        assert_eq!(rest_after_first_word("solid"), "");
    }
}
