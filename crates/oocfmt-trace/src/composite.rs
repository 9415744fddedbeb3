//! Semi-transparent LOD entries (spec §5.1): a voxel or R-LOD that covers only part of its
//! cell shows its coverage α of its own shade and lets 1 − α of what lies behind through. A
//! primary ray composites the surfaces it meets front to back; a shadow or occlusion ray
//! multiplies the transmittance of those it passes. So a thin part seen from afar covers as
//! much of the image as it does at full detail instead of swelling into a solid block.

use crate::intersect::Ray;
use crate::light::occludes;
use crate::traverse::{Hit, Memo, Tracer};

/// The most surfaces one ray composites; the last one is taken as opaque (spec §5.1 allows a
/// cap). Past a few layers what is left behind hardly shows.
pub const MAX_LAYERS: u32 = 16;

/// Transmittance below which what lies behind cannot move an 8-bit pixel by a level.
pub const MIN_TRANSMITTANCE: f32 = 1.0 / 512.0;

/// Where the ray goes on behind `hit`: just past the cell it ended in (or past the hit itself
/// for a surface without a cell).
fn beyond(tracer: &Tracer<'_>, ray: &Ray, hit: &Hit) -> f32 {
    let exit = hit.exit.max(hit.t);
    exit + tracer.ray_eps(ray).max(exit.abs() * 1e-6)
}

/// The colour a primary `ray` shows, its first hit `first` given: `shade(hit)` (the linear
/// RGB of one surface) composited front to back over what lies behind every translucent one
/// (each lets 1 − α through), and over `background` where the ray leaves the scene.
pub fn composite(
    tracer: &Tracer<'_>,
    ray: &Ray,
    first: &Hit,
    memo: &mut Memo,
    background: [f32; 3],
    shade: &mut dyn FnMut(&Hit, &mut Memo) -> [f32; 3],
) -> [f32; 3] {
    let mut colour = [0f32; 3];
    let mut through = 1f32;
    let mut hit = first.clone();
    for layer in 1..=MAX_LAYERS {
        // The last layer allowed stands for everything behind it.
        let alpha = if layer == MAX_LAYERS {
            1.0
        } else {
            hit.coverage.clamp(0.0, 1.0)
        };
        if alpha > 0.0 {
            let c = shade(&hit, memo);
            for (o, c) in colour.iter_mut().zip(c) {
                *o += through * alpha * c;
            }
        }
        through *= 1.0 - alpha;
        if through < MIN_TRANSMITTANCE {
            return colour;
        }
        let from = beyond(tracer, ray, &hit);
        match tracer.trace_between(ray, from, f32::INFINITY, memo) {
            Some(next) => hit = next,
            None => break,
        }
    }
    for (o, b) in colour.iter_mut().zip(background) {
        *o += through * b;
    }
    colour
}

/// The share of light that passes along `ray` up to `t_max` (exclusive): 1 when nothing is in
/// the way, 0 behind an opaque surface, the product of 1 − α over the translucent ones passed.
/// A hit that does not block a secondary ray ([`occludes`]) is passed at no cost.
pub fn transmittance(tracer: &Tracer<'_>, ray: &Ray, t_max: f32, memo: &Memo) -> f32 {
    let mut through = 1f32;
    let mut from = 0f32;
    for layer in 1..=MAX_LAYERS {
        let Some(hit) = tracer.trace_between(ray, from, t_max, memo) else {
            return through;
        };
        if occludes(&hit) {
            if layer == MAX_LAYERS || !hit.is_translucent() {
                return 0.0;
            }
            through *= 1.0 - hit.coverage.clamp(0.0, 1.0);
            if through < MIN_TRANSMITTANCE {
                return 0.0;
            }
        }
        from = beyond(tracer, ray, &hit);
    }
    0.0
}
