//! The contact sheet: the reference, the aliasing floor and every measurement's image side by
//! side at full size, each under a label with its PoE, frame time and RMSE on the model's
//! pixels, and over a crop of one fixed region at the model's centre zoomed 4× (nearest
//! neighbour), so that a LOD's shading and aliasing can be told apart by eye; one row per
//! cache. The region is outlined on the reference.

use std::path::Path;

use oocfmt_trace::Image;

use super::{text, Shot};
use crate::error::CliError;

const GAP: u32 = 4;
const BACKGROUND: [u8; 3] = [32, 32, 36];
const INK: [u8; 3] = [240, 240, 240];
/// The outline of the cropped region on the reference.
const MARK: [u8; 3] = [255, 210, 0];
/// The largest sheet written, in pixels (768 MiB of RGB).
const MAX_PIXELS: u64 = 1 << 28;
/// The cropped region's size in source pixels (smaller for images smaller than it).
const CROP: (u32, u32) = (64, 48);
/// The crops' zoom.
const ZOOM: u32 = 4;

/// The images every row starts with.
pub struct Fixed {
    /// The first camera's reference (full detail supersampled).
    pub reference: Image,
    /// The first camera's full-detail image at one ray per pixel.
    pub floor: Image,
}

/// A rectangle of source pixels: left, top, width, height.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    pub x: u32,
    pub y: u32,
    pub w: u32,
    pub h: u32,
}

/// The crop: [`CROP`] (clamped to the image) centred on the centre of the bounding box of the
/// pixels `model` marks in an image of `width` × `height`, or on the image's centre when none
/// is marked, and moved inside the image.
pub fn crop_region(width: u32, height: u32, model: &[bool]) -> Region {
    let (w, h) = (CROP.0.min(width), CROP.1.min(height));
    let mut bounds: Option<(u32, u32, u32, u32)> = None;
    for (i, _) in model.iter().enumerate().filter(|(_, m)| **m) {
        let (x, y) = (
            (i % width.max(1) as usize) as u32,
            (i / width.max(1) as usize) as u32,
        );
        bounds = Some(match bounds {
            None => (x, y, x, y),
            Some((x0, y0, x1, y1)) => (x0.min(x), y0.min(y), x1.max(x), y1.max(y)),
        });
    }
    let (cx, cy) = match bounds {
        Some((x0, y0, x1, y1)) => ((x0 + x1).div_ceil(2), (y0 + y1).div_ceil(2)),
        None => (width / 2, height / 2),
    };
    Region {
        x: cx.saturating_sub(w / 2).min(width - w),
        y: cy.saturating_sub(h / 2).min(height - h),
        w,
        h,
    }
}

/// The layout: image size, crop size, label height, glyph scale, columns and rows.
struct Layout {
    w: u32,
    h: u32,
    crop: Region,
    label: u32,
    scale: u32,
    cols: u32,
    rows: u32,
}

impl Layout {
    fn tile_w(&self) -> u32 {
        self.w.max(ZOOM * self.crop.w)
    }

    fn tile_h(&self) -> u32 {
        self.label + self.h + GAP + ZOOM * self.crop.h
    }

    fn width(&self) -> u64 {
        u64::from(self.cols) * u64::from(self.tile_w() + GAP) + u64::from(GAP)
    }

    fn height(&self) -> u64 {
        u64::from(self.rows) * u64::from(self.tile_h() + GAP) + u64::from(GAP)
    }

    /// Top left corner of the tile in column `c`, row `r` (its label above the image).
    fn corner(&self, c: u32, r: u32) -> (i64, i64) {
        (
            i64::from(GAP + c * (self.tile_w() + GAP)),
            i64::from(GAP + r * (self.tile_h() + GAP)),
        )
    }
}

/// The sheet's pixels, and its size.
struct Sheet {
    rgb: Vec<u8>,
    w: u32,
    h: u32,
}

impl Sheet {
    fn put(&mut self, x: i64, y: i64, c: &[u8]) {
        if x < 0 || y < 0 || x >= i64::from(self.w) || y >= i64::from(self.h) {
            return;
        }
        let at = 3 * (y as usize * self.w as usize + x as usize);
        if let (Some(p), Some(c)) = (self.rgb.get_mut(at..at + 3), c.get(..3)) {
            p.copy_from_slice(c);
        }
    }
}

/// Writes the sheet of `shots` (rows by cache, in order), each row starting with the
/// reference (of `spp` rays per pixel) and the floor (of RMSE `floor_rmse` on the model).
pub fn write(
    path: &Path,
    fixed: &Fixed,
    (spp, floor_rmse): (u32, f64),
    shots: &[Shot],
) -> Result<(), CliError> {
    let reference = &fixed.reference;
    let mut caches: Vec<&str> = Vec::new();
    for s in shots {
        if !caches.contains(&s.cache.as_str()) {
            caches.push(&s.cache);
        }
    }
    let per_row = caches
        .iter()
        .map(|c| shots.iter().filter(|s| s.cache == *c).count())
        .max()
        .unwrap_or(0);
    // Two label lines; big glyphs only where a tile is wide enough for them (32 characters).
    let scale = if reference.width >= 512 { 2 } else { 1 };
    let layout = Layout {
        w: reference.width,
        h: reference.height,
        crop: crop_region(reference.width, reference.height, &reference.model),
        label: 2 * (text::GLYPH * scale + 4),
        scale,
        cols: u32::try_from(per_row + 2).unwrap_or(u32::MAX),
        rows: u32::try_from(caches.len().max(1)).unwrap_or(u32::MAX),
    };
    let (sw, sh) = (layout.width(), layout.height());
    if sw.saturating_mul(sh) > MAX_PIXELS || sw > u64::from(u32::MAX) || sh > u64::from(u32::MAX) {
        return Err(CliError::Usage(format!(
            "--sheet: {sw}x{sh} pixels is too large; ask for a smaller --size or fewer PoEs"
        )));
    }
    let mut sheet = Sheet {
        rgb: BACKGROUND
            .iter()
            .copied()
            .cycle()
            .take(3 * sw as usize * sh as usize)
            .collect(),
        w: sw as u32,
        h: sh as u32,
    };
    for (r, cache) in caches.iter().enumerate() {
        let r = r as u32;
        tile(
            &mut sheet,
            &layout,
            (0, r),
            reference,
            [
                format!("reference: {spp} spp"),
                "PoE 0 blocking".to_string(),
            ],
        );
        outline(&mut sheet, &layout, (0, r));
        tile(
            &mut sheet,
            &layout,
            (1, r),
            &fixed.floor,
            [
                "floor: PoE 0, 1 spp".to_string(),
                format!("RMSE {floor_rmse:.2}"),
            ],
        );
        for (c, s) in shots.iter().filter(|s| s.cache == *cache).enumerate() {
            tile(
                &mut sheet,
                &layout,
                (c as u32 + 2, r),
                &s.image,
                [
                    format!("PoE {} {}", s.poe, s.cache),
                    format!("{:.1} ms RMSE {:.2}", s.ms, s.rmse),
                ],
            );
        }
    }
    oocfmt_trace::output::write_png(path, sheet.w, sheet.h, &sheet.rgb).map_err(CliError::from)
}

/// Copies `image` into its tile of the sheet under its two label lines, and the crop zoomed
/// under it.
fn tile(sheet: &mut Sheet, l: &Layout, (c, r): (u32, u32), image: &Image, label: [String; 2]) {
    let (x0, y0) = l.corner(c, r);
    let clip = (x0, y0, x0 + i64::from(l.tile_w()), y0 + i64::from(l.label));
    let line = i64::from(text::GLYPH * l.scale + 4);
    for (k, s) in label.iter().enumerate() {
        let label = text::Label {
            text: s,
            at: (x0 + 2, y0 + 2 + k as i64 * line),
            scale: l.scale,
            colour: INK,
            clip,
        };
        text::draw(&mut sheet.rgb, sheet.w, sheet.h, &label);
    }
    let row_bytes = 3 * image.width as usize;
    let top = y0 as usize + l.label as usize;
    for (y, src) in image.rgb.chunks_exact(row_bytes.max(3)).enumerate() {
        let at = 3 * ((top + y) * sheet.w as usize + x0 as usize);
        if let Some(dst) = sheet.rgb.get_mut(at..at + row_bytes) {
            dst.copy_from_slice(src);
        }
    }
    let crop_top = i64::from(l.label + l.h + GAP) + y0;
    let Region { x, y, w, h } = l.crop;
    for sy in 0..h * ZOOM {
        for sx in 0..w * ZOOM {
            let (ix, iy) = (x + sx / ZOOM, y + sy / ZOOM);
            let at = 3 * (iy as usize * image.width as usize + ix as usize);
            if let Some(p) = image.rgb.get(at..at + 3) {
                sheet.put(x0 + i64::from(sx), crop_top + i64::from(sy), p);
            }
        }
    }
}

/// Outlines the cropped region on the full image of the tile in column `c`, row `r`.
fn outline(sheet: &mut Sheet, l: &Layout, (c, r): (u32, u32)) {
    let (x0, y0) = l.corner(c, r);
    let top = y0 + i64::from(l.label);
    let Region { x, y, w, h } = l.crop;
    let (x, y, w, h) = (i64::from(x), i64::from(y), i64::from(w), i64::from(h));
    for k in 0..w {
        sheet.put(x0 + x + k, top + y, &MARK);
        sheet.put(x0 + x + k, top + y + h - 1, &MARK);
    }
    for k in 0..h {
        sheet.put(x0 + x, top + y + k, &MARK);
        sheet.put(x0 + x + w - 1, top + y + k, &MARK);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_crop_is_centred_on_the_model_and_stays_inside() {
        // A 200 x 100 image whose model covers x 100..=139, y 20..=59: centre (120, 40).
        let (w, h) = (200u32, 100u32);
        let model: Vec<bool> = (0..w * h)
            .map(|i| (100..140).contains(&(i % w)) && (20..60).contains(&(i / w)))
            .collect();
        assert_eq!(
            crop_region(w, h, &model),
            Region {
                x: 88,
                y: 16,
                w: 64,
                h: 48
            }
        );
        // A model at the bottom right corner: the crop is moved inside the image.
        let corner: Vec<bool> = (0..w * h).map(|i| i == w * h - 1).collect();
        assert_eq!(
            crop_region(w, h, &corner),
            Region {
                x: 136,
                y: 52,
                w: 64,
                h: 48
            }
        );
        // No model: the image's centre; an image smaller than the crop: all of it.
        assert_eq!(crop_region(w, h, &[]).x, 68);
        assert_eq!(
            crop_region(40, 30, &[]),
            Region {
                x: 0,
                y: 0,
                w: 40,
                h: 30
            }
        );
    }
}
