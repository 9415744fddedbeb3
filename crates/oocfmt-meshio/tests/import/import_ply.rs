//! The PLY importer on files built by a small encoder of the test's own: the three encodings
//! of one model give one mesh, elements in any order, unknown elements and properties
//! stepped over (lists included), polygons and strips, parts and materials from our
//! exporter's comments, and every count checked against the file before it is trusted.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::io::Cursor;

use oocfmt_meshio::import::ply::{import, import_from, import_stream, PlyOptions};
use oocfmt_meshio::import::{DropReason, ImportError, ImportReport, MeshSink, Skipped};
use oocfmt_meshio::mesh::Mesh;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Enc {
    Ascii,
    Le,
    Be,
}

pub(crate) const ENCODINGS: [Enc; 3] = [Enc::Ascii, Enc::Le, Enc::Be];

#[derive(Clone, Debug)]
pub(crate) enum Val {
    N(f64),
    L(Vec<f64>),
}

#[derive(Clone, Debug)]
pub(crate) struct El {
    pub(crate) name: &'static str,
    /// As in the header after `property`: `float x`, `list uchar int vertex_indices`.
    pub(crate) props: Vec<&'static str>,
    pub(crate) rows: Vec<Vec<Val>>,
}

fn put(out: &mut Vec<u8>, ty: &str, v: f64, enc: Enc) {
    macro_rules! bytes {
        ($t:ty) => {{
            let x = v as $t;
            out.extend_from_slice(&if enc == Enc::Be {
                x.to_be_bytes()
            } else {
                x.to_le_bytes()
            })
        }};
    }
    match ty {
        "char" | "int8" => bytes!(i8),
        "uchar" | "uint8" => bytes!(u8),
        "short" | "int16" => bytes!(i16),
        "ushort" | "uint16" => bytes!(u16),
        "int" | "int32" => bytes!(i32),
        "uint" | "uint32" => bytes!(u32),
        "float" | "float32" => bytes!(f32),
        "double" | "float64" => bytes!(f64),
        other => panic!("type {other}"),
    }
}

/// A PLY file: header with `comments`, then `elements` in `enc`.
pub(crate) fn ply(enc: Enc, comments: &[&str], elements: &[El]) -> Vec<u8> {
    let format = match enc {
        Enc::Ascii => "ascii",
        Enc::Le => "binary_little_endian",
        Enc::Be => "binary_big_endian",
    };
    let mut h = format!("ply\nformat {format} 1.0\n");
    for c in comments {
        h += &format!("comment {c}\n");
    }
    for e in elements {
        h += &format!("element {} {}\n", e.name, e.rows.len());
        for p in &e.props {
            h += &format!("property {p}\n");
        }
    }
    h += "end_header\n";
    let mut out = h.into_bytes();
    for e in elements {
        for row in &e.rows {
            let mut words = Vec::new();
            for (p, v) in e.props.iter().zip(row) {
                let types: Vec<&str> = p.split_whitespace().collect();
                match (types.as_slice(), v) {
                    (["list", count, item, _], Val::L(items)) => {
                        words.push(items.len().to_string());
                        words.extend(items.iter().map(f64::to_string));
                        if enc != Enc::Ascii {
                            put(&mut out, count, items.len() as f64, enc);
                            for &i in items {
                                put(&mut out, item, i, enc);
                            }
                        }
                    }
                    ([ty, _], Val::N(x)) => {
                        words.push(x.to_string());
                        if enc != Enc::Ascii {
                            put(&mut out, ty, *x, enc);
                        }
                    }
                    other => panic!("{other:?}"),
                }
            }
            if enc == Enc::Ascii {
                out.extend_from_slice(words.join(" ").as_bytes());
                out.push(b'\n');
            }
        }
    }
    out
}

pub(crate) fn n(v: f64) -> Val {
    Val::N(v)
}

pub(crate) fn l(v: &[f64]) -> Val {
    Val::L(v.to_vec())
}

/// The eight corners of a unit cube, with normals (the direction from the centre) and
/// colours.
pub(crate) fn cube_vertices(props: Vec<&'static str>, extra: impl Fn(usize) -> Vec<Val>) -> El {
    let rows = (0..8)
        .map(|i| {
            let p = [i & 1, (i >> 1) & 1, (i >> 2) & 1].map(|b| b as f64);
            let nrm = p.map(|c| (c - 0.5) / 0.75f64.sqrt());
            let mut row: Vec<Val> = p.into_iter().chain(nrm).map(n).collect();
            row.extend([n((i * 30) as f64), n(255.0 - (i * 30) as f64), n(7.0)]);
            row.extend(extra(i));
            row
        })
        .collect();
    let mut all = vec![
        "float x",
        "float y",
        "float z",
        "float nx",
        "float ny",
        "float nz",
        "uchar red",
        "uchar green",
        "uchar blue",
    ];
    all.extend(props);
    El {
        name: "vertex",
        props: all,
        rows,
    }
}

/// The cube's six faces as quads, counter-clockwise from outside.
const QUADS: [[f64; 4]; 6] = [
    [0., 2., 3., 1.],
    [4., 5., 7., 6.],
    [0., 1., 5., 4.],
    [2., 6., 7., 3.],
    [0., 4., 6., 2.],
    [1., 3., 7., 5.],
];

pub(crate) fn cube_faces(props: Vec<&'static str>, extra: impl Fn(usize) -> Vec<Val>) -> El {
    let mut all = vec!["list uchar int vertex_indices"];
    all.extend(props);
    El {
        name: "face",
        props: all,
        rows: QUADS
            .iter()
            .enumerate()
            .map(|(i, q)| {
                let mut row = vec![l(q)];
                row.extend(extra(i));
                row
            })
            .collect(),
    }
}

pub(crate) fn plain_cube(enc: Enc) -> Vec<u8> {
    ply(
        enc,
        &[],
        &[
            cube_vertices(vec![], |_| vec![]),
            cube_faces(vec![], |_| vec![]),
        ],
    )
}

fn load_with(
    bytes: &[u8],
    strict: bool,
    opts: &PlyOptions,
) -> Result<(Mesh, ImportReport), ImportError> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.ply");
    std::fs::write(&path, bytes).unwrap();
    let mut sink = MeshSink::new(strict);
    import(&path, &mut sink, opts)?;
    let (mesh, report) = sink.finish()?;
    mesh.validate().unwrap();
    assert_eq!(
        report.triangles_in,
        report.triangles_out + report.dropped_total()
    );
    assert_eq!(report.triangles_out, mesh.triangles.len() as u64);
    Ok((mesh, report))
}

fn load(bytes: &[u8]) -> Result<(Mesh, ImportReport), ImportError> {
    load_with(bytes, false, &PlyOptions::default())
}

fn error(bytes: &[u8]) -> String {
    match load(bytes) {
        Ok((m, _)) => panic!("expected an error, got {} triangles", m.triangles.len()),
        Err(e) => e.to_string(),
    }
}

fn names(m: &Mesh) -> Vec<&str> {
    m.parts.iter().map(|p| p.name.as_str()).collect()
}

// ---------------------------------------------------------------- vertex tables on disk

/// 200 000 scattered vertices with normals and colours, and 50 000 triangles whose corners lie
/// far apart in the table, so that reading them goes back to pages moved to disk.
fn scattered_ply(enc: Enc) -> Vec<u8> {
    let count = 200_000usize;
    let rows = (0..count)
        .map(|i| {
            let f = i as f64;
            let p = [f.sin(), f.cos(), (f * 0.37).sin()].map(|c| n(c * 100.0));
            let c = [i % 256, (i / 7) % 256, (i / 13) % 256].map(|c| n(c as f64));
            let mut row = p.to_vec();
            row.extend([n(0.0), n(0.6), n(0.8)]);
            row.extend(c);
            row
        })
        .collect();
    let vertices = cube_vertices(vec![], |_| vec![]);
    let vertices = El { rows, ..vertices };
    let faces = El {
        name: "face",
        props: vec!["list uchar int vertex_indices"],
        rows: (0..count / 4)
            .map(|k| {
                let a = (k * 7919) % count;
                vec![l(
                    &[a, (a + count / 2) % count, (a + 1) % count].map(|v| v as f64)
                )]
            })
            .collect(),
    };
    ply(enc, &[], &[vertices, faces])
}

/// Vertex tables past their memory budget move to an unnamed temporary file and read back:
/// the same triangles as in memory, from a file and from a stream, the file's bytes charged
/// to the sink and released at the end, nothing left in the folder, and the spill's vertex
/// bound in force instead of `max_vertices`.
#[test]
fn vertex_tables_past_their_budget_give_the_same_triangles() {
    use crate::import_obj::{vertex_spill, Recorder};
    let spill_dir = tempfile::tempdir().unwrap();
    let spill = |max_vertices| PlyOptions {
        max_vertices: 10,
        spill: Some(vertex_spill(spill_dir.path(), max_vertices)),
        ..PlyOptions::default()
    };
    let bytes = scattered_ply(Enc::Le);
    let mut kept = Recorder::default();
    import_from(
        Cursor::new(&bytes),
        "m.ply",
        &mut kept,
        &PlyOptions::default(),
    )
    .unwrap();
    assert_eq!(kept.triangles.len(), 50_000);
    assert_eq!(kept.disk, (0, 0));
    let mut moved = Recorder::default();
    import_from(Cursor::new(&bytes), "m.ply", &mut moved, &spill(1 << 20)).unwrap();
    assert!(kept.triangles == moved.triangles, "the triangles differ");
    // Pages of 65 536 records: 1 MiB keeps one page of positions and of normals (12 bytes a
    // record), three of colours (5 bytes), so 3, 3 and 1 of their 4 pages move.
    assert_eq!(moved.disk.0, (3 + 3) * 65_536 * 12 + 65_536 * 5);
    assert_eq!(moved.disk.0, moved.disk.1);
    let mut streamed = Recorder::default();
    import_stream(Cursor::new(&bytes), "m.ply", &mut streamed, &spill(1 << 20)).unwrap();
    assert!(
        kept.triangles == streamed.triangles,
        "the stream's triangles differ"
    );
    assert_eq!(std::fs::read_dir(spill_dir.path()).unwrap().count(), 0);
    let mut refused = Recorder::default();
    let e = import_from(Cursor::new(&bytes), "m.ply", &mut refused, &spill(100_000));
    let msg = e.map(|()| String::new()).unwrap_or_else(|e| e.to_string());
    assert!(
        msg.contains("vertices") && msg.contains("limit of 100000"),
        "{msg}"
    );
}

// ---------------------------------------------------------------- encodings and layout

#[test]
fn ascii_and_both_binary_encodings_give_the_same_mesh() -> Result<(), ImportError> {
    let (a, ra) = load(&plain_cube(Enc::Ascii))?;
    assert_eq!(a.triangles.len(), 12, "six quads, two triangles each");
    assert_eq!(a.positions.len(), 8);
    // The file's vertex 3, wherever the mesh put it.
    let v3 = a
        .positions
        .iter()
        .position(|p| *p == [1.0, 1.0, 0.0])
        .unwrap();
    let nrm = a.normals.as_ref().unwrap()[v3];
    assert!(
        (nrm[0] - 0.57735).abs() < 1e-5 && (nrm[2] + 0.57735).abs() < 1e-5,
        "{nrm:?}"
    );
    assert_eq!(a.colours.as_ref().unwrap()[v3], [90, 165, 7, 255]);
    assert!(ra.warnings.is_empty(), "{:?}", ra.warnings);
    for enc in [Enc::Le, Enc::Be] {
        let (b, _) = load(&plain_cube(enc))?;
        assert_eq!(a, b, "{enc:?}");
    }
    // Float colours are 0..1.
    let mut v = cube_vertices(vec![], |_| vec![]);
    v.props[6..9].copy_from_slice(&["float red", "float green", "float blue"]);
    for row in &mut v.rows {
        for c in &mut row[6..9] {
            if let Val::N(x) = c {
                *x /= 255.0;
            }
        }
    }
    let (f, _) = load(&ply(Enc::Le, &[], &[v, cube_faces(vec![], |_| vec![])]))?;
    assert_eq!(f, a);
    Ok(())
}

#[test]
fn polygons_are_ear_clipped_and_small_faces_counted() -> Result<(), ImportError> {
    let square = El {
        name: "vertex",
        props: vec!["float x", "float y", "float z"],
        rows: [[0., 0.], [2., 0.], [2., 2.], [1., 1.5], [0., 2.]]
            .iter()
            .map(|p| vec![n(p[0]), n(p[1]), n(0.0)])
            .collect(),
    };
    // A concave pentagon (corner 3 is reflex), a point and a line.
    let faces = El {
        name: "face",
        props: vec!["list uint8 uint32 vertex_index"],
        rows: vec![
            vec![l(&[0., 1., 2., 3., 4.])],
            vec![l(&[0.])],
            vec![l(&[0., 1.])],
        ],
    };
    for enc in ENCODINGS {
        let (m, r) = load(&ply(enc, &[], &[square.clone(), faces.clone()]))?;
        assert_eq!(m.triangles.len(), 3);
        let area: f64 = m
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| m.positions[v as usize].map(f64::from));
                ((p[1][0] - p[0][0]) * (p[2][1] - p[0][1])
                    - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]))
                    / 2.0
            })
            .sum();
        assert_eq!(area, 3.5, "no triangle covers the notch");
        assert_eq!(r.skipped.get(&Skipped::Points), Some(&1));
        assert_eq!(r.skipped.get(&Skipped::Lines), Some(&1));
    }
    Ok(())
}

#[test]
fn elements_before_vertex_and_unknown_properties_are_stepped_over() -> Result<(), ImportError> {
    let camera = El {
        name: "camera",
        props: vec!["float view_px", "list uchar double track"],
        rows: vec![vec![n(1.0), l(&[1.0, 2.0, 3.0])], vec![n(2.0), l(&[])]],
    };
    let vertices = cube_vertices(vec!["float confidence", "list ushort int junk"], |i| {
        vec![n(0.5), l(&vec![9.0; i])]
    });
    let faces = cube_faces(vec!["uchar flags", "list int short other"], |i| {
        vec![n(i as f64), l(&[1.0, -2.0])]
    });
    let after = El {
        name: "edge",
        props: vec!["int vertex1", "int vertex2"],
        rows: vec![vec![n(0.0), n(1.0)]],
    };
    for enc in ENCODINGS {
        let (want, _) = load(&plain_cube(enc))?;
        let bytes = ply(
            enc,
            &["made by hand", "obj_info is only a comment here"],
            &[
                camera.clone(),
                vertices.clone(),
                faces.clone(),
                after.clone(),
            ],
        );
        let (got, r) = load(&bytes)?;
        assert_eq!(got, want, "{enc:?}");
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    }
    Ok(())
}

#[test]
fn faces_stored_before_the_vertices_are_read_in_a_second_pass() -> Result<(), ImportError> {
    for enc in ENCODINGS {
        let (want, _) = load(&plain_cube(enc))?;
        let bytes = ply(
            enc,
            &[],
            &[
                cube_faces(vec![], |_| vec![]),
                cube_vertices(vec![], |_| vec![]),
            ],
        );
        let (got, _) = load(&bytes)?;
        assert_eq!(got.triangles.len(), 12);
        assert_eq!(got.positions.len(), 8);
        assert_eq!(got, want, "{enc:?}");
    }
    Ok(())
}

#[test]
fn big_endian_doubles_keep_their_precision() -> Result<(), ImportError> {
    let xs = [10_000_000.123_456_78, 10_000_001.5, 10_000_000.25];
    let vertices = El {
        name: "vertex",
        props: vec!["double x", "double y", "double z"],
        rows: xs
            .iter()
            .enumerate()
            .map(|(i, &x)| vec![n(x), n(i as f64 * -2.5e-8), n(f64::from(i == 2))])
            .collect(),
    };
    let faces = El {
        name: "face",
        props: vec!["list uchar uint vertex_indices"],
        rows: vec![vec![l(&[0., 1., 2.])]],
    };
    let bytes = ply(Enc::Be, &[], &[vertices, faces]);
    let origin = [10_000_000.0, 0.0, 0.0];
    let mut sink = MeshSink::new(false).with_origin(origin);
    import_from(
        Cursor::new(&bytes),
        "be.ply",
        &mut sink,
        &PlyOptions::default(),
    )?;
    let (m, _) = sink.finish()?;
    for (i, &x) in xs.iter().enumerate() {
        let p = m.positions[m.triangles[0][i] as usize];
        assert_eq!(p[0], (x - origin[0]) as f32, "read as f64, then placed");
        assert_eq!(p[1], (i as f64 * -2.5e-8) as f32);
    }
    Ok(())
}

#[test]
fn triangle_strips_restart_at_minus_one_and_keep_their_winding() -> Result<(), ImportError> {
    let vertices = El {
        name: "vertex",
        props: vec!["float x", "float y", "float z"],
        rows: [[0., 0.], [0., 1.], [1., 0.], [1., 1.]]
            .iter()
            .map(|p| vec![n(p[0]), n(p[1]), n(0.0)])
            .collect(),
    };
    let strips = El {
        name: "tristrips",
        props: vec!["list int int vertex_indices"],
        rows: vec![vec![l(&[0., 2., 1., 3., -1., 0., 2., 1.])]],
    };
    for enc in ENCODINGS {
        let (m, _) = load(&ply(enc, &[], &[vertices.clone(), strips.clone()]))?;
        let tris: Vec<[[f32; 3]; 3]> = m
            .triangles
            .iter()
            .map(|t| t.map(|v| m.positions[v as usize]))
            .collect();
        let (a, b, c, d) = ([0., 0., 0.], [0., 1., 0.], [1., 0., 0.], [1., 1., 0.]);
        assert_eq!(tris, [[a, c, b], [b, c, d], [a, c, b]], "{enc:?}");
    }
    Ok(())
}

// ---------------------------------------------------------------- parts, materials, origin

#[test]
fn part_ids_become_parts_named_by_the_header_comments() -> Result<(), ImportError> {
    let comments = ["part 0 -1 wing assembly", "part 1 0 bolt-17"];
    let ids = [0.0, 1.0, 1.0, 2.0, 1.0, 0.0];
    for enc in ENCODINGS {
        let faces = cube_faces(vec!["int part"], |i| vec![n(ids[i])]);
        let bytes = ply(enc, &comments, &[cube_vertices(vec![], |_| vec![]), faces]);
        let (m, _) = load(&bytes)?;
        assert_eq!(names(&m), ["wing assembly", "bolt-17", "part 2"]);
        let parents: Vec<Option<u32>> = m.parts.iter().map(|p| p.parent).collect();
        assert_eq!(parents, [None, Some(0), None]);
        let per_tri: Vec<u32> = ids.iter().flat_map(|&i| [i as u32; 2]).collect();
        assert_eq!(m.part_ids.as_deref(), Some(&per_tri[..]));
    }
    // Without comments (and under the other name), parts are numbered by their ids.
    let faces = cube_faces(vec!["uchar part_id"], |i| {
        vec![n(5.0 + (i % 2) as f64 * 2.0)]
    });
    let (m, _) = load(&ply(
        Enc::Le,
        &[],
        &[cube_vertices(vec![], |_| vec![]), faces],
    ))?;
    assert_eq!(names(&m), ["part 5", "part 7"]);
    // A comment naming a parent it cannot have is warned about; the part is top level.
    let faces = cube_faces(vec!["int part"], |_| vec![n(0.0)]);
    let bytes = ply(
        Enc::Ascii,
        &["part 0 3 orphan", "part x y broken"],
        &[cube_vertices(vec![], |_| vec![]), faces],
    );
    let (m, r) = load(&bytes)?;
    assert_eq!(names(&m), ["orphan"]);
    assert!(m.part_ids.is_none(), "one part: no ids");
    assert_eq!(r.warnings.len(), 2, "{:?}", r.warnings);
    assert!(r.warnings[0].contains("m.ply:4") && r.warnings[0].contains("does not parse"));
    assert!(r.warnings[1].contains("name a parent without a smaller id"));
    Ok(())
}

#[test]
fn materials_and_the_origin_come_from_our_exporters_comments() -> Result<(), ImportError> {
    let comments = [
        "exported by oocfmt-build from a.oocf",
        "positions are relative to the scene origin 100 0 -0.5",
        "material 0 brushed steel 0.5 0.25 1",
    ];
    let faces = cube_faces(vec!["ushort material_index"], |i| {
        vec![n((i % 2) as f64 * 3.0)]
    });
    let (m, _) = load(&ply(
        Enc::Be,
        &comments,
        &[cube_vertices(vec![], |_| vec![]), faces],
    ))?;
    assert!(m.positions.iter().all(|p| p[0] >= 100.0 && p[2] <= 0.5));
    assert!(m.positions.contains(&[101.0, 1.0, 0.5]));
    let table: Vec<(&str, [f32; 3])> = m
        .material_table
        .iter()
        .map(|t| (t.name.as_str(), t.diffuse))
        .collect();
    assert_eq!(
        table,
        [
            ("brushed steel", [0.5, 0.25, 1.0]),
            ("material 3", [0.8, 0.8, 0.8])
        ]
    );
    assert_eq!(
        m.materials.as_deref(),
        Some(&[0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1][..])
    );
    Ok(())
}

// ---------------------------------------------------------------- bad input

#[test]
fn out_of_range_indices_reject_the_face_and_strict_says_where() {
    let faces = El {
        name: "face",
        props: vec!["list uchar float vertex_indices"],
        rows: vec![
            vec![l(&[0., 1., 2.])],
            vec![l(&[0., 1., 8.])],
            vec![l(&[0., -1., 2., 3.])],
            vec![l(&[0., 1.5, 2.])],
        ],
    };
    for enc in ENCODINGS {
        let bytes = ply(
            enc,
            &[],
            &[cube_vertices(vec![], |_| vec![]), faces.clone()],
        );
        let (m, r) = load(&bytes).unwrap();
        assert_eq!(m.triangles.len(), 1);
        assert_eq!(r.dropped.get(&DropReason::IndexOutOfRange), Some(&4));
        let e = load_with(&bytes, true, &PlyOptions::default()).unwrap_err();
        assert!(matches!(e, ImportError::Strict { .. }), "{e}");
        let want = match enc {
            Enc::Ascii => "m.ply:25".to_string(),
            _ => {
                // The header, eight vertices of 9 values (6 floats, 3 bytes), one face of 13.
                let header = bytes
                    .windows(11)
                    .position(|w| w == b"end_header\n")
                    .unwrap()
                    + 11;
                format!("face 1 at byte {}", header + 8 * 27 + 13)
            }
        };
        assert!(e.to_string().contains(&want), "{enc:?}: {e}");
    }
}

#[test]
fn a_list_longer_than_the_file_is_a_clear_error_not_an_allocation() {
    let faces = El {
        name: "face",
        props: vec!["list uint uint vertex_indices"],
        rows: vec![vec![l(&[0., 1., 2.])]],
    };
    let mut bytes = ply(Enc::Le, &[], &[cube_vertices(vec![], |_| vec![]), faces]);
    let at = bytes.len() - 16;
    bytes[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = error(&bytes);
    assert!(
        e.contains(
            "list `vertex_indices` of 4294967295 items (17179869180 bytes) runs past the end"
        ),
        "{e}"
    );
    assert!(e.contains("face 0 at byte"), "{e}");
    // The same for a list that is only stepped over, and in ASCII.
    let junk = cube_vertices(vec!["list uint uint junk"], |_| vec![l(&[1.0])]);
    let mut bytes = ply(Enc::Be, &[], &[junk, cube_faces(vec![], |_| vec![])]);
    let header = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    bytes[header + 27..header + 31].copy_from_slice(&4_000_000_000u32.to_be_bytes());
    assert!(error(&bytes).contains("list `junk` of 4000000000 items"));
    let text = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                 end_header\n0 0 0\n1 0 0\n0 1 0\n200 0 1 2\n";
    let e = error(text);
    assert!(e.contains("list `vertex_indices` of 200 items"), "{e}");
    assert!(e.contains("m.ply:13"), "{e}");
    // Element counts are checked against the file before anything is reserved.
    let text = b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n\
                 property float x\nproperty float y\nproperty float z\nend_header\n";
    let e = error(text);
    assert!(e.contains("m.ply:3"), "{e}");
    assert!(
        e.contains("declares 1000000000000 records of at least 12 bytes"),
        "{e}"
    );
    let opts = PlyOptions {
        max_vertices: 4,
        ..PlyOptions::default()
    };
    let e = load_with(&plain_cube(Enc::Le), false, &opts).unwrap_err();
    assert!(matches!(e, ImportError::Limit { .. }), "{e}");
}

#[test]
fn header_and_body_errors_name_their_line() {
    let head = "ply\nformat ascii 1.0\n";
    let xyz = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
    let face = "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    for (text, needle) in [
        ("plx\n".to_string(), "m.ply:1: not a PLY file"),
        ("ply\nformat text 1.0\n".into(), "m.ply:2: unknown format line"),
        ("ply\nformat ascii 2.0\n".into(), "m.ply:2: unsupported: PLY version 2.0"),
        (format!("{head}property float x\n"), "m.ply:3: `property` before any `element`"),
        (format!("{head}element vertex\n"), "m.ply:3: expected `element <name> <count>`"),
        (format!("{head}element vertex -3\n"), "m.ply:3: element count `-3`"),
        (format!("{head}element vertex 1\nproperty int64 x\n"), "m.ply:4: unsupported: property type `int64`"),
        (format!("{head}bogus\n"), "m.ply:3: unknown header line `bogus`"),
        (format!("{head}{xyz}"), "m.ply:6: the file ends inside the header"),
        ("ply\nelement vertex 0\nend_header\n".into(), "the header has no `format` line"),
        (
            format!("{head}element vertex 1\nproperty float x\nproperty float y\n{face}0 0\n3 0 0 0\n"),
            "m.ply:3: element `vertex` has no scalar property `z`",
        ),
        (format!("{head}{xyz}{face}0 0 0\n1 0 0\n0 1 zero\n3 0 1 2\n"), "m.ply:12: `zero` is not a number"),
        (format!("{head}{xyz}{face}0 0 0\n1 0 0\n0 1 0\n3 0 1\n"), "ends inside property `vertex_indices`"),
        (format!("{head}element face 1\nproperty list uchar int vertex_indices\nend_header\n3 0 1 2\n"), "faces but no `vertex` element"),
    ] {
        let e = error(text.as_bytes());
        assert!(e.contains(needle), "{needle}: {e}");
    }
    // A point cloud is no error of the format's, but gives no triangle.
    let cloud = format!("{head}{xyz}end_header\n0 0 0\n1 0 0\n0 1 0\n");
    assert!(matches!(
        load(cloud.as_bytes()),
        Err(ImportError::Empty { .. })
    ));
}

#[test]
fn bytes_after_the_last_element_are_warned_about() -> Result<(), ImportError> {
    let mut bytes = plain_cube(Enc::Le);
    bytes.extend_from_slice(b"tail");
    let (m, r) = load(&bytes)?;
    assert_eq!(m.triangles.len(), 12);
    assert_eq!(r.warnings.len(), 1);
    assert!(
        r.warnings[0].contains("4 bytes after the last element"),
        "{:?}",
        r.warnings
    );
    Ok(())
}
