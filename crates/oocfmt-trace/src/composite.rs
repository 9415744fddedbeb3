//! Semi-transparent LOD entries (spec §5.1): a voxel or R-LOD that covers only part of its
//! cell shows its coverage α of its own shade and lets 1 − α of what lies behind through. A
//! primary ray composites the surfaces it meets front to back, so a thin part seen from afar
//! covers as much of the image as it does at full detail instead of swelling into a solid
//! block. The surfaces come from one walk of the tree ([`Tracer::trace_layers`]). Shadow rays
//! take LOD entries as opaque: one cell's coverage does not say whether the cells behind close
//! the surface, and light must not leak into a closed one. Occlusion rays take their
//! transmittance ([`crate::occlusion`]): each stands for a cone, of which a cell blocks α.

use crate::intersect::Ray;
use crate::traverse::{Memo, Tracer};

pub use crate::traverse::{Layers, MAX_LAYERS, MIN_TRANSMITTANCE};

/// The colour `ray` shows: `shade(hit)` (the linear RGB of one surface) of the translucent
/// surfaces it meets, front to back, each weighted by its coverage and what the ones before
/// let through, over the opaque surface it ends on or, where it leaves the scene,
/// `background`. Surfaces at `t_max` or beyond are not met (a section plane's end of the
/// ray; infinity for the whole ray).
pub fn composite(
    tracer: &Tracer<'_>,
    ray: &Ray,
    t_max: f32,
    memo: &mut Memo,
    background: [f32; 3],
    shade: &mut dyn FnMut(&crate::traverse::Hit, &mut Memo) -> [f32; 3],
) -> [f32; 3] {
    let layers = tracer.trace_layers(ray, t_max, memo);
    let mut colour = [0f32; 3];
    let mut through = 1f32;
    for hit in &layers.translucent {
        let alpha = hit.coverage.clamp(0.0, 1.0);
        if alpha > 0.0 {
            let c = shade(hit, memo);
            for (o, c) in colour.iter_mut().zip(c) {
                *o += through * alpha * c;
            }
        }
        through *= 1.0 - alpha;
    }
    let behind = match &layers.end {
        Some(hit) => shade(hit, memo),
        None => background,
    };
    for (o, b) in colour.iter_mut().zip(behind) {
        *o += through * b;
    }
    colour
}
