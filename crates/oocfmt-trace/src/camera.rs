//! A pinhole camera. Positions are in the container's stored coordinates (world minus the
//! metadata origin). One ray per pixel through the pixel centre (x + 0.5, y + 0.5), row 0 at
//! the top; more rays per pixel go through points inside the pixel ([`Frame::ray_at`]). A frame
//! aimed at a sample ([`Frame::aimed`]) moves each pixel's one ray on the image plane to that
//! pixel's sample point, so a pass of an accumulated image is an ordinary frame.

use crate::error::TraceError;
use crate::intersect::Ray;
use crate::sampling::pixel_offset;

/// A pinhole camera and its image size; [`Camera::frame`] checks it and makes its rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// The eye position: where every ray starts.
    pub eye: [f64; 3],
    /// The point seen at the centre of the image; must differ from `eye`.
    pub look_at: [f64; 3],
    /// Which way is up; need not be unit or perpendicular to the view, but not parallel to it.
    pub up: [f64; 3],
    /// Vertical field of view, degrees.
    pub fov_y: f64,
    /// Image width in pixels (at least 1).
    pub width: u32,
    /// Image height in pixels (at least 1).
    pub height: u32,
}

/// The camera's frame, ready to make rays.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    eye: [f64; 3],
    forward: [f64; 3],
    right: [f64; 3],
    up: [f64; 3],
    /// The size of a pixel on the image plane at distance 1.
    pixel: f64,
    width: u32,
    height: u32,
    /// Where in its pixel [`Frame::ray`] aims.
    aim: Aim,
}

/// Where in its pixel a frame's one ray per pixel ([`Frame::ray`]) goes through the image
/// plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Aim {
    /// The pixel centre (x + 0.5, y + 0.5).
    Centre,
    /// Sample `k` of the `n` that `render --spp n` averages in each pixel: the pixel's own
    /// stratified point ([`pixel_offset`]); with `n` ≤ 1 the centre.
    Sample {
        /// Which sample, 0 ..= n − 1.
        k: u32,
        /// Samples per pixel.
        n: u32,
    },
}

/// The vertical field of view, in degrees, of a camera that does not say.
pub const DEFAULT_FOV_Y: f64 = 45.0;

impl Camera {
    /// Looks at the centre of the box [lo, hi] from a direction above and to the side, from
    /// the nearest distance at which all eight corners of the box lie inside the view.
    pub fn framing(lo: [f32; 3], hi: [f32; 3], width: u32, height: u32) -> Camera {
        let c = [0, 1, 2].map(|k| (f64::from(lo[k]) + f64::from(hi[k])) / 2.0);
        let half = [0, 1, 2].map(|k| (f64::from(hi[k]) - f64::from(lo[k])) / 2.0);
        let u = normalize([0.55, 0.45, 0.7]);
        let up = [0.0, 1.0, 0.0];
        let right = normalize(cross(neg(u), up));
        let cam_up = cross(right, neg(u));
        let aspect = f64::from(width.max(1)) / f64::from(height.max(1));
        let tan_y = (DEFAULT_FOV_Y / 2.0).to_radians().tan();
        let tan_x = tan_y * aspect;
        let mut dist: f64 = 0.0;
        for corner in 0..8 {
            let q = [0, 1, 2].map(|k| {
                if corner >> k & 1 == 1 {
                    half[k]
                } else {
                    -half[k]
                }
            });
            let along = dot(q, u);
            dist = dist
                .max(along + dot(q, right).abs() / tan_x)
                .max(along + dot(q, cam_up).abs() / tan_y);
        }
        // A margin of a few pixels; a point-like scene still gets a distance.
        let dist = if dist > 0.0 { dist * 1.05 } else { 1.0 };
        Camera {
            eye: [0, 1, 2].map(|k| c[k] + u[k] * dist),
            look_at: c,
            up,
            fov_y: DEFAULT_FOV_Y,
            width,
            height,
        }
    }

    /// The camera's orthonormal frame, or a [`TraceError::Camera`] saying why it cannot make
    /// rays (an empty image, a field of view outside 0..180 degrees, a degenerate view).
    pub fn frame(&self) -> Result<Frame, TraceError> {
        let bad = |what: &str| Err(TraceError::Camera(what.to_string()));
        if self.width == 0 || self.height == 0 {
            return bad("the image needs a width and a height of at least 1");
        }
        if !(self.fov_y > 0.0 && self.fov_y < 180.0) {
            return bad("the vertical field of view must lie strictly between 0 and 180 degrees");
        }
        let all = [self.eye, self.look_at, self.up];
        if all.iter().flatten().any(|c| !c.is_finite()) {
            return bad("eye, look-at and up must be finite");
        }
        let f = sub(self.look_at, self.eye);
        if length(f) == 0.0 {
            return bad("the eye and the look-at point are the same");
        }
        let forward = normalize(f);
        let r = cross(forward, self.up);
        if length(r) <= 1e-12 * length(self.up) || length(self.up) == 0.0 {
            return bad("the up vector is zero or parallel to the view direction");
        }
        let right = normalize(r);
        let up = cross(right, forward);
        let tan_half = (self.fov_y / 2.0).to_radians().tan();
        Ok(Frame {
            eye: self.eye,
            forward,
            right,
            up,
            pixel: 2.0 * tan_half / f64::from(self.height),
            width: self.width,
            height: self.height,
            aim: Aim::Centre,
        })
    }
}

impl Frame {
    /// The primary ray of pixel (x, y), with a unit direction: through its centre, or through
    /// its sample point when the frame is [`Frame::aimed`] at one.
    #[inline]
    pub fn ray(&self, x: u32, y: u32) -> Ray {
        let [ox, oy] = match self.aim {
            Aim::Centre => [0.5, 0.5],
            Aim::Sample { k, n } => pixel_offset(x, y, k, n),
        };
        self.ray_at(f64::from(x) + ox, f64::from(y) + oy)
    }

    /// This frame with [`Frame::ray`] aimed at `aim`: the eye, the view and the image plane
    /// stay; only the point each pixel's ray goes through moves, so the move is the same in the
    /// corners as at the centre.
    pub fn aimed(self, aim: Aim) -> Frame {
        Frame { aim, ..self }
    }

    /// Where [`Frame::ray`] aims.
    pub fn aim(&self) -> Aim {
        self.aim
    }

    /// The primary ray through the point (px, py) of the image plane, in pixels from the top
    /// left corner (pixel (x, y) covers [x, x + 1) × [y, y + 1)), with a unit direction.
    #[inline]
    pub fn ray_at(&self, px: f64, py: f64) -> Ray {
        // The point on the image plane at distance 1, in pixels from the image's centre (exact
        // for pixel centres: halves of integers), then scaled: the centre pixel of an
        // odd-sized image looks exactly forward.
        let sx = (px - f64::from(self.width) / 2.0) * self.pixel;
        let sy = (f64::from(self.height) / 2.0 - py) * self.pixel;
        let d = [0, 1, 2].map(|k| self.forward[k] + sx * self.right[k] + sy * self.up[k]);
        let r = 1.0 / length(d);
        Ray::new(self.eye.map(|c| c as f32), d.map(|c| (c * r) as f32))
    }

    /// The eye position.
    pub fn eye(&self) -> [f64; 3] {
        self.eye
    }

    /// The unit vectors forward, right and up of the view.
    pub fn basis(&self) -> ([f64; 3], [f64; 3], [f64; 3]) {
        (self.forward, self.right, self.up)
    }

    /// World size of one pixel per unit of distance along the view axis.
    pub fn pixel_angle(&self) -> f64 {
        self.pixel
    }

    /// Image width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn neg(a: [f64; 3]) -> [f64; 3] {
    a.map(|c| -c)
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn length(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

pub(crate) fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = length(a);
    a.map(|c| c / l)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_centre_pixel_looks_forward_and_row_zero_is_the_top() {
        let cam = Camera {
            eye: [0.0, 0.0, 5.0],
            look_at: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y: 90.0,
            width: 3,
            height: 3,
        };
        let f = cam.frame().ok();
        let centre = f.map(|f| f.ray(1, 1).dir);
        assert_eq!(centre, Some([0.0, 0.0, -1.0]));
        let top = f.map(|f| f.ray(1, 0).dir[1]);
        assert!(top.is_some_and(|y| y > 0.0));
        let left = f.map(|f| f.ray(0, 1).dir[0]);
        assert!(left.is_some_and(|x| x < 0.0));
    }

    /// Where `dir` crosses the image plane at distance 1, in pixels right and down of the
    /// image centre.
    fn on_plane(f: &Frame, dir: [f32; 3]) -> [f64; 2] {
        let (fwd, right, up) = f.basis();
        let d = dir.map(f64::from);
        let along = dot(d, fwd);
        let p = f.pixel_angle() * along;
        [dot(d, right) / p, -dot(d, up) / p]
    }

    #[test]
    fn an_aimed_frame_moves_every_ray_on_the_image_plane_by_its_sample_offset() {
        let cam = Camera {
            eye: [1.0, 2.0, 5.0],
            look_at: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y: 60.0,
            width: 160,
            height: 120,
        };
        let centre = cam.frame().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(centre.aim(), Aim::Centre);
        let n = 4;
        for k in 0..n {
            let aimed = centre.aimed(Aim::Sample { k, n });
            // The corners and the middle: turning the camera instead would move the corner
            // rays by about a sixth less than the middle one at this field of view.
            for (x, y) in [(0, 0), (159, 119), (159, 0), (80, 60)] {
                let [ox, oy] = pixel_offset(x, y, k, n);
                let want = [ox - 0.5, oy - 0.5];
                let from = on_plane(&centre, centre.ray(x, y).dir);
                let to = on_plane(&centre, aimed.ray(x, y).dir);
                for a in 0..2 {
                    let moved = to[a] - from[a];
                    assert!(
                        (moved - want[a]).abs() < 1e-4,
                        "pixel ({x}, {y}) sample {k}: moved {moved}, want {}",
                        want[a]
                    );
                }
                assert_eq!(
                    aimed.ray(x, y).dir,
                    centre.ray_at(f64::from(x) + ox, f64::from(y) + oy).dir
                );
            }
        }
        // One sample per pixel is the centre, bit for bit.
        let one = centre.aimed(Aim::Sample { k: 0, n: 1 });
        assert_eq!(one.ray(0, 0).dir, centre.ray(0, 0).dir);
        assert_eq!(one.ray(159, 119).dir, centre.ray(159, 119).dir);
    }

    #[test]
    fn bad_cameras_are_refused() {
        let mut cam = Camera::framing([0.0; 3], [1.0; 3], 4, 4);
        assert!(cam.frame().is_ok());
        cam.up = cam.look_at.map(|_| 0.0);
        assert!(cam.frame().is_err());
        cam = Camera::framing([0.0; 3], [1.0; 3], 0, 4);
        assert!(cam.frame().is_err());
    }
}
