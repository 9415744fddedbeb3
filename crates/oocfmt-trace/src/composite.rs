//! Semi-transparent LOD entries (spec §5.1): a voxel or R-LOD that covers only part of its
//! cell shows its coverage α of its own shade and lets 1 − α of what lies behind through. A
//! primary ray composites the surfaces it meets front to back, so a thin part seen from afar
//! covers as much of the image as it does at full detail instead of swelling into a solid
//! block. The surfaces come from one walk of the tree ([`Tracer::trace_layers`], or
//! [`Tracer::trace_packet_layers`] for a packet of primary rays). Shadow rays
//! take LOD entries as opaque: one cell's coverage does not say whether the cells behind close
//! the surface, and light must not leak into a closed one. Occlusion rays take their
//! transmittance ([`crate::occlusion`]): each stands for a cone, of which a cell blocks α.

#[cfg(doc)]
use crate::traverse::Tracer;
use crate::traverse::{Hit, Memo};

pub use crate::traverse::{Layers, MAX_LAYERS, MIN_TRANSMITTANCE};

/// The colour of a ray that met the translucent surfaces `front`, nearest first, and then
/// `end` (None: it left the scene, showing `background`): each surface's `shade` (its linear
/// RGB) weighted by its coverage and by what the ones before it let through, over what `end`
/// shows. The surfaces come from [`Tracer::trace_layers`] or [`Tracer::trace_packet_layers`].
pub fn blend(
    front: &[Hit],
    end: Option<&Hit>,
    background: [f32; 3],
    memo: &mut Memo,
    shade: &mut dyn FnMut(&Hit, &mut Memo) -> [f32; 3],
) -> [f32; 3] {
    let mut colour = [0f32; 3];
    let mut through = 1f32;
    for hit in front {
        let alpha = hit.coverage.clamp(0.0, 1.0);
        if alpha > 0.0 {
            let c = shade(hit, memo);
            for (o, c) in colour.iter_mut().zip(c) {
                *o += through * alpha * c;
            }
        }
        through *= 1.0 - alpha;
    }
    let behind = match end {
        Some(hit) => shade(hit, memo),
        None => background,
    };
    for (o, b) in colour.iter_mut().zip(behind) {
        *o += through * b;
    }
    colour
}
