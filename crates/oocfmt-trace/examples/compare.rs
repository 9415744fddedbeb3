//! Renders a container at --poe 0 and 2 (warm cache) and compares the depth images with a
//! brute-force reference (every triangle record tested with the same kernel) on every
//! STRIDE-th pixel in each direction. Prints the figures as JSON.
//!
//! cargo run --release -p oocfmt-trace --example compare -- MODEL.oocf 1024x768 STRIDE [EYE_X,Y,Z]

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use oocfmt::BlockKind;
use oocfmt_trace::{render, BlockingCache, Camera, RenderOptions, Scene, TraceError};
use rayon::prelude::*;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: compare MODEL.oocf WxH STRIDE [EYE_X,Y,Z]";
    let model = PathBuf::from(args.get(1).ok_or(usage)?);
    let (w, h) = args.get(2).and_then(|s| s.split_once('x')).ok_or(usage)?;
    let (w, h): (u32, u32) = (w.parse()?, h.parse()?);
    let stride: u32 = args.get(3).ok_or(usage)?.parse()?;
    let scene = Arc::new(Scene::open(&model)?);
    let m = scene.metadata();
    let mut cam = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, w, h);
    if let Some(e) = args.get(4) {
        let v: Vec<f64> = e.split(',').map(str::parse).collect::<Result<_, _>>()?;
        if let [x, y, z] = v[..] {
            cam.eye = [x, y, z];
        }
    }
    let mut triangles = Vec::new();
    for (id, e) in (0u32..).zip(scene.reader().entries()) {
        if e.kind == BlockKind::Triangle {
            triangles.extend(scene.load_triangles(id)?.positions);
        }
    }
    let frame = cam.frame()?;
    let samples: Vec<(u32, u32)> = (0..h)
        .step_by(stride as usize)
        .flat_map(|y| (0..w).step_by(stride as usize).map(move |x| (x, y)))
        .collect();
    let start = Instant::now();
    let reference: Vec<f32> = samples
        .par_iter()
        .map(|&(x, y)| {
            let r = frame.ray(x, y);
            triangles
                .iter()
                .filter_map(|[a, b, c]| r.triangle(a, b, c))
                .fold(f32::INFINITY, |m, h| m.min(h.t))
        })
        .collect();
    let brute_s = start.elapsed().as_secs_f64();
    let mut runs = Vec::new();
    for poe in [0.0f32, 2.0] {
        let cache = BlockingCache::new(Arc::clone(&scene), 4 << 30);
        let opts = RenderOptions {
            poe,
            ..RenderOptions::default()
        };
        let (_, cold) = render(&scene, &cache, &cam, &opts)?;
        let (img, warm) = render(&scene, &cache, &cam, &opts)?;
        let (mut differ, mut holes, mut err_sum, mut both) = (0u64, 0u64, 0f64, 0u64);
        for (&(x, y), &want) in samples.iter().zip(&reference) {
            let got = img
                .depth
                .get((y * w + x) as usize)
                .copied()
                .ok_or_else(|| TraceError::Options("pixel outside the image".into()))?;
            let same = if want.is_finite() {
                got.is_finite() && ((got - want) / want).abs() <= 1e-5
            } else {
                got.is_infinite()
            };
            differ += u64::from(!same);
            holes += u64::from(want.is_finite() && !got.is_finite());
            if want.is_finite() && got.is_finite() {
                err_sum += f64::from(((got - want) / want).abs());
                both += 1;
            }
        }
        runs.push(serde_json::json!({
            "poe": poe,
            "cold_ms": cold.ms,
            "warm_ms": warm.ms,
            "warm_rays_per_second": warm.rays_per_second,
            "primary": warm.primary,
            "blocks_loaded": warm.cache.blocks_loaded,
            "bytes_resident": warm.cache.bytes_resident,
            "pixels_compared": samples.len(),
            "pixels_differing": differ,
            "holes": holes,
            "mean_relative_depth_error": err_sum / both.max(1) as f64,
        }));
    }
    let out = serde_json::json!({
        "model": model.display().to_string(),
        "size": [w, h],
        "threads": rayon::current_num_threads(),
        "triangle_records": triangles.len(),
        "brute_force_seconds": brute_s,
        "runs": runs,
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
