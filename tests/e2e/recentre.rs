//! End-to-end tests of `oocfmt convert --recentre`: models far from zero keep their precision
//! through convert and export, the error the report gives bounds what export gives back, and
//! without re-centring positions stay bit-exact.

use crate::common;

use common::*;

use std::collections::{BTreeSet, HashMap};
use std::path::Path;

fn inspect(dir: &Path, file: &str) -> serde_json::Value {
    let o = oocfmt(&["inspect", "--json", file], dir);
    ok(&o, "inspect");
    serde_json::from_slice(&o.stdout).unwrap_or_default()
}

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("{v} is not a number"))
}

/// Where the far model sits: an aircraft part in plant coordinates, where f32 positions are
/// 0.25 to 1 unit apart.
const FAR: [f64; 3] = [10_000_000.0, -3_500_000.0, 200_000.0];

/// A jittered 24 × 24 grid of quads, 0.37 units apart, around [`FAR`], as OBJ text whose
/// numbers are exact f64 values (Rust prints the shortest text that parses back).
fn far_grid() -> (String, Vec<[f64; 3]>) {
    far_grid_of(24)
}

/// The same with `n` × `n` quads.
fn far_grid_of(n: usize) -> (String, Vec<[f64; 3]>) {
    let mut text = String::from("# a plate far from zero\n");
    let mut v = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let jitter = |k: usize| ((i * 7919 + j * 104_729 + k * 31) % 1000) as f64 * 1e-5;
            let p = [
                FAR[0] + 0.37 * i as f64 + jitter(0),
                FAR[1] + 0.37 * j as f64 + jitter(1),
                FAR[2] + 0.011 * (i + j) as f64 + jitter(2),
            ];
            text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
            v.push(p);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i + 1;
            text += &format!(
                "f {} {} {}\nf {} {} {}\n",
                a,
                a + 1,
                a + n + 2,
                a,
                a + n + 2,
                a + n + 1
            );
        }
    }
    (text, v)
}

/// The vertices (f64, as written) and triangles (vertex numbers from 0) of an OBJ file.
fn read_obj(path: &Path) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut v = Vec::new();
    let mut f = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f64> = it.take(3).map(|x| x.parse().unwrap_or(f64::NAN)).collect();
                v.push([c[0], c[1], c[2]]);
            }
            Some("f") => {
                let idx: Vec<usize> = it
                    .map(|c| {
                        c.split('/')
                            .next()
                            .and_then(|i| i.parse::<usize>().ok())
                            .unwrap_or(0)
                    })
                    .collect();
                assert_eq!(idx.len(), 3, "{line}");
                f.push([idx[0] - 1, idx[1] - 1, idx[2] - 1]);
            }
            _ => {}
        }
    }
    (v, f)
}

/// The input vertex nearest `p` and the largest per-axis difference to it.
fn nearest(input: &[[f64; 3]], p: [f64; 3]) -> (usize, f64) {
    let far = |q: &[f64; 3]| (0..3).map(|a| (q[a] - p[a]).abs()).fold(0.0, f64::max);
    input
        .iter()
        .enumerate()
        .map(|(i, q)| (i, far(q)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((usize::MAX, f64::INFINITY))
}

/// A triangle as its sorted corner numbers.
fn key(t: [usize; 3]) -> [usize; 3] {
    let mut k = t;
    k.sort_unstable();
    k
}

#[test]
fn recentre_auto_keeps_far_coordinates_and_export_is_within_the_reported_error() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (text, input) = far_grid();
    std::fs::write(tmp.path().join("far.obj"), &text).unwrap_or_else(|e| panic!("{e}"));
    let (_, input_faces) = read_obj(&tmp.path().join("far.obj"));

    let report = convert_ok(
        tmp.path(),
        &["far.obj", "-o", "auto.oocf", "--recentre", "auto"],
    );
    let placement = &report["import"]["placement"];
    let error = num(&placement["max_abs_error"]);
    let without = num(&placement["max_abs_error_without_origin"]);
    // The plate spans 8.9 units: stored offsets stay under 8, where f32 steps are 2^-21.
    assert!(error > 0.0 && error <= 2f64.powi(-22), "{report}");
    // At 1e7 f32 steps are 1 unit: about half of one is lost without an origin.
    assert!(without > 0.3 && without <= 0.5, "{report}");
    assert_eq!(
        report["import"]["dropped"],
        serde_json::json!({}),
        "{report}"
    );
    let origin: Vec<f64> = (0..3).map(|a| num(&placement["origin"][a])).collect();
    for a in 0..3 {
        assert!((origin[a] - FAR[a]).abs() < 8.0, "{origin:?}");
    }

    let meta = inspect(tmp.path(), "auto.oocf")["metadata"].clone();
    assert_eq!(meta["scene"]["origin"], placement["origin"], "{meta}");
    let params = meta["build"]["params"].to_string();
    assert!(
        params.contains(r#"["recentre","auto"]"#) && params.contains(r#"["origin","#),
        "{params}"
    );
    ok(
        &oocfmt(&["verify", "--deep", "auto.oocf"], tmp.path()),
        "verify",
    );

    ok(
        &oocfmt(
            &["export", "auto.oocf", "-o", "back.obj", "--quiet"],
            tmp.path(),
        ),
        "export",
    );
    let (back, faces) = read_obj(&tmp.path().join("back.obj"));
    // Every exported vertex is an input vertex, to within the reported error, and the
    // triangles are the input's.
    let mut to_input = HashMap::new();
    let mut worst = 0.0f64;
    for (k, &p) in back.iter().enumerate() {
        let (i, d) = nearest(&input, p);
        assert!(
            d <= error,
            "vertex {p:?} is {d} from input {i}, over {error}"
        );
        worst = worst.max(d);
        to_input.insert(k, i);
    }
    // The report's figure is exactly the largest difference export gives back.
    assert_eq!(worst, error);
    let want: BTreeSet<[usize; 3]> = input_faces.into_iter().map(key).collect();
    let got: BTreeSet<[usize; 3]> = faces
        .iter()
        .map(|t| key(t.map(|k| to_input.get(&k).copied().unwrap_or(usize::MAX))))
        .collect();
    assert_eq!(faces.len(), want.len());
    assert_eq!(got, want);
}

#[test]
fn without_recentring_far_coordinates_are_stored_bit_exact_and_lose_what_f32_loses() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (text, _) = far_grid();
    std::fs::write(tmp.path().join("far.obj"), &text).unwrap_or_else(|e| panic!("{e}"));
    let default = convert_ok(tmp.path(), &["far.obj", "-o", "default.oocf"]);
    let none = convert_ok(
        tmp.path(),
        &["far.obj", "-o", "none.oocf", "--recentre", "none"],
    );
    let p = &none["import"]["placement"];
    assert_eq!(p["origin"], serde_json::json!([0.0, 0.0, 0.0]), "{none}");
    assert_eq!(p["max_abs_error"], p["max_abs_error_without_origin"]);
    assert!(num(&p["max_abs_error"]) > 0.3, "{none}");
    assert_eq!(default["import"], none["import"]);
    // Rounded to f32 at 1e7, neighbouring vertices 0.37 apart merge: triangles collapse.
    let dropped = none["import"]["dropped"]
        .as_object()
        .map(|d| {
            d.values()
                .filter_map(serde_json::Value::as_u64)
                .sum::<u64>()
        })
        .unwrap_or(0);
    assert!(dropped > 0, "{none}");
    // The default writes the same file as `none`, with no re-centring parameters.
    assert_eq!(
        std::fs::read(tmp.path().join("default.oocf")).unwrap_or_default(),
        std::fs::read(tmp.path().join("none.oocf")).unwrap_or_default()
    );
    let meta = inspect(tmp.path(), "none.oocf")["metadata"].clone();
    assert!(!meta["build"]["params"].to_string().contains("recentre"));

    ok(
        &oocfmt(
            &["export", "none.oocf", "-o", "back.obj", "--quiet"],
            tmp.path(),
        ),
        "export",
    );
    let (_, faces) = read_obj(&tmp.path().join("back.obj"));
    assert_eq!(faces.len() as u64 + dropped, 2 * 24 * 24);
    // Bit-exact: every exported position is an input position read as f32.
    let stored = f32_vertices(&text);
    let back = std::fs::read_to_string(tmp.path().join("back.obj")).unwrap_or_default();
    let back = f32_vertices(&back);
    assert!(!back.is_empty());
    for p in &back {
        assert!(stored.contains(p), "{p:?} is no input vertex");
    }
}

/// The positions of OBJ text read as f32, as bit patterns.
fn f32_vertices(text: &str) -> BTreeSet<[u32; 3]> {
    text.lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<u32> = l
                .split_whitespace()
                .take(3)
                .map(|x| x.parse::<f32>().unwrap_or(f32::NAN).to_bits())
                .collect();
            [c[0], c[1], c[2]]
        })
        .collect()
}

/// One quad (two triangles) under a node 1e7 units out, whose child node moves it by a
/// fraction: only f64 composition keeps the fraction.
const FAR_GLTF: &str = r#"{"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"children": [1], "translation": [10000000, -3500000, 0]}, {"mesh": 0, "translation": [0.125, 0.375, 0.0625]}], "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}], "buffers": [{"byteLength": 60, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAACAPwAAgD8AAAAAAAABAAIAAQADAAIA"}], "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 12}], "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}, {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}]}"#;

#[test]
fn gltf_node_transforms_are_recentred_in_f64() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(tmp.path().join("far.gltf"), FAR_GLTF).unwrap_or_else(|e| panic!("{e}"));
    let auto = convert_ok(
        tmp.path(),
        &["far.gltf", "-o", "auto.oocf", "--recentre", "auto"],
    );
    let p = &auto["import"]["placement"];
    // The quad's corners are short binary fractions: relative to a nearby origin they are
    // exact in f32. At 1e7 they are not.
    assert_eq!(num(&p["max_abs_error"]), 0.0, "{auto}");
    assert!(num(&p["max_abs_error_without_origin"]) >= 0.125, "{auto}");
    ok(
        &oocfmt(
            &["export", "auto.oocf", "-o", "back.obj", "--quiet"],
            tmp.path(),
        ),
        "export",
    );
    let (back, faces) = read_obj(&tmp.path().join("back.obj"));
    assert_eq!(faces.len(), 2);
    let want: BTreeSet<[u64; 3]> = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]
        .iter()
        .map(|[x, y]| [10_000_000.125 + x, -3_500_000.0 + 0.375 + y, 0.0625].map(f64::to_bits))
        .collect();
    let got: BTreeSet<[u64; 3]> = back.iter().map(|q| q.map(f64::to_bits)).collect();
    assert_eq!(got, want);
}

#[test]
fn an_explicit_origin_is_recorded_and_bad_values_are_refused_by_the_command_line() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (text, _) = far_grid();
    std::fs::write(tmp.path().join("far.obj"), &text).unwrap_or_else(|e| panic!("{e}"));
    let r = convert_ok(
        tmp.path(),
        &[
            "far.obj",
            "-o",
            "at.oocf",
            "--recentre",
            "10000002,-3499996,200000",
        ],
    );
    assert_eq!(
        r["import"]["placement"]["origin"],
        serde_json::json!([10_000_002.0, -3_499_996.0, 200_000.0])
    );
    assert!(
        num(&r["import"]["placement"]["max_abs_error"]) < 1e-6,
        "{r}"
    );
    let meta = inspect(tmp.path(), "at.oocf")["metadata"].clone();
    assert_eq!(
        meta["scene"]["origin"],
        serde_json::json!([10_000_002.0, -3_499_996.0, 200_000.0])
    );
    // A negative first number is a value, not an option.
    convert_ok(
        tmp.path(),
        &["far.obj", "-o", "neg.oocf", "--recentre", "-1e7,0,0"],
    );

    for (bad, why) in [
        ("centre", "expected auto, none or X,Y,Z"),
        ("1,2", "expected auto, none or X,Y,Z"),
        ("1,2,3,4", "expected auto, none or X,Y,Z"),
        ("1,x,3", "`x` is not a number"),
        ("nan,0,0", "`nan` is not finite"),
        ("0,inf,0", "`inf` is not finite"),
        ("0,0,-infinity", "`-infinity` is not finite"),
        ("1e400,0,0", "`1e400` is not finite"),
    ] {
        let o = oocfmt(
            &["convert", "far.obj", "-o", "bad.oocf", "--recentre", bad],
            tmp.path(),
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{bad}: {err}");
        assert!(
            err.contains("--recentre") && err.contains(why),
            "{bad}: {err}"
        );
        assert!(!tmp.path().join("bad.oocf").exists());
    }
}

#[test]
fn the_out_of_core_build_keeps_the_origin_too() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    // 2 × 90 × 90 = 16 200 triangles: over what a 16 MiB build holds in core.
    let (text, input) = far_grid_of(90);
    std::fs::write(tmp.path().join("far.obj"), &text).unwrap_or_else(|e| panic!("{e}"));
    let report = convert_ok(
        tmp.path(),
        &[
            "far.obj",
            "-o",
            "ooc.oocf",
            "--recentre",
            "auto",
            "--mem-limit",
            "16M",
        ],
    );
    assert!(report["out_of_core"].is_object(), "{report}");
    let placement = &report["import"]["placement"];
    let error = num(&placement["max_abs_error"]);
    assert!(error > 0.0 && error < 1e-5, "{report}");
    let meta = inspect(tmp.path(), "ooc.oocf")["metadata"].clone();
    assert_eq!(meta["scene"]["origin"], placement["origin"], "{meta}");
    assert!(meta["build"]["params"]
        .to_string()
        .contains(r#"["recentre","auto"]"#));
    ok(
        &oocfmt(&["verify", "--deep", "ooc.oocf"], tmp.path()),
        "verify",
    );
    ok(
        &oocfmt(
            &["export", "ooc.oocf", "-o", "back.obj", "--quiet"],
            tmp.path(),
        ),
        "export",
    );
    let (back, faces) = read_obj(&tmp.path().join("back.obj"));
    assert_eq!(faces.len(), 2 * 90 * 90);
    // Each exported vertex is the grid vertex it rounds to, within the reported error.
    let mut worst = 0.0f64;
    for p in &back {
        let i = ((p[0] - FAR[0]) / 0.37).round() as usize;
        let j = ((p[1] - FAR[1]) / 0.37).round() as usize;
        let q = input[j * 91 + i];
        let d = (0..3).map(|a| (q[a] - p[a]).abs()).fold(0.0, f64::max);
        assert!(d <= error, "{p:?} is {d} from {q:?}, over {error}");
        worst = worst.max(d);
    }
    assert_eq!(worst, error);
}
