//! The three caches against each other: at --poe 0, once the asynchronous cache has loaded
//! what a view wants, blocking, mmap and async give the same image; the asynchronous cache
//! stays within its budget under many render threads and many frames with every fetch order,
//! eviction policy and with look-ahead prefetching; prefetching never changes the converged
//! image; a corrupted block is survived and reported; a cold walkthrough starts coarse and
//! converges; decoded blocks hold no spare capacity the budget would count, and the proxies
//! are held once.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use oocfmt::records::{LodKinds, Node, TreeletBlock, Voxel, NO_PROXY};
use oocfmt::{BlockKind, Codec, WriteOptions};
use oocfmt_build::layout::LayoutOptions;
use oocfmt_trace::blocks::{LodKind, NodeView, Shown, NONE};
use oocfmt_trace::cache::asynchronous::AsyncOptions;
use oocfmt_trace::cache::prefetch::LookAhead;
use oocfmt_trace::cache::{Eviction, FetchOrder};
use oocfmt_trace::render::{FrameStats, Image};
use oocfmt_trace::traverse::{Memo, Surface, Tracer};
use oocfmt_trace::{
    render, AsyncCache, BlockCache, BlockingCache, Camera, MmapCache, RenderOptions, Scene,
};

const W: u32 = 64;
const H: u32 = 48;

/// A Mandelbulb container with uncompressed blocks (what the mmap cache wants) of the smallest
/// size (many blocks).
fn uncompressed_mandelbulb(dir: &Path, triangles: u64) -> PathBuf {
    let layout = LayoutOptions {
        write: WriteOptions {
            codec: Codec::None,
            ..WriteOptions::default()
        }
        .with_block_size(4096)
        .unwrap(),
        ..LayoutOptions::default()
    };
    common::mandelbulb_with(dir, triangles, layout)
}

fn views(scene: &Scene) -> Vec<Camera> {
    let m = scene.metadata();
    let (lo, hi) = (m.scene.bounds_min, m.scene.bounds_max);
    let framing = Camera::framing(lo, hi, W, H);
    let c = [0, 1, 2].map(|k| (f64::from(lo[k]) + f64::from(hi[k])) / 2.0);
    let ext = (0..3).map(|k| f64::from(hi[k] - lo[k])).fold(0.0, f64::max);
    // Close to one side: a different and smaller set of blocks.
    let close = Camera {
        eye: [c[0] - 0.75 * ext, c[1], c[2]],
        look_at: [c[0], c[1] + 0.1 * ext, c[2] + 0.1 * ext],
        up: [0.0, 1.0, 0.0],
        fov_y: 40.0,
        width: W,
        height: H,
    };
    vec![framing, close]
}

const POE0: RenderOptions = RenderOptions::DEFAULT;

/// Renders with the asynchronous cache until a frame finds every block it wants (the
/// fetchers finish between frames); returns that frame and how many frames it took.
fn converge(scene: &Scene, cache: &AsyncCache, cam: &Camera) -> (Image, FrameStats, usize) {
    for n in 1..=200 {
        let (img, stats) = render(scene, cache, cam, &POE0).unwrap();
        cache.end_frame();
        if cache.stats().blocks_wanted_last_frame == 0 {
            return (img, stats, n);
        }
        cache.wait_for_fetchers();
        cache.end_frame();
    }
    panic!(
        "the async cache did not converge in 200 frames: {:?}",
        cache.stats()
    );
}

#[test]
fn blocking_mmap_and_async_give_the_same_image_at_poe_0() {
    let dir = tempfile::tempdir().unwrap();
    let path = uncompressed_mandelbulb(dir.path(), 5_000);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let mmap = MmapCache::open(&path, 256 << 20).unwrap();
    for cam in views(&scene) {
        let blocking = BlockingCache::new(Arc::clone(&scene), 256 << 20);
        let (a, _) = render(&scene, &blocking, &cam, &POE0).unwrap();
        let (b, sb) = render(mmap.scene(), &mmap, &cam, &POE0).unwrap();
        assert_eq!(sb.cache.mode, "mmap");
        let cache = AsyncCache::new(Arc::clone(&scene), 256 << 20, 2);
        let (c, sc, frames) = converge(&scene, &cache, &cam);
        assert!(frames > 1, "a cold async cache needs more than one frame");
        // The fetchers decoded the blocks of the frames after the first, on their own CPU.
        assert!(cache.stats().fetch_cpu_ms > 0.0, "{:?}", cache.stats());
        assert_eq!(sc.primary.voxel + sc.primary.proxy, 0, "{:?}", sc.primary);
        assert!(a.depth.iter().any(|d| d.is_finite()));
        assert_eq!(a.rgb, b.rgb, "mmap differs from blocking");
        assert_eq!(a.depth, b.depth);
        assert_eq!(a.rgb, c.rgb, "async differs from blocking");
        assert_eq!(a.depth, c.depth);
    }
}

#[test]
fn mmap_refuses_a_compressed_container() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 2_000);
    let e = MmapCache::open(&path, 1 << 20).err().unwrap().to_string();
    assert!(e.contains("--codec none"), "{e}");
}

#[test]
fn async_stays_within_a_tiny_budget_under_many_threads() {
    let dir = tempfile::tempdir().unwrap();
    let path = uncompressed_mandelbulb(dir.path(), 8_000);
    let scene = Arc::new(Scene::open(&path).unwrap());
    // Close views from opposite sides: different blocks.
    let m = scene.metadata();
    let (lo, hi) = (m.scene.bounds_min, m.scene.bounds_max);
    let c = [0, 1, 2].map(|k| (f64::from(lo[k]) + f64::from(hi[k])) / 2.0);
    let ext = (0..3).map(|k| f64::from(hi[k] - lo[k])).fold(0.0, f64::max);
    let cams: Vec<Camera> = [-0.8, 0.8]
        .map(|side| Camera {
            eye: [c[0] + side * ext, c[1], c[2]],
            look_at: c,
            up: [0.0, 1.0, 0.0],
            fov_y: 30.0,
            width: W,
            height: H,
        })
        .to_vec();
    // The working set of each view, from a blocking cache that keeps everything.
    let mut references = Vec::new();
    let mut sets = Vec::new();
    for cam in &cams {
        let big = BlockingCache::new(Arc::clone(&scene), 256 << 20);
        let (img, st) = render(&scene, &big, cam, &POE0).unwrap();
        references.push(img);
        sets.push(st.cache.bytes_resident as usize);
    }
    let budget = sets.iter().copied().max().unwrap() * 11 / 10;
    let both = BlockingCache::new(Arc::clone(&scene), 256 << 20);
    for cam in &cams {
        render(&scene, &both, cam, &POE0).unwrap();
    }
    let union = both.stats().bytes_resident as usize;
    assert!(
        budget < union,
        "the views' blocks ({union} bytes) fit {budget}"
    );
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(8)
        .build()
        .unwrap();
    for eviction in [Eviction::Lru, Eviction::SecondChance] {
        for fetch_order in [FetchOrder::Afra, FetchOrder::Wald] {
            for prefetch in [false, true] {
                let opts = AsyncOptions {
                    fetchers: 3,
                    fetch_order,
                    eviction,
                    prefetch_bytes: if prefetch { budget as u64 / 4 } else { 0 },
                    ..AsyncOptions::default()
                };
                let what = format!("{eviction}, {fetch_order}, prefetch {prefetch}");
                let cache = AsyncCache::with_options(Arc::clone(&scene), budget, &opts);
                let mut look_ahead = LookAhead::new(2, 16);
                pool.install(|| {
                    // Switching views every few frames, without waiting for the fetchers:
                    // blocks of the other view must be evicted to make room.
                    for f in 0..40 {
                        let cam = &cams[(f / 4) % cams.len()];
                        let (img, _) = render(&scene, &cache, cam, &POE0).unwrap();
                        assert_eq!(img.rgb.len(), (3 * W * H) as usize);
                        cache.end_frame();
                        if prefetch {
                            look_ahead.after_frame(&scene, &cache, cam, 0.0);
                        }
                        let s = cache.stats();
                        assert!(
                            s.bytes_resident <= budget as u64
                                && s.peak_bytes_resident <= budget as u64,
                            "{what}, frame {f}: {s:?} over the budget {budget}"
                        );
                    }
                    for (cam, reference) in cams.iter().zip(&references) {
                        let (img, _, _) = converge(&scene, &cache, cam);
                        assert_eq!(img.rgb, reference.rgb, "{what}");
                        assert_eq!(img.depth, reference.depth, "{what}");
                    }
                });
                let s = cache.stats();
                assert!(s.blocks_evicted > 0, "{what}: {s:?}");
                assert!(s.peak_bytes_resident <= budget as u64, "{what}: {s:?}");
                assert!(s.missing_blocks.is_empty(), "{what}: {s:?}");
                assert_eq!(
                    (s.fetch_order, s.eviction),
                    (fetch_order.name(), eviction.name())
                );
            }
        }
    }
}

#[test]
fn a_corrupted_block_in_async_mode_is_reported_and_the_frame_completes() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 5_000);
    let scene = Scene::open(&path).unwrap();
    let (id, e) = (0u32..)
        .zip(scene.reader().entries())
        .find(|(_, e)| e.kind == BlockKind::Triangle)
        .map(|(id, e)| (id, *e))
        .unwrap();
    drop(scene);
    let mut bytes = std::fs::read(&path).unwrap();
    let at = (e.offset + u64::from(e.stored_length) / 2) as usize;
    bytes[at] ^= 0x40;
    std::fs::write(&path, &bytes).unwrap();
    let scene = Arc::new(Scene::open(&path).unwrap());
    let cache = AsyncCache::new(Arc::clone(&scene), 64 << 20, 2);
    let m = scene.metadata();
    let cam = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, W, H);
    let (img, stats, _) = converge(&scene, &cache, &cam);
    let s = cache.stats();
    let missing: Vec<u32> = s.missing_blocks.iter().map(|b| b.id).collect();
    assert_eq!(missing, vec![id], "{:?}", s.missing_blocks);
    assert!(
        s.missing_blocks[0]
            .error
            .to_lowercase()
            .contains("checksum"),
        "{:?}",
        s.missing_blocks
    );
    assert_eq!(img.rgb.len(), (3 * W * H) as usize);
    assert!(stats.primary.triangle > 0);
}

#[test]
fn a_cold_walkthrough_starts_coarse_and_converges_to_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 8_000);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let cams = views(&scene);
    // A path from the framing view to the close one, in 6 steps.
    let path_cams: Vec<Camera> = (0..6)
        .map(|i| {
            let u = f64::from(i) / 5.0;
            let mix = |p: [f64; 3], q: [f64; 3]| [0, 1, 2].map(|k| p[k] + (q[k] - p[k]) * u);
            Camera {
                eye: mix(cams[0].eye, cams[1].eye),
                look_at: mix(cams[0].look_at, cams[1].look_at),
                fov_y: cams[0].fov_y + (cams[1].fov_y - cams[0].fov_y) * u,
                ..cams[0]
            }
        })
        .collect();
    let cache = AsyncCache::new(Arc::clone(&scene), 64 << 20, 2);
    let mut first = None;
    for cam in &path_cams {
        let (_, stats) = render(&scene, &cache, cam, &POE0).unwrap();
        cache.end_frame();
        first.get_or_insert(stats);
    }
    let first = first.unwrap();
    assert!(
        first.primary.voxel + first.primary.proxy > 0,
        "a cold first frame shows coarse levels: {:?}",
        first.primary
    );
    assert_eq!(first.primary.triangle, 0, "{:?}", first.primary);
    let last = path_cams.last().unwrap();
    let (img, stats, _) = converge(&scene, &cache, last);
    let blocking = BlockingCache::new(Arc::clone(&scene), 64 << 20);
    let (reference, _) = render(&scene, &blocking, last, &POE0).unwrap();
    assert_eq!(stats.primary.voxel + stats.primary.proxy, 0);
    assert_eq!(img.rgb, reference.rgb);
    assert_eq!(img.depth, reference.depth);
}

/// A cold walkthrough at --poe 0 along `cams`, then frames on the last camera until it
/// converges: the converged image, and the blocks prefetched on the way.
fn walk_and_converge(
    scene: &Arc<Scene>,
    cams: &[Camera],
    opts: &AsyncOptions,
    budget: usize,
) -> (Image, u64) {
    let cache = AsyncCache::with_options(Arc::clone(scene), budget, opts);
    let mut look_ahead = LookAhead::new(2, 24);
    for cam in cams {
        render(scene, &cache, cam, &POE0).unwrap();
        cache.end_frame();
        if opts.prefetch_bytes > 0 {
            look_ahead.after_frame(scene, &cache, cam, 0.0);
        }
    }
    let (img, stats, _) = converge(scene, &cache, cams.last().unwrap());
    assert_eq!(stats.primary.voxel + stats.primary.proxy, 0);
    (img, cache.stats().blocks_prefetched)
}

#[test]
fn prefetching_never_changes_the_converged_image() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 20_000);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let cams = views(&scene);
    // A steady approach and turn from the framing view to the close one: what the look-ahead
    // predicts well.
    let path_cams: Vec<Camera> = (0..10)
        .map(|i| {
            let u = f64::from(i) / 9.0;
            let mix = |p: [f64; 3], q: [f64; 3]| [0, 1, 2].map(|k| p[k] + (q[k] - p[k]) * u);
            Camera {
                eye: mix(cams[0].eye, cams[1].eye),
                look_at: mix(cams[0].look_at, cams[1].look_at),
                ..cams[1]
            }
        })
        .collect();
    let blocking = BlockingCache::new(Arc::clone(&scene), 256 << 20);
    let (reference, _) = render(&scene, &blocking, path_cams.last().unwrap(), &POE0).unwrap();
    // A budget that holds everything, and one that makes both walks evict.
    let everything = blocking.stats().bytes_resident as usize * 8;
    for budget in [everything, blocking.stats().bytes_resident as usize * 3 / 2] {
        let (without, none) =
            walk_and_converge(&scene, &path_cams, &AsyncOptions::default(), budget);
        assert_eq!(none, 0);
        for eviction in [Eviction::Lru, Eviction::SecondChance] {
            let opts = AsyncOptions {
                eviction,
                prefetch_bytes: 1 << 20,
                ..AsyncOptions::default()
            };
            let (with, prefetched) = walk_and_converge(&scene, &path_cams, &opts, budget);
            assert!(
                prefetched > 0,
                "{eviction}, budget {budget}: nothing was prefetched"
            );
            assert_eq!(with.rgb, without.rgb, "{eviction}, budget {budget}");
            assert_eq!(with.depth, without.depth, "{eviction}, budget {budget}");
            assert_eq!(with.rgb, reference.rgb);
            assert_eq!(with.depth, reference.depth);
        }
    }
}

/// Frames of one view until no block is missing, each followed by the step between frames and
/// a wait for the fetchers (as a still image converges).
fn frames_to_full_detail(scene: &Scene, cache: &AsyncCache, cam: &Camera) -> usize {
    for n in 1..=200 {
        let (_, stats) = render(scene, cache, cam, &POE0).unwrap();
        cache.end_frame();
        cache.wait_for_fetchers();
        if stats.primary.voxel + stats.primary.proxy == 0
            && stats.cache.blocks_wanted_last_frame == 0
        {
            return n;
        }
    }
    panic!("the view never reached full detail");
}

#[test]
fn reading_ahead_fills_a_cold_view_in_fewer_frames_and_only_into_free_room() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 20_000);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let cam = views(&scene)[1];
    let budget = 256 << 20;
    let plain = AsyncCache::with_read_ahead(Arc::clone(&scene), budget, 2, 0);
    let without = frames_to_full_detail(&scene, &plain, &cam);
    assert_eq!(plain.stats().blocks_looked_ahead, 0);
    let ahead = AsyncCache::new(Arc::clone(&scene), budget, 2);
    let with = frames_to_full_detail(&scene, &ahead, &cam);
    let read = ahead.stats().blocks_looked_ahead;
    assert!(
        with < without,
        "reading ahead {with} frames, without {without} ({read} blocks read ahead)"
    );
    // A budget that the view's blocks fill more than half of reads ahead into free room only.
    let needed = plain.stats().bytes_resident as usize;
    let tight = AsyncCache::new(Arc::clone(&scene), needed + needed / 4, 2);
    frames_to_full_detail(&scene, &tight, &cam);
    assert!(tight.stats().peak_bytes_resident as usize <= needed + needed / 4);
}

#[test]
fn the_fetch_share_spreads_a_burst_over_frames_and_idling_or_waiting_lifts_it() {
    let dir = tempfile::tempdir().unwrap();
    // Small blocks: each level of the view's tree spreads over many of them.
    let path = uncompressed_mandelbulb(dir.path(), 20_000);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let cam = views(&scene)[0];
    let cache_with = |share: f64| {
        let opts = AsyncOptions {
            fetchers: 1,
            read_ahead: 0,
            fetch_share: share,
            ..AsyncOptions::default()
        };
        AsyncCache::with_options(Arc::clone(&scene), 256 << 20, &opts)
    };
    // The most blocks one step published in 8 frames, the fetchers given time to spare.
    let largest_burst = |cache: &AsyncCache| {
        let mut largest = 0;
        for _ in 0..8 {
            let before = cache.stats().blocks_loaded;
            render(&scene, cache, &cam, &POE0).unwrap();
            std::thread::sleep(std::time::Duration::from_millis(50));
            cache.end_frame();
            largest = largest.max(cache.stats().blocks_loaded - before);
        }
        largest
    };
    let free = cache_with(f64::INFINITY);
    let unlimited = largest_burst(&free);
    assert!(
        unlimited > 1,
        "the view wants several blocks a frame: {unlimited}"
    );
    // A share of next to nothing: one block per frame (the first after a step always starts).
    let tight = cache_with(1e-9);
    assert_eq!(largest_burst(&tight), 1);
    // While the caller idles between frames the fetchers are not limited: at the same share,
    // the step after an idle spell publishes what they fetched meanwhile.
    let idling = cache_with(1e-9);
    let mut after_idle = 0;
    for _ in 0..8 {
        render(&scene, &idling, &cam, &POE0).unwrap();
        idling.end_frame();
        idling.idle();
        std::thread::sleep(std::time::Duration::from_millis(50));
        let before = idling.stats().blocks_loaded;
        idling.end_frame();
        after_idle = after_idle.max(idling.stats().blocks_loaded - before);
    }
    assert!(after_idle > 1, "{after_idle}");
    // A caller that waits for the fetchers gets every block, whatever the share.
    frames_to_full_detail(&scene, &tight, &cam);
}

/// The nice value in a task's `stat` (field 19; the command name before it may hold spaces,
/// so the fields are counted from its closing parenthesis).
#[cfg(target_os = "linux")]
fn nice_of(stat_path: &Path) -> Option<i32> {
    let stat = std::fs::read_to_string(stat_path).ok()?;
    let (_, rest) = stat.rsplit_once(')')?;
    rest.split_whitespace().nth(16)?.parse().ok()
}

/// The nice values of this process's threads.
#[cfg(target_os = "linux")]
fn thread_nice_values() -> Vec<i32> {
    std::fs::read_dir("/proc/self/task")
        .unwrap()
        .filter_map(|t| nice_of(&t.ok()?.path().join("stat")))
        .collect()
}

/// The fetchers run the nice levels asked for below the caller, the render threads and the
/// caller keep theirs, and the stats say what the fetchers got; nice 0 leaves them alone.
#[cfg(target_os = "linux")]
#[test]
fn fetchers_run_at_the_nice_value_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let path = uncompressed_mandelbulb(dir.path(), 2_000);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let own = || nice_of(Path::new("/proc/thread-self/stat"));
    // This test's thread moves four levels down first (that needs no privilege), so that the
    // fetchers it starts are seen to count from it rather than from nice 0 (4 + 7 is no other
    // test's fetcher value).
    let tid = rustix::thread::gettid();
    let start = rustix::process::getpriority_process(Some(tid)).unwrap();
    if start + 4 + 7 > 19 {
        // Run under `nice` so far that 4 + 7 levels more pass 19: every thread is at 19 and
        // the fetchers' level cannot be told from the others'.
        eprintln!("skipped: this process runs at nice {start}");
        return;
    }
    rustix::process::setpriority_process(Some(tid), (start + 4).min(19)).unwrap();
    let mine = own();
    assert!(mine.is_some());
    // Counted from this thread's own nice value, which the fetchers start at.
    let want = (mine.unwrap() + 7).min(19);
    assert_ne!(want, 7);
    let before = thread_nice_values();
    assert!(!before.contains(&want), "{before:?}");
    for (nice, fetchers) in [(7u8, 3usize), (0, 2)] {
        let opts = AsyncOptions {
            fetchers,
            fetcher_nice: nice,
            ..AsyncOptions::default()
        };
        let cache = AsyncCache::with_options(Arc::clone(&scene), 64 << 20, &opts);
        // The fetchers lower themselves as they start.
        let mut at = Vec::new();
        for _ in 0..500 {
            at = thread_nice_values();
            if at.iter().filter(|&&n| n == want).count() == if nice > 0 { fetchers } else { 0 } {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        let lowered = at.iter().filter(|&&n| n == want).count();
        assert_eq!(lowered, if nice > 0 { fetchers } else { 0 }, "{at:?}");
        let cam = &views(&scene)[0];
        let (_, stats) = render(&scene, &cache, cam, &POE0).unwrap();
        assert_eq!(
            stats.cache.fetcher_nice,
            (nice > 0).then_some(i32::from(nice))
        );
        // This thread kept its priority.
        assert_eq!(own(), mine);
        drop(cache);
    }
}

#[test]
fn decoded_blocks_and_proxies_hold_no_spare_bytes_and_blocks_decode_alike_in_any_order() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Scene::open(&uncompressed_mandelbulb(dir.path(), 20_000)).unwrap();
    let ids: Vec<u32> = (0u32..)
        .zip(scene.reader().entries())
        .filter(|(_, e)| e.kind == BlockKind::Treelet)
        .map(|(id, _)| id)
        .collect();
    assert!(ids.len() > 10, "{} treelet blocks", ids.len());
    // One thread decodes every block forwards, then backwards: the working arrays it keeps
    // between blocks must not leak one block into the next.
    let forwards: Vec<String> = ids
        .iter()
        .map(|&id| {
            let d = scene.load_treelets(id).unwrap();
            // Exact sizes: the cache budget counts capacity, and a doubled vector would be
            // up to half slack.
            assert!(d.is_exactly_sized(), "block {id}");
            format!("{d:?}")
        })
        .collect();
    assert!(forwards.iter().any(|d| d.contains("Lod {")));
    for (id, e) in (0u32..).zip(scene.reader().entries()) {
        if e.kind == BlockKind::Triangle {
            let d = scene.load_triangles(id).unwrap();
            assert_eq!(d.list.capacity(), d.list.len(), "block {id}");
            assert_eq!(d.positions.capacity(), d.positions.len(), "block {id}");
        }
    }
    // The proxies are held once, by the reader.
    assert!(std::ptr::eq(scene.proxies(), scene.reader().proxies()));
    for (&id, f) in ids.iter().zip(&forwards).rev() {
        let d = scene.load_treelets(id).unwrap();
        assert_eq!(&format!("{d:?}"), f, "block {id}");
    }
}

/// Every decoded node says what the file's node says: the same axis, split plane and fields,
/// children at the nodes the file points to, each LOD node's voxel or plane and proxy, and each
/// treelet's root; for a file with voxels and R-LODs, decoded either way.
#[test]
fn decoded_treelet_blocks_say_what_the_file_says() {
    let dir = tempfile::tempdir().unwrap();
    let layout = LayoutOptions {
        write: WriteOptions {
            lod: LodKinds::BOTH,
            ..WriteOptions::default()
        }
        .with_block_size(4096)
        .unwrap(),
        triangles_per_proxy: 0,
        ..LayoutOptions::default()
    };
    let path = common::mandelbulb_with(dir.path(), 20_000, layout);
    let mut seen = [0usize; 4];
    for kind in [LodKind::Voxel, LodKind::Rlod] {
        let scene = Scene::open(&path).unwrap().with_lod(kind).unwrap();
        for (id, e) in (0u32..).zip(scene.reader().entries()) {
            if e.kind != BlockKind::Treelet {
                continue;
            }
            let d = scene.load_treelets(id).unwrap();
            let block = scene.reader().read_block(id).unwrap();
            let tb = block.treelets().unwrap();
            let mut raw = Vec::new();
            tb.walk_lods(|t, pos, n, entry| {
                raw.push((t, pos, *n, *entry));
                Ok(())
            })
            .unwrap();
            let index = |pos: usize| raw.iter().position(|r| r.1 == pos).map(|i| i as u32);
            let views: Vec<NodeView> = d.nodes().collect();
            assert_eq!(views.len(), raw.len(), "block {id}");
            for (i, (&(_, pos, node, entry), &view)) in raw.iter().zip(&views).enumerate() {
                let child = |units: u16| match units {
                    0 => NONE,
                    u => index(TreeletBlock::child_pos(pos, u)).unwrap(),
                };
                match (node, view) {
                    (
                        Node::Basic {
                            axis,
                            split,
                            left,
                            right,
                        },
                        NodeView::Inner {
                            axis: a,
                            split: s,
                            left: l,
                            right: r,
                        },
                    ) => {
                        assert_eq!((a, s.to_bits()), (axis, split.to_bits()));
                        assert_eq!((l, r), (child(left), child(right)), "block {id} node {i}");
                        seen[0] += usize::from(left != 0 && right != 0);
                    }
                    (
                        Node::Lod {
                            axis,
                            split,
                            radius,
                            child_block,
                            proxy,
                            ..
                        },
                        NodeView::Lod {
                            axis: a,
                            split: s,
                            lod,
                        },
                    ) => {
                        assert_eq!((a, s.to_bits()), (axis, split.to_bits()));
                        let l = d.lods[lod as usize];
                        assert_eq!(l.child_block, child_block);
                        let (shown, p) = d.look(lod).unwrap();
                        assert_eq!(p, (proxy != NO_PROXY).then_some(proxy));
                        seen[3] += usize::from(p.is_some());
                        match (kind, shown) {
                            (LodKind::Voxel, Shown::Voxel(v)) => {
                                assert_eq!(l.radius, radius);
                                assert_eq!(Some(v), entry.voxel, "block {id} node {i}");
                                seen[1] += usize::from(matches!(v, Voxel::Six(_, _)));
                            }
                            (LodKind::Rlod, Shown::Plane(plane)) => {
                                let r = entry.rlod.unwrap();
                                assert_eq!(l.radius, r.error_radius(radius));
                                assert_eq!((plane.normal, plane.offset), (r.normal, r.offset));
                                assert_eq!(plane.expansion, r.expansion(radius));
                            }
                            other => panic!("block {id} node {i}: {other:?}"),
                        }
                    }
                    (
                        Node::Leaf {
                            first,
                            count,
                            block,
                        },
                        NodeView::Leaf {
                            first: f,
                            count: c,
                            block: b,
                        },
                    ) => {
                        assert_eq!((f, c, b), (first, count, block));
                        seen[2] += 1;
                    }
                    other => panic!("block {id} node {i}: {other:?}"),
                }
            }
            for t in 0..tb.treelet_count() {
                let start = tb.treelet_span(t).unwrap().start;
                assert_eq!(Some(d.roots[t]), index(start), "block {id} treelet {t}");
            }
        }
    }
    // Inner nodes with both children, six-sided voxels, leaves and proxies were all met.
    assert!(seen.iter().all(|&n| n > 0), "{seen:?}");
}

/// Render threads keep their memo between tiles and frames (`Memo::pooled`): one handed back
/// must not keep a block alive for the cache (its budget could not free it), and the next tile
/// that takes it traces alike.
#[test]
fn a_memo_its_thread_keeps_holds_no_block() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Arc::new(Scene::open(&uncompressed_mandelbulb(dir.path(), 20_000)).unwrap());
    let cache = BlockingCache::new(Arc::clone(&scene), 64 << 20);
    let frame = views(&scene)[0].frame().unwrap();
    let tracer = Tracer::new(&scene, &cache, 0.0);
    let ray = frame.ray(W / 2, H / 2);
    let trace = || {
        let memo = Memo::pooled(&scene);
        let hit = tracer.trace(&ray, &memo).unwrap();
        let Surface::Triangle { data, triangle, .. } = hit.surface else {
            panic!("the middle ray ends on {:?}", hit.surface);
        };
        (hit.t, data, triangle)
    };
    let (t, data, triangle) = trace();
    // The cache's reference and ours: the memo this thread kept holds none.
    assert_eq!(Arc::strong_count(&data), 2);
    let again = trace();
    assert_eq!((again.0, again.2), (t, triangle));
    assert!(Arc::ptr_eq(&again.1, &data));
    assert_eq!(Arc::strong_count(&data), 3);
}
