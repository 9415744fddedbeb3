//! One must-fail file per rule that spec/oocfmt.md states for `verify` beyond the framing the
//! corruption tests cover: each test builds a file that breaks exactly that rule (and a control
//! that keeps it, which must stay clean), and checks the issue code the spec gives it.

use crate::common;

use common::{
    deep, encode_like, fixture, leaf, metadata, metadata_bytes, open_bytes, read_all_blocks,
    rebuild, scene, square_vertices, vectors, verify_bytes, with_metadata, TestResult,
};
use oocfmt::metadata::{Counts, Schema, TreeletRef};
use oocfmt::records::{LodKinds, Node, TreeletBlock, TreeletBlockWriter, TriangleBlockWriter};
use oocfmt::verify::{Depth, Report, VerifyOptions};
use oocfmt::{
    BlockEntry, BlockKind, Code, Codec, CodecId, EncodedBlock, Metadata, ReadOptions, Severity,
    Writer,
};

pub(crate) fn at_depth(depth: Depth) -> VerifyOptions {
    VerifyOptions {
        depth,
        ..VerifyOptions::default()
    }
}

/// Every error in `r` has code `code`, and there is at least one.
pub(crate) fn only_errors(r: &Report, code: Code, what: &str) {
    let errors: Vec<_> = r
        .issues
        .iter()
        .filter(|i| i.severity == Severity::Error)
        .collect();
    assert!(
        !r.valid && !errors.is_empty() && errors.iter().all(|i| i.code == code),
        "{what}: expected only {code}, got {:?}",
        r.issues
    );
}

/// No issue at all under deep verify.
pub(crate) fn clean(b: &[u8], what: &str) -> TestResult {
    let r = verify_bytes(b, &deep())?;
    assert!(r.valid && r.issues.is_empty(), "{what}: {:?}", r.issues);
    Ok(())
}

pub(crate) fn vector(name: &str) -> TestResult<Vec<u8>> {
    vectors()?
        .into_iter()
        .find(|v| v.name == name)
        .map(|v| v.bytes)
        .ok_or_else(|| format!("no vector {name}").into())
}

pub(crate) fn meta_of(b: &[u8]) -> TestResult<Metadata> {
    Ok(open_bytes(b, ReadOptions::default())?.metadata().clone())
}

// ---------------------------------------------------------------------------------------------
// §6.2: nodes in strict preorder

/// Box 0..1 × 0..1 × 0: root P (x = 0.5) over L (y = 0.5) and the leaf R; L over the leaves LL
/// and LR. `preorder` lays it out P L LL LR R; otherwise breadth first, P L R LL LR: every child
/// forward, the right after the left, every byte covered once, but not preorder.
fn two_level_quad(preorder: bool) -> TestResult<Vec<u8>> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("f.oocf");
    let mut w = Writer::create(&path, common::opts(12, Codec::None))?;
    let p = |left, right| Node::Basic {
        axis: 0,
        split: 0.5,
        left,
        right,
    };
    let l = |left, right| Node::Basic {
        axis: 1,
        split: 0.5,
        left,
        right,
    };
    let (ll, lr, r) = (leaf(0, 1, 1), leaf(1, 1, 1), leaf(0, 2, 1));
    let mut t = TreeletBlockWriter::new();
    t.begin_treelet();
    let order = if preorder {
        [p(1, 4), l(1, 2), ll, lr, r]
    } else {
        [p(1, 2), l(2, 3), r, ll, lr]
    };
    for n in &order {
        t.push_node(n);
    }
    assert_eq!(w.write_block(BlockKind::Treelet, 0, 1, &t.finish())?, 0);
    let mut tri = TriangleBlockWriter::new(0);
    square_vertices(&mut tri, 0.0, 0)?;
    for v in [[0, 1, 2], [0, 2, 3]] {
        tri.push_triangle(oocfmt::records::Triangle {
            v,
            material: None,
            part: None,
        })?;
    }
    tri.push_list(0)?;
    tri.push_list(1)?;
    tri.set_primary_count(2);
    assert_eq!(w.write_block(BlockKind::Triangle, 0, 2, &tri.finish())?, 1);
    let counts = Counts {
        triangles: 2,
        triangle_records: 2,
        vertices: 4,
        basic_nodes: 2,
        leaves: 3,
        treelets: 1,
        depth: 3,
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
    w.finish(&meta)?;
    Ok(std::fs::read(&path)?)
}

#[test]
fn nodes_out_of_preorder_are_node_order() -> TestResult {
    clean(&two_level_quad(true)?, "preorder")?;
    let b = two_level_quad(false)?;
    only_errors(
        &verify_bytes(&b, &at_depth(Depth::Full))?,
        Code::NodeOrder,
        "breadth first",
    );
    let r = open_bytes(&b, ReadOptions::default())?;
    assert_eq!(
        read_all_blocks(&r).err().map(|e| e.code()),
        Some(Code::NodeOrder)
    );
    Ok(())
}

#[test]
fn a_node_reached_twice_in_a_treelet_is_node_overlap() -> TestResult {
    // P (left +8, right +16) over L (left +16 only): L's child and P's right child are one
    // leaf, which preorder walks twice; the second visit starts before the preorder position.
    let mut t = TreeletBlockWriter::new();
    t.begin_treelet();
    for n in [
        Node::Basic {
            axis: 0,
            split: 0.5,
            left: 1,
            right: 2,
        },
        Node::Basic {
            axis: 1,
            split: 0.5,
            left: 1,
            right: 0,
        },
        leaf(0, 2, 1),
    ] {
        t.push_node(&n);
    }
    let raw = t.finish();
    let src = two_level_quad(true)?;
    let b = rebuild(&src, &meta_of(&src)?, |id, e, data| {
        let data = if id == 0 { raw.clone() } else { data };
        encode_like(e, &data)
    })?;
    only_errors(
        &verify_bytes(&b, &at_depth(Depth::Full))?,
        Code::NodeOverlap,
        "shared leaf",
    );
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// §6.2: LOD entries tile the LOD area in node order

/// Positions (in the raw block) of the LOD nodes of a treelet block, in node order.
fn lod_nodes(raw: &[u8], kinds: LodKinds) -> TestResult<Vec<usize>> {
    let block = TreeletBlock::parse_with(raw, kinds)?;
    let base = 16 + 4 * block.treelet_count();
    let mut out = Vec::new();
    block.walk(|_, pos, n| {
        if matches!(n, Node::Lod { .. }) {
            out.push(base + pos);
        }
        Ok(())
    })?;
    Ok(out)
}

/// `name` with its first treelet block holding LOD nodes edited by `edit(raw, lod_node_positions)`.
fn with_lod_block(
    b: &[u8],
    edit: &dyn Fn(&mut Vec<u8>, &[usize]) -> TestResult,
) -> TestResult<Vec<u8>> {
    let r = open_bytes(b, ReadOptions::default())?;
    let kinds = r.lod_kinds();
    drop(r);
    let mut done = false;
    rebuild(b, &meta_of(b)?, |_, e: &BlockEntry, mut raw| {
        if !done && e.kind == BlockKind::Treelet {
            let lods = lod_nodes(&raw, kinds)?;
            if !lods.is_empty() {
                edit(&mut raw, &lods)?;
                done = true;
            }
        }
        encode_like(e, &raw)
    })
}

fn lod_bytes_add(raw: &mut [u8], n: u32) {
    let v = common::get_u32(raw, 8) + n;
    common::put_u32(raw, 8, v);
}

#[test]
fn lod_entries_must_tile_the_lod_area() -> TestResult {
    type LodEdit = fn(&mut Vec<u8>, &[usize]) -> TestResult;
    let cases: [(&str, LodEdit); 3] = [
        ("unreferenced bytes at the end", |raw, _| {
            raw.extend_from_slice(&[0; 4]);
            lod_bytes_add(raw, 4);
            Ok(())
        }),
        ("unreferenced bytes before the entries", |raw, lods| {
            let treelets = common::get_u32(raw, 0) as usize;
            let area = 16 + 4 * treelets + common::get_u32(raw, 4) as usize;
            let entry = raw[area..area + 4].to_vec();
            raw.splice(area..area, entry);
            lod_bytes_add(raw, 4);
            for &p in lods {
                let off = common::get_u32(raw, p + 16);
                common::put_u32(raw, p + 16, off + 4);
            }
            Ok(())
        }),
        ("two LOD nodes share an entry", |raw, lods| {
            // Two voxels of one size: the second node is pointed at the first's entry, and the
            // bytes it leaves unreferenced are made a copy of it, so nothing but the layout
            // changes.
            let treelets = common::get_u32(raw, 0) as usize;
            let area = 16 + 4 * treelets + common::get_u32(raw, 4) as usize;
            let mut ends: Vec<u32> = lods.iter().map(|&p| common::get_u32(raw, p + 16)).collect();
            ends.push((raw.len() - area) as u32);
            let len = |k: usize| ends[k + 1] - ends[k];
            let (i, j) = (0..lods.len())
                .flat_map(|i| (i + 1..lods.len()).map(move |j| (i, j)))
                .find(|&(i, j)| len(i) == len(j))
                .ok_or("no two entries of one size")?;
            let (from, to) = (area + ends[i] as usize, area + ends[j] as usize);
            let entry = raw[from..from + len(i) as usize].to_vec();
            raw[to..to + entry.len()].copy_from_slice(&entry);
            common::put_u32(raw, lods[j] + 16, ends[i]);
            Ok(())
        }),
    ];
    for name in ["lod-none.oocf", "lod-rlod.oocf", "rlod-only.oocf"] {
        let src = vector(name)?;
        clean(&with_lod_block(&src, &|_, _| Ok(()))?, name)?;
        for (what, edit) in cases {
            if what.starts_with("two") && name != "lod-none.oocf" {
                continue; // an R-LOD plane moved to another node's cell would miss it
            }
            let b = with_lod_block(&src, &edit)?;
            only_errors(
                &verify_bytes(&b, &deep())?,
                Code::LodArea,
                &format!("{name}: {what}"),
            );
            let full = verify_bytes(&b, &at_depth(Depth::Full))?;
            assert!(full.valid, "{name}: {what}: a deep rule: {:?}", full.issues);
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// §7: a proxy stands for a LOD node of the block it names

#[test]
fn a_proxy_must_name_the_block_of_its_lod_node() -> TestResult {
    // fx-deep-zstd: block 2 holds proxy 0 (for the LOD node in block 1) and proxy 1 (block 3).
    let src = fixture("fx-deep-zstd")?;
    clean(&src, "fx-deep-zstd")?;
    let b = rebuild(&src, &meta_of(&src)?, |id, e, mut raw| {
        if id == 2 {
            let (a, c) = (common::get_u32(&raw, 0), common::get_u32(&raw, 80));
            common::put_u32(&mut raw, 0, c);
            common::put_u32(&mut raw, 80, a);
        }
        encode_like(e, &raw)
    })?;
    only_errors(
        &verify_bytes(&b, &deep())?,
        Code::TreeReference,
        "proxies swapped",
    );
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// §6.1: the treelet shape the reference writer uses is not a requirement

#[test]
fn treelets_need_not_follow_the_writer_s_lod_depths() -> TestResult {
    // fx-deep-zstd says treelet height 1, yet a level-1 treelet is a basic node over two leaves
    // (the writer would make every inner node a LOD node): valid.
    let b = fixture("fx-deep-zstd")?;
    assert_eq!(meta_of(&b)?.build.treelet_height, 1);
    assert!(meta_of(&b)?.counts.basic_nodes > 0);
    clean(&b, "fx-deep-zstd")
}

// ---------------------------------------------------------------------------------------------
// §9: metadata values and canonical encoding

#[test]
fn an_over_long_varint_in_the_metadata_is_non_canonical() -> TestResult {
    for name in ["quad.oocf", "lod-zstd.oocf", "rlod-only.oocf"] {
        let src = vector(name)?;
        let m = metadata_bytes(&src).to_vec();
        // Scene: 6 f32 and 3 f64 (48 bytes); then root's Some tag (1) and its block varint.
        assert_eq!(m[48], 1, "{name}: root is Some");
        let block = m[49];
        assert!(block < 0x80, "{name}: a one-byte varint");
        let mut long = m.clone();
        long.splice(49..50, [block | 0x80, 0x00]);
        let b = with_metadata(&src, &long)?;
        only_errors(
            &verify_bytes(&b, &at_depth(Depth::Quick))?,
            Code::MetadataNonCanonical,
            name,
        );
        assert_eq!(
            open_bytes(&b, ReadOptions::default())
                .err()
                .map(|e| e.code()),
            Some(Code::MetadataNonCanonical),
            "{name}: reader"
        );
        // The same value, canonically encoded, is the vector's own bytes.
        assert_eq!(Metadata::decode(&m, 2)?.encode()?, m, "{name}");
    }
    Ok(())
}

#[test]
fn metadata_values_break_their_rules_as_metadata_decode() -> TestResult {
    type MetaEdit = fn(&mut Metadata);
    let cases: [(&str, MetaEdit); 5] = [
        ("treelet height 0", |m| m.build.treelet_height = 0),
        ("bounds min > max", |m| {
            m.scene.bounds_min[1] = m.scene.bounds_max[1] + 1.0
        }),
        ("origin not finite", |m| m.scene.origin[2] = f64::INFINITY),
        ("origin NaN", |m| m.scene.origin[0] = f64::NAN),
        ("bounds not finite", |m| m.scene.bounds_max[0] = f32::NAN),
    ];
    let src = fixture("fx-quad-none")?;
    for (what, edit) in cases {
        let mut m = meta_of(&src)?;
        edit(&mut m);
        let b = with_metadata(&src, &m.encode()?)?;
        only_errors(
            &verify_bytes(&b, &at_depth(Depth::Quick))?,
            Code::MetadataDecode,
            what,
        );
    }
    // Without a root (no geometry), inverted bounds are allowed: there is no cell to build.
    let src = fixture("fx-empty")?;
    let mut m = meta_of(&src)?;
    m.scene.bounds_min = [1.0; 3];
    let b = with_metadata(&src, &m.encode()?)?;
    let r = verify_bytes(&b, &deep())?;
    assert!(r.valid, "{:?}", r.issues);
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// §4: a zstd block is exactly one frame, without dictionary, stating its content size

/// A skippable frame (RFC 8878 §3.1.2) with no content.
const SKIPPABLE: [u8; 8] = [0x50, 0x2a, 0x4d, 0x18, 0, 0, 0, 0];

/// The offset of the Dictionary_ID field of a zstd frame (after magic, descriptor and, without
/// the single-segment flag, the window descriptor).
fn dict_id_at(frame: &[u8]) -> usize {
    5 + usize::from(frame[4] & 0x20 == 0)
}

type Frame = fn(&[u8]) -> TestResult<Vec<u8>>;

fn zstd_cases() -> [(&'static str, Frame); 6] {
    [
        ("a skippable frame after the frame", |raw| {
            let mut f = zstd::bulk::compress(raw, 3)?;
            f.extend_from_slice(&SKIPPABLE);
            Ok(f)
        }),
        ("a skippable frame first", |raw| {
            let mut f = SKIPPABLE.to_vec();
            f.extend(zstd::bulk::compress(raw, 3)?);
            Ok(f)
        }),
        ("an empty second frame", |raw| {
            let mut f = zstd::bulk::compress(raw, 3)?;
            f.extend(zstd::bulk::compress(&[], 3)?);
            Ok(f)
        }),
        ("no content size in the frame header", |raw| {
            let mut enc = zstd::stream::Encoder::new(Vec::new(), 3)?;
            enc.include_contentsize(false)?;
            std::io::Write::write_all(&mut enc, raw)?;
            Ok(enc.finish()?)
        }),
        ("a Dictionary_ID field (of value 0)", |raw| {
            let mut f = zstd::bulk::compress(raw, 3)?;
            assert_eq!(f[4] & 3, 0);
            f[4] |= 1;
            let at = dict_id_at(&f);
            f.insert(at, 0);
            Ok(f)
        }),
        ("a content size other than the raw length", |raw| {
            let mut longer = raw.to_vec();
            longer.push(0);
            Ok(zstd::bulk::compress(&longer, 3)?)
        }),
    ]
}

#[test]
fn zstd_blocks_follow_the_frame_rules() -> TestResult {
    let src = fixture("fx-deep-zstd")?;
    let meta = meta_of(&src)?;
    // Block 0 is a triangle block stored under zstd.
    let zstd_block = |frame: Frame| -> TestResult<Vec<u8>> {
        rebuild(&src, &meta, |id, e, raw| {
            if id != 0 {
                return encode_like(e, &raw);
            }
            assert_eq!(e.codec, CodecId::Zstd);
            let stored = frame(&raw)?;
            assert!(stored.len() < raw.len());
            Ok(EncodedBlock {
                kind: e.kind,
                level: e.level,
                item_count: e.item_count,
                raw_length: e.raw_length,
                codec: CodecId::Zstd,
                crc: oocfmt::checksum::crc32c(&stored),
                stored,
            })
        })
    };
    clean(
        &zstd_block(|raw| Ok(zstd::bulk::compress(raw, 3)?))?,
        "one frame",
    )?;
    for (what, frame) in zstd_cases() {
        let b = zstd_block(frame)?;
        only_errors(
            &verify_bytes(&b, &at_depth(Depth::Full))?,
            Code::BlockDecompress,
            what,
        );
        let r = open_bytes(&b, ReadOptions::default())?;
        assert_eq!(
            r.read_block(0).err().map(|e| e.code()),
            Some(Code::BlockDecompress),
            "{what}: reader"
        );
    }
    Ok(())
}

/// The writer's own zstd blocks keep every frame rule (its spec vectors verify clean too).
#[test]
fn the_writer_s_zstd_frames_state_their_content_size() -> TestResult {
    let raw: Vec<u8> = (0..20_000u32).map(|i| (i % 251) as u8).collect();
    let (id, stored) = Codec::Zstd(19).encode(&raw)?;
    assert_eq!(id, CodecId::Zstd);
    assert_eq!(
        zstd::zstd_safe::get_frame_content_size(&stored)
            .ok()
            .flatten(),
        Some(raw.len() as u64)
    );
    let mut out = vec![0; raw.len()];
    oocfmt::codec::decode_into(id, &stored, &mut out)?;
    assert_eq!(out, raw);
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// §5.1 and §6.4: footprints and the R-LOD's coverage and shade (`LOD_FILTERED`, since 1.2)

/// `common::write_filtered_with(kinds)`, as bytes.
fn filtered_file(kinds: LodKinds) -> TestResult<Vec<u8>> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("f.oocf");
    common::write_filtered_with(&path, kinds)?;
    Ok(std::fs::read(&path)?)
}

/// Bytes of the four voxels of `write_filtered_with` in a file with (`filtered`) or without
/// `LOD_FILTERED`, in node order (spec §5.1: 4, 8, 24, 36; without footprints 4, 4, 24, 24).
fn filtered_voxel_lens(filtered: bool) -> [usize; 4] {
    if filtered {
        [4, 8, 24, 36]
    } else {
        [4, 4, 24, 24]
    }
}

/// `b` with its first treelet block holding LOD nodes edited by `edit(raw, entry_starts)`:
/// where each LOD node's entry starts in the raw block, in node order.
fn with_lod_area(
    b: &[u8],
    edit: &dyn Fn(&mut Vec<u8>, &[usize]) -> TestResult,
) -> TestResult<Vec<u8>> {
    with_lod_block(b, &|raw, lods| {
        let treelets = common::get_u32(raw, 0) as usize;
        let area = 16 + 4 * treelets + common::get_u32(raw, 4) as usize;
        let entries: Vec<usize> = lods
            .iter()
            .map(|&p| area + common::get_u32(raw, p + 16) as usize)
            .collect();
        edit(raw, &entries)
    })
}

/// Full verify reports `code` and no other error; so does deep verify, but for the metadata
/// counts that the tree, whose walk stops at the broken block, no longer adds up to
/// (`TREE_COUNTS`); and the reader refuses the block with `code`.
fn refused_as(b: &[u8], code: Code, what: &str) -> TestResult {
    only_errors(&verify_bytes(b, &at_depth(Depth::Full))?, code, what);
    let r = verify_bytes(b, &deep())?;
    let errors: Vec<Code> = r
        .issues
        .iter()
        .filter(|i| i.severity == Severity::Error)
        .map(|i| i.code)
        .collect();
    assert!(
        !r.valid
            && errors.contains(&code)
            && errors.iter().all(|&c| c == code || c == Code::TreeCounts),
        "{what}: deep: expected {code}, got {:?}",
        r.issues
    );
    let r = open_bytes(b, ReadOptions::default())?;
    assert_eq!(
        read_all_blocks(&r).err().map(|e| e.code()),
        Some(code),
        "{what}: reader"
    );
    Ok(())
}

fn or_byte(raw: &mut [u8], at: usize, bits: u8) {
    raw[at] |= bits;
}

#[test]
fn the_filtered_fixture_holds_every_voxel_length() -> TestResult {
    for (kinds, minor) in [
        (LodKinds::BOTH.filtered(), 2),
        (LodKinds::VOXEL.filtered(), 2),
        (LodKinds::BOTH, 1),
        (LodKinds::VOXEL, 0),
    ] {
        let b = filtered_file(kinds)?;
        clean(&b, &format!("{kinds:?}"))?;
        let r = open_bytes(&b, ReadOptions::default())?;
        assert_eq!((r.lod_kinds(), r.header().minor), (kinds, minor));
        let block = r.read_block(0)?;
        let t = block.treelets()?;
        let mut lens = Vec::new();
        let mut feet = Vec::new();
        t.walk_lods(|_, _, _, e| {
            if let Some(v) = e.voxel {
                lens.push(v.byte_len(kinds.filtered));
                feet.extend((0..6).map(|f| v.face(f).1));
            }
            if let Some(x) = e.rlod {
                feet.push(oocfmt::records::Footprint {
                    shade: x.shade,
                    coverage: x.coverage,
                });
            }
            Ok(())
        })?;
        assert_eq!(lens, filtered_voxel_lens(kinds.filtered), "{kinds:?}");
        let partial = feet.iter().filter(|f| f.coverage < 255).count();
        assert_eq!(partial > 0, kinds.filtered, "{kinds:?}");
    }
    Ok(())
}

#[test]
fn bit_30_on_a_voxel_without_lod_filtered_is_voxel() -> TestResult {
    // Each voxel's first sample in the unfiltered twin of the filtered fixture, and in the
    // 1.0 vector: bit 30 is the proxies' empty flag there, never a voxel's.
    let twin = filtered_file(LodKinds::BOTH)?;
    for k in 0..4 {
        let b = with_lod_area(&twin, &|raw, entries| {
            or_byte(raw, entries[k] + 3, 0x40);
            Ok(())
        })?;
        refused_as(&b, Code::Voxel, &format!("unfiltered voxel {k}"))?;
    }
    let b = with_lod_area(&vector("lod-none.oocf")?, &|raw, entries| {
        or_byte(raw, entries[0] + 3, 0x40);
        Ok(())
    })?;
    refused_as(&b, Code::Voxel, "lod-none.oocf")
}

#[test]
fn bit_30_on_samples_1_to_5_of_a_six_sample_voxel_is_voxel() -> TestResult {
    // Voxel 2 is a 6-sample voxel without footprints, voxel 3 one with: only sample 0 may
    // carry the flag, in every file.
    for kinds in [LodKinds::BOTH.filtered(), LodKinds::BOTH] {
        let src = filtered_file(kinds)?;
        for k in [2, 3] {
            for i in 1..6 {
                let b = with_lod_area(&src, &|raw, entries| {
                    or_byte(raw, entries[k] + 4 * i + 3, 0x40);
                    Ok(())
                })?;
                refused_as(&b, Code::Voxel, &format!("{kinds:?}: voxel {k} sample {i}"))?;
            }
        }
    }
    Ok(())
}

#[test]
fn a_one_sample_footprint_word_with_high_bits_is_voxel() -> TestResult {
    // Voxel 1: a 1-sample voxel with its footprint word at bytes 4..8.
    let src = filtered_file(LodKinds::BOTH.filtered())?;
    for (byte, bits) in [(6, 0x01), (7, 0x80)] {
        let b = with_lod_area(&src, &|raw, entries| {
            or_byte(raw, entries[1] + byte, bits);
            Ok(())
        })?;
        refused_as(&b, Code::Voxel, &format!("footprint byte {byte}"))?;
    }
    Ok(())
}

#[test]
fn footprint_words_past_the_lod_area_are_voxel() -> TestResult {
    // Voxel-only: voxel 3 (36 bytes) ends the area; cut one, two or three of its footprint
    // words off.
    let src = filtered_file(LodKinds::VOXEL.filtered())?;
    for cut in [4u32, 8, 12] {
        let b = with_lod_area(&src, &|raw, _| {
            let len = raw.len() - cut as usize;
            raw.truncate(len);
            let v = common::get_u32(raw, 8) - cut;
            common::put_u32(raw, 8, v);
            Ok(())
        })?;
        refused_as(&b, Code::Voxel, &format!("{cut} bytes short"))?;
    }
    Ok(())
}

#[test]
fn r_lod_coverage_and_shade_are_reserved_without_lod_filtered() -> TestResult {
    let lens = filtered_voxel_lens(false);
    let twin = filtered_file(LodKinds::BOTH)?;
    for byte in [19, 22] {
        for k in 0..4 {
            let b = with_lod_area(&twin, &|raw, entries| {
                or_byte(raw, entries[k] + lens[k] + byte, 1);
                Ok(())
            })?;
            refused_as(&b, Code::Rlod, &format!("R-LOD {k} byte {byte}"))?;
        }
    }
    // R-LODs alone, as in 1.1.
    let b = with_lod_area(&vector("rlod-only.oocf")?, &|raw, entries| {
        or_byte(raw, entries[0] + 19, 1);
        Ok(())
    })?;
    refused_as(&b, Code::Rlod, "rlod-only.oocf byte 19")
}

#[test]
fn r_lod_byte_23_is_reserved_with_lod_filtered() -> TestResult {
    let lens = filtered_voxel_lens(true);
    let src = filtered_file(LodKinds::BOTH.filtered())?;
    for k in 0..4 {
        let b = with_lod_area(&src, &|raw, entries| {
            or_byte(raw, entries[k] + lens[k] + 23, 1);
            Ok(())
        })?;
        refused_as(&b, Code::Rlod, &format!("R-LOD {k} byte 23"))?;
    }
    let src = filtered_file(LodKinds::RLOD.filtered())?;
    clean(&src, "filtered R-LODs alone")?;
    let b = with_lod_area(&src, &|raw, entries| {
        or_byte(raw, entries[3] + 23, 0x80);
        Ok(())
    })?;
    refused_as(&b, Code::Rlod, "R-LODs alone, byte 23")
}

#[test]
fn footprint_words_that_say_full_are_valid() -> TestResult {
    // Spec §5.1: a writer SHOULD leave bit 30 clear where every footprint is full; a file that
    // stores them anyway is valid, and what follows the voxel is read after its words.
    let src = filtered_file(LodKinds::BOTH.filtered())?;
    let b = with_lod_area(&src, &|raw, entries| {
        common::put_u32(raw, entries[1] + 4, 0xffff);
        for k in 0..3 {
            common::put_u32(raw, entries[3] + 24 + 4 * k, 0xffff_ffff);
        }
        Ok(())
    })?;
    clean(&b, "full footprints stored")?;
    let r = open_bytes(&b, ReadOptions::default())?;
    let block = r.read_block(0)?;
    let t = block.treelets()?;
    let mut got = Vec::new();
    t.walk_lods(|_, _, _, e| {
        if let (Some(v), Some(x)) = (e.voxel, e.rlod) {
            got.push((v.face(5).1, e.voxel_len, x.offset));
        }
        Ok(())
    })?;
    // Every footprint now full, the stored lengths kept, each R-LOD found after its voxel.
    let full = oocfmt::records::Footprint::FULL;
    let want: Vec<_> = (0..4)
        .map(|k| (full, filtered_voxel_lens(true)[k], 0.5 + k as f32 / 8.0))
        .collect();
    assert_eq!(got, want);
    Ok(())
}
