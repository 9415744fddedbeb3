//! Live views on a real container: a still view ends on the blocking cache's full-detail
//! image bit for bit, accumulation averages its passes, the viewer serves several views with
//! the newest camera winning, and a pick answers what the still frame shows.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use oocfmt_build::convert::{convert, ConvertOptions};
use oocfmt_build::progress::NoProgress;
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};

use super::*;
use crate::cache::asynchronous::AsyncOptions;
use crate::session::{stored_point, Cache, CacheKind};
use crate::{render, BlockingCache, Camera, RenderOptions, Scene};

fn mandelbulb(dir: &Path, triangles: u64) -> PathBuf {
    let obj = dir.join("mb.obj");
    let opts = MandelbulbOptions {
        triangles,
        ..MandelbulbOptions::default()
    };
    mandelbulb::write_obj(&obj, &opts, &mut |_, _| {}).unwrap();
    let out = dir.join("mb.oocf");
    let opts = ConvertOptions {
        mem_limit: 1 << 30,
        ..ConvertOptions::default()
    };
    convert(&[obj], &out, &opts, &mut NoProgress).unwrap();
    out
}

/// Quick to refine: the tests wait for real.
const FAST: LiveOptions = LiveOptions {
    target_ms: 10.0,
    still_ms: 30.0,
    ..LiveOptions::DEFAULT
};

fn framing(scene: &Scene, w: u32, h: u32) -> Camera {
    let m = scene.metadata();
    Camera::framing(m.scene.bounds_min, m.scene.bounds_max, w, h)
}

/// Runs the view's schedule to its end; every frame rendered.
fn run_to_end(view: &mut LiveView, scene: &Scene, cache: &Cache) -> Vec<LiveFrame> {
    let mut rate = LoadRate::new();
    let mut frames = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(60);
    while Instant::now() < deadline {
        match view.next(Instant::now()) {
            Next::Render(plan) => frames.push(view.render(plan, scene, cache, &mut rate).unwrap()),
            Next::Sleep(t) => std::thread::sleep(t.saturating_duration_since(Instant::now())),
            Next::Idle => break,
        }
    }
    frames
}

#[test]
fn a_still_view_ends_on_the_blocking_full_detail_image_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = mandelbulb(dir.path(), 20_000);
    let (scene, cache) = Cache::open(
        &path,
        None,
        CacheKind::Async,
        256 << 20,
        &AsyncOptions::default(),
        None,
    )
    .unwrap();
    let q = Quality { poe: 0.0, spp: 1 };
    let mut view = LiveView::new(FAST, RenderOptions::DEFAULT, q).unwrap();
    let camera = framing(&scene, 160, 120);
    view.set_camera(camera, 7, Instant::now()).unwrap();
    let frames = run_to_end(&mut view, &scene, &cache);
    let stages: Vec<&str> = frames.iter().map(|f| f.figures.stage).collect();
    assert_eq!(stages.first(), Some(&"moving"), "{stages:?}");
    let last = frames.last().unwrap();
    assert!(
        last.figures.last && last.figures.complete,
        "{:?}",
        last.figures
    );
    assert_eq!(last.figures.stage, "settle");
    assert_eq!(
        (last.image.width, last.image.height, last.seq),
        (160, 120, 7)
    );
    let blocking = BlockingCache::new(Arc::clone(&scene), 256 << 20);
    let opts = RenderOptions {
        poe: 0.0,
        ..RenderOptions::DEFAULT
    };
    let (want, _) = render(&scene, &blocking, &camera, &opts).unwrap();
    assert!(
        last.image.rgb == want.rgb,
        "the settled frame differs from full detail"
    );
    assert_eq!(last.image.depth, want.depth);
    // Only the last frame says so.
    assert_eq!(frames.iter().filter(|f| f.figures.last).count(), 1);
    assert!(frames.iter().all(|f| !f.figures.stale));
}

#[test]
fn accumulation_averages_passes_into_the_asked_samples_as_render_spp_does() {
    let dir = tempfile::tempdir().unwrap();
    let path = mandelbulb(dir.path(), 6_000);
    let (scene, cache) = Cache::open(
        &path,
        None,
        CacheKind::Blocking,
        256 << 20,
        &AsyncOptions::default(),
        None,
    )
    .unwrap();
    let q = Quality { poe: 0.0, spp: 4 };
    let mut view = LiveView::new(FAST, RenderOptions::DEFAULT, q).unwrap();
    let camera = framing(&scene, 96, 72);
    view.set_camera(camera, 1, Instant::now()).unwrap();
    let frames = run_to_end(&mut view, &scene, &cache);
    let acc: Vec<u32> = frames
        .iter()
        .filter(|f| f.figures.stage == "accumulate")
        .map(|f| f.figures.samples)
        .collect();
    assert_eq!(acc, [2, 3, 4]);
    let settled = frames
        .iter()
        .rfind(|f| f.figures.stage == "settle")
        .unwrap();
    let last = frames.last().unwrap();
    assert!(last.figures.last);
    // Antialiasing changes the model's edges, and not the whole picture.
    let differ = (settled.image.rgb.iter())
        .zip(&last.image.rgb)
        .filter(|(a, b)| a.abs_diff(**b) > 2)
        .count();
    let n = last.image.rgb.len();
    assert!(
        differ > 0 && differ < n / 2,
        "{differ} of {n} channels differ"
    );
    // The passes went through `render --spp 4`'s points: the same image but for each pass's
    // rounding to 8 bits before the average.
    let blocking = BlockingCache::new(Arc::clone(&scene), 256 << 20);
    let opts = RenderOptions {
        spp: 4,
        ..RenderOptions::DEFAULT
    };
    let (want, _) = render(&scene, &blocking, &camera, &opts).unwrap();
    let off = (want.rgb.iter().zip(&last.image.rgb)).map(|(a, b)| a.abs_diff(*b));
    let (worst, rounded) = off.fold((0, 0), |(w, r), d| (w.max(d), r + usize::from(d > 0)));
    assert!(
        worst <= 1 && rounded < n / 20,
        "off by up to {worst} levels in {rounded} of {n} channels"
    );
}

#[test]
fn bad_cameras_and_qualities_are_refused_and_change_nothing() {
    let mut view =
        LiveView::new(FAST, RenderOptions::DEFAULT, Quality { poe: 1.0, spp: 1 }).unwrap();
    let mut cam = Camera::framing([0.0; 3], [1.0; 3], 64, 48);
    cam.eye[0] = f64::NAN;
    assert!(view.set_camera(cam, 1, Instant::now()).is_err());
    let huge = Camera {
        width: 8192,
        height: 8192,
        ..Camera::framing([0.0; 3], [1.0; 3], 64, 48)
    };
    assert!(view.set_camera(huge, 2, Instant::now()).is_err());
    assert_eq!(view.next(Instant::now()), Next::Idle, "no camera was taken");
    for q in [
        Quality { poe: -1.0, spp: 1 },
        Quality {
            poe: f32::NAN,
            spp: 1,
        },
        Quality { poe: 0.0, spp: 0 },
    ] {
        assert!(view.set_quality(q).is_err(), "{q:?}");
    }
    assert_eq!(view.schedule().asked(), Quality { poe: 1.0, spp: 1 });
}

/// The frames a sink received.
type Received = Arc<Mutex<Vec<Arc<LiveFrame>>>>;

fn sink(into: &Received) -> Sink {
    let into = Arc::clone(into);
    Box::new(move |e| {
        if let Event::Frame(f) = e {
            into.lock().unwrap().push(f);
        }
    })
}

fn wait_for_last(frames: &Received, seq: u64) -> Arc<LiveFrame> {
    let deadline = Instant::now() + Duration::from_secs(60);
    while Instant::now() < deadline {
        if let Some(f) = frames.lock().unwrap().last() {
            if f.figures.last && f.seq == seq {
                return Arc::clone(f);
            }
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    panic!("no last frame for camera {seq}");
}

#[test]
fn a_viewer_serves_several_views_and_the_newest_camera_wins() {
    let dir = tempfile::tempdir().unwrap();
    let path = mandelbulb(dir.path(), 6_000);
    let (scene, cache) = Cache::open(
        &path,
        None,
        CacheKind::Async,
        256 << 20,
        &AsyncOptions::default(),
        None,
    )
    .unwrap();
    let origin = scene.metadata().scene.origin;
    let viewer = Viewer::start(Arc::clone(&scene), cache, RenderOptions::DEFAULT, FAST).unwrap();
    let q = Quality { poe: 0.0, spp: 1 };
    let (a, b): (Received, Received) = Default::default();
    let ia = viewer.connect(q, sink(&a)).unwrap();
    let ib = viewer.connect(q, sink(&b)).unwrap();
    assert_eq!(viewer.views(), 2);
    // World coordinates: the framing camera moved by the origin.
    let world = |c: Camera| Camera {
        eye: [0, 1, 2].map(|k| c.eye[k] + origin[k]),
        look_at: [0, 1, 2].map(|k| c.look_at[k] + origin[k]),
        ..c
    };
    let base = framing(&scene, 64, 48);
    for seq in 1..=5 {
        let mut c = base;
        c.eye[0] += seq as f64 * 0.01;
        viewer.camera(ia, world(c), seq).unwrap();
    }
    viewer.camera(ib, world(base), 1).unwrap();
    let la = wait_for_last(&a, 5);
    let lb = wait_for_last(&b, 1);
    // A's cameras came faster than frames: not every one was rendered, the last one was.
    let seqs: Vec<u64> = a.lock().unwrap().iter().map(|f| f.seq).collect();
    assert!(seqs.windows(2).all(|w| w[0] <= w[1]), "{seqs:?}");
    // The cameras as the viewer stores them (world coordinates back less the origin).
    let stored = |c: Camera| {
        let w = world(c);
        Camera {
            eye: stored_point(&scene, w.eye),
            look_at: stored_point(&scene, w.look_at),
            ..w
        }
    };
    let mut c5 = base;
    c5.eye[0] += 0.05;
    let blocking = BlockingCache::new(Arc::clone(&scene), 64 << 20);
    let (want, _) = render(&scene, &blocking, &stored(c5), &RenderOptions::DEFAULT).unwrap();
    assert!(la.image.rgb == want.rgb);
    let (want, _) = render(&scene, &blocking, &stored(base), &RenderOptions::DEFAULT).unwrap();
    assert!(lb.image.rgb == want.rgb);
    // A refused camera changes nothing.
    let mut bad = base;
    bad.fov_y = 0.0;
    assert!(viewer.camera(ia, world(bad), 6).is_err());
    viewer.disconnect(ia);
    assert_eq!(viewer.views(), 1);
    drop(viewer);
}

#[test]
fn a_pick_answers_what_the_still_frame_shows_at_that_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let path = mandelbulb(dir.path(), 6_000);
    let (scene, cache) = Cache::open(
        &path,
        None,
        CacheKind::Async,
        256 << 20,
        &AsyncOptions::default(),
        None,
    )
    .unwrap();
    let origin = scene.metadata().scene.origin;
    let viewer = Viewer::start(Arc::clone(&scene), cache, RenderOptions::DEFAULT, FAST).unwrap();
    let frames: Received = Default::default();
    let picks: Arc<Mutex<Vec<Picked>>> = Default::default();
    let errors: Arc<Mutex<Vec<String>>> = Default::default();
    let (f, p, e) = (Arc::clone(&frames), Arc::clone(&picks), Arc::clone(&errors));
    let sink: Sink = Box::new(move |ev| match ev {
        Event::Frame(x) => f.lock().unwrap().push(x),
        Event::Pick(x) => p.lock().unwrap().push(x),
        Event::Error(x) => e.lock().unwrap().push(x),
    });
    let id = viewer.connect(Quality { poe: 0.0, spp: 1 }, sink).unwrap();
    // Before any camera a pick has nothing to look through.
    viewer.pick(id, 1, (0, 0));
    let deadline = Instant::now() + Duration::from_secs(20);
    while errors.lock().unwrap().is_empty() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(
        errors.lock().unwrap()[0].contains("pick 1"),
        "{:?}",
        errors.lock().unwrap()
    );
    let cam = framing(&scene, 64, 48);
    let world = Camera {
        eye: [0, 1, 2].map(|k| cam.eye[k] + origin[k]),
        look_at: [0, 1, 2].map(|k| cam.look_at[k] + origin[k]),
        ..cam
    };
    viewer.camera(id, world, 1).unwrap();
    let last = wait_for_last(&frames, 1);
    viewer.pick(id, 2, (32, 24));
    viewer.pick(id, 3, (0, 0));
    while picks.lock().unwrap().len() < 2 && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(5));
    }
    let got = picks.lock().unwrap();
    assert_eq!(got.iter().map(|p| p.seq).collect::<Vec<_>>(), [2, 3]);
    let centre = got[0].hit.as_ref().expect("the model is at the centre");
    let depth = f64::from(last.image.depth[24 * 64 + 32]);
    assert!(
        (centre.distance - depth).abs() <= 1e-4 * depth,
        "{centre:?} {depth}"
    );
    assert!(
        !centre.lod && centre.triangle.is_some(),
        "full detail at PoE 0"
    );
    assert!(got[1].hit.is_none(), "the corner is background");
    assert_eq!(got[1].pixel, (0, 0));
}

#[test]
fn a_sectioned_view_settles_on_the_sectioned_full_detail_image_and_keeps_its_plane_to_itself() {
    let dir = tempfile::tempdir().unwrap();
    let path = mandelbulb(dir.path(), 8_000);
    let (scene, cache) = Cache::open(
        &path,
        None,
        CacheKind::Async,
        256 << 20,
        &AsyncOptions::default(),
        None,
    )
    .unwrap();
    let m = scene.metadata();
    let mid = (m.scene.bounds_min[0] + m.scene.bounds_max[0]) / 2.0;
    let plane = crate::Section::axis(0, f64::from(mid) + m.scene.origin[0]).unwrap();
    let q = Quality { poe: 0.0, spp: 1 };
    let camera = framing(&scene, 96, 72);
    let mut cut = LiveView::new(FAST, RenderOptions::DEFAULT, q).unwrap();
    cut.set_camera(camera, 1, Instant::now()).unwrap();
    cut.set_section(Some(plane), Instant::now());
    let mut whole = LiveView::new(FAST, RenderOptions::DEFAULT, q).unwrap();
    whole.set_camera(camera, 1, Instant::now()).unwrap();
    let cut_last = run_to_end(&mut cut, &scene, &cache).pop().unwrap();
    let whole_last = run_to_end(&mut whole, &scene, &cache).pop().unwrap();
    assert!(cut_last.figures.last && whole_last.figures.last);
    let blocking = BlockingCache::new(Arc::clone(&scene), 256 << 20);
    scene.set_section(Some(plane));
    let (want_cut, _) = render(&scene, &blocking, &camera, &RenderOptions::DEFAULT).unwrap();
    scene.set_section(None);
    let (want_whole, _) = render(&scene, &blocking, &camera, &RenderOptions::DEFAULT).unwrap();
    assert_ne!(
        want_cut.rgb, want_whole.rgb,
        "the plane cuts the model in view"
    );
    assert!(
        cut_last.image.rgb == want_cut.rgb,
        "the cut view's still frame"
    );
    assert!(
        whole_last.image.rgb == want_whole.rgb,
        "the other view is not cut"
    );
    // Taking the plane away refines again, to the whole model.
    cut.set_section(None, Instant::now());
    let again = run_to_end(&mut cut, &scene, &cache).pop().unwrap();
    assert!(again.image.rgb == want_whole.rgb);
}
