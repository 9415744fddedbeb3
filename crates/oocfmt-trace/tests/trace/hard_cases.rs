//! Numerical stability on hard cases, through the whole path (converted container, blocking
//! cache, tree traversal, watertight kernel): rays at shared edges and vertices of closed
//! meshes, axis-parallel rays with ±0 components, rays in split planes, on box faces, inside
//! cells and grazing surfaces, ten million random rays against brute force, scenes translated
//! and scaled far from unit size, slivers and jittered coplanar surfaces, and ties between
//! coplanar duplicates.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use oocfmt_build::convert::{convert, ConvertOptions};
use oocfmt_build::progress::NoProgress;
use oocfmt_meshio::import::Recentre;
use oocfmt_scenes::cad::{self, CadOptions};
use oocfmt_scenes::rng::Rng;
use oocfmt_trace::blocks::{NodeView, TreeletData};
use oocfmt_trace::intersect::{ray_box, Ray};
use oocfmt_trace::traverse::{Memo, Tracer};
use oocfmt_trace::{render, BlockingCache, Camera, RenderOptions, Scene};
use rayon::prelude::*;

type Tri = [[f32; 3]; 3];
type Edge = ([f32; 3], [f32; 3]);
/// A case of the translation and scale test: name, coordinate map, re-centring, the map's
/// scale (depths divide by it).
type Placement = (&'static str, Box<dyn Fn(f64) -> f64>, Recentre, f64);

/// A uniform direction in f32.
fn direction(rng: &mut Rng) -> [f32; 3] {
    rng.direction().map(|c| c as f32)
}

/// Writes `v` and `f` lines (positions printed so that they read back bit-exact) and converts.
fn container(
    dir: &Path,
    name: &str,
    v: &[[f64; 3]],
    f: &[[usize; 3]],
    opts: &ConvertOptions,
) -> PathBuf {
    let mut text = String::new();
    for p in v {
        writeln!(text, "v {} {} {}", p[0], p[1], p[2]).unwrap();
    }
    for t in f {
        writeln!(text, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
    let obj = dir.join(format!("{name}.obj"));
    std::fs::write(&obj, text).unwrap();
    let out = dir.join(format!("{name}.oocf"));
    convert(&[obj], &out, opts, &mut NoProgress).unwrap();
    out
}

fn plain() -> ConvertOptions {
    ConvertOptions {
        mem_limit: 1 << 30,
        ..ConvertOptions::default()
    }
}

/// A triangle soup as an indexed mesh (three vertices per triangle).
fn soup(tris: &[Tri]) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let v = tris.iter().flatten().map(|p| p.map(f64::from)).collect();
    let f = (0..tris.len())
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    (v, f)
}

/// The nearest hit distance of each ray through the tree (+inf for a miss), at full detail.
fn trace_all(scene: &Arc<Scene>, rays: &[Ray]) -> Vec<f32> {
    let cache = BlockingCache::new(Arc::clone(scene), 512 << 20);
    let tracer = Tracer::new(scene, &cache, 0.0);
    rays.par_chunks(4096)
        .map_init(
            || Memo::new(scene),
            |memo, chunk| {
                memo.clear();
                chunk
                    .iter()
                    .map(|r| tracer.trace(r, memo).map_or(f32::INFINITY, |h| h.t))
                    .collect::<Vec<_>>()
            },
        )
        .flatten()
        .collect()
}

/// The nearest hit over every triangle, skipping triangles whose box (padded by `pad`) the
/// ray misses; the kernel is the tracer's, so distances compare exactly.
fn brute_force(rays: &[Ray], tris: &[Tri], pad: f32) -> Vec<f32> {
    let boxes: Vec<([f32; 3], [f32; 3])> = tris
        .iter()
        .map(|t| {
            let lo = [0, 1, 2].map(|k| t[0][k].min(t[1][k]).min(t[2][k]));
            let hi = [0, 1, 2].map(|k| t[0][k].max(t[1][k]).max(t[2][k]));
            (lo, hi)
        })
        .collect();
    rays.par_iter()
        .map(|r| {
            let mut best = f32::INFINITY;
            for (t, &(lo, hi)) in tris.iter().zip(&boxes) {
                if ray_box(r, lo, hi, pad, 0.0, f32::INFINITY).is_none() {
                    continue;
                }
                if let Some(h) = r.triangle(&t[0], &t[1], &t[2]) {
                    best = best.min(h.t);
                }
            }
            best
        })
        .collect()
}

/// Pixels where tree and brute force disagree, with the first few for the failure message.
fn disagreements(rays: &[Ray], got: &[f32], want: &[f32]) -> (usize, String) {
    let mut n = 0;
    let mut first = String::new();
    for ((r, g), w) in rays.iter().zip(got).zip(want) {
        let same = g == w || (g.is_infinite() && w.is_infinite());
        if !same || g.is_nan() {
            n += 1;
            if n <= 5 {
                writeln!(
                    first,
                    "  org {:?} dir {:?}: tree {g}, brute force {w}",
                    r.org, r.dir
                )
                .unwrap();
            }
        }
    }
    (n, first)
}

fn scene_bounds(scene: &Scene) -> ([f32; 3], [f32; 3]) {
    let m = scene.metadata();
    (m.scene.bounds_min, m.scene.bounds_max)
}

/// Every split plane of the tree, as (axis, position).
fn split_planes(scene: &Scene) -> Vec<(usize, f32)> {
    let mut planes = Vec::new();
    for (id, e) in (0u32..).zip(scene.reader().entries()) {
        if e.kind != oocfmt::BlockKind::Treelet {
            continue;
        }
        let d: TreeletData = scene.load_treelets(id).unwrap();
        for n in d.nodes() {
            match n {
                NodeView::Inner { axis, split, .. } | NodeView::Lod { axis, split, .. } => {
                    planes.push((usize::from(axis), split));
                }
                NodeView::Leaf { .. } => {}
            }
        }
    }
    planes
}

/// Interior edges of a triangle set (shared by exactly two triangles, matched by the bits of
/// their end points) and its vertices.
fn shared_edges_and_vertices(tris: &[Tri]) -> (Vec<Edge>, Vec<[f32; 3]>) {
    let key = |p: &[f32; 3]| p.map(f32::to_bits);
    let mut edges: HashMap<[[u32; 3]; 2], (usize, Edge)> = HashMap::new();
    let mut vertices: HashMap<[u32; 3], [f32; 3]> = HashMap::new();
    for t in tris {
        for (i, j) in [(0, 1), (1, 2), (2, 0)] {
            let (a, b) = (t[i], t[j]);
            let mut k = [key(&a), key(&b)];
            k.sort_unstable();
            edges.entry(k).or_insert((0, (a, b))).0 += 1;
            vertices.insert(key(&a), a);
        }
    }
    let mut e: Vec<_> = edges
        .into_values()
        .filter(|&(n, _)| n == 2)
        .map(|(_, e)| e)
        .collect();
    e.sort_by(|x, y| {
        x.0.map(f32::to_bits)
            .cmp(&y.0.map(f32::to_bits))
            .then(x.1.map(f32::to_bits).cmp(&y.1.map(f32::to_bits)))
    });
    let mut v: Vec<_> = vertices.into_values().collect();
    v.sort_by_key(|p| p.map(f32::to_bits));
    (e, v)
}

/// A cube [-1, 1]³ whose faces are cut into n × n squares of two triangles each.
fn split_cube(n: usize) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let mut index: HashMap<[i64; 3], usize> = HashMap::new();
    let mut v = Vec::new();
    let mut f = Vec::new();
    let mut vertex = |g: [i64; 3], v: &mut Vec<[f64; 3]>| {
        *index.entry(g).or_insert_with(|| {
            v.push(g.map(|c| 2.0 * c as f64 / n as f64 - 1.0));
            v.len() - 1
        })
    };
    let n = n as i64;
    for axis in 0..3 {
        for side in [0, n] {
            for i in 0..n {
                for j in 0..n {
                    let at = |a: i64, b: i64| {
                        let mut g = [0; 3];
                        g[axis] = side;
                        g[(axis + 1) % 3] = a;
                        g[(axis + 2) % 3] = b;
                        g
                    };
                    let q = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]
                        .map(|g| vertex(g, &mut v));
                    f.push([q[0], q[1], q[2]]);
                    f.push([q[0], q[2], q[3]]);
                }
            }
        }
    }
    (v, f)
}

#[test]
fn a_million_rays_at_shared_edges_and_vertices_of_closed_meshes_never_slip_through() {
    let dir = tempfile::tempdir().unwrap();
    let (sv, sf) = common::sphere(5);
    let sphere = container(
        dir.path(),
        "sphere",
        &sv.iter().map(|p| p.map(f64::from)).collect::<Vec<_>>(),
        &sf,
        &plain(),
    );
    let (cv, cf) = split_cube(24);
    let cube = container(dir.path(), "cube", &cv, &cf, &plain());
    let bulb_dir = dir.path().join("bulb");
    std::fs::create_dir(&bulb_dir).unwrap();
    let bulb = common::mandelbulb(&bulb_dir, 5_000);
    let mut rng = Rng(1);
    let mut total = 0;
    // Origins inside each closed surface (radius: how far from the centre, as a share of the
    // size): every ray from inside must cross the surface, so a miss is a crack. (From
    // outside, a ray aimed at a surface point that rounding moved a hair outside a convex
    // surface may rightly pass it by.)
    for (path, spread) in [(sphere, 0.35), (cube, 0.4), (bulb, 0.01)] {
        let scene = Arc::new(Scene::open(&path).unwrap());
        let tris = common::all_triangles(&scene);
        let (edges, vertices) = shared_edges_and_vertices(&tris);
        let mut targets = vertices;
        for &(a, b) in &edges {
            for s in [0.5, 0.25, 0.875, 1.0 / 3.0, rng.unit() as f32] {
                targets.push([0, 1, 2].map(|k| a[k] + s * (b[k] - a[k])));
            }
        }
        let (lo, hi) = scene_bounds(&scene);
        let c = [0, 1, 2].map(|k| (lo[k] + hi[k]) / 2.0);
        let size = (0..3).map(|k| hi[k] - lo[k]).fold(0f32, f32::max);
        let origins: Vec<[f32; 3]> = (0..8)
            .map(|i| {
                let d = direction(&mut rng);
                let r = if i == 0 {
                    0.0
                } else {
                    spread * size * rng.unit() as f32
                };
                [0, 1, 2].map(|k| c[k] + r * d[k])
            })
            .collect();
        let mut rays = Vec::new();
        for o in &origins {
            for t in &targets {
                let d = [0, 1, 2].map(|k| t[k] - o[k]);
                rays.push(Ray::new(*o, d));
            }
        }
        let got = trace_all(&scene, &rays);
        // The direction is target − origin, so the target sits at t ≈ 1: the ray must meet
        // the surface there or before.
        let slipped: Vec<_> = rays
            .iter()
            .zip(&got)
            .filter(|(_, &t)| t.is_nan() || t > 1.0 + 1e-5)
            .map(|(ray, t)| (ray.org, ray.dir, *t))
            .collect();
        assert!(
            slipped.is_empty(),
            "{}: {} of {} rays slipped through, e.g. {:?}",
            path.display(),
            slipped.len(),
            rays.len(),
            &slipped[..slipped.len().min(3)]
        );
        total += rays.len();
    }
    assert!(total >= 1_000_000, "{total} rays");
}

/// A CAD-like scene (thin pipes, bolts, jittered coplanar panels) of `n` triangles.
fn cad(dir: &Path, n: u64) -> PathBuf {
    let obj = dir.join(format!("cad-{n}.obj"));
    let opts = CadOptions {
        triangles: n,
        seed: 11,
        normals: false,
        parts: Some(0),
    };
    cad::write_obj(&obj, &opts, &mut |_, _| {}).unwrap();
    let out = dir.join(format!("cad-{n}.oocf"));
    common::convert_obj(&obj, &out);
    out
}

#[test]
fn ten_million_random_rays_find_the_brute_force_nearest_hit() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Arc::new(Scene::open(&cad(dir.path(), 240)).unwrap());
    let tris = common::all_triangles(&scene);
    let (lo, hi) = scene_bounds(&scene);
    let size = (0..3).map(|k| hi[k] - lo[k]).fold(0f32, f32::max);
    let mut rng = Rng(2);
    let mut total = 0;
    // In batches, to keep memory small.
    for _ in 0..10 {
        let rays: Vec<Ray> = (0..1_000_000)
            .map(|_| {
                let o = [0, 1, 2].map(|k| {
                    let m = 0.25 * (hi[k] - lo[k]);
                    rng.range(f64::from(lo[k] - m), f64::from(hi[k] + m)) as f32
                });
                Ray::new(o, direction(&mut rng))
            })
            .collect();
        let got = trace_all(&scene, &rays);
        let want = brute_force(&rays, &tris, 1e-3 * size);
        let (n, first) = disagreements(&rays, &got, &want);
        assert_eq!(n, 0, "{n} of {} rays disagree:\n{first}", rays.len());
        assert!(want.iter().filter(|t| t.is_finite()).count() > 100_000);
        total += rays.len();
    }
    assert_eq!(total, 10_000_000);
}

#[test]
fn axis_parallel_split_plane_box_face_inside_and_grazing_rays_agree_with_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    for path in [
        cad(dir.path(), 2_000),
        common::mandelbulb(dir.path(), 3_000),
    ] {
        let scene = Arc::new(Scene::open(&path).unwrap());
        let tris = common::all_triangles(&scene);
        let (lo, hi) = scene_bounds(&scene);
        let size = (0..3).map(|k| hi[k] - lo[k]).fold(0f32, f32::max);
        let planes = split_planes(&scene);
        assert!(planes.len() > 100);
        let mut rng = Rng(3);
        let inside =
            |rng: &mut Rng| [0, 1, 2].map(|k| rng.range(f64::from(lo[k]), f64::from(hi[k])) as f32);
        let mut rays = Vec::new();
        let axes = [[1.0f32, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        // Axis-parallel, with +0 and −0 in the other components, from outside and inside.
        for i in 0..30_000 {
            let k = i % 3;
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            let zero = if (i / 6) % 2 == 0 { 0.0 } else { -0.0 };
            let mut d = [zero; 3];
            d[k] = sign;
            let mut o = inside(&mut rng);
            if i % 4 < 2 {
                o[k] = if sign > 0.0 {
                    lo[k] - 0.1 * size
                } else {
                    hi[k] + 0.1 * size
                };
            }
            rays.push(Ray::new(o, d));
        }
        // In a split plane (one component exactly the split, that direction component ±0),
        // and across it from a point on it.
        for i in 0..30_000 {
            let (k, split) = planes[rng.next_u64() as usize % planes.len()];
            let mut o = inside(&mut rng);
            o[k] = split;
            let mut d = direction(&mut rng);
            if i % 2 == 0 {
                d[k] = if i % 4 == 0 { 0.0 } else { -0.0 };
            }
            rays.push(Ray::new(o, d));
        }
        // From the faces of the scene's box, and exactly along its edges.
        for i in 0..20_000 {
            let k = i % 3;
            let mut o = inside(&mut rng);
            o[k] = if i % 2 == 0 { lo[k] } else { hi[k] };
            let d = if i % 5 == 0 {
                axes[(k + 1) % 3]
            } else {
                direction(&mut rng)
            };
            rays.push(Ray::new(o, d));
        }
        // Grazing: from a point in a triangle's plane, along one of its edges or nearly so.
        for i in 0..20_000 {
            let t = &tris[rng.next_u64() as usize % tris.len()];
            let e = [0, 1, 2].map(|k| t[1][k] - t[0][k]);
            let s = rng.range(-2.0, -0.5) as f32;
            let o = [0, 1, 2].map(|k| t[0][k] + s * e[k]);
            let tilt = if i % 2 == 0 { 0.0 } else { 1e-6 };
            let n = direction(&mut rng);
            let d = [0, 1, 2].map(|k| e[k] + tilt * n[k]);
            rays.push(Ray::new(o, d));
        }
        assert!(rays.len() >= 100_000);
        let got = trace_all(&scene, &rays);
        let want = brute_force(&rays, &tris, 1e-3 * size);
        let (n, first) = disagreements(&rays, &got, &want);
        assert_eq!(
            n,
            0,
            "{}: {n} of {} rays disagree:\n{first}",
            path.display(),
            rays.len()
        );
    }
}

/// The Mandelbulb of `common::mandelbulb` as written, with every coordinate mapped.
fn mapped_bulb(dir: &Path, name: &str, map: impl Fn(f64) -> f64, recentre: Recentre) -> PathBuf {
    let scene = Scene::open(&common::mandelbulb(dir, 4_000)).unwrap();
    let (v, f) = soup(&common::all_triangles(&scene));
    let v: Vec<[f64; 3]> = v.iter().map(|p| p.map(&map)).collect();
    let opts = ConvertOptions {
        recentre,
        ..plain()
    };
    container(dir, name, &v, &f, &opts)
}

#[test]
fn translated_and_scaled_scenes_give_the_same_picture() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (121, 91);
    let cases: Vec<Placement> = vec![
        ("unit", Box::new(|c| c), Recentre::None, 1.0),
        ("small", Box::new(|c| c * 1e-6), Recentre::None, 1e-6),
        ("large", Box::new(|c| c * 1e6), Recentre::None, 1e6),
        ("far", Box::new(|c| c + 1e6), Recentre::Auto, 1.0),
        ("farther", Box::new(|c| c + 1e7), Recentre::Auto, 1.0),
    ];
    let mut reference: Option<Vec<f32>> = None;
    for (name, map, recentre, scale) in cases {
        let sub = dir.path().join(name);
        std::fs::create_dir(&sub).unwrap();
        let path = mapped_bulb(&sub, name, &map, recentre);
        let scene = Arc::new(Scene::open(&path).unwrap());
        let origin = scene.metadata().scene.origin;
        // The same camera, mapped like the scene, in stored coordinates.
        let place = |p: [f64; 3]| [0, 1, 2].map(|k| map(p[k]) - origin[k]);
        let cam = Camera {
            eye: place([0.4, 0.9, 3.1]),
            look_at: place([0.0, 0.05, 0.0]),
            up: [0.0, 1.0, 0.0],
            fov_y: 40.0,
            width: w,
            height: h,
        };
        let cache = BlockingCache::new(Arc::clone(&scene), 256 << 20);
        let (img, _) = render(&scene, &cache, &cam, &RenderOptions::default()).unwrap();
        assert!(img.depth.iter().all(|d| !d.is_nan()), "{name}: NaN depth");
        let depth: Vec<f32> = img
            .depth
            .iter()
            .map(|&d| (f64::from(d) / scale) as f32)
            .collect();
        match &reference {
            None => {
                assert!(depth.iter().filter(|d| d.is_finite()).count() > (w * h / 4) as usize);
                reference = Some(depth);
            }
            Some(r) => {
                let flips = r
                    .iter()
                    .zip(&depth)
                    .filter(|(a, b)| a.is_finite() != b.is_finite())
                    .count();
                assert_eq!(
                    flips, 0,
                    "{name}: {flips} pixels change between hit and miss"
                );
                let worst = r
                    .iter()
                    .zip(&depth)
                    .filter(|(a, _)| a.is_finite())
                    .map(|(a, b)| ((a - b) / a).abs())
                    .fold(0f32, f32::max);
                // Stated bound: relative depth error 1e-5 (the positions themselves move by
                // up to one f32 rounding, 6e-8 of their magnitude).
                assert!(worst <= 1e-5, "{name}: relative depth error {worst}");
            }
        }
    }
}

#[test]
fn slivers_and_jittered_coplanar_surfaces_stay_finite_exact_and_repeatable() {
    let mut rng = Rng(4);
    let mut tris: Vec<Tri> = Vec::new();
    // Two overlapping grids of the same plane, one jittered by up to 1e-6 off it (as in
    // the 777's overlapping panels).
    for layer in 0..2 {
        for i in 0..20 {
            for j in 0..20 {
                let jit = |rng: &mut Rng| {
                    if layer == 0 {
                        0.0
                    } else {
                        rng.range(-1e-6, 1e-6) as f32
                    }
                };
                let p = |a: usize, b: usize, rng: &mut Rng| {
                    [a as f32 * 0.05, b as f32 * 0.05, jit(rng)]
                };
                let q = [
                    p(i, j, &mut rng),
                    p(i + 1, j, &mut rng),
                    p(i + 1, j + 1, &mut rng),
                    p(i, j + 1, &mut rng),
                ];
                tris.push([q[0], q[1], q[2]]);
                tris.push([q[0], q[2], q[3]]);
            }
        }
    }
    // Needles: aspect ratios up to 1e7, across the grid and standing on it.
    for i in 0..200 {
        let x = rng.range(0.0, 1.0) as f32;
        let y = rng.range(0.0, 1.0) as f32;
        let thin = 10f32.powi(-(i % 8) - 1);
        tris.push([
            [x, y, 0.2],
            [x + 0.5, y + 0.3, 0.21],
            [x + 0.5, y + 0.3 + thin, 0.21],
        ]);
        tris.push([[x, y, 0.0], [x, y, 0.3], [x + thin, y, 0.15]]);
    }
    let dir = tempfile::tempdir().unwrap();
    let (v, f) = soup(&tris);
    let path = container(dir.path(), "slivers", &v, &f, &plain());
    let scene = Arc::new(Scene::open(&path).unwrap());
    let stored = common::all_triangles(&scene);
    let (w, h) = (97, 73);
    let cams = [
        ([0.5, 0.45, 2.0], [0.5, 0.5, 0.0]),
        ([1.8, -0.6, 0.4], [0.5, 0.5, 0.1]),
        ([0.5, -1.5, 0.0], [0.5, 0.5, 0.0]),
    ];
    for (eye, look_at) in cams {
        let cam = Camera {
            eye,
            look_at,
            up: [0.0, 0.0, 1.0],
            fov_y: 50.0,
            width: w,
            height: h,
        };
        let frame = cam.frame().unwrap();
        let rays: Vec<Ray> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| frame.ray(x, y))
            .collect();
        let want = brute_force(&rays, &stored, 1e-3);
        let mut images = Vec::new();
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let cache = BlockingCache::new(Arc::clone(&scene), 64 << 20);
            let (img, _) = pool
                .install(|| render(&scene, &cache, &cam, &RenderOptions::default()))
                .unwrap();
            assert!(img.depth.iter().all(|d| !d.is_nan()));
            let (n, first) = disagreements(&rays, &img.depth, &want);
            assert_eq!(n, 0, "{n} pixels disagree:\n{first}");
            images.push(img.rgb);
        }
        assert!(
            images.windows(2).all(|p| p[0] == p[1]),
            "the image depends on the thread count"
        );
    }
}

#[test]
fn coplanar_duplicates_resolve_to_the_same_triangle_every_run() {
    // Every square twice, exactly, in two colours: which copy a ray sees is a tie.
    let mut text = String::new();
    let mut n = 0;
    for i in 0..16 {
        for j in 0..16 {
            for colour in ["1 0 0", "0 0 1"] {
                let (x, y) = (i as f32 * 0.1, j as f32 * 0.1);
                for (a, b) in [(0.0, 0.0), (0.1, 0.0), (0.1, 0.1), (0.0, 0.1)] {
                    writeln!(text, "v {} {} 0 {colour}", x + a, y + b).unwrap();
                }
                writeln!(text, "f {} {} {}", n + 1, n + 2, n + 3).unwrap();
                writeln!(text, "f {} {} {}", n + 1, n + 3, n + 4).unwrap();
                n += 4;
            }
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("dup.obj");
    std::fs::write(&obj, text).unwrap();
    let path = dir.path().join("dup.oocf");
    common::convert_obj(&obj, &path);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let cam = Camera {
        eye: [0.83, 0.71, 2.2],
        look_at: [0.8, 0.8, 0.0],
        up: [0.0, 1.0, 0.0],
        fov_y: 45.0,
        width: 101,
        height: 77,
    };
    let mut images = Vec::new();
    for threads in [1, 2, 4, 1, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let cache = BlockingCache::new(Arc::clone(&scene), 64 << 20);
        let (img, _) = pool
            .install(|| render(&scene, &cache, &cam, &RenderOptions::default()))
            .unwrap();
        images.push(img.rgb);
    }
    let red = images[0]
        .chunks(3)
        .filter(|p| u16::from(p[0]) > 2 * u16::from(p[2]))
        .count();
    let blue = images[0]
        .chunks(3)
        .filter(|p| u16::from(p[2]) > 2 * u16::from(p[0]))
        .count();
    assert!(
        red + blue > 3_000,
        "the squares fill the view: {red} red, {blue} blue"
    );
    assert!(
        images.windows(2).all(|p| p[0] == p[1]),
        "a tie resolved differently between runs"
    );
}

#[test]
fn a_voxel_is_chosen_only_when_its_projected_radius_is_within_the_poe() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Arc::new(Scene::open(&common::mandelbulb(dir.path(), 20_000)).unwrap());
    let cache = BlockingCache::new(Arc::clone(&scene), 256 << 20);
    let (lo, hi) = scene_bounds(&scene);
    let memo = Memo::new(&scene);
    for (eye, fov_y) in [([0.3, 0.8, 3.5], 45.0), ([0.1, 0.2, 1.6], 60.0)] {
        let cam = Camera {
            eye,
            look_at: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y,
            width: 160,
            height: 120,
        };
        let frame = cam.frame().unwrap();
        let mut fewer = 0;
        for poe in [0.0f32, 0.5, 2.0, 8.0, 32.0] {
            let c = poe * frame.pixel_angle() as f32;
            let tracer = Tracer::new(&scene, &cache, c);
            let (mut voxels, mut hits) = (0, 0);
            for y in 0..cam.height {
                for x in 0..cam.width {
                    let Some(h) = tracer.trace(&frame.ray(x, y), &memo) else {
                        continue;
                    };
                    hits += 1;
                    if matches!(h.surface, oocfmt_trace::traverse::Surface::Triangle { .. }) {
                        continue;
                    }
                    voxels += 1;
                    // The voxel's radius in pixels at its distance.
                    assert!(
                        h.radius <= h.t * c,
                        "poe {poe}: a voxel of radius {} at distance {} is {} pixels",
                        h.radius,
                        h.t,
                        h.radius / (h.t * frame.pixel_angle() as f32)
                    );
                }
            }
            assert!(hits > 1_000, "the view sees the model ({lo:?} .. {hi:?})");
            if poe == 0.0 {
                assert_eq!(voxels, 0, "a voxel at poe 0");
            }
            // A larger PoE lets a ray stop at the same LOD node or an earlier one.
            assert!(
                voxels >= fewer,
                "poe {poe}: {voxels} voxels, fewer than {fewer}"
            );
            fewer = voxels;
        }
        assert!(fewer > 0, "no voxel even at poe 32");
    }
}
