//! The scene generators and the exporter, checked from the outside: generated files are read
//! back by a small OBJ reader of the test's own, and exported containers are compared with the
//! meshes they were built from, triangle for triangle and bit for bit.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};

use oocfmt::records::triangle::{oct_decode, oct_encode};
use oocfmt::{BlockKind, EncodedBlock, ReadOptions, Reader, WriteOptions, Writer};
use oocfmt_build::kdtree::{build, KdBuildOptions};
use oocfmt_build::layout::{build_blocks, write_container, LayoutOptions};
use oocfmt_meshio::export::{self, ExportError, ExportOptions};
use oocfmt_meshio::mesh::Mesh;
use oocfmt_scenes::cad::{self, CadOptions};
use oocfmt_scenes::demo_scene;
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};

type Res = Result<(), Box<dyn std::error::Error>>;

/// Vertex and normal indices (0-based) and the material in force.
type Face = ([usize; 3], Option<[usize; 3]>, Option<String>);

/// What the test's OBJ reader keeps.
#[derive(Debug, Default)]
struct Obj {
    positions: Vec<[f32; 3]>,
    colours: Vec<Option<[f32; 3]>>,
    normals: Vec<[f32; 3]>,
    faces: Vec<Face>,
    objects: usize,
    /// `g` lines: components of the CAD scene's assemblies.
    groups: usize,
    mtllib: Option<String>,
}

fn read_obj(path: &Path) -> Obj {
    let text = std::fs::read_to_string(path).unwrap();
    let mut obj = Obj::default();
    let mut material = None;
    for (n, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        let nums = |it: std::str::SplitWhitespace<'_>| -> Vec<f32> {
            it.map(|t| {
                t.parse()
                    .unwrap_or_else(|_| panic!("line {}: {line}", n + 1))
            })
            .collect()
        };
        match it.next() {
            Some("v") => {
                let c = nums(it);
                assert!(c.len() == 3 || c.len() == 6, "line {}: {line}", n + 1);
                obj.positions.push([c[0], c[1], c[2]]);
                obj.colours.push((c.len() == 6).then(|| [c[3], c[4], c[5]]));
            }
            Some("vn") => {
                let c = nums(it);
                obj.normals.push([c[0], c[1], c[2]]);
            }
            Some("f") => {
                let corners: Vec<&str> = it.collect();
                assert_eq!(corners.len(), 3, "line {}: {line}", n + 1);
                let index = |t: &str| -> usize {
                    let i: usize = t.parse().unwrap();
                    assert!(i >= 1, "line {}: {line}", n + 1);
                    i - 1
                };
                let v = [0, 1, 2].map(|k| index(corners[k].split('/').next().unwrap()));
                let vn = corners[0]
                    .contains("//")
                    .then(|| [0, 1, 2].map(|k| index(corners[k].split("//").nth(1).unwrap())));
                for i in v {
                    assert!(i < obj.positions.len(), "line {}: {line}", n + 1);
                }
                obj.faces.push((v, vn, material.clone()));
            }
            Some("usemtl") => material = it.next().map(String::from),
            Some("mtllib") => obj.mtllib = it.next().map(String::from),
            Some("o") => obj.objects += 1,
            Some("g") => obj.groups += 1,
            Some("#") | None => {}
            Some(other) => panic!("line {}: unexpected `{other}`", n + 1),
        }
    }
    obj
}

fn read_mtl(path: &Path) -> BTreeMap<String, [f32; 3]> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = BTreeMap::new();
    let mut current = None;
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("newmtl") => current = it.next().map(String::from),
            Some("Kd") => {
                let c: Vec<f32> = it.map(|t| t.parse().unwrap()).collect();
                out.insert(current.clone().unwrap(), [c[0], c[1], c[2]]);
            }
            _ => {}
        }
    }
    out
}

/// Each directed edge of a closed, consistently wound surface appears once, and so does its
/// reverse.
fn assert_closed_and_consistent(faces: &[[usize; 3]]) {
    let mut edges: HashMap<(usize, usize), u32> = HashMap::new();
    for f in faces {
        for k in 0..3 {
            *edges.entry((f[k], f[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "edge {a}->{b} used {n} times");
        assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}->{b} has no twin");
    }
}

fn signed_volume(positions: &[[f32; 3]], faces: &[[usize; 3]]) -> f64 {
    faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| positions[i].map(f64::from));
            (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]))
                / 6.0
        })
        .sum()
}

fn mandelbulb_in_pool(path: &Path, opts: &MandelbulbOptions, threads: usize) -> Vec<u8> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| mandelbulb::write_obj(path, opts, &mut |_, _| {}))
        .unwrap();
    std::fs::read(path).unwrap()
}

#[test]
fn the_mandelbulb_is_closed_outward_shared_and_thread_independent() -> Res {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("bulb.obj");
    let opts = MandelbulbOptions {
        resolution: Some(40),
        seed: 5,
        ..MandelbulbOptions::default()
    };
    let mut slabs = 0;
    let report = mandelbulb::write_obj(&path, &opts, &mut |done, total| {
        assert_eq!((done, total), (slabs + 1, 40));
        slabs = done;
    })?;
    let bytes = std::fs::read(&path)?;
    assert_eq!(report.bytes, bytes.len() as u64);
    let obj = read_obj(&path);
    assert_eq!(obj.faces.len() as u64, report.triangles);
    assert_eq!(obj.positions.len() as u64, report.vertices);
    assert!(report.triangles > 10_000, "{report:?}");
    let faces: Vec<[usize; 3]> = obj.faces.iter().map(|f| f.0).collect();
    assert_closed_and_consistent(&faces);
    // Outward winding: the enclosed volume comes out positive (the sampled box is 15.6).
    let volume = signed_volume(&obj.positions, &faces);
    assert!(volume > 1.0 && volume < 8.0, "{volume}");
    // Every vertex is written once and used: a closed surface has V = F/2 + χ, where
    // per-slab or per-cell vertices would give three times as many.
    let used: HashSet<usize> = faces.iter().flatten().copied().collect();
    assert_eq!(used.len(), obj.positions.len());
    assert!(obj.positions.len() <= faces.len() / 2 + 200);
    for threads in [1, 3] {
        assert!(
            mandelbulb_in_pool(&path, &opts, threads) == bytes,
            "{threads} threads"
        );
    }
    let other = mandelbulb_in_pool(&path, &MandelbulbOptions { seed: 6, ..opts }, 2);
    assert!(other != bytes);
    Ok(())
}

#[test]
fn coarse_mandelbulbs_are_closed_too() -> Res {
    // Coarse cells put the iso-level far out: the grid's margin must still hold the surface.
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("coarse.obj");
    for resolution in [8, 9, 12, 17] {
        for seed in [0, 1, 2] {
            let opts = MandelbulbOptions {
                resolution: Some(resolution),
                seed,
                ..MandelbulbOptions::default()
            };
            mandelbulb::write_obj(&path, &opts, &mut |_, _| {})?;
            let obj = read_obj(&path);
            assert!(!obj.faces.is_empty());
            let faces: Vec<[usize; 3]> = obj.faces.iter().map(|f| f.0).collect();
            assert_closed_and_consistent(&faces);
            assert!(signed_volume(&obj.positions, &faces) > 0.0);
        }
    }
    Ok(())
}

#[test]
fn the_mandelbulb_lands_near_its_target() -> Res {
    let dir = tempfile::tempdir()?;
    for target in [100_000, 300_000] {
        let path = dir.path().join(format!("{target}.obj"));
        let opts = MandelbulbOptions {
            triangles: target,
            seed: 11,
            resolution: None,
        };
        let report = mandelbulb::write_obj(&path, &opts, &mut |_, _| {})?;
        let off = report.triangles as f64 / target as f64;
        assert!((0.8..=1.2).contains(&off), "{target}: {report:?}");
    }
    Ok(())
}

#[test]
fn the_cad_scene_has_its_parts_materials_and_overlaps() -> Res {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("cad.obj");
    let opts = CadOptions {
        triangles: 60_000,
        seed: 9,
        normals: true,
        parts: None,
    };
    let report = cad::write_obj(&path, &opts, &mut |_, _| {})?;
    assert_eq!(report.triangles, 60_000);
    let bytes = std::fs::read(&path)?;
    assert_eq!(report.bytes, bytes.len() as u64);
    let obj = read_obj(&path);
    assert_eq!(obj.faces.len(), 60_000);
    assert_eq!(obj.positions.len() as u64, report.vertices);
    assert_eq!(obj.normals.len(), obj.positions.len());
    // Assemblies (`o`) of components (`g`), hundreds of parts in all.
    assert!(obj.objects > 20, "{} assemblies", obj.objects);
    assert!(obj.groups > 3 * obj.objects, "{} components", obj.groups);
    assert_eq!(obj.mtllib.as_deref(), Some("cad.mtl"));
    let mtl = read_mtl(&dir.path().join("cad.mtl"));
    let used: HashSet<&str> = obj.faces.iter().filter_map(|f| f.2.as_deref()).collect();
    assert!(used.len() >= 6, "{used:?}");
    for m in &used {
        assert!(mtl.contains_key(*m), "{m} is not in the .mtl");
    }
    // Faces agree with their normals (jitter is far smaller than the parts).
    for (v, n, _) in &obj.faces {
        let p = v.map(|i| obj.positions[i].map(f64::from));
        let e1 = [0, 1, 2].map(|a| p[1][a] - p[0][a]);
        let e2 = [0, 1, 2].map(|a| p[2][a] - p[0][a]);
        let g = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let vn = n.expect("normals")[0];
        let d: f64 = (0..3).map(|a| g[a] * f64::from(obj.normals[vn][a])).sum();
        assert!(d > 0.0, "face {v:?}");
    }
    // Coplanar overlaps: some axis-aligned plane holds faces of two different panels (each
    // panel is a component, a `g` under its assembly's `o`).
    let mut planes: HashMap<(usize, u32), HashSet<usize>> = HashMap::new();
    let mut object_of_face = Vec::new();
    let mut object = 0;
    for line in std::str::from_utf8(&bytes)?.lines() {
        if line.starts_with("g ") {
            object += 1;
        } else if line.starts_with("f ") {
            object_of_face.push(object);
        }
    }
    for ((v, _, m), object) in obj.faces.iter().zip(&object_of_face) {
        if !m.as_deref().is_some_and(|m| m.starts_with("panel")) {
            continue;
        }
        for a in 0..3 {
            let c = v.map(|i| obj.positions[i][a].to_bits());
            if c[0] == c[1] && c[1] == c[2] {
                planes.entry((a, c[0])).or_default().insert(*object);
            }
        }
    }
    assert!(
        planes.values().any(|objects| objects.len() >= 2),
        "no two panels share a plane"
    );
    // Deterministic by seed (the same name elsewhere: the `mtllib` line names the file).
    let elsewhere = tempfile::tempdir()?;
    let again = elsewhere.path().join("cad.obj");
    cad::write_obj(&again, &opts, &mut |_, _| {})?;
    assert!(std::fs::read(&again)? == bytes);
    cad::write_obj(&again, &CadOptions { seed: 10, ..opts }, &mut |_, _| {})?;
    assert!(std::fs::read(&again)? != bytes);
    Ok(())
}

/// One corner as compared: position bits, decoded-normal bits, RGB.
type Corner = ([u32; 3], Option<[u32; 3]>, Option<[u8; 3]>);
/// A triangle as compared: corners rotated so the smallest leads (winding kept), material.
type Key = ([Corner; 3], Option<String>);

fn key(mut corners: [Corner; 3], material: Option<String>) -> Key {
    let first = (0..3).min_by_key(|&k| corners[k]).unwrap_or(0);
    corners.rotate_left(first);
    (corners, material)
}

fn multiset(keys: impl IntoIterator<Item = Key>) -> BTreeMap<Key, usize> {
    let mut m = BTreeMap::new();
    for k in keys {
        *m.entry(k).or_insert(0) += 1;
    }
    m
}

fn mesh_keys(mesh: &Mesh) -> BTreeMap<Key, usize> {
    multiset(mesh.triangles.iter().enumerate().map(|(t, tri)| {
        let corners = tri.map(|v| {
            let v = v as usize;
            (
                mesh.positions[v].map(f32::to_bits),
                mesh.normals
                    .as_ref()
                    .map(|n| oct_decode(oct_encode(n[v])).map(f32::to_bits)),
                mesh.colours.as_ref().map(|c| [c[v][0], c[v][1], c[v][2]]),
            )
        });
        // The exporter makes names single words for OBJ's `usemtl`.
        let material = mesh.materials.as_ref().map(|m| {
            mesh.material_table[usize::from(m[t])]
                .name
                .replace(' ', "_")
        });
        key(corners, material)
    }))
}

/// Compares two multisets, reporting a few differences rather than both in full.
fn assert_same(got: &BTreeMap<Key, usize>, want: &BTreeMap<Key, usize>) {
    let total = |m: &BTreeMap<Key, usize>| m.values().sum::<usize>();
    let missing: Vec<_> = want
        .iter()
        .filter(|(k, n)| got.get(*k) != Some(n))
        .take(3)
        .collect();
    let extra: Vec<_> = got
        .iter()
        .filter(|(k, n)| want.get(*k) != Some(n))
        .take(3)
        .collect();
    assert!(
        missing.is_empty() && extra.is_empty(),
        "{} triangles exported, {} expected; expected but not exported (first 3): {missing:?}; \
         exported but not expected: {extra:?}",
        total(got),
        total(want)
    );
}

fn obj_keys(obj: &Obj) -> BTreeMap<Key, usize> {
    multiset(obj.faces.iter().map(|(v, vn, material)| {
        let corners = [0, 1, 2].map(|k| {
            let i = v[k];
            (
                obj.positions[i].map(f32::to_bits),
                vn.map(|n| obj.normals[n[k]].map(f32::to_bits)),
                obj.colours[i].map(|c| c.map(|x| (x * 255.0).round() as u8)),
            )
        });
        key(corners, material.clone())
    }))
}

/// The demo sphere plus long slivers through it: slivers cross many split planes, so their
/// copies land in several triangle blocks.
fn straddling_mesh() -> Mesh {
    let mut mesh = demo_scene(3000);
    let mut state = 0x1234_5678_u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32 * 2.4 - 1.2
    };
    for i in 0..40u32 {
        let base = mesh.positions.len() as u32;
        let a = [next(), next(), next()];
        let b = a.map(|c| -c);
        let c = [next(), next(), next()];
        mesh.positions.extend([a, b, c]);
        if let Some(n) = mesh.normals.as_mut() {
            n.extend([[0.0, 0.0, 1.0], [0.6, 0.0, -0.8], [-1.0, 0.0, 0.0]]);
        }
        if let Some(c) = mesh.colours.as_mut() {
            c.extend([[10, 20, 30, 255], [200, 100, 0, 128], [1, 2, 3, 4]]);
        }
        mesh.triangles.push([base, base + 1, base + 2]);
        if let Some(m) = mesh.materials.as_mut() {
            m.push((i % 2) as u16);
        }
    }
    mesh.material_table[1].name = "cap paint".into();
    mesh
}

fn small_blocks() -> LayoutOptions {
    LayoutOptions {
        write: WriteOptions::default().with_block_size(4096).unwrap(),
        ..LayoutOptions::default()
    }
}

fn write_mesh(mesh: &Mesh, path: &Path) -> oocfmt::Metadata {
    let tree = build(
        mesh,
        &KdBuildOptions {
            max_leaf_triangles: 6,
            ..KdBuildOptions::default()
        },
    )
    .unwrap();
    write_container(path, mesh, &tree, &small_blocks())
        .unwrap()
        .1
}

#[test]
fn an_obj_export_gives_back_every_triangle_bit_for_bit() -> Res {
    let dir = tempfile::tempdir()?;
    let mesh = straddling_mesh();
    let container = dir.path().join("m.oocf");
    let meta = write_mesh(&mesh, &container);
    assert!(
        meta.counts.triangle_records > meta.counts.triangles,
        "no triangle was copied into a second block: {:?}",
        meta.counts
    );
    let out = dir.path().join("m.obj");
    let mut calls = Vec::new();
    let report = export::write_obj(&container, &out, &ExportOptions::default(), &mut |d, t| {
        calls.push((d, t))
    })?;
    let blocks = Reader::open(&container, ReadOptions::default())?
        .entries()
        .iter()
        .filter(|e| e.kind == BlockKind::Triangle)
        .count() as u64;
    assert!(blocks > 1);
    assert_eq!(calls.len() as u64, blocks);
    assert_eq!(calls.last(), Some(&(blocks, blocks)));
    assert_eq!(report.triangles, mesh.triangles.len() as u64);
    assert!(report.bit_exact && report.max_abs_error == 0.0);
    assert_eq!(report.bytes, std::fs::metadata(&out)?.len());
    let obj = read_obj(&out);
    assert_eq!(obj.positions.len() as u64, report.vertices);
    assert_same(&obj_keys(&obj), &mesh_keys(&mesh));
    // The materials went to the .mtl, names made single words.
    let mtl = read_mtl(&dir.path().join("m.mtl"));
    assert_eq!(obj.mtllib.as_deref(), Some("m.mtl"));
    assert_eq!(
        mtl.keys().cloned().collect::<Vec<_>>(),
        ["body", "cap_paint"]
    );
    assert_eq!(mtl.get("body"), Some(&mesh.material_table[0].diffuse));
    Ok(())
}

/// The test's reader for the binary PLY the exporter writes.
#[derive(Debug, Default)]
struct Ply {
    vertex_props: Vec<(String, String)>,
    face_props: Vec<String>,
    vertices: Vec<Vec<f64>>,
    faces: Vec<([usize; 3], Option<u16>)>,
    comments: Vec<String>,
}

fn read_ply(path: &Path) -> Ply {
    let bytes = std::fs::read(path).unwrap();
    let end = b"end_header\n";
    let at = bytes
        .windows(end.len())
        .position(|w| w == end)
        .expect("end_header")
        + end.len();
    let header = std::str::from_utf8(&bytes[..at]).unwrap();
    let mut ply = Ply::default();
    let (mut nv, mut nf, mut element) = (0usize, 0usize, "");
    let mut lines = header.lines();
    assert_eq!(lines.next(), Some("ply"));
    assert_eq!(lines.next(), Some("format binary_little_endian 1.0"));
    for line in lines {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["comment", rest @ ..] => ply.comments.push(rest.join(" ")),
            ["element", "vertex", n] => (nv, element) = (n.parse().unwrap(), "vertex"),
            ["element", "face", n] => (nf, element) = (n.parse().unwrap(), "face"),
            ["property", "list", "uchar", "uint", "vertex_indices"] => {
                ply.face_props.push("vertex_indices".into())
            }
            ["property", ty, name] if element == "vertex" => {
                ply.vertex_props.push((ty.to_string(), name.to_string()))
            }
            ["property", "ushort", "material_index"] => {
                ply.face_props.push("material_index".into())
            }
            // A container with parts (the `parts` vector) adds each face's part id.
            ["property", "int", "part"] => ply.face_props.push("part".into()),
            ["end_header"] => {}
            other => panic!("unexpected header line {other:?}"),
        }
    }
    let mut pos = at;
    let mut take = |n: usize| {
        let s = &bytes[pos..pos + n];
        pos += n;
        s
    };
    for _ in 0..nv {
        let mut v = Vec::new();
        for (ty, _) in &ply.vertex_props {
            v.push(match ty.as_str() {
                "float" => f64::from(f32::from_le_bytes(take(4).try_into().unwrap())),
                "double" => f64::from_le_bytes(take(8).try_into().unwrap()),
                "uchar" => f64::from(take(1)[0]),
                other => panic!("type {other}"),
            });
        }
        ply.vertices.push(v);
    }
    for _ in 0..nf {
        assert_eq!(take(1)[0], 3);
        let idx = [0; 3].map(|_| u32::from_le_bytes(take(4).try_into().unwrap()) as usize);
        let has = |p: &str| ply.face_props.iter().any(|f| f == p);
        let material =
            has("material_index").then(|| u16::from_le_bytes(take(2).try_into().unwrap()));
        if has("part") {
            take(4);
        }
        ply.faces.push((idx, material));
    }
    assert_eq!(pos, bytes.len(), "trailing bytes");
    ply
}

#[test]
fn a_ply_export_gives_back_every_triangle_bit_for_bit() -> Res {
    let dir = tempfile::tempdir()?;
    let mesh = straddling_mesh();
    let container = dir.path().join("m.oocf");
    write_mesh(&mesh, &container);
    let out = dir.path().join("m.ply");
    let report = export::write_ply(&container, &out, &ExportOptions::default(), &mut |_, _| {})?;
    assert_eq!(report.bytes, std::fs::metadata(&out)?.len());
    let ply = read_ply(&out);
    assert_eq!(ply.vertices.len() as u64, report.vertices);
    assert_eq!(ply.faces.len(), mesh.triangles.len());
    let names: Vec<&str> = ply.vertex_props.iter().map(|p| p.1.as_str()).collect();
    assert_eq!(
        names,
        ["x", "y", "z", "nx", "ny", "nz", "red", "green", "blue", "alpha"]
    );
    assert!(ply
        .comments
        .iter()
        .any(|c| c.starts_with("material 1 cap_paint")));
    let got = multiset(ply.faces.iter().map(|(v, m)| {
        let corners = [0, 1, 2].map(|k| {
            let r = &ply.vertices[v[k]];
            (
                [r[0], r[1], r[2]].map(|c| (c as f32).to_bits()),
                Some([r[3], r[4], r[5]].map(|c| (c as f32).to_bits())),
                Some([r[6], r[7], r[8]].map(|c| c as u8)),
            )
        });
        let material = m.map(|m| mesh.material_table[usize::from(m)].name.replace(' ', "_"));
        key(corners, material)
    }));
    assert_same(&got, &mesh_keys(&mesh));
    // Alpha survives in PLY.
    let alphas: HashSet<u8> = ply.vertices.iter().map(|r| r[9] as u8).collect();
    assert!(alphas.contains(&128) && alphas.contains(&255));
    Ok(())
}

fn vectors() -> Vec<PathBuf> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec/vectors"));
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "oocf"))
        .collect();
    v.sort();
    v
}

#[test]
fn every_spec_vector_exports_all_its_triangles() -> Res {
    let dir = tempfile::tempdir()?;
    let paths = vectors();
    assert!(paths.len() >= 4);
    for path in paths {
        let expected = Reader::open(&path, ReadOptions::default())?
            .metadata()
            .counts
            .triangles;
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let obj_path = dir.path().join(format!("{name}.obj"));
        let r = export::write_obj(&path, &obj_path, &ExportOptions::default(), &mut |_, _| {})?;
        assert_eq!(r.triangles, expected, "{name}");
        assert_eq!(read_obj(&obj_path).faces.len() as u64, expected, "{name}");
        let ply_path = dir.path().join(format!("{name}.ply"));
        let r = export::write_ply(&path, &ply_path, &ExportOptions::default(), &mut |_, _| {})?;
        assert_eq!(r.triangles, expected, "{name}");
        assert_eq!(read_ply(&ply_path).faces.len() as u64, expected, "{name}");
    }
    Ok(())
}

/// A container like `write_mesh` makes, with a scene origin set.
fn write_with_origin(mesh: &Mesh, path: &Path, origin: [f64; 3]) -> Res {
    let tree = build(mesh, &KdBuildOptions::default())?;
    let opts = small_blocks();
    let mut container = build_blocks(mesh, &tree, &opts)?;
    container.metadata.scene.origin = origin;
    let mut w = Writer::create(path, opts.write)?;
    for b in &container.blocks {
        w.write_encoded(EncodedBlock::encode(
            opts.write.codec,
            b.kind,
            b.level,
            b.item_count,
            &b.raw,
        )?)?;
    }
    w.finish(&container.metadata)?;
    Ok(())
}

#[test]
fn an_origin_is_added_in_f64_and_reported() -> Res {
    let dir = tempfile::tempdir()?;
    let mesh = demo_scene(500);
    let container = dir.path().join("o.oocf");
    let origin = [1.0e7, -2.5, 0.1];
    write_with_origin(&mesh, &container, origin)?;
    let out = dir.path().join("o.obj");
    let r = export::write_obj(&container, &out, &ExportOptions::default(), &mut |_, _| {})?;
    assert!(!r.bit_exact);
    assert_eq!(r.origin, origin);
    assert!(r.max_abs_error > 0.0 && r.max_abs_error < 1e-8, "{r:?}");
    // Every written coordinate is within the reported error of origin + stored.
    let text = std::fs::read_to_string(&out)?;
    let written: Vec<[f64; 3]> = text
        .lines()
        .filter(|l| l.starts_with("v "))
        .map(|l| {
            let c: Vec<f64> = l
                .split_whitespace()
                .skip(1)
                .map(|t| t.parse().unwrap())
                .collect();
            [c[0], c[1], c[2]]
        })
        .collect();
    let stored: HashSet<[u32; 3]> = mesh.positions.iter().map(|p| p.map(f32::to_bits)).collect();
    for w in &written {
        let back = [0, 1, 2].map(|a| ((w[a] - origin[a]) as f32).to_bits());
        assert!(stored.contains(&back), "{w:?}");
    }
    let ply = dir.path().join("o.ply");
    let r = export::write_ply(&container, &ply, &ExportOptions::default(), &mut |_, _| {})?;
    assert!(!r.bit_exact);
    assert_eq!(read_ply(&ply).vertex_props[0].0, "double");
    // Stored coordinates stay bit-exact when asked for, and the origin is noted.
    let stay = ExportOptions {
        world_coordinates: false,
        ..ExportOptions::default()
    };
    let r = export::write_obj(&container, &out, &stay, &mut |_, _| {})?;
    assert!(r.bit_exact && r.origin == [0.0; 3]);
    let obj = read_obj(&out);
    assert_same(&obj_keys(&obj), &mesh_keys(&mesh));
    assert!(
        std::fs::read_to_string(&out)?.contains("relative to the scene origin 10000000 -2.5 0.1")
    );
    Ok(())
}

#[test]
fn a_failed_export_leaves_nothing_and_keeps_an_old_file() -> Res {
    let dir = tempfile::tempdir()?;
    let mesh = straddling_mesh();
    let container = dir.path().join("m.oocf");
    write_mesh(&mesh, &container);
    // Corrupt one byte of the last triangle block: its checksum fails mid-export.
    let reader = Reader::open(&container, ReadOptions::default())?;
    let last = reader
        .entries()
        .iter()
        .rfind(|e| e.kind == BlockKind::Triangle)
        .copied()
        .unwrap();
    drop(reader);
    let mut bytes = std::fs::read(&container)?;
    bytes[last.offset as usize + 20] ^= 0x55;
    let bad = dir.path().join("bad.oocf");
    std::fs::write(&bad, &bytes)?;
    for ext in ["obj", "ply"] {
        let out = dir.path().join(format!("out.{ext}"));
        std::fs::write(&out, "old")?;
        let opts = ExportOptions::default();
        let r = if ext == "obj" {
            export::write_obj(&bad, &out, &opts, &mut |_, _| {})
        } else {
            export::write_ply(&bad, &out, &opts, &mut |_, _| {})
        };
        let err = r.expect_err("a corrupt block must fail the export");
        assert!(matches!(err, ExportError::Format(_)), "{err}");
        assert!(err.to_string().contains("bad.oocf"), "{err}");
        assert_eq!(std::fs::read_to_string(&out)?, "old");
    }
    let names: Vec<String> = std::fs::read_dir(dir.path())?
        .map(|e| e.map(|e| e.file_name().to_string_lossy().into_owned()))
        .collect::<Result<_, _>>()?;
    assert!(
        names
            .iter()
            .all(|n| !n.ends_with(".partial") && n != "out.mtl"),
        "{names:?}"
    );
    // A missing container and an unwritable destination are errors that name the path.
    let missing = dir.path().join("missing.oocf");
    let err = export::write_obj(
        &missing,
        &dir.path().join("x.obj"),
        &ExportOptions::default(),
        &mut |_, _| {},
    )
    .expect_err("missing input");
    assert!(err.to_string().contains("missing.oocf"), "{err}");
    let nowhere = dir.path().join("no/such/dir/x.obj");
    let err = export::write_obj(
        &container,
        &nowhere,
        &ExportOptions::default(),
        &mut |_, _| {},
    )
    .expect_err("missing folder");
    assert!(
        matches!(err, ExportError::Write(_)) && err.to_string().contains("no/such/dir"),
        "{err}"
    );
    Ok(())
}
