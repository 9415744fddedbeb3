//! Which part (assembly node) each face belongs to: OBJ objects and groups, or the part table
//! that `oocfmt export` writes into comments ([`super::part_table`]).
//!
//! `o NAME` starts a top-level part; `g NAME…` a part under the current object (top level
//! when there is none). OBJ's `g a b` puts the face in the groups `a` and `b` at once, which a
//! tree cannot say: it becomes the one part "a b" (the names joined by one space), so faces
//! grouped alike stay together and the name keeps every group. `g` alone is OBJ's group
//! "default" (and so is `o` alone). The same name under the same parent continues its part
//! (OBJ files reopen groups). A part is declared when its first face comes, so a `g default`
//! above the vertices (as Maya writes) or an empty object makes none, and a file without
//! `o`/`g` declares no part at all. Faces before any `o`/`g` are in no part.
//!
//! Once a `# oocfmt parts N` comment is read, the table's comments decide instead, and `o`/`g`
//! are only names for other readers.

use std::collections::HashMap;

use super::part_table::{self, Directive, Entry};
use crate::import::{ImportError, Location, PartDef, TriangleSink};

/// An `o` or `g` that has been read, and its part once a face has needed it.
struct Named {
    name: String,
    part: Option<u32>,
}

impl Named {
    fn new(name: String) -> Named {
        Named { name, part: None }
    }
}

/// The part table read from comments.
struct Table {
    /// How many parts the header announced.
    announced: u32,
    /// The sink's index of each part listed so far, by its id in the file.
    parts: Vec<u32>,
    /// The part chosen by the last `# part ID`.
    selected: Option<u32>,
}

#[derive(Default)]
pub(super) struct Parts {
    /// (parent part, name) → the part declared for it.
    known: HashMap<(Option<u32>, String), u32>,
    object: Option<Named>,
    group: Option<Named>,
    table: Option<Table>,
}

/// The error a sink gave for a part, placed at the statement that needed it.
fn placed(e: ImportError, at: &Location) -> ImportError {
    match e {
        ImportError::Limit { at: a, what, limit } if a.file.is_empty() => ImportError::Limit {
            at: at.clone(),
            what,
            limit,
        },
        ImportError::Parse { at: a, message } if a.file.is_empty() => ImportError::Parse {
            at: at.clone(),
            message,
        },
        e => e,
    }
}

fn parse_error(at: &Location, message: String) -> ImportError {
    ImportError::Parse {
        at: at.clone(),
        message,
    }
}

impl Parts {
    /// `o NAME` (the text after the keyword).
    pub(super) fn object(&mut self, name: &str) {
        if self.table.is_none() {
            let name = if name.is_empty() { "default" } else { name };
            self.object = Some(Named::new(name.to_string()));
            self.group = None;
        }
    }

    /// `g NAME…` (the text after the keyword).
    pub(super) fn group(&mut self, names: &str) {
        if self.table.is_some() {
            return;
        }
        let joined = names.split_whitespace().collect::<Vec<_>>().join(" ");
        let name = if joined.is_empty() {
            "default".to_string()
        } else {
            joined
        };
        if self.group.as_ref().is_none_or(|g| g.name != name) {
            self.group = Some(Named::new(name));
        }
    }

    /// A comment line (from its `#`): the part table's header, entries and selections; any
    /// other comment is nothing.
    pub(super) fn comment(
        &mut self,
        comment: &str,
        at: &Location,
        sink: &mut dyn TriangleSink,
    ) -> Result<(), ImportError> {
        let body = comment.trim_start_matches('#').trim_start();
        if let Some(count) = body.strip_prefix(part_table::TABLE_HEADER) {
            return self.header(count, at);
        }
        let Some(table) = self.table.as_mut() else {
            return Ok(());
        };
        let Some(args) = body
            .strip_prefix(part_table::PART)
            .filter(|a| a.starts_with(char::is_whitespace))
        else {
            return Ok(());
        };
        match part_table::parse_directive(args) {
            None => Ok(()),
            Some(Directive::Select(id)) => {
                let part = table.parts.get(id as usize).copied().ok_or_else(|| {
                    parse_error(
                        at,
                        format!(
                            "`# part {id}` names a part the table has not listed ({} listed)",
                            table.parts.len()
                        ),
                    )
                })?;
                table.selected = Some(part);
                Ok(())
            }
            Some(Directive::Entry(entry)) => table.entry(entry, at, sink),
        }
    }

    fn header(&mut self, count: &str, at: &Location) -> Result<(), ImportError> {
        if self.table.is_some() {
            return Err(parse_error(at, "a second part table".into()));
        }
        let announced = count
            .trim()
            .parse::<u32>()
            .ok()
            .filter(|&n| n <= crate::import::MAX_PARTS)
            .ok_or_else(|| {
                parse_error(
                    at,
                    format!(
                        "`# {} {}`: expected a part count of at most {}",
                        part_table::TABLE_HEADER,
                        count.trim(),
                        crate::import::MAX_PARTS
                    ),
                )
            })?;
        self.table = Some(Table {
            announced,
            parts: Vec::new(),
            selected: None,
        });
        Ok(())
    }

    /// The part of the face being read, declaring it (and its object) on first use.
    pub(super) fn current(
        &mut self,
        at: &Location,
        sink: &mut dyn TriangleSink,
    ) -> Result<Option<u32>, ImportError> {
        if let Some(table) = &self.table {
            return Ok(table.selected);
        }
        let parent = match self.object.as_mut() {
            Some(o) => Some(declare(&mut self.known, o, None, at, sink)?),
            None => None,
        };
        match self.group.as_mut() {
            Some(g) => declare(&mut self.known, g, parent, at, sink).map(Some),
            None => Ok(parent),
        }
    }

    /// Checks, at the end of the file, that the table listed every part it announced.
    pub(super) fn finish(&self, at: &Location) -> Result<(), ImportError> {
        match &self.table {
            Some(t) if t.parts.len() as u64 != u64::from(t.announced) => Err(parse_error(
                at,
                format!(
                    "the part table announces {} parts but lists {}",
                    t.announced,
                    t.parts.len()
                ),
            )),
            _ => Ok(()),
        }
    }
}

impl Table {
    fn entry(
        &mut self,
        entry: Entry,
        at: &Location,
        sink: &mut dyn TriangleSink,
    ) -> Result<(), ImportError> {
        let next = self.parts.len();
        if entry.id as usize != next || next >= self.announced as usize {
            return Err(parse_error(
                at,
                format!(
                    "part table entry {} out of order: expected part {next} of {}",
                    entry.id, self.announced
                ),
            ));
        }
        let parent = match entry.parent {
            None => None,
            Some(p) => Some(*self.parts.get(p as usize).ok_or_else(|| {
                parse_error(
                    at,
                    format!(
                        "part {} names parent {p}, which is not listed before it",
                        entry.id
                    ),
                )
            })?),
        };
        let part = sink
            .add_part(PartDef::new(entry.name, parent))
            .map_err(|e| placed(e, at))?;
        self.parts.push(part);
        Ok(())
    }
}

/// The part of `named` under `parent`: the one declared before for the same parent and name,
/// else a new one.
fn declare(
    known: &mut HashMap<(Option<u32>, String), u32>,
    named: &mut Named,
    parent: Option<u32>,
    at: &Location,
    sink: &mut dyn TriangleSink,
) -> Result<u32, ImportError> {
    if let Some(p) = named.part {
        return Ok(p);
    }
    let key = (parent, named.name.clone());
    let part = match known.get(&key) {
        Some(&p) => p,
        None => {
            let p = sink
                .add_part(PartDef::new(named.name.clone(), parent))
                .map_err(|e| placed(e, at))?;
            known.insert(key, p);
            p
        }
    };
    named.part = Some(part);
    Ok(part)
}
