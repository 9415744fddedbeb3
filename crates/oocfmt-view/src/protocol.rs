//! The messages between the page and the server, over one WebSocket.
//!
//! Page to server: JSON text, at most [`MAX_MESSAGE`] bytes, one of [`ClientMessage`]; unknown
//! types and fields are refused. A refused message is answered with an `error` and changes
//! nothing. Server to page: JSON text ([`ServerMessage`]: `hello` once, then `pick` answers and
//! `error`s), and
//! frames as binary messages: the 4 bytes `OVF1`, the header's length (u32, little-endian),
//! the header ([`FrameHeader`], JSON), then the image file (JPEG or PNG).

use serde::{Deserialize, Serialize};

use oocfmt_trace::live::{LiveFigures, Quality};
use oocfmt_trace::pick::Pick;
use oocfmt_trace::{Camera, Section};

use crate::tree::PartItem;

/// The longest text message the page may send; longer ones are answered with an error.
pub const MAX_MESSAGE: usize = 4096;

/// The longest message the socket takes at all: beyond it the connection is closed.
pub const MAX_SOCKET_MESSAGE: usize = 64 << 10;

/// What starts a frame message.
pub const FRAME_MAGIC: &[u8; 4] = b"OVF1";

/// A message from the page.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ClientMessage {
    /// The view's camera, world coordinates, and the size of the image to show.
    Camera {
        /// Echoed by the frames that show this camera.
        seq: u64,
        /// Eye position.
        eye: [f64; 3],
        /// The point seen at the centre.
        look_at: [f64; 3],
        /// Which way is up.
        up: [f64; 3],
        /// Vertical field of view, degrees.
        fov_y: f64,
        /// Image width in pixels.
        width: u32,
        /// Image height in pixels.
        height: u32,
    },
    /// What the still image refines to.
    Quality {
        /// Pixels of error (0: full detail).
        poe: f32,
        /// Samples per pixel.
        spp: u32,
    },
    /// The view's section plane, world coordinates: keeps `normal · p ≥ offset`; null (or
    /// left out): no cut. A zero or non-finite normal is refused.
    Section {
        /// The plane, or null.
        plane: Option<Section>,
    },
    /// Which parts the view shows, by id (the model tree): `hide` hides those parts,
    /// `isolate` (when not empty) every part outside it, each with its descendants; both empty
    /// shows every part. An id past the part table is refused.
    Parts {
        /// Parts to hide.
        #[serde(default)]
        hide: Vec<u32>,
        /// Parts to show alone.
        #[serde(default)]
        isolate: Vec<u32>,
    },
    /// The children of a part (null: the top-level parts), from `offset`, answered with a
    /// `part_children` message of at most [`crate::tree::MAX_CHILDREN`].
    PartChildren {
        /// Echoed by the answer.
        seq: u64,
        /// The part, or null for the top level.
        parent: Option<u32>,
        /// How many children to skip.
        #[serde(default)]
        offset: u32,
    },
    /// What a pixel of the full-size image shows (answered with a `pick` message).
    Pick {
        /// Echoed by the answer.
        seq: u64,
        /// Column, from the left.
        x: u32,
        /// Row, from the top.
        y: u32,
    },
}

impl ClientMessage {
    /// The camera of a camera message and its number.
    pub fn camera(&self) -> Option<(Camera, u64)> {
        match *self {
            ClientMessage::Camera {
                seq,
                eye,
                look_at,
                up,
                fov_y,
                width,
                height,
            } => Some((
                Camera {
                    eye,
                    look_at,
                    up,
                    fov_y,
                    width,
                    height,
                },
                seq,
            )),
            ClientMessage::Quality { .. }
            | ClientMessage::Pick { .. }
            | ClientMessage::Section { .. }
            | ClientMessage::Parts { .. }
            | ClientMessage::PartChildren { .. } => None,
        }
    }
}

/// What the page is told about the model, in world coordinates.
#[derive(Clone, Debug, Serialize)]
pub struct ModelInfo {
    /// The container's file name.
    pub name: String,
    /// Input triangles.
    pub triangles: u64,
    /// Low corner of the scene box.
    pub bounds_min: [f64; 3],
    /// High corner of the scene box.
    pub bounds_max: [f64; 3],
    /// Named parts in the file (0: none).
    pub parts: usize,
}

/// The quality as the page sees it.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct QualityInfo {
    /// Pixels of error of the still image.
    pub poe: f32,
    /// Samples per pixel of the still image.
    pub spp: u32,
}

impl From<Quality> for QualityInfo {
    fn from(q: Quality) -> Self {
        QualityInfo {
            poe: q.poe,
            spp: q.spp,
        }
    }
}

/// A text message to the page.
#[derive(Clone, Debug, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ServerMessage {
    /// Sent once, when the socket opens.
    Hello {
        /// The model.
        model: ModelInfo,
        /// The quality a view starts with.
        quality: QualityInfo,
        /// The frame time held while moving.
        target_ms: f64,
        /// The most pixels a view's image may have.
        max_pixels: u64,
        /// oocfmt's version.
        version: &'static str,
    },
    /// The answer to a pick.
    Pick {
        /// The pick's number.
        seq: u64,
        /// The pixel picked.
        x: u32,
        /// See `x`.
        y: u32,
        /// What its centre ray met first (world coordinates); null on the background.
        hit: Option<Pick>,
        /// The picked part's ancestors from the top level down, then the part (empty without
        /// a part), for the model tree to open down to it.
        lineage: Vec<u32>,
    },
    /// The answer to a `part_children` message.
    PartChildren {
        /// The request's number.
        seq: u64,
        /// The part asked about, or null for the top level.
        parent: Option<u32>,
        /// The offset asked for.
        offset: u32,
        /// How many children there are in all.
        total: usize,
        /// The children from `offset`, at most [`crate::tree::MAX_CHILDREN`].
        children: Vec<PartItem>,
    },
    /// A message was refused, or a frame could not be rendered.
    Error {
        /// What and why.
        message: String,
    },
}

/// The header of a frame message.
#[derive(Clone, Debug, Serialize)]
pub struct FrameHeader<'a> {
    /// The number of the camera it shows.
    pub seq: u64,
    /// `jpeg` or `png`.
    pub format: &'static str,
    /// The JPEG quality (none for PNG).
    pub quality: Option<u8>,
    /// Milliseconds spent encoding it.
    pub encode_ms: f64,
    /// Bytes of the image file.
    pub bytes: usize,
    /// Frames of this view that were replaced by a newer one before they could be sent.
    pub dropped: u64,
    /// The frame's figures.
    pub figures: &'a LiveFigures,
}

/// A frame message: magic, header length, header, image.
pub fn frame_message(header: &FrameHeader<'_>, image: &[u8]) -> Result<Vec<u8>, serde_json::Error> {
    let json = serde_json::to_vec(header)?;
    let len = u32::try_from(json.len()).unwrap_or(u32::MAX);
    let mut out = Vec::with_capacity(8 + json.len() + image.len());
    out.extend_from_slice(FRAME_MAGIC);
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(image);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_parse_and_strangers_are_refused() {
        let cam = r#"{"type":"camera","seq":3,"eye":[0,0,5],"look_at":[0,0,0],"up":[0,1,0],"fov_y":45,"width":64,"height":48}"#;
        let m: Result<ClientMessage, _> = serde_json::from_str(cam);
        assert!(
            matches!(
                m,
                Ok(ClientMessage::Camera {
                    seq: 3,
                    width: 64,
                    ..
                })
            ),
            "{m:?}"
        );
        let s: Result<ClientMessage, _> =
            serde_json::from_str(r#"{"type":"section","plane":{"normal":[0,0,2],"offset":1}}"#);
        assert!(
            matches!(&s, Ok(ClientMessage::Section { plane: Some(p) }) if p.offset == 1.0),
            "{s:?}"
        );
        let s: Result<ClientMessage, _> =
            serde_json::from_str(r#"{"type":"section","plane":null}"#);
        assert!(
            matches!(s, Ok(ClientMessage::Section { plane: None })),
            "{s:?}"
        );
        let q: Result<ClientMessage, _> =
            serde_json::from_str(r#"{"type":"quality","poe":1.5,"spp":4}"#);
        assert!(
            matches!(q, Ok(ClientMessage::Quality { spp: 4, .. })),
            "{q:?}"
        );
        for bad in [
            r#"{"type":"quality","poe":1,"spp":4,"extra":1}"#,
            r#"{"type":"delete","path":"/"}"#,
            r#"{"poe":1,"spp":4}"#,
            r#"{"type":"quality","poe":"x","spp":4}"#,
            r#"{"type":"quality","poe":1,"spp":-4}"#,
            r#"{"type":"camera","seq":1}"#,
            r#"{"type":"section","plane":{"normal":[1,0,0]}}"#,
            r#"{"type":"section","plane":{"normal":[1,0,0],"offset":1,"x":2}}"#,
            r#"{"type":"section","plane":{"normal":[1,0],"offset":1}}"#,
            r#"{"type":"parts","hide":[-1]}"#,
            r#"{"type":"parts","hide":"all"}"#,
            r#"{"type":"parts","show":[1]}"#,
            r#"{"type":"part_children","parent":1}"#,
            "[]",
            "not json",
        ] {
            assert!(serde_json::from_str::<ClientMessage>(bad).is_err(), "{bad}");
        }
    }
}
