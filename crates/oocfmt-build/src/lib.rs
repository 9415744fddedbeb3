//! `oocfmt-build`: turns triangles into an `.oocf` container.
//!
//! [`convert()`] is the whole job (import, build in core or out of core, write) with a
//! [`report::ConvertReport`]. Its stages are independent so each can be replaced on its own:
//! [`kdtree`] builds the tree, [`lod`] estimates voxels, proxies and R-LODs, [`layout`] cuts the
//! tree into treelets, packs blocks and writes the file, and [`ooc`] builds a scene larger than
//! memory in chunks. The meshes come from `oocfmt-meshio`.
//!
//! ```
//! use oocfmt_build::kdtree::{self, KdBuildOptions};
//! use oocfmt_build::layout::{write_container, LayoutOptions};
//! use oocfmt_meshio::Mesh;
//!
//! let mesh = Mesh::new(
//!     vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]],
//!     vec![[0, 1, 2], [1, 3, 2]],
//! );
//! let tree = kdtree::build(&mesh, &KdBuildOptions::default())?;
//! let dir = tempfile::tempdir()?;
//! let out = dir.path().join("quad.oocf");
//! write_container(&out, &mesh, &tree, &LayoutOptions::default())?;
//! assert!(oocfmt::Reader::open(&out, oocfmt::ReadOptions::default()).is_ok());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod convert;
pub mod interrupt;
pub mod kdtree;
pub mod layout;
pub mod lod;
pub mod ooc;
pub mod progress;
pub mod raycast;
pub mod report;
mod spill_dir;
pub mod subsets;
#[cfg(test)]
mod test_mesh;

pub use convert::{convert, ConvertError, ConvertOptions};
pub use interrupt::Interrupt;
pub use report::ConvertReport;
