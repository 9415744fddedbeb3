//! How far a rendered image is from a reference of the same view, on two regions: the whole
//! image and the model's pixels (those that show the model in either image, [`Image::model`]).
//! Per region: colour RMSE and PSNR, SSIM on luma, the share of pixels within a tolerance
//! (iWalk's "accuracy"), the mean signed luma bias and the pixel count; and, once, the
//! silhouette and depth error. The background, where both images miss, matches exactly and
//! would dilute every whole-image figure; the model's figures are what the picture gets wrong.
//! Every measure is finite except the PSNR of identical regions, which is +inf on purpose
//! (callers decide how to print it).

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
    /// Pixels that hit in one image and miss in the other (the silhouette error).
    pub hit_miss_differ: u64,
    /// Pixels that hit in both.
    pub both_hit: u64,
    /// Of the pixels that hit in both, |d - d_ref| / d_ref: the median (0 when none did).
    pub median_relative: f64,
    /// Of the pixels that hit in both, the largest |d - d_ref| / d_ref (0 when none did). A
    /// reference depth of 0 counts with the absolute error.
    pub max_relative: f64,
}

/// The colour error over one region of an image (or of a sequence of frames). A region of no
/// pixels has the figures of identical images: RMSE 0, PSNR +inf, SSIM 1, all within
/// tolerance, bias 0, so a view that misses the model still has defined figures.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct RegionError {
    /// Pixels in the region.
    pub pixels: u64,
    /// Root mean square difference over the region's channels, in levels of 255.
    pub rmse: f64,
    /// 20 log10(255 / rmse) in dB; +inf for identical regions, written as `null` in JSON
    /// (which has no infinity).
    #[serde(serialize_with = "finite_or_null")]
    pub psnr_db: f64,
    /// Structural similarity on luma ([`ssim`]): the mean over the SSIM windows that hold at
    /// least one of the region's pixels (every window for the whole image); at most 1.
    pub ssim: f64,
    /// Share of the region's pixels whose three channels all differ by at most the tolerance.
    pub within_tolerance: f64,
    /// Mean of the test's luma minus the reference's ([`luma`]), in levels of 255: positive
    /// where the test is too bright.
    pub bias: f64,
}

impl RegionError {
    /// The figures of a region of no pixels (see the type).
    pub const EMPTY: RegionError = RegionError {
        pixels: 0,
        rmse: 0.0,
        psnr_db: f64::INFINITY,
        ssim: 1.0,
        within_tolerance: 1.0,
        bias: 0.0,
    };
}

/// Every measure of how far an image (or a sequence of frames) is from its reference.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct ImageError {
    /// The tolerance of `within_tolerance`, in levels of 255.
    pub tolerance: u8,
    /// Over the model's pixels: those either image marks in [`Image::model`].
    pub model: RegionError,
    /// Over every pixel, background included.
    pub whole: RegionError,
    /// The hit distances' error, and the silhouette's.
    pub depth: DepthError,
}

/// The colour error of an image on both regions, without the depth error: what can be
/// measured of a frame kept only as its colours and model mask.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Regions {
    /// The tolerance of `within_tolerance`, in levels of 255.
    pub tolerance: u8,
    /// Over the model's pixels (see [`ImageError::model`]).
    pub model: RegionError,
    /// Over every pixel.
    pub whole: RegionError,
}

/// A non-finite number as JSON `null`.
fn finite_or_null<S: serde::Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    if v.is_finite() {
        s.serialize_f64(*v)
    } else {
        s.serialize_none()
    }
}

/// What the colour measures need of an image: its size, its sRGB bytes and which of its
/// pixels show the model.
#[derive(Clone, Copy, Debug)]
pub struct Pixels<'a> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGB8, rows top to bottom: 3 × width × height bytes.
    pub rgb: &'a [u8],
    /// Whether each pixel shows the model, as [`Image::model`]: width × height entries.
    pub model: &'a [bool],
}

impl<'a> From<&'a Image> for Pixels<'a> {
    fn from(i: &'a Image) -> Pixels<'a> {
        Pixels {
            width: i.width,
            height: i.height,
            rgb: &i.rgb,
            model: &i.model,
        }
    }
}

/// Compares `test` with `reference`.
pub fn compare(reference: &Image, test: &Image, tolerance: u8) -> Result<ImageError, SizeMismatch> {
    let mut acc = Accumulator::new(tolerance);
    acc.add(reference, test)?;
    Ok(acc.finish())
}

/// The colour error of `test` against `reference` on both regions.
pub fn compare_pixels(
    reference: Pixels<'_>,
    test: Pixels<'_>,
    tolerance: u8,
) -> Result<Regions, SizeMismatch> {
    let mut acc = Accumulator::new(tolerance);
    acc.add_pixels(reference, test)?;
    let e = acc.finish();
    Ok(Regions {
        tolerance,
        model: e.model,
        whole: e.whole,
    })
}

/// Sums of one region over the frames added so far.
#[derive(Clone, Debug, Default)]
struct Sums {
    square_sum: u64,
    channels: u64,
    within: u64,
    pixels: u64,
    luma_difference: f64,
    ssim_sum: f64,
    windows: u64,
}

impl Sums {
    /// Adds a pixel whose channels differ by `d` (test minus reference) and whose luma
    /// differs by `dl`.
    #[inline]
    fn pixel(&mut self, d: [i32; 3], dl: f64, tolerance: u8) {
        for c in d {
            self.square_sum += u64::from(c.unsigned_abs() * c.unsigned_abs());
        }
        self.channels += 3;
        self.within += u64::from(d.iter().all(|c| c.unsigned_abs() <= u32::from(tolerance)));
        self.pixels += 1;
        self.luma_difference += dl;
    }

    fn finish(&self) -> RegionError {
        if self.pixels == 0 {
            return RegionError::EMPTY;
        }
        let rmse = (self.square_sum as f64 / self.channels as f64).sqrt();
        RegionError {
            pixels: self.pixels,
            rmse,
            psnr_db: psnr(rmse),
            ssim: if self.windows == 0 {
                1.0
            } else {
                self.ssim_sum / self.windows as f64
            },
            within_tolerance: self.within as f64 / self.pixels as f64,
            bias: self.luma_difference / self.pixels as f64,
        }
    }
}

/// The error of a sequence of frames (a walkthrough) against their references, as if they
/// were one image: the pixel measures over all the frames' pixels of each region, SSIM the
/// mean over all their windows (for frames of one size, the whole image's is the mean of the
/// frames').
#[derive(Clone, Debug, Default)]
pub struct Accumulator {
    tolerance: u8,
    model: Sums,
    whole: Sums,
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
        let n = reference.width as usize * reference.height as usize;
        if reference.depth.len() != n || test.depth.len() != n {
            return Err(mismatch(reference.into(), test.into()));
        }
        self.add_pixels(reference.into(), test.into())?;
        self.differ += depth_parts(&reference.depth, &test.depth, &mut self.relative);
        Ok(())
    }

    /// Adds the colours of a frame and its reference, which must be of the same size; the
    /// depth error is not touched.
    pub fn add_pixels(
        &mut self,
        reference: Pixels<'_>,
        test: Pixels<'_>,
    ) -> Result<(), SizeMismatch> {
        let consistent = |i: &Pixels<'_>| {
            let n = i.width as usize * i.height as usize;
            i.rgb.len() == 3 * n && i.model.len() == n
        };
        if reference.width != test.width
            || reference.height != test.height
            || !consistent(&reference)
            || !consistent(&test)
        {
            return Err(mismatch(reference, test));
        }
        let model: Vec<bool> = reference
            .model
            .iter()
            .zip(test.model)
            .map(|(a, b)| *a || *b)
            .collect();
        let (lr, lt) = (luma(reference.rgb), luma(test.rgb));
        let pixels = reference.rgb.chunks_exact(3).zip(test.rgb.chunks_exact(3));
        for ((((pr, pt), m), yr), yt) in pixels.zip(&model).zip(&lr).zip(&lt) {
            let d = [0, 1, 2].map(|c| {
                i32::from(pt.get(c).copied().unwrap_or(0))
                    - i32::from(pr.get(c).copied().unwrap_or(0))
            });
            let dl = yt - yr;
            self.whole.pixel(d, dl, self.tolerance);
            if *m {
                self.model.pixel(d, dl, self.tolerance);
            }
        }
        let (w, h) = (reference.width as usize, reference.height as usize);
        ssim_windows(&lr, &lt, w, h, |(x0, y0, wx, wy), s| {
            self.whole.ssim_sum += s;
            self.whole.windows += 1;
            let shows_model = (y0..y0 + wy).any(|y| {
                model
                    .get(y * w + x0..y * w + x0 + wx)
                    .is_some_and(|row| row.contains(&true))
            });
            if shows_model {
                self.model.ssim_sum += s;
                self.model.windows += 1;
            }
        });
        Ok(())
    }

    /// The error over every frame added; with none, that of identical images (RMSE 0, SSIM 1).
    pub fn finish(mut self) -> ImageError {
        self.relative.sort_by(f64::total_cmp);
        ImageError {
            tolerance: self.tolerance,
            model: self.model.finish(),
            whole: self.whole.finish(),
            depth: DepthError {
                hit_miss_differ: self.differ,
                both_hit: self.relative.len() as u64,
                median_relative: median_sorted(&self.relative),
                max_relative: self.relative.last().copied().unwrap_or(0.0),
            },
        }
    }
}

fn mismatch(a: Pixels<'_>, b: Pixels<'_>) -> SizeMismatch {
    SizeMismatch {
        a_width: a.width,
        a_height: a.height,
        b_width: b.width,
        b_height: b.height,
    }
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

/// Pixels that hit in one of two equally long hit masks and miss in the other.
pub fn hit_miss_differ(reference: &[bool], test: &[bool]) -> u64 {
    reference.iter().zip(test).filter(|(a, b)| a != b).count() as u64
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

/// Rec. 709 luma of RGB8 pixels, taken on the sRGB bytes as they are (the primaries sRGB
/// shares with Rec. 709), in levels of 255.
pub fn luma(rgb: &[u8]) -> Vec<f64> {
    rgb.chunks_exact(3)
        .map(|p| {
            let [r, g, b] = [0, 1, 2].map(|c| f64::from(p.get(c).copied().unwrap_or(0)));
            0.2126 * r + 0.7152 * g + 0.0722 * b
        })
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

/// Calls `window((x0, y0, wx, wy), ssim)` for every SSIM window of two luma planes of
/// `width` × `height` (see [`ssim`]); nothing for an empty or inconsistent image.
fn ssim_windows(
    la: &[f64],
    lb: &[f64],
    width: usize,
    height: usize,
    mut window: impl FnMut((usize, usize, usize, usize), f64),
) {
    let n = width * height;
    if n == 0 || la.len() != n || lb.len() != n {
        return;
    }
    let (wx, wy) = (SSIM_WINDOW.min(width), SSIM_WINDOW.min(height));
    let c1 = (0.01f64 * 255.0).powi(2);
    let c2 = (0.03f64 * 255.0).powi(2);
    let count = (wx * wy) as f64;
    for &y0 in &starts(height, wy) {
        for &x0 in &starts(width, wx) {
            let rows = || {
                (y0..y0 + wy).filter_map(|y| {
                    let r = y * width + x0..y * width + x0 + wx;
                    Some((la.get(r.clone())?, lb.get(r)?))
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
            let s = ((2.0 * ma * mb + c1) * (2.0 * cov + c2))
                / ((ma * ma + mb * mb + c1) * (va + vb + c2));
            window((x0, y0, wx, wy), s);
        }
    }
}

/// The structural similarity index (Wang, Bovik, Sheikh and Simoncelli 2004) of two RGB8
/// images of `width` × `height`, on their luma ([`luma`]): the mean over square windows of
/// side [`SSIM_WINDOW`] (uniform weights, every [`SSIM_STRIDE`] pixels) of
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
    let (mut total, mut windows) = (0.0, 0u64);
    ssim_windows(&luma(a), &luma(b), width, height, |_, s| {
        total += s;
        windows += 1;
    });
    total / windows.max(1) as f64
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

    /// A `width` × `height` image of grey `v`, every pixel a hit at depth 1 and none marked
    /// as the model.
    fn flat(width: u32, height: u32, v: u8) -> Image {
        let n = (width * height) as usize;
        Image {
            width,
            height,
            rgb: vec![v; 3 * n],
            depth: vec![1.0; n],
            model: vec![false; n],
        }
    }

    const C1: f64 = 6.5025;
    const C2: f64 = 58.5225;

    #[test]
    fn identical_images_have_no_error() {
        let rgb: Vec<u8> = (0..3 * 20 * 13).map(|i| (i * 37 % 256) as u8).collect();
        let depth: Vec<f32> = (0..20 * 13)
            .map(|i| if i % 5 == 0 { f32::INFINITY } else { i as f32 })
            .collect();
        let model = depth.iter().map(|d| d.is_finite()).collect();
        let img = Image {
            width: 20,
            height: 13,
            rgb,
            depth,
            model,
        };
        let e = compare(&img, &img, 0).unwrap();
        for r in [e.model, e.whole] {
            assert_eq!(r.rmse, 0.0);
            assert_eq!(r.psnr_db, f64::INFINITY);
            assert_eq!(r.ssim, 1.0);
            assert_eq!(r.within_tolerance, 1.0);
            assert_eq!(r.bias, 0.0);
        }
        assert_eq!(e.whole.pixels, 20 * 13);
        assert_eq!(e.model.pixels, 20 * 13 - 52);
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
    fn luma_has_the_rec_709_weights() {
        let l = luma(&[255, 0, 0, 0, 255, 0, 0, 0, 255, 200, 200, 200]);
        assert!(close(l[0], 0.2126 * 255.0));
        assert!(close(l[1], 0.7152 * 255.0));
        assert!(close(l[2], 0.0722 * 255.0));
        assert!(close(l[3], 200.0));
    }

    #[test]
    fn an_offset_on_the_model_pixels_only_is_diluted_by_the_whole_image_exactly() {
        // 16 x 12 grey 100; the test is 104 on a 4 x 3 block at the top left. The reference
        // marks its right half as the model, the test its left half: the model's pixels are
        // the union, the whole block.
        let (w, h) = (16u32, 12u32);
        let reference = {
            let mut r = flat(w, h, 100);
            for y in 0..3 {
                for x in 2..4 {
                    r.model[y * 16 + x] = true;
                }
            }
            r
        };
        let mut test = flat(w, h, 100);
        for y in 0..3 {
            for x in 0..4 {
                test.rgb[3 * (y * 16 + x)..3 * (y * 16 + x) + 3].copy_from_slice(&[104; 3]);
                test.model[y * 16 + x] = x < 2;
            }
        }
        let e = compare(&reference, &test, 3).unwrap();
        let (m, all) = (e.model, e.whole);
        assert_eq!((m.pixels, all.pixels), (12, 192));
        assert!(close(m.rmse, 4.0), "{m:?}");
        assert!(close(m.psnr_db, 20.0 * (255.0f64 / 4.0).log10()));
        assert!(close(m.bias, 4.0), "{m:?}");
        assert_eq!(m.within_tolerance, 0.0);
        // The whole image: the same squared error over 16 times the pixels, RMSE 4 / 4 = 1;
        // the bias 4 · 12 / 192; 180 of 192 pixels exact.
        assert!(close(all.rmse, 1.0), "{all:?}");
        assert!(close(all.bias, 0.25), "{all:?}");
        assert!(close(all.within_tolerance, 180.0 / 192.0));
        // SSIM: windows start at x = 0, 4, 8 and y = 0, 4; only (0, 0) holds the block. In
        // it, the reference is flat 100 and the test has 12 of 64 pixels at 104: mean 100.75,
        // variance (12 · 3.25² + 52 · 0.75²) / 64 = 2.4375, no covariance.
        let block =
            (2.0 * 100.0 * 100.75 + C1) * C2 / ((10000.0 + 100.75f64.powi(2) + C1) * (2.4375 + C2));
        assert!(close(m.ssim, block), "{} against {block}", m.ssim);
        assert!(close(all.ssim, (block + 5.0) / 6.0), "{}", all.ssim);
        // One tolerance level more and every pixel is within it.
        let e4 = compare(&reference, &test, 4).unwrap();
        assert_eq!(
            (e4.model.within_tolerance, e4.whole.within_tolerance),
            (1.0, 1.0)
        );
        assert_eq!(e4.tolerance, 4);
    }

    #[test]
    fn a_darker_test_has_a_negative_bias() {
        let mut reference = flat(2, 1, 0);
        reference.rgb = vec![100, 100, 100, 50, 60, 70];
        reference.model = vec![true, true];
        let mut test = flat(2, 1, 0);
        test.model = vec![true, true];
        // Pixel 0 darker by 6 in red only (within 8), pixel 1 by 20 in green only.
        test.rgb = vec![94, 100, 100, 50, 40, 70];
        let e = compare(&reference, &test, 8).unwrap();
        let want = -(0.2126 * 6.0 + 0.7152 * 20.0) / 2.0;
        assert!(close(e.model.bias, want), "{}", e.model.bias);
        assert!(close(e.whole.bias, want));
        assert_eq!(e.model.within_tolerance, 0.5);
    }

    #[test]
    fn a_view_without_the_model_has_defined_model_figures() {
        // The background differs (say, another colour), but neither image shows the model.
        let reference = flat(8, 8, 20);
        let test = flat(8, 8, 30);
        let e = compare(&reference, &test, 8).unwrap();
        assert_eq!(e.model, RegionError::EMPTY);
        assert_eq!(e.model.pixels, 0);
        assert!(e.model.rmse == 0.0 && e.model.ssim == 1.0 && e.model.bias == 0.0);
        assert_eq!(e.model.within_tolerance, 1.0);
        assert!(close(e.whole.rmse, 10.0) && close(e.whole.bias, 10.0));
        let json = serde_json::to_value(e).unwrap();
        assert!(json["model"]["psnr_db"].is_null());
        assert_eq!(json["model"]["pixels"], 0);
        assert!(json["whole"]["psnr_db"].is_f64());
    }

    #[test]
    fn ssim_of_flat_windows_by_hand() {
        // One 8x8 window, flat 100 against flat 110: no variance, so SSIM is the luminance term
        // (2·100·110 + C1) / (100² + 110² + C1), C1 = 6.5025.
        let a = grey(&[100; 64]);
        let b = grey(&[110; 64]);
        let want = (22000.0 + C1) / (10000.0 + 12100.0 + C1);
        assert!(close(ssim(&a, &b, 8, 8), want), "{}", ssim(&a, &b, 8, 8));
    }

    #[test]
    fn ssim_of_inverted_halves_by_hand() {
        // One 2x2 window: a = [0, 200; 0, 200], b = [200, 0; 200, 0]. Both have mean 100 and
        // variance 10000; the covariance is -10000. SSIM = (2·100·100 + C1)(-20000 + C2) /
        // ((20000 + C1)(20000 + C2)), C2 = 58.5225: the luminance term is 1.
        let a = grey(&[0, 200, 0, 200]);
        let b = grey(&[200, 0, 200, 0]);
        let want = (-20000.0 + C2) / (20000.0 + C2);
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
        let first = (2.0 * 90.0 * 100.0 + C1) * C2 / ((8100.0 + 10000.0 + C1) * (700.0 + C2));
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
        let hits = |v: &[f32]| v.iter().map(|d| d.is_finite()).collect::<Vec<_>>();
        assert_eq!(hit_miss_differ(&hits(&r), &hits(&t)), 2);
    }

    #[test]
    fn frames_accumulate_as_one_image() {
        let frame = |v: u8, d: f32| Image {
            width: 2,
            height: 1,
            rgb: vec![v; 6],
            depth: vec![d, f32::INFINITY],
            model: vec![true, false],
        };
        let mut acc = Accumulator::new(8);
        // Frame 1 identical; frame 2 off by 10 everywhere, depths 10 % further.
        acc.add(&frame(50, 10.0), &frame(50, 10.0)).unwrap();
        acc.add(&frame(50, 10.0), &frame(60, 11.0)).unwrap();
        let e = acc.finish();
        // Mean square (6·0 + 6·100) / 12 = 50 over the whole; on the model's pixel, one of
        // each frame: (3·0 + 3·100) / 6, the same.
        assert!(close(e.whole.rmse, 50f64.sqrt()));
        assert!(close(e.model.rmse, 50f64.sqrt()));
        assert_eq!((e.whole.pixels, e.model.pixels), (4, 2));
        assert_eq!(e.whole.within_tolerance, 0.5);
        assert!(close(e.model.bias, 5.0) && close(e.whole.bias, 5.0));
        assert_eq!(e.depth.both_hit, 2);
        assert_eq!(e.depth.median_relative, 0.05);
        assert!((e.depth.max_relative - 0.1).abs() < 1e-6);
        // SSIM is the mean of the frames' (one window each): 1 and that of flat 50 against
        // flat 60.
        let flat = (2.0 * 50.0 * 60.0 + C1) / (2500.0 + 3600.0 + C1);
        assert!(close(e.whole.ssim, (1.0 + flat) / 2.0), "{}", e.whole.ssim);
        assert!(close(e.model.ssim, (1.0 + flat) / 2.0), "{}", e.model.ssim);
    }

    #[test]
    fn a_frame_without_the_model_adds_no_model_window() {
        // Frame 1 shows the model and differs; frame 2 does not show it and is identical. The
        // model's SSIM is frame 1's alone, the whole image's the mean of both.
        let mut shown = flat(8, 8, 100);
        shown.model = vec![true; 64];
        let mut brighter = flat(8, 8, 110);
        brighter.model = vec![true; 64];
        let empty = flat(8, 8, 100);
        let mut acc = Accumulator::new(8);
        acc.add(&shown, &brighter).unwrap();
        acc.add(&empty, &empty).unwrap();
        let e = acc.finish();
        let one = (22000.0 + C1) / (10000.0 + 12100.0 + C1);
        assert!(close(e.model.ssim, one), "{}", e.model.ssim);
        assert!(close(e.whole.ssim, (one + 1.0) / 2.0));
        assert!(close(e.model.rmse, 10.0));
        assert!(close(e.whole.rmse, 50f64.sqrt()));
    }

    #[test]
    fn pixels_alone_give_the_same_regions() {
        let reference = flat(6, 5, 40);
        let mut test = flat(6, 5, 40);
        test.rgb[0] = 90;
        test.model[0] = true;
        let full = compare(&reference, &test, 8).unwrap();
        let colours = compare_pixels((&reference).into(), (&test).into(), 8).unwrap();
        assert_eq!((colours.model, colours.whole), (full.model, full.whole));
        assert_eq!(colours.model.pixels, 1);
    }

    #[test]
    fn infinite_psnr_is_null_in_json() {
        let img = Image {
            width: 1,
            height: 1,
            rgb: vec![1, 2, 3],
            depth: vec![1.0],
            model: vec![true],
        };
        let json = serde_json::to_value(compare(&img, &img, 8).unwrap()).unwrap();
        assert!(json["model"]["psnr_db"].is_null());
        assert!(json["whole"]["psnr_db"].is_null());
        assert_eq!(json["whole"]["rmse"], 0.0);
    }

    #[test]
    fn different_sizes_are_an_error() {
        let (a, b) = (flat(2, 1, 0), flat(1, 2, 0));
        assert!(compare(&a, &b, 8).is_err());
        let mut short = flat(2, 1, 0);
        short.model.pop();
        assert!(compare(&a, &short, 8).is_err());
        let mut shallow = flat(2, 1, 0);
        shallow.depth.pop();
        assert!(compare(&a, &shallow, 8).is_err());
    }
}
