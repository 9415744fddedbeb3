//! The fuzz properties, one function per target. `crates/oocfmt/tests/format/fuzz_corpus.rs` includes
//! `props.rs` by path so `cargo test` replays the corpora through these very functions on stable;
//! `crates/oocfmt-trace/tests/trace/fuzz_corpus.rs` does the same with `render.rs`, and
//! `crates/oocfmt-meshio/tests/import/fuzz_corpus.rs` with `import.rs`,
//! `crates/oocfmt-build/tests/fuzz_corpus.rs` with `subset.rs`.

pub mod import;
pub mod props;
pub mod render;
pub mod subset;
