//! docs/cli.md against the real binary: every subcommand `oocfmt --help` lists (and those of
//! subcommands with their own, `gen mandelbulb`) has a section in docs/cli.md, every long flag
//! its `--help` lists is in that section's tables, every value of a flag's `[possible values:
//! ..]` is named in its row; and every command and flag the document names exists. The test
//! fails naming each difference, so a flag added without its documentation (or removed with
//! its documentation left behind) cannot pass.
//!
//! The document's shape that this relies on: a command's section starts at a heading naming
//! it in backticks (`` ## `oocfmt render` ``; a heading may name several commands that share
//! one table), and its flags are table rows (`| `--poe <POE>` | ...`) up to the next heading
//! that names a command.

use crate::common;

use std::collections::BTreeMap;
use std::path::Path;

use common::oocfmt;

/// Flags every command has, documented once at the top of docs/cli.md.
const GLOBAL: [&str; 2] = ["--help", "--version"];

/// `oocfmt ARGS --help`, as text.
fn help(args: &[&str]) -> String {
    let mut all = args.to_vec();
    all.push("--help");
    let o = oocfmt(&all, Path::new(env!("CARGO_MANIFEST_DIR")));
    assert_eq!(o.status.code(), Some(0), "oocfmt {all:?}");
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The subcommands a help text lists under `Commands:` (without clap's `help`).
fn subcommands(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| l.trim() != "Commands:")
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(str::to_string)
        .collect()
}

/// A flag's name: `--xyz` of `--xyz <XYZ>`, `--xyz=..` or `--xyz,`.
fn flag_name(token: &str) -> Option<String> {
    let rest = token.strip_prefix("--")?;
    let name: String = rest
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
        .collect();
    (!name.is_empty()).then(|| format!("--{name}"))
}

/// The long flags of a help text and, for each, the values its `[possible values: ..]` lists.
/// Options are the lines of the `Options:` section indented by at most six spaces that start
/// with a dash (descriptions are indented further, and may mention other flags).
fn flags(help: &str) -> BTreeMap<String, Vec<String>> {
    let mut out: BTreeMap<String, Vec<String>> = BTreeMap::new();
    let mut current: Option<String> = None;
    let mut in_options = false;
    for line in help.lines() {
        let trimmed = line.trim_start();
        let indent = line.len() - trimmed.len();
        if indent == 0 && !trimmed.is_empty() {
            in_options = trimmed.ends_with(':') && trimmed.contains("Options");
            current = None;
            continue;
        }
        if !in_options {
            continue;
        }
        if indent <= 6 && trimmed.starts_with('-') {
            current = trimmed.split([' ', ',']).find_map(flag_name);
            if let Some(f) = &current {
                out.entry(f.clone()).or_default();
            }
        }
        if let (Some(f), Some(at)) = (&current, line.find("[possible values: ")) {
            let list = &line[at + "[possible values: ".len()..];
            let list = list.split(']').next().unwrap_or("");
            let values = list.split(',').map(|v| v.trim().to_string());
            out.entry(f.clone()).or_default().extend(values);
        }
    }
    for g in GLOBAL {
        out.remove(g);
    }
    out
}

/// Every command of the binary, as its words after `oocfmt` (`[]` for `oocfmt` itself), with
/// its flags.
fn commands() -> BTreeMap<Vec<String>, BTreeMap<String, Vec<String>>> {
    let mut out = BTreeMap::new();
    let mut todo: Vec<Vec<String>> = vec![Vec::new()];
    while let Some(path) = todo.pop() {
        let args: Vec<&str> = path.iter().map(String::as_str).collect();
        let text = help(&args);
        for sub in subcommands(&text) {
            let mut p = path.clone();
            p.push(sub);
            todo.push(p);
        }
        out.insert(path, flags(&text));
    }
    out
}

/// A document's sections: for each command a heading names, the table rows under it.
fn sections(doc: &str) -> BTreeMap<Vec<String>, Vec<String>> {
    let mut out: BTreeMap<Vec<String>, Vec<String>> = BTreeMap::new();
    let mut current: Vec<Vec<String>> = Vec::new();
    for line in doc.lines() {
        if line.starts_with('#') {
            let named: Vec<Vec<String>> = line
                .split('`')
                .skip(1)
                .step_by(2)
                .filter_map(|code| {
                    let mut words = code.split_whitespace();
                    (words.next() == Some("oocfmt"))
                        .then(|| words.map(str::to_string).collect::<Vec<_>>())
                })
                .filter(|words| words.iter().all(|w| !w.starts_with('-')))
                .collect();
            if !named.is_empty() {
                for c in &named {
                    out.entry(c.clone()).or_default();
                }
                current = named;
            }
            continue;
        }
        if line.trim_start().starts_with('|') {
            for c in &current {
                out.entry(c.clone()).or_default().push(line.to_string());
            }
        }
    }
    out
}

/// The flags a section's table rows document: a `--flag` in backticks in a row's first cell.
fn documented_flags(rows: &[String]) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for row in rows {
        let first = row
            .trim()
            .trim_start_matches('|')
            .split('|')
            .next()
            .unwrap_or("");
        for code in first.split('`').skip(1).step_by(2) {
            for token in code.split([' ', ',', '/']) {
                if let Some(f) = flag_name(token) {
                    out.insert(f, row.clone());
                }
            }
        }
    }
    out
}

fn show(command: &[String]) -> String {
    let mut s = "oocfmt".to_string();
    for w in command {
        s.push(' ');
        s.push_str(w);
    }
    s
}

#[test]
fn docs_cli_md_lists_every_subcommand_and_flag_of_the_binary_and_no_other() {
    let doc_path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/cli.md");
    let doc = std::fs::read_to_string(doc_path)
        .unwrap_or_else(|e| panic!("cannot read docs/cli.md ({doc_path}): {e}"));
    for g in GLOBAL {
        assert!(
            doc.contains(&format!("`{g}`")),
            "docs/cli.md: {g} is not mentioned"
        );
    }
    let binary = commands();
    assert!(
        binary.len() > 8,
        "too few commands found: {:?}",
        binary.keys()
    );
    let documented = sections(&doc);
    let mut problems = Vec::new();
    for (command, flags) in &binary {
        let Some(rows) = documented.get(command) else {
            problems.push(format!(
                "`{}` has no section (a heading naming it in backticks)",
                show(command)
            ));
            continue;
        };
        let doc_flags = documented_flags(rows);
        for (flag, values) in flags {
            match doc_flags.get(flag) {
                None => problems.push(format!(
                    "`{} {flag}` is in `{} --help` but not in its section's tables",
                    show(command),
                    show(command)
                )),
                Some(row) => {
                    for v in values {
                        if !row.contains(&format!("`{v}`")) {
                            problems.push(format!(
                                "`{} {flag}` accepts `{v}`, which its row does not name",
                                show(command)
                            ));
                        }
                    }
                }
            }
        }
        for flag in doc_flags.keys() {
            if !flags.contains_key(flag) && !GLOBAL.contains(&flag.as_str()) {
                problems.push(format!(
                    "`{} {flag}` is documented but `{} --help` has no such flag",
                    show(command),
                    show(command)
                ));
            }
        }
    }
    for command in documented.keys() {
        if !binary.contains_key(command) {
            problems.push(format!(
                "`{}` is documented but the binary has no such command",
                show(command)
            ));
        }
    }
    assert!(
        problems.is_empty(),
        "docs/cli.md has drifted from the binary's --help:\n  {}",
        problems.join("\n  ")
    );
}

#[test]
fn the_help_parser_finds_flags_values_and_commands() {
    let text = "Does things\n\nUsage: oocfmt x [OPTIONS] <FILE>\n\nCommands:\n  one  The first\n  \
                help  Print this message\n\nArguments:\n  <FILE>\n          The file\n\nOptions:\n  \
                -o, --output <OUTPUT>\n          Where; see --not-a-flag\n\n      --cache <CACHE>\n          \
                Which\n\n          [default: async]\n          [possible values: async, blocking]\n\n  \
                -h, --help\n          Print help\n";
    assert_eq!(subcommands(text), ["one"]);
    let f = flags(text);
    assert_eq!(f.keys().collect::<Vec<_>>(), ["--cache", "--output"]);
    assert_eq!(f["--cache"], ["async", "blocking"]);
    let doc = "# `oocfmt`\n| `--x` | |\n## `oocfmt a`, `oocfmt b`\n| Flag | Value |\n| `-o`, `--output <F>` | `--cache` is elsewhere |\n### Example\n| `--y` | |\n## Exit codes\n";
    let s = sections(doc);
    let a = documented_flags(&s[&vec!["a".to_string()]]);
    assert_eq!(a.keys().collect::<Vec<_>>(), ["--output", "--y"]);
    assert_eq!(s[&vec!["a".to_string()]], s[&vec!["b".to_string()]]);
    assert!(documented_flags(&s[&Vec::new()]).contains_key("--x"));
}
