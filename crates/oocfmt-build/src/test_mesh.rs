//! Meshes the builder's unit tests share.

use oocfmt_meshio::mesh::Mesh;

/// Appends the closed box [lo, hi] to `mesh`: 8 corners and 12 triangles wound
/// counter-clockwise seen from outside, each corner in `colour` where the mesh has colours.
pub(crate) fn closed_box(mesh: &mut Mesh, lo: [f32; 3], hi: [f32; 3], colour: [u8; 4]) {
    let base = mesh.positions.len() as u32;
    // Corner k takes x from bit 0, y from bit 1, z from bit 2.
    let corner = |k: u32| -> [f32; 3] {
        std::array::from_fn(|a| if k >> a & 1 == 1 { hi[a] } else { lo[a] })
    };
    mesh.positions.extend((0..8).map(corner));
    if let Some(c) = mesh.colours.as_mut() {
        c.extend([colour; 8]);
    }
    for q in [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ] {
        let v = q.map(|k| base + k);
        mesh.triangles.push([v[0], v[1], v[2]]);
        mesh.triangles.push([v[0], v[2], v[3]]);
    }
}
