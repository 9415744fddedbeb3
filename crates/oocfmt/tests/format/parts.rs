//! Parts (spec 1.3): the part table, the part ids of triangle blocks and the part words of LOD
//! entries round-trip; a file without parts keeps the bytes of a 1.2 writer and a one-part file
//! stores no ids; and one must-fail file per rule (`PART_TABLE`, `PART_ID`, `PART_COUNTS`,
//! `PART_BOUNDS`, and the part-id sides of `TRIANGLE_ATTRIBUTES`, `TRIANGLE_LAYOUT`,
//! `LOD_AREA`), each breaking that rule alone.

use crate::common;
use crate::rules::{at_depth, clean, meta_of, only_errors, vector};

use common::{
    deep, encode_like, fixture, fixture_parts, lod_triangle_block, metadata_bytes, minor_of,
    open_bytes, put_u16, read_all_blocks, rebuild, reseal, verify_bytes, with_metadata,
    write_lod_with_parts, TestResult,
};
use oocfmt::header::{INCOMPAT_PART_IDS, OFF_MINOR, VERSION_MINOR_PARTS};
use oocfmt::metadata::{Part, MAX_PARTS};
use oocfmt::records::triangle::{
    ATTR_COLOURS, ATTR_MATERIALS, ATTR_NORMALS, ATTR_PART_WIDTH, ATTR_PART_WIDTH_SHIFT,
};
use oocfmt::records::{Node, PART_WORD_LEN};
use oocfmt::verify::Depth;
use oocfmt::{BlockKind, Code, Codec, EncodedBlock, Metadata, ReadOptions};

/// The attributes of `fx-lod-lz4`'s triangle block, without a part-id width.
const LOD_ATTRS: u16 = ATTR_NORMALS | ATTR_COLOURS | ATTR_MATERIALS;
/// Where the one LOD entry of `fx-parts-lz4`'s block 0 puts its part word: after the 16-byte
/// header, one treelet start, 40 node bytes and a 24-byte six-sample voxel.
const LOD_PART_AT: usize = 16 + 4 + 40 + 24;
/// Where `fx-parts-lz4`'s triangle block (block 2) puts its part ids: after the header, five
/// list entries padded to 12 bytes and 48 triangle records of 8 bytes.
const TRIANGLE_PARTS_AT: usize = 16 + 12 + 48 * 8;

/// `fx-lod-lz4`'s file with the part table `parts` (see `common::write_lod_with_parts`).
fn with_parts(parts: &[Part], lod_part: u32) -> TestResult<Vec<u8>> {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("parts.oocf");
    write_lod_with_parts(&path, parts, lod_part)?;
    Ok(std::fs::read(&path)?)
}

/// The fixture's one part: every triangle of the square.
fn one_part() -> Vec<Part> {
    vec![Part {
        name: "whole".into(),
        source: Some(0),
        triangles: 48,
        bounds_min: [0.0, 0.0, 0.5],
        bounds_max: [1.0, 1.0, 0.5],
        ..Part::default()
    }]
}

/// `src` re-written with block `id`'s raw bytes edited by `edit` (same kind, level, count and
/// codec), ending with `meta`.
fn edit_block(
    src: &[u8],
    meta: &Metadata,
    id: u32,
    edit: impl Fn(&mut Vec<u8>),
) -> TestResult<Vec<u8>> {
    rebuild(src, meta, |i, e, mut raw| {
        if i == id {
            edit(&mut raw);
        }
        encode_like(e, &raw)
    })
}

/// `src` re-written with block 2 (the triangle block) replaced by `raw` holding `items`
/// triangles, ending with `meta`.
fn replace_triangles(src: &[u8], meta: &Metadata, raw: &[u8], items: u32) -> TestResult<Vec<u8>> {
    rebuild(src, meta, |i, e, old| {
        if i != 2 {
            return encode_like(e, &old);
        }
        Ok(EncodedBlock::encode(
            Codec::Lz4,
            BlockKind::Triangle,
            0,
            items,
            raw,
        )?)
    })
}

/// `src` with its metadata replaced by `meta`'s encoding in the form of minor `minor` (the
/// header says `minor`), every checksum fixed: a file the writer would refuse to make.
fn with_meta_at_minor(src: &[u8], meta: &Metadata, minor: u16) -> TestResult<Vec<u8>> {
    let mut bytes = meta.encode()?;
    if meta.parts.is_empty() && minor >= VERSION_MINOR_PARTS {
        bytes.push(0); // the empty part table of a 1.3 file
    }
    let mut b = with_metadata(src, &bytes)?;
    put_u16(&mut b, OFF_MINOR, minor);
    reseal(&b)
}

fn reader_code(b: &[u8]) -> Option<Code> {
    open_bytes(b, ReadOptions::default())
        .err()
        .map(|e| e.code())
}

// ---------------------------------------------------------------------------------------------
// Round trips

#[test]
fn a_part_table_round_trips_with_its_ids_and_part_words() -> TestResult {
    let b = fixture("fx-parts-lz4")?;
    let r = open_bytes(&b, ReadOptions::default())?;
    assert_eq!(r.header().minor, VERSION_MINOR_PARTS);
    assert_ne!(r.header().incompatible_features & INCOMPAT_PART_IDS, 0);
    assert!(r.lod_kinds().parts);
    let m = r.metadata();
    assert_eq!(m.parts, fixture_parts());
    // Three parts: u8 ids (width code 1) beside the schema's bits.
    assert_eq!(
        m.triangle_attributes(),
        LOD_ATTRS | 1 << ATTR_PART_WIDTH_SHIFT
    );
    read_all_blocks(&r)?;
    let tri = r.read_block(2)?;
    let t = tri.triangles(m.triangle_attributes())?;
    assert!(t.has_parts());
    t.check_parts(m.parts.len())?;
    for i in 0..t.triangle_count() {
        let want = Some(1 + (i as u32 % 2));
        assert_eq!(t.part(i)?, want, "triangle {i}");
        assert_eq!(t.triangle(i)?.part, want, "triangle {i}");
    }
    assert!(t.part(t.triangle_count()).is_err());
    assert_eq!(
        tri.data[TRIANGLE_PARTS_AT..TRIANGLE_PARTS_AT + 4],
        [1, 2, 1, 2]
    );
    let tb = r.read_block(0)?;
    let mut words = Vec::new();
    tb.treelets()?.walk_lods(|_, _, n, entry| {
        if matches!(n, Node::Lod { .. }) {
            words.push(entry.part);
            assert_eq!(entry.byte_len(), 24 + PART_WORD_LEN);
        } else {
            assert_eq!(entry.part, None);
        }
        Ok(())
    })?;
    assert_eq!(words, vec![Some(2)]);
    assert_eq!(common::get_u32(&tb.data, LOD_PART_AT), 2);
    clean(&b, "fx-parts-lz4")
}

#[test]
fn a_one_part_table_writes_no_ids_and_no_bit() -> TestResult {
    let plain = fixture("fx-lod-lz4")?;
    let b = with_parts(&one_part(), 0)?;
    clean(&b, "one part")?;
    let r = open_bytes(&b, ReadOptions::default())?;
    // Minor 3 for the metadata field, no PART_IDS: the blocks are those of the plain file.
    assert_eq!(r.header().minor, VERSION_MINOR_PARTS);
    assert_eq!(r.header().incompatible_features & INCOMPAT_PART_IDS, 0);
    assert!(!r.lod_kinds().parts);
    assert_eq!(r.metadata().triangle_attributes(), LOD_ATTRS);
    assert_eq!(r.metadata().parts, one_part());
    let blocks_end = |f: &[u8]| common::get_u64(f, oocfmt::header::OFF_METADATA_OFFSET) as usize;
    assert_eq!(
        b[64..blocks_end(&b)],
        plain[64..blocks_end(&plain)],
        "blocks and directory"
    );
    // The metadata is the plain file's with the table appended.
    let mut want = metadata_bytes(&plain).to_vec();
    want.extend(postcard::to_stdvec(&one_part())?);
    assert_eq!(metadata_bytes(&b), &want[..]);
    // The one part holds every triangle: a count or a box that says otherwise is caught.
    let mut m = meta_of(&b)?;
    m.parts[0].triangles = 47;
    let bad = with_meta_at_minor(&b, &m, VERSION_MINOR_PARTS)?;
    only_errors(&verify_bytes(&bad, &deep())?, Code::PartCounts, "one part");
    let mut m = meta_of(&b)?;
    m.parts[0].bounds_min[1] = -0.5;
    let bad = with_meta_at_minor(&b, &m, VERSION_MINOR_PARTS)?;
    only_errors(&verify_bytes(&bad, &deep())?, Code::PartBounds, "one part");
    Ok(())
}

/// The fixtures without parts are byte for byte the seeds committed under
/// `fuzz/corpus/open_verify/`, which a 1.2 writer made: a file without a part table is what it
/// was before 1.3.
#[test]
fn files_without_parts_keep_the_bytes_of_a_1_2_writer() -> TestResult {
    let seeds = std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fuzz/corpus/open_verify"
    ));
    let mut compared = 0;
    for f in common::fixtures()? {
        let r = open_bytes(&f.bytes, ReadOptions::default())?;
        if !r.metadata().parts.is_empty() {
            continue;
        }
        assert!(r.header().minor < VERSION_MINOR_PARTS, "{}", f.name);
        let Ok(committed) = std::fs::read(seeds.join(format!("{}.oocf", f.name))) else {
            continue;
        };
        assert!(committed == f.bytes, "{} differs from its seed", f.name);
        compared += 1;
    }
    assert!(compared >= 4, "only {compared} fixtures compared");
    // And every vector's metadata re-encodes to its own bytes at its own minor.
    for v in common::vectors()? {
        let m = Metadata::decode(metadata_bytes(&v.bytes), minor_of(&v.bytes))?;
        if m.parts.is_empty() {
            assert!(minor_of(&v.bytes) < VERSION_MINOR_PARTS, "{}", v.name);
            assert_eq!(m.encode()?, metadata_bytes(&v.bytes), "{}", v.name);
        }
    }
    Ok(())
}

#[test]
fn a_1_2_file_still_reads() -> TestResult {
    let b = vector("lod-filtered.oocf")?;
    let r = open_bytes(&b, ReadOptions::default())?;
    assert_eq!(r.header().minor, 2);
    assert!(r.metadata().parts.is_empty() && !r.lod_kinds().parts);
    read_all_blocks(&r)?;
    clean(&b, "lod-filtered")?;
    // Its metadata has no part-table field: read as 1.3, the bytes end too early.
    let meta = metadata_bytes(&b);
    assert!(Metadata::decode(meta, 2).is_ok());
    assert_eq!(
        Metadata::decode(meta, VERSION_MINOR_PARTS)
            .err()
            .map(|e| e.code()),
        Some(Code::MetadataDecode)
    );
    Ok(())
}

#[test]
fn the_writer_takes_the_bit_and_minor_from_the_part_table() -> TestResult {
    // Two parts give the bit even when the options did not ask for it...
    let src = fixture("fx-parts-lz4")?;
    let meta = meta_of(&src)?;
    let r = open_bytes(&src, ReadOptions::default())?;
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("w.oocf");
    let mut w = oocfmt::Writer::create(&path, common::opts(12, Codec::Lz4))?;
    for id in 0..r.header().sections.block_count {
        let blk = r.read_block(id)?;
        w.write_encoded(encode_like(&blk.entry, &blk.data)?)?;
    }
    w.finish(&meta)?;
    assert_eq!(std::fs::read(&path)?, src);
    // ...and asking for part words without two parts is refused.
    let mut w = oocfmt::Writer::create(
        &path,
        oocfmt::WriteOptions {
            lod: oocfmt::records::LodKinds::VOXEL.with_parts(true),
            ..common::opts(12, Codec::Lz4)
        },
    )?;
    let blk = r.read_block(2)?;
    w.write_encoded(encode_like(&blk.entry, &blk.data)?)?;
    let mut m = meta.clone();
    m.parts.truncate(1);
    assert_eq!(
        w.finish(&m).err().map(|e| e.code()),
        Some(Code::InvalidParameter)
    );
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// §9: PART_TABLE, at open

#[test]
fn a_part_table_that_breaks_a_rule_is_part_table() -> TestResult {
    type Edit = fn(&mut Vec<Part>);
    let cases: [(&str, Edit); 5] = [
        ("a part its own parent", |p| p[1].parent = Some(1)),
        ("a parent after its child", |p| p[1].parent = Some(2)),
        ("a source past the sources", |p| p[2].source = Some(1)),
        ("a bound not finite", |p| p[1].bounds_max[0] = f32::NAN),
        ("a bound infinite", |p| {
            p[0].bounds_min[2] = f32::NEG_INFINITY
        }),
    ];
    let src = fixture("fx-parts-lz4")?;
    for (what, edit) in cases {
        let mut m = meta_of(&src)?;
        edit(&mut m.parts);
        let b = with_meta_at_minor(&src, &m, VERSION_MINOR_PARTS)?;
        only_errors(
            &verify_bytes(&b, &at_depth(Depth::Quick))?,
            Code::PartTable,
            what,
        );
        assert_eq!(reader_code(&b), Some(Code::PartTable), "{what}: reader");
    }
    Ok(())
}

#[test]
fn more_parts_than_the_limit_are_refused_before_decoding() -> TestResult {
    let src = fixture("fx-parts-lz4")?;
    let mut m = meta_of(&src)?;
    m.parts.clear();
    for (n, code) in [
        (MAX_PARTS as u64 + 1, Code::PartTable),
        (u64::MAX, Code::PartTable),
        // At the limit the count passes; the parts it promises are missing.
        (MAX_PARTS as u64, Code::MetadataDecode),
    ] {
        let mut bytes = m.encode()?;
        bytes.extend(postcard::to_stdvec(&n)?);
        let mut b = with_metadata(&src, &bytes)?;
        put_u16(&mut b, OFF_MINOR, VERSION_MINOR_PARTS);
        let b = reseal(&b)?;
        let what = format!("{n} parts");
        only_errors(&verify_bytes(&b, &at_depth(Depth::Quick))?, code, &what);
        assert_eq!(reader_code(&b), Some(code), "{what}: reader");
    }
    Ok(())
}

#[test]
fn the_part_ids_bit_follows_the_table_s_length() -> TestResult {
    // PART_IDS with one part.
    let src = fixture("fx-parts-lz4")?;
    let mut m = meta_of(&src)?;
    m.parts.truncate(1);
    let b = with_meta_at_minor(&src, &m, VERSION_MINOR_PARTS)?;
    only_errors(
        &verify_bytes(&b, &at_depth(Depth::Quick))?,
        Code::PartTable,
        "the bit with one part",
    );
    assert_eq!(reader_code(&b), Some(Code::PartTable));
    // Two parts without PART_IDS.
    let src = fixture("fx-lod-lz4")?;
    let mut m = meta_of(&src)?;
    m.parts = fixture_parts();
    m.parts.truncate(2);
    let b = with_meta_at_minor(&src, &m, VERSION_MINOR_PARTS)?;
    only_errors(
        &verify_bytes(&b, &at_depth(Depth::Quick))?,
        Code::PartTable,
        "two parts without the bit",
    );
    assert_eq!(reader_code(&b), Some(Code::PartTable));
    // The control: one part without the bit.
    let mut m = meta_of(&src)?;
    m.parts = one_part();
    clean(
        &with_meta_at_minor(&src, &m, VERSION_MINOR_PARTS)?,
        "one part",
    )
}

// ---------------------------------------------------------------------------------------------
// §8 and §6.2: ids in range, the width the table asks for, padding, the part word's place

#[test]
fn a_part_id_past_the_table_is_part_id() -> TestResult {
    let src = fixture("fx-parts-lz4")?;
    let meta = meta_of(&src)?;
    let full = at_depth(Depth::Full);
    // A triangle's id.
    let b = edit_block(&src, &meta, 2, |raw| raw[TRIANGLE_PARTS_AT + 5] = 3)?;
    only_errors(
        &verify_bytes(&b, &full)?,
        Code::PartId,
        "triangle 5 in part 3",
    );
    // A LOD entry's part word.
    let b = edit_block(&src, &meta, 0, |raw| {
        common::put_u32(raw, LOD_PART_AT, 3);
    })?;
    only_errors(
        &verify_bytes(&b, &full)?,
        Code::PartId,
        "LOD entry in part 3",
    );
    // The control: the last part is fine (and then only the counts disagree, deep).
    let b = edit_block(&src, &meta, 2, |raw| raw[TRIANGLE_PARTS_AT + 5] = 1)?;
    let r = verify_bytes(&b, &full)?;
    assert!(r.valid && r.issues.is_empty(), "{:?}", r.issues);
    only_errors(&verify_bytes(&b, &deep())?, Code::PartCounts, "moved");
    Ok(())
}

#[test]
fn a_part_id_width_other_than_the_table_s_is_triangle_attributes() -> TestResult {
    let part = |i: u16| Some(1 + u32::from(i % 2));
    // u16 ids where three parts ask for u8.
    let src = fixture("fx-parts-lz4")?;
    let meta = meta_of(&src)?;
    let raw = lod_triangle_block(LOD_ATTRS | 2 << ATTR_PART_WIDTH_SHIFT, 48, part)?;
    let b = replace_triangles(&src, &meta, &raw, 48)?;
    only_errors(
        &verify_bytes(&b, &at_depth(Depth::Full))?,
        Code::TriangleAttributes,
        "u16 ids for three parts",
    );
    // No ids where the table asks for them.
    let raw = lod_triangle_block(LOD_ATTRS, 48, |_| None)?;
    let b = replace_triangles(&src, &meta, &raw, 48)?;
    only_errors(
        &verify_bytes(&b, &at_depth(Depth::Full))?,
        Code::TriangleAttributes,
        "no ids for three parts",
    );
    // u8 ids in a file without PART_IDS.
    let src = fixture("fx-lod-lz4")?;
    let meta = meta_of(&src)?;
    let raw = lod_triangle_block(LOD_ATTRS | 1 << ATTR_PART_WIDTH_SHIFT, 48, |_| Some(0))?;
    let b = replace_triangles(&src, &meta, &raw, 48)?;
    only_errors(
        &verify_bytes(&b, &at_depth(Depth::Full))?,
        Code::TriangleAttributes,
        "ids without parts",
    );
    assert_eq!(ATTR_PART_WIDTH, 0b11 << ATTR_PART_WIDTH_SHIFT);
    Ok(())
}

#[test]
fn part_id_padding_must_be_zero() -> TestResult {
    // 50 u8 ids take 52 bytes: two of padding. Full depth only: the counts are deep's.
    let src = fixture("fx-parts-lz4")?;
    let meta = meta_of(&src)?;
    let attrs = LOD_ATTRS | 1 << ATTR_PART_WIDTH_SHIFT;
    let raw = lod_triangle_block(attrs, 50, |i| Some(1 + u32::from(i % 2)))?;
    let pad = 16 + 12 + 50 * 8 + 50;
    assert_eq!(raw[pad..pad + 2], [0, 0]);
    let full = at_depth(Depth::Full);
    let ok = replace_triangles(&src, &meta, &raw, 50)?;
    let r = verify_bytes(&ok, &full)?;
    assert!(r.valid && r.issues.is_empty(), "{:?}", r.issues);
    let mut bad = raw.clone();
    bad[pad + 1] = 7;
    let b = replace_triangles(&src, &meta, &bad, 50)?;
    only_errors(&verify_bytes(&b, &full)?, Code::TriangleLayout, "padding");
    Ok(())
}

#[test]
fn a_lod_entry_without_room_for_its_part_word_is_lod_area() -> TestResult {
    let src = fixture("fx-parts-lz4")?;
    let meta = meta_of(&src)?;
    // Drop the part word: the LOD area ends with the voxel.
    let b = edit_block(&src, &meta, 0, |raw| {
        raw.truncate(LOD_PART_AT);
        let lod_bytes = common::get_u32(raw, 8) - PART_WORD_LEN as u32;
        common::put_u32(raw, 8, lod_bytes);
    })?;
    only_errors(
        &verify_bytes(&b, &at_depth(Depth::Full))?,
        Code::LodArea,
        "no part word",
    );
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// §9: PART_COUNTS and PART_BOUNDS, deep

#[test]
fn a_part_count_other_than_its_triangles_is_part_counts() -> TestResult {
    let src = fixture("fx-parts-lz4")?;
    type Edit = fn(&mut Vec<Part>);
    let cases: [(&str, Edit); 3] = [
        ("one triangle moved in the table", |p| {
            p[1].triangles -= 1;
            p[2].triangles += 1;
        }),
        // Its bounds stay zero: the box of what the blocks give it.
        ("a triangle for the assembly", |p| p[0].triangles = 1),
        ("a count over the scene's", |p| p[2].triangles = 1 << 40),
    ];
    for (what, edit) in cases {
        let mut m = meta_of(&src)?;
        edit(&mut m.parts);
        let b = with_meta_at_minor(&src, &m, VERSION_MINOR_PARTS)?;
        let quick = verify_bytes(&b, &at_depth(Depth::Full))?;
        assert!(quick.valid && quick.issues.is_empty(), "{what}: {quick:?}");
        only_errors(&verify_bytes(&b, &deep())?, Code::PartCounts, what);
    }
    Ok(())
}

#[test]
fn part_bounds_other_than_its_triangles_box_are_part_bounds() -> TestResult {
    let src = fixture("fx-parts-lz4")?;
    type Edit = fn(&mut Vec<Part>);
    let cases: [(&str, Edit); 4] = [
        ("a box too large", |p| p[1].bounds_max[2] = 0.75),
        ("a box too small", |p| p[2].bounds_min[0] = 0.25),
        ("a part without triangles with a box", |p| {
            p[0].bounds_max = [1.0; 3]
        }),
        ("a box one ulp off", |p| {
            p[2].bounds_max[1] = f32::from_bits(1.0f32.to_bits() + 1)
        }),
    ];
    for (what, edit) in cases {
        let mut m = meta_of(&src)?;
        edit(&mut m.parts);
        let b = with_meta_at_minor(&src, &m, VERSION_MINOR_PARTS)?;
        only_errors(&verify_bytes(&b, &deep())?, Code::PartBounds, what);
    }
    // −0 and +0 are one bound.
    let mut m = meta_of(&src)?;
    m.parts[1].bounds_min[0] = -0.0;
    clean(&with_meta_at_minor(&src, &m, VERSION_MINOR_PARTS)?, "-0")
}
