//! The fuzz properties, one function per target. `crates/oocfmt/tests/fuzz_corpus.rs` includes
//! `props.rs` by path so `cargo test` replays the corpora through these very functions on stable;
//! `crates/oocfmt-trace/tests/fuzz_corpus.rs` does the same with `render.rs`.

pub mod props;
pub mod render;
