//! Golden tree statistics: small scenes converted end to end, their `inspect --json` figures
//! (node counts by kind, leaves, depth, LOD levels, voxels, proxies, blocks and bytes per
//! level, triangles, records, vertices) compared with `tests/golden/*.json`.
//!
//! The figures follow from every choice the builder makes, so they change whenever the kd-tree,
//! LOD or layout code changes on purpose. Then check that the new figures are what the change
//! meant, and re-bless: `OOCFMT_BLESS=1 cargo test -p oocfmt-cli --test e2e golden_stats::`.

use crate::common;

use common::*;

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/golden")
}

const REBLESS: &str = "if the builder changed on purpose, check the new figures and re-bless \
                       with `OOCFMT_BLESS=1 cargo test -p oocfmt-cli --test e2e golden_stats::`";

/// Converts `input` (in `dir`) with default options and returns the tree statistics.
fn stats(dir: &Path, input: &str) -> Value {
    run_ok(
        &[
            "convert",
            input,
            "-o",
            "scene.oocf",
            "--quiet",
            "--report-json",
            "report.json",
        ],
        dir,
    );
    let report: Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap_or_default())
            .unwrap_or_else(|e| panic!("report: {e}"));
    let o = run_ok(&["inspect", "--json", "scene.oocf"], dir);
    let s: Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("inspect: {e}"));
    let m = &s["metadata"];
    json!({
        "import": {
            "triangles_in": report["import"]["triangles_in"],
            "triangles_out": report["import"]["triangles_out"],
            "dropped": report["import"]["dropped"],
        },
        "file_length": s["file_length"],
        "block_size": s["block_size"],
        "block_count": s["block_count"],
        "counts": m["counts"],
        "schema": m["schema"],
        "materials": m["materials"].as_array().map_or(0, Vec::len),
        "tree": s["tree"],
        "residency": s["residency"],
        "levels": s["levels"],
    })
}

/// Where `got` differs from `want`, as `path: want → got` lines.
fn differences(want: &Value, got: &Value, path: &str, out: &mut Vec<String>) {
    match (want, got) {
        (Value::Object(w), Value::Object(g)) => {
            for k in w.keys().chain(g.keys().filter(|k| !w.contains_key(*k))) {
                let (a, b) = (
                    w.get(k).unwrap_or(&Value::Null),
                    g.get(k).unwrap_or(&Value::Null),
                );
                differences(a, b, &format!("{path}.{k}"), out);
            }
        }
        (Value::Array(w), Value::Array(g)) if w.len() == g.len() => {
            for (i, (a, b)) in w.iter().zip(g).enumerate() {
                differences(a, b, &format!("{path}[{i}]"), out);
            }
        }
        _ if want != got => out.push(format!("  {path}: {want} → {got}")),
        _ => {}
    }
}

/// Compares `got` with `tests/golden/NAME.json`, or writes it under `OOCFMT_BLESS`.
fn check(name: &str, got: &Value) {
    let path = golden_dir().join(format!("{name}.json"));
    let text = serde_json::to_string_pretty(got).unwrap_or_default() + "\n";
    if std::env::var_os("OOCFMT_BLESS").is_some() {
        std::fs::write(&path, text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        return;
    }
    let want = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e}; write it with `OOCFMT_BLESS=1 cargo test -p oocfmt-cli --test e2e golden_stats::`",
            path.display()
        )
    });
    let want: Value =
        serde_json::from_str(&want).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut diff = Vec::new();
    differences(&want, got, "", &mut diff);
    assert!(
        diff.is_empty(),
        "the tree statistics of scene `{name}` differ from {} (golden → now):\n{}\n{REBLESS}",
        path.display(),
        diff.join("\n")
    );
}

fn generated(scene: &str) {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let obj = format!("{scene}.obj");
    run_ok(
        &[
            "gen", scene, "--tris", "20000", "--seed", "1", "-o", &obj, "--quiet",
        ],
        tmp.path(),
    );
    check(&format!("{scene}-20k"), &stats(tmp.path(), &obj));
}

#[test]
fn generated_mandelbulb_tree_statistics_match_the_golden_file() {
    generated("mandelbulb");
}

#[test]
fn generated_cad_tree_statistics_match_the_golden_file() {
    generated("cad");
}

/// An 8 × 8 field of boxes of three heights in three materials, on a floor.
fn boxes_obj() -> String {
    let mut o = String::from("mtllib boxes.mtl\nv 0 0 0\nv 12 0 0\nv 12 12 0\nv 0 12 0\n");
    o += "usemtl floor\nf 1 2 3 4\n";
    let mut base = 4;
    for by in 0..8 {
        for bx in 0..8 {
            let (x, y) = (0.5 + 1.45 * f64::from(bx), 0.5 + 1.45 * f64::from(by));
            let h = 0.5 + 0.5 * f64::from((bx * by) % 3);
            for (dx, dy, z) in [
                (0.0, 0.0, 0.0),
                (1.0, 0.0, 0.0),
                (1.0, 1.0, 0.0),
                (0.0, 1.0, 0.0),
                (0.0, 0.0, h),
                (1.0, 0.0, h),
                (1.0, 1.0, h),
                (0.0, 1.0, h),
            ] {
                o += &format!("v {} {} {z}\n", x + dx, y + dy);
            }
            let material = ["steel", "paint", "rubber"][(bx + by) as usize % 3];
            o += &format!("usemtl {material}\n");
            // Outward quads: bottom, top, then the four sides.
            for q in [
                [1, 4, 3, 2],
                [5, 6, 7, 8],
                [1, 2, 6, 5],
                [2, 3, 7, 6],
                [3, 4, 8, 7],
                [4, 1, 5, 8],
            ] {
                let [a, b, c, d] = q.map(|k| k + base);
                o += &format!("f {a} {b} {c} {d}\n");
            }
            base += 8;
        }
    }
    o
}

const BOXES_MTL: &str = "newmtl floor\nKd 0.6 0.6 0.6\nnewmtl steel\nKd 0.5 0.55 0.6\n\
                         newmtl paint\nKd 0.1 0.5 0.2\nnewmtl rubber\nKd 0.1 0.1 0.1\n";

#[test]
fn obj_with_materials_tree_statistics_match_the_golden_file() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(tmp.path().join("boxes.obj"), boxes_obj()).unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(tmp.path().join("boxes.mtl"), BOXES_MTL).unwrap_or_else(|e| panic!("{e}"));
    let s = stats(tmp.path(), "boxes.obj");
    assert_eq!(s["import"]["triangles_out"], 2 + 64 * 12, "{s}");
    assert_eq!(s["materials"], 4, "{s}");
    check("obj-boxes", &s);
}

/// A unit cube (8 corners, 12 triangles, indexed) placed by a tree of nodes: a rotated root
/// over a 3 × 3 × 2 grid of translated, rotated and scaled instances, one of them mirrored,
/// and a chain of two nested nodes.
fn nodes_gltf() -> (String, Vec<u8>) {
    let mut bin = Vec::new();
    for i in 0..8u8 {
        for axis in 0..3 {
            let c = if i >> axis & 1 == 1 { 1.0f32 } else { 0.0 };
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let faces: [[u16; 3]; 12] = [
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    for i in faces.iter().flatten() {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let mut nodes = vec![json!({
        "rotation": [0.0, 0.0, 0.258_819_04, 0.965_925_8],
        "children": (1..=19).collect::<Vec<u32>>(),
    })];
    for k in 0..2 {
        for j in 0..3 {
            for i in 0..3 {
                let n = nodes.len();
                let s = 0.5 + 0.25 * f64::from((i + j + k) % 3);
                let scale = if n == 5 { [-s, s, s] } else { [s, s, 1.5 * s] };
                let angle = 0.3 * f64::from(i * 3 + j) / 2.0;
                nodes.push(json!({
                    "mesh": 0,
                    "translation": [2.5 * f64::from(i), 2.5 * f64::from(j), 3.0 * f64::from(k)],
                    "rotation": [angle.sin(), 0.0, 0.0, angle.cos()],
                    "scale": scale,
                }));
            }
        }
    }
    nodes.push(json!({"translation": [-4.0, 0.0, 0.0], "children": [20]}));
    nodes.push(json!({"mesh": 0, "translation": [0.0, -4.0, 1.0], "scale": [2.0, 0.5, 0.5]}));
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{"name": "orange", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.5, 0.1, 1.0]}}],
        "buffers": [{"byteLength": bin.len(), "uri": "nodes.bin"}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 96},
            {"buffer": 0, "byteOffset": 96, "byteLength": 72}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 1.0]},
            {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}
        ]
    });
    (doc.to_string(), bin)
}

#[test]
fn gltf_with_node_transforms_tree_statistics_match_the_golden_file() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let (doc, bin) = nodes_gltf();
    std::fs::write(tmp.path().join("nodes.gltf"), doc).unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(tmp.path().join("nodes.bin"), bin).unwrap_or_else(|e| panic!("{e}"));
    let s = stats(tmp.path(), "nodes.gltf");
    // 18 grid instances and the nested one.
    assert_eq!(s["import"]["triangles_out"], 19 * 12, "{s}");
    check("gltf-nodes", &s);
}
