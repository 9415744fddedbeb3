//! Accumulating a still view into an antialiased image, one pass at a time, so that a new
//! camera never waits behind a many-sample frame: pass k of `spp` renders the whole image once
//! with each pixel's ray through the point `render --spp` uses for its sample k
//! ([`pass_frame`]), and the passes' colours are averaged in linear RGB.
//!
//! The pass moves the point on the image plane, not the camera: every ray moves by its pixel's
//! offset, in the corners as at the centre (turning the camera by the centre's offset moved a
//! 45° view's corner rays about 30 % farther, and across too: a wider filter there). With the same points the last image is `render --spp` of the same
//! camera but for rounding: each pass is rounded to 8-bit sRGB before it is averaged.

use std::sync::OnceLock;

use crate::camera::{Aim, Camera, Frame};
use crate::error::TraceError;
use crate::render::Image;
use crate::shade::encode_srgb;

/// The frame of pass `k` of `spp` through `camera`: its rays go through the points of
/// sample `k` of `render --spp spp` ([`crate::sampling::pixel_offset`]), so pass 0 of 1 is the
/// pixel centres, an ordinary frame of `render`.
pub fn pass_frame(camera: &Camera, k: u32, spp: u32) -> Result<Frame, TraceError> {
    Ok(camera.frame()?.aimed(Aim::Sample { k, n: spp }))
}

/// The linear value of each sRGB level.
fn linear(level: u8) -> f32 {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    let t = TABLE.get_or_init(|| {
        std::array::from_fn(|i| {
            let c = i as f64 / 255.0;
            let l = if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            };
            l as f32
        })
    });
    t.get(usize::from(level)).copied().unwrap_or(1.0)
}

/// The running average of a still view's passes.
pub struct Accumulator {
    width: u32,
    height: u32,
    /// Linear RGB summed over the passes, 3 a pixel.
    sum: Vec<f32>,
    samples: u32,
    /// The first pass's depths; the pixels any pass found the model in.
    depth: Vec<f32>,
    model: Vec<bool>,
}

impl Accumulator {
    /// An average of one pass: `first` (sample 0).
    pub fn new(first: &Image) -> Accumulator {
        Accumulator {
            width: first.width,
            height: first.height,
            sum: first.rgb.iter().map(|&c| linear(c)).collect(),
            samples: 1,
            depth: first.depth.clone(),
            model: first.model.clone(),
        }
    }

    /// Adds a pass; false (and nothing added) when its size differs from the first's.
    pub fn add(&mut self, pass: &Image) -> bool {
        if (pass.width, pass.height) != (self.width, self.height)
            || pass.rgb.len() != self.sum.len()
        {
            return false;
        }
        for (s, &c) in self.sum.iter_mut().zip(&pass.rgb) {
            *s += linear(c);
        }
        for (m, &p) in self.model.iter_mut().zip(&pass.model) {
            *m |= p;
        }
        self.samples += 1;
        true
    }

    /// The passes added so far, the first included.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// The average, sRGB-encoded; depths of the first pass.
    pub fn image(&self) -> Image {
        let n = self.samples.max(1) as f32;
        Image {
            width: self.width,
            height: self.height,
            rgb: self.sum.iter().map(|&s| encode_srgb(s / n)).collect(),
            depth: self.depth.clone(),
            model: self.model.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(rgb: Vec<u8>) -> Image {
        let n = rgb.len() / 3;
        Image {
            width: n as u32,
            height: 1,
            rgb,
            depth: vec![1.0; n],
            model: vec![true; n],
        }
    }

    #[test]
    fn one_pass_is_its_own_average_for_every_level() {
        let levels: Vec<u8> = (0..=255).flat_map(|l| [l, l, l]).collect();
        let a = Accumulator::new(&image(levels.clone()));
        assert_eq!(a.image().rgb, levels);
        assert_eq!(a.samples(), 1);
    }

    #[test]
    fn passes_average_in_linear_light() {
        let mut a = Accumulator::new(&image(vec![0, 0, 0]));
        assert!(a.add(&image(vec![255, 255, 255])));
        // Half of full linear intensity is sRGB level 188, not 128.
        assert_eq!(a.image().rgb, vec![188, 188, 188]);
        assert_eq!(a.samples(), 2);
        assert!(
            !a.add(&image(vec![1, 2, 3, 4, 5, 6])),
            "a pass of another size"
        );
        assert_eq!(a.samples(), 2);
    }

    /// Where `dir` crosses the image plane at distance 1 of `f`, in pixels right and down of
    /// the image centre.
    fn on_plane(f: &Frame, dir: [f32; 3]) -> [f64; 2] {
        let (fwd, right, up) = f.basis();
        let d = dir.map(f64::from);
        let p = f.pixel_angle() * crate::camera::dot(d, fwd);
        [
            crate::camera::dot(d, right) / p,
            -crate::camera::dot(d, up) / p,
        ]
    }

    #[test]
    fn a_pass_moves_a_corner_ray_by_its_whole_offset_on_the_image_plane() -> Result<(), TraceError>
    {
        // A wide view, where turning the camera by half a pixel at the centre would move a
        // corner ray by 1.4 pixels across and 0.65 down.
        let cam = Camera {
            eye: [0.0, 0.0, 5.0],
            look_at: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y: 90.0,
            width: 160,
            height: 120,
        };
        let centre = cam.frame()?;
        let spp = 8;
        for k in 0..spp {
            let pass = pass_frame(&cam, k, spp)?;
            for (x, y) in [(0, 0), (159, 119), (0, 119), (80, 60)] {
                let [ox, oy] = crate::sampling::pixel_offset(x, y, k, spp);
                let from = on_plane(&centre, centre.ray(x, y).dir);
                let to = on_plane(&centre, pass.ray(x, y).dir);
                let moved = [to[0] - from[0], to[1] - from[1]];
                let want = [ox - 0.5, oy - 0.5];
                assert!(
                    (moved[0] - want[0]).abs() < 1e-4 && (moved[1] - want[1]).abs() < 1e-4,
                    "pixel ({x}, {y}) pass {k}: moved {moved:?}, want {want:?}"
                );
            }
        }
        // One sample: the pixel centres, bit for bit.
        let one = pass_frame(&cam, 0, 1)?;
        for (x, y) in [(0, 0), (159, 119), (80, 60)] {
            assert_eq!(one.ray(x, y).dir, centre.ray(x, y).dir);
        }
        Ok(())
    }
}
