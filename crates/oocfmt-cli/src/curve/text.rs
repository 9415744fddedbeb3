//! Labels on RGB8 pictures with the public-domain 8 × 8 bitmap font of `font8x8`: no font
//! file and no system fonts, so the contact sheet and the PNG plot look the same everywhere.

use font8x8::legacy::BASIC_LEGACY;

/// Glyph side in font pixels.
pub const GLYPH: u32 = 8;

/// The 8 rows of `c`'s glyph (bit 0 the leftmost pixel); `?` for a character outside ASCII.
fn glyph(c: char) -> [u8; 8] {
    let q = BASIC_LEGACY
        .get(usize::from(b'?'))
        .copied()
        .unwrap_or([0; 8]);
    u32::from(c)
        .try_into()
        .ok()
        .and_then(|i: usize| BASIC_LEGACY.get(i))
        .copied()
        .unwrap_or(q)
}

/// Width and height in pixels of `text` drawn at `scale`.
pub fn size(text: &str, scale: u32) -> (u32, u32) {
    let n = u32::try_from(text.chars().count()).unwrap_or(u32::MAX);
    (n.saturating_mul(GLYPH * scale), GLYPH * scale)
}

/// Calls `plot(x, y)` for every set pixel of `text` drawn at `scale` with its top left
/// corner at (x0, y0).
pub fn pixels(text: &str, x0: i64, y0: i64, scale: u32, mut plot: impl FnMut(i64, i64)) {
    let s = i64::from(scale);
    for (k, c) in text.chars().enumerate() {
        let gx = x0 + k as i64 * 8 * s;
        for (row, bits) in glyph(c).iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) == 0 {
                    continue;
                }
                for dy in 0..s {
                    for dx in 0..s {
                        plot(gx + col * s + dx, y0 + row as i64 * s + dy);
                    }
                }
            }
        }
    }
}

/// A line of text to draw: where (its top left corner), how large, in what colour, and the
/// rectangle it is clipped to, (x0, y0, x1, y1), exclusive at the far ends.
pub struct Label<'a> {
    pub text: &'a str,
    pub at: (i64, i64),
    pub scale: u32,
    pub colour: [u8; 3],
    pub clip: (i64, i64, i64, i64),
}

/// Draws `label` into an RGB8 picture of `width` × `height` (rows top to bottom), within its
/// clip rectangle and the picture.
pub fn draw(rgb: &mut [u8], width: u32, height: u32, label: &Label<'_>) {
    let Label {
        text,
        at: (x, y),
        scale,
        colour,
        clip,
    } = *label;
    let (cx0, cy0) = (clip.0.max(0), clip.1.max(0));
    let (cx1, cy1) = (clip.2.min(i64::from(width)), clip.3.min(i64::from(height)));
    pixels(text, x, y, scale, |px, py| {
        if px < cx0 || py < cy0 || px >= cx1 || py >= cy1 {
            return;
        }
        let at = 3 * (py as usize * width as usize + px as usize);
        if let Some(p) = rgb.get_mut(at..at + 3) {
            p.copy_from_slice(&colour);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_glyph_sets_pixels_inside_its_box() {
        let mut n = 0;
        pixels("A1", 10, 20, 2, |x, y| {
            assert!((10..10 + 32).contains(&x) && (20..20 + 16).contains(&y));
            n += 1;
        });
        assert!(n > 0);
        assert_eq!(size("A1", 2), (32, 16));
        // A space sets nothing; a character beyond ASCII is drawn as `?`.
        let mut blank = 0;
        pixels(" ", 0, 0, 1, |_, _| blank += 1);
        assert_eq!(blank, 0);
        assert_eq!(glyph('é'), glyph('?'));
    }

    #[test]
    fn drawing_is_clipped() {
        let mut rgb = vec![0u8; 3 * 8 * 8];
        let label = Label {
            text: "MM",
            at: (-4, 0),
            scale: 1,
            colour: [255, 0, 0],
            clip: (0, 0, 4, 8),
        };
        draw(&mut rgb, 8, 8, &label);
        for y in 0..8 {
            for x in 4..8 {
                assert_eq!(rgb[3 * (y * 8 + x)], 0);
            }
        }
        assert!(rgb.chunks(3).any(|p| p[0] == 255));
    }
}
