//! Models through a pipe: `gen -o -` into `convert -` builds what a convert of the file
//! builds, PLY and STL from standard input convert as their files do, what standard input
//! cannot do is refused with exit code 2, and `gen -o -` into a reader that goes away ends
//! quietly with 141.

use crate::common;

use common::*;

use std::fs::File;
use std::io::Read;
use std::path::Path;
use std::process::{Command, Output, Stdio};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_oocfmt"))
}

/// `inspect --json` of `file`, without what names the file and its sources (and the sizes
/// and checksums the source names change).
fn contents(dir: &Path, file: &str) -> serde_json::Value {
    let o = run_ok(&["inspect", file, "--json"], dir);
    let mut v: serde_json::Value =
        serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{file}: {e}"));
    strip(&mut v);
    v
}

fn strip(v: &mut serde_json::Value) {
    const VARY: [&str; 6] = [
        "file",
        "file_length",
        "identity",
        "sources",
        "resident_stored_bytes",
        "bytes_per_triangle",
    ];
    match v {
        serde_json::Value::Object(m) => {
            m.retain(|k, _| !VARY.contains(&k.as_str()));
            m.values_mut().for_each(strip);
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
        _ => {}
    }
}

/// `oocfmt convert - ARGS --quiet` in `dir` with `input` as standard input.
fn convert_stdin(dir: &Path, input: &Path, args: &[&str]) -> Output {
    let file = File::open(input).unwrap_or_else(|e| panic!("{}: {e}", input.display()));
    bin()
        .args(["convert", "-"])
        .args(args)
        .arg("--quiet")
        .current_dir(dir)
        .stdin(file)
        .output()
        .unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn gen_piped_into_convert_builds_what_the_file_builds() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = tmp.path();
    gen(dir, "mandelbulb", "30000", "m.obj");
    run_ok(&["convert", "m.obj", "-o", "file.oocf", "--quiet"], dir);
    let mut producer = bin()
        .args(["gen", "mandelbulb", "--tris", "30000", "-o", "-", "--quiet"])
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{e}"));
    let pipe = producer
        .stdout
        .take()
        .unwrap_or_else(|| panic!("no stdout"));
    let consumer = bin()
        .args([
            "convert",
            "-",
            "--format",
            "obj",
            "-o",
            "pipe.oocf",
            "--quiet",
        ])
        .current_dir(dir)
        .stdin(pipe)
        .output()
        .unwrap_or_else(|e| panic!("{e}"));
    ok(&consumer, "convert -");
    let produced = producer
        .wait_with_output()
        .unwrap_or_else(|e| panic!("{e}"));
    ok(&produced, "gen -o -");
    let summary = String::from_utf8_lossy(&produced.stderr);
    assert!(summary.starts_with("wrote standard output ("), "{summary}");
    assert!(stdout(&consumer).contains("inputs     <stdin>\n"));
    assert_eq!(contents(dir, "pipe.oocf"), contents(dir, "file.oocf"));
}

#[test]
fn ply_and_stl_from_standard_input_convert_as_their_files() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = tmp.path();
    gen(dir, "mandelbulb", "5000", "m.obj");
    run_ok(&["convert", "m.obj", "-o", "m.oocf", "--quiet"], dir);
    run_ok(&["export", "m.oocf", "-o", "m.ply", "--quiet"], dir);
    // A binary STL of the same triangles, written here from the PLY's OBJ twin.
    run_ok(&["export", "m.oocf", "-o", "t.obj", "--quiet"], dir);
    std::fs::write(dir.join("m.stl"), stl_of_obj(&dir.join("t.obj"))).unwrap_or_default();
    for (file, format) in [("m.ply", "ply"), ("m.stl", "stl")] {
        run_ok(&["convert", file, "-o", "file.oocf", "--quiet"], dir);
        let o = convert_stdin(
            dir,
            &dir.join(file),
            &["--format", format, "-o", "pipe.oocf"],
        );
        ok(&o, &format!("convert - --format {format}"));
        assert_eq!(
            contents(dir, "pipe.oocf"),
            contents(dir, "file.oocf"),
            "{format}"
        );
    }
}

/// The triangles of the plain OBJ at `path` (`v` and triangle `f` lines) as binary STL.
fn stl_of_obj(path: &Path) -> Vec<u8> {
    let mut text = String::new();
    let _ = File::open(path).and_then(|mut f| f.read_to_string(&mut text));
    let mut v: Vec<[f32; 3]> = Vec::new();
    let mut facets = Vec::new();
    for line in text.lines() {
        let mut w = line.split_whitespace();
        match w.next() {
            Some("v") => {
                let c: Vec<f32> = w.take(3).filter_map(|x| x.parse().ok()).collect();
                v.push([c[0], c[1], c[2]]);
            }
            Some("f") => {
                let i: Vec<usize> = w
                    .filter_map(|x| x.split('/').next()?.parse::<usize>().ok())
                    .collect();
                facets.push([v[i[0] - 1], v[i[1] - 1], v[i[2] - 1]]);
            }
            _ => {}
        }
    }
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&(facets.len() as u32).to_le_bytes());
    for t in facets {
        b.extend_from_slice(&[0u8; 12]);
        for c in t.iter().flatten() {
            b.extend_from_slice(&c.to_le_bytes());
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}

#[test]
fn what_standard_input_cannot_do_is_refused() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = tmp.path();
    std::fs::write(dir.join("empty"), b"").unwrap_or_default();
    let input = dir.join("empty");
    for (args, says) in [
        (&["-o", "x.oocf"][..], "needs `--format obj|ply|stl`"),
        (
            &["--format", "gltf", "-o", "x.oocf"],
            "glTF cannot be read from standard input",
        ),
        (
            &["--format", "obj", "--recentre", "auto", "-o", "x.oocf"],
            "pass `--recentre none` or `--recentre X,Y,Z`",
        ),
        (
            &["-", "--format", "obj", "-o", "x.oocf"],
            "can be an input only once",
        ),
    ] {
        let o = convert_stdin(dir, &input, args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
    assert_eq!(std::fs::read_dir(dir).map(|r| r.count()).unwrap_or(0), 1);
}

#[test]
fn gen_into_a_reader_that_goes_away_ends_quietly() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let mut child = bin()
        .args([
            "gen",
            "mandelbulb",
            "--tris",
            "200000",
            "-o",
            "-",
            "--quiet",
        ])
        .current_dir(tmp.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{e}"));
    let mut pipe = child.stdout.take().unwrap_or_else(|| panic!("no stdout"));
    let mut start = [0u8; 1000];
    assert!(pipe.read_exact(&mut start).is_ok());
    assert!(start.starts_with(b"# power-8 Mandelbulb"));
    drop(pipe);
    let o = child.wait_with_output().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(o.status.code(), Some(141));
    assert_eq!(String::from_utf8_lossy(&o.stderr), "");
}
