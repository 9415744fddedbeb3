//! The `render_file` property: whatever a file holds, the tracer renders frames of it in each
//! cache mode (at full detail and at PoE 2, with shadow and ambient-occlusion rays) without
//! panicking, without NaN in the depth image, within the node bound of spec §12 ("Following
//! LOD links"), and in bounded time. It follows the tree the way only a deep
//! verify otherwise does, so it covers what the format targets cannot: the tracer's decoders
//! and the traversal over blocks that are each well formed but do not make a tree.
//!
//! The only copy of the target body: `fuzz_targets/render_file.rs` calls it through the
//! `oocfmt_fuzz` library, and `crates/oocfmt-trace/tests/trace/fuzz_corpus.rs` includes it by path
//! (with `props.rs`, whose re-sealing it uses) to replay the inputs on stable.

use std::sync::Arc;

use oocfmt::{Checksums, ReadOptions, Reader};
use oocfmt_trace::{render, AsyncCache, BlockCache, BlockingCache, Camera, RenderOptions, Scene};

use super::props::reseal_with_blocks;

/// Small enough for many executions a second, large enough for packets and single rays.
const W: u32 = 12;
const H: u32 = 9;
/// Decoded bytes each cache may hold.
const BUDGET: usize = 8 << 20;

/// `render_file`: the bytes as a whole file, as given and with every checksum recomputed (so
/// that mutations inside blocks reach the decoders and the traversal).
pub fn render_file(data: &[u8]) {
    render_bytes(data.to_vec());
    if let Some(sealed) = reseal_with_blocks(data) {
        if sealed != data {
            render_bytes(sealed);
        }
    }
}

fn render_bytes(bytes: Vec<u8>) {
    let opts = ReadOptions {
        checksums: Checksums::Skip,
        ..ReadOptions::default()
    };
    let Ok(reader) = Reader::from_source(Box::new(bytes), Arc::from("fuzz"), opts) else {
        return;
    };
    let scene = Arc::new(Scene::from_reader(reader));
    let m = scene.metadata();
    let camera = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, W, H);
    let blocking = BlockingCache::new(Arc::clone(&scene), BUDGET);
    // Full detail with shadows; LOD with its translucent layers, alone and with a shadow ray
    // and two ambient-occlusion rays from every layer.
    for (poe, shadows, ao) in [(0.0, true, 0), (2.0, false, 0), (2.0, true, 2)] {
        frame(&scene, &blocking, &camera, poe, (shadows, ao));
    }
    // The asynchronous cache: a cold frame on what is loaded, then one on everything asked for.
    let cache = AsyncCache::new(Arc::clone(&scene), BUDGET, 1);
    for _ in 0..2 {
        frame(&scene, &cache, &camera, 0.0, (false, 0));
        cache.wait_for_fetchers();
        cache.end_frame();
    }
}

/// One frame at `poe`, with shadow rays or not and `ao` ambient-occlusion rays per hit.
fn frame(
    scene: &Scene,
    cache: &dyn BlockCache,
    camera: &Camera,
    poe: f32,
    (shadows, ao): (bool, u32),
) {
    let opts = RenderOptions {
        poe,
        shadows,
        ao,
        ..RenderOptions::default()
    };
    // A camera or options the renderer refuses (a scene box of infinities) is an error, not a
    // frame: nothing to check.
    let Ok((image, stats)) = render(scene, cache, camera, &opts) else {
        return;
    };
    assert_eq!(image.rgb.len(), 3 * (W * H) as usize);
    assert!(
        image.depth.iter().all(|d| !d.is_nan()),
        "NaN in the depth image"
    );
    assert!(
        stats.nodes_visited <= stats.rays.saturating_mul(scene.node_bound()),
        "{} nodes visited by {} rays: over the bound of {} a ray",
        stats.nodes_visited,
        stats.rays,
        scene.node_bound()
    );
}
