//! Parts in `render` and `inspect` end to end: `inspect --parts` prints the tree (and JSON of
//! schema `oocfmt-parts/1` whose counts add up), `render --hide/--isolate/--highlight` accept
//! globs that match and refuse, with exit 2, globs that match nothing and any glob on a file
//! without parts; `render --pick X,Y --json` prints the part a pixel shows (schema
//! `oocfmt-pick/1`) and renders nothing without `--output`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use crate::common;

use common::*;

/// A small CAD assembly with parts, and a Mandelbulb without.
fn converted(d: &Path) {
    run_ok(
        &[
            "gen", "cad", "--tris", "20000", "--parts", "40", "-o", "cad.obj", "--quiet",
        ],
        d,
    );
    run_ok(&["convert", "cad.obj", "-o", "cad.oocf", "--quiet"], d);
    gen(d, "mandelbulb", "2000", "mb.obj");
    run_ok(&["convert", "mb.obj", "-o", "mb.oocf", "--quiet"], d);
}

fn json(o: &std::process::Output) -> serde_json::Value {
    serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&o.stdout)))
}

fn fails_with_usage(args: &[&str], d: &Path, says: &str) {
    let o = oocfmt(args, d);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(says), "{args:?}: {err}");
}

#[test]
fn parts_are_listed_chosen_and_picked() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    converted(d);

    // The tree, for people and as JSON.
    let text = stdout(&run_ok(&["inspect", "--parts", "cad.oocf"], d));
    assert!(text.starts_with("parts "), "{text}");
    assert!(text.contains("assembly-"), "{text}");
    let tree = json(&run_ok(&["inspect", "--parts", "--json", "cad.oocf"], d));
    assert_eq!(tree["schema"], "oocfmt-parts/1");
    let parts = tree["parts"].as_array().unwrap();
    assert!(parts.len() >= 10, "{} parts", parts.len());
    let sum = |key: &str, top: bool| -> u64 {
        parts
            .iter()
            .filter(|p| !top || p["parent"].is_null())
            .map(|p| p[key].as_u64().unwrap())
            .sum()
    };
    assert_eq!(sum("triangles", false), 20000);
    assert_eq!(sum("subtree_triangles", true), 20000);
    let top = parts.iter().find(|p| p["parent"].is_null()).unwrap();
    let name = top["name"].as_str().unwrap().to_string();
    let child = parts
        .iter()
        .find(|p| p["parent"] == top["id"])
        .unwrap_or(top);
    assert_eq!(
        child["path"].as_str().unwrap(),
        if child == top {
            name.clone()
        } else {
            format!("{name}/{}", child["name"].as_str().unwrap())
        }
    );

    // Globs that match render; the line says what they chose.
    let o = run_ok(
        &[
            "render",
            "cad.oocf",
            "-o",
            "hidden.png",
            "--size",
            "48x32",
            "--hide",
            &name,
            "--highlight",
            "*-1?",
            "--cache",
            "blocking",
        ],
        d,
    );
    let out = stdout(&o);
    assert!(out.contains(&format!("of {} hidden", parts.len())), "{out}");
    assert!(d.join("hidden.png").exists());
    // A path glob and isolate.
    let path = child["path"].as_str().unwrap();
    run_ok(
        &[
            "render",
            "cad.oocf",
            "-o",
            "iso.png",
            "--size",
            "48x32",
            "--isolate",
            path,
        ],
        d,
    );
    fails_with_usage(
        &[
            "render",
            "cad.oocf",
            "-o",
            "x.png",
            "--hide",
            "no-such-part",
        ],
        d,
        &format!("matches none of the file's {} part names", parts.len()),
    );
    // A near miss is suggested.
    let typo = name.to_uppercase();
    fails_with_usage(
        &["render", "cad.oocf", "-o", "x.png", "--hide", &typo],
        d,
        &format!("close: {name}"),
    );
    fails_with_usage(
        &["render", "cad.oocf", "-o", "x.png", "--hide", "[bad"],
        d,
        "not a glob",
    );

    // A pick of the middle of the default view: a part, at full detail, and no image.
    let pick = json(&run_ok(
        &[
            "render", "cad.oocf", "--size", "48x32", "--pick", "24,16", "--poe", "0", "--json",
        ],
        d,
    ));
    assert_eq!(pick["schema"], "oocfmt-pick/1");
    assert_eq!(pick["pixel"], serde_json::json!([24, 16]));
    let hit = &pick["hit"];
    assert!(hit.is_object(), "{pick}");
    assert_eq!(hit["lod"], false);
    let id = hit["part"].as_u64().unwrap() as usize;
    assert_eq!(hit["part_name"], parts[id]["name"]);
    assert_eq!(hit["part_path"], parts[id]["path"]);
    assert!(hit["triangle"]["block"].is_u64() && hit["triangle"]["index"].is_u64());
    assert!(hit["distance"].as_f64().unwrap() > 0.0);
    // Hiding the picked part picks something else there, or nothing.
    let picked = hit["part_path"].as_str().unwrap().to_string();
    let again = json(&run_ok(
        &[
            "render", "cad.oocf", "--size", "48x32", "--pick", "24,16", "--poe", "0", "--json",
            "--hide", &picked,
        ],
        d,
    ));
    assert_ne!(again["hit"]["part_path"].as_str(), Some(picked.as_str()));
    // The line for people, after the frame with --output.
    let o = run_ok(
        &[
            "render", "cad.oocf", "-o", "p.png", "--size", "48x32", "--pick", "0,0",
        ],
        d,
    );
    let out = stdout(&o);
    assert!(
        out.contains("wrote p.png") && out.contains("pick 0,0"),
        "{out}"
    );
    assert!(d.join("p.png").exists());
    fails_with_usage(
        &["render", "cad.oocf", "--pick", "48,0", "--size", "48x32"],
        d,
        "outside the 48x32 image",
    );
    fails_with_usage(
        &["render", "cad.oocf", "--json", "-o", "x.png"],
        d,
        "--pick",
    );
    fails_with_usage(&["render", "cad.oocf"], d, "--output");
    fails_with_usage(
        &[
            "render", "cad.oocf", "--pick", "1,1", "--path", "p.json", "-o", "x.png",
        ],
        d,
        "--path",
    );
}

#[test]
fn a_file_without_parts_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    gen(d, "mandelbulb", "2000", "mb.obj");
    run_ok(&["convert", "mb.obj", "-o", "mb.oocf", "--quiet"], d);
    let text = stdout(&run_ok(&["inspect", "--parts", "mb.oocf"], d));
    assert!(text.starts_with("no parts"), "{text}");
    let tree = json(&run_ok(&["inspect", "--parts", "--json", "mb.oocf"], d));
    assert_eq!(tree["parts"], serde_json::json!([]));
    for flag in ["--hide", "--isolate", "--highlight"] {
        fails_with_usage(
            &["render", "mb.oocf", "-o", "x.png", flag, "*"],
            d,
            "the file has no parts",
        );
    }
    let pick = json(&run_ok(
        &[
            "render", "mb.oocf", "--size", "32x24", "--pick", "16,12", "--json",
        ],
        d,
    ));
    assert!(pick["hit"].is_object(), "{pick}");
    assert!(pick["hit"]["part"].is_null());
}
