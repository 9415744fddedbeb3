//! What the end-to-end test binaries share: running the `oocfmt` binary and reading its output.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs the `oocfmt` binary built for this test with `args` in `cwd`.
pub fn oocfmt(args: &[&str], cwd: &Path) -> Output {
    match Command::new(env!("CARGO_BIN_EXE_oocfmt"))
        .args(args)
        .current_dir(cwd)
        .output()
    {
        Ok(o) => o,
        Err(e) => panic!("cannot run oocfmt: {e}"),
    }
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Asserts that `o` exited with 0, showing its output otherwise.
pub fn ok(o: &Output, what: &str) {
    assert_eq!(
        o.status.code(),
        Some(0),
        "{what}: {}{}",
        stdout(o),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Runs `oocfmt ARGS` in `cwd` and asserts success.
pub fn run_ok(args: &[&str], cwd: &Path) -> Output {
    let o = oocfmt(args, cwd);
    ok(&o, &format!("oocfmt {args:?}"));
    o
}

/// Runs `oocfmt convert ARGS --quiet --report-json report.json` in `dir`, asserts success and
/// returns the report.
pub fn convert_ok(dir: &Path, args: &[&str]) -> serde_json::Value {
    let mut all = vec!["convert"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--quiet", "--report-json", "report.json"]);
    ok(&oocfmt(&all, dir), &format!("convert {args:?}"));
    let bytes = std::fs::read(dir.join("report.json")).unwrap_or_default();
    serde_json::from_slice(&bytes).unwrap_or_else(|e| panic!("{args:?}: report: {e}"))
}

/// `oocfmt gen SCENE --tris N -o OUT` in `dir`.
pub fn gen(dir: &Path, scene: &str, tris: &str, out: &str) {
    run_ok(&["gen", scene, "--tris", tris, "-o", out, "--quiet"], dir);
}
