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

/// What the LOD entries of a file hold: the voxel lengths seen, how many voxel faces and R-LOD
/// records are partly covered, and how many R-LODs have a shade below 1. (The scene's faces are
/// axis-aligned, so no voxel face sees normals that disagree: its shade stays 1.)
#[derive(Debug, Default)]
struct LodSurvey {
    voxel_lens: std::collections::BTreeSet<usize>,
    faces_partly_covered: usize,
    rlods: usize,
    rlods_partly_covered: usize,
    rlods_shaded: usize,
}

fn survey_lods(path: &Path) -> Result<LodSurvey, String> {
    use oocfmt::{BlockKind, ReadOptions, Reader};
    let r = Reader::open(path, ReadOptions::default()).map_err(|e| e.to_string())?;
    let mut s = LodSurvey::default();
    for (id, e) in (0u32..).zip(r.entries()) {
        if e.kind != BlockKind::Treelet {
            continue;
        }
        let b = r.read_block(id).map_err(|e| e.to_string())?;
        let t = b.treelets().map_err(|e| e.to_string())?;
        t.walk_lods(|_, _, _, entry| {
            if let Some(v) = entry.voxel {
                s.voxel_lens.insert(entry.voxel_len);
                let faces = match v {
                    oocfmt::records::Voxel::Single(..) => 1,
                    oocfmt::records::Voxel::Six(..) => 6,
                };
                for f in (0..faces).map(|f| v.face(f).1) {
                    s.faces_partly_covered += usize::from(f.coverage < 255);
                }
            }
            if let Some(x) = entry.rlod {
                s.rlods += 1;
                s.rlods_partly_covered += usize::from(x.coverage < 255);
                s.rlods_shaded += usize::from(x.shade < 255);
            }
            Ok(())
        })
        .map_err(|e| e.to_string())?;
    }
    Ok(s)
}

/// Spec §14: `lod-filtered` holds voxels of all four lengths (4, 8, 24 and 36 bytes),
/// footprints with coverage below 1, and R-LOD records with coverage and shade; the other
/// vectors but `parts` (1.3) are unfiltered 1.0 and 1.1 files with neither.
#[test]
fn the_filtered_vector_holds_what_the_spec_lists() -> Result<(), String> {
    use oocfmt::records::LodKinds;
    use oocfmt::{ReadOptions, Reader};
    let fresh = tempfile::tempdir().map_err(|e| e.to_string())?;
    let paths = write_vectors(fresh.path()).map_err(|e| e.to_string())?;
    assert!(VECTOR_NAMES.contains(&"lod-filtered"));
    for (path, name) in paths.iter().zip(VECTOR_NAMES) {
        let r = Reader::open(path, ReadOptions::default()).map_err(|e| e.to_string())?;
        let (kinds, minor) = (r.lod_kinds(), r.header().minor);
        let s = survey_lods(path)?;
        // `inspect --json` names the bit (docs/inspect-json.md).
        let names = oocfmt::summary::summarize(&r)
            .map_err(|e| e.to_string())?
            .feature_names;
        let named = names.iter().any(|n| n == "LOD_FILTERED");
        assert_eq!(named, kinds.filtered, "{name}: {names:?}");
        // `parts` (1.3) is pre-filtered too, with a part word closing every LOD entry.
        let parts = names.iter().any(|n| n == "PART_IDS");
        assert_eq!((parts, kinds.parts), (name == "parts", name == "parts"));
        if name == "parts" {
            assert_eq!(
                (kinds, minor),
                (LodKinds::BOTH.filtered().with_parts(true), 3)
            );
            continue;
        }
        if name != "lod-filtered" {
            assert!(
                !kinds.filtered && minor <= 1,
                "{name}: {kinds:?} minor {minor}"
            );
            assert!(
                s.voxel_lens.iter().all(|&l| l == 4 || l == 24),
                "{name}: {s:?}"
            );
            continue;
        }
        assert_eq!((kinds, minor), (LodKinds::BOTH.filtered(), 2), "{name}");
        let lens: Vec<usize> = s.voxel_lens.iter().copied().collect();
        assert_eq!(lens, [4, 8, 24, 36], "{name}: {s:?}");
        assert!(s.faces_partly_covered > 0, "{name}: {s:?}");
        assert!(
            s.rlods > 0 && s.rlods_partly_covered > 0 && s.rlods_shaded > 0,
            "{name}: {s:?}"
        );
    }
    Ok(())
}
