//! Kernel benchmarks: checksums, block codecs and record decoding, per 64 KiB block.
//! `cargo bench -p oocfmt --bench kernels`; criterion prints medians and throughput.

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use oocfmt::codec::decode_into;
use oocfmt::records::{
    Node, Sample, TreeletBlock, TreeletBlockWriter, Triangle, TriangleBlock, TriangleBlockWriter,
    Vertex, Voxel,
};
use oocfmt::Codec;

/// A 64 KiB-class treelet block with realistic structure: small treelets of basic and LOD
/// nodes with voxels, pseudo-random split positions.
fn treelet_block() -> Vec<u8> {
    let mut w = TreeletBlockWriter::new();
    let mut x = 0x2545_f491_u32;
    let mut rnd = move || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        x
    };
    while w.raw_len() + 120 < 65536 {
        w.begin_treelet();
        w.push_node(&Node::Basic {
            axis: (rnd() % 3) as u8,
            split: (rnd() % 1000) as f32 * 0.01,
            left: 1,
            right: 4,
        });
        w.push_node(&Node::Basic {
            axis: (rnd() % 3) as u8,
            split: (rnd() % 1000) as f32 * 0.01,
            left: 1,
            right: 2,
        });
        w.push_node(&Node::Leaf {
            count: 3,
            first: (rnd() % 1000) as u16,
            block: 900 + rnd() % 50,
        });
        w.push_node(&Node::Leaf {
            count: 2,
            first: (rnd() % 1000) as u16,
            block: 900 + rnd() % 50,
        });
        let s = Sample::pack([(rnd() % 7) as f32 - 3.0, 1.0, 0.5], [0.2, 0.6, 0.9]);
        let voxel = w.push_voxel(&Voxel::single(s), false);
        w.push_node(&Node::Lod {
            axis: 1,
            split: (rnd() % 1000) as f32 * 0.01,
            radius: 2.0,
            left_present: true,
            right_present: true,
            child_treelet: rnd() % 4000,
            child_block: 40 + rnd() % 100,
            voxel_offset: voxel,
            proxy: rnd() % 10_000,
        });
    }
    w.finish()
}

/// A triangle block of a smooth height field: shared vertices, positions only.
fn triangle_block() -> Vec<u8> {
    let mut w = TriangleBlockWriter::new(0);
    let n = 60u16;
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (f32::from(i) * 0.1, f32::from(j) * 0.1);
            let _ = w.push_vertex(Vertex {
                position: [x, y, (x * 3.0).sin() * (y * 2.0).cos()],
                normal: None,
                colour: None,
            });
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = j * n + i;
            let _ = w.push_triangle(Triangle {
                v: [v, v + 1, v + n],
                material: None,
                part: None,
            });
            let _ = w.push_triangle(Triangle {
                v: [v + 1, v + n + 1, v + n],
                material: None,
                part: None,
            });
        }
    }
    for t in 0..w.triangle_count() as u16 {
        let _ = w.push_list(t);
    }
    w.set_primary_count(w.triangle_count() as u16);
    w.finish()
}

fn checksums(c: &mut Criterion) {
    let data = treelet_block();
    let mut g = c.benchmark_group("checksum");
    g.throughput(Throughput::Bytes(data.len() as u64));
    g.bench_function("crc32c", |b| {
        b.iter(|| oocfmt::checksum::crc32c(black_box(&data)))
    });
    g.bench_function("crc32-ieee (crc32fast)", |b| {
        b.iter(|| crc32fast::hash(black_box(&data)))
    });
    g.finish();
}

fn codecs(c: &mut Criterion) {
    for (name, raw) in [("treelet", treelet_block()), ("triangle", triangle_block())] {
        let mut g = c.benchmark_group(format!("decode-{name}"));
        g.throughput(Throughput::Bytes(raw.len() as u64));
        for codec in [Codec::None, Codec::Lz4, Codec::Zstd(3)] {
            let Ok((id, stored)) = codec.encode(&raw) else {
                continue;
            };
            let mut out = vec![0u8; raw.len()];
            let label = format!(
                "{:?} ({:.2}x)",
                codec,
                raw.len() as f64 / stored.len() as f64
            );
            g.bench_with_input(BenchmarkId::from_parameter(label), &stored, |b, s| {
                b.iter(|| decode_into(id, black_box(s), &mut out))
            });
        }
        g.finish();
    }
}

fn records(c: &mut Criterion) {
    let treelets = treelet_block();
    let triangles = triangle_block();
    let mut g = c.benchmark_group("records");
    g.throughput(Throughput::Bytes(treelets.len() as u64));
    g.bench_function("treelet block parse+walk", |b| {
        b.iter(|| TreeletBlock::parse(black_box(&treelets)).and_then(|t| t.walk(|_, _, _| Ok(()))))
    });
    g.bench_function("node decode (one)", |b| {
        let view = TreeletBlock::parse(&treelets).ok();
        b.iter(|| view.map(|v| v.node(black_box(8))))
    });
    g.throughput(Throughput::Bytes(triangles.len() as u64));
    g.bench_function("triangle block parse+check", |b| {
        b.iter(|| {
            TriangleBlock::parse(black_box(&triangles), Some(0)).and_then(|t| t.check_contents())
        })
    });
    g.finish();
    let s = Sample::pack([0.3, -0.8, 0.5], [0.1, 0.5, 0.9]);
    c.bench_function("voxel sample decode (normal+colour)", |b| {
        b.iter(|| (black_box(s).normal(), black_box(s).colour()))
    });
}

criterion_group!(benches, checksums, codecs, records);
criterion_main!(benches);
