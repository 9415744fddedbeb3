//! Parts end to end: `gen cad --parts N` writes an assembly of `o`/`g` parts, `convert` keeps
//! them (in core and out of core, byte-identical for any thread count), and the file's part
//! table and per-triangle ids agree with a plain reading of the OBJ; a scene of one part or
//! none pays nothing per triangle.

use crate::common;

use common::*;

use std::collections::HashMap;
use std::path::Path;

use oocfmt::header::INCOMPAT_PART_IDS;
use oocfmt::{BlockKind, ReadOptions, Reader};

/// A triangle's corners as stored, bit for bit.
type Key = [[u32; 3]; 3];

/// What a plain reading of an OBJ file says about its parts.
#[derive(Default)]
struct ObjParts {
    /// Per face, by its corners: the part name (its `g`, else its `o`) and its object's name
    /// (more than one where faces coincide).
    face_part: HashMap<Key, Vec<(String, String)>>,
    /// Per part name: faces and the box of their corners.
    stats: HashMap<String, (u64, [f32; 3], [f32; 3])>,
    faces: u64,
}

/// Reads `v`, `o`, `g` and `f` lines; the CAD scene's faces are triangles.
fn read_obj_parts(path: &Path) -> ObjParts {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{e}"));
    let mut out = ObjParts::default();
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let (mut object, mut group) = (String::new(), None::<String>);
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f32> = it.map(|t| t.parse().unwrap_or(f32::NAN)).collect();
                positions.push([c[0], c[1], c[2]]);
            }
            Some("o") => {
                object = it.collect::<Vec<_>>().join(" ");
                group = None;
            }
            Some("g") => group = Some(it.collect::<Vec<_>>().join(" ")),
            Some("f") => {
                let v: Vec<usize> = it
                    .map(|t| t.split('/').next().unwrap_or("").parse().unwrap_or(0))
                    .collect();
                let corners = [0, 1, 2].map(|k| positions[v[k] - 1]);
                let name = group.clone().unwrap_or_else(|| object.clone());
                let s = out.stats.entry(name.clone()).or_insert((
                    0,
                    [f32::INFINITY; 3],
                    [f32::NEG_INFINITY; 3],
                ));
                s.0 += 1;
                for p in corners {
                    for ((lo, hi), c) in s.1.iter_mut().zip(s.2.iter_mut()).zip(p) {
                        *lo = lo.min(c);
                        *hi = hi.max(c);
                    }
                }
                out.faces += 1;
                out.face_part
                    .entry(corners.map(|p| p.map(f32::to_bits)))
                    .or_default()
                    .push((name, object.clone()));
            }
            _ => {}
        }
    }
    out
}

/// Checks the file's part table and every triangle record's id against the OBJ.
fn check_against_obj(file: &Path, obj: &ObjParts) {
    let reader = Reader::open(file, ReadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let meta = reader.metadata();
    let parts = &meta.parts;
    for name in obj.stats.keys() {
        assert!(
            parts.iter().any(|p| &p.name == name),
            "{name} is not a part"
        );
    }
    assert_eq!(
        parts.iter().map(|p| p.triangles).sum::<u64>(),
        meta.counts.triangles
    );
    for p in parts {
        match obj.stats.get(&p.name) {
            Some(&(n, lo, hi)) => assert_eq!(
                (p.triangles, p.bounds_min, p.bounds_max),
                (n, lo, hi),
                "{}",
                p.name
            ),
            // An assembly holds components, no faces of its own.
            None => assert_eq!(
                (p.triangles, p.bounds_min, p.bounds_max, p.parent),
                (0, [0.0; 3], [0.0; 3], None),
                "{}",
                p.name
            ),
        }
        assert_eq!(p.source, Some(0), "{}", p.name);
    }
    let attrs = meta.triangle_attributes();
    let mut records = 0u64;
    for (id, e) in reader.entries().iter().enumerate() {
        if e.kind != BlockKind::Triangle {
            continue;
        }
        let block = reader
            .read_block(id as u32)
            .unwrap_or_else(|e| panic!("{e}"));
        let t = block.triangles(attrs).unwrap_or_else(|e| panic!("{e}"));
        for i in 0..t.triangle_count() {
            let key = t
                .positions(i)
                .unwrap_or_else(|e| panic!("{e}"))
                .map(|p| p.map(f32::to_bits));
            let part = t.part(i).unwrap_or_else(|e| panic!("{e}"));
            let part = &parts[part.unwrap_or_else(|| panic!("block {id}: no part id")) as usize];
            // Its name, and a component's parent is the assembly its `g` sits in.
            let parent = part.parent.map(|p| parts[p as usize].name.clone());
            assert!(
                obj.face_part[&key]
                    .iter()
                    .any(|(name, object)| *name == part.name
                        && parent.as_ref().is_none_or(|p| p == object)),
                "block {id} triangle {i}: part {} under {parent:?}, the OBJ says {:?}",
                part.name,
                obj.face_part[&key]
            );
            records += 1;
        }
    }
    assert!(
        records >= obj.faces,
        "{records} records for {} faces",
        obj.faces
    );
}

/// `convert` with `extra` flags and `--threads threads`; returns the file's bytes.
fn convert_with(dir: &Path, obj: &str, out: &str, threads: &str, extra: &[&str]) -> Vec<u8> {
    let mut args = vec![obj, "-o", out, "--threads", threads];
    args.extend_from_slice(extra);
    convert_ok(dir, &args);
    std::fs::read(dir.join(out)).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn cad_parts_survive_in_core_and_out_of_core_builds_for_any_thread_count() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = tmp.path();
    run_ok(
        &[
            "gen", "cad", "--tris", "30000", "--seed", "3", "--parts", "300", "-o", "cad.obj",
            "--quiet",
        ],
        dir,
    );
    let obj = read_obj_parts(&dir.join("cad.obj"));
    assert!(
        obj.stats.len() > 150,
        "{} parts with faces",
        obj.stats.len()
    );
    // R-LOD-only entries take their part word from the planes' areas (in the chunks and in
    // the split passes above them), the others from the rays.
    let modes: [(&str, &[&str]); 3] = [
        ("in-core", &[]),
        ("chunked", &["--mem-limit", "16M"]),
        ("chunked-rlod", &["--mem-limit", "16M", "--lod", "rlod"]),
    ];
    for (mode, extra) in modes {
        let mut first: Option<Vec<u8>> = None;
        for threads in ["1", "2", "4"] {
            let out = format!("{mode}-{threads}.oocf");
            let bytes = convert_with(dir, "cad.obj", &out, threads, extra);
            match &first {
                None => {
                    let v = oocfmt(&["verify", "--deep", &out], dir);
                    assert_eq!(v.status.code(), Some(0), "{mode}: {}", stdout(&v));
                    check_against_obj(&dir.join(&out), &obj);
                    let r = Reader::open(&dir.join(&out), ReadOptions::default())
                        .unwrap_or_else(|e| panic!("{e}"));
                    assert_ne!(r.header().incompatible_features & INCOMPAT_PART_IDS, 0);
                    first = Some(bytes);
                }
                Some(b) => assert!(
                    *b == bytes,
                    "{mode}: {threads} threads wrote another file than 1 thread"
                ),
            }
        }
    }
    // In core and out of core: the same part table.
    let table = |f: &str| {
        Reader::open(&dir.join(f), ReadOptions::default())
            .unwrap_or_else(|e| panic!("{e}"))
            .metadata()
            .parts
            .clone()
    };
    assert_eq!(table("in-core-1.oocf"), table("chunked-1.oocf"));
    let report = convert_ok(dir, &["cad.obj", "-o", "again.oocf", "--mem-limit", "16M"]);
    assert!(
        report["out_of_core"]["chunks"].as_u64() >= Some(2),
        "{report}"
    );
    assert_eq!(report["parts"], 300, "{report}");
}

#[test]
fn a_scene_of_one_part_or_none_stores_no_ids() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let dir = tmp.path();
    let mut files = Vec::new();
    for parts in ["0", "1"] {
        let obj = format!("cad-{parts}.obj");
        run_ok(
            &[
                "gen", "cad", "--tris", "8000", "--parts", parts, "-o", &obj, "--quiet",
            ],
            dir,
        );
        let out = format!("cad-{parts}.oocf");
        convert_ok(dir, &[&obj, "-o", &out]);
        let r =
            Reader::open(&dir.join(&out), ReadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(r.header().incompatible_features & INCOMPAT_PART_IDS, 0);
        let meta = r.metadata();
        assert_eq!(
            meta.triangle_attributes(),
            meta.schema.triangle_attributes()
        );
        match parts {
            "0" => {
                assert!(meta.parts.is_empty());
                assert_eq!(r.header().minor, 2, "a file without parts stays 1.2");
            }
            _ => {
                assert_eq!(meta.parts.len(), 1);
                assert_eq!(meta.parts[0].name, "assembly-1");
                assert_eq!(meta.parts[0].triangles, 8000);
                assert_eq!(
                    (meta.parts[0].bounds_min, meta.parts[0].bounds_max),
                    (meta.scene.bounds_min, meta.scene.bounds_max)
                );
                assert_eq!(r.header().minor, 3);
            }
        }
        files.push(r);
    }
    // The blocks are the same bytes: one part adds its table entry and nothing else.
    let (none, one) = (&files[0], &files[1]);
    assert_eq!(none.entries().len(), one.entries().len());
    for id in 0..none.entries().len() as u32 {
        let (a, b) = (none.read_block(id), one.read_block(id));
        let (a, b) = (
            a.unwrap_or_else(|e| panic!("{e}")),
            b.unwrap_or_else(|e| panic!("{e}")),
        );
        assert!(a.data == b.data, "block {id}");
    }
}
