//! The committed spec vectors must be exactly what the generators produce today.
//!
//! `OOCFMT_BLESS=1 cargo test -p oocfmt-scenes --test scenes vectors::` rewrites them instead; commit the
//! result together with whatever change made them differ (and refresh the `inspect` outputs
//! beside them).

use std::path::{Path, PathBuf};

use oocfmt_scenes::vectors::{write_vectors, VECTOR_NAMES};

fn committed_dir() -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../spec/vectors")).to_path_buf()
}

#[test]
fn committed_vectors_match_the_generators() -> Result<(), String> {
    let committed = committed_dir();
    if std::env::var_os("OOCFMT_BLESS").is_some_and(|v| v == "1") {
        std::fs::create_dir_all(&committed).map_err(|e| e.to_string())?;
        write_vectors(&committed).map_err(|e| e.to_string())?;
        return Ok(());
    }
    let fresh = tempfile::tempdir().map_err(|e| e.to_string())?;
    let paths = write_vectors(fresh.path()).map_err(|e| e.to_string())?;
    assert_eq!(paths.len(), VECTOR_NAMES.len());
    for (path, name) in paths.iter().zip(VECTOR_NAMES) {
        let file = format!("{name}.oocf");
        let want = committed.join(&file);
        let expected = std::fs::read(&want).map_err(|e| {
            format!(
                "{}: {e} (run with OOCFMT_BLESS=1 to create it)",
                want.display()
            )
        })?;
        let got = std::fs::read(path).map_err(|e| e.to_string())?;
        if got != expected {
            let at = got
                .iter()
                .zip(&expected)
                .position(|(a, b)| a != b)
                .unwrap_or(got.len().min(expected.len()));
            return Err(format!(
                "{file}: regenerated ({} bytes) differs from spec/vectors ({} bytes) from byte {at}; \
                 if the change is intended, rerun with OOCFMT_BLESS=1",
                got.len(),
                expected.len()
            ));
        }
    }
    Ok(())
}

#[test]
fn leaves_sharing_triangles_store_them_once_per_block() -> Result<(), String> {
    use oocfmt::{BlockKind, Codec, WriteOptions};
    use oocfmt_build::layout::{build_blocks, LayoutOptions};
    let mesh = oocfmt_scenes::vectors::quad_mesh();
    let tree = oocfmt_scenes::vectors::quad_tree(&mesh).map_err(|e| e.to_string())?;
    let write = WriteOptions {
        codec: Codec::None,
        ..WriteOptions::default()
    }
    .with_block_size(4096)
    .map_err(|e| e.to_string())?;
    let opts = LayoutOptions {
        write,
        treelet_height: 3,
        ..LayoutOptions::default()
    };
    let container = build_blocks(&mesh, &tree, &opts).map_err(|e| e.to_string())?;
    let c = container.metadata.counts;
    assert_eq!(
        (
            c.triangles,
            c.triangle_records,
            c.vertices,
            c.basic_nodes,
            c.leaves,
            c.depth
        ),
        (2, 2, 4, 1, 2, 2)
    );
    let kinds: Vec<BlockKind> = container.blocks.iter().map(|b| b.kind).collect();
    assert_eq!(kinds, vec![BlockKind::Treelet, BlockKind::Triangle]);
    Ok(())
}
