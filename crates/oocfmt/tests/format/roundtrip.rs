//! Round trips (proptest): arbitrary well-formed contents — metadata, sequences of treelet,
//! triangle and proxy blocks built with the record writers, every codec, block sizes 4 KiB to
//! 64 KiB — are written, read back through positioned reads and a memory map, and compared
//! field by field; plus record-level, codec, header, trailer and directory-entry round trips.

use crate::common;

use common::{proptest_config, read_all_blocks, verify_bytes};
use oocfmt::directory::BlockEntry;
use oocfmt::header::{Header, SectionTable};
use oocfmt::metadata::{Build, Counts, Material, Part, Provenance, Scene, Schema, TreeletRef};
use oocfmt::records::triangle::{oct_decode, oct_encode, ATTR_PART_WIDTH};
use oocfmt::records::{
    Footprint, LodKinds, Node, ProxyRecord, Sample, TreeletBlock, TreeletBlockWriter, Triangle,
    TriangleBlock, TriangleBlockWriter, Vertex, Voxel,
};
use oocfmt::verify::VerifyOptions;
use oocfmt::{
    BlockKind, Codec, CodecId, Metadata, ReadOptions, Reader, Trailer, WriteOptions, Writer,
};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// Strategies

fn finite_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -1.0e6f32..1.0e6f32,
        1 => prop::num::f32::NORMAL | prop::num::f32::SUBNORMAL | prop::num::f32::ZERO,
    ]
}

fn finite_f64() -> impl Strategy<Value = f64> {
    prop_oneof![4 => -1.0e9f64..1.0e9f64, 1 => prop::num::f64::NORMAL | prop::num::f64::ZERO]
}

fn text() -> impl Strategy<Value = String> {
    "\\PC{0,16}"
}

fn metadata() -> impl Strategy<Value = Metadata> {
    let scene = (
        prop::array::uniform3(finite_f32()),
        prop::array::uniform3(finite_f32()),
        prop::array::uniform3(finite_f64()),
    )
        .prop_map(|(a, b, origin)| {
            // A box: min ≤ max on every axis (the reader refuses an inverted box with a root).
            let bounds_min = [a[0].min(b[0]), a[1].min(b[1]), a[2].min(b[2])];
            let bounds_max = [a[0].max(b[0]), a[1].max(b[1]), a[2].max(b[2])];
            Scene {
                bounds_min,
                bounds_max,
                origin,
            }
        });
    let root = prop::option::of(
        (any::<u32>(), any::<u32>()).prop_map(|(block, treelet)| TreeletRef { block, treelet }),
    );
    let counts = (
        prop::array::uniform10(any::<u64>()),
        any::<u32>(),
        any::<u32>(),
    )
        .prop_map(|(c, depth, lod_levels)| Counts {
            triangles: c[0],
            triangle_records: c[1],
            vertices: c[2],
            basic_nodes: c[3],
            lod_nodes: c[4],
            leaves: c[5],
            voxels_single: c[6],
            voxels_six: c[7],
            proxies: c[8],
            treelets: c[9],
            depth,
            lod_levels,
        });
    let schema = prop::array::uniform4(any::<bool>()).prop_map(|b| Schema {
        vertex_normals: b[0],
        vertex_colours: b[1],
        triangle_materials: b[2],
        six_sample_voxels: b[3],
    });
    let materials = prop::collection::vec(
        (text(), prop::array::uniform3(finite_f32()))
            .prop_map(|(name, diffuse)| Material { name, diffuse }),
        0..4,
    );
    let build = (
        1u8..=255,
        any::<u32>(),
        prop::collection::vec((text(), text()), 0..4),
    )
        .prop_map(|(treelet_height, max_leaf_triangles, params)| Build {
            treelet_height,
            max_leaf_triangles,
            params,
        });
    let provenance = (text(), prop::collection::vec(text(), 0..3))
        .prop_map(|(generator, sources)| Provenance { generator, sources });
    // Raw parts: parent and source pick among what exists once the table is known.
    let parts = prop::collection::vec(
        (
            text(),
            any::<Option<u32>>(),
            any::<Option<u32>>(),
            any::<u64>(),
            prop::array::uniform6(finite_f32()),
        ),
        0..5,
    );
    (
        scene, root, counts, schema, materials, build, provenance, parts,
    )
        .prop_map(
            |(scene, root, counts, schema, materials, build, provenance, parts)| {
                let sources = provenance.sources.len() as u32;
                let parts = parts
                    .into_iter()
                    .zip(0u32..)
                    .map(|((name, parent, source, triangles, b), i)| Part {
                        name,
                        parent: parent.filter(|_| i > 0).map(|p| p % i.max(1)),
                        source: source.filter(|_| sources > 0).map(|s| s % sources.max(1)),
                        triangles,
                        bounds_min: [b[0], b[1], b[2]],
                        bounds_max: [b[3], b[4], b[5]],
                    })
                    .collect();
                Metadata {
                    scene,
                    root,
                    counts,
                    schema,
                    materials,
                    build,
                    provenance,
                    parts,
                }
            },
        )
}

/// A valid sample: not empty, not single, axis < 3, u and v ≠ −32.
fn sample() -> impl Strategy<Value = Sample> {
    let component = (0u32..63).prop_map(|c| if c >= 32 { c + 1 } else { c });
    (
        0u32..1 << 15,
        any::<bool>(),
        0u32..3,
        component.clone(),
        component,
    )
        .prop_map(|(rgb, sign, axis, u, v)| {
            Sample(rgb | (u32::from(sign) << 15) | (axis << 16) | (u << 18) | (v << 24))
        })
}

/// A footprint: often [`Footprint::FULL`] (nothing to store), else any shade and coverage.
fn footprint() -> impl Strategy<Value = Footprint> {
    prop_oneof![
        1 => Just(Footprint::FULL),
        2 => (any::<u8>(), any::<u8>()).prop_map(|(shade, coverage)| Footprint { shade, coverage }),
    ]
}

/// A voxel of either kind, with footprints (all [`Footprint::FULL`] about a third of the time
/// for 1-sample voxels, rarely for 6-sample ones).
fn voxel() -> impl Strategy<Value = Voxel> {
    prop_oneof![
        (sample(), footprint()).prop_map(|(s, f)| Voxel::Single(s, f)),
        (
            prop::array::uniform6(sample()),
            prop::array::uniform6(footprint())
        )
            .prop_map(|(s, f)| Voxel::Six(s, f)),
        prop::array::uniform6(sample()).prop_map(Voxel::six),
    ]
}

/// What `v` decodes to from a file written with (`filtered`) or without `LOD_FILTERED`: the
/// same voxel, or without footprints.
fn as_stored(v: Voxel, filtered: bool) -> Voxel {
    match (v, filtered) {
        (v, true) => v,
        (Voxel::Single(s, _), false) => Voxel::single(s),
        (Voxel::Six(s, _), false) => Voxel::six(s),
    }
}

fn proxy_sample() -> impl Strategy<Value = Sample> {
    prop_oneof![3 => sample(), 1 => Just(Sample::EMPTY)]
}

fn proxy_record() -> impl Strategy<Value = ProxyRecord> {
    (
        any::<u32>(),
        0.0f32..1.0e9,
        prop::array::uniform32(proxy_sample()),
    )
        .prop_map(|(node_block, area, s)| {
            let mut samples = [Sample(0); 18];
            samples.copy_from_slice(&s[..18]);
            ProxyRecord {
                node_block,
                area,
                samples,
            }
        })
}

/// A node of a treelet as the test lays it out: basic nodes have children in the treelet; LOD
/// nodes and leaves are at its bottom.
#[derive(Clone, Debug)]
enum Shape {
    Basic {
        axis: u8,
        split: f32,
        left: Option<Box<Shape>>,
        right: Option<Box<Shape>>,
    },
    Lod {
        axis: u8,
        split: f32,
        radius: f32,
        presence: u8,
        child_treelet: u32,
        child_block: u32,
        proxy: u32,
        voxel: Voxel,
    },
    Leaf {
        count: u16,
        first: u16,
        block: u32,
    },
}

fn bottom() -> impl Strategy<Value = Shape> {
    let lod = (
        0u8..3,
        finite_f32(),
        0.0f32..1.0e6,
        1u8..4,
        0u32..=0x00ff_ffff,
        any::<u32>(),
        any::<u32>(),
        voxel(),
    )
        .prop_map(
            |(axis, split, radius, presence, child_treelet, child_block, proxy, voxel)| {
                Shape::Lod {
                    axis,
                    split,
                    radius,
                    presence,
                    child_treelet,
                    child_block,
                    proxy,
                    voxel,
                }
            },
        );
    let leaf =
        (1u16..=4095, any::<u16>(), any::<u32>()).prop_map(|(count, first, block)| Shape::Leaf {
            count,
            first,
            block,
        });
    prop_oneof![leaf, lod]
}

fn shape() -> impl Strategy<Value = Shape> {
    bottom().prop_recursive(4, 16, 2, |inner| {
        (
            0u8..3,
            finite_f32(),
            prop::option::of(inner.clone()),
            prop::option::of(inner),
            any::<bool>(),
        )
            .prop_map(|(axis, split, left, right, which)| {
                // An inner node needs at least one child.
                let (left, right) = match (left, right) {
                    (None, None) if which => (
                        Some(Box::new(Shape::Leaf {
                            count: 1,
                            first: 0,
                            block: 0,
                        })),
                        None,
                    ),
                    (None, None) => (
                        None,
                        Some(Box::new(Shape::Leaf {
                            count: 2,
                            first: 1,
                            block: 1,
                        })),
                    ),
                    (l, r) => (l.map(Box::new), r.map(Box::new)),
                };
                Shape::Basic {
                    axis,
                    split,
                    left,
                    right,
                }
            })
    })
}

/// A node as laid out: its position, the node, and its LOD entry's voxel and part word as they
/// decode.
type Laid = (usize, Node, Option<Voxel>, Option<u32>);

/// Lays `s` out in preorder, voxels as a file with (`filtered`) or without `LOD_FILTERED`
/// stores them, each LOD entry ending with a part word below `parts` where the file has part
/// ids (two or more parts); appends what every node decodes to.
fn emit(
    w: &mut TreeletBlockWriter,
    s: &Shape,
    filtered: bool,
    parts: usize,
    out: &mut Vec<Laid>,
) -> oocfmt::Result<()> {
    let pos = w.next_node_pos();
    match s {
        Shape::Basic {
            axis,
            split,
            left,
            right,
        } => {
            let placeholder = Node::Basic {
                axis: *axis,
                split: *split,
                left: 1,
                right: 1,
            };
            w.push_node(&placeholder);
            let slot = out.len();
            out.push((pos, placeholder, None, None));
            let mut units = [0u16; 2];
            for (k, child) in [left, right].into_iter().enumerate() {
                if let Some(c) = child {
                    let at = w.next_node_pos();
                    emit(w, c, filtered, parts, out)?;
                    units[k] = TreeletBlockWriter::units_between(pos, at)?;
                }
            }
            let node = Node::Basic {
                axis: *axis,
                split: *split,
                left: units[0],
                right: units[1],
            };
            w.patch_node(pos, &node)?;
            out[slot].1 = node;
        }
        Shape::Lod {
            axis,
            split,
            radius,
            presence,
            child_treelet,
            child_block,
            proxy,
            voxel,
        } => {
            let voxel_offset = w.push_voxel(voxel, filtered);
            let part = (parts >= 2).then(|| child_treelet % parts as u32);
            if let Some(p) = part {
                w.push_lod_part(p);
            }
            let node = Node::Lod {
                axis: *axis,
                split: *split,
                radius: *radius,
                left_present: presence & 1 != 0,
                right_present: presence & 2 != 0,
                child_treelet: *child_treelet,
                child_block: *child_block,
                voxel_offset,
                proxy: *proxy,
            };
            w.push_node(&node);
            out.push((pos, node, Some(as_stored(*voxel, filtered)), part));
        }
        Shape::Leaf {
            count,
            first,
            block,
        } => {
            let node = Node::Leaf {
                count: *count,
                first: *first,
                block: *block,
            };
            w.push_node(&node);
            out.push((pos, node, None, None));
        }
    }
    Ok(())
}

#[derive(Clone, Debug)]
struct TriangleSpec {
    vertices: Vec<([f32; 3], [i16; 2], [u8; 4])>,
    triangles: Vec<([u16; 3], u16)>,
    list: Vec<u16>,
    primary: u16,
}

fn triangle_spec() -> impl Strategy<Value = TriangleSpec> {
    (1usize..20, 1usize..30).prop_flat_map(|(w, t)| {
        let wmax = w as u16;
        let tmax = t as u16;
        (
            prop::collection::vec(
                (
                    prop::array::uniform3(finite_f32()),
                    any::<[i16; 2]>(),
                    any::<[u8; 4]>(),
                ),
                w,
            ),
            prop::collection::vec((prop::array::uniform3(0..wmax), any::<u16>()), t),
            prop::collection::vec(0..tmax, 0..40),
            0..=tmax,
        )
            .prop_map(|(vertices, triangles, list, primary)| TriangleSpec {
                vertices,
                triangles,
                list,
                primary,
            })
    })
}

#[derive(Clone, Debug)]
enum BlockSpec {
    Treelets(Vec<Shape>),
    Triangles(TriangleSpec),
    Proxies(Vec<ProxyRecord>),
}

fn block_spec() -> impl Strategy<Value = BlockSpec> {
    prop_oneof![
        2 => prop::collection::vec(shape(), 1..4).prop_map(BlockSpec::Treelets),
        2 => triangle_spec().prop_map(BlockSpec::Triangles),
        1 => prop::collection::vec(proxy_record(), 1..4).prop_map(BlockSpec::Proxies),
    ]
}

fn codec() -> impl Strategy<Value = Codec> {
    prop_oneof![
        Just(Codec::None),
        Just(Codec::Lz4),
        (1i32..=5).prop_map(Codec::Zstd)
    ]
}

// ---------------------------------------------------------------------------------------------
// Encoding a block and what it must decode to

/// A block as written: kind, level, item count, raw bytes, and the records it must decode to.
struct Built {
    kind: BlockKind,
    level: u16,
    items: u32,
    raw: Vec<u8>,
    expect: Expect,
}

enum Expect {
    Treelets(Vec<Vec<Laid>>),
    Triangles {
        list: Vec<u16>,
        triangles: Vec<Triangle>,
        vertices: Vec<Vertex>,
        primary: u16,
        attrs: u16,
    },
    Proxies(Vec<ProxyRecord>),
}

/// Encodes `spec` as a block of a file with (`filtered`) or without `LOD_FILTERED`, whose part
/// table has `parts` parts (ids where `attrs` has a part-id width, below `parts`).
fn build(
    spec: &BlockSpec,
    level: u16,
    attrs: u16,
    filtered: bool,
    parts: usize,
) -> oocfmt::Result<Built> {
    Ok(match spec {
        BlockSpec::Treelets(shapes) => {
            let mut w = TreeletBlockWriter::new();
            let mut all = Vec::new();
            for s in shapes {
                w.begin_treelet();
                let start = w.next_node_pos();
                let mut nodes = Vec::new();
                emit(&mut w, s, filtered, parts, &mut nodes)?;
                // Positions relative to the treelet start, as the walk reports them absolute.
                let _ = start;
                all.push(nodes);
            }
            assert_eq!(w.treelet_count(), shapes.len());
            let raw_len = w.raw_len();
            let raw = w.finish();
            assert_eq!(raw.len(), raw_len, "TreeletBlockWriter::raw_len");
            Built {
                kind: BlockKind::Treelet,
                level,
                items: shapes.len() as u32,
                raw,
                expect: Expect::Treelets(all),
            }
        }
        BlockSpec::Triangles(t) => {
            let mut w = TriangleBlockWriter::new(attrs);
            let mut vertices = Vec::new();
            for &(position, n, c) in &t.vertices {
                let v = Vertex {
                    position,
                    normal: (attrs & 1 != 0).then_some(n),
                    colour: (attrs & 2 != 0).then_some(c),
                };
                w.push_vertex(v)?;
                vertices.push(v);
            }
            let mut triangles = Vec::new();
            let ids = attrs & ATTR_PART_WIDTH != 0;
            for (i, &(v, m)) in (0u32..).zip(&t.triangles) {
                let tri = Triangle {
                    v,
                    material: (attrs & 4 != 0).then_some(m),
                    part: ids.then(|| (u32::from(m) + 7 * i) % parts.max(1) as u32),
                };
                w.push_triangle(tri)?;
                triangles.push(tri);
            }
            for &e in &t.list {
                w.push_list(e)?;
            }
            w.set_primary_count(t.primary);
            assert_eq!(w.triangle_count(), triangles.len());
            let raw_len = w.raw_len();
            assert_eq!(
                raw_len,
                TriangleBlockWriter::raw_len_for(
                    attrs,
                    t.list.len(),
                    triangles.len(),
                    vertices.len()
                )
            );
            let raw = w.finish();
            assert_eq!(raw.len(), raw_len, "TriangleBlockWriter::raw_len");
            let items = triangles.len() as u32;
            Built {
                kind: BlockKind::Triangle,
                level: 0,
                items,
                raw,
                expect: Expect::Triangles {
                    list: t.list.clone(),
                    triangles,
                    vertices,
                    primary: t.primary,
                    attrs,
                },
            }
        }
        BlockSpec::Proxies(p) => {
            let mut raw = Vec::new();
            for r in p {
                r.encode_into(&mut raw);
            }
            Built {
                kind: BlockKind::Proxy,
                level: 0,
                items: p.len() as u32,
                raw,
                expect: Expect::Proxies(p.clone()),
            }
        }
    })
}

/// Checks that the decoded block `b` holds what `e` says.
fn check_block(b: &oocfmt::Block, e: &Expect) -> Result<(), TestCaseError> {
    match e {
        Expect::Treelets(treelets) => {
            let block = b
                .treelets()
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert_eq!(block.treelet_count(), treelets.len());
            let mut seen = Vec::new();
            let sum = block
                .walk_lods(|t, pos, n, entry| {
                    seen.push((t, pos, *n, entry.part));
                    Ok(())
                })
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            let mut expected = Vec::new();
            for (t, nodes) in treelets.iter().enumerate() {
                for &(pos, node, voxel, part) in nodes {
                    expected.push((t, pos, node, part));
                    prop_assert_eq!(block.node(pos).ok(), Some(node));
                    if let (Node::Lod { voxel_offset, .. }, Some(v)) = (node, voxel) {
                        prop_assert_eq!(block.voxel(voxel_offset).ok(), Some(v));
                    }
                }
            }
            prop_assert_eq!(&seen, &expected);
            let all = treelets.iter().flatten();
            let lods = all
                .clone()
                .filter(|x| matches!(x.1, Node::Lod { .. }))
                .count() as u64;
            prop_assert_eq!(sum.lod_nodes, lods);
            prop_assert_eq!(
                sum.basic_nodes + sum.lod_nodes + sum.leaves,
                all.count() as u64
            );
        }
        Expect::Triangles {
            list,
            triangles,
            vertices,
            primary,
            attrs,
        } => {
            let t = b
                .triangles(*attrs)
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert!(t.check_contents().is_ok());
            prop_assert_eq!(t.attributes(), *attrs);
            prop_assert_eq!(t.primary_count(), usize::from(*primary));
            prop_assert_eq!(t.list_count(), list.len());
            prop_assert_eq!(t.triangle_count(), triangles.len());
            prop_assert_eq!(t.vertex_count(), vertices.len());
            for (i, &e) in list.iter().enumerate() {
                prop_assert_eq!(t.list(i).ok(), Some(e));
            }
            for (i, tri) in triangles.iter().enumerate() {
                prop_assert_eq!(t.triangle(i).ok(), Some(*tri));
                let p = t.positions(i).ok();
                prop_assert_eq!(p, Some(tri.v.map(|v| vertices[usize::from(v)].position)));
            }
            for (i, v) in vertices.iter().enumerate() {
                prop_assert_eq!(t.vertex(i).ok(), Some(*v));
            }
            // The bulk readers a decoder uses give the records written, in order.
            prop_assert_eq!(&t.list_entries().collect::<Vec<_>>(), list);
            prop_assert_eq!(&t.all_triangles().collect::<Vec<_>>(), triangles);
            prop_assert_eq!(&t.all_vertices().collect::<Vec<_>>(), vertices);
            prop_assert!(
                t.list(list.len()).is_err()
                    && t.triangle(triangles.len()).is_err()
                    && t.vertex(vertices.len()).is_err()
            );
        }
        Expect::Proxies(p) => {
            let got = b
                .proxies()
                .map_err(|e| TestCaseError::fail(e.to_string()))?;
            prop_assert_eq!(&got, p);
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Container round trip

fn write_file(
    path: &std::path::Path,
    opts: WriteOptions,
    blocks: &[Built],
    meta: &Metadata,
) -> oocfmt::Result<oocfmt::WriteSummary> {
    let mut w = Writer::create(path, opts)?;
    for (i, b) in blocks.iter().enumerate() {
        let id = w.write_block(b.kind, b.level, b.items, &b.raw)?;
        assert_eq!(id as usize, i);
    }
    w.finish(meta)
}

fn round_trip(
    meta: Metadata,
    specs: Vec<BlockSpec>,
    mut levels: Vec<u16>,
    codec: Codec,
    log2: u8,
    filtered: bool,
) -> Result<(), TestCaseError> {
    let fail = |e: &dyn std::fmt::Display| TestCaseError::fail(e.to_string());
    let attrs = meta.triangle_attributes();
    let parts = meta.parts.len();
    levels.sort_unstable();
    let mut level_iter = levels.into_iter();
    let mut blocks = Vec::new();
    for s in &specs {
        let level = if matches!(s, BlockSpec::Treelets(_)) {
            level_iter.next().unwrap_or(u16::MAX)
        } else {
            0
        };
        blocks.push(build(s, level, attrs, filtered, parts).map_err(|e| fail(&e))?);
    }
    let block_size = 1usize << log2;
    blocks.retain(|b| b.raw.len() <= block_size);
    let dir = tempfile::tempdir().map_err(|e| fail(&e))?;
    let path = dir.path().join("rt.oocf");
    let lod = if filtered {
        LodKinds::VOXEL.filtered()
    } else {
        LodKinds::VOXEL
    }
    .with_parts(parts >= 2);
    let opts = WriteOptions {
        block_size_log2: log2,
        codec,
        lod,
    };
    let summary = write_file(&path, opts, &blocks, &meta).map_err(|e| fail(&e))?;
    let bytes = std::fs::read(&path).map_err(|e| fail(&e))?;
    prop_assert_eq!(bytes.len() as u64, summary.file_length);
    prop_assert_eq!(summary.block_count as usize, blocks.len());

    for mmap in [false, true] {
        let r = if mmap {
            Reader::open_mmap(&path, ReadOptions::default())
        } else {
            Reader::open(&path, ReadOptions::default())
        };
        let r = r.map_err(|e| fail(&e))?;
        prop_assert_eq!(r.metadata(), &meta);
        prop_assert_eq!(r.identity(), summary.identity);
        prop_assert_eq!(r.file_len(), summary.file_length);
        prop_assert_eq!(r.header().block_size_log2, log2);
        // Spec §11: an unfiltered voxel-only file is a 1.0 file; a filtered one is 1.2; one
        // with a part table 1.3, with part ids from two parts on.
        let (mut minor, mut bits) = if filtered {
            (2, oocfmt::header::INCOMPAT_LOD_FILTERED)
        } else {
            (0, 0)
        };
        if parts > 0 {
            minor = 3;
        }
        if parts >= 2 {
            bits |= oocfmt::header::INCOMPAT_PART_IDS;
        }
        prop_assert_eq!((r.header().major, r.header().minor), (1, minor));
        prop_assert_eq!(r.header().incompatible_features, bits);
        prop_assert_eq!(r.lod_kinds(), lod);
        let has_proxies = blocks.iter().any(|b| b.kind == BlockKind::Proxy);
        prop_assert_eq!(
            r.header().compatible_features & oocfmt::header::COMPAT_PROXIES != 0,
            has_proxies
        );
        prop_assert_eq!(r.entries().len(), blocks.len());
        let mut offset = oocfmt::header::HEADER_LEN as u64;
        let mut proxies = Vec::new();
        for (id, (e, b)) in (0u32..).zip(r.entries().iter().zip(&blocks)) {
            prop_assert_eq!(e.kind, b.kind);
            prop_assert_eq!(e.level, b.level);
            prop_assert_eq!(e.item_count, b.items);
            prop_assert_eq!(e.raw_length as usize, b.raw.len());
            prop_assert_eq!(e.offset, offset);
            offset += u64::from(e.stored_length);
            match e.codec {
                CodecId::None => prop_assert_eq!(e.stored_length, e.raw_length),
                c => {
                    prop_assert_eq!(c, codec.id());
                    prop_assert!(e.stored_length < e.raw_length);
                }
            }
            prop_assert_eq!(r.entry(id).ok(), Some(e));
            if mmap {
                prop_assert_eq!(
                    r.stored_slice(id).map(<[u8]>::len),
                    Some(e.stored_length as usize)
                );
            }
            let got = r.read_block(id).map_err(|e| fail(&e))?;
            prop_assert_eq!(&got.data, &b.raw);
            prop_assert_eq!(got.entry, *e);
            check_block(&got, &b.expect)?;
            if let Expect::Proxies(p) = &b.expect {
                proxies.extend_from_slice(p);
            }
        }
        prop_assert_eq!(offset, r.header().sections.directory_offset);
        prop_assert_eq!(r.proxies(), &proxies[..]);
        prop_assert!(r.read_block(blocks.len() as u32).is_err());
        read_all_blocks(&r).map_err(|e| fail(&e))?;
    }
    let report = verify_bytes(&bytes, &VerifyOptions::default()).map_err(|e| fail(&e))?;
    prop_assert!(
        report.valid && report.issues.is_empty(),
        "{:?}",
        report.issues
    );
    prop_assert_eq!(report.blocks_checked as usize, blocks.len());

    // The same input gives a byte-identical file.
    let again = dir.path().join("again.oocf");
    write_file(&again, opts, &blocks, &meta).map_err(|e| fail(&e))?;
    prop_assert!(
        std::fs::read(&again).map_err(|e| fail(&e))? == bytes,
        "writing twice gave different files"
    );
    Ok(())
}

proptest! {
    #![proptest_config(proptest_config(96))]

    #[test]
    fn arbitrary_contents_round_trip(
        meta in metadata(),
        specs in prop::collection::vec(block_spec(), 0..7),
        levels in prop::collection::vec(0u16..4, 7),
        codec in codec(),
        log2 in 12u8..=16,
        filtered in any::<bool>(),
    ) {
        round_trip(meta, specs, levels, codec, log2, filtered)?;
    }
}

// ---------------------------------------------------------------------------------------------
// Record-level round trips

fn node() -> impl Strategy<Value = Node> {
    let basic = (0u8..3, finite_f32(), 0u16..=4095, 0u16..=4095).prop_filter_map(
        "two empty children",
        |(axis, split, l, r)| {
            (l != 0 || r != 0).then_some(Node::Basic {
                axis,
                split,
                left: l,
                right: r,
            })
        },
    );
    let lod = (
        0u8..3,
        finite_f32(),
        0.0f32..1.0e30,
        1u8..4,
        0u32..=0x00ff_ffff,
        any::<u32>(),
        any::<u32>(),
        any::<u32>(),
    )
        .prop_map(
            |(axis, split, radius, p, child_treelet, child_block, voxel_offset, proxy)| Node::Lod {
                axis,
                split,
                radius,
                left_present: p & 1 != 0,
                right_present: p & 2 != 0,
                child_treelet,
                child_block,
                voxel_offset,
                proxy,
            },
        );
    let leaf =
        (1u16..=4095, any::<u16>(), any::<u32>()).prop_map(|(count, first, block)| Node::Leaf {
            count,
            first,
            block,
        });
    prop_oneof![basic, lod, leaf]
}

fn unit_vector() -> impl Strategy<Value = [f32; 3]> {
    prop::array::uniform3(-1.0f32..1.0).prop_filter_map("too short", |v| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        (l > 1e-3).then(|| [v[0] / l, v[1] / l, v[2] / l])
    })
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

proptest! {
    #![proptest_config(proptest_config(256))]

    #[test]
    fn nodes_round_trip(n in node(), pad in 0usize..3) {
        let mut v = vec![0xeeu8; pad * 8];
        n.encode_into(&mut v);
        prop_assert_eq!(v.len(), pad * 8 + n.byte_len());
        prop_assert_eq!(Node::decode(&v, pad * 8).ok(), Some(n));
        prop_assert!(n.check().is_ok());
        // A truncated node never decodes.
        prop_assert!(Node::decode(&v[..v.len() - 1], pad * 8).is_err());
    }

    #[test]
    fn samples_and_voxels_round_trip(s in sample(), vox in voxel(), pad in 0usize..4) {
        prop_assert!(s.check().is_ok());
        prop_assert!(!s.is_single() && !s.is_empty());
        prop_assert!(s.with_single(true).is_single());
        prop_assert_eq!(s.with_single(true).with_single(false), s);
        let n = s.normal();
        prop_assert!((dot(n, n) - 1.0).abs() < 1e-5);
        for filtered in [false, true] {
            let mut area = vec![0u8; pad * 4];
            vox.encode_into(&mut area, filtered);
            prop_assert_eq!(area.len(), pad * 4 + vox.byte_len(filtered));
            let back = as_stored(vox, filtered);
            prop_assert_eq!(Voxel::decode(&area, pad * 4, filtered).ok(), Some(back));
            prop_assert!(Voxel::decode(&area, pad * 4 + 1, filtered).is_err(), "unaligned voxel offset");
            prop_assert!(Voxel::decode(&area[..area.len() - 1], pad * 4, filtered).is_err());
            for face in 0..6 {
                let f = back.face(face);
                let want = match back { Voxel::Single(x, g) => (x, g), Voxel::Six(x, g) => (x[face], g[face]) };
                prop_assert_eq!(f, want);
            }
        }
    }

    /// Spec §5.1: a file with `LOD_FILTERED` keeps a voxel's footprints, in 8 or 36 bytes where
    /// one is not full (4 or 24 where all are, bit 30 clear); a file without it drops them, so
    /// they decode full, in 4 or 24 bytes.
    #[test]
    fn voxel_footprints_round_trip_as_the_spec_lays_them_out(vox in voxel(), pad in 0usize..3) {
        let (six, feet): (bool, Vec<Footprint>) = match vox {
            Voxel::Single(_, f) => (false, vec![f]),
            Voxel::Six(_, f) => (true, f.to_vec()),
        };
        let partial = feet.iter().any(|f| *f != Footprint::FULL);
        for filtered in [false, true] {
            let words = filtered && partial;
            let want_len = match (six, words) {
                (false, false) => 4,
                (false, true) => 8,
                (true, false) => 24,
                (true, true) => 36,
            };
            let mut area = vec![0u8; pad * 4];
            vox.encode_into(&mut area, filtered);
            let at = pad * 4;
            prop_assert_eq!(area.len() - at, want_len);
            let word = |i: usize| u32::from_le_bytes([area[at + 4 * i], area[at + 4 * i + 1], area[at + 4 * i + 2], area[at + 4 * i + 3]]);
            prop_assert_eq!(word(0) >> 30 & 1 == 1, words, "bit 30 of the first sample");
            if words && !six {
                let f = feet[0];
                prop_assert_eq!(word(1), u32::from(f.shade) | u32::from(f.coverage) << 8);
            }
            if words && six {
                for k in 0..3 {
                    let half = |f: Footprint| u32::from(f.shade) | u32::from(f.coverage) << 8;
                    prop_assert_eq!(word(6 + k), half(feet[2 * k]) | half(feet[2 * k + 1]) << 16);
                }
            }
            let got = Voxel::decode(&area, at, filtered).ok();
            let got_feet: Option<Vec<Footprint>> = got.map(|v| (0..6).map(|f| v.face(f).1).collect());
            let want_feet: Vec<Footprint> = (0..6)
                .map(|f| if filtered { feet[f.min(feet.len() - 1)] } else { Footprint::FULL })
                .collect();
            prop_assert_eq!(got_feet, Some(want_feet));
            // The other reading: unfiltered bytes are valid in a filtered file (as 1.1 voxels);
            // footprint words are refused in an unfiltered one.
            let other = Voxel::decode(&area, at, !filtered).ok();
            if words {
                prop_assert_eq!(other, None);
            } else {
                prop_assert_eq!(other, Some(as_stored(vox, false)));
            }
        }
    }

    #[test]
    fn packing_keeps_normals_and_colours(n in unit_vector(), scale in 1.0e-3f32..1.0e3, c in prop::array::uniform3(0.0f32..=1.0)) {
        let s = Sample::pack([n[0] * scale, n[1] * scale, n[2] * scale], c);
        prop_assert!(s.check().is_ok());
        prop_assert!(!s.is_single() && !s.is_empty());
        let m = s.normal();
        prop_assert!(dot(n, m) > 0.999, "{:?} -> {:?}", n, m);
        let back = s.colour();
        for k in 0..3 {
            prop_assert!((back[k] - c[k]).abs() <= 0.5 / 31.0 + 1e-6, "{:?} -> {:?}", c, back);
        }
    }

    #[test]
    fn any_packed_sample_is_valid(n in prop::array::uniform3(any::<f32>()), c in prop::array::uniform3(any::<f32>())) {
        let s = Sample::pack(n, c);
        prop_assert!(s.check().is_ok() && !s.is_empty() && !s.is_single());
        prop_assert!(s.normal().iter().all(|x| x.is_finite()));
    }

    #[test]
    fn proxy_blocks_round_trip(records in prop::collection::vec(proxy_record(), 1..6)) {
        let mut raw = Vec::new();
        for r in &records {
            r.encode_into(&mut raw);
        }
        prop_assert_eq!(raw.len(), records.len() * oocfmt::records::PROXY_LEN);
        prop_assert_eq!(ProxyRecord::decode_block(&raw, records.len()).ok(), Some(records.clone()));
        prop_assert!(ProxyRecord::decode_block(&raw, records.len() + 1).is_err());
        prop_assert!(ProxyRecord::decode_block(&raw[..raw.len() - 1], records.len()).is_err());
    }

    #[test]
    fn treelet_and_triangle_blocks_round_trip_alone(spec in block_spec(), attrs in 0u16..8, filtered in any::<bool>()) {
        let lod = if filtered { LodKinds::VOXEL.filtered() } else { LodKinds::VOXEL };
        let b = build(&spec, 0, attrs, filtered, 0).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let block = oocfmt::Block {
            id: 0,
            entry: BlockEntry {
                offset: 64,
                stored_length: b.raw.len() as u32,
                raw_length: b.raw.len() as u32,
                crc: oocfmt::checksum::crc32c(&b.raw),
                kind: b.kind,
                codec: CodecId::None,
                level: 0,
                item_count: b.items,
            },
            data: b.raw.clone(),
            lod,
        };
        check_block(&block, &b.expect)?;
        let schema = oocfmt::summary::BlockSchema { triangle_attributes: attrs, parts: 0 };
        let facts = oocfmt::summary::survey_block(&block.entry, &b.raw, Some(schema), lod);
        prop_assert!(facts.is_ok(), "{:?}", facts.err().map(|e| e.to_string()));
        if b.kind == BlockKind::Treelet {
            prop_assert!(TreeletBlock::parse_with(&b.raw, lod).is_ok());
        }
        if b.kind == BlockKind::Triangle {
            prop_assert!(TriangleBlock::parse(&b.raw, None).is_ok());
            if attrs != 0 {
                prop_assert!(TriangleBlock::parse(&b.raw, Some(attrs ^ 1)).is_err());
            }
        }
    }

    #[test]
    fn octahedral_normals_round_trip(n in unit_vector()) {
        let m = oct_decode(oct_encode(n));
        prop_assert!(dot(n, m) > 0.9999, "{:?} -> {:?}", n, m);
        prop_assert!((dot(m, m) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn codecs_round_trip_and_never_grow(
        data in prop_oneof![
            prop::collection::vec(any::<u8>(), 0..4096),
            (prop::collection::vec(any::<u8>(), 1..8), 1usize..2000).prop_map(|(p, n)| p.repeat(n)),
        ],
        codec in codec(),
    ) {
        let (id, stored) = codec.encode(&data).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert!(stored.len() <= data.len());
        if id == CodecId::None {
            prop_assert_eq!(&stored, &data);
        } else {
            prop_assert_eq!(id, codec.id());
            prop_assert!(stored.len() < data.len());
        }
        let mut out = vec![0u8; data.len()];
        prop_assert!(oocfmt::codec::decode_into(id, &stored, &mut out).is_ok());
        prop_assert_eq!(&out, &data);
        // Any other output length is refused.
        let mut longer = vec![0u8; data.len() + 1];
        prop_assert!(oocfmt::codec::decode_into(id, &stored, &mut longer).is_err());
        if !data.is_empty() {
            let mut shorter = vec![0u8; data.len() - 1];
            prop_assert!(oocfmt::codec::decode_into(id, &stored, &mut shorter).is_err());
        }
    }

    #[test]
    fn metadata_round_trips_and_tolerates_newer_fields(meta in metadata(), extra in prop::collection::vec(any::<u8>(), 1..16)) {
        use oocfmt::header::{VERSION_MINOR, VERSION_MINOR_FILTERED};
        let bytes = meta.encode().map_err(|e| TestCaseError::fail(e.to_string()))?;
        // The writer's minor for the value: 1.3 exactly with a part table.
        let minor = meta.minor_version().max(VERSION_MINOR_FILTERED);
        prop_assert_eq!(meta.parts.is_empty(), minor < 3);
        prop_assert_eq!(Metadata::decode(&bytes, minor).ok(), Some(meta.clone()));
        // A newer file always has the part-table field: an empty table is its zero length.
        let mut longer = bytes.clone();
        if meta.parts.is_empty() {
            longer.push(0);
        }
        prop_assert_eq!(Metadata::decode(&longer, VERSION_MINOR).ok(), Some(meta.clone()));
        longer.extend_from_slice(&extra);
        prop_assert_eq!(Metadata::decode(&longer, VERSION_MINOR + 1).ok(), Some(meta.clone()));
        prop_assert_eq!(Metadata::decode(&longer, VERSION_MINOR).err().map(|e| e.code()), Some(oocfmt::Code::MetadataDecode));
        for cut in [0, bytes.len() / 2, bytes.len() - 1] {
            prop_assert!(Metadata::decode(&bytes[..cut], VERSION_MINOR + 1).is_err());
        }
    }

    #[test]
    fn header_trailer_and_entries_round_trip(
        log2 in 12u8..=20,
        compat in any::<u64>(),
        minor in any::<u16>(),
        dir in any::<u64>(),
        count in any::<u32>(),
        meta_off in any::<u64>(),
        meta_len in any::<u32>(),
        crcs in any::<[u32; 3]>(),
        e in (any::<u64>(), 1u32..=4096, any::<u32>(), 1u8..=3, 0u8..3, any::<u16>(), 1u32..),
    ) {
        let sections = SectionTable { directory_offset: dir, block_count: count, metadata_offset: meta_off, metadata_length: meta_len };
        let mut h = Header::new(log2);
        h.minor = minor;
        h.compatible_features = compat;
        h.sections = sections;
        prop_assert_eq!(Header::decode(&h.encode()).ok(), Some(h));
        let t = Trailer { sections, directory_crc: crcs[0], metadata_crc: crcs[1], root_checksum: crcs[2] };
        prop_assert_eq!(Trailer::decode(&t.encode(), 0).ok(), Some(t));

        let (offset, raw, crc, kind, codec, level, item_count) = e;
        let kind = BlockKind::from_u8(kind).ok_or_else(|| TestCaseError::fail("kind"))?;
        let codec = CodecId::from_u8(codec).ok_or_else(|| TestCaseError::fail("codec"))?;
        let (stored_length, raw_length) = if codec == CodecId::None { (raw, raw) } else { (raw.max(2) / 2, raw.max(2)) };
        let level = if kind == BlockKind::Treelet { level } else { 0 };
        // The directory bounds item_count by what raw_length can hold (spec §4).
        let most = match kind {
            BlockKind::Treelet => raw_length.saturating_sub(16) / 12,
            BlockKind::Triangle => raw_length.saturating_sub(16) / 6,
            BlockKind::Proxy => raw_length / 80,
        };
        prop_assume!(most > 0);
        let item_count = 1 + (item_count - 1) % most;
        let offset = offset % (u64::MAX - 8192);
        let entry = BlockEntry { offset, stored_length, raw_length, crc, kind, codec, level, item_count };
        let mut v = Vec::new();
        entry.encode_into(&mut v);
        prop_assert_eq!(v.len(), oocfmt::directory::ENTRY_LEN);
        prop_assert_eq!(BlockEntry::decode(&v, 4096).ok(), Some(entry));
    }
}
