//! Triangle blocks: leaves are packed in depth-first order so neighbours share blocks; each
//! leaf's list entries are contiguous, triangles and vertices are stored once per block, and
//! the first copy of a triangle anywhere in the file is its primary.

// Fx hashing: these maps take a lookup per triangle corner; SipHash cost 6 % of a convert.
use rustc_hash::FxHashMap as HashMap;

use oocfmt::records::triangle::{
    oct_encode, TriangleBlockWriter, ATTR_MATERIALS, ATTR_PART_WIDTH, MAX_ITEMS,
};
use oocfmt::records::{Triangle, Vertex};

use super::{parts, LayoutError};
use crate::kdtree::{KdNode, KdTree};
use oocfmt_meshio::mesh::Mesh;

/// Where a leaf's list entries live.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub(crate) struct LeafRef {
    /// Index among the triangle blocks (not yet a block id).
    pub block: u32,
    pub first: u16,
    pub count: u16,
}

/// A vertex as stored, so equal keys mean byte-identical records that can be shared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct VertexKey {
    position: [u32; 3],
    normal: Option<[i16; 2]>,
    colour: Option<[u8; 4]>,
}

impl VertexKey {
    fn vertex(&self) -> Vertex {
        Vertex {
            position: self.position.map(f32::from_bits),
            normal: self.normal,
            colour: self.colour,
        }
    }
}

/// The stored vertex of each mesh vertex, and a number per distinct stored vertex: two mesh
/// vertices may store the same bytes (normals are quantised), and a block stores those once.
pub(crate) struct VertexTable {
    keys: Vec<VertexKey>,
    /// Per mesh vertex: the first mesh vertex with the same key.
    distinct: Vec<u32>,
}

impl VertexTable {
    pub fn new(mesh: &Mesh) -> VertexTable {
        let keys: Vec<VertexKey> = (0..mesh.positions.len())
            .map(|v| VertexKey {
                position: mesh
                    .positions
                    .get(v)
                    .copied()
                    .unwrap_or_default()
                    .map(f32::to_bits),
                normal: mesh
                    .normals
                    .as_ref()
                    .map(|n| oct_encode(n.get(v).copied().unwrap_or_default())),
                colour: mesh
                    .colours
                    .as_ref()
                    .map(|c| c.get(v).copied().unwrap_or([255; 4])),
            })
            .collect();
        let mut first: HashMap<VertexKey, u32> =
            HashMap::with_capacity_and_hasher(keys.len(), Default::default());
        let distinct = keys
            .iter()
            .zip(0u32..)
            .map(|(k, v)| *first.entry(*k).or_insert(v))
            .collect();
        VertexTable { keys, distinct }
    }

    fn key(&self, v: u32) -> VertexKey {
        self.keys.get(v as usize).copied().unwrap_or(VertexKey {
            position: [0; 3],
            normal: None,
            colour: None,
        })
    }

    fn distinct(&self, v: u32) -> u32 {
        self.distinct.get(v as usize).copied().unwrap_or(v)
    }
}

/// The contents of one triangle block, as mesh triangle ids.
#[derive(Clone, Debug, Default)]
pub(crate) struct PlannedTriangles {
    /// List section, in order.
    list: Vec<u32>,
    /// Distinct triangles in the order first stored here.
    triangles: Vec<u32>,
    /// Parallel to `triangles`: whether this is the triangle's first copy in the file.
    primary: Vec<bool>,
}

/// What an encoded triangle block holds, for the metadata counts.
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub(crate) struct TriangleCounts {
    pub primaries: u64,
    pub triangles: u64,
    pub vertices: u64,
}

pub(crate) struct TrianglePlan {
    /// By node id; `Some` for every leaf.
    pub leaves: Vec<Option<LeafRef>>,
    pub blocks: Vec<PlannedTriangles>,
}

/// Assigns every leaf's triangles to triangle blocks, in depth-first leaf order.
pub(crate) fn plan_triangles(
    mesh: &Mesh,
    tree: &KdTree,
    vertices: &VertexTable,
    attrs: u16,
    block_size: usize,
) -> Result<TrianglePlan, LayoutError> {
    let ever_stored = vec![false; mesh.triangles.len()];
    plan_triangles_with(mesh, tree, vertices, attrs, block_size, ever_stored)
}

/// [`plan_triangles`] for part of a scene: `stored_elsewhere[t]` marks the triangles whose
/// primary copy lives in another part, so they are stored here only as copies.
pub(crate) fn plan_triangles_with(
    mesh: &Mesh,
    tree: &KdTree,
    vertices: &VertexTable,
    attrs: u16,
    block_size: usize,
    mut ever_stored: Vec<bool>,
) -> Result<TrianglePlan, LayoutError> {
    let mut open = OpenBlock::new(mesh, vertices);
    let mut plan = TrianglePlan {
        leaves: vec![None; tree.nodes().len()],
        blocks: Vec::new(),
    };
    ever_stored.resize(mesh.triangles.len(), false);
    let fits = |(l, t, w): (usize, usize, usize)| {
        l <= MAX_ITEMS
            && t <= MAX_ITEMS
            && w <= MAX_ITEMS
            && TriangleBlockWriter::raw_len_for(attrs, l, t, w) <= block_size
    };
    for leaf in tree.leaves_depth_first() {
        let Some(KdNode::Leaf { triangles }) = tree.node(leaf) else {
            continue;
        };
        let count = u16::try_from(triangles.len())
            .map_err(|_| LayoutError::TooMany("triangles in a leaf"))?;
        let mut counts = open.try_add(triangles);
        if !fits(counts) {
            // Closing also forgets the failed attempt, an empty block's included.
            let full = open.close();
            if !full.list.is_empty() {
                plan.blocks.push(full);
            }
            counts = open.try_add(triangles);
            if !fits(counts) {
                let (l, t, w) = counts;
                return Err(LayoutError::LeafTooLarge {
                    triangles: triangles.len(),
                    bytes: TriangleBlockWriter::raw_len_for(attrs, l, t, w),
                    block_size,
                });
            }
        }
        let first = u16::try_from(open.planned.list.len())
            .map_err(|_| LayoutError::TooMany("list entries"))?;
        let block = u32::try_from(plan.blocks.len())
            .map_err(|_| LayoutError::TooMany("triangle blocks"))?;
        open.commit(triangles, counts.2, &mut ever_stored);
        if let Some(slot) = plan.leaves.get_mut(leaf.index()) {
            *slot = Some(LeafRef {
                block,
                first,
                count,
            });
        }
    }
    if !open.planned.list.is_empty() {
        plan.blocks.push(open.planned);
    }
    Ok(plan)
}

/// The block being filled. Membership is kept as stamps in per-triangle and per-vertex arrays
/// instead of sets: a stamp at or above `opened` means "in the open block", so closing a block
/// is one increment and a leaf costs a few array reads, not two hash sets.
struct OpenBlock<'a> {
    mesh: &'a Mesh,
    vertices: &'a VertexTable,
    planned: PlannedTriangles,
    /// Distinct stored vertices in the block.
    vertex_count: usize,
    triangle_stamp: Vec<u32>,
    /// Indexed by [`VertexTable::distinct`].
    vertex_stamp: Vec<u32>,
    /// The stamp of the current attempt; every attempt takes a new one.
    stamp: u32,
    /// The first stamp of the open block.
    opened: u32,
    /// The triangles of the last attempt not yet in the block, in order of first appearance.
    new: Vec<u32>,
}

impl<'a> OpenBlock<'a> {
    fn new(mesh: &'a Mesh, vertices: &'a VertexTable) -> OpenBlock<'a> {
        OpenBlock {
            mesh,
            vertices,
            planned: PlannedTriangles::default(),
            vertex_count: 0,
            triangle_stamp: vec![0; mesh.triangles.len()],
            vertex_stamp: vec![0; mesh.positions.len()],
            stamp: 0,
            opened: 1,
            new: Vec::new(),
        }
    }

    /// The list, triangle and vertex counts of the block once `tris` is added; the new
    /// triangles and vertices get this attempt's stamp, which [`OpenBlock::commit`] keeps
    /// and [`OpenBlock::close`] forgets.
    fn try_add(&mut self, tris: &[u32]) -> (usize, usize, usize) {
        self.stamp += 1;
        let (stamp, opened) = (self.stamp, self.opened);
        self.new.clear();
        let mut new_vertices = 0;
        for &t in tris {
            let Some(s) = self.triangle_stamp.get_mut(t as usize) else {
                continue;
            };
            if *s >= opened {
                continue;
            }
            *s = stamp;
            self.new.push(t);
            for &v in self.mesh.triangles.get(t as usize).into_iter().flatten() {
                if let Some(s) = self
                    .vertex_stamp
                    .get_mut(self.vertices.distinct(v) as usize)
                {
                    if *s < opened {
                        *s = stamp;
                        new_vertices += 1;
                    }
                }
            }
        }
        (
            self.planned.list.len() + tris.len(),
            self.planned.triangles.len() + self.new.len(),
            self.vertex_count + new_vertices,
        )
    }

    /// Adds the leaf of the last [`OpenBlock::try_add`], whose counts were `(_, _, vertices)`.
    fn commit(&mut self, tris: &[u32], vertices: usize, ever_stored: &mut [bool]) {
        self.planned.list.extend_from_slice(tris);
        for &t in &self.new {
            let primary = ever_stored
                .get_mut(t as usize)
                .is_some_and(|s| !std::mem::replace(s, true));
            self.planned.triangles.push(t);
            self.planned.primary.push(primary);
        }
        self.vertex_count = vertices;
    }

    /// Ends the block: every stamp so far now means "elsewhere".
    fn close(&mut self) -> PlannedTriangles {
        if self.stamp > u32::MAX / 2 {
            // Blocks close long before a block's attempts could use up the other half.
            self.triangle_stamp.fill(0);
            self.vertex_stamp.fill(0);
            self.stamp = 0;
        }
        self.stamp += 1;
        self.opened = self.stamp + 1;
        self.vertex_count = 0;
        std::mem::take(&mut self.planned)
    }
}

/// Encodes one planned block: primaries first, vertices in order of first use.
pub(crate) fn encode_triangles(
    planned: &PlannedTriangles,
    mesh: &Mesh,
    vertices: &VertexTable,
    attrs: u16,
) -> Result<(Vec<u8>, TriangleCounts), LayoutError> {
    let order: Vec<(u32, bool)> = {
        let pairs = planned
            .triangles
            .iter()
            .copied()
            .zip(planned.primary.iter().copied());
        let (prim, copies): (Vec<_>, Vec<_>) = pairs.partition(|&(_, p)| p);
        prim.into_iter().chain(copies).collect()
    };
    let mut w = TriangleBlockWriter::new(attrs);
    let mut local_tri: HashMap<u32, u16> =
        HashMap::with_capacity_and_hasher(order.len(), Default::default());
    let mut local_vert: HashMap<VertexKey, u16> = HashMap::default();
    for &(t, _) in &order {
        let corners = mesh.triangles.get(t as usize).copied().unwrap_or_default();
        let mut v = [0u16; 3];
        for (slot, &mv) in v.iter_mut().zip(&corners) {
            let key = vertices.key(mv);
            *slot = match local_vert.get(&key) {
                Some(&i) => i,
                None => {
                    let i = w.push_vertex(key.vertex())?;
                    local_vert.insert(key, i);
                    i
                }
            };
        }
        let material = if attrs & ATTR_MATERIALS != 0 {
            Some(
                mesh.materials
                    .as_ref()
                    .and_then(|m| m.get(t as usize))
                    .copied()
                    .unwrap_or(0),
            )
        } else {
            None
        };
        // A copy carries its primary's id: both are the one mesh triangle.
        let part = (attrs & ATTR_PART_WIDTH != 0).then(|| parts::part_of(mesh, t as usize));
        local_tri.insert(t, w.push_triangle(Triangle { v, material, part })?);
    }
    for t in &planned.list {
        let local = local_tri.get(t).copied().ok_or(LayoutError::Internal(
            "a list entry names a triangle not in its block",
        ))?;
        w.push_list(local)?;
    }
    let primaries = order.iter().filter(|(_, p)| *p).count();
    w.set_primary_count(
        u16::try_from(primaries).map_err(|_| LayoutError::TooMany("primaries in a block"))?,
    );
    let counts = TriangleCounts {
        primaries: primaries as u64,
        triangles: order.len() as u64,
        vertices: local_vert.len() as u64,
    };
    Ok((w.finish(), counts))
}

#[cfg(test)]
mod tests {
    use std::collections::HashSet;

    use oocfmt::records::triangle::ATTR_NORMALS;

    use super::*;
    use crate::kdtree::{build, KdBuildOptions};
    use oocfmt_scenes::demo::demo_scene;

    /// The greedy packing written plainly, with sets of stored vertices: the blocks the
    /// stamped planner must reproduce.
    fn reference(mesh: &Mesh, tree: &KdTree, attrs: u16, block_size: usize) -> Vec<Vec<u32>> {
        let vertices = VertexTable::new(mesh);
        let mut blocks = Vec::new();
        let (mut list, mut tris, mut verts) = (Vec::new(), HashSet::new(), HashSet::new());
        for leaf in tree.leaves_depth_first() {
            let Some(KdNode::Leaf { triangles }) = tree.node(leaf) else {
                continue;
            };
            let size = |tris: &HashSet<u32>, verts: &HashSet<VertexKey>, list: usize| {
                let mut t2 = tris.clone();
                let mut v2 = verts.clone();
                for &t in triangles {
                    if t2.insert(t) {
                        for &v in &mesh.triangles[t as usize] {
                            v2.insert(vertices.key(v));
                        }
                    }
                }
                let n = (list + triangles.len(), t2.len(), v2.len());
                n.0 <= MAX_ITEMS
                    && n.1 <= MAX_ITEMS
                    && n.2 <= MAX_ITEMS
                    && TriangleBlockWriter::raw_len_for(attrs, n.0, n.1, n.2) <= block_size
            };
            if !size(&tris, &verts, list.len()) {
                blocks.push(std::mem::take(&mut list));
                tris.clear();
                verts.clear();
            }
            for &t in triangles {
                list.push(t);
                if tris.insert(t) {
                    for &v in &mesh.triangles[t as usize] {
                        verts.insert(vertices.key(v));
                    }
                }
            }
        }
        blocks.push(list);
        blocks
    }

    #[test]
    fn the_stamped_planner_packs_as_plain_sets_do() {
        // Every vertex twice, the copy's normal one unit in the last place off: different
        // mesh vertices that store the same bytes, which a block must count once.
        let base = demo_scene(4000);
        let n = base.positions.len() as u32;
        let mut mesh = Mesh::new(
            [base.positions.clone(), base.positions.clone()].concat(),
            base.triangles
                .iter()
                .enumerate()
                .map(|(i, t)| if i % 2 == 0 { *t } else { t.map(|v| v + n) })
                .collect(),
        );
        let normals: Vec<[f32; 3]> = base
            .positions
            .iter()
            .map(|p| {
                let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt().max(1e-3);
                p.map(|c| c / l)
            })
            .collect();
        let nudged = normals
            .iter()
            .map(|v| [f32::from_bits(v[0].to_bits() ^ 1), v[1], v[2]]);
        mesh.normals = Some(normals.iter().copied().chain(nudged).collect());
        let tree = match build(
            &mesh,
            &KdBuildOptions {
                max_leaf_triangles: 6,
                ..KdBuildOptions::default()
            },
        ) {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        };
        let vertices = VertexTable::new(&mesh);
        let shared = (0..2 * n).filter(|&v| vertices.distinct(v) != v).count();
        assert!(
            shared > n as usize / 2,
            "{shared} of {n} copies share their bytes"
        );
        let attrs = ATTR_NORMALS;
        for block_size in [2048, 8192, 65536] {
            let plan = match plan_triangles(&mesh, &tree, &vertices, attrs, block_size) {
                Ok(p) => p,
                Err(e) => panic!("{e}"),
            };
            let lists: Vec<Vec<u32>> = plan.blocks.iter().map(|b| b.list.clone()).collect();
            assert_eq!(
                lists,
                reference(&mesh, &tree, attrs, block_size),
                "{block_size}"
            );
            let mut primaries = 0;
            for b in &plan.blocks {
                let (raw, counts) = match encode_triangles(b, &mesh, &vertices, attrs) {
                    Ok(r) => r,
                    Err(e) => panic!("{e}"),
                };
                assert!(raw.len() <= block_size);
                let distinct: HashSet<VertexKey> = b
                    .triangles
                    .iter()
                    .flat_map(|&t| mesh.triangles[t as usize].map(|v| vertices.key(v)))
                    .collect();
                assert_eq!(counts.vertices as usize, distinct.len());
                primaries += counts.primaries;
            }
            assert_eq!(primaries as usize, mesh.triangles.len());
            if block_size == 2048 {
                assert!(plan.blocks.len() > 20);
            }
        }
    }
}
