//! The node graph: checked to be a forest (the gltf crate lets cycles through), then walked
//! from the selected scenes' roots to place every mesh in world space.

use std::collections::BTreeSet;

use gltf::json;

use super::transform::Affine;
use crate::import::{ImportError, Location, TriangleSink};

/// Deeper hierarchies than this are refused: no exporter nests so deep, and a walk that did
/// would be a sign of a generated attack rather than a model.
pub(super) const MAX_DEPTH: usize = 1024;

/// A mesh placed by a node.
#[derive(Clone, Copy, Debug)]
pub(super) struct Instance {
    /// The index, among the scenes imported, of the scene it was reached from.
    pub scene: usize,
    pub node: usize,
    pub mesh: usize,
    pub world: Affine,
}

/// The instances of the imported scenes, and what is needed to name their parts.
pub(super) struct Placed {
    pub instances: Vec<Instance>,
    /// Each node's parent (the nodes form a forest).
    pub parents: Vec<Option<usize>>,
    /// The glTF index of each imported scene (`None`: the file has no scene and its root
    /// nodes stand for one).
    pub scenes: Vec<Option<usize>>,
}

fn node_error(file: &str, node: usize, message: impl Into<String>) -> ImportError {
    ImportError::Parse {
        at: Location::item(file, format!("node {node}")),
        message: message.into(),
    }
}

fn children(root: &json::Root, node: usize) -> impl Iterator<Item = usize> + '_ {
    root.nodes
        .get(node)
        .and_then(|n| n.children.as_deref())
        .unwrap_or(&[])
        .iter()
        .map(|c| c.value())
}

/// Each node's parent, after checking that the nodes form a forest: children exist, no node
/// has two parents, no cycle, no branch deeper than [`MAX_DEPTH`].
pub(super) fn parents(root: &json::Root, file: &str) -> Result<Vec<Option<usize>>, ImportError> {
    let n = root.nodes.len();
    let mut parent: Vec<Option<usize>> = vec![None; n];
    for p in 0..n {
        for c in children(root, p) {
            let Some(slot) = parent.get_mut(c) else {
                return Err(node_error(file, p, format!("child {c} does not exist")));
            };
            if c == p {
                return Err(node_error(
                    file,
                    p,
                    "the node is its own child: the node graph has a cycle",
                ));
            }
            if let Some(q) = *slot {
                let message = if q == p {
                    format!("the node is listed twice among the children of node {p}")
                } else {
                    format!("the node has two parents, node {q} and node {p}")
                };
                return Err(node_error(file, c, message));
            }
            *slot = Some(p);
        }
    }
    // With one parent at most, a walk down from the parentless nodes meets each node once;
    // a node it never meets lies on a cycle or below one.
    let mut reached = vec![false; n];
    let mut stack: Vec<(usize, usize)> = (0..n)
        .filter(|&i| parent.get(i).is_some_and(Option::is_none))
        .map(|i| (i, 1))
        .collect();
    while let Some((x, depth)) = stack.pop() {
        if depth > MAX_DEPTH {
            return Err(node_error(
                file,
                x,
                format!("the node hierarchy is deeper than {MAX_DEPTH} levels here"),
            ));
        }
        if let Some(r) = reached.get_mut(x) {
            *r = true;
        }
        stack.extend(children(root, x).map(|c| (c, depth + 1)));
    }
    if let Some(start) = reached.iter().position(|r| !r) {
        // Every unreached node has a parent, so following parents must repeat a node within
        // n steps; that node is on the cycle.
        let mut seen = vec![false; n];
        let mut x = start;
        while let Some(false) = seen.get(x) {
            if let Some(s) = seen.get_mut(x) {
                *s = true;
            }
            match parent.get(x).copied().flatten() {
                Some(p) => x = p,
                None => break,
            }
        }
        return Err(node_error(
            file,
            x,
            "the node lies on a cycle of the node graph",
        ));
    }
    Ok(parent)
}

/// The node's own transform: its matrix, or T·R·S.
fn local(node: &json::Node) -> Result<Affine, String> {
    match &node.matrix {
        Some(m) => Affine::from_column_major(m),
        None => Affine::from_trs(
            node.translation.unwrap_or([0.0; 3]),
            node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0),
            node.scale.unwrap_or([1.0; 3]),
        ),
    }
}

/// A scene to import: its glTF index (`None`: the file has none and its root nodes stand for
/// one) and its root nodes.
type Roots = (Option<usize>, Vec<usize>);

/// The scenes to import: all, or the default one (scene 0 when none is marked). A file
/// without scenes gets one made of its root nodes.
fn selected_scenes(
    root: &json::Root,
    parent: &[Option<usize>],
    file: &str,
    all_scenes: bool,
    sink: &mut dyn TriangleSink,
) -> Result<Vec<Roots>, ImportError> {
    let at = Location::file(file);
    if root.scenes.is_empty() {
        if !root.nodes.is_empty() {
            sink.warn(
                &at,
                "the file has no scene: importing every root node".into(),
            );
        }
        return Ok(vec![(
            None,
            (0..parent.len())
                .filter(|&i| parent.get(i).is_some_and(Option::is_none))
                .collect(),
        )]);
    }
    let scene_nodes = |s: usize| -> Roots {
        let nodes = root
            .scenes
            .get(s)
            .map(|sc| sc.nodes.iter().map(|n| n.value()).collect())
            .unwrap_or_default();
        (Some(s), nodes)
    };
    if all_scenes {
        return Ok((0..root.scenes.len()).map(scene_nodes).collect());
    }
    let default = root.scene.map_or(0, |s| s.value());
    if default >= root.scenes.len() {
        return Err(ImportError::Parse {
            at: Location::item(file, "scene"),
            message: format!(
                "the default scene {default} does not exist ({} scenes)",
                root.scenes.len()
            ),
        });
    }
    if root.scenes.len() > 1 {
        sink.warn(
            &at,
            format!(
                "imported the default scene {default} only, of {} scenes (the others need the \
                 all-scenes option)",
                root.scenes.len()
            ),
        );
    }
    Ok(vec![scene_nodes(default)])
}

/// Every mesh the selected scenes place, with its world transform, in scene order and
/// depth-first order within a scene.
pub(super) fn instances(
    root: &json::Root,
    file: &str,
    all_scenes: bool,
    sink: &mut dyn TriangleSink,
) -> Result<Placed, ImportError> {
    let parent = parents(root, file)?;
    let scenes = selected_scenes(root, &parent, file, all_scenes, sink)?;
    let mut out = Vec::new();
    let mut matrix_and_trs = BTreeSet::new();
    let mut skinned = BTreeSet::new();
    for (imported, (index, roots)) in scenes.iter().enumerate() {
        let s = index.unwrap_or(imported);
        let mut seen = BTreeSet::new();
        for &r in roots {
            let scene_error = |message: String| ImportError::Parse {
                at: Location::item(file, format!("scene {s}")),
                message,
            };
            match parent.get(r) {
                None => return Err(scene_error(format!("node {r} does not exist"))),
                Some(Some(p)) => {
                    return Err(scene_error(format!(
                        "node {r} is listed as a root but is a child of node {p}"
                    )))
                }
                Some(None) => {}
            }
            if !seen.insert(r) {
                return Err(scene_error(format!("node {r} is listed twice")));
            }
            let mut stack = vec![(r, Affine::IDENTITY)];
            while let Some((x, above)) = stack.pop() {
                let Some(node) = root.nodes.get(x) else {
                    return Err(node_error(file, x, "the node does not exist"));
                };
                let world = above.then(&local(node).map_err(|m| node_error(file, x, m))?);
                if node.matrix.is_some()
                    && (node.translation.is_some()
                        || node.rotation.is_some()
                        || node.scale.is_some())
                {
                    matrix_and_trs.insert(x);
                }
                if let Some(m) = node.mesh {
                    let mesh = m.value();
                    if mesh >= root.meshes.len() {
                        return Err(node_error(file, x, format!("mesh {mesh} does not exist")));
                    }
                    if node.skin.is_some() {
                        skinned.insert(x);
                    }
                    out.push(Instance {
                        scene: imported,
                        node: x,
                        mesh,
                        world,
                    });
                }
                let kids: Vec<usize> = children(root, x).collect();
                stack.extend(kids.into_iter().rev().map(|c| (c, world)));
            }
        }
    }
    let at = Location::file(file);
    if let Some(first) = matrix_and_trs.first() {
        sink.warn(
            &at,
            format!(
                "{} node(s), first node {first}, have both a matrix and TRS properties: the \
                 matrix is used",
                matrix_and_trs.len()
            ),
        );
    }
    if let Some(first) = skinned.first() {
        sink.warn(
            &at,
            format!(
                "{} skinned node(s), first node {first}: skins are not applied, the meshes are \
                 imported in their bind pose under the node transform",
                skinned.len()
            ),
        );
    }
    Ok(Placed {
        instances: out,
        parents: parent,
        scenes: scenes.into_iter().map(|(index, _)| index).collect(),
    })
}
