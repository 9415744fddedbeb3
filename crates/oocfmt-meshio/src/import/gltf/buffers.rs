//! Loads the buffers the selected meshes use: the GLB BIN chunk, `data:` URIs, and files in
//! the model's folder. Nothing else is read: no `file:` or other schemes, no absolute paths,
//! nothing that leaves the folder (through `..` or a symbolic link), nothing but regular
//! files, and never more than the buffers' declared lengths, whose sum is capped beforehand.

use std::collections::BTreeSet;
use std::fs::File;
use std::io::{Seek, SeekFrom};
use std::path::{Component, Path, PathBuf};

use base64::engine::general_purpose::{GeneralPurpose, GeneralPurposeConfig};
use base64::engine::DecodePaddingMode;
use base64::Engine;
use gltf::json;

use super::glb::{read_exact_len, BinChunk};
use super::io_error;
use crate::import::{ImportError, Location};

/// Padding is optional in practice: writers differ.
const BASE64: GeneralPurpose = GeneralPurpose::new(
    &base64::alphabet::STANDARD,
    GeneralPurposeConfig::new().with_decode_padding_mode(DecodePaddingMode::Indifferent),
);

/// Buffer contents by buffer index; each loaded buffer holds exactly its declared length.
pub(super) struct Buffers {
    data: Vec<Option<Vec<u8>>>,
}

impl Buffers {
    pub(super) fn get(&self, buffer: usize) -> Option<&[u8]> {
        self.data.get(buffer)?.as_deref()
    }
}

/// Where buffers come from.
pub(super) struct Origin<'a> {
    /// The .gltf or .glb file.
    pub model: &'a Path,
    /// Its name as errors give it.
    pub file: &'a str,
    pub bin: Option<BinChunk>,
}

/// Loads the `needed` buffers, refusing before any read when their declared lengths add up
/// to more than `max_bytes`.
pub(super) fn load(
    root: &json::Root,
    needed: &BTreeSet<usize>,
    origin: &Origin<'_>,
    max_bytes: u64,
) -> Result<Buffers, ImportError> {
    let mut total: u64 = 0;
    for &b in needed {
        let len = root.buffers.get(b).map_or(0, |buf| buf.byte_length.0);
        total = total.saturating_add(len);
    }
    if total > max_bytes {
        return Err(ImportError::Limit {
            at: Location::file(origin.file),
            what: format!(
                "the {} buffer(s) the imported meshes use ({total} bytes)",
                needed.len()
            ),
            limit: max_bytes,
        });
    }
    let mut data = vec![None; root.buffers.len()];
    for &b in needed {
        let (Some(buffer), Some(slot)) = (root.buffers.get(b), data.get_mut(b)) else {
            return Err(ImportError::Parse {
                at: Location::file(origin.file),
                message: format!("buffer {b} does not exist"),
            });
        };
        *slot = Some(load_one(b, buffer, origin)?);
    }
    Ok(Buffers { data })
}

fn load_one(b: usize, buffer: &json::Buffer, origin: &Origin<'_>) -> Result<Vec<u8>, ImportError> {
    let len = buffer.byte_length.0;
    let at = || Location::item(origin.file, format!("buffer {b}"));
    let Some(uri) = buffer.uri.as_deref() else {
        return match origin.bin {
            Some(bin) if b == 0 => read_bin_chunk(bin, len, origin),
            _ => Err(ImportError::Parse {
                at: at(),
                message: "the buffer has no uri (only buffer 0 of a .glb may use its BIN chunk)"
                    .into(),
            }),
        };
    };
    if uri
        .get(..5)
        .is_some_and(|s| s.eq_ignore_ascii_case("data:"))
    {
        return decode_data_uri(uri, len, at);
    }
    let path = resolve_relative(uri, origin.model, at)?;
    read_file(&path, len, origin.file)
}

fn read_bin_chunk(bin: BinChunk, len: u64, origin: &Origin<'_>) -> Result<Vec<u8>, ImportError> {
    // The chunk may be padded by up to 3 bytes past the buffer, never shorter.
    if bin.len < len {
        return Err(ImportError::Parse {
            at: Location::item(origin.file, "buffer 0"),
            message: format!(
                "byteLength is {len} but the GLB BIN chunk holds only {} bytes",
                bin.len
            ),
        });
    }
    let mut f = File::open(origin.model).map_err(|e| io_error(origin.model, e))?;
    f.seek(SeekFrom::Start(bin.offset))
        .map_err(|e| io_error(origin.model, e))?;
    read_exact_len(
        &mut f,
        len,
        bin.len,
        origin.model,
        origin.file,
        "buffer 0 (GLB BIN chunk)",
    )
}

fn decode_data_uri(uri: &str, len: u64, at: impl Fn() -> Location) -> Result<Vec<u8>, ImportError> {
    let Some((header, payload)) = uri.split_once(',') else {
        return Err(ImportError::Parse {
            at: at(),
            message: "data URI without a ',' before its data".into(),
        });
    };
    if !header.to_ascii_lowercase().ends_with(";base64") {
        return Err(ImportError::Unsupported {
            at: at(),
            what: format!(
                "data URI \"{}\" that is not base64-encoded",
                shorten(header)
            ),
        });
    }
    let mut bytes = BASE64
        .decode(payload.trim())
        .map_err(|e| ImportError::Parse {
            at: at(),
            message: format!("data URI: invalid base64: {e}"),
        })?;
    if (bytes.len() as u64) < len {
        return Err(ImportError::Parse {
            at: at(),
            message: format!(
                "byteLength is {len} but the data URI holds only {} bytes",
                bytes.len()
            ),
        });
    }
    bytes.truncate(usize::try_from(len).unwrap_or(usize::MAX));
    Ok(bytes)
}

/// The file a relative URI names inside the model's folder, or why it is refused.
fn resolve_relative(
    uri: &str,
    model: &Path,
    at: impl Fn() -> Location,
) -> Result<PathBuf, ImportError> {
    let refuse = |why: &str| ImportError::Unsupported {
        at: at(),
        what: format!(
            "buffer URI \"{}\": {why}; only data: URIs and relative paths inside the model's \
             folder are read",
            shorten(uri)
        ),
    };
    // A scheme (`file:`, `http:`) or a drive letter: a ':' before the first '/'.
    if uri
        .split('/')
        .next()
        .is_some_and(|first| first.contains(':'))
    {
        return Err(refuse("it names a scheme"));
    }
    let decoded = percent_decode(uri).ok_or_else(|| refuse("bad percent-encoding"))?;
    if decoded.contains('\0') {
        return Err(refuse("it holds a NUL character"));
    }
    let relative = Path::new(&decoded);
    let escapes = decoded.starts_with(['/', '\\'])
        || decoded.split(['/', '\\']).any(|segment| segment == "..")
        || relative
            .components()
            .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir));
    if escapes {
        return Err(refuse("it leaves the model's folder"));
    }
    let folder = match model.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let path = folder.join(relative);
    // Symbolic links must not lead out of the folder either.
    let real_folder = folder.canonicalize().map_err(|e| io_error(&folder, e))?;
    let real = path.canonicalize().map_err(|e| io_error(&path, e))?;
    if !real.starts_with(&real_folder) {
        return Err(refuse("it leads out of the model's folder through a link"));
    }
    Ok(real)
}

fn read_file(path: &Path, len: u64, file: &str) -> Result<Vec<u8>, ImportError> {
    let meta = std::fs::metadata(path).map_err(|e| io_error(path, e))?;
    // Devices and pipes could block or never end.
    if !meta.is_file() {
        return Err(ImportError::Parse {
            at: Location::file(file),
            message: format!("buffer file {} is not a regular file", path.display()),
        });
    }
    let mut f = File::open(path).map_err(|e| io_error(path, e))?;
    read_exact_len(
        &mut f,
        len,
        meta.len(),
        path,
        file,
        &format!("buffer file {}", path.display()),
    )
}

/// RFC 3986 percent-decoding; `None` for a malformed escape or a result that is not UTF-8.
fn percent_decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while let Some(&c) = bytes.get(i) {
        if c == b'%' {
            let digit = |k: usize| char::from(*bytes.get(k)?).to_digit(16);
            out.push(u8::try_from(digit(i + 1)? * 16 + digit(i + 2)?).ok()?);
            i += 3;
        } else {
            out.push(c);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// A URI as errors quote it: data URIs can be megabytes long.
fn shorten(s: &str) -> String {
    const MAX: usize = 120;
    match s.char_indices().nth(MAX) {
        Some((cut, _)) => format!("{}…", &s[..cut]),
        None => s.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b.bin").as_deref(), Some("a b.bin"));
        assert_eq!(percent_decode("%2e%2E/x").as_deref(), Some("../x"));
        assert_eq!(percent_decode("bad%2"), None);
        assert_eq!(percent_decode("bad%zz"), None);
        assert_eq!(percent_decode("bad%+1"), None);
    }

    #[test]
    fn shortening_respects_characters() {
        let long = "é".repeat(200);
        assert_eq!(shorten(&long).chars().count(), 121);
        assert_eq!(shorten("x.bin"), "x.bin");
    }
}
