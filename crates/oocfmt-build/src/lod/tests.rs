//! LOD sampling on small scenes: one sample or six as the faces differ, hidden geometry does not
//! tint what is seen from outside, shared triangles count once, the recorded sampling matches
//! the ray counts, and the data does not depend on the thread count.

use oocfmt::records::{Sample, Voxel};

use super::*;
use crate::kdtree::{build, KdBuildOptions};

fn tree_of(mesh: &Mesh, max_leaf: u32) -> KdTree {
    let tree = build(
        mesh,
        &KdBuildOptions {
            max_leaf_triangles: max_leaf,
            ..KdBuildOptions::default()
        },
    );
    match tree {
        Ok(t) => t,
        Err(e) => panic!("{e}"),
    }
}

fn lod_of_root(mesh: &Mesh, threshold: f32) -> LodData {
    let tree = tree_of(mesh, 1);
    let root = tree.root().unwrap_or(NodeId(0));
    let out = compute(mesh, &tree, &[root], threshold);
    assert_eq!(out.len(), 1);
    out[0]
}

/// Quads given by a corner and two edges, each with one vertex colour, wound so that their
/// geometric normal is `du × dv`.
#[derive(Default)]
struct Quads {
    mesh: Mesh,
}

impl Quads {
    fn add(&mut self, corner: [f32; 3], du: [f32; 3], dv: [f32; 3], colour: [u8; 4]) {
        let m = &mut self.mesh;
        let b = m.positions.len() as u32;
        let at = |s: f32, t: f32| [0, 1, 2].map(|a| corner[a] + s * du[a] + t * dv[a]);
        m.positions
            .extend([at(0.0, 0.0), at(1.0, 0.0), at(1.0, 1.0), at(0.0, 1.0)]);
        m.triangles.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
        m.colours.get_or_insert_with(Vec::new).extend([colour; 4]);
    }

    /// The six faces of the box `lo + [0, size]`, facing outwards.
    fn closed_box(&mut self, lo: [f32; 3], size: f32, colour: [u8; 4]) {
        let hi = lo.map(|c| c + size);
        let (x, y, z) = ([size, 0.0, 0.0], [0.0, size, 0.0], [0.0, 0.0, size]);
        self.add(lo, z, y, colour); // −x
        self.add([hi[0], lo[1], lo[2]], y, z, colour); // +x
        self.add(lo, x, z, colour); // −y
        self.add([lo[0], hi[1], lo[2]], z, x, colour); // +y
        self.add(lo, y, x, colour); // −z
        self.add([lo[0], lo[1], hi[2]], x, y, colour); // +z
    }
}

/// Two unit squares: one facing +z (red), one facing +x (blue), apart from each other.
fn two_walls() -> Mesh {
    let mut q = Quads::default();
    q.add([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [255, 0, 0, 255]);
    q.add(
        [3.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0, 0, 255, 255],
    );
    q.mesh
}

const GREEN: [f32; 3] = [0.0, 1.0, 0.0];

#[test]
fn a_flat_patch_gets_one_sample_and_is_seen_from_both_sides() {
    let mut mesh = two_walls();
    mesh.triangles.truncate(2);
    let lod = lod_of_root(&mesh, DEFAULT_VOXEL_THRESHOLD);
    let Voxel::Single(s, _) = lod.sampled_voxel() else {
        panic!("{:?}", lod.voxel)
    };
    // Oriented as the mesh orients it, though half the rays see its back.
    assert_eq!(s.normal(), [0.0, 0.0, 1.0]);
    assert_eq!(s.colour(), [1.0, 0.0, 0.0]);
    assert_eq!(lod.area, 1.0);
    // Direction 5 is −z: a ray going down sees the front; direction 4 (+z) its back, with the
    // normal turned towards the ray. Edge-on (the cell is flat in z) nothing is seen.
    assert_eq!(lod.proxy_samples[5], s.with_single(false));
    assert_eq!(lod.proxy_samples[4].normal(), [0.0, 0.0, -1.0]);
    assert_eq!(lod.proxy_samples[4].colour(), [1.0, 0.0, 0.0]);
    assert_eq!(lod.proxy_samples[0], Sample::EMPTY);
    assert_eq!(lod.proxy_samples[2], Sample::EMPTY);
    assert!(lod.proxy_samples[10..18].iter().all(|p| !p.is_empty()));
}

#[test]
fn differently_facing_walls_get_six_samples() {
    let lod = lod_of_root(&two_walls(), DEFAULT_VOXEL_THRESHOLD);
    let Voxel::Six(s, _) = lod.sampled_voxel() else {
        panic!("{:?}", lod.voxel)
    };
    // Through +x the blue wall's front, through −x its back; through ±z the red floor.
    assert_eq!(s[1].normal(), [1.0, 0.0, 0.0]);
    assert_eq!(s[1].colour(), [0.0, 0.0, 1.0]);
    assert_eq!(s[0].normal(), [-1.0, 0.0, 0.0]);
    assert_eq!(s[0].colour(), [0.0, 0.0, 1.0]);
    assert_eq!(s[5].normal(), [0.0, 0.0, 1.0]);
    assert_eq!(s[5].colour(), [1.0, 0.0, 0.0]);
    assert_eq!(s[4].colour(), [1.0, 0.0, 0.0]);
    // Rays along y run parallel to both walls: those faces show the mean.
    assert_eq!(s[2], s[3]);
    assert_eq!(lod.area, 2.0);
    // With a threshold above every difference the same node is one sample.
    assert!(matches!(
        lod_of_root(&two_walls(), 3.0).sampled_voxel(),
        Voxel::Single(_, _)
    ));
}

#[test]
fn materials_colour_when_vertices_do_not() {
    let mut mesh = two_walls();
    mesh.colours = None;
    mesh.materials = Some(vec![0, 0, 1, 1]);
    mesh.material_table = vec![
        oocfmt::metadata::Material {
            name: "green".into(),
            diffuse: GREEN,
        },
        oocfmt::metadata::Material {
            name: "grey".into(),
            diffuse: [0.5; 3],
        },
    ];
    let lod = lod_of_root(&mesh, DEFAULT_VOXEL_THRESHOLD);
    assert_eq!(lod.proxy_samples[5].colour(), GREEN);
    assert_eq!(
        lod.proxy_samples[1].colour(),
        Sample::pack([1.0, 0.0, 0.0], [0.5; 3]).colour()
    );
}

#[test]
fn shared_triangles_count_once() {
    let mesh = Mesh::new(
        vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]],
        vec![[0, 1, 2]],
    );
    let nodes = vec![
        KdNode::Inner {
            axis: 0,
            split: 1.0,
            children: [Some(NodeId(1)), Some(NodeId(2))],
        },
        KdNode::Leaf { triangles: vec![0] },
        KdNode::Leaf { triangles: vec![0] },
    ];
    let tree = KdTree::from_parts(&mesh, nodes, Some(NodeId(0)), mesh.bounds(), Vec::new());
    let Ok(tree) = tree else { panic!("{tree:?}") };
    assert_eq!(subtree_triangles(&tree, NodeId(0)), vec![0]);
    assert_eq!(compute(&mesh, &tree, &[NodeId(0)], 0.1)[0].area, 2.0);
}

/// A green closed box with a yellow box inside it, and optionally a small red box far away.
fn hull_with_cargo(far: bool) -> Mesh {
    let mut q = Quads::default();
    q.closed_box([0.0; 3], 4.0, [0, 255, 0, 255]);
    q.closed_box([1.0, 1.5, 1.2], 1.5, [255, 255, 0, 255]);
    if far {
        q.closed_box([30.0, 0.0, 0.0], 0.5, [255, 0, 0, 255]);
    }
    q.mesh
}

fn assert_green(lod: &LodData, what: &str) {
    match lod.sampled_voxel() {
        Voxel::Single(s, _) => assert_eq!(s.colour(), GREEN, "{what}"),
        Voxel::Six(s, _) => assert!(s.iter().all(|f| f.colour() == GREEN), "{what}: {s:?}"),
    }
    for (k, p) in lod.proxy_samples.iter().enumerate() {
        assert!(!p.is_empty(), "{what}: proxy direction {k} sees nothing");
        assert_eq!(p.colour(), GREEN, "{what}: proxy direction {k}");
    }
}

#[test]
fn hidden_cargo_does_not_tint_its_hull() {
    let mesh = hull_with_cargo(false);
    let tree = tree_of(&mesh, 2);
    let root = tree.root().unwrap_or(NodeId(0));
    let lod = compute(&mesh, &tree, &[root], DEFAULT_VOXEL_THRESHOLD);
    assert_green(&lod[0], "root");
    // Every face sees the hull's outside: the normals point out of the box.
    let Voxel::Six(faces, _) = lod[0].sampled_voxel() else {
        panic!("a box looks different from each side: {:?}", lod[0].voxel)
    };
    let outward = [
        [-1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, -1.0],
        [0.0, 0.0, 1.0],
    ];
    for (f, n) in faces.iter().zip(outward) {
        assert_eq!(f.normal(), n);
    }
}

#[test]
fn every_lod_cell_around_the_whole_hull_is_green() {
    // With a far object the tree cuts the gap away, so inner nodes below the root enclose the
    // hull exactly, as the layout's LOD nodes would.
    let mesh = hull_with_cargo(true);
    let tree = tree_of(&mesh, 2);
    let all: Vec<NodeId> = (0..tree.nodes().len() as u32).map(NodeId).collect();
    let cells: Vec<Bounds> = cells_of(&tree, &all).into_iter().map(|(_, c)| c).collect();
    assert_eq!(cells.len(), tree.nodes().len());
    let hull = Bounds {
        min: [0.0; 3],
        max: [4.0; 3],
    };
    let enclosing: Vec<NodeId> = (0..tree.nodes().len() as u32)
        .map(NodeId)
        .filter(|&id| {
            let c = cells[id.index()];
            let inner = matches!(tree.node(id), Some(KdNode::Inner { .. }));
            let inside_far = c.max[0] <= 5.0;
            inner && inside_far && (0..3).all(|a| c.min[a] <= 0.0 && c.max[a] >= 4.0)
        })
        .collect();
    assert!(!enclosing.is_empty(), "no node holds just the hull");
    for (id, lod) in
        enclosing
            .iter()
            .zip(compute(&mesh, &tree, &enclosing, DEFAULT_VOXEL_THRESHOLD))
    {
        assert_green(&lod, &format!("node {id:?} cell {:?}", cells[id.index()]));
    }
    assert!(enclosing.iter().any(|id| cells[id.index()] == hull));
}

#[test]
fn a_sliver_the_rays_miss_still_gets_a_voxel() {
    let mut mesh = Mesh::new(
        vec![[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 1.001, 0.0]],
        vec![[0, 1, 2]],
    );
    mesh.colours = Some(vec![[0, 0, 255, 255]; 3]);
    let nodes = vec![
        KdNode::Inner {
            axis: 0,
            split: 0.5,
            children: [Some(NodeId(1)), Some(NodeId(2))],
        },
        KdNode::Leaf { triangles: vec![0] },
        KdNode::Leaf { triangles: vec![0] },
    ];
    let tree = KdTree::from_parts(&mesh, nodes, Some(NodeId(0)), mesh.bounds(), Vec::new());
    let Ok(tree) = tree else { panic!("{tree:?}") };
    let lod = compute(&mesh, &tree, &[NodeId(0)], DEFAULT_VOXEL_THRESHOLD);
    let Voxel::Single(s, _) = lod[0].sampled_voxel() else {
        panic!("{:?}", lod[0].voxel)
    };
    assert_eq!(s.colour(), [0.0, 0.0, 1.0]);
    assert_eq!(s.normal(), [0.0, 0.0, 1.0]);
    assert!(lod[0].proxy_samples.iter().all(|p| p.is_empty()));
}

#[test]
fn lod_data_is_the_same_whatever_the_thread_count() {
    let mesh = oocfmt_scenes::demo_scene(30_000);
    let tree = tree_of(&mesh, 8);
    let inner: Vec<NodeId> = (0..tree.nodes().len() as u32)
        .map(NodeId)
        .filter(|&id| matches!(tree.node(id), Some(KdNode::Inner { .. })))
        .step_by(3)
        .collect();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
        let Ok(pool) = pool else {
            panic!("no thread pool")
        };
        pool.install(|| compute(&mesh, &tree, &inner, DEFAULT_VOXEL_THRESHOLD))
    };
    let one = run(1);
    assert!(one == run(2), "one and two threads differ");
    let six = one
        .iter()
        .filter(|l| matches!(l.sampled_voxel(), Voxel::Six(_, _)))
        .count();
    assert!(six > 0 && six < one.len(), "{six} of {}", one.len());
}

#[test]
fn the_recorded_sampling_matches_the_ray_counts() {
    let described = format!(
        "first-hit rays, Owen-scrambled Sobol: 1 per {TRIANGLES_PER_FACE_RAY} triangles per face \
         ({FACE_RAYS_MIN}..{FACE_RAYS_BASE}, x4 while uncertain up to {FACE_RAYS_MAX}), \
         1 per {TRIANGLES_PER_DIAGONAL_RAY} per diagonal ({DIAGONAL_RAYS_MIN}..{DIAGONAL_RAYS_MAX}, \
         else blended faces); shade and coverage per face"
    );
    assert_eq!(LOD_SAMPLING, described);
    let proxies = format!(
        "first-hit rays for proxies only, Owen-scrambled Sobol: 1 per {TRIANGLES_PER_FACE_RAY} \
         triangles per face ({FACE_RAYS_MIN}..{FACE_RAYS_BASE}), 1 per \
         {TRIANGLES_PER_DIAGONAL_RAY} per diagonal ({DIAGONAL_RAYS_MIN}..{DIAGONAL_RAYS_MAX}, \
         else blended faces)"
    );
    assert_eq!(LOD_SAMPLING_PROXIES, proxies);
}

/// LOD data of every inner node of a demo scene, with or without voxels, the root proxied.
fn sampled(voxels: bool) -> (KdTree, Vec<NodeId>, Vec<LodData>) {
    let mesh = oocfmt_scenes::demo_scene(30_000);
    let tree = tree_of(&mesh, 8);
    let inner: Vec<NodeId> = (0..tree.nodes().len() as u32)
        .map(NodeId)
        .filter(|&id| matches!(tree.node(id), Some(KdNode::Inner { .. })))
        .collect();
    let cells = cells_of(&tree, &inner);
    let cell = |id: NodeId| {
        cells
            .iter()
            .find(|&&(n, _)| n == id)
            .map_or(Bounds::EMPTY, |&(_, c)| c)
    };
    let totals = triangle_totals(&mesh, &tree);
    let sample = Sampling {
        threshold: DEFAULT_VOXEL_THRESHOLD,
        voxels,
    };
    let root = tree.root();
    let lod = compute_in(&mesh, &tree, &inner, &cell, &totals, sample, &|id| {
        Some(id) == root
    });
    (tree, inner, lod)
}

#[test]
fn without_voxels_only_proxied_nodes_are_sampled_and_without_refinement() {
    let (tree, inner, with) = sampled(true);
    let (_, _, without) = sampled(false);
    let mut refined = 0;
    for ((id, w), o) in inner.iter().zip(&with).zip(&without) {
        assert!(o.voxel.is_none() && w.voxel.is_some(), "{id:?}");
        assert_eq!(o.area, w.area, "{id:?}: the area is kept");
        if Some(*id) == tree.root() {
            // The diagonals are cast the same way; the faces at the base count only.
            assert_eq!(o.proxy_samples[6..], w.proxy_samples[6..]);
            assert!(o.proxy_samples.iter().all(|s| *s != Sample::EMPTY));
            refined += usize::from(o.proxy_samples[..6] != w.proxy_samples[..6]);
        } else {
            assert!(
                o.proxy_samples.iter().all(|s| *s == Sample::EMPTY),
                "{id:?}"
            );
        }
    }
    assert_eq!(refined, 1, "the root's faces are refined only with voxels");
}

#[test]
fn subtree_totals_match_a_walk_of_every_subtree() {
    let mesh = oocfmt_scenes::demo::demo_scene(3000);
    let tree = tree_of(&mesh, 4);
    let areas: Vec<f64> = (0..mesh.triangles.len())
        .map(|t| triangle_area(&mesh, t))
        .collect();
    let totals = totals::totals(&tree, &areas);
    let mut straddling = 0;
    for k in 0..tree.nodes().len() {
        let id = NodeId(k as u32);
        let tris = subtree_triangles(&tree, id);
        let refs: usize = {
            let mut stack = vec![id];
            let mut n = 0;
            while let Some(x) = stack.pop() {
                match tree.node(x) {
                    Some(KdNode::Leaf { triangles }) => n += triangles.len(),
                    Some(KdNode::Inner { children, .. }) => stack.extend(children.iter().flatten()),
                    None => {}
                }
            }
            n
        };
        straddling += usize::from(refs > tris.len());
        let (count, area) = totals.of(id);
        assert_eq!(count, tris.len(), "node {k}");
        let expected: f64 = tris.iter().map(|&t| areas[t as usize]).sum();
        assert!(
            (area - expected).abs() <= 1e-9 * expected.max(1.0),
            "node {k}"
        );
    }
    // The scene must exercise the duplicate handling.
    assert!(straddling > 10, "{straddling}");
}
