//! One frame: rays in parallel over 16 × 16 tiles, an RGB8 image, a depth image and figures.
//!
//! Each pixel's centre ray gives its depth and its ending (the figures' primary endings). With
//! one ray per pixel it also gives the colour; with `spp` > 1 the colour is the mean, in linear
//! RGB, of `spp` further rays through stratified points of the pixel
//! ([`crate::sampling::pixel_offset`]), so the depth stays that of the centre. The centre rays
//! of a tile are traced first, in packets of 2 × 2 pixels ([`Tracer::trace_packet`]: the same
//! hits as ray by ray, in a fraction of the time; with translucent LOD entries
//! [`Tracer::trace_packet_layers`], every layer each ray meets in the same walk), then each pixel
//! is shaded in turn. A tile
//! none of whose pixels can see the scene's box ([`crate::reach`]) is background without a
//! ray.

use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::cache::{BlockCache, CacheStats};
use crate::camera::{Camera, Frame};
use crate::composite::blend;
use crate::error::TraceError;
use crate::intersect::Ray;
use crate::light::{shoulder_light, Shadows};
use crate::occlusion::{default_distance, Occlusion};
use crate::parts::PartFilter;
use crate::reach::{box_pixels, PixelRect};
use crate::sampling::{hash, pixel_offset, Stream};
use crate::scene::Scene;
use crate::section::{Clip, Section};
use crate::shade::{encode_srgb, Lighting, Secondary};
use crate::traverse::{Hit, Layers, Memo, Surface, Tracer};

const TILE: u32 = 16;

/// The pixels of a packet of primary rays traced together ([`Tracer::trace_packet`]).
const PACKET_W: usize = 2;
const PACKET_H: usize = 2;

/// The most primary rays per pixel and ambient-occlusion rays per primary ray.
pub const MAX_SAMPLES: u32 = 1024;

/// A finished tile: what its pixels show and what tracing them cost.
struct TileOut {
    /// The tile's index, row-major over the frame's tiles.
    tile: u32,
    /// sRGB colours, row-major over the tile.
    rgb: Vec<[u8; 3]>,
    /// Centre-ray depths, in the order of `rgb`.
    depth: Vec<f32>,
    /// Whether the pixel shows the model ([`Image::model`]), in the order of `rgb`.
    model: Vec<bool>,
    /// How the tile's centre rays ended.
    endings: Endings,
    /// Shadow and ambient-occlusion rays traced while shading the tile.
    secondary: Secondary,
    /// Kd-tree nodes the tile's rays visited.
    visited: u64,
}

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
    /// Show LOD entries that cover part of their cell as translucent, composited front to back
    /// over what lies behind (spec §5.1), so thin parts keep their size; off, every LOD entry
    /// ends its ray, a little faster on rough surfaces, and thin parts swell to their cells.
    pub translucent: bool,
}

impl RenderOptions {
    /// Full detail, headlight, one ray per pixel, translucent LOD entries.
    pub const DEFAULT: RenderOptions = RenderOptions {
        poe: 0.0,
        background: [0.05, 0.06, 0.08],
        spp: 1,
        shadows: false,
        light: None,
        ao: 0,
        ao_distance: None,
        translucent: true,
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
    /// Whether the pixel shows the model: its centre ray or one of its sample rays hit
    /// something (a semi-transparent voxel counts); same order as `depth`. Error measures
    /// taken "on the model's pixels" use the pixels this marks in either image.
    pub model: Vec<bool>,
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
    /// Counts how a centre ray ended: on `hit`'s surface, or on nothing.
    #[inline]
    fn record(&mut self, hit: Option<&Hit>) {
        match hit.map(|h| &h.surface) {
            Some(Surface::Triangle { .. }) => self.triangle += 1,
            Some(Surface::Voxel { .. }) => self.voxel += 1,
            Some(Surface::Plane { .. }) => self.rlod += 1,
            Some(Surface::Proxy(_)) => self.proxy += 1,
            None => self.miss += 1,
        }
    }

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
    /// Times a render thread waited on I/O during the frame: block reads made on render
    /// threads ([`CacheStats::render_waits`]), every miss with the blocking and mmap caches,
    /// none with the asynchronous cache.
    pub waits: u64,
    /// The cache's counters after the frame (cumulative over the cache's life).
    pub cache: CacheStats,
}

/// Pixels of a tile traced together: a packet of [`PACKET_W`] × [`PACKET_H`], or one pixel of
/// the tile's ragged edge (row-major indices in the tile).
enum Pixels {
    Packet([usize; PACKET_W * PACKET_H]),
    Alone(usize),
}

/// Calls `each` with the pixels of a tile of `width` × `height` in the order they are traced.
fn packets(width: usize, height: usize, mut each: impl FnMut(Pixels)) {
    for py in (0..height).step_by(PACKET_H) {
        for px in (0..width).step_by(PACKET_W) {
            if px + PACKET_W <= width && py + PACKET_H <= height {
                each(Pixels::Packet(std::array::from_fn(|j| {
                    (py + j / PACKET_W) * width + px + j % PACKET_W
                })));
                continue;
            }
            for y in py..(py + PACKET_H).min(height) {
                for x in px..(px + PACKET_W).min(width) {
                    each(Pixels::Alone(y * width + x));
                }
            }
        }
    }
}

/// The rays of packet `idx` in `rays` (None past the end).
fn packet_rays(
    rays: &[Ray],
    idx: [usize; PACKET_W * PACKET_H],
) -> Option<[Ray; PACKET_W * PACKET_H]> {
    let &fill = rays.get(idx[0])?;
    // Every index is inside a whole packet: `fill` is never used.
    Some(idx.map(|k| rays.get(k).copied().unwrap_or(fill)))
}

/// What a tile's primary rays met, pixel by pixel: the surface each ends on and, where LOD
/// entries are translucent, the layers in front of it (`front[spans[k]]`, nearest first).
struct Primaries {
    ends: Vec<Option<Hit>>,
    front: Vec<Hit>,
    spans: Vec<(u32, u32)>,
}

impl Primaries {
    /// Takes `layers` as what pixel `k`'s ray met.
    fn put(&mut self, k: usize, layers: &mut Layers) {
        let start = self.front.len() as u32;
        self.front.extend(layers.translucent.drain(..));
        if let (Some(span), Some(end)) = (self.spans.get_mut(k), self.ends.get_mut(k)) {
            *span = (start, self.front.len() as u32);
            *end = layers.end.take();
        }
    }

    /// Pixel `k`'s translucent layers and the surface behind them.
    fn of(&self, k: usize) -> (&[Hit], Option<&Hit>) {
        let front = self
            .spans
            .get(k)
            .and_then(|&(a, b)| self.front.get(a as usize..b as usize));
        let end = self.ends.get(k).and_then(Option::as_ref);
        (front.unwrap_or(&[]), end)
    }
}

/// What a tile's primary `rays` (row-major, `width` per row) meet, traced in packets
/// ([`packets`]): with `limits` (each ray's farthest distance, infinity past its end) every
/// translucent LOD entry in front of the surface each ends on ([`Tracer::trace_packet_layers`]),
/// without, that surface alone ([`Tracer::trace_packet`]). Each ray's wants are logged under
/// its index in the tile, for the caller to release in pixel order.
fn primaries(
    tracer: &Tracer<'_>,
    rays: &[Ray],
    limits: Option<&[f32]>,
    width: usize,
    memo: &Memo,
) -> Primaries {
    let height = rays.len() / width.max(1);
    let mut out = Primaries {
        ends: (0..rays.len()).map(|_| None).collect(),
        front: Vec::new(),
        spans: vec![(0, 0); rays.len()],
    };
    let limit = |k: usize, l: &[f32]| l.get(k).copied().unwrap_or(f32::INFINITY);
    let mut scratch: [Layers; PACKET_W * PACKET_H] = Default::default();
    packets(width, height, |pixels| match pixels {
        Pixels::Packet(idx) => {
            let Some(packet) = packet_rays(rays, idx) else {
                return;
            };
            let keys = idx.map(|k| k as u32);
            match limits {
                Some(l) => {
                    let t_max = idx.map(|k| limit(k, l));
                    tracer.trace_packet_layers(&packet, &keys, t_max, memo, &mut scratch);
                    for (k, layers) in idx.into_iter().zip(&mut scratch) {
                        out.put(k, layers);
                    }
                }
                None => {
                    let hits = tracer.trace_packet(&packet, &keys, memo);
                    for (k, hit) in idx.into_iter().zip(hits) {
                        if let Some(end) = out.ends.get_mut(k) {
                            *end = hit;
                        }
                    }
                }
            }
        }
        Pixels::Alone(k) => {
            let Some(ray) = rays.get(k) else {
                return;
            };
            memo.defer_wants(Some(k as u32));
            match limits {
                Some(l) => out.put(k, &mut tracer.trace_layers(ray, limit(k, l), memo)),
                None => {
                    if let Some(end) = out.ends.get_mut(k) {
                        *end = tracer.trace(ray, memo);
                    }
                }
            }
            memo.defer_wants(None);
        }
    });
    out
}

/// Adds linear RGB `c` to `sum`.
#[inline]
fn add_to(sum: &mut [f32; 3], c: [f32; 3]) {
    for (s, c) in sum.iter_mut().zip(c) {
        *s += c;
    }
}

/// The sRGB encoding of the mean of `n` ≥ 1 linear RGB colours summing to `sum`.
fn mean_srgb(sum: [f32; 3], n: u32) -> [u8; 3] {
    sum.map(|s| encode_srgb(s / n.max(1) as f32))
}

/// Renders one frame of `scene` through `cache`. `camera` is in stored coordinates. The
/// frame shows the parts the scene's filter shows ([`Scene::set_parts`], read once here), cut
/// by the scene's section plane ([`Scene::set_section`], read once here): primary rays see
/// only the kept half-space ([`crate::section`]).
pub fn render(
    scene: &Scene,
    cache: &dyn BlockCache,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<(Image, FrameStats), TraceError> {
    opts.check()?;
    render_frame(scene, cache, &camera.frame()?, opts)
}

/// [`render`] through a camera's frame made already: one aimed at a sample of every pixel
/// ([`Frame::aimed`]) renders a pass of an accumulated image (`crate::live`).
pub fn render_frame(
    scene: &Scene,
    cache: &dyn BlockCache,
    frame: &Frame,
    opts: &RenderOptions,
) -> Result<(Image, FrameStats), TraceError> {
    opts.check()?;
    let parts = scene.parts();
    let mut job = FrameJob::new(scene, cache, frame, opts, &parts);
    job.section = scene.stored_section();
    let start = Instant::now();
    let waits = cache.render_waits();
    cache.begin_frame();
    let done: Vec<TileOut> = (0..job.tiles())
        .into_par_iter()
        .map_init(|| Memo::pooled(scene), |memo, tile| job.tile(tile, memo))
        .collect();
    let seconds = start.elapsed().as_secs_f64();
    let (image, mut totals) = job.assemble(done);
    totals.waits = cache.render_waits().saturating_sub(waits);
    Ok((image, job.stats(&totals, seconds)))
}

/// What every tile of one frame shares: the camera, the tracer and the lighting, built once
/// before the first tile.
struct FrameJob<'a> {
    frame: &'a Frame,
    opts: &'a RenderOptions,
    cache: &'a dyn BlockCache,
    tracer: Tracer<'a>,
    lighting: Lighting<'a>,
    /// The LOD constant ([`FrameStats::lod_c`]).
    lod_c: f64,
    /// Tiles per row of the image.
    tiles_x: u32,
    /// The sRGB colour of a centre ray that hits nothing, with one ray per pixel.
    background: [u8; 3],
    /// The sRGB colour of a pixel all of whose rays hit nothing: `background`, or with
    /// `spp` > 1 the mean of `spp` background colours as [`FrameJob::stratified`] takes it.
    missed: [u8; 3],
    /// The pixels whose rays may meet the scene's box; the others miss ([`box_pixels`]).
    reach: PixelRect,
    /// The section plane clipping the primary rays, in stored coordinates.
    section: Option<Section>,
}

/// The figures of a frame's tiles, added up.
#[derive(Default)]
struct FrameTotals {
    primary: Endings,
    secondary: Secondary,
    nodes_visited: u64,
    /// Block reads the frame's render threads waited for ([`FrameStats::waits`]).
    waits: u64,
}

impl<'a> FrameJob<'a> {
    /// The frame setup: the LOD constant from the pixels of error, the shadow light and the
    /// occlusion distance (the options' or the defaults for this camera and scene), and the
    /// part filter every tracer and the shading follow.
    fn new(
        scene: &'a Scene,
        cache: &'a dyn BlockCache,
        frame: &'a Frame,
        opts: &'a RenderOptions,
        parts: &'a PartFilter,
    ) -> FrameJob<'a> {
        let lod_c = f64::from(opts.poe) * frame.pixel_angle();
        let m = scene.metadata();
        let bounds = (m.scene.bounds_min, m.scene.bounds_max);
        let shadows = opts.shadows.then(|| {
            let light = opts
                .light
                .unwrap_or_else(|| shoulder_light(frame, bounds.0, bounds.1));
            Shadows::new(scene, cache, light.map(|c| c as f32), lod_c as f32).with_parts(parts)
        });
        let occlusion = (opts.ao > 0).then(|| {
            let distance = opts
                .ao_distance
                .unwrap_or_else(|| default_distance(bounds.0, bounds.1));
            Occlusion::new(scene, cache, opts.ao, distance, opts.poe > 0.0).with_parts(parts)
        });
        let tracer = Tracer::new(scene, cache, lod_c as f32).with_parts(parts);
        // The box as the tracer's root test pads it for these rays (all start at the eye).
        let pad = f64::from(tracer.ray_eps(&frame.ray(0, 0)));
        let reach = box_pixels(
            frame,
            tracer.lo.map(|c| f64::from(c) - pad),
            tracer.hi.map(|c| f64::from(c) + pad),
        );
        let missed = if opts.spp > 1 {
            let mut sum = [0f32; 3];
            for _ in 0..opts.spp {
                add_to(&mut sum, opts.background);
            }
            mean_srgb(sum, opts.spp)
        } else {
            opts.background.map(encode_srgb)
        };
        FrameJob {
            frame,
            opts,
            cache,
            tracer,
            lighting: Lighting::new(&m.materials, shadows, occlusion, bounds).with_parts(parts),
            lod_c,
            tiles_x: frame.width().div_ceil(TILE),
            background: opts.background.map(encode_srgb),
            missed,
            reach,
            section: None,
        }
    }

    fn tiles(&self) -> u32 {
        self.tiles_x * self.frame.height().div_ceil(TILE)
    }

    /// The pixels of tile `tile`: x0..x1 by y0..y1, as `(x0, y0, x1, y1)`.
    fn tile_rect(&self, tile: u32) -> (u32, u32, u32, u32) {
        let (x0, y0) = ((tile % self.tiles_x) * TILE, (tile / self.tiles_x) * TILE);
        let (x1, y1) = (
            (x0 + TILE).min(self.frame.width()),
            (y0 + TILE).min(self.frame.height()),
        );
        (x0, y0, x1, y1)
    }

    /// Traces and shades one tile: its centre rays first, in packets ([`primaries`]), then
    /// each pixel in row-major order.
    fn tile(&self, tile: u32, memo: &mut Memo) -> TileOut {
        let (x0, y0, x1, y1) = self.tile_rect(tile);
        let n = ((x1 - x0) * (y1 - y0)) as usize;
        if !self.reach.overlaps((x0, y0, x1, y1)) {
            return self.missed_tile(tile, n);
        }
        memo.clear();
        let mut out = TileOut {
            tile,
            rgb: Vec::with_capacity(n),
            depth: Vec::with_capacity(n),
            model: Vec::with_capacity(n),
            endings: Endings::default(),
            secondary: Secondary::default(),
            visited: 0,
        };
        let mut rays = Vec::with_capacity(n);
        for y in y0..y1 {
            for x in x0..x1 {
                rays.push(self.frame.ray(x, y));
            }
        }
        // Under a section each ray is traced from where it enters the kept half-space; a ray
        // that keeps nothing is traced as it is and its hit dropped.
        let clips: Option<Vec<Clip>> = self
            .section
            .map(|s| rays.iter().map(|r| s.clip(r)).collect());
        if let Some(clips) = &clips {
            for (r, c) in rays.iter_mut().zip(clips) {
                if let Some(t) = c.ray(r) {
                    *r = t;
                }
            }
        }
        let width = (x1 - x0) as usize;
        let limits: Option<Vec<f32>> = self
            .layered()
            .then(|| clips.iter().flatten().map(|c| c.limit()).collect());
        let prim = primaries(&self.tracer, &rays, limits.as_deref(), width, memo);
        let pixels = (y0..y1).flat_map(|y| (x0..x1).map(move |x| (y, x)));
        for (k, (y, x)) in pixels.enumerate() {
            // The primary ray's wants, in the order it would have made them traced alone:
            // before its shading's.
            memo.release_deferred(k as u32);
            let Some(&ray) = rays.get(k) else {
                continue;
            };
            let clip = clips.as_ref().and_then(|c| c.get(k)).copied();
            let clip = clip.unwrap_or(Clip::Whole);
            let (front, end) = prim.of(k);
            let end = end.filter(|h| h.t <= clip.limit());
            let first = front.first().or(end);
            out.endings.record(first);
            out.depth
                .push(first.map_or(f32::INFINITY, |h| h.t + clip.start()));
            let (colour, sampled) = self.colour(x, y, &ray, (front, end), memo, &mut out.secondary);
            out.model.push(first.is_some() || sampled);
            out.rgb.push(colour);
        }
        memo.flush(self.cache);
        out.visited = memo.take_visited();
        out
    }

    /// Whether rays go on behind translucent LOD entries: asked for, and rays stop on LOD
    /// entries at all (at PoE 0 a ray ends on one only where a block is missing, as opaque).
    fn layered(&self) -> bool {
        self.opts.translucent && self.tracer.lod_c > 0.0
    }

    /// Tile `tile` of `n` pixels, none of whose rays can meet the scene's box: what tracing
    /// them would give, without a ray.
    fn missed_tile(&self, tile: u32, n: usize) -> TileOut {
        TileOut {
            tile,
            rgb: vec![self.missed; n],
            depth: vec![f32::INFINITY; n],
            model: vec![false; n],
            endings: Endings {
                miss: n as u64,
                ..Endings::default()
            },
            secondary: Secondary::default(),
            visited: 0,
        }
    }

    /// The shading: the sRGB colour of pixel (x, y), whose centre ray (as traced) `centre`
    /// met the translucent layers `front` and then `end`, and whether one of the pixel's
    /// sample rays hit the model. With one ray per pixel that is the centre ray's colour (and
    /// no sample ray); with more, the stratified mean ([`FrameJob::stratified`]).
    #[inline]
    fn colour(
        &self,
        x: u32,
        y: u32,
        centre: &Ray,
        met: (&[Hit], Option<&Hit>),
        memo: &mut Memo,
        secondary: &mut Secondary,
    ) -> ([u8; 3], bool) {
        if self.opts.spp > 1 {
            return self.stratified(x, y, memo, secondary);
        }
        let seed = hash(x, y, 0, Stream::Occlusion);
        let colour = self.shaded(centre, met, seed, memo, secondary);
        (
            colour.map_or(self.background, |c| c.map(encode_srgb)),
            false,
        )
    }

    /// The linear RGB colour of `ray`, which met the translucent layers `front` (nearest
    /// first) and then `end`: the shade of each, composited front to back over the background
    /// ([`blend`]). None when it met nothing.
    #[inline]
    fn shaded(
        &self,
        ray: &Ray,
        (front, end): (&[Hit], Option<&Hit>),
        seed: u64,
        memo: &mut Memo,
        secondary: &mut Secondary,
    ) -> Option<[f32; 3]> {
        let lighting = &self.lighting;
        Some(match (front, end) {
            ([], None) => return None,
            ([], Some(hit)) => lighting.colour(hit, ray, seed, memo, secondary),
            _ => {
                let mut shade = |h: &Hit, m: &mut Memo| lighting.colour(h, ray, seed, m, secondary);
                blend(front, end, self.opts.background, memo, &mut shade)
            }
        })
    }

    /// The sRGB encoding of the mean, in linear RGB, of `spp` rays through stratified points
    /// of pixel (x, y), and whether one of them hit the model.
    #[inline]
    fn stratified(
        &self,
        x: u32,
        y: u32,
        memo: &mut Memo,
        secondary: &mut Secondary,
    ) -> ([u8; 3], bool) {
        let spp = self.opts.spp;
        let mut sum = [0f32; 3];
        let mut any = false;
        for k in 0..spp {
            let [ox, oy] = pixel_offset(x, y, k, spp);
            let ray = self.frame.ray_at(f64::from(x) + ox, f64::from(y) + oy);
            let clip = self.section.map_or(Clip::Whole, |s| s.clip(&ray));
            let seed = hash(x, y, k, Stream::Occlusion);
            let c = clip.ray(&ray).and_then(|r| {
                let limit = clip.limit();
                if self.layered() {
                    let l = self.tracer.trace_layers(&r, limit, memo);
                    self.shaded(&r, (&l.translucent, l.end.as_ref()), seed, memo, secondary)
                } else {
                    let hit = self.tracer.trace(&r, memo).filter(|h| h.t <= limit);
                    self.shaded(&r, (&[], hit.as_ref()), seed, memo, secondary)
                }
            });
            any |= c.is_some();
            add_to(&mut sum, c.unwrap_or(self.opts.background));
        }
        (mean_srgb(sum, spp), any)
    }

    /// Places the finished tiles' pixels in one image and adds up their figures.
    fn assemble(&self, done: Vec<TileOut>) -> (Image, FrameTotals) {
        let (w, h) = (self.frame.width(), self.frame.height());
        let mut image = Image {
            width: w,
            height: h,
            rgb: vec![0; 3 * (w as usize) * (h as usize)],
            depth: vec![f32::INFINITY; (w as usize) * (h as usize)],
            model: vec![false; (w as usize) * (h as usize)],
        };
        let mut totals = FrameTotals::default();
        for t in done {
            totals.primary.add(&t.endings);
            totals.secondary.add(&t.secondary);
            totals.nodes_visited += t.visited;
            let (x0, y0, x1, _) = self.tile_rect(t.tile);
            let tw = (x1 - x0) as usize;
            for (k, ((c, d), m)) in t.rgb.iter().zip(&t.depth).zip(&t.model).enumerate() {
                let (x, y) = (x0 as usize + k % tw, y0 as usize + k / tw);
                let at = y * w as usize + x;
                if let Some(p) = image.depth.get_mut(at) {
                    *p = *d;
                }
                if let Some(p) = image.model.get_mut(at) {
                    *p = *m;
                }
                if let Some(p) = image.rgb.get_mut(3 * at..3 * at + 3) {
                    p.copy_from_slice(c);
                }
            }
        }
        (image, totals)
    }

    /// The frame's figures from its tiles' `totals` and its wall time in `seconds`.
    fn stats(&self, totals: &FrameTotals, seconds: f64) -> FrameStats {
        let (w, h) = (self.frame.width(), self.frame.height());
        let spp = self.opts.spp;
        let pixels = u64::from(w) * u64::from(h);
        let primary_rays = if spp > 1 {
            pixels * (1 + u64::from(spp))
        } else {
            pixels
        };
        let secondary = totals.secondary;
        let rays = primary_rays + secondary.shadow + secondary.ao;
        FrameStats {
            width: w,
            height: h,
            poe: self.opts.poe,
            lod_c: self.lod_c,
            threads: rayon::current_num_threads(),
            ms: seconds * 1e3,
            rays,
            rays_per_second: rays as f64 / seconds.max(1e-9),
            spp,
            primary_rays,
            shadow_rays: secondary.shadow,
            ao_rays: secondary.ao,
            primary: totals.primary,
            nodes_visited: totals.nodes_visited,
            nodes_per_ray: totals.nodes_visited as f64 / rays.max(1) as f64,
            waits: totals.waits,
            cache: self.cache.stats(),
        }
    }
}
