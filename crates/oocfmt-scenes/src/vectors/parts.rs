//! The `parts` vector (spec §14): the LOD vectors' scene as an assembly, so the part table, the
//! triangle blocks' part ids and the LOD entries' part words have a file of their own.

use std::path::Path;

use oocfmt::records::LodKinds;
use oocfmt::Codec;
use oocfmt_build::layout::write_container;
use oocfmt_meshio::mesh::{Mesh, PartDef};

use super::{lod_mesh, lod_tree, vector_options, VectorError};

/// The floor's triangles: the first face of [`lod_mesh`], 4 × 4 unit squares.
const FLOOR_TRIANGLES: usize = 32;
/// The cube's side triangles that follow the floor: four faces of 2 × 2 squares.
const SIDE_TRIANGLES: usize = 32;

/// [`lod_mesh`] as four parts three deep: an assembly with no triangles of its own over the
/// floor and the cube (its four sides), the cube over its lid (the top face). Four parts give
/// u8 ids; the assembly's box is all zeros (spec §9).
pub fn parts_mesh() -> Mesh {
    let mut mesh = lod_mesh();
    mesh.parts = vec![
        PartDef::new("assembly", None),
        PartDef::new("floor", Some(0)),
        PartDef::new("cube", Some(0)),
        PartDef::new("lid", Some(2)),
    ];
    let ids = (0..mesh.triangles.len())
        .map(|t| match t {
            t if t < FLOOR_TRIANGLES => 1,
            t if t < FLOOR_TRIANGLES + SIDE_TRIANGLES => 2,
            _ => 3,
        })
        .collect();
    mesh.part_ids = Some(ids);
    mesh
}

/// The `parts` vector: [`parts_mesh`] with both LOD kinds, pre-filtered, so each LOD entry is a
/// voxel, an R-LOD record and a part word; under LZ4.
pub fn write_parts(path: &Path) -> Result<(), VectorError> {
    let mesh = parts_mesh();
    let tree = lod_tree(&mesh)?;
    let mut opts = vector_options(Codec::Lz4)?;
    opts.write.lod = LodKinds::BOTH.filtered().with_parts(true);
    write_container(path, &mesh, &tree, &opts)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_part_but_the_assembly_has_triangles() {
        let m = parts_mesh();
        assert_eq!(m.validate(), Ok(()));
        assert_eq!(m.triangles.len(), 72);
        let ids = m.part_ids.clone().unwrap_or_default();
        let count = |p: u32| ids.iter().filter(|&&i| i == p).count();
        assert_eq!([count(0), count(1), count(2), count(3)], [0, 32, 32, 8]);
        // The lid is the top face: every corner at z = 1.
        for (t, &p) in ids.iter().enumerate() {
            let z = m.corners(t).map(|c| c.map(|v| v[2]));
            assert_eq!(p == 3, z == Some([1.0; 3]), "triangle {t}");
        }
    }
}
