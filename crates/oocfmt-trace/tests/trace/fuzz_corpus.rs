//! Replays fuzz inputs through the `render_file` property on stable, the very function the
//! cargo-fuzz target runs (`fuzz/src/render.rs`, included by path): the whole-file seeds of
//! `fuzz/corpus/open_verify/` and every input under `fuzz/regressions/open_verify/` and
//! `fuzz/regressions/render_file/`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

#[allow(dead_code)]
#[path = "../../../../fuzz/src/props.rs"]
mod props;
#[path = "../../../../fuzz/src/render.rs"]
mod render;

fn fuzz_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fuzz"))
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

fn replay(paths: &[PathBuf]) {
    for p in paths {
        eprintln!("{}", p.display());
        render::render_file(&std::fs::read(p).unwrap());
    }
}

#[test]
fn whole_file_seeds_render_without_panic() {
    let seeds = files(&fuzz_dir().join("corpus/open_verify"));
    assert!(seeds.len() >= 4, "{seeds:?}");
    replay(&seeds);
}

#[test]
fn regressions_render_without_panic() {
    for target in ["open_verify", "render_file"] {
        replay(&files(&fuzz_dir().join("regressions").join(target)));
    }
}
