//! Triangle blocks: leaves are packed in depth-first order so neighbours share blocks; each
//! leaf's list entries are contiguous, triangles and vertices are stored once per block, and
//! the first copy of a triangle anywhere in the file is its primary.

// Fx hashing: these maps take a lookup per triangle corner; SipHash cost 6 % of a convert.
use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};

use oocfmt::records::triangle::{oct_encode, TriangleBlockWriter, ATTR_MATERIALS, MAX_ITEMS};
use oocfmt::records::{Triangle, Vertex};

use super::LayoutError;
use crate::kdtree::{KdNode, KdTree};
use crate::mesh::Mesh;

/// Where a leaf's list entries live.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
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

/// The stored vertex of each mesh vertex.
pub(crate) struct VertexTable {
    keys: Vec<VertexKey>,
}

impl VertexTable {
    pub fn new(mesh: &Mesh) -> VertexTable {
        let keys = (0..mesh.positions.len())
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
        VertexTable { keys }
    }

    fn key(&self, v: u32) -> VertexKey {
        self.keys.get(v as usize).copied().unwrap_or(VertexKey {
            position: [0; 3],
            normal: None,
            colour: None,
        })
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
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct TriangleCounts {
    pub primaries: u64,
    pub triangles: u64,
    pub vertices: u64,
}

#[derive(Default)]
struct OpenBlock {
    planned: PlannedTriangles,
    stored: HashSet<u32>,
    vertices: HashSet<VertexKey>,
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
    let packer = Packer {
        mesh,
        vertices,
        attrs,
        block_size,
    };
    let mut plan = TrianglePlan {
        leaves: vec![None; tree.nodes().len()],
        blocks: Vec::new(),
    };
    ever_stored.resize(mesh.triangles.len(), false);
    let mut open = OpenBlock::default();
    for leaf in tree.leaves_depth_first() {
        let Some(KdNode::Leaf { triangles }) = tree.node(leaf) else {
            continue;
        };
        let count = u16::try_from(triangles.len())
            .map_err(|_| LayoutError::TooMany("triangles in a leaf"))?;
        if !packer.fits(&open, triangles) {
            if !open.planned.list.is_empty() {
                plan.blocks.push(std::mem::take(&mut open).planned);
            }
            if !packer.fits(&open, triangles) {
                let needed = packer.raw_len(&open, triangles);
                return Err(LayoutError::LeafTooLarge {
                    triangles: triangles.len(),
                    bytes: needed,
                    block_size,
                });
            }
        }
        let first = u16::try_from(open.planned.list.len())
            .map_err(|_| LayoutError::TooMany("list entries"))?;
        let block = u32::try_from(plan.blocks.len())
            .map_err(|_| LayoutError::TooMany("triangle blocks"))?;
        for &t in triangles {
            open.planned.list.push(t);
            if open.stored.insert(t) {
                let primary = ever_stored
                    .get_mut(t as usize)
                    .is_some_and(|s| !std::mem::replace(s, true));
                open.planned.triangles.push(t);
                open.planned.primary.push(primary);
                open.vertices.extend(packer.corner_keys(t));
            }
        }
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

struct Packer<'a> {
    mesh: &'a Mesh,
    vertices: &'a VertexTable,
    attrs: u16,
    block_size: usize,
}

impl Packer<'_> {
    fn corner_keys(&self, t: u32) -> impl Iterator<Item = VertexKey> + '_ {
        self.mesh
            .triangles
            .get(t as usize)
            .into_iter()
            .flatten()
            .map(|&v| self.vertices.key(v))
    }

    /// The list, triangle and vertex counts of `open` once `tris` is added.
    fn counts_with(&self, open: &OpenBlock, tris: &[u32]) -> (usize, usize, usize) {
        let mut new_tris = HashSet::default();
        let mut new_verts = HashSet::default();
        for &t in tris {
            if !open.stored.contains(&t) && new_tris.insert(t) {
                new_verts.extend(self.corner_keys(t).filter(|k| !open.vertices.contains(k)));
            }
        }
        (
            open.planned.list.len() + tris.len(),
            open.planned.triangles.len() + new_tris.len(),
            open.vertices.len() + new_verts.len(),
        )
    }

    fn raw_len(&self, open: &OpenBlock, tris: &[u32]) -> usize {
        let (l, t, w) = self.counts_with(open, tris);
        TriangleBlockWriter::raw_len_for(self.attrs, l, t, w)
    }

    fn fits(&self, open: &OpenBlock, tris: &[u32]) -> bool {
        let (l, t, w) = self.counts_with(open, tris);
        l <= MAX_ITEMS
            && t <= MAX_ITEMS
            && w <= MAX_ITEMS
            && TriangleBlockWriter::raw_len_for(self.attrs, l, t, w) <= self.block_size
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
        local_tri.insert(t, w.push_triangle(Triangle { v, material })?);
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
