//! The contact sheet: the reference and every measurement's image side by side at full
//! size (so the artefacts show), each under a label with its PoE, frame time and PSNR; one row
//! per cache.

use std::path::Path;

use oocfmt_trace::Image;

use super::{db, text, Shot};
use crate::error::CliError;

const GAP: u32 = 4;
const BACKGROUND: [u8; 3] = [32, 32, 36];
const INK: [u8; 3] = [240, 240, 240];
/// The largest sheet written, in pixels (768 MiB of RGB).
const MAX_PIXELS: u64 = 1 << 28;

/// The layout: tile size, label height, glyph scale, columns and rows.
struct Layout {
    w: u32,
    h: u32,
    label: u32,
    scale: u32,
    cols: u32,
    rows: u32,
}

impl Layout {
    fn width(&self) -> u64 {
        u64::from(self.cols) * u64::from(self.w + GAP) + u64::from(GAP)
    }

    fn height(&self) -> u64 {
        u64::from(self.rows) * u64::from(self.h + self.label + GAP) + u64::from(GAP)
    }

    /// Top left corner of the tile in column `c`, row `r` (its label above the image).
    fn corner(&self, c: u32, r: u32) -> (i64, i64) {
        (
            i64::from(GAP + c * (self.w + GAP)),
            i64::from(GAP + r * (self.h + self.label + GAP)),
        )
    }
}

/// Writes the sheet of `shots` (rows by cache, in order) with `reference` first in each row.
pub fn write(path: &Path, reference: &Image, shots: &[Shot]) -> Result<(), CliError> {
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
    // Two label lines; big glyphs only where a tile is wide enough for them.
    let scale = if reference.width >= 320 { 2 } else { 1 };
    let layout = Layout {
        w: reference.width,
        h: reference.height,
        label: 2 * (text::GLYPH * scale + 4),
        scale,
        cols: u32::try_from(per_row + 1).unwrap_or(u32::MAX),
        rows: u32::try_from(caches.len().max(1)).unwrap_or(u32::MAX),
    };
    let (sw, sh) = (layout.width(), layout.height());
    if sw.saturating_mul(sh) > MAX_PIXELS || sw > u64::from(u32::MAX) || sh > u64::from(u32::MAX) {
        return Err(CliError::Usage(format!(
            "--sheet: {sw}x{sh} pixels is too large; ask for a smaller --size or fewer PoEs"
        )));
    }
    let (sw, sh) = (sw as u32, sh as u32);
    let mut rgb: Vec<u8> = BACKGROUND
        .iter()
        .copied()
        .cycle()
        .take(3 * sw as usize * sh as usize)
        .collect();
    for (r, cache) in caches.iter().enumerate() {
        let r = r as u32;
        tile(
            &mut rgb,
            (sw, sh),
            &layout,
            (0, r),
            reference,
            ["reference: PoE 0".to_string(), "blocking".to_string()],
        );
        for (c, s) in shots.iter().filter(|s| s.cache == *cache).enumerate() {
            tile(
                &mut rgb,
                (sw, sh),
                &layout,
                (c as u32 + 1, r),
                &s.image,
                [
                    format!("PoE {} {}", s.poe, s.cache),
                    format!("{:.1} ms {} dB", s.ms, db(s.psnr_db)),
                ],
            );
        }
    }
    oocfmt_trace::output::write_png(path, sw, sh, &rgb).map_err(CliError::from)
}

/// Copies `image` into its tile of the sheet under its two label lines.
fn tile(
    rgb: &mut [u8],
    (sw, sh): (u32, u32),
    l: &Layout,
    (c, r): (u32, u32),
    image: &Image,
    label: [String; 2],
) {
    let (x0, y0) = l.corner(c, r);
    let clip = (x0, y0, x0 + i64::from(l.w), y0 + i64::from(l.label));
    let line = i64::from(text::GLYPH * l.scale + 4);
    for (k, s) in label.iter().enumerate() {
        let label = text::Label {
            text: s,
            at: (x0 + 2, y0 + 2 + k as i64 * line),
            scale: l.scale,
            colour: INK,
            clip,
        };
        text::draw(rgb, sw, sh, &label);
    }
    let row_bytes = 3 * image.width as usize;
    let top = y0 as usize + l.label as usize;
    for (y, src) in image.rgb.chunks_exact(row_bytes.max(3)).enumerate() {
        let at = 3 * ((top + y) * sw as usize + x0 as usize);
        if let Some(dst) = rgb.get_mut(at..at + row_bytes) {
            dst.copy_from_slice(src);
        }
    }
}
