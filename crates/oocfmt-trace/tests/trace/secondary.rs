//! Secondary rays: no shadow acne on a lit plane, no light leaking into or around a closed mesh,
//! ambient-occlusion rays that never meet the surface or voxel they leave, pbrt's
//! re-intersection test over triangles from 1e-8 to 1e8, and the `--spp` sampling.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use oocfmt::records::LodKinds;
use oocfmt::WriteOptions;
use oocfmt_build::layout::LayoutOptions;
use oocfmt_scenes::rng::Rng;
use oocfmt_trace::intersect::Ray;
use oocfmt_trace::light::Shadows;
use oocfmt_trace::occlusion::{ao_lod_c, Occlusion};
use oocfmt_trace::sampling::{cosine_hemisphere, hash, pixel_offset, point, Stream};
use oocfmt_trace::shade::{encode_srgb, shade, Lighting, Secondary, AMBIENT, DEFAULT_ALBEDO};
use oocfmt_trace::spawn::{from_triangle, Origin};
use oocfmt_trace::traverse::{Hit, Memo, Surface, Tracer};
use oocfmt_trace::{render, BlockingCache, Camera, Image, RenderOptions, Scene};

/// ±10^u, u uniform in [−e, e]: magnitudes spread evenly over 2e decades.
fn exp(rng: &mut Rng, e: f64) -> f64 {
    rng.sign() * 10f64.powf(rng.range(-e, e))
}

fn write_obj(path: &Path, v: &[[f64; 3]], n: &[[f64; 3]], faces: &[[usize; 3]]) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    for p in v {
        writeln!(f, "v {} {} {}", p[0], p[1], p[2]).unwrap();
    }
    for q in n {
        writeln!(f, "vn {} {} {}", q[0], q[1], q[2]).unwrap();
    }
    for t in faces {
        let [a, b, c] = t.map(|i| i + 1);
        if n.is_empty() {
            writeln!(f, "f {a} {b} {c}").unwrap();
        } else {
            writeln!(f, "f {a}//{a} {b}//{b} {c}//{c}").unwrap();
        }
    }
}

/// A tilted square, 10 units across, centred far from the origin, cut into 2·q² triangles:
/// its f32 vertices are not exactly coplanar, as in real data.
fn plane(dir: &Path, q: usize) -> PathBuf {
    let c = [1000.0, 200.0, -500.0];
    let e1 = [0.8, 0.1, 0.3];
    let e2 = [-0.15, 0.3, 0.9];
    let mut v = Vec::new();
    for j in 0..=q {
        for i in 0..=q {
            let (s, t) = (
                10.0 * i as f64 / q as f64 - 5.0,
                10.0 * j as f64 / q as f64 - 5.0,
            );
            v.push([0, 1, 2].map(|k| c[k] + s * e1[k] + t * e2[k]));
        }
    }
    let mut faces = Vec::new();
    for j in 0..q {
        for i in 0..q {
            let a = j * (q + 1) + i;
            faces.push([a, a + 1, a + q + 2]);
            faces.push([a, a + q + 2, a + q + 1]);
        }
    }
    let obj = dir.join("plane.obj");
    write_obj(&obj, &v, &[], &faces);
    let out = dir.join("plane.oocf");
    common::convert_obj(&obj, &out);
    out
}

/// The unit sphere around the origin, an icosahedron subdivided `levels` times, with vertex
/// normals; shared vertices are written once, so the mesh is closed.
fn sphere(dir: &Path, levels: u32) -> PathBuf {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let unit = |p: [f64; 3]| {
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        p.map(|c| c / l)
    };
    v = v.into_iter().map(unit).collect();
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::new();
        for f in &faces {
            let mut m = [0; 3];
            for e in 0..3 {
                let (a, b) = (f[e].min(f[(e + 1) % 3]), f[e].max(f[(e + 1) % 3]));
                m[e] = *mid.entry((a, b)).or_insert_with(|| {
                    v.push(unit([0, 1, 2].map(|k| (v[a][k] + v[b][k]) / 2.0)));
                    v.len() - 1
                });
            }
            next.push([f[0], m[0], m[2]]);
            next.push([f[1], m[1], m[0]]);
            next.push([f[2], m[2], m[1]]);
            next.push(m);
        }
        faces = next;
    }
    let obj = dir.join("sphere.obj");
    write_obj(&obj, &v, &v, &faces);
    let out = dir.join("sphere.oocf");
    common::convert_obj(&obj, &out);
    out
}

fn camera(eye: [f64; 3], look_at: [f64; 3], w: u32, h: u32) -> Camera {
    Camera {
        eye,
        look_at,
        up: [0.0, 1.0, 0.0],
        fov_y: 60.0,
        width: w,
        height: h,
    }
}

fn lit(poe: f32, light: [f64; 3]) -> RenderOptions {
    RenderOptions {
        poe,
        shadows: true,
        light: Some(light),
        ..RenderOptions::DEFAULT
    }
}

fn draw(path: &Path, cam: &Camera, opts: &RenderOptions) -> (Image, oocfmt_trace::FrameStats) {
    let scene = Arc::new(Scene::open(path).unwrap());
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    render(&scene, &cache, cam, opts).unwrap()
}

/// Pixels that hit something and whose colour is not the unlit one (the default albedo under
/// the ambient term alone): the pixels the light reaches.
fn lit_pixels(img: &Image) -> usize {
    let unlit = DEFAULT_ALBEDO.map(|c| encode_srgb(c * AMBIENT));
    img.rgb
        .chunks_exact(3)
        .zip(&img.depth)
        .filter(|(c, d)| d.is_finite() && **c != unlit)
        .count()
}

#[test]
fn a_lit_plane_shows_no_shadow_acne() {
    let dir = tempfile::tempdir().unwrap();
    let path = plane(dir.path(), 40);
    let c = [1000.0, 200.0, -500.0];
    // The plane's normal is about (0.0, -0.75, 0.3) × ... : light and eye on the same side,
    // the light low (about 20 degrees over the plane) to graze it.
    let n = {
        let (a, b) = ([0.8, 0.1, 0.3], [-0.15, 0.3, 0.9]);
        let n: [f64; 3] = [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ];
        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        n.map(|x| x / l)
    };
    let along = [0.8, 0.1, 0.3];
    let light = [0, 1, 2].map(|k| c[k] + 40.0 * n[k] + 100.0 * along[k]);
    let eye = [0, 1, 2].map(|k| c[k] + 9.0 * n[k] - 6.0 * along[k]);
    let cam = camera(eye, c, 96, 72);
    // The image: every pixel of the plane is lit.
    let (img, stats) = draw(&path, &cam, &lit(0.0, light));
    let hits = stats.primary.triangle;
    assert!(hits > 2000, "the plane fills much of the view: {hits} hits");
    assert_eq!(stats.shadow_rays, hits, "one shadow ray per hit");
    assert_eq!(lit_pixels(&img) as u64, hits, "shadow acne");
    // The direct light of every primary hit, with LOD too (voxels have their own colours, so
    // the image alone cannot tell lit from unlit there).
    for poe in [0.0, 2.0, 8.0] {
        let (hits, lit, rays, voxels) = lit_hits(&path, &cam, poe, light);
        assert!(poe == 0.0 || voxels > 0, "LOD is in use at --poe {poe}");
        assert_eq!(rays, hits as u64);
        assert_eq!(lit, hits, "--poe {poe}: shadow acne on {} hits", hits - lit);
    }
}

/// Over the primary hits of a view at `poe` with a point light at `light`: the hits, those the
/// light reaches, the shadow rays traced and the hits on voxels or proxies.
fn lit_hits(path: &Path, cam: &Camera, poe: f32, light: [f64; 3]) -> (usize, usize, u64, usize) {
    let scene = Arc::new(Scene::open(path).unwrap());
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    let m = scene.metadata();
    let c = poe * cam.frame().unwrap().pixel_angle() as f32;
    let shadows = Shadows::new(&scene, &cache, light.map(|x| x as f32), c);
    let bounds = (m.scene.bounds_min, m.scene.bounds_max);
    let lighting = Lighting::new(&m.materials, Some(shadows), None, bounds);
    let mut memo = Memo::new(&scene);
    let mut counts = Secondary::default();
    let (mut lit, mut voxels) = (0, 0);
    let hits = hits_of(&scene, &cache, cam, poe);
    for (ray, hit) in &hits {
        voxels += usize::from(!matches!(hit.surface, Surface::Triangle { .. }));
        if lighting.direct(hit, ray, &mut memo, &mut counts) > 0.0 {
            lit += 1;
        }
    }
    (hits.len(), lit, counts.shadow, voxels)
}

#[test]
fn a_closed_sphere_leaks_no_light() {
    let dir = tempfile::tempdir().unwrap();
    let path = sphere(dir.path(), 4);
    let light = [4.0, 3.0, 2.5];
    let behind = light.map(|c| -c);
    let inside = [
        camera([0.1, -0.05, 0.02], light, 64, 48),
        camera([0.1, -0.05, 0.02], behind, 64, 48),
        camera([-0.3, 0.2, 0.1], [1.0, 0.0, 0.0], 64, 48),
    ];
    let outside = camera(behind.map(|c| c * 0.4), [0.0; 3], 64, 48);
    let facing = camera(light.map(|c| c * 0.4), [0.0; 3], 64, 48);
    // The images at full detail: from inside the light is always behind the wall; from
    // outside, opposite the light, only the dark side is seen.
    for cam in inside.iter().chain([&outside]) {
        let (img, stats) = draw(&path, cam, &lit(0.0, light));
        assert!(stats.primary.triangle > 1000);
        assert_eq!(lit_pixels(&img), 0, "light leaks: {cam:?}");
    }
    // The direct light of every primary hit, with LOD too.
    for poe in [0.0, 2.0, 8.0] {
        let mut rays = 0;
        for cam in &inside {
            let (hits, lit, r, _) = lit_hits(&path, cam, poe, light);
            assert_eq!(hits, 64 * 48, "the wall surrounds the eye");
            assert_eq!(lit, 0, "--poe {poe}: light leaks inside");
            rays += r;
        }
        assert!(rays > 2000, "inner walls facing the light: {rays}");
        let (hits, lit, _, _) = lit_hits(&path, &outside, poe, light);
        assert!(hits > 1000);
        assert_eq!(lit, 0, "--poe {poe}: the far side is lit");
        // From the light's side most of it is lit: the tests above can fail. (At LOD the
        // first hit of a rim pixel may be a translucent voxel shaded where the ray enters its
        // cell, which the sphere behind it can shadow: 1698 of 1893 hits lit at --poe 2.)
        let (hits, lit, _, voxels) = lit_hits(&path, &facing, poe, light);
        assert!(lit > hits * 85 / 100, "{lit} of {hits} lit");
        assert!(poe == 0.0 || voxels > 0, "LOD is in use at --poe {poe}");
    }
}

/// Primary hits of a view, traced with the tracer.
fn hits_of(scene: &Scene, cache: &BlockingCache, cam: &Camera, poe: f32) -> Vec<(Ray, Hit)> {
    let frame = cam.frame().unwrap();
    let tracer = Tracer::new(scene, cache, poe * frame.pixel_angle() as f32);
    let memo = Memo::new(scene);
    let mut out = Vec::new();
    for y in 0..cam.height {
        for x in 0..cam.width {
            let ray = frame.ray(x, y);
            if let Some(h) = tracer.trace(&ray, &memo) {
                out.push((ray, h));
            }
        }
    }
    out
}

fn facing_normal(hit: &Hit, ray: &Ray) -> [f32; 3] {
    let n = match &hit.surface {
        Surface::Triangle { data, triangle, .. } => {
            let p = data.positions[*triangle as usize];
            oocfmt_trace::spawn::triangle_normal(&p)
                .unwrap()
                .map(|c| c as f32)
        }
        Surface::Proxy(s) => s.normal(),
        Surface::Voxel { normal, .. } => *normal,
        Surface::Plane { normal, .. } => *normal,
    };
    let d: f32 = (0..3).map(|k| n[k] * ray.dir[k]).sum();
    if d > 0.0 {
        n.map(|c| -c)
    } else {
        n
    }
}

#[test]
fn ambient_occlusion_on_an_open_plane_is_never_blocked() {
    let dir = tempfile::tempdir().unwrap();
    let path = plane(dir.path(), 40);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    let c = [1000.0, 200.0, -500.0];
    let cam = camera([c[0] - 3.0, c[1] - 7.0, c[2] + 6.0], c, 64, 48);
    let mut memo = Memo::new(&scene);
    for poe in [0.0, 8.0] {
        let ao = Occlusion::new(&scene, &cache, 16, 20.0, poe > 0.0);
        let hits = hits_of(&scene, &cache, &cam, poe);
        assert!(hits.len() > 1000, "{} hits", hits.len());
        let mut voxels = 0;
        for (i, (ray, hit)) in hits.iter().enumerate() {
            voxels += usize::from(!matches!(hit.surface, Surface::Triangle { .. }));
            let from = Origin::of(hit, ray, 1500.0);
            let n = facing_normal(hit, ray);
            let open = ao.open(&from, n, i as u64, &mut memo);
            assert_eq!(open, 1.0, "--poe {poe}: a ray from hit {i} met the plane");
        }
        assert!(poe == 0.0 || voxels > 0);
    }
}

/// 16 AO rays from each primary hit of a 64×48 framing view of `path` at PoE 6 that `keep`
/// selects: `check(source, its point, its facing normal, what the AO ray met, where)` for each
/// AO ray that meets something. The sources and the AO rays that met something.
fn ao_from_hits(
    path: &Path,
    keep: impl Fn(&Hit) -> bool,
    mut check: impl FnMut(&Hit, [f64; 3], [f32; 3], &Hit, [f64; 3]),
) -> (u32, usize) {
    let scene = Arc::new(Scene::open(path).unwrap());
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    let m = scene.metadata();
    let (lo, hi) = (m.scene.bounds_min, m.scene.bounds_max);
    let scale = lo.iter().chain(&hi).fold(0f32, |a, &c| a.max(c.abs()));
    let cam = Camera::framing(lo, hi, 64, 48);
    let n = 16;
    let ao = Tracer::new(&scene, &cache, ao_lod_c(n));
    let reach = (0..3).map(|k| hi[k] - lo[k]).fold(0f32, f32::max) * 0.3;
    let memo = Memo::new(&scene);
    let (mut sources, mut met) = (0, 0);
    for (ray, hit) in hits_of(&scene, &cache, &cam, 6.0) {
        if !keep(&hit) {
            continue;
        }
        sources += 1;
        let from = Origin::of(&hit, &ray, scale);
        let p = from.point().map(f64::from);
        let nrm = facing_normal(&hit, &ray);
        for i in 0..n {
            let d = cosine_hemisphere(nrm, point(i, n, hash(sources, 0, 0, Stream::Occlusion)));
            let r = Ray::new(from.spawn(d), d);
            let Some(h) = ao.trace_to(&r, reach, &memo) else {
                continue;
            };
            met += 1;
            assert!(h.t > 0.0, "an AO ray met something behind its origin");
            let q = [0, 1, 2].map(|k| f64::from(r.org[k]) + f64::from(h.t) * f64::from(r.dir[k]));
            check(&hit, p, nrm, &h, q);
        }
    }
    (sources, met)
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn ambient_occlusion_rays_never_meet_the_voxel_they_leave() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 20_000);
    let voxel = |h: &Hit| !matches!(h.surface, Surface::Triangle { .. });
    let (sources, met) = ao_from_hits(&path, voxel, |source, p, _, _, q| {
        // The hit lies on the boundary of the cell it ended in (or on a triangle); the source
        // cell holds the source point and is 2·radius across, so a hit farther away is not in
        // it.
        let dist = distance(q, p);
        assert!(
            dist > 2.0 * f64::from(source.radius),
            "an AO ray met its own voxel: {dist} from the source, radius {}",
            source.radius
        );
    });
    assert!(sources > 100, "{sources} primary rays ended on voxels");
    assert!(met > 100, "{met} AO rays met something");
}

/// An R-LOD's triangles lie within its deviation δ of its plane (spec §6.4): AO rays leaving a
/// plane hit start past δ, so whatever they meet lies beyond that slab, and they still meet
/// surfaces closer than the cell's diameter (the crease walls around the cell that a start 2r
/// off would skip).
#[test]
fn occlusion_rays_leaving_a_plane_clear_its_triangles_and_meet_the_walls_around_it() {
    let dir = tempfile::tempdir().unwrap();
    let layout = LayoutOptions {
        write: WriteOptions {
            lod: LodKinds::RLOD.filtered(),
            ..WriteOptions::default()
        },
        ..LayoutOptions::default()
    };
    let path = common::mandelbulb_with(dir.path(), 20_000, layout);
    let plane = |h: &Hit| matches!(h.surface, Surface::Plane { .. });
    let mut close = 0;
    let (sources, met) = ao_from_hits(&path, plane, |source, p, nrm, _, q| {
        let Surface::Plane { deviation, .. } = source.surface else {
            unreachable!("only plane hits are kept");
        };
        let height: f64 = (0..3).map(|k| (q[k] - p[k]) * f64::from(nrm[k])).sum();
        assert!(
            height > f64::from(deviation),
            "an AO ray met the slab of its own plane: {height} above it, δ {deviation}"
        );
        close += usize::from(distance(q, p) <= 2.0 * f64::from(source.radius));
    });
    assert!(sources > 100, "{sources} primary rays ended on planes");
    assert!(met > 100, "{met} AO rays met something");
    assert!(
        close > 0,
        "no AO ray met a surface within the cell's diameter"
    );
}

/// pbrt's re-intersection test: rays spawned from a hit on a triangle, in every direction,
/// never meet that triangle again.
#[test]
fn rays_spawned_from_a_triangle_never_hit_it_again() {
    let mut rng = Rng(0x5EED);
    let (mut triangles, mut spawned) = (0, 0u64);
    for case in 0..2000 {
        // Half the triangles have vertices at independent magnitudes from 1e-8 to 1e8 (huge
        // slivers among them); half are of one size from 1e-8 to 1e8, up to a thousand times
        // their size away from the origin.
        let v: [[f32; 3]; 3] = if case % 2 == 0 {
            [0; 3].map(|_| [0; 3].map(|_| exp(&mut rng, 8.0) as f32))
        } else {
            let size = 10f64.powf(rng.range(-8.0, 8.0));
            let far = size * 10f64.powf(rng.range(0.0, 3.0));
            let c = [0; 3].map(|_| rng.range(-far, far));
            [0; 3].map(|_| {
                let d = rng.direction();
                [0, 1, 2].map(|k| (c[k] + size * d[k]) as f32)
            })
        };
        // A primary ray from somewhere at a random point of the triangle.
        let (s, t) = (rng.unit().sqrt(), rng.unit());
        let b = [1.0 - s, s * (1.0 - t), s * t];
        let target = [0, 1, 2].map(|k| (0..3).map(|i| b[i] * f64::from(v[i][k])).sum::<f64>());
        let size = (0..3)
            .map(|k| (f64::from(v[0][k]) - target[k]).abs())
            .fold(0.0, f64::max);
        let away = rng.direction();
        let dist = size.max(1e-30) * 10f64.powf(rng.range(-2.0, 3.0));
        let org = [0, 1, 2].map(|k| (target[k] + dist * away[k]) as f32);
        let dir = [0, 1, 2].map(|k| (target[k] - f64::from(org[k])) as f32);
        if dir.iter().all(|c| *c == 0.0) || dir.iter().any(|c| !c.is_finite()) {
            continue;
        }
        let Some(h) = Ray::new(org, dir).triangle(&v[0], &v[1], &v[2]) else {
            continue;
        };
        triangles += 1;
        for _ in 0..1000 {
            let d = rng.direction().map(|c| c as f32);
            let o = from_triangle(&v, h.bary, d);
            spawned += 1;
            let again = Ray::new(o, d).triangle(&v[0], &v[1], &v[2]);
            assert!(
                again.is_none(),
                "re-hit: triangle {v:?} bary {:?} dir {d:?} origin {o:?}: {again:?}",
                h.bary
            );
        }
    }
    assert!(triangles > 1000, "{triangles} triangles were hit");
    assert!(spawned > 1_000_000);
}

#[test]
fn one_sample_per_pixel_is_the_default_image_and_more_average_stratified_rays() {
    let dir = tempfile::tempdir().unwrap();
    let path = sphere(dir.path(), 3);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    let cam = camera([0.5, 0.8, 3.0], [0.0; 3], 40, 30);
    let plain = render(&scene, &cache, &cam, &RenderOptions::DEFAULT).unwrap();
    let one = RenderOptions {
        spp: 1,
        ..RenderOptions::DEFAULT
    };
    let (a, sa) = render(&scene, &cache, &cam, &one).unwrap();
    assert_eq!((&a.rgb, &a.depth), (&plain.0.rgb, &plain.0.depth));
    assert_eq!(sa.rays, 40 * 30);
    let four = RenderOptions {
        spp: 4,
        ..RenderOptions::DEFAULT
    };
    let (b, sb) = render(&scene, &cache, &cam, &four).unwrap();
    // The depth stays the centre ray's.
    assert_eq!(b.depth, a.depth);
    assert_eq!((sb.primary_rays, sb.rays), (5 * 40 * 30, 5 * 40 * 30));
    // The colour is the mean of four rays through stratified points of the pixel.
    let frame = cam.frame().unwrap();
    let tracer = Tracer::new(&scene, &cache, 0.0);
    let memo = Memo::new(&scene);
    let materials = &scene.metadata().materials;
    let mut differ = 0;
    for y in 0..30 {
        for x in 0..40 {
            let mut sum = [0f32; 3];
            for k in 0..4 {
                let [ox, oy] = pixel_offset(x, y, k, 4);
                assert!((0.0..1.0).contains(&ox) && (0.0..1.0).contains(&oy));
                let r = frame.ray_at(f64::from(x) + ox, f64::from(y) + oy);
                let c = match tracer.trace(&r, &memo) {
                    Some(h) => shade(&h, &r, materials),
                    None => RenderOptions::DEFAULT.background,
                };
                for (s, c) in sum.iter_mut().zip(c) {
                    *s += c;
                }
            }
            let at = 3 * (y * 40 + x) as usize;
            assert_eq!(b.rgb[at..at + 3], sum.map(|s| encode_srgb(s / 4.0)));
            differ += usize::from(b.rgb[at..at + 3] != a.rgb[at..at + 3]);
        }
    }
    // Antialiasing changes the silhouette's pixels at least.
    assert!(differ > 20, "{differ} pixels changed");
}

#[test]
fn secondary_rays_are_counted_and_bad_options_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = sphere(dir.path(), 2);
    let cam = camera([0.5, 0.8, 3.0], [0.0; 3], 32, 24);
    let opts = RenderOptions {
        shadows: true,
        ao: 3,
        ..RenderOptions::DEFAULT
    };
    let (_, s) = draw(&path, &cam, &opts);
    let hits = s.primary.triangle + s.primary.voxel + s.primary.proxy;
    assert!(hits > 100);
    assert_eq!(s.ao_rays, 3 * hits);
    assert!(s.shadow_rays > 0 && s.shadow_rays <= hits);
    assert_eq!(s.rays, s.primary_rays + s.shadow_rays + s.ao_rays);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    let bad = [
        RenderOptions {
            spp: 0,
            ..RenderOptions::DEFAULT
        },
        RenderOptions {
            ao: 5000,
            ..RenderOptions::DEFAULT
        },
        RenderOptions {
            ao: 2,
            ao_distance: Some(f32::NAN),
            ..RenderOptions::DEFAULT
        },
        RenderOptions {
            shadows: true,
            light: Some([f64::INFINITY, 0.0, 0.0]),
            ..RenderOptions::DEFAULT
        },
    ];
    for o in bad {
        assert!(render(&scene, &cache, &cam, &o).is_err(), "{o:?}");
    }
}
