//! The fuzz properties, one function per target. `crates/oocfmt/tests/fuzz_corpus.rs` includes
//! `props.rs` by path so `cargo test` replays the corpora through these very functions on stable.

pub mod props;
