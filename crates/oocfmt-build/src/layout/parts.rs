//! The part table (spec §9): per part, the primary triangles whose id it is and the exact box
//! of their corners, tallied over a mesh (in core) or chunk by chunk (out of core) and merged;
//! plus the part-id width code of the triangle blocks.

use std::collections::BTreeMap;

use oocfmt::metadata::Part;
use oocfmt::records::part_id_width;
use oocfmt::records::triangle::ATTR_PART_WIDTH_SHIFT;

use crate::lod::triangle_area;
use oocfmt_meshio::mesh::{Bounds, Mesh, PartDef};

/// What the primaries of one part add up to.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct PartStat {
    pub triangles: u64,
    /// The box of their corners, exact (min/max of stored coordinates).
    pub bounds: Bounds,
    /// Their area, for the part word of an out-of-core LOD node no ray hit.
    pub area: f64,
}

impl Default for PartStat {
    fn default() -> Self {
        PartStat {
            triangles: 0,
            bounds: Bounds::EMPTY,
            area: 0.0,
        }
    }
}

impl PartStat {
    fn add_triangle(&mut self, corners: [[f32; 3]; 3], area: f64) {
        self.triangles += 1;
        for p in corners {
            self.bounds.extend(p);
        }
        self.area += area;
    }

    fn merge(&mut self, o: &PartStat) {
        self.triangles += o.triangles;
        for p in [o.bounds.min, o.bounds.max]
            .into_iter()
            .filter(|_| o.triangles > 0)
        {
            self.bounds.extend(p);
        }
        self.area += o.area;
    }
}

/// The attribute bits of the scene's triangle blocks: `schema_attrs` with the part-id width
/// of a table of `parts` parts (none for at most one).
pub(crate) fn triangle_attributes(schema_attrs: u16, parts: usize) -> u16 {
    schema_attrs | part_id_width(parts) << ATTR_PART_WIDTH_SHIFT
}

/// The part of mesh triangle `t`: its id, or 0 in a mesh without ids (every triangle in the
/// one part, if any).
pub(crate) fn part_of(mesh: &Mesh, t: usize) -> u32 {
    mesh.part_ids
        .as_ref()
        .and_then(|ids| ids.get(t))
        .copied()
        .unwrap_or(0)
}

/// The stats of the parts the triangles `primary` names use, sparse and in part order:
/// what one chunk (or a whole in-core mesh) contributes.
pub(crate) fn tally(mesh: &Mesh, primary: impl Fn(usize) -> bool) -> Vec<(u32, PartStat)> {
    let mut by_part: BTreeMap<u32, PartStat> = BTreeMap::new();
    for t in (0..mesh.triangles.len()).filter(|&t| primary(t)) {
        if let Some(c) = mesh.corners(t) {
            by_part
                .entry(part_of(mesh, t))
                .or_default()
                .add_triangle(c, triangle_area(mesh, t));
        }
    }
    by_part.into_iter().collect()
}

/// Per part of the scene, the stats merged over every piece.
pub(crate) struct PartTotals {
    stats: Vec<PartStat>,
}

impl PartTotals {
    /// Totals for a table of `parts` parts, all empty. The table is already in memory with
    /// that many entries, so this allocates in proportion to it.
    pub fn new(parts: usize) -> PartTotals {
        PartTotals {
            stats: vec![PartStat::default(); parts],
        }
    }

    /// Adds one piece's sparse stats ([`tally`]); ids past the table are ignored (the mesh
    /// was validated against it).
    pub fn add(&mut self, piece: &[(u32, PartStat)]) {
        for (p, s) in piece {
            if let Some(slot) = self.stats.get_mut(*p as usize) {
                slot.merge(s);
            }
        }
    }

    /// The metadata's part table: each declared part with its counts and bounds (zeros
    /// without triangles).
    pub fn table(&self, defs: &[PartDef]) -> Vec<Part> {
        defs.iter()
            .zip(&self.stats)
            .map(|(d, s)| {
                let (bounds_min, bounds_max) = if s.triangles > 0 {
                    (s.bounds.min, s.bounds.max)
                } else {
                    ([0.0; 3], [0.0; 3])
                };
                Part {
                    name: d.name.clone(),
                    parent: d.parent,
                    source: d.source,
                    triangles: s.triangles,
                    bounds_min,
                    bounds_max,
                }
            })
            .collect()
    }
}

/// The part with the largest summed area among `pieces` (ties: the lowest id), 0 for none:
/// the part word of an out-of-core LOD node that no ray hit.
pub(crate) fn largest_by_area<'a>(pieces: impl Iterator<Item = &'a [(u32, PartStat)]>) -> u32 {
    let mut area: BTreeMap<u32, f64> = BTreeMap::new();
    for piece in pieces {
        for (p, s) in piece {
            *area.entry(*p).or_insert(0.0) += s.area;
        }
    }
    let mut best: Option<(u32, f64)> = None;
    for (p, a) in area {
        if best.is_none_or(|(_, b)| a > b) {
            best = Some((p, a));
        }
    }
    best.map_or(0, |(p, _)| p)
}
