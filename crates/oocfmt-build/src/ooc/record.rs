//! The triangle record of the soup's spill files. A record holds its own triangle, so a file can
//! be split, counted and streamed without any index into other data, and carries only the
//! fields its triangle has: a flag byte, then the fields it names, little-endian.
//!
//! | bytes | field | present |
//! |------:|-------|---------|
//! | 1 | flags (below) | always |
//! | 36 | 9 × f32 corner positions, every bit kept | always |
//! | 12 or 36 | f32 normals: one for all three corners (flat) or one per corner | `NORMALS` |
//! | 4 or 12 | RGBA8 colours: one for all corners (flat) or one per corner | `COLOURS` |
//! | 1–5 | LEB128 u32: the material as the importer numbered it | `MATERIAL` |
//! | 1–5 | LEB128 u32: the part as the importer numbered it | `PART` |
//!
//! Flags: bit 0 a copy that is not the primary, bit 1 normals, bit 2 the normals are flat
//! (bit-identical corners), bit 3 colours, bit 4 flat colours, bit 5 material, bit 6 part;
//! bit 7 is reserved and zero. A positions-only triangle takes 37 bytes (96 in the fixed
//! layout this replaced).

use oocfmt_meshio::import::InputTriangle;

/// The longest record: flags, positions, three normals, three colours, two 5-byte numbers.
pub const MAX_RECORD_LEN: usize = 1 + 36 + 36 + 12 + 5 + 5;

const NOT_PRIMARY: u8 = 1;
const NORMALS: u8 = 1 << 1;
const FLAT_NORMALS: u8 = 1 << 2;
const COLOURS: u8 = 1 << 3;
const FLAT_COLOURS: u8 = 1 << 4;
const MATERIAL: u8 = 1 << 5;
const PART: u8 = 1 << 6;
const RESERVED: u8 = 1 << 7;

/// One triangle of the soup. `primary` is false on the copies a split made of a triangle
/// reaching both sides: exactly one copy of each input triangle is primary, so the file stores
/// it once as a primary (what `export` writes back).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoupTriangle {
    /// The triangle as the importer gave it (its `hint` is not stored).
    pub triangle: InputTriangle,
    /// Whether this is the one copy of the input triangle that counts as the original.
    pub primary: bool,
}

/// Why a record did not decode: where it goes wrong, for [`super::OocError::SpillCorrupt`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordError {
    /// The flag byte has its reserved bit set.
    Reserved,
    /// The bytes end inside the record.
    Truncated,
    /// A LEB128 number is longer than 5 bytes or above `u32::MAX`.
    Number,
}

impl RecordError {
    /// What went wrong, in words.
    pub fn describe(self) -> &'static str {
        match self {
            RecordError::Reserved => "a record's reserved flag bit is set",
            RecordError::Truncated => "a record is cut short",
            RecordError::Number => "a record's material or part number is malformed",
        }
    }
}

impl SoupTriangle {
    /// Writes the record into `out`; returns its length.
    #[inline]
    pub fn encode(&self, out: &mut [u8; MAX_RECORD_LEN]) -> usize {
        let t = &self.triangle;
        let mut w = Cursor { out, at: 1 };
        let mut flags = if self.primary { 0 } else { NOT_PRIMARY };
        for p in &t.positions {
            w.floats(p);
        }
        if let Some(n) = &t.normals {
            flags |= NORMALS;
            let bits = n.map(|c| c.map(f32::to_bits));
            if bits[0] == bits[1] && bits[1] == bits[2] {
                flags |= FLAT_NORMALS;
                w.floats(&n[0]);
            } else {
                n.iter().for_each(|c| w.floats(c));
            }
        }
        if let Some(c) = &t.colours {
            flags |= COLOURS;
            if c[0] == c[1] && c[1] == c[2] {
                flags |= FLAT_COLOURS;
                w.bytes(&c[0]);
            } else {
                c.iter().for_each(|rgba| w.bytes(rgba));
            }
        }
        if let Some(m) = t.material {
            flags |= MATERIAL;
            w.leb128(m);
        }
        if let Some(p) = t.part {
            flags |= PART;
            w.leb128(p);
        }
        w.out[0] = flags;
        w.at
    }

    /// The triangle at the start of `bytes` and the record's length.
    #[inline]
    pub fn decode(bytes: &[u8]) -> Result<(SoupTriangle, usize), RecordError> {
        let (&flags, rest) = bytes.split_first().ok_or(RecordError::Truncated)?;
        if flags & RESERVED != 0 {
            return Err(RecordError::Reserved);
        }
        let mut r = Reader { rest, taken: 1 };
        let positions = [r.floats()?, r.floats()?, r.floats()?];
        let normals = match (flags & NORMALS != 0, flags & FLAT_NORMALS != 0) {
            (false, _) => None,
            (true, true) => Some([r.floats()?; 3]),
            (true, false) => Some([r.floats()?, r.floats()?, r.floats()?]),
        };
        let colours = match (flags & COLOURS != 0, flags & FLAT_COLOURS != 0) {
            (false, _) => None,
            (true, true) => Some([r.rgba()?; 3]),
            (true, false) => Some([r.rgba()?, r.rgba()?, r.rgba()?]),
        };
        let material = (flags & MATERIAL != 0).then(|| r.leb128()).transpose()?;
        let part = (flags & PART != 0).then(|| r.leb128()).transpose()?;
        let triangle = InputTriangle {
            positions,
            normals,
            colours,
            material,
            part,
            hint: None,
        };
        let primary = flags & NOT_PRIMARY == 0;
        Ok((SoupTriangle { triangle, primary }, r.taken))
    }

    /// The vertex mean: inside the triangle, so inside every cell holding its primary copy.
    pub fn centroid(&self) -> [f32; 3] {
        let p = &self.triangle.positions;
        std::array::from_fn(|a| {
            ((f64::from(p[0][a]) + f64::from(p[1][a]) + f64::from(p[2][a])) / 3.0) as f32
        })
    }
}

/// Writes fields one after another; the record's size bounds every write.
struct Cursor<'a> {
    out: &'a mut [u8; MAX_RECORD_LEN],
    at: usize,
}

impl Cursor<'_> {
    fn bytes(&mut self, b: &[u8]) {
        if let Some(slot) = self.out.get_mut(self.at..self.at + b.len()) {
            slot.copy_from_slice(b);
            self.at += b.len();
        }
    }

    fn floats(&mut self, v: &[f32; 3]) {
        for f in v {
            self.bytes(&f.to_le_bytes());
        }
    }

    fn leb128(&mut self, mut v: u32) {
        loop {
            let low = (v & 0x7f) as u8;
            v >>= 7;
            if v == 0 {
                self.bytes(&[low]);
                return;
            }
            self.bytes(&[low | 0x80]);
        }
    }
}

/// Takes fields off the front of a record.
struct Reader<'a> {
    rest: &'a [u8],
    taken: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], RecordError> {
        let (head, rest) = self
            .rest
            .split_first_chunk::<N>()
            .ok_or(RecordError::Truncated)?;
        self.rest = rest;
        self.taken += N;
        Ok(*head)
    }

    fn floats(&mut self) -> Result<[f32; 3], RecordError> {
        let b: [u8; 12] = self.take()?;
        Ok(std::array::from_fn(|k| {
            f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]])
        }))
    }

    fn rgba(&mut self) -> Result<[u8; 4], RecordError> {
        self.take()
    }

    fn leb128(&mut self) -> Result<u32, RecordError> {
        let mut v = 0u64;
        for shift in (0..35).step_by(7) {
            let [b] = self.take::<1>()?;
            v |= u64::from(b & 0x7f) << shift;
            if b & 0x80 == 0 {
                return u32::try_from(v).map_err(|_| RecordError::Number);
            }
        }
        Err(RecordError::Number)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip(t: SoupTriangle) -> usize {
        let mut buf = [0u8; MAX_RECORD_LEN];
        let len = t.encode(&mut buf);
        // Trailing bytes (the next record) are not read.
        buf[len..].fill(0xff);
        assert_eq!(SoupTriangle::decode(&buf), Ok((t, len)));
        for cut in 0..len {
            assert_eq!(
                SoupTriangle::decode(&buf[..cut]),
                Err(RecordError::Truncated)
            );
        }
        len
    }

    #[test]
    fn records_round_trip_every_bit_with_only_the_fields_they_have() {
        let p = [[1.0, -2.5, 3.0], [f32::MAX, 0.0, -0.0], [1e-30, 7.0, 8.0]];
        let mut t = InputTriangle::new(p);
        assert_eq!(
            round_trip(SoupTriangle {
                triangle: t,
                primary: true,
            }),
            37
        );
        // Flat normals whose bits differ (0.0 and -0.0, NaN payloads) are not flat.
        let nan = f32::from_bits(0x7fc0_0001);
        t.normals = Some([[0.0, 0.0, 1.0], [-0.0, 0.0, 1.0], [nan, 0.0, 0.0]]);
        t.colours = Some([[1, 2, 3, 4], [5, 6, 7, 8], [9, 10, 11, 12]]);
        t.material = Some(7);
        t.part = Some(u32::MAX);
        let full = SoupTriangle {
            triangle: t,
            primary: false,
        };
        let mut buf = [0u8; MAX_RECORD_LEN];
        let len = full.encode(&mut buf);
        assert_eq!(len, MAX_RECORD_LEN - 4);
        let (back, _) = SoupTriangle::decode(&buf).unwrap_or_else(|e| panic!("{e:?}"));
        let bits = |n: Option<[[f32; 3]; 3]>| n.map(|n| n.map(|c| c.map(f32::to_bits)));
        assert_eq!(bits(back.triangle.normals), bits(t.normals));
        assert_eq!(
            (back.triangle.colours, back.triangle.part, back.primary),
            (t.colours, t.part, false)
        );
        t.normals = Some([[0.0, 0.6, 0.8]; 3]);
        t.colours = Some([[9, 8, 7, 6]; 3]);
        t.material = Some(300);
        t.part = Some(0);
        let flat = SoupTriangle {
            triangle: t,
            primary: true,
        };
        assert_eq!(round_trip(flat), 37 + 12 + 4 + 2 + 1);
    }

    #[test]
    fn malformed_records_are_refused() {
        let mut buf = [0u8; MAX_RECORD_LEN];
        buf[0] = RESERVED;
        assert_eq!(SoupTriangle::decode(&buf), Err(RecordError::Reserved));
        buf[0] = MATERIAL;
        buf[37..43].fill(0x80);
        assert_eq!(SoupTriangle::decode(&buf), Err(RecordError::Number));
        // 2^32 does not fit a u32.
        buf[37..42].copy_from_slice(&[0x80, 0x80, 0x80, 0x80, 0x10]);
        assert_eq!(SoupTriangle::decode(&buf), Err(RecordError::Number));
        buf[37..42].copy_from_slice(&[0xff, 0xff, 0xff, 0xff, 0x0f]);
        let m = SoupTriangle::decode(&buf).map(|(t, n)| (t.triangle.material, n));
        assert_eq!(m, Ok((Some(u32::MAX), 42)));
    }
}
