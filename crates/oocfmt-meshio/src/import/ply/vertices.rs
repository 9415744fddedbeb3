//! The `vertex` element: positions (`x`, `y`, `z`), normals (`nx`, `ny`, `nz`) and colours
//! (`red`, `green`, `blue`, optional `alpha`, or their `diffuse_` names) of any scalar type;
//! every other property is stepped over. The table is the one thing the importer holds: it
//! grows page by page as it is read, and with a spill its older pages move to disk.

use super::body::Body;
use super::header::{Element, Kind};
use super::scalar::Scalar;
use crate::import::spill_table::{Record, SpillTable, SpillTo};
use crate::import::{ImportError, InputTriangle, Location, TriangleSink};

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
pub(super) struct Table {
    positions: SpillTable<[f32; 3]>,
    normals: Option<SpillTable<[f32; 3]>>,
    colours: Option<SpillTable<Option<[u8; 4]>>>,
    /// Where the tables move pages (for errors), and the bytes the sink was charged for.
    spill: Option<SpillTo>,
    charged: u64,
    file: String,
}

impl Table {
    fn new(plan: &VertexPlan, spill: Option<&SpillTo>, file: &str) -> Table {
        Table {
            positions: SpillTable::new(spill.cloned()),
            normals: plan.normals.then(|| SpillTable::new(spill.cloned())),
            colours: plan.colours.then(|| SpillTable::new(spill.cloned())),
            spill: spill.cloned(),
            charged: 0,
            file: file.to_string(),
        }
    }

    /// Vertices read.
    pub(super) fn len(&self) -> usize {
        self.positions.len()
    }

    /// The position of vertex `i`, if there is one.
    pub(super) fn position(&mut self, i: u32) -> Result<Option<[f32; 3]>, ImportError> {
        let got = self.positions.get(i as usize);
        got.map_err(|e| self.error(e))
    }

    /// The triangle of vertices `v` (in range) with the table's attributes.
    pub(super) fn triangle(
        &mut self,
        v: [u32; 3],
        part: Option<u32>,
        material: Option<u32>,
    ) -> Result<InputTriangle, ImportError> {
        fn get<T: Record>(t: &mut SpillTable<T>, v: [u32; 3]) -> std::io::Result<[T; 3]> {
            let mut out = [T::default(); 3];
            for (o, i) in out.iter_mut().zip(v) {
                *o = t.get(i as usize)?.unwrap_or_default();
            }
            Ok(out)
        }
        let got = (|| {
            let positions = get(&mut self.positions, v)?;
            let normals = self.normals.as_mut().map(|n| get(n, v)).transpose()?;
            let colours = self.colours.as_mut().map(|c| get(c, v)).transpose()?;
            Ok((positions, normals, colours))
        })();
        let (positions, normals, colours) = got.map_err(|e| self.error(e))?;
        Ok(InputTriangle {
            positions,
            normals,
            colours: colours.map(|c| c.map(Option::unwrap_or_default)),
            material,
            part,
            hint: Some(v),
        })
    }

    /// Appends one vertex, and tells the sink of the file bytes its pages moved to.
    fn push(
        &mut self,
        p: [f32; 3],
        n: [f32; 3],
        c: [u8; 4],
        sink: &mut dyn TriangleSink,
    ) -> Result<(), ImportError> {
        let pushed = (|| {
            self.positions.push(p)?;
            self.normals.as_mut().map(|t| t.push(n)).transpose()?;
            self.colours.as_mut().map(|t| t.push(Some(c))).transpose()?;
            let now = self.positions.file_bytes()
                + self.normals.as_ref().map_or(0, SpillTable::file_bytes)
                + self.colours.as_ref().map_or(0, SpillTable::file_bytes);
            if now > self.charged {
                sink.charge_disk(now - self.charged)?;
                self.charged = now;
            }
            Ok(())
        })();
        pushed.map_err(|e| self.error(e))
    }

    /// Gives back the disk the tables' files were charged for (the files go with the table).
    pub(super) fn release(&mut self, sink: &mut dyn TriangleSink) {
        sink.release_disk(std::mem::take(&mut self.charged));
    }

    /// A failure of the tables' file, named by the input and the folder.
    fn error(&self, source: std::io::Error) -> ImportError {
        let dir = self.spill.as_ref().map(|s| s.dir.display().to_string());
        ImportError::Io {
            path: format!(
                "{} (vertices moved to a temporary file in {})",
                self.file,
                dir.unwrap_or_default()
            ),
            source,
        }
    }
}

/// Reads the (entered) vertex element: positions are `origin` + the stored values, placed by
/// the sink. With `keep` false (a bounds pass) they are only placed. Pages past `spill`'s
/// budget move to its folder.
pub(super) fn read<B: Body>(
    body: &mut B,
    element: &Element,
    plan: &VertexPlan,
    origin: [f64; 3],
    sink: &mut dyn TriangleSink,
    keep: bool,
    spill: Option<&SpillTo>,
) -> Result<Table, ImportError> {
    let mut table = Table::new(plan, spill, &body.location().file);
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
            table.push(placed, n, c, sink)?;
        }
    }
    Ok(table)
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
