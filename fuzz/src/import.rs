//! Fuzz properties of the STL and PLY importers, one function per target: whatever the bytes,
//! the import never panics, and the report adds up (triangles out = triangles in − dropped),
//! lenient (even after an error) and strict (when it finishes), with the mesh it gives valid; the bounds pass of `--recentre auto`
//! (a sink that wants positions only) never panics either.
//!
//! The only copy of the target bodies: `fuzz_targets/{stl,ply}_import.rs` call them through
//! the `oocfmt_fuzz` library, and `crates/oocfmt-meshio/tests/import/fuzz_corpus.rs` includes
//! this file by path (`#[path]`), so `cargo test` replays every seed and regression on stable.
//! Only the public API of `oocfmt-meshio` is used.

use std::io::Cursor;

use oocfmt_meshio::import::placement::BoundsSink;
use oocfmt_meshio::import::{ply, stl, ImportError, ImportReport, MeshSink, TriangleSink};

/// `stl_import`: the bytes as an STL file.
pub fn stl_import(data: &[u8]) {
    exercise(data, |input, sink| {
        stl::import_from(input, "fuzz.stl", sink, &stl::StlOptions::default())
    });
}

/// `ply_import`: the bytes as a PLY file.
pub fn ply_import(data: &[u8]) {
    exercise(data, |input, sink| {
        ply::import_from(input, "fuzz.ply", sink, &ply::PlyOptions::default())
    });
}

fn exercise(
    data: &[u8],
    import: impl Fn(Cursor<&[u8]>, &mut dyn TriangleSink) -> Result<(), ImportError>,
) {
    for strict in [false, true] {
        let mut sink = MeshSink::new(strict);
        let imported = import(Cursor::new(data), &mut sink);
        // A strict import stops at a refused triangle, which the sink has counted in but not
        // as dropped: only a finished strict import has a report to add up.
        if !strict || imported.is_ok() {
            adds_up(sink.report());
        }
        if imported.is_err() {
            continue;
        }
        // An empty result is an error of the sink's; anything else must make a valid mesh.
        if let Ok((mesh, report)) = sink.finish() {
            adds_up(&report);
            assert_eq!(mesh.triangles.len() as u64, report.triangles_out);
            if let Err(e) = mesh.validate() {
                panic!("the imported mesh is not valid: {e}");
            }
        }
    }
    let mut bounds = BoundsSink::default();
    let _ = import(Cursor::new(data), &mut bounds);
}

fn adds_up(r: &ImportReport) {
    assert_eq!(
        r.triangles_in,
        r.triangles_out + r.dropped_total(),
        "the report does not add up: {r:?}"
    );
}
