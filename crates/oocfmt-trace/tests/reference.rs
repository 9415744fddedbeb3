//! The tracer against a brute-force reference: at --poe 0 with the blocking cache the depth
//! image is the nearest hit over every triangle; at --poe > 0 voxels stand in for detail but
//! no pixel goes missing; a corrupted block is survived and reported.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::Path;
use std::sync::Arc;

use oocfmt::BlockKind;
use oocfmt_trace::{render, BlockingCache, Camera, RenderOptions, Scene};

const W: u32 = 101;
const H: u32 = 75;

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
    vec![framing, axis]
}

/// Renders at `poe` and compares the depths with brute force: returns (pixels differing,
/// pixels the reference hits that the render misses, rays ending on voxels).
fn compare(path: &Path, poe: f32) -> (usize, usize, u64) {
    let scene = Arc::new(Scene::open(path).unwrap());
    let triangles = Arc::new(common::all_triangles(&scene));
    let (mut differ, mut holes, mut voxels) = (0, 0, 0);
    for cam in cameras(&scene) {
        let cache = BlockingCache::new(Arc::clone(&scene), 256 << 20);
        let opts = RenderOptions {
            poe,
            ..RenderOptions::default()
        };
        let (img, stats) = render(&scene, &cache, &cam, &opts).unwrap();
        assert!(stats.cache.missing_blocks.is_empty(), "{stats:?}");
        voxels += stats.primary.voxel;
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
        for (&got, &want) in img.depth.iter().zip(&reference) {
            let same = if want.is_finite() {
                got.is_finite() && ((got - want) / want).abs() <= 1e-5
            } else {
                got.is_infinite()
            };
            differ += usize::from(!same);
            holes += usize::from(want.is_finite() && !got.is_finite());
        }
    }
    (differ, holes, voxels)
}

fn assert_exact(path: &Path) {
    let (differ, _, voxels) = compare(path, 0.0);
    let pixels = 2 * (W * H) as usize;
    assert_eq!(voxels, 0, "--poe 0 never stops on a voxel");
    assert!(
        differ as f64 <= pixels as f64 * 1e-4,
        "{differ} of {pixels} pixels differ from brute force"
    );
}

#[test]
fn mandelbulb_depth_at_poe_0_equals_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 20_000);
    assert_exact(&path);
    let (_, holes, voxels) = compare(&path, 4.0);
    assert!(voxels > 0, "--poe 4 uses voxels");
    assert_eq!(holes, 0, "a coarse picture is still complete");
}

#[test]
fn cad_depth_at_poe_0_equals_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::cad_scene(dir.path(), 20_000);
    assert_exact(&path);
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
    let m = scene.metadata();
    let cam = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, W, H);
    let big = BlockingCache::new(Arc::clone(&scene), 256 << 20);
    let (a, _) = render(&scene, &big, &cam, &RenderOptions::default()).unwrap();
    let budget = 300 << 10;
    let tiny = BlockingCache::new(Arc::clone(&scene), budget);
    let (b, stats) = render(&scene, &tiny, &cam, &RenderOptions::default()).unwrap();
    assert_eq!(a.rgb, b.rgb);
    assert!(stats.cache.blocks_evicted > 0, "{:?}", stats.cache);
    assert!(stats.cache.bytes_resident <= budget as u64 || stats.cache.blocks_evicted > 0);
}
