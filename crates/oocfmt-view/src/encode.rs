//! Frames as image files for the wire: JPEG while the view is still changing (small and quick
//! to encode; its quality adapts to whether frames are being dropped), lossless PNG for the
//! last frame of a still view, the one a person looks at and saves.

use std::time::Instant;

use oocfmt_trace::live::LiveFrame;
use oocfmt_trace::render::Image;

/// The JPEG quality of frames while the view refines (sharpen, settle, accumulate).
pub const REFINE_QUALITY: u8 = 92;

/// The JPEG quality moving frames start at, and its bounds.
pub const MOVING_QUALITY: u8 = 80;
const MOVING_MIN: u8 = 40;
const MOVING_MAX: u8 = 85;

/// An encoded frame.
pub struct Encoded {
    /// The image file.
    pub bytes: Vec<u8>,
    /// `jpeg` or `png`.
    pub format: &'static str,
    /// The JPEG quality (none for PNG).
    pub quality: Option<u8>,
    /// Milliseconds spent encoding.
    pub ms: f64,
}

/// The quality of a view's moving frames: lowered while frames are dropped (the encoder or
/// the connection cannot keep up with the renderer), raised slowly while none are.
#[derive(Clone, Copy, Debug)]
pub struct MovingQuality(u8);

impl MovingQuality {
    /// The starting quality.
    pub fn new() -> MovingQuality {
        MovingQuality(MOVING_QUALITY)
    }

    /// The quality for the next frame, `dropped` frames having been replaced before it.
    pub fn next(&mut self, dropped: u64) -> u8 {
        self.0 = if dropped > 0 {
            self.0.saturating_sub(10).max(MOVING_MIN)
        } else {
            (self.0 + 1).min(MOVING_MAX)
        };
        self.0
    }
}

impl Default for MovingQuality {
    fn default() -> Self {
        MovingQuality::new()
    }
}

/// `frame` encoded for the page: PNG when it is the last of its schedule, else JPEG (at the
/// moving quality while moving).
pub fn frame(
    frame: &LiveFrame,
    moving: &mut MovingQuality,
    dropped: u64,
) -> Result<Encoded, String> {
    let f = &frame.figures;
    if f.last {
        return png(&frame.image);
    }
    let q = if f.stage == "moving" {
        moving.next(dropped)
    } else {
        REFINE_QUALITY
    };
    jpeg(&frame.image, q)
}

/// `image` as a baseline JPEG of quality `q` (1 ..= 100), 4:2:0.
pub fn jpeg(image: &Image, q: u8) -> Result<Encoded, String> {
    let start = Instant::now();
    let (w, h) = dims(image)?;
    let mut bytes = Vec::new();
    jpeg_encoder::Encoder::new(&mut bytes, q.clamp(1, 100))
        .encode(&image.rgb, w, h, jpeg_encoder::ColorType::Rgb)
        .map_err(|e| format!("cannot encode the {w}x{h} frame as JPEG: {e}"))?;
    Ok(Encoded {
        bytes,
        format: "jpeg",
        quality: Some(q),
        ms: start.elapsed().as_secs_f64() * 1e3,
    })
}

/// `image` as an 8-bit RGB PNG, compressed for speed (the Sub filter and fast deflate: a
/// fraction of the default's time for a few per cent more bytes on rendered frames).
pub fn png(image: &Image) -> Result<Encoded, String> {
    let start = Instant::now();
    let mut bytes = Vec::new();
    let err = |e: png::EncodingError| {
        format!(
            "cannot encode the {}x{} frame as PNG: {e}",
            image.width, image.height
        )
    };
    {
        let mut enc = png::Encoder::new(&mut bytes, image.width, image.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Fast);
        enc.set_filter(png::FilterType::Sub);
        let mut w = enc.write_header().map_err(err)?;
        w.write_image_data(&image.rgb).map_err(err)?;
        w.finish().map_err(err)?;
    }
    Ok(Encoded {
        bytes,
        format: "png",
        quality: None,
        ms: start.elapsed().as_secs_f64() * 1e3,
    })
}

fn dims(image: &Image) -> Result<(u16, u16), String> {
    match (u16::try_from(image.width), u16::try_from(image.height)) {
        (Ok(w), Ok(h)) => Ok((w, h)),
        _ => Err(format!(
            "{}x{}: too large for a JPEG",
            image.width, image.height
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: u32, h: u32) -> Image {
        let rgb = (0..w * h)
            .flat_map(|i| {
                let (x, y) = (i % w, i / w);
                [(x * 255 / w) as u8, (y * 255 / h) as u8, 128]
            })
            .collect();
        Image {
            width: w,
            height: h,
            rgb,
            depth: vec![1.0; (w * h) as usize],
            model: vec![true; (w * h) as usize],
        }
    }

    #[test]
    fn png_is_lossless_and_jpeg_is_a_jpeg() -> Result<(), String> {
        let img = gradient(37, 21);
        let p = png(&img)?;
        let dec = png::Decoder::new(std::io::Cursor::new(&p.bytes));
        let mut reader = dec.read_info().map_err(|e| e.to_string())?;
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).map_err(|e| e.to_string())?;
        assert_eq!((info.width, info.height), (37, 21));
        assert!(buf[..info.buffer_size()] == img.rgb[..]);
        let j = jpeg(&img, 80)?;
        assert_eq!(
            j.bytes.get(..3),
            Some(&[0xFF, 0xD8, 0xFF][..]),
            "a JPEG starts with SOI"
        );
        assert_eq!((j.format, j.quality), ("jpeg", Some(80)));
        Ok(())
    }

    #[test]
    fn moving_quality_drops_with_dropped_frames_and_recovers() {
        let mut q = MovingQuality::new();
        assert_eq!(q.next(0), MOVING_QUALITY + 1);
        assert_eq!(q.next(2), MOVING_QUALITY - 9);
        for _ in 0..10 {
            q.next(1);
        }
        assert_eq!(q.next(1), MOVING_MIN);
        for _ in 0..100 {
            q.next(0);
        }
        assert_eq!(q.next(0), MOVING_MAX);
    }
}
