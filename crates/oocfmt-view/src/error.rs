//! The server's errors: each says what failed and where (the address, the source).

use std::net::SocketAddr;

use oocfmt_trace::TraceError;

/// Why the viewer's server could not start or went down.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// The address could not be listened on (in use, not this machine's, not allowed).
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address asked for.
        addr: SocketAddr,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The asynchronous runtime could not start.
    #[error("cannot start the server's runtime: {0}")]
    Runtime(std::io::Error),
    /// Accepting connections failed.
    #[error("the server failed: {0}")]
    Serve(std::io::Error),
    /// The operating system gave no random bytes for the token.
    #[error("no random source for the server's token: {0}")]
    Random(String),
    /// Waiting for Ctrl-C failed.
    #[error("cannot wait for Ctrl-C: {0}")]
    Signal(std::io::Error),
    /// The tracer refused a setting or could not start its render thread.
    #[error(transparent)]
    Trace(#[from] TraceError),
}
