//! Section planes: with the plane between two spheres a frame shows, pixel for pixel, what a
//! file of the kept sphere alone shows (the eye on the plane: no ray is moved); from an eye on
//! the cut side every hit lies in the kept half-space and the image matches the kept sphere's
//! to rounding; a plane past the whole model leaves the background, also with samples per
//! pixel; a pick cannot see what the plane cuts away.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use oocfmt_trace::pick::pick;
use oocfmt_trace::render::Image;
use oocfmt_trace::{render, BlockingCache, Camera, RenderOptions, Scene, Section};

use crate::common;

const W: u32 = 96;
const H: u32 = 64;

/// An OBJ of a unit sphere at each of `centres`; positions print as f32, so that every file
/// stores the same coordinates.
fn obj(centres: &[[f64; 3]]) -> String {
    let (v, f) = common::sphere(4);
    let mut text = String::new();
    for (k, c) in centres.iter().enumerate() {
        for p in &v {
            let q = [0, 1, 2].map(|i| (f64::from(p[i]) + c[i]) as f32);
            writeln!(text, "v {} {} {}", q[0], q[1], q[2]).unwrap();
        }
        let base = k * v.len() + 1;
        for t in &f {
            writeln!(text, "f {} {} {}", t[0] + base, t[1] + base, t[2] + base).unwrap();
        }
    }
    text
}

fn convert(dir: &Path, name: &str, centres: &[[f64; 3]]) -> PathBuf {
    let src = dir.join(format!("{name}.obj"));
    std::fs::write(&src, obj(centres)).unwrap();
    let out = dir.join(format!("{name}.oocf"));
    common::convert_obj(&src, &out);
    out
}

const LEFT: [f64; 3] = [-3.0, 0.0, 0.0];
const RIGHT: [f64; 3] = [3.0, 0.0, 0.0];

fn camera(eye: [f64; 3]) -> Camera {
    Camera {
        eye,
        look_at: [0.0, 0.0, 0.0],
        up: [0.0, 1.0, 0.0],
        fov_y: 45.0,
        width: W,
        height: H,
    }
}

fn frame(scene: &Arc<Scene>, cam: &Camera, opts: &RenderOptions) -> Image {
    let cache = BlockingCache::new(Arc::clone(scene), usize::MAX);
    render(scene, &cache, cam, opts).unwrap().0
}

/// The world points the image's centre rays hit.
fn hit_points(scene: &Scene, cam: &Camera, image: &Image) -> Vec<[f64; 3]> {
    let f = cam.frame().unwrap();
    let o = scene.metadata().scene.origin;
    let mut out = Vec::new();
    for y in 0..H {
        for x in 0..W {
            let d = image.depth[(y * W + x) as usize];
            if d.is_finite() {
                let r = f.ray(x, y);
                let p = [0, 1, 2]
                    .map(|k| f64::from(r.org[k]) + f64::from(d) * f64::from(r.dir[k]) + o[k]);
                out.push(p);
            }
        }
    }
    out
}

struct Files {
    both: PathBuf,
    right: PathBuf,
    _dir: tempfile::TempDir,
}

fn files() -> Files {
    let dir = tempfile::tempdir().unwrap();
    Files {
        both: convert(dir.path(), "both", &[LEFT, RIGHT]),
        right: convert(dir.path(), "right", &[RIGHT]),
        _dir: dir,
    }
}

#[test]
fn a_section_between_the_spheres_renders_the_kept_sphere_alone() {
    let f = files();
    let both = Arc::new(Scene::open(&f.both).unwrap());
    let right = Arc::new(Scene::open(&f.right).unwrap());
    let opts = RenderOptions::DEFAULT;
    // The eye on the plane x = 0: rays keep all of themselves or nothing, none is moved.
    let cam = camera([0.0, 0.0, 12.0]);
    let alone = frame(&right, &cam, &opts);
    assert!(
        alone.model.iter().any(|&m| m),
        "the right sphere is in view"
    );
    let whole = frame(&both, &cam, &opts);
    both.set_section(Some(Section::parse("x=0").unwrap()));
    let cut = frame(&both, &cam, &opts);
    assert_ne!(
        whole.model, cut.model,
        "the section removed the left sphere"
    );
    assert_eq!(cut.rgb, alone.rgb, "colours");
    let bits = |i: &Image| i.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&cut), bits(&alone), "depths");
    // Flipped, the left sphere is kept and the right one cut away.
    both.set_section(Some(Section::parse("x=0").unwrap().flipped()));
    let flipped = frame(&both, &cam, &opts);
    assert!(hit_points(&both, &cam, &flipped)
        .iter()
        .all(|p| p[0] <= 0.0));
    assert!(flipped.model.iter().any(|&m| m));
}

#[test]
fn from_the_cut_side_every_hit_is_on_the_kept_side_and_the_image_is_the_kept_spheres() {
    let f = files();
    let both = Arc::new(Scene::open(&f.both).unwrap());
    let right = Arc::new(Scene::open(&f.right).unwrap());
    let opts = RenderOptions::DEFAULT;
    // The eye left of the plane x = 1: every ray that sees the right sphere is moved to
    // where it crosses the plane; the left sphere, in front of it, is cut away.
    let cam = camera([-6.0, 0.5, 9.0]);
    let c = 1.0;
    both.set_section(Some(Section::axis(0, c).unwrap()));
    let cut = frame(&both, &cam, &opts);
    let alone = frame(&right, &cam, &opts);
    let points = hit_points(&both, &cam, &cut);
    assert!(
        points.len() > 60,
        "the right sphere fills part of the image"
    );
    for p in &points {
        assert!(p[0] >= c - 1e-4, "a hit at {p:?} is on the cut side");
    }
    // The same surface to rounding: the moved origins change the last bits of a distance,
    // and at most a pixel or two of the silhouette.
    let n = (W * H) as usize;
    let mask_diff = (0..n).filter(|&i| cut.model[i] != alone.model[i]).count();
    assert!(mask_diff <= 2, "{mask_diff} pixels differ in coverage");
    for i in (0..n).filter(|&i| cut.model[i] && alone.model[i]) {
        let (a, b) = (cut.depth[i], alone.depth[i]);
        assert!(
            (a - b).abs() <= 1e-4 * b,
            "pixel {i}: depth {a} against {b}"
        );
        for k in 0..3 {
            let (p, q) = (cut.rgb[3 * i + k], alone.rgb[3 * i + k]);
            assert!(p.abs_diff(q) <= 2, "pixel {i}: colour {p} against {q}");
        }
    }
}

#[test]
fn a_section_past_the_whole_model_shows_the_background() {
    let f = files();
    let both = Arc::new(Scene::open(&f.both).unwrap());
    let cam = camera([0.0, 0.0, 12.0]);
    let empty = frame(&both, &cam, &RenderOptions::DEFAULT);
    let background = empty.rgb[..3].to_vec();
    for text in ["x=10", "-x=-10", "-z=-20", "0,0,5,0,0,1"] {
        both.set_section(Some(Section::parse(text).unwrap()));
        for spp in [1, 4] {
            let opts = RenderOptions {
                spp,
                ..RenderOptions::DEFAULT
            };
            let cache = BlockingCache::new(Arc::clone(&both), usize::MAX);
            let (image, stats) = render(&both, &cache, &cam, &opts).unwrap();
            assert!(
                image.model.iter().all(|&m| !m),
                "{text}, spp {spp}: a pixel shows the model"
            );
            assert!(image.depth.iter().all(|d| d.is_infinite()));
            assert!(image.rgb.chunks(3).all(|p| p == background.as_slice()));
            assert_eq!(stats.primary.miss, u64::from(W * H));
        }
    }
}

#[test]
fn a_pick_does_not_see_what_the_section_cuts_away() {
    let f = files();
    let both = Arc::new(Scene::open(&f.both).unwrap());
    let cam = camera([0.0, 0.0, 12.0]);
    let cache = BlockingCache::new(Arc::clone(&both), usize::MAX);
    // Pixels on the sphere centres' lines of sight.
    let f0 = cam.frame().unwrap();
    let column = |x: f64| {
        (0..W)
            .min_by(|&a, &b| {
                let ra = f0.ray(a, H / 2);
                let rb = f0.ray(b, H / 2);
                let da = (f64::from(ra.dir[0] / -ra.dir[2]) * 12.0 - x).abs();
                let db = (f64::from(rb.dir[0] / -rb.dir[2]) * 12.0 - x).abs();
                da.total_cmp(&db)
            })
            .unwrap()
    };
    let (left, right) = (column(LEFT[0]), column(RIGHT[0]));
    assert!(pick(&both, &cache, &cam, (left, H / 2), 0.0)
        .unwrap()
        .is_some());
    both.set_section(Some(Section::parse("x=0").unwrap()));
    assert_eq!(pick(&both, &cache, &cam, (left, H / 2), 0.0).unwrap(), None);
    let p = pick(&both, &cache, &cam, (right, H / 2), 0.0)
        .unwrap()
        .unwrap();
    assert!(p.point[0] > 1.5, "picked {:?}", p.point);
    // A plane through the right sphere's front keeping what lies behind it: the pick passes
    // the cut-away front and lands on the sphere's back, seen from inside, and reports its
    // distance from the eye.
    both.set_section(Some(Section::parse("0,0,0.5,0,0,-1").unwrap()));
    let p = pick(&both, &cache, &cam, (right, H / 2), 0.0)
        .unwrap()
        .unwrap();
    assert!(p.point[2] < -0.5, "picked {:?}", p.point);
    let eye = cam.eye;
    let d = (0..3)
        .map(|k| (p.point[k] - eye[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        (p.distance - d).abs() < 1e-3 * d,
        "distance {} to {d}",
        p.distance
    );
}
