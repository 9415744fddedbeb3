//! The subset file, `.oocfp` (spec §16.2): a 64-byte header, the subset's blocks (raw, each
//! checksummed), and a postcard body describing its part of the tree. Written under a
//! temporary name and renamed into place; read with every length checked against the file.

use std::fs::File;
use std::io::{Seek, SeekFrom, Write};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::SubsetError;
use crate::lod::rlod::PlaneFit;
use crate::lod::Seen;
use crate::ooc::chunk::{BlockSpill, ChunkOut, SpilledBlock};
use crate::ooc::split::TopNode;
use crate::ooc::SceneInfo;
use oocfmt_meshio::mesh::Bounds;

/// The first eight bytes of a subset file.
pub const MAGIC: [u8; 8] = *b"OOCFSUB\0";
/// The layout version this build writes and reads.
pub const VERSION: u16 = 2;
/// Bytes of the header; the blocks start here.
pub const HEADER_LEN: u64 = 64;

/// The fixed header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Header {
    pub index: u32,
    pub subsets: u32,
    pub plan_identity: u32,
    pub body_offset: u64,
    pub body_len: u64,
    pub body_crc: u32,
}

impl Header {
    fn encode(&self) -> [u8; HEADER_LEN as usize] {
        let mut h = [0u8; HEADER_LEN as usize];
        h[0..8].copy_from_slice(&MAGIC);
        h[8..10].copy_from_slice(&VERSION.to_le_bytes());
        h[12..16].copy_from_slice(&self.index.to_le_bytes());
        h[16..20].copy_from_slice(&self.subsets.to_le_bytes());
        h[20..24].copy_from_slice(&self.plan_identity.to_le_bytes());
        h[24..32].copy_from_slice(&self.body_offset.to_le_bytes());
        h[32..40].copy_from_slice(&self.body_len.to_le_bytes());
        h[40..44].copy_from_slice(&self.body_crc.to_le_bytes());
        let crc = crc32c::crc32c(&h[..60]);
        h[60..64].copy_from_slice(&crc.to_le_bytes());
        h
    }

    /// Decodes and checks a header; `len` is the file's length.
    fn decode(h: &[u8; HEADER_LEN as usize], len: u64) -> Result<Header, &'static str> {
        let u16_at = |at: usize| u16::from_le_bytes([h[at], h[at + 1]]);
        let u32_at = |at: usize| u32::from_le_bytes([h[at], h[at + 1], h[at + 2], h[at + 3]]);
        let u64_at = |at: usize| u64::from(u32_at(at)) | (u64::from(u32_at(at + 4)) << 32);
        if h[0..8] != MAGIC {
            return Err("not an oocfmt subset file (bad magic)");
        }
        if u16_at(8) != VERSION {
            return Err("a subset file version this build does not read");
        }
        if crc32c::crc32c(&h[..60]) != u32_at(60) {
            return Err("header checksum mismatch");
        }
        if u16_at(10) != 0 || h[44..60].iter().any(|&b| b != 0) {
            return Err("reserved header bytes are not zero");
        }
        let header = Header {
            index: u32_at(12),
            subsets: u32_at(16),
            plan_identity: u32_at(20),
            body_offset: u64_at(24),
            body_len: u64_at(32),
            body_crc: u32_at(40),
        };
        if header.index >= header.subsets {
            return Err("the subset index is not below the subset count");
        }
        if header.body_offset < HEADER_LEN
            || header.body_offset.checked_add(header.body_len) != Some(len)
        {
            return Err("the body does not end the file");
        }
        Ok(header)
    }
}

/// The subset's part of the tree, as the merge needs it. Node ids below the plan's node count
/// are the plan's; the subset's own nodes follow them in `nodes`.
#[derive(Serialize, Deserialize)]
pub struct Body {
    /// The plan's JSON, as the subset read it.
    pub plan: String,
    pub scene: SceneInfo,
    /// Triangles the import read and kept, over the whole scene.
    pub triangles_in: u64,
    pub triangles_out: u64,
    /// The node at the subset's cell: a cut or a chunk.
    pub root: TopNode,
    /// Nodes the subset added below it, from id `plan.nodes.len()` on.
    pub nodes: Vec<TopNode>,
    pub chunks: Vec<ChunkRecord>,
    /// Chunks over the budget.
    pub oversized: Vec<usize>,
    /// The R-LOD planes of the subset's own LOD nodes, measured against all its chunks.
    pub planes: Vec<(usize, PlaneFit)>,
    /// The LOD nodes above the chunks the subset sampled: its own and the plan's above it.
    pub top_lod: Vec<TopLodRecord>,
    pub proxy_count: u32,
}

/// One chunk: its cell and place, and what it built (block places in this file).
#[derive(Serialize, Deserialize)]
pub struct ChunkRecord {
    pub count: u64,
    pub cell: Bounds,
    pub depth: u32,
    pub ancestors: Vec<usize>,
    pub out: ChunkOut,
}

/// The answered rays of a LOD node above the chunks: the nearest hit of each, if any.
#[derive(Serialize, Deserialize)]
pub struct TopLodRecord {
    pub node: usize,
    pub cell: Bounds,
    pub answers: Vec<Option<(f64, Seen)>>,
}

/// Writes the subset file `path`: the blocks of `body.chunks` from `spill`, level by level
/// then the triangle blocks, then the body. Nothing is left under `path` on failure.
pub fn write(
    path: &Path,
    mut header: Header,
    body: &mut Body,
    spill: &mut BlockSpill,
) -> Result<u64, SubsetError> {
    let io = |source| SubsetError::Io {
        path: path.display().to_string(),
        source,
    };
    let mut tmp = temp_beside(path).map_err(io)?;
    spill.close();
    let file = tmp.as_file_mut();
    file.write_all(&[0u8; HEADER_LEN as usize]).map_err(io)?;
    let mut at = HEADER_LEN;
    let deepest = body
        .chunks
        .iter()
        .flat_map(|c| c.out.treelet_blocks.iter().map(|b| b.level))
        .max()
        .unwrap_or(0);
    let mut copy = |b: &mut SpilledBlock| -> Result<(), SubsetError> {
        let raw = spill.read(b)?;
        file.write_all(&raw).map_err(io)?;
        b.segment = 0;
        b.offset = at;
        at += b.len;
        Ok(())
    };
    for level in 0..=deepest {
        for c in &mut body.chunks {
            for b in c.out.treelet_blocks.iter_mut().filter(|b| b.level == level) {
                copy(b)?;
            }
        }
    }
    for c in &mut body.chunks {
        for b in &mut c.out.triangle_blocks {
            copy(b)?;
        }
    }
    let bytes = postcard::to_stdvec(&*body).map_err(|e| SubsetError::Json(e.to_string()))?;
    file.write_all(&bytes).map_err(io)?;
    header.body_offset = at;
    header.body_len = bytes.len() as u64;
    header.body_crc = crc32c::crc32c(&bytes);
    file.seek(SeekFrom::Start(0)).map_err(io)?;
    file.write_all(&header.encode()).map_err(io)?;
    file.sync_all().map_err(io)?;
    tmp.persist(path).map_err(|e| io(e.error))?;
    Ok(at + header.body_len)
}

/// A temporary file in `path`'s folder, to be renamed to `path` once complete (and removed if
/// dropped before), made as an ordinary file would be (0666 less the umask), not 0600.
pub(crate) fn temp_beside(path: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    let dir = super::build::folder_of(path);
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    tempfile::Builder::new()
        .prefix(&format!(".{}-", name.unwrap_or_default()))
        .suffix(".tmp")
        .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666))
        .tempfile_in(dir)
}

/// A subset file, open for the merge: its header and body checked, its blocks read on demand.
pub struct SubsetFile {
    pub path: PathBuf,
    pub header: Header,
    pub body: Body,
    file: File,
}

impl SubsetFile {
    /// Opens `path` and checks its header, its body's checksum and its body's encoding.
    pub fn open(path: &Path) -> Result<SubsetFile, SubsetError> {
        let name = path.display().to_string();
        let corrupt = |offset: u64, what: &str| SubsetError::Corrupt {
            path: name.clone(),
            offset,
            what: what.to_string(),
        };
        let file = File::open(path).map_err(|source| SubsetError::Io {
            path: name.clone(),
            source,
        })?;
        let len = file
            .metadata()
            .map_err(|source| SubsetError::Io {
                path: name.clone(),
                source,
            })?
            .len();
        let mut h = [0u8; HEADER_LEN as usize];
        if len < HEADER_LEN {
            return Err(corrupt(0, "shorter than the 64-byte header"));
        }
        file.read_exact_at(&mut h, 0)
            .map_err(|source| SubsetError::Io {
                path: name.clone(),
                source,
            })?;
        let header = Header::decode(&h, len).map_err(|what| corrupt(0, what))?;
        // The body's length was checked against the file's: it is there to read.
        let mut bytes = vec![0u8; usize::try_from(header.body_len).unwrap_or(0)];
        file.read_exact_at(&mut bytes, header.body_offset)
            .map_err(|source| SubsetError::Io {
                path: name.clone(),
                source,
            })?;
        if crc32c::crc32c(&bytes) != header.body_crc {
            return Err(corrupt(header.body_offset, "body checksum mismatch"));
        }
        let body: Body = postcard::from_bytes(&bytes)
            .map_err(|e| corrupt(header.body_offset, &format!("body does not decode: {e}")))?;
        Ok(SubsetFile {
            path: path.to_path_buf(),
            header,
            body,
            file,
        })
    }

    /// Reads every block and checks its checksum, and that the blocks tile the block area in
    /// the order they are listed (level by level, then the triangle blocks); returns the
    /// blocks and their bytes.
    pub fn check_blocks(&self) -> Result<(u64, u64), SubsetError> {
        let mut at = HEADER_LEN;
        let mut count = 0u64;
        let chunks = &self.body.chunks;
        let deepest = chunks
            .iter()
            .flat_map(|c| c.out.treelet_blocks.iter().map(|b| b.level))
            .max()
            .unwrap_or(0);
        let treelets = (0..=deepest).flat_map(|level| {
            chunks.iter().flat_map(move |c| {
                c.out
                    .treelet_blocks
                    .iter()
                    .filter(move |b| b.level == level)
            })
        });
        let triangles = chunks.iter().flat_map(|c| c.out.triangle_blocks.iter());
        for b in treelets.chain(triangles) {
            if b.offset != at {
                return Err(SubsetError::Corrupt {
                    path: self.path.display().to_string(),
                    offset: b.offset,
                    what: format!(
                        "a block starts at byte {}, not {at} where the one before ends",
                        b.offset
                    ),
                });
            }
            self.read_block(b)?;
            at += b.len;
            count += 1;
        }
        if at != self.header.body_offset {
            return Err(SubsetError::Corrupt {
                path: self.path.display().to_string(),
                offset: at,
                what: "the blocks end before the body".into(),
            });
        }
        Ok((count, at - HEADER_LEN))
    }

    /// Reads block `b`, checking that it lies among the blocks and its checksum.
    pub fn read_block(&self, b: &SpilledBlock) -> Result<Vec<u8>, SubsetError> {
        let corrupt = |what: &str| SubsetError::Corrupt {
            path: self.path.display().to_string(),
            offset: b.offset,
            what: what.to_string(),
        };
        let end = b.offset.checked_add(b.len);
        if b.offset < HEADER_LEN || end.is_none_or(|e| e > self.header.body_offset) {
            return Err(corrupt("a block lies outside the block area"));
        }
        let mut raw = vec![0u8; usize::try_from(b.len).unwrap_or(0)];
        self.file
            .read_exact_at(&mut raw, b.offset)
            .map_err(|source| SubsetError::Io {
                path: self.path.display().to_string(),
                source,
            })?;
        if crc32c::crc32c(&raw) != b.crc {
            return Err(corrupt("block checksum mismatch"));
        }
        Ok(raw)
    }
}
