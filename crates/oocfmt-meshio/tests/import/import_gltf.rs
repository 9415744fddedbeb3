//! The glTF importer on files written by the tests: every mode, transform and attribute it
//! reads, and every malformed input it must refuse with a clear error instead of a panic,
//! a hang or an unbounded read (including the inputs that crash the gltf crate's own
//! readers, validation and GLB parser).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use base64::Engine;
use oocfmt::metadata::Material;
use oocfmt_meshio::import::gltf::{import, GltfOptions};
use oocfmt_meshio::import::{
    DropReason, ImportError, ImportReport, InputTriangle, Location, MeshSink, Skipped, TriangleSink,
};
use oocfmt_meshio::mesh::Mesh;
use serde_json::{json, Value};

use crate::import_obj::{node, part_tree};

const BYTE: u32 = 5120;
const UBYTE: u32 = 5121;
const SHORT: u32 = 5122;
const USHORT: u32 = 5123;
const UINT: u32 = 5125;
const FLOAT: u32 = 5126;

const TRI: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Collects binary data, buffer views and accessors for one buffer.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    fn view(&mut self, bytes: &[u8], stride: Option<usize>) -> usize {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()});
        if let Some(s) = stride {
            v["byteStride"] = json!(s);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    fn accessor(&mut self, view: Option<usize>, comp: u32, count: usize, ty: &str) -> usize {
        let mut a = json!({"componentType": comp, "count": count, "type": ty});
        if let Some(v) = view {
            a["bufferView"] = json!(v);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn positions(&mut self, p: &[[f32; 3]]) -> usize {
        let flat: Vec<f32> = p.iter().flatten().copied().collect();
        let v = self.view(&f32_bytes(&flat), None);
        self.accessor(Some(v), FLOAT, p.len(), "VEC3")
    }

    fn floats(&mut self, values: &[f32], ty: &str, per: usize) -> usize {
        let v = self.view(&f32_bytes(values), None);
        self.accessor(Some(v), FLOAT, values.len() / per, ty)
    }

    fn indices(&mut self, comp: u32, idx: &[u32]) -> usize {
        let bytes: Vec<u8> = match comp {
            UBYTE => idx.iter().map(|&i| i as u8).collect(),
            USHORT => idx.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect(),
            _ => idx.iter().flat_map(|&i| i.to_le_bytes()).collect(),
        };
        let v = self.view(&bytes, None);
        self.accessor(Some(v), comp, idx.len(), "SCALAR")
    }

    /// The document: `rest` plus asset, buffer, views and accessors.
    fn finish(mut self, rest: Value) -> (Value, Vec<u8>) {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let mut doc = json!({
            "asset": {"version": "2.0"},
            "buffers": [{"byteLength": self.bin.len()}],
            "bufferViews": self.views,
            "accessors": self.accessors,
        });
        if let Value::Object(m) = rest {
            for (k, v) in m {
                doc[k] = v;
            }
        }
        (doc, self.bin)
    }
}

/// One mesh of the given primitives, placed by node 0 of scene 0.
fn one_mesh(primitives: Value) -> Value {
    json!({
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": primitives}],
    })
}

fn triangle_doc() -> (Value, Vec<u8>) {
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    b.finish(one_mesh(json!([{"attributes": {"POSITION": p}}])))
}

fn write_gltf(dir: &Path, doc: &Value, bin: &[u8]) -> PathBuf {
    let mut doc = doc.clone();
    if doc["buffers"][0].is_object() && doc["buffers"][0].get("uri").is_none() {
        doc["buffers"][0]["uri"] = json!("model.bin");
    }
    std::fs::write(dir.join("model.bin"), bin).unwrap();
    let path = dir.join("model.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    path
}

fn glb_bytes(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).unwrap();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

fn write_glb(dir: &Path, doc: &Value, bin: &[u8]) -> PathBuf {
    let path = dir.join("model.glb");
    std::fs::write(&path, glb_bytes(doc, bin)).unwrap();
    path
}

fn run_with(path: &Path, opts: &GltfOptions) -> Result<(Mesh, ImportReport), ImportError> {
    let mut sink = MeshSink::new(false);
    import(path, &mut sink, opts)?;
    sink.finish()
}

fn run(path: &Path) -> Result<(Mesh, ImportReport), ImportError> {
    run_with(path, &GltfOptions::default())
}

fn gltf_ok(doc: &Value, bin: &[u8]) -> (Mesh, ImportReport) {
    let dir = tempfile::tempdir().unwrap();
    let path = write_gltf(dir.path(), doc, bin);
    run(&path).unwrap_or_else(|e| panic!("import failed: {e}"))
}

/// The error importing `doc`, as a message; the file name must be in it.
fn gltf_err(doc: &Value, bin: &[u8]) -> (ImportError, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = write_gltf(dir.path(), doc, bin);
    let mut sink = MeshSink::new(false);
    let e = import(&path, &mut sink, &GltfOptions::default()).expect_err("import succeeded");
    let msg = e.to_string();
    assert!(
        msg.contains("model.gltf") || msg.contains("model.bin"),
        "{msg}"
    );
    (e, msg)
}

fn triangles(mesh: &Mesh) -> Vec<[[f32; 3]; 3]> {
    mesh.triangles
        .iter()
        .map(|t| t.map(|i| mesh.positions[i as usize]))
        .collect()
}

fn close(a: [f32; 3], b: [f64; 3], tol: f64) -> bool {
    a.iter()
        .zip(&b)
        .all(|(x, y)| (f64::from(*x) - y).abs() <= tol)
}

fn geometric_normal(t: &[[f32; 3]; 3]) -> [f64; 3] {
    let d = |a: [f32; 3], b: [f32; 3]| [0, 1, 2].map(|k| f64::from(b[k]) - f64::from(a[k]));
    let (u, v) = (d(t[0], t[1]), d(t[0], t[2]));
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    n.map(|c| c / len)
}

// ---------------------------------------------------------------------------------------
// Happy paths

#[test]
fn indexed_triangles_with_each_index_type() {
    let quad = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    for comp in [UBYTE, USHORT, UINT] {
        let mut b = Builder::default();
        let p = b.positions(&quad);
        let i = b.indices(comp, &[0, 1, 2, 0, 2, 3]);
        let (doc, bin) = b.finish(one_mesh(
            json!([{"attributes": {"POSITION": p}, "indices": i}]),
        ));
        let (mesh, report) = gltf_ok(&doc, &bin);
        assert_eq!(
            triangles(&mesh),
            vec![[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]],
            "component type {comp}"
        );
        assert_eq!((report.triangles_in, report.triangles_out), (2, 2));
        assert!(mesh.normals.is_none() && mesh.colours.is_none() && mesh.materials.is_none());
    }
}

#[test]
fn non_indexed_triangles_and_a_ragged_tail_is_warned() {
    let mut b = Builder::default();
    let mut pts = TRI.to_vec();
    pts.extend([
        [5.0, 5.0, 5.0],
        [6.0, 5.0, 5.0],
        [5.0, 6.0, 5.0],
        [9.0, 9.0, 9.0],
    ]);
    let p = b.positions(&pts);
    let (doc, bin) = b.finish(one_mesh(json!([{"attributes": {"POSITION": p}}])));
    let (mesh, report) = gltf_ok(&doc, &bin);
    assert_eq!(triangles(&mesh), vec![TRI, [pts[3], pts[4], pts[5]]]);
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("mesh 0 primitive 0") && w.contains("last 1")),
        "{:?}",
        report.warnings
    );
}

#[test]
fn triangle_strip_alternates_winding_as_the_spec_says() {
    let v = [
        [0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [2.0, 0.0, 0.0],
    ];
    let mut b = Builder::default();
    let p = b.positions(&v);
    let (doc, bin) = b.finish(one_mesh(
        json!([{"attributes": {"POSITION": p}, "mode": 5}]),
    ));
    let (mesh, _) = gltf_ok(&doc, &bin);
    let tris = triangles(&mesh);
    // p_i = {v_i, v_(i+1+i%2), v_(i+2-i%2)}
    assert_eq!(
        tris,
        vec![[v[0], v[1], v[2]], [v[1], v[3], v[2]], [v[2], v[3], v[4]]]
    );
    for t in &tris {
        assert_eq!(geometric_normal(t), [0.0, 0.0, -1.0], "all face one way");
    }
}

#[test]
fn triangle_fan_turns_around_the_first_vertex() {
    let v = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [-1.0, 1.0, 0.0],
    ];
    let mut b = Builder::default();
    let p = b.positions(&v);
    let i = b.indices(USHORT, &[0, 1, 2, 3, 4]);
    let (doc, bin) = b.finish(one_mesh(
        json!([{"attributes": {"POSITION": p}, "indices": i, "mode": 6}]),
    ));
    let (mesh, _) = gltf_ok(&doc, &bin);
    // p_i = {v_(i+1), v_(i+2), v_0}
    assert_eq!(
        triangles(&mesh),
        vec![[v[1], v[2], v[0]], [v[2], v[3], v[0]], [v[3], v[4], v[0]]]
    );
}

#[test]
fn points_and_lines_are_skipped_and_counted() {
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    let (doc, bin) = b.finish(one_mesh(json!([
        {"attributes": {"POSITION": p}, "mode": 0},
        {"attributes": {"POSITION": p}, "mode": 1},
        {"attributes": {"POSITION": p}, "mode": 2},
        {"attributes": {"POSITION": p}, "mode": 3},
        {"attributes": {"POSITION": p}},
    ])));
    let (mesh, report) = gltf_ok(&doc, &bin);
    assert_eq!(mesh.triangles.len(), 1);
    assert_eq!(
        report.skipped.get(&Skipped::NonTrianglePrimitives),
        Some(&4)
    );
}

#[test]
fn node_hierarchy_composes_parent_times_child_with_trs_as_t_r_s() {
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let mut b = Builder::default();
    let p = b.positions(&[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    let (doc, bin) = b.finish(json!({
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            // 2× scale, then 90° about z, then +10 x.
            {"children": [1], "translation": [10.0, 0.0, 0.0], "rotation": [0.0, 0.0, h, h],
             "scale": [2.0, 2.0, 2.0]},
            // column-major: translation (0, 1, 0) in the last column.
            {"children": [2], "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,1,0,1]},
            {"mesh": 0, "scale": [1.0, 1.0, 3.0]},
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": p}}]}],
    }));
    let (mesh, _) = gltf_ok(&doc, &bin);
    let t = triangles(&mesh);
    assert_eq!(t.len(), 1);
    // By hand: grandchild scale, child translation, parent scale, rotation, translation.
    // (1,0,0) -> (1,0,0) -> (1,1,0) -> (2,2,0) -> (-2,2,0) -> (8,2,0)
    // (0,1,0) -> (0,1,0) -> (0,2,0) -> (0,4,0) -> (-4,0,0) -> (6,0,0)
    // (0,0,1) -> (0,0,3) -> (0,1,3) -> (0,2,6) -> (-2,0,6) -> (8,0,6)
    let want = [[8.0, 2.0, 0.0], [6.0, 0.0, 0.0], [8.0, 0.0, 6.0]];
    for k in 0..3 {
        assert!(close(t[0][k], want[k], 1e-5), "{:?} vs {:?}", t[0], want);
    }
}

#[test]
fn a_mirroring_node_keeps_front_faces_front() {
    // A tilted triangle whose normal attribute is its outward (counter-clockwise) normal.
    let pts = [[0.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 0.0]];
    let n = geometric_normal(&pts);
    assert!(close([-0.5f32.sqrt(), 0.0, 0.5f32.sqrt()], n, 1e-6));
    let nf = [n[0] as f32, n[1] as f32, n[2] as f32];
    for node in [
        json!({"mesh": 0, "scale": [-2.0, 1.0, 1.0]}),
        json!({"mesh": 0, "matrix": [1,0,0,0, 0,1,0,0, 0,0,-3,0, 0,0,0,1]}),
    ] {
        let mut b = Builder::default();
        let p = b.positions(&pts);
        let nn = b.floats(&[nf, nf, nf].concat(), "VEC3", 3);
        let (doc, bin) = b.finish(json!({
            "scenes": [{"nodes": [0]}],
            "nodes": [node.clone()],
            "meshes": [{"primitives": [{"attributes": {"POSITION": p, "NORMAL": nn}}]}],
        }));
        let (mesh, _) = gltf_ok(&doc, &bin);
        let t = triangles(&mesh)[0];
        let geometric = geometric_normal(&t);
        let normals = mesh.normals.as_ref().unwrap();
        for k in 0..3 {
            let vn = normals[mesh.triangles[0][k] as usize];
            assert!(
                close(vn, geometric, 1e-6),
                "{node}: corner normal {vn:?}, geometric {geometric:?}"
            );
        }
        // The inverse transpose of the mirror applied to n, by hand.
        let s = if node.get("scale").is_some() {
            [-2.0, 1.0, 1.0]
        } else {
            [1.0, 1.0, -3.0]
        };
        let m = [n[0] / s[0], n[1] / s[1], n[2] / s[2]];
        let len = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
        assert!(close(
            [
                geometric[0] as f32,
                geometric[1] as f32,
                geometric[2] as f32
            ],
            m.map(|c| c / len),
            1e-6
        ));
    }
}

#[test]
fn normals_rotate_with_their_node() {
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    let n = b.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0], "VEC3", 3);
    let (doc, bin) = b.finish(json!({
        "scenes": [{"nodes": [0]}],
        // 90° about x: +z -> -y, +x stays.
        "nodes": [{"mesh": 0, "rotation": [h, 0.0, 0.0, h], "scale": [1.0, 4.0, 1.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": p, "NORMAL": n}}]}],
    }));
    let (mesh, _) = gltf_ok(&doc, &bin);
    let normals = mesh.normals.unwrap();
    let tri = mesh.triangles[0];
    assert!(close(normals[tri[0] as usize], [0.0, -1.0, 0.0], 1e-6));
    assert!(close(normals[tri[2] as usize], [1.0, 0.0, 0.0], 1e-6));
}

#[test]
fn untransformed_positions_and_normals_are_bit_exact() {
    let pts = [[0.1, -3.7e-5, 1.0e7], [1.0e-3, 0.3, -0.0], [7.25, 1.0, 2.0]];
    let mut b = Builder::default();
    let p = b.positions(&pts);
    let n = b.floats(&[0.6, 0.8, 0.0, 0.0, 0.6, 0.8, 0.8, 0.0, 0.6], "VEC3", 3);
    let (doc, bin) = b.finish(one_mesh(
        json!([{"attributes": {"POSITION": p, "NORMAL": n}}]),
    ));
    let (mesh, _) = gltf_ok(&doc, &bin);
    let t = triangles(&mesh)[0];
    for k in 0..3 {
        assert_eq!(t[k].map(f32::to_bits), pts[k].map(f32::to_bits));
    }
    let normals = mesh.normals.unwrap();
    assert_eq!(normals[mesh.triangles[0][0] as usize], [0.6, 0.8, 0.0]);
}

#[test]
fn quantized_positions_decode_per_the_spec() {
    // i16 normalized with a padded stride of 8, u16 normalized, u8 and i8 as plain integers.
    let mut b = Builder::default();
    let mut i16_bytes = Vec::new();
    for v in [[0i16, 0, 0], [32767, 0, 0], [-32768, 16384, 0]] {
        for c in v {
            i16_bytes.extend_from_slice(&c.to_le_bytes());
        }
        i16_bytes.extend_from_slice(&[0, 0]);
    }
    let v16 = b.view(&i16_bytes, Some(8));
    let a16 = b.accessor(Some(v16), SHORT, 3, "VEC3");
    let u16_bytes: Vec<u8> = [0u16, 0, 0, 0, 65535, 0, 0, 0, 0, 65535, 0, 0]
        .iter()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    let vu16 = b.view(&u16_bytes, Some(8));
    let au16 = b.accessor(Some(vu16), USHORT, 3, "VEC3");
    let vu8 = b.view(&[0, 0, 0, 0, 200, 0, 0, 0, 0, 7, 0, 0], Some(4));
    let au8 = b.accessor(Some(vu8), UBYTE, 3, "VEC3");
    let vi8 = b.view(&[0, 0, 0, 0, 0x80, 0, 0, 0, 0, 5, 0, 0], Some(4));
    let ai8 = b.accessor(Some(vi8), BYTE, 3, "VEC3");
    b.accessors[a16]["normalized"] = json!(true);
    b.accessors[au16]["normalized"] = json!(true);
    let (mut doc, bin) = b.finish(one_mesh(json!([
        {"attributes": {"POSITION": a16}},
        {"attributes": {"POSITION": au16}},
        {"attributes": {"POSITION": au8}},
        {"attributes": {"POSITION": ai8}},
    ])));
    doc["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    doc["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
    // Quantized files undo the scale with a node transform.
    doc["nodes"][0]["scale"] = json!([2.0, 2.0, 2.0]);
    let (mesh, _) = gltf_ok(&doc, &bin);
    let t = triangles(&mesh);
    assert_eq!(t.len(), 4);
    // i16: -32768 / 32767 clamps to -1.
    assert_eq!(
        t[0],
        [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [-2.0, 2.0 * 16384.0 / 32767.0, 0.0]
        ]
    );
    assert_eq!(t[1], [[0.0; 3], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]]);
    assert_eq!(t[2], [[0.0; 3], [400.0, 0.0, 0.0], [0.0, 14.0, 0.0]]);
    assert_eq!(t[3], [[0.0; 3], [-256.0, 0.0, 0.0], [0.0, 10.0, 0.0]]);
}

#[test]
fn quantized_normals_decode_and_need_the_extension() {
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    // Normalized i8 normals padded to 4 bytes: -128 clamps to -1.
    let v = b.view(&[0, 0, 127, 0, 0, 0x80, 0, 0, 127, 0, 0, 0], Some(4));
    let n = b.accessor(Some(v), BYTE, 3, "VEC3");
    b.accessors[n]["normalized"] = json!(true);
    let (mut doc, bin) = b.finish(one_mesh(
        json!([{"attributes": {"POSITION": p, "NORMAL": n}}]),
    ));
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(msg.contains("attribute NORMAL"), "{msg}");
    doc["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    let (mesh, _) = gltf_ok(&doc, &bin);
    let normals = mesh.normals.unwrap();
    let got: Vec<[f32; 3]> = mesh.triangles[0]
        .iter()
        .map(|&i| normals[i as usize])
        .collect();
    assert_eq!(
        got,
        vec![[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]]
    );
}

#[test]
fn trap_integer_positions_without_the_extension_are_an_error_not_a_panic() {
    // The gltf crate's position reader asserts on these in debug builds.
    let mut b = Builder::default();
    let v = b.view(&[0u8; 24], Some(8));
    let a = b.accessor(Some(v), USHORT, 3, "VEC3");
    let (doc, bin) = b.finish(one_mesh(json!([{"attributes": {"POSITION": a}}])));
    let (e, msg) = gltf_err(&doc, &bin);
    assert!(matches!(e, ImportError::Parse { .. }));
    assert!(
        msg.contains("mesh 0 primitive 0 attribute POSITION")
            && msg.contains("KHR_mesh_quantization"),
        "{msg}"
    );
}

#[test]
fn vertex_colours_and_base_colour_factor() {
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    let c8 = b.view(&[255, 0, 0, 255, 0, 255, 0, 128, 0, 0, 255, 0], None);
    let a8 = b.accessor(Some(c8), UBYTE, 3, "VEC4");
    b.accessors[a8]["normalized"] = json!(true);
    let c16: Vec<u8> = [65535u16, 32768, 0, 0, 0, 0, 0, 0, 65535]
        .iter()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    let c16 = b.view(&c16, None);
    let a16 = b.accessor(Some(c16), USHORT, 3, "VEC3");
    b.accessors[a16]["normalized"] = json!(true);
    let af = b.floats(&[0.5, 2.0, -1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0], "VEC3", 3);
    // Three copies of the triangle, shifted so the sink keeps their vertices apart.
    let p2 = b.positions(&TRI.map(|v| [v[0], v[1], 1.0]));
    let p3 = b.positions(&TRI.map(|v| [v[0], v[1], 2.0]));
    let p4 = b.positions(&TRI.map(|v| [v[0], v[1], 3.0]));
    let (mut doc, bin) = b.finish(one_mesh(json!([
        {"attributes": {"POSITION": p, "COLOR_0": a8}, "material": 1},
        {"attributes": {"POSITION": p2, "COLOR_0": a16}, "material": 1},
        {"attributes": {"POSITION": p3, "COLOR_0": af}},
        {"attributes": {"POSITION": p4}, "material": 2},
    ])));
    doc["materials"] = json!([
        {"name": "unused", "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 1.0, 1.0]}},
        {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.0, 0.0, 0.5]}},
        {"pbrMetallicRoughness": {"baseColorFactor": [0.25, 0.5, 0.75, 1.0]}},
    ]);
    let dir = tempfile::tempdir().unwrap();
    let path = write_gltf(dir.path(), &doc, &bin);
    let mut sink = Recording::default();
    import(&path, &mut sink, &GltfOptions::default()).unwrap();
    // Added once each, on first use, in order of use; the unused one never.
    assert_eq!(
        sink.materials,
        vec![
            Material {
                name: "red".into(),
                diffuse: [1.0, 0.0, 0.0]
            },
            Material {
                name: "material 2".into(),
                diffuse: [0.25, 0.5, 0.75]
            },
        ]
    );
    let mats: Vec<Option<u32>> = sink.triangles.iter().map(|t| t.material).collect();
    assert_eq!(mats, vec![Some(0), Some(0), None, Some(1)]);
    let colours: Vec<Option<[[u8; 4]; 3]>> = sink.triangles.iter().map(|t| t.colours).collect();
    assert_eq!(
        colours,
        vec![
            Some([[255, 0, 0, 255], [0, 255, 0, 128], [0, 0, 255, 0]]),
            Some([[255, 128, 0, 255], [0, 0, 0, 255], [0, 0, 255, 255]]),
            Some([[128, 255, 0, 255], [0, 0, 0, 255], [255, 255, 255, 255]]),
            None,
        ]
    );
}

#[test]
fn glb_reads_its_bin_chunk_and_matches_the_gltf() {
    let mut b = Builder::default();
    let p = b.positions(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ]);
    let i = b.indices(USHORT, &[0, 1, 2, 0, 2, 3]);
    let (doc, bin) = b.finish(one_mesh(
        json!([{"attributes": {"POSITION": p}, "indices": i}]),
    ));
    let dir = tempfile::tempdir().unwrap();
    let glb = write_glb(dir.path(), &doc, &bin);
    let (from_glb, _) = run(&glb).unwrap();
    let (from_gltf, _) = gltf_ok(&doc, &bin);
    assert_eq!(from_glb, from_gltf);
    assert_eq!(from_glb.triangles.len(), 2);
}

#[test]
fn data_uri_buffers_are_decoded_in_memory() {
    let (mut doc, bin) = triangle_doc();
    let b64 = base64::engine::general_purpose::STANDARD.encode(&bin);
    doc["buffers"][0]["uri"] = json!(format!("data:application/octet-stream;base64,{b64}"));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("inline.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let (mesh, _) = run(&path).unwrap();
    assert_eq!(triangles(&mesh), vec![TRI]);

    doc["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@@");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let msg = run(&path).unwrap_err().to_string();
    assert!(msg.contains("buffer 0") && msg.contains("base64"), "{msg}");

    doc["buffers"][0]["uri"] = json!("data:application/octet-stream,plain");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let msg = run(&path).unwrap_err().to_string();
    assert!(msg.contains("not base64"), "{msg}");
}

#[test]
fn sparse_accessors_replace_elements() {
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    let idx = b.view(&[2u8, 0, 0, 0], None);
    let val = b.view(&f32_bytes(&[0.0, 5.0, 0.0]), None);
    b.accessors[p]["sparse"] = json!({
        "count": 1,
        "indices": {"bufferView": idx, "componentType": UBYTE},
        "values": {"bufferView": val},
    });
    // A sparse accessor without a buffer view: zeros, then the replacements.
    let val2 = b.view(&f32_bytes(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]), None);
    let idx2 = b.view(&[1u16, 0, 2, 0].map(|x| x as u8), None);
    let z = b.accessor(None, FLOAT, 3, "VEC3");
    b.accessors[z]["sparse"] = json!({
        "count": 2,
        "indices": {"bufferView": idx2, "componentType": USHORT},
        "values": {"bufferView": val2},
    });
    let (doc, bin) = b.finish(json!({
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"mesh": 0, "translation": [0.0, 0.0, 1.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": p}}, {"attributes": {"POSITION": z}}]}],
    }));
    let (mesh, _) = gltf_ok(&doc, &bin);
    let t = triangles(&mesh);
    assert_eq!(t.len(), 4);
    assert_eq!(t[0], [TRI[0], TRI[1], [0.0, 5.0, 0.0]]);
    assert_eq!(t[1], TRI);
    assert_eq!(t[3], TRI.map(|v| [v[0], v[1], 1.0]));
}

#[test]
fn default_scene_only_unless_all_scenes() {
    let mut b = Builder::default();
    let pa = b.positions(&TRI);
    let pb = b.positions(&TRI.map(|v| [v[0] + 10.0, v[1], v[2]]));
    let pc = b.positions(&TRI.map(|v| [v[0] + 20.0, v[1], v[2]]));
    let (doc, bin) = b.finish(json!({
        "scene": 1,
        "scenes": [{"nodes": [0]}, {"nodes": [1, 2]}],
        "nodes": [{"mesh": 0}, {"mesh": 1}, {"mesh": 2}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": pa}}]},
            {"primitives": [{"attributes": {"POSITION": pb}}]},
            {"primitives": [{"attributes": {"POSITION": pc}}]},
        ],
    }));
    let dir = tempfile::tempdir().unwrap();
    let path = write_gltf(dir.path(), &doc, &bin);
    let (mesh, report) = run(&path).unwrap();
    let xs: Vec<f32> = triangles(&mesh).iter().map(|t| t[0][0]).collect();
    assert_eq!(xs, vec![10.0, 20.0]);
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("default scene 1")),
        "{:?}",
        report.warnings
    );
    assert!(report.warnings.iter().any(|w| w.contains("1 of 3 meshes")));

    let all = GltfOptions {
        all_scenes: true,
        ..GltfOptions::default()
    };
    let (mesh, _) = run_with(&path, &all).unwrap();
    let xs: Vec<f32> = triangles(&mesh).iter().map(|t| t[0][0]).collect();
    assert_eq!(xs, vec![0.0, 10.0, 20.0]);

    // No default marked: scene 0.
    let mut doc0 = doc.clone();
    doc0.as_object_mut().unwrap().remove("scene");
    let (mesh, _) = gltf_ok(&doc0, &bin);
    assert_eq!(triangles(&mesh).len(), 1);
    assert_eq!(triangles(&mesh)[0][0][0], 0.0);
}

#[test]
fn a_mesh_placed_twice_is_imported_twice() {
    let (mut doc, bin) = triangle_doc();
    doc["scenes"] = json!([{"nodes": [0, 1]}]);
    doc["nodes"] = json!([{"mesh": 0}, {"mesh": 0, "translation": [0.0, 0.0, 5.0]}]);
    let (mesh, _) = gltf_ok(&doc, &bin);
    assert_eq!(mesh.triangles.len(), 2);
}

#[test]
fn out_of_range_indices_are_dropped_and_counted_not_fatal() {
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    let i = b.indices(UINT, &[0, 1, 2, 0, 9, 2, 0xFFFF_FFFF, 1, 2]);
    let (doc, bin) = b.finish(one_mesh(
        json!([{"attributes": {"POSITION": p}, "indices": i}]),
    ));
    let (mesh, report) = gltf_ok(&doc, &bin);
    assert_eq!(mesh.triangles.len(), 1);
    assert_eq!(report.dropped.get(&DropReason::IndexOutOfRange), Some(&2));
    assert_eq!(report.triangles_in, 3);
}

#[test]
fn strict_refusal_names_node_mesh_primitive_and_triangle() {
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    let i = b.indices(UBYTE, &[0, 1, 2, 0, 1, 7]);
    let (doc, bin) = b.finish(one_mesh(
        json!([{"attributes": {"POSITION": p}, "indices": i}]),
    ));
    let dir = tempfile::tempdir().unwrap();
    let path = write_gltf(dir.path(), &doc, &bin);
    let mut sink = MeshSink::new(true);
    let msg = import(&path, &mut sink, &GltfOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("model.gltf") && msg.contains("node 0 mesh 0 primitive 0 triangle 1"),
        "{msg}"
    );
}

#[test]
fn used_but_unknown_extensions_are_warned_about() {
    let (mut doc, bin) = triangle_doc();
    doc["extensionsUsed"] = json!(["EXT_mesh_gpu_instancing", "KHR_texture_transform"]);
    let (_, report) = gltf_ok(&doc, &bin);
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("EXT_mesh_gpu_instancing") && !w.contains("KHR_texture")),
        "{:?}",
        report.warnings
    );
}

#[test]
fn a_file_without_scenes_imports_its_root_nodes() {
    let (mut doc, bin) = triangle_doc();
    let o = doc.as_object_mut().unwrap();
    o.remove("scene");
    o.remove("scenes");
    let (mesh, report) = gltf_ok(&doc, &bin);
    assert_eq!(mesh.triangles.len(), 1);
    assert!(report.warnings.iter().any(|w| w.contains("no scene")));
}

/// Records what the importer sends, materials included.
#[derive(Default)]
struct Recording {
    parts: Vec<oocfmt_meshio::import::PartDef>,
    materials: Vec<Material>,
    triangles: Vec<InputTriangle>,
}

impl TriangleSink for Recording {
    fn add_material(&mut self, material: Material) -> Result<u32, ImportError> {
        self.materials.push(material);
        Ok(self.materials.len() as u32 - 1)
    }
    fn add_part(&mut self, part: oocfmt_meshio::import::PartDef) -> Result<u32, ImportError> {
        self.parts.push(part);
        Ok(self.parts.len() as u32 - 1)
    }
    fn push(&mut self, triangle: InputTriangle, _: &Location) -> Result<(), ImportError> {
        self.triangles.push(triangle);
        Ok(())
    }
    fn reject(&mut self, _: DropReason, _: &Location) -> Result<(), ImportError> {
        Ok(())
    }
    fn skip(&mut self, _: Skipped, _: u64) {}
    fn warn(&mut self, _: &Location, _: String) {}
    fn begin_file(&mut self, _: &str) {}
    fn place(&mut self, exact: [f64; 3]) -> [f32; 3] {
        exact.map(|c| c as f32)
    }
}

// ---------------------------------------------------------------------------------------
// Parts

/// Three meshes (x = 0, 10, 20) and the given scenes and nodes.
fn parts_doc(rest: Value) -> (Value, Vec<u8>) {
    let mut b = Builder::default();
    let p: Vec<usize> = [0.0, 10.0, 20.0]
        .iter()
        .map(|&dx| b.positions(&TRI.map(|v| [v[0] + dx, v[1], v[2]])))
        .collect();
    let mut doc = json!({
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": p[0]}}]},
            {"name": "Bolt", "primitives": [{"attributes": {"POSITION": p[1]}}]},
            {"primitives": [{"attributes": {"POSITION": p[2]}}]},
        ],
    });
    for (k, v) in rest.as_object().unwrap() {
        doc[k] = v.clone();
    }
    b.finish(doc)
}

#[test]
fn mesh_nodes_and_their_ancestors_become_the_part_tree() {
    let (doc, bin) = parts_doc(json!({
        "scenes": [{"nodes": [0, 5]}],
        "nodes": [
            {"name": "assembly", "children": [1, 2, 4]},
            {"name": "wheel", "mesh": 0},
            {"mesh": 1, "children": [3]},
            {"mesh": 2},
            {"name": "camera"},
            {"name": "", "children": [6]},
            {"mesh": 0, "translation": [0.0, 0.0, 5.0]},
        ],
    }));
    let (mesh, _) = gltf_ok(&doc, &bin);
    assert_eq!(
        part_tree(&mesh),
        [
            node("assembly", None, 0),
            node("wheel", Some(0), 1),
            // No node name: the mesh's; neither: the node's index.
            node("Bolt", Some(0), 1),
            node("node 3", Some(2), 1),
            // An empty name is no name; the camera branch holds no mesh and is no part.
            node("node 5", None, 0),
            node("node 6", Some(4), 1),
        ]
    );
    let xs: Vec<f32> = triangles(&mesh).iter().map(|t| t[0][0]).collect();
    assert_eq!(xs, [0.0, 10.0, 20.0, 0.0]);
    assert_eq!(mesh.part_ids.as_deref(), Some(&[1, 2, 3, 5][..]));
}

#[test]
fn a_mesh_placed_by_two_nodes_is_two_parts() {
    let (doc, bin) = parts_doc(json!({
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"children": [1, 2]},
            {"mesh": 1},
            {"mesh": 1, "translation": [0.0, 0.0, 5.0]},
        ],
    }));
    let (mesh, _) = gltf_ok(&doc, &bin);
    assert_eq!(
        part_tree(&mesh),
        [
            node("node 0", None, 0),
            node("Bolt", Some(0), 1),
            node("Bolt", Some(0), 1),
        ]
    );
}

#[test]
fn a_node_in_two_imported_scenes_has_parts_under_each() {
    let (doc, bin) = parts_doc(json!({
        "scenes": [{"name": "day", "nodes": [0]}, {"nodes": [0, 2]}],
        "nodes": [{"name": "frame", "children": [1]}, {"mesh": 0}, {"mesh": 2}],
    }));
    let dir = tempfile::tempdir().unwrap();
    let path = write_gltf(dir.path(), &doc, &bin);
    let all = GltfOptions {
        all_scenes: true,
        ..GltfOptions::default()
    };
    let (mesh, _) = run_with(&path, &all).unwrap();
    assert_eq!(
        part_tree(&mesh),
        [
            node("day", None, 0),
            node("frame", Some(0), 0),
            node("node 1", Some(1), 1),
            node("scene 1", None, 0),
            node("frame", Some(3), 0),
            node("node 1", Some(4), 1),
            node("node 2", Some(3), 1),
        ]
    );
    // The default scene alone: no scene parts.
    let (mesh, _) = run(&path).unwrap();
    assert_eq!(
        part_tree(&mesh),
        [node("frame", None, 0), node("node 1", Some(0), 1)]
    );
}

#[test]
fn one_anonymous_mesh_instance_declares_no_part() {
    // Nested under anonymous nodes, still nothing to name.
    let (doc, bin) = parts_doc(json!({
        "scenes": [{"nodes": [0]}],
        "nodes": [{"children": [1]}, {"mesh": 2}],
    }));
    let (mesh, _) = gltf_ok(&doc, &bin);
    assert!(mesh.parts.is_empty() && mesh.part_ids.is_none());
    let (doc, bin) = triangle_doc();
    let (mesh, _) = gltf_ok(&doc, &bin);
    assert!(mesh.parts.is_empty());
    // A name anywhere on the way keeps its part, even alone.
    for named in [
        json!({"scenes": [{"nodes": [0]}], "nodes": [{"name": "a", "children": [1]}, {"mesh": 2}]}),
        json!({"scenes": [{"nodes": [0]}], "nodes": [{"mesh": 1}]}),
    ] {
        let (doc, bin) = parts_doc(named);
        let (mesh, _) = gltf_ok(&doc, &bin);
        assert!(!mesh.parts.is_empty());
        assert!(mesh.part_ids.is_none() || mesh.parts.len() > 1);
    }
    // The importer tells the sink the part of every triangle it declared parts for.
    let (doc, bin) = parts_doc(json!({
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"mesh": 2}],
    }));
    let dir = tempfile::tempdir().unwrap();
    let path = write_gltf(dir.path(), &doc, &bin);
    let mut r = Recording::default();
    import(&path, &mut r, &GltfOptions::default()).unwrap();
    let names: Vec<&str> = r.parts.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["node 0", "node 1"]);
    let parts: Vec<Option<u32>> = r.triangles.iter().map(|t| t.part).collect();
    assert_eq!(parts, [Some(0), Some(1)]);
}

// ---------------------------------------------------------------------------------------
// Extensions

#[test]
fn required_extensions_not_decoded_are_refused_by_name() {
    for ext in [
        "KHR_draco_mesh_compression",
        "EXT_meshopt_compression",
        "EXT_something_new",
    ] {
        let (mut doc, bin) = triangle_doc();
        doc["extensionsUsed"] = json!([ext]);
        doc["extensionsRequired"] = json!([ext]);
        let (e, msg) = gltf_err(&doc, &bin);
        assert!(matches!(e, ImportError::Unsupported { .. }), "{msg}");
        assert!(msg.contains(ext) && msg.contains("model.gltf"), "{msg}");
    }
    // Extensions that change nothing the importer reads may be required.
    let (mut doc, bin) = triangle_doc();
    doc["extensionsRequired"] = json!(["KHR_texture_basisu", "KHR_materials_unlit"]);
    gltf_ok(&doc, &bin);
}

// ---------------------------------------------------------------------------------------
// The node graph

#[test]
fn trap_cyclic_node_graphs_are_refused_naming_a_node() {
    // The gltf crate's validation accepts these; a naive walk never ends.
    let cases = [
        (
            json!([{"children": [1], "mesh": 0}, {"children": [0]}]),
            json!([0]),
        ),
        (
            json!([{"mesh": 0}, {"children": [2]}, {"children": [1]}]),
            json!([0]),
        ),
        (json!([{"children": [0], "mesh": 0}]), json!([0])),
    ];
    for (nodes, roots) in cases {
        let (mut doc, bin) = triangle_doc();
        doc["nodes"] = nodes.clone();
        doc["scenes"] = json!([{"nodes": roots}]);
        let (e, msg) = gltf_err(&doc, &bin);
        assert!(matches!(e, ImportError::Parse { .. }));
        assert!(
            msg.contains("(node ") && msg.contains("cycle"),
            "{nodes}: {msg}"
        );
    }
}

#[test]
fn a_node_with_two_parents_is_refused() {
    let (mut doc, bin) = triangle_doc();
    doc["nodes"] = json!([{"children": [2]}, {"children": [2]}, {"mesh": 0}]);
    doc["scenes"] = json!([{"nodes": [0, 1]}]);
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(
        msg.contains("node 2") && msg.contains("two parents"),
        "{msg}"
    );
}

#[test]
fn hierarchies_deeper_than_the_bound_are_refused() {
    let (mut doc, bin) = triangle_doc();
    let deep = 2000;
    let mut nodes: Vec<Value> = (1..deep).map(|i| json!({"children": [i]})).collect();
    nodes.push(json!({"mesh": 0}));
    doc["nodes"] = json!(nodes);
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(msg.contains("deeper than"), "{msg}");

    // A deep but reasonable chain is fine.
    let mut nodes: Vec<Value> = (1..500)
        .map(|i| json!({"children": [i], "translation": [1.0, 0.0, 0.0]}))
        .collect();
    nodes.push(json!({"mesh": 0}));
    doc["nodes"] = json!(nodes);
    let (mesh, _) = gltf_ok(&doc, &bin);
    assert_eq!(triangles(&mesh)[0][0], [499.0, 0.0, 0.0]);
}

#[test]
fn node_and_scene_errors_name_the_item() {
    let cases = [
        (
            json!({"nodes": [{"children": [5]}]}),
            "child 5 does not exist",
        ),
        (json!({"nodes": [{"mesh": 3}]}), "mesh 3 does not exist"),
        (json!({"scenes": [{"nodes": [4]}]}), "node 4 does not exist"),
        (json!({"scene": 2}), "default scene 2 does not exist"),
        (
            json!({"nodes": [{"children": [1]}, {"mesh": 0}], "scenes": [{"nodes": [1]}]}),
            "is a child of node 0",
        ),
        (json!({"scenes": [{"nodes": [0, 0]}]}), "listed twice"),
        (
            json!({"nodes": [{"mesh": 0, "matrix": [1,0,0,1, 0,1,0,0, 0,0,1,0, 0,0,0,1]}]}),
            "not affine",
        ),
        (
            json!({"nodes": [{"mesh": 0, "rotation": [0.0, 0.0, 0.0, 0.0]}]}),
            "not a usable quaternion",
        ),
    ];
    for (patch, want) in cases {
        let (mut doc, bin) = triangle_doc();
        for (k, v) in patch.as_object().unwrap() {
            doc[k] = v.clone();
        }
        let (e, msg) = gltf_err(&doc, &bin);
        assert!(matches!(e, ImportError::Parse { .. }), "{msg}");
        assert!(msg.contains(want), "{patch}: {msg}");
    }
}

// ---------------------------------------------------------------------------------------
// Accessors

/// The error for a triangle document after `patch` edits it.
fn accessor_error(patch: impl FnOnce(&mut Value)) -> String {
    let (mut doc, bin) = triangle_doc();
    patch(&mut doc);
    let (e, msg) = gltf_err(&doc, &bin);
    assert!(matches!(e, ImportError::Parse { .. }), "{msg}");
    msg
}

#[test]
fn trap_accessor_count_zero_is_an_error_not_a_panic() {
    let msg = accessor_error(|d| d["accessors"][0]["count"] = json!(0));
    assert!(
        msg.contains("mesh 0 primitive 0 attribute POSITION") && msg.contains("count 0"),
        "{msg}"
    );
}

#[test]
fn trap_absurd_counts_are_an_error_not_a_panic_or_allocation() {
    for count in [4u64, 4_000_000_000, u64::MAX / 2, u64::MAX] {
        let msg = accessor_error(|d| d["accessors"][0]["count"] = json!(count));
        assert!(
            msg.contains("attribute POSITION") && msg.contains("do not fit buffer view 0"),
            "{count}: {msg}"
        );
    }
    // Without a buffer view an accessor is zeros: its count is capped by the buffer limit.
    let msg = accessor_error(|d| {
        let a = d["accessors"][0].as_object_mut().unwrap();
        a.remove("bufferView");
        a.insert("count".into(), json!(u64::MAX / 2));
    });
    assert!(msg.contains("no buffer view"), "{msg}");
}

#[test]
fn trap_byte_stride_smaller_than_the_element_is_an_error_not_a_panic() {
    let msg = accessor_error(|d| d["bufferViews"][0]["byteStride"] = json!(4));
    assert!(
        msg.contains("attribute POSITION") && msg.contains("byteStride 4"),
        "{msg}"
    );
    let msg = accessor_error(|d| d["bufferViews"][0]["byteStride"] = json!(14));
    assert!(msg.contains("byteStride 14"), "{msg}");
}

#[test]
fn views_and_offsets_out_of_range_are_errors() {
    let msg = accessor_error(|d| d["accessors"][0]["byteOffset"] = json!(4));
    assert!(msg.contains("do not fit buffer view 0"), "{msg}");
    let msg = accessor_error(|d| d["bufferViews"][0]["byteOffset"] = json!(8));
    assert!(msg.contains("lies outside buffer 0"), "{msg}");
    let msg = accessor_error(|d| d["bufferViews"][0]["byteLength"] = json!(u64::MAX));
    assert!(msg.contains("lies outside buffer 0"), "{msg}");
    let msg = accessor_error(|d| d["accessors"][0]["bufferView"] = json!(9));
    assert!(msg.contains("buffer view 9 does not exist"), "{msg}");
    let msg = accessor_error(|d| d["bufferViews"][0]["buffer"] = json!(3));
    assert!(msg.contains("buffer 3"), "{msg}");
}

#[test]
fn trap_a_position_naming_a_missing_accessor_is_an_error_not_a_panic() {
    // The gltf crate's own validation indexes the accessor list unchecked here.
    let msg =
        accessor_error(|d| d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(7));
    assert!(
        msg.contains("attribute POSITION") && msg.contains("accessor 7 does not exist"),
        "{msg}"
    );
}

#[test]
fn component_types_invalid_for_their_semantic_are_errors() {
    let msg = accessor_error(|d| d["accessors"][0]["componentType"] = json!(UINT));
    assert!(
        msg.contains("attribute POSITION") && msg.contains("not a valid type"),
        "{msg}"
    );
    let msg = accessor_error(|d| d["accessors"][0]["type"] = json!("VEC2"));
    assert!(msg.contains("not a valid type"), "{msg}");
    let msg = accessor_error(|d| d["accessors"][0]["componentType"] = json!(1234));
    assert!(msg.contains("invalid componentType"), "{msg}");

    // COLOR_0 of signed bytes; indices of floats; normals of unsigned shorts.
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    let c = b.view(&[0u8; 12], None);
    let ac = b.accessor(Some(c), BYTE, 3, "VEC4");
    b.accessors[ac]["normalized"] = json!(true);
    let fi = b.floats(&[0.0, 1.0, 2.0], "SCALAR", 1);
    let n = b.view(&[0u8; 24], Some(8));
    let an = b.accessor(Some(n), USHORT, 3, "VEC3");
    let (mut doc, bin) = b.finish(one_mesh(json!([
        {"attributes": {"POSITION": p, "COLOR_0": ac}},
    ])));
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(msg.contains("attribute COLOR_0"), "{msg}");
    doc["meshes"][0]["primitives"] = json!([{"attributes": {"POSITION": p}, "indices": fi}]);
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(msg.contains("mesh 0 primitive 0 indices"), "{msg}");
    doc["meshes"][0]["primitives"] = json!([{"attributes": {"POSITION": p, "NORMAL": an}}]);
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(msg.contains("attribute NORMAL"), "{msg}");
}

#[test]
fn attribute_counts_must_agree_and_position_must_exist() {
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    let n = b.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC3", 3);
    let (mut doc, bin) = b.finish(one_mesh(
        json!([{"attributes": {"POSITION": p, "NORMAL": n}}]),
    ));
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(
        msg.contains("attribute NORMAL") && msg.contains("POSITION count 3"),
        "{msg}"
    );
    doc["meshes"][0]["primitives"] = json!([{"attributes": {"NORMAL": n}}]);
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(msg.contains("no POSITION"), "{msg}");
    doc["meshes"][0]["primitives"] = json!([{"attributes": {"POSITION": p}, "material": 4}]);
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(msg.contains("material 4 does not exist"), "{msg}");
    doc["meshes"][0]["primitives"] = json!([{"attributes": {"POSITION": p}, "mode": 9}]);
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(msg.contains("mode"), "{msg}");
}

#[test]
fn an_index_view_with_a_stride_is_an_error() {
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    let i = b.indices(USHORT, &[0, 1, 2, 0]);
    b.views[1]["byteStride"] = json!(4);
    let (doc, bin) = b.finish(one_mesh(
        json!([{"attributes": {"POSITION": p}, "indices": i}]),
    ));
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(
        msg.contains("indices") && msg.contains("byteStride"),
        "{msg}"
    );
}

fn sparse_doc(count: usize, indices: &[u8]) -> (Value, Vec<u8>) {
    let mut b = Builder::default();
    let p = b.positions(&TRI);
    let idx = b.view(indices, None);
    let val = b.view(&f32_bytes(&[0.0; 6]), None);
    b.accessors[p]["sparse"] = json!({
        "count": count,
        "indices": {"bufferView": idx, "componentType": UBYTE},
        "values": {"bufferView": val},
    });
    b.finish(one_mesh(json!([{"attributes": {"POSITION": p}}])))
}

#[test]
fn trap_sparse_count_zero_is_an_error_not_a_panic() {
    let (doc, bin) = sparse_doc(0, &[0, 1]);
    let (_, msg) = gltf_err(&doc, &bin);
    assert!(
        msg.contains("attribute POSITION") && msg.contains("sparse: count 0"),
        "{msg}"
    );
}

#[test]
fn bad_sparse_accessors_are_errors() {
    let cases: [(usize, &[u8], &str); 4] = [
        (2, &[0, 3], "beyond the accessor's count"),
        (2, &[1, 1], "strictly increase"),
        (4, &[0, 1, 2, 3], "count 4"),
        (3, &[0, 1], "indices:"),
    ];
    for (count, idx, want) in cases {
        let (doc, bin) = sparse_doc(count, idx);
        let (_, msg) = gltf_err(&doc, &bin);
        assert!(
            msg.contains("attribute POSITION") && msg.contains(want),
            "{want}: {msg}"
        );
    }
}

// ---------------------------------------------------------------------------------------
// Buffers and URIs

#[test]
fn a_missing_bin_is_an_io_error_naming_it() {
    let (mut doc, bin) = triangle_doc();
    doc["buffers"][0]["uri"] = json!("gone.bin");
    let dir = tempfile::tempdir().unwrap();
    let path = write_gltf(dir.path(), &doc, &bin);
    let e = run(&path).unwrap_err();
    assert!(matches!(e, ImportError::Io { .. }));
    assert!(e.to_string().contains("gone.bin"), "{e}");
}

#[test]
fn a_short_bin_is_an_error() {
    let (doc, bin) = triangle_doc();
    let dir = tempfile::tempdir().unwrap();
    let path = write_gltf(dir.path(), &doc, &bin);
    std::fs::write(dir.path().join("model.bin"), &bin[..20]).unwrap();
    let msg = run(&path).unwrap_err().to_string();
    assert!(
        msg.contains("model.bin") && msg.contains("ends after 20"),
        "{msg}"
    );
}

#[test]
fn percent_encoded_uris_name_files_in_the_folder() {
    let (mut doc, bin) = triangle_doc();
    doc["buffers"][0]["uri"] = json!("sub%20dir/my%20data.bin");
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("sub dir")).unwrap();
    std::fs::write(dir.path().join("sub dir/my data.bin"), &bin).unwrap();
    let path = dir.path().join("m.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let (mesh, _) = run(&path).unwrap();
    assert_eq!(triangles(&mesh), vec![TRI]);
}

#[test]
fn trap_uris_leaving_the_model_folder_are_refused() {
    let root = tempfile::tempdir().unwrap();
    let dir = root.path().join("model");
    std::fs::create_dir(&dir).unwrap();
    let (mut doc, bin) = triangle_doc();
    // The file exists: refusing it is policy, not a missing file.
    std::fs::write(root.path().join("outside.bin"), &bin).unwrap();
    let outside = root.path().join("outside.bin");
    for uri in [
        "../outside.bin".to_string(),
        "sub/../../outside.bin".to_string(),
        "%2e%2e/outside.bin".to_string(),
        outside.display().to_string(),
        format!("file://{}", outside.display()),
        "file:///dev/zero".to_string(),
        "http://example.invalid/x.bin".to_string(),
    ] {
        doc["buffers"][0]["uri"] = json!(uri);
        let path = dir.join("m.gltf");
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        let e = run(&path).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, ImportError::Unsupported { .. }), "{uri}: {msg}");
        assert!(
            msg.contains("m.gltf") && msg.contains("buffer 0") && msg.contains(&uri),
            "{msg}"
        );
    }
}

#[cfg(unix)]
#[test]
fn links_out_of_the_folder_and_special_files_are_refused() {
    let root = tempfile::tempdir().unwrap();
    let dir = root.path().join("model");
    std::fs::create_dir(&dir).unwrap();
    let (mut doc, bin) = triangle_doc();
    std::fs::write(root.path().join("outside.bin"), &bin).unwrap();
    std::os::unix::fs::symlink(root.path().join("outside.bin"), dir.join("link.bin")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", dir.join("zero.bin")).unwrap();
    for uri in ["link.bin", "zero.bin"] {
        doc["buffers"][0]["uri"] = json!(uri);
        let path = dir.join("m.gltf");
        std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
        let msg = run(&path).unwrap_err().to_string();
        assert!(msg.contains("through a link") && msg.contains(uri), "{msg}");
    }
    // A directory is no buffer (nor would a pipe or a device be).
    std::fs::create_dir(dir.join("dir.bin")).unwrap();
    doc["buffers"][0]["uri"] = json!("dir.bin");
    let path = dir.join("m.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let msg = run(&path).unwrap_err().to_string();
    assert!(msg.contains("not a regular file"), "{msg}");
}

#[test]
fn buffer_reads_are_capped() {
    let (mut doc, bin) = triangle_doc();
    let dir = tempfile::tempdir().unwrap();
    let path = write_gltf(dir.path(), &doc, &bin);
    let small = GltfOptions {
        max_buffer_bytes: 16,
        ..GltfOptions::default()
    };
    let e = run_with(&path, &small).unwrap_err();
    assert!(matches!(e, ImportError::Limit { limit: 16, .. }), "{e}");

    // A huge declared length is refused before anything is read.
    doc["buffers"][0]["byteLength"] = json!(1u64 << 40);
    let path = write_gltf(dir.path(), &doc, &bin);
    let e = run(&path).unwrap_err();
    assert!(matches!(e, ImportError::Limit { .. }), "{e}");

    let tiny_json = GltfOptions {
        max_json_bytes: 10,
        ..GltfOptions::default()
    };
    let e = run_with(&path, &tiny_json).unwrap_err();
    assert!(matches!(e, ImportError::Limit { limit: 10, .. }), "{e}");
}

#[test]
fn buffers_no_mesh_uses_are_not_read() {
    let (mut doc, bin) = triangle_doc();
    doc["buffers"] =
        json!([doc["buffers"][0].clone(), {"uri": "textures.bin", "byteLength": 1u64 << 40}]);
    let (mesh, _) = gltf_ok(&doc, &bin);
    assert_eq!(mesh.triangles.len(), 1);
}

#[test]
fn invalid_json_is_a_parse_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.gltf");
    std::fs::write(&path, b"{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [").unwrap();
    let e = run(&path).unwrap_err();
    assert!(
        matches!(e, ImportError::Parse { .. }) && e.to_string().contains("bad.gltf"),
        "{e}"
    );
    // Deep nesting in unused parts does not overflow the stack.
    let deep = format!(
        "{{\"asset\":{{\"version\":\"2.0\",\"extras\":{}1{}}}}}",
        "[".repeat(100_000),
        "]".repeat(100_000)
    );
    std::fs::write(&path, deep).unwrap();
    assert!(run(&path).is_err());
}

// ---------------------------------------------------------------------------------------
// GLB containers

fn glb_error(bytes: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.glb");
    std::fs::write(&path, bytes).unwrap();
    let msg = run(&path).unwrap_err().to_string();
    assert!(msg.contains("bad.glb"), "{msg}");
    msg
}

#[test]
fn trap_a_glb_header_length_below_twelve_is_an_error_not_a_panic() {
    let (doc, bin) = triangle_doc();
    let mut bytes = glb_bytes(&doc, &bin);
    bytes[8..12].copy_from_slice(&4u32.to_le_bytes());
    let msg = glb_error(&bytes);
    assert!(msg.contains("GLB header"), "{msg}");
}

#[test]
fn malformed_glb_containers_are_errors() {
    let (mut doc, bin) = triangle_doc();
    doc["buffers"][0].as_object_mut().unwrap().remove("uri");
    let good = glb_bytes(&doc, &bin);

    let mut b = good.clone();
    b[8..12].copy_from_slice(&(good.len() as u32 + 100).to_le_bytes());
    assert!(glb_error(&b).contains("the file holds"));

    let mut b = good.clone();
    b[4..8].copy_from_slice(&1u32.to_le_bytes());
    assert!(glb_error(&b).contains("GLB version 1"));

    let mut b = good.clone();
    b[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(glb_error(&b).contains("JSON chunk"));

    let mut b = good.clone();
    b[16..20].copy_from_slice(b"BIN\0");
    assert!(glb_error(&b).contains("not JSON"));

    assert!(glb_error(&good[..10]).contains("GLB header"));

    // The BIN chunk shorter than the buffer it holds.
    let mut short = doc.clone();
    short["buffers"][0]["byteLength"] = json!(bin.len() + 8);
    let msg = glb_error(&glb_bytes(&short, &bin));
    assert!(msg.contains("BIN chunk holds only"), "{msg}");

    // Only buffer 0 of a GLB may live in its BIN chunk.
    let mut two = doc.clone();
    two["buffers"] = json!([{"byteLength": bin.len()}, {"byteLength": bin.len()}]);
    two["bufferViews"][0]["buffer"] = json!(1);
    let msg = glb_error(&glb_bytes(&two, &bin));
    assert!(msg.contains("buffer 1") && msg.contains("no uri"), "{msg}");
}

// ---------------------------------------------------------------------------------------
// Sweeps: whatever a field or byte says, the import ends with triangles or an error.

/// A document touching every feature: indices, normals, colours, sparse values, a
/// material, a hierarchy with TRS and a matrix, two scenes.
fn rich_doc() -> (Value, Vec<u8>) {
    let mut b = Builder::default();
    let p = b.positions(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ]);
    let n = b.floats(&[0.0, 0.0, 1.0].repeat(4), "VEC3", 3);
    let c = b.view(&[255u8; 16], None);
    let ac = b.accessor(Some(c), UBYTE, 4, "VEC4");
    b.accessors[ac]["normalized"] = json!(true);
    let i = b.indices(USHORT, &[0, 1, 2, 0, 2, 3]);
    let si = b.view(&[1, 0, 0, 0], None);
    let sv = b.view(&f32_bytes(&[2.0, 0.0, 0.0]), None);
    b.accessors[p]["sparse"] = json!({
        "count": 1,
        "indices": {"bufferView": si, "componentType": UBYTE, "byteOffset": 0},
        "values": {"bufferView": sv, "byteOffset": 0},
    });
    b.finish(json!({
        "scene": 0,
        "scenes": [{"nodes": [0]}, {"nodes": [2]}],
        "nodes": [
            {"children": [1], "translation": [1.0, 2.0, 3.0], "rotation": [0.0, 0.0, 0.0, 1.0],
             "scale": [1.0, 1.0, 1.0]},
            {"mesh": 0, "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]},
            {"mesh": 0},
        ],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": p, "NORMAL": n, "COLOR_0": ac},
            "indices": i, "material": 0, "mode": 4,
        }]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.5, 0.25, 1.0]}}],
    }))
}

fn numeric_paths(v: &Value, path: String, out: &mut Vec<String>) {
    match v {
        Value::Number(_) => out.push(path),
        Value::Array(a) => {
            for (k, x) in a.iter().enumerate() {
                numeric_paths(x, format!("{path}/{k}"), out);
            }
        }
        Value::Object(o) => {
            for (k, x) in o {
                numeric_paths(x, format!("{path}/{k}"), out);
            }
        }
        _ => {}
    }
}

#[test]
fn every_numeric_field_at_edge_values_ends_in_triangles_or_an_error() {
    let (doc, bin) = rich_doc();
    gltf_ok(&doc, &bin);
    let mut paths = Vec::new();
    numeric_paths(&doc, String::new(), &mut paths);
    assert!(paths.len() > 60, "{}", paths.len());
    let edges = [
        json!(0),
        json!(1),
        json!(3),
        json!(7),
        json!(255),
        json!(65535),
        json!(4294967295u64),
        json!(u64::MAX),
        json!(-1),
        json!(1e30),
    ];
    let dir = tempfile::tempdir().unwrap();
    let mut outcomes = (0, 0);
    for path in &paths {
        for edge in &edges {
            let mut d = doc.clone();
            *d.pointer_mut(path).unwrap() = edge.clone();
            let file = write_gltf(dir.path(), &d, &bin);
            match run(&file) {
                Ok(_) => outcomes.0 += 1,
                Err(_) => outcomes.1 += 1,
            }
        }
    }
    assert!(outcomes.0 > 0 && outcomes.1 > 0, "{outcomes:?}");
}

#[test]
fn glb_bytes_overwritten_anywhere_end_in_triangles_or_an_error() {
    let (mut doc, bin) = rich_doc();
    doc["buffers"][0].as_object_mut().unwrap().remove("uri");
    let good = glb_bytes(&doc, &bin);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.glb");
    // Every byte of the headers and the binary data; a sample of the JSON text, whose
    // damage the JSON parser reports.
    let json_end = 20 + u32::from_le_bytes(good[12..16].try_into().unwrap()) as usize;
    let positions = (0..20)
        .chain((20..json_end).step_by(17))
        .chain(json_end..good.len());
    for at in positions {
        for byte in [0x00, 0x7F, 0xFF] {
            let mut b = good.clone();
            b[at] = byte;
            std::fs::write(&path, &b).unwrap();
            let _ = run(&path);
        }
    }
    for len in [0, 3, 11, 12, 19, 20, good.len() / 2, good.len() - 1] {
        std::fs::write(&path, &good[..len]).unwrap();
        assert!(run(&path).is_err(), "truncated to {len}");
    }
}
