//! PLY's scalar types: their names (the original ones and the sized aliases), sizes, and
//! values. Every type's values are exact in f64, so one representation serves them all.

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    /// The type a header names, if it is one.
    pub(super) fn parse(word: &str) -> Option<Scalar> {
        Some(match word {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Bytes in a binary file.
    pub(super) fn size(self) -> u64 {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    pub(super) fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The value of the first [`Scalar::size`] bytes of `bytes`, in the byte order given.
    pub(super) fn decode(self, bytes: [u8; 8], big_endian: bool) -> f64 {
        let [a, b, c, d, e, f, g, h] = bytes;
        let (b2, b4) = if big_endian {
            ([a, b], [a, b, c, d])
        } else {
            ([b, a], [d, c, b, a])
        };
        let b8 = if big_endian {
            bytes
        } else {
            [h, g, f, e, d, c, b, a]
        };
        match self {
            Scalar::I8 => f64::from(a as i8),
            Scalar::U8 => f64::from(a),
            Scalar::I16 => f64::from(i16::from_be_bytes(b2)),
            Scalar::U16 => f64::from(u16::from_be_bytes(b2)),
            Scalar::I32 => f64::from(i32::from_be_bytes(b4)),
            Scalar::U32 => f64::from(u32::from_be_bytes(b4)),
            Scalar::F32 => f64::from(f32::from_be_bytes(b4)),
            Scalar::F64 => f64::from_be_bytes(b8),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_type_decodes_in_both_byte_orders() {
        let pad = |b: &[u8]| {
            let mut out = [0u8; 8];
            out[..b.len()].copy_from_slice(b);
            out
        };
        let cases: [(Scalar, f64); 8] = [
            (Scalar::I8, -5.0),
            (Scalar::U8, 200.0),
            (Scalar::I16, -30000.0),
            (Scalar::U16, 60000.0),
            (Scalar::I32, -2_000_000_000.0),
            (Scalar::U32, 4_000_000_000.0),
            (Scalar::F32, 1.5e-3_f32 as f64),
            (Scalar::F64, -1.234_567_890_123e200),
        ];
        for (ty, v) in cases {
            let (le, be): (Vec<u8>, Vec<u8>) = match ty {
                Scalar::I8 => (vec![v as i8 as u8], vec![v as i8 as u8]),
                Scalar::U8 => (vec![v as u8], vec![v as u8]),
                Scalar::I16 => (
                    (v as i16).to_le_bytes().into(),
                    (v as i16).to_be_bytes().into(),
                ),
                Scalar::U16 => (
                    (v as u16).to_le_bytes().into(),
                    (v as u16).to_be_bytes().into(),
                ),
                Scalar::I32 => (
                    (v as i32).to_le_bytes().into(),
                    (v as i32).to_be_bytes().into(),
                ),
                Scalar::U32 => (
                    (v as u32).to_le_bytes().into(),
                    (v as u32).to_be_bytes().into(),
                ),
                Scalar::F32 => (
                    (v as f32).to_le_bytes().into(),
                    (v as f32).to_be_bytes().into(),
                ),
                Scalar::F64 => (v.to_le_bytes().into(), v.to_be_bytes().into()),
            };
            assert_eq!(le.len() as u64, ty.size());
            assert_eq!(ty.decode(pad(&le), false), v, "{ty:?} little-endian");
            assert_eq!(ty.decode(pad(&be), true), v, "{ty:?} big-endian");
        }
        for (name, ty) in [
            ("uint8", Scalar::U8),
            ("float", Scalar::F32),
            ("float64", Scalar::F64),
        ] {
            assert_eq!(Scalar::parse(name), Some(ty));
        }
        assert_eq!(Scalar::parse("int64"), None);
    }
}
