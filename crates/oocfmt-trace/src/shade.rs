//! Headlight Lambert shading: the light sits at the eye, so a surface is as bright as it faces
//! the viewer. Normals are turned towards the viewer (both sides of a triangle are lit).

use oocfmt::metadata::Material;

use crate::intersect::Ray;
use crate::traverse::{Hit, Surface};

/// The colour of surfaces without vertex colours or materials (linear RGB).
pub const DEFAULT_ALBEDO: [f32; 3] = [0.78, 0.76, 0.72];
const AMBIENT: f32 = 0.12;

/// The linear RGB colour of a hit.
pub fn shade(hit: &Hit, ray: &Ray, materials: &[Material]) -> [f32; 3] {
    let (albedo, normal) = match &hit.surface {
        Surface::Triangle {
            data,
            triangle,
            bary,
        } => {
            let i = *triangle as usize;
            let interp = |c: &[[f32; 3]; 3]| {
                [0, 1, 2].map(|k| bary[0] * c[0][k] + bary[1] * c[1][k] + bary[2] * c[2][k])
            };
            let albedo = if let Some(c) = data.colours.as_ref().and_then(|c| c.get(i)) {
                interp(c)
            } else if let Some(m) = data
                .materials
                .as_ref()
                .and_then(|m| m.get(i))
                .and_then(|&m| materials.get(usize::from(m)))
            {
                m.diffuse
            } else {
                DEFAULT_ALBEDO
            };
            let geometric = data.positions.get(i).map(|p| {
                let e1 = sub(p[1], p[0]);
                let e2 = sub(p[2], p[0]);
                cross(e1, e2)
            });
            let n = match data.normals.as_ref().and_then(|n| n.get(i)) {
                Some(n) => interp(n),
                None => geometric.unwrap_or([0.0, 0.0, 1.0]),
            };
            (albedo, n)
        }
        Surface::Voxel(s) | Surface::Proxy(s) => (s.colour(), s.normal()),
    };
    let len = dot(normal, normal).sqrt();
    let cos = if len > 0.0 && len.is_finite() {
        (dot(normal, ray.dir) / len).abs().min(1.0)
    } else {
        1.0
    };
    let light = AMBIENT + (1.0 - AMBIENT) * cos;
    albedo.map(|c| c.clamp(0.0, 1.0) * light)
}

/// Linear to sRGB-encoded 8 bits: the sRGB curve rounded to the nearest level, without a
/// `powf` per pixel and with the same bytes as the formula. The 255 linear values where the
/// level changes are found once, by bisection over the exact curve; a table of 4096 equal
/// steps of [0, 1] gives the level at the start of each step, and the few level changes
/// inside a step are then passed one by one.
pub fn encode_srgb(c: f32) -> u8 {
    if c.is_nan() || c <= 0.0 {
        return 0;
    }
    let t = SRGB.get_or_init(SrgbTable::new);
    let mut level = t
        .start
        .get((c * BUCKETS as f32) as usize)
        .copied()
        .unwrap_or(255);
    while let Some(&step) = t.steps.get(usize::from(level)) {
        if c < step {
            break;
        }
        level += 1;
    }
    level
}

const BUCKETS: usize = 4096;

struct SrgbTable {
    /// `steps[l]`: the smallest linear value encoded as level l + 1.
    steps: Vec<f32>,
    /// The level of each bucket's lower end.
    start: Vec<u8>,
}

impl SrgbTable {
    fn new() -> SrgbTable {
        let steps: Vec<f32> = (1..=255u32)
            .map(|level| {
                let (mut lo, mut hi) = (0u32, 1f32.to_bits());
                while lo < hi {
                    let mid = lo + (hi - lo) / 2;
                    if u32::from(srgb_exact(f32::from_bits(mid))) >= level {
                        hi = mid;
                    } else {
                        lo = mid + 1;
                    }
                }
                f32::from_bits(lo)
            })
            .collect();
        let start = (0..BUCKETS)
            .map(|b| {
                // The smallest value that lands in bucket b, as `encode_srgb` computes buckets.
                let (mut lo, mut hi) = (0u32, 1f32.to_bits());
                while lo < hi {
                    let mid = lo + (hi - lo) / 2;
                    if (f32::from_bits(mid) * BUCKETS as f32) as usize >= b {
                        hi = mid;
                    } else {
                        lo = mid + 1;
                    }
                }
                steps.partition_point(|&s| s <= f32::from_bits(lo)) as u8
            })
            .collect();
        SrgbTable { steps, start }
    }
}

static SRGB: std::sync::OnceLock<SrgbTable> = std::sync::OnceLock::new();

fn srgb_exact(c: f32) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_ends_and_middle() {
        assert_eq!(encode_srgb(0.0), 0);
        assert_eq!(encode_srgb(1.0), 255);
        assert_eq!(encode_srgb(f32::NAN), 0);
        assert_eq!(encode_srgb(0.18), 118);
        assert_eq!(encode_srgb(-1.0), 0);
        assert_eq!(encode_srgb(f32::INFINITY), 255);
    }

    #[test]
    fn the_lookup_equals_the_formula() {
        let mut c = 0f32;
        while c < 1.01 {
            assert_eq!(encode_srgb(c), srgb_exact(c), "at {c}");
            c = if c < 1e-3 { c + 1e-7 } else { c * 1.0001 };
        }
    }
}
