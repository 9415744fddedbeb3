//! Reads the JSON of a `.gltf`, or the JSON chunk of a `.glb` and where its BIN chunk lies.
//! The GLB container is parsed here rather than by the gltf crate, whose `Glb::from_slice`
//! underflows on a header length below 12 and whose `Glb::from_reader` allocates whatever
//! length the header claims.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use super::io_error;
use crate::import::{ImportError, Location};

const MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;
const HEADER_LEN: u64 = 12;
const CHUNK_HEADER_LEN: u64 = 8;

/// Where a GLB's binary chunk lies in the file.
#[derive(Clone, Copy, Debug)]
pub(super) struct BinChunk {
    pub offset: u64,
    pub len: u64,
}

pub(super) struct Source {
    pub json: Vec<u8>,
    pub bin: Option<BinChunk>,
}

/// Reads the document: a GLB when the file starts with the GLB magic, JSON otherwise.
pub(super) fn read_source(path: &Path, file: &str, max_json: u64) -> Result<Source, ImportError> {
    let mut f = File::open(path).map_err(|e| io_error(path, e))?;
    let size = f.metadata().map_err(|e| io_error(path, e))?.len();
    let mut magic = [0u8; 4];
    let is_glb = size >= 4 && {
        f.read_exact(&mut magic).map_err(|e| io_error(path, e))?;
        &magic == MAGIC
    };
    if is_glb {
        return read_glb(&mut f, path, file, size, max_json);
    }
    if size > max_json {
        return Err(ImportError::Limit {
            at: Location::file(file),
            what: format!("the glTF JSON ({size} bytes)"),
            limit: max_json,
        });
    }
    f.seek(SeekFrom::Start(0)).map_err(|e| io_error(path, e))?;
    let json = read_exact_len(&mut f, size, size, path, file, "the glTF JSON")?;
    Ok(Source {
        json: strip_bom(json),
        bin: None,
    })
}

fn read_glb(
    f: &mut File,
    path: &Path,
    file: &str,
    size: u64,
    max_json: u64,
) -> Result<Source, ImportError> {
    let bad = |message: String| ImportError::Parse {
        at: Location::item(file, "GLB header"),
        message,
    };
    let mut header = [0u8; 8];
    f.read_exact(&mut header).map_err(|_| {
        bad(format!(
            "the file ends inside the GLB header ({size} bytes)"
        ))
    })?;
    let version = u32::from_le_bytes([header[0], header[1], header[2], header[3]]);
    let length = u64::from(u32::from_le_bytes([
        header[4], header[5], header[6], header[7],
    ]));
    if version != 2 {
        return Err(ImportError::Unsupported {
            at: Location::item(file, "GLB header"),
            what: format!("GLB version {version} (only 2 is glTF 2.0)"),
        });
    }
    if length > size {
        return Err(bad(format!(
            "the header says {length} bytes but the file holds {size}"
        )));
    }
    let (json_len, json_type) = chunk_header(f, HEADER_LEN, length)
        .ok_or_else(|| bad(format!("no JSON chunk header within the {length} bytes")))?;
    if json_type != CHUNK_JSON {
        return Err(bad(format!(
            "the first chunk is of type {json_type:#010x}, not JSON"
        )));
    }
    let json_start = HEADER_LEN + CHUNK_HEADER_LEN;
    if json_len > length - json_start {
        return Err(bad(format!(
            "the JSON chunk of {json_len} bytes overruns the {length} bytes of the file"
        )));
    }
    if json_len > max_json {
        return Err(ImportError::Limit {
            at: Location::item(file, "GLB JSON chunk"),
            what: format!("the glTF JSON ({json_len} bytes)"),
            limit: max_json,
        });
    }
    f.seek(SeekFrom::Start(json_start))
        .map_err(|e| io_error(path, e))?;
    let json = read_exact_len(f, json_len, json_len, path, file, "the GLB JSON chunk")?;

    // Chunks are 4-byte aligned; a BIN chunk, if any, comes right after the JSON.
    let next = json_start + json_len.next_multiple_of(4);
    let bin = match chunk_header(f, next, length) {
        Some((len, CHUNK_BIN)) => {
            let offset = next + CHUNK_HEADER_LEN;
            if len > length - offset {
                return Err(ImportError::Parse {
                    at: Location::item(file, "GLB BIN chunk"),
                    message: format!(
                        "the BIN chunk of {len} bytes at offset {offset} overruns the {length} \
                         bytes of the file"
                    ),
                });
            }
            Some(BinChunk { offset, len })
        }
        // Unknown chunk types are to be ignored (glTF 2.0 §4.4.3.2).
        _ => None,
    };
    Ok(Source {
        json: strip_bom(json),
        bin,
    })
}

/// The chunk header at `at` when it lies within `length`: `(chunk length, chunk type)`.
fn chunk_header(f: &mut File, at: u64, length: u64) -> Option<(u64, u32)> {
    if length.checked_sub(at)? < CHUNK_HEADER_LEN {
        return None;
    }
    let mut h = [0u8; 8];
    f.seek(SeekFrom::Start(at)).ok()?;
    f.read_exact(&mut h).ok()?;
    Some((
        u64::from(u32::from_le_bytes([h[0], h[1], h[2], h[3]])),
        u32::from_le_bytes([h[4], h[5], h[6], h[7]]),
    ))
}

/// Reads exactly `len` bytes from the current position. Reserves no more than `available`
/// (what the file's size says is there), so a lying length cannot make us reserve memory.
pub(super) fn read_exact_len(
    f: &mut impl Read,
    len: u64,
    available: u64,
    path: &Path,
    file: &str,
    what: &str,
) -> Result<Vec<u8>, ImportError> {
    let mut out = Vec::with_capacity(usize::try_from(len.min(available)).unwrap_or(0));
    f.take(len)
        .read_to_end(&mut out)
        .map_err(|e| io_error(path, e))?;
    if (out.len() as u64) < len {
        return Err(ImportError::Parse {
            at: Location::file(file),
            message: format!(
                "{what}: expected {len} bytes from {}, the file ends after {}",
                path.display(),
                out.len()
            ),
        });
    }
    Ok(out)
}

fn strip_bom(mut json: Vec<u8>) -> Vec<u8> {
    if json.starts_with(&[0xEF, 0xBB, 0xBF]) {
        json.drain(..3);
    }
    json
}
