//! Per-frame accuracy of a walkthrough, after iWalk's Figure 7 (approximate against
//! conservative): the share of a frame's pixels equal to the full-detail reference, the same
//! camera rendered with the blocking cache at PoE 0. The references are rendered after the
//! walkthrough, so that their time gives the walkthrough's fetchers no head start; the frames
//! are read back from the PNGs the walkthrough wrote (lossless), so nothing is held in memory
//! across the frames.

use std::fs::File;
use std::io::BufReader;
use std::path::Path;
use std::sync::Arc;

use serde::Serialize;

use oocfmt_trace::compare::within_tolerance;
use oocfmt_trace::{render, BlockingCache, Camera, RenderOptions, Scene};

use crate::error::CliError;

#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Accuracy {
    /// Share of pixels whose colour equals the reference's exactly.
    pub exact: f64,
    /// Share of pixels whose three channels all differ from the reference's by at most
    /// `tolerance` levels of 255.
    pub within_tolerance: f64,
    pub tolerance: u8,
}

/// The least memory the references' blocking cache gets: a full-detail view's blocks take
/// several times what an LOD view's do (333 MiB for a view of 10M triangles), and a reference
/// cache that thrashes only costs time, never accuracy.
pub const MIN_REFERENCE_BUDGET: usize = 1 << 30;

/// Renders the reference of each camera (blocking cache of `budget` bytes, at least
/// [`MIN_REFERENCE_BUDGET`], PoE 0, the other options as `opts`) and compares the frame written
/// to `files[i]` with it.
pub fn measure(
    scene: &Arc<Scene>,
    cameras: &[Camera],
    files: &[std::path::PathBuf],
    opts: &RenderOptions,
    budget: usize,
    tolerance: u8,
) -> Result<Vec<Accuracy>, CliError> {
    let cache = BlockingCache::new(Arc::clone(scene), budget.max(MIN_REFERENCE_BUDGET));
    let reference_opts = RenderOptions { poe: 0.0, ..*opts };
    cameras
        .iter()
        .zip(files)
        .map(|(camera, file)| {
            let (reference, _) = render(scene, &cache, camera, &reference_opts)?;
            let (w, h, rgb) = read_rgb8(file)?;
            if (w, h) != (reference.width, reference.height) {
                return Err(CliError::Io {
                    path: file.display().to_string(),
                    source: std::io::Error::other(format!(
                        "{w}x{h}, where the reference is {}x{}",
                        reference.width, reference.height
                    )),
                });
            }
            Ok(Accuracy {
                exact: within_tolerance(&reference.rgb, &rgb, 0),
                within_tolerance: within_tolerance(&reference.rgb, &rgb, tolerance),
                tolerance,
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
