//! The point light of `--shadows`: where it sits by default, and the level of detail of shadow
//! rays.
//!
//! The metric. Shadows are projections from the light (Áfra 2012 §6.2; Yoon et al. 2006 §4.3):
//! an occluder that is off by R at distance s from the receiver, with the light at distance L,
//! moves the edge of its shadow on the receiver by R·L/(L − s). The receiver, at distance t_p
//! from the eye, shows `poe` pixels over C·t_p (C the primary rays' LOD constant). A shadow ray
//! is traced from the receiver towards the light and may end on a voxel when R ≤ s·k, with the
//! per-ray constant k = C·t_p·(L − s_m) / (L·s_m), s_m = min(s_exit, L/2), s_exit where the ray
//! leaves the scene's box: for every occluder closer than s_m (all of them unless the light is
//! inside the box) the shadow's edge moves at most `poe` pixels, to first order, for a receiver
//! seen face-on. Near the receiver the metric asks for full detail, so a shadow ray never stops
//! on a coarse voxel around the surface it leaves; at `poe` 0, k = 0 and shadow rays see full
//! detail.

use crate::cache::BlockCache;
use crate::camera::Frame;
use crate::intersect::{ray_box, Ray};
use crate::parts::PartFilter;
use crate::scene::Scene;
use crate::spawn::Origin;
use crate::traverse::{Hit, Memo, Surface, Tracer};

/// The default light, relative to the camera, in diagonals of the scene's box: to the right,
/// above and behind the eye, like a light over the viewer's right shoulder.
pub const SHOULDER: [f64; 3] = [0.5, 0.7, -0.3];

/// The default light position for a view: eye + D·(0.5·right + 0.7·up − 0.3·forward), D the
/// diagonal of the box [lo, hi]; in the same coordinates as the camera.
pub fn shoulder_light(frame: &Frame, lo: [f32; 3], hi: [f32; 3]) -> [f64; 3] {
    let d = (0..3)
        .map(|k| (f64::from(hi[k]) - f64::from(lo[k])).powi(2))
        .sum::<f64>()
        .sqrt();
    // A point-like scene still gets a light away from the eye.
    let d = if d > 0.0 && d.is_finite() { d } else { 1.0 };
    let (forward, right, up) = frame.basis();
    let eye = frame.eye();
    [0, 1, 2].map(|k| {
        eye[k] + d * (SHOULDER[0] * right[k] + SHOULDER[1] * up[k] + SHOULDER[2] * forward[k])
    })
}

/// The LOD constant of one shadow ray (see the module comment): `pixel_c` the primary rays'
/// constant, `t_primary` the receiver's distance from the eye, `light` its distance from the
/// light, `exit` where the shadow ray leaves the scene's box. 0 (full detail) when any of them
/// makes no sense.
pub fn shadow_lod_c(pixel_c: f32, t_primary: f32, light: f32, exit: f32) -> f32 {
    let s_m = exit.min(light / 2.0);
    let k = pixel_c * t_primary * (light - s_m) / (light * s_m);
    if s_m > 0.0 && k.is_finite() && k > 0.0 {
        k
    } else {
        0.0
    }
}

/// Whether a secondary ray's hit blocks it. A voxel or proxy met at distance 0 is the stand-in
/// of a cell that holds the ray's origin (only where a block is missing): it says nothing about
/// what lies along the ray, so it does not block.
pub fn occludes(hit: &Hit) -> bool {
    matches!(hit.surface, Surface::Triangle { .. }) || hit.t > 0.0
}

/// Shadow rays towards one point light.
pub struct Shadows<'a> {
    scene: &'a Scene,
    cache: &'a dyn BlockCache,
    light: [f32; 3],
    pixel_c: f32,
    lo: [f32; 3],
    hi: [f32; 3],
    /// Hidden parts cast no shadow ([`Shadows::with_parts`]).
    parts: Option<&'a PartFilter>,
}

impl<'a> Shadows<'a> {
    /// `light` in stored coordinates; `pixel_c` the primary rays' LOD constant.
    pub fn new(
        scene: &'a Scene,
        cache: &'a dyn BlockCache,
        light: [f32; 3],
        pixel_c: f32,
    ) -> Shadows<'a> {
        let m = scene.metadata();
        Shadows {
            scene,
            cache,
            light,
            pixel_c,
            lo: m.scene.bounds_min,
            hi: m.scene.bounds_max,
            parts: None,
        }
    }

    /// Shadow rays that pass the parts `filter` hides ([`Tracer::with_parts`]).
    pub fn with_parts(mut self, filter: &'a PartFilter) -> Shadows<'a> {
        self.parts = Some(filter);
        self
    }

    /// The light's position, in stored coordinates.
    pub fn light(&self) -> [f32; 3] {
        self.light
    }

    /// Whether the light reaches the hit `from` of a primary ray that travelled `t_primary`:
    /// one shadow ray from the offset origin to the light.
    pub fn visible(&self, from: &Origin, t_primary: f32, memo: &mut Memo) -> bool {
        let p = from.point();
        let Some(l) = unit_towards(p, self.light) else {
            return true;
        };
        let o = from.spawn(l.0);
        let Some((dir, dist)) = unit_towards(o, self.light) else {
            return true;
        };
        let ray = Ray::new(o, dir);
        let exit = ray_box(&ray, self.lo, self.hi, 0.0, 0.0, dist).map_or(0.0, |b| b.1);
        let k = shadow_lod_c(self.pixel_c, t_primary, dist, exit);
        let tracer = Tracer::new(self.scene, self.cache, k);
        let tracer = match self.parts {
            Some(f) => tracer.with_parts(f),
            None => tracer,
        };
        !tracer
            .trace_to(&ray, dist, memo)
            .is_some_and(|h| occludes(&h))
    }
}

/// The unit direction from `a` to `b` and the distance, computed in f64; None when they
/// coincide or the distance is not finite.
pub fn unit_towards(a: [f32; 3], b: [f32; 3]) -> Option<([f32; 3], f32)> {
    let d = [0, 1, 2].map(|k| f64::from(b[k]) - f64::from(a[k]));
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    (len > 0.0 && len.is_finite()).then(|| (d.map(|c| (c / len) as f32), len as f32))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shadow_metric_bounds_the_edge_shift_for_every_occluder_before_s_m() {
        let (c, tp, light, exit) = (0.002f32, 10.0, 50.0, 8.0);
        let k = shadow_lod_c(c, tp, light, exit);
        for i in 1..=80 {
            let s = exit * i as f32 / 80.0;
            let shift = s * k * light / (light - s);
            assert!(shift <= c * tp * 1.0001, "s {s}: {shift} > {}", c * tp);
        }
        // The bound is tight at s_m.
        let shift = exit * k * light / (light - exit);
        assert!((shift - c * tp).abs() < 1e-6);
    }

    #[test]
    fn full_detail_when_lod_is_off_or_the_ray_never_enters_the_scene() {
        assert_eq!(shadow_lod_c(0.0, 10.0, 50.0, 8.0), 0.0);
        assert_eq!(shadow_lod_c(0.01, 10.0, 50.0, 0.0), 0.0);
        assert_eq!(shadow_lod_c(0.01, 10.0, 0.0, 8.0), 0.0);
        assert_eq!(shadow_lod_c(f32::NAN, 10.0, 50.0, 8.0), 0.0);
        // A light inside the box: occluders up to half way are bounded.
        let k = shadow_lod_c(0.01, 10.0, 4.0, 8.0);
        assert!((k - 0.01 * 10.0 / 4.0).abs() < 1e-7);
    }

    #[test]
    fn unit_towards_refuses_coincident_points() {
        assert!(unit_towards([1.0; 3], [1.0; 3]).is_none());
        let (d, len) = unit_towards([0.0; 3], [0.0, 3.0, 4.0]).unwrap_or_default();
        assert_eq!((d, len), ([0.0, 0.6, 0.8], 5.0));
    }
}
