//! `oocfmt-trace`: the reference CPU ray tracer over `.oocf` containers, with level of detail
//! after Áfra (2012). A [`Scene`] is an open container with its proxies resident; a
//! [`cache::BlockCache`] hands decoded blocks to the traversal; [`render::render`] makes one
//! frame.

#![forbid(unsafe_code)]

pub mod affinity;
pub mod blocks;
pub mod cache;
pub mod camera;
pub mod compare;
pub mod error;
pub mod intersect;
pub mod lanes;
pub mod light;
pub mod memo;
pub mod occlusion;
pub mod output;
pub mod packet;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod shade;
pub mod spawn;
pub mod traverse;
pub mod walk;

pub use cache::{AsyncCache, BlockCache, BlockingCache, CacheStats, MmapCache};
pub use camera::Camera;
pub use error::TraceError;
pub use render::{render, FrameStats, Image, RenderOptions};
pub use scene::Scene;
