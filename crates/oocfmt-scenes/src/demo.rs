//! The demo scene: a bumpy, colour-banded sphere with per-vertex normals and colours and two
//! materials, sized by triangle count. Its low-frequency colours and bumps make small patches
//! nearly flat (one-sample voxels) and large cells varied (six-sample voxels).
//!
//! The sphere is a subdivided cube pushed out to the sphere, not a latitude-longitude grid:
//! every vertex has at most six neighbours, whereas a pole fan of hundreds of triangles all
//! overlapping one point would defeat the kd-tree's bounding-box splits.

use std::collections::HashMap;

use oocfmt::metadata::Material;

use oocfmt_meshio::mesh::Mesh;

/// A displaced cube-sphere of about `target_triangles` triangles (at least 12), radius about 1
/// around the origin. Triangles are wound so their geometric normals point outwards.
pub fn demo_scene(target_triangles: usize) -> Mesh {
    // 6 faces × n² squares × 2 triangles ≈ target.
    let n = ((target_triangles as f64 / 12.0).sqrt().round() as u32).max(1);
    let mut lattice: HashMap<[u32; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut colours = Vec::new();
    let mut vertex = |l: [u32; 3]| -> u32 {
        *lattice.entry(l).or_insert_with(|| {
            let dir = normalise(l.map(|c| 2.0 * c as f32 / n as f32 - 1.0));
            let theta = dir[2].clamp(-1.0, 1.0).acos();
            let phi = dir[1].atan2(dir[0]);
            positions.push(surface(dir, theta, phi));
            colours.push(colour(theta, phi));
            (positions.len() - 1) as u32
        })
    };
    let mut triangles = Vec::with_capacity(12 * (n as usize).pow(2));
    for axis in 0..3 {
        for high in [false, true] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let at = |i: u32, j: u32| {
                let mut l = [0u32; 3];
                l[axis] = if high { n } else { 0 };
                l[u] = i;
                l[v] = j;
                l
            };
            for j in 0..n {
                for i in 0..n {
                    let (a, b, c, d) = (
                        vertex(at(i, j)),
                        vertex(at(i + 1, j)),
                        vertex(at(i + 1, j + 1)),
                        vertex(at(i, j + 1)),
                    );
                    // (u, v, axis) is right-handed, so this winding faces +axis; flip on the low face.
                    for t in [[a, b, c], [a, c, d]] {
                        triangles.push(if high { t } else { [t[0], t[2], t[1]] });
                    }
                }
            }
        }
    }
    let materials = triangles
        .iter()
        .map(|t| {
            let z = t
                .iter()
                .filter_map(|&v| positions.get(v as usize))
                .map(|p| p[2])
                .sum::<f32>()
                / 3.0;
            u16::from(z > 0.7)
        })
        .collect();
    let normals = vertex_normals(&positions, &triangles);
    Mesh {
        positions,
        triangles,
        normals: Some(normals),
        colours: Some(colours),
        materials: Some(materials),
        material_table: vec![
            Material {
                name: "body".into(),
                diffuse: [0.8, 0.8, 0.8],
            },
            Material {
                name: "cap".into(),
                diffuse: [0.9, 0.85, 0.3],
            },
        ],
        ..Mesh::default()
    }
}

fn normalise(v: [f32; 3]) -> [f32; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / len)
}

/// The unit direction pushed out by smooth bumps (integer frequencies in `phi` keep the seam
/// at `phi = ±π` continuous).
fn surface(dir: [f32; 3], theta: f32, phi: f32) -> [f32; 3] {
    let bump =
        0.06 * (6.0 * theta).sin() * (5.0 * phi).cos() + 0.025 * (3.0 * theta + 7.0 * phi).sin();
    let r = 1.0 + bump * theta.sin();
    dir.map(|c| r * c)
}

fn colour(theta: f32, phi: f32) -> [u8; 4] {
    let channel = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    [
        channel(0.55 + 0.4 * (2.0 * theta).cos()),
        channel(0.5 + 0.35 * phi.sin() * theta.sin()),
        channel(0.45 + 0.4 * (theta + phi).cos()),
        255,
    ]
}

/// Area-weighted averages of the adjacent faces' normals.
fn vertex_normals(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> Vec<[f32; 3]> {
    let mut sums = vec![[0.0f32; 3]; positions.len()];
    for t in triangles {
        let p = t.map(|v| positions.get(v as usize).copied().unwrap_or_default());
        let e1 = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
        let e2 = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
        let n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        for &v in t {
            if let Some(s) = sums.get_mut(v as usize) {
                for a in 0..3 {
                    s[a] += n[a];
                }
            }
        }
    }
    sums.into_iter()
        .map(|s| {
            let len = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
            if len > 0.0 {
                s.map(|c| c / len)
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn size_follows_the_target_and_the_mesh_is_valid() {
        for target in [0, 12, 1000, 20_000] {
            let m = demo_scene(target);
            assert_eq!(m.validate(), Ok(()));
            let n = m.triangles.len();
            assert!(n >= 12);
            if target >= 1000 {
                assert!(
                    n.abs_diff(target) * 10 < target,
                    "{n} triangles for {target}"
                );
            }
        }
        assert_eq!(demo_scene(5000), demo_scene(5000));
    }

    #[test]
    fn the_surface_is_closed() {
        let m = demo_scene(3000);
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &m.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                // A directed edge and its reverse cancel in a closed, consistently wound mesh.
                *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
        }
        assert!(edges.values().all(|&c| c == 0));
    }

    #[test]
    fn triangles_face_outwards() {
        let m = demo_scene(2000);
        for t in 0..m.triangles.len() {
            let Some(p) = m.corners(t) else { continue };
            let c: Vec<f32> = (0..3)
                .map(|a| (p[0][a] + p[1][a] + p[2][a]) / 3.0)
                .collect();
            let e1: Vec<f32> = (0..3).map(|a| p[1][a] - p[0][a]).collect();
            let e2: Vec<f32> = (0..3).map(|a| p[2][a] - p[0][a]).collect();
            let n = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            assert!(
                n[0] * c[0] + n[1] * c[1] + n[2] * c[2] > 0.0,
                "triangle {t}"
            );
        }
    }
}
