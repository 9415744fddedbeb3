//! The tracer against a brute-force reference: at --poe 0 with the blocking cache the depth
//! image is the nearest hit over every triangle; at --poe > 0 voxels stand in for detail but
//! no pixel goes missing; a corrupted block is survived and reported.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;

use std::path::Path;
use std::sync::Arc;

use oocfmt::BlockKind;
use oocfmt_trace::compare;
use oocfmt_trace::{render, BlockingCache, Camera, RenderOptions, Scene};

const W: u32 = 81;
const H: u32 = 61;

fn cameras(scene: &Scene) -> Vec<Camera> {
    let m = scene.metadata();
    let (lo, hi) = (m.scene.bounds_min, m.scene.bounds_max);
    let framing = Camera::framing(lo, hi, W, H);
    let c = [0, 1, 2].map(|k| (f64::from(lo[k]) + f64::from(hi[k])) / 2.0);
    let ext = (0..3).map(|k| f64::from(hi[k] - lo[k])).fold(0.0, f64::max);
    // Straight down the z axis through the box centre, close: the middle column and row of
    // rays have direction components of exactly ±0.
    let axis = Camera {
        eye: [c[0], c[1], c[2] + 0.9 * ext],
        look_at: c,
        up: [0.0, 1.0, 0.0],
        fov_y: 50.0,
        width: W,
        height: H,
    };
    // The model off to one side, partly out of the image: most tiles see only background and
    // are filled without a ray (`oocfmt_trace::reach`), and the box's edge crosses others.
    let aside = Camera {
        look_at: [c[0] + 0.45 * ext, c[1] - 0.35 * ext, c[2]],
        ..framing
    };
    vec![framing, axis, aside]
}

/// What a render at one PoE gave against brute force, over every camera.
#[derive(Default)]
struct Outcome {
    /// Pixels whose depth differs (relative error over 1e-5, or hit against miss).
    differ: usize,
    /// Pixels the reference hits that the render misses.
    holes: usize,
    /// Rays ending on voxels.
    voxels: u64,
}

/// Renders at each of `poes` from every camera and compares the depths with brute force
/// (computed once per camera).
fn compare(path: &Path, poes: &[f32]) -> Vec<Outcome> {
    let scene = Arc::new(Scene::open(path).unwrap());
    let triangles = Arc::new(common::all_triangles(&scene));
    let mut out: Vec<Outcome> = poes.iter().map(|_| Outcome::default()).collect();
    for cam in cameras(&scene) {
        let frame = cam.frame().unwrap();
        let rays: Vec<_> = (0..H)
            .flat_map(|y| (0..W).map(move |x| (x, y)))
            .map(|(x, y)| frame.ray(x, y))
            .collect();
        let reference = common::brute_force(&rays, &triangles);
        assert!(
            reference.iter().any(|d| d.is_finite()),
            "the camera sees the model"
        );
        for (o, &poe) in out.iter_mut().zip(poes) {
            let cache = BlockingCache::new(Arc::clone(&scene), 256 << 20);
            let opts = RenderOptions {
                poe,
                ..RenderOptions::default()
            };
            let (img, stats) = render(&scene, &cache, &cam, &opts).unwrap();
            assert!(stats.cache.missing_blocks.is_empty(), "{stats:?}");
            o.voxels += stats.primary.voxel;
            for (&got, &want) in img.depth.iter().zip(&reference) {
                let same = if want.is_finite() {
                    got.is_finite() && ((got - want) / want).abs() <= 1e-5
                } else {
                    got.is_infinite()
                };
                o.differ += usize::from(!same);
                o.holes += usize::from(want.is_finite() && !got.is_finite());
            }
        }
    }
    out
}

fn assert_exact(o: &Outcome) {
    let pixels = 3 * (W * H) as usize;
    assert_eq!(o.voxels, 0, "--poe 0 never stops on a voxel");
    assert!(
        o.differ as f64 <= pixels as f64 * 1e-4,
        "{} of {pixels} pixels differ from brute force",
        o.differ
    );
}

#[test]
fn mandelbulb_depth_at_poe_0_equals_brute_force_and_poe_4_is_complete() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 20_000);
    let out = compare(&path, &[0.0, 4.0]);
    assert_exact(&out[0]);
    assert!(out[1].voxels > 0, "--poe 4 uses voxels");
    assert_eq!(out[1].holes, 0, "a coarse picture is still complete");
}

#[test]
fn cad_depth_at_poe_0_equals_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::cad_scene(dir.path(), 20_000);
    assert_exact(&compare(&path, &[0.0])[0]);
}

#[test]
fn a_corrupted_triangle_block_renders_and_is_reported() {
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
    let cache = BlockingCache::new(Arc::clone(&scene), 64 << 20);
    let m = scene.metadata();
    let cam = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, W, H);
    let (img, stats) = render(&scene, &cache, &cam, &RenderOptions::default()).unwrap();
    let missing: Vec<u32> = stats.cache.missing_blocks.iter().map(|b| b.id).collect();
    assert_eq!(missing, vec![id], "{:?}", stats.cache.missing_blocks);
    assert!(
        stats.cache.missing_blocks[0]
            .error
            .contains("BLOCK_CHECKSUM")
            || stats.cache.missing_blocks[0]
                .error
                .to_lowercase()
                .contains("checksum"),
        "{:?}",
        stats.cache.missing_blocks
    );
    assert_eq!(img.rgb.len(), (3 * W * H) as usize);
    assert!(stats.primary.triangle > 0);
}

#[test]
fn a_tiny_cache_stays_within_its_budget_and_gives_the_same_image() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 5_000);
    let scene = Arc::new(Scene::open(&path).unwrap());
    // Decoded sizes of every block: the budget is a third of them, but at least the largest.
    let sizes: Vec<usize> = (0u32..)
        .zip(scene.reader().entries())
        .filter_map(|(id, e)| match e.kind {
            BlockKind::Treelet => Some(scene.load_treelets(id).unwrap().bytes()),
            BlockKind::Triangle => Some(scene.load_triangles(id).unwrap().bytes()),
            _ => None,
        })
        .collect();
    let total: usize = sizes.iter().sum();
    let budget = (total / 3).max(sizes.iter().copied().max().unwrap());
    let m = scene.metadata();
    let cam = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, W, H);
    let big = BlockingCache::new(Arc::clone(&scene), 256 << 20);
    let (a, full) = render(&scene, &big, &cam, &RenderOptions::default()).unwrap();
    assert_eq!(full.cache.blocks_evicted, 0);
    let tiny = BlockingCache::new(Arc::clone(&scene), budget);
    let (b, stats) = render(&scene, &tiny, &cam, &RenderOptions::default()).unwrap();
    assert_eq!(a.depth, b.depth);
    assert_eq!(a.rgb, b.rgb);
    assert!(stats.cache.blocks_evicted > 0, "{:?}", stats.cache);
    assert!(
        stats.cache.peak_bytes_resident <= budget as u64,
        "peak {} over the budget {budget}",
        stats.cache.peak_bytes_resident
    );
}

#[test]
fn the_supersampled_reference_differs_from_full_detail_on_the_model_only() {
    // The true picture of the error measures: full detail at 16 stratified rays per pixel.
    // Against it, the one-ray full-detail image (the aliasing floor) differs only where
    // either image shows the model: elsewhere both are the background, exactly. So the whole
    // image's squared error is the model's, and its RMSE the model's times √(model / all).
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 20_000);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let m = scene.metadata();
    let cam = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, W, H);
    let cache = BlockingCache::new(Arc::clone(&scene), 256 << 20);
    let one = RenderOptions::default();
    let sixteen = RenderOptions { spp: 16, ..one };
    let (floor, _) = render(&scene, &cache, &cam, &one).unwrap();
    let (reference, _) = render(&scene, &cache, &cam, &sixteen).unwrap();
    // With one ray the model's pixels are the centre hits; with more, the centre hits and
    // the pixels a sample ray hit besides (the silhouette's edge).
    let hits: Vec<bool> = floor.depth.iter().map(|d| d.is_finite()).collect();
    assert_eq!(floor.model, hits);
    assert!(reference.model.iter().zip(&hits).all(|(m, h)| *m || !*h));
    let edge = reference.model.iter().filter(|m| **m).count() - hits.iter().filter(|h| **h).count();
    assert!(
        edge > 0,
        "sample rays find the model beyond the centre hits"
    );
    let e = compare::compare(&reference, &floor, 8).unwrap();
    assert_eq!(e.whole.pixels, u64::from(W * H));
    let model = reference.model.iter().filter(|m| **m).count() as u64;
    assert_eq!(e.model.pixels, model);
    assert!(e.model.rmse > 0.0, "one ray per pixel aliases: {e:?}");
    let ratio = (e.model.pixels as f64 / e.whole.pixels as f64).sqrt();
    assert!((e.whole.rmse - e.model.rmse * ratio).abs() < 1e-9, "{e:?}");
    // SSIM and the share within tolerance are diluted too: closer to 1 over the whole image.
    assert!(e.whole.ssim >= e.model.ssim && e.whole.within_tolerance >= e.model.within_tolerance);
    // A reference of one ray is the floor itself.
    let same = compare::compare(&floor, &floor, 0).unwrap();
    assert_eq!(
        (same.model.rmse, same.model.bias, same.model.ssim),
        (0.0, 0.0, 1.0)
    );
}
