//! The piecewise sampling of the LOD nodes above the chunks gives what sampling the whole
//! subtree at once gives.

use oocfmt::records::Voxel;

use super::chunk::{answer_rays, take_nearer};
use super::top::{finish_top_lod, record_rays, TopLod};
use crate::kdtree::{build_cell, KdBuildOptions, KdTree, NodeId};
use crate::layout::parts::part_of;
use crate::lod::{sample_cell, shade, DEFAULT_VOXEL_THRESHOLD, DIAGONAL_RAYS_MAX, FACE_RAYS_MAX};
use crate::raycast::intersect_triangle;
use crate::test_mesh::closed_box;
use oocfmt_meshio::mesh::{Bounds, Mesh};

/// A green hull (part 1) with yellow cargo (part 0) inside.
fn hull_with_cargo() -> Mesh {
    let mut mesh = Mesh {
        colours: Some(Vec::new()),
        ..Mesh::default()
    };
    closed_box(&mut mesh, [0.0; 3], [4.0; 3], [0, 255, 0, 255]);
    closed_box(
        &mut mesh,
        [1.0, 1.5, 1.2],
        [2.5, 3.0, 2.7],
        [255, 255, 0, 255],
    );
    mesh.part_ids = Some([[1; 12], [0; 12]].concat());
    mesh.parts = vec![
        oocfmt_meshio::mesh::PartDef::new("cargo", None),
        oocfmt_meshio::mesh::PartDef::new("hull", None),
    ];
    mesh
}

/// The part of `mesh` whose triangles reach `cell`, with its own kd-tree.
fn chunk_of(mesh: &Mesh, cell: Bounds) -> (Mesh, KdTree) {
    let mut part = Mesh {
        positions: mesh.positions.clone(),
        colours: mesh.colours.clone(),
        part_ids: mesh.part_ids.as_ref().map(|_| Vec::new()),
        parts: mesh.parts.clone(),
        ..Mesh::default()
    };
    for t in 0..mesh.triangles.len() {
        let b = mesh.triangle_bounds(t);
        if (0..3).all(|a| b.min[a] <= cell.max[a] && b.max[a] >= cell.min[a]) {
            part.triangles.push(mesh.triangles[t]);
            if let (Some(ids), Some(all)) = (part.part_ids.as_mut(), mesh.part_ids.as_ref()) {
                ids.push(all[t]);
            }
        }
    }
    let all: Vec<u32> = (0..part.triangles.len() as u32).collect();
    let opts = KdBuildOptions {
        max_leaf_triangles: 2,
        ..KdBuildOptions::default()
    };
    let nodes = build_cell(&part, all, cell, 2, &opts).unwrap_or_default();
    let tree = KdTree::from_parts(&part, nodes, Some(NodeId(0)), cell, Vec::new());
    let Ok(tree) = tree else { panic!("{tree:?}") };
    (part, tree)
}

#[test]
fn sampling_in_pieces_matches_sampling_the_whole() {
    let mesh = hull_with_cargo();
    let cell = mesh.bounds();
    let mut rays = record_rays(cell, DEFAULT_VOXEL_THRESHOLD);
    assert_eq!(rays.len(), 6 * FACE_RAYS_MAX + 12 * DIAGONAL_RAYS_MAX);
    // The reference: every triangle tested against every ray.
    let mut reference = rays.iter();
    let whole = sample_cell(
        cell,
        DEFAULT_VOXEL_THRESHOLD,
        1.0,
        0,
        &mut |ray, t1, eps| {
            let r = reference.next()?;
            assert_eq!((r.ray, r.t1), (*ray, t1));
            let mut best: Option<crate::raycast::Hit> = None;
            for t in 0..mesh.triangles.len() {
                let c = mesh.corners(t)?.map(|p| p.map(f64::from));
                if let Some((th, u, v)) = intersect_triangle(ray, c) {
                    if th >= -eps && th <= t1 + eps && best.is_none_or(|b| th < b.t) {
                        best = Some(crate::raycast::Hit {
                            t: th,
                            triangle: t as u32,
                            u,
                            v,
                        });
                    }
                }
            }
            let best = best?;
            Some((
                shade(&mesh, &best, ray.dir)?,
                part_of(&mesh, best.triangle as usize),
            ))
        },
    );
    // In pieces: the two halves of the cell, each with the triangles reaching it.
    let (left, right) = cell.split(0, 2.0);
    for half in [left, right] {
        let (part, tree) = chunk_of(&mesh, half);
        let hits = answer_rays(&part, &tree, &half, &[rays.as_slice()]);
        take_nearer(&mut rays, hits.first().map_or(&[][..], Vec::as_slice));
    }
    let lod = TopLod {
        node: 0,
        cell,
        rays,
    };
    let pieces = finish_top_lod(&lod, DEFAULT_VOXEL_THRESHOLD, 1.0, 0);
    assert_eq!(pieces, whole);
    // And it is the hull's green, not the cargo's yellow, from every side; the hull's part.
    assert_eq!(pieces.part, 1);
    let Voxel::Six(faces, _) = pieces.sampled_voxel() else {
        panic!("{:?}", pieces.voxel)
    };
    for f in faces {
        assert_eq!(f.colour(), [0.0, 1.0, 0.0]);
    }
    for p in pieces.proxy_samples {
        assert_eq!(p.colour(), [0.0, 1.0, 0.0]);
    }
}

/// The R-LOD of a LOD node above the chunks: moments streamed over the node's triangles in the
/// split pass, deviation measured chunk by chunk and widened, gives the in-core fit's record.
#[test]
fn rlod_fit_in_pieces_matches_the_fit_of_the_whole() {
    use crate::lod::rlod::{fit, Deviation, PlaneMoments};

    let mut mesh = hull_with_cargo();
    // A slanted sheet through the hull, so the plane is not axis-aligned and the deviation is
    // not a face's.
    let base = mesh.positions.len() as u32;
    mesh.positions.extend([
        [0.2, 0.1, 0.3],
        [3.9, 0.4, 2.9],
        [3.7, 3.8, 3.6],
        [0.1, 3.5, 1.1],
    ]);
    if let Some(c) = mesh.colours.as_mut() {
        c.extend([[200, 40, 10, 255]; 4]);
    }
    mesh.triangles
        .extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
    if let Some(ids) = mesh.part_ids.as_mut() {
        ids.extend([2, 2]);
    }
    mesh.parts
        .push(oocfmt_meshio::mesh::PartDef::new("sheet", None));
    let all: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
    let cell = mesh.bounds();
    let whole = fit(&mesh, &all, cell);

    let colour = |t: u32| -> [f64; 3] {
        let idx = mesh.triangles[t as usize];
        let cs = mesh.colours.as_ref().unwrap_or_else(|| panic!("colours"));
        let mut sum = [0.0; 3];
        for v in idx {
            for (s, c) in sum.iter_mut().zip(cs[v as usize]) {
                *s += f64::from(c) / 255.0 / 3.0;
            }
        }
        sum
    };
    // Streamed in another order than the in-core fit's, as a spill file would be.
    let mut moments = PlaneMoments::new(cell);
    for &t in all.iter().rev() {
        let Some(c) = mesh.corners(t as usize) else {
            continue;
        };
        moments.add(c, Some(part_of(&mesh, t as usize)), || colour(t));
    }
    let mut pieces = moments.plane();
    assert_eq!(pieces.deviation, 0.0);
    // Three chunks along x, each with the triangles reaching it (straddlers in several).
    let (a, rest) = cell.split(0, 1.3);
    let (b, c) = rest.split(0, 2.9);
    for chunk in [a, b, c] {
        let (part, _) = chunk_of(&mesh, chunk);
        let mut d = Deviation::new(&pieces, chunk);
        for t in 0..part.triangles.len() {
            if let Some(corners) = part.corners(t) {
                d.add(corners);
            }
        }
        let piece = d.finish();
        pieces.widen(&piece);
    }
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * (1.0 + x.abs());
    for k in 0..3 {
        assert!(
            close(pieces.normal[k], whole.normal[k]),
            "{pieces:?} {whole:?}"
        );
        assert!(
            close(pieces.point[k], whole.point[k]),
            "{pieces:?} {whole:?}"
        );
        assert!(
            close(pieces.colour[k], whole.colour[k]),
            "{pieces:?} {whole:?}"
        );
    }
    assert!(close(pieces.area, whole.area), "{pieces:?} {whole:?}");
    // The hull's six faces are the largest area in the cell (the part word of an
    // R-LOD-only entry).
    assert_eq!((pieces.part, whole.part), (1, 1));
    assert!(whole.deviation > 0.5, "{whole:?}");
    assert!(
        close(pieces.deviation, whole.deviation),
        "{pieces:?} {whole:?}"
    );
    assert!(
        close(pieces.stored_deviation, whole.stored_deviation),
        "{pieces:?} {whole:?}"
    );
    assert!(close(pieces.shade(), whole.shade()), "{pieces:?} {whole:?}");
    assert!(
        close(pieces.coverage(), whole.coverage()),
        "{pieces:?} {whole:?}"
    );
    // The shade and coverage codes round values equal to 1e-9, which may sit on a half step.
    let radius = cell.half_diagonal_up().unwrap_or(f32::MAX);
    let (p, w) = (pieces.record(radius), whole.record(radius));
    assert!(p.shade.abs_diff(w.shade) <= 1 && p.coverage.abs_diff(w.coverage) <= 1);
    let codes = |r: oocfmt::records::Rlod| oocfmt::records::Rlod {
        shade: 0,
        coverage: 0,
        ..r
    };
    assert_eq!(codes(p), codes(w));
}
