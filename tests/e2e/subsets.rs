//! A build split into subsets through the binary: `plan`, `convert --plan --subset`, `merge`
//! give the bytes of `convert --plan`; `verify` checks a subset file and finds a damaged one;
//! build flags beside `--plan`, a missing subset and standard input are refused with exit 2.

use crate::common;

use common::*;

#[test]
fn plan_subsets_and_merge_through_the_binary() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let d = dir.path();
    gen(d, "mandelbulb", "30000", "m.obj");
    let o = run_ok(
        &[
            "plan",
            "m.obj",
            "--subsets",
            "3",
            "--mem-limit",
            "16M",
            "-o",
            "plan.json",
            "--json",
            "--quiet",
        ],
        d,
    );
    let report: serde_json::Value =
        serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("plan --json: {e}"));
    assert_eq!(report["subsets"], 3, "{report}");
    let plan: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("plan.json")).unwrap_or_default())
            .unwrap_or_else(|e| panic!("plan.json: {e}"));
    assert_eq!(plan["format"], "oocfmt-plan");
    for i in ["0", "1", "2"] {
        let part = format!("part-{i}.oocfp");
        run_ok(
            &[
                "convert",
                "--plan",
                "plan.json",
                "--subset",
                i,
                "-o",
                &part,
                "--quiet",
            ],
            d,
        );
        let o = run_ok(&["verify", &part], d);
        assert!(stdout(&o).contains("valid subset file"), "{}", stdout(&o));
    }
    let o = run_ok(
        &[
            "merge",
            "part-2.oocfp",
            "part-0.oocfp",
            "part-1.oocfp",
            "-o",
            "merged.oocf",
            "--quiet",
        ],
        d,
    );
    assert!(
        stdout(&o).contains("merged     3 subsets"),
        "{}",
        stdout(&o)
    );
    let report = convert_ok(d, &["--plan", "plan.json", "-o", "single.oocf"]);
    assert_eq!(report["import"]["triangles_in"], report["triangles_stored"]);
    let (a, b) = (
        std::fs::read(d.join("merged.oocf")),
        std::fs::read(d.join("single.oocf")),
    );
    assert!(
        a.is_ok() && a.ok() == b.ok(),
        "merge and convert --plan differ"
    );
    run_ok(&["verify", "--deep", "merged.oocf"], d);

    // A damaged subset file: verify says so (exit 1), and so does the merge, writing nothing.
    let mut bytes = std::fs::read(d.join("part-1.oocfp")).unwrap_or_default();
    if let Some(b) = bytes.get_mut(200) {
        *b ^= 1;
    }
    std::fs::write(d.join("bad.oocfp"), &bytes).unwrap_or_else(|e| panic!("{e}"));
    let o = oocfmt(&["verify", "bad.oocfp"], d);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(
        stdout(&o).contains("block checksum mismatch"),
        "{}",
        stdout(&o)
    );
    let o = oocfmt(
        &[
            "merge",
            "part-0.oocfp",
            "bad.oocfp",
            "part-2.oocfp",
            "-o",
            "x.oocf",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(!d.join("x.oocf").exists());

    // A subset missing; build flags beside --plan; standard input planned.
    let o = oocfmt(
        &["merge", "part-0.oocfp", "part-2.oocfp", "-o", "x.oocf"],
        d,
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("missing subsets 1 of 3"));
    let o = oocfmt(
        &[
            "convert",
            "--plan",
            "plan.json",
            "--lod",
            "voxel",
            "-o",
            "x.oocf",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(2));
    let o = oocfmt(&["plan", "-", "--subsets", "2", "-o", "p.json"], d);
    assert_eq!(o.status.code(), Some(2));
    assert!(!d.join("x.oocf").exists() && !d.join("p.json").exists());
}
