//! Primitives: checked once per mesh (attributes, indices, material), then turned into
//! world-space triangles once per node that places the mesh.

use std::fmt::Write as _;

use gltf::json;
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use super::accessor::{Accessor, Reader, Role, Rules};
use super::buffers::Buffers;
use super::scene::Instance;
use super::transform::transform_normal;
use crate::import::{DropReason, ImportError, InputTriangle, Location, TriangleSink};

/// How a primitive is drawn, from the triangle modes only.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Assembly {
    List,
    Strip,
    Fan,
}

/// A primitive whose accessors and material have been checked.
#[derive(Clone, Copy, Debug)]
pub(super) struct Draw {
    assembly: Assembly,
    positions: Accessor,
    normals: Option<Accessor>,
    colours: Option<Accessor>,
    indices: Option<Accessor>,
    /// The glTF material index.
    pub material: Option<usize>,
}

/// What to do with a primitive.
#[derive(Clone, Debug)]
pub(super) enum Plan {
    /// A point or line primitive: counted, not imported.
    Skip,
    Draw(Box<Draw>),
}

fn item(mesh: usize, prim: usize, what: &str) -> String {
    format!("mesh {mesh} primitive {prim} {what}")
}

/// Checks primitive `prim` of mesh `mesh`.
pub(super) fn plan(
    root: &json::Root,
    mesh: usize,
    prim: usize,
    p: &json::mesh::Primitive,
    rules: Rules,
    file: &str,
    sink: &mut dyn TriangleSink,
) -> Result<Plan, ImportError> {
    let parse = |what: &str, message: String| ImportError::Parse {
        at: Location::item(file, item(mesh, prim, what)),
        message,
    };
    let assembly = match p.mode {
        Checked::Valid(Mode::Triangles) => Assembly::List,
        Checked::Valid(Mode::TriangleStrip) => Assembly::Strip,
        Checked::Valid(Mode::TriangleFan) => Assembly::Fan,
        Checked::Valid(_) => return Ok(Plan::Skip),
        Checked::Invalid => return Err(parse("mode", "invalid primitive mode".into())),
    };
    let attribute = |semantic: Semantic, role: Role| -> Result<Option<Accessor>, ImportError> {
        let name = semantic.to_string();
        match p.attributes.get(&Checked::Valid(semantic)) {
            None => Ok(None),
            Some(a) => Accessor::check(root, a.value(), role, rules)
                .map(Some)
                .map_err(|m| parse(&format!("attribute {name}"), m)),
        }
    };
    let Some(positions) = attribute(Semantic::Positions, Role::Position)? else {
        return Err(parse(
            "attribute POSITION",
            "the primitive has no POSITION attribute".into(),
        ));
    };
    let normals = attribute(Semantic::Normals, Role::Normal)?;
    let colours = attribute(Semantic::Colors(0), Role::Colour)?;
    for (name, a) in [("NORMAL", &normals), ("COLOR_0", &colours)] {
        if let Some(a) = a {
            if a.count() != positions.count() {
                return Err(parse(
                    &format!("attribute {name}"),
                    format!(
                        "count {} differs from the POSITION count {}",
                        a.count(),
                        positions.count()
                    ),
                ));
            }
        }
    }
    let indices = match p.indices {
        Some(i) => Some(
            Accessor::check(root, i.value(), Role::Indices, rules)
                .map_err(|m| parse("indices", m))?,
        ),
        None => None,
    };
    let material = match p.material {
        Some(m) if m.value() >= root.materials.len() => {
            return Err(parse(
                "material",
                format!("material {} does not exist", m.value()),
            ))
        }
        m => m.map(|m| m.value()),
    };

    let at = Location::item(file, item(mesh, prim, "").trim_end());
    let n = indices.map_or(positions.count(), |i| i.count());
    let (what, unused) = match assembly {
        Assembly::List => ("a triangle list", n % 3),
        Assembly::Strip | Assembly::Fan if n < 3 => ("a strip or fan", n),
        _ => ("", 0),
    };
    if unused > 0 {
        sink.warn(
            &at,
            format!("{what} of {n} vertices: the last {unused} form no triangle"),
        );
    }
    if p.targets.as_ref().is_some_and(|t| !t.is_empty()) {
        sink.warn(
            &at,
            "morph targets are not applied: the base shape is imported".into(),
        );
    }
    Ok(Plan::Draw(Box::new(Draw {
        assembly,
        positions,
        normals,
        colours,
        indices,
        material,
    })))
}

/// Readers for a checked primitive's accessors.
pub(super) struct Readers<'a> {
    positions: Reader<'a>,
    normals: Option<Reader<'a>>,
    colours: Option<(Reader<'a>, usize)>,
    indices: Option<Reader<'a>>,
}

impl Draw {
    /// The buffers the primitive reads.
    pub(super) fn buffers(&self) -> impl Iterator<Item = usize> + '_ {
        [
            Some(&self.positions),
            self.normals.as_ref(),
            self.colours.as_ref(),
            self.indices.as_ref(),
        ]
        .into_iter()
        .flatten()
        .flat_map(Accessor::buffers)
    }

    pub(super) fn readers<'a>(
        &self,
        buffers: &'a Buffers,
        mesh: usize,
        prim: usize,
        file: &str,
    ) -> Result<Readers<'a>, ImportError> {
        let open = |a: &Accessor, what: &str| {
            a.reader(buffers).map_err(|message| ImportError::Parse {
                at: Location::item(file, item(mesh, prim, what)),
                message,
            })
        };
        Ok(Readers {
            positions: open(&self.positions, "attribute POSITION")?,
            normals: match &self.normals {
                Some(a) => Some(open(a, "attribute NORMAL")?),
                None => None,
            },
            colours: match &self.colours {
                Some(a) => Some((open(a, "attribute COLOR_0")?, a.components())),
                None => None,
            },
            indices: match &self.indices {
                Some(a) => Some(open(a, "indices")?),
                None => None,
            },
        })
    }
}

/// The vertex slots of triangle `t` (glTF 2.0 §3.7.2.1): strips alternate their winding so
/// that every triangle faces the same way; fans turn around the first vertex.
fn corners(assembly: Assembly, t: usize) -> [usize; 3] {
    match assembly {
        Assembly::List => [3 * t, 3 * t + 1, 3 * t + 2],
        Assembly::Strip if t % 2 == 0 => [t, t + 1, t + 2],
        Assembly::Strip => [t, t + 2, t + 1],
        Assembly::Fan => [t + 1, t + 2, 0],
    }
}

fn colour_byte(x: f64) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0).round() as u8
}

impl Readers<'_> {
    /// The vertices of triangle `t` (assembled as `assembly`); None when an index is past the
    /// primitive's `vertices`.
    fn triangle_vertices(
        &self,
        assembly: Assembly,
        t: usize,
        vertices: usize,
    ) -> Option<[usize; 3]> {
        let slots = corners(assembly, t);
        let mut v = [0usize; 3];
        for (k, &slot) in slots.iter().enumerate() {
            let index = match &self.indices {
                Some(ix) => ix.index(slot).map(|i| i as usize),
                None => Some(slot),
            };
            match index {
                Some(i) if i < vertices => v[k] = i,
                _ => return None,
            }
        }
        Some(v)
    }

    /// The unit normals of vertices `v`, turned by `normal_matrix` (None: the identity);
    /// None without normals, or when one does not turn into a unit vector.
    fn corner_normals(
        &self,
        v: &[usize; 3],
        normal_matrix: Option<&[[f64; 3]; 3]>,
    ) -> Option<[[f32; 3]; 3]> {
        let nr = self.normals.as_ref()?;
        let mut out = Some([[0.0f32; 3]; 3]);
        for (k, &i) in v.iter().enumerate() {
            let e = nr.get(i).unwrap_or([f64::NAN; 4]);
            let n = match normal_matrix {
                None => Some([e[0] as f32, e[1] as f32, e[2] as f32]),
                Some(m) => transform_normal(m, [e[0], e[1], e[2]]),
            };
            match (n, out.as_mut()) {
                (Some(n), Some(o)) => o[k] = n,
                _ => out = None,
            }
        }
        out
    }

    /// The RGBA bytes of vertices `v` (alpha 255 for RGB colours); None without colours.
    fn corner_colours(&self, v: &[usize; 3]) -> Option<[[u8; 4]; 3]> {
        self.colours.as_ref().map(|(cr, ncomp)| {
            v.map(|i| {
                let e = cr.get(i).unwrap_or([0.0; 4]);
                let alpha = if *ncomp == 4 { colour_byte(e[3]) } else { 255 };
                [
                    colour_byte(e[0]),
                    colour_byte(e[1]),
                    colour_byte(e[2]),
                    alpha,
                ]
            })
        })
    }
}

/// Pushes the triangles of one primitive placed by one node, with the sink's indices of their
/// material and part.
pub(super) fn emit(
    draw: &Draw,
    r: &Readers<'_>,
    instance: &Instance,
    prim: usize,
    (material, part): (Option<u32>, Option<u32>),
    file: &str,
    sink: &mut dyn TriangleSink,
) -> Result<(), ImportError> {
    let base = format!(
        "node {} mesh {} primitive {prim}",
        instance.node, instance.mesh
    );
    let mut at = Location::item(file, base.clone());
    let vertices = r.positions.count();
    let n = r.indices.as_ref().map_or(vertices, Reader::count);
    let triangles = match draw.assembly {
        Assembly::List => n / 3,
        Assembly::Strip | Assembly::Fan => n.saturating_sub(2),
    };
    let world = &instance.world;
    let identity = world.is_identity();
    let mirrored = world.determinant() < 0.0;
    let turn = world.normal_matrix();
    // None: normals are taken as they are.
    let normal_matrix = (!identity).then_some(&turn);
    for t in 0..triangles {
        if let Some(item) = at.item.as_mut() {
            item.truncate(base.len());
            let _ = write!(item, " triangle {t}");
        }
        let Some(v) = r.triangle_vertices(draw.assembly, t, vertices) else {
            sink.reject(DropReason::IndexOutOfRange, &at)?;
            continue;
        };
        let mut positions = [[0.0f32; 3]; 3];
        for (p, &i) in positions.iter_mut().zip(&v) {
            let e = r.positions.get(i).unwrap_or([f64::NAN; 4]);
            let q = if identity {
                [e[0], e[1], e[2]]
            } else {
                world.apply_point([e[0], e[1], e[2]])
            };
            *p = sink.place(q);
        }
        let mut tri = InputTriangle {
            positions,
            normals: r.corner_normals(&v, normal_matrix),
            colours: r.corner_colours(&v),
            material,
            part,
            hint: None,
        };
        if mirrored {
            // A mirroring transform turns counter-clockwise corners clockwise.
            tri.positions.swap(1, 2);
            if let Some(n) = tri.normals.as_mut() {
                n.swap(1, 2);
            }
            if let Some(c) = tri.colours.as_mut() {
                c.swap(1, 2);
            }
        }
        sink.push(tri, &at)?;
    }
    Ok(())
}
