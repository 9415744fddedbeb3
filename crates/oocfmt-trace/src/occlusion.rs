//! Ambient occlusion (`--ao N`): N rays per primary hit, cosine-weighted over the hemisphere on
//! the viewer's side of the surface, each blocked or not within a distance; the share that
//! escapes scales the ambient light.
//!
//! The metric is the solid-angle one of Áfra (2012) §6.2, after Pantaleoni et al. 2010: N rays
//! over the hemisphere each stand for a cone of 2π/N steradians. A cone of solid angle Ω is, at
//! distance t, a disc of radius t·√(Ω/π) (the disc of that solid angle seen face-on, to first
//! order), so an AO ray may end on a voxel whose radius is at most t·√(2/N): the voxel is no
//! larger than the ray's share of the hemisphere. The metric is on whenever LOD is (`poe` > 0);
//! at `poe` 0 every ray, AO included, sees full detail.
//!
//! A LOD entry covering α of its cell blocks α of the cone that stops on it, on average: an AO
//! ray goes on behind it and lets through Π (1 − α) of the entries it crosses before an opaque
//! surface (spec §5.1). Taken as opaque, thin parts and rough cells seen through coarse entries
//! made LOD ambient occlusion several levels too dark (docs/benchmarks.md).

use crate::cache::BlockCache;
use crate::intersect::Ray;
use crate::light::occludes;
use crate::parts::PartFilter;
use crate::sampling::{cosine_hemisphere, point};
use crate::scene::Scene;
use crate::spawn::Origin;
use crate::traverse::{Memo, Tracer};

/// The default reach of AO rays, as a share of the diagonal of the scene's box.
pub const DEFAULT_DISTANCE: f32 = 0.1;

/// The solid-angle LOD constant of N rays over the hemisphere: √(2/N).
pub fn ao_lod_c(rays: u32) -> f32 {
    (2.0 / rays.max(1) as f32).sqrt()
}

/// [`DEFAULT_DISTANCE`] times the diagonal of the box [lo, hi] (1 for an empty box).
pub fn default_distance(lo: [f32; 3], hi: [f32; 3]) -> f32 {
    let d = (0..3)
        .map(|k| (f64::from(hi[k]) - f64::from(lo[k])).powi(2))
        .sum::<f64>()
        .sqrt() as f32;
    if d > 0.0 && d.is_finite() {
        DEFAULT_DISTANCE * d
    } else {
        1.0
    }
}

/// The AO rays of one frame: how many per hit, how far they reach, and the tracer they run
/// on (with the solid-angle LOD constant when LOD is on).
pub struct Occlusion<'a> {
    tracer: Tracer<'a>,
    rays: u32,
    distance: f32,
}

impl<'a> Occlusion<'a> {
    /// `rays` ≥ 1 per hit reaching `distance`; `lod` switches the solid-angle metric on.
    pub fn new(
        scene: &'a Scene,
        cache: &'a dyn BlockCache,
        rays: u32,
        distance: f32,
        lod: bool,
    ) -> Occlusion<'a> {
        let rays = rays.max(1);
        let c = if lod { ao_lod_c(rays) } else { 0.0 };
        Occlusion {
            tracer: Tracer::new(scene, cache, c),
            rays,
            distance,
        }
    }

    /// Occlusion rays that pass the parts `filter` hides ([`Tracer::with_parts`]).
    pub fn with_parts(mut self, filter: &'a PartFilter) -> Occlusion<'a> {
        self.tracer = self.tracer.with_parts(filter);
        self
    }

    /// AO rays traced per shaded hit, at least 1.
    pub fn rays(&self) -> u32 {
        self.rays
    }

    /// The share of the light from the hemisphere around the unit vector `n` that reaches
    /// `from` within the distance: the mean of the rays' transmittance; `seed` rotates the
    /// pattern (one per primary ray).
    pub fn open(&self, from: &Origin, n: [f32; 3], seed: u64, memo: &mut Memo) -> f32 {
        let mut open = 0.0;
        for i in 0..self.rays {
            let dir = cosine_hemisphere(n, point(i, self.rays, seed));
            let ray = Ray::new(from.spawn(dir), dir);
            open += self.transmittance(&ray, memo);
        }
        open / self.rays as f32
    }

    /// What `ray` lets through within the distance: 0 when it ends on an opaque surface, else
    /// the product of 1 − α over the translucent LOD entries it crosses (1 past nothing).
    fn transmittance(&self, ray: &Ray, memo: &Memo) -> f32 {
        let layers = self.tracer.trace_layers(ray, self.distance, memo);
        if layers.end.as_ref().is_some_and(occludes) {
            return 0.0;
        }
        layers
            .translucent
            .iter()
            .filter(|h| occludes(h))
            .map(|h| 1.0 - h.coverage.clamp(0.0, 1.0))
            .product()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cone_radius_shrinks_with_the_square_root_of_the_ray_count() {
        assert!((ao_lod_c(2) - 1.0).abs() < 1e-7);
        assert!((ao_lod_c(8) - 0.5).abs() < 1e-7);
        assert_eq!(ao_lod_c(0), ao_lod_c(1));
    }

    #[test]
    fn the_default_distance_follows_the_scene() {
        assert!((default_distance([0.0; 3], [3.0, 4.0, 0.0]) - 0.5).abs() < 1e-6);
        assert_eq!(default_distance([1.0; 3], [1.0; 3]), 1.0);
    }
}
