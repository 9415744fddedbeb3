//! STL and PLY through the command line: each encoding of one cube converts to the same 12
//! triangles, several ASCII STL solids become named parts, and a PLY export of a container
//! with parts converts back to the same part tree.

use crate::common;

use common::*;

use std::path::Path;

/// The 12 triangles of the unit cube, counter-clockwise seen from outside.
fn cube() -> Vec<[[f32; 3]; 3]> {
    let v = |i: usize| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32];
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    quads
        .iter()
        .flat_map(|q| [[v(q[0]), v(q[1]), v(q[2])], [v(q[0]), v(q[2]), v(q[3])]])
        .collect()
}

/// An ASCII STL of `solids`, each a named solid of the cube shifted by its index along x.
fn ascii_stl(solids: &[&str]) -> String {
    let mut s = String::new();
    for (k, name) in solids.iter().enumerate() {
        s.push_str(&format!("solid {name}\n"));
        for t in cube() {
            s.push_str(" facet normal 0 0 0\n  outer loop\n");
            for p in t {
                s.push_str(&format!(
                    "   vertex {} {} {}\n",
                    p[0] + 2.0 * k as f32,
                    p[1],
                    p[2]
                ));
            }
            s.push_str("  endloop\n endfacet\n");
        }
        s.push_str(&format!("endsolid {name}\n"));
    }
    s
}

/// A binary STL of the cube whose 80-byte header starts with "solid", as many exporters write.
fn binary_stl() -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b[..14].copy_from_slice(b"solid exported");
    b.extend_from_slice(&(cube().len() as u32).to_le_bytes());
    for t in cube() {
        b.extend_from_slice(&[0u8; 12]);
        for c in t.iter().flatten() {
            b.extend_from_slice(&c.to_le_bytes());
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}

/// The cube as PLY in `encoding` (`ascii`, `binary_little_endian`, `binary_big_endian`):
/// 8 vertices and 6 quads.
fn ply(encoding: &str) -> Vec<u8> {
    let header = format!(
        "ply\nformat {encoding} 1.0\ncomment a cube\nelement vertex 8\nproperty float x\n\
         property float y\nproperty float z\nelement face 6\n\
         property list uchar int vertex_indices\nend_header\n"
    );
    let quads: [[i32; 4]; 6] = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let v = |i: usize| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32];
    let mut b = header.into_bytes();
    match encoding {
        "ascii" => {
            for i in 0..8 {
                let p = v(i);
                b.extend_from_slice(format!("{} {} {}\n", p[0], p[1], p[2]).as_bytes());
            }
            for q in quads {
                b.extend_from_slice(format!("4 {} {} {} {}\n", q[0], q[1], q[2], q[3]).as_bytes());
            }
        }
        _ => {
            let big = encoding == "binary_big_endian";
            for i in 0..8 {
                for c in v(i) {
                    b.extend_from_slice(&if big {
                        c.to_be_bytes()
                    } else {
                        c.to_le_bytes()
                    });
                }
            }
            for q in quads {
                b.push(4);
                for i in q {
                    b.extend_from_slice(&if big {
                        i.to_be_bytes()
                    } else {
                        i.to_le_bytes()
                    });
                }
            }
        }
    }
    b
}

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    std::fs::write(dir.join(name), bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
}

fn parts_json(dir: &Path, file: &str) -> serde_json::Value {
    let o = run_ok(&["inspect", file, "--parts", "--json"], dir);
    serde_json::from_str(&stdout(&o)).unwrap_or_else(|e| panic!("{file}: {e}"))
}

/// (name, parent, triangles) of every part, in id order.
fn part_rows(v: &serde_json::Value) -> Vec<(String, Option<u64>, u64)> {
    v["parts"]
        .as_array()
        .map(|a| {
            a.iter()
                .map(|p| {
                    (
                        p["name"].as_str().unwrap_or_default().to_string(),
                        p["parent"].as_u64(),
                        p["triangles"].as_u64().unwrap_or(u64::MAX),
                    )
                })
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn every_stl_and_ply_encoding_of_a_cube_converts_to_its_12_triangles() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let d = dir.path();
    write(d, "ascii.stl", ascii_stl(&[""]).as_bytes());
    write(d, "binary.stl", &binary_stl());
    for enc in ["ascii", "binary_little_endian", "binary_big_endian"] {
        write(d, &format!("{enc}.ply"), &ply(enc));
    }
    let inputs = [
        "ascii.stl",
        "binary.stl",
        "ascii.ply",
        "binary_little_endian.ply",
        "binary_big_endian.ply",
    ];
    for input in inputs {
        let out = format!("{input}.oocf");
        let report = convert_ok(d, &[input, "-o", &out]);
        assert_eq!(report["triangles_stored"], 12, "{input}: {report}");
        assert_eq!(report["import"]["triangles_in"], 12, "{input}: {report}");
        run_ok(&["verify", &out, "--deep"], d);
        // One unnamed solid or a PLY without a part property: no part table.
        assert_eq!(part_rows(&parts_json(d, &out)), vec![], "{input}");
    }
}

#[test]
fn stl_solids_become_parts_and_a_ply_export_keeps_them() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let d = dir.path();
    write(d, "two.stl", ascii_stl(&["housing", "lid"]).as_bytes());
    convert_ok(d, &["two.stl", "-o", "two.oocf"]);
    run_ok(&["verify", "two.oocf", "--deep"], d);
    let want = vec![
        ("housing".to_string(), None, 12),
        ("lid".to_string(), None, 12),
    ];
    assert_eq!(part_rows(&parts_json(d, "two.oocf")), want);

    run_ok(&["export", "two.oocf", "-o", "back.ply", "--quiet"], d);
    let report = convert_ok(d, &["back.ply", "-o", "back.oocf"]);
    assert_eq!(report["triangles_stored"], 24, "{report}");
    assert_eq!(part_rows(&parts_json(d, "back.oocf")), want);
}

#[test]
fn several_files_are_parts_above_their_own_parts() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let d = dir.path();
    write(d, "lid.stl", ascii_stl(&["lid"]).as_bytes());
    write(d, "box.ply", &ply("ascii"));
    let obj = "v 0 0 5\nv 1 0 5\nv 0 1 5\nv 1 1 5\no frame\ng bar\nf 1 2 3\ng rod\nf 2 4 3\n";
    write(d, "frame.obj", obj.as_bytes());
    let report = convert_ok(d, &["lid.stl", "box.ply", "frame.obj", "-o", "all.oocf"]);
    assert_eq!(report["triangles_stored"], 26, "{report}");
    run_ok(&["verify", "all.oocf", "--deep"], d);
    let rows = part_rows(&parts_json(d, "all.oocf"));
    let row =
        |name: &str, parent: Option<u64>, triangles: u64| (name.to_string(), parent, triangles);
    assert_eq!(
        rows,
        vec![
            row("lid.stl", None, 0),
            row("lid", Some(0), 12),
            row("box.ply", None, 12),
            row("frame.obj", None, 0),
            row("frame", Some(3), 0),
            row("bar", Some(4), 1),
            row("rod", Some(4), 1),
        ]
    );
}
