//! Level-of-detail data for LOD nodes: a voxel (one or six shading samples) and an 18-direction
//! proxy record, sampled with rays against the node's own subtree so that only what is visible
//! from outside counts (Áfra et al. 2012, §4.2; Wald et al. 2004, §5.2): yellow cables inside a
//! green hull leave the hull's voxel and proxy green.
//!
//! Each face of a LOD node's cell shoots Halton-distributed rays straight in; the first hit of
//! each gives a normal and a colour, and their means are the face's sample. The faces' samples
//! double as the proxy's six axis directions; the twelve diagonal directions shoot their own
//! rays over the cell's silhouette. Ray counts grow with the subtree up to a fixed cap, so a
//! node costs O(rays × depth), not O(triangles).
//!
//! In a scene of several parts the face rays also vote: the entry's part word is the part
//! they hit most (ties to the lowest id), so picking at a coarse level answers the part that
//! covers the cell as seen. An R-LOD-only entry, which no ray defines, takes the part of the
//! largest triangle area clipped to the cell, as does a cell no ray hit.

pub mod rlod;
mod sampling;
mod sequence;
mod totals;

pub(crate) use totals::Totals;

use oocfmt::records::triangle::DEFAULT_ALBEDO;
use oocfmt::records::{Footprint, ProxyRecord, Rlod, Sample, Voxel};
use rayon::prelude::*;

use crate::kdtree::{KdNode, KdTree, NodeId};
use crate::raycast::{cross, dot, normalise, sub, triangle_corners, Prepared, Tracer};
use oocfmt_meshio::mesh::{Bounds, Mesh};
pub(crate) use sampling::shade;
pub use sampling::{
    Oracle, Seen, Shade, DIAGONAL_RAYS_MAX, DIAGONAL_RAYS_MIN, FACE_RAYS_BASE, FACE_RAYS_MAX,
    FACE_RAYS_MIN, TRIANGLES_PER_DIAGONAL_RAY, TRIANGLES_PER_FACE_RAY,
};

/// Subtrees of at most this many distinct triangles test every ray against each of them
/// instead of traversing the tree: the lowest LOD levels are most of the work, and there a
/// flat loop over a few prepared triangles beats pointer-chasing through a handful of nodes.
pub const EACH_TRIANGLE_MAX: usize = 24;

/// The value recorded under `rlod_fit` in the build parameters of files with R-LODs.
pub const RLOD_FIT: &str = "area-weighted PCA of the triangles clipped to the cell (f64); \
     deviation: largest vertex distance; expansion: deviation + radius/128";

/// The R-LOD records of `nodes`, in the same order: each node's subtree triangles clipped to
/// its cell and fitted by [`rlod::fit`], with the part of the largest clipped area (the part
/// word of an R-LOD-only entry). Runs in parallel over the nodes; the result does not depend
/// on the thread count.
pub fn rlods(mesh: &Mesh, tree: &KdTree, nodes: &[NodeId]) -> Vec<(Rlod, u32)> {
    let cells = cells_of(tree, nodes);
    nodes
        .par_iter()
        .map(|&id| {
            let cell = cells
                .binary_search_by_key(&id, |&(n, _)| n)
                .ok()
                .and_then(|k| cells.get(k))
                .map_or(Bounds::EMPTY, |&(_, c)| c);
            // An unrepresentable radius fails the layout when the node is encoded.
            let radius = cell.half_diagonal_up().unwrap_or(f32::MAX);
            let fit = rlod::fit(mesh, &subtree_triangles(tree, id), cell);
            (fit.record(radius), fit.part)
        })
        .collect()
}

/// The value recorded under `lod_sampling` in the build parameters: the method and the ray
/// counts above (checked against them by a test).
pub const LOD_SAMPLING: &str = "first-hit rays, Owen-scrambled Sobol: 1 per 8 triangles per face \
     (4..16, x4 while uncertain up to 256), 1 per 24 per diagonal (2..16, else blended faces); \
     shade and coverage per face";
/// `lod_sampling` in a file without voxels: only the nodes with a proxy are sampled, and their
/// faces are not refined (checked against the ray counts by a test).
pub const LOD_SAMPLING_PROXIES: &str = "first-hit rays for proxies only, Owen-scrambled Sobol: \
     1 per 8 triangles per face (4..16), 1 per 24 per diagonal (2..16, else blended faces)";
/// The default largest difference (normal component or colour channel) between a face sample
/// and the mean for a voxel to be stored as one sample.
pub const DEFAULT_VOXEL_THRESHOLD: f32 = 0.1;

/// The LOD data of one node.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LodData {
    /// The node's look from outside: one sample, or one per face when the faces differ by
    /// more than the voxel threshold. `None` where the file stores no voxels (an R-LOD-only
    /// build samples only the nodes with a proxy, and only for their proxy).
    pub voxel: Option<Voxel>,
    /// What a ray travelling along each of [`oocfmt::records::PROXY_DIRECTIONS`] sees;
    /// [`Sample::EMPTY`] where no ray hit anything.
    pub proxy_samples: [Sample; 18],
    /// Total area of the subtree's distinct triangles.
    pub area: f32,
    /// The part the entry stands for (its part word when the file has `PART_IDS`): the part
    /// most face rays hit; without hits, or for an R-LOD-only entry, the part of the largest
    /// triangle area in the cell. 0 in a scene without part ids, and from `compute_in`
    /// without voxels (the planner takes the R-LOD's part then).
    pub part: u32,
}

#[cfg(test)]
impl LodData {
    /// The voxel of data sampled with voxels.
    pub(crate) fn sampled_voxel(&self) -> Voxel {
        match self.voxel {
            Some(v) => v,
            None => panic!("sampled without voxels"),
        }
    }
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

/// Computes the LOD data of `nodes` (nodes of `tree` over `mesh`), in the same order, every
/// node with its diagonal proxy directions. Runs in parallel over the nodes; the result does
/// not depend on the thread count.
pub fn compute(mesh: &Mesh, tree: &KdTree, nodes: &[NodeId], voxel_threshold: f32) -> Vec<LodData> {
    let cells = cells_of(tree, nodes);
    let cell = |id: NodeId| {
        cells
            .binary_search_by_key(&id, |&(n, _)| n)
            .ok()
            .and_then(|k| cells.get(k))
            .map_or(Bounds::EMPTY, |&(_, c)| c)
    };
    let totals = triangle_totals(mesh, tree);
    let sample = Sampling {
        threshold: voxel_threshold,
        voxels: true,
    };
    compute_in(mesh, tree, nodes, &cell, &totals, sample, &|_| true)
}

/// The distinct triangles and their area under every node of `tree`, for [`compute_in`].
pub(crate) fn triangle_totals(mesh: &Mesh, tree: &KdTree) -> Totals {
    // Every LOD level sums the areas of (nearly) every triangle once more.
    let areas: Vec<f64> = (0..mesh.triangles.len())
        .into_par_iter()
        .map(|t| triangle_area(mesh, t))
        .collect();
    totals::totals(tree, &areas)
}

/// [`compute`] with each node's cell and the subtree totals given, for a caller that has them
/// already (the layout planner knows every cell). The twelve diagonal proxy directions are
/// cast only for the nodes `proxied` names: a node without a proxy never writes them, and they
/// are most of the rays of a large subtree; the others' diagonal samples stay
/// [`Sample::EMPTY`]. Without voxels a node without a proxy casts no ray at all: only its area
/// is kept.
pub(crate) fn compute_in(
    mesh: &Mesh,
    tree: &KdTree,
    nodes: &[NodeId],
    cell: &(dyn Fn(NodeId) -> Bounds + Sync),
    totals: &Totals,
    sample: Sampling,
    proxied: &(dyn Fn(NodeId) -> bool + Sync),
) -> Vec<LodData> {
    let corners = triangle_corners(mesh);
    nodes
        .par_iter()
        .map_init(
            || {
                (
                    Tracer::with_corners(mesh, tree, &corners),
                    Scratch::default(),
                )
            },
            |(tracer, scratch), &id| {
                let (triangles, area) = totals.of(id);
                let diagonals = proxied(id);
                if !sample.voxels && !diagonals {
                    return LodData {
                        voxel: None,
                        proxy_samples: [Sample::EMPTY; 18],
                        area: (area as f32).min(f32::MAX),
                        part: 0,
                    };
                }
                let node = NodeToSample {
                    id,
                    cell: cell(id),
                    totals: NodeTotals { triangles, area },
                    diagonals,
                };
                node_lod(mesh, tree, tracer, scratch, node, sample)
            },
        )
        .collect()
}

/// The cells of `nodes`, sorted by node id (a node not reached from the root is left out).
pub fn cells_of(tree: &KdTree, nodes: &[NodeId]) -> Vec<(NodeId, Bounds)> {
    let mut wanted = vec![false; tree.nodes().len()];
    for id in nodes {
        if let Some(w) = wanted.get_mut(id.index()) {
            *w = true;
        }
    }
    let mut out = Vec::with_capacity(nodes.len());
    let mut stack: Vec<(NodeId, Bounds)> = tree
        .root()
        .map(|r| (r, tree.bounds()))
        .into_iter()
        .collect();
    while let Some((id, cell)) = stack.pop() {
        if wanted.get(id.index()).copied().unwrap_or(false) {
            out.push((id, cell));
        }
        if let Some(&KdNode::Inner {
            axis,
            split,
            children,
        }) = tree.node(id)
        {
            let (lo, hi) = cell.split(usize::from(axis), split);
            for (c, cc) in children.into_iter().zip([lo, hi]) {
                if let Some(c) = c {
                    stack.push((c, cc));
                }
            }
        }
    }
    out.sort_unstable_by_key(|&(id, _)| id);
    out
}

/// Per-thread buffers for the small subtrees whose triangles are tested one by one.
#[derive(Default)]
struct Scratch {
    stack: Vec<NodeId>,
    triangles: Vec<u32>,
    prepared: Vec<Prepared>,
}

impl Scratch {
    /// The distinct triangles under `id`, in the order a depth-first walk meets them: for
    /// subtrees of at most [`EACH_TRIANGLE_MAX`] of them, where a linear search beats marks.
    fn collect_small(&mut self, tree: &KdTree, id: NodeId) -> &[u32] {
        self.triangles.clear();
        self.stack.clear();
        self.stack.push(id);
        while let Some(n) = self.stack.pop() {
            match tree.node(n) {
                Some(KdNode::Leaf { triangles }) => {
                    for &t in triangles {
                        if !self.triangles.contains(&t) {
                            self.triangles.push(t);
                        }
                    }
                }
                Some(KdNode::Inner { children, .. }) => {
                    self.stack.extend(children.iter().flatten())
                }
                None => {}
            }
        }
        &self.triangles
    }
}

/// What [`totals`] found under a node.
struct NodeTotals {
    triangles: usize,
    area: f64,
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

/// What [`compute_in`] samples: the one-sample voxel threshold, and whether the file stores
/// voxels (without them only the proxies' samples are wanted).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sampling {
    pub threshold: f32,
    pub voxels: bool,
}

/// A LOD node to sample: its cell, what its subtree holds, and whether it casts the diagonal
/// proxy directions.
struct NodeToSample {
    id: NodeId,
    cell: Bounds,
    totals: NodeTotals,
    diagonals: bool,
}

/// The LOD data of `node`, sampled against the triangles of its subtree in `mesh`.
fn node_lod<'a>(
    mesh: &'a Mesh,
    tree: &KdTree,
    tracer: &mut Tracer<'a>,
    scratch: &mut Scratch,
    node: NodeToSample,
    sample: Sampling,
) -> LodData {
    let NodeToSample {
        id,
        cell,
        totals,
        diagonals,
    } = node;
    let each = totals.triangles <= EACH_TRIANGLE_MAX;
    scratch.prepared.clear();
    if each {
        scratch.collect_small(tree, id);
        let Scratch {
            triangles,
            prepared,
            ..
        } = &mut *scratch;
        prepared.extend(triangles.iter().filter_map(|&t| {
            let c = mesh.corners(t as usize)?;
            Some(Prepared::new(t, c.map(|p| p.map(f64::from))))
        }));
    }
    let target = if each {
        sampling::Target::Each(&scratch.prepared)
    } else {
        sampling::Target::Subtree(id)
    };
    let sampled = sampling::NodeSampler {
        mesh,
        tracer,
        target,
        cell,
        triangles: totals.triangles,
        threshold: sample.threshold,
        diagonals,
        force_max: false,
        refine: sample.voxels,
        count_parts: sample.voxels && mesh.part_ids.is_some(),
    }
    .run();
    // No ray hit (or no part ids): the part of the largest area in the cell.
    let part = sampled.part.unwrap_or_else(|| match mesh.part_ids {
        Some(_) if !sample.voxels => 0,
        Some(_) if each => rlod::fit(mesh, &scratch.triangles, cell).part,
        Some(_) => rlod::fit(mesh, &subtree_triangles(tree, id), cell).part,
        None => 0,
    });
    // No ray hit anything (a sliver too thin for the rays between them): the voxel still
    // needs a colour, so fall back on the area-weighted mean of the subtree.
    let voxel = sample.voxels.then(|| {
        sampled.voxel.unwrap_or_else(|| {
            let tris = if each {
                scratch.triangles.clone()
            } else {
                subtree_triangles(tree, id)
            };
            // No ray hit: whatever is there covers too little of the cell to be seen.
            Voxel::Single(unoccluded_mean(mesh, &tris), Footprint::new(1.0, 0.0))
        })
    });
    LodData {
        voxel,
        proxy_samples: sampled.proxy,
        area: (totals.area as f32).min(f32::MAX),
        part,
    }
}

/// The LOD data of a cell whose subtree is not in memory (the top of an out-of-core build):
/// `answer` gives what each ray sees. Casts the most rays on every face and direction, so a
/// first call that records the rays and a second that answers them cast the same sequence.
/// `area` is the subtree's triangle area; a cell no ray hits gets a grey voxel and the part
/// `fallback_part`; otherwise the part is the one most face rays hit.
pub fn sample_cell(
    cell: Bounds,
    threshold: f32,
    area: f64,
    fallback_part: u32,
    answer: Oracle<'_>,
) -> LodData {
    let mesh = Mesh::default();
    let tree = KdTree::empty();
    let mut tracer = Tracer::new(&mesh, &tree);
    let sampled = sampling::NodeSampler {
        mesh: &mesh,
        tracer: &mut tracer,
        target: sampling::Target::Oracle(answer),
        cell,
        triangles: usize::MAX,
        threshold,
        diagonals: true,
        force_max: true,
        refine: true,
        count_parts: true,
    }
    .run();
    LodData {
        voxel: Some(sampled.voxel.unwrap_or(Voxel::Single(
            Sample::pack([0.0, 0.0, 1.0], [0.5; 3]),
            Footprint::new(1.0, 0.0),
        ))),
        proxy_samples: sampled.proxy,
        area: (area as f32).min(f32::MAX),
        part: sampled.part.unwrap_or(fallback_part),
    }
}

pub(crate) fn triangle_area(mesh: &Mesh, t: usize) -> f64 {
    mesh.corners(t).map_or(0.0, |c| {
        let p = c.map(|v| v.map(f64::from));
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        0.5 * dot(n, n).sqrt()
    })
}

/// The area-weighted mean geometric normal and colour of `tris`, ignoring occlusion.
fn unoccluded_mean(mesh: &Mesh, tris: &[u32]) -> Sample {
    let (mut normal, mut colour, mut weight) = ([0.0f64; 3], [0.0f64; 3], 0.0f64);
    for &t in tris {
        let t = t as usize;
        let (Some(c), Some(idx)) = (mesh.corners(t), mesh.triangles.get(t)) else {
            continue;
        };
        let p = c.map(|v| v.map(f64::from));
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        // Degenerate triangles still lend their colour.
        let w = 0.5 * dot(n, n).sqrt() + 1e-30;
        let col = vertex_colour(mesh, idx).unwrap_or_else(|| material_colour(mesh, t));
        for a in 0..3 {
            normal[a] += 0.5 * n[a];
            colour[a] += w * col[a];
        }
        weight += w;
    }
    let colour = if weight > 0.0 {
        colour.map(|c| (c / weight) as f32)
    } else {
        DEFAULT_ALBEDO
    };
    Sample::pack(normalise(normal).map(|c| c as f32), colour)
}

/// The mean of a triangle's vertex colours, when the mesh has them.
fn vertex_colour(mesh: &Mesh, idx: &[u32; 3]) -> Option<[f64; 3]> {
    let cs = mesh.colours.as_ref()?;
    Some(mean_vertex_colour(
        idx.iter().filter_map(|&v| cs.get(v as usize).copied()),
    ))
}

/// The linear RGB of a triangle from its vertices' colours: their mean (a third of each).
pub(crate) fn mean_vertex_colour(colours: impl IntoIterator<Item = [u8; 4]>) -> [f64; 3] {
    let mut sum = [0.0f64; 3];
    for c in colours {
        for a in 0..3 {
            sum[a] += f64::from(c[a]) / 255.0 / 3.0;
        }
    }
    sum
}

/// The triangle's material's diffuse colour, else the default albedo (spec §8).
fn material_colour(mesh: &Mesh, t: usize) -> [f64; 3] {
    mesh.materials
        .as_ref()
        .and_then(|m| m.get(t))
        .and_then(|&m| mesh.material_table.get(usize::from(m)))
        .map_or(default_albedo(), |m| m.diffuse.map(f64::from))
}

/// [`DEFAULT_ALBEDO`] in f64.
pub(crate) fn default_albedo() -> [f64; 3] {
    DEFAULT_ALBEDO.map(f64::from)
}

/// The largest difference of a normal component or colour channel, as stored.
fn difference(a: Sample, b: Sample) -> f32 {
    let (na, nb, ca, cb) = (a.normal(), b.normal(), a.colour(), b.colour());
    (0..3)
        .map(|i| (na[i] - nb[i]).abs().max((ca[i] - cb[i]).abs()))
        .fold(0.0, f32::max)
}

#[cfg(test)]
mod footprint_tests;
#[cfg(test)]
mod tests;
