//! The in-memory triangle mesh every builder stage reads, with its bounds and validation.

use oocfmt::metadata::Material;

/// An axis-aligned box. An empty box has `min > max` on every axis, so extending it by any
/// point yields that point.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Bounds {
    /// The lowest corner: the smallest coordinate on each axis.
    pub min: [f32; 3],
    /// The highest corner: the largest coordinate on each axis.
    pub max: [f32; 3],
}

impl Bounds {
    /// The box around no point: `min` +∞ and `max` −∞ on every axis.
    pub const EMPTY: Bounds = Bounds {
        min: [f32::INFINITY; 3],
        max: [f32::NEG_INFINITY; 3],
    };

    /// True when the box holds no point (`min > max` on some axis).
    #[inline]
    pub fn is_empty(&self) -> bool {
        (0..3).any(|a| self.min[a] > self.max[a])
    }

    /// Grows the box to hold `p`.
    #[inline]
    pub fn extend(&mut self, p: [f32; 3]) {
        for ((lo, hi), c) in self.min.iter_mut().zip(&mut self.max).zip(p) {
            *lo = lo.min(c);
            *hi = hi.max(c);
        }
    }

    /// The smallest box holding every point of `points` ([`Bounds::EMPTY`] for none).
    #[inline]
    pub fn of_points(points: &[[f32; 3]]) -> Bounds {
        let mut b = Bounds::EMPTY;
        for &p in points {
            b.extend(p);
        }
        b
    }

    /// The size along `axis` (0 for an axis above 2).
    pub fn extent(&self, axis: usize) -> f32 {
        match (self.min.get(axis), self.max.get(axis)) {
            (Some(lo), Some(hi)) => hi - lo,
            _ => 0.0,
        }
    }

    /// The axis with the largest extent; ties go to the lowest axis so builds are reproducible.
    pub fn longest_axis(&self) -> usize {
        let mut best = 0;
        for a in 1..3 {
            if self.extent(a) > self.extent(best) {
                best = a;
            }
        }
        best
    }

    /// The two halves of this box cut by the plane `axis = split` (for an axis above 2, two
    /// copies of the box).
    pub fn split(&self, axis: usize, split: f32) -> (Bounds, Bounds) {
        let (mut left, mut right) = (*self, *self);
        if let (Some(hi), Some(lo)) = (left.max.get_mut(axis), right.min.get_mut(axis)) {
            *hi = split;
            *lo = split;
        }
        (left, right)
    }

    /// Half the diagonal, rounded up to the next f32 (spec §6.3: a LOD radius never
    /// understates the cell). `None` when it does not fit an f32.
    pub fn half_diagonal_up(&self) -> Option<f32> {
        let d2: f64 = (0..3)
            .map(|a| {
                let e = f64::from(self.max[a]) - f64::from(self.min[a]);
                e * e
            })
            .sum();
        let exact = 0.5 * d2.sqrt();
        let near = exact as f32;
        let r = if f64::from(near) < exact {
            next_up(near)
        } else {
            near
        };
        (r.is_finite() && r >= 0.0).then_some(r)
    }
}

/// The next larger f32 of a non-negative finite value (`f32::next_up` needs Rust 1.86).
fn next_up(x: f32) -> f32 {
    if x == 0.0 {
        f32::from_bits(1)
    } else {
        f32::from_bits(x.to_bits() + 1)
    }
}

/// What makes a mesh unusable; the first problem found is reported.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// A vertex position has a NaN or infinite coordinate.
    #[error("vertex {vertex} has a non-finite position {position:?}")]
    PositionNotFinite {
        /// The vertex's index in [`Mesh::positions`].
        vertex: usize,
        /// Its position.
        position: [f32; 3],
    },
    /// A vertex normal has a NaN or infinite component.
    #[error("vertex {vertex} has a non-finite normal {normal:?}")]
    NormalNotFinite {
        /// The vertex's index.
        vertex: usize,
        /// Its normal.
        normal: [f32; 3],
    },
    /// A triangle names a vertex past [`Mesh::positions`].
    #[error("triangle {triangle} names vertex {index}, but there are {vertices} vertices")]
    IndexOutOfRange {
        /// The triangle's index in [`Mesh::triangles`].
        triangle: usize,
        /// The vertex index it names.
        index: u32,
        /// How many vertices the mesh has.
        vertices: usize,
    },
    /// A per-vertex or per-triangle attribute array has the wrong length.
    #[error("{what} has {len} entries, expected {expected}")]
    AttributeLength {
        /// Which array: `normals`, `colours`, `materials` or `part ids`.
        what: &'static str,
        /// Its length.
        len: usize,
        /// The vertex count (normals, colours) or triangle count (materials).
        expected: usize,
    },
    /// A triangle's material index is past [`Mesh::material_table`].
    #[error("triangle {triangle} uses material {material}, but the table has {materials}")]
    MaterialOutOfRange {
        /// The triangle's index.
        triangle: usize,
        /// The material index it uses.
        material: u16,
        /// How many materials the table holds.
        materials: usize,
    },
    /// A triangle's part id is past [`Mesh::parts`].
    #[error("triangle {triangle} is in part {part}, but the scene has {parts} parts")]
    PartOutOfRange {
        /// The triangle's index.
        triangle: usize,
        /// The part id it has.
        part: u32,
        /// How many parts the scene has.
        parts: usize,
    },
    /// A part's parent is not a part before it.
    #[error("part {part} names parent {parent}, which is not a part before it")]
    PartParent {
        /// The part's index.
        part: usize,
        /// The parent it names.
        parent: u32,
    },
    /// More triangles than 32-bit triangle ids can number.
    #[error("{triangles} triangles: at most {max} fit 32-bit triangle ids")]
    TooManyTriangles {
        /// The mesh's triangle count.
        triangles: usize,
        /// The most allowed, `u32::MAX`.
        max: usize,
    },
}

/// A triangle mesh. Normals and colours are per vertex, materials per triangle; each is
/// optional and the container stores only what is present.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions, in stored coordinates (world = the scene origin + position).
    pub positions: Vec<[f32; 3]>,
    /// Each triangle's three indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// One normal per vertex, when the input has normals.
    pub normals: Option<Vec<[f32; 3]>>,
    /// One RGBA colour per vertex (value / 255), when the input has colours.
    pub colours: Option<Vec<[u8; 4]>>,
    /// One index into `material_table` per triangle, when the input has materials.
    pub materials: Option<Vec<u16>>,
    /// The materials `materials` indexes.
    pub material_table: Vec<Material>,
    /// One index into `parts` per triangle, when the scene has more than one part.
    pub part_ids: Option<Vec<u32>>,
    /// The scene's parts (assembly nodes), parents before children; empty when the input
    /// named none.
    pub parts: Vec<PartDef>,
}

/// A named node of the input's assembly (an OBJ `o`/`g`, a glTF node with a mesh, an STL
/// `solid`, an input file), as an importer declares it.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct PartDef {
    /// The name the input gives it (may be empty).
    pub name: String,
    /// The index [`crate::import::TriangleSink::add_part`] returned for its parent; always lower than its own.
    /// `None`: a top-level part (under the file's part when several files are read).
    pub parent: Option<u32>,
    /// The index of the file it came from in [`crate::import::ImportReport::files`]; filled in by the sink.
    pub source: Option<u32>,
}

impl PartDef {
    /// A part named `name` under `parent`.
    pub fn new(name: impl Into<String>, parent: Option<u32>) -> PartDef {
        PartDef {
            name: name.into(),
            parent,
            source: None,
        }
    }
}

impl Mesh {
    /// A mesh with positions only.
    pub fn new(positions: Vec<[f32; 3]>, triangles: Vec<[u32; 3]>) -> Mesh {
        Mesh {
            positions,
            triangles,
            ..Mesh::default()
        }
    }

    /// Checks everything later stages rely on, so they can index without further checks.
    pub fn validate(&self) -> Result<(), MeshError> {
        let vertices = self.positions.len();
        if self.triangles.len() > u32::MAX as usize {
            return Err(MeshError::TooManyTriangles {
                triangles: self.triangles.len(),
                max: u32::MAX as usize,
            });
        }
        if let Some((vertex, &position)) = self
            .positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.iter().all(|c| c.is_finite()))
        {
            return Err(MeshError::PositionNotFinite { vertex, position });
        }
        if let Some(normals) = &self.normals {
            check_len("normals", normals.len(), vertices)?;
            if let Some((vertex, &normal)) = normals
                .iter()
                .enumerate()
                .find(|(_, n)| !n.iter().all(|c| c.is_finite()))
            {
                return Err(MeshError::NormalNotFinite { vertex, normal });
            }
        }
        if let Some(colours) = &self.colours {
            check_len("colours", colours.len(), vertices)?;
        }
        for (triangle, t) in self.triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i as usize >= vertices) {
                return Err(MeshError::IndexOutOfRange {
                    triangle,
                    index,
                    vertices,
                });
            }
        }
        if let Some(ids) = &self.part_ids {
            check_len("part ids", ids.len(), self.triangles.len())?;
            if let Some((triangle, &part)) = ids
                .iter()
                .enumerate()
                .find(|(_, &p)| p as usize >= self.parts.len())
            {
                return Err(MeshError::PartOutOfRange {
                    triangle,
                    part,
                    parts: self.parts.len(),
                });
            }
        }
        if let Some((part, def)) = self
            .parts
            .iter()
            .enumerate()
            .find(|(i, d)| d.parent.is_some_and(|p| p as usize >= *i))
        {
            return Err(MeshError::PartParent {
                part,
                parent: def.parent.unwrap_or_default(),
            });
        }
        if let Some(materials) = &self.materials {
            check_len("materials", materials.len(), self.triangles.len())?;
            let table = self.material_table.len();
            if let Some((triangle, &material)) = materials
                .iter()
                .enumerate()
                .find(|(_, &m)| usize::from(m) >= table)
            {
                return Err(MeshError::MaterialOutOfRange {
                    triangle,
                    material,
                    materials: table,
                });
            }
        }
        Ok(())
    }

    /// The box around every vertex some triangle uses (unused vertices do not widen the scene).
    pub fn bounds(&self) -> Bounds {
        let mut b = Bounds::EMPTY;
        for t in 0..self.triangles.len() {
            if let Some(corners) = self.corners(t) {
                for p in corners {
                    b.extend(p);
                }
            }
        }
        b
    }

    /// The three corner positions of triangle `t`, or `None` when `t` or an index is out of range.
    pub fn corners(&self, t: usize) -> Option<[[f32; 3]; 3]> {
        let [a, b, c] = *self.triangles.get(t)?;
        Some([
            *self.positions.get(a as usize)?,
            *self.positions.get(b as usize)?,
            *self.positions.get(c as usize)?,
        ])
    }

    /// The box around triangle `t`'s corners ([`Bounds::EMPTY`] when `t` is out of range).
    pub fn triangle_bounds(&self, t: usize) -> Bounds {
        self.corners(t)
            .map_or(Bounds::EMPTY, |c| Bounds::of_points(&c))
    }

    /// Whether the mesh has vertex normals.
    pub fn has_normals(&self) -> bool {
        self.normals.is_some()
    }

    /// Whether the mesh has vertex colours.
    pub fn has_colours(&self) -> bool {
        self.colours.is_some()
    }

    /// Whether the mesh has per-triangle materials.
    pub fn has_materials(&self) -> bool {
        self.materials.is_some()
    }
}

fn check_len(what: &'static str, len: usize, expected: usize) -> Result<(), MeshError> {
    if len == expected {
        Ok(())
    } else {
        Err(MeshError::AttributeLength {
            what,
            len,
            expected,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> Mesh {
        Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
                [9.0, 9.0, 9.0],
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    #[test]
    fn bounds_cover_only_used_vertices() {
        let b = quad().bounds();
        assert_eq!(
            b,
            Bounds {
                min: [0.0; 3],
                max: [1.0, 1.0, 0.0]
            }
        );
        assert_eq!(b.longest_axis(), 0);
        assert!(Mesh::default().bounds().is_empty());
    }

    #[test]
    fn validation_finds_each_problem() {
        assert_eq!(quad().validate(), Ok(()));
        let mut m = quad();
        m.triangles.push([0, 1, 5]);
        assert_eq!(
            m.validate(),
            Err(MeshError::IndexOutOfRange {
                triangle: 2,
                index: 5,
                vertices: 5
            })
        );
        let mut m = quad();
        m.positions[1][2] = f32::NAN;
        assert!(matches!(
            m.validate(),
            Err(MeshError::PositionNotFinite { vertex: 1, .. })
        ));
        let mut m = quad();
        m.colours = Some(vec![[0; 4]; 2]);
        assert!(matches!(
            m.validate(),
            Err(MeshError::AttributeLength {
                what: "colours",
                ..
            })
        ));
        let mut m = quad();
        m.materials = Some(vec![0, 1]);
        m.material_table = vec![Material::default()];
        assert_eq!(
            m.validate(),
            Err(MeshError::MaterialOutOfRange {
                triangle: 1,
                material: 1,
                materials: 1
            })
        );
    }

    #[test]
    fn half_diagonal_never_understates() {
        let b = Bounds {
            min: [0.0; 3],
            max: [1.0, 1.0, 1.0],
        };
        let r = b.half_diagonal_up().unwrap_or(0.0);
        assert!(f64::from(r) >= 0.5 * 3f64.sqrt());
        assert!(f64::from(r) - 0.5 * 3f64.sqrt() < 1e-6);
        let point = Bounds {
            min: [2.0; 3],
            max: [2.0; 3],
        };
        assert_eq!(point.half_diagonal_up(), Some(0.0));
        let huge = Bounds {
            min: [-f32::MAX; 3],
            max: [f32::MAX; 3],
        };
        assert_eq!(huge.half_diagonal_up(), None);
    }
}
