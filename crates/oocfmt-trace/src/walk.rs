//! Walkthroughs: a camera path from JSON, either a list of cameras, one per frame,
//!
//! ```json
//! [{"eye": [0, 1, 5], "look_at": [0, 0, 0]}, {"eye": [1, 1, 5], "look_at": [0, 0, 0], "fov_y": 40}]
//! ```
//!
//! or keyframes and a frame count, the cameras interpolated linearly between the keyframes
//! (eye, look-at point, up and field of view; the frames evenly spaced over the path's
//! keyframe intervals, the first and last frames on the first and last keyframes):
//!
//! ```json
//! {"keyframes": [{"eye": [0, 1, 5], "look_at": [0, 0, 0]}, {"eye": [0, 1, 2], "look_at": [0, 0, 0]}], "frames": 20}
//! ```
//!
//! Positions are in world coordinates, as on the command line.

use std::path::Path;

use serde::Deserialize;

use crate::camera::{Camera, DEFAULT_FOV_Y};
use crate::error::TraceError;

/// The most frames one path may ask for.
pub const MAX_FRAMES: u32 = 100_000;

/// One camera of a path file, as written there (world coordinates); unknown keys are refused.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Key {
    /// The eye position.
    pub eye: [f64; 3],
    /// The point the camera looks at.
    pub look_at: [f64; 3],
    /// The up direction; None: +y.
    pub up: Option<[f64; 3]>,
    /// Vertical field of view in degrees; None: [`DEFAULT_FOV_Y`].
    pub fov_y: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Keyframes {
    keyframes: Vec<serde_json::Value>,
    frames: u32,
}

const SHAPE: &str = "expected a list of cameras [{\"eye\": [x, y, z], \"look_at\": [x, y, z], \
                     \"up\"?: [x, y, z], \"fov_y\"?: degrees}, ...], or {\"keyframes\": [cameras], \
                     \"frames\": N}";

/// Reads a path file and returns the frames' cameras in world coordinates, each `width` ×
/// `height`; a camera without `up` looks with +y up, one without `fov_y` has the default.
pub fn read_path(path: &Path, width: u32, height: u32) -> Result<Vec<Camera>, TraceError> {
    let text = std::fs::read_to_string(path).map_err(|e| TraceError::io(path, e))?;
    parse_path(&text, width, height).map_err(|message| TraceError::Path {
        path: path.to_path_buf(),
        message,
    })
}

/// [`read_path`] on the text of a path file; the error says what is wrong and where.
pub fn parse_path(text: &str, width: u32, height: u32) -> Result<Vec<Camera>, String> {
    let value: serde_json::Value = serde_json::from_str(text)
        .map_err(|e| format!("line {} column {}: {e}", e.line(), e.column()))?;
    let (values, frames) = match value {
        serde_json::Value::Array(list) => {
            let n = u32::try_from(list.len()).unwrap_or(u32::MAX);
            (list, n)
        }
        v @ serde_json::Value::Object(_) => {
            let k: Keyframes = serde_json::from_value(v).map_err(|e| format!("{e}; {SHAPE}"))?;
            (k.keyframes, k.frames)
        }
        _ => return Err(SHAPE.into()),
    };
    let keys = values
        .into_iter()
        .enumerate()
        .map(|(i, v)| serde_json::from_value::<Key>(v).map_err(|e| format!("camera {i}: {e}")))
        .collect::<Result<Vec<Key>, String>>()?;
    if keys.is_empty() {
        return Err("the path has no cameras".into());
    }
    if !(1..=MAX_FRAMES).contains(&frames) {
        return Err(format!("{frames} frames: expected 1 to {MAX_FRAMES}"));
    }
    for (i, k) in keys.iter().enumerate() {
        let finite = k
            .eye
            .iter()
            .chain(&k.look_at)
            .chain(k.up.iter().flatten())
            .chain(&k.fov_y)
            .all(|c| c.is_finite());
        if !finite {
            return Err(format!("camera {i}: every number must be finite"));
        }
    }
    let camera = |k: &Key| Camera {
        eye: k.eye,
        look_at: k.look_at,
        up: k.up.unwrap_or([0.0, 1.0, 0.0]),
        fov_y: k.fov_y.unwrap_or(DEFAULT_FOV_Y),
        width,
        height,
    };
    if frames as usize == keys.len() {
        return Ok(keys.iter().map(camera).collect());
    }
    let intervals = (keys.len() - 1) as f64;
    Ok((0..frames)
        .map(|f| {
            let s = if frames > 1 {
                f64::from(f) / f64::from(frames - 1) * intervals
            } else {
                0.0
            };
            let i = (s.floor() as usize).min(keys.len().saturating_sub(2));
            let (a, b) = match (keys.get(i), keys.get(i + 1)) {
                (Some(a), Some(b)) => (camera(a), camera(b)),
                (Some(a), None) => (camera(a), camera(a)),
                _ => (camera(&keys[0]), camera(&keys[0])),
            };
            let u = (s - i as f64).clamp(0.0, 1.0);
            let mix = |p: [f64; 3], q: [f64; 3]| [0, 1, 2].map(|k| p[k] + (q[k] - p[k]) * u);
            Camera {
                eye: mix(a.eye, b.eye),
                look_at: mix(a.look_at, b.look_at),
                up: mix(a.up, b.up),
                fov_y: a.fov_y + (b.fov_y - a.fov_y) * u,
                width,
                height,
            }
        })
        .collect())
}

/// `out.png` → `out-0007.png`: frame `i` of a walkthrough written to `output`.
pub fn frame_file(output: &Path, i: usize) -> std::path::PathBuf {
    let stem = output
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "frame".into());
    let ext = output
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_else(|| "png".into());
    output.with_file_name(format!("{stem}-{i:04}.{ext}"))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_list_is_one_camera_per_frame() {
        let cams = parse_path(
            r#"[{"eye":[0,0,5],"look_at":[0,0,0]},{"eye":[1,0,5],"look_at":[0,0,0],"fov_y":30,"up":[0,0,1]}]"#,
            8,
            6,
        )
        .unwrap();
        assert_eq!(cams.len(), 2);
        assert_eq!(cams[0].up, [0.0, 1.0, 0.0]);
        assert_eq!(cams[1].fov_y, 30.0);
        assert_eq!(cams[1].up, [0.0, 0.0, 1.0]);
        assert_eq!((cams[1].width, cams[1].height), (8, 6));
    }

    #[test]
    fn keyframes_interpolate_linearly_end_to_end() {
        let cams = parse_path(
            r#"{"keyframes":[{"eye":[0,0,10],"look_at":[0,0,0]},{"eye":[0,0,2],"look_at":[0,0,0]},{"eye":[4,0,2],"look_at":[0,0,0]}],"frames":5}"#,
            8,
            6,
        )
        .unwrap();
        let eyes: Vec<[f64; 3]> = cams.iter().map(|c| c.eye).collect();
        assert_eq!(
            eyes,
            vec![
                [0.0, 0.0, 10.0],
                [0.0, 0.0, 6.0],
                [0.0, 0.0, 2.0],
                [2.0, 0.0, 2.0],
                [4.0, 0.0, 2.0]
            ]
        );
    }

    #[test]
    fn bad_paths_say_what_is_wrong() {
        for (text, says) in [
            ("[]", "no cameras"),
            (
                "{\"keyframes\":[{\"eye\":[0,0,1],\"look_at\":[0,0,0]}],\"frames\":0}",
                "0 frames",
            ),
            ("[{\"eye\":[0,0],\"look_at\":[0,0,0]}]", "camera 0"),
            (
                "[{\"eye\":[0,0,1],\"look_at\":[0,0,0],\"fov\":3}]",
                "unknown field `fov`",
            ),
            ("[{\"eye\":[0,0,1],\"look_at\":[0,0,0]}", "line 1"),
            ("{\"frames\": 3}", "keyframes"),
            ("3", "expected a list"),
        ] {
            let e = parse_path(text, 8, 6).unwrap_err();
            assert!(e.contains(says), "{text}: {e}");
        }
    }

    #[test]
    fn frame_files_are_numbered_beside_the_output() {
        assert_eq!(
            frame_file(Path::new("dir/out.png"), 7),
            Path::new("dir/out-0007.png")
        );
    }
}
