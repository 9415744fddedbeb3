//! `render --section` end to end: a plane past the model leaves no pixel on it, the flipped
//! plane keeps every one (with the `-x=V` form given as the flag's next word), a plane
//! through the middle keeps some, a pick does not see what is cut away, and a malformed plane
//! is a usage error (exit 2) that says what is wrong.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use crate::common;

use common::*;

/// How many pixels of `render ... --depth-out` hit the model, with `extra` flags.
fn covered(d: &Path, extra: &[&str]) -> usize {
    let mut args = vec![
        "render",
        "mb.oocf",
        "-o",
        "cut.png",
        "--size",
        "64x48",
        "--poe",
        "0",
        "--depth-out",
        "cut.pfm",
    ];
    args.extend_from_slice(extra);
    run_ok(&args, d);
    let pfm = std::fs::read(d.join("cut.pfm")).unwrap();
    let head = b"Pf\n64 48\n-1.0\n".len();
    pfm[head..]
        .chunks_exact(4)
        .filter(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]).is_finite())
        .count()
}

#[test]
fn render_section_cuts_the_model_and_refuses_a_malformed_plane() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    gen(d, "mandelbulb", "4000", "mb.obj");
    run_ok(&["convert", "mb.obj", "-o", "mb.oocf", "--quiet"], d);
    let whole = covered(d, &[]);
    assert!(whole > 200, "{whole} pixels on the model");
    assert_eq!(covered(d, &["--section", "x=1e6"]), 0);
    assert_eq!(covered(d, &["--section", "-x=1e6"]), whole);
    assert_eq!(covered(d, &["--section=0,0,-1e6,0,0,1"]), whole);
    let half = covered(d, &["--section", "0,0,0,1,1,0"]);
    assert!(half > 0 && half != whole, "{half} of {whole}");

    // The middle pixel picked through a plane past the model: nothing there.
    let pick = |extra: &[&str]| {
        let mut args = vec![
            "render", "mb.oocf", "--size", "64x48", "--pick", "32,24", "--json",
        ];
        args.extend_from_slice(extra);
        let o = run_ok(&args, d);
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        v["hit"].clone()
    };
    assert!(pick(&[]).is_object(), "the middle pixel shows the model");
    assert!(pick(&["--section", "y=1e6"]).is_null());

    for (bad, says) in [
        ("w=1", "expected AXIS=VALUE"),
        ("x=abc", "not a finite number"),
        ("1,2,3", "expected AXIS=VALUE or X,Y,Z,NX,NY,NZ"),
        ("0,0,0,0,0,0", "the normal is zero"),
    ] {
        let o = oocfmt(&["render", "mb.oocf", "-o", "x.png", "--section", bad], d);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{bad}: {err}");
        assert!(err.contains(says), "{bad}: {err}");
    }
}
