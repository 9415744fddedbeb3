//! Known answers for pre-filtered voxels (spec §5.1): a voxel over a rough surface keeps the
//! surface's mean shade, and one over a surface covering part of its cell says how much.

use oocfmt::records::Voxel;

use super::*;
use crate::kdtree::{build, KdBuildOptions};
use crate::test_mesh::closed_box;

const TAU: f64 = std::f64::consts::TAU;

/// The height field z = a sin(2πkx) sin(2πky) over the unit square, `n` × `n` quads.
fn height_field(a: f64, k: f64, n: u32) -> Mesh {
    let h = |x: f64, y: f64| a * (TAU * k * x).sin() * (TAU * k * y).sin();
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (f64::from(i) / f64::from(n), f64::from(j) / f64::from(n));
            positions.push([x as f32, y as f32, h(x, y) as f32]);
        }
    }
    let at = |i: u32, j: u32| j * (n + 1) + i;
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            triangles.extend([[a, b, c], [a, c, d]]);
        }
    }
    Mesh::new(positions, triangles)
}

/// The mean over the unit square of the z component of the field's unit normal: the mean
/// Lambert term of a light straight above, by the midpoint rule on a fine grid (f64).
fn mean_cosine(a: f64, k: f64) -> f64 {
    let n = 2000;
    let mut sum = 0.0;
    for j in 0..n {
        for i in 0..n {
            let (x, y) = ((f64::from(i) + 0.5) / 2000.0, (f64::from(j) + 0.5) / 2000.0);
            let w = TAU * k;
            let gx = a * w * (w * x).cos() * (w * y).sin();
            let gy = a * w * (w * x).sin() * (w * y).cos();
            sum += 1.0 / (1.0 + gx * gx + gy * gy).sqrt();
        }
    }
    sum / f64::from(n * n)
}

fn root_lod(mesh: &Mesh) -> LodData {
    let tree = build(
        mesh,
        &KdBuildOptions {
            max_leaf_triangles: 8,
            ..KdBuildOptions::default()
        },
    );
    let Ok(tree) = tree else { panic!("{tree:?}") };
    let root = tree.root().unwrap_or(NodeId(0));
    let out = compute(mesh, &tree, &[root], DEFAULT_VOXEL_THRESHOLD);
    assert_eq!(out.len(), 1);
    out[0]
}

/// The shade the +z face shows a ray straight down: σ times the cosine of its normal.
fn shade_from_above(v: &Voxel) -> f64 {
    let (s, f) = v.face(5);
    f64::from(f.shade_f32()) * f64::from(s.normal()[2]).abs()
}

#[test]
fn a_rough_surface_keeps_its_mean_shade() {
    let (a, k) = (0.05, 2.0);
    let want = mean_cosine(a, k);
    // A surface rough enough that the mean normal alone would be far too bright.
    assert!(want < 0.93, "{want}");
    let lod = root_lod(&height_field(a, k, 96));
    let got = shade_from_above(&lod.sampled_voxel());
    // σ is quantised to 1/255; the rest is the rays' sampling of the field.
    assert!((got - want).abs() < 0.01, "shade {got}, mean cosine {want}");
    let (_, f) = lod.sampled_voxel().face(5);
    assert_eq!(f.coverage, 255, "the field covers the whole square");
}

#[test]
fn a_flat_surface_has_no_footprint_to_store() {
    let lod = root_lod(&height_field(0.0, 1.0, 8));
    let Voxel::Single(_, f) = lod.sampled_voxel() else {
        panic!("{:?}", lod.voxel)
    };
    assert_eq!(f.shade, 255);
    assert!(!lod.sampled_voxel().has_footprints() || f.coverage < 255);
}

/// `strips` strips along y of width 1 / (2 strips), one every 1 / strips along x, each `rows`
/// quads long, in the plane z = 0: half of the unit square covered.
pub(crate) fn comb(strips: u32, rows: u32) -> Mesh {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let w = 1.0 / f64::from(strips);
    for s in 0..strips {
        let x0 = f64::from(s) * w;
        for r in 0..rows {
            let (y0, y1) = (
                f64::from(r) / f64::from(rows),
                f64::from(r + 1) / f64::from(rows),
            );
            let b = positions.len() as u32;
            positions.extend(
                [[x0, y0], [x0 + w / 2.0, y0], [x0 + w / 2.0, y1], [x0, y1]]
                    .map(|[x, y]| [x as f32, y as f32, 0.0]),
            );
            triangles.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
        }
    }
    // The last strip ends at x = 1 − w/2: a speck at (1, 1) makes the square the cell.
    let b = positions.len() as u32;
    positions.extend([[1.0, 1.0, 0.0], [0.9999, 1.0, 0.0], [1.0, 0.9999, 0.0]]);
    triangles.push([b, b + 1, b + 2]);
    Mesh::new(positions, triangles)
}

#[test]
fn a_comb_covering_half_its_cell_gets_coverage_one_half() {
    let lod = root_lod(&comb(16, 4));
    for face in [4, 5] {
        let (_, f) = lod.sampled_voxel().face(face);
        let c = f.coverage_f32();
        assert!((c - 0.5).abs() < 0.07, "face {face}: coverage {c}");
    }
}

fn unit_cell() -> Bounds {
    Bounds {
        min: [0.0, 0.0, -0.5],
        max: [1.0, 1.0, 0.5],
    }
}

fn all_triangles(mesh: &Mesh) -> Vec<u32> {
    (0..mesh.triangles.len() as u32).collect()
}

#[test]
fn an_r_lod_over_a_comb_covers_half_its_plane() {
    let mesh = comb(16, 4);
    let fit = rlod::fit(&mesh, &all_triangles(&mesh), unit_cell());
    // The plane z = 0 meets the cell in the unit square; the strips cover half of it (the
    // speck at the corner adds 5e-9).
    assert!((fit.section - 1.0).abs() < 1e-9, "{}", fit.section);
    assert!((fit.coverage() - 0.5).abs() < 1e-6, "{}", fit.coverage());
    assert!((fit.shade() - 1.0).abs() < 1e-9, "{}", fit.shade());
    let r = fit.record(1.0);
    assert_eq!((r.coverage, r.shade), (128, 255));
}

/// Closed plates, `strips` of them across the unit square and 2·`half` thick: the comb's
/// strips as boxes.
fn closed_comb(strips: u32, half: f32) -> Mesh {
    let mut mesh = Mesh::default();
    let w = 1.0 / strips as f32;
    for s in 0..strips {
        let x0 = s as f32 * w;
        closed_box(
            &mut mesh,
            [x0, 0.0, -half],
            [x0 + w / 2.0, 1.0, half],
            [0; 4],
        );
    }
    mesh
}

#[test]
fn an_r_lod_over_closed_plates_counts_their_shadow_once() {
    // Both faces of a plate project onto the plane through it; the plates cover half of it.
    let mesh = closed_comb(16, 1e-3);
    let fit = rlod::fit(&mesh, &all_triangles(&mesh), unit_cell());
    assert!((fit.section - 1.0).abs() < 1e-6, "{}", fit.section);
    assert!((fit.coverage() - 0.5).abs() < 1e-3, "{}", fit.coverage());
    assert!((fit.shade() - 1.0).abs() < 1e-3, "{}", fit.shade());
}

#[test]
fn an_r_lod_over_a_rough_surface_keeps_its_mean_shade() {
    let (a, k) = (0.05, 2.0);
    let mesh = height_field(a, k, 96);
    let fit = rlod::fit(&mesh, &all_triangles(&mesh), unit_cell());
    let want = mean_cosine(a, k);
    assert!(
        (fit.shade() - want).abs() < 2e-3,
        "{} against {want}",
        fit.shade()
    );
    assert!((fit.coverage() - 1.0).abs() < 1e-6, "{}", fit.coverage());
}
