//! `oocfmt-build`: turns a triangle mesh into an `.oocf` container.
//!
//! The stages are independent so each can be replaced on its own: [`mesh`] holds the input,
//! [`kdtree`] builds the tree, [`lod`] estimates voxels and proxies, and [`layout`] cuts the
//! tree into treelets, packs blocks and writes the file. [`gen`] makes demo scenes and
//! [`vectors`] the spec's test vectors.

pub mod convert;
pub mod export;
pub mod gen;
pub mod import;
pub mod kdtree;
pub mod layout;
pub mod lod;
pub mod mesh;
pub mod ooc;
pub mod progress;
pub mod raycast;
pub mod report;
pub mod vectors;
