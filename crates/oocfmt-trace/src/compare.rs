//! How far a rendered image is from a reference of the same view: colour RMSE and PSNR, SSIM
//! on luminance, the share of pixels within a tolerance (iWalk's "accuracy") and the depth
//! error. Every measure is finite except the PSNR of identical images, which is +inf on
//! purpose (callers decide how to print it).

use serde::Serialize;

use crate::render::Image;

/// SSIM's window side, in pixels (smaller for images smaller than it).
pub const SSIM_WINDOW: usize = 8;
/// Windows start every this many pixels, so neighbouring windows overlap by half.
pub const SSIM_STRIDE: usize = 4;

/// The images to compare differ in size, or one's buffers do not hold width × height pixels.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error("images of different sizes: {a_width}x{a_height} and {b_width}x{b_height}")]
pub struct SizeMismatch {
    /// The reference image's width, in pixels.
    pub a_width: u32,
    /// The reference image's height, in pixels.
    pub a_height: u32,
    /// The tested image's width, in pixels.
    pub b_width: u32,
    /// The tested image's height, in pixels.
    pub b_height: u32,
}

/// How far the hit distances of an image are from the reference's, pixel by pixel; a depth
/// is a hit when finite.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct DepthError {
    /// Pixels that hit in one image and miss in the other.
    pub hit_miss_differ: u64,
    /// Pixels that hit in both.
    pub both_hit: u64,
    /// Of the pixels that hit in both, |d - d_ref| / d_ref: the median (0 when none did).
    pub median_relative: f64,
    /// Of the pixels that hit in both, the largest |d - d_ref| / d_ref (0 when none did). A
    /// reference depth of 0 counts with the absolute error.
    pub max_relative: f64,
}

/// Every measure of how far an image (or a sequence of frames) is from its reference.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct ImageError {
    /// Root mean square difference over all channels, in levels of 255.
    pub rmse: f64,
    /// 20 log10(255 / rmse) in dB; +inf for identical images, written as `null` in JSON
    /// (which has no infinity).
    #[serde(serialize_with = "finite_or_null")]
    pub psnr_db: f64,
    /// Structural similarity on luma ([`ssim`]): 1 for identical images, at most 1; the mean
    /// of the frames' for a sequence.
    pub ssim: f64,
    /// The tolerance of `within_tolerance`, in levels of 255.
    pub tolerance: u8,
    /// Share of pixels whose three channels all differ by at most `tolerance`.
    pub within_tolerance: f64,
    /// The hit distances' error.
    pub depth: DepthError,
}

/// A non-finite number as JSON `null`.
fn finite_or_null<S: serde::Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    if v.is_finite() {
        s.serialize_f64(*v)
    } else {
        s.serialize_none()
    }
}

/// Compares `test` with `reference`.
pub fn compare(reference: &Image, test: &Image, tolerance: u8) -> Result<ImageError, SizeMismatch> {
    let mut acc = Accumulator::new(tolerance);
    acc.add(reference, test)?;
    Ok(acc.finish())
}

/// The error of a sequence of frames (a walkthrough) against their references, as if they
/// were one image: the pixel measures over all pixels, SSIM the mean of the frames'.
#[derive(Clone, Debug, Default)]
pub struct Accumulator {
    tolerance: u8,
    square_sum: u64,
    channels: u64,
    within: u64,
    pixels: u64,
    ssim_sum: f64,
    frames: u64,
    differ: u64,
    relative: Vec<f64>,
}

impl Accumulator {
    /// An empty accumulator counting pixels within `tolerance` levels of 255 per channel.
    pub fn new(tolerance: u8) -> Accumulator {
        Accumulator {
            tolerance,
            ..Accumulator::default()
        }
    }

    /// Adds a frame and its reference, which must be of the same size.
    pub fn add(&mut self, reference: &Image, test: &Image) -> Result<(), SizeMismatch> {
        let consistent = |i: &Image| {
            let n = i.width as usize * i.height as usize;
            i.rgb.len() == 3 * n && i.depth.len() == n
        };
        if reference.width != test.width
            || reference.height != test.height
            || !consistent(reference)
            || !consistent(test)
        {
            return Err(SizeMismatch {
                a_width: reference.width,
                a_height: reference.height,
                b_width: test.width,
                b_height: test.height,
            });
        }
        let (sq, n) = square_sum(&reference.rgb, &test.rgb);
        self.square_sum += sq;
        self.channels += n;
        let (w, p) = within_count(&reference.rgb, &test.rgb, self.tolerance);
        self.within += w;
        self.pixels += p;
        self.ssim_sum += ssim(
            &reference.rgb,
            &test.rgb,
            reference.width as usize,
            reference.height as usize,
        );
        self.frames += 1;
        self.differ += depth_parts(&reference.depth, &test.depth, &mut self.relative);
        Ok(())
    }

    /// The error over every frame added; with none, that of identical images (RMSE 0, SSIM 1).
    pub fn finish(mut self) -> ImageError {
        let rmse = if self.channels == 0 {
            0.0
        } else {
            (self.square_sum as f64 / self.channels as f64).sqrt()
        };
        self.relative.sort_by(f64::total_cmp);
        ImageError {
            rmse,
            psnr_db: psnr(rmse),
            ssim: if self.frames == 0 {
                1.0
            } else {
                self.ssim_sum / self.frames as f64
            },
            tolerance: self.tolerance,
            within_tolerance: if self.pixels == 0 {
                1.0
            } else {
                self.within as f64 / self.pixels as f64
            },
            depth: DepthError {
                hit_miss_differ: self.differ,
                both_hit: self.relative.len() as u64,
                median_relative: median_sorted(&self.relative),
                max_relative: self.relative.last().copied().unwrap_or(0.0),
            },
        }
    }
}

/// Sum of squared differences of two byte images, and the number of bytes compared.
fn square_sum(a: &[u8], b: &[u8]) -> (u64, u64) {
    a.iter().zip(b).fold((0u64, 0u64), |(s, n), (x, y)| {
        let d = u64::from(x.abs_diff(*y));
        (s + d * d, n + 1)
    })
}

/// RGB pixels whose channels all differ by at most `tolerance`, and the pixels compared.
fn within_count(a: &[u8], b: &[u8], tolerance: u8) -> (u64, u64) {
    a.chunks_exact(3)
        .zip(b.chunks_exact(3))
        .fold((0u64, 0u64), |(w, n), (pa, pb)| {
            let ok = pa.iter().zip(pb).all(|(x, y)| x.abs_diff(*y) <= tolerance);
            (w + u64::from(ok), n + 1)
        })
}

/// Pushes the relative depth error of each pixel both hit onto `relative` and returns the
/// number of hit/miss disagreements; a depth is a hit when finite. A reference depth of 0 (a
/// hit at the eye) counts with an absolute error.
fn depth_parts(reference: &[f32], test: &[f32], relative: &mut Vec<f64>) -> u64 {
    let mut differ = 0u64;
    for (r, t) in reference.iter().zip(test) {
        match (r.is_finite(), t.is_finite()) {
            (true, true) => {
                let d = (f64::from(*t) - f64::from(*r)).abs();
                let scale = f64::from(r.abs());
                relative.push(if scale > 0.0 { d / scale } else { d });
            }
            (false, false) => {}
            _ => differ += 1,
        }
    }
    differ
}

/// Root mean square difference of two equally long byte images, in levels; 0 for empty ones.
pub fn rmse(a: &[u8], b: &[u8]) -> f64 {
    match square_sum(a, b) {
        (_, 0) => 0.0,
        (sq, n) => (sq as f64 / n as f64).sqrt(),
    }
}

/// Peak signal-to-noise ratio of 8-bit images with this RMSE, in dB: +inf at 0.
pub fn psnr(rmse: f64) -> f64 {
    if rmse > 0.0 {
        20.0 * (255.0 / rmse).log10()
    } else {
        f64::INFINITY
    }
}

/// Share of RGB pixels whose channels all differ by at most `tolerance`; 1 for empty images.
pub fn within_tolerance(a: &[u8], b: &[u8], tolerance: u8) -> f64 {
    match within_count(a, b, tolerance) {
        (_, 0) => 1.0,
        (w, n) => w as f64 / n as f64,
    }
}

/// BT.601 luma of RGB8 pixels, in levels of 255.
fn luma(rgb: &[u8]) -> Vec<f64> {
    rgb.chunks_exact(3)
        .map(|p| 0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2]))
        .collect()
}

/// Window starts along an axis of `len` pixels for windows of `win`: every [`SSIM_STRIDE`],
/// and the last window flush with the edge so every pixel is covered.
fn starts(len: usize, win: usize) -> Vec<usize> {
    let last = len - win;
    let mut s: Vec<usize> = (0..=last).step_by(SSIM_STRIDE).collect();
    if s.last() != Some(&last) {
        s.push(last);
    }
    s
}

/// The structural similarity index (Wang, Bovik, Sheikh and Simoncelli 2004) of two RGB8
/// images of `width` × `height`, on their luma: the mean over square windows of side
/// [`SSIM_WINDOW`] (uniform weights, every [`SSIM_STRIDE`] pixels) of
/// (2 μa μb + C1)(2 σab + C2) / ((μa² + μb² + C1)(σa² + σb² + C2)),
/// C1 = (0.01 · 255)², C2 = (0.03 · 255)². 1 for identical images, at most 1; 1 for an
/// empty image, and the buffers must hold `width` × `height` pixels (else 0).
pub fn ssim(a: &[u8], b: &[u8], width: usize, height: usize) -> f64 {
    let n = width * height;
    if n == 0 {
        return 1.0;
    }
    if a.len() != 3 * n || b.len() != 3 * n {
        return 0.0;
    }
    let (la, lb) = (luma(a), luma(b));
    let (wx, wy) = (SSIM_WINDOW.min(width), SSIM_WINDOW.min(height));
    let c1 = (0.01f64 * 255.0).powi(2);
    let c2 = (0.03f64 * 255.0).powi(2);
    let count = (wx * wy) as f64;
    let (mut total, mut windows) = (0.0, 0u64);
    for &y0 in &starts(height, wy) {
        for &x0 in &starts(width, wx) {
            let rows = || {
                (y0..y0 + wy).map(|y| {
                    let r = y * width + x0..y * width + x0 + wx;
                    (&la[r.clone()], &lb[r])
                })
            };
            let (mut sa, mut sb) = (0.0, 0.0);
            for (ra, rb) in rows() {
                sa += ra.iter().sum::<f64>();
                sb += rb.iter().sum::<f64>();
            }
            let (ma, mb) = (sa / count, sb / count);
            // Centred sums, a second pass: exact for identical windows (SSIM exactly 1) and
            // never a negative variance.
            let (mut va, mut vb, mut cov) = (0.0, 0.0, 0.0);
            for (ra, rb) in rows() {
                for (pa, pb) in ra.iter().zip(rb) {
                    let (da, db) = (pa - ma, pb - mb);
                    va += da * da;
                    vb += db * db;
                    cov += da * db;
                }
            }
            let (va, vb, cov) = (va / count, vb / count, cov / count);
            total += ((2.0 * ma * mb + c1) * (2.0 * cov + c2))
                / ((ma * ma + mb * mb + c1) * (va + vb + c2));
            windows += 1;
        }
    }
    total / windows as f64
}

/// Hit/miss disagreements and the relative depth error of the pixels both hit (see
/// [`Accumulator`]).
pub fn depth_error(reference: &[f32], test: &[f32]) -> DepthError {
    let mut relative = Vec::new();
    let differ = depth_parts(reference, test, &mut relative);
    relative.sort_by(f64::total_cmp);
    DepthError {
        hit_miss_differ: differ,
        both_hit: relative.len() as u64,
        median_relative: median_sorted(&relative),
        max_relative: relative.last().copied().unwrap_or(0.0),
    }
}

/// The median of sorted values (the mean of the middle two for an even count); 0 for none.
pub fn median_sorted(v: &[f64]) -> f64 {
    let n = v.len();
    match (v.get(n / 2), n.checked_sub(1).and_then(|m| v.get(m / 2))) {
        (Some(hi), Some(lo)) => 0.5 * (hi + lo),
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn grey(v: &[u8]) -> Vec<u8> {
        v.iter().flat_map(|&g| [g, g, g]).collect()
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn identical_images_have_no_error() {
        let rgb: Vec<u8> = (0..3 * 20 * 13).map(|i| (i * 37 % 256) as u8).collect();
        let depth: Vec<f32> = (0..20 * 13)
            .map(|i| if i % 5 == 0 { f32::INFINITY } else { i as f32 })
            .collect();
        let img = Image {
            width: 20,
            height: 13,
            rgb,
            depth,
        };
        let e = compare(&img, &img, 0).unwrap();
        assert_eq!(e.rmse, 0.0);
        assert_eq!(e.psnr_db, f64::INFINITY);
        assert_eq!(e.ssim, 1.0);
        assert_eq!(e.within_tolerance, 1.0);
        assert_eq!(e.depth.hit_miss_differ, 0);
        assert_eq!(e.depth.both_hit, 20 * 13 - 52);
        assert_eq!(e.depth.max_relative, 0.0);
    }

    #[test]
    fn rmse_psnr_and_tolerance_by_hand() {
        // Differences 0, 3, 4 and 12 on four channels: mean square (0+9+16+144)/4 = 42.25.
        assert!(close(rmse(&[10, 10, 10, 10], &[10, 13, 6, 22]), 6.5));
        assert!(close(psnr(6.5), 20.0 * (255.0f64 / 6.5).log10()));
        assert!(close(psnr(255.0), 0.0));
        // Pixel 1 differs by at most 3, pixel 2 by 12 in one channel.
        let (a, b) = ([0, 0, 0, 50, 50, 50], [3, 0, 1, 50, 62, 50]);
        assert_eq!(within_tolerance(&a, &b, 8), 0.5);
        assert_eq!(within_tolerance(&a, &b, 12), 1.0);
        assert_eq!(within_tolerance(&a, &b, 2), 0.0);
    }

    #[test]
    fn ssim_of_flat_windows_by_hand() {
        // One 8x8 window, flat 100 against flat 110: no variance, so SSIM is the luminance term
        // (2·100·110 + C1) / (100² + 110² + C1), C1 = 6.5025.
        let a = grey(&[100; 64]);
        let b = grey(&[110; 64]);
        let want = (22000.0 + 6.5025) / (10000.0 + 12100.0 + 6.5025);
        assert!(close(ssim(&a, &b, 8, 8), want), "{}", ssim(&a, &b, 8, 8));
    }

    #[test]
    fn ssim_of_inverted_halves_by_hand() {
        // One 2x2 window: a = [0, 200; 0, 200], b = [200, 0; 200, 0]. Both have mean 100 and
        // variance 10000; the covariance is -10000. SSIM = (2·100·100 + C1)(-20000 + C2) /
        // ((20000 + C1)(20000 + C2)), C2 = 58.5225: the luminance term is 1.
        let a = grey(&[0, 200, 0, 200]);
        let b = grey(&[200, 0, 200, 0]);
        let c2 = 58.5225;
        let want = (-20000.0 + c2) / (20000.0 + c2);
        assert!(close(ssim(&a, &b, 2, 2), want), "{}", ssim(&a, &b, 2, 2));
        assert!(ssim(&a, &b, 2, 2) < -0.99);
    }

    #[test]
    fn ssim_averages_overlapping_windows() {
        // 12 wide: windows start at x = 0 and 4 (the last flush with the edge). A change in
        // column 0 falls in the first window only.
        let a = grey(&[90; 12 * 8]);
        let mut b = a.clone();
        for y in 0..8 {
            b[3 * (y * 12)..3 * (y * 12) + 3].copy_from_slice(&[170, 170, 170]);
        }
        let s = ssim(&a, &b, 12, 8);
        // The first window: a flat, b with 8 of 64 pixels at 170: mean 100, variance 700.
        let c1 = 6.5025;
        let c2 = 58.5225;
        let first = (2.0 * 90.0 * 100.0 + c1) * c2 / ((8100.0 + 10000.0 + c1) * (700.0 + c2));
        assert!(close(s, (first + 1.0) / 2.0), "{s}");
    }

    #[test]
    fn depth_error_counts_disagreements_and_relative_error() {
        let inf = f32::INFINITY;
        let r = [10.0, 10.0, 20.0, inf, inf, 4.0];
        let t = [10.0, 11.0, 19.0, inf, 3.0, inf];
        let d = depth_error(&r, &t);
        assert_eq!(d.hit_miss_differ, 2);
        assert_eq!(d.both_hit, 3);
        // Relative errors 0, 0.1, 0.05: median 0.05, max 0.1.
        assert!(close(d.median_relative, 0.05));
        assert!((d.max_relative - 0.1).abs() < 1e-6);
        assert_eq!(median_sorted(&[]), 0.0);
        assert_eq!(median_sorted(&[1.0, 2.0]), 1.5);
    }

    #[test]
    fn frames_accumulate_as_one_image() {
        let frame = |v: u8, d: f32| Image {
            width: 2,
            height: 1,
            rgb: vec![v; 6],
            depth: vec![d, f32::INFINITY],
        };
        let mut acc = Accumulator::new(8);
        // Frame 1 identical; frame 2 off by 10 everywhere, depths 10 % further.
        acc.add(&frame(50, 10.0), &frame(50, 10.0)).unwrap();
        acc.add(&frame(50, 10.0), &frame(60, 11.0)).unwrap();
        let e = acc.finish();
        // Mean square (6·0 + 6·100) / 12 = 50.
        assert!(close(e.rmse, 50f64.sqrt()));
        assert_eq!(e.within_tolerance, 0.5);
        assert_eq!(e.depth.both_hit, 2);
        assert_eq!(e.depth.median_relative, 0.05);
        assert!((e.depth.max_relative - 0.1).abs() < 1e-6);
        // SSIM is the mean of the frames': 1 and that of flat 50 against flat 60.
        let flat = (2.0 * 50.0 * 60.0 + 6.5025) / (2500.0 + 3600.0 + 6.5025);
        assert!(close(e.ssim, (1.0 + flat) / 2.0), "{}", e.ssim);
    }

    #[test]
    fn infinite_psnr_is_null_in_json() {
        let img = Image {
            width: 1,
            height: 1,
            rgb: vec![1, 2, 3],
            depth: vec![1.0],
        };
        let json = serde_json::to_value(compare(&img, &img, 8).unwrap()).unwrap();
        assert!(json["psnr_db"].is_null());
        assert_eq!(json["rmse"], 0.0);
    }

    #[test]
    fn different_sizes_are_an_error() {
        let a = Image {
            width: 2,
            height: 1,
            rgb: vec![0; 6],
            depth: vec![0.0; 2],
        };
        let b = Image {
            width: 1,
            height: 2,
            rgb: vec![0; 6],
            depth: vec![0.0; 2],
        };
        assert!(compare(&a, &b, 8).is_err());
    }
}
