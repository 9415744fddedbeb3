//! Proxy records (spec §7): 18 directional shading samples for a subtree in another block.

use super::sample::Sample;
use crate::bytes::{f32_at, u32_at, PutLe};
use crate::error::{bad, Code, Result};

/// Bytes of one proxy record; a proxy block's raw length is this times its item count.
pub const PROXY_LEN: usize = 80;

/// The 18 directions, unnormalised, in record order.
pub const PROXY_DIRECTIONS: [[f32; 3]; 18] = [
    [1.0, 0.0, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.0, 0.0, -1.0],
    [1.0, 1.0, 0.0],
    [1.0, -1.0, 0.0],
    [-1.0, 1.0, 0.0],
    [-1.0, -1.0, 0.0],
    [1.0, 0.0, 1.0],
    [1.0, 0.0, -1.0],
    [-1.0, 0.0, 1.0],
    [-1.0, 0.0, -1.0],
    [0.0, 1.0, 1.0],
    [0.0, 1.0, -1.0],
    [0.0, -1.0, 1.0],
    [0.0, -1.0, -1.0],
];

/// What a LOD node's subtree looks like from 18 directions, resident from open so a renderer
/// has something to show before the subtree's blocks arrive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProxyRecord {
    /// The treelet block holding the LOD node this proxy stands for.
    pub node_block: u32,
    /// Surface area of the subtree's triangles, in stored units squared, ≥ 0: a hint for
    /// fetch priority.
    pub area: f32,
    /// Sample `k` is what a ray travelling along [`PROXY_DIRECTIONS`]`[k]` sees, or
    /// [`Sample::EMPTY`] when nothing is seen from there.
    pub samples: [Sample; 18],
}

impl ProxyRecord {
    /// Appends the record's 80 bytes to `v`.
    pub fn encode_into(&self, v: &mut Vec<u8>) {
        v.put_u32(self.node_block);
        v.put_f32(self.area);
        for s in &self.samples {
            v.put_u32(s.0);
        }
    }

    /// Decodes and checks record `index` of a proxy block's raw bytes `b` (area finite and
    /// non-negative, every sample valid or exactly [`Sample::EMPTY`]).
    pub fn decode(b: &[u8], index: usize) -> Result<ProxyRecord> {
        let base = index * PROXY_LEN;
        let c = Code::ProxyLayout;
        let area = f32_at(b, base + 4, c)?;
        if !(area.is_finite() && area >= 0.0) {
            return bad(
                c,
                format!("proxy {index}: area {area} is not a finite non-negative number"),
            );
        }
        let mut samples = [Sample(0); 18];
        for (k, s) in samples.iter_mut().enumerate() {
            *s = Sample(u32_at(b, base + 8 + 4 * k, c)?);
            let ok = if s.is_empty() {
                s.0 == Sample::EMPTY.0
            } else {
                !s.is_single() && s.check().is_ok()
            };
            if !ok {
                return bad(
                    c,
                    format!("proxy {index}: sample {k} ({:#010x}) is invalid", s.0),
                );
            }
        }
        Ok(ProxyRecord {
            node_block: u32_at(b, base, c)?,
            area,
            samples,
        })
    }

    /// Decodes a whole proxy block of `count` records.
    pub fn decode_block(raw: &[u8], count: usize) -> Result<Vec<ProxyRecord>> {
        if raw.len() != count.saturating_mul(PROXY_LEN) {
            return bad(
                Code::ProxyLayout,
                format!("{} bytes for {count} proxies of 80 bytes", raw.len()),
            );
        }
        (0..count).map(|i| ProxyRecord::decode(raw, i)).collect()
    }
}
