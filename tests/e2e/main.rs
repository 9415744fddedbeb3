//! End-to-end tests of the `oocfmt` binary, one test binary: exit codes and outputs (`cli`),
//! docs/cli.md against `--help` (`cli_docs`), `curve`, golden build statistics, `--recentre`,
//! `render`, R-LODs, STL and PLY (`formats`), parts and `view`; models through a pipe
//! (`stdin`), interrupted conversions (`interrupt`) and split builds (`subsets`).

mod cli;
mod cli_docs;
mod common;
mod curve;
mod formats;
mod golden_stats;
mod interrupt;
mod parts;
mod parts_render;
mod recentre;
mod render;
mod rlod;
mod section;
mod stdin;
mod subsets;
mod view;
