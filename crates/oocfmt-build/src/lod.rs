//! Level-of-detail data for LOD nodes: a voxel (one or six shading samples) and an 18-direction
//! proxy record, both estimated from the projected area of the subtree's triangles.
//!
//! This estimate ignores occlusion (a triangle hidden behind another still counts); a later
//! ray-sampled estimator can replace [`compute`] without touching the layout.

use oocfmt::records::{ProxyRecord, Sample, Voxel, PROXY_DIRECTIONS};
use rayon::prelude::*;

use crate::kdtree::{KdNode, KdTree, NodeId};
use crate::mesh::Mesh;

/// The value recorded under `lod_sampling` in the build parameters.
pub const LOD_SAMPLING: &str = "projected-area";
/// The default largest difference (normal component or colour channel) between a face sample
/// and the mean for a voxel to be stored as one sample.
pub const DEFAULT_VOXEL_THRESHOLD: f32 = 0.1;

/// Outward normals of the voxel faces in spec order: −x, +x, −y, +y, −z, +z.
const FACE_NORMALS: [[f64; 3]; 6] = [
    [-1.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, -1.0],
    [0.0, 0.0, 1.0],
];

/// The LOD data of one node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LodData {
    pub voxel: Voxel,
    /// What a ray travelling along each of [`PROXY_DIRECTIONS`] sees.
    pub proxy_samples: [Sample; 18],
    /// Total area of the subtree's distinct triangles.
    pub area: f32,
}

impl LodData {
    /// The proxy record of this node, once the layout knows which block holds the node.
    pub fn proxy(&self, node_block: u32) -> ProxyRecord {
        ProxyRecord {
            node_block,
            area: self.area,
            samples: self.proxy_samples,
        }
    }
}

/// What one triangle contributes to a sample, precomputed once per triangle.
#[derive(Clone, Copy, Debug, Default)]
struct Shade {
    area: f64,
    /// Unit geometric normal (zero for a degenerate triangle): decides which way it faces.
    facing: [f64; 3],
    /// The normal that gets averaged: the mean vertex normal, else the geometric one.
    normal: [f64; 3],
    colour: [f64; 3],
}

/// Weighted sums of normals and colours.
#[derive(Clone, Copy, Debug, Default)]
struct Acc {
    weight: f64,
    normal: [f64; 3],
    colour: [f64; 3],
}

impl Acc {
    fn add(&mut self, w: f64, s: &Shade) {
        self.weight += w;
        for a in 0..3 {
            self.normal[a] += w * s.normal[a];
            self.colour[a] += w * s.colour[a];
        }
    }

    fn merge(&mut self, o: &Acc) {
        self.weight += o.weight;
        for a in 0..3 {
            self.normal[a] += o.normal[a];
            self.colour[a] += o.colour[a];
        }
    }

    fn sample(&self) -> Sample {
        let n = self.normal.map(|c| c as f32);
        let c = if self.weight > 0.0 {
            self.colour.map(|c| (c / self.weight) as f32)
        } else {
            [1.0; 3]
        };
        Sample::pack(n, c)
    }
}

/// Computes the LOD data of `nodes` (which must be inner nodes of `tree` over `mesh`), in the
/// same order. Runs in parallel; the result does not depend on the thread count.
pub fn compute(mesh: &Mesh, tree: &KdTree, nodes: &[NodeId], voxel_threshold: f32) -> Vec<LodData> {
    let shades: Vec<Shade> = (0..mesh.triangles.len())
        .into_par_iter()
        .map(|t| shade(mesh, t))
        .collect();
    let directions = proxy_directions();
    nodes
        .par_iter()
        .map(|&id| {
            let tris = subtree_triangles(tree, id);
            node_lod(&tris, &shades, &directions, voxel_threshold)
        })
        .collect()
}

/// The distinct mesh triangles referenced by the leaves under `id`, sorted.
pub fn subtree_triangles(tree: &KdTree, id: NodeId) -> Vec<u32> {
    let mut out = Vec::new();
    let mut stack = vec![id];
    while let Some(n) = stack.pop() {
        match tree.node(n) {
            Some(KdNode::Leaf { triangles }) => out.extend_from_slice(triangles),
            Some(KdNode::Inner { children, .. }) => stack.extend(children.iter().flatten()),
            None => {}
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

fn proxy_directions() -> [[f64; 3]; 18] {
    PROXY_DIRECTIONS.map(|d| normalise(d.map(f64::from)))
}

fn node_lod(
    tris: &[u32],
    shades: &[Shade],
    directions: &[[f64; 3]; 18],
    threshold: f32,
) -> LodData {
    let mut faces = [Acc::default(); 6];
    let mut proxies = [Acc::default(); 18];
    let mut area = 0.0f64;
    let mut unweighted = Acc::default();
    for s in tris.iter().filter_map(|&t| shades.get(t as usize)) {
        area += s.area;
        unweighted.add(1.0, s);
        for (acc, n) in faces.iter_mut().zip(&FACE_NORMALS) {
            let d = dot(s.facing, *n);
            if d > 0.0 {
                acc.add(s.area * d, s);
            }
        }
        for (acc, dir) in proxies.iter_mut().zip(directions) {
            // A ray travelling along `dir` sees the surfaces that face back against it.
            let d = -dot(s.facing, *dir);
            if d > 0.0 {
                acc.add(s.area * d, s);
            }
        }
    }
    let mut mean = Acc::default();
    for f in &faces {
        mean.merge(f);
    }
    // A subtree of degenerate triangles faces nowhere; its voxel still needs a colour.
    if mean.weight <= 0.0 {
        mean = unweighted;
    }
    let mean_sample = mean.sample();
    let face_samples = faces.map(|f| {
        if f.weight > 0.0 {
            f.sample()
        } else {
            mean_sample
        }
    });
    let agree = face_samples
        .iter()
        .all(|s| difference(*s, mean_sample) <= threshold);
    let voxel = if agree {
        Voxel::Single(mean_sample)
    } else {
        Voxel::Six(face_samples)
    };
    let proxy_samples = proxies.map(|p| {
        if p.weight > 0.0 {
            p.sample()
        } else {
            Sample::EMPTY
        }
    });
    LodData {
        voxel,
        proxy_samples,
        area: (area as f32).min(f32::MAX),
    }
}

/// The largest difference of a normal component or colour channel, as stored.
fn difference(a: Sample, b: Sample) -> f32 {
    let (na, nb, ca, cb) = (a.normal(), b.normal(), a.colour(), b.colour());
    (0..3)
        .map(|i| (na[i] - nb[i]).abs().max((ca[i] - cb[i]).abs()))
        .fold(0.0, f32::max)
}

fn shade(mesh: &Mesh, t: usize) -> Shade {
    let Some(idx) = mesh.triangles.get(t) else {
        return Shade::default();
    };
    let Some(p) = mesh.corners(t) else {
        return Shade::default();
    };
    let p = p.map(|v| v.map(f64::from));
    let e1 = sub(p[1], p[0]);
    let e2 = sub(p[2], p[0]);
    let cross = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let len = dot(cross, cross).sqrt();
    let facing = if len > 0.0 {
        cross.map(|c| c / len)
    } else {
        [0.0; 3]
    };
    let normal = mesh
        .normals
        .as_ref()
        .map(|ns| {
            let mut sum = [0.0f64; 3];
            for n in idx.iter().filter_map(|&v| ns.get(v as usize)) {
                for a in 0..3 {
                    sum[a] += f64::from(n[a]);
                }
            }
            normalise(sum)
        })
        .filter(|n| dot(*n, *n) > 0.0)
        .unwrap_or(facing);
    Shade {
        area: 0.5 * len,
        facing,
        normal,
        colour: colour(mesh, t, idx),
    }
}

/// Vertex colours averaged, else the material's diffuse colour, else white.
fn colour(mesh: &Mesh, t: usize, idx: &[u32; 3]) -> [f64; 3] {
    if let Some(cs) = &mesh.colours {
        let mut sum = [0.0f64; 3];
        for c in idx.iter().filter_map(|&v| cs.get(v as usize)) {
            for a in 0..3 {
                sum[a] += f64::from(c[a]) / 255.0;
            }
        }
        return sum.map(|c| c / 3.0);
    }
    let material = mesh
        .materials
        .as_ref()
        .and_then(|m| m.get(t))
        .and_then(|&m| mesh.material_table.get(usize::from(m)));
    material.map_or([1.0; 3], |m| m.diffuse.map(f64::from))
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalise(v: [f64; 3]) -> [f64; 3] {
    let len = dot(v, v).sqrt();
    if len > 0.0 {
        v.map(|c| c / len)
    } else {
        [0.0; 3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kdtree::{build, KdBuildOptions};

    /// Two unit squares: one facing +z (red), one facing +x (blue), apart from each other.
    fn two_walls() -> Mesh {
        let positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [3.0, 0.0, 0.0],
            [3.0, 1.0, 0.0],
            [3.0, 1.0, 1.0],
            [3.0, 0.0, 1.0],
        ];
        let triangles = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
        let mut m = Mesh::new(positions, triangles);
        m.colours = Some(
            [[255, 0, 0, 255]; 4]
                .into_iter()
                .chain([[0, 0, 255, 255]; 4])
                .collect(),
        );
        m
    }

    fn lod_of_root(mesh: &Mesh, threshold: f32) -> LodData {
        let tree = build(
            mesh,
            &KdBuildOptions {
                max_leaf_triangles: 1,
                max_depth: 16,
                ..KdBuildOptions::default()
            },
        );
        let Ok(tree) = tree else { panic!("{tree:?}") };
        let root = tree.root().unwrap_or(NodeId(0));
        let out = compute(mesh, &tree, &[root], threshold);
        assert_eq!(out.len(), 1);
        out[0]
    }

    #[test]
    fn a_flat_patch_gets_one_sample_and_proxies_see_its_front_only() {
        let mut mesh = two_walls();
        mesh.triangles.truncate(2);
        let lod = lod_of_root(&mesh, DEFAULT_VOXEL_THRESHOLD);
        let Voxel::Single(s) = lod.voxel else {
            panic!("{:?}", lod.voxel)
        };
        assert_eq!(s.normal(), [0.0, 0.0, 1.0]);
        assert_eq!(s.colour(), [1.0, 0.0, 0.0]);
        assert_eq!(lod.area, 1.0);
        // Direction 5 is −z: a ray going down sees the +z face; direction 4 (+z) sees nothing.
        assert_eq!(lod.proxy_samples[5], s.with_single(false));
        assert_eq!(lod.proxy_samples[4], Sample::EMPTY);
        assert_eq!(lod.proxy_samples[0], Sample::EMPTY);
        assert!(lod.proxy_samples[10..14]
            .iter()
            .any(|p| *p != Sample::EMPTY));
    }

    #[test]
    fn differently_facing_walls_get_six_samples() {
        let lod = lod_of_root(&two_walls(), DEFAULT_VOXEL_THRESHOLD);
        let Voxel::Six(s) = lod.voxel else {
            panic!("{:?}", lod.voxel)
        };
        assert_eq!(s[1].normal(), [1.0, 0.0, 0.0]);
        assert_eq!(s[1].colour(), [0.0, 0.0, 1.0]);
        assert_eq!(s[5].normal(), [0.0, 0.0, 1.0]);
        assert_eq!(s[5].colour(), [1.0, 0.0, 0.0]);
        // Faces nothing points through show the mean.
        assert_eq!(s[0], s[2]);
        assert_eq!(lod.area, 2.0);
        // With a threshold above every difference the same node is one sample.
        assert!(matches!(
            lod_of_root(&two_walls(), 3.0).voxel,
            Voxel::Single(_)
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
                diffuse: [0.0, 1.0, 0.0],
            },
            oocfmt::metadata::Material {
                name: "grey".into(),
                diffuse: [0.5; 3],
            },
        ];
        let lod = lod_of_root(&mesh, DEFAULT_VOXEL_THRESHOLD);
        assert_eq!(lod.proxy_samples[5].colour(), [0.0, 1.0, 0.0]);
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
}
