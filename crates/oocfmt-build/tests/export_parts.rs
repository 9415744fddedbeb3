//! Containers with parts exported to OBJ and PLY: the part table comes back (names, parents,
//! per-part counts and bounds) when the OBJ is converted again, faces come grouped by part in
//! the table's order, and the number of passes never changes a byte.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use base64::Engine;
use oocfmt::metadata::{Metadata, Part};
use oocfmt::{ReadOptions, Reader, WriteOptions};
use oocfmt_build::convert::{convert, ConvertOptions};
use oocfmt_build::kdtree::KdBuildOptions;
use oocfmt_build::layout::LayoutOptions;
use oocfmt_build::progress::NoProgress;
use oocfmt_meshio::export::{write_obj, write_ply, ExportOptions, ExportReport};

type Res<T = ()> = Result<T, Box<dyn std::error::Error>>;

/// Small blocks and leaves, so every part is spread over several blocks.
fn options() -> Res<ConvertOptions> {
    Ok(ConvertOptions {
        layout: LayoutOptions {
            write: WriteOptions::default().with_block_size(4096)?,
            ..LayoutOptions::default()
        },
        kd: KdBuildOptions {
            max_leaf_triangles: 4,
            ..KdBuildOptions::default()
        },
        mem_limit: 1 << 30,
        ..ConvertOptions::default()
    })
}

fn convert_to(inputs: &[PathBuf], out: &Path) -> Res<Metadata> {
    convert(inputs, out, &options()?, &mut NoProgress)?;
    Ok(Reader::open(out, ReadOptions::default())?
        .metadata()
        .clone())
}

/// A wavy grid of `n`×`n` quads whose rows take turns between objects and groups, so the
/// parts reopen and interleave; the first row comes before any `o`/`g`.
fn assembly_obj(n: usize) -> String {
    let mut text = String::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f64, j as f64);
            let z = (0.7 * x).sin() * (0.5 * y).cos();
            text += &format!("v {x} {y} {z:.5}\n");
        }
    }
    let v = |i: usize, j: usize| j * (n + 1) + i + 1;
    for j in 0..n {
        for i in 0..n {
            if j > 0 && i % (n / 3) == 0 {
                let band = i / (n / 3);
                text += &format!("o engine {}\n", j % 2);
                if band > 0 {
                    text += &format!("g blade  {band}\n");
                }
            }
            let (a, b, c, d) = (v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
            text += &format!("f {a} {b} {c} {d}\n");
        }
    }
    text
}

/// The part table without what a file's bounds and sources make differ, for comparisons
/// across formats: (name, parent, triangles).
fn tree(parts: &[Part]) -> Vec<(String, Option<u32>, u64)> {
    parts
        .iter()
        .map(|p| (p.name.clone(), p.parent, p.triangles))
        .collect()
}

fn export_obj(container: &Path, out: &Path, faces_per_pass: u64) -> Res<ExportReport> {
    let opts = ExportOptions {
        faces_per_pass,
        ..ExportOptions::default()
    };
    Ok(write_obj(container, out, &opts, &mut |_, _| {})?)
}

/// The part of each face of an exported OBJ, by the `# part ID` comments.
fn obj_face_parts(text: &str) -> Vec<u32> {
    let mut part = u32::MAX;
    let mut out = Vec::new();
    for line in text.lines() {
        if let Some(id) = line.strip_prefix("# part ") {
            if let Ok(id) = id.parse() {
                part = id;
            }
        } else if line.starts_with("f ") {
            out.push(part);
        }
    }
    out
}

/// Each part's faces form one run, the runs in the table's order, and the runs' lengths are
/// the table's counts.
fn assert_grouped(face_parts: &[u32], parts: &[Part]) {
    assert!(
        face_parts.windows(2).all(|w| w[0] <= w[1]),
        "faces out of part order"
    );
    let mut counts = vec![0u64; parts.len()];
    for &p in face_parts {
        counts[p as usize] += 1;
    }
    let want: Vec<u64> = parts.iter().map(|p| p.triangles).collect();
    assert_eq!(counts, want);
}

#[test]
fn an_obj_export_converts_back_to_the_same_part_table() -> Res {
    let dir = tempfile::tempdir()?;
    let input = dir.path().join("assembly.obj");
    std::fs::write(&input, assembly_obj(24))?;
    let first = dir.path().join("a.oocf");
    let meta = convert_to(std::slice::from_ref(&input), &first)?;
    assert_eq!(
        tree(&meta.parts),
        [
            ("engine 1".to_string(), None, 192),
            ("blade 1".to_string(), Some(0), 192),
            ("blade 2".to_string(), Some(0), 192),
            ("engine 0".to_string(), None, 176),
            ("blade 1".to_string(), Some(3), 176),
            ("blade 2".to_string(), Some(3), 176),
            ("(no part)".to_string(), None, 48),
        ]
    );

    let out = dir.path().join("a.obj");
    let report = export_obj(&first, &out, ExportOptions::default().faces_per_pass)?;
    assert_eq!((report.parts, report.triangles), (7, 1152));
    assert!(report.triangle_blocks > 4, "{report:?}");
    let text = std::fs::read_to_string(&out)?;
    assert!(text.contains("# oocfmt parts 7\n# part 0 -1 engine 1\n# part 1 0 blade 1\n"));
    assert!(
        text.contains("\n# part 4\ng engine 0/blade 1\nf "),
        "{text}"
    );
    assert_grouped(&obj_face_parts(&text), &meta.parts);
    // Every vertex precedes the faces.
    assert!(text.rfind("\nv ") < text.find("\nf "));

    // However many passes the grouping takes, the same bytes.
    for per_pass in [1, 7, 500] {
        let again = dir.path().join(format!("a{per_pass}.obj"));
        export_obj(&first, &again, per_pass)?;
        assert!(
            std::fs::read(&again)? == text.as_bytes(),
            "{per_pass} faces per pass"
        );
    }

    let second = dir.path().join("b.oocf");
    let back = convert_to(&[out], &second)?;
    // Names, parents, counts and bounds (positions are bit-exact), and the source index.
    assert_eq!(back.parts, meta.parts);
    Ok(())
}

/// A glTF of one triangle mesh placed by the nodes given, its buffer in a data URI.
fn gltf_with_nodes(nodes: serde_json::Value, roots: &[usize]) -> String {
    let tri: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let bytes: Vec<u8> = tri.iter().flat_map(|x| x.to_le_bytes()).collect();
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bytes)
    );
    serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": nodes,
        "meshes": [{"name": "plate", "primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": [{"byteLength": bytes.len(), "uri": uri}],
        "bufferViews": [{"buffer": 0, "byteLength": bytes.len()}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}],
    })
    .to_string()
}

#[test]
fn a_deep_tree_with_same_named_siblings_and_odd_names_survives_obj() -> Res {
    // Three levels under the file parts, two siblings both named "bolt", names with a `%`,
    // a backslash at the end, a `#` and surrounding spaces; and a second file of one part.
    let offset = |x: f32| serde_json::json!([x, 0.0, 0.0]);
    let nodes = serde_json::json!([
        {"name": "wing", "children": [1, 4]},
        {"name": "flap 50%", "children": [2, 3]},
        {"name": "bolt", "mesh": 0, "translation": offset(2.0)},
        {"name": "bolt", "mesh": 0, "translation": offset(4.0)},
        {"name": " #7 rib\\", "mesh": 0, "translation": offset(6.0)},
        {"mesh": 0, "translation": offset(8.0)},
    ]);
    let dir = tempfile::tempdir()?;
    let gltf = dir.path().join("wing.gltf");
    std::fs::write(&gltf, gltf_with_nodes(nodes, &[0, 5]))?;
    let obj = dir.path().join("tail.obj");
    std::fs::write(&obj, "v 0 0 9\nv 1 0 9\nv 0 1 9\no fin\nf 1 2 3\n")?;
    let first = dir.path().join("a.oocf");
    let meta = convert_to(&[gltf.clone(), obj.clone()], &first)?;
    // File parts are named by the file name; the path is the source.
    let (g, o) = ("wing.gltf".to_string(), "tail.obj".to_string());
    assert_eq!(
        tree(&meta.parts),
        [
            (g, None, 0),
            ("wing".into(), Some(0), 0),
            ("flap 50%".into(), Some(1), 0),
            ("bolt".into(), Some(2), 1),
            ("bolt".into(), Some(2), 1),
            (" #7 rib\\".into(), Some(1), 1),
            ("plate".into(), Some(0), 1),
            (o, None, 0),
            ("fin".into(), Some(7), 1),
        ]
    );
    let out = dir.path().join("a.obj");
    export_obj(&first, &out, 2)?;
    let text = std::fs::read_to_string(&out)?;
    assert!(text.contains("\n# part 5 1 %20#7 rib%5C\n"), "{text}");
    assert!(text.contains("\ng "), "{text}");
    let second = dir.path().join("b.oocf");
    let back = convert_to(&[out], &second)?;
    // One source now: the file parts are ordinary parts of it.
    let no_source = |parts: &[Part]| -> Vec<Part> {
        parts
            .iter()
            .map(|p| Part {
                source: None,
                ..p.clone()
            })
            .collect()
    };
    assert_eq!(no_source(&back.parts), no_source(&meta.parts));
    Ok(())
}

#[test]
fn one_part_or_none_exports_as_before_plus_its_name() -> Res {
    let dir = tempfile::tempdir()?;
    let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
    for (name, text, parts) in [
        ("plain", format!("{quad}f 1 2 3 4\n"), 0),
        ("cube", format!("{quad}o cube\nf 1 2 3 4\n"), 1),
    ] {
        let input = dir.path().join(format!("{name}.obj"));
        std::fs::write(&input, text)?;
        let container = dir.path().join(format!("{name}.oocf"));
        let meta = convert_to(&[input], &container)?;
        assert_eq!(meta.parts.len(), parts);
        let out = dir.path().join(format!("{name}-out.obj"));
        let report = export_obj(&container, &out, 1)?;
        assert_eq!(report.parts, parts);
        let exported = std::fs::read_to_string(&out)?;
        assert_eq!(exported.contains("# oocfmt parts"), parts > 0, "{exported}");
        assert_eq!(exported.contains("\ng cube\n"), parts > 0, "{exported}");
        let ply = dir.path().join(format!("{name}.ply"));
        write_ply(&container, &ply, &ExportOptions::default(), &mut |_, _| {})?;
        let header = read_ply(&ply)?.header;
        assert_eq!(header.contains("property int part"), parts > 0, "{header}");
        let back = convert_to(&[out], &dir.path().join(format!("{name}-back.oocf")))?;
        assert_eq!(back.parts, meta.parts);
    }
    Ok(())
}

/// What the test reads of an exported PLY: its header text and each face's part.
struct Ply {
    header: String,
    face_parts: Vec<i32>,
}

/// Reads the binary PLY our exporter writes: float positions (no normals or colours), faces
/// of three uint indices, then the int part when the header has it.
fn read_ply(path: &Path) -> Res<Ply> {
    let bytes = std::fs::read(path)?;
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .ok_or("no end_header")?
        + 11;
    let header = String::from_utf8(bytes[..end].to_vec())?;
    let count = |element: &str| -> Res<usize> {
        let line = header
            .lines()
            .find(|l| l.starts_with(&format!("element {element} ")))
            .ok_or("no element line")?;
        Ok(line.rsplit(' ').next().ok_or("no count")?.parse()?)
    };
    let (vertices, faces) = (count("vertex")?, count("face")?);
    assert!(!header.contains("property float nx") && !header.contains("alpha"));
    let with_part = header.contains("property int part");
    let mut at = end + 12 * vertices;
    let mut face_parts = Vec::new();
    for _ in 0..faces {
        assert_eq!(bytes[at], 3);
        at += 13;
        if with_part {
            let b: [u8; 4] = bytes[at..at + 4].try_into()?;
            face_parts.push(i32::from_le_bytes(b));
            at += 4;
        }
    }
    assert_eq!(at, bytes.len());
    Ok(Ply { header, face_parts })
}

#[test]
fn a_ply_export_names_its_parts_in_comments_and_groups_its_faces() -> Res {
    let dir = tempfile::tempdir()?;
    let input = dir.path().join("assembly.obj");
    std::fs::write(&input, assembly_obj(12))?;
    let container = dir.path().join("a.oocf");
    let meta = convert_to(&[input], &container)?;
    assert_eq!(meta.parts.len(), 7);
    let ply = dir.path().join("a.ply");
    let mut calls = Vec::new();
    let opts = ExportOptions {
        faces_per_pass: 50,
        ..ExportOptions::default()
    };
    let report = write_ply(&container, &ply, &opts, &mut |d, t| calls.push((d, t)))?;
    assert_eq!(report.parts, 7);
    // One pass for the vertices, then ceil(288 / 50) = 6 for the faces.
    let blocks = report.triangle_blocks;
    assert_eq!(calls.len() as u64, 7 * blocks);
    assert_eq!(calls.last(), Some(&(7 * blocks, 7 * blocks)));
    let read = read_ply(&ply)?;
    let mut table = BTreeMap::new();
    for line in read.header.lines() {
        if let Some(entry) = line.strip_prefix("comment part ") {
            let mut words = entry.splitn(3, ' ');
            let id: u32 = words.next().ok_or("id")?.parse()?;
            let parent: i64 = words.next().ok_or("parent")?.parse()?;
            table.insert(id, (words.next().unwrap_or("").to_string(), parent));
        }
    }
    let want: BTreeMap<u32, (String, i64)> = (0u32..)
        .zip(&meta.parts)
        .map(|(i, p)| (i, (p.name.clone(), p.parent.map_or(-1, i64::from))))
        .collect();
    assert_eq!(table, want);
    let parts: Vec<u32> = read.face_parts.iter().map(|&p| p as u32).collect();
    assert_grouped(&parts, &meta.parts);
    // The same bytes in one pass.
    let single = dir.path().join("b.ply");
    write_ply(
        &container,
        &single,
        &ExportOptions::default(),
        &mut |_, _| {},
    )?;
    assert!(std::fs::read(&single)? == std::fs::read(&ply)?);
    Ok(())
}
