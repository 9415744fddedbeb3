//! The 4-byte shading sample of voxels and proxies (spec §5) and the voxel built from it.

use crate::error::{bad, Code, Result};

/// A packed normal + colour sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Sample(pub u32);

const SINGLE: u32 = 1 << 31;
const EMPTY: u32 = 1 << 30;

fn quant5(c: f32) -> u32 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    (c * 31.0).round() as u32
}

fn quant6(c: f32) -> u32 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(-1.0, 1.0) };
    ((c * 31.0).round() as i32 as u32) & 0x3f
}

fn signed6(bits: u32) -> i32 {
    ((bits as i32) << 26) >> 26
}

impl Sample {
    /// Packs a normal (any length; zero or non-finite gives +z) and a linear RGB colour in 0..=1.
    pub fn pack(normal: [f32; 3], colour: [f32; 3]) -> Sample {
        let n = if normal.iter().all(|c| c.is_finite()) && normal.iter().any(|&c| c != 0.0) {
            normal
        } else {
            [0.0, 0.0, 1.0]
        };
        let axis = (0..3)
            .max_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs()))
            .unwrap_or(2);
        let m = n[axis].abs();
        let u = n[(axis + 1) % 3] / m;
        let v = n[(axis + 2) % 3] / m;
        let bits = quant5(colour[0])
            | (quant5(colour[1]) << 5)
            | (quant5(colour[2]) << 10)
            | (u32::from(n[axis] < 0.0) << 15)
            | ((axis as u32) << 16)
            | (quant6(u) << 18)
            | (quant6(v) << 24);
        Sample(bits)
    }

    /// The proxy sample for a direction from which nothing is seen.
    pub const EMPTY: Sample = Sample(EMPTY);

    /// The same sample with the single flag (bit 31) set or cleared.
    pub fn with_single(self, single: bool) -> Sample {
        Sample(if single {
            self.0 | SINGLE
        } else {
            self.0 & !SINGLE
        })
    }

    /// Whether bit 31 is set: the only sample of a 1-sample voxel.
    pub fn is_single(self) -> bool {
        self.0 & SINGLE != 0
    }

    /// Whether bit 30 is set: a proxy direction from which nothing is seen.
    pub fn is_empty(self) -> bool {
        self.0 & EMPTY != 0
    }

    /// The colour, linear RGB in 0..=1 in steps of 1/31.
    pub fn colour(self) -> [f32; 3] {
        let c = |s: u32| ((self.0 >> s) & 31) as f32 / 31.0;
        [c(0), c(5), c(10)]
    }

    /// The unit normal. Only meaningful on a sample that passed [`Sample::check`].
    pub fn normal(self) -> [f32; 3] {
        let axis = ((self.0 >> 16) & 3).min(2) as usize;
        let sign = if self.0 & (1 << 15) != 0 { -1.0 } else { 1.0 };
        let mut n = [0.0f32; 3];
        n[axis] = sign;
        n[(axis + 1) % 3] = signed6(self.0 >> 18) as f32 / 31.0;
        n[(axis + 2) % 3] = signed6(self.0 >> 24) as f32 / 31.0;
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        [n[0] / len, n[1] / len, n[2] / len]
    }

    /// Checks the fields valid in every sample: axis < 3 and u, v ≠ −32.
    pub fn check(self) -> Result<()> {
        if self.is_empty() {
            return Ok(());
        }
        if (self.0 >> 16) & 3 == 3 {
            return bad(
                Code::Voxel,
                format!("sample {:#010x}: normal axis 3", self.0),
            );
        }
        if (self.0 >> 18) & 0x3f == 0x20 || (self.0 >> 24) & 0x3f == 0x20 {
            return bad(
                Code::Voxel,
                format!("sample {:#010x}: normal component −32", self.0),
            );
        }
        Ok(())
    }
}

/// A LOD voxel: one sample for the whole cell, or one per face (−x, +x, −y, +y, −z, +z).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Voxel {
    /// One sample for every direction (stored with the single flag; decoded without it).
    Single(Sample),
    /// One sample per cell face, in the order −x, +x, −y, +y, −z, +z.
    Six([Sample; 6]),
}

impl Voxel {
    /// Bytes the voxel takes in the LOD area: 4 or 24.
    pub fn byte_len(&self) -> usize {
        match self {
            Voxel::Single(_) => 4,
            Voxel::Six(_) => 24,
        }
    }

    /// Appends the voxel's samples to `v`, setting the single flag on a 1-sample voxel and
    /// clearing it on the six of a 6-sample one.
    pub fn encode_into(&self, v: &mut Vec<u8>) {
        match self {
            Voxel::Single(s) => v.extend_from_slice(&s.with_single(true).0.to_le_bytes()),
            Voxel::Six(s) => {
                for x in s {
                    v.extend_from_slice(&x.with_single(false).0.to_le_bytes());
                }
            }
        }
    }

    /// Decodes the voxel at byte `off` of a voxel area.
    #[inline]
    pub fn decode(area: &[u8], off: usize) -> Result<Voxel> {
        let word = |i: usize| -> Result<Sample> {
            let at = off + 4 * i;
            match area.get(at..at + 4) {
                Some(&[a, b, c, d]) => Ok(Sample(u32::from_le_bytes([a, b, c, d]))),
                _ => bad(
                    Code::Voxel,
                    format!(
                        "voxel at {off} runs past the voxel area ({} bytes)",
                        area.len()
                    ),
                ),
            }
        };
        if off % 4 != 0 {
            return bad(
                Code::Voxel,
                format!("voxel offset {off} is not a multiple of 4"),
            );
        }
        let first = word(0)?;
        let check = |s: Sample| -> Result<()> {
            if s.is_empty() {
                return bad(
                    Code::Voxel,
                    format!("voxel sample {:#010x} has the proxy-only empty bit", s.0),
                );
            }
            s.check()
        };
        check(first)?;
        if first.is_single() {
            return Ok(Voxel::Single(first.with_single(false)));
        }
        let mut six = [first; 6];
        for (i, slot) in six.iter_mut().enumerate().skip(1) {
            let s = word(i)?;
            if s.is_single() {
                return bad(
                    Code::Voxel,
                    format!("sample {i} of the 6-sample voxel at {off} has the single flag"),
                );
            }
            check(s)?;
            *slot = s;
        }
        Ok(Voxel::Six(six))
    }

    /// The sample shown for a ray entering through face `face` (0..6, as in the layout).
    pub fn face(&self, face: usize) -> Sample {
        match self {
            Voxel::Single(s) => *s,
            Voxel::Six(s) => s[face.min(5)],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_normals_and_colours_survive_packing() {
        let s = Sample::pack([0.0, -2.0, 0.0], [1.0, 0.0, 0.5]);
        assert_eq!(s.normal(), [0.0, -1.0, 0.0]);
        let c = s.colour();
        assert_eq!(c[0], 1.0);
        assert_eq!(c[1], 0.0);
        assert!((c[2] - 0.5).abs() < 1.0 / 31.0);
    }

    #[test]
    fn packed_normals_stay_within_quantisation_error() {
        for i in 0..200 {
            let t = i as f32 * 0.37;
            let n = [t.sin(), (t * 1.3).cos(), (t * 0.7).sin() - 0.2];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let m = Sample::pack(n, [0.0; 3]).normal();
            let dot = (n[0] * m[0] + n[1] * m[1] + n[2] * m[2]) / len;
            assert!(dot > 0.999, "{n:?} -> {m:?}");
        }
    }

    #[test]
    fn nan_inputs_give_a_valid_sample() {
        let s = Sample::pack([f32::NAN, 0.0, 0.0], [f32::NAN, 2.0, -1.0]);
        assert!(s.check().is_ok());
        assert!(s.normal().iter().all(|c| c.is_finite()));
    }
}
