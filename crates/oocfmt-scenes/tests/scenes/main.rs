//! The generators' and exporters' round trips, and the committed spec vectors, one binary.

mod gen_export;
mod vectors;
