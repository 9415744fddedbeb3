//! The format crate's integration tests, one binary: fault injection, fixtures and vectors,
//! the fuzz corpus on stable, parts, round trips, the spec's rules, the spec's constants.
//! `corruption.rs` stays a binary of its own: its counting allocator measures the whole process.

#[path = "../common/mod.rs"]
mod common;
mod faults;
mod fixtures;
mod fuzz_corpus;
mod parts;
mod roundtrip;
mod rules;
mod spec_constants;
