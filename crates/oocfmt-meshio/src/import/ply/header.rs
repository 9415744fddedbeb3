//! The PLY header: `ply`, `format`, `element`s with their `property` lines, `end_header`.
//! Comments are ignored except the three our exporter writes (see the module above): part
//! names (escaped as in the OBJ part table, `crate::import::obj::part_table`), material names
//! and colours, and the scene origin of relative positions.

use std::io::BufRead;

use oocfmt::metadata::Material;

use super::scalar::Scalar;
use super::PlyOptions;
use crate::import::obj::part_table::{self, Directive};
use crate::import::stl::lines::{LineError, Lines};
use crate::import::{ImportError, Location};

/// How the body is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Encoding {
    Ascii,
    /// Binary; `true`: big-endian.
    Binary(bool),
}

/// A property's type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Kind {
    Scalar(Scalar),
    /// A length of type `count`, then that many `item`s.
    List {
        count: Scalar,
        item: Scalar,
    },
}

#[derive(Clone, Debug)]
pub(super) struct Property {
    pub name: String,
    pub kind: Kind,
}

#[derive(Clone, Debug)]
pub(super) struct Element {
    pub name: String,
    pub count: u64,
    pub properties: Vec<Property>,
    /// The header line that declares it.
    pub line: u64,
}

impl Element {
    /// The fewest bytes one record can take: in a binary file its scalars and list lengths;
    /// in an ASCII file one character and one separator per property.
    pub(super) fn min_record_bytes(&self, encoding: Encoding) -> u64 {
        match encoding {
            Encoding::Ascii => 2 * self.properties.len() as u64,
            Encoding::Binary(_) => self
                .properties
                .iter()
                .map(|p| match p.kind {
                    Kind::Scalar(s) => s.size(),
                    Kind::List { count, .. } => count.size(),
                })
                .sum(),
        }
    }

    /// The size of every record, when it has no list.
    pub(super) fn fixed_record_bytes(&self) -> Option<u64> {
        self.properties
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(s) => Some(s.size()),
                Kind::List { .. } => None,
            })
            .sum()
    }
}

/// `comment part <id> <parent or -1> <name>`.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct CommentPart {
    pub id: u32,
    pub parent: Option<u32>,
    pub name: String,
}

pub(super) struct Header {
    pub encoding: Encoding,
    pub elements: Vec<Element>,
    pub parts: Vec<CommentPart>,
    /// `comment material <index> <name> <r> <g> <b>`.
    pub materials: Vec<(u32, Material)>,
    /// `comment positions are relative to the scene origin <x> <y> <z>`.
    pub origin: Option<[f64; 3]>,
    /// Comments that look like ours but do not parse, as (line, text), for warnings.
    pub bad_comments: Vec<(u64, String)>,
}

const ORIGIN_COMMENT: &str = "positions are relative to the scene origin";

/// Reads the header from `lines`, which stand at the start of the file; on return they stand
/// at the first byte of the body.
pub(super) fn read<R: BufRead>(
    lines: &mut Lines<R>,
    file: &str,
    opts: &PlyOptions,
) -> Result<Header, ImportError> {
    let mut h = Header {
        encoding: Encoding::Ascii,
        elements: Vec::new(),
        parts: Vec::new(),
        materials: Vec::new(),
        origin: None,
        bad_comments: Vec::new(),
    };
    let mut format = false;
    loop {
        let next = lines.line() + 1;
        let line = match lines.next_line() {
            Ok(Some(line)) => line,
            Ok(None) => {
                return Err(ImportError::Parse {
                    at: Location::line(file, next - 1),
                    message: "the file ends inside the header (no `end_header`)".into(),
                })
            }
            Err(LineError::Io(source)) => {
                return Err(ImportError::Io {
                    path: format!("{file}:{next}"),
                    source,
                })
            }
            Err(LineError::TooLong) if next == 1 => {
                return Err(not_ply(file));
            }
            Err(LineError::TooLong) => {
                return Err(ImportError::Limit {
                    at: Location::line(file, next),
                    what: "header line length in bytes".into(),
                    limit: opts.max_line_bytes as u64,
                })
            }
        };
        let n = line.number;
        let at = || Location::line(file, n);
        let parse = |message: String| ImportError::Parse { at: at(), message };
        if n == 1 {
            if line.text.trim() != "ply" {
                return Err(not_ply(file));
            }
            continue;
        }
        let mut words = line.text.split_whitespace();
        match words.next() {
            None => {}
            Some("format") => {
                let (kind, version) = (words.next(), words.next());
                h.encoding = match kind {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::Binary(false),
                    Some("binary_big_endian") => Encoding::Binary(true),
                    _ => return Err(parse(format!("unknown format line `{}`", line.text.trim()))),
                };
                if !matches!(version, Some("1.0" | "1")) {
                    return Err(ImportError::Unsupported {
                        at: at(),
                        what: format!("PLY version {}", version.unwrap_or("(none)")),
                    });
                }
                format = true;
            }
            Some("element") => {
                let (Some(name), Some(count), None) = (words.next(), words.next(), words.next())
                else {
                    return Err(parse("expected `element <name> <count>`".into()));
                };
                let count = count
                    .parse()
                    .map_err(|_| parse(format!("element count `{count}` is not a whole number")))?;
                h.elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                    line: n,
                });
            }
            Some("property") => {
                let property = property(words).map_err(|e| match e {
                    PropertyError::Malformed(m) => parse(m),
                    PropertyError::Type(t) => ImportError::Unsupported {
                        at: at(),
                        what: format!("property type `{t}`"),
                    },
                })?;
                h.elements
                    .last_mut()
                    .ok_or_else(|| parse("`property` before any `element`".into()))?
                    .properties
                    .push(property);
            }
            Some("comment") => comment(&mut h, n, rest_after(line.text, 1)),
            Some("obj_info") => {}
            Some("end_header") => break,
            Some(other) => return Err(parse(format!("unknown header line `{other}`"))),
        }
        if lines.offset() > opts.max_header_bytes {
            return Err(ImportError::Limit {
                at: at(),
                what: "header size in bytes".into(),
                limit: opts.max_header_bytes,
            });
        }
    }
    if !format {
        return Err(ImportError::Parse {
            at: Location::line(file, lines.line()),
            message: "the header has no `format` line".into(),
        });
    }
    Ok(h)
}

fn not_ply(file: &str) -> ImportError {
    ImportError::Parse {
        at: Location::line(file, 1),
        message: "not a PLY file: the first line is not `ply`".into(),
    }
}

enum PropertyError {
    Malformed(String),
    Type(String),
}

/// The words after `property`: `<type> <name>` or `list <count type> <item type> <name>`.
fn property<'a>(mut words: impl Iterator<Item = &'a str>) -> Result<Property, PropertyError> {
    let scalar = |w: Option<&str>| {
        let w = w.ok_or_else(|| {
            PropertyError::Malformed(
                "expected `property <type> <name>` or `property list <count type> <item type> \
                 <name>`"
                    .into(),
            )
        })?;
        Scalar::parse(w).ok_or_else(|| PropertyError::Type(w.to_string()))
    };
    let first = words.next();
    let kind = if first == Some("list") {
        let count = scalar(words.next())?;
        let item = scalar(words.next())?;
        if count.is_float() {
            return Err(PropertyError::Malformed(format!(
                "a list's length must be of an integer type, not {count:?}"
            )));
        }
        Kind::List { count, item }
    } else {
        Kind::Scalar(scalar(first)?)
    };
    match (words.next(), words.next()) {
        (Some(name), None) => Ok(Property {
            name: name.to_string(),
            kind,
        }),
        _ => Err(PropertyError::Malformed(
            "expected one name after the property's type".into(),
        )),
    }
}

/// The text after the first `words` words, trimmed.
fn rest_after(text: &str, words: usize) -> &str {
    let mut t = text.trim_start();
    for _ in 0..words {
        let end = t.find(char::is_whitespace).unwrap_or(t.len());
        t = t.get(end..).unwrap_or_default().trim_start();
    }
    t.trim_end()
}

/// A comment: ours are kept, the rest ignored.
fn comment(h: &mut Header, line: u64, text: &str) {
    let mut words = text.split_whitespace();
    let ok = match words.next() {
        Some("part") => part_comment(text).map(|p| h.parts.push(p)),
        Some("material") => material_comment(text).map(|m| h.materials.push(m)),
        _ if text.starts_with(ORIGIN_COMMENT) => {
            let v: Vec<f64> = rest_after(text, 7)
                .split_whitespace()
                .filter_map(|w| w.parse().ok())
                .filter(|v: &f64| v.is_finite())
                .collect();
            match v[..] {
                [x, y, z] => {
                    h.origin = Some([x, y, z]);
                    Some(())
                }
                _ => None,
            }
        }
        _ => Some(()),
    };
    if ok.is_none() {
        h.bad_comments.push((line, text.to_string()));
    }
}

/// `part <id> <parent or -1> <name>`, the name escaped as the OBJ part table's.
fn part_comment(text: &str) -> Option<CommentPart> {
    match part_table::parse_directive(text.strip_prefix(part_table::PART)?)? {
        Directive::Entry(e) => Some(CommentPart {
            id: e.id,
            parent: e.parent,
            name: e.name,
        }),
        Directive::Select(_) => None,
    }
}

/// `material <index> <name> <r> <g> <b>` (the name may hold spaces).
fn material_comment(text: &str) -> Option<(u32, Material)> {
    let index = text.split_whitespace().nth(1)?.parse().ok()?;
    let rest = rest_after(text, 2);
    let mut words = rest.rsplitn(4, char::is_whitespace);
    let mut diffuse = [0.0f32; 3];
    for c in diffuse.iter_mut().rev() {
        *c = words.next()?.parse().ok().filter(|c: &f32| c.is_finite())?;
    }
    let name = words.next()?.trim_end().to_string();
    Some((index, Material { name, diffuse }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn our_comments_parse_and_others_are_ignored() {
        let mut h = Header {
            encoding: Encoding::Ascii,
            elements: Vec::new(),
            parts: Vec::new(),
            materials: Vec::new(),
            origin: None,
            bad_comments: Vec::new(),
        };
        comment(&mut h, 3, "part 0 -1 wing assembly");
        comment(&mut h, 4, "part 1 0 bolt%2017");
        comment(&mut h, 5, "part x -1 bad");
        comment(&mut h, 6, "material 2 brushed steel 0.5 0.25 1");
        comment(&mut h, 7, "material 3 nocolour");
        comment(
            &mut h,
            8,
            "positions are relative to the scene origin 1e7 -2.5 0",
        );
        comment(&mut h, 9, "exported by something");
        assert_eq!(
            h.parts,
            [
                CommentPart {
                    id: 0,
                    parent: None,
                    name: "wing assembly".into()
                },
                CommentPart {
                    id: 1,
                    parent: Some(0),
                    name: "bolt 17".into()
                }
            ]
        );
        assert_eq!(h.materials.len(), 1);
        assert_eq!(h.materials[0].0, 2);
        assert_eq!(h.materials[0].1.name, "brushed steel");
        assert_eq!(h.materials[0].1.diffuse, [0.5, 0.25, 1.0]);
        assert_eq!(h.origin, Some([1e7, -2.5, 0.0]));
        let bad: Vec<u64> = h.bad_comments.iter().map(|b| b.0).collect();
        assert_eq!(bad, [5, 7]);
    }

    #[test]
    fn properties_and_their_errors() {
        let p = |s: &str| property(s.split_whitespace());
        assert!(matches!(
            p("list uint8 int32 vertex_indices"),
            Ok(Property {
                kind: Kind::List {
                    count: Scalar::U8,
                    item: Scalar::I32
                },
                ..
            })
        ));
        assert!(matches!(
            p("float x"),
            Ok(Property {
                kind: Kind::Scalar(Scalar::F32),
                ..
            })
        ));
        assert!(matches!(
            p("list float int v"),
            Err(PropertyError::Malformed(_))
        ));
        assert!(matches!(p("int64 x"), Err(PropertyError::Type(t)) if t == "int64"));
        assert!(matches!(p("float"), Err(PropertyError::Malformed(_))));
        assert!(matches!(p("float x y"), Err(PropertyError::Malformed(_))));
    }
}
