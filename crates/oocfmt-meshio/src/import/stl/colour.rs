//! Colours in binary STL attribute words. There is no standard, only two conventions that
//! mirror each other's bit order, so the header decides: Materialise Magics files say
//! `COLOR=` in it, everything else is read as VisCAM/SolidView (see the module above).

/// How a file's attribute words carry colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Convention {
    /// Attribute words are ignored.
    None,
    /// Bit 15 set: a valid colour, red in bits 10–14, green 5–9, blue 0–4.
    VisCam,
    /// Bit 15 clear: the facet's own colour, red in bits 0–4, green 5–9, blue 10–14; set: the
    /// default colour of the header's `COLOR=`.
    Magics {
        /// The header's RGBA.
        default: [u8; 4],
    },
}

impl Convention {
    /// The convention of a file with `header`; `None` when colours are not wanted.
    pub(super) fn of(header: &[u8; 80], wanted: bool) -> Convention {
        if !wanted {
            return Convention::None;
        }
        let key = b"COLOR=";
        let found = header
            .windows(key.len() + 4)
            .find(|w| w.starts_with(key))
            .and_then(|w| w.get(key.len()..))
            .and_then(|rgba| <[u8; 4]>::try_from(rgba).ok());
        match found {
            Some(default) => Convention::Magics { default },
            None => Convention::VisCam,
        }
    }

    /// The colour `attribute` gives a facet, if any.
    pub(super) fn colour(self, attribute: u16) -> Option<[u8; 4]> {
        let valid = attribute & 0x8000 != 0;
        let (low, mid, high) = (five(attribute), five(attribute >> 5), five(attribute >> 10));
        match self {
            Convention::None => None,
            Convention::VisCam => valid.then_some([high, mid, low, 255]),
            Convention::Magics { default } if valid => Some(default),
            Convention::Magics { .. } => Some([low, mid, high, 255]),
        }
    }
}

/// The low five bits of `bits` as eight, the top bits repeated below (0 → 0, 31 → 255).
fn five(bits: u16) -> u8 {
    let c = (bits & 31) as u8;
    (c << 3) | (c >> 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_two_conventions_mirror_each_other() {
        let mut header = [b' '; 80];
        assert_eq!(Convention::of(&header, true), Convention::VisCam);
        assert_eq!(Convention::of(&header, false), Convention::None);
        header[10..20].copy_from_slice(b"COLOR=\x10\x20\x30\x40");
        let magics = Convention::of(&header, true);
        assert_eq!(
            magics,
            Convention::Magics {
                default: [0x10, 0x20, 0x30, 0x40]
            }
        );
        // Red 31, green 0, blue 8 in each convention's order.
        let viscam_word = 0x8000 | (31 << 10) | 8;
        assert_eq!(
            Convention::VisCam.colour(viscam_word),
            Some([255, 0, 66, 255])
        );
        assert_eq!(Convention::VisCam.colour(viscam_word & 0x7fff), None);
        let magics_word = 31 | (8 << 10);
        assert_eq!(magics.colour(magics_word), Some([255, 0, 66, 255]));
        assert_eq!(
            magics.colour(0x8000 | magics_word),
            Some([0x10, 0x20, 0x30, 0x40])
        );
        assert_eq!(Convention::None.colour(0xffff), None);
        // `COLOR=` too near the end for its four bytes is no Magics header.
        let mut late = [b' '; 80];
        late[74..80].copy_from_slice(b"COLOR=");
        assert_eq!(Convention::of(&late, true), Convention::VisCam);
    }
}
