//! Shading. By default a headlight: the light sits at the eye, so a surface is as bright as it
//! faces the viewer; normals are turned towards the viewer (both sides of a triangle are lit).
//! With `--shadows` the direct light is Lambert from a point light, times what one shadow ray
//! finds; a surface lights only when the light is on the viewer's side of it (a closed mesh is
//! dark inside and on its far side). With `--ao N` the ambient term is scaled by the share of
//! N ambient-occlusion rays that escape, and weighs [`AO_AMBIENT`] instead of [`AMBIENT`], so
//! that it shows. Colour = albedo · (ambient · open share + (1 − ambient) · direct).

use oocfmt::metadata::Material;

use crate::intersect::Ray;
use crate::light::{unit_towards, Shadows};
use crate::occlusion::Occlusion;
use crate::parts::{tint, PartFilter};
use crate::rough::{lit_cosine, rough_cosine};
use crate::spawn::{triangle_normal, Origin};
use crate::traverse::{Hit, Memo, Surface};

/// The colour of surfaces without vertex colours or materials (linear RGB, spec §8).
pub use oocfmt::records::triangle::DEFAULT_ALBEDO;
/// The weight of the ambient term without ambient occlusion.
pub const AMBIENT: f32 = 0.12;
/// The weight of the ambient term with ambient occlusion.
pub const AO_AMBIENT: f32 = 0.35;

/// The linear RGB colour of a hit under the headlight: the cosine of a rough surface of the
/// hit's shade σ ([`rough_cosine`], spec §5.1), so a pre-filtered LOD sample shows its
/// footprint's mean shade.
pub fn shade(hit: &Hit, ray: &Ray, materials: &[Material]) -> [f32; 3] {
    let (albedo, normal) = attributes(hit, materials);
    headlight(hit, ray, albedo, normal)
}

/// [`shade`] of a hit whose albedo and (not normalised) shading normal are given.
fn headlight(hit: &Hit, ray: &Ray, albedo: [f32; 3], normal: [f32; 3]) -> [f32; 3] {
    let len = dot(normal, normal).sqrt();
    let cos = if len > 0.0 && len.is_finite() {
        (dot(normal, ray.dir) / len).abs().min(1.0)
    } else {
        1.0
    };
    let cos = rough_cosine(cos, hit.shade);
    let light = AMBIENT + (1.0 - AMBIENT) * cos;
    albedo.map(|c| c.clamp(0.0, 1.0) * light)
}

/// The albedo and the (not normalised) shading normal of a hit: vertex colours, else the
/// material, else [`DEFAULT_ALBEDO`]; interpolated vertex normals, else the geometric normal.
fn attributes(hit: &Hit, materials: &[Material]) -> ([f32; 3], [f32; 3]) {
    match &hit.surface {
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
        Surface::Proxy(s) => (s.colour(), s.normal()),
        Surface::Voxel { normal, colour } => (*colour, *normal),
        Surface::Plane { normal, colour, .. } => (*colour, *normal),
    }
}

/// Secondary rays traced while shading.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Secondary {
    /// Shadow rays: one per shaded hit with the point light in front of it.
    pub shadow: u64,
    /// Ambient-occlusion rays, [`Occlusion::rays`] per shaded hit.
    pub ao: u64,
}

impl Secondary {
    /// Adds `o`'s counts to these (a tile's counts into the frame's).
    pub fn add(&mut self, o: &Secondary) {
        self.shadow += o.shadow;
        self.ao += o.ao;
    }
}

/// Everything shading needs for one frame.
pub struct Lighting<'a> {
    materials: &'a [Material],
    shadows: Option<Shadows<'a>>,
    occlusion: Option<Occlusion<'a>>,
    /// The largest coordinate of the scene's box (for the origins of rays leaving voxels).
    scale: f32,
    /// The part filter, when it highlights a part ([`Lighting::with_parts`]).
    highlight: Option<&'a PartFilter>,
}

impl<'a> Lighting<'a> {
    /// Shading with the scene's `materials`, the point light's `shadows` and ambient
    /// `occlusion` when on; `bounds` is the scene's box (lo, hi), which sets how far a
    /// secondary ray's origin is pushed off a voxel.
    pub fn new(
        materials: &'a [Material],
        shadows: Option<Shadows<'a>>,
        occlusion: Option<Occlusion<'a>>,
        bounds: ([f32; 3], [f32; 3]),
    ) -> Lighting<'a> {
        let scale = bounds
            .0
            .iter()
            .chain(&bounds.1)
            .fold(0f32, |a, &c| a.max(c.abs()));
        Lighting {
            materials,
            shadows,
            occlusion,
            scale,
            highlight: None,
        }
    }

    /// Shading that tints the parts `filter` highlights ([`crate::parts::tint`]): a triangle
    /// by its own part, a LOD entry by its part word. (Hidden parts are the tracers'.)
    pub fn with_parts(mut self, filter: &'a PartFilter) -> Lighting<'a> {
        self.highlight = (filter.highlighted() > 0).then_some(filter);
        self
    }

    /// The albedo and shading normal of `hit` ([`attributes`]), tinted where highlighted.
    #[inline]
    fn attributes(&self, hit: &Hit) -> ([f32; 3], [f32; 3]) {
        let (albedo, normal) = attributes(hit, self.materials);
        match self.highlight {
            Some(f) if f.highlights(hit.part) => (tint(albedo), normal),
            _ => (albedo, normal),
        }
    }

    /// True when neither shadows nor ambient occlusion are on: [`shade`] is the whole story.
    pub fn is_headlight(&self) -> bool {
        self.shadows.is_none() && self.occlusion.is_none()
    }

    /// The linear RGB colour of `hit`, the nearest hit of primary `ray`, tracing the secondary
    /// rays it needs (counted in `counts`); `seed` rotates the AO pattern of this primary ray.
    pub fn colour(
        &self,
        hit: &Hit,
        ray: &Ray,
        seed: u64,
        memo: &mut Memo,
        counts: &mut Secondary,
    ) -> [f32; 3] {
        if self.is_headlight() {
            let (albedo, normal) = self.attributes(hit);
            return headlight(hit, ray, albedo, normal);
        }
        let (albedo, normal) = self.attributes(hit);
        let at = self.point(hit, ray, normal);
        let direct = self.direct_from(hit, ray, &at, memo, counts);
        let (ambient, open) = match &self.occlusion {
            None => (AMBIENT, 1.0),
            Some(o) => {
                counts.ao += u64::from(o.rays());
                (AO_AMBIENT, o.open(&at.from, at.g, seed, memo))
            }
        };
        let light = ambient * open + (1.0 - ambient) * direct;
        albedo.map(|c| c.clamp(0.0, 1.0) * light)
    }

    /// The direct light at `hit` (the nearest hit of primary `ray`) in [0, 1]: the headlight's
    /// cosine, or the point light's cosine times what its shadow ray finds (0 when the light is
    /// behind the surface as the viewer sees it).
    pub fn direct(&self, hit: &Hit, ray: &Ray, memo: &mut Memo, counts: &mut Secondary) -> f32 {
        let (_, normal) = attributes(hit, self.materials);
        let at = self.point(hit, ray, normal);
        self.direct_from(hit, ray, &at, memo, counts)
    }

    /// Where `hit` (with shading normal `normal`) is shaded from.
    fn point(&self, hit: &Hit, ray: &Ray, normal: [f32; 3]) -> ShadingPoint {
        let (g, n) = self.normals(hit, ray, normal);
        ShadingPoint {
            from: Origin::of(hit, ray, self.scale),
            g,
            n,
        }
    }

    /// The geometric and the shading unit normals, both turned towards the viewer.
    fn normals(&self, hit: &Hit, ray: &Ray, normal: [f32; 3]) -> ([f32; 3], [f32; 3]) {
        let back = ray.dir.map(|c| -c);
        let geometric = match &hit.surface {
            Surface::Triangle { data, triangle, .. } => data
                .positions
                .get(*triangle as usize)
                .and_then(triangle_normal)
                .map(|n| n.map(|c| c as f32)),
            Surface::Voxel { .. } | Surface::Proxy(_) | Surface::Plane { .. } => unit(normal),
        };
        let g = facing(geometric.unwrap_or(back), ray.dir);
        (g, unit(normal).map_or(g, |n| facing(n, ray.dir)))
    }

    /// [`Lighting::direct`] from the shading point `at` of `hit`.
    fn direct_from(
        &self,
        hit: &Hit,
        ray: &Ray,
        at: &ShadingPoint,
        memo: &mut Memo,
        counts: &mut Secondary,
    ) -> f32 {
        let ShadingPoint { from, g, n } = at;
        let (g, n) = (*g, *n);
        let sigma = hit.shade;
        let Some(s) = &self.shadows else {
            return rough_cosine(dot(n, ray.dir.map(|c| -c)).clamp(0.0, 1.0), sigma);
        };
        match unit_towards(from.point(), s.light()) {
            // The light must be on the viewer's side of the surface.
            Some((l, _)) if dot(g, l) > 0.0 => {
                let cos = lit_cosine(n, ray.dir.map(|c| -c), l, sigma);
                if cos > 0.0 {
                    counts.shadow += 1;
                    if s.visible(from, hit.t, memo) {
                        return cos;
                    }
                }
                0.0
            }
            _ => 0.0,
        }
    }
}

/// Where a hit is shaded from: the origin of its secondary rays, and its geometric and shading
/// unit normals, both turned towards the viewer.
struct ShadingPoint {
    from: Origin,
    g: [f32; 3],
    n: [f32; 3],
}

/// `n` turned to face against `dir` (towards the viewer).
fn facing(n: [f32; 3], dir: [f32; 3]) -> [f32; 3] {
    if dot(n, dir) > 0.0 {
        n.map(|c| -c)
    } else {
        n
    }
}

/// `v` over its length; None for a zero or non-finite vector.
fn unit(v: [f32; 3]) -> Option<[f32; 3]> {
    let len = dot(v, v).sqrt();
    (len > 0.0 && len.is_finite()).then(|| v.map(|c| c / len))
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
