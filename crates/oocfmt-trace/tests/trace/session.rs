//! The render session (`oocfmt_trace::session`), the loop `oocfmt render` and a viewer drive:
//! a walkthrough's frames are the images `render` makes for the same cameras, its per-frame
//! figures add up to the cache's totals, a revisited view loads nothing, a missing block is
//! reported once, look-ahead prefetching needs the async cache, and a still view settles with
//! the async cache to the blocking cache's image.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;

use std::path::Path;
use std::sync::Arc;

use oocfmt::BlockKind;
use oocfmt_trace::cache::asynchronous::AsyncOptions;
use oocfmt_trace::session::{self, Cache, CacheKind, Walkthrough};
use oocfmt_trace::{render, BlockingCache, Camera, RenderOptions, Scene, TraceError};

const W: u32 = 48;
const H: u32 = 36;

/// A path around the model: a framing view, two closer ones, and the framing view again.
fn cameras(scene: &Scene) -> Vec<Camera> {
    let m = scene.metadata();
    let (lo, hi) = (m.scene.bounds_min, m.scene.bounds_max);
    let framing = Camera::framing(lo, hi, W, H);
    let c = [0, 1, 2].map(|k| (f64::from(lo[k]) + f64::from(hi[k])) / 2.0);
    let ext = (0..3).map(|k| f64::from(hi[k] - lo[k])).fold(0.0, f64::max);
    let close = |dx: f64| Camera {
        eye: [c[0] + dx * ext, c[1], c[2] - 0.8 * ext],
        look_at: c,
        ..framing
    };
    vec![framing, close(-0.3), close(0.3), framing]
}

const OPTS: RenderOptions = RenderOptions {
    poe: 1.0,
    ..RenderOptions::DEFAULT
};

fn open(path: &Path, kind: CacheKind, opts: &AsyncOptions) -> (Arc<Scene>, Cache) {
    Cache::open(path, None, kind, 256 << 20, opts, None).unwrap()
}

#[test]
fn a_blocking_walkthrough_renders_what_render_does_and_its_figures_add_up() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 6_000);
    let (scene, cache) = open(&path, CacheKind::Blocking, &AsyncOptions::default());
    assert_eq!(cache.kind(), CacheKind::Blocking);
    let cams = cameras(&scene);
    let mut walk = Walkthrough::new(&scene, &cache, OPTS, None).unwrap();
    assert!(!walk.prefetching());
    let reference = BlockingCache::new(Arc::clone(&scene), 256 << 20);
    let mut loaded = 0;
    let mut figures = Vec::new();
    for (i, cam) in cams.iter().enumerate() {
        let f = walk.frame(cam).unwrap();
        assert_eq!(f.index, i);
        let (expected, _) = render(&scene, &reference, cam, &OPTS).unwrap();
        assert_eq!(f.image.rgb, expected.rgb, "frame {i}");
        assert_eq!(f.image.depth, expected.depth, "frame {i}");
        assert_eq!(f.figures.ms, f.stats.ms);
        assert_eq!(f.figures.primary, f.stats.primary);
        assert!((0.0..=1.0).contains(&f.figures.hit_rate), "{:?}", f.figures);
        assert!(f.new_missing.is_empty());
        loaded += f.figures.blocks_loaded;
        figures.push(f.figures);
    }
    let total = cache.get().stats();
    assert_eq!(loaded, total.blocks_loaded, "{total:?}");
    assert!(figures[0].blocks_loaded > 0, "{:?}", figures[0]);
    // The last frame revisits the first view with everything still resident.
    let last = figures.last().unwrap();
    assert_eq!(last.blocks_loaded, 0, "{last:?}");
    assert_eq!(last.hit_rate, 1.0, "{last:?}");
}

#[test]
fn a_missing_block_is_reported_by_the_frame_that_finds_it_and_only_then() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 5_000);
    let e = {
        let scene = Scene::open(&path).unwrap();
        *scene
            .reader()
            .entries()
            .iter()
            .find(|e| e.kind == BlockKind::Triangle)
            .unwrap()
    };
    let mut bytes = std::fs::read(&path).unwrap();
    let at = (e.offset + u64::from(e.stored_length) / 2) as usize;
    bytes[at] ^= 0x40;
    std::fs::write(&path, &bytes).unwrap();
    let (scene, cache) = open(&path, CacheKind::Blocking, &AsyncOptions::default());
    let m = scene.metadata();
    let cam = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, W, H);
    let mut walk = Walkthrough::new(&scene, &cache, OPTS, None).unwrap();
    let reports: Vec<usize> = (0..3)
        .map(|_| walk.frame(&cam).unwrap().new_missing.len())
        .collect();
    assert_eq!(
        reports,
        [1, 0, 0],
        "{:?}",
        cache.get().stats().missing_blocks
    );
}

#[test]
fn prefetching_needs_the_async_cache_and_its_figures_add_up() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 6_000);
    let (scene, blocking) = open(&path, CacheKind::Blocking, &AsyncOptions::default());
    let refused = Walkthrough::new(&scene, &blocking, OPTS, Some(2));
    assert!(matches!(refused, Err(TraceError::Options(_))));
    let opts = AsyncOptions {
        prefetch_bytes: 64 << 20,
        ..AsyncOptions::default()
    };
    let (scene, cache) = open(&path, CacheKind::Async, &opts);
    assert!(cache.as_async().is_some());
    // What the cache loaded before the first frame (the root treelets) is no frame's.
    let start = cache.get().stats();
    let mut walk = Walkthrough::new(&scene, &cache, OPTS, Some(2)).unwrap();
    assert!(walk.prefetching());
    let (mut prefetched, mut loaded, mut fetch_ms) = (0, 0, 0.0);
    let mut last = None;
    for cam in cameras(&scene) {
        let f = walk.frame(&cam).unwrap();
        assert!(f.figures.prefetch_ms >= 0.0 && f.figures.fetch_cpu_ms >= 0.0);
        prefetched += f.figures.blocks_prefetched;
        loaded += f.figures.blocks_loaded;
        fetch_ms += f.figures.fetch_cpu_ms;
        last = Some(f.stats.cache);
    }
    // The fetchers go on after the last step: the figures add up to the cache's as of then.
    let total = last.unwrap();
    assert_eq!(
        prefetched,
        total.blocks_prefetched - start.blocks_prefetched,
        "{total:?}"
    );
    assert_eq!(
        loaded,
        total.blocks_loaded - start.blocks_loaded,
        "{total:?}"
    );
    assert!(loaded > 0, "{total:?}");
    assert!(
        (fetch_ms - (total.fetch_cpu_ms - start.fetch_cpu_ms)).abs() < 1e-6,
        "{total:?}"
    );
}

#[test]
fn a_still_view_settles_with_the_async_cache_to_the_blocking_image() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 6_000);
    let (scene, cache) = open(&path, CacheKind::Async, &AsyncOptions::default());
    let cams = cameras(&scene);
    // The generated model has its origin at zero: stored and world coordinates agree.
    assert_eq!(scene.metadata().scene.origin, [0.0; 3]);
    assert_eq!(session::stored_cameras(&scene, cams.clone()), cams);
    let reference = BlockingCache::new(Arc::clone(&scene), 256 << 20);
    for cam in &cams[..2] {
        let settled = session::settle(&scene, &cache, cam, &OPTS).unwrap();
        assert!(settled.complete);
        assert_eq!(settled.frame.stats.cache.blocks_wanted_last_frame, 0);
        let (expected, _) = render(&scene, &reference, cam, &OPTS).unwrap();
        assert_eq!(settled.frame.image.rgb, expected.rgb);
    }
    // A budget of one block cannot hold the view: the settling gives up once 16 frames in a
    // row miss no fewer blocks than the best, instead of reading the file for 1000 frames.
    let (scene, tiny) = Cache::open(
        &path,
        None,
        CacheKind::Async,
        64 << 10,
        &AsyncOptions::default(),
        None,
    )
    .unwrap();
    let settled = session::settle(&scene, &tiny, &cams[0], &OPTS).unwrap();
    assert!(!settled.complete);
    assert!(
        settled.frames <= 1 + 4 * session::SETTLE_PATIENCE,
        "{}",
        settled.frames
    );
    // A cache that loads on demand settles in one frame.
    let (scene, blocking) = open(&path, CacheKind::Blocking, &AsyncOptions::default());
    let settled = session::settle(&scene, &blocking, &cams[0], &OPTS).unwrap();
    assert_eq!((settled.frames, settled.complete), (1, true));
}
