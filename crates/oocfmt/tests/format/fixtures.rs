//! The fixtures of `tests/common` and the spec vectors are valid: deep verify finds nothing in a
//! fixture (the empty one only warns `TREE_EMPTY`), and every block of every file reads back.

use crate::common;

use common::{
    deep, fixtures, has_error, open_bytes, read_all_blocks, vectors, verify_bytes, TestResult,
};
use oocfmt::verify::Depth;
use oocfmt::{Code, ReadOptions, Reader};

#[test]
fn every_fixture_is_deep_valid_with_no_issue() -> TestResult {
    let all = fixtures()?;
    assert!(all.len() >= 4);
    for f in &all {
        let r = verify_bytes(&f.bytes, &deep())?;
        assert!(r.valid, "{}: {:?}", f.name, r.issues);
        if f.name == "fx-empty" {
            assert_eq!(common::codes(&r), vec![Code::TreeEmpty], "{}", f.name);
        } else {
            assert!(r.issues.is_empty(), "{}: {:?}", f.name, r.issues);
            assert_eq!(r.errors + r.warnings + r.infos, 0);
        }
        assert_eq!(
            r.blocks_checked,
            u64::from(
                open_bytes(&f.bytes, ReadOptions::default())?
                    .header()
                    .sections
                    .block_count
            )
        );
    }
    Ok(())
}

#[test]
fn fixtures_exercise_every_codec_kind_and_feature() -> TestResult {
    let mut codecs = std::collections::BTreeSet::new();
    let mut kinds = std::collections::BTreeSet::new();
    let mut features = 0u64;
    for f in fixtures()? {
        let r = open_bytes(&f.bytes, ReadOptions::default())?;
        read_all_blocks(&r)?;
        features |= r.header().compatible_features;
        for e in r.entries() {
            codecs.insert(e.codec);
            kinds.insert(e.kind);
        }
    }
    assert_eq!(
        codecs.len(),
        3,
        "fixtures should store blocks under every codec: {codecs:?}"
    );
    assert_eq!(kinds.len(), 3, "{kinds:?}");
    assert_eq!(features, oocfmt::header::KNOWN_COMPAT);
    Ok(())
}

#[test]
fn fixtures_are_deterministic() -> TestResult {
    let a = fixtures()?;
    let b = fixtures()?;
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(
            x.bytes, y.bytes,
            "{}: the same input must give a byte-identical file",
            x.name
        );
    }
    Ok(())
}

#[test]
fn every_vector_is_valid_and_reads_back() -> TestResult {
    for v in vectors()? {
        let r = verify_bytes(&v.bytes, &deep())?;
        assert!(!has_error(&r), "{}: {:?}", v.name, r.issues);
        let path = common::vectors_dir().join(&v.name);
        for reader in [
            Reader::open(&path, ReadOptions::default())?,
            Reader::open_mmap(&path, ReadOptions::default())?,
        ] {
            read_all_blocks(&reader)?;
        }
        let quick = verify_bytes(
            &v.bytes,
            &oocfmt::verify::VerifyOptions {
                depth: Depth::Quick,
                ..Default::default()
            },
        )?;
        assert!(quick.valid, "{}", v.name);
    }
    Ok(())
}
