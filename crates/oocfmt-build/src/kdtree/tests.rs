//! The kd-tree builder on small hand-made and generated meshes: leaves cover every triangle,
//! straddlers go to both sides, empty space is cut off, rays find what a brute-force test finds,
//! bad options and parts are refused, and the tree does not depend on the thread count.

use super::*;
use crate::raycast::{first_hit_of, Prepared, Ray, Tracer};
use oocfmt_scenes::demo_scene;

/// A row of `n` unit squares along x, two triangles each.
fn strip(n: u32) -> Mesh {
    let mut positions = Vec::new();
    for i in 0..=n {
        positions.push([i as f32, 0.0, 0.0]);
        positions.push([i as f32, 1.0, 0.0]);
    }
    let triangles = (0..n)
        .flat_map(|i| [[2 * i, 2 * i + 2, 2 * i + 3], [2 * i, 2 * i + 3, 2 * i + 1]])
        .collect();
    Mesh::new(positions, triangles)
}

/// Two copies of a small demo sphere, `gap` apart along x.
fn two_clusters(gap: f32) -> Mesh {
    let one = demo_scene(600);
    let mut mesh = one.clone();
    let base = one.positions.len() as u32;
    mesh.positions
        .extend(one.positions.iter().map(|p| [p[0] + gap, p[1], p[2]]));
    mesh.triangles
        .extend(one.triangles.iter().map(|t| t.map(|v| v + base)));
    if let (Some(all), Some(part)) = (mesh.normals.as_mut(), one.normals.as_ref()) {
        all.extend_from_slice(part);
    }
    if let (Some(all), Some(part)) = (mesh.colours.as_mut(), one.colours.as_ref()) {
        all.extend_from_slice(part);
    }
    if let (Some(all), Some(part)) = (mesh.materials.as_mut(), one.materials.as_ref()) {
        all.extend_from_slice(part);
    }
    mesh
}

fn built(mesh: &Mesh, opts: &KdBuildOptions) -> KdTree {
    match build(mesh, opts) {
        Ok(t) => t,
        Err(e) => panic!("build failed: {e}"),
    }
}

fn leaf_sets(tree: &KdTree) -> Vec<Vec<u32>> {
    tree.leaves_depth_first()
        .into_iter()
        .filter_map(|id| match tree.node(id) {
            Some(KdNode::Leaf { triangles }) => Some(triangles.clone()),
            _ => None,
        })
        .collect()
}

/// (nodes, leaves, inner nodes with an empty child, references, depth)
fn stats(tree: &KdTree) -> (usize, usize, usize, usize, u32) {
    let leaves = leaf_sets(tree);
    let cuts = tree
        .nodes()
        .iter()
        .filter(|n| matches!(n, KdNode::Inner { children, .. } if children.contains(&None)))
        .count();
    (
        tree.nodes().len(),
        leaves.len(),
        cuts,
        leaves.iter().map(Vec::len).sum(),
        tree.depth(),
    )
}

fn check_reaches_every_triangle(mesh: &Mesh, tree: &KdTree, max_leaf: usize) {
    assert_eq!(tree.validate(mesh), Ok(()));
    let leaves = leaf_sets(tree);
    assert!(
        leaves.iter().all(|l| l.len() <= max_leaf),
        "a leaf is too big"
    );
    let mut all: Vec<u32> = leaves.concat();
    all.sort_unstable();
    all.dedup();
    assert_eq!(all, (0..mesh.triangles.len() as u32).collect::<Vec<_>>());
}

#[test]
fn a_strip_is_split_into_small_leaves_covering_every_triangle() {
    let mesh = strip(8);
    let opts = KdBuildOptions {
        max_leaf_triangles: 2,
        ..KdBuildOptions::default()
    };
    let tree = built(&mesh, &opts);
    check_reaches_every_triangle(&mesh, &tree, 2);
    // Splits fall on the squares' edges, so no triangle is cut: 8 leaves of one square each.
    assert_eq!(stats(&tree), (15, 8, 0, 16, 4));
    assert!(leaf_sets(&tree).iter().all(|l| l.len() == 2));
}

#[test]
fn straddlers_go_both_ways_and_unsplittable_sets_stop() {
    // Both triangles of a square span the whole square: no plane separates them.
    let tree = build(
        &strip(1),
        &KdBuildOptions {
            max_leaf_triangles: 1,
            ..KdBuildOptions::default()
        },
    );
    assert_eq!(tree.map(|t| leaf_sets(&t)), Ok(vec![vec![0, 1]]));
    // A long thin triangle crossing a cluster of small ones is referenced on both sides.
    let mut mesh = strip(6);
    let b = mesh.positions.len() as u32;
    mesh.positions
        .extend([[0.0, 0.4, 0.5], [6.0, 0.5, 0.5], [0.0, 0.6, 0.5]]);
    mesh.triangles.push([b, b + 1, b + 2]);
    let tree = built(
        &mesh,
        &KdBuildOptions {
            max_leaf_triangles: 3,
            ..KdBuildOptions::default()
        },
    );
    check_reaches_every_triangle(&mesh, &tree, 3);
    let holding = leaf_sets(&tree).iter().filter(|l| l.contains(&12)).count();
    assert!(holding >= 3, "the long triangle is in {holding} leaves");
}

#[test]
fn the_demo_scene_tree_is_valid_and_reaches_everything() {
    let mesh = demo_scene(20_000);
    let tree = built(&mesh, &KdBuildOptions::default());
    check_reaches_every_triangle(&mesh, &tree, 8);
    assert!(tree.depth() <= 64);
    let again = KdTree::from_parts(
        &mesh,
        tree.nodes().to_vec(),
        tree.root(),
        tree.bounds(),
        Vec::new(),
    );
    assert!(again.is_ok(), "{again:?}");
}

/// Every ray's first hit through the tree is the first hit among all triangles: the tree
/// references each triangle wherever the triangle is, not merely near it.
#[test]
fn rays_through_the_tree_find_what_testing_every_triangle_finds() {
    let mesh = demo_scene(6_000);
    let tree = built(
        &mesh,
        &KdBuildOptions {
            max_leaf_triangles: 4,
            ..KdBuildOptions::default()
        },
    );
    let all: Vec<Prepared> = (0..mesh.triangles.len())
        .filter_map(|t| {
            let c = mesh.corners(t)?;
            Some(Prepared::new(t as u32, c.map(|p| p.map(f64::from))))
        })
        .collect();
    let root = tree.root().unwrap_or(NodeId(0));
    let mut tracer = Tracer::new(&mesh, &tree);
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        // xorshift: a fixed pseudo-random sequence.
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut hits, mut rays) = (0, 0);
    for _ in 0..3000 {
        let origin = [0, 1, 2].map(|_| 3.0 * next() - 1.5);
        let dir = crate::raycast::normalise([0, 1, 2].map(|_| next() - 0.5));
        let ray = Ray::new(origin, dir);
        let Some((t0, t1)) = crate::raycast::clip_to_box(&ray, &tree.bounds()) else {
            continue;
        };
        let (t0, t1) = (t0.max(0.0), t1);
        if t0 > t1 {
            continue;
        }
        rays += 1;
        let want = first_hit_of(&all, &ray, t0, t1, 0.0);
        let got = tracer.first_hit(root, &ray, t0, t1, 0.0);
        assert_eq!(got.map(|h| h.t), want.map(|h| h.t), "ray {ray:?}");
        hits += usize::from(got.is_some());
    }
    assert!(rays > 1000 && hits > 300, "{rays} rays, {hits} hits");
}

#[test]
fn empty_space_is_cut_off_next_to_the_root() {
    let mesh = two_clusters(20.0);
    let tree = built(&mesh, &KdBuildOptions::default());
    check_reaches_every_triangle(&mesh, &tree, 8);
    // The root separates the clusters; each child's cell is mostly empty gap, which the next
    // split cuts off as an empty child.
    let root = tree.root().unwrap_or(NodeId(0));
    let [Some(l), Some(r)] = tree.children(root) else {
        panic!("the root does not split: {:?}", tree.node(root))
    };
    for child in [l, r] {
        match tree.node(child) {
            Some(KdNode::Inner {
                axis: 0, children, ..
            }) => assert!(children.contains(&None), "{children:?}"),
            other => panic!("child {child:?} does not cut the gap: {other:?}"),
        }
    }
    // Without cutting, the same scene needs no empty child near the root.
    let uncut = built(
        &mesh,
        &KdBuildOptions {
            empty_cut: 1.0,
            ..KdBuildOptions::default()
        },
    );
    // (Without cuts, one-sided splits along the gap run into `max_bad_splits`: bigger leaves.)
    check_reaches_every_triangle(&mesh, &uncut, MAX_LEAF_TRIANGLES as usize);
    assert!(stats(&uncut).2 < stats(&tree).2);
}

/// Changes to the builder show up here: node and leaf counts, empty-space cuts, references
/// and depth of two small scenes, exactly.
#[test]
fn golden_tree_statistics() {
    let sphere = built(&demo_scene(2_000), &KdBuildOptions::default());
    assert_eq!(stats(&sphere), (2538, 938, 663, 5995, 21));
    let clusters = built(
        &two_clusters(5.0),
        &KdBuildOptions {
            max_leaf_triangles: 4,
            ..KdBuildOptions::default()
        },
    );
    assert_eq!(stats(&clusters), (4319, 1585, 1150, 5312, 25));
}

/// The tree, and so the container file, is the same whatever the thread count: the whole
/// pipeline (tree, LOD sampling, layout, compression) runs inside pools of one, two and three
/// threads.
#[test]
fn the_tree_and_container_are_the_same_whatever_the_thread_count() {
    // Big enough for parallel subtrees and parallel binning and partitioning.
    let mesh = demo_scene(100_000);
    let opts = KdBuildOptions::default();
    let layout = crate::layout::LayoutOptions::default();
    let Ok(dir) = tempfile::tempdir() else {
        panic!("no temporary folder")
    };
    let in_pool = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
        let Ok(pool) = pool else {
            panic!("no thread pool")
        };
        pool.install(|| {
            let tree = built(&mesh, &opts);
            let path = dir.path().join(format!("{threads}.oocf"));
            let written = crate::layout::write_container(&path, &mesh, &tree, &layout);
            assert!(written.is_ok(), "{written:?}");
            let bytes = std::fs::read(&path);
            let Ok(bytes) = bytes else {
                panic!("{bytes:?}")
            };
            (tree, bytes)
        })
    };
    let one = in_pool(1);
    assert!(one.0.nodes().len() > 100_000);
    let two = in_pool(2);
    assert!(one.0 == two.0, "one and two threads build different trees");
    assert!(one.1 == two.1, "one and two threads write different files");
    let three = in_pool(3);
    assert!(
        one.0 == three.0 && one.1 == three.1,
        "one and three threads differ"
    );
}

#[test]
fn a_subtree_can_be_built_for_part_of_a_scene() {
    let mesh = strip(10);
    let cell = Bounds {
        min: [2.0, 0.0, 0.0],
        max: [6.0, 1.0, 0.0],
    };
    let tris: Vec<u32> = (4..12).collect();
    let opts = KdBuildOptions {
        max_leaf_triangles: 2,
        ..KdBuildOptions::default()
    };
    let nodes = build_cell(&mesh, tris, cell, 10, &opts);
    let Ok(nodes) = nodes else {
        panic!("{nodes:?}")
    };
    let sub = KdTree::from_parts(&mesh, nodes, Some(NodeId(0)), cell, Vec::new());
    let Ok(sub) = sub else { panic!("{sub:?}") };
    let mut all: Vec<u32> = leaf_sets(&sub).concat();
    all.sort_unstable();
    all.dedup();
    assert_eq!(all, (4..12).collect::<Vec<_>>());
    assert_eq!(sub.depth(), 3);
    assert_eq!(
        build_cell(&mesh, Vec::new(), cell, 1, &opts),
        Ok(Vec::new())
    );
    assert!(matches!(
        build_cell(&mesh, vec![99], cell, 1, &opts),
        Err(KdError::TriangleOutOfRange { triangle: 99, .. })
    ));
}

#[test]
fn an_empty_mesh_gives_an_empty_tree() {
    let tree = build(&Mesh::default(), &KdBuildOptions::default());
    assert_eq!(tree.as_ref().map(|t| (t.root(), t.depth())), Ok((None, 0)));
}

#[test]
fn inseparable_piles_beyond_the_leaf_limit_are_an_error() {
    // 5000 copies of one triangle: no plane separates them, and no leaf may hold them.
    let mut mesh = Mesh::new(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]; 5000],
    );
    assert!(matches!(
        build(&mesh, &KdBuildOptions::default()),
        Err(KdError::LeafTooLarge {
            triangles: 5000,
            ..
        })
    ));
    // 4000 of them make one (oversized) leaf.
    mesh.triangles.truncate(4000);
    let tree = built(&mesh, &KdBuildOptions::default());
    assert_eq!(stats(&tree).1, 1);
}

#[test]
fn bad_options_and_parts_are_refused() {
    let mesh = strip(1);
    let bad = |o: KdBuildOptions| build(&mesh, &o).err();
    let d = KdBuildOptions::default;
    assert_eq!(
        bad(KdBuildOptions {
            max_leaf_triangles: 0,
            ..d()
        }),
        Some(KdError::MaxLeafTriangles(0))
    );
    assert_eq!(
        bad(KdBuildOptions {
            max_depth: 129,
            ..d()
        }),
        Some(KdError::MaxDepth(129))
    );
    for o in [
        KdBuildOptions { sah_bins: 1, ..d() },
        KdBuildOptions {
            traversal_cost: 0.0,
            ..d()
        },
        KdBuildOptions {
            intersection_cost: f32::NAN,
            ..d()
        },
        KdBuildOptions {
            empty_cut: 0.0,
            ..d()
        },
        KdBuildOptions {
            empty_cut: 1.5,
            ..d()
        },
    ] {
        assert!(matches!(bad(o), Some(KdError::BadOption { .. })));
    }

    let bounds = mesh.bounds();
    let leaf = KdNode::Leaf {
        triangles: vec![0, 1],
    };
    let shared = vec![
        KdNode::Inner {
            axis: 0,
            split: 0.5,
            children: [Some(NodeId(1)), Some(NodeId(1))],
        },
        leaf.clone(),
    ];
    assert_eq!(
        KdTree::from_parts(&mesh, shared, Some(NodeId(0)), bounds, Vec::new()),
        Err(KdError::NotATree { node: 1 })
    );
    let outside = vec![
        KdNode::Inner {
            axis: 0,
            split: 2.0,
            children: [Some(NodeId(1)), None],
        },
        leaf,
    ];
    assert!(matches!(
        KdTree::from_parts(&mesh, outside, Some(NodeId(0)), bounds, Vec::new()),
        Err(KdError::BadSplit { .. })
    ));
    let bad_tri = vec![KdNode::Leaf { triangles: vec![2] }];
    assert!(matches!(
        KdTree::from_parts(&mesh, bad_tri, Some(NodeId(0)), bounds, Vec::new()),
        Err(KdError::TriangleOutOfRange { .. })
    ));
}

#[test]
fn the_parameters_describe_the_build() {
    let tree = built(&strip(3), &KdBuildOptions::default());
    let get = |k: &str| {
        tree.params()
            .iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v.clone())
    };
    assert_eq!(get("kd_split").as_deref(), Some("binned-sah"));
    assert_eq!(get("kd_sah_bins").as_deref(), Some("32"));
    assert_eq!(get("kd_intersection_cost").as_deref(), Some("1.5"));
    assert_eq!(get("kd_empty_cut").as_deref(), Some("0.15"));
    assert_eq!(get("kd_max_depth").as_deref(), Some("64"));
}
