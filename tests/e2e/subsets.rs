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

/// Six OBJ files side by side along x in `dir`; `bump` moves file 4's vertices in depth.
fn row_of_parts(dir: &std::path::Path, bump: u32) -> Vec<String> {
    (0..6)
        .map(|f| {
            let mut text = String::new();
            for k in 0..400u32 {
                let x = f as f32 * 2.0 + (k % 40) as f32 * 0.04;
                let y = (k / 40) as f32 * 0.1;
                let z = ((k + if f == 4 { bump } else { 0 }) % 5) as f32 * 0.1;
                text += &format!(
                    "v {x} {y} {z}\nv {} {y} 0.2\nv {x} {} 0.1\n",
                    x + 0.05,
                    y + 0.08
                );
            }
            for k in 0..400 {
                text += &format!("f {} {} {}\n", 3 * k + 1, 3 * k + 2, 3 * k + 3);
            }
            let name = format!("p{f}.obj");
            std::fs::write(dir.join(&name), text).unwrap_or_else(|e| panic!("{e}"));
            name
        })
        .collect()
}

#[test]
fn an_updated_plan_rebuilds_what_changed_and_merges_to_a_full_rebuild() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let d = dir.path();
    let files = row_of_parts(d, 0);
    let mut args = vec!["plan"];
    args.extend(files.iter().map(String::as_str));
    args.extend([
        "--subsets",
        "8",
        "--mem-limit",
        "16M",
        "-o",
        "old.json",
        "--quiet",
    ]);
    run_ok(&args, d);
    for i in 0..8 {
        let (i, part) = (i.to_string(), format!("old-{i}.oocfp"));
        run_ok(
            &[
                "convert", "--plan", "old.json", "--subset", &i, "-o", &part, "--quiet",
            ],
            d,
        );
    }
    row_of_parts(d, 2);
    let o = run_ok(
        &[
            "plan", "--update", "old.json", "-o", "new.json", "--json", "--quiet",
        ],
        d,
    );
    let report: serde_json::Value =
        serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("plan --update: {e}"));
    let rebuild: Vec<u64> = report["rebuild"]
        .as_array()
        .map(|a| a.iter().filter_map(|v| v.as_u64()).collect())
        .unwrap_or_default();
    assert!(!rebuild.is_empty() && rebuild.len() < 8, "{report}");
    let mut parts = Vec::new();
    for i in 0..8u64 {
        let part = match rebuild.contains(&i) {
            true => {
                let part = format!("new-{i}.oocfp");
                let i = i.to_string();
                run_ok(
                    &[
                        "convert", "--plan", "new.json", "--subset", &i, "-o", &part, "--quiet",
                    ],
                    d,
                );
                part
            }
            false => format!("old-{i}.oocfp"),
        };
        parts.push(part);
    }
    let mut args = vec![
        "merge",
        "--plan",
        "new.json",
        "-o",
        "updated.oocf",
        "--quiet",
    ];
    args.extend(parts.iter().map(String::as_str));
    run_ok(&args, d);
    run_ok(
        &[
            "convert",
            "--plan",
            "new.json",
            "-o",
            "full.oocf",
            "--quiet",
        ],
        d,
    );
    let (a, b) = (
        std::fs::read(d.join("updated.oocf")),
        std::fs::read(d.join("full.oocf")),
    );
    assert!(
        a.is_ok() && a.ok() == b.ok(),
        "the update differs from a full rebuild"
    );
    let o = oocfmt(
        &[
            "plan", "--update", "old.json", "--lod", "voxel", "-o", "x.json",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(2));
}
