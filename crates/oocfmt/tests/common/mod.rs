//! Shared test support: small, fully valid containers built through the public API only (deep
//! verify must find nothing in them), the spec's test vectors (whatever `spec/vectors/` holds),
//! and helpers to read everything in a file and to re-seal a modified file.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use oocfmt::metadata::{Build, Counts, Material, Part, Provenance, Scene, Schema, TreeletRef};
use oocfmt::records::triangle::{
    oct_encode, ATTR_COLOURS, ATTR_MATERIALS, ATTR_NORMALS, ATTR_PART_WIDTH_SHIFT,
};
use oocfmt::records::{
    Footprint, LodKinds, Node, ProxyRecord, Rlod, Sample, TreeletBlockWriter, Triangle,
    TriangleBlockWriter, Vertex, Voxel, NO_PROXY, PROXY_DIRECTIONS,
};
use oocfmt::verify::{verify, Depth, Report, VerifyOptions};
use oocfmt::{BlockKind, Code, Codec, Metadata, Reader, Severity, WriteOptions, Writer};

/// The fuzz properties (one copy, shared with `fuzz/` and `tests/format/fuzz_corpus.rs`), which also
/// hold the re-sealing helpers.
#[path = "../../../../fuzz/src/props.rs"]
pub mod props;

pub type TestResult<T = ()> = Result<T, Box<dyn std::error::Error>>;

/// A named file image: a spec vector or a fixture.
#[derive(Clone, Debug)]
pub struct NamedFile {
    pub name: String,
    pub bytes: Vec<u8>,
}

pub fn vectors_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec/vectors"))
}

/// Every `spec/vectors/*.oocf`, sorted by name; empty while the vectors do not exist yet.
pub fn vectors() -> TestResult<Vec<NamedFile>> {
    let mut out = Vec::new();
    let Ok(dir) = std::fs::read_dir(vectors_dir()) else {
        return Ok(out);
    };
    for entry in dir {
        let path = entry?.path();
        if path.extension().is_some_and(|e| e == "oocf") {
            let name = path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            out.push(NamedFile {
                name,
                bytes: std::fs::read(&path)?,
            });
        }
    }
    out.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(out)
}

/// The fixtures, built fresh; every one is valid under deep verify.
pub fn fixtures() -> TestResult<Vec<NamedFile>> {
    let dir = tempfile::tempdir()?;
    let mut out = Vec::new();
    for (name, build) in FIXTURES {
        let path = dir.path().join(format!("{name}.oocf"));
        build(&path)?;
        out.push(NamedFile {
            name: (*name).to_string(),
            bytes: std::fs::read(&path)?,
        });
    }
    Ok(out)
}

/// Vectors and fixtures together: what the corruption and fuzz tests run over.
pub fn all_files() -> TestResult<Vec<NamedFile>> {
    let mut v = vectors()?;
    v.extend(fixtures()?);
    Ok(v)
}

type Build1 = fn(&Path) -> TestResult<oocfmt::WriteSummary>;

/// Name and builder of every fixture.
pub const FIXTURES: &[(&str, Build1)] = &[
    ("fx-quad-none", write_quad),
    ("fx-lod-lz4", write_lod),
    ("fx-deep-zstd", write_deep),
    ("fx-filtered-lz4", write_filtered),
    ("fx-parts-lz4", write_parts),
    ("fx-empty", write_empty),
];

pub fn fixture(name: &str) -> TestResult<Vec<u8>> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("f.oocf");
    let build = FIXTURES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, b)| *b)
        .ok_or_else(|| format!("no fixture {name}"))?;
    build(&path)?;
    Ok(std::fs::read(&path)?)
}

/// Options for an unfiltered voxel-only file (the 1.0 layout every fixture but
/// `fx-filtered-lz4` keeps, so their bytes do not change with the writer's default).
pub fn opts(block_size_log2: u8, codec: Codec) -> WriteOptions {
    WriteOptions {
        block_size_log2,
        codec,
        lod: LodKinds::VOXEL,
    }
}

pub fn leaf(first: u16, count: u16, block: u32) -> Node {
    Node::Leaf {
        count,
        first,
        block,
    }
}

pub fn metadata(
    scene: Scene,
    root: Option<TreeletRef>,
    counts: Counts,
    schema: Schema,
    materials: Vec<Material>,
    height: u8,
) -> Metadata {
    Metadata {
        scene,
        root,
        counts,
        schema,
        materials,
        build: Build {
            treelet_height: height,
            max_leaf_triangles: 4,
            params: vec![("fixture".into(), "yes".into())],
        },
        provenance: Provenance {
            generator: "oocfmt tests/common".into(),
            sources: vec!["hand-built".into()],
        },
        parts: Vec::new(),
    }
}

pub fn scene(min: [f32; 3], max: [f32; 3]) -> Scene {
    Scene {
        bounds_min: min,
        bounds_max: max,
        origin: [100.0, -50.0, 0.25],
    }
}

/// Six face samples for a voxel: each face's outward normal, a colour per face.
fn six_samples() -> [Sample; 6] {
    let n = [
        [-1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, -1.0],
        [0.0, 0.0, 1.0],
    ];
    let mut s = [Sample(0); 6];
    for (k, slot) in s.iter_mut().enumerate() {
        *slot = Sample::pack(n[k], [k as f32 / 5.0, 0.5, 1.0 - k as f32 / 5.0]);
    }
    s
}

/// A proxy for the LOD node in block `node_block`: what each of the 18 directions sees; two
/// directions see nothing.
fn proxy(node_block: u32, area: f32) -> ProxyRecord {
    let mut samples = [Sample::EMPTY; 18];
    for (k, slot) in samples.iter_mut().enumerate() {
        if k % 9 != 4 {
            let d = PROXY_DIRECTIONS[k];
            *slot = Sample::pack([-d[0], -d[1], -d[2]], [0.25, k as f32 / 17.0, 0.75]);
        }
    }
    ProxyRecord {
        node_block,
        area,
        samples,
    }
}

pub fn square_vertices(w: &mut TriangleBlockWriter, z: f32, attrs: u16) -> TestResult {
    for (i, p) in [[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]]
        .into_iter()
        .enumerate()
    {
        let v = Vertex {
            position: p,
            normal: (attrs & ATTR_NORMALS != 0).then(|| oct_encode([0.0, 0.3, 1.0])),
            colour: (attrs & ATTR_COLOURS != 0).then_some([10 * i as u8, 200, 30, 255]),
        };
        w.push_vertex(v)?;
    }
    Ok(())
}

/// The smallest geometry: a root basic node splitting a unit square at x = 0.5 into two leaves,
/// one triangle block of two triangles, no attributes, stored uncompressed.
pub fn write_quad(path: &Path) -> TestResult<oocfmt::WriteSummary> {
    let mut w = Writer::create(path, opts(12, Codec::None))?;
    let mut t = TreeletBlockWriter::new();
    t.begin_treelet();
    t.push_node(&Node::Basic {
        axis: 0,
        split: 0.5,
        left: 1,
        right: 2,
    });
    t.push_node(&leaf(0, 1, 1));
    t.push_node(&leaf(1, 1, 1));
    let root = w.write_block(BlockKind::Treelet, 0, 1, &t.finish())?;
    let mut tri = TriangleBlockWriter::new(0);
    square_vertices(&mut tri, 0.0, 0)?;
    tri.push_triangle(Triangle {
        v: [0, 1, 2],
        material: None,
        part: None,
    })?;
    tri.push_triangle(Triangle {
        v: [0, 2, 3],
        material: None,
        part: None,
    })?;
    tri.push_list(1)?;
    tri.push_list(0)?;
    tri.set_primary_count(2);
    let tb = w.write_block(BlockKind::Triangle, 0, 2, &tri.finish())?;
    assert_eq!((root, tb), (0, 1));
    let counts = Counts {
        triangles: 2,
        triangle_records: 2,
        vertices: 4,
        basic_nodes: 1,
        leaves: 2,
        treelets: 1,
        depth: 2,
        lod_levels: 1,
        ..Counts::default()
    };
    let meta = metadata(
        scene([0.0; 3], [1.0, 1.0, 0.0]),
        Some(TreeletRef {
            block: 0,
            treelet: 0,
        }),
        counts,
        Schema::default(),
        Vec::new(),
        3,
    );
    Ok(w.finish(&meta)?)
}

/// A LOD level: root basic node (x = 1) over the box 0..2 × 0..1 × 0..1; its left child is a LOD
/// node (y = 0.5, six-sample voxel, proxy 0) whose two children are one-leaf treelets in a level-1
/// block; its right child is a leaf. A triangle block with normals, colours and materials (48
/// repetitive triangles, so LZ4 shrinks it) and a proxy block. LZ4, 4 KiB blocks.
pub fn write_lod(path: &Path) -> TestResult<oocfmt::WriteSummary> {
    write_lod_with_parts(path, &[], 0)
}

/// The triangle block of [`write_lod`] with `attrs` and `count` ≥ 48 triangles, all primaries:
/// triangle `i` alternates between the square's two halves and its two materials, and has the
/// part `part(i)`. Its list names triangles 0–3 and 47.
pub fn lod_triangle_block(
    attrs: u16,
    count: u16,
    part: impl Fn(u16) -> Option<u32>,
) -> TestResult<Vec<u8>> {
    let mut tri = TriangleBlockWriter::new(attrs);
    square_vertices(&mut tri, 0.5, attrs)?;
    for i in 0..count {
        let v = if i % 2 == 0 { [0, 1, 2] } else { [0, 2, 3] };
        tri.push_triangle(Triangle {
            v,
            material: Some(i % 2),
            part: part(i),
        })?;
    }
    for e in [0, 1, 2, 3, 47] {
        tri.push_list(e)?;
    }
    tri.set_primary_count(count);
    Ok(tri.finish())
}

/// The parts of `fx-parts-lz4`: an assembly with no triangles of its own over a bracket over a
/// bolt (a hierarchy three deep), each with the box of the fixture's square, which both
/// triangle shapes fill.
pub fn fixture_parts() -> Vec<Part> {
    let square = ([0.0, 0.0, 0.5], [1.0, 1.0, 0.5]);
    let part = |name: &str, parent, source, triangles: u64| Part {
        name: name.into(),
        parent,
        source,
        triangles,
        bounds_min: if triangles > 0 { square.0 } else { [0.0; 3] },
        bounds_max: if triangles > 0 { square.1 } else { [0.0; 3] },
    };
    vec![
        part("assembly", None, Some(0), 0),
        part("bracket", Some(0), Some(0), 24),
        part("bolt ✓", Some(1), None, 24),
    ]
}

/// `fx-parts-lz4`: [`write_lod`]'s file with [`fixture_parts`] (`PART_IDS`, minor 3): u8 part
/// ids, the even triangles the bracket's and the odd ones the bolt's, and the LOD node's part
/// word naming the bolt.
pub fn write_parts(path: &Path) -> TestResult<oocfmt::WriteSummary> {
    write_lod_with_parts(path, &fixture_parts(), 2)
}

/// [`write_lod`] with a part table: with two or more parts, triangle `i` gets part `1 + i % 2`
/// (of `parts.len()`) and the LOD entry ends with the part word `lod_part`.
pub fn write_lod_with_parts(
    path: &Path,
    parts: &[Part],
    lod_part: u32,
) -> TestResult<oocfmt::WriteSummary> {
    let ids = parts.len() >= 2;
    let attrs = ATTR_NORMALS
        | ATTR_COLOURS
        | ATTR_MATERIALS
        | (oocfmt::records::part_id_width(parts.len()) << ATTR_PART_WIDTH_SHIFT);
    let o = WriteOptions {
        lod: LodKinds::VOXEL.with_parts(ids),
        ..opts(12, Codec::Lz4)
    };
    let mut w = Writer::create(path, o)?;
    // Block 0: level 0.
    let mut t = TreeletBlockWriter::new();
    t.begin_treelet();
    t.push_node(&Node::Basic {
        axis: 0,
        split: 1.0,
        left: 1,
        right: 4,
    });
    let vox = t.push_voxel(&Voxel::six(six_samples()), false);
    if ids {
        t.push_lod_part(lod_part);
    }
    t.push_node(&Node::Lod {
        axis: 1,
        split: 0.5,
        radius: 0.8661,
        left_present: true,
        right_present: true,
        child_treelet: 0,
        child_block: 1,
        voxel_offset: vox,
        proxy: 0,
    });
    t.push_node(&leaf(0, 2, 2));
    assert_eq!(w.write_block(BlockKind::Treelet, 0, 1, &t.finish())?, 0);
    // Block 1: level 1, two one-leaf treelets.
    let mut t = TreeletBlockWriter::new();
    t.begin_treelet();
    t.push_node(&leaf(2, 1, 2));
    t.begin_treelet();
    t.push_node(&leaf(3, 2, 2));
    assert_eq!(w.write_block(BlockKind::Treelet, 1, 2, &t.finish())?, 1);
    // Block 2: triangles.
    let part = |i: u16| ids.then_some(1 + u32::from(i % 2));
    let tri = lod_triangle_block(attrs, 48, part)?;
    assert_eq!(w.write_block(BlockKind::Triangle, 0, 48, &tri)?, 2);
    // Block 3: the proxy of the LOD node in block 0.
    let mut p = Vec::new();
    proxy(0, 2.0).encode_into(&mut p);
    assert_eq!(w.write_block(BlockKind::Proxy, 0, 1, &p)?, 3);
    let counts = Counts {
        triangles: 48,
        triangle_records: 48,
        vertices: 4,
        basic_nodes: 1,
        lod_nodes: 1,
        leaves: 3,
        voxels_single: 0,
        voxels_six: 1,
        proxies: 1,
        treelets: 3,
        depth: 3,
        lod_levels: 2,
    };
    let schema = Schema {
        vertex_normals: true,
        vertex_colours: true,
        triangle_materials: true,
        six_sample_voxels: true,
    };
    let materials = vec![
        Material {
            name: "white".into(),
            diffuse: [0.9, 0.9, 0.9],
        },
        Material {
            name: "rouge ✓".into(),
            diffuse: [0.8, 0.1, 0.1],
        },
    ];
    let mut meta = metadata(
        scene([0.0; 3], [2.0, 1.0, 1.0]),
        Some(TreeletRef {
            block: 0,
            treelet: 0,
        }),
        counts,
        schema,
        materials,
        2,
    );
    meta.parts = parts.to_vec();
    Ok(w.finish(&meta)?)
}

/// Three LOD levels, blocks of every kind interleaved (only treelet levels are ordered):
/// 0 triangles A, 1 level-0 treelet (a lone LOD node, x = 1, over the box 0..2³), 2 proxies,
/// 3 level 1 (treelet 0: LOD node y = 1 with proxy 1; treelet 1: basic node z = 1, two leaves),
/// 4 triangles B, 5 level 2 (two one-leaf treelets). Single-sample voxels, vertex normals, zstd.
pub fn write_deep(path: &Path) -> TestResult<oocfmt::WriteSummary> {
    let attrs = ATTR_NORMALS;
    let mut w = Writer::create(path, opts(13, Codec::Zstd(3)))?;
    let tri_block = |z: f32, n: u16| -> TestResult<Vec<u8>> {
        let mut tri = TriangleBlockWriter::new(attrs);
        square_vertices(&mut tri, z, attrs)?;
        for i in 0..n {
            tri.push_triangle(Triangle {
                v: if i % 2 == 0 { [0, 1, 2] } else { [2, 3, 0] },
                material: None,
                part: None,
            })?;
        }
        for e in 0..n.min(6) {
            tri.push_list(e)?;
        }
        tri.set_primary_count(n - 1);
        Ok(tri.finish())
    };
    assert_eq!(
        w.write_block(BlockKind::Triangle, 0, 40, &tri_block(0.5, 40)?)?,
        0
    );
    let single = |c: f32| Voxel::single(Sample::pack([0.0, 1.0, 0.2], [c, c, c]));
    // Block 1: level 0, the root treelet is a lone LOD node.
    let mut t = TreeletBlockWriter::new();
    t.begin_treelet();
    let vox = t.push_voxel(&single(0.5), false);
    t.push_node(&Node::Lod {
        axis: 0,
        split: 1.0,
        radius: 1.7321,
        left_present: true,
        right_present: true,
        child_treelet: 0,
        child_block: 3,
        voxel_offset: vox,
        proxy: 0,
    });
    assert_eq!(w.write_block(BlockKind::Treelet, 0, 1, &t.finish())?, 1);
    // Block 2: proxies for the LOD nodes in blocks 1 and 3.
    let mut p = Vec::new();
    proxy(1, 8.0).encode_into(&mut p);
    proxy(3, 4.0).encode_into(&mut p);
    assert_eq!(w.write_block(BlockKind::Proxy, 0, 2, &p)?, 2);
    // Block 3: level 1.
    let mut t = TreeletBlockWriter::new();
    t.begin_treelet();
    let vox = t.push_voxel(&single(0.9), false);
    t.push_node(&Node::Lod {
        axis: 1,
        split: 1.0,
        radius: 1.5,
        left_present: true,
        right_present: true,
        child_treelet: 0,
        child_block: 5,
        voxel_offset: vox,
        proxy: 1,
    });
    t.begin_treelet();
    t.push_node(&Node::Basic {
        axis: 2,
        split: 1.0,
        left: 1,
        right: 2,
    });
    t.push_node(&leaf(0, 3, 0));
    t.push_node(&leaf(0, 2, 4));
    assert_eq!(w.write_block(BlockKind::Treelet, 1, 2, &t.finish())?, 3);
    assert_eq!(
        w.write_block(BlockKind::Triangle, 0, 24, &tri_block(1.5, 24)?)?,
        4
    );
    // Block 5: level 2.
    let mut t = TreeletBlockWriter::new();
    t.begin_treelet();
    t.push_node(&leaf(3, 3, 0));
    t.begin_treelet();
    t.push_node(&leaf(2, 4, 4));
    assert_eq!(w.write_block(BlockKind::Treelet, 2, 2, &t.finish())?, 5);
    let counts = Counts {
        triangles: 39 + 23,
        triangle_records: 40 + 24,
        vertices: 8,
        basic_nodes: 1,
        lod_nodes: 2,
        leaves: 4,
        voxels_single: 2,
        voxels_six: 0,
        proxies: 2,
        treelets: 5,
        depth: 3,
        lod_levels: 3,
    };
    let schema = Schema {
        vertex_normals: true,
        ..Schema::default()
    };
    let meta = metadata(
        scene([0.0; 3], [2.0; 3]),
        Some(TreeletRef {
            block: 1,
            treelet: 0,
        }),
        counts,
        schema,
        Vec::new(),
        1,
    );
    Ok(w.finish(&meta)?)
}

/// Pre-filtered LOD entries (`LOD_RLODS` and `LOD_FILTERED`, minor 2): over the box 0..2 × 0..2
/// × 0..2, a root basic node (x = 1) over two basic nodes (y = 1), each over two LOD nodes
/// (z = 1, left child only) whose child treelets are one leaf each, in a level-1 block. The four
/// voxels take the four lengths of spec §5.1, in node order: 1-sample (4 bytes), 1-sample with
/// a footprint (8), 6-sample (24), 6-sample with footprints (36); each is followed by an R-LOD
/// record (coverage and shade 255 on the first, below 255 on the others). LZ4, 4 KiB blocks.
pub fn write_filtered(path: &Path) -> TestResult<oocfmt::WriteSummary> {
    write_filtered_with(path, LodKinds::BOTH.filtered())
}

/// [`write_filtered`]'s tree with the LOD entries `kinds` lays out: without `LOD_FILTERED` the
/// footprints and the R-LODs' coverage and shade are dropped (the voxels are then 4 or 24 bytes).
pub fn write_filtered_with(path: &Path, kinds: LodKinds) -> TestResult<oocfmt::WriteSummary> {
    let o = WriteOptions {
        lod: kinds,
        ..opts(12, Codec::Lz4)
    };
    let mut w = Writer::create(path, o)?;
    let up = Sample::pack([0.0, 0.0, 1.0], [0.8, 0.6, 0.4]);
    let half = |k: usize| Footprint::new(0.5 + 0.05 * k as f64, 0.25 + 0.1 * k as f64);
    let mut feet = [Footprint::FULL; 6];
    for (k, f) in feet.iter_mut().enumerate().skip(1) {
        *f = half(k);
    }
    let voxels = [
        Voxel::single(up),
        Voxel::Single(up, Footprint::new(0.7, 0.4)),
        Voxel::six(six_samples()),
        Voxel::Six(six_samples(), feet),
    ];
    // Block 0: level 0. Root at 0, basic nodes at 8 and 64, LOD nodes at 16, 40, 72, 96.
    let mut t = TreeletBlockWriter::new();
    t.begin_treelet();
    let basic = |axis, left, right| Node::Basic {
        axis,
        split: 1.0,
        left,
        right,
    };
    t.push_node(&basic(0, 1, 8));
    for (half_x, pair) in voxels.chunks(2).enumerate() {
        t.push_node(&basic(1, 1, 4));
        for (half_y, voxel) in pair.iter().enumerate() {
            let k = 2 * half_x + half_y;
            let (coverage, shade) = if k == 0 {
                (255, 255)
            } else {
                (60 * k as u8, 250 - 20 * k as u8)
            };
            // The plane z = 0.5 + k / 8 crosses every LOD node's cell.
            let rlod = Rlod {
                normal: [0.0, 0.0, 1.0],
                offset: 0.5 + k as f32 / 8.0,
                colour: [200, 100 + k as u8, 50],
                deviation_code: 3,
                expansion_code: 5,
                coverage,
                shade,
            };
            let vox = kinds.voxel.then(|| t.push_voxel(voxel, kinds.filtered));
            let rl = kinds.rlod.then(|| t.push_rlod(&rlod, kinds.filtered));
            let entry = vox.or(rl).ok_or("no LOD kind")?;
            t.push_node(&Node::Lod {
                axis: 2,
                split: 1.0,
                // Half the diagonal of a 1 × 1 × 2 cell, √6 / 2 = 1.22474…, rounded up.
                radius: 1.2248,
                left_present: true,
                right_present: false,
                child_treelet: k as u32,
                child_block: 1,
                voxel_offset: entry,
                proxy: NO_PROXY,
            });
        }
    }
    assert_eq!(w.write_block(BlockKind::Treelet, 0, 1, &t.finish())?, 0);
    // Block 1: level 1, four one-leaf treelets.
    let mut t = TreeletBlockWriter::new();
    for k in 0..4u16 {
        t.begin_treelet();
        t.push_node(&leaf(k, 1, 2));
    }
    assert_eq!(w.write_block(BlockKind::Treelet, 1, 4, &t.finish())?, 1);
    // Block 2: triangles.
    let mut tri = TriangleBlockWriter::new(ATTR_COLOURS);
    square_vertices(&mut tri, 0.5, ATTR_COLOURS)?;
    for i in 0..4u16 {
        let v = if i % 2 == 0 { [0, 1, 2] } else { [0, 2, 3] };
        tri.push_triangle(Triangle {
            v,
            material: None,
            part: None,
        })?;
    }
    for e in 0..4 {
        tri.push_list(e)?;
    }
    tri.set_primary_count(4);
    assert_eq!(w.write_block(BlockKind::Triangle, 0, 4, &tri.finish())?, 2);
    let counts = Counts {
        triangles: 4,
        triangle_records: 4,
        vertices: 4,
        basic_nodes: 3,
        lod_nodes: 4,
        leaves: 4,
        voxels_single: if kinds.voxel { 2 } else { 0 },
        voxels_six: if kinds.voxel { 2 } else { 0 },
        proxies: 0,
        treelets: 5,
        depth: 4,
        lod_levels: 2,
    };
    let schema = Schema {
        vertex_colours: true,
        six_sample_voxels: kinds.voxel,
        ..Schema::default()
    };
    let meta = metadata(
        scene([0.0; 3], [2.0; 3]),
        Some(TreeletRef {
            block: 0,
            treelet: 0,
        }),
        counts,
        schema,
        Vec::new(),
        2,
    );
    Ok(w.finish(&meta)?)
}

/// No geometry: no blocks, no root (deep verify warns `TREE_EMPTY`, nothing else).
pub fn write_empty(path: &Path) -> TestResult<oocfmt::WriteSummary> {
    let w = Writer::create(path, opts(16, Codec::Lz4))?;
    let meta = metadata(
        scene([0.0; 3], [0.0; 3]),
        None,
        Counts::default(),
        Schema::default(),
        Vec::new(),
        3,
    );
    Ok(w.finish(&meta)?)
}

pub fn verify_bytes(bytes: &[u8], opts: &VerifyOptions) -> oocfmt::Result<Report> {
    verify(&bytes.to_vec(), "test", opts, &|_| {})
}

pub fn deep() -> VerifyOptions {
    VerifyOptions {
        depth: Depth::Deep,
        ..VerifyOptions::default()
    }
}

/// Whether the report has at least one error-severity issue (and says invalid).
pub fn has_error(r: &Report) -> bool {
    !r.valid && r.errors > 0 && r.issues.iter().any(|i| i.severity == Severity::Error)
}

pub fn codes(r: &Report) -> Vec<Code> {
    r.issues.iter().map(|i| i.code).collect()
}

pub fn open_bytes(bytes: &[u8], opts: oocfmt::ReadOptions) -> oocfmt::Result<Reader> {
    Reader::from_source(Box::new(bytes.to_vec()), std::sync::Arc::from("test"), opts)
}

/// Reads every block and decodes it by kind (walking treelet blocks); the first error.
pub fn read_all_blocks(r: &Reader) -> oocfmt::Result<()> {
    let attrs = r.metadata().triangle_attributes();
    for id in 0..r.header().sections.block_count {
        let b = r.read_block(id)?;
        match b.entry.kind {
            BlockKind::Treelet => {
                b.treelets()?.walk(|_, _, _| Ok(()))?;
            }
            BlockKind::Triangle => b.triangles(attrs)?.check_contents()?,
            BlockKind::Proxy => {
                b.proxies()?;
            }
        }
    }
    Ok(())
}

/// Little-endian field writes for hand-made corruptions.
pub fn put_u16(b: &mut [u8], at: usize, v: u16) {
    b[at..at + 2].copy_from_slice(&v.to_le_bytes());
}

pub fn put_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

pub fn put_u64(b: &mut [u8], at: usize, v: u64) {
    b[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

pub fn get_u32(b: &[u8], at: usize) -> u32 {
    let mut w = [0u8; 4];
    w.copy_from_slice(&b[at..at + 4]);
    u32::from_le_bytes(w)
}

pub fn get_u64(b: &[u8], at: usize) -> u64 {
    let mut w = [0u8; 8];
    w.copy_from_slice(&b[at..at + 8]);
    u64::from_le_bytes(w)
}

/// Re-seals a file after an edit: header CRC, directory CRC, metadata CRC, root checksum and
/// trailer CRC (see `props::reseal`).
pub fn reseal(b: &[u8]) -> TestResult<Vec<u8>> {
    props::reseal(b).ok_or_else(|| "file too short to re-seal".into())
}

/// Writes `v` at header offset `at` and the same trailer offset `tat` (when given), so header
/// and trailer agree, then re-seals.
pub fn set_section_u64(b: &mut [u8], at: usize, tat: Option<usize>, v: u64) {
    put_u64(b, at, v);
    if let Some(t) = tat {
        let base = b.len() - oocfmt::trailer::TRAILER_LEN;
        put_u64(b, base + t, v);
    }
}

pub fn set_section_u32(b: &mut [u8], at: usize, tat: Option<usize>, v: u32) {
    put_u32(b, at, v);
    if let Some(t) = tat {
        let base = b.len() - oocfmt::trailer::TRAILER_LEN;
        put_u32(b, base + t, v);
    }
}

/// The directory offset and entry count of a valid file.
pub fn directory_of(b: &[u8]) -> (usize, usize) {
    (
        get_u64(b, oocfmt::header::OFF_DIRECTORY_OFFSET) as usize,
        get_u32(b, oocfmt::header::OFF_BLOCK_COUNT) as usize,
    )
}

pub const NO_PROXY_ID: u32 = NO_PROXY;

/// A proptest configuration with `cases` cases, a fixed seed unless `PROPTEST_RNG_SEED` is set
/// (CI runs are reproducible), and no failure files written into the source tree.
pub fn proptest_config(cases: u32) -> proptest::test_runner::Config {
    use proptest::test_runner::{Config, RngSeed};
    let mut c = Config::with_cases(cases);
    if c.rng_seed == RngSeed::Random {
        c.rng_seed = RngSeed::Fixed(0x00CF_2024_0F0F_0001);
    }
    c.failure_persistence = None;
    c
}

/// The minor version in a file's header: the metadata decoder's form.
pub fn minor_of(b: &[u8]) -> u16 {
    u16::from_le_bytes([
        b[oocfmt::header::OFF_MINOR],
        b[oocfmt::header::OFF_MINOR + 1],
    ])
}

/// The metadata bytes of a valid file.
pub fn metadata_bytes(b: &[u8]) -> &[u8] {
    let off = get_u64(b, oocfmt::header::OFF_METADATA_OFFSET) as usize;
    let len = get_u32(b, oocfmt::header::OFF_METADATA_LENGTH) as usize;
    &b[off..off + len]
}

/// Replaces the metadata section of a valid file with `meta`, fixing the metadata length in
/// header and trailer and every checksum.
pub fn with_metadata(b: &[u8], meta: &[u8]) -> TestResult<Vec<u8>> {
    let off = get_u64(b, oocfmt::header::OFF_METADATA_OFFSET) as usize;
    let mut out = b[..off].to_vec();
    out.extend_from_slice(meta);
    out.extend_from_slice(&b[b.len() - oocfmt::trailer::TRAILER_LEN..]);
    let len = u32::try_from(meta.len())?;
    set_section_u32(
        &mut out,
        oocfmt::header::OFF_METADATA_LENGTH,
        Some(oocfmt::trailer::OFF_METADATA_LENGTH),
        len,
    );
    reseal(&out)
}

/// Re-writes a valid file through the public writer, block by block: `edit` gets each block's
/// id, directory entry and raw bytes and returns what to store (see [`encode_like`] to keep the
/// block's own codec), and the file ends with `meta`. Rule tests use it to build a file that
/// breaks one rule and nothing else.
pub fn rebuild(
    bytes: &[u8],
    meta: &Metadata,
    mut edit: impl FnMut(u32, &oocfmt::BlockEntry, Vec<u8>) -> TestResult<oocfmt::EncodedBlock>,
) -> TestResult<Vec<u8>> {
    let r = open_bytes(bytes, oocfmt::ReadOptions::default())?;
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("rebuilt.oocf");
    let wopts = WriteOptions {
        lod: r.lod_kinds(),
        ..opts(r.header().block_size_log2, Codec::None)
    };
    let mut w = Writer::create(&path, wopts)?;
    for id in 0..r.header().sections.block_count {
        let b = r.read_block(id)?;
        w.write_encoded(edit(id, &b.entry, b.data)?)?;
    }
    w.finish(meta)?;
    Ok(std::fs::read(&path)?)
}

/// `raw` encoded as block `e` of the source was: same kind, level, item count and codec.
pub fn encode_like(e: &oocfmt::BlockEntry, raw: &[u8]) -> TestResult<oocfmt::EncodedBlock> {
    let codec = match e.codec {
        oocfmt::CodecId::None => Codec::None,
        oocfmt::CodecId::Lz4 => Codec::Lz4,
        oocfmt::CodecId::Zstd => Codec::Zstd(3),
    };
    Ok(oocfmt::EncodedBlock::encode(
        codec,
        e.kind,
        e.level,
        e.item_count,
        raw,
    )?)
}
