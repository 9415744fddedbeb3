//! `inspect --hexdump`: every byte of a small file, each field named (spec §14's worked example).

use std::fmt::Write;
use std::path::Path;

use oocfmt::directory as dir;
use oocfmt::header as hdr;
use oocfmt::records::triangle::{ATTR_PART_WIDTH, ATTR_PART_WIDTH_SHIFT};
use oocfmt::records::{
    LodKinds, Node, TreeletBlock, TriangleBlock, Voxel, PART_WORD_LEN, RLOD_LEN,
};
use oocfmt::trailer as trl;
use oocfmt::{BlockKind, CodecId, ReadOptions, Reader};

use crate::error::CliError;

/// Files larger than this are refused: the dump is for worked examples, not real models.
const MAX_DUMP: u64 = 256 * 1024;

pub fn annotate(path: &Path) -> Result<String, CliError> {
    let reader = Reader::open(path, ReadOptions::default())?;
    if reader.file_len() > MAX_DUMP {
        return Err(CliError::Usage(format!(
            "--hexdump is for files up to {MAX_DUMP} bytes; use --block for one block"
        )));
    }
    let bytes = std::fs::read(path).map_err(|e| CliError::Io {
        path: path.display().to_string(),
        source: e,
    })?;
    let mut d = Dump {
        o: String::new(),
        bytes: &bytes,
    };
    let _ = writeln!(d.o, "{} ({} bytes)", path.display(), bytes.len());
    d.header();
    for (id, e) in (0u32..).zip(reader.entries()) {
        d.block(&reader, id, e);
    }
    d.directory(&reader);
    d.metadata(&reader);
    d.trailer(reader.header().sections.trailer_offset().unwrap_or(0) as usize);
    Ok(d.o)
}

struct Dump<'a> {
    o: String,
    bytes: &'a [u8],
}

impl Dump<'_> {
    fn title(&mut self, t: &str) {
        let _ = writeln!(self.o, "\n## {t}\n");
    }

    /// Prints `len` bytes at `at`, 16 per line, with `label` on the first line.
    fn field(&mut self, at: usize, len: usize, label: &str) {
        let data = self.bytes.get(at..at + len).unwrap_or(&[]);
        for (i, chunk) in data.chunks(16).enumerate() {
            let hex: Vec<String> = chunk.iter().map(|b| format!("{b:02x}")).collect();
            let text = if i == 0 { label } else { "" };
            let _ = writeln!(self.o, "{:08x}  {:<47}  {text}", at + 16 * i, hex.join(" "));
        }
    }

    fn header(&mut self) {
        self.title("header (64 bytes)");
        let h = match oocfmt::Header::decode(self.bytes) {
            Ok(h) => h,
            Err(_) => return,
        };
        let s = h.sections;
        let rows: [(usize, usize, String); 13] = [
            (hdr::OFF_MAGIC, 8, "magic \\x89OCF\\r\\n\\x1a\\n".into()),
            (hdr::OFF_MAJOR, 2, format!("major version {}", h.major)),
            (hdr::OFF_MINOR, 2, format!("minor version {}", h.minor)),
            (
                hdr::OFF_BLOCK_SIZE_LOG2,
                1,
                format!("block size 2^{} = {}", h.block_size_log2, h.block_size()),
            ),
            (hdr::OFF_RESERVED_A, 3, "reserved".into()),
            (
                hdr::OFF_INCOMPAT,
                8,
                format!("incompatible features {:#x}", h.incompatible_features),
            ),
            (
                hdr::OFF_COMPAT,
                8,
                format!("compatible features {:#x}", h.compatible_features),
            ),
            (
                hdr::OFF_DIRECTORY_OFFSET,
                8,
                format!("directory offset {}", s.directory_offset),
            ),
            (
                hdr::OFF_BLOCK_COUNT,
                4,
                format!("block count {}", s.block_count),
            ),
            (
                hdr::OFF_METADATA_LENGTH,
                4,
                format!("metadata length {}", s.metadata_length),
            ),
            (
                hdr::OFF_METADATA_OFFSET,
                8,
                format!("metadata offset {}", s.metadata_offset),
            ),
            (hdr::OFF_RESERVED_B, 4, "reserved".into()),
            (
                hdr::OFF_HEADER_CRC,
                4,
                "header CRC-32C of bytes 0..60".into(),
            ),
        ];
        for (at, len, label) in rows {
            self.field(at, len, &label);
        }
    }

    fn block(&mut self, reader: &Reader, id: u32, e: &oocfmt::BlockEntry) {
        let at = e.offset as usize;
        self.title(&format!(
            "block {id}: {} block, level {}, codec {}, {} stored bytes",
            e.kind.name(),
            e.level,
            e.codec.name(),
            e.stored_length
        ));
        if e.codec != CodecId::None {
            self.field(at, e.stored_length as usize, "compressed bytes");
            return;
        }
        let raw = self
            .bytes
            .get(at..at + e.stored_length as usize)
            .unwrap_or(&[])
            .to_vec();
        match e.kind {
            BlockKind::Treelet => self.treelet_block(at, &raw, reader.lod_kinds()),
            BlockKind::Triangle => {
                self.triangle_block(at, &raw, reader.metadata().triangle_attributes())
            }
            BlockKind::Proxy => {
                for i in 0..e.item_count as usize {
                    let p = at + 80 * i;
                    self.field(p, 4, &format!("proxy {i}: node block"));
                    self.field(p + 4, 4, "surface area f32");
                    self.field(p + 8, 72, "18 shading samples");
                }
            }
        }
    }

    fn treelet_block(&mut self, at: usize, raw: &[u8], kinds: LodKinds) {
        let Ok(b) = TreeletBlock::parse_with(raw, kinds) else {
            self.field(at, raw.len(), "undecodable treelet block");
            return;
        };
        let t = b.treelet_count();
        self.field(at, 4, &format!("treelet count {t}"));
        self.field(at + 4, 4, &format!("node bytes {}", b.node_area().len()));
        let area = match (kinds.rlod, kinds.parts) {
            (false, false) => "voxel bytes",
            (true, false) => "LOD area bytes (voxels and R-LODs)",
            (false, true) => "LOD area bytes (voxels and part words)",
            (true, true) => "LOD area bytes (voxels, R-LODs and part words)",
        };
        self.field(at + 8, 4, &format!("{area} {}", b.voxel_area().len()));
        self.field(at + 12, 4, "reserved");
        self.field(at + 16, 4 * t, "treelet start offsets");
        let nodes_at = at + 16 + 4 * t;
        let mut rows = Vec::new();
        let mut entries = Vec::new();
        let _ = b.walk_lods(|tl, pos, n, entry| {
            if let Node::Lod { voxel_offset, .. } = *n {
                let off = voxel_offset as usize;
                if let Some(v) = entry.voxel {
                    let samples = match v {
                        Voxel::Single(..) => 1,
                        Voxel::Six(..) => 6,
                    };
                    let label = format!("voxel of the LOD node at {pos}: {samples} sample(s)");
                    entries.push((off, 4 * samples, label));
                    // Footprint words (spec §5.1): what the stored length has beyond the samples.
                    let words = entry.voxel_len.saturating_sub(4 * samples);
                    if words > 0 {
                        let feet: Vec<String> = (0..samples)
                            .map(|f| {
                                let fp = v.face(f).1;
                                format!("{}/{}", fp.shade, fp.coverage)
                            })
                            .collect();
                        let label = format!(
                            "footprints of the LOD node at {pos} (shade/coverage, /255): {}",
                            feet.join(" ")
                        );
                        entries.push((off + 4 * samples, words, label));
                    }
                }
                if let Some(r) = entry.rlod {
                    let label = if kinds.filtered {
                        format!(
                            "R-LOD of the LOD node at {pos}: normal, offset, colour, coverage {}, deviation and expansion codes, shade {}",
                            r.coverage, r.shade
                        )
                    } else {
                        format!("R-LOD of the LOD node at {pos}: normal, offset, colour, deviation and expansion codes")
                    };
                    entries.push((off + entry.voxel_len, RLOD_LEN, label));
                }
                if let Some(p) = entry.part {
                    let label = format!("part word of the LOD node at {pos}: part {p}");
                    entries.push((off + entry.byte_len() - PART_WORD_LEN, PART_WORD_LEN, label));
                }
            }
            let label = match *n {
                Node::Basic { axis, split, left, right } => format!("treelet {tl} basic node: axis {axis}, split {split}, children +{left} +{right} (8-byte units)"),
                Node::Lod { axis, split, radius, child_block, child_treelet, voxel_offset, proxy, .. } => format!(
                    "treelet {tl} LOD node: axis {axis}, split {split}, radius {radius}, child block {child_block} treelet {child_treelet}, voxel at {voxel_offset}, proxy {proxy:#x}"
                ),
                Node::Leaf { count, first, block } => format!("treelet {tl} leaf: {count} triangles from list entry {first} of block {block}"),
            };
            rows.push((pos, n.byte_len(), label));
            Ok(())
        });
        for (pos, len, label) in rows {
            self.field(nodes_at + pos, len, &label);
        }
        let lod_at = nodes_at + b.node_area().len();
        entries.sort_by_key(|e| e.0);
        for (off, len, label) in entries {
            self.field(lod_at + off, len, &label);
        }
    }

    fn triangle_block(&mut self, at: usize, raw: &[u8], attrs: u16) {
        let Ok(b) = TriangleBlock::parse(raw, Some(attrs)) else {
            self.field(at, raw.len(), "undecodable triangle block");
            return;
        };
        let (l, t, w) = (b.list_count(), b.triangle_count(), b.vertex_count());
        self.field(at, 4, &format!("list count {l}"));
        self.field(at + 4, 4, &format!("triangle count {t}"));
        self.field(at + 8, 4, &format!("vertex count {w}"));
        let width = (attrs & ATTR_PART_WIDTH) >> ATTR_PART_WIDTH_SHIFT;
        let attr_label = match width {
            0 => format!("attributes {attrs:#x}"),
            c => format!("attributes {attrs:#x} (part-id width code {c})"),
        };
        self.field(at + 12, 2, &attr_label);
        self.field(at + 14, 2, &format!("primary count {}", b.primary_count()));
        let list_len = (2 * l + 3) & !3;
        self.field(
            at + 16,
            list_len,
            "list section: u16 triangle indices (+ padding)",
        );
        let tri_rec = if attrs & 4 != 0 { 8 } else { 6 };
        let tri_at = at + 16 + list_len;
        for i in 0..t {
            let label = b.triangle(i).map(|x| {
                format!(
                    "triangle {i}: vertices {:?}{}",
                    x.v,
                    x.material
                        .map(|m| format!(" material {m}"))
                        .unwrap_or_default()
                )
            });
            self.field(tri_at + tri_rec * i, tri_rec, &label.unwrap_or_default());
        }
        let tri_len = (tri_rec * t + 3) & !3;
        if tri_len > tri_rec * t {
            self.field(tri_at + tri_rec * t, tri_len - tri_rec * t, "padding");
        }
        // The part-id section (spec §8): one id per triangle, then padding.
        let id_len = match width {
            0 => 0,
            1 => 1,
            2 => 2,
            _ => 4,
        };
        let parts_at = tri_at + tri_len;
        let parts_len = (id_len * t + 3) & !3;
        if id_len > 0 {
            let ids: Vec<String> = (0..t)
                .map(|i| match b.part(i) {
                    Ok(Some(p)) => p.to_string(),
                    _ => "?".into(),
                })
                .collect();
            let label = format!(
                "part-id section: {t} × u{} part ids {} (+ padding)",
                8 * id_len,
                ids.join(" ")
            );
            self.field(parts_at, parts_len, &label);
        }
        let vert_at = parts_at + parts_len;
        let vert_len = (raw.len() - (vert_at - at)).checked_div(w).unwrap_or(0);
        for i in 0..w {
            let label = b.vertex(i).map(|v| {
                format!(
                    "vertex {i}: position {:?}{}{}",
                    v.position,
                    v.normal
                        .map(|n| format!(" normal(oct) {n:?}"))
                        .unwrap_or_default(),
                    v.colour
                        .map(|c| format!(" colour {c:?}"))
                        .unwrap_or_default()
                )
            });
            self.field(vert_at + vert_len * i, vert_len, &label.unwrap_or_default());
        }
    }

    fn directory(&mut self, reader: &Reader) {
        let base = reader.header().sections.directory_offset as usize;
        self.title(&format!(
            "directory ({} entries of 32 bytes)",
            reader.entries().len()
        ));
        for (i, e) in reader.entries().iter().enumerate() {
            let at = base + dir::ENTRY_LEN * i;
            self.field(
                at + dir::OFF_OFFSET,
                8,
                &format!("block {i}: offset {}", e.offset),
            );
            self.field(
                at + dir::OFF_STORED_LENGTH,
                4,
                &format!("stored length {}", e.stored_length),
            );
            self.field(
                at + dir::OFF_RAW_LENGTH,
                4,
                &format!("raw length {}", e.raw_length),
            );
            self.field(
                at + dir::OFF_CRC,
                4,
                &format!("CRC-32C of stored bytes {:#010x}", e.crc),
            );
            self.field(
                at + dir::OFF_KIND,
                1,
                &format!("kind {} ({})", e.kind as u8, e.kind.name()),
            );
            self.field(
                at + dir::OFF_CODEC,
                1,
                &format!("codec {} ({})", e.codec as u8, e.codec.name()),
            );
            self.field(at + dir::OFF_LEVEL, 2, &format!("level {}", e.level));
            self.field(
                at + dir::OFF_ITEM_COUNT,
                4,
                &format!("item count {}", e.item_count),
            );
            self.field(at + dir::OFF_RESERVED, 4, "reserved");
        }
    }

    fn metadata(&mut self, reader: &Reader) {
        let s = reader.header().sections;
        self.title(&format!("metadata ({} bytes, postcard)", s.metadata_length));
        self.field(
            s.metadata_offset as usize,
            s.metadata_length as usize,
            "postcard-encoded Metadata, decoded below",
        );
        let json = serde_json::to_string_pretty(reader.metadata()).unwrap_or_default();
        let _ = writeln!(self.o, "\n```json\n{json}\n```");
    }

    fn trailer(&mut self, at: usize) {
        self.title("trailer (48 bytes)");
        let rows: [(usize, usize, &str); 9] = [
            (trl::OFF_DIRECTORY_OFFSET, 8, "directory offset"),
            (trl::OFF_METADATA_OFFSET, 8, "metadata offset"),
            (trl::OFF_BLOCK_COUNT, 4, "block count"),
            (trl::OFF_METADATA_LENGTH, 4, "metadata length"),
            (trl::OFF_DIRECTORY_CRC, 4, "CRC-32C of the directory"),
            (trl::OFF_METADATA_CRC, 4, "CRC-32C of the metadata"),
            (
                trl::OFF_ROOT_CHECKSUM,
                4,
                "root checksum (the file identity)",
            ),
            (trl::OFF_TRAILER_CRC, 4, "CRC-32C of trailer bytes 0..36"),
            (trl::OFF_END_MAGIC, 8, "end magic OCFEND\\r\\n"),
        ];
        for (off, len, label) in rows {
            self.field(at + off, len, label);
        }
    }
}
