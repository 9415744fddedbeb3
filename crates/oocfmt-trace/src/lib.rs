//! `oocfmt-trace`: the reference CPU ray tracer over `.oocf` containers, with level of detail
//! after Áfra (2012). A [`Scene`] is an open container with its proxies resident; a
//! [`cache::BlockCache`] hands decoded blocks to the traversal; [`render::render`] makes one
//! frame.
//!
//! ```
//! use std::sync::Arc;
//! use oocfmt_trace::{render, BlockingCache, Camera, RenderOptions, Scene};
//!
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec/vectors/lod-lz4.oocf");
//! let scene = Arc::new(Scene::open(std::path::Path::new(path))?);
//! let cache = BlockingCache::new(Arc::clone(&scene), 16 << 20);
//! let s = scene.metadata().scene;
//! let camera = Camera::framing(s.bounds_min, s.bounds_max, 64, 48);
//! let (image, stats) = render(&scene, &cache, &camera, &RenderOptions::default())?;
//! assert_eq!(image.rgb.len(), 64 * 48 * 3);
//! assert!(image.depth.iter().any(|d| d.is_finite()), "the model is in view");
//! assert!(stats.rays >= 64 * 48);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod affinity;
pub mod blocks;
pub mod cache;
pub mod camera;
pub mod compare;
pub mod composite;
pub mod error;
pub mod intersect;
mod lanes;
pub mod light;
pub mod live;
mod memo;
pub mod occlusion;
pub mod output;
mod packet;
pub mod parts;
pub mod pick;
pub mod reach;
pub mod render;
pub mod rough;
pub mod sampling;
pub mod scene;
pub mod section;
pub mod session;
pub mod shade;
pub mod spawn;
pub mod traverse;
pub mod walk;

pub use cache::{AsyncCache, BlockCache, BlockingCache, CacheStats, MmapCache};
pub use camera::Camera;
pub use error::TraceError;
pub use render::{render, FrameStats, Image, RenderOptions};
pub use scene::Scene;
pub use section::Section;
pub use session::Walkthrough;
