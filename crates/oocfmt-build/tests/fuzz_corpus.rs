//! Replays the `subset_file` fuzz corpus on stable, through the very property the cargo-fuzz
//! target runs (`fuzz/src/subset.rs`, included by path): every file under
//! `fuzz/corpus/subset_file/` and `fuzz/regressions/subset_file/`, the seeds as this file
//! builds them, and a few damaged copies of them.
//!
//! `OOCFMT_WRITE_CORPUS=1 cargo test -p oocfmt-build --test fuzz_corpus` rewrites the seeds.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use oocfmt_build::convert::ConvertOptions;
use oocfmt_build::progress::NoProgress;
use oocfmt_build::subsets::{build_subset, make_plan};

#[path = "../../../fuzz/src/subset.rs"]
mod props;

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

/// The seeds: the one subset of a one-subset plan of a small mesh, with R-LODs and with
/// voxels, the mesh built in two chunks so the subset has a node of its own above them.
fn seeds() -> Vec<(String, Vec<u8>)> {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("strip.obj");
    let mut text = String::new();
    for k in 0..120 {
        let x = k as f32 * 0.25;
        text += &format!(
            "v {x} 0 0\nv {} 0 {}\nv {x} 1 0.5\n",
            x + 0.4,
            (k % 7) as f32 * 0.1
        );
    }
    for k in 0..120 {
        text += &format!("f {} {} {}\n", 3 * k + 1, 3 * k + 2, 3 * k + 3);
    }
    std::fs::write(&obj, text).unwrap();
    let mut out = Vec::new();
    for lod in [
        oocfmt::records::LodKinds::RLOD,
        oocfmt::records::LodKinds::VOXEL,
    ] {
        let mut opts = ConvertOptions {
            mem_limit: 70 * oocfmt_build::convert::BYTES_PER_TRIANGLE_IN_CORE,
            ..ConvertOptions::default()
        };
        opts.layout.write.lod = lod.filtered();
        let inputs = [obj.clone()];
        let (plan, _) = make_plan(&inputs, 1, Vec::new(), &opts, &mut NoProgress).unwrap();
        let part = dir.path().join("part.oocfp");
        build_subset(&plan, 0, &part, &opts, &mut NoProgress).unwrap();
        out.push((
            format!("one-subset-{}", lod.name()),
            std::fs::read(&part).unwrap(),
        ));
    }
    out
}

#[test]
fn the_seeds_and_the_committed_corpus_never_panic() {
    let seeds = seeds();
    let corpus = fuzz_dir().join("corpus/subset_file");
    if std::env::var_os("OOCFMT_WRITE_CORPUS").is_some() {
        std::fs::create_dir_all(&corpus).unwrap();
        for (name, bytes) in &seeds {
            std::fs::write(corpus.join(name), bytes).unwrap();
        }
    }
    for (_, bytes) in &seeds {
        props::subset_file(bytes);
        // Damaged copies: cut short, and a byte flipped every 97 bytes (re-sealed too).
        props::subset_file(&bytes[..bytes.len() / 2]);
        for at in (0..bytes.len()).step_by(97) {
            let mut bad = bytes.clone();
            bad[at] ^= 0x5a;
            props::subset_file(&bad);
        }
    }
    let mut replayed = 0;
    for dir in ["corpus/subset_file", "regressions/subset_file"] {
        for file in files(&fuzz_dir().join(dir)) {
            props::subset_file(&std::fs::read(&file).unwrap());
            replayed += 1;
        }
    }
    assert!(replayed >= seeds.len(), "the committed seeds are missing");
}
