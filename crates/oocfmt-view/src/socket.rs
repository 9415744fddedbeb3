//! One WebSocket: a view of the viewer. Two tasks: the receiver validates the page's messages
//! and posts cameras, qualities and picks to the viewer (so they reach the render thread at once,
//! even while a frame is being sent); the sender writes the hello, pick answers, errors and frames. Frames
//! come through a channel that keeps only the newest: one the sender had no time for is
//! replaced, never queued.

use std::sync::Arc;

use axum::extract::ws::{Message, WebSocket};
use futures_util::stream::{SplitSink, SplitStream};
use futures_util::{SinkExt, StreamExt};
use tokio::sync::{mpsc, watch};

use oocfmt_trace::live::{Event, LiveFrame, Quality, Sink, ViewId, Viewer};
use oocfmt_trace::parts::PartFilter;
use oocfmt_trace::Section;

use crate::encode::{self, MovingQuality};
use crate::host::Hosts;
use crate::protocol::{frame_message, ClientMessage, FrameHeader, ServerMessage, MAX_MESSAGE};
use crate::token::Token;
use crate::tree::PartIndex;

/// What every connection shares.
pub struct App {
    /// The render thread and its views.
    pub viewer: Arc<Viewer>,
    /// The server's token.
    pub token: Token,
    /// The names requests may carry as their Host.
    pub hosts: Hosts,
    /// The hello message, JSON.
    pub hello: String,
    /// The quality a new view starts with.
    pub quality: Quality,
    /// Becomes true when the server stops.
    pub shutdown: watch::Receiver<bool>,
    /// The file's part tree, for the model tree's messages.
    pub tree: PartIndex,
}

/// The newest frame of a view and its number (counting every frame the view was given).
type Latest = Option<(u64, Arc<LiveFrame>)>;

/// An error message, JSON.
pub fn error_json(message: &str) -> String {
    let m = ServerMessage::Error {
        message: message.to_string(),
    };
    serde_json::to_string(&m).unwrap_or_else(|_| r#"{"type":"error","message":"?"}"#.into())
}

/// Serves one socket until either side closes it or the server stops.
pub async fn serve(socket: WebSocket, app: Arc<App>) {
    let (mut tx, mut rx) = socket.split();
    let (frames_tx, frames_rx) = watch::channel::<Latest>(None);
    // Text for the page: the hello, pick answers, errors.
    let (ctl_tx, ctl_rx) = mpsc::unbounded_channel::<String>();
    let texts = ctl_tx.clone();
    let mut given = 0u64;
    let tree_app = Arc::clone(&app);
    let sink: Sink = Box::new(move |e| match e {
        Event::Frame(f) => {
            given += 1;
            frames_tx.send_replace(Some((given, f)));
        }
        Event::Pick(p) => {
            let part = p.hit.as_ref().and_then(|h| h.part);
            let m = ServerMessage::Pick {
                seq: p.seq,
                x: p.pixel.0,
                y: p.pixel.1,
                hit: p.hit,
                lineage: part.map_or_else(Vec::new, |q| tree_app.tree.lineage(q)),
            };
            let _ = texts
                .send(serde_json::to_string(&m).unwrap_or_else(|e| error_json(&e.to_string())));
        }
        Event::Error(m) => {
            let _ = texts.send(error_json(&m));
        }
    });
    let id = match app.viewer.connect(app.quality, sink) {
        Ok(id) => id,
        Err(e) => {
            let _ = tx
                .send(Message::Text(error_json(&e.to_string()).into()))
                .await;
            return;
        }
    };
    let _ = ctl_tx.send(app.hello.clone());
    let sender = tokio::spawn(send_loop(tx, frames_rx, ctl_rx, app.shutdown.clone()));
    receive_loop(&mut rx, &app, id, &ctl_tx).await;
    app.viewer.disconnect(id);
    drop(ctl_tx);
    let _ = sender.await;
}

async fn receive_loop(
    rx: &mut SplitStream<WebSocket>,
    app: &App,
    id: ViewId,
    ctl: &mpsc::UnboundedSender<String>,
) {
    let mut shutdown = app.shutdown.clone();
    loop {
        let msg = tokio::select! {
            _ = shutdown.changed() => break,
            m = rx.next() => m,
        };
        let refused = match msg {
            None | Some(Err(_)) | Some(Ok(Message::Close(_))) => break,
            Some(Ok(Message::Text(t))) => match handle(app, id, t.as_str()) {
                Ok(reply) => {
                    if let Some(r) = reply {
                        let _ = ctl.send(r);
                    }
                    None
                }
                Err(why) => Some(why),
            },
            Some(Ok(Message::Binary(b))) => Some(format!(
                "a binary message of {} bytes refused: messages are JSON text",
                b.len()
            )),
            Some(Ok(Message::Ping(_) | Message::Pong(_))) => None,
        };
        if let Some(why) = refused {
            let _ = ctl.send(error_json(&why));
        }
    }
}

/// Checks one text message and passes it to the viewer; the error says why it was refused.
fn handle(app: &App, id: ViewId, text: &str) -> Result<Option<String>, String> {
    if text.len() > MAX_MESSAGE {
        return Err(format!(
            "a message of {} bytes refused: the limit is {MAX_MESSAGE}",
            text.len()
        ));
    }
    let m: ClientMessage =
        serde_json::from_str(text).map_err(|e| format!("message refused: {e}"))?;
    if let Some((camera, seq)) = m.camera() {
        return app
            .viewer
            .camera(id, camera, seq)
            .map(|()| None)
            .map_err(|e| format!("camera {seq} refused: {e}"));
    }
    match m {
        ClientMessage::Quality { poe, spp } => app
            .viewer
            .quality(id, Quality { poe, spp })
            .map(|()| None)
            .map_err(|e| format!("quality refused: {e}")),
        ClientMessage::Pick { seq, x, y } => {
            app.viewer.pick(id, seq, (x, y));
            Ok(None)
        }
        ClientMessage::Section { plane } => {
            // Normalised and checked here: a plane the tracer cannot use changes nothing.
            let plane = plane
                .map(|p| Section::new(p.normal, p.offset))
                .transpose()
                .map_err(|e| format!("section refused: {e}"))?;
            app.viewer.section(id, plane);
            Ok(None)
        }
        ClientMessage::Parts { hide, isolate } => {
            let parts = &app.viewer.scene().metadata().parts;
            let filter = PartFilter::from_ids(parts, &hide, &isolate, &[])
                .map_err(|e| format!("parts refused: {e}"))?;
            app.viewer.parts(id, filter);
            Ok(None)
        }
        ClientMessage::PartChildren {
            seq,
            parent,
            offset,
        } => {
            let (total, children) = app
                .tree
                .children(parent, offset as usize)
                .map_err(|e| format!("part_children {seq} refused: {e}"))?;
            let m = ServerMessage::PartChildren {
                seq,
                parent,
                offset,
                total,
                children,
            };
            serde_json::to_string(&m)
                .map(Some)
                .map_err(|e| format!("part_children {seq}: {e}"))
        }
        ClientMessage::Camera { .. } => Ok(None),
    }
}

async fn send_loop(
    mut tx: SplitSink<WebSocket, Message>,
    mut frames: watch::Receiver<Latest>,
    mut ctl: mpsc::UnboundedReceiver<String>,
    mut shutdown: watch::Receiver<bool>,
) {
    let mut moving = MovingQuality::new();
    let mut sent = 0u64;
    loop {
        tokio::select! {
            biased;
            _ = shutdown.changed() => {
                let _ = tx.send(Message::Close(None)).await;
                break;
            }
            m = ctl.recv() => {
                let Some(text) = m else { break };
                if tx.send(Message::Text(text.into())).await.is_err() {
                    break;
                }
            }
            r = frames.changed() => {
                if r.is_err() {
                    break;
                }
                let latest = frames.borrow_and_update().clone();
                let Some((n, frame)) = latest else { continue };
                let dropped = n.saturating_sub(sent + 1);
                sent = n;
                let message = match encoded(frame, &mut moving, dropped).await {
                    Ok(bytes) => Message::Binary(bytes.into()),
                    Err(why) => Message::Text(error_json(&why).into()),
                };
                if tx.send(message).await.is_err() {
                    break;
                }
            }
        }
    }
}

/// The frame message of `frame`, encoded off the async threads.
async fn encoded(
    frame: Arc<LiveFrame>,
    moving: &mut MovingQuality,
    dropped: u64,
) -> Result<Vec<u8>, String> {
    let mut q = *moving;
    let (result, q) = tokio::task::spawn_blocking(move || {
        let e = encode::frame(&frame, &mut q, dropped).and_then(|enc| {
            let header = FrameHeader {
                seq: frame.seq,
                format: enc.format,
                quality: enc.quality,
                encode_ms: enc.ms,
                bytes: enc.bytes.len(),
                dropped,
                figures: &frame.figures,
            };
            frame_message(&header, &enc.bytes).map_err(|e| format!("frame header: {e}"))
        });
        (e, q)
    })
    .await
    .map_err(|e| format!("the encoder stopped: {e}"))?;
    *moving = q;
    result
}
