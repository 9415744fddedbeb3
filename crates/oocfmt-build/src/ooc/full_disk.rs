//! A disk that fills up during a conversion: whichever spill write runs out of space (the
//! import's, a split pass's, a chunk's blocks), the error says so and names the file, and the
//! conversion leaves no output, no spill files, and an existing output untouched.

use std::path::Path;

use super::disk::with_test_disk;
use crate::convert::{convert, ConvertError, ConvertOptions, BYTES_PER_TRIANGLE_IN_CORE};
use crate::progress::NoProgress;
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut n: Vec<String> = std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(Result::ok)
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    n.sort();
    n
}

#[test]
fn a_full_disk_at_any_point_leaves_nothing_and_says_why() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let obj = dir.path().join("mb.obj");
    let opts = MandelbulbOptions {
        triangles: 20_000,
        ..MandelbulbOptions::default()
    };
    mandelbulb::write_obj(&obj, &opts, &mut |_, _| {}).unwrap_or_else(|e| panic!("{e}"));
    let out = dir.path().join("out.oocf");
    // Treelets of one level make the chunks' blocks outweigh the triangle records, so the
    // spill peaks while chunks are built, not while the soup is split.
    let convert_opts = ConvertOptions {
        mem_limit: 5000 * BYTES_PER_TRIANGLE_IN_CORE,
        layout: crate::layout::LayoutOptions {
            treelet_height: 1,
            ..Default::default()
        },
        ..ConvertOptions::default()
    };
    let run = |budget: Option<u64>| {
        with_test_disk(8192, budget, || {
            convert(
                std::slice::from_ref(&obj),
                &out,
                &convert_opts,
                &mut NoProgress,
            )
        })
    };
    let full = run(None).unwrap_or_else(|e| panic!("{e}"));
    assert!(full.out_of_core.is_some());
    let good = std::fs::read(&out).unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(&out, b"an older file").unwrap_or_else(|e| panic!("{e}"));
    let before = names(dir.path());

    let mut failed_in = std::collections::BTreeSet::new();
    let step = full.peak_disk_bytes / 40;
    for k in 1..=40 {
        match run(Some(step * k)) {
            Ok(_) => {
                // Enough room after all: the same file as without a budget.
                assert_eq!(std::fs::read(&out).ok().as_ref(), Some(&good), "budget {k}");
                std::fs::write(&out, b"an older file").unwrap_or_else(|e| panic!("{e}"));
            }
            Err(e) => {
                let m = e.to_string();
                assert!(
                    m.contains("no space left") && m.contains("--tmp-dir"),
                    "{m}"
                );
                let phase = match &e {
                    ConvertError::Import(_) => "import",
                    // The import run's last segment, flushed once the input is read.
                    _ if m.contains("import.soup") => "import",
                    _ if m.contains("blocks-") => "blocks",
                    _ if m.contains("-l.soup") || m.contains("-r.soup") => "split",
                    _ => panic!("an unexpected failure: {m}"),
                };
                failed_in.insert(phase);
                assert_eq!(
                    std::fs::read(&out).ok().as_deref(),
                    Some(&b"an older file"[..])
                );
                assert_eq!(names(dir.path()), before, "budget {k}: {m}");
            }
        }
    }
    assert_eq!(
        failed_in.into_iter().collect::<Vec<_>>(),
        ["blocks", "import", "split"]
    );
}
