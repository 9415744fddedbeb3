//! The tracer's integration tests, one binary (one link instead of nine): caches, kernels against
//! an f64 reference, hard cases, packets against single rays, references, secondary rays,
//! walkthrough sessions, render threads waiting on I/O, malformed files, and the fuzz corpus
//! replayed on stable.

mod caches;
mod common;
mod fuzz_corpus;
mod hard_cases;
mod kernels;
mod malformed;
mod measure;
mod packets;
mod parts;
mod prefiltered;
mod reference;
mod secondary;
mod section;
mod session;
mod waits;
