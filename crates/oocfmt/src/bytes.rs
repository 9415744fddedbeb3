//! Little-endian field access on byte slices, bounds-checked so file bytes can never panic us.

use crate::error::{bad, Code, Result};

// Inlined, with the error kept out of line: these read every field of every block a fetcher
// decodes, and as calls they were a tenth of the treelet decoder's profile.
#[inline]
pub(crate) fn u16_at(b: &[u8], off: usize, code: Code) -> Result<u16> {
    match b.get(off..off.wrapping_add(2)) {
        Some(&[x0, x1]) => Ok(u16::from_le_bytes([x0, x1])),
        _ => past_end(code, 2, off, b.len()),
    }
}

#[inline]
pub(crate) fn u32_at(b: &[u8], off: usize, code: Code) -> Result<u32> {
    match b.get(off..off.wrapping_add(4)) {
        Some(&[x0, x1, x2, x3]) => Ok(u32::from_le_bytes([x0, x1, x2, x3])),
        _ => past_end(code, 4, off, b.len()),
    }
}

#[cold]
#[inline(never)]
fn past_end<T>(code: Code, size: usize, off: usize, len: usize) -> Result<T> {
    bad(
        code,
        format!("{size}-byte field at {off} is past the end ({len} bytes)"),
    )
}

#[inline]
pub(crate) fn u64_at(b: &[u8], off: usize, code: Code) -> Result<u64> {
    let lo = u32_at(b, off, code)?;
    let hi = u32_at(b, off.wrapping_add(4), code)?;
    Ok(u64::from(lo) | (u64::from(hi) << 32))
}

#[inline]
pub(crate) fn f32_at(b: &[u8], off: usize, code: Code) -> Result<f32> {
    u32_at(b, off, code).map(f32::from_bits)
}

/// Little-endian appends for encoders.
pub(crate) trait PutLe {
    fn put_u16(&mut self, v: u16);
    fn put_u32(&mut self, v: u32);
    fn put_u64(&mut self, v: u64);
    fn put_f32(&mut self, v: f32);
}

impl PutLe for Vec<u8> {
    fn put_u16(&mut self, v: u16) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn put_u32(&mut self, v: u32) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn put_u64(&mut self, v: u64) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn put_f32(&mut self, v: f32) {
        self.extend_from_slice(&v.to_le_bytes());
    }
}
