//! Live views: a camera in, progressively better frames out, for an interactive viewer
//! (`oocfmt view`). The viewer's server only carries cameras and frames; everything about what
//! to render lives here.
//!
//! - [`schedule`]: the refine schedule, pure bookkeeping: while the camera moves, the
//!   resolution and PoE that hold the target frame time; once still, full resolution, then the
//!   PoE asked for until every block has arrived, then accumulated samples.
//! - [`accumulate`]: passes through `render --spp`'s sample points, averaged in linear RGB.
//! - [`view`]: one view ([`LiveView`]): its camera, schedule and accumulated image, rendered
//!   through a session cache ([`crate::session::Cache`]); frames come with [`LiveFigures`].
//! - [`viewer`]: the render thread serving many views of one scene and cache ([`Viewer`]);
//!   the newest camera of a view wins, and a sink receives each frame.
//!
//! ```
//! use std::sync::Arc;
//! use std::time::Instant;
//! use oocfmt_trace::cache::asynchronous::AsyncOptions;
//! use oocfmt_trace::live::{LiveOptions, LiveView, LoadRate, Next, Quality};
//! use oocfmt_trace::session::{Cache, CacheKind};
//! use oocfmt_trace::{Camera, RenderOptions};
//!
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec/vectors/lod-lz4.oocf");
//! let (scene, cache) = Cache::open(
//!     std::path::Path::new(path), None, CacheKind::Async, 16 << 20, &AsyncOptions::default(), None,
//! )?;
//! let opts = LiveOptions { still_ms: 0.0, ..LiveOptions::DEFAULT };
//! let mut view = LiveView::new(opts, RenderOptions::DEFAULT, Quality { poe: 0.0, spp: 2 })?;
//! let s = scene.metadata().scene;
//! view.set_camera(Camera::framing(s.bounds_min, s.bounds_max, 64, 48), 1, Instant::now())?;
//! let mut rate = LoadRate::new();
//! let mut last = None;
//! loop {
//!     match view.next(Instant::now()) {
//!         Next::Render(plan) => last = Some(view.render(plan, &scene, &cache, &mut rate)?),
//!         Next::Sleep(until) => std::thread::sleep(until.saturating_duration_since(Instant::now())),
//!         Next::Idle => break,
//!     }
//! }
//! let last = last.ok_or("no frame")?;
//! assert!(last.figures.last && last.figures.samples == 2);
//! assert_eq!((last.image.width, last.image.height), (64, 48));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod accumulate;
pub mod schedule;
pub mod view;
pub mod viewer;

#[cfg(test)]
mod tests;

pub use schedule::{LiveOptions, Next, Plan, Quality, Stage};
pub use view::{LiveFigures, LiveFrame, LiveView, LoadRate};
pub use viewer::{Event, Picked, Sink, ViewId, Viewer};
