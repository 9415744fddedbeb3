//! Replays the fuzz corpora on stable, through the very property functions the cargo-fuzz
//! targets run (`fuzz/src/props.rs`, included by `tests/common`): every file under
//! `fuzz/corpus/<target>/` and, in its own test, `fuzz/regressions/<target>/`.
//!
//! `OOCFMT_WRITE_CORPUS=1 cargo test -p oocfmt --test format fuzz_corpus::write_seed_corpus` rewrites the
//! seed corpora from the fixtures and the spec vectors.

use crate::common;

use std::path::{Path, PathBuf};

use common::{all_files, open_bytes, props, NamedFile, TestResult};
use oocfmt::{BlockKind, Checksums, ReadOptions};

const TARGETS: [&str; 4] = [
    "open_verify",
    "block_decode",
    "treelet_decode",
    "triangle_decode",
];

fn fuzz_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fuzz"))
}

fn run_target(target: &str, data: &[u8]) -> TestResult {
    match target {
        "open_verify" => props::open_verify(data),
        "block_decode" => props::block_decode(data),
        "treelet_decode" => props::treelet_decode(data),
        "triangle_decode" => props::triangle_decode(data),
        // The tracer's target: `crates/oocfmt-trace/tests/trace/fuzz_corpus.rs` replays it.
        "render_file" => {}
        // The importers': `crates/oocfmt-meshio/tests/import/fuzz_corpus.rs` replays them.
        "stl_import" | "ply_import" => {}
        // The split build's: `crates/oocfmt-build/tests/fuzz_corpus.rs` replays it.
        "subset_file" => {}
        other => return Err(format!("unknown fuzz target directory {other}").into()),
    }
    Ok(())
}

/// Every file of `root/<target>/`, for every target directory present; `(target, path)`.
fn inputs(root: &Path) -> TestResult<Vec<(String, PathBuf)>> {
    let mut out = Vec::new();
    let Ok(dirs) = std::fs::read_dir(root) else {
        return Ok(out);
    };
    for d in dirs {
        let d = d?;
        if !d.file_type()?.is_dir() {
            continue;
        }
        let target = d.file_name().to_string_lossy().into_owned();
        for f in std::fs::read_dir(d.path())? {
            let f = f?;
            if f.file_type()?.is_file() && !f.file_name().to_string_lossy().starts_with('.') {
                out.push((target.clone(), f.path()));
            }
        }
    }
    out.sort();
    Ok(out)
}

fn replay(root: &Path) -> TestResult<usize> {
    let all = inputs(root)?;
    for (target, path) in &all {
        let data = std::fs::read(path)?;
        run_target(target, &data).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(all.len())
}

#[test]
fn corpus_replays_without_panic() -> TestResult {
    let n = replay(&fuzz_dir().join("corpus"))?;
    let present = inputs(&fuzz_dir().join("corpus"))?;
    for t in TARGETS {
        assert!(
            present.iter().any(|(x, _)| x == t),
            "fuzz/corpus/{t}/ has no seed"
        );
    }
    assert!(n >= TARGETS.len());
    Ok(())
}

#[test]
fn regressions_replay_without_panic() -> TestResult {
    replay(&fuzz_dir().join("regressions"))?;
    Ok(())
}

/// The seeds, built from the fixtures and vectors: whole files for `open_verify`; every block's
/// stored bytes behind its selector and raw length for `block_decode`; decoded treelet and
/// triangle blocks for the record targets.
fn seeds(files: &[NamedFile]) -> TestResult<Vec<(&'static str, String, Vec<u8>)>> {
    let mut out = Vec::new();
    let opts = ReadOptions {
        checksums: Checksums::Verify,
        ..ReadOptions::default()
    };
    for f in files {
        let stem = f.name.trim_end_matches(".oocf").to_string();
        out.push(("open_verify", format!("{stem}.oocf"), f.bytes.clone()));
        let r = open_bytes(&f.bytes, opts)?;
        for (id, e) in (0u32..).zip(r.entries()) {
            let b = r.read_block(id)?;
            let start = usize::try_from(e.offset)?;
            let stored = &f.bytes[start..start + e.stored_length as usize];
            let kind_bits: u8 = match e.kind {
                BlockKind::Treelet => 0,
                BlockKind::Triangle => 1,
                BlockKind::Proxy => 2,
            };
            let attrs = r.metadata().schema.triangle_attributes() as u8;
            let mut seed = vec![(e.codec as u8) | (kind_bits << 2) | (attrs << 4) | 0x80];
            seed.extend_from_slice(&e.raw_length.to_le_bytes()[..3]);
            seed.extend_from_slice(stored);
            out.push(("block_decode", format!("{stem}-b{id}"), seed));
            match e.kind {
                BlockKind::Treelet => out.push(("treelet_decode", format!("{stem}-b{id}"), b.data)),
                BlockKind::Triangle => {
                    out.push(("triangle_decode", format!("{stem}-b{id}"), b.data))
                }
                BlockKind::Proxy => {}
            }
        }
    }
    Ok(out)
}

#[test]
fn seeds_replay_without_panic() -> TestResult {
    for (target, name, data) in seeds(&all_files()?)? {
        run_target(target, &data).map_err(|e| format!("{target}/{name}: {e}"))?;
    }
    Ok(())
}

#[test]
fn write_seed_corpus() -> TestResult {
    if std::env::var_os("OOCFMT_WRITE_CORPUS").is_none() {
        return Ok(());
    }
    for (target, name, data) in seeds(&all_files()?)? {
        let dir = fuzz_dir().join("corpus").join(target);
        std::fs::create_dir_all(&dir)?;
        std::fs::write(dir.join(name), data)?;
    }
    // Hand-made regression: a directory entry at offset u64::MAX (re-sealed) used to overflow
    // `BlockEntry::end()` in `check_placement`.
    let mut b = common::fixture("fx-quad-none")?;
    let (dir, _) = common::directory_of(&b);
    common::put_u64(&mut b, dir + oocfmt::directory::OFF_OFFSET, u64::MAX);
    let b = common::reseal(&b)?;
    let out = fuzz_dir().join("regressions").join("open_verify");
    std::fs::create_dir_all(&out)?;
    std::fs::write(out.join("entry-offset-u64-max-overflows"), b)?;
    Ok(())
}
