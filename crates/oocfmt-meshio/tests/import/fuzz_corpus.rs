//! Replays the STL and PLY fuzz corpora on stable, through the very property functions the
//! cargo-fuzz targets run (`fuzz/src/import.rs`, included by path): every file under
//! `fuzz/corpus/{stl,ply}_import/` and `fuzz/regressions/{stl,ply}_import/`, and the seeds as
//! this file builds them.
//!
//! `OOCFMT_WRITE_CORPUS=1 cargo test -p oocfmt-meshio --test import fuzz_corpus::the_committed_seeds`
//! rewrites the seed corpora.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use crate::import_ply::{cube_faces, cube_vertices, l, n, plain_cube, ply, El, Enc};
use crate::import_stl::{ascii, binary, cube, plain, two};

#[path = "../../../../fuzz/src/import.rs"]
mod props;

const TARGETS: [&str; 2] = ["stl_import", "ply_import"];

fn fuzz_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fuzz"))
}

fn run(target: &str, data: &[u8]) {
    match target {
        "stl_import" => props::stl_import(data),
        "ply_import" => props::ply_import(data),
        other => panic!("no property for {other}"),
    }
}

/// The files of `dir` (none when it does not exist), sorted.
fn files(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut out: Vec<PathBuf> = entries
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file() && !p.file_name().unwrap().to_string_lossy().starts_with('.'))
        .collect();
    out.sort();
    out
}

/// The seeds: small files of every kind each importer reads, by target and name.
fn seeds() -> Vec<(&'static str, &'static str, Vec<u8>)> {
    let c = cube();
    let (left, right) = c.split_at(4);
    let [a, b] = two();
    let mut magics = b"COLOR=\x0a\x14\x1e\x28".to_vec();
    magics.resize(20, b' ');
    let quad = "SOLID\r\n FACET NORMAL 0 0 1\r\n OUTER LOOP\r\n VERTEX 0 0 0\r\n VERTEX 1 0 0\r\n \
                VERTEX 1 1 0\r\n VERTEX 0 1 0\r\n ENDLOOP\r\n ENDFACET\r\nENDSOLID\r\n";
    let parts = cube_faces(vec!["int part", "ushort material_index"], |i| {
        vec![n((i % 3) as f64), n((i % 2) as f64)]
    });
    let comments = [
        "part 0 -1 assembly",
        "part 1 0 bolt",
        "material 0 steel 0.5 0.5 0.5",
        "positions are relative to the scene origin 10 0 0",
    ];
    let strips = El {
        name: "tristrips",
        props: vec!["list int int vertex_indices"],
        rows: vec![vec![l(&[0., 2., 1., 3., -1., 4., 5., 6.])]],
    };
    let camera = El {
        name: "camera",
        props: vec!["float view_px", "list uchar double track"],
        rows: vec![vec![n(1.0), l(&[1.0, 2.0])]],
    };
    let odd_vertices = cube_vertices(vec!["list ushort int junk"], |i| vec![l(&vec![1.0; i % 3])]);
    vec![
        (
            "stl_import",
            "ascii-cube.stl",
            ascii(&[("", &c, &[])]).into_bytes(),
        ),
        (
            "stl_import",
            "ascii-two-solids-flipped.stl",
            ascii(&[("left", left, &[1]), ("", right, &[])]).into_bytes(),
        ),
        (
            "stl_import",
            "ascii-quad-loop.stl",
            quad.as_bytes().to_vec(),
        ),
        (
            "stl_import",
            "binary-cube.stl",
            binary(b"binary cube", &plain(&c)),
        ),
        (
            "stl_import",
            "binary-solid-header.stl",
            binary(b"solid cube", &plain(&c)),
        ),
        (
            "stl_import",
            "binary-viscam.stl",
            binary(b"", &[(a, 0x8000 | (31 << 10), false), (b, 7, true)]),
        ),
        (
            "stl_import",
            "binary-magics.stl",
            binary(&magics, &[(a, 31, false), (b, 0x8000, false)]),
        ),
        ("ply_import", "ascii-cube.ply", plain_cube(Enc::Ascii)),
        ("ply_import", "le-cube.ply", plain_cube(Enc::Le)),
        ("ply_import", "be-cube.ply", plain_cube(Enc::Be)),
        (
            "ply_import",
            "le-parts-materials-origin.ply",
            ply(
                Enc::Le,
                &comments,
                &[cube_vertices(vec![], |_| vec![]), parts],
            ),
        ),
        (
            "ply_import",
            "ascii-strips.ply",
            ply(
                Enc::Ascii,
                &[],
                &[cube_vertices(vec![], |_| vec![]), strips],
            ),
        ),
        (
            "ply_import",
            "be-faces-first-skipped-elements.ply",
            ply(
                Enc::Be,
                &["faces come first"],
                &[
                    camera,
                    cube_faces(vec!["uchar flags"], |i| vec![n(i as f64)]),
                    odd_vertices,
                ],
            ),
        ),
    ]
}

#[test]
fn seeds_replay_and_their_reports_add_up() {
    for (target, name, data) in seeds() {
        eprintln!("{target}/{name}");
        run(target, &data);
    }
}

#[test]
fn corpus_replays_and_reports_add_up() {
    for target in TARGETS {
        let dir = fuzz_dir().join("corpus").join(target);
        let inputs = files(&dir);
        assert!(
            inputs.len() >= 6,
            "{} has {} seeds",
            dir.display(),
            inputs.len()
        );
        for p in inputs {
            eprintln!("{}", p.display());
            run(target, &std::fs::read(&p).unwrap());
        }
    }
}

#[test]
fn regressions_replay_and_reports_add_up() {
    for target in TARGETS {
        for p in files(&fuzz_dir().join("regressions").join(target)) {
            eprintln!("{}", p.display());
            run(target, &std::fs::read(&p).unwrap());
        }
    }
}

#[test]
fn the_committed_seeds_are_the_built_ones() {
    let write = std::env::var_os("OOCFMT_WRITE_CORPUS").is_some();
    for (target, name, data) in seeds() {
        let path = fuzz_dir().join("corpus").join(target).join(name);
        if write {
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(&path, &data).unwrap();
        }
        let committed = std::fs::read(&path).unwrap_or_default();
        assert!(
            committed == data,
            "{} differs from its seed: rewrite the corpus (see this file's header)",
            path.display()
        );
    }
}
