//! Parts in the tracer: hiding a part renders, pixel for pixel, what a file converted without
//! it renders (at PoE 0); isolating is hiding every other part; highlighting changes exactly
//! the pixels of the highlighted part; at PoE > 0 a hidden part leaves nothing behind (its
//! LOD entries stand in for nothing). Picking answers the triangle and part at a pixel known
//! to show it, None on the background and on a hidden part, and the LOD entry's part word at
//! PoE > 0, the same with the blocking, asynchronous (cold: no stand-ins) and mmap caches;
//! the asynchronous cache converges to the blocking cache's masked image; packets and single
//! rays agree under a filter.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use oocfmt::{Codec, WriteOptions};
use oocfmt_build::convert::{convert, ConvertOptions};
use oocfmt_build::layout::LayoutOptions;
use oocfmt_build::progress::NoProgress;
use oocfmt_trace::cache::asynchronous::AsyncOptions;
use oocfmt_trace::parts::{PartFilter, PartSelection};
use oocfmt_trace::pick::{pick, Pick};
use oocfmt_trace::render::Image;
use oocfmt_trace::session::{self, Cache, CacheKind};
use oocfmt_trace::traverse::{Memo, Tracer};
use oocfmt_trace::{render, BlockCache, BlockingCache, Camera, RenderOptions, Scene};

use crate::common;

const W: u32 = 96;
const H: u32 = 64;
/// The spheres' centres: far apart (no LOD cell at a few pixels of error holds both).
const LEFT: [f64; 3] = [-3.0, 0.0, 0.0];
const RIGHT: [f64; 3] = [3.0, 0.0, 0.0];

/// An OBJ of a unit sphere at each of `spheres` (subdivided 5 times), each under `o NAME`
/// when named. Positions print as f32 so that every file stores the same coordinates.
fn obj(spheres: &[(Option<&str>, [f64; 3])]) -> String {
    let (v, f) = common::sphere(5);
    let mut text = String::new();
    for (k, (name, c)) in spheres.iter().enumerate() {
        if let Some(n) = name {
            writeln!(text, "o {n}").unwrap();
        }
        for p in &v {
            let q = [0, 1, 2].map(|i| (f64::from(p[i]) + c[i]) as f32);
            writeln!(text, "v {} {} {}", q[0], q[1], q[2]).unwrap();
        }
        let base = k * v.len() + 1;
        for t in &f {
            writeln!(text, "f {} {} {}", t[0] + base, t[1] + base, t[2] + base).unwrap();
        }
    }
    text
}

fn convert_text(dir: &Path, name: &str, text: &str, codec: Codec) -> PathBuf {
    let obj = dir.join(format!("{name}.obj"));
    std::fs::write(&obj, text).unwrap();
    let out = dir.join(format!("{name}.oocf"));
    let opts = ConvertOptions {
        mem_limit: 1 << 30,
        layout: LayoutOptions {
            write: WriteOptions {
                codec,
                ..WriteOptions::default()
            },
            ..LayoutOptions::default()
        },
        ..ConvertOptions::default()
    };
    convert(&[obj], &out, &opts, &mut NoProgress).unwrap();
    out
}

/// The two-sphere file (`left`, `right`), the file of the left sphere alone (named, so it is
/// the same triangles in a file of one part), and the two spheres unnamed (no parts).
struct Files {
    both: PathBuf,
    left: PathBuf,
    plain: PathBuf,
    _dir: tempfile::TempDir,
}

fn files(codec: Codec) -> Files {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    Files {
        both: convert_text(
            d,
            "both",
            &obj(&[(Some("left"), LEFT), (Some("right"), RIGHT)]),
            codec,
        ),
        left: convert_text(d, "left", &obj(&[(Some("left"), LEFT)]), codec),
        plain: convert_text(d, "plain", &obj(&[(None, LEFT), (None, RIGHT)]), codec),
        _dir: dir,
    }
}

/// Looking at both spheres from the front, in stored coordinates (every file here has origin
/// 0): the left sphere fills the left half of the image, the right one the right half.
fn camera() -> Camera {
    Camera {
        eye: [0.0, 0.0, 12.0],
        look_at: [0.0, 0.0, 0.0],
        up: [0.0, 1.0, 0.0],
        fov_y: 40.0,
        width: W,
        height: H,
    }
}

/// The pixel whose centre ray passes nearest the point `p` (stored coordinates).
fn pixel_of(cam: &Camera, p: [f64; 3]) -> (u32, u32) {
    let f = cam.frame().unwrap();
    let mut best = (f64::INFINITY, (0, 0));
    for y in 0..H {
        for x in 0..W {
            let r = f.ray(x, y);
            let o = r.org.map(f64::from);
            let d = r.dir.map(f64::from);
            let op = [0, 1, 2].map(|k| p[k] - o[k]);
            let t = op[0] * d[0] + op[1] * d[1] + op[2] * d[2];
            let miss: f64 = (0..3).map(|k| (op[k] - t * d[k]).powi(2)).sum();
            if miss < best.0 {
                best = (miss, (x, y));
            }
        }
    }
    best.1
}

fn open(path: &Path) -> Arc<Scene> {
    Arc::new(Scene::open(path).unwrap())
}

fn select(scene: &Scene, sel: PartSelection) {
    scene.set_parts(PartFilter::new(&scene.metadata().parts, &sel).unwrap());
}

fn hide(globs: &[&str]) -> PartSelection {
    PartSelection {
        hide: globs.iter().map(|g| g.to_string()).collect(),
        ..PartSelection::default()
    }
}

fn opts(poe: f32) -> RenderOptions {
    RenderOptions {
        poe,
        ..RenderOptions::DEFAULT
    }
}

fn frame(scene: &Arc<Scene>, poe: f32) -> Image {
    let cache = BlockingCache::new(Arc::clone(scene), usize::MAX);
    render(scene, &cache, &camera(), &opts(poe)).unwrap().0
}

fn same_image(a: &Image, b: &Image, what: &str) {
    assert_eq!(a.rgb, b.rgb, "{what}: colours");
    let bits = |i: &Image| i.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(a), bits(b), "{what}: depths");
}

/// The pixels where two images differ in colour.
fn differ(a: &Image, b: &Image) -> Vec<bool> {
    a.rgb
        .chunks(3)
        .zip(b.rgb.chunks(3))
        .map(|(p, q)| p != q)
        .collect()
}

#[test]
fn the_files_hold_the_parts_they_were_given() {
    let f = files(Codec::Lz4);
    let both = open(&f.both);
    let names: Vec<&str> = both
        .metadata()
        .parts
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    assert_eq!(names, ["left", "right"]);
    assert_eq!(open(&f.left).metadata().parts.len(), 1);
    assert!(open(&f.plain).metadata().parts.is_empty());
}

#[test]
fn hiding_a_part_renders_the_file_without_it_and_isolating_hides_the_rest() {
    let f = files(Codec::Lz4);
    let both = open(&f.both);
    let without = frame(&open(&f.left), 0.0);
    select(&both, hide(&["right"]));
    let hidden = frame(&both, 0.0);
    same_image(
        &hidden,
        &without,
        "--hide right against the left sphere alone",
    );
    assert!(
        hidden.depth.iter().any(|d| d.is_finite()),
        "left is in view"
    );
    select(
        &both,
        PartSelection {
            isolate: vec!["l*".into()],
            ..PartSelection::default()
        },
    );
    same_image(&frame(&both, 0.0), &without, "--isolate l*");
    // Hiding both leaves the background only.
    select(&both, hide(&["left", "right"]));
    assert!(frame(&both, 0.0).depth.iter().all(|d| d.is_infinite()));
    // And the unfiltered file shows both, as the file without parts does.
    select(&both, PartSelection::default());
    same_image(
        &frame(&both, 0.0),
        &frame(&open(&f.plain), 0.0),
        "no filter",
    );
}

#[test]
fn highlighting_changes_exactly_the_pixels_of_the_part() {
    let f = files(Codec::Lz4);
    let both = open(&f.both);
    let plain = frame(&both, 0.0);
    select(&both, hide(&["right"]));
    let right_pixels = differ(&plain, &frame(&both, 0.0));
    assert!(right_pixels.iter().filter(|&&d| d).count() > 100);
    select(
        &both,
        PartSelection {
            highlight: vec!["right".into()],
            ..PartSelection::default()
        },
    );
    let lit = frame(&both, 0.0);
    assert_eq!(differ(&plain, &lit), right_pixels, "highlighted pixels");
    let bits = |i: &Image| i.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&lit), bits(&plain), "highlighting changes no depth");
    // Towards orange: more red than blue on a highlighted pixel, unlike the grey original.
    let k = right_pixels.iter().position(|&d| d).unwrap();
    let (p, q) = (&plain.rgb[3 * k..3 * k + 3], &lit.rgb[3 * k..3 * k + 3]);
    assert!(q[0] > q[2] + 40 && p[0] < p[2] + 40, "{p:?} -> {q:?}");
}

#[test]
fn at_lod_a_hidden_part_leaves_nothing_and_highlighting_follows_the_part_words() {
    let f = files(Codec::Lz4);
    let both = open(&f.both);
    let cam = camera();
    let right_half = |img: &Image| -> Vec<f32> {
        (0..H)
            .flat_map(|y| (W / 2..W).map(move |x| (y * W + x) as usize))
            .map(|k| img.depth[k])
            .collect()
    };
    for poe in [2.0f32, 8.0] {
        let plain = frame(&both, poe);
        assert!(right_half(&plain).iter().any(|d| d.is_finite()));
        let cache = BlockingCache::new(Arc::clone(&both), usize::MAX);
        let (_, stats) = render(&both, &cache, &cam, &opts(poe)).unwrap();
        assert!(stats.primary.voxel > 0, "PoE {poe} stops on LOD entries");
        select(&both, hide(&["right"]));
        let hidden = frame(&both, poe);
        assert!(
            right_half(&hidden).iter().all(|d| d.is_infinite()),
            "PoE {poe}: nothing of the hidden sphere shows"
        );
        assert!(hidden.depth.iter().any(|d| d.is_finite()));
        select(
            &both,
            PartSelection {
                highlight: vec!["right".into()],
                ..PartSelection::default()
            },
        );
        let lit = frame(&both, poe);
        select(&both, PartSelection::default());
        let changed = differ(&plain, &lit);
        assert!(changed.iter().any(|&c| c), "PoE {poe}: something is tinted");
        // Every tinted pixel picks the right sphere at the same PoE.
        for (k, _) in changed.iter().enumerate().filter(|(_, &c)| c) {
            let (x, y) = (k as u32 % W, k as u32 / W);
            let p = pick(&both, &cache, &cam, (x, y), poe).unwrap().unwrap();
            assert_eq!(
                p.part_name.as_deref(),
                Some("right"),
                "PoE {poe} at {x},{y}"
            );
        }
    }
}

/// The three caches a pick can go through, fresh (the asynchronous one cold).
fn caches(path: &Path) -> Vec<(&'static str, Arc<Scene>, Cache)> {
    [CacheKind::Blocking, CacheKind::Async, CacheKind::Mmap]
        .into_iter()
        .map(|kind| {
            let (scene, cache) =
                Cache::open(path, None, kind, 64 << 20, &AsyncOptions::default(), None).unwrap();
            (kind.name(), scene, cache)
        })
        .collect()
}

fn picks(scene: &Scene, cache: &dyn BlockCache, at: (u32, u32), poe: f32) -> Option<Pick> {
    pick(scene, cache, &camera(), at, poe).unwrap()
}

#[test]
fn a_pick_names_the_triangle_and_part_in_every_cache_mode() {
    let f = files(Codec::None);
    let cam = camera();
    let centre = pixel_of(&cam, LEFT);
    let mut seen = Vec::new();
    for (mode, scene, cache) in caches(&f.both) {
        let c = cache.get();
        let p = picks(&scene, c, centre, 0.0).unwrap_or_else(|| panic!("{mode}: a hit"));
        assert_eq!(p.part, Some(0), "{mode}");
        assert_eq!(p.part_name.as_deref(), Some("left"), "{mode}");
        assert_eq!(p.part_path.as_deref(), Some("left"), "{mode}");
        assert!(!p.lod, "{mode}: full detail, no stand-in even when cold");
        // The ray aims at the centre: it meets the unit sphere one short of it, where the
        // normal points out of the sphere, towards the eye.
        let eye = cam.eye;
        let to_centre = (0..3)
            .map(|k| (LEFT[k] - eye[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            (p.distance - (to_centre - 1.0)).abs() < 0.01,
            "{mode}: {p:?}"
        );
        let out = [0, 1, 2].map(|k| p.point[k] - LEFT[k]);
        let r = out.iter().map(|c| c * c).sum::<f64>().sqrt();
        assert!((r - 1.0).abs() < 0.01, "{mode}: on the sphere: {p:?}");
        let cos: f64 = (0..3).map(|k| out[k] * f64::from(p.normal[k])).sum();
        assert!(cos > 0.99, "{mode}: the outward normal: {p:?}");
        let t = p.triangle.unwrap();
        let td = scene.load_triangles(t.block).unwrap();
        assert_eq!(td.part(t.index), Some(0), "{mode}: the triangle's own part");
        // Background: above the spheres.
        assert_eq!(picks(&scene, c, (W / 2, 0), 0.0), None, "{mode}");
        // A hidden part cannot be picked: the ray goes on to the background.
        select(&scene, hide(&["left"]));
        assert_eq!(picks(&scene, c, centre, 0.0), None, "{mode}: hidden");
        let right = picks(&scene, c, pixel_of(&cam, RIGHT), 0.0).unwrap();
        assert_eq!(right.part_name.as_deref(), Some("right"), "{mode}");
        select(&scene, PartSelection::default());
        seen.push(p);
    }
    assert!(seen.windows(2).all(|w| w[0] == w[1]), "{seen:?}");
}

#[test]
fn a_pick_at_lod_answers_the_entry_s_part_word() {
    let f = files(Codec::None);
    let far = Camera {
        eye: [0.0, 0.0, 60.0],
        ..camera()
    };
    let at = pixel_of(&far, RIGHT);
    let mut seen = Vec::new();
    for (mode, scene, cache) in caches(&f.both) {
        let p = pick(&scene, cache.get(), &far, at, 6.0).unwrap().unwrap();
        assert!(p.lod && p.triangle.is_none(), "{mode}: {p:?}");
        assert_eq!(p.part_name.as_deref(), Some("right"), "{mode}");
        let full = pick(&scene, cache.get(), &far, at, 0.0).unwrap().unwrap();
        assert!(!full.lod && full.part == p.part, "{mode}: {full:?}");
        seen.push(p);
    }
    assert!(seen.windows(2).all(|w| w[0] == w[1]), "{seen:?}");
    // A file without parts picks no part.
    let plain = open(&f.plain);
    let cache = BlockingCache::new(Arc::clone(&plain), usize::MAX);
    let p = pick(&plain, &cache, &far, at, 0.0).unwrap().unwrap();
    assert_eq!((p.part, p.part_name), (None, None));
    // Outside the image: an error.
    assert!(pick(&plain, &cache, &far, (W, 0), 0.0).is_err());
}

#[test]
fn the_async_cache_converges_to_the_blocking_cache_s_masked_image() {
    let f = files(Codec::Lz4);
    for poe in [0.0f32, 2.0] {
        let (scene, cache) = Cache::open(
            &f.both,
            None,
            CacheKind::Async,
            64 << 20,
            &AsyncOptions::default(),
            None,
        )
        .unwrap();
        select(&scene, hide(&["right"]));
        let settled = session::settle(&scene, &cache, &camera(), &opts(poe)).unwrap();
        assert!(settled.complete);
        same_image(
            &settled.frame.image,
            &frame(&scene, poe),
            &format!("async against blocking at PoE {poe}"),
        );
    }
}

#[test]
fn hiding_and_isolating_give_the_same_image_in_every_cache_mode() {
    // Uncompressed: the mmap cache maps blocks in place.
    let f = files(Codec::None);
    let without = frame(&open(&f.left), 0.0);
    for (name, scene, cache) in caches(&f.both) {
        for sel in [
            hide(&["right"]),
            PartSelection {
                isolate: vec!["left".into()],
                ..PartSelection::default()
            },
        ] {
            select(&scene, sel);
            let image = if cache.kind() == CacheKind::Async {
                let settled = session::settle(&scene, &cache, &camera(), &opts(0.0)).unwrap();
                assert!(settled.complete, "{name}");
                settled.frame.image
            } else {
                render(&scene, cache.get(), &camera(), &opts(0.0))
                    .unwrap()
                    .0
            };
            same_image(&image, &without, &format!("{name}: the left sphere alone"));
        }
    }
}

#[test]
fn packets_and_single_rays_agree_under_a_filter() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("cad.obj");
    let opts = oocfmt_scenes::cad::CadOptions {
        triangles: 30_000,
        seed: 3,
        normals: false,
        parts: None,
    };
    oocfmt_scenes::cad::write_obj(&obj, &opts, &mut |_, _| {}).unwrap();
    let path = dir.path().join("cad.oocf");
    common::convert_obj(&obj, &path);
    let scene = open(&path);
    let parts = &scene.metadata().parts;
    assert!(parts.len() > 10, "{} parts", parts.len());
    // Every other top-level assembly, with what is under it.
    let globs: Vec<String> = parts
        .iter()
        .filter(|p| p.parent.is_none())
        .step_by(2)
        .map(|p| p.name.clone())
        .collect();
    let filter = PartFilter::new(
        parts,
        &PartSelection {
            hide: globs,
            ..PartSelection::default()
        },
    )
    .unwrap();
    assert!(filter.hidden() > 0 && filter.hidden() < parts.len());
    let m = scene.metadata();
    let cam = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, 64, 48);
    let f = cam.frame().unwrap();
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    for poe in [0.0f64, 3.0] {
        let tracer = Tracer::new(&scene, &cache, (poe * f.pixel_angle()) as f32);
        let plain = Tracer::new(&scene, &cache, (poe * f.pixel_angle()) as f32);
        let tracer = tracer.with_parts(&filter);
        let memo = Memo::new(&scene);
        let (mut hidden_hits, mut differ) = (0, 0);
        for y in (0..48).step_by(2) {
            for x in (0..64).step_by(2) {
                let rays = [
                    f.ray(x, y),
                    f.ray(x + 1, y),
                    f.ray(x, y + 1),
                    f.ray(x + 1, y + 1),
                ];
                let packet = tracer.trace_packet(&rays, &[0, 1, 2, 3], &memo);
                memo.release_deferred(u32::MAX);
                for (ray, hp) in rays.iter().zip(&packet) {
                    let hs = tracer.trace(ray, &memo);
                    let key = |h: &Option<oocfmt_trace::traverse::Hit>| {
                        h.as_ref().map(|h| (h.t.to_bits(), h.part))
                    };
                    assert_eq!(key(hp), key(&hs), "PoE {poe}, pixel {x},{y}");
                    assert!(!filter.hides(hs.as_ref().and_then(|h| h.part)));
                    let unmasked = plain.trace(ray, &memo);
                    if filter.hides(unmasked.as_ref().and_then(|h| h.part)) {
                        hidden_hits += 1;
                    }
                    if key(&unmasked) != key(&hs) {
                        differ += 1;
                    }
                }
            }
        }
        assert!(hidden_hits > 0 && differ >= hidden_hits, "PoE {poe}");
    }
}

/// The nodes a frame's rays visit with `o` (primary, shadow and AO rays), with the scene's
/// filter.
fn nodes(scene: &Arc<Scene>, o: &RenderOptions) -> u64 {
    let cache = BlockingCache::new(Arc::clone(scene), usize::MAX);
    render(scene, &cache, &camera(), o).unwrap().1.nodes_visited
}

/// Lit from the right, beyond the right sphere (which shadows the left one), with ambient
/// occlusion; the light and the occlusion distance fixed, as the defaults follow the file's
/// box.
fn lit(poe: f32) -> RenderOptions {
    RenderOptions {
        shadows: true,
        light: Some([12.0, 0.5, 1.0]),
        ao: 4,
        ao_distance: Some(2.5),
        ..opts(poe)
    }
}

#[test]
fn a_hidden_region_is_skipped_whole_and_costs_about_what_the_file_without_it_does() {
    let f = files(Codec::Lz4);
    let both = open(&f.both);
    let left = open(&f.left);
    for o in [opts(0.0), opts(2.0), lit(0.0)] {
        let all = nodes(&both, &o);
        select(&both, hide(&["right"]));
        let hidden = nodes(&both, &o);
        select(&both, PartSelection::default());
        let alone = nodes(&left, &o);
        // Walking the hidden sphere down to its leaves would cost what drawing it does: the
        // grid stops the rays at its region's top nodes instead.
        assert!(
            (hidden as f64) < 0.6 * all as f64,
            "PoE {}: {hidden} nodes hidden, {all} shown",
            o.poe
        );
        assert!(
            (hidden as f64) < 1.4 * alone as f64,
            "PoE {}: {hidden} nodes hidden, {alone} in the file without it",
            o.poe
        );
    }
    let grid = PartFilter::new(&both.metadata().parts, &hide(&["right"])).unwrap();
    let g = grid.grid().expect("a part is hidden: a grid");
    assert!(g.marked() > 0 && g.cells().iter().all(|&n| n >= 1));
    assert!(
        PartFilter::new(&both.metadata().parts, &PartSelection::default())
            .unwrap()
            .grid()
            .is_none()
    );
}

#[test]
fn shadow_and_occlusion_rays_pass_a_hidden_part_as_if_the_file_lacked_it() {
    let f = files(Codec::Lz4);
    let both = open(&f.both);
    let cache = BlockingCache::new(Arc::clone(&both), usize::MAX);
    let shown = render(&both, &cache, &camera(), &lit(0.0)).unwrap().0;
    select(&both, hide(&["right"]));
    let cache = BlockingCache::new(Arc::clone(&both), usize::MAX);
    let hidden = render(&both, &cache, &camera(), &lit(0.0)).unwrap().0;
    let left = open(&f.left);
    let cache = BlockingCache::new(Arc::clone(&left), usize::MAX);
    let alone = render(&left, &cache, &camera(), &lit(0.0)).unwrap().0;
    same_image(
        &hidden,
        &alone,
        "shadows and AO with the right sphere hidden",
    );
    // The right sphere did shadow the left one: the left half changes when it is hidden.
    let left_half = |img: &Image| -> Vec<u8> {
        (0..H)
            .flat_map(|y| (0..W / 2).map(move |x| (y * W + x) as usize))
            .flat_map(|k| img.rgb[3 * k..3 * k + 3].to_vec())
            .collect()
    };
    assert_ne!(left_half(&shown), left_half(&alone), "a shadow to lift");
}

#[test]
fn packets_visit_the_nodes_single_rays_do_under_a_filter() {
    let f = files(Codec::Lz4);
    let scene = open(&f.both);
    let filter = PartFilter::new(&scene.metadata().parts, &hide(&["right"])).unwrap();
    let cam = camera();
    let fr = cam.frame().unwrap();
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    for poe in [0.0f64, 2.0] {
        let tracer =
            Tracer::new(&scene, &cache, (poe * fr.pixel_angle()) as f32).with_parts(&filter);
        let mut memo = Memo::new(&scene);
        let (mut packets, mut singles) = (0u64, 0u64);
        for y in (0..H).step_by(2) {
            for x in (0..W).step_by(2) {
                let rays = [
                    fr.ray(x, y),
                    fr.ray(x + 1, y),
                    fr.ray(x, y + 1),
                    fr.ray(x + 1, y + 1),
                ];
                let hits = tracer.trace_packet(&rays, &[0, 1, 2, 3], &memo);
                memo.release_deferred(u32::MAX);
                let p = memo.take_visited();
                let mut s = 0;
                for (ray, hp) in rays.iter().zip(&hits) {
                    let hs = tracer.trace(ray, &memo);
                    s += memo.take_visited();
                    let key = |h: &Option<oocfmt_trace::traverse::Hit>| {
                        h.as_ref().map(|h| (h.t.to_bits(), h.part))
                    };
                    assert_eq!(key(hp), key(&hs), "PoE {poe}, pixel {x},{y}");
                }
                assert_eq!(p, s, "PoE {poe}, packet at {x},{y}: nodes visited");
                (packets, singles) = (packets + p, singles + s);
            }
        }
        assert!(packets > 0 && packets == singles);
    }
}
