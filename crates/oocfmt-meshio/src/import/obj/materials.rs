//! `mtllib` and `usemtl`: which material libraries are read, and which material each face
//! gets.
//!
//! A material reaches the sink on its first use by a face, so the hundreds of unused entries
//! of a shared CAD library cost nothing. A name no library defines (the library may be
//! missing) still becomes a material of its own, in the default colour, so faces that were
//! told apart in the input stay apart.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Component, Path, PathBuf};

use oocfmt::metadata::Material;

use super::mtl::{self, Library, DEFAULT_DIFFUSE};
use super::notes::{Kind, Notes};
use super::ObjOptions;
use crate::import::{ImportError, Location, TriangleSink};

/// The material chosen by the last `usemtl`.
struct Selected {
    name: String,
    /// Where it was chosen, for the warning about an undefined name.
    line: u64,
    /// Its index in the sink, once a face has used it.
    index: Option<u32>,
}

pub(super) struct Materials {
    /// The OBJ file's folder: libraries are looked up there and may not leave it.
    dir: PathBuf,
    library: Library,
    in_sink: HashMap<String, u32>,
    current: Option<Selected>,
}

impl Materials {
    pub(super) fn new(dir: PathBuf) -> Materials {
        Materials {
            dir,
            library: Library::new(),
            in_sink: HashMap::new(),
            current: None,
        }
    }

    /// `usemtl NAME`; an empty name goes back to no material.
    pub(super) fn select(&mut self, name: &str, line: u64) {
        if self.current.as_ref().is_some_and(|s| s.name == name) {
            return;
        }
        self.current = (!name.is_empty()).then(|| Selected {
            name: name.to_string(),
            line,
            index: self.in_sink.get(name).copied(),
        });
    }

    /// The sink's index of the selected material, adding it to the sink on first use.
    pub(super) fn current(
        &mut self,
        sink: &mut dyn TriangleSink,
        notes: &mut Notes,
        file: &str,
    ) -> Result<Option<u32>, ImportError> {
        let Some(sel) = &mut self.current else {
            return Ok(None);
        };
        if let Some(i) = sel.index {
            return Ok(Some(i));
        }
        let diffuse = match self.library.get(&sel.name) {
            Some(&rgb) => rgb,
            None => {
                notes.warn(
                    sink,
                    Kind::UnknownMaterial,
                    &Location::line(file, sel.line),
                    || {
                        format!(
                            "material `{}` is not defined in any material library read so far; \
                             it gets the default colour",
                            sel.name
                        )
                    },
                );
                DEFAULT_DIFFUSE
            }
        };
        let i = sink.add_material(Material {
            name: sel.name.clone(),
            diffuse,
        })?;
        self.in_sink.insert(sel.name.clone(), i);
        sel.index = Some(i);
        Ok(Some(i))
    }

    /// `mtllib FILE...`. Never fails: a library that cannot be read is a warning.
    pub(super) fn load(
        &mut self,
        args: &str,
        at: &Location,
        opts: &ObjOptions,
        sink: &mut dyn TriangleSink,
        notes: &mut Notes,
    ) {
        if args.is_empty() {
            notes.warn(sink, Kind::Library, at, || {
                "`mtllib` without a file name".into()
            });
            return;
        }
        // The statement lists files separated by spaces, but exporters also write one name
        // that contains spaces; a whole-line name that exists wins.
        if args.contains(char::is_whitespace) && self.dir.join(args).is_file() {
            self.load_one(args, at, opts, sink, notes);
        } else {
            for name in args.split_whitespace() {
                self.load_one(name, at, opts, sink, notes);
            }
        }
    }

    fn load_one(
        &mut self,
        name: &str,
        at: &Location,
        opts: &ObjOptions,
        sink: &mut dyn TriangleSink,
        notes: &mut Notes,
    ) {
        let mut warn = |notes: &mut Notes, why: String| {
            notes.warn(sink, Kind::Library, at, || {
                format!("material library `{name}` {why}; its materials get the default colour")
            });
        };
        let path = match self.inside_folder(name) {
            Ok(p) => p,
            Err(why) => return warn(notes, why),
        };
        let file = match File::open(&path) {
            Ok(f) => f,
            Err(e) => return warn(notes, format!("cannot be opened ({e})")),
        };
        match file.metadata() {
            Ok(m) if !m.is_file() => return warn(notes, "is not a regular file".into()),
            Ok(m) if m.len() > opts.max_mtl_bytes => {
                return warn(
                    notes,
                    format!("is larger than the limit of {} bytes", opts.max_mtl_bytes),
                )
            }
            Ok(_) => {}
            Err(e) => return warn(notes, format!("cannot be read ({e})")),
        }
        let shown = self.dir.join(name).display().to_string();
        // The cap on reading holds even if the file grows after the size check.
        let reader = BufReader::new(file.take(opts.max_mtl_bytes));
        let result = mtl::parse(
            reader,
            &shown,
            opts.max_line_bytes,
            &mut self.library,
            &mut |at, message| notes.warn(sink, Kind::Library, &at, || message),
        );
        if let Err((at, message)) = result {
            notes.warn(sink, Kind::Library, &at, || {
                format!("{message}; the rest of this material library is ignored")
            });
        }
    }

    /// The library's path, if it stays inside the OBJ file's folder (links followed).
    fn inside_folder(&self, name: &str) -> Result<PathBuf, String> {
        // Windows exporters write `sub\lib.mtl`.
        let relative = PathBuf::from(name.replace('\\', "/"));
        let plain = relative
            .components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir));
        if !plain {
            return Err("is refused: it is not a path inside the model's folder".into());
        }
        let canonical = |p: &Path| p.canonicalize().map_err(|e| format!("is not found ({e})"));
        let full = canonical(&self.dir.join(&relative))?;
        let dir = canonical(&self.dir)?;
        if !full.starts_with(&dir) {
            return Err("is refused: it links to a file outside the model's folder".into());
        }
        Ok(full)
    }
}
