//! One frame: rays in parallel over 16 × 16 tiles, an RGB8 image, a depth image and figures.
//!
//! Each pixel's centre ray gives its depth and its ending (the figures' primary endings). With
//! one ray per pixel it also gives the colour; with `spp` > 1 the colour is the mean, in linear
//! RGB, of `spp` further rays through stratified points of the pixel
//! ([`crate::sampling::pixel_offset`]), so the depth stays that of the centre. The centre rays
//! of a tile are traced first, in packets of 2 × 2 pixels ([`Tracer::trace_packet`]: the same
//! hits as ray by ray, in a fraction of the time), then each pixel is shaded in turn.

use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::cache::{BlockCache, CacheStats};
use crate::camera::Camera;
use crate::error::TraceError;
use crate::intersect::Ray;
use crate::light::{shoulder_light, Shadows};
use crate::occlusion::{default_distance, Occlusion};
use crate::sampling::{hash, pixel_offset, Stream};
use crate::scene::Scene;
use crate::shade::{encode_srgb, Lighting, Secondary};
use crate::traverse::{Hit, Memo, Surface, Tracer};

const TILE: u32 = 16;

/// The pixels of a packet of primary rays traced together ([`Tracer::trace_packet`]).
const PACKET_W: usize = 2;
const PACKET_H: usize = 2;

/// The most primary rays per pixel and ambient-occlusion rays per primary ray.
pub const MAX_SAMPLES: u32 = 1024;

/// A finished tile: its index, colours, depths, ray endings, secondary rays and nodes visited.
type TileOut = (u32, Vec<[u8; 3]>, Vec<f32>, Endings, Secondary, u64);

/// What one frame shows and at what level of detail; [`RenderOptions::DEFAULT`] is full
/// detail under the headlight. [`render`] refuses values out of range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Pixels of error: a LOD voxel ends a ray when its radius is at most this many pixels.
    /// 0 renders full detail.
    pub poe: f32,
    /// Linear RGB of a ray that hits nothing.
    pub background: [f32; 3],
    /// Primary rays per pixel, 1 ..= [`MAX_SAMPLES`]: 1 is the pixel's centre; more are
    /// stratified over the pixel and averaged in linear RGB.
    pub spp: u32,
    /// Lambert from a point light, with one shadow ray per primary hit, instead of the
    /// headlight.
    pub shadows: bool,
    /// The point light in stored coordinates; None: [`shoulder_light`] of the camera.
    pub light: Option<[f64; 3]>,
    /// Ambient-occlusion rays per primary hit, 0 ..= [`MAX_SAMPLES`] (0: none).
    pub ao: u32,
    /// How far ambient-occlusion rays look; None: [`default_distance`] of the scene.
    pub ao_distance: Option<f32>,
}

impl RenderOptions {
    /// Full detail, headlight, one ray per pixel.
    pub const DEFAULT: RenderOptions = RenderOptions {
        poe: 0.0,
        background: [0.05, 0.06, 0.08],
        spp: 1,
        shadows: false,
        light: None,
        ao: 0,
        ao_distance: None,
    };

    fn check(&self) -> Result<(), TraceError> {
        let bad = |m: String| Err(TraceError::Options(m));
        if !(self.poe.is_finite() && self.poe >= 0.0) {
            return bad(format!("--poe {}: expected a finite number >= 0", self.poe));
        }
        if !(1..=MAX_SAMPLES).contains(&self.spp) {
            return bad(format!("--spp {}: expected 1 to {MAX_SAMPLES}", self.spp));
        }
        if self.ao > MAX_SAMPLES {
            return bad(format!("--ao {}: expected 0 to {MAX_SAMPLES}", self.ao));
        }
        if let Some(d) = self.ao_distance {
            if !(d.is_finite() && d > 0.0) {
                return bad(format!("--ao-distance {d}: expected a finite number > 0"));
            }
        }
        if let Some(l) = self.light {
            if l.iter()
                .any(|c| !c.is_finite() || c.abs() > f64::from(f32::MAX))
            {
                return bad(format!("--light {l:?}: expected finite coordinates"));
            }
        }
        Ok(())
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions::DEFAULT
    }
}

/// A rendered frame: colour and depth per pixel.
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// sRGB-encoded colour, row-major, row 0 at the top, 3 bytes per pixel.
    pub rgb: Vec<u8>,
    /// Hit distance of the pixel's centre ray along its unit direction, +inf for a miss; same
    /// order as `rgb`.
    pub depth: Vec<f32>,
}

/// How primary rays ended.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq, Eq)]
pub struct Endings {
    /// On a triangle: full detail.
    pub triangle: u64,
    /// On a LOD voxel (within the pixels of error, or above a missing block).
    pub voxel: u64,
    /// On an R-LOD plane.
    pub rlod: u64,
    /// On the proxy of a subtree whose block was not available.
    pub proxy: u64,
    /// On nothing: the background.
    pub miss: u64,
}

impl Endings {
    fn add(&mut self, o: &Endings) {
        self.triangle += o.triangle;
        self.voxel += o.voxel;
        self.rlod += o.rlod;
        self.proxy += o.proxy;
        self.miss += o.miss;
    }
}

/// The figures of one frame, as `oocfmt render` reports them.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FrameStats {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The pixels of error the frame was rendered at ([`RenderOptions::poe`]).
    pub poe: f32,
    /// The LOD constant C = poe · 2 tan(fov_y / 2) / height.
    pub lod_c: f64,
    /// Render threads (rayon's pool size).
    pub threads: usize,
    /// Milliseconds of wall time from the frame's start ([`BlockCache::begin_frame`]) until
    /// the last tile was traced and shaded; setup and image assembly excluded.
    pub ms: f64,
    /// Every ray traced: primary, shadow and ambient occlusion.
    pub rays: u64,
    /// `rays` per second of the frame.
    pub rays_per_second: f64,
    /// Primary rays per pixel for the colour.
    pub spp: u32,
    /// Primary rays: one per pixel, plus `spp` per pixel when `spp` > 1 (the centre ray then
    /// gives the depth and the endings only).
    pub primary_rays: u64,
    /// Shadow rays towards the point light (with `shadows`).
    pub shadow_rays: u64,
    /// Ambient-occlusion rays.
    pub ao_rays: u64,
    /// How the pixels' centre rays ended.
    pub primary: Endings,
    /// Kd-tree nodes (inner, LOD, leaf) the frame's rays visited.
    pub nodes_visited: u64,
    /// `nodes_visited` over `rays`.
    pub nodes_per_ray: f64,
    /// The cache's counters after the frame (cumulative over the cache's life).
    pub cache: CacheStats,
}

/// The primary hits of a tile's `rays` (row-major, `width` per row): packets of
/// [`PACKET_W`] × [`PACKET_H`] pixels traced together, the pixels of the tile's ragged edge
/// alone. Each ray's wants are logged under its index in the tile, for the caller to release
/// in pixel order.
fn primary_hits(tracer: &Tracer<'_>, rays: &[Ray], width: usize, memo: &Memo) -> Vec<Option<Hit>> {
    const N: usize = PACKET_W * PACKET_H;
    let height = rays.len() / width.max(1);
    let mut hits: Vec<Option<Hit>> = (0..rays.len()).map(|_| None).collect();
    for py in (0..height).step_by(PACKET_H) {
        for px in (0..width).step_by(PACKET_W) {
            let idx: [usize; N] =
                std::array::from_fn(|j| (py + j / PACKET_W) * width + px + j % PACKET_W);
            let whole = px + PACKET_W <= width && py + PACKET_H <= height;
            if let (true, Some(&fill)) = (whole, rays.get(idx[0])) {
                // Every index is inside a whole packet: `fill` is never used.
                let packet = idx.map(|k| rays.get(k).copied().unwrap_or(fill));
                let out = tracer.trace_packet(&packet, &idx.map(|k| k as u32), memo);
                for (k, hit) in idx.into_iter().zip(out) {
                    if let Some(h) = hits.get_mut(k) {
                        *h = hit;
                    }
                }
                continue;
            }
            for y in py..(py + PACKET_H).min(height) {
                for x in px..(px + PACKET_W).min(width) {
                    let k = y * width + x;
                    if let (Some(ray), Some(h)) = (rays.get(k), hits.get_mut(k)) {
                        memo.defer_wants(Some(k as u32));
                        *h = tracer.trace(ray, memo);
                        memo.defer_wants(None);
                    }
                }
            }
        }
    }
    hits
}

/// Renders one frame of `scene` through `cache`. `camera` is in stored coordinates.
pub fn render(
    scene: &Scene,
    cache: &dyn BlockCache,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<(Image, FrameStats), TraceError> {
    opts.check()?;
    let frame = camera.frame()?;
    let lod_c = f64::from(opts.poe) * frame.pixel_angle();
    let tracer = Tracer::new(scene, cache, lod_c as f32);
    let m = scene.metadata();
    let bounds = (m.scene.bounds_min, m.scene.bounds_max);
    let shadows = opts.shadows.then(|| {
        let light = opts
            .light
            .unwrap_or_else(|| shoulder_light(&frame, bounds.0, bounds.1));
        Shadows::new(scene, cache, light.map(|c| c as f32), lod_c as f32)
    });
    let occlusion = (opts.ao > 0).then(|| {
        let distance = opts
            .ao_distance
            .unwrap_or_else(|| default_distance(bounds.0, bounds.1));
        Occlusion::new(scene, cache, opts.ao, distance, opts.poe > 0.0)
    });
    let lighting = Lighting::new(&m.materials, shadows, occlusion, bounds);
    let (w, h) = (frame.width(), frame.height());
    let spp = opts.spp;
    let tiles_x = w.div_ceil(TILE);
    let tiles = tiles_x * h.div_ceil(TILE);
    let background = opts.background.map(encode_srgb);
    let start = Instant::now();
    cache.begin_frame();
    let done: Vec<TileOut> = (0..tiles)
        .into_par_iter()
        .map_init(
            || Memo::pooled(scene),
            |memo, tile| {
                memo.clear();
                let (x0, y0) = ((tile % tiles_x) * TILE, (tile / tiles_x) * TILE);
                let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
                let n = ((x1 - x0) * (y1 - y0)) as usize;
                let mut rgb = Vec::with_capacity(n);
                let mut depth = Vec::with_capacity(n);
                let mut endings = Endings::default();
                let mut secondary = Secondary::default();
                let mut rays = Vec::with_capacity(n);
                for y in y0..y1 {
                    for x in x0..x1 {
                        rays.push(frame.ray(x, y));
                    }
                }
                let mut hits = primary_hits(&tracer, &rays, (x1 - x0) as usize, memo);
                for (k, (y, x)) in (y0..y1)
                    .flat_map(|y| (x0..x1).map(move |x| (y, x)))
                    .enumerate()
                {
                    // The primary ray's wants, in the order it would have made them traced
                    // alone: before its shading's.
                    memo.release_deferred(k as u32);
                    let (Some(&ray), Some(hit)) = (rays.get(k), hits.get_mut(k)) else {
                        continue;
                    };
                    let hit = hit.take();
                    match &hit {
                        Some(hit) => {
                            match hit.surface {
                                Surface::Triangle { .. } => endings.triangle += 1,
                                Surface::Voxel(_) => endings.voxel += 1,
                                Surface::Plane { .. } => endings.rlod += 1,
                                Surface::Proxy(_) => endings.proxy += 1,
                            }
                            depth.push(hit.t);
                        }
                        None => {
                            endings.miss += 1;
                            depth.push(f32::INFINITY);
                        }
                    }
                    if spp == 1 {
                        rgb.push(match &hit {
                            Some(hit) => {
                                let seed = hash(x, y, 0, Stream::Occlusion);
                                lighting
                                    .colour(hit, &ray, seed, memo, &mut secondary)
                                    .map(encode_srgb)
                            }
                            None => background,
                        });
                        continue;
                    }
                    let mut sum = [0f32; 3];
                    for k in 0..spp {
                        let [ox, oy] = pixel_offset(x, y, k, spp);
                        let ray = frame.ray_at(f64::from(x) + ox, f64::from(y) + oy);
                        let c = match tracer.trace(&ray, memo) {
                            Some(hit) => {
                                let seed = hash(x, y, k, Stream::Occlusion);
                                lighting.colour(&hit, &ray, seed, memo, &mut secondary)
                            }
                            None => opts.background,
                        };
                        for (s, c) in sum.iter_mut().zip(c) {
                            *s += c;
                        }
                    }
                    rgb.push(sum.map(|s| encode_srgb(s / spp as f32)));
                }
                memo.flush(cache);
                (tile, rgb, depth, endings, secondary, memo.take_visited())
            },
        )
        .collect();
    let seconds = start.elapsed().as_secs_f64();
    let mut image = Image {
        width: w,
        height: h,
        rgb: vec![0; 3 * (w as usize) * (h as usize)],
        depth: vec![f32::INFINITY; (w as usize) * (h as usize)],
    };
    let mut primary = Endings::default();
    let mut secondary = Secondary::default();
    let mut nodes_visited = 0;
    for (tile, rgb, depth, endings, more, visited) in done {
        primary.add(&endings);
        secondary.add(&more);
        nodes_visited += visited;
        let (x0, y0) = ((tile % tiles_x) * TILE, (tile / tiles_x) * TILE);
        let tw = ((x0 + TILE).min(w) - x0) as usize;
        for (k, (c, d)) in rgb.iter().zip(&depth).enumerate() {
            let (x, y) = (x0 as usize + k % tw, y0 as usize + k / tw);
            let at = y * w as usize + x;
            if let Some(p) = image.depth.get_mut(at) {
                *p = *d;
            }
            if let Some(p) = image.rgb.get_mut(3 * at..3 * at + 3) {
                p.copy_from_slice(c);
            }
        }
    }
    let pixels = u64::from(w) * u64::from(h);
    let primary_rays = if spp > 1 {
        pixels * (1 + u64::from(spp))
    } else {
        pixels
    };
    let rays = primary_rays + secondary.shadow + secondary.ao;
    let stats = FrameStats {
        width: w,
        height: h,
        poe: opts.poe,
        lod_c,
        threads: rayon::current_num_threads(),
        ms: seconds * 1e3,
        rays,
        rays_per_second: rays as f64 / seconds.max(1e-9),
        spp,
        primary_rays,
        shadow_rays: secondary.shadow,
        ao_rays: secondary.ao,
        primary,
        nodes_visited,
        nodes_per_ray: nodes_visited as f64 / rays.max(1) as f64,
        cache: cache.stats(),
    };
    Ok((image, stats))
}
