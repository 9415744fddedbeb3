//! glTF 2.0 importer for `.gltf` (JSON with `.bin` files or `data:` URIs) and `.glb`.
//!
//! The gltf crate is used to deserialize the JSON only. Its other parts are not safe on
//! malformed input: `Gltf::from_slice` validation indexes accessors unchecked (a POSITION
//! naming a missing accessor panics) and lets cyclic node graphs through, `Glb::from_slice`
//! underflows on a short header length, its accessor readers panic on several malformed
//! accessors, and `gltf::import` reads `file:` and `../` URIs with no size cap. So the GLB
//! container, the node graph, the accessors and the URIs are all checked here, before any
//! buffer byte is read, and every read is bounded.
//!
//! Everything the importer does not carry is reported rather than dropped silently: point
//! and line primitives are counted as skipped, unused scenes and meshes, ignored extensions,
//! skins and morph targets are warned about, and required extensions it cannot decode
//! (Draco, meshopt) are errors.

mod accessor;
mod buffers;
mod glb;
mod parts;
mod primitive;
mod scene;
mod transform;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use gltf::json;
use oocfmt::metadata::Material;

use self::accessor::Rules;
use self::primitive::Plan;
use crate::import::{ImportError, Location, Skipped, TriangleSink};

/// Options of the glTF importer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GltfOptions {
    /// Import every scene, not only the default one (scene 0 when none is marked).
    pub all_scenes: bool,
    /// Cap on the bytes read from buffers, in all (`.bin` files, `data:` URIs, the GLB BIN
    /// chunk). Checked against the declared lengths before anything is read.
    pub max_buffer_bytes: u64,
    /// Cap on the size of the JSON (the `.gltf` file or the GLB JSON chunk).
    pub max_json_bytes: u64,
}

impl Default for GltfOptions {
    fn default() -> GltfOptions {
        GltfOptions {
            all_scenes: false,
            max_buffer_bytes: 4 << 30,
            max_json_bytes: 256 << 20,
        }
    }
}

/// Extensions this importer decodes.
const DECODED: &[&str] = &["KHR_mesh_quantization"];

/// Extensions that change nothing the importer reads (textures, lights, shading terms
/// beyond the base colour), so a file that requires them imports correctly without them.
const IRRELEVANT: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_anisotropy",
    "KHR_materials_clearcoat",
    "KHR_materials_dispersion",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_iridescence",
    "KHR_materials_sheen",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_unlit",
    "KHR_materials_variants",
    "KHR_materials_volume",
    "KHR_texture_basisu",
    "KHR_texture_transform",
    "KHR_xmp_json_ld",
    "EXT_texture_avif",
    "EXT_texture_webp",
    "MSFT_texture_dds",
];

fn io_error(path: &Path, source: std::io::Error) -> ImportError {
    ImportError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Imports the default scene (or every scene) of a `.gltf` or `.glb` file: each mesh placed
/// by a node, in world space, in a part of its node (`gltf/parts.rs` says how the tree is made).
pub fn import(
    path: &Path,
    sink: &mut dyn TriangleSink,
    opts: &GltfOptions,
) -> Result<(), ImportError> {
    let file = path.display().to_string();
    sink.begin_file(&file);
    let source = glb::read_source(path, &file, opts.max_json_bytes)?;
    let root: json::Root =
        json::deserialize::from_slice(&source.json).map_err(|e| ImportError::Parse {
            at: Location::file(&file),
            message: format!("not valid glTF JSON: {e}"),
        })?;
    let rules = Rules {
        quantization: check_extensions(&root, &file, sink)?,
        max_bytes: opts.max_buffer_bytes,
    };
    let placed = scene::instances(&root, &file, opts.all_scenes, sink)?;
    let instances = &placed.instances;
    warn_unplaced_meshes(&root, instances, &file, sink);

    // Check every primitive the instances draw before reading any buffer.
    let mut plans: BTreeMap<usize, Vec<Plan>> = BTreeMap::new();
    for inst in instances {
        if plans.contains_key(&inst.mesh) {
            continue;
        }
        let Some(mesh) = root.meshes.get(inst.mesh) else {
            continue;
        };
        let mut prims = Vec::with_capacity(mesh.primitives.len());
        for (p, prim) in mesh.primitives.iter().enumerate() {
            prims.push(primitive::plan(
                &root, inst.mesh, p, prim, rules, &file, sink,
            )?);
        }
        plans.insert(inst.mesh, prims);
    }
    let needed: BTreeSet<usize> = plans
        .values()
        .flatten()
        .filter_map(|plan| match plan {
            Plan::Draw(d) => Some(d.as_ref()),
            Plan::Skip => None,
        })
        .flat_map(|d| d.buffers())
        .collect();
    let origin = buffers::Origin {
        model: path,
        file: &file,
        bin: source.bin,
    };
    let buffers = buffers::load(&root, &needed, &origin, opts.max_buffer_bytes)?;

    let mut readers = BTreeMap::new();
    for (&mesh, prims) in &plans {
        for (p, plan) in prims.iter().enumerate() {
            if let Plan::Draw(d) = plan {
                readers.insert((mesh, p), d.readers(&buffers, mesh, p, &file)?);
            }
        }
    }

    let parts = parts::declare(&root, &placed, &file, sink)?;
    let mut materials: BTreeMap<usize, u32> = BTreeMap::new();
    for (inst, &part) in instances.iter().zip(&parts) {
        let Some(prims) = plans.get(&inst.mesh) else {
            continue;
        };
        for (p, plan) in prims.iter().enumerate() {
            let (Plan::Draw(d), Some(r)) = (plan, readers.get(&(inst.mesh, p))) else {
                sink.skip(Skipped::NonTrianglePrimitives, 1);
                continue;
            };
            let material = match d.material {
                Some(m) => Some(material_index(&root, m, &mut materials, sink)?),
                None => None,
            };
            primitive::emit(d, r, inst, p, (material, part), &file, sink)?;
        }
    }
    Ok(())
}

/// Refuses required extensions that change what is read and are not decoded; warns about
/// used ones that are ignored. Returns whether KHR_mesh_quantization is in use.
fn check_extensions(
    root: &json::Root,
    file: &str,
    sink: &mut dyn TriangleSink,
) -> Result<bool, ImportError> {
    let known = |e: &str| DECODED.contains(&e) || IRRELEVANT.contains(&e);
    for e in &root.extensions_required {
        if !known(e) {
            let why = match e.as_str() {
                "KHR_draco_mesh_compression"
                | "EXT_meshopt_compression"
                | "KHR_meshopt_compression" => {
                    "compressed geometry is not decoded; export the model uncompressed"
                }
                _ => "the importer does not decode it",
            };
            return Err(ImportError::Unsupported {
                at: Location::item(file, "extensionsRequired"),
                what: format!("required extension {e}: {why}"),
            });
        }
    }
    let ignored: Vec<&str> = root
        .extensions_used
        .iter()
        .map(String::as_str)
        .filter(|e| !known(e))
        .collect();
    if !ignored.is_empty() {
        sink.warn(
            &Location::item(file, "extensionsUsed"),
            format!(
                "extension(s) not decoded, imported without them: {}",
                ignored.join(", ")
            ),
        );
    }
    let quantization = "KHR_mesh_quantization";
    Ok(root
        .extensions_used
        .iter()
        .chain(&root.extensions_required)
        .any(|e| e == quantization))
}

fn warn_unplaced_meshes(
    root: &json::Root,
    instances: &[scene::Instance],
    file: &str,
    sink: &mut dyn TriangleSink,
) {
    let placed: BTreeSet<usize> = instances.iter().map(|i| i.mesh).collect();
    let unplaced = root.meshes.len() - placed.len().min(root.meshes.len());
    if unplaced > 0 {
        sink.warn(
            &Location::file(file),
            format!(
                "{unplaced} of {} meshes are placed by no node of the imported scene(s) and \
                 are not imported",
                root.meshes.len()
            ),
        );
    }
}

/// The sink's index of glTF material `m`, added on first use: named as in the file (or
/// "material N"), with the base colour factor as diffuse colour.
fn material_index(
    root: &json::Root,
    m: usize,
    added: &mut BTreeMap<usize, u32>,
    sink: &mut dyn TriangleSink,
) -> Result<u32, ImportError> {
    if let Some(&i) = added.get(&m) {
        return Ok(i);
    }
    let gm = root.materials.get(m);
    let name = gm
        .and_then(|g| g.name.clone())
        .unwrap_or_else(|| format!("material {m}"));
    let factor = gm.map_or([1.0; 4], |g| g.pbr_metallic_roughness.base_color_factor.0);
    let diffuse =
        [factor[0], factor[1], factor[2]].map(|c| if c.is_nan() { 1.0 } else { c.clamp(0.0, 1.0) });
    let i = sink.add_material(Material { name, diffuse })?;
    added.insert(m, i);
    Ok(i)
}
