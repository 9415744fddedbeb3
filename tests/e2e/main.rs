//! End-to-end tests of the `oocfmt` binary, one test binary: exit codes and outputs (`cli`),
//! docs/cli.md against `--help` (`cli_docs`), `curve`, golden build statistics, `--recentre`,
//! `render` and R-LODs.

mod cli;
mod cli_docs;
mod common;
mod curve;
mod golden_stats;
mod recentre;
mod render;
mod rlod;
