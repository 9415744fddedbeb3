//! Files whose LOD links break the tree's rules, though every block is well formed on its own:
//! the tracer must finish every frame (spec §12, "Following LOD links"). A block's checksum
//! does not protect a traversal (a writer with a bug, or anyone, can compute one), so these
//! tests change LOD nodes in an uncompressed container and read it without block checksums.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::sync::Arc;
use std::time::Duration;

use oocfmt::records::node::Node;
use oocfmt::{BlockKind, Checksums, Codec, ReadOptions, Reader};
use oocfmt_build::layout::LayoutOptions;
use oocfmt_trace::{
    render, AsyncCache, BlockCache, BlockingCache, Camera, FrameStats, RenderOptions, Scene,
};

/// A LOD node of a file: where it is and what holds it.
struct LodSite {
    block: u32,
    level: u16,
    treelet: u32,
    /// The node is its treelet's root.
    root: bool,
    /// Its first byte in the file.
    at: usize,
}

fn uncompressed(dir: &Path, triangles: u64, treelet_height: u8) -> PathBuf {
    let mut layout = LayoutOptions {
        treelet_height,
        ..LayoutOptions::default()
    };
    layout.write.codec = Codec::None;
    common::mandelbulb_with(dir, triangles, layout)
}

fn lod_sites(path: &Path) -> Vec<LodSite> {
    let reader = Reader::open(path, ReadOptions::default()).unwrap();
    let mut sites = Vec::new();
    for (id, e) in (0u32..).zip(reader.entries()) {
        if e.kind != BlockKind::Treelet {
            continue;
        }
        let block = reader.read_block(id).unwrap();
        let tb = block.treelets().unwrap();
        let nodes_at = e.offset as usize + 16 + 4 * tb.treelet_count();
        tb.walk(|t, pos, node| {
            if let Node::Lod { .. } = node {
                sites.push(LodSite {
                    block: id,
                    level: e.level,
                    treelet: t as u32,
                    root: tb.treelet_span(t)?.start == pos,
                    at: nodes_at + pos,
                });
            }
            Ok(())
        })
        .unwrap();
    }
    sites
}

/// Makes the LOD node at `at` split on x at `split` (when given) with both children present,
/// the first being treelet `treelet` of `block`.
fn relink(bytes: &mut [u8], at: usize, split: Option<f32>, treelet: u32, block: u32) {
    let word = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    let word = match split {
        // Type 1, axis x, both children present.
        Some(s) => {
            bytes[at + 4..at + 8].copy_from_slice(&s.to_le_bytes());
            1
        }
        None => word & 0xFF,
    } | treelet << 8;
    bytes[at..at + 4].copy_from_slice(&word.to_le_bytes());
    bytes[at + 12..at + 16].copy_from_slice(&block.to_le_bytes());
}

fn open_without_block_checksums(path: &Path) -> Arc<Scene> {
    let opts = ReadOptions {
        checksums: Checksums::Skip,
        ..ReadOptions::default()
    };
    Arc::new(Scene::from_reader(Reader::open(path, opts).unwrap()))
}

/// Runs `f` on another thread and fails when it takes over a minute: without the rules these
/// tests check, the frames below take hours or never end.
fn within_a_minute<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(60))
        .unwrap_or_else(|_| panic!("{what} did not finish within a minute"))
}

fn frame(scene: &Scene, cache: &dyn BlockCache, w: u32, h: u32, shadows: bool) -> FrameStats {
    let m = scene.metadata();
    let cam = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, w, h);
    let opts = RenderOptions {
        shadows,
        ..RenderOptions::default()
    };
    let (img, stats) = render(scene, cache, &cam, &opts).unwrap();
    assert_eq!(img.rgb.len(), (3 * w * h) as usize);
    assert!(img.depth.iter().all(|d| !d.is_nan()));
    stats
}

#[test]
fn a_lod_link_that_is_not_to_the_next_level_makes_its_block_missing_and_the_frame_ends() {
    let dir = tempfile::tempdir().unwrap();
    let path = uncompressed(dir.path(), 20_000, 3);
    let sites = lod_sites(&path);
    let triangle_block = (0u32..)
        .zip(
            Reader::open(&path, ReadOptions::default())
                .unwrap()
                .entries(),
        )
        .find(|(_, e)| e.kind == BlockKind::Triangle)
        .map(|(id, _)| id)
        .unwrap();
    let original = std::fs::read(&path).unwrap();
    // Every LOD node links back to its own treelet (a cycle: without the check a ray descends
    // for ever), or to a triangle block.
    let cycle = |s: &LodSite| (s.treelet, s.block);
    let triangles = |_: &LodSite| (0, triangle_block);
    for (name, link, code) in [
        (
            "cycle",
            &cycle as &dyn Fn(&LodSite) -> (u32, u32),
            "TREE_LEVEL",
        ),
        ("triangle block", &triangles, "TREE_REFERENCE"),
    ] {
        let mut bytes = original.clone();
        for s in &sites {
            let (treelet, block) = link(s);
            relink(&mut bytes, s.at, None, treelet, block);
        }
        std::fs::write(&path, &bytes).unwrap();
        let scene = open_without_block_checksums(&path);
        let root = scene.metadata().root.unwrap().block;
        let (blocking, asynchronous) = within_a_minute(name, move || {
            let blocking = BlockingCache::new(Arc::clone(&scene), 64 << 20);
            // Primary rays go through the packet traversal, shadow rays one by one.
            let b = frame(&scene, &blocking, 64, 48, true);
            let cache = AsyncCache::new(Arc::clone(&scene), 64 << 20, 2);
            for _ in 0..3 {
                frame(&scene, &cache, 64, 48, false);
                cache.wait_for_fetchers();
                cache.end_frame();
            }
            (b, cache.stats())
        });
        for missing in [&blocking.cache.missing_blocks, &asynchronous.missing_blocks] {
            let m = missing.iter().find(|m| m.id == root);
            let m =
                m.unwrap_or_else(|| panic!("{name}: the root block is not missing: {missing:?}"));
            assert!(m.error.contains(code), "{name}: {m:?}");
        }
    }
}

#[test]
fn a_ray_visits_no_more_nodes_than_the_treelet_blocks_hold_when_treelets_are_shared() {
    let dir = tempfile::tempdir().unwrap();
    // One node per treelet: every inner node is a LOD node, so the tree has about 25 levels.
    let path = uncompressed(dir.path(), 20_000, 1);
    let sites = lod_sites(&path);
    let m = Reader::open(&path, ReadOptions::default())
        .unwrap()
        .metadata()
        .clone();
    let mid = 0.5 * (m.scene.bounds_min[0] + m.scene.bounds_max[0]);
    // Per level, a treelet t of some block whose treelets t and t + 1 are both LOD nodes.
    let mut pair = std::collections::BTreeMap::new();
    for (s, next) in sites.iter().zip(sites.iter().skip(1)) {
        if s.root && next.root && s.block == next.block && next.treelet == s.treelet + 1 {
            pair.entry(s.level).or_insert((s.treelet, s.block));
        }
    }
    // Every LOD node of a level splits on the same plane and links to the same pair of the next
    // level. A ray across the plane reaches each shared treelet once more per level: about 2^25
    // visits per ray, where a tree lets it meet each node once.
    let mut bytes = std::fs::read(&path).unwrap();
    let mut relinked = 0;
    for s in &sites {
        if let Some(&(treelet, block)) = pair.get(&(s.level + 1)) {
            relink(&mut bytes, s.at, Some(mid), treelet, block);
            relinked += 1;
        }
    }
    assert!(pair.len() >= 20, "{} levels with a pair", pair.len());
    assert!(relinked > 1000, "{relinked}");
    std::fs::write(&path, &bytes).unwrap();
    let scene = open_without_block_checksums(&path);
    let bound = scene.node_bound();
    let stats = within_a_minute("the shared treelets' frame", move || {
        let cache = BlockingCache::new(Arc::clone(&scene), 64 << 20);
        frame(&scene, &cache, 8, 6, true)
    });
    assert!(stats.rays >= 48, "{stats:?}");
    assert!(
        stats.nodes_visited <= stats.rays * bound,
        "{} nodes visited by {} rays, bound {bound} each",
        stats.nodes_visited,
        stats.rays
    );
}
