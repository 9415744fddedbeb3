//! Packets of rays traced together ([`Tracer::trace_packet`]) against the single-ray path
//! ([`Tracer::trace`]): the same hit, bit for bit (distance, surface, weights, sample, radius),
//! for every ray, the same count of nodes visited and the same block requests (ids, weights
//! and sizes bit for bit), on many random packets and camera views: coherent and incoherent
//! rays, rays with ±0 direction components, rays starting inside the scene and on split planes,
//! grazing rays; at PoE 0 and above, with voxels and with R-LOD planes, with the blocking cache
//! and with an asynchronous cache that starts cold (missing blocks, proxies, last voxels).
//! Also: a render (which traces its primary rays in packets) gives, pixel for pixel, the depth
//! of the single-ray path.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use oocfmt::records::LodKinds;
use oocfmt::WriteOptions;
use oocfmt_build::layout::LayoutOptions;
use oocfmt_scenes::rng::Rng;
use oocfmt_trace::blocks::{LodKind, NodeView, TreeletData, TriangleData};
use oocfmt_trace::cache::{CacheStats, Wish};
use oocfmt_trace::intersect::Ray;
use oocfmt_trace::traverse::{Hit, Layers, Memo, Surface, Tracer};
use oocfmt_trace::{render, AsyncCache, BlockCache, BlockingCache, Camera, RenderOptions, Scene};

/// A cache that hands out another's blocks and records the requests it is given (each flush
/// sorted by block id: the memo's map drains in no particular order).
struct Recording {
    inner: Arc<dyn BlockCache>,
    requests: Mutex<Vec<Vec<(u32, u32, u32)>>>,
}

impl Recording {
    fn new(inner: Arc<dyn BlockCache>) -> Recording {
        Recording {
            inner,
            requests: Mutex::default(),
        }
    }
}

impl BlockCache for Recording {
    fn treelets(&self, id: u32) -> Option<Arc<TreeletData>> {
        self.inner.treelets(id)
    }
    fn triangles(&self, id: u32) -> Option<Arc<TriangleData>> {
        self.inner.triangles(id)
    }
    fn request(&self, wanted: &[(u32, Wish)]) {
        let mut w: Vec<_> = wanted
            .iter()
            .map(|(id, w)| (*id, w.weight.to_bits(), w.size.to_bits()))
            .collect();
        w.sort_unstable();
        self.requests.lock().unwrap().push(w);
        self.inner.request(wanted);
    }
    fn stats(&self) -> CacheStats {
        self.inner.stats()
    }
}

/// A hit as bits: distance, kind, what it met, radius, shade and coverage.
fn bits(h: Option<&Hit>) -> Option<(u32, u8, Vec<u32>, [u32; 3])> {
    let h = h?;
    let f = |v: &[f32]| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
    let (kind, what) = match &h.surface {
        Surface::Triangle {
            data,
            triangle,
            bary,
        } => {
            let mut w = vec![*triangle];
            w.extend(f(bary));
            w.extend(f(data.positions[*triangle as usize].as_flattened()));
            (0, w)
        }
        Surface::Voxel { normal, colour } => (
            1,
            normal.iter().chain(colour).map(|x| x.to_bits()).collect(),
        ),
        Surface::Proxy(s) => (2, vec![s.0]),
        Surface::Plane {
            normal,
            colour,
            deviation,
        } => (3, [f(normal), f(colour), f(&[*deviation])].concat()),
    };
    let (radius, shade, coverage) = (h.radius, h.shade, h.coverage);
    Some((
        h.t.to_bits(),
        kind,
        what,
        [radius, shade, coverage].map(f32::to_bits),
    ))
}

/// A ray's layers as bits ([`bits`]): the translucent surfaces, front to back, then the end.
type LayerBits = Vec<Option<(u32, u8, Vec<u32>, [u32; 3])>>;

fn layer_bits(l: &Layers) -> LayerBits {
    let front = l.translucent.iter().map(|h| bits(Some(h)));
    front.chain([bits(l.end.as_ref())]).collect()
}

/// A cache and what to do between two frames.
type Cache = (Arc<dyn BlockCache>, Box<dyn Fn()>);

/// How the rays ended: triangle, voxel, proxy, plane, miss; and how many met translucent
/// layers in front.
type Endings = [usize; 6];

/// Traces `packets` both ways through `cache` (packets of 16 make a tile: the memos are
/// cleared and flushed between tiles) and asserts the same hits, nodes visited and requests;
/// then the same of their layers ([`Tracer::trace_packet_layers`] against
/// [`Tracer::trace_layers`]), every other ray ending at 1.5 times its hit's distance.
fn same<const N: usize>(
    scene: &Scene,
    cache: Arc<dyn BlockCache>,
    lod_c: f32,
    packets: &[[Ray; N]],
    what: &str,
) -> Endings {
    let (a, b) = (Recording::new(Arc::clone(&cache)), Recording::new(cache));
    let (ta, tb) = (Tracer::new(scene, &a, lod_c), Tracer::new(scene, &b, lod_c));
    let (mut ma, mut mb) = (Memo::new(scene), Memo::new(scene));
    let mut endings = [0; 6];
    let mut layered = 0;
    let keys: [u32; N] = std::array::from_fn(|i| i as u32);
    for tile in packets.chunks(16) {
        ma.clear();
        mb.clear();
        let mut ends = Vec::new();
        for p in tile {
            let hp = ta.trace_packet(p, &keys, &ma);
            ma.release_deferred(u32::MAX);
            for (i, (ray, hp)) in p.iter().zip(&hp).enumerate() {
                let hs = tb.trace(ray, &mb);
                assert_eq!(
                    bits(hp.as_ref()),
                    bits(hs.as_ref()),
                    "{what}: ray {i} of {p:?}, lod_c {lod_c}"
                );
                endings[bits(hs.as_ref()).map_or(4, |b| usize::from(b.1))] += 1;
                ends.push(hs.map_or(f32::INFINITY, |h| h.t));
            }
        }
        let mut lp: [Layers; N] = std::array::from_fn(|_| Layers::default());
        for (p, ends) in tile.iter().zip(ends.chunks(N)) {
            let t_max = std::array::from_fn(|i| match i % 2 {
                0 => f32::INFINITY,
                _ => 1.5 * ends[i],
            });
            ta.trace_packet_layers(p, &keys, t_max, &ma, &mut lp);
            ma.release_deferred(u32::MAX);
            for (i, (ray, lp)) in p.iter().zip(&lp).enumerate() {
                let ls = tb.trace_layers(ray, t_max[i], &mb);
                assert_eq!(
                    layer_bits(lp),
                    layer_bits(&ls),
                    "{what}: layers of ray {i} of {p:?} to {}, lod_c {lod_c}",
                    t_max[i]
                );
                layered += usize::from(!ls.translucent.is_empty());
            }
        }
        assert_eq!(
            ma.take_visited(),
            mb.take_visited(),
            "{what}: nodes visited"
        );
        ma.flush(&a);
        mb.flush(&b);
    }
    let (ra, rb) = (a.requests.into_inner(), b.requests.into_inner());
    assert_eq!(ra.unwrap(), rb.unwrap(), "{what}: block requests");
    endings[5] += layered;
    endings
}

fn mandelbulb_with(dir: &Path, triangles: u64, lod: LodKinds) -> PathBuf {
    let layout = LayoutOptions {
        write: WriteOptions {
            lod,
            ..WriteOptions::default()
        },
        // A proxy for every LOD node: a cold cache ends rays on them.
        triangles_per_proxy: 0,
        ..LayoutOptions::default()
    };
    common::mandelbulb_with(dir, triangles, layout)
}

/// Cameras: the default framing, straight down the z axis (the middle row and column have ±0
/// components: those packets go ray by ray), from the centre of the box (rays start inside),
/// and grazing along the bottom face of the box.
fn cameras(scene: &Scene, w: u32, h: u32) -> Vec<Camera> {
    let m = scene.metadata();
    let (lo, hi) = (m.scene.bounds_min, m.scene.bounds_max);
    let c = [0, 1, 2].map(|k| (f64::from(lo[k]) + f64::from(hi[k])) / 2.0);
    let ext = (0..3).map(|k| f64::from(hi[k] - lo[k])).fold(0.0, f64::max);
    let cam = |eye: [f64; 3], look_at: [f64; 3], fov_y: f64| Camera {
        eye,
        look_at,
        up: [0.0, 1.0, 0.0],
        fov_y,
        width: w,
        height: h,
    };
    let low = f64::from(lo[1]) + 0.2 * (f64::from(hi[1]) - f64::from(lo[1]));
    vec![
        Camera::framing(lo, hi, w, h),
        cam([c[0], c[1], c[2] + 0.9 * ext], c, 50.0),
        cam(c, [c[0] + 1.0, c[1] + 0.3, c[2] - 0.2], 90.0),
        cam([c[0] - ext, low, c[2]], [c[0], low, c[2] + 0.01], 20.0),
    ]
}

/// The camera's rays in packets of `PW` × `PH` pixels.
fn camera_packets<const PW: usize, const PH: usize, const N: usize>(cam: &Camera) -> Vec<[Ray; N]> {
    let f = cam.frame().unwrap();
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut out = Vec::new();
    for py in (0..h - PH + 1).step_by(PH) {
        for px in (0..w - PW + 1).step_by(PW) {
            out.push(std::array::from_fn(|j| {
                f.ray((px + j % PW) as u32, (py + j / PW) as u32)
            }));
        }
    }
    out
}

/// Random packets: an origin (outside the box, inside it, or on a split plane of the root
/// treelet) and a direction, each ray jittered from them by a random amount (none to large),
/// some with components set to ±0 in one ray or all.
fn random_packets<const N: usize>(scene: &Scene, rng: &mut Rng, count: usize) -> Vec<[Ray; N]> {
    let m = scene.metadata();
    let (lo, hi) = (m.scene.bounds_min, m.scene.bounds_max);
    let splits: Vec<(u8, f32)> = m
        .root
        .and_then(|r| scene.load_treelets(r.block).ok())
        .map(|t| {
            t.nodes()
                .filter_map(|n| match n {
                    NodeView::Inner { axis, split, .. } | NodeView::Lod { axis, split, .. } => {
                        Some((axis, split))
                    }
                    NodeView::Leaf { .. } => None,
                })
                .collect()
        })
        .unwrap_or_default();
    let point = |rng: &mut Rng, pad: f64| {
        [0, 1, 2].map(|k| {
            let (l, h) = (f64::from(lo[k]), f64::from(hi[k]));
            rng.range(l - pad * (h - l), h + pad * (h - l)) as f32
        })
    };
    (0..count)
        .map(|_| {
            let pad = if rng.chance(0.5) { 0.0 } else { 1.5 };
            let mut org = point(rng, pad);
            if !splits.is_empty() && rng.chance(0.3) {
                let (axis, split) = splits[rng.int(0, splits.len() as u32 - 1) as usize];
                org[usize::from(axis.min(2))] = split;
            }
            let dir = if rng.chance(0.5) {
                // Towards a point of the box: most rays meet something.
                let to = point(rng, 0.0);
                [0, 1, 2].map(|k| to[k] - org[k])
            } else {
                rng.direction().map(|c| c as f32)
            };
            let jitter = [0.0, 1e-7, 1e-4, 1e-2, 0.3][rng.int(0, 4) as usize];
            let spread = [0.0, 1e-5, 1e-2][rng.int(0, 2) as usize];
            let zero = rng
                .chance(0.15)
                .then(|| (rng.int(0, 2) as usize, rng.sign() as f32 * 0.0));
            let zero_all = rng.chance(0.5);
            std::array::from_fn(|i| {
                let mut d =
                    dir.map(|c| c + jitter * rng.range(-1.0, 1.0) as f32 * c.abs().max(1e-3));
                let o = org.map(|c| c + spread * rng.range(-1.0, 1.0) as f32);
                if let Some((k, z)) = zero.filter(|_| zero_all || i == 0) {
                    d[k] = z;
                }
                if d.iter().all(|&c| c == 0.0) {
                    d[0] = 1.0;
                }
                Ray::new(o, d)
            })
        })
        .collect()
}

fn add(a: &mut Endings, b: Endings) {
    for (a, b) in a.iter_mut().zip(b) {
        *a += b;
    }
}

/// Every packet source against `scene` through the cache `make` gives, at PoE 0, 2 and 40.
fn all_sources(scene: &Arc<Scene>, make: &dyn Fn() -> Cache, frames: usize) -> [Endings; 3] {
    let mut out = [[0; 6]; 3];
    for (p, poe) in [0.0f64, 2.0, 40.0].into_iter().enumerate() {
        let (cache, between_frames) = make();
        let mut rng = Rng(17 + p as u64);
        for frame in 0..frames {
            for (c, cam) in cameras(scene, 64, 48).iter().enumerate() {
                let lod_c = (poe * cam.frame().unwrap().pixel_angle()) as f32;
                let what = format!("camera {c}, poe {poe}, frame {frame}");
                add(
                    &mut out[p],
                    same(
                        scene,
                        Arc::clone(&cache),
                        lod_c,
                        &camera_packets::<2, 2, 4>(cam),
                        &what,
                    ),
                );
                add(
                    &mut out[p],
                    same(
                        scene,
                        Arc::clone(&cache),
                        lod_c,
                        &camera_packets::<4, 2, 8>(cam),
                        &what,
                    ),
                );
            }
            let lod_c = (poe * cameras(scene, 64, 48)[0].frame().unwrap().pixel_angle()) as f32;
            let what = format!("random, poe {poe}, frame {frame}");
            add(
                &mut out[p],
                same(
                    scene,
                    Arc::clone(&cache),
                    lod_c,
                    &random_packets::<4>(scene, &mut rng, 3000),
                    &what,
                ),
            );
            add(
                &mut out[p],
                same(
                    scene,
                    Arc::clone(&cache),
                    lod_c,
                    &random_packets::<8>(scene, &mut rng, 1500),
                    &what,
                ),
            );
            between_frames();
        }
    }
    eprintln!("endings (triangle, voxel, proxy, plane, miss; layered) at PoE 0, 2, 40: {out:?}");
    out
}

/// A warm-on-demand blocking cache and nothing to do between frames.
fn blocking(scene: &Arc<Scene>) -> Cache {
    let cache = BlockingCache::new(Arc::clone(scene), usize::MAX);
    (Arc::new(cache), Box::new(|| {}))
}

#[test]
fn packets_give_the_single_ray_hits_with_the_blocking_cache() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Arc::new(Scene::open(&common::mandelbulb(dir.path(), 20_000)).unwrap());
    let make = || blocking(&scene);
    let [poe0, poe2, poe40] = all_sources(&scene, &make, 1);
    assert!(poe0[0] > 10_000 && poe0[4] > 1_000, "{poe0:?}");
    assert_eq!(
        poe0[1] + poe0[2] + poe0[3],
        0,
        "PoE 0 is full detail: {poe0:?}"
    );
    assert!(poe2[1] > 0 && poe40[1] > poe2[1], "{poe2:?} {poe40:?}");
    // Pre-filtered voxels: some rays composite layers.
    assert!(poe2[5] > 0 && poe40[5] > 0, "{poe2:?} {poe40:?}");
}

#[test]
fn packets_give_the_single_ray_hits_on_jittered_overlapping_surfaces() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Arc::new(Scene::open(&common::cad_scene(dir.path(), 20_000)).unwrap());
    let make = || blocking(&scene);
    let [poe0, _, poe40] = all_sources(&scene, &make, 1);
    assert!(poe0[0] > 10_000, "{poe0:?}");
    assert!(poe40[1] > 0, "{poe40:?}");
}

#[test]
fn packets_give_the_single_ray_hits_with_r_lod_planes() {
    let dir = tempfile::tempdir().unwrap();
    let path = mandelbulb_with(dir.path(), 8_000, LodKinds::BOTH.filtered());
    let scene = Scene::open(&path).unwrap().with_lod(LodKind::Rlod).unwrap();
    let scene = Arc::new(scene);
    let make = || blocking(&scene);
    let [poe0, poe2, poe40] = all_sources(&scene, &make, 1);
    assert_eq!(poe0[3], 0, "{poe0:?}");
    assert!(poe2[3] + poe40[3] > 0, "{poe2:?} {poe40:?}");
    assert!(poe2[5] + poe40[5] > 0, "{poe2:?} {poe40:?}");
}

#[test]
fn packets_give_the_single_ray_hits_with_a_cold_async_cache() {
    let dir = tempfile::tempdir().unwrap();
    let path = mandelbulb_with(dir.path(), 20_000, LodKinds::VOXEL);
    let scene = Arc::new(Scene::open(&path).unwrap());
    // Each frame finds what the fetchers loaded since the last: missing blocks, proxies and
    // last voxels first, more detail later.
    let make = || -> Cache {
        let cache = Arc::new(AsyncCache::new(Arc::clone(&scene), 64 << 20, 1));
        let c = Arc::clone(&cache);
        let between = move || {
            c.end_frame();
            c.wait_for_fetchers();
        };
        (cache, Box::new(between))
    };
    let [poe0, poe2, _] = all_sources(&scene, &make, 6);
    assert!(poe0[0] > 0 && poe0[1] > 0 && poe0[2] > 0, "{poe0:?}");
    assert!(poe2[1] > 0, "{poe2:?}");
}

#[test]
fn a_render_gives_the_depth_of_the_single_ray_path() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Arc::new(Scene::open(&common::mandelbulb(dir.path(), 20_000)).unwrap());
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    // Odd sizes: ragged tiles and packets at the edges.
    for cam in cameras(&scene, 83, 45) {
        for (poe, translucent) in [(0.0f32, false), (2.0, false), (2.0, true)] {
            let opts = RenderOptions {
                poe,
                translucent,
                ..RenderOptions::DEFAULT
            };
            let (img, stats) = render(&scene, &cache, &cam, &opts).unwrap();
            let frame = cam.frame().unwrap();
            let tracer = Tracer::new(
                &scene,
                &cache,
                (f64::from(poe) * frame.pixel_angle()) as f32,
            );
            let (mut memo, nearest) = (Memo::new(&scene), Memo::new(&scene));
            let mut k = 0;
            for y in 0..cam.height {
                for x in 0..cam.width {
                    let ray = frame.ray(x, y);
                    let hit = tracer.trace(&ray, &nearest);
                    let t = hit.map_or(f32::INFINITY, |h| h.t);
                    if translucent {
                        // The renderer walks such a ray once, collecting every layer; the
                        // nearest of them is the nearest surface.
                        let l = tracer.trace_layers(&ray, f32::INFINITY, &memo);
                        let first = l.translucent.first().or(l.end.as_ref());
                        let first = first.map_or(f32::INFINITY, |h| h.t);
                        assert_eq!(first.to_bits(), t.to_bits(), "pixel ({x}, {y})");
                    } else {
                        tracer.trace(&ray, &memo);
                    }
                    assert_eq!(
                        img.depth[k].to_bits(),
                        t.to_bits(),
                        "pixel ({x}, {y}), poe {poe}"
                    );
                    k += 1;
                }
            }
            assert_eq!(stats.nodes_visited, memo.take_visited(), "poe {poe}");
            memo.flush(&cache);
        }
    }
}
