//! Binary STL: after the 80-byte header and the facet count, 50 bytes a facet (normal, three
//! corners as little-endian f32, an attribute word), read one facet at a time.

use std::fmt::Write as _;
use std::io::{ErrorKind, Read};

use super::colour::Convention;
use super::facet::Facets;
use super::{StlOptions, BINARY_FACET, BINARY_HEAD};
use crate::import::{ImportError, Location, TriangleSink};

/// Reads `count` facets from `input`, which stands just after the facet count. `short` says
/// why the input may end inside a facet, for the error when it does.
pub(super) fn read<R: Read>(
    mut input: R,
    file: &str,
    header: &[u8; 80],
    count: u32,
    sink: &mut dyn TriangleSink,
    opts: &StlOptions,
    short: &str,
) -> Result<(), ImportError> {
    let convention = Convention::of(header, opts.colours);
    let mut facets = Facets::new(file);
    let mut at = Location::item(file, String::new());
    let mut record = [0u8; BINARY_FACET as usize];
    for i in 0..count {
        if let Some(item) = at.item.as_mut() {
            item.clear();
            let byte = BINARY_HEAD + BINARY_FACET * u64::from(i);
            // Writing to a String cannot fail.
            let _ = write!(item, "facet {i} at byte {byte}");
        }
        input.read_exact(&mut record).map_err(|e| match e.kind() {
            ErrorKind::UnexpectedEof => ImportError::Parse {
                at: at.clone(),
                message: format!("the input ends inside this facet ({short})"),
            },
            _ => ImportError::Io {
                path: at.to_string(),
                source: e,
            },
        })?;
        let mut floats = [0.0f64; 12];
        for (f, b) in floats.iter_mut().zip(record.chunks_exact(4)) {
            *f = f64::from(f32::from_le_bytes(b.try_into().unwrap_or_default()));
        }
        let attribute = u16::from_le_bytes([record[48], record[49]]);
        let [nx, ny, nz, ax, ay, az, bx, by, bz, cx, cy, cz] = floats;
        facets.emit(
            sink,
            &[[ax, ay, az], [bx, by, bz], [cx, cy, cz]],
            [nx, ny, nz],
            convention.colour(attribute),
            None,
            &at,
        )?;
    }
    facets.finish(sink);
    Ok(())
}
