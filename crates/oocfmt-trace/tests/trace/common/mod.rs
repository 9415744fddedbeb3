//! Scenes for the tracer's tests: generated, converted into a temporary folder.
#![allow(clippy::unwrap_used, clippy::expect_used, dead_code)]

use std::path::{Path, PathBuf};
use std::sync::Arc;

use oocfmt::BlockKind;
use oocfmt_build::convert::{convert, ConvertOptions};
use oocfmt_build::layout::LayoutOptions;
use oocfmt_build::progress::NoProgress;
use oocfmt_scenes::cad::{self, CadOptions};
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};
use oocfmt_trace::intersect::Ray;
use oocfmt_trace::Scene;
use rayon::prelude::*;

pub fn convert_obj(obj: &Path, out: &Path) {
    convert_obj_with(obj, out, LayoutOptions::default());
}

fn convert_obj_with(obj: &Path, out: &Path, layout: LayoutOptions) {
    let opts = ConvertOptions {
        mem_limit: 1 << 30,
        layout,
        ..ConvertOptions::default()
    };
    convert(&[obj.to_path_buf()], out, &opts, &mut NoProgress).unwrap();
}

pub fn mandelbulb(dir: &Path, triangles: u64) -> PathBuf {
    mandelbulb_with(dir, triangles, LayoutOptions::default())
}

/// A Mandelbulb converted with `layout`.
pub fn mandelbulb_with(dir: &Path, triangles: u64, layout: LayoutOptions) -> PathBuf {
    let obj = dir.join("mb.obj");
    let opts = MandelbulbOptions {
        triangles,
        ..MandelbulbOptions::default()
    };
    mandelbulb::write_obj(&obj, &opts, &mut |_, _| {}).unwrap();
    let out = dir.join("mb.oocf");
    convert_obj_with(&obj, &out, layout);
    out
}

pub fn cad_scene(dir: &Path, triangles: u64) -> PathBuf {
    let obj = dir.join("cad.obj");
    let opts = CadOptions {
        triangles,
        seed: 7,
        normals: true,
        // No `o`/`g` lines: the files these tests were written against.
        parts: Some(0),
    };
    cad::write_obj(&obj, &opts, &mut |_, _| {}).unwrap();
    let out = dir.join("cad.oocf");
    convert_obj(&obj, &out);
    out
}

/// Every triangle record of the file, copies included.
pub fn all_triangles(scene: &Scene) -> Vec<[[f32; 3]; 3]> {
    let mut v = Vec::new();
    for (id, e) in (0u32..).zip(scene.reader().entries()) {
        if e.kind == BlockKind::Triangle {
            v.extend(scene.load_triangles(id).unwrap().positions);
        }
    }
    v
}

/// The nearest hit of each ray over every triangle, with the tracer's kernel.
pub fn brute_force(rays: &[Ray], triangles: &Arc<Vec<[[f32; 3]; 3]>>) -> Vec<f32> {
    rays.par_iter()
        .map(|r| {
            triangles
                .iter()
                .filter_map(|[a, b, c]| r.triangle(a, b, c))
                .fold(f32::INFINITY, |m, h| m.min(h.t))
        })
        .collect()
}

/// A unit sphere: an octahedron subdivided `levels` times, vertices pushed onto the sphere
/// (shared between neighbouring triangles: a closed mesh).
pub fn sphere(levels: u32) -> (Vec<[f32; 3]>, Vec<[usize; 3]>) {
    let mut v: Vec<[f64; 3]> = vec![
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let mut f: Vec<[usize; 3]> = vec![
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    for _ in 0..levels {
        let mut mids = std::collections::HashMap::new();
        let mut mid = |i: usize, j: usize, v: &mut Vec<[f64; 3]>| {
            *mids.entry((i.min(j), i.max(j))).or_insert_with(|| {
                let m = [0, 1, 2].map(|k| (v[i][k] + v[j][k]) / 2.0);
                let l = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
                v.push(m.map(|c| c / l));
                v.len() - 1
            })
        };
        let mut next = Vec::new();
        for [a, b, c] in f {
            let (ab, bc, ca) = (mid(a, b, &mut v), mid(b, c, &mut v), mid(c, a, &mut v));
            next.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        f = next;
    }
    (v.iter().map(|p| p.map(|c| c as f32)).collect(), f)
}
