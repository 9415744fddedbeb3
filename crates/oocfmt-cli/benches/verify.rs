//! How fast `verify` runs against the floor it cannot beat: reading, CRC-checking and
//! decompressing every block. Builds a demo container per codec once, then measures on one
//! thread (per-core figures) and on all threads. `cargo bench -p oocfmt-cli --bench verify`.

use std::path::{Path, PathBuf};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use oocfmt::verify::{verify, Depth, VerifyOptions};
use oocfmt::{Codec, FileSource, ReadOptions, Reader, WriteOptions};
use oocfmt_build::kdtree::{self, KdBuildOptions};
use oocfmt_build::layout::{write_container, LayoutOptions};
use oocfmt_scenes::demo::demo_scene;

const TRIANGLES: usize = 400_000;

fn container(dir: &Path, codec: Codec) -> Option<PathBuf> {
    let mesh = demo_scene(TRIANGLES);
    let tree = kdtree::build(&mesh, &KdBuildOptions::default()).ok()?;
    let path = dir.join(format!("bench-{:?}.oocf", codec).replace([':', '(', ')'], ""));
    let opts = LayoutOptions {
        write: WriteOptions {
            codec,
            ..WriteOptions::default()
        },
        ..LayoutOptions::default()
    };
    write_container(&path, &mesh, &tree, &opts).ok()?;
    Some(path)
}

/// Reads, checks and decompresses every block: the floor under a full verify.
fn read_all(path: &Path) -> usize {
    let Ok(r) = Reader::open(path, ReadOptions::default()) else {
        return 0;
    };
    (0..r.entries().len() as u32)
        .filter_map(|id| r.read_block(id).ok())
        .map(|b| b.data.len())
        .sum()
}

fn run_verify(path: &Path, depth: Depth) -> bool {
    let Ok(src) = FileSource::open(path) else {
        return false;
    };
    let opts = VerifyOptions {
        depth,
        ..VerifyOptions::default()
    };
    verify(&src, "bench", &opts, &|_| {})
        .map(|r| r.valid)
        .unwrap_or(false)
}

fn bench(c: &mut Criterion) {
    let Ok(dir) = tempfile::tempdir() else { return };
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().ok();
    for codec in [Codec::None, Codec::Lz4, Codec::Zstd(3)] {
        let Some(path) = container(dir.path(), codec) else {
            continue;
        };
        assert!(
            run_verify(&path, Depth::Deep),
            "the bench container must be valid"
        );
        let len = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
        let mut g = c.benchmark_group(format!("verify-{}", codec.id().name()));
        g.throughput(Throughput::Bytes(len));
        g.sample_size(10);
        g.bench_function("read+crc+decompress, 1 thread", |b| {
            b.iter(|| read_all(&path))
        });
        if let Some(pool) = &one {
            g.bench_function("full, 1 thread", |b| {
                b.iter(|| pool.install(|| run_verify(&path, Depth::Full)))
            });
            g.bench_function("deep, 1 thread", |b| {
                b.iter(|| pool.install(|| run_verify(&path, Depth::Deep)))
            });
        }
        g.bench_function("full, all threads", |b| {
            b.iter(|| run_verify(&path, Depth::Full))
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
