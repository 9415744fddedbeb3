//! `oocfmt-view`: the server behind `oocfmt view`. It knows HTTP, WebSockets, its token and
//! the JSON messages, never traversal: the views, their refine schedule and their frames come
//! from [`oocfmt_trace::live`]. A page embedded in the binary (no build step, no network)
//! flies through the model in the browser.
//!
//! - [`token`]: the per-start secret in the printed URL, checked on every request.
//! - [`host`]: the names it answers to, and the one its URL prints.
//! - [`server`]: routes, the token and Host guard, the Origin check on the socket, headers.
//! - [`socket`]: one WebSocket, one view; the newest frame wins.
//! - [`protocol`]: the messages ([`protocol::ClientMessage`], [`protocol::ServerMessage`],
//!   the binary frame layout).
//! - [`encode`]: JPEG while moving, PNG for the last frame of a still view.
//! - [`tree`]: the part tree as the page's model tree reads it.
//! - [`assets`]: the page, its script and its style.
//!
//! Threads: tokio's runtime (two workers) runs the server and the sockets; frames are
//! encoded on its blocking pool; one render thread ([`Viewer`]) renders every view's frames
//! on rayon's pool. Safe by default: it listens on 127.0.0.1 unless told otherwise.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod assets;
pub mod encode;
pub mod error;
pub mod host;
pub mod protocol;
pub mod server;
pub mod socket;
pub mod token;
pub mod tree;

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::watch;

use oocfmt_trace::live::view::MAX_PIXELS;
use oocfmt_trace::live::{Quality, Viewer};

pub use error::ViewError;
use protocol::{ModelInfo, ServerMessage};
use socket::App;
use token::Token;

/// Where the server listens and what a new view starts with.
#[derive(Clone, Debug)]
pub struct ViewConfig {
    /// The address to listen on: 127.0.0.1 unless the person asks otherwise.
    pub bind: IpAddr,
    /// The port; 0 takes any free one.
    pub port: u16,
    /// The still image a new view refines to.
    pub quality: Quality,
    /// The model's name for the page (its file name).
    pub name: String,
}

impl ViewConfig {
    /// Localhost, any free port, `quality`, named `name`.
    pub fn local(name: &str, quality: Quality) -> ViewConfig {
        ViewConfig {
            bind: IpAddr::V4(Ipv4Addr::LOCALHOST),
            port: 0,
            quality,
            name: name.to_string(),
        }
    }
}

/// A started server.
pub struct Running {
    url: String,
    host: String,
    addr: SocketAddr,
    token: String,
    stop: watch::Sender<bool>,
    task: tokio::task::JoinHandle<std::io::Result<()>>,
}

/// How long stopping waits for open connections to finish.
const STOP_GRACE: Duration = Duration::from_secs(5);

impl Running {
    /// The page's URL, token included: what `oocfmt view` prints.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// The host its URL names: the address listened on, or this machine's name when that is
    /// every interface ([`host::url_host`]).
    pub fn host(&self) -> &str {
        &self.host
    }

    /// The address it listens on (the port chosen when 0 was asked).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The token.
    pub fn token(&self) -> &str {
        &self.token
    }

    /// Stops: sockets are closed, then the listener, waiting at most a few seconds for open
    /// requests.
    pub async fn stop(self) -> Result<(), ViewError> {
        let _ = self.stop.send(true);
        match tokio::time::timeout(STOP_GRACE, self.task).await {
            Ok(Ok(Err(e))) => Err(ViewError::Serve(e)),
            _ => Ok(()),
        }
    }
}

/// The hello message for `viewer`'s model.
fn hello(viewer: &Viewer, config: &ViewConfig) -> String {
    let m = viewer.scene().metadata();
    let s = &m.scene;
    let world = |p: [f32; 3]| [0, 1, 2].map(|k| s.origin[k] + f64::from(p[k]));
    let msg = ServerMessage::Hello {
        model: ModelInfo {
            name: config.name.clone(),
            triangles: m.counts.triangles,
            bounds_min: world(s.bounds_min),
            bounds_max: world(s.bounds_max),
            parts: m.parts.len(),
        },
        quality: config.quality.into(),
        target_ms: viewer.options().target_ms,
        max_pixels: MAX_PIXELS,
        version: env!("CARGO_PKG_VERSION"),
    };
    serde_json::to_string(&msg).unwrap_or_default()
}

/// Starts serving `viewer` on the runtime this is called on.
pub async fn start(viewer: Arc<Viewer>, config: &ViewConfig) -> Result<Running, ViewError> {
    let token = Token::random()?;
    let addr = SocketAddr::new(config.bind, config.port);
    let listener = tokio::net::TcpListener::bind(addr)
        .await
        .map_err(|source| ViewError::Bind { addr, source })?;
    let addr = listener
        .local_addr()
        .map_err(|source| ViewError::Bind { addr, source })?;
    let (stop, shutdown) = watch::channel(false);
    let mut on_stop = shutdown.clone();
    let host = host::url_host(addr.ip(), host::machine_name().as_deref());
    let url = format!("http://{host}:{}/?token={}", addr.port(), token.as_str());
    let viewer_parts = viewer.scene().metadata().parts.clone();
    let app = Arc::new(App {
        hello: hello(&viewer, config),
        viewer,
        token: token.clone(),
        hosts: host::Hosts::new(&host),
        quality: config.quality,
        shutdown,
        tree: tree::PartIndex::new(&viewer_parts),
    });
    let router = server::router(app);
    let task = tokio::spawn(async move {
        axum::serve(listener, router)
            .with_graceful_shutdown(async move {
                let _ = on_stop.changed().await;
            })
            .await
    });
    Ok(Running {
        url,
        host,
        addr,
        token: token.as_str().to_string(),
        stop,
        task,
    })
}

/// Serves `viewer` until Ctrl-C, on a runtime of its own; `ready` gets the server once it
/// listens (its URL to print). The render thread stops when this returns.
pub fn run(
    viewer: Viewer,
    config: &ViewConfig,
    ready: impl FnOnce(&Running),
) -> Result<(), ViewError> {
    let viewer = Arc::new(viewer);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("oocfmt-view")
        .enable_all()
        .build()
        .map_err(ViewError::Runtime)?;
    let result = runtime.block_on(async {
        let running = start(Arc::clone(&viewer), config).await?;
        ready(&running);
        let signal = tokio::signal::ctrl_c().await.map_err(ViewError::Signal);
        let stopped = running.stop().await;
        signal.and(stopped)
    });
    // Tasks still holding the viewer end with the runtime; the render thread is joined after.
    drop(runtime);
    drop(viewer);
    result
}
