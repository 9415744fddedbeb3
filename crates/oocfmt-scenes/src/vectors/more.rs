//! The vectors that cover what the first six do not: an R-LOD-only file, and a file with a
//! block size other than 4 KiB, several triangle blocks, triangle copies (primaries fewer than
//! records), list and triangle-section padding, no vertex attributes and a non-zero origin.

use std::path::Path;

use oocfmt::records::LodKinds;
use oocfmt::Codec;
use oocfmt_build::kdtree::{build, KdBuildOptions};
use oocfmt_build::layout::write_container;
use oocfmt_meshio::mesh::Mesh;

use super::{lod_mesh, lod_tree, vector_options, BoxBuilder, Face, VectorError, FLOOR_COLOUR};

/// The block size of the `grid-8k` vector.
pub const GRID_BLOCK_SIZE: u64 = 8192;
/// The `grid-8k` vector's scene origin: exact in f64, far enough from zero to matter.
pub const GRID_ORIGIN: [f64; 3] = [1024.0, -512.0, 64.5];
/// Quads per side of the `grid-8k` height field (2 × 31² = 1 922 triangles).
const GRID_SIDE: u32 = 31;

/// The `lod-filtered` vector's scene: the LOD vectors' scene with the floor's quadrant away
/// from the cube (x, y in 2..4) made a perforated plate: 8 × 8 squares of 1/4 with one
/// triangle of each, so the flat floor cells there are half covered from above and below and
/// get 1-sample voxels with a footprint (8 bytes), which a floor covering its cells never gives.
pub fn filtered_mesh() -> Mesh {
    let mut mesh = lod_mesh();
    // The floor is the first face: 4 × 4 unit squares, two triangles each, row by row.
    let keep: Vec<bool> = (0..mesh.triangles.len())
        .map(|t| {
            let square = t / 2;
            !(t < 32 && square % 4 >= 2 && square / 4 >= 2)
        })
        .collect();
    fn kept<T: Copy>(v: &[T], keep: &[bool]) -> Vec<T> {
        v.iter()
            .zip(keep)
            .filter(|(_, k)| **k)
            .map(|(x, _)| *x)
            .collect()
    }
    mesh.triangles = kept(&mesh.triangles, &keep);
    mesh.materials = mesh.materials.as_deref().map(|m| kept(m, &keep));
    let mut plate = BoxBuilder::default();
    plate.face(Face {
        corner: [2.0, 2.0, 0.0],
        du: [0.25, 0.0, 0.0],
        nu: 8,
        dv: [0.0, 0.25, 0.0],
        nv: 8,
        normal: [0.0, 0.0, 1.0],
        colour: FLOOR_COLOUR,
        material: 0,
    });
    let base = mesh.positions.len() as u32;
    mesh.positions.extend(&plate.positions);
    if let Some(n) = mesh.normals.as_mut() {
        n.extend(&plate.normals);
    }
    if let Some(c) = mesh.colours.as_mut() {
        c.extend(&plate.colours);
    }
    // The first triangle of each square: half of every square covered.
    for (t, (tri, m)) in plate.triangles.iter().zip(&plate.materials).enumerate() {
        if t % 2 == 0 {
            mesh.triangles.push(tri.map(|v| v + base));
            if let Some(ms) = mesh.materials.as_mut() {
                ms.push(*m);
            }
        }
    }
    mesh
}

/// The `lod-filtered` vector: [`filtered_mesh`] with both LOD kinds, pre-filtered (spec §5.1),
/// under LZ4.
pub fn write_filtered(path: &Path) -> Result<(), VectorError> {
    let mesh = filtered_mesh();
    let tree = lod_tree(&mesh)?;
    let mut opts = vector_options(Codec::Lz4)?;
    opts.write.lod = LodKinds::BOTH.filtered();
    write_container(path, &mesh, &tree, &opts)?;
    Ok(())
}

/// The LOD vectors' scene with R-LOD records and no voxels (spec §6.4).
pub fn write_rlod_only(path: &Path) -> Result<(), VectorError> {
    let mesh = lod_mesh();
    let tree = lod_tree(&mesh)?;
    let mut opts = vector_options(Codec::None)?;
    opts.write.lod = LodKinds::RLOD;
    write_container(path, &mesh, &tree, &opts)?;
    Ok(())
}

/// A height field on a 31 × 31 grid with steps of 1/8 and heights in eighths, so every
/// coordinate is exact. No normals, colours or materials; an odd triangle count per leaf
/// is common, so lists and triangle sections need their padding.
pub fn grid_mesh() -> Mesh {
    let n = GRID_SIDE + 1;
    let height = |i: u32, j: u32| ((i * 7 + j * 3) % 5) as f32 / 8.0;
    let positions = (0..n)
        .flat_map(|j| (0..n).map(move |i| (i, j)))
        .map(|(i, j)| [i as f32 / 8.0, j as f32 / 8.0, height(i, j)])
        .collect();
    let at = |i: u32, j: u32| j * n + i;
    let triangles = (0..GRID_SIDE)
        .flat_map(|j| (0..GRID_SIDE).map(move |i| (i, j)))
        .flat_map(|(i, j)| {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            [[a, b, c], [a, c, d]]
        })
        .collect();
    Mesh::new(positions, triangles)
}

/// The `grid-8k` vector: [`grid_mesh`] in 8 KiB LZ4 blocks, leaves of at most 3 triangles,
/// stored relative to [`GRID_ORIGIN`].
pub fn write_grid(path: &Path) -> Result<(), VectorError> {
    let mesh = grid_mesh();
    let tree = build(
        &mesh,
        &KdBuildOptions {
            max_leaf_triangles: 3,
            ..KdBuildOptions::default()
        },
    )?;
    let mut opts = vector_options(Codec::Lz4)?;
    opts.write = opts.write.with_block_size(GRID_BLOCK_SIZE)?;
    opts.origin = GRID_ORIGIN;
    write_container(path, &mesh, &tree, &opts)?;
    Ok(())
}
