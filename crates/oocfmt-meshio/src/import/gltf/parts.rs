//! Parts from the node hierarchy, so the part tree mirrors the glTF one: every node that
//! places a mesh is a part, and so is each node above it up to the scene root (declared once,
//! parents first, when the first mesh below it is reached, so branches without meshes make no
//! part). A part is named by its node's name, else (for a node with a mesh) the mesh's name,
//! else `node N` by the node's index, so its path reads like `node 3/node 7`. A mesh placed by
//! two nodes is two parts; glTF forbids a node two parents, but with every scene imported a
//! node may be reached from several, so then each scene is a part above its nodes (named by
//! the scene, else `scene N`) and each instance path has its own parts.
//!
//! A scene that places one mesh once, with no name on the node, its ancestors or the mesh,
//! declares no part: the anonymous single part it would be pays nothing.

use std::collections::HashMap;

use gltf::json;

use super::scene::Placed;
use crate::import::{ImportError, Location, PartDef, TriangleSink};

/// A name the file gives, if it is not empty.
fn given(name: Option<&String>) -> Option<&str> {
    name.map(String::as_str).filter(|n| !n.is_empty())
}

fn node_name(root: &json::Root, node: usize) -> String {
    let n = root.nodes.get(node);
    let mesh = n
        .and_then(|n| n.mesh)
        .and_then(|m| root.meshes.get(m.value()));
    given(n.and_then(|n| n.name.as_ref()))
        .or_else(|| given(mesh.and_then(|m| m.name.as_ref())))
        .map_or_else(|| format!("node {node}"), str::to_string)
}

fn scene_name(root: &json::Root, scene: Option<usize>, imported: usize) -> String {
    let index = scene.unwrap_or(imported);
    given(root.scenes.get(index).and_then(|s| s.name.as_ref()))
        .map_or_else(|| format!("scene {index}"), str::to_string)
}

/// Whether the scenes name anything a part would be named by: a node on the way to a mesh
/// (the node itself included), the mesh, or a scene when there are several.
fn names_anything(root: &json::Root, placed: &Placed) -> bool {
    let scenes = placed.scenes.len() > 1
        && placed.scenes.iter().any(|&s| {
            given(
                s.and_then(|s| root.scenes.get(s))
                    .and_then(|s| s.name.as_ref()),
            )
            .is_some()
        });
    scenes
        || placed.instances.iter().any(|inst| {
            let mesh = root.meshes.get(inst.mesh).and_then(|m| m.name.as_ref());
            let mut node = Some(inst.node);
            let mut named = given(mesh).is_some();
            while let (false, Some(n)) = (named, node) {
                named = given(root.nodes.get(n).and_then(|n| n.name.as_ref())).is_some();
                node = placed.parents.get(n).copied().flatten();
            }
            named
        })
}

/// Declares the parts of `placed`'s instances; returns each instance's part, or none at all
/// for a scene that has one anonymous mesh instance.
pub(super) fn declare(
    root: &json::Root,
    placed: &Placed,
    file: &str,
    sink: &mut dyn TriangleSink,
) -> Result<Vec<Option<u32>>, ImportError> {
    let instances = &placed.instances;
    if instances.len() <= 1 && !names_anything(root, placed) {
        return Ok(vec![None; instances.len()]);
    }
    let mut scene_parts: HashMap<usize, u32> = HashMap::new();
    // (imported scene, node) → part.
    let mut node_parts: HashMap<(usize, usize), u32> = HashMap::new();
    let mut chain = Vec::new();
    let mut out = Vec::with_capacity(instances.len());
    for inst in instances {
        // The nodes from this one up to the first with a part (or the scene root).
        chain.clear();
        let mut above = None;
        let mut node = Some(inst.node);
        while let Some(n) = node {
            if let Some(&p) = node_parts.get(&(inst.scene, n)) {
                above = Some(p);
                break;
            }
            chain.push(n);
            node = placed.parents.get(n).copied().flatten();
        }
        if above.is_none() && placed.scenes.len() > 1 {
            above = Some(match scene_parts.get(&inst.scene) {
                Some(&p) => p,
                None => {
                    let scene = placed.scenes.get(inst.scene).copied().flatten();
                    let name = scene_name(root, scene, inst.scene);
                    let p = sink.add_part(PartDef::new(name, None)).map_err(|e| {
                        placed_at(e, file, format!("scene {}", scene.unwrap_or(inst.scene)))
                    })?;
                    scene_parts.insert(inst.scene, p);
                    p
                }
            });
        }
        for &n in chain.iter().rev() {
            let p = sink
                .add_part(PartDef::new(node_name(root, n), above))
                .map_err(|e| placed_at(e, file, format!("node {n}")))?;
            node_parts.insert((inst.scene, n), p);
            above = Some(p);
        }
        out.push(above);
    }
    Ok(out)
}

/// The error a sink gave for a part, placed at the item it was declared for.
fn placed_at(e: ImportError, file: &str, item: String) -> ImportError {
    match e {
        ImportError::Limit { at, what, limit } if at.file.is_empty() => ImportError::Limit {
            at: Location::item(file, item),
            what,
            limit,
        },
        ImportError::Parse { at, message } if at.file.is_empty() => ImportError::Parse {
            at: Location::item(file, item),
            message,
        },
        e => e,
    }
}
