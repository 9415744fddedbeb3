//! Puts an out-of-core build's pieces into one container: treelet blocks level by level (the
//! top's first, then each chunk's, in chunk order), then every chunk's triangle blocks, then
//! the proxies. Chunk blocks were encoded with chunk-local ids; their child-block, triangle-
//! block and proxy node-block references are rewritten to the final ids on the way out.

use std::path::Path;

use oocfmt::records::{Node, TreeletBlock, PROXY_LEN};
use oocfmt::{BlockKind, EncodedBlock, Metadata, WriteOptions, WriteSummary, Writer};

use super::chunk::{BlockSpill, ChunkOut, SpilledBlock};
use super::disk::SpillDisk;
use super::OocError;
use crate::layout::{Appender, LayoutError, RawBlock, ENCODE_BATCH};
use crate::progress::Progress;

/// Where each block of the file comes from, in file order, and the final id of every chunk
/// block.
pub struct Order {
    pub blocks: Vec<Source>,
    /// Final id of each top treelet block.
    pub top: Vec<u32>,
    /// Final id of each chunk's treelet blocks, then of its triangle blocks.
    pub chunk_treelets: Vec<Vec<u32>>,
    pub chunk_triangles: Vec<Vec<u32>>,
    /// LOD levels (one more than the deepest treelet block's level).
    pub levels: u32,
    /// What each chunk's treelet blocks add to the proxy ids they hold (none: 0).
    pub proxy_shift: Vec<u32>,
}

/// Where the chunks' encoded blocks wait for the file order: the build's own spill, or the
/// subset files a merge reads.
pub trait BlockSource {
    /// Ends writing: what follows only reads.
    fn close(&mut self) {}
    /// The raw bytes of block `b` of chunk `chunk`, each block read once.
    fn read(&mut self, chunk: usize, b: &SpilledBlock) -> Result<Vec<u8>, OocError>;
}

impl BlockSource for BlockSpill {
    fn close(&mut self) {
        BlockSpill::close(self);
    }

    fn read(&mut self, _chunk: usize, b: &SpilledBlock) -> Result<Vec<u8>, OocError> {
        BlockSpill::read(self, b)
    }
}

#[derive(Clone, Copy, Debug)]
pub enum Source {
    Top(usize),
    Chunk(usize, SpilledBlock),
}

/// The file order: the spec wants every treelet block of level k before any of level k + 1.
pub fn order(top_levels: &[u16], chunks: &[ChunkOut]) -> Result<Order, LayoutError> {
    let deepest = top_levels
        .iter()
        .chain(
            chunks
                .iter()
                .flat_map(|c| c.treelet_blocks.iter().map(|b| &b.level)),
        )
        .copied()
        .max()
        .unwrap_or(0);
    let mut o = Order {
        blocks: Vec::new(),
        top: vec![0; top_levels.len()],
        chunk_treelets: chunks
            .iter()
            .map(|c| vec![0; c.treelet_blocks.len()])
            .collect(),
        chunk_triangles: chunks
            .iter()
            .map(|c| vec![0; c.triangle_blocks.len()])
            .collect(),
        levels: u32::from(deepest) + 1,
        proxy_shift: Vec::new(),
    };
    let next =
        |o: &Order| u32::try_from(o.blocks.len()).map_err(|_| LayoutError::TooMany("blocks"));
    for level in 0..=deepest {
        for (k, &l) in top_levels.iter().enumerate() {
            if l == level {
                let id = next(&o)?;
                if let Some(slot) = o.top.get_mut(k) {
                    *slot = id;
                }
                o.blocks.push(Source::Top(k));
            }
        }
        for (i, c) in chunks.iter().enumerate() {
            for (k, b) in c.treelet_blocks.iter().enumerate() {
                if b.level == level {
                    let id = next(&o)?;
                    if let Some(slot) = o.chunk_treelets.get_mut(i).and_then(|v| v.get_mut(k)) {
                        *slot = id;
                    }
                    o.blocks.push(Source::Chunk(i, *b));
                }
            }
        }
    }
    for (i, c) in chunks.iter().enumerate() {
        for (k, b) in c.triangle_blocks.iter().enumerate() {
            let id = next(&o)?;
            if let Some(slot) = o.chunk_triangles.get_mut(i).and_then(|v| v.get_mut(k)) {
                *slot = id;
            }
            o.blocks.push(Source::Chunk(i, *b));
        }
    }
    Ok(o)
}

fn lookup(map: &[u32], local: u32) -> Result<u32, LayoutError> {
    map.get(local as usize)
        .copied()
        .ok_or(LayoutError::Internal(
            "a block reference points past its chunk",
        ))
}

impl Order {
    /// Rewrites a chunk treelet block's references from chunk-local to final ids; `kinds` is
    /// what the file's LOD entries hold.
    fn patch_treelets(
        &self,
        chunk: usize,
        raw: &mut [u8],
        kinds: oocfmt::records::LodKinds,
    ) -> Result<(), OocError> {
        let empty = Vec::new();
        let treelets = self.chunk_treelets.get(chunk).unwrap_or(&empty);
        let triangles = self.chunk_triangles.get(chunk).unwrap_or(&empty);
        let shift = self.proxy_shift.get(chunk).copied().unwrap_or(0);
        let mut nodes = Vec::new();
        let block = TreeletBlock::parse_with(raw, kinds)?;
        let area = 16 + 4 * block.treelet_count();
        block.walk(|_, pos, node| {
            if !matches!(node, Node::Basic { .. }) {
                nodes.push((area + pos, *node));
            }
            Ok(())
        })?;
        for (at, mut node) in nodes {
            match &mut node {
                Node::Lod {
                    child_block, proxy, ..
                } => {
                    *child_block = lookup(treelets, *child_block)?;
                    if *proxy != oocfmt::records::NO_PROXY {
                        *proxy = proxy
                            .checked_add(shift)
                            .ok_or(LayoutError::TooMany("proxies"))?;
                    }
                }
                Node::Leaf { block, .. } => *block = lookup(triangles, *block)?,
                Node::Basic { .. } => {}
            }
            let mut bytes = Vec::with_capacity(node.byte_len());
            node.encode_into(&mut bytes);
            raw.get_mut(at..at + bytes.len())
                .ok_or(LayoutError::Internal("a patched node lies past its block"))?
                .copy_from_slice(&bytes);
        }
        Ok(())
    }

    /// Rewrites the node-block field of a chunk's proxy records.
    pub fn patch_proxies(&self, chunk: usize, records: &mut [u8]) -> Result<(), OocError> {
        let empty = Vec::new();
        let treelets = self.chunk_treelets.get(chunk).unwrap_or(&empty);
        for r in records.chunks_exact_mut(PROXY_LEN) {
            let mut b = [0u8; 4];
            b.copy_from_slice(&r[..4]);
            let id = lookup(treelets, u32::from_le_bytes(b))?;
            r[..4].copy_from_slice(&id.to_le_bytes());
        }
        Ok(())
    }
}

/// What goes into the file besides the metadata.
pub struct Parts<'a> {
    pub order: &'a Order,
    /// The top's treelet blocks, encoded with final ids.
    pub top: &'a [RawBlock],
    /// Final proxy records in id order.
    pub proxies: &'a [u8],
    /// What the LOD entries hold, the part word included: how spilled treelet blocks parse.
    pub lod: oocfmt::records::LodKinds,
}

/// Writes every block in file order, then the proxies, then the metadata. Top blocks come
/// from memory, chunk blocks from the `spill`, which frees them as they are read; `disk`
/// follows the output's growth.
pub fn write(
    path: &Path,
    write: WriteOptions,
    parts: &Parts,
    blocks: &mut dyn BlockSource,
    disk: &SpillDisk,
    metadata: &Metadata,
    progress: &mut dyn Progress,
) -> Result<WriteSummary, OocError> {
    let Parts {
        order,
        top: top_raw,
        proxies,
        lod,
    } = *parts;
    let block_size = 1usize << write.block_size_log2.min(20);
    blocks.close();
    let per_block = (block_size / PROXY_LEN).max(1);
    let proxy_blocks = proxies.len().div_ceil(PROXY_LEN * per_block);
    progress.phase("write", Some((order.blocks.len() + proxy_blocks) as u64));
    let mut writer = Writer::create(path, write)?;
    let temp = writer.temp_path().to_path_buf();
    let mut appender = Appender::new(&mut writer, write.codec);
    let mut done = 0u64;
    for batch in order.blocks.chunks(ENCODE_BATCH) {
        let raws: Vec<RawBlock> = batch
            .iter()
            .map(|s| match *s {
                Source::Top(k) => top_raw
                    .get(k)
                    .cloned()
                    .ok_or_else(|| LayoutError::Internal("a top block is missing").into()),
                Source::Chunk(i, b) => {
                    let mut raw = blocks.read(i, &b)?;
                    if b.kind == BlockKind::Treelet {
                        order.patch_treelets(i, &mut raw, lod)?;
                    }
                    Ok(RawBlock {
                        kind: b.kind,
                        level: b.level,
                        item_count: b.item_count,
                        raw,
                    })
                }
            })
            .collect::<Result<_, OocError>>()?;
        appender.push(&raws)?;
        // What the output holds so far (its write buffer aside), for the peak disk use.
        if let Ok(m) = std::fs::metadata(&temp) {
            disk.set_output(m.len());
        }
        done += batch.len() as u64;
        progress.advance(done);
    }
    appender.finish()?;
    for records in proxies.chunks(PROXY_LEN * per_block) {
        let n = u32::try_from(records.len() / PROXY_LEN)
            .map_err(|_| LayoutError::TooMany("proxies"))?;
        writer.write_encoded(EncodedBlock::encode(
            write.codec,
            BlockKind::Proxy,
            0,
            n,
            records,
        )?)?;
        done += 1;
        progress.advance(done);
    }
    let summary = writer.finish(metadata)?;
    progress.finish_phase();
    Ok(summary)
}
