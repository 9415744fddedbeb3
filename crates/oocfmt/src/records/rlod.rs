//! R-LOD records (spec §6.4, after Yoon et al. 2006): a plane standing for a LOD node's
//! triangles, with their mean colour, a quantized bound on how far they lie from the plane and
//! the extent expansion that hides cracks between neighbouring R-LODs. 24 bytes, fixed layout.
//!
//! Which LOD kinds a file holds ([`LodKinds`]) is announced by header feature bits; it fixes the
//! layout of a treelet block's LOD area, where each LOD node's entry is its voxel (if the file
//! has voxels) followed by its R-LOD record (if it has R-LODs).

use crate::bytes::{f32_at, u32_at, PutLe};
use crate::error::{bad, Code, Result};
use crate::header::{
    Header, INCOMPAT_LOD_FILTERED, INCOMPAT_LOD_NO_VOXELS, INCOMPAT_LOD_RLODS, INCOMPAT_PART_IDS,
    VERSION_MINOR_BASE, VERSION_MINOR_FILTERED, VERSION_MINOR_PARTS, VERSION_MINOR_RLODS,
};

/// Bytes of one R-LOD record in a LOD area.
pub const RLOD_LEN: usize = 24;
/// A stored normal's squared length must lie within this of 1.
pub const RLOD_NORMAL_TOLERANCE: f32 = 1e-3;
/// Deviation and expansion codes count this many steps per node radius (deviation: up to two
/// radii, the most a plane through the cell can be from a point of the cell's sphere).
const CODE_STEPS: f64 = 127.5;

/// Which LOD representations a file's LOD nodes carry (header feature bits, spec §3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LodKinds {
    /// Every LOD node's entry starts with a voxel.
    pub voxel: bool,
    /// Every LOD node's entry holds an R-LOD record (after the voxel, if any).
    pub rlod: bool,
    /// The records are pre-filtered (`LOD_FILTERED`, spec §5.1): voxels may carry footprints,
    /// R-LOD records a shade and a coverage.
    pub filtered: bool,
    /// Every LOD entry ends with a part word (`PART_IDS`, spec §6.2): the part picking at that
    /// level answers.
    pub parts: bool,
}

impl Default for LodKinds {
    /// Version 1.0 files: voxels only.
    fn default() -> Self {
        LodKinds::VOXEL
    }
}

impl LodKinds {
    /// Voxels only: every 1.0 file, and the default.
    pub const VOXEL: LodKinds = LodKinds {
        voxel: true,
        rlod: false,
        filtered: false,
        parts: false,
    };
    /// R-LODs only (`LOD_RLODS` and `LOD_NO_VOXELS`).
    pub const RLOD: LodKinds = LodKinds {
        voxel: false,
        rlod: true,
        filtered: false,
        parts: false,
    };
    /// A voxel then an R-LOD record per LOD node (`LOD_RLODS` alone).
    pub const BOTH: LodKinds = LodKinds {
        voxel: true,
        rlod: true,
        filtered: false,
        parts: false,
    };

    /// The same kinds, pre-filtered (spec §5.1): what a writer of 1.2 makes by default.
    pub const fn filtered(self) -> LodKinds {
        LodKinds {
            filtered: true,
            ..self
        }
    }

    /// The same kinds with a part word after every LOD entry (spec §6.2): a file whose part
    /// table has two or more parts.
    pub const fn with_parts(self, parts: bool) -> LodKinds {
        LodKinds { parts, ..self }
    }

    /// The kinds the header's incompatible feature bits announce. `LOD_NO_VOXELS` without
    /// `LOD_RLODS` would leave LOD nodes with nothing; the header decoder refuses it, and here it
    /// reads as voxels so a caller never sees an empty set.
    pub fn of_header(h: &Header) -> LodKinds {
        let rlod = h.incompatible_features & INCOMPAT_LOD_RLODS != 0;
        let voxel = !rlod || h.incompatible_features & INCOMPAT_LOD_NO_VOXELS == 0;
        let filtered = h.incompatible_features & INCOMPAT_LOD_FILTERED != 0;
        let parts = h.incompatible_features & INCOMPAT_PART_IDS != 0;
        LodKinds {
            voxel,
            rlod,
            filtered,
            parts,
        }
    }

    /// The incompatible feature bits that announce these kinds (none for voxels alone).
    pub fn incompatible_bits(self) -> u64 {
        let kinds = match (self.voxel, self.rlod) {
            (_, false) => 0,
            (true, true) => INCOMPAT_LOD_RLODS,
            (false, true) => INCOMPAT_LOD_RLODS | INCOMPAT_LOD_NO_VOXELS,
        };
        let filtered = if self.filtered {
            INCOMPAT_LOD_FILTERED
        } else {
            0
        };
        let parts = if self.parts { INCOMPAT_PART_IDS } else { 0 };
        kinds | filtered | parts
    }

    /// The lowest minor version that describes a file of these kinds (spec §11); a part table
    /// of one part needs 1.3 too, which the writer adds from the metadata.
    pub fn minor_version(self) -> u16 {
        if self.parts {
            VERSION_MINOR_PARTS
        } else if self.filtered {
            VERSION_MINOR_FILTERED
        } else if self.rlod {
            VERSION_MINOR_RLODS
        } else {
            VERSION_MINOR_BASE
        }
    }

    /// `voxel`, `rlod` or `voxel+rlod`.
    pub fn name(self) -> &'static str {
        match (self.voxel, self.rlod) {
            (true, true) => "voxel+rlod",
            (false, true) => "rlod",
            _ => "voxel",
        }
    }
}

/// One R-LOD record. The plane is `{x : normal · x = offset}` in stored coordinates; the
/// deviation and expansion are codes in steps of a node radius / 127.5, rounded up by
/// the writer so the bounds they decode to never fall short.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Rlod {
    /// Unit plane normal (|n|² within [`RLOD_NORMAL_TOLERANCE`] of 1), finite.
    pub normal: [f32; 3],
    /// The plane's `d` in `normal · x = d`, in stored coordinates; finite.
    pub offset: f32,
    /// Linear RGB, value / 255.
    pub colour: [u8; 3],
    /// Code of the bound on the triangles' distance from the plane; see [`Rlod::deviation`].
    pub deviation_code: u8,
    /// Code of how far outside the cell the plane still counts; see [`Rlod::expansion`].
    pub expansion_code: u8,
    /// The share of the plane's part in the cell the triangles cover, value / 255 (spec §6.4);
    /// 255 in a file without `LOD_FILTERED`.
    pub coverage: u8,
    /// The length of the area-weighted mean unit normal, value / 255; 255 without
    /// `LOD_FILTERED`.
    pub shade: u8,
}

impl Rlod {
    /// The code of the smallest stored bound ≥ `value` for a node of enclosing radius `radius`
    /// (255 at most; 0 for a zero or non-finite radius, which has nothing to bound).
    pub fn code_for(value: f64, radius: f64) -> u8 {
        if !(radius.is_finite() && radius > 0.0) || value.is_nan() || value <= 0.0 {
            return 0;
        }
        (value / radius * CODE_STEPS).ceil().min(255.0) as u8
    }

    /// Bound `code` decodes to for a node of radius `radius`.
    pub fn decode_code(code: u8, radius: f32) -> f32 {
        (f64::from(code) / CODE_STEPS * f64::from(radius)) as f32
    }

    /// The largest distance of the node's (clipped) triangles from the plane.
    pub fn deviation(&self, radius: f32) -> f32 {
        Self::decode_code(self.deviation_code, radius)
    }

    /// How far past the node's cell the plane still counts (spec §6.4).
    pub fn expansion(&self, radius: f32) -> f32 {
        Self::decode_code(self.expansion_code, radius)
    }

    /// The error radius the traversal compares with t · C: the radius of a sphere whose volume
    /// is the node's enclosing sphere plus a slab of ±deviation over its great disc,
    /// cbrt(r³ + 1.5 r² δ) (Yoon et al. 2006, §4.3), rounded up to the next f32.
    pub fn error_radius(&self, radius: f32) -> f32 {
        let r = f64::from(radius.max(0.0));
        let d = f64::from(self.deviation(radius));
        let e = (r * r * r + 1.5 * r * r * d).cbrt();
        let f = e as f32;
        if f64::from(f) < e && f.is_finite() {
            // The next f32 up (e > 0 here, so its bits grow with it).
            f32::from_bits(f.to_bits() + 1)
        } else {
            f
        }
    }

    /// The colour as linear RGB in 0..=1.
    pub fn colour_f32(&self) -> [f32; 3] {
        self.colour.map(|c| f32::from(c) / 255.0)
    }

    /// The coverage as a share in 0..=1.
    pub fn coverage_f32(&self) -> f32 {
        f32::from(self.coverage) / 255.0
    }

    /// The shade factor as a share in 0..=1.
    pub fn shade_f32(&self) -> f32 {
        f32::from(self.shade) / 255.0
    }

    /// Appends the record's 24 bytes to `v`, reserved bytes zero; coverage and shade only in a
    /// `filtered` file (where they are fields; elsewhere reserved).
    pub fn encode_into(&self, v: &mut Vec<u8>, filtered: bool) {
        for c in self.normal {
            v.put_f32(c);
        }
        v.put_f32(self.offset);
        v.extend_from_slice(&self.colour);
        v.push(if filtered { self.coverage } else { 0 });
        v.push(self.deviation_code);
        v.push(self.expansion_code);
        v.push(if filtered { self.shade } else { 0 });
        v.push(0);
    }

    /// Decodes the record at byte `at` of a LOD area, checking every field; `filtered` says
    /// whether the file has `LOD_FILTERED` (coverage and shade are then fields, else reserved
    /// and decoded as 255).
    pub fn decode(area: &[u8], at: usize, filtered: bool) -> Result<Rlod> {
        let c = Code::Rlod;
        if at % 4 != 0 || area.len() < at.saturating_add(RLOD_LEN) {
            return bad(
                c,
                format!(
                    "R-LOD record at {at} is unaligned or past the end of the {}-byte LOD area",
                    area.len()
                ),
            );
        }
        let normal = [
            f32_at(area, at, c)?,
            f32_at(area, at + 4, c)?,
            f32_at(area, at + 8, c)?,
        ];
        let offset = f32_at(area, at + 12, c)?;
        let word = u32_at(area, at + 16, c)?;
        let codes = u32_at(area, at + 20, c)?;
        if normal.iter().any(|x| !x.is_finite()) || !offset.is_finite() {
            return bad(
                c,
                format!("R-LOD record at {at}: plane {normal:?}, {offset} is not finite"),
            );
        }
        let len2 = normal.iter().map(|x| x * x).sum::<f32>();
        if (len2 - 1.0).abs() > RLOD_NORMAL_TOLERANCE {
            return bad(
                c,
                format!(
                    "R-LOD record at {at}: normal {normal:?} is not a unit vector (|n|² = {len2})"
                ),
            );
        }
        let [r, g, b, coverage] = word.to_le_bytes();
        let [dev, exp, shade, reserved] = codes.to_le_bytes();
        if reserved != 0 || (!filtered && (coverage != 0 || shade != 0)) {
            return bad(
                c,
                format!("R-LOD record at {at}: reserved bytes are not zero"),
            );
        }
        let (coverage, shade) = if filtered {
            (coverage, shade)
        } else {
            (255, 255)
        };
        Ok(Rlod {
            normal,
            offset,
            colour: [r, g, b],
            deviation_code: dev,
            expansion_code: exp,
            coverage,
            shade,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Rlod {
        Rlod {
            normal: [0.6, 0.0, 0.8],
            offset: -2.5,
            colour: [10, 200, 255],
            deviation_code: 17,
            expansion_code: 18,
            coverage: 255,
            shade: 255,
        }
    }

    #[test]
    fn round_trip_at_an_offset() {
        let mut v = vec![0u8; 4];
        sample().encode_into(&mut v, false);
        assert_eq!(v.len(), 4 + RLOD_LEN);
        assert_eq!(Rlod::decode(&v, 4, false).ok(), Some(sample()));
        let filtered = Rlod {
            coverage: 77,
            shade: 201,
            ..sample()
        };
        let mut v = Vec::new();
        filtered.encode_into(&mut v, true);
        assert_eq!((v[19], v[22]), (77, 201));
        assert_eq!(Rlod::decode(&v, 0, true).ok(), Some(filtered));
        // Unfiltered files have no such fields: they are reserved there.
        assert!(Rlod::decode(&v, 0, false).is_err());
    }

    #[test]
    fn bad_bytes_get_typed_errors() {
        let mut v = Vec::new();
        sample().encode_into(&mut v, false);
        let code = |b: &[u8], at: usize| Rlod::decode(b, at, false).err().map(|e| e.code());
        // Truncated, unaligned.
        assert_eq!(code(&v[..RLOD_LEN - 1], 0), Some(Code::Rlod));
        assert_eq!(code(&v, 2), Some(Code::Rlod));
        // A NaN normal component.
        let mut nan = v.clone();
        nan[0..4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(code(&nan, 0), Some(Code::Rlod));
        // An infinite offset.
        let mut inf = v.clone();
        inf[12..16].copy_from_slice(&f32::INFINITY.to_le_bytes());
        assert_eq!(code(&inf, 0), Some(Code::Rlod));
        // Not unit length.
        let mut long = v.clone();
        long[8..12].copy_from_slice(&2.0f32.to_le_bytes());
        assert_eq!(code(&long, 0), Some(Code::Rlod));
        // Reserved bytes.
        for at in [19, 22, 23] {
            let mut r = v.clone();
            r[at] = 1;
            assert_eq!(code(&r, 0), Some(Code::Rlod), "byte {at}");
        }
        let mut r = v.clone();
        r[23] = 1;
        assert_eq!(
            Rlod::decode(&r, 0, true).err().map(|e| e.code()),
            Some(Code::Rlod),
            "byte 23 of a filtered file"
        );
    }

    #[test]
    fn codes_round_up_and_the_error_radius_grows_with_the_deviation() {
        let r = 2.0f32;
        for dev in [0.0, 1e-9, 0.01, 0.5, 1.0, 3.99, 4.0] {
            let code = Rlod::code_for(dev, f64::from(r));
            assert!(
                f64::from(Rlod::decode_code(code, r)) >= dev * (1.0 - 1e-6),
                "{dev}"
            );
        }
        assert_eq!(Rlod::code_for(f64::NAN, 1.0), 0);
        assert_eq!(Rlod::code_for(1.0, 0.0), 0);
        assert_eq!(Rlod::code_for(1e9, 1.0), 255);
        let flat = Rlod {
            deviation_code: 0,
            ..sample()
        };
        assert!(
            flat.error_radius(r) >= r && flat.error_radius(r) <= f32::from_bits(r.to_bits() + 1)
        );
        let rough = Rlod {
            deviation_code: 255,
            ..sample()
        };
        // δ = 2r: cbrt(1 + 3) r.
        let want = 4f32.cbrt() * r;
        assert!(
            (rough.error_radius(r) - want).abs() < 1e-5,
            "{}",
            rough.error_radius(r)
        );
    }

    #[test]
    fn kinds_and_their_header_bits() {
        for k in [LodKinds::VOXEL, LodKinds::RLOD, LodKinds::BOTH] {
            for k in [k, k.filtered()] {
                let mut h = Header::new(16);
                h.incompatible_features = k.incompatible_bits();
                assert_eq!(LodKinds::of_header(&h), k);
            }
        }
        assert_eq!(LodKinds::VOXEL.incompatible_bits(), 0);
        assert_eq!(
            [LodKinds::VOXEL, LodKinds::BOTH, LodKinds::RLOD.filtered()]
                .map(LodKinds::minor_version),
            [0, 1, 2]
        );
    }
}
