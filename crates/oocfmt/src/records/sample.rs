//! The 4-byte shading sample of voxels and proxies (spec §5) and the voxel built from it.

use crate::error::{bad, Code, Result};

/// A packed normal + colour sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct Sample(pub u32);

const SINGLE: u32 = 1 << 31;
const EMPTY: u32 = 1 << 30;
/// Bit 30 on a voxel's first sample in a file with `LOD_FILTERED`: footprint words follow.
const FOOTPRINTS: u32 = EMPTY;

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

    /// Checks the fields valid in every sample: axis < 3 and u, v ≠ −32 (bit 30 is left to
    /// the caller: a proxy's empty flag, a voxel's footprint flag).
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

/// What a sample's footprint looks like beyond its mean normal and colour (spec §5.1): how
/// much the normals seen disagree, and how much of the footprint the surface covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct Footprint {
    /// σ × 255: the length of the mean of the unit normals seen, each turned to face the ray.
    pub shade: u8,
    /// α × 255: the share of the footprint in which the surface is hit.
    pub coverage: u8,
}

impl Default for Footprint {
    fn default() -> Self {
        Footprint::FULL
    }
}

impl Footprint {
    /// σ = α = 1: an opaque sample whose normals agree, what every unfiltered sample means.
    pub const FULL: Footprint = Footprint {
        shade: 255,
        coverage: 255,
    };

    /// The footprint of shade `shade` and coverage `coverage`, each clamped to 0..=1 and
    /// rounded to the nearest 1/255 (NaN counts as 1).
    pub fn new(shade: f64, coverage: f64) -> Footprint {
        let q = |x: f64| {
            if x.is_nan() {
                255
            } else {
                (x.clamp(0.0, 1.0) * 255.0).round() as u8
            }
        };
        Footprint {
            shade: q(shade),
            coverage: q(coverage),
        }
    }

    /// σ in 0..=1: the factor on the headlight's (or a point light's) cosine.
    pub fn shade_f32(self) -> f32 {
        f32::from(self.shade) / 255.0
    }

    /// α in 0..=1: the share of what the ray shows that is this sample.
    pub fn coverage_f32(self) -> f32 {
        f32::from(self.coverage) / 255.0
    }

    /// Whether this is [`Footprint::FULL`]: nothing for a writer to store.
    pub fn is_full(self) -> bool {
        self == Footprint::FULL
    }

    fn bits(self) -> u32 {
        u32::from(self.shade) | (u32::from(self.coverage) << 8)
    }

    fn from_bits(bits: u32) -> Footprint {
        Footprint {
            shade: (bits & 0xff) as u8,
            coverage: ((bits >> 8) & 0xff) as u8,
        }
    }
}

/// A LOD voxel: one sample for the whole cell, or one per face (−x, +x, −y, +y, −z, +z), each
/// with its footprint ([`Footprint::FULL`] where the file stores none).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Voxel {
    /// One sample for every direction (stored with the single flag; decoded without it).
    Single(Sample, Footprint),
    /// One sample per cell face, in the order −x, +x, −y, +y, −z, +z.
    Six([Sample; 6], [Footprint; 6]),
}

impl Voxel {
    /// A 1-sample voxel without a footprint (opaque, σ = 1).
    pub fn single(s: Sample) -> Voxel {
        Voxel::Single(s, Footprint::FULL)
    }

    /// A 6-sample voxel without footprints.
    pub fn six(s: [Sample; 6]) -> Voxel {
        Voxel::Six(s, [Footprint::FULL; 6])
    }

    /// Whether a file with `LOD_FILTERED` stores footprint words for this voxel: some
    /// footprint is not [`Footprint::FULL`].
    pub fn has_footprints(&self) -> bool {
        match self {
            Voxel::Single(_, f) => !f.is_full(),
            Voxel::Six(_, f) => f.iter().any(|f| !f.is_full()),
        }
    }

    /// Bytes [`Voxel::encode_into`] writes for the voxel in a file with (`filtered`) or without
    /// `LOD_FILTERED`: 4 or 24, or 8 or 36 with footprint words. A stored voxel may take more
    /// (footprint words that say full, spec §5.1): [`Voxel::decode_sized`] gives that length.
    pub fn byte_len(&self, filtered: bool) -> usize {
        let words = filtered && self.has_footprints();
        match (self, words) {
            (Voxel::Single(..), false) => 4,
            (Voxel::Single(..), true) => 8,
            (Voxel::Six(..), false) => 24,
            (Voxel::Six(..), true) => 36,
        }
    }

    /// Appends the voxel to `v`: the single flag set on a 1-sample voxel and cleared on the six
    /// of a 6-sample one, and, in a `filtered` file, the footprint flag and words where
    /// [`Voxel::has_footprints`] (elsewhere the footprints are dropped).
    pub fn encode_into(&self, v: &mut Vec<u8>, filtered: bool) {
        let words = filtered && self.has_footprints();
        let flag = |s: Sample| {
            if words {
                s.0 | FOOTPRINTS
            } else {
                s.0 & !FOOTPRINTS
            }
        };
        match self {
            Voxel::Single(s, f) => {
                v.extend_from_slice(&flag(s.with_single(true)).to_le_bytes());
                if words {
                    v.extend_from_slice(&f.bits().to_le_bytes());
                }
            }
            Voxel::Six(s, f) => {
                for (i, x) in s.iter().enumerate() {
                    let x = x.with_single(false);
                    let w = if i == 0 { flag(x) } else { x.0 & !FOOTPRINTS };
                    v.extend_from_slice(&w.to_le_bytes());
                }
                if words {
                    for pair in f.chunks(2) {
                        let w = pair
                            .iter()
                            .enumerate()
                            .fold(0u32, |w, (k, f)| w | (f.bits() << (16 * k)));
                        v.extend_from_slice(&w.to_le_bytes());
                    }
                }
            }
        }
    }

    /// Decodes the voxel at byte `off` of a LOD area of a file with (`filtered`) or without
    /// `LOD_FILTERED`.
    #[inline]
    pub fn decode(area: &[u8], off: usize, filtered: bool) -> Result<Voxel> {
        Self::decode_sized(area, off, filtered).map(|(v, _)| v)
    }

    /// [`Voxel::decode`], with the bytes the voxel takes as stored: its bit 30 says whether
    /// footprint words follow, whatever they hold (a writer should, not must, leave out words
    /// that say full), so what follows it is found after them.
    #[inline]
    pub fn decode_sized(area: &[u8], off: usize, filtered: bool) -> Result<(Voxel, usize)> {
        let word = |i: usize| -> Result<u32> {
            let at = off + 4 * i;
            match area.get(at..at + 4) {
                Some(&[a, b, c, d]) => Ok(u32::from_le_bytes([a, b, c, d])),
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
        let words = first & FOOTPRINTS != 0;
        if words && !filtered {
            return bad(
                Code::Voxel,
                format!("voxel sample {first:#010x} has bit 30 set in a file without LOD_FILTERED"),
            );
        }
        let first = Sample(first & !FOOTPRINTS);
        first.check()?;
        if first.is_single() {
            let foot = if words {
                let w = word(1)?;
                if w >> 16 != 0 {
                    return bad(
                        Code::Voxel,
                        format!("footprint word {w:#010x} of the voxel at {off}: bits 16-31 are not zero"),
                    );
                }
                Footprint::from_bits(w)
            } else {
                Footprint::FULL
            };
            let len = if words { 8 } else { 4 };
            return Ok((Voxel::Single(first.with_single(false), foot), len));
        }
        let mut six = [first; 6];
        for (i, slot) in six.iter_mut().enumerate().skip(1) {
            let s = Sample(word(i)?);
            if s.is_single() || s.0 & FOOTPRINTS != 0 {
                return bad(
                    Code::Voxel,
                    format!("sample {i} of the 6-sample voxel at {off} has bit 31 or 30 set"),
                );
            }
            s.check()?;
            *slot = s;
        }
        let mut feet = [Footprint::FULL; 6];
        if words {
            for (k, pair) in feet.chunks_mut(2).enumerate() {
                let w = word(6 + k)?;
                for (j, f) in pair.iter_mut().enumerate() {
                    *f = Footprint::from_bits(w >> (16 * j));
                }
            }
        }
        let len = if words { 36 } else { 24 };
        Ok((Voxel::Six(six, feet), len))
    }

    /// The sample and footprint shown for a ray entering through face `face` (0..6, as in the
    /// layout).
    pub fn face(&self, face: usize) -> (Sample, Footprint) {
        match self {
            Voxel::Single(s, f) => (*s, *f),
            Voxel::Six(s, f) => (s[face.min(5)], f[face.min(5)]),
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

    fn six_with(feet: [Footprint; 6]) -> Voxel {
        let mut s = [Sample(0); 6];
        for (k, x) in s.iter_mut().enumerate() {
            *x = Sample::pack([1.0, k as f32 / 6.0, 0.0], [0.5; 3]);
        }
        Voxel::Six(s, feet)
    }

    fn word_at(v: &[u8], i: usize) -> u32 {
        let mut w = [0u8; 4];
        w.copy_from_slice(&v[4 * i..4 * i + 4]);
        u32::from_le_bytes(w)
    }

    #[test]
    fn footprint_words_follow_the_spec_layout() {
        let feet: [Footprint; 6] = std::array::from_fn(|k| Footprint {
            shade: 10 + k as u8,
            coverage: 100 + k as u8,
        });
        let vox = six_with(feet);
        let mut v = Vec::new();
        vox.encode_into(&mut v, true);
        assert_eq!((v.len(), vox.byte_len(true)), (36, 36));
        // Bit 30 on the first sample only; word k holds faces 2k (low half) and 2k + 1.
        assert_ne!(word_at(&v, 0) & FOOTPRINTS, 0);
        assert!((1..6).all(|i| word_at(&v, i) & (FOOTPRINTS | SINGLE) == 0));
        for k in 0..3 {
            let lo = u32::from(10 + 2 * k as u8) | u32::from(100 + 2 * k as u8) << 8;
            let hi = u32::from(11 + 2 * k as u8) | u32::from(101 + 2 * k as u8) << 8;
            assert_eq!(word_at(&v, 6 + k), lo | hi << 16, "word {k}");
        }
        assert_eq!(Voxel::decode(&v, 0, true).ok(), Some(vox));
        let one = Voxel::Single(
            Sample::pack([0.0, 0.0, 1.0], [1.0; 3]),
            Footprint::new(0.5, 0.2),
        );
        let mut v = Vec::new();
        one.encode_into(&mut v, true);
        assert_eq!((v.len(), one.byte_len(true)), (8, 8));
        assert_eq!(word_at(&v, 0) & (FOOTPRINTS | SINGLE), FOOTPRINTS | SINGLE);
        assert_eq!(word_at(&v, 1), 128 | 51 << 8);
        assert_eq!(Voxel::decode(&v, 0, true).ok(), Some(one));
    }

    #[test]
    fn full_footprints_cost_nothing_and_unfiltered_files_drop_them() {
        let full = six_with([Footprint::FULL; 6]);
        let part = six_with(std::array::from_fn(|k| {
            if k == 3 {
                Footprint::new(1.0, 0.5)
            } else {
                Footprint::FULL
            }
        }));
        let mut a = Vec::new();
        full.encode_into(&mut a, true);
        let mut b = Vec::new();
        part.encode_into(&mut b, false);
        // Both are the 24 bytes a 1.1 writer makes; each decodes FULL.
        assert_eq!(
            (a.len(), full.byte_len(true), part.byte_len(false)),
            (24, 24, 24)
        );
        assert_eq!(a, b);
        for filtered in [false, true] {
            assert_eq!(Voxel::decode(&b, 0, filtered).ok(), Some(full));
        }
    }

    #[test]
    fn footprint_rules_are_voxel_errors() {
        let code = |v: &[u8], filtered| Voxel::decode(v, 0, filtered).err().map(|e| e.code());
        let one = Voxel::Single(
            Sample::pack([0.0, 0.0, 1.0], [1.0; 3]),
            Footprint::new(0.5, 0.2),
        );
        let mut v = Vec::new();
        one.encode_into(&mut v, true);
        // Bit 30 in an unfiltered file; footprint word missing; high half set.
        assert_eq!(code(&v, false), Some(Code::Voxel));
        assert_eq!(code(&v[..4], true), Some(Code::Voxel));
        let mut high = v.clone();
        high[6] = 1;
        assert_eq!(code(&high, true), Some(Code::Voxel));
        let six = six_with([Footprint::new(0.5, 0.5); 6]);
        let mut v = Vec::new();
        six.encode_into(&mut v, true);
        assert_eq!(code(&v[..32], true), Some(Code::Voxel));
        for i in 1..6 {
            let mut w = v.clone();
            w[4 * i + 3] |= 0x40;
            assert_eq!(code(&w, true), Some(Code::Voxel), "bit 30 on sample {i}");
        }
    }

    #[test]
    fn stored_full_footprint_words_keep_their_length() {
        // Bit 30 with words that say full: valid (spec §5.1 SHOULD), 8 and 36 bytes as stored.
        let s = Sample::pack([0.0, 0.0, 1.0], [1.0; 3]);
        let mut v = Vec::new();
        Voxel::Single(s, Footprint::new(0.5, 0.5)).encode_into(&mut v, true);
        v[4..8].copy_from_slice(&0xffffu32.to_le_bytes());
        let got = Voxel::decode_sized(&v, 0, true).ok();
        assert_eq!(got, Some((Voxel::single(s), 8)));
        let mut v = Vec::new();
        six_with([Footprint::new(0.5, 0.5); 6]).encode_into(&mut v, true);
        v[24..].fill(0xff);
        let got = Voxel::decode_sized(&v, 0, true)
            .ok()
            .map(|(x, n)| (x.has_footprints(), n));
        assert_eq!(got, Some((false, 36)));
    }

    #[test]
    fn footprints_quantise_to_the_nearest_step() {
        assert_eq!(Footprint::new(1.0, 1.0), Footprint::FULL);
        assert_eq!(Footprint::new(f64::NAN, 2.0), Footprint::FULL);
        assert_eq!(
            Footprint::new(-1.0, 0.5),
            Footprint {
                shade: 0,
                coverage: 128
            }
        );
        let f = Footprint::new(0.3, 0.71);
        let step = 0.5 / 255.0 + 1e-6;
        assert!((f.shade_f32() - 0.3).abs() <= step);
        assert!((f.coverage_f32() - 0.71).abs() <= step);
    }

    #[test]
    fn nan_inputs_give_a_valid_sample() {
        let s = Sample::pack([f32::NAN, 0.0, 0.0], [f32::NAN, 2.0, -1.0]);
        assert!(s.check().is_ok());
        assert!(s.normal().iter().all(|c| c.is_finite()));
    }
}
