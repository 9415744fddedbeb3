//! What a viewer's measure snaps to: a pick at full detail gives the hit triangle's corners,
//! world coordinates, and the hit point lies in that triangle (on its plane, inside its
//! edges).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::Arc;

use oocfmt_trace::pick::pick;
use oocfmt_trace::{BlockingCache, Camera, Scene};

use crate::common;

#[test]
fn a_full_detail_pick_gives_the_corners_of_the_triangle_it_hit() {
    let dir = tempfile::tempdir().unwrap();
    let path = common::mandelbulb(dir.path(), 4_000);
    let scene = Arc::new(Scene::open(&path).unwrap());
    let cache = BlockingCache::new(Arc::clone(&scene), usize::MAX);
    let m = scene.metadata();
    let cam = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, 64, 48);
    let mut seen = 0;
    for (x, y) in [(32, 24), (28, 20), (36, 27), (30, 26)] {
        let Some(p) = pick(&scene, &cache, &cam, (x, y), 0.0).unwrap() else {
            continue;
        };
        seen += 1;
        let [a, b, c] = p.corners.expect("a full-detail pick has corners");
        let sub = |u: [f64; 3], v: [f64; 3]| [0, 1, 2].map(|k| u[k] - v[k]);
        let cross = |u: [f64; 3], v: [f64; 3]| {
            [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ]
        };
        let dot = |u: [f64; 3], v: [f64; 3]| (0..3).map(|k| u[k] * v[k]).sum::<f64>();
        let n = cross(sub(b, a), sub(c, a));
        let area2 = dot(n, n).sqrt();
        assert!(area2 > 0.0);
        // On the plane, to f32 rounding of the scene's size.
        let off = dot(n, sub(p.point, a)).abs() / area2;
        assert!(off < 1e-4, "the point is {off} off the triangle's plane");
        // Inside the edges: the three sub-triangles have the normal's orientation.
        for (u, v) in [(a, b), (b, c), (c, a)] {
            let s = dot(cross(sub(v, u), sub(p.point, u)), n) / (area2 * area2);
            assert!(s > -1e-4, "the point is outside edge {u:?}-{v:?}: {s}");
        }
    }
    assert!(seen >= 3, "the picks hit the model");
}
