//! The part table `oocfmt export` writes into the comments of an OBJ (and the header comments
//! of a PLY, as `comment part ID PARENT NAME`), so that a re-import gives back the container's
//! exact tree: ids, parents and names, where `o`/`g` could only say two levels and would merge
//! same-named siblings. The syntax is in the OBJ importer's documentation
//! ([`crate::import::obj`]); a PLY importer can parse the same lines with [`parse_directive`].

use std::fmt::Write as _;

/// The comment that announces the table: `# oocfmt parts N`.
pub(crate) const TABLE_HEADER: &str = "oocfmt parts";

/// The word that starts an entry (`part ID PARENT NAME`) or a selection (`part ID`).
pub(crate) const PART: &str = "part";

/// One line of the table: a part, its parent (`None`: top level, written -1) and its name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Entry {
    pub id: u32,
    pub parent: Option<u32>,
    pub name: String,
}

/// What a `part …` comment says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Directive {
    /// `part ID PARENT NAME`: a line of the table.
    Entry(Entry),
    /// `part ID`: the faces that follow belong to part `ID`.
    Select(u32),
}

/// `ID PARENT NAME` as a table line writes it (after `part `), the name escaped.
pub(crate) fn format_entry(id: u32, parent: Option<u32>, name: &str) -> String {
    let parent = parent.map_or_else(|| "-1".to_string(), |p| p.to_string());
    format!("{id} {parent} {}", escape(name))
}

/// The words after `part `: a selection (one id) or an entry (id, parent, name); `None` when
/// they are neither, e.g. an ordinary comment that happens to start with "part".
pub(crate) fn parse_directive(args: &str) -> Option<Directive> {
    let (id, rest) = split_word(args.trim_start());
    let id = id.parse::<u32>().ok()?;
    let rest = rest.trim_start();
    if rest.trim_end().is_empty() {
        return Some(Directive::Select(id));
    }
    let (parent, name) = split_word(rest);
    let parent = match parent {
        "-1" => None,
        p => Some(p.parse::<u32>().ok()?),
    };
    Some(Directive::Entry(Entry {
        id,
        parent,
        name: unescape(name.trim()),
    }))
}

/// The first whitespace-separated word and what follows it.
fn split_word(s: &str) -> (&str, &str) {
    s.split_once(char::is_whitespace).unwrap_or((s, ""))
}

/// The name with `%`, `\` (which would continue an OBJ line), control characters and leading
/// or trailing whitespace (which readers trim) written as `%XX` per UTF-8 byte.
pub(crate) fn escape(name: &str) -> String {
    let body_start = name.len() - name.trim_start().len();
    let body_end = name.trim_end().len().max(body_start);
    let mut out = String::with_capacity(name.len());
    for (i, c) in name.char_indices() {
        let edge = i < body_start || i >= body_end;
        if edge || c == '%' || c == '\\' || c.is_control() {
            let mut bytes = [0u8; 4];
            for b in c.encode_utf8(&mut bytes).bytes() {
                let _ = write!(out, "%{b:02X}");
            }
        } else {
            out.push(c);
        }
    }
    out
}

/// Undoes [`escape`]; a `%` not followed by two hex digits stands for itself.
pub(crate) fn unescape(text: &str) -> String {
    if !text.contains('%') {
        return text.to_string();
    }
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while let Some(&b) = bytes.get(i) {
        let hex = bytes
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .filter(|h| h.bytes().all(|d| d.is_ascii_hexdigit()))
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (b, hex) {
            (b'%', Some(v)) => {
                out.push(v);
                i += 3;
            }
            _ => {
                out.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_survive_escaping_whatever_they_hold() {
        for name in [
            "engine",
            "",
            "turbine blade",
            "50% scale",
            "a\\",
            " lead and trail\u{a0} ",
            "tab\tnew\nline\r\u{85}",
            "#5 bolt",
            "café/ü",
            "%41",
        ] {
            let text = escape(name);
            assert!(!text.chars().any(char::is_control), "{text:?}");
            assert!(!text.contains('\\'), "{text:?}");
            assert_eq!(text.trim(), text, "{text:?}");
            assert_eq!(unescape(&text), name, "{text:?}");
        }
        assert_eq!(escape("50% a\\"), "50%25 a%5C");
        assert_eq!(unescape("100%"), "100%");
        assert_eq!(unescape("%zz%4"), "%zz%4");
    }

    #[test]
    fn directives_are_entries_or_selections_and_nothing_else() {
        assert_eq!(parse_directive("7"), Some(Directive::Select(7)));
        assert_eq!(parse_directive(" 7  "), Some(Directive::Select(7)));
        let entry = |id, parent, name: &str| {
            Some(Directive::Entry(Entry {
                id,
                parent,
                name: name.into(),
            }))
        };
        assert_eq!(parse_directive("0 -1 engine"), entry(0, None, "engine"));
        assert_eq!(parse_directive("3 1 a  b "), entry(3, Some(1), "a  b"));
        assert_eq!(parse_directive("3 1"), entry(3, Some(1), ""));
        assert_eq!(
            parse_directive(&format_entry(4, Some(2), " x%\t")),
            entry(4, Some(2), " x%\t")
        );
        for other in ["of the engine", "", "1 of 3", "-1", "2 -2 x", "99999999999"] {
            assert_eq!(parse_directive(other), None, "{other}");
        }
    }
}
