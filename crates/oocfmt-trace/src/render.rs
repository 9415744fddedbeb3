//! One frame: rays in parallel over 16 × 16 tiles, an RGB8 image, a depth image and figures.

use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::cache::{BlockCache, CacheStats};
use crate::camera::Camera;
use crate::error::TraceError;
use crate::scene::Scene;
use crate::shade::{encode_srgb, shade};
use crate::traverse::{Memo, Surface, Tracer};

const TILE: u32 = 16;

/// A finished tile: its index, colours, depths and ray endings.
type TileOut = (u32, Vec<[u8; 3]>, Vec<f32>, Endings, u64);

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Pixels of error: a LOD voxel ends a ray when its radius is at most this many pixels.
    /// 0 renders full detail.
    pub poe: f32,
    /// Linear RGB of a ray that hits nothing.
    pub background: [f32; 3],
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            poe: 0.0,
            background: [0.05, 0.06, 0.08],
        }
    }
}

pub struct Image {
    pub width: u32,
    pub height: u32,
    /// Row-major, row 0 at the top, 3 bytes per pixel.
    pub rgb: Vec<u8>,
    /// Hit distance along the unit ray direction, +inf for a miss; same order as `rgb`.
    pub depth: Vec<f32>,
}

/// How primary rays ended.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq, Eq)]
pub struct Endings {
    pub triangle: u64,
    pub voxel: u64,
    pub proxy: u64,
    pub miss: u64,
}

impl Endings {
    fn add(&mut self, o: &Endings) {
        self.triangle += o.triangle;
        self.voxel += o.voxel;
        self.proxy += o.proxy;
        self.miss += o.miss;
    }
}

#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct FrameStats {
    pub width: u32,
    pub height: u32,
    pub poe: f32,
    /// The LOD constant C = poe · 2 tan(fov_y / 2) / height.
    pub lod_c: f64,
    pub threads: usize,
    pub ms: f64,
    pub rays: u64,
    pub rays_per_second: f64,
    pub primary: Endings,
    /// Kd-tree nodes (inner, LOD, leaf) the frame's rays visited.
    pub nodes_visited: u64,
    pub nodes_per_ray: f64,
    pub cache: CacheStats,
}

/// Renders one frame of `scene` through `cache`. `camera` is in stored coordinates.
pub fn render(
    scene: &Scene,
    cache: &dyn BlockCache,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<(Image, FrameStats), TraceError> {
    if !(opts.poe.is_finite() && opts.poe >= 0.0) {
        return Err(TraceError::Options(format!(
            "--poe {}: expected a finite number >= 0",
            opts.poe
        )));
    }
    let frame = camera.frame()?;
    let lod_c = f64::from(opts.poe) * frame.pixel_angle();
    let tracer = Tracer::new(scene, cache, lod_c as f32);
    let materials = &scene.metadata().materials;
    let (w, h) = (frame.width(), frame.height());
    let tiles_x = w.div_ceil(TILE);
    let tiles = tiles_x * h.div_ceil(TILE);
    let background = opts.background.map(encode_srgb);
    let start = Instant::now();
    let done: Vec<TileOut> = (0..tiles)
        .into_par_iter()
        .map_init(
            || Memo::new(scene),
            |memo, tile| {
                memo.clear();
                let (x0, y0) = ((tile % tiles_x) * TILE, (tile / tiles_x) * TILE);
                let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
                let n = ((x1 - x0) * (y1 - y0)) as usize;
                let mut rgb = Vec::with_capacity(n);
                let mut depth = Vec::with_capacity(n);
                let mut endings = Endings::default();
                for y in y0..y1 {
                    for x in x0..x1 {
                        let ray = frame.ray(x, y);
                        match tracer.trace(&ray, memo) {
                            Some(hit) => {
                                match hit.surface {
                                    Surface::Triangle { .. } => endings.triangle += 1,
                                    Surface::Voxel(_) => endings.voxel += 1,
                                    Surface::Proxy(_) => endings.proxy += 1,
                                }
                                rgb.push(shade(&hit, &ray, materials).map(encode_srgb));
                                depth.push(hit.t);
                            }
                            None => {
                                endings.miss += 1;
                                rgb.push(background);
                                depth.push(f32::INFINITY);
                            }
                        }
                    }
                }
                memo.flush(cache);
                (tile, rgb, depth, endings, memo.take_visited())
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
    let mut nodes_visited = 0;
    for (tile, rgb, depth, endings, visited) in done {
        primary.add(&endings);
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
    let rays = u64::from(w) * u64::from(h);
    let stats = FrameStats {
        width: w,
        height: h,
        poe: opts.poe,
        lod_c,
        threads: rayon::current_num_threads(),
        ms: seconds * 1e3,
        rays,
        rays_per_second: rays as f64 / seconds.max(1e-9),
        primary,
        nodes_visited,
        nodes_per_ray: nodes_visited as f64 / rays.max(1) as f64,
        cache: cache.stats(),
    };
    Ok((image, stats))
}
