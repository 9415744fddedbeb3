//! Writes containers and reads them back through `oocfmt::Reader`, checking the layout rules
//! from the outside: every block decodes, references land where the spec says, counts match.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use oocfmt::metadata::Metadata;
use oocfmt::records::{Node, TreeletBlock, NO_PROXY};
use oocfmt::{BlockKind, Codec, ReadOptions, Reader, WriteOptions};

use super::*;
use crate::kdtree::{build, KdBuildOptions, KdNode, NodeId};
use oocfmt_scenes::demo_scene;

pub(super) type Res<T> = std::result::Result<T, String>;

pub(super) fn s<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

pub(super) fn opts(block_size: u64, codec: Codec, treelet_height: u8) -> LayoutOptions {
    let write = WriteOptions {
        codec,
        ..WriteOptions::default()
    }
    .with_block_size(block_size);
    LayoutOptions {
        write: write.unwrap_or_default(),
        treelet_height,
        generator: "layout tests".into(),
        sources: vec!["demo".into()],
        ..LayoutOptions::default()
    }
}

/// What reading a container back found.
#[derive(Debug, Default)]
pub(super) struct Found {
    pub(super) meta: Metadata,
    pub(super) treelet_blocks: usize,
    pub(super) triangle_blocks: usize,
    pub(super) proxy_blocks: usize,
    pub(super) compressed_blocks: usize,
    /// Mesh triangles some leaf reaches.
    pub(super) reached: HashSet<usize>,
    /// Mesh triangle ids of every primary copy, over all blocks.
    pub(super) primaries: Vec<usize>,
    /// The part word of every LOD entry, in file order (`None` without `PART_IDS`).
    pub(super) lod_parts: Vec<Option<u32>>,
}

pub(super) fn triangle_ids(mesh: &Mesh) -> HashMap<[[u32; 3]; 3], Vec<usize>> {
    let mut map: HashMap<[[u32; 3]; 3], Vec<usize>> = HashMap::new();
    for t in 0..mesh.triangles.len() {
        if let Some(c) = mesh.corners(t) {
            map.entry(c.map(|p| p.map(f32::to_bits)))
                .or_default()
                .push(t);
        }
    }
    map
}

/// Opens `path`, decodes every block, walks the tree from the root and checks the layout rules;
/// every triangle record (copies included) must carry the part id of its mesh triangle.
pub(super) fn read_back(path: &Path, mesh: &Mesh) -> Res<Found> {
    let reader = Reader::open(path, ReadOptions::default()).map_err(s)?;
    let meta = reader.metadata().clone();
    let mut r = ReadBack {
        reader: &reader,
        attrs: meta.triangle_attributes(),
        mesh,
        ids: triangle_ids(mesh),
        found: Found {
            meta: meta.clone(),
            ..Found::default()
        },
    };
    let (blocks, mut sums, six) = r.decode_blocks()?;
    if sums.proxies != reader.proxies().len() as u64 {
        return Err("the reader's resident proxies differ from the proxy blocks".into());
    }
    let walked = r.walk_tree(&blocks)?;
    sums.depth = walked.depth;
    sums.lod_levels = walked.levels;
    let (max_proxied_level, min_unproxied_level) =
        (walked.max_proxied_level, walked.min_unproxied_level);
    if min_unproxied_level != u32::MAX && max_proxied_level > min_unproxied_level {
        return Err(format!(
            "a proxy at level {max_proxied_level}, a LOD node without one at level {min_unproxied_level}"
        ));
    }
    if walked.treelets as u64 != sums.treelets {
        return Err(format!(
            "{} of {} treelets reachable",
            walked.treelets, sums.treelets
        ));
    }
    if sums != meta.counts {
        return Err(format!(
            "metadata counts {:?}\n  blocks hold {sums:?}",
            meta.counts
        ));
    }
    if six != meta.schema.six_sample_voxels {
        return Err("six_sample_voxels flag disagrees with the voxels".into());
    }
    let mut found = r.found;
    found.meta = meta;
    Ok(found)
}

/// A container being read back, and what was found in it so far.
struct ReadBack<'a> {
    reader: &'a Reader,
    attrs: u16,
    mesh: &'a Mesh,
    ids: HashMap<[[u32; 3]; 3], Vec<usize>>,
    found: Found,
}

/// What the walk from the root found: the treelets reached, the deepest node level, the LOD
/// levels, and the finest level with a proxy and the coarsest with a LOD node without one.
struct Walked {
    treelets: usize,
    depth: u32,
    levels: u32,
    max_proxied_level: u32,
    min_unproxied_level: u32,
}

impl ReadBack<'_> {
    /// The mesh triangle stored with corners `pos`.
    fn lookup(&self, pos: [[f32; 3]; 3]) -> Res<usize> {
        self.ids
            .get(&pos.map(|p| p.map(f32::to_bits)))
            .and_then(|v| v.first().copied())
            .ok_or_else(|| format!("stored triangle {pos:?} is not in the mesh"))
    }

    /// Decodes every block in file order, checking the order of kinds: returns them with what
    /// their records add up to, and whether some voxel has six samples.
    fn decode_blocks(&mut self) -> Res<(Vec<oocfmt::Block>, Counts, bool)> {
        let (reader, attrs) = (self.reader, self.attrs);
        let mut blocks = Vec::new();
        let mut sums = Counts::default();
        let mut six = false;
        let mut last_kind = BlockKind::Treelet;
        for id in 0..reader.entries().len() as u32 {
            let block = reader.read_block(id).map_err(s)?;
            if block.entry.kind < last_kind {
                return Err(format!(
                    "block {id}: a {:?} block after a {last_kind:?} block",
                    block.entry.kind
                ));
            }
            last_kind = block.entry.kind;
            if block.entry.codec != oocfmt::CodecId::None {
                self.found.compressed_blocks += 1;
            }
            match block.entry.kind {
                BlockKind::Treelet => {
                    self.found.treelet_blocks += 1;
                    let t = block.treelets().map_err(s)?;
                    let lod_parts = &mut self.found.lod_parts;
                    let sum = t
                        .walk_lods(|_, _, n, entry| {
                            if let Node::Lod { voxel_offset, .. } = n {
                                six |= matches!(t.voxel(*voxel_offset), Ok(Voxel::Six(_, _)));
                                lod_parts.push(entry.part);
                            }
                            Ok(())
                        })
                        .map_err(s)?;
                    sums.treelets += sum.treelets;
                    sums.basic_nodes += sum.basic_nodes;
                    sums.lod_nodes += sum.lod_nodes;
                    sums.leaves += sum.leaves;
                    sums.voxels_single += sum.voxels_single;
                    sums.voxels_six += sum.voxels_six;
                }
                BlockKind::Triangle => {
                    self.found.triangle_blocks += 1;
                    let t = block.triangles(attrs).map_err(s)?;
                    t.check_contents().map_err(s)?;
                    sums.triangles += t.primary_count() as u64;
                    sums.triangle_records += t.triangle_count() as u64;
                    sums.vertices += t.vertex_count() as u64;
                    for i in 0..t.primary_count() {
                        let m = self.lookup(t.positions(i).map_err(s)?)?;
                        self.found.primaries.push(m);
                    }
                    if let Some(m) = (0..t.triangle_count())
                        .filter_map(|i| t.triangle(i).ok()?.material)
                        .find(|&m| usize::from(m) >= self.found.meta.materials.len())
                    {
                        return Err(format!("material {m} out of range"));
                    }
                    for i in 0..t.triangle_count() {
                        let stored = t.part(i).map_err(s)?;
                        let key = t.positions(i).map_err(s)?.map(|p| p.map(f32::to_bits));
                        let ids = self.mesh.part_ids.as_ref();
                        let expected: Vec<Option<u32>> = self
                            .ids
                            .get(&key)
                            .into_iter()
                            .flatten()
                            .map(|&m| ids.and_then(|ids| ids.get(m).copied()))
                            .collect();
                        if !expected.contains(&stored) {
                            return Err(format!(
                                "block {id} triangle {i}: part {stored:?}, the mesh says {expected:?}"
                            ));
                        }
                    }
                }
                BlockKind::Proxy => {
                    self.found.proxy_blocks += 1;
                    sums.proxies += block.proxies().map_err(s)?.len() as u64;
                }
            }
            blocks.push(block);
        }
        Ok((blocks, sums, six))
    }

    /// Walks the tree: every treelet once, LOD children one level down and side by side.
    fn walk_tree(&mut self, blocks: &[oocfmt::Block]) -> Res<Walked> {
        let (reader, attrs) = (self.reader, self.attrs);
        let mut seen_treelets = HashSet::new();
        let mut depth = 0u32;
        let mut levels = 0u32;
        let mut max_proxied_level = 0u32;
        let mut min_unproxied_level = u32::MAX;
        let root = self.found.meta.root.iter();
        let mut stack: Vec<(u32, u32, u32)> = root.map(|r| (r.block, r.treelet, 1)).collect();
        while let Some((b, t, d0)) = stack.pop() {
            if !seen_treelets.insert((b, t)) {
                return Err(format!("treelet {b}/{t} reached twice"));
            }
            let block = blocks.get(b as usize).ok_or("child block out of range")?;
            levels = levels.max(u32::from(block.entry.level) + 1);
            let tb = block.treelets().map_err(s)?;
            let span = tb.treelet_span(t as usize).map_err(s)?;
            let mut nodes = vec![(span.start, d0)];
            while let Some((pos, d)) = nodes.pop() {
                depth = depth.max(d);
                match tb.node(pos).map_err(s)? {
                    Node::Basic { left, right, .. } => {
                        for u in [left, right].into_iter().filter(|&u| u != 0) {
                            nodes.push((TreeletBlock::child_pos(pos, u), d + 1));
                        }
                    }
                    Node::Lod {
                        left_present,
                        right_present,
                        child_treelet,
                        child_block,
                        proxy,
                        ..
                    } => {
                        let child = blocks
                            .get(child_block as usize)
                            .ok_or("LOD child block out of range")?;
                        if child.entry.kind != BlockKind::Treelet
                            || child.entry.level != block.entry.level + 1
                        {
                            return Err(format!("LOD node in block {b} (level {}) points at block {child_block} of level {}", block.entry.level, child.entry.level));
                        }
                        let n = u32::from(left_present) + u32::from(right_present);
                        if child_treelet + n > child.entry.item_count {
                            return Err("LOD child treelets out of range".into());
                        }
                        for k in 0..n {
                            stack.push((child_block, child_treelet + k, d + 1));
                        }
                        // Proxies go to the coarsest LOD nodes first: no level may have a
                        // proxy finer than a level with a node without one (checked after the
                        // walk).
                        let level = u32::from(block.entry.level);
                        if proxy == NO_PROXY {
                            min_unproxied_level = min_unproxied_level.min(level);
                            continue;
                        }
                        max_proxied_level = max_proxied_level.max(level);
                        let p = reader
                            .proxies()
                            .get(proxy as usize)
                            .ok_or("LOD node with an out-of-range proxy")?;
                        if p.node_block != b {
                            return Err(format!(
                                "proxy {proxy} names block {}, its node is in block {b}",
                                p.node_block
                            ));
                        }
                    }
                    Node::Leaf {
                        count,
                        first,
                        block: tri_block,
                    } => {
                        let tblock = blocks
                            .get(tri_block as usize)
                            .ok_or("leaf block out of range")?;
                        let tris = tblock.triangles(attrs).map_err(s)?;
                        for e in usize::from(first)..usize::from(first) + usize::from(count) {
                            let local = tris.list(e).map_err(s)?;
                            let m = self.lookup(tris.positions(usize::from(local)).map_err(s)?)?;
                            self.found.reached.insert(m);
                        }
                    }
                }
            }
        }
        Ok(Walked {
            treelets: seen_treelets.len(),
            depth,
            levels,
            max_proxied_level,
            min_unproxied_level,
        })
    }
}

pub(super) fn build_tree(mesh: &Mesh, max_leaf: u32) -> Res<KdTree> {
    build(
        mesh,
        &KdBuildOptions {
            max_leaf_triangles: max_leaf,
            ..KdBuildOptions::default()
        },
    )
    .map_err(s)
}

pub(super) fn write_and_read(
    mesh: &Mesh,
    tree: &KdTree,
    o: &LayoutOptions,
) -> Res<(Found, Vec<u8>)> {
    let dir = tempfile::tempdir().map_err(s)?;
    let path = dir.path().join("t.oocf");
    let (summary, meta) = write_container(&path, mesh, tree, o).map_err(s)?;
    let bytes = std::fs::read(&path).map_err(s)?;
    if summary.file_length != bytes.len() as u64 {
        return Err("summary length differs from the file".into());
    }
    deep_verify(&path)?;
    let found = read_back(&path, mesh)?;
    if found.meta != meta {
        return Err("returned metadata differs from the stored one".into());
    }
    Ok((found, bytes))
}

/// Runs the format crate's deep verifier; any error or warning fails (an empty scene's
/// `TREE_EMPTY` warning aside).
pub(crate) fn deep_verify(path: &Path) -> Res<()> {
    use oocfmt::verify::{verify, Depth, VerifyOptions};
    let src = oocfmt::FileSource::open(path).map_err(s)?;
    let opts = VerifyOptions {
        depth: Depth::Deep,
        ..VerifyOptions::default()
    };
    let report = verify(&src, &path.display().to_string(), &opts, &|_| {}).map_err(s)?;
    let complaints: Vec<String> = report
        .issues
        .iter()
        .filter(|i| i.code != oocfmt::Code::TreeEmpty)
        .map(|i| i.to_string())
        .collect();
    if !report.valid || !complaints.is_empty() {
        return Err(format!(
            "deep verify of {}: {complaints:#?}",
            path.display()
        ));
    }
    Ok(())
}

fn check_full_coverage(mesh: &Mesh, found: &Found) -> Res<()> {
    let mut prim = found.primaries.clone();
    prim.sort_unstable();
    if prim != (0..mesh.triangles.len()).collect::<Vec<_>>() {
        return Err(format!(
            "primaries are not each mesh triangle once ({} primaries, {} triangles)",
            prim.len(),
            mesh.triangles.len()
        ));
    }
    if found.reached.len() != mesh.triangles.len() {
        return Err(format!(
            "{} of {} triangles reachable",
            found.reached.len(),
            mesh.triangles.len()
        ));
    }
    if found.meta.counts.triangles != mesh.triangles.len() as u64 {
        return Err("counts.triangles is not the mesh's triangle count".into());
    }
    Ok(())
}

#[test]
fn the_demo_scene_lays_out_correctly_under_every_codec() -> Res<()> {
    let mesh = demo_scene(20_000);
    let tree = build_tree(&mesh, 8)?;
    for codec in [Codec::None, Codec::Lz4, Codec::Zstd(3)] {
        let (found, _) = write_and_read(&mesh, &tree, &opts(4096, codec, 3))?;
        check_full_coverage(&mesh, &found)?;
        let c = found.meta.counts;
        assert!(c.lod_levels >= 3, "{c:?}");
        assert!(c.voxels_single > 0 && c.voxels_six > 0, "{c:?}");
        // One proxy per 64 triangles, coarsest LOD nodes first.
        let cap = opts(4096, codec, 3).max_proxies(mesh.triangles.len()) as u64;
        assert_eq!(c.proxies, c.lod_nodes.min(cap), "{c:?}");
        assert!(
            c.proxies < c.lod_nodes,
            "the cap must bite on this scene: {c:?}"
        );
        assert!(
            found.treelet_blocks > c.lod_levels as usize,
            "several treelet blocks on some level"
        );
        assert!(found.triangle_blocks > 1 && found.proxy_blocks > 1);
        assert!(
            found.meta.schema.vertex_normals
                && found.meta.schema.vertex_colours
                && found.meta.schema.triangle_materials
        );
        assert!(
            c.triangle_records > c.triangles,
            "straddlers are copied across blocks"
        );
        assert_eq!(found.meta.materials.len(), 2);
        assert_eq!(found.meta.provenance.sources, vec!["demo".to_string()]);
        if codec != Codec::None {
            assert!(found.compressed_blocks > 0);
        }
    }
    Ok(())
}

#[test]
fn every_treelet_height_and_block_size_works() -> Res<()> {
    let mesh = demo_scene(3000);
    let tree = build_tree(&mesh, 4)?;
    for (h, bs) in [(1, 4096), (2, 4096), (3, 65536), (4, 8192), (6, 1 << 20)] {
        let (found, _) = write_and_read(&mesh, &tree, &opts(bs, Codec::Lz4, h))?;
        check_full_coverage(&mesh, &found)?;
        let expected_levels = tree.depth().div_ceil(u32::from(h));
        assert!(
            found.meta.counts.lod_levels <= expected_levels,
            "height {h}"
        );
        assert_eq!(found.meta.build.treelet_height, h);
        assert_eq!(found.meta.counts.depth, tree.depth(), "height {h}");
    }
    Ok(())
}

#[test]
fn output_is_byte_identical_across_runs_and_thread_counts() -> Res<()> {
    let mesh = demo_scene(6000);
    let tree = build_tree(&mesh, 8)?;
    for lod in [LodKinds::VOXEL, LodKinds::BOTH, LodKinds::RLOD] {
        let mut o = opts(4096, Codec::Zstd(3), 3);
        o.write.lod = lod;
        let run = |threads: usize| -> Res<Vec<u8>> {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(s)?;
            pool.install(|| write_and_read(&mesh, &tree, &o))
                .map(|(_, b)| b)
        };
        let one = run(1)?;
        assert!(one == run(1)?, "{lod:?}: two single-thread runs differ");
        assert!(one == run(2)?, "{lod:?}: one and two threads differ");
        assert!(one == run(4)?, "{lod:?}: one and four threads differ");
    }
    Ok(())
}

#[test]
fn siblings_share_a_block_and_levels_ascend() -> Res<()> {
    // Covered by read_back's walk; here a tiny block size forces many blocks per level.
    let mesh = demo_scene(2000);
    let tree = build_tree(&mesh, 2)?;
    let (found, _) = write_and_read(&mesh, &tree, &opts(4096, Codec::None, 2))?;
    check_full_coverage(&mesh, &found)?;
    assert!(found.treelet_blocks > 2 * found.meta.counts.lod_levels as usize);
    Ok(())
}

#[test]
fn a_lone_leaf_and_an_empty_mesh_are_valid_containers() -> Res<()> {
    let mesh = Mesh::new(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
    );
    let tree = build_tree(&mesh, 8)?;
    let (found, _) = write_and_read(&mesh, &tree, &opts(4096, Codec::Lz4, 3))?;
    check_full_coverage(&mesh, &found)?;
    let c = found.meta.counts;
    assert_eq!(
        (c.depth, c.lod_levels, c.leaves, c.treelets, c.lod_nodes),
        (1, 1, 1, 1, 0)
    );
    assert!(!found.meta.schema.vertex_normals && !found.meta.schema.six_sample_voxels);

    let empty = Mesh::default();
    let tree = build_tree(&empty, 8)?;
    let (found, _) = write_and_read(&empty, &tree, &opts(4096, Codec::Lz4, 3))?;
    assert_eq!(found.meta.root, None);
    assert_eq!(found.meta.counts, Counts::default());
    assert_eq!(
        found.treelet_blocks + found.triangle_blocks + found.proxy_blocks,
        0
    );
    Ok(())
}

#[test]
fn impossible_layouts_are_refused_with_a_reason() -> Res<()> {
    // 300 separate triangles in one leaf cannot fit a 4 KiB triangle block.
    let positions: Vec<[f32; 3]> = (0..900).map(|i| [i as f32, (i % 3) as f32, 0.0]).collect();
    let triangles: Vec<[u32; 3]> = (0..300).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
    let mesh = Mesh::new(positions, triangles);
    let nodes = vec![KdNode::Leaf {
        triangles: (0..300).collect(),
    }];
    let tree =
        KdTree::from_parts(&mesh, nodes, Some(NodeId(0)), mesh.bounds(), Vec::new()).map_err(s)?;
    let err = build_blocks(&mesh, &tree, &opts(4096, Codec::None, 3));
    assert!(
        matches!(err, Err(LayoutError::LeafTooLarge { triangles: 300, .. })),
        "{err:?}"
    );

    let mut o = opts(4096, Codec::None, 0);
    assert!(matches!(
        build_blocks(&mesh, &tree, &o),
        Err(LayoutError::TreeletHeight(0))
    ));
    o.treelet_height = 3;
    o.voxel_threshold = f32::NAN;
    assert!(matches!(
        build_blocks(&mesh, &tree, &o),
        Err(LayoutError::VoxelThreshold(_))
    ));

    // A treelet too tall for 12-bit child offsets.
    let demo = demo_scene(20_000);
    let demo_tree = build_tree(&demo, 8)?;
    let err = build_blocks(&demo, &demo_tree, &opts(1 << 20, Codec::None, 16));
    assert!(
        matches!(err, Err(LayoutError::TreeletSpan { .. })),
        "{err:?}"
    );
    // Sibling treelets that do not fit one block together.
    let err = build_blocks(&demo, &demo_tree, &opts(4096, Codec::None, 12));
    assert!(
        matches!(err, Err(LayoutError::TreeletsTooLarge { .. })),
        "{err:?}"
    );

    // A tree built for another mesh is refused rather than laid out wrongly.
    let other = oocfmt_scenes::vectors::quad_mesh();
    assert!(matches!(
        build_blocks(&other, &tree, &opts(4096, Codec::None, 3)),
        Err(LayoutError::Tree(_))
    ));
    Ok(())
}

#[test]
fn a_failed_write_leaves_nothing_behind() -> Res<()> {
    let dir = tempfile::tempdir().map_err(s)?;
    let path = dir.path().join("never.oocf");
    let mesh = Mesh::new(vec![[0.0; 3]; 3], vec![[0, 1, 2]]);
    let tree = build_tree(&mesh, 8)?;
    let bad = LayoutOptions {
        treelet_height: 0,
        ..LayoutOptions::default()
    };
    assert!(write_container(&path, &mesh, &tree, &bad).is_err());
    let leftovers = std::fs::read_dir(dir.path()).map_err(s)?.count();
    assert_eq!(leftovers, 0);
    Ok(())
}

#[test]
fn deep_verify_notices_wrong_counts() -> Res<()> {
    // Guards the guard: the verifier used above must not pass everything.
    let mesh = demo_scene(500);
    let tree = build_tree(&mesh, 4)?;
    let mut container = build_blocks(&mesh, &tree, &opts(4096, Codec::None, 3)).map_err(s)?;
    container.metadata.counts.leaves += 1;
    let dir = tempfile::tempdir().map_err(s)?;
    let path = dir.path().join("bad.oocf");
    let mut w = Writer::create(&path, opts(4096, Codec::None, 3).write).map_err(s)?;
    for b in &container.blocks {
        w.write_block(b.kind, b.level, b.item_count, &b.raw)
            .map_err(s)?;
    }
    w.finish(&container.metadata).map_err(s)?;
    let err = deep_verify(&path).err().unwrap_or_default();
    assert!(err.contains("TREE_COUNTS"), "{err}");
    Ok(())
}
