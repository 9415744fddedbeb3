//! Accumulating a still view into an antialiased image, one pass at a time, so that a new
//! camera never waits behind a many-sample frame: pass k renders the whole image once with the
//! camera turned by a sub-pixel offset ([`jitter`], [`jittered`]), and the passes' colours are
//! averaged in linear RGB.
//!
//! Turning the camera moves every pixel's ray by the offset at the image centre exactly and
//! by slightly less towards the edges (at a 45° field of view, a 4:3 image's corners by about a
//! fifth less): an antialiasing filter a little narrower there, not a shift of the picture.

use std::sync::OnceLock;

use crate::camera::{length, Camera};
use crate::error::TraceError;
use crate::render::Image;
use crate::shade::encode_srgb;

/// The sub-pixel offset (x right, y down, in pixels, each in [-0.5, 0.5)) of accumulation pass
/// `k`: pass 0 is the pixel centres, the others follow the R2 sequence (Roberts 2018), whose
/// first n points cover the pixel evenly for every n, so the average is good at any pass.
pub fn jitter(k: u32) -> [f64; 2] {
    // The plastic number's powers: 1/g and 1/g² are the R2 sequence's steps.
    const G: f64 = 1.324_717_957_244_746;
    let step = [1.0 / G, 1.0 / (G * G)];
    let k = f64::from(k);
    step.map(|a| {
        let v = 0.5 + a * k;
        v - v.floor() - 0.5
    })
}

/// `camera` turned about its eye so that the centre ray passes `offset` pixels (x right, y
/// down) from the image centre; the distance to the look-at point and the up vector are kept.
pub fn jittered(camera: &Camera, offset: [f64; 2]) -> Result<Camera, TraceError> {
    let f = camera.frame()?;
    if offset == [0.0, 0.0] {
        return Ok(*camera);
    }
    let (fwd, right, up) = f.basis();
    let p = f.pixel_angle();
    let d = [0, 1, 2].map(|k| fwd[k] + offset[0] * p * right[k] - offset[1] * p * up[k]);
    let to = [0, 1, 2].map(|k| camera.look_at[k] - camera.eye[k]);
    let scale = length(to) / length(d);
    Ok(Camera {
        look_at: [0, 1, 2].map(|k| camera.eye[k] + d[k] * scale),
        ..*camera
    })
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
    /// The first pass's depths and model pixels (the centre rays').
    depth: Vec<f32>,
    model: Vec<bool>,
}

impl Accumulator {
    /// An average of one pass: `first`, the pixel centres.
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

    #[test]
    fn jitter_starts_at_the_centre_and_stays_inside_the_pixel() {
        assert_eq!(jitter(0), [0.0, 0.0]);
        let mut quadrants = [0u32; 4];
        for k in 1..65 {
            let [x, y] = jitter(k);
            assert!((-0.5..0.5).contains(&x) && (-0.5..0.5).contains(&y));
            quadrants[usize::from(x >= 0.0) + 2 * usize::from(y >= 0.0)] += 1;
        }
        // 64 points spread over the pixel: each quadrant gets about a quarter.
        assert!(
            quadrants.iter().all(|&q| (12..=20).contains(&q)),
            "{quadrants:?}"
        );
    }

    #[test]
    fn a_jittered_camera_moves_the_centre_ray_by_the_offset() -> Result<(), TraceError> {
        let cam = Camera {
            eye: [0.0, 0.0, 5.0],
            look_at: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y: 90.0,
            width: 100,
            height: 100,
        };
        let j = jittered(&cam, [0.5, 0.25])?;
        // The jittered centre ray is the original's ray through (50.5, 50.25).
        let want = cam.frame()?.ray_at(50.5, 50.25).dir;
        let got = j.frame()?.ray_at(50.0, 50.0).dir;
        for k in 0..3 {
            assert!((want[k] - got[k]).abs() < 1e-6, "{want:?} {got:?}");
        }
        assert_eq!(
            jittered(&cam, [0.0, 0.0])?.frame()?.ray(3, 7).dir,
            cam.frame()?.ray(3, 7).dir
        );
        Ok(())
    }
}
