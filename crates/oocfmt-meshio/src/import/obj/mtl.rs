//! A material library (.mtl) parser that keeps only what the container stores: each
//! material's name and diffuse colour.
//!
//! Our own because tobj 4.0 panics (an `unwrap` in its `Kd` parsing) on `Kd 1 2`, which a
//! plain `load_obj` reaches through `mtllib`. Nothing in a library is fatal here: a material's
//! look is not worth refusing a model for, so problems become warnings naming the .mtl file
//! and line, and the material keeps the default colour.

use std::collections::HashMap;
use std::io::BufRead;

use super::lines::{LineError, Lines};
use crate::import::Location;

/// The colour of materials the input names but does not define, or defines without `Kd`.
pub(super) const DEFAULT_DIFFUSE: [f32; 3] = [0.8, 0.8, 0.8];

/// Materials by name; a later definition of a name replaces an earlier one.
pub(super) type Library = HashMap<String, [f32; 3]>;

/// Reads `reader` (the library `file`) into `library`, reporting problems through `warn`.
/// Returns `Err` with a location and message when reading had to stop early (a read error or
/// an over-long line); the materials before that point are kept.
pub(super) fn parse<R: BufRead>(
    reader: R,
    file: &str,
    max_line: usize,
    library: &mut Library,
    warn: &mut dyn FnMut(Location, String),
) -> Result<(), (Location, String)> {
    let mut lines = Lines::new(reader, max_line);
    let mut current: Option<String> = None;
    loop {
        let (n, text) = match lines.next_line() {
            Ok(Some(line)) => line,
            Ok(None) => return Ok(()),
            Err(f) => {
                let message = match f.error {
                    LineError::Io(e) => format!("read error: {e}"),
                    LineError::TooLong => format!("line longer than {max_line} bytes"),
                };
                return Err((Location::line(file, f.line), message));
            }
        };
        let mut words = text.split_whitespace();
        match words.next() {
            Some("newmtl") => {
                let name = rest_after(text, "newmtl");
                if name.is_empty() {
                    warn(
                        Location::line(file, n),
                        "`newmtl` without a name; what follows up to the next `newmtl` is ignored"
                            .into(),
                    );
                    current = None;
                    continue;
                }
                if library.insert(name.to_string(), DEFAULT_DIFFUSE).is_some() {
                    warn(
                        Location::line(file, n),
                        format!("material `{name}` is defined again; the later definition wins"),
                    );
                }
                current = Some(name.to_string());
            }
            Some("Kd") => {
                let Some(name) = &current else {
                    warn(
                        Location::line(file, n),
                        "`Kd` before any `newmtl` is ignored".into(),
                    );
                    continue;
                };
                match diffuse(words) {
                    Ok(rgb) => {
                        if let Some(slot) = library.get_mut(name) {
                            *slot = rgb;
                        }
                    }
                    Err(why) => warn(
                        Location::line(file, n),
                        format!("{why}; material `{name}` keeps the default colour"),
                    ),
                }
            }
            // Everything else (other colours, textures, illumination models) does not reach
            // the container.
            _ => {}
        }
    }
}

/// `Kd r g b`, or `Kd r` which the MTL specification defines as grey `r r r`.
fn diffuse<'a>(words: impl Iterator<Item = &'a str>) -> Result<[f32; 3], String> {
    let words: Vec<&str> = words.take(4).collect();
    let mut rgb = [0.0f32; 3];
    for (slot, w) in rgb.iter_mut().zip(&words) {
        *slot = w
            .parse::<f32>()
            .map_err(|_| format!("`Kd` has `{w}` where a number belongs"))?;
    }
    match words.len() {
        1 => rgb = [rgb[0]; 3],
        3 => {}
        k => {
            let found = if k > 3 {
                "more than 3".to_string()
            } else {
                k.to_string()
            };
            return Err(format!(
                "`Kd` needs 3 numbers (or 1 for grey), found {found}"
            ));
        }
    }
    if !rgb.iter().all(|c| c.is_finite()) {
        return Err(format!("`Kd` {rgb:?} is not finite"));
    }
    Ok(rgb)
}

/// The text after a statement's keyword: a name, which may contain spaces.
pub(super) fn rest_after<'a>(text: &'a str, keyword: &str) -> &'a str {
    text.get(keyword.len()..).unwrap_or_default().trim()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(text: &str) -> (Library, Vec<String>, Option<String>) {
        let mut lib = Library::new();
        let mut warnings = Vec::new();
        let r = parse(text.as_bytes(), "m.mtl", 256, &mut lib, &mut |at, m| {
            warnings.push(format!("{at}: {m}"))
        });
        (lib, warnings, r.err().map(|(at, m)| format!("{at}: {m}")))
    }

    #[test]
    fn names_and_diffuse_colours() {
        let (lib, w, e) = run(
            "# c\r\nnewmtl red\r\n\tKd 1 0 0 \r\nKs 1 1 1\r\n\r\nnewmtl grey metal\nKd 0.5\nnewmtl plain\n",
        );
        assert!(w.is_empty() && e.is_none(), "{w:?} {e:?}");
        assert_eq!(lib.get("red"), Some(&[1.0, 0.0, 0.0]));
        assert_eq!(lib.get("grey metal"), Some(&[0.5; 3]));
        assert_eq!(lib.get("plain"), Some(&DEFAULT_DIFFUSE));
    }

    #[test]
    fn malformed_statements_warn_with_file_and_line() {
        let (lib, w, e) = run(
            "Kd 1 1 1\nnewmtl a\nKd 1 2\nnewmtl b\nKd 1 x 0\nnewmtl c\nKd 1 1 1 1\nnewmtl d\nKd nan 0 0\nnewmtl\nnewmtl a\n",
        );
        assert!(e.is_none());
        assert_eq!(w.len(), 7, "{w:?}");
        for (k, line) in [1, 3, 5, 7, 9, 10, 11].iter().enumerate() {
            assert!(w[k].starts_with(&format!("m.mtl:{line}: ")), "{}", w[k]);
        }
        assert!(w[1].contains("found 2"), "{}", w[1]);
        for name in ["a", "b", "c", "d"] {
            assert_eq!(lib.get(name), Some(&DEFAULT_DIFFUSE), "{name}");
        }
    }

    #[test]
    fn an_over_long_line_stops_the_library_but_keeps_what_came_before() {
        let text = format!("newmtl a\nKd 0 1 0\nnewmtl b {}\n", "x".repeat(300));
        let (lib, _, e) = run(&text);
        assert_eq!(lib.get("a"), Some(&[0.0, 1.0, 0.0]));
        assert!(e.is_some_and(|e| e.starts_with("m.mtl:3: line longer than 256")));
    }
}
