//! Faces in part order: grouped by part in the order of the part table, each part's faces in
//! the order the blocks hold them, so a part is one run of faces (one `g` in an OBJ).
//!
//! The blocks hold a part's triangles wherever the kd-tree put them, so the order is made by
//! a counting sort over the part table's counts, with bounded memory: each pass over the
//! blocks keeps only the faces whose place in the final order falls in its window of
//! [`super::ExportOptions::faces_per_pass`] places. The counts are checked against the blocks
//! by the vertex pass that comes first ([`super::Container::walk`]).

use oocfmt::metadata::{Metadata, Part};
use oocfmt::records::triangle::Vertex;

use super::{Container, ExportError, Face, PrimarySink};

/// Where each part's faces start in the part order.
pub(super) struct PartOrder {
    starts: Vec<u64>,
    total: u64,
}

impl PartOrder {
    pub(super) fn new(meta: &Metadata) -> PartOrder {
        let mut starts = Vec::with_capacity(meta.parts.len());
        let mut total = 0u64;
        for p in &meta.parts {
            starts.push(total);
            total = total.saturating_add(p.triangles);
        }
        PartOrder { starts, total }
    }

    /// The passes needed with `per_pass` faces each (at least one).
    pub(super) fn passes(&self, per_pass: u64) -> u64 {
        self.total.div_ceil(per_pass.max(1)).max(1)
    }

    /// The place of the `rank`-th face of `part` in the order.
    fn place(&self, part: Option<u32>, rank: u64) -> Option<u64> {
        self.starts
            .get(part? as usize)
            .and_then(|s| s.checked_add(rank))
    }
}

/// One pass's window of the order.
struct Window<'a> {
    order: &'a PartOrder,
    start: u64,
    faces: Vec<Face>,
    filled: usize,
}

impl PrimarySink for Window<'_> {
    fn vertex(&mut self, _index: u64, _v: &Vertex) -> Result<(), ExportError> {
        Ok(())
    }

    fn triangle(&mut self, face: Face, rank: u64) -> Result<(), ExportError> {
        let slot = self
            .order
            .place(face.part, rank)
            .and_then(|p| p.checked_sub(self.start))
            .and_then(|i| usize::try_from(i).ok())
            .and_then(|i| self.faces.get_mut(i));
        if let Some(slot) = slot {
            *slot = face;
            self.filled += 1;
        }
        Ok(())
    }
}

/// Feeds `sink` every face of `c` in part order, one pass over the blocks per `per_pass`
/// faces (vertex calls are not repeated). `progress` as for [`Container::walk`], counting
/// every pass's blocks from `done_before`.
pub(super) fn walk_in_part_order(
    c: &Container,
    sink: &mut dyn PrimarySink,
    per_pass: u64,
    progress: &mut dyn FnMut(u64, u64),
    done_before: u64,
    total: u64,
) -> Result<(), ExportError> {
    let order = PartOrder::new(c.meta());
    // Bounded so that a window's length always fits a `usize` allocation request.
    let per_pass = per_pass.clamp(1, isize::MAX as u64 / std::mem::size_of::<Face>() as u64);
    let blocks = c.blocks.len() as u64;
    let mut start = 0u64;
    let mut done = done_before;
    while start < order.total {
        let len = (order.total - start).min(per_pass);
        let mut window = Window {
            order: &order,
            start,
            // The counts were checked against the blocks by the vertex pass, so this is no
            // more than the faces the file holds, and no more than `per_pass`.
            faces: vec![Face::default(); len as usize],
            filled: 0,
        };
        c.walk(&mut window, progress, done, total)?;
        done += blocks;
        if window.filled != window.faces.len() {
            return Err(ExportError::Changed { file: c.name() });
        }
        for face in window.faces {
            sink.triangle(face, 0)?;
        }
        start += len;
    }
    Ok(())
}

/// The names from the root down to `part`, joined by `/`, made fit for a `g` line (control
/// characters, `#` and `\`, which would start a comment or continue the line, become `_`):
/// how other readers show the part.
pub(super) fn path(parts: &[Part], part: u32) -> String {
    let mut names = Vec::new();
    let mut at = Some(part);
    // Parents come before children (checked at open); the bound guards the walk regardless.
    while let Some(p) = at.filter(|_| names.len() <= parts.len()) {
        let Some(def) = parts.get(p as usize) else {
            break;
        };
        names.push(def.name.as_str());
        at = def.parent;
    }
    names.reverse();
    names
        .join("/")
        .chars()
        .map(|c| {
            if c.is_control() || c == '#' || c == '\\' {
                '_'
            } else {
                c
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(name: &str, parent: Option<u32>, triangles: u64) -> Part {
        Part {
            name: name.into(),
            parent,
            triangles,
            ..Part::default()
        }
    }

    #[test]
    fn paths_join_the_names_from_the_root() {
        let parts = [
            part("plane", None, 0),
            part("wing #2", Some(0), 0),
            part("bolt\\", Some(1), 0),
        ];
        assert_eq!(path(&parts, 2), "plane/wing _2/bolt_");
        assert_eq!(path(&parts, 0), "plane");
        assert_eq!(path(&parts, 9), "");
    }

    #[test]
    fn the_order_places_each_part_after_the_ones_before_it() {
        let meta = Metadata {
            parts: vec![part("a", None, 3), part("b", None, 0), part("c", None, 2)],
            ..Metadata::default()
        };
        let order = PartOrder::new(&meta);
        assert_eq!(order.total, 5);
        assert_eq!(order.place(Some(0), 2), Some(2));
        assert_eq!(order.place(Some(2), 0), Some(3));
        assert_eq!(order.place(Some(3), 0), None);
        assert_eq!(order.place(None, 0), None);
        assert_eq!(
            (order.passes(2), order.passes(5), order.passes(0)),
            (3, 1, 5)
        );
    }
}
