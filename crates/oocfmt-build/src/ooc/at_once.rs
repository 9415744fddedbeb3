//! Chunks built several at once give the bytes of the same chunks built one after another:
//! proxy ids, spill order, the top LOD nodes' nearest hits (an earlier chunk's on a tie) and the
//! R-LOD deviations are all settled in chunk order.

use std::path::Path;
use std::time::Instant;

use super::{build, Chunking};
use crate::convert::{import_soup, ConvertOptions};
use crate::progress::NoProgress;
use crate::report::PhaseClock;
use oocfmt::verify::{verify, Depth, VerifyOptions};
use oocfmt_scenes::cad::{self, CadOptions};
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};

/// Converts `obj` out of core in chunks of at most `chunk` triangles, `at_once` at a time;
/// returns the file's bytes and the number of chunks.
fn convert(obj: &Path, opts: &ConvertOptions, chunk: u64, at_once: usize) -> (Vec<u8>, u64) {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let out = dir.path().join("out.oocf");
    let inputs = [obj.to_path_buf()];
    let soup = import_soup(&inputs, opts, dir.path(), 0, [0.0; 3], &mut NoProgress)
        .unwrap_or_else(|e| panic!("{e}"));
    let chunking = Chunking {
        chunk_triangles: chunk * at_once as u64,
        at_once,
        dir: dir.path(),
    };
    let mut layout = opts.layout.clone();
    layout.sources = vec!["input.obj".into()];
    let mut clock = PhaseClock::new(Instant::now());
    let (_, stats) = build(
        soup,
        &out,
        &opts.kd,
        &layout,
        chunking,
        &mut clock,
        &mut NoProgress,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let src = oocfmt::FileSource::open(&out).unwrap_or_else(|e| panic!("{e}"));
    let deep = VerifyOptions {
        depth: Depth::Deep,
        ..VerifyOptions::default()
    };
    let report = verify(&src, "out.oocf", &deep, &|_| {}).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        report.valid && report.issues.is_empty(),
        "{:#?}",
        report.issues
    );
    let bytes = std::fs::read(&out).unwrap_or_else(|e| panic!("{e}"));
    (bytes, stats.chunks)
}

fn same_bytes_at_once(obj: &Path, opts: &ConvertOptions, chunk: u64) {
    let (one, chunks) = convert(obj, opts, chunk, 1);
    assert!(chunks >= 5, "{chunks} chunks");
    for at_once in [2, 3] {
        let (many, n) = convert(obj, opts, chunk, at_once);
        assert_eq!(n, chunks);
        assert!(one == many, "{at_once} chunks at once change the file");
    }
}

#[test]
fn chunks_built_at_once_give_the_bytes_of_chunks_built_in_turn() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let bulb = dir.path().join("mb.obj");
    let opts = MandelbulbOptions {
        triangles: 30_000,
        ..MandelbulbOptions::default()
    };
    mandelbulb::write_obj(&bulb, &opts, &mut |_, _| {}).unwrap_or_else(|e| panic!("{e}"));
    same_bytes_at_once(&bulb, &ConvertOptions::default(), 4000);
    // Voxels and parts too: six-sided samples, part words and part tallies per chunk.
    let parts = dir.path().join("cad.obj");
    let opts = CadOptions {
        triangles: 30_000,
        parts: Some(40),
        ..CadOptions::default()
    };
    cad::write_obj(&parts, &opts, &mut |_, _| {}).unwrap_or_else(|e| panic!("{e}"));
    let mut convert_opts = ConvertOptions::default();
    convert_opts.layout.write.lod = oocfmt::records::LodKinds::BOTH.filtered();
    same_bytes_at_once(&parts, &convert_opts, 4000);
}
