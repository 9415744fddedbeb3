//! Render threads waiting on I/O, counted per frame (`FrameStats::waits`): never with the
//! asynchronous cache, from a cold start on, however many blocks its frames miss; every miss
//! with the blocking and mmap caches, so the counter is not dead. Reading past the page cache
//! (`Io::Direct`) renders what buffered reads do, and the figures say which mode was in effect.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;

use std::path::Path;
use std::sync::Arc;

use oocfmt::{Codec, Io, ReadOptions, Reader, WriteOptions};
use oocfmt_build::layout::LayoutOptions;
use oocfmt_trace::cache::asynchronous::AsyncOptions;
use oocfmt_trace::session::{self, Cache, CacheKind, Walkthrough};
use oocfmt_trace::{render, BlockingCache, Camera, MmapCache, RenderOptions, Scene};

const W: u32 = 48;
const H: u32 = 36;

const OPTS: RenderOptions = RenderOptions {
    poe: 1.0,
    ..RenderOptions::DEFAULT
};

/// A path that approaches the model, so that every frame wants blocks the last did not.
fn approach(scene: &Scene, frames: usize) -> Vec<Camera> {
    let m = scene.metadata();
    let (lo, hi) = (m.scene.bounds_min, m.scene.bounds_max);
    let framing = Camera::framing(lo, hi, W, H);
    let c = [0, 1, 2].map(|k| (f64::from(lo[k]) + f64::from(hi[k])) / 2.0);
    (0..frames)
        .map(|i| {
            let s = 1.0 - 0.7 * i as f64 / frames as f64;
            Camera {
                eye: [0, 1, 2].map(|k| c[k] + s * (framing.eye[k] - c[k])),
                ..framing
            }
        })
        .collect()
}

#[test]
fn async_frames_never_wait_on_io_from_a_cold_start() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 20_000);
    // A small budget and one fetcher: frames miss blocks all along the path.
    let opts = AsyncOptions {
        fetchers: 1,
        ..AsyncOptions::default()
    };
    let (scene, cache) = Cache::open(&path, None, CacheKind::Async, 4 << 20, &opts, None).unwrap();
    let mut walk = Walkthrough::new(&scene, &cache, OPTS, None).unwrap();
    let (mut missed, mut loaded) = (0, 0);
    for (i, cam) in approach(&scene, 12).iter().enumerate() {
        let f = walk.frame(cam).unwrap();
        assert_eq!(f.figures.waits, 0, "frame {i} waited on I/O");
        assert_eq!(f.stats.waits, 0);
        missed += f.figures.blocks_missed;
        loaded += f.figures.blocks_loaded;
    }
    assert!(
        missed > 0 && loaded > 0,
        "the walk was cold: {missed} missed, {loaded} loaded"
    );
    let stats = cache.get().stats();
    assert_eq!(stats.render_waits, 0);
    assert_eq!(stats.io, "buffered");
}

#[test]
fn blocking_frames_count_every_read_and_warm_ones_none() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 20_000);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    let cam = approach(&scene, 1)[0];
    let (_, cold) = render(&scene, &cache, &cam, &OPTS).unwrap();
    // Two threads missing on one block may both read it: at least one read per block loaded.
    assert!(cold.cache.blocks_loaded > 0);
    assert!(
        cold.waits >= cold.cache.blocks_loaded,
        "{} waits",
        cold.waits
    );
    assert_eq!(cold.cache.render_waits, cold.waits);
    let (_, warm) = render(&scene, &cache, &cam, &OPTS).unwrap();
    assert_eq!(warm.waits, 0, "a warm frame reads nothing");
}

#[test]
fn mmap_frames_count_their_reads() {
    let dir = tempfile::tempdir().unwrap();
    let layout = LayoutOptions {
        write: WriteOptions {
            codec: Codec::None,
            ..WriteOptions::default()
        },
        ..LayoutOptions::default()
    };
    let path = common::mandelbulb_with(dir.path(), 20_000, layout);
    let cache = MmapCache::open(&path, usize::MAX).unwrap();
    let scene = Arc::clone(cache.scene());
    let (_, cold) = render(&scene, &cache, &approach(&scene, 1)[0], &OPTS).unwrap();
    assert!(cold.waits > 0 && cold.waits >= cold.cache.blocks_loaded);
    assert_eq!(cold.cache.mode, "mmap");
}

/// The scene of `path` read as `io` asks.
fn scene_with(path: &Path, io: Io) -> Arc<Scene> {
    Arc::new(Scene::from_reader(
        Reader::open_with(path, ReadOptions::default(), io).unwrap(),
    ))
}

#[test]
fn reading_past_the_page_cache_renders_what_buffered_reads_do() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 20_000);
    let cam = approach(&Scene::open(&path).unwrap(), 1)[0];
    let image = |io| {
        let scene = scene_with(&path, io);
        let (img, stats) = render(
            &scene,
            &BlockingCache::new(Arc::clone(&scene), usize::MAX),
            &cam,
            &OPTS,
        )
        .unwrap();
        (img.rgb, stats.cache.io)
    };
    let (buffered, io) = image(Io::Buffered);
    assert_eq!(io, "buffered");
    let (direct, io) = image(Io::Direct);
    assert!(buffered == direct, "direct reads changed the image");
    // O_DIRECT where the temporary folder's file system takes it, else dropping pages.
    assert!(io == "direct" || io == "dontneed", "{io}");
    // The async cache over the direct reader settles to the same image.
    let scene = scene_with(&path, Io::Direct);
    let (_, cache) = Cache::open(
        &path,
        Some(Arc::clone(&scene)),
        CacheKind::Async,
        usize::MAX,
        &AsyncOptions::default(),
        None,
    )
    .unwrap();
    let settled = session::settle(&scene, &cache, &cam, &OPTS).unwrap();
    assert!(settled.complete);
    assert!(settled.frame.image.rgb == buffered);
    assert_eq!(settled.frame.stats.cache.io, io);
}
