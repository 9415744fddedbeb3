//! End-to-end tests of the `oocfmt` binary: spec vectors against their expected `inspect --json`,
//! exit codes, verify reports, and the demo. Set OOCFMT_BLESS=1 to rewrite expected outputs.

use crate::common;

use common::*;

use std::path::{Path, PathBuf};

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
fn the_demo_generates_converts_verifies_and_renders() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let o = run_ok(
        &[
            "demo",
            "--triangles",
            "20000",
            "--width",
            "64",
            "--out",
            "demo-out",
        ],
        tmp.path(),
    );
    let out = stdout(&o);
    assert!(out.contains("valid (0 errors"), "{out}");
    assert!(out.contains("PSNR"), "{out}");
    let dir = tmp.path().join("demo-out");
    for f in [
        "mandelbulb.obj",
        "mandelbulb.oocf",
        "mandelbulb-poe0.png",
        "mandelbulb-poe2.png",
    ] {
        assert!(dir.join(f).is_file(), "{f} missing: {out}");
    }
    // A LOD of zero pixels would be the full-detail image again: refused.
    let bad = oocfmt(&["demo", "--poe", "0", "--out", "x"], tmp.path());
    assert_eq!(bad.status.code(), Some(2));
}

/// A small OBJ scene: a floor quad and a concave L-shaped panel with a material library,
/// vertex colours on the panel, a degenerate face, a NaN vertex, a line and a point.
const SCENE_OBJ: &str = "mtllib scene.mtl
o floor
v 0 0 0
v 4 0 0
v 4 4 0
v 0 4 0
usemtl grey
f 1 2 3 4
o panel
v 0 0 1 1 0 0
v 2 0 1 1 0 0
v 2 1 1 1 0 0
v 1 1 1 1 0 0
v 1 2 1 1 0 0
v 0 2 1 1 0 0
usemtl red
f -6 -5 -4 -3 -2 -1
f 5 5 6
v nan 0 0
f 11 1 2
l 1 2 3
p 4
";

const SCENE_MTL: &str = "newmtl grey\nKd 0.5 0.5 0.5\nnewmtl red\nKd 0.9 0.1 0.1\n";

fn scene_dir() -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(tmp.path().join("scene.obj"), SCENE_OBJ).unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(tmp.path().join("scene.mtl"), SCENE_MTL).unwrap_or_else(|e| panic!("{e}"));
    tmp
}

#[test]
fn convert_obj_reports_drops_verifies_and_round_trips_through_export() {
    let tmp = scene_dir();
    let report = convert_ok(tmp.path(), &["scene.obj", "-o", "scene.oocf"]);
    // 2 floor + 4 panel triangles kept; one zero-area and one NaN triangle dropped.
    assert_eq!(report["import"]["triangles_in"], 8, "{report}");
    assert_eq!(report["import"]["triangles_out"], 6, "{report}");
    assert_eq!(report["import"]["dropped"]["zero_area"], 1, "{report}");
    assert_eq!(report["import"]["dropped"]["non_finite"], 1, "{report}");
    assert_eq!(report["import"]["skipped"]["lines"], 2, "{report}");
    assert_eq!(report["import"]["skipped"]["points"], 1, "{report}");
    assert_eq!(report["triangles_stored"], 6, "{report}");
    let v = oocfmt(&["verify", "--deep", "scene.oocf"], tmp.path());
    assert_eq!(v.status.code(), Some(0), "{}", stdout(&v));
    let e = oocfmt(&["export", "scene.oocf", "-o", "back.obj"], tmp.path());
    assert_eq!(
        e.status.code(),
        Some(0),
        "{}{}",
        stdout(&e),
        String::from_utf8_lossy(&e.stderr)
    );
    let back = std::fs::read_to_string(tmp.path().join("back.obj")).unwrap_or_default();
    assert_eq!(
        back.lines().filter(|l| l.starts_with("f ")).count(),
        6,
        "{back}"
    );
}

#[test]
fn strict_convert_fails_with_the_line_and_leaves_an_existing_output_alone() {
    let tmp = scene_dir();
    std::fs::write(tmp.path().join("scene.oocf"), b"precious").unwrap_or_else(|e| panic!("{e}"));
    let o = oocfmt(
        &[
            "convert",
            "scene.obj",
            "-o",
            "scene.oocf",
            "--strict",
            "--quiet",
        ],
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("scene.obj:18"), "{err}");
    assert_eq!(
        std::fs::read(tmp.path().join("scene.oocf")).unwrap_or_default(),
        b"precious"
    );
    let leftovers: Vec<String> = std::fs::read_dir(tmp.path())
        .map(|d| {
            d.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(".partial"))
                .collect()
        })
        .unwrap_or_default();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn convert_refuses_empty_missing_and_unknown_inputs() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(tmp.path().join("empty.obj"), "# nothing\nv 0 0 0\n")
        .unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(tmp.path().join("model.3ds"), "solid x\n").unwrap_or_else(|e| panic!("{e}"));
    let empty = oocfmt(
        &["convert", "empty.obj", "-o", "x.oocf", "--quiet"],
        tmp.path(),
    );
    assert_eq!(
        empty.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&empty.stderr)
    );
    assert_eq!(
        oocfmt(
            &["convert", "missing.obj", "-o", "x.oocf", "--quiet"],
            tmp.path()
        )
        .status
        .code(),
        Some(2)
    );
    assert_eq!(
        oocfmt(
            &["convert", "model.3ds", "-o", "x.oocf", "--quiet"],
            tmp.path()
        )
        .status
        .code(),
        Some(2)
    );
    assert_eq!(
        oocfmt(
            &[
                "convert",
                "empty.obj",
                "-o",
                "x.oocf",
                "--mem-limit",
                "lots"
            ],
            tmp.path()
        )
        .status
        .code(),
        Some(2)
    );
    std::fs::write(
        tmp.path().join("tri.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let over = oocfmt(
        &[
            "convert",
            "tri.obj",
            "-o",
            "x.oocf",
            "--mem-limit",
            "100",
            "--quiet",
        ],
        tmp.path(),
    );
    assert_eq!(over.status.code(), Some(2));
    let msg = String::from_utf8_lossy(&over.stderr);
    assert!(
        msg.contains("--mem-limit") && msg.contains("minimum"),
        "{msg}"
    );
    assert!(!tmp.path().join("x.oocf").exists());
}

/// Two triangles under a translated node, with a base-colour material and a data: URI buffer.
const QUAD_GLTF: &str = r#"{"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "translation": [10, 0, 0]}], "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}], "materials": [{"name": "blue", "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.2, 0.9, 1]}}], "buffers": [{"byteLength": 60, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAACAPwAAgD8AAAAAAAABAAIAAQADAAIA"}], "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 12}], "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}, {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}]}"#;

#[test]
fn convert_gltf_and_obj_together_into_one_scene() {
    let tmp = scene_dir();
    std::fs::write(tmp.path().join("quad.gltf"), QUAD_GLTF).unwrap_or_else(|e| panic!("{e}"));
    let report = convert_ok(tmp.path(), &["scene.obj", "quad.gltf", "-o", "both.oocf"]);
    assert_eq!(report["triangles_stored"], 8, "{report}");
    assert_eq!(
        report["import"]["files"].as_array().map(Vec::len),
        Some(2),
        "{report}"
    );
    let i = oocfmt(&["inspect", "--json", "both.oocf"], tmp.path());
    let summary: serde_json::Value = serde_json::from_slice(&i.stdout).unwrap_or_default();
    let names: Vec<&str> = summary["metadata"]["materials"]
        .as_array()
        .map(|m| m.iter().filter_map(|x| x["name"].as_str()).collect())
        .unwrap_or_default();
    assert_eq!(names, ["grey", "red", "blue"], "{summary}");
    // The glTF node translation puts the quad at x = 10..11.
    assert_eq!(
        summary["metadata"]["scene"]["bounds_max"][0], 11.0,
        "{summary}"
    );
    assert_eq!(
        oocfmt(&["verify", "--deep", "both.oocf"], tmp.path())
            .status
            .code(),
        Some(0)
    );
}

#[test]
fn convert_refuses_a_gltf_uri_outside_its_folder() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let bad = QUAD_GLTF.replace(
        "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAACAPwAAgD8AAAAAAAABAAIAAQADAAIA",
        "../../etc/passwd",
    );
    std::fs::write(tmp.path().join("bad.gltf"), bad).unwrap_or_else(|e| panic!("{e}"));
    let o = oocfmt(
        &["convert", "bad.gltf", "-o", "x.oocf", "--quiet"],
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.gltf") && err.contains(".."), "{err}");
    assert!(!tmp.path().join("x.oocf").exists());
}

/// The triangles of an OBJ file as sorted corner triples of position bit patterns (each
/// triangle rotated so its smallest corner comes first), for multiset comparison.
fn obj_triangles(path: &Path) -> Vec<[[u32; 3]; 3]> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut v: Vec<[u32; 3]> = Vec::new();
    let mut tris = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f32> = it.take(3).map(|x| x.parse().unwrap_or(f32::NAN)).collect();
                v.push([c[0].to_bits(), c[1].to_bits(), c[2].to_bits()]);
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
                for k in 1..idx.len() - 1 {
                    let mut t = [v[idx[0] - 1], v[idx[k] - 1], v[idx[k + 1] - 1]];
                    let min = (0..3).min_by_key(|&i| t[i]).unwrap_or(0);
                    t.rotate_left(min);
                    tris.push(t);
                }
            }
            _ => {}
        }
    }
    tris.sort_unstable();
    tris
}

#[test]
fn generated_scenes_convert_verify_and_export_without_loss() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    for (scene, tris) in [("mandelbulb", "3000"), ("cad", "3000")] {
        let obj = format!("{scene}.obj");
        gen(tmp.path(), scene, tris, &obj);
        let oocf = format!("{scene}.oocf");
        let report = convert_ok(tmp.path(), &[&obj, "-o", &oocf, "--max-leaf", "4"]);
        assert_eq!(
            oocfmt(&["verify", "--deep", &oocf], tmp.path())
                .status
                .code(),
            Some(0),
            "{scene}"
        );
        let back = format!("{scene}-back.obj");
        assert_eq!(
            oocfmt(&["export", &oocf, "-o", &back, "--quiet"], tmp.path())
                .status
                .code(),
            Some(0)
        );
        let input = obj_triangles(&tmp.path().join(&obj));
        let output = obj_triangles(&tmp.path().join(&back));
        let dropped = report["import"]["dropped"]
            .as_object()
            .map(|d| d.values().filter_map(|n| n.as_u64()).sum::<u64>())
            .unwrap_or(0);
        assert_eq!(
            output.len() as u64 + dropped,
            input.len() as u64,
            "{scene}: {report}"
        );
        if dropped == 0 {
            assert_eq!(
                input, output,
                "{scene}: the exported triangles differ from the input"
            );
        }
    }
}

#[test]
fn a_scene_over_the_memory_limit_converts_out_of_core_without_loss() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    for (scene, tris) in [("mandelbulb", "40000"), ("cad", "30000")] {
        let obj = format!("{scene}.obj");
        gen(tmp.path(), scene, tris, &obj);
        let mut exported = Vec::new();
        for (name, limit) in [("in-core", "8G"), ("chunked", "16M")] {
            let oocf = format!("{scene}-{name}.oocf");
            let report = convert_ok(tmp.path(), &[&obj, "-o", &oocf, "--mem-limit", limit]);
            let chunks = report["out_of_core"]["chunks"].as_u64();
            if name == "in-core" {
                assert_eq!(chunks, None, "{scene}: {report}");
            } else {
                assert!(chunks.is_some_and(|c| c >= 2), "{scene}: {report}");
            }
            let v = oocfmt(&["verify", "--deep", &oocf], tmp.path());
            assert_eq!(v.status.code(), Some(0), "{scene} {name}: {}", stdout(&v));
            let back = format!("{scene}-{name}.obj");
            let e = oocfmt(&["export", &oocf, "-o", &back, "--quiet"], tmp.path());
            assert_eq!(e.status.code(), Some(0));
            exported.push(obj_triangles(&tmp.path().join(&back)));
        }
        assert!(!exported[0].is_empty());
        assert_eq!(
            exported[0], exported[1],
            "{scene}: the chunked build lost or added triangles"
        );
        // Nothing of the spill files is left behind.
        let leftovers: Vec<String> = std::fs::read_dir(tmp.path())
            .map(|d| {
                d.filter_map(|e| e.ok())
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .filter(|n| n.starts_with(".oocfmt-spill"))
                    .collect()
            })
            .unwrap_or_default();
        assert!(leftovers.is_empty(), "{leftovers:?}");
    }
}

/// "Model only what a scene needs": a scene without normals, colours or materials stores
/// none, and its container is smaller than the same scene's with them.
#[test]
fn a_scene_without_attributes_stores_none() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let d = dir.path();
    gen(d, "cad", "3000", "full.obj");
    let full = std::fs::read_to_string(d.join("full.obj")).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        full.contains("\nvn ") && full.contains("usemtl"),
        "the generator writes attributes"
    );
    // The same triangles with the normals and materials stripped from the input.
    let bare: String = full
        .lines()
        .filter(|l| !(l.starts_with("vn ") || l.starts_with("usemtl") || l.starts_with("mtllib")))
        .map(|l| match l.strip_prefix("f ") {
            Some(f) => {
                let corners: Vec<&str> = f
                    .split_whitespace()
                    .map(|c| c.split('/').next().unwrap_or(c))
                    .collect();
                format!("f {}\n", corners.join(" "))
            }
            None => format!("{l}\n"),
        })
        .collect();
    std::fs::write(d.join("bare.obj"), bare).unwrap_or_else(|e| panic!("{e}"));
    let mut per_triangle = Vec::new();
    let mut sizes = Vec::new();
    for name in ["full", "bare"] {
        let report = convert_ok(d, &[&format!("{name}.obj"), "-o", &format!("{name}.oocf")]);
        assert_eq!(report["import"]["triangles_out"], 3000, "{name}: {report}");
        let info = run_ok(&["inspect", &format!("{name}.oocf"), "--json"], d);
        let info: serde_json::Value =
            serde_json::from_slice(&info.stdout).unwrap_or_else(|e| panic!("{e}"));
        let schema = &info["metadata"]["schema"];
        let stored = name == "full";
        assert_eq!(schema["vertex_normals"], stored, "{name}: {schema}");
        assert_eq!(schema["triangle_materials"], stored, "{name}: {schema}");
        assert_eq!(schema["vertex_colours"], false, "{name}: {schema}");
        per_triangle.push(
            info["tree"]["bytes_per_triangle"]
                .as_f64()
                .unwrap_or(f64::NAN),
        );
        sizes.push(
            std::fs::metadata(d.join(format!("{name}.oocf")))
                .unwrap_or_else(|e| panic!("{e}"))
                .len(),
        );
    }
    assert!(
        sizes[1] < sizes[0],
        "bare {} bytes, with attributes {}",
        sizes[1],
        sizes[0]
    );
    assert!(
        per_triangle[1] < per_triangle[0],
        "bytes per triangle {per_triangle:?}"
    );
}

#[test]
fn a_reader_that_stops_early_does_not_make_inspect_fail() {
    use std::io::Read;
    use std::process::{Command, Stdio};
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    gen(tmp.path(), "mandelbulb", "60000", "m.obj");
    run_ok(&["convert", "m.obj", "-o", "m.oocf", "--quiet"], tmp.path());
    // The block with the longest dump: it must be more than a pipe's buffer for the test to
    // mean anything.
    let (block, len) = (0..40)
        .map(|b| {
            let o = oocfmt(
                &["inspect", "m.oocf", "--block", &b.to_string()],
                tmp.path(),
            );
            (b, o.stdout.len())
        })
        .max_by_key(|&(_, len)| len)
        .unwrap_or((0, 0));
    assert!(len > 1 << 18, "longest block dump {len} bytes");
    let mut child = Command::new(env!("CARGO_BIN_EXE_oocfmt"))
        .args(["inspect", "m.oocf", "--block", &block.to_string()])
        .current_dir(tmp.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("{e}"));
    let mut first = [0u8; 64];
    if let Some(mut out) = child.stdout.take() {
        out.read_exact(&mut first).unwrap_or_else(|e| panic!("{e}"));
    }
    let o = child.wait_with_output().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}
