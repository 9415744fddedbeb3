//! Fuzz properties: one function per cargo-fuzz target, each "never panics" plus the cross-checks
//! noted on it. This file is the only copy of the target bodies: the targets in `fuzz_targets/`
//! call it through the `oocfmt_fuzz` library, and `crates/oocfmt/tests/format/fuzz_corpus.rs` includes it
//! by path (`#[path]`), so `cargo test` replays every corpus and regression input on stable.
//!
//! Checksums are skipped explicitly (as a `--cfg fuzzing` build of `oocfmt` also forces) so the
//! replay test, built without that feature, runs exactly the code the fuzzer runs.
//!
//! Only the public API of `oocfmt` is used, and nothing here may panic except the `assert!`s
//! that state a property.

use std::sync::Arc;

use oocfmt::checksum::{crc32c, Crc32c};
use oocfmt::codec::decode_into;
use oocfmt::directory::{self, BlockEntry};
use oocfmt::records::triangle::{oct_decode, part_id_width, ATTR_PART_WIDTH_SHIFT};
use oocfmt::records::{LodKinds, Node, TreeletBlock, TriangleBlock, PART_WORD_LEN};
use oocfmt::summary::{survey_block, BlockSchema};
use oocfmt::verify::{verify, Depth, VerifyOptions};
use oocfmt::{header, trailer, BlockKind, Checksums, Codec, CodecId, ReadOptions, Reader};

/// The largest raw length `block_decode` asks for (the largest block size).
pub const MAX_RAW: usize = 1 << 20;

fn read_opts() -> ReadOptions {
    ReadOptions {
        checksums: Checksums::Skip,
        ..ReadOptions::default()
    }
}

fn verify_opts(depth: Depth) -> VerifyOptions {
    VerifyOptions {
        depth,
        checksums: Checksums::Skip,
        ..VerifyOptions::default()
    }
}

/// `open_verify`: the bytes as a whole file, as given and re-sealed (every CRC but the blocks'
/// recomputed, so mutations reach the structural checks behind the checksums).
pub fn open_verify(data: &[u8]) {
    exercise_file(data.to_vec());
    if let Some(sealed) = reseal(data) {
        if sealed != data {
            exercise_file(sealed);
        }
    }
}

/// Opens `bytes`, reads and decodes every block, summarises, and verifies at deep depth; then
/// checks that the reader and verify agree: a file verify calls valid at full depth is read
/// completely by the reader, and a file the reader reads completely is valid at full depth.
pub fn exercise_file(bytes: Vec<u8>) {
    let read = read_everything(&bytes);
    let full = verify(&bytes, "fuzz", &verify_opts(Depth::Full), &|_| {});
    let deep = verify(&bytes, "fuzz", &verify_opts(Depth::Deep), &|_| {});
    if let (Ok(full), Ok(deep)) = (&full, &deep) {
        assert!(
            !deep.valid || full.valid,
            "deep verify is valid but full verify is not: {:?}",
            full.issues
        );
        match &read {
            Ok(()) => assert!(
                full.valid,
                "the reader reads every block but verify says {:?}",
                full.issues
            ),
            Err(e) => assert!(!full.valid, "verify says valid but the reader fails: {e}"),
        }
    }
}

/// Everything a reader does with a file: open (which loads the proxies), read and decode every
/// block by kind, walk every treelet block, check item counts, summarise.
pub fn read_everything(bytes: &[u8]) -> Result<(), String> {
    let reader = Reader::from_source(Box::new(bytes.to_vec()), Arc::from("fuzz"), read_opts())
        .map_err(|e| e.to_string())?;
    let attrs = reader.metadata().triangle_attributes();
    let parts = reader.metadata().parts.len();
    let _ = reader.proxies().len();
    for id in 0..reader.header().sections.block_count {
        let block = reader.read_block(id).map_err(|e| e.to_string())?;
        let items = match block.entry.kind {
            BlockKind::Treelet => {
                let t = block.treelets().map_err(|e| e.to_string())?;
                // A part word names a part of the table (PART_ID), as verify checks.
                t.walk_lods(|_, pos, n, entry| match entry.part {
                    Some(p) if p as usize >= parts => Err(oocfmt::Error::malformed(
                        oocfmt::Code::PartId,
                        format!("LOD node at {pos}: part {p} of {parts}"),
                    )),
                    _ => n.check(),
                })
                .map_err(|e| e.to_string())?
                .treelets
            }
            BlockKind::Triangle => {
                let t = block.triangles(attrs).map_err(|e| e.to_string())?;
                t.check_contents().map_err(|e| e.to_string())?;
                t.check_parts(parts).map_err(|e| e.to_string())?;
                t.triangle_count() as u64
            }
            BlockKind::Proxy => block.proxies().map_err(|e| e.to_string())?.len() as u64,
        };
        if items != u64::from(block.entry.item_count) {
            return Err(format!(
                "block {id}: {items} items, the directory says {}",
                block.entry.item_count
            ));
        }
    }
    oocfmt::summary::summarize(&reader).map_err(|e| e.to_string())?;
    Ok(())
}

/// `block_decode`: byte 0 selects codec (bits 0–1), kind (bits 2–3), the schema's triangle
/// attributes (bits 4–6) and whether the schema is known (bit 7); bytes 1–3 are the raw length
/// (LE, capped at 1 MiB); the rest are the stored bytes. Decodes with `decode_into`, then
/// surveys the block under each LOD kind and, with a schema, each part-id width (with a part
/// table of a size that width fits: [`PART_TABLES`]). A successful decode must re-encode and
/// decode to the same bytes.
pub fn block_decode(data: &[u8]) {
    let Some((&sel, rest)) = data.split_first() else {
        return;
    };
    let Some((len_bytes, stored)) = rest.split_at_checked(3) else {
        return;
    };
    let raw_len = (usize::from(len_bytes[0])
        | usize::from(len_bytes[1]) << 8
        | usize::from(len_bytes[2]) << 16)
        .min(MAX_RAW);
    let codec = match sel & 3 {
        1 => CodecId::Lz4,
        2 => CodecId::Zstd,
        _ => CodecId::None,
    };
    let kind = match (sel >> 2) & 3 {
        1 => BlockKind::Triangle,
        2 => BlockKind::Proxy,
        _ => BlockKind::Treelet,
    };
    let schema_attrs = (sel & 0x80 != 0).then_some(u16::from((sel >> 4) & 7));
    let mut raw = vec![0u8; raw_len];
    if decode_into(codec, stored, &mut raw).is_err() {
        return;
    }
    if codec == CodecId::None {
        assert_eq!(raw, stored, "codec none must copy");
    }
    let codec_setting = match codec {
        CodecId::None => Codec::None,
        CodecId::Lz4 => Codec::Lz4,
        CodecId::Zstd => Codec::Zstd(1),
    };
    if let Ok((id, again)) = codec_setting.encode(&raw) {
        assert!(again.len() <= raw.len(), "encode grew the block");
        let mut back = vec![0u8; raw.len()];
        assert!(
            decode_into(id, &again, &mut back).is_ok(),
            "re-encoded block does not decode"
        );
        assert_eq!(back, raw, "re-encoded block decodes to other bytes");
    }
    let Ok(raw_length) = u32::try_from(raw.len()) else {
        return;
    };
    let item_count = match kind {
        BlockKind::Proxy => raw_length / 80,
        _ => 1,
    };
    let entry = BlockEntry {
        offset: header::HEADER_LEN as u64,
        stored_length: u32::try_from(stored.len()).unwrap_or(u32::MAX),
        raw_length,
        crc: crc32c(stored),
        kind,
        codec,
        level: 0,
        item_count: item_count.max(1),
    };
    for kinds in LOD_KINDS {
        match schema_attrs {
            None => {
                let _ = survey_block(&entry, &raw, None, kinds);
            }
            Some(a) => {
                for parts in PART_TABLES {
                    let schema = BlockSchema {
                        triangle_attributes: a | part_id_width(parts) << ATTR_PART_WIDTH_SHIFT,
                        parts,
                    };
                    let _ = survey_block(&entry, &raw, Some(schema), kinds);
                }
            }
        }
    }
    match kind {
        BlockKind::Treelet => treelet_decode(&raw),
        BlockKind::Triangle => triangle_decode(&raw),
        BlockKind::Proxy => {
            let _ = oocfmt::records::ProxyRecord::decode_block(&raw, item_count as usize);
        }
    }
}

/// The LOD kinds a treelet block can be read under: a block does not say which its file has.
const LOD_KINDS: [LodKinds; 12] = [
    LodKinds::VOXEL,
    LodKinds::BOTH,
    LodKinds::RLOD,
    LodKinds::VOXEL.filtered(),
    LodKinds::BOTH.filtered(),
    LodKinds::RLOD.filtered(),
    LodKinds::VOXEL.with_parts(true),
    LodKinds::BOTH.with_parts(true),
    LodKinds::RLOD.with_parts(true),
    LodKinds::VOXEL.filtered().with_parts(true),
    LodKinds::BOTH.filtered().with_parts(true),
    LodKinds::RLOD.filtered().with_parts(true),
];

/// Part-table lengths that give each part-id width (none, u8, u16, u32), small within their
/// width so that `PART_ID` is reachable.
const PART_TABLES: [usize; 4] = [0, 3, 300, 70_000];

/// `treelet_decode`: parse a treelet block under every LOD kind, walk it, and decode every node,
/// voxel and R-LOD record the walk reaches through the accessors as well.
pub fn treelet_decode(data: &[u8]) {
    for kinds in LOD_KINDS {
        treelet_decode_as(data, kinds);
    }
}

fn treelet_decode_as(data: &[u8], kinds: LodKinds) {
    let Ok(block) = TreeletBlock::parse_with(data, kinds) else {
        return;
    };
    let mut seen = Vec::new();
    let walked = block.walk_lods(|t, pos, n, entry| {
        seen.push((t, pos, *n, *entry));
        n.check()
    });
    for &(_, pos, node, entry) in &seen {
        assert_eq!(
            block.node(pos).ok(),
            Some(node),
            "node at {pos} decodes differently on its own"
        );
        let Node::Lod { voxel_offset, .. } = node else {
            continue;
        };
        if let Ok(v) = block.voxel(voxel_offset) {
            if entry.voxel.is_some() {
                assert_eq!(entry.voxel, Some(v), "the walk and the accessor disagree");
            }
            for face in 0..6 {
                let (s, f) = v.face(face);
                if s.check().is_ok() {
                    let n = s.normal();
                    assert!(
                        n.iter().all(|c| c.is_finite()),
                        "normal of a checked sample is not finite"
                    );
                    let _ = s.colour();
                }
                let (shade, coverage) = (f.shade_f32(), f.coverage_f32());
                assert!(
                    (0.0..=1.0).contains(&shade) && (0.0..=1.0).contains(&coverage),
                    "footprint out of range"
                );
                if !kinds.filtered {
                    assert!(f.is_full(), "a footprint in an unfiltered file");
                }
            }
        }
        if let Ok(r) = block.rlod(voxel_offset) {
            if entry.rlod.is_some() {
                assert_eq!(entry.rlod, Some(r), "the walk and the accessor disagree");
            }
            if !kinds.filtered {
                assert_eq!(
                    (r.coverage, r.shade),
                    (255, 255),
                    "unfiltered R-LOD not full"
                );
            }
        }
    }
    for &(_, _, node, entry) in &seen {
        if matches!(node, Node::Lod { .. }) {
            assert_eq!(
                entry.part.is_some(),
                kinds.parts,
                "a LOD entry's part word and the kinds disagree"
            );
            let parts_len = if kinds.parts { PART_WORD_LEN } else { 0 };
            let rest = entry.byte_len() - entry.voxel_len;
            let rlod_len = rest - parts_len;
            assert!(rlod_len == 0 || rlod_len == oocfmt::records::RLOD_LEN);
        } else {
            assert_eq!(entry.part, None, "a part word outside a LOD entry");
        }
    }
    if let Ok(sum) = walked {
        assert_eq!(sum.treelets, block.treelet_count() as u64);
        assert_eq!(
            sum.basic_nodes + sum.lod_nodes + sum.leaves,
            seen.len() as u64
        );
        let voxels = if kinds.voxel { sum.lod_nodes } else { 0 };
        let rlods = if kinds.rlod { sum.lod_nodes } else { 0 };
        assert_eq!(sum.voxels_single + sum.voxels_six, voxels);
        assert_eq!(sum.rlods, rlods);
    }
    for t in 0..=block.treelet_count() {
        if let Ok(span) = block.treelet_span(t) {
            let _ = block.node(span.start);
        }
    }
    let _ = (block.node_area().len(), block.voxel_area().len());
}

/// `triangle_decode`: parse a triangle block without a schema, check its contents, and call
/// every accessor on every index (and one past the end).
pub fn triangle_decode(data: &[u8]) {
    let Ok(block) = TriangleBlock::parse(data, None) else {
        return;
    };
    assert!(
        TriangleBlock::parse(data, Some(block.attributes())).is_ok(),
        "parse with its own attributes fails"
    );
    let contents_ok = block.check_contents().is_ok();
    let (l, t, w) = (
        block.list_count(),
        block.triangle_count(),
        block.vertex_count(),
    );
    assert!(block.primary_count() <= t, "more primaries than triangles");
    for i in 0..=l {
        let e = block.list(i);
        if contents_ok && i < l {
            assert!(
                e.as_ref().is_ok_and(|&e| usize::from(e) < t),
                "list entry {i} passed the check but is bad"
            );
        }
    }
    assert!(block.list(l).is_err(), "list entry past the end reads");
    for i in 0..=t {
        let tri = block.triangle(i);
        let pos = block.positions(i);
        if contents_ok && i < t {
            assert!(
                tri.is_ok() && pos.is_ok(),
                "triangle {i} passed the check but does not read"
            );
        }
    }
    assert!(block.triangle(t).is_err(), "triangle past the end reads");
    // Part ids: there exactly when the width says, the same through both accessors.
    for (i, tri) in block.all_triangles().enumerate() {
        let part = block.part(i);
        assert!(
            part.as_ref().is_ok_and(|&p| p == tri.part),
            "triangle {i}: part {part:?}, the record says {:?}",
            tri.part
        );
        assert_eq!(tri.part.is_some(), block.has_parts(), "triangle {i}");
    }
    assert!(block.part(t).is_err(), "part past the end reads");
    if block.check_parts(usize::MAX).is_err() {
        panic!("a part id not below usize::MAX");
    }
    for i in 0..=w {
        if let Ok(v) = block.vertex(i) {
            if contents_ok {
                assert!(
                    v.position.iter().all(|c| c.is_finite()),
                    "vertex {i} passed the check but is not finite"
                );
            }
            if let Some(n) = v.normal {
                let _ = oct_decode(n);
            }
        }
    }
    assert!(block.vertex(w).is_err(), "vertex past the end reads");
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(
        b.get(at..at.checked_add(4)?)?.try_into().ok()?,
    ))
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(
        b.get(at..at.checked_add(8)?)?.try_into().ok()?,
    ))
}

fn put_u32(b: &mut [u8], at: usize, v: u32) {
    if let Some(slot) = at.checked_add(4).and_then(|end| b.get_mut(at..end)) {
        slot.copy_from_slice(&v.to_le_bytes());
    }
}

/// `len` bytes at `offset`, where they lie inside `b`.
fn region(b: &[u8], offset: u64, len: u64) -> Option<&[u8]> {
    let start = usize::try_from(offset).ok()?;
    let end = start.checked_add(usize::try_from(len).ok()?)?;
    b.get(start..end)
}

/// Recomputes every checksum of a file except the blocks': header CRC, directory CRC, metadata
/// CRC, root checksum and trailer CRC, using the section table in the header. Regions the header
/// places outside the file keep their stored CRC (and then the root checksum is left alone).
/// `None` when the file is too short to hold a header and a trailer.
pub fn reseal(data: &[u8]) -> Option<Vec<u8>> {
    let mut f = data.to_vec();
    let t = f.len().checked_sub(trailer::TRAILER_LEN)?;
    if t < header::HEADER_LEN {
        return None;
    }
    let crc = crc32c(f.get(..header::OFF_HEADER_CRC)?);
    put_u32(&mut f, header::OFF_HEADER_CRC, crc);
    let dir_off = u64_at(&f, header::OFF_DIRECTORY_OFFSET)?;
    let count = u32_at(&f, header::OFF_BLOCK_COUNT)?;
    let meta_len = u32_at(&f, header::OFF_METADATA_LENGTH)?;
    let meta_off = u64_at(&f, header::OFF_METADATA_OFFSET)?;
    let dir =
        region(&f, dir_off, u64::from(count) * directory::ENTRY_LEN as u64).map(<[u8]>::to_vec);
    let meta = region(&f, meta_off, u64::from(meta_len)).map(<[u8]>::to_vec);
    if let Some(d) = &dir {
        put_u32(&mut f, t + trailer::OFF_DIRECTORY_CRC, crc32c(d));
    }
    if let Some(m) = &meta {
        put_u32(&mut f, t + trailer::OFF_METADATA_CRC, crc32c(m));
    }
    if let (Some(d), Some(m)) = (&dir, &meta) {
        let mut root = Crc32c::new();
        root.update(f.get(..header::OFF_HEADER_CRC)?);
        root.update(d);
        root.update(m);
        put_u32(&mut f, t + trailer::OFF_ROOT_CHECKSUM, root.finish());
    }
    let tcrc = crc32c(f.get(t..t + trailer::OFF_TRAILER_CRC)?);
    put_u32(&mut f, t + trailer::OFF_TRAILER_CRC, tcrc);
    Some(f)
}

/// Like [`reseal`], and first sets every directory entry's CRC to that of the bytes it names
/// (where they lie inside the file), so even a reader that checks block CRCs reaches the
/// structural checks.
pub fn reseal_with_blocks(data: &[u8]) -> Option<Vec<u8>> {
    let mut f = data.to_vec();
    let dir_off = usize::try_from(u64_at(&f, header::OFF_DIRECTORY_OFFSET)?).ok()?;
    let count = u32_at(&f, header::OFF_BLOCK_COUNT)? as usize;
    for i in 0..count {
        let Some(at) = i
            .checked_mul(directory::ENTRY_LEN)
            .and_then(|x| x.checked_add(dir_off))
        else {
            break;
        };
        // The directory offset comes from the file: an entry near the end of the address
        // space has no fields.
        let field = |off: usize| at.checked_add(off);
        let (Some(offset), Some(stored), Some(crc_at)) = (
            field(directory::OFF_OFFSET).and_then(|p| u64_at(&f, p)),
            field(directory::OFF_STORED_LENGTH).and_then(|p| u32_at(&f, p)),
            field(directory::OFF_CRC),
        ) else {
            break;
        };
        if let Some(bytes) = region(&f, offset, u64::from(stored)) {
            let c = crc32c(bytes);
            put_u32(&mut f, crc_at, c);
        }
    }
    reseal(&f)
}
