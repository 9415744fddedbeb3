//! Which parts a frame shows (`--hide`, `--isolate`, `--highlight`): globs over the part
//! table's names and paths, resolved once per selection into a state per part, which the
//! traversal and the shading then look up by part id.
//!
//! A glob without `/` is matched against part names; one with `/` against paths, the names
//! from a top-level part down joined with `/` (`assembly-3/bolt-17`). `*` matches any run of
//! characters but `/`, `**` any run, `?` one character, `[abc]` one of a set (the `glob`
//! crate's patterns; `[*]` matches a literal `*`). Matching a part matches its descendants.
//! Isolating hides every part outside the isolated subtrees; hiding wins over isolating and
//! highlighting; a highlighted part is drawn with its albedo [`HIGHLIGHT_MIX`] of the way
//! towards [`HIGHLIGHT`] (orange), at full detail by the triangle's part and at a LOD entry by
//! its part word.
//!
//! A filter that hides a part also holds a [`VisibilityGrid`] of the parts it leaves visible
//! (by the part table's bounds), with which the traversal skips whole subtrees that could show
//! only hidden parts.

mod grid;

pub use grid::{segment_box, Cover, VisibilityGrid, MAX_CELLS};

use std::sync::atomic::{AtomicU64, Ordering};

use glob::{MatchOptions, Pattern};
use oocfmt::metadata::Part;
use serde::Serialize;

/// The colour a highlighted part is tinted towards, linear RGB: orange.
pub const HIGHLIGHT: [f32; 3] = [1.0, 0.35, 0.0];
/// How far a highlighted part's albedo moves towards [`HIGHLIGHT`]: half way.
pub const HIGHLIGHT_MIX: f32 = 0.5;

/// At most this many bytes of part paths are built to match globs with `/` against: a deep
/// chain of parts would otherwise need the square of its length.
pub const MAX_PATH_BYTES: usize = 1 << 28;

/// How many close names a glob that matches nothing suggests.
const SUGGESTIONS: usize = 5;
/// The part names looked at for suggestions (the first this many distinct ones).
const SUGGESTION_POOL: usize = 200_000;

/// What a frame does with one part.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[repr(u8)]
pub enum PartState {
    /// Drawn as it is.
    Visible,
    /// Not drawn, not picked, casting no shadow: as if the file did not hold it.
    Hidden,
    /// Drawn tinted towards [`HIGHLIGHT`].
    Highlighted,
}

/// The globs of a part selection, as given on the command line (each list may repeat a flag).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PartSelection {
    /// Parts to hide, with their descendants.
    pub hide: Vec<String>,
    /// Parts to keep, with their descendants; every other part is hidden.
    pub isolate: Vec<String>,
    /// Parts to tint, with their descendants.
    pub highlight: Vec<String>,
}

impl PartSelection {
    /// No glob at all: every part drawn as it is.
    pub fn is_empty(&self) -> bool {
        self.hide.is_empty() && self.isolate.is_empty() && self.highlight.is_empty()
    }
}

/// Why a part selection cannot be resolved against a file's part table.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PartError {
    /// The file's part table is empty.
    #[error("{flag} {glob}: the file has no parts (its input named none); `oocfmt inspect --parts` lists a file's parts")]
    NoParts {
        /// The flag the glob came with (`--hide`, `--isolate`, `--highlight`).
        flag: &'static str,
        /// The glob as given.
        glob: String,
    },
    /// The glob is malformed (an unclosed `[`, say).
    #[error("{flag} {glob}: not a glob: {message}")]
    Pattern {
        /// The flag the glob came with.
        flag: &'static str,
        /// The glob as given.
        glob: String,
        /// What the pattern parser said.
        message: String,
    },
    /// The glob matches no part's name (or, with `/`, no part's path).
    #[error(
        "{flag} {glob}: matches none of the file's {parts} part {what}{}",
        suggest(close)
    )]
    NoMatch {
        /// The flag the glob came with.
        flag: &'static str,
        /// The glob as given.
        glob: String,
        /// How many parts the file has.
        parts: usize,
        /// `names` or `paths`: what the glob was matched against.
        what: &'static str,
        /// The names (or paths) nearest the glob's text, nearest first.
        close: Vec<String>,
    },
    /// A part id given to [`PartFilter::from_ids`] is past the part table.
    #[error("part id {id}: the file has {parts} parts (ids 0 to {parts} - 1)")]
    IdOutOfRange {
        /// The id given.
        id: u32,
        /// How many parts the file has.
        parts: usize,
    },
    /// The part tree is too deep to build every path of.
    #[error("{flag} {glob}: the part paths would take over {limit} bytes; match names instead (a glob without `/`)")]
    PathsTooLong {
        /// The flag the glob came with.
        flag: &'static str,
        /// The glob as given.
        glob: String,
        /// [`MAX_PATH_BYTES`].
        limit: usize,
    },
}

fn suggest(close: &[String]) -> String {
    if close.is_empty() {
        "; `oocfmt inspect --parts` lists them".into()
    } else {
        format!("; close: {}", close.join(", "))
    }
}

/// Gives every filter its own id, so a memo can tell a block's summary for one filter from
/// another's.
static NEXT_ID: AtomicU64 = AtomicU64::new(1);

/// A part selection resolved against one file's part table: a state per part id. Looked up
/// once per triangle of a leaf (hidden parts) and once per shaded hit (highlighted ones).
#[derive(Debug, PartialEq, Eq)]
pub struct PartFilter {
    id: u64,
    states: Vec<PartState>,
    hidden: usize,
    highlighted: usize,
    /// The cells near a visible part's own triangles, when some part is hidden.
    grid: Option<VisibilityGrid>,
}

impl Default for PartFilter {
    fn default() -> Self {
        PartFilter::none()
    }
}

/// What a filter makes of a decoded triangle block's parts ([`PartFilter::block_mask`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlockMask {
    /// No triangle of the block is hidden: its leaves are tested as without a filter.
    NoneHidden,
    /// Every triangle is hidden: its leaves test nothing.
    AllHidden,
    /// Some are: each leaf's triangles are looked up, the hidden ones dropped before testing.
    Mixed,
}

impl PartFilter {
    /// Every part drawn as it is (what a file without parts always gets).
    pub const fn none() -> PartFilter {
        PartFilter {
            id: 0,
            states: Vec::new(),
            hidden: 0,
            highlighted: 0,
            grid: None,
        }
    }

    /// Resolves `sel` against the part table `parts`: each glob must match at least one part
    /// (a glob on a file without parts, or one that matches nothing, is an error naming the
    /// glob and the closest names).
    pub fn new(parts: &[Part], sel: &PartSelection) -> Result<PartFilter, PartError> {
        if sel.is_empty() {
            return Ok(PartFilter::none());
        }
        let mut paths = None;
        let mut resolve = |flag, globs: &[String]| -> Result<Option<Vec<bool>>, PartError> {
            if globs.is_empty() {
                return Ok(None);
            }
            let mut all = vec![false; parts.len()];
            for g in globs {
                let m = matches(parts, flag, g, &mut paths)?;
                for (a, b) in all.iter_mut().zip(m) {
                    *a |= b;
                }
            }
            with_descendants(parts, &mut all);
            Ok(Some(all))
        };
        let hide = resolve("--hide", &sel.hide)?;
        let isolate = resolve("--isolate", &sel.isolate)?;
        let highlight = resolve("--highlight", &sel.highlight)?;
        Ok(PartFilter::from_marks(parts, hide, isolate, highlight))
    }

    /// The filter of part ids (a viewer's model tree, which names parts by id, not by glob):
    /// `hide` hides those parts, `isolate` (when not empty) hides every part outside it, and
    /// `highlight` tints, each with every descendant, as [`PartFilter::new`] does for globs.
    /// An id past the table is an error; nothing given makes [`PartFilter::none`].
    pub fn from_ids(
        parts: &[Part],
        hide: &[u32],
        isolate: &[u32],
        highlight: &[u32],
    ) -> Result<PartFilter, PartError> {
        if hide.is_empty() && isolate.is_empty() && highlight.is_empty() {
            return Ok(PartFilter::none());
        }
        let marks = |ids: &[u32]| -> Result<Option<Vec<bool>>, PartError> {
            if ids.is_empty() {
                return Ok(None);
            }
            let mut all = vec![false; parts.len()];
            for &id in ids {
                let at = all.get_mut(id as usize).ok_or(PartError::IdOutOfRange {
                    id,
                    parts: parts.len(),
                })?;
                *at = true;
            }
            with_descendants(parts, &mut all);
            Ok(Some(all))
        };
        let (hide, isolate, highlight) = (marks(hide)?, marks(isolate)?, marks(highlight)?);
        Ok(PartFilter::from_marks(parts, hide, isolate, highlight))
    }

    /// The filter of per-part marks (`None`: that selection is empty): hidden where hidden or
    /// outside a non-empty isolation, else highlighted where marked, else visible.
    fn from_marks(
        parts: &[Part],
        hide: Option<Vec<bool>>,
        isolate: Option<Vec<bool>>,
        highlight: Option<Vec<bool>>,
    ) -> PartFilter {
        let at = |v: &Option<Vec<bool>>, i: usize| v.as_ref().and_then(|v| v.get(i).copied());
        let states: Vec<PartState> = (0..parts.len())
            .map(|i| {
                if at(&hide, i).unwrap_or(false) || !at(&isolate, i).unwrap_or(true) {
                    PartState::Hidden
                } else if at(&highlight, i).unwrap_or(false) {
                    PartState::Highlighted
                } else {
                    PartState::Visible
                }
            })
            .collect();
        let count = |s| states.iter().filter(|&&x| x == s).count();
        let hidden = count(PartState::Hidden);
        PartFilter {
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            hidden,
            highlighted: count(PartState::Highlighted),
            grid: (hidden > 0).then(|| visible_grid(parts, &states)).flatten(),
            states,
        }
    }

    /// The grid of the visible parts' boxes, when some part is hidden (None also when a
    /// visible part's bounds are not finite: then nothing is skipped).
    pub fn grid(&self) -> Option<&VisibilityGrid> {
        self.grid.as_ref()
    }

    /// Identifies this filter among every filter made in the process (0: [`PartFilter::none`]).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Whether the filter changes nothing: no part hidden or highlighted.
    pub fn is_empty(&self) -> bool {
        self.hidden == 0 && self.highlighted == 0
    }

    /// How many parts are hidden.
    pub fn hidden(&self) -> usize {
        self.hidden
    }

    /// How many parts are highlighted.
    pub fn highlighted(&self) -> usize {
        self.highlighted
    }

    /// How many parts the filter was made for (0 for [`PartFilter::none`]).
    pub fn parts(&self) -> usize {
        self.states.len()
    }

    /// The state of part `part`; a part past the table is visible.
    #[inline]
    pub fn state(&self, part: u32) -> PartState {
        self.states
            .get(part as usize)
            .copied()
            .unwrap_or(PartState::Visible)
    }

    /// Whether part `part` is hidden.
    #[inline(always)]
    pub fn is_hidden(&self, part: u32) -> bool {
        matches!(self.states.get(part as usize), Some(PartState::Hidden))
    }

    /// Whether a surface of part `part` (None: of no part) is hidden.
    #[inline(always)]
    pub fn hides(&self, part: Option<u32>) -> bool {
        part.is_some_and(|p| self.is_hidden(p))
    }

    /// Whether a surface of part `part` (None: of no part) is highlighted.
    #[inline]
    pub fn highlights(&self, part: Option<u32>) -> bool {
        part.is_some_and(|p| self.state(p) == PartState::Highlighted)
    }

    /// What the filter makes of a block whose triangles are of the parts `present`.
    pub fn block_mask(&self, present: &[u32]) -> BlockMask {
        let hidden = present.iter().filter(|&&p| self.is_hidden(p)).count();
        if hidden == 0 {
            BlockMask::NoneHidden
        } else if hidden == present.len() {
            BlockMask::AllHidden
        } else {
            BlockMask::Mixed
        }
    }
}

/// The [`VisibilityGrid`] of the boxes of the parts of `parts` that `states` does not hide and
/// that have triangles of their own (the bounds are of a part's own triangles; a triangle's
/// part is its own, never an ancestor's).
fn visible_grid(parts: &[Part], states: &[PartState]) -> Option<VisibilityGrid> {
    let boxes: Vec<([f32; 3], [f32; 3])> = parts
        .iter()
        .zip(states)
        .filter(|(p, &s)| s != PartState::Hidden && p.triangles > 0)
        .map(|(p, _)| (p.bounds_min, p.bounds_max))
        .collect();
    VisibilityGrid::new(&boxes)
}

/// `albedo` tinted the way a highlighted part shows: [`HIGHLIGHT_MIX`] towards [`HIGHLIGHT`].
pub fn tint(albedo: [f32; 3]) -> [f32; 3] {
    [0, 1, 2].map(|k| albedo[k] + HIGHLIGHT_MIX * (HIGHLIGHT[k] - albedo[k]))
}

/// Marks the descendants of every marked part: parents come first in the table, so one pass
/// in index order reaches every depth.
fn with_descendants(parts: &[Part], marked: &mut [bool]) {
    for i in 0..parts.len().min(marked.len()) {
        let parent = parts
            .get(i)
            .and_then(|p| p.parent)
            .and_then(|p| marked.get(p as usize).copied());
        if parent == Some(true) {
            if let Some(m) = marked.get_mut(i) {
                *m = true;
            }
        }
    }
}

/// Which parts glob `g` of `flag` matches: by name, or by path when it holds a `/` (the paths
/// built once into `paths` and kept for the next glob).
fn matches(
    parts: &[Part],
    flag: &'static str,
    g: &str,
    paths: &mut Option<Vec<String>>,
) -> Result<Vec<bool>, PartError> {
    if parts.is_empty() {
        return Err(PartError::NoParts {
            flag,
            glob: g.into(),
        });
    }
    let pattern = Pattern::new(g).map_err(|e| PartError::Pattern {
        flag,
        glob: g.into(),
        message: e.to_string(),
    })?;
    let opts = MatchOptions {
        case_sensitive: true,
        require_literal_separator: true,
        require_literal_leading_dot: false,
    };
    let by_path = g.contains('/');
    let m: Vec<bool> = if by_path {
        if paths.is_none() {
            *paths = Some(all_paths(parts).ok_or_else(|| PartError::PathsTooLong {
                flag,
                glob: g.into(),
                limit: MAX_PATH_BYTES,
            })?);
        }
        let p = paths.as_deref().unwrap_or(&[]);
        p.iter().map(|s| pattern.matches_with(s, opts)).collect()
    } else {
        parts
            .iter()
            .map(|p| pattern.matches_with(&p.name, opts))
            .collect()
    };
    if !m.iter().any(|&x| x) {
        let names: Box<dyn Iterator<Item = &str>> = match paths.as_deref() {
            Some(p) if by_path => Box::new(p.iter().map(String::as_str)),
            _ => Box::new(parts.iter().map(|p| p.name.as_str())),
        };
        return Err(PartError::NoMatch {
            flag,
            glob: g.into(),
            parts: parts.len(),
            what: if by_path { "paths" } else { "names" },
            close: closest(g, names),
        });
    }
    Ok(m)
}

/// Every part's path, or None past [`MAX_PATH_BYTES`] in all.
fn all_paths(parts: &[Part]) -> Option<Vec<String>> {
    let mut out: Vec<String> = Vec::with_capacity(parts.len());
    let mut total = 0usize;
    for (i, p) in parts.iter().enumerate() {
        let parent = p
            .parent
            .filter(|&q| (q as usize) < i)
            .and_then(|q| out.get(q as usize));
        let path = match parent {
            Some(pp) => format!("{pp}/{}", p.name),
            None => p.name.clone(),
        };
        total = total.checked_add(path.len())?;
        if total > MAX_PATH_BYTES {
            return None;
        }
        out.push(path);
    }
    Some(out)
}

/// Part `part`'s path: the names from its top-level ancestor down, joined with `/`; None past
/// the table.
pub fn part_path(parts: &[Part], part: u32) -> Option<String> {
    let mut names = Vec::new();
    let mut at = Some(part);
    while let Some(i) = at {
        let p = parts.get(i as usize)?;
        names.push(p.name.as_str());
        // Parents come first (checked at open): the walk ends.
        at = p.parent.filter(|&q| q < i);
    }
    names.reverse();
    Some(names.join("/"))
}

/// One part as `oocfmt inspect --parts` shows it: the table's fields, where it sits in the
/// tree, and its subtree's totals (the table counts a part's own triangles only).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PartNode {
    /// Its index in the part table: the id triangles and LOD entries carry.
    pub id: u32,
    /// Its name.
    pub name: String,
    /// Its path ([`part_path`]); None when the tree is too deep to spell every path
    /// ([`MAX_PATH_BYTES`]).
    pub path: Option<String>,
    /// Its parent's id; None for a top-level part.
    pub parent: Option<u32>,
    /// The index of its input file among the provenance's sources, when known.
    pub source: Option<u32>,
    /// 0 for a top-level part, its parent's + 1 below.
    pub depth: u32,
    /// How many parts have it as their parent.
    pub children: u32,
    /// Its own triangles (not its descendants').
    pub triangles: u64,
    /// Its own triangles' bounds, stored coordinates; zeros without triangles.
    pub bounds_min: [f32; 3],
    /// Like `bounds_min`.
    pub bounds_max: [f32; 3],
    /// Its and its descendants' triangles.
    pub subtree_triangles: u64,
    /// Their bounds, stored coordinates; zeros without triangles.
    pub subtree_bounds_min: [f32; 3],
    /// Like `subtree_bounds_min`.
    pub subtree_bounds_max: [f32; 3],
}

/// Every part of the table as a [`PartNode`], in id order (parents first).
pub fn part_tree(parts: &[Part]) -> Vec<PartNode> {
    let paths = all_paths(parts);
    let mut nodes: Vec<PartNode> = Vec::with_capacity(parts.len());
    for (i, p) in parts.iter().enumerate() {
        let parent = p.parent.filter(|&q| (q as usize) < i);
        let depth = parent
            .and_then(|q| nodes.get(q as usize))
            .map_or(0, |n| n.depth + 1);
        nodes.push(PartNode {
            id: i as u32,
            name: p.name.clone(),
            path: paths.as_ref().and_then(|v| v.get(i).cloned()),
            parent,
            source: p.source,
            depth,
            children: 0,
            triangles: p.triangles,
            bounds_min: p.bounds_min,
            bounds_max: p.bounds_max,
            subtree_triangles: p.triangles,
            subtree_bounds_min: p.bounds_min,
            subtree_bounds_max: p.bounds_max,
        });
    }
    // Children come after their parents: adding each part into its parent from the last
    // one up gives every subtree's totals.
    for i in (0..nodes.len()).rev() {
        let Some((&q, child)) = nodes
            .get(i)
            .and_then(|n| n.parent.as_ref().map(|q| (q, n.clone())))
        else {
            continue;
        };
        if let Some(up) = nodes.get_mut(q as usize) {
            up.children += 1;
            if child.subtree_triangles > 0 {
                if up.subtree_triangles == 0 {
                    up.subtree_bounds_min = child.subtree_bounds_min;
                    up.subtree_bounds_max = child.subtree_bounds_max;
                } else {
                    for k in 0..3 {
                        up.subtree_bounds_min[k] =
                            up.subtree_bounds_min[k].min(child.subtree_bounds_min[k]);
                        up.subtree_bounds_max[k] =
                            up.subtree_bounds_max[k].max(child.subtree_bounds_max[k]);
                    }
                }
                up.subtree_triangles += child.subtree_triangles;
            }
        }
    }
    nodes
}

/// The part ids in depth-first order, each part followed by its subtree, siblings by id: the
/// order a tree is printed in.
pub fn preorder(parts: &[Part]) -> Vec<u32> {
    let n = parts.len();
    // Children by parent, as one array with an offset per part (no list per part).
    let parent_of = |i: usize| {
        parts
            .get(i)
            .and_then(|p| p.parent)
            .filter(|&q| (q as usize) < i)
    };
    let mut start = vec![0usize; n + 1];
    for i in 0..n {
        if let Some(s) = parent_of(i).and_then(|q| start.get_mut(q as usize + 1)) {
            *s += 1;
        }
    }
    for i in 0..n {
        let before = start.get(i).copied().unwrap_or(0);
        if let Some(s) = start.get_mut(i + 1) {
            *s += before;
        }
    }
    let mut fill = start.clone();
    let mut kids = vec![0u32; start.get(n).copied().unwrap_or(0)];
    for i in 0..n {
        if let Some(q) = parent_of(i) {
            if let Some(at) = fill.get_mut(q as usize) {
                if let Some(k) = kids.get_mut(*at) {
                    *k = i as u32;
                }
                *at += 1;
            }
        }
    }
    let mut out = Vec::with_capacity(n);
    let mut stack: Vec<u32> = (0..n)
        .rev()
        .filter(|&i| parent_of(i).is_none())
        .map(|i| i as u32)
        .collect();
    while let Some(i) = stack.pop() {
        out.push(i);
        let (a, b) = (
            start.get(i as usize).copied().unwrap_or(0),
            start.get(i as usize + 1).copied().unwrap_or(0),
        );
        if let Some(k) = kids.get(a..b) {
            stack.extend(k.iter().rev());
        }
    }
    out
}

/// Up to [`SUGGESTIONS`] of `names` nearest `glob`'s literal text, by edit distance, among
/// the first [`SUGGESTION_POOL`] distinct ones; only those within a third of the text's length
/// (at least 3 edits).
fn closest<'a>(glob: &str, names: impl Iterator<Item = &'a str>) -> Vec<String> {
    let text: Vec<char> = glob
        .chars()
        .filter(|c| !matches!(c, '*' | '?' | '[' | ']'))
        .flat_map(char::to_lowercase)
        .collect();
    let limit = (text.len() / 3).max(3);
    let mut seen = std::collections::HashSet::new();
    let mut scored: Vec<(usize, &str)> = names
        .filter(|n| seen.insert(*n))
        .take(SUGGESTION_POOL)
        .filter_map(|n| {
            let lower: Vec<char> = n.chars().flat_map(char::to_lowercase).collect();
            let d = edit_distance(&text, &lower, limit)?;
            Some((d, n))
        })
        .collect();
    scored.sort();
    scored
        .into_iter()
        .take(SUGGESTIONS)
        .map(|(_, n)| n.to_string())
        .collect()
}

/// The Levenshtein distance of `a` and `b`, or None when it is over `limit`.
fn edit_distance(a: &[char], b: &[char], limit: usize) -> Option<usize> {
    if a.len().abs_diff(b.len()) > limit {
        return None;
    }
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.iter().enumerate() {
        let mut prev = row.first().copied().unwrap_or(0);
        if let Some(r) = row.first_mut() {
            *r = i + 1;
        }
        let mut best = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let up = row.get(j + 1).copied().unwrap_or(usize::MAX);
            let left = row.get(j).copied().unwrap_or(usize::MAX);
            let d = (prev + usize::from(ca != cb))
                .min(up.saturating_add(1))
                .min(left.saturating_add(1));
            prev = up;
            if let Some(r) = row.get_mut(j + 1) {
                *r = d;
            }
            best = best.min(d);
        }
        if best > limit {
            return None;
        }
    }
    row.last().copied().filter(|&d| d <= limit)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(name: &str, parent: Option<u32>) -> Part {
        Part {
            name: name.into(),
            parent,
            ..Part::default()
        }
    }

    /// assembly-1 { bolt-1, plate-1 }, assembly-2 { bolt-2 { washer } }, loose.
    fn tree() -> Vec<Part> {
        vec![
            part("assembly-1", None),
            part("bolt-1", Some(0)),
            part("plate-1", Some(0)),
            part("assembly-2", None),
            part("bolt-2", Some(3)),
            part("washer", Some(4)),
            part("loose", None),
        ]
    }

    fn states(sel: PartSelection) -> Result<Vec<PartState>, PartError> {
        let parts = tree();
        let f = PartFilter::new(&parts, &sel)?;
        Ok((0..parts.len() as u32).map(|i| f.state(i)).collect())
    }

    use PartState::{Hidden as H, Highlighted as L, Visible as V};

    #[test]
    fn a_name_glob_hides_the_parts_it_names_and_their_descendants() -> Result<(), PartError> {
        let s = states(PartSelection {
            hide: vec!["bolt-?".into()],
            ..PartSelection::default()
        })?;
        assert_eq!(s, [V, H, V, V, H, H, V]);
        let s = states(PartSelection {
            hide: vec!["assembly-1".into(), "loose".into()],
            ..PartSelection::default()
        })?;
        assert_eq!(s, [H, H, H, V, V, V, H]);
        Ok(())
    }

    #[test]
    fn a_path_glob_matches_paths_and_its_star_stops_at_a_slash() -> Result<(), PartError> {
        let s = states(PartSelection {
            hide: vec!["assembly-2/*".into()],
            ..PartSelection::default()
        })?;
        assert_eq!(s, [V, V, V, V, H, H, V]);
        // `*` does not cross `/`: no depth-3 path is `*/washer`.
        let e = states(PartSelection {
            hide: vec!["*/washer".into()],
            ..PartSelection::default()
        });
        assert!(
            matches!(e, Err(PartError::NoMatch { what: "paths", .. })),
            "{e:?}"
        );
        let s = states(PartSelection {
            hide: vec!["**/washer".into()],
            ..PartSelection::default()
        })?;
        assert_eq!(s, [V, V, V, V, V, H, V]);
        Ok(())
    }

    #[test]
    fn isolate_hides_the_rest_and_highlight_tints_only_what_is_shown() -> Result<(), PartError> {
        let s = states(PartSelection {
            isolate: vec!["assembly-2".into()],
            highlight: vec!["bolt-*".into()],
            ..PartSelection::default()
        })?;
        assert_eq!(s, [H, H, H, V, L, L, H]);
        let s = states(PartSelection {
            isolate: vec!["assembly-2".into()],
            hide: vec!["washer".into()],
            ..PartSelection::default()
        })?;
        assert_eq!(s, [H, H, H, V, V, H, H]);
        Ok(())
    }

    #[test]
    fn ids_hide_isolate_and_highlight_with_descendants_like_globs() -> Result<(), PartError> {
        let t = tree();
        for (name, ids) in [("hide", 0usize), ("isolate", 1), ("highlight", 2)] {
            // Each id form against the glob form of the same parts.
            for id in 0..t.len() as u32 {
                let mut lists: [Vec<u32>; 3] = Default::default();
                lists[ids] = vec![id];
                let by_id = PartFilter::from_ids(&t, &lists[0], &lists[1], &lists[2])?;
                let glob = part_path(&t, id).unwrap_or_default();
                let mut sel = PartSelection::default();
                match name {
                    "hide" => sel.hide = vec![glob],
                    "isolate" => sel.isolate = vec![glob],
                    _ => sel.highlight = vec![glob],
                }
                let by_glob = PartFilter::new(&t, &sel)?;
                let states =
                    |f: &PartFilter| (0..t.len() as u32).map(|p| f.state(p)).collect::<Vec<_>>();
                assert_eq!(states(&by_id), states(&by_glob), "{name} {id}");
            }
        }
        assert!(PartFilter::from_ids(&t, &[], &[], &[])?.is_empty());
        let e = PartFilter::from_ids(&t, &[t.len() as u32], &[], &[]);
        assert_eq!(
            e,
            Err(PartError::IdOutOfRange {
                id: t.len() as u32,
                parts: t.len()
            })
        );
        Ok(())
    }

    #[test]
    fn globs_that_match_nothing_or_files_without_parts_are_errors() {
        let sel = PartSelection {
            hide: vec!["Bolt-1".into()],
            ..PartSelection::default()
        };
        match PartFilter::new(&tree(), &sel) {
            Err(PartError::NoMatch { parts, close, .. }) => {
                assert_eq!(parts, 7);
                assert_eq!(close.first().map(String::as_str), Some("bolt-1"));
            }
            other => panic!("{other:?}"),
        }
        let e = PartFilter::new(&[], &sel);
        assert!(matches!(e, Err(PartError::NoParts { flag: "--hide", .. })));
        let bad = PartSelection {
            highlight: vec!["[bolt".into()],
            ..PartSelection::default()
        };
        assert!(matches!(
            PartFilter::new(&tree(), &bad),
            Err(PartError::Pattern { .. })
        ));
        // No globs: nothing to match, even without parts.
        assert_eq!(
            PartFilter::new(&[], &PartSelection::default()),
            Ok(PartFilter::none())
        );
    }

    #[test]
    fn block_masks_and_paths() -> Result<(), PartError> {
        let f = PartFilter::new(
            &tree(),
            &PartSelection {
                hide: vec!["bolt-1".into()],
                ..PartSelection::default()
            },
        )?;
        assert_eq!(f.block_mask(&[0, 2]), BlockMask::NoneHidden);
        assert_eq!(f.block_mask(&[1]), BlockMask::AllHidden);
        assert_eq!(f.block_mask(&[0, 1]), BlockMask::Mixed);
        assert_eq!(f.block_mask(&[]), BlockMask::NoneHidden);
        assert!(f.hides(Some(1)) && !f.hides(None) && !f.hides(Some(99)));
        assert_ne!(f.id(), 0);
        assert_eq!(
            part_path(&tree(), 5).as_deref(),
            Some("assembly-2/bolt-2/washer")
        );
        assert_eq!(part_path(&tree(), 7), None);
        assert_eq!(tint([0.0, 0.0, 0.0]), [0.5, 0.175, 0.0]);
        Ok(())
    }

    #[test]
    fn the_tree_totals_subtrees_and_lists_depth_first() {
        let mut parts = tree();
        for (i, p) in parts.iter_mut().enumerate() {
            p.triangles = i as u64;
            let c = i as f32;
            (p.bounds_min, p.bounds_max) = ([c, 0.0, 0.0], [c + 1.0, 1.0, 1.0]);
        }
        parts[0].triangles = 0;
        parts[0].bounds_max = [0.0; 3];
        let t = part_tree(&parts);
        assert_eq!(t[0].subtree_triangles, 1 + 2);
        assert_eq!(t[0].subtree_bounds_min, [1.0, 0.0, 0.0]);
        assert_eq!(t[0].subtree_bounds_max, [3.0, 1.0, 1.0]);
        assert_eq!(t[3].subtree_triangles, 3 + 4 + 5);
        assert_eq!((t[5].depth, t[5].children, t[3].children), (2, 0, 1));
        assert_eq!(t[5].path.as_deref(), Some("assembly-2/bolt-2/washer"));
        assert_eq!(preorder(&parts), [0, 1, 2, 3, 4, 5, 6]);
        // Parents listed before children but not next to them.
        let shuffled = vec![
            part("a", None),
            part("b", None),
            part("a1", Some(0)),
            part("b1", Some(1)),
            part("a2", Some(0)),
        ];
        assert_eq!(preorder(&shuffled), [0, 2, 4, 1, 3]);
    }

    #[test]
    fn edit_distance_has_its_known_answers() {
        let c = |s: &str| s.chars().collect::<Vec<_>>();
        assert_eq!(edit_distance(&c("kitten"), &c("sitting"), 5), Some(3));
        assert_eq!(edit_distance(&c("kitten"), &c("sitting"), 2), None);
        assert_eq!(edit_distance(&c(""), &c("ab"), 3), Some(2));
    }
}
