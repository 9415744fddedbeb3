//! Tracer kernels: ray/triangle, ray/box, primary rays through the LOD traversal of a small
//! converted Mandelbulb (one thread, a warm blocking cache, full detail and PoE 2; ray by ray
//! and in 2 × 2 packets), and the decode of its largest treelet and triangle blocks into the
//! traversal's shapes. The format's kernels (checksums,
//! LZ4 and zstd block decode, record parsing, voxel samples) are in `oocfmt`'s `kernels`
//! bench. `cargo bench -p oocfmt-trace --bench kernels` (add `-- --quick` for a short run).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::sync::Arc;

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use oocfmt::BlockKind;
use oocfmt_build::convert::{convert, ConvertOptions};
use oocfmt_build::progress::NoProgress;
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};
use oocfmt_trace::blocks::{TreeletData, TriangleData};
use oocfmt_trace::intersect::{ray_box, Ray};
use oocfmt_trace::traverse::{Memo, Tracer};
use oocfmt_trace::{BlockingCache, Camera, Scene};

fn intersect(c: &mut Criterion) {
    let (a, b, t) = ([-1.0, -1.0, 5.0], [1.0, -1.0, 5.0], [0.0, 1.0, 5.0]);
    let hit = Ray::new([0.1, 0.2, 0.0], [0.01, -0.02, 1.0]);
    let miss = Ray::new([3.0, 0.2, 0.0], [0.01, -0.02, 1.0]);
    let mut g = c.benchmark_group("intersect");
    g.bench_function("ray/triangle hit", |bch| {
        bch.iter(|| black_box(&hit).triangle(black_box(&a), &b, &t))
    });
    g.bench_function("ray/triangle miss", |bch| {
        bch.iter(|| black_box(&miss).triangle(black_box(&a), &b, &t))
    });
    // What robustness costs: the textbook Möller–Trumbore test on the same rays, which lets
    // rays slip through shared edges (no common edge functions, no exact fallback).
    let (ho, hd) = ([0.1f32, 0.2, 0.0], [0.01f32, -0.02, 1.0]);
    let (mo, md) = ([3.0f32, 0.2, 0.0], [0.01f32, -0.02, 1.0]);
    g.bench_function("ray/triangle hit, not watertight", |bch| {
        bch.iter(|| moller_trumbore(black_box(ho), black_box(hd), &a, &b, &t))
    });
    g.bench_function("ray/triangle miss, not watertight", |bch| {
        bch.iter(|| moller_trumbore(black_box(mo), black_box(md), &a, &b, &t))
    });
    let (lo, hi) = ([-1.0, -1.0, 4.0], [1.0, 1.0, 6.0]);
    g.bench_function("ray/box hit", |bch| {
        bch.iter(|| ray_box(black_box(&hit), black_box(lo), hi, 0.0, 0.0, f32::INFINITY))
    });
    g.bench_function("ray/box miss", |bch| {
        bch.iter(|| ray_box(black_box(&miss), black_box(lo), hi, 0.0, 0.0, f32::INFINITY))
    });
    g.finish();
}

/// Möller and Trumbore (1997), both sides, t > 0: the non-robust baseline.
fn moller_trumbore(
    o: [f32; 3],
    d: [f32; 3],
    a: &[f32; 3],
    b: &[f32; 3],
    c: &[f32; 3],
) -> Option<f32> {
    let sub = |p: &[f32; 3], q: &[f32; 3]| [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
    let cross = |p: [f32; 3], q: [f32; 3]| {
        [
            p[1] * q[2] - p[2] * q[1],
            p[2] * q[0] - p[0] * q[2],
            p[0] * q[1] - p[1] * q[0],
        ]
    };
    let dot = |p: [f32; 3], q: [f32; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
    let (e1, e2) = (sub(b, a), sub(c, a));
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let s = sub(&o, a);
    let u = dot(s, p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = cross(s, e1);
    let v = dot(d, q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = dot(e2, q) * inv;
    (t > 0.0).then_some(t)
}

/// A 50k-triangle Mandelbulb converted into `dir`.
fn scene(dir: &Path) -> Arc<Scene> {
    let obj = dir.join("mb.obj");
    let opts = MandelbulbOptions {
        triangles: 50_000,
        ..MandelbulbOptions::default()
    };
    mandelbulb::write_obj(&obj, &opts, &mut |_, _| {}).unwrap();
    let out = dir.join("mb.oocf");
    convert(&[obj], &out, &ConvertOptions::default(), &mut NoProgress).unwrap();
    Arc::new(Scene::open(&out).unwrap())
}

fn traversal(c: &mut Criterion, scene: &Arc<Scene>) {
    let m = scene.metadata();
    let (w, h) = (32, 24);
    let mut camera = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, w, h);
    // Zoomed in on the middle, so nearly every ray meets the surface.
    camera.fov_y /= 3.0;
    let frame = camera.frame().unwrap();
    let rays: Vec<Ray> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| frame.ray(x, y))
        .collect();
    let packets: Vec<[Ray; 4]> = (0..h / 2)
        .flat_map(|py| (0..w / 2).map(move |px| (2 * px, 2 * py)))
        .map(|(x, y)| [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(i, j)| frame.ray(x + i, y + j)))
        .collect();
    let cache = BlockingCache::new(Arc::clone(scene), usize::MAX);
    let mut g = c.benchmark_group("primary rays (32x24, warm)");
    g.throughput(Throughput::Elements(rays.len() as u64));
    for poe in [0.0f64, 2.0] {
        let tracer = Tracer::new(scene, &cache, (poe * frame.pixel_angle()) as f32);
        let mut memo = Memo::new(scene);
        // Loads every block the rays want, so the timed runs only traverse.
        for r in &rays {
            tracer.trace(r, &memo);
        }
        g.bench_function(format!("poe {poe}"), |b| {
            b.iter(|| {
                rays.iter()
                    .filter(|r| tracer.trace(r, &memo).is_some())
                    .count()
            })
        });
        // The same rays in packets of 2 × 2 pixels, as `render` traces them.
        g.bench_function(format!("poe {poe}, 2x2 packets"), |b| {
            b.iter(|| {
                let mut hits = 0;
                for p in &packets {
                    let out = tracer.trace_packet(p, &[0, 1, 2, 3], &memo);
                    hits += out.iter().filter(|h| h.is_some()).count();
                }
                memo.release_deferred(u32::MAX);
                hits
            })
        });
        memo.flush(&cache);
    }
    g.finish();
}

fn block_decode(c: &mut Criterion, scene: &Scene) {
    let r = scene.reader();
    // The largest block of each kind: a full one, not the small top of the tree.
    let largest = |kind: BlockKind| {
        (0u32..)
            .zip(r.entries())
            .filter(|(_, e)| e.kind == kind)
            .max_by_key(|(_, e)| e.raw_length)
            .map(|(id, _)| r.read_block(id).unwrap())
            .unwrap()
    };
    let treelets = largest(BlockKind::Treelet);
    let triangles = largest(BlockKind::Triangle);
    let attrs = scene.metadata().triangle_attributes();
    let parts = scene.metadata().parts.len();
    let mut g = c.benchmark_group("block decode (of the decompressed block)");
    g.throughput(Throughput::Bytes(treelets.data.len() as u64));
    g.bench_function("treelet block -> TreeletData", |b| {
        b.iter(|| {
            TreeletData::decode(black_box(&treelets), r.entries(), parts)
                .unwrap()
                .node_count()
        })
    });
    g.throughput(Throughput::Bytes(triangles.data.len() as u64));
    g.bench_function("triangle block -> TriangleData", |b| {
        b.iter(|| {
            TriangleData::decode(black_box(&triangles), attrs, parts)
                .unwrap()
                .positions
                .len()
        })
    });
    g.finish();
}

fn on_a_scene(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene(dir.path());
    traversal(c, &scene);
    block_decode(c, &scene);
}

criterion_group!(benches, intersect, on_a_scene);
criterion_main!(benches);
