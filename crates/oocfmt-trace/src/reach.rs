//! Which pixels' primary rays can reach a box: the box's corners projected onto the image.
//!
//! A frame renders a pixel outside that rectangle as a miss without making or tracing its
//! rays (`render::FrameJob::tile`): most of a far view is background, and setting up, tracing
//! and shading a ray that misses the scene's box cost more than all the rays that hit it
//! together on the 10M Mandelbulb's default view (`docs/benchmarks.md`).

use crate::camera::{dot, sub, Frame};

/// Pixels x0..x1 by y0..y1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    /// The first column.
    pub x0: u32,
    /// The first row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl PixelRect {
    /// Whether the rectangle and pixels x0..x1 by y0..y1 share a pixel.
    pub fn overlaps(&self, (x0, y0, x1, y1): (u32, u32, u32, u32)) -> bool {
        x0 < self.x1 && self.x0 < x1 && y0 < self.y1 && self.y0 < y1
    }
}

/// The pixels of `frame` whose rays, through any point of the pixel, may meet the box
/// [lo, hi]; every other pixel's rays miss it. No pixel when the whole box lies behind the eye's
/// plane (every ray goes forward); the whole image when only part of it does (the eye inside
/// the box, or beside it), where a projection cannot bound the rays.
///
/// The rectangle is widened by two pixels, and by far more than the angle a ray's f32
/// direction is rounded by (1e-6 on the image plane at distance 1, growing towards the edge
/// of a wide view as the plane does); the box is taken as given, so a caller pads it by what
/// its own ray-box test pads.
pub fn box_pixels(frame: &Frame, lo: [f64; 3], hi: [f64; 3]) -> PixelRect {
    let (w, h) = (frame.width(), frame.height());
    let whole = PixelRect {
        x0: 0,
        y0: 0,
        x1: w,
        y1: h,
    };
    let (forward, right, up) = frame.basis();
    let eye = frame.eye();
    let corners = (0..8).map(|c: u32| {
        let p = [0, 1, 2].map(|k| if c >> k & 1 == 1 { hi[k] } else { lo[k] });
        sub(p, eye)
    });
    // A ray's points ahead of the eye have dot(v, forward) > 0: none meets a box behind, by
    // more than the rounding of the eye to f32 (the rays' origin).
    let rounding = 1e-6 * dot(eye, eye).sqrt();
    if corners
        .clone()
        .all(|v| dot(v, forward) < -rounding - 1e-6 * dot(v, v).sqrt())
    {
        return PixelRect {
            x0: 0,
            y0: 0,
            x1: 0,
            y1: 0,
        };
    }
    // The image plane at distance 1: s = (sx, sy) of the corners, as `Frame::ray_at` spans it.
    let (mut s_lo, mut s_hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for v in corners {
        let z = dot(v, forward);
        // At or behind the eye's plane, or NaN.
        if z.is_nan() || z <= 0.0 {
            return whole;
        }
        for (k, axis) in [right, up].into_iter().enumerate() {
            let s = dot(v, axis) / z;
            s_lo[k] = s_lo[k].min(s);
            s_hi[k] = s_hi[k].max(s);
        }
    }
    let pixel = frame.pixel_angle();
    let reach = s_lo.iter().chain(&s_hi).fold(0f64, |m, s| m.max(s.abs()));
    let margin = 2.0 + 1e-6 * (1.0 + 2.0 * reach * reach) / pixel;
    // Pixels from the top left corner, as `Frame::ray_at` takes them: x grows with sx, y
    // falls with sy.
    let (cx, cy) = (f64::from(w) / 2.0, f64::from(h) / 2.0);
    let x = [cx + s_lo[0] / pixel - margin, cx + s_hi[0] / pixel + margin];
    let y = [cy - s_hi[1] / pixel - margin, cy - s_lo[1] / pixel + margin];
    if !x.iter().chain(&y).all(|c| c.is_finite()) {
        return whole;
    }
    // A pixel [x, x + 1) reaches when it overlaps [x[0], x[1]]; `as` saturates.
    let clamp = |v: f64, n: u32| v.clamp(0.0, f64::from(n)) as u32;
    PixelRect {
        x0: clamp(x[0].floor(), w),
        y0: clamp(y[0].floor(), h),
        x1: clamp(x[1].ceil() + 1.0, w),
        y1: clamp(y[1].ceil() + 1.0, h),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::intersect::ray_box;
    use crate::sampling::pixel_offset;

    fn frame(eye: [f64; 3], look_at: [f64; 3], fov_y: f64, (w, h): (u32, u32)) -> Frame {
        let cam = Camera {
            eye,
            look_at,
            up: [0.0, 1.0, 0.0],
            fov_y,
            width: w,
            height: h,
        };
        cam.frame().unwrap_or_else(|e| panic!("{e}"))
    }

    /// Every pixel outside the rectangle, at its centre and at 16 stratified points, misses
    /// the box; and where the rectangle is neither empty nor the whole image, some pixel
    /// within four of its edge hits it (it is no looser than its margin).
    fn check(f: &Frame, lo: [f64; 3], hi: [f64; 3]) -> PixelRect {
        let r = box_pixels(f, lo, hi);
        let (lo32, hi32) = (lo.map(|c| c as f32), hi.map(|c| c as f32));
        let mut near_edge_hits = 0;
        for y in 0..f.height() {
            for x in 0..f.width() {
                let inside = r.overlaps((x, y, x + 1, y + 1));
                for k in 0..17 {
                    let [ox, oy] = if k == 16 {
                        [0.5, 0.5]
                    } else {
                        pixel_offset(x, y, k, 16)
                    };
                    let ray = f.ray_at(f64::from(x) + ox, f64::from(y) + oy);
                    let hit = ray_box(&ray, lo32, hi32, 0.0, 0.0, f32::INFINITY).is_some();
                    assert!(
                        inside || !hit,
                        "pixel ({x}, {y}) hits the box outside {r:?}"
                    );
                    let edge = x < r.x0 + 4 || x + 4 >= r.x1 || y < r.y0 + 4 || y + 4 >= r.y1;
                    near_edge_hits += usize::from(hit && edge);
                }
            }
        }
        let whole = r.x0 == 0 && r.y0 == 0 && r.x1 == f.width() && r.y1 == f.height();
        let empty = r.x0 >= r.x1 || r.y0 >= r.y1;
        assert!(
            whole || empty || near_edge_hits > 0,
            "{r:?} is looser than its margin"
        );
        r
    }

    #[test]
    fn pixels_outside_the_rectangle_miss_the_box() {
        let (lo, hi) = ([-1.0, -0.5, -2.0], [1.5, 0.5, 0.0]);
        // Ahead, off to a side, at a steep angle, and through a narrow and a wide lens.
        for (eye, at, fov) in [
            ([0.3, 0.2, 9.0], [0.0, 0.0, 0.0], 45.0),
            ([6.0, 1.0, 6.0], [3.0, 0.0, 0.0], 45.0),
            ([0.5, 8.0, 0.5], [0.0, 0.0, -1.0], 60.0),
            ([0.0, 0.0, 40.0], [0.2, 0.1, -1.0], 2.0),
            ([2.0, 1.0, 3.0], [0.0, 0.0, -1.0], 150.0),
        ] {
            let f = frame(eye, at, fov, (96, 64));
            let r = check(&f, lo, hi);
            assert!(r.x0 < r.x1 && r.y0 < r.y1, "{r:?}");
        }
    }

    #[test]
    fn a_box_beside_or_around_the_eye_gives_the_whole_image() {
        let (lo, hi) = ([-1.0; 3], [1.0; 3]);
        let whole = PixelRect {
            x0: 0,
            y0: 0,
            x1: 40,
            y1: 30,
        };
        // The eye inside the box, and a box reaching behind the eye's plane.
        let f = frame([0.2, 0.0, 0.5], [0.0, 0.0, -5.0], 45.0, (40, 30));
        assert_eq!(box_pixels(&f, lo, hi), whole);
        let f = frame([0.0, 0.0, 1.5], [5.0, 0.0, 1.5], 45.0, (40, 30));
        assert_eq!(box_pixels(&f, lo, hi), whole);
    }

    #[test]
    fn a_box_behind_the_eye_reaches_no_pixel() {
        let (lo, hi) = ([-1.0; 3], [1.0; 3]);
        for fov in [45.0, 170.0] {
            let f = frame([0.0, 0.0, 1.5], [0.2, 0.1, 9.0], fov, (40, 30));
            let r = check(&f, lo, hi);
            assert!(!r.overlaps((0, 0, 40, 30)), "{r:?}");
        }
    }

    #[test]
    fn a_box_out_of_view_reaches_no_pixel() {
        // In front of the eye, 38 to 50 degrees to its left; the view spans 29 either side.
        let (lo, hi) = ([-1.0; 3], [1.0; 3]);
        let f = frame([0.0, 0.0, 10.0], [10.0, 0.0, 0.0], 45.0, (40, 30));
        let r = check(&f, lo, hi);
        assert!(!r.overlaps((0, 0, 40, 30)), "{r:?}");
    }
}
