//! The out-of-core build: deterministic whatever the thread count, and its failures leave
//! neither an output nor spill files.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use oocfmt_build::convert::{convert, ConvertError, ConvertOptions, BYTES_PER_TRIANGLE_IN_CORE};
use oocfmt_build::progress::NoProgress;
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};

fn options(chunk_triangles: u64) -> ConvertOptions {
    ConvertOptions {
        mem_limit: chunk_triangles * BYTES_PER_TRIANGLE_IN_CORE,
        ..ConvertOptions::default()
    }
}

fn convert_in_pool(input: &Path, output: &Path, threads: usize) -> Vec<u8> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let report = pool
        .install(|| {
            convert(
                &[input.to_path_buf()],
                output,
                &options(6000),
                &mut NoProgress,
            )
        })
        .unwrap();
    let stats = report.out_of_core.expect("built out of core");
    assert!(stats.chunks >= 3, "{stats:?}");
    assert_eq!(stats.oversized_chunks, 0);
    std::fs::read(output).unwrap()
}

#[test]
fn the_chunked_build_is_byte_identical_whatever_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("mb.obj");
    let opts = MandelbulbOptions {
        triangles: 25_000,
        ..MandelbulbOptions::default()
    };
    mandelbulb::write_obj(&obj, &opts, &mut |_, _| {}).unwrap();
    let one = convert_in_pool(&obj, &dir.path().join("1.oocf"), 1);
    let two = convert_in_pool(&obj, &dir.path().join("2.oocf"), 2);
    let three = convert_in_pool(&obj, &dir.path().join("3.oocf"), 3);
    assert!(
        one == two && two == three,
        "outputs differ between thread counts"
    );
}

#[test]
fn a_failed_chunked_build_leaves_no_output_and_no_spill_files() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("bad.obj");
    let mut text = String::new();
    for k in 0..50 {
        let x = k as f32;
        text += &format!("v {x} 0 0\nv {} 0 0\nv {x} 1 0\n", x + 0.5);
    }
    for k in 0..50 {
        text += &format!("f {} {} {}\n", 3 * k + 1, 3 * k + 2, 3 * k + 3);
    }
    // A degenerate triangle at the end: refused under --strict after 50 have been spilled.
    text += "f 1 1 2\n";
    std::fs::write(&obj, text).unwrap();
    let out = dir.path().join("out.oocf");
    std::fs::write(&out, b"an older file").unwrap();
    let mut opts = options(10);
    opts.strict = true;
    let err = convert(std::slice::from_ref(&obj), &out, &opts, &mut NoProgress).unwrap_err();
    assert!(matches!(err, ConvertError::Import(_)), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"an older file");
    opts.strict = false;
    let report = convert(&[obj], &out, &opts, &mut NoProgress).unwrap();
    assert!(report.out_of_core.is_some_and(|s| s.chunks >= 3));
    assert_eq!(report.triangles_stored, 50);
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        names.iter().all(|n| !n.starts_with(".oocfmt-spill")),
        "{names:?}"
    );
}
