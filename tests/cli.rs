//! End-to-end tests of the `oocfmt` binary: spec vectors against their expected `inspect --json`,
//! exit codes, verify reports, and the demo. Set OOCFMT_BLESS=1 to rewrite expected outputs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn oocfmt(args: &[&str], cwd: &Path) -> Output {
    match Command::new(env!("CARGO_BIN_EXE_oocfmt"))
        .args(args)
        .current_dir(cwd)
        .output()
    {
        Ok(o) => o,
        Err(e) => panic!("cannot run oocfmt: {e}"),
    }
}

fn vectors_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../spec/vectors")
}

fn vectors() -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(vectors_dir())
        .map(|d| {
            d.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(".oocf"))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

fn bless() -> bool {
    std::env::var_os("OOCFMT_BLESS").is_some()
}

/// Compares `actual` with the file `expected`, or writes it when blessing.
fn golden(expected: &Path, actual: &str) {
    if bless() {
        if let Err(e) = std::fs::write(expected, actual) {
            panic!("{}: {e}", expected.display());
        }
        return;
    }
    let want = std::fs::read_to_string(expected)
        .unwrap_or_else(|e| panic!("{}: {e} (run with OOCFMT_BLESS=1)", expected.display()));
    assert_eq!(
        actual,
        want,
        "{} differs from the output",
        expected.display()
    );
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn the_spec_vectors_exist() {
    let v = vectors();
    for name in [
        "quad.oocf",
        "lod-none.oocf",
        "lod-lz4.oocf",
        "lod-zstd.oocf",
    ] {
        assert!(
            v.iter().any(|n| n == name),
            "spec/vectors/{name} is missing"
        );
    }
}

#[test]
fn inspect_json_of_every_vector_matches_its_expected_output() {
    let dir = vectors_dir();
    for name in vectors() {
        let o = oocfmt(&["inspect", "--json", &name], &dir);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        golden(
            &dir.join(name.replace(".oocf", ".inspect.json")),
            &stdout(&o),
        );
    }
}

#[test]
fn the_worked_example_dump_matches_the_spec_file() {
    let dir = vectors_dir();
    let o = oocfmt(&["inspect", "--hexdump", "quad.oocf"], &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = format!("# Annotated dump of `spec/vectors/quad.oocf`\n\nProduced by `oocfmt inspect --hexdump quad.oocf`; a test keeps it current.\n\n```text{}```\n", stdout(&o));
    golden(&dir.join("quad.hex.md"), &text);
}

#[test]
fn every_vector_verifies_deep_with_exit_0() {
    let dir = vectors_dir();
    for name in vectors() {
        for depth in ["--quick", "--deep"] {
            let o = oocfmt(&["verify", depth, "--json", &name], &dir);
            assert_eq!(o.status.code(), Some(0), "{name} {depth}: {}", stdout(&o));
            let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap_or_default();
            assert_eq!(report["schema"], "oocfmt-verify/1");
            assert_eq!(report["valid"], true);
            assert_eq!(report["errors"], 0);
        }
    }
}

#[test]
fn a_flipped_bit_is_reported_with_exit_1_and_a_code() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let mut bytes = std::fs::read(vectors_dir().join("lod-lz4.oocf")).unwrap_or_default();
    assert!(bytes.len() > 200);
    bytes[100] ^= 0x10;
    let path = tmp.path().join("bad.oocf");
    std::fs::write(&path, &bytes).unwrap_or_else(|e| panic!("{e}"));
    let o = oocfmt(&["verify", "--json", "bad.oocf"], tmp.path());
    assert_eq!(o.status.code(), Some(1));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap_or_default();
    assert_eq!(report["valid"], false);
    assert!(report["issues"][0]["code"].is_string(), "{report}");
    let text = oocfmt(&["verify", "bad.oocf"], tmp.path());
    assert!(stdout(&text).contains("INVALID"));
    let inspect = oocfmt(&["inspect", "bad.oocf"], tmp.path());
    assert_eq!(inspect.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&inspect.stderr).contains("bad.oocf"));
}

#[test]
fn usage_and_io_errors_exit_2() {
    let dir = vectors_dir();
    assert_eq!(
        oocfmt(&["verify", "no-such-file.oocf"], &dir).status.code(),
        Some(2)
    );
    assert_eq!(
        oocfmt(&["verify", "--quick", "--deep", "quad.oocf"], &dir)
            .status
            .code(),
        Some(2)
    );
    assert_eq!(
        oocfmt(&["inspect", "--block", "999", "quad.oocf"], &dir)
            .status
            .code(),
        Some(2)
    );
    assert_eq!(oocfmt(&["frobnicate"], &dir).status.code(), Some(2));
    assert_eq!(oocfmt(&["--help"], &dir).status.code(), Some(0));
}

#[test]
fn inspect_block_decodes_every_block_of_every_vector() {
    let dir = vectors_dir();
    for name in vectors() {
        for id in 0.. {
            let o = oocfmt(
                &["inspect", "--json", "--block", &id.to_string(), &name],
                &dir,
            );
            if o.status.code() == Some(2) {
                assert!(id > 0, "{name} has no block 0");
                break;
            }
            assert_eq!(
                o.status.code(),
                Some(0),
                "{name} block {id}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap_or_default();
            assert_eq!(v["id"], id);
        }
    }
}

#[test]
fn the_demo_builds_inspects_and_verifies() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let o = oocfmt(
        &["demo", "--triangles", "20000", "--out", "demo-out"],
        tmp.path(),
    );
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}{}",
        stdout(&o),
        String::from_utf8_lossy(&o.stderr)
    );
    let out = stdout(&o);
    assert!(out.contains("valid"), "{out}");
    assert!(tmp.path().join("demo-out/demo.oocf").is_file());
}
