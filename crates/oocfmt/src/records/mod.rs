//! The hot records: fixed little-endian layouts, encoded and decoded by hand (spec §5–§8).
//! Each file holds one record family with its bit layout in one place.

pub mod node;
pub mod proxy;
pub mod rlod;
pub mod sample;
pub mod treelet;
pub mod triangle;

pub use node::{
    lod_child_treelets, Node, MAX_CHILD_TREELET, MAX_CHILD_UNITS, MAX_LEAF_TRIANGLES,
    MAX_TREE_DEPTH, NODE_BASIC_LEN, NODE_LEAF_LEN, NODE_LOD_LEN, NO_PROXY,
};
pub use proxy::{ProxyRecord, PROXY_DIRECTIONS, PROXY_LEN};
pub use rlod::{LodKinds, Rlod, RLOD_LEN};
pub use sample::{Footprint, Sample, Voxel};
pub use treelet::{LodEntry, TreeletBlock, TreeletBlockWriter, TreeletSummary, PART_WORD_LEN};
pub use triangle::{part_id_width, Triangle, TriangleBlock, TriangleBlockWriter, Vertex};
