//! `subset_file`: the bytes as a subset file of a split build (spec §16.2), as given and
//! re-sealed (the header's and the body's CRCs recomputed, so mutations reach the decoding and
//! the merge behind the checksums). `verify_subset` and a merge of the file alone (a plan of
//! one subset) must never panic, hang or allocate past the file; a failed merge must leave no
//! output. This file is the only copy of the property: the target calls it through the
//! `oocfmt_fuzz` library, and `crates/oocfmt-build/tests/fuzz_corpus.rs` includes it by path.

use oocfmt_build::convert::ConvertOptions;
use oocfmt_build::progress::NoProgress;
use oocfmt_build::subsets::{merge, verify_subset, SUBSET_HEADER_LEN};

/// The property on `data` as given and re-sealed.
pub fn subset_file(data: &[u8]) {
    exercise(data);
    if let Some(sealed) = reseal(data) {
        if sealed != data {
            exercise(&sealed);
        }
    }
}

fn exercise(bytes: &[u8]) {
    let Ok(dir) = tempfile::tempdir() else {
        return;
    };
    let part = dir.path().join("part.oocfp");
    if std::fs::write(&part, bytes).is_err() {
        return;
    }
    let checked = verify_subset(&part);
    let out = dir.path().join("out.oocf");
    let opts = ConvertOptions {
        mem_limit: 64 << 20,
        ..ConvertOptions::default()
    };
    match merge(
        std::slice::from_ref(&part),
        &out,
        &opts,
        None,
        &mut NoProgress,
    ) {
        // The merge reads what verify checks, and more.
        Ok(_) => assert!(checked.is_ok(), "merged a subset file that verify refuses"),
        Err(_) => assert!(!out.exists(), "a failed merge left its output"),
    }
}

/// `data` with its body's and header's CRC-32C recomputed, when its header places the body
/// at the file's end; `None` otherwise.
pub fn reseal(data: &[u8]) -> Option<Vec<u8>> {
    let header = usize::try_from(SUBSET_HEADER_LEN).ok()?;
    let mut f = data.to_vec();
    let u64_at = |at: usize| -> Option<u64> {
        Some(u64::from_le_bytes(f.get(at..at + 8)?.try_into().ok()?))
    };
    let (offset, len) = (u64_at(24)?, u64_at(32)?);
    if offset < SUBSET_HEADER_LEN || offset.checked_add(len)? != f.len() as u64 {
        return None;
    }
    let body = crc32c::crc32c(f.get(usize::try_from(offset).ok()?..)?);
    f.get_mut(40..44)?.copy_from_slice(&body.to_le_bytes());
    let head = crc32c::crc32c(f.get(..60)?);
    f.get_mut(60..header)?.copy_from_slice(&head.to_le_bytes());
    Some(f)
}
