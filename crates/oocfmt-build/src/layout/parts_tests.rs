//! Parts through the in-core layout: the part table against a recount from the mesh, ids in
//! every triangle record, part words in every LOD entry, nothing of it for one part, and the
//! part word of a LOD entry as the part the rays see most.

use oocfmt::header::INCOMPAT_PART_IDS;
use oocfmt::records::triangle::ATTR_PART_WIDTH_SHIFT;
use oocfmt::records::LodKinds;
use oocfmt::{Codec, ReadOptions, Reader};

use super::tests::{build_tree, opts, read_back, s, write_and_read, Res};
use super::*;
use crate::lod::{compute, rlods, DEFAULT_VOXEL_THRESHOLD};
use oocfmt_meshio::mesh::{Bounds, PartDef};
use oocfmt_scenes::demo_scene;

/// The demo scene with `parts` parts: part 0 an assembly without triangles of its own, the
/// others under it, each holding the triangles of one slab along x (so LOD cells see several).
fn parted_demo(triangles: usize, parts: u32) -> Mesh {
    let mut mesh = demo_scene(triangles);
    let b = mesh.bounds();
    let slabs = parts - 1;
    let ids = (0..mesh.triangles.len())
        .map(|t| {
            let c = mesh.corners(t).unwrap_or_default();
            let x = (c[0][0] + c[1][0] + c[2][0]) / 3.0;
            let k = ((x - b.min[0]) / b.extent(0) * slabs as f32) as u32;
            1 + k.min(slabs - 1)
        })
        .collect();
    mesh.part_ids = Some(ids);
    mesh.parts = (0..parts)
        .map(|p| match p {
            0 => PartDef::new("assembly", None),
            _ => PartDef::new(format!("slab {p}"), Some(0)),
        })
        .collect();
    mesh
}

/// Per part, the triangles whose id it is and the box of their corners, counted plainly.
fn recount(mesh: &Mesh) -> Vec<(u64, Bounds)> {
    let mut out = vec![(0u64, Bounds::EMPTY); mesh.parts.len().max(1)];
    for t in 0..mesh.triangles.len() {
        let p = mesh.part_ids.as_ref().map_or(0, |ids| ids[t]) as usize;
        out[p].0 += 1;
        for c in mesh.corners(t).unwrap_or_default() {
            out[p].1.extend(c);
        }
    }
    out
}

fn check_table(found: &super::tests::Found, mesh: &Mesh) -> Res<()> {
    let table = &found.meta.parts;
    if table.len() != mesh.parts.len() {
        return Err(format!(
            "{} parts in the file, {} in the mesh",
            table.len(),
            mesh.parts.len()
        ));
    }
    for (k, ((part, def), (n, b))) in table.iter().zip(&mesh.parts).zip(recount(mesh)).enumerate() {
        let (lo, hi) = if n > 0 {
            (b.min, b.max)
        } else {
            ([0.0; 3], [0.0; 3])
        };
        if (
            &part.name,
            part.parent,
            part.triangles,
            part.bounds_min,
            part.bounds_max,
        ) != (&def.name, def.parent, n, lo, hi)
        {
            return Err(format!(
                "part {k}: {part:?}, recounted {n} in {lo:?}..{hi:?}"
            ));
        }
    }
    Ok(())
}

#[test]
fn the_part_table_and_ids_match_a_recount_of_the_mesh() -> Res<()> {
    // Four parts take u8 ids, 300 u16 ones.
    for (parts, width) in [(4u32, 1u16), (300, 2)] {
        let mesh = parted_demo(20_000, parts);
        let tree = build_tree(&mesh, 6)?;
        let o = opts(16 << 10, Codec::Lz4, 3);
        let (found, bytes) = write_and_read(&mesh, &tree, &o)?;
        check_table(&found, &mesh)?;
        let code = found.meta.triangle_attributes() >> ATTR_PART_WIDTH_SHIFT;
        assert_eq!(code, width, "{parts} parts");
        // Every LOD entry has a part word naming a part that has triangles; with slabs along
        // x, the words differ between cells.
        assert!(
            found.lod_parts.len() > 50,
            "{} LOD entries",
            found.lod_parts.len()
        );
        let words: Vec<u32> = found
            .lod_parts
            .iter()
            .map(|p| p.ok_or("no part word"))
            .collect::<Result<_, _>>()?;
        assert!(words.iter().all(|&p| p >= 1 && p < parts), "{words:?}");
        let distinct: std::collections::BTreeSet<u32> = words.iter().copied().collect();
        assert!(distinct.len() >= 3, "{distinct:?}");
        // The same bytes whatever the thread count.
        for threads in [1, 2, 4] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(s)?;
            let again = pool.install(|| write_and_read(&mesh, &tree, &o))?.1;
            assert!(
                again == bytes,
                "{parts} parts, {threads} threads: the file changed"
            );
        }
    }
    Ok(())
}

#[test]
fn a_scene_of_one_part_stores_no_ids_and_its_blocks_are_unchanged() -> Res<()> {
    let plain = demo_scene(8000);
    let mut one = plain.clone();
    one.parts = vec![PartDef::new("the model", None)];
    let tree = build_tree(&plain, 6)?;
    let o = opts(16 << 10, Codec::Lz4, 3);
    let dir = tempfile::tempdir().map_err(s)?;
    let (a, b) = (dir.path().join("plain.oocf"), dir.path().join("one.oocf"));
    write_container(&a, &plain, &tree, &o).map_err(s)?;
    write_container(&b, &one, &tree, &o).map_err(s)?;
    super::tests::deep_verify(&b)?;
    let found = read_back(&b, &one)?;
    check_table(&found, &one)?;
    assert_eq!(found.meta.parts[0].triangles, plain.triangles.len() as u64);
    assert!(found.lod_parts.iter().all(Option::is_none));
    let (ra, rb) = (
        Reader::open(&a, ReadOptions::default()).map_err(s)?,
        Reader::open(&b, ReadOptions::default()).map_err(s)?,
    );
    assert_eq!(rb.header().incompatible_features & INCOMPAT_PART_IDS, 0);
    assert_eq!(
        rb.header().incompatible_features,
        ra.header().incompatible_features
    );
    assert_eq!(rb.header().minor, 3);
    assert_eq!(
        rb.metadata().triangle_attributes(),
        ra.metadata().triangle_attributes()
    );
    // Every block's bytes are those of the scene without parts: only the metadata grew.
    assert_eq!(ra.entries().len(), rb.entries().len());
    for id in 0..ra.entries().len() as u32 {
        let (x, y) = (ra.read_block(id).map_err(s)?, rb.read_block(id).map_err(s)?);
        assert!(x.data == y.data, "block {id} differs");
    }
    Ok(())
}

/// An axis-aligned plate `[x0, x1] × [0, 1]` at height `z`, of `n` quads along x, facing +z.
fn plate(mesh: &mut Mesh, ids: &mut Vec<u32>, (x0, x1): (f32, f32), z: f32, n: u32, part: u32) {
    let base = mesh.positions.len() as u32;
    for i in 0..=n {
        let x = x0 + (x1 - x0) * i as f32 / n as f32;
        mesh.positions.extend([[x, 0.0, z], [x, 1.0, z]]);
    }
    for i in 0..n {
        let (a, b, c, d) = (
            base + 2 * i,
            base + 2 * i + 2,
            base + 2 * i + 3,
            base + 2 * i + 1,
        );
        mesh.triangles.extend([[a, b, c], [a, c, d]]);
        ids.extend([part, part]);
    }
}

/// Two plates side by side at different heights in one cell, the one of part `large` three
/// times the other's area; `n` quads per unit of length.
fn two_plates(large: u32, small: u32, n: u32) -> Mesh {
    let mut mesh = Mesh::default();
    let mut ids = Vec::new();
    plate(&mut mesh, &mut ids, (0.0, 3.0), 0.0, 3 * n, large);
    plate(&mut mesh, &mut ids, (3.0, 4.0), 0.5, n, small);
    mesh.part_ids = Some(ids);
    mesh.parts = vec![PartDef::new("a", None), PartDef::new("b", None)];
    mesh
}

#[test]
fn a_lod_entry_stands_for_the_part_covering_most_of_its_cell() -> Res<()> {
    // Few triangles are tested one by one, many through the subtree: both ways count votes.
    for n in [1, 8] {
        for (large, small) in [(1, 0), (0, 1)] {
            let mesh = two_plates(large, small, n);
            let tree = build_tree(&mesh, 1)?;
            let root = tree.root().ok_or("no root")?;
            let lod = compute(&mesh, &tree, &[root], DEFAULT_VOXEL_THRESHOLD);
            assert_eq!(
                lod.first().map(|d| d.part),
                Some(large),
                "{n} quads per unit"
            );
            // R-LOD only: the larger area clipped to the cell.
            let r = rlods(&mesh, &tree, &[root]);
            assert_eq!(r.first().map(|p| p.1), Some(large));
            // Through the layout, R-LOD-only entries included.
            for kinds in [LodKinds::VOXEL, LodKinds::RLOD, LodKinds::BOTH] {
                let mut o = opts(16 << 10, Codec::None, 1);
                o.write.lod = kinds.filtered();
                let (found, _) = write_and_read(&mesh, &tree, &o)?;
                assert_eq!(
                    found.lod_parts.first().copied().flatten(),
                    Some(large),
                    "{kinds:?}"
                );
            }
        }
    }
    Ok(())
}
