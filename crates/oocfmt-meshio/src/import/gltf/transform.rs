//! Node transforms in f64: glTF's column-major matrices and T·R·S, composed parent · child.
//! Only affine transforms are valid glTF, so a transform is kept as its top three rows.

/// An affine transform: `rows[i] = [m_i0, m_i1, m_i2, t_i]`, so `p' = L p + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Affine {
    rows: [[f64; 4]; 3],
}

impl Affine {
    pub(super) const IDENTITY: Affine = Affine {
        rows: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ],
    };

    /// A glTF `matrix`: 16 numbers, column by column. Its bottom row must be `0 0 0 1`.
    pub(super) fn from_column_major(m: &[f32; 16]) -> Result<Affine, String> {
        let at = |row: usize, col: usize| f64::from(m[col * 4 + row]);
        if [at(3, 0), at(3, 1), at(3, 2), at(3, 3)] != [0.0, 0.0, 0.0, 1.0] {
            return Err(format!(
                "matrix is not affine: its bottom row is [{}, {}, {}, {}], not [0, 0, 0, 1]",
                at(3, 0),
                at(3, 1),
                at(3, 2),
                at(3, 3)
            ));
        }
        let mut rows = [[0.0; 4]; 3];
        for (r, row) in rows.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = at(r, c);
            }
        }
        Ok(Affine { rows })
    }

    /// `T · R · S` from a translation, a rotation quaternion `[x, y, z, w]` and a scale. The
    /// quaternion is normalised (exporters round it); a zero or non-finite one is an error.
    pub(super) fn from_trs(t: [f32; 3], q: [f32; 4], s: [f32; 3]) -> Result<Affine, String> {
        let q = q.map(f64::from);
        let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !(norm.is_finite() && norm > 0.0) {
            return Err(format!("rotation {q:?} is not a usable quaternion"));
        }
        let [x, y, z, w] = q.map(|c| c / norm);
        let r = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - z * w),
                2.0 * (x * z + y * w),
            ],
            [
                2.0 * (x * y + z * w),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - x * w),
            ],
            [
                2.0 * (x * z - y * w),
                2.0 * (y * z + x * w),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        let mut rows = [[0.0; 4]; 3];
        for (i, row) in rows.iter_mut().enumerate() {
            for j in 0..3 {
                row[j] = r[i][j] * f64::from(s[j]);
            }
            row[3] = f64::from(t[i]);
        }
        Ok(Affine { rows })
    }

    /// `self · child`: the child's transform seen from this (parent) frame.
    pub(super) fn then(&self, child: &Affine) -> Affine {
        let (a, b) = (&self.rows, &child.rows);
        let mut rows = [[0.0; 4]; 3];
        for (i, row) in rows.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
            }
            row[3] += a[i][3];
        }
        Affine { rows }
    }

    pub(super) fn is_identity(&self) -> bool {
        *self == Affine::IDENTITY
    }

    pub(super) fn apply_point(&self, p: [f64; 3]) -> [f64; 3] {
        self.rows
            .map(|r| r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + r[3])
    }

    /// The determinant of the linear part: negative when the transform mirrors.
    pub(super) fn determinant(&self) -> f64 {
        let m = &self.rows;
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }

    /// A matrix proportional, with a positive factor, to the inverse transpose of the linear
    /// part: the cofactor matrix times the sign of the determinant. Normals transformed by it
    /// only need renormalising, and singular transforms need no division by zero.
    pub(super) fn normal_matrix(&self) -> [[f64; 3]; 3] {
        let m = &self.rows;
        let cof = |r0: usize, r1: usize, c0: usize, c1: usize| {
            m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]
        };
        let sign = if self.determinant() < 0.0 { -1.0 } else { 1.0 };
        [
            [cof(1, 2, 1, 2), -cof(1, 2, 0, 2), cof(1, 2, 0, 1)],
            [-cof(0, 2, 1, 2), cof(0, 2, 0, 2), -cof(0, 2, 0, 1)],
            [cof(0, 1, 1, 2), -cof(0, 1, 0, 2), cof(0, 1, 0, 1)],
        ]
        .map(|row| row.map(|v| v * sign))
    }
}

/// `m · v`, renormalised; `None` when the result has no direction.
pub(super) fn transform_normal(m: &[[f64; 3]; 3], v: [f64; 3]) -> Option<[f32; 3]> {
    let n = m.map(|r| r[0] * v[0] + r[1] * v[1] + r[2] * v[2]);
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    (len.is_finite() && len > 0.0).then(|| n.map(|c| (c / len) as f32))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn trs_is_translate_after_rotate_after_scale() -> Result<(), String> {
        // 90° about z: (x, y) -> (-y, x).
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let m = Affine::from_trs([10.0, 0.0, 0.0], [0.0, 0.0, h, h], [2.0, 1.0, 1.0])?;
        // Scale first: (1,0,0) -> (2,0,0); rotate: (0,2,0); translate: (10,2,0).
        assert!(close(m.apply_point([1.0, 0.0, 0.0]), [10.0, 2.0, 0.0]));
        Ok(())
    }

    #[test]
    fn column_major_puts_translation_in_the_last_column() -> Result<(), String> {
        let mut c = [0.0f32; 16];
        c[0] = 1.0;
        c[5] = 1.0;
        c[10] = 1.0;
        c[15] = 1.0;
        c[12] = 5.0;
        c[13] = 6.0;
        c[14] = 7.0;
        let m = Affine::from_column_major(&c)?;
        assert_eq!(m.apply_point([1.0, 1.0, 1.0]), [6.0, 7.0, 8.0]);
        c[3] = 1.0;
        assert!(Affine::from_column_major(&c).is_err());
        Ok(())
    }

    #[test]
    fn normal_matrix_keeps_normals_perpendicular_to_surfaces() -> Result<(), String> {
        // A non-uniform scale with a mirror: the normal of the plane x + y = 0 must stay
        // perpendicular to the transformed plane and point to the transformed outside.
        let m = Affine::from_trs([0.0; 3], [0.0, 0.0, 0.0, 1.0], [-3.0, 1.0, 2.0])?;
        assert!(m.determinant() < 0.0);
        let n = transform_normal(&m.normal_matrix(), [1.0, 1.0, 0.0]).ok_or("no normal")?;
        let along = m.apply_point([1.0, -1.0, 0.0]);
        let dot = f64::from(n[0]) * along[0] + f64::from(n[1]) * along[1];
        assert!(dot.abs() < 1e-6, "{n:?}");
        // The outside point (1, 1, 0) maps to (-3, 1, 0); the normal must point towards it.
        let outside = m.apply_point([1.0, 1.0, 0.0]);
        assert!(f64::from(n[0]) * outside[0] + f64::from(n[1]) * outside[1] > 0.0);
        Ok(())
    }

    #[test]
    fn composition_applies_the_child_first() -> Result<(), String> {
        let parent = Affine::from_trs([1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], [2.0; 3])?;
        let child = Affine::from_trs([0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0], [1.0; 3])?;
        // child: (0,0,0) -> (0,1,0); parent: -> (1,2,0).
        assert_eq!(parent.then(&child).apply_point([0.0; 3]), [1.0, 2.0, 0.0]);
        Ok(())
    }
}
