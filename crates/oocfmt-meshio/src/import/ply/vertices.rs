//! The `vertex` element: positions (`x`, `y`, `z`), normals (`nx`, `ny`, `nz`) and colours
//! (`red`, `green`, `blue`, optional `alpha`, or their `diffuse_` names) of any scalar type;
//! every other property is stepped over. The table is the one thing the importer holds, and
//! its length was checked against the file's size before it is reserved (a stream's grows).

use super::body::Body;
use super::header::{Element, Kind};
use super::scalar::Scalar;
use crate::import::{ImportError, Location, TriangleSink};

/// What a vertex property is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Position(usize),
    Normal(usize),
    Colour(usize),
    Skip,
}

/// How each property of the vertex element is read.
pub(super) struct VertexPlan {
    roles: Vec<Role>,
    normals: bool,
    colours: bool,
}

impl VertexPlan {
    /// The plan for `element`; fails when it lacks a scalar `x`, `y` or `z`.
    pub(super) fn new(element: &Element, file: &str) -> Result<VertexPlan, ImportError> {
        let role = |name: &str| match name {
            "x" => Role::Position(0),
            "y" => Role::Position(1),
            "z" => Role::Position(2),
            "nx" => Role::Normal(0),
            "ny" => Role::Normal(1),
            "nz" => Role::Normal(2),
            "red" | "diffuse_red" => Role::Colour(0),
            "green" | "diffuse_green" => Role::Colour(1),
            "blue" | "diffuse_blue" => Role::Colour(2),
            "alpha" | "diffuse_alpha" => Role::Colour(3),
            _ => Role::Skip,
        };
        let roles: Vec<Role> = element
            .properties
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(_) => role(&p.name),
                Kind::List { .. } => Role::Skip,
            })
            .collect();
        let has = |r: Role| roles.contains(&r);
        for (axis, name) in ["x", "y", "z"].iter().enumerate() {
            if !has(Role::Position(axis)) {
                return Err(ImportError::Parse {
                    at: Location::line(file, element.line),
                    message: format!("element `vertex` has no scalar property `{name}`"),
                });
            }
        }
        let normals = (0..3).all(|a| has(Role::Normal(a)));
        let colours = (0..3).all(|a| has(Role::Colour(a)));
        let roles = roles
            .into_iter()
            .map(|r| match r {
                Role::Normal(_) if !normals => Role::Skip,
                Role::Colour(_) if !colours => Role::Skip,
                r => r,
            })
            .collect();
        Ok(VertexPlan {
            roles,
            normals,
            colours,
        })
    }
}

/// The vertices, as the faces index them.
#[derive(Default)]
pub(super) struct Table {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub colours: Option<Vec<[u8; 4]>>,
}

/// Reads the (entered) vertex element: positions are `origin` + the stored values, placed by
/// the sink. With `keep` false (a bounds pass) they are only placed.
pub(super) fn read<B: Body>(
    body: &mut B,
    element: &Element,
    plan: &VertexPlan,
    origin: [f64; 3],
    sink: &mut dyn TriangleSink,
    keep: bool,
) -> Result<Table, ImportError> {
    // The count was checked against the vertex limit, and against the file's size where it
    // has one; a stream's table grows from a modest start instead.
    let n = usize::try_from(element.count).unwrap_or(0);
    let n = if body.sized() {
        n
    } else {
        n.min(STREAM_RESERVE)
    };
    let mut table = Table {
        positions: reserve(n, keep).unwrap_or_default(),
        normals: reserve(n, keep && plan.normals),
        colours: reserve(n, keep && plan.colours),
    };
    for r in 0..element.count {
        body.record(r);
        let mut p = origin;
        let mut n = [0.0f32; 3];
        let mut c = [255u8; 4];
        for (prop, role) in element.properties.iter().zip(&plan.roles) {
            let ty = match prop.kind {
                Kind::Scalar(ty) if *role != Role::Skip => ty,
                kind => {
                    body.skip_property(kind, &prop.name)?;
                    continue;
                }
            };
            let v = body.scalar(ty, &prop.name)?;
            match *role {
                Role::Position(a) => p[a] += v,
                Role::Normal(a) => n[a] = v as f32,
                Role::Colour(a) => c[a] = colour(v, ty),
                Role::Skip => {}
            }
        }
        let placed = sink.place(p);
        if keep {
            table.positions.push(placed);
            if let Some(normals) = table.normals.as_mut() {
                normals.push(n);
            }
            if let Some(colours) = table.colours.as_mut() {
                colours.push(c);
            }
        }
    }
    Ok(table)
}

/// Most vertices reserved up front for a stream, whose count no size vouches for.
const STREAM_RESERVE: usize = 1 << 16;

/// Room for `n` values, when they are wanted.
fn reserve<T>(n: usize, wanted: bool) -> Option<Vec<T>> {
    wanted.then(|| Vec::with_capacity(n))
}

/// A colour channel: integer types are 0..255, float types 0..1; out of range is clamped
/// (NaN is 0).
fn colour(v: f64, ty: Scalar) -> u8 {
    let v = if ty.is_float() { v * 255.0 } else { v };
    v.round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_channels_by_type() {
        assert_eq!(colour(200.0, Scalar::U8), 200);
        assert_eq!(colour(300.0, Scalar::I16), 255);
        assert_eq!(colour(-3.0, Scalar::I8), 0);
        assert_eq!(colour(0.5, Scalar::F32), 128);
        assert_eq!(colour(1.5, Scalar::F64), 255);
        assert_eq!(colour(f64::NAN, Scalar::F32), 0);
    }
}
