//! The part tree as the page's model tree reads it: children of a part (or the top level), a
//! page at a time, and the ancestors of a picked part, so the page can open the tree down to
//! it. Built once per server from the file's part table (parents come before their children
//! there, so one pass finds every child list).

use serde::Serialize;

use oocfmt::metadata::Part;

/// The most children one answer lists; the page asks for the next ones by offset.
pub const MAX_CHILDREN: usize = 200;

/// One part as a tree row shows it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PartItem {
    /// Its id (index in the part table).
    pub id: u32,
    /// Its name.
    pub name: String,
    /// How many parts have it as their parent.
    pub children: u32,
    /// Its own triangles.
    pub triangles: u64,
}

/// The file's part tree, indexed by parent.
#[derive(Debug, Default)]
pub struct PartIndex {
    items: Vec<PartItem>,
    parents: Vec<Option<u32>>,
    top: Vec<u32>,
    children: Vec<Vec<u32>>,
}

impl PartIndex {
    /// The index of part table `parts` (a parent that is not below its child, which the
    /// reader refuses, would make the part top-level here).
    pub fn new(parts: &[Part]) -> PartIndex {
        let mut children = vec![Vec::new(); parts.len()];
        let mut top = Vec::new();
        let mut parents = Vec::with_capacity(parts.len());
        for (i, p) in parts.iter().enumerate() {
            let id = i as u32;
            let parent = p.parent.filter(|&q| (q as usize) < i);
            match parent.and_then(|q| children.get_mut(q as usize)) {
                Some(list) => list.push(id),
                None => top.push(id),
            }
            parents.push(parent);
        }
        let items = parts
            .iter()
            .enumerate()
            .map(|(i, p)| PartItem {
                id: i as u32,
                name: p.name.clone(),
                children: children.get(i).map_or(0, |c| c.len() as u32),
                triangles: p.triangles,
            })
            .collect();
        PartIndex {
            items,
            parents,
            top,
            children,
        }
    }

    /// How many parts the tree holds.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Whether the file has no parts.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// The children of `parent` (None: the top-level parts) from `offset`, at most
    /// [`MAX_CHILDREN`], and how many there are in all; an error for an id past the table.
    pub fn children(
        &self,
        parent: Option<u32>,
        offset: usize,
    ) -> Result<(usize, Vec<PartItem>), String> {
        let list = match parent {
            None => &self.top,
            Some(p) => self.children.get(p as usize).ok_or_else(|| {
                format!(
                    "part {p}: the file has {} parts (ids 0 to {} - 1)",
                    self.len(),
                    self.len()
                )
            })?,
        };
        let page = list
            .iter()
            .skip(offset)
            .take(MAX_CHILDREN)
            .filter_map(|&id| self.items.get(id as usize).cloned())
            .collect();
        Ok((list.len(), page))
    }

    /// The ids from `part`'s top-level ancestor down to `part` itself; empty for an id past
    /// the table. Each step goes to a lower id, so this ends.
    pub fn lineage(&self, part: u32) -> Vec<u32> {
        let mut out = Vec::new();
        let mut at = Some(part).filter(|&p| (p as usize) < self.len());
        while let Some(p) = at {
            out.push(p);
            at = self.parents.get(p as usize).copied().flatten();
        }
        out.reverse();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(name: &str, parent: Option<u32>) -> Part {
        Part {
            name: name.into(),
            parent,
            source: None,
            triangles: 1,
            bounds_min: [0.0; 3],
            bounds_max: [1.0; 3],
        }
    }

    #[test]
    fn children_page_by_offset_and_lineage_climbs_to_the_top() -> Result<(), String> {
        let mut parts = vec![part("a", None), part("b", None)];
        for k in 0..(MAX_CHILDREN + 5) {
            parts.push(part(&format!("a{k}"), Some(0)));
        }
        parts.push(part("deep", Some(2)));
        let t = PartIndex::new(&parts);
        let (n, top) = t.children(None, 0)?;
        assert_eq!((n, top.len()), (2, 2));
        assert_eq!(top[0].children as usize, MAX_CHILDREN + 5);
        let (n, first) = t.children(Some(0), 0)?;
        assert_eq!((n, first.len()), (MAX_CHILDREN + 5, MAX_CHILDREN));
        let (_, rest) = t.children(Some(0), MAX_CHILDREN)?;
        assert_eq!(rest.len(), 5);
        assert_eq!(t.children(Some(1), 0)?.0, 0);
        let last = parts.len() as u32 - 1;
        assert_eq!(t.lineage(last), vec![0, 2, last]);
        assert!(t.lineage(last + 1).is_empty());
        assert!(t.children(Some(last + 1), 0).is_err());
        Ok(())
    }
}
