//! The error of walkthrough frames against the true picture (`render --accuracy`): each frame
//! against the same camera at full detail supersampled (PoE 0, blocking cache,
//! `--reference-spp` stratified rays per pixel), on the model's pixels and on the whole image;
//! beside it the aliasing floor, full detail at the frame's own sampling against the same
//! reference, and the share of pixels equal to that full-detail image (iWalk's Figure 7,
//! approximate against conservative). The references are rendered after the walkthrough, so
//! that their time gives the walkthrough's fetchers no head start; the frames are read back
//! from the PNGs the walkthrough wrote (lossless), and of each only its model mask and centre
//! hits are kept in memory, a bit per pixel each.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

use oocfmt_trace::compare::{
    compare_pixels, hit_miss_differ, within_tolerance, Pixels, RegionError,
};
use oocfmt_trace::{render, BlockingCache, Camera, Image, RenderOptions, Scene};

use crate::error::CliError;

/// Rays per pixel of the reference unless `--reference-spp` says otherwise: enough that the
/// reference's own aliasing sits well below a LOD's error.
pub const DEFAULT_REFERENCE_SPP: u32 = 16;
/// The most `--reference-spp` takes: the reference costs that many times a frame's rays.
pub const MAX_REFERENCE_SPP: u32 = 256;

/// The options of the true picture of a view rendered with `opts`: full detail, `spp` rays
/// per pixel, everything else (lighting, background) the same.
pub fn reference_options(opts: &RenderOptions, spp: u32) -> RenderOptions {
    RenderOptions {
        poe: 0.0,
        spp,
        ..*opts
    }
}

/// How far one image is from the reference, as far as colours, model mask and centre hits
/// tell.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Measured {
    /// Over the pixels that show the model in either image.
    pub model: RegionError,
    /// Over every pixel.
    pub whole: RegionError,
    /// Pixels whose centre ray hits in one image and misses in the other.
    pub hit_miss_differ: u64,
}

#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Accuracy {
    /// Share of pixels equal to full detail with the frame's own options (PoE 0, blocking
    /// cache): what the walkthrough would show with every block loaded.
    pub exact: f64,
    /// The tolerance of `within_tolerance`, in levels of 255 per channel.
    pub tolerance: u8,
    /// Rays per pixel of the reference.
    pub reference_spp: u32,
    /// The frame against the reference.
    pub error: Measured,
    /// Full detail with the frame's own options against the reference: the floor that
    /// aliasing sets.
    pub floor: Measured,
}

/// The least memory the references' blocking cache gets: a full-detail view's blocks take
/// several times what an LOD view's do (333 MiB for a view of 10M triangles), and a reference
/// cache that thrashes only costs time, never accuracy.
pub const MIN_REFERENCE_BUDGET: usize = 1 << 30;

/// One bit per pixel.
#[derive(Clone, Debug)]
struct Bits {
    words: Vec<u64>,
    len: usize,
}

impl Bits {
    fn of(v: impl ExactSizeIterator<Item = bool>) -> Bits {
        let len = v.len();
        let mut words = vec![0u64; len.div_ceil(64)];
        for (i, b) in v.enumerate() {
            if let (true, Some(w)) = (b, words.get_mut(i / 64)) {
                *w |= 1 << (i % 64);
            }
        }
        Bits { words, len }
    }

    fn to_vec(&self) -> Vec<bool> {
        (0..self.len)
            .map(|i| {
                self.words
                    .get(i / 64)
                    .is_some_and(|w| w & (1 << (i % 64)) != 0)
            })
            .collect()
    }
}

/// What `--accuracy` keeps of a walkthrough frame besides its PNG: which pixels show the
/// model and which centre rays hit.
#[derive(Clone, Debug)]
pub struct Kept {
    file: PathBuf,
    model: Bits,
    hit: Bits,
}

impl Kept {
    /// Keeps what the PNG written to `file` does not hold of `image`.
    pub fn new(image: &Image, file: &Path) -> Kept {
        Kept {
            file: file.to_path_buf(),
            model: Bits::of(image.model.iter().copied()),
            hit: Bits::of(image.depth.iter().map(|d| d.is_finite())),
        }
    }
}

/// What to measure against: the reference's rays per pixel and the tolerance.
#[derive(Clone, Copy, Debug)]
pub struct Against {
    pub reference_spp: u32,
    pub tolerance: u8,
}

/// Renders, for each camera, the reference ([`reference_options`] of `opts`) and full detail
/// with `opts` (the floor) through one blocking cache of `budget` bytes, at least
/// [`MIN_REFERENCE_BUDGET`], and measures the frame kept in `frames[i]` against them.
pub fn measure(
    scene: &Arc<Scene>,
    cameras: &[Camera],
    frames: &[Kept],
    opts: &RenderOptions,
    budget: usize,
    against: Against,
) -> Result<Vec<Accuracy>, CliError> {
    let cache = BlockingCache::new(Arc::clone(scene), budget.max(MIN_REFERENCE_BUDGET));
    let reference_opts = reference_options(opts, against.reference_spp);
    let full_opts = RenderOptions { poe: 0.0, ..*opts };
    cameras
        .iter()
        .zip(frames)
        .map(|(camera, kept)| {
            let (reference, _) = render(scene, &cache, camera, &reference_opts)?;
            let (full, _) = render(scene, &cache, camera, &full_opts)?;
            let (w, h, rgb) = read_rgb8(&kept.file)?;
            let model = kept.model.to_vec();
            if (w, h) != (reference.width, reference.height)
                || model.len() != w as usize * h as usize
            {
                return Err(CliError::Io {
                    path: kept.file.display().to_string(),
                    source: std::io::Error::other(format!(
                        "{w}x{h}, where the reference is {}x{}",
                        reference.width, reference.height
                    )),
                });
            }
            let hits = |i: &Image| i.depth.iter().map(|d| d.is_finite()).collect::<Vec<_>>();
            let reference_hits = hits(&reference);
            let test = Pixels {
                width: w,
                height: h,
                rgb: &rgb,
                model: &model,
            };
            let e = compare_pixels((&reference).into(), test, against.tolerance)?;
            let f = compare_pixels((&reference).into(), (&full).into(), against.tolerance)?;
            Ok(Accuracy {
                exact: within_tolerance(&full.rgb, &rgb, 0),
                tolerance: against.tolerance,
                reference_spp: against.reference_spp,
                error: Measured {
                    model: e.model,
                    whole: e.whole,
                    hit_miss_differ: hit_miss_differ(&reference_hits, &kept.hit.to_vec()),
                },
                floor: Measured {
                    model: f.model,
                    whole: f.whole,
                    hit_miss_differ: hit_miss_differ(&reference_hits, &hits(&full)),
                },
            })
        })
        .collect()
}

/// Reads back an 8-bit RGB PNG as written by `oocfmt render`.
fn read_rgb8(path: &Path) -> Result<(u32, u32, Vec<u8>), CliError> {
    let io = |e: std::io::Error| CliError::Io {
        path: path.display().to_string(),
        source: e,
    };
    let bad = |e: png::DecodingError| io(std::io::Error::other(e.to_string()));
    let file = File::open(path).map_err(io)?;
    let mut reader = png::Decoder::new(BufReader::new(file))
        .read_info()
        .map_err(bad)?;
    let info = reader.info();
    let (w, h) = (info.width, info.height);
    if info.color_type != png::ColorType::Rgb || info.bit_depth != png::BitDepth::Eight {
        return Err(io(std::io::Error::other(
            "expected an 8-bit RGB PNG as render writes",
        )));
    }
    let mut buf = vec![0; reader.output_buffer_size()];
    let frame = reader.next_frame(&mut buf).map_err(bad)?;
    buf.truncate(frame.buffer_size());
    Ok((w, h, buf))
}

/// A PSNR for people: `inf` for identical images.
pub fn db(psnr: f64) -> String {
    if psnr.is_finite() {
        format!("{psnr:.1}")
    } else {
        "inf".to_string()
    }
}

/// A region's figures on one line: "RMSE 9.20, PSNR 28.8 dB, SSIM 0.9120, 81.0 % within 8,
/// bias -0.80".
pub fn region_line(r: &RegionError, tolerance: u8) -> String {
    format!(
        "RMSE {:.2}, PSNR {} dB, SSIM {:.4}, {:.1} % within {tolerance}, bias {:+.2}",
        r.rmse,
        db(r.psnr_db),
        r.ssim,
        100.0 * r.within_tolerance,
        r.bias
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_keep_every_pixel() {
        let v: Vec<bool> = (0..130).map(|i| i % 3 == 0 || i == 129).collect();
        let b = Bits::of(v.iter().copied());
        assert_eq!(b.words.len(), 3);
        assert_eq!(b.to_vec(), v);
        assert!(Bits::of(std::iter::empty()).to_vec().is_empty());
    }
}
