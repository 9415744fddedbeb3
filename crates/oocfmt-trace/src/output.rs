//! Image files, written atomically: into a temporary file beside the target, then renamed over
//! it, so a reader never sees half an image and a failure leaves the old file alone.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::TraceError;

fn temp_beside(target: &Path) -> PathBuf {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "image".into());
    target.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

fn atomic(
    target: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<(), TraceError>,
) -> Result<(), TraceError> {
    let tmp = temp_beside(target);
    let result = (|| {
        let file = File::create(&tmp).map_err(|e| TraceError::io(&tmp, e))?;
        let mut out = BufWriter::new(file);
        write(&mut out)?;
        let file = out
            .into_inner()
            .map_err(|e| TraceError::io(&tmp, e.into_error()))?;
        file.sync_all().map_err(|e| TraceError::io(&tmp, e))?;
        std::fs::rename(&tmp, target).map_err(|e| TraceError::io(target, e))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes an 8-bit RGB PNG (`rgb`: rows top to bottom, 3 bytes a pixel).
pub fn write_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), TraceError> {
    atomic(path, |out| {
        let png_err = |source| TraceError::Png {
            path: path.to_path_buf(),
            source,
        };
        let mut enc = png::Encoder::new(out, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(png_err)?;
        w.write_image_data(rgb).map_err(png_err)?;
        w.finish().map_err(png_err)
    })
}

/// Writes a greyscale PFM (`Pf`, little-endian: scale −1), whose rows run bottom to top;
/// `values` rows run top to bottom as everywhere else here.
pub fn write_pfm(path: &Path, width: u32, height: u32, values: &[f32]) -> Result<(), TraceError> {
    atomic(path, |out| {
        let io = |e| TraceError::io(path, e);
        write!(out, "Pf\n{width} {height}\n-1.0\n").map_err(io)?;
        let w = width as usize;
        for row in values.chunks(w.max(1)).rev() {
            for v in row {
                out.write_all(&v.to_le_bytes()).map_err(io)?;
            }
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn pfm_rows_run_bottom_up_and_no_temp_file_is_left() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.pfm");
        write_pfm(&p, 2, 2, &[1.0, 2.0, 3.0, f32::INFINITY]).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let head = b"Pf\n2 2\n-1.0\n";
        assert_eq!(&bytes[..head.len()], head);
        let body: Vec<f32> = bytes[head.len()..]
            .chunks(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        assert_eq!(body, vec![3.0, f32::INFINITY, 1.0, 2.0]);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
