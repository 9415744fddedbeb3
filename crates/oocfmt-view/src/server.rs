//! HTTP: the routes, the token guard in front of all of them, the Origin check on the
//! WebSocket upgrade, and the headers every answer carries.
//!
//! Order of refusals: no token → 401, a wrong one → 403 (before anything else, so a stranger
//! learns nothing, not even which paths exist); a Host that is not one of this server's names
//! ([`crate::host`]) → 403; then a path that is not the page, one of its assets or the socket
//! → 404; a WebSocket whose Origin is not this server's own → 403.

use std::sync::Arc;

use axum::body::Body;
use axum::extract::ws::WebSocketUpgrade;
use axum::extract::{Request, State};
use axum::http::header::{self, HeaderMap, HeaderValue};
use axum::http::{StatusCode, Uri};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;

use crate::assets;
use crate::host::Hosts;
use crate::socket::{self, App};
use crate::token;

/// The page's policy: its own scripts, styles and socket, frames as blobs; never in a frame.
const CSP: &str =
    "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; \
                   connect-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'";

/// The router over `app`.
pub fn router(app: Arc<App>) -> Router {
    Router::new()
        .route("/", get(index))
        .route("/ws", get(upgrade))
        .fallback(asset)
        .layer(middleware::from_fn_with_state(Arc::clone(&app), guard))
        .with_state(app)
}

/// Refuses a request without the token (401), with a wrong one (403) or for a host that is
/// not this server's (403), and puts the headers every answer carries on the others: not
/// cached, not sniffed, no referrer (the URL holds the token), never framed.
async fn guard(State(app): State<Arc<App>>, req: Request, next: Next) -> Response {
    let mut resp = match token::in_query(req.uri().query()) {
        None => text(
            StatusCode::UNAUTHORIZED,
            "this server needs its token: open the URL `oocfmt view` printed\n",
        ),
        Some(t) if !app.token.matches(t) => text(StatusCode::FORBIDDEN, "wrong token\n"),
        Some(_) if !host_of(req.headers()).is_some_and(|h| app.hosts.allows(h)) => text(
            StatusCode::FORBIDDEN,
            "this server does not answer to that host name: open the URL `oocfmt view` printed\n",
        ),
        Some(_) => next.run(req).await,
    };
    let h = resp.headers_mut();
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    resp
}

fn text(status: StatusCode, body: &'static str) -> Response {
    (
        status,
        [(header::CONTENT_TYPE, "text/plain; charset=utf-8")],
        body,
    )
        .into_response()
}

/// The page, with the token in its assets' URLs.
async fn index(State(app): State<Arc<App>>) -> Response {
    let mut resp = Response::new(Body::from(assets::index(app.token.as_str())));
    let h = resp.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/html; charset=utf-8"),
    );
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(CSP),
    );
    resp
}

/// One of the page's assets by its exact path, else 404.
async fn asset(uri: Uri) -> Response {
    match assets::asset(uri.path()) {
        Some(a) => ([(header::CONTENT_TYPE, a.mime)], a.body).into_response(),
        None => text(StatusCode::NOT_FOUND, "not found\n"),
    }
}

/// The Host header, when it is text.
fn host_of(headers: &HeaderMap) -> Option<&str> {
    headers.get(header::HOST).and_then(|v| v.to_str().ok())
}

/// Whether `headers` carry a Host this server answers to and an Origin that is this server as
/// the browser reached it (`http://` and that Host): a page from anywhere else cannot open the
/// socket, even with the token.
fn same_origin(headers: &HeaderMap, hosts: &Hosts) -> bool {
    let origin = headers
        .get(header::ORIGIN)
        .and_then(|v: &HeaderValue| v.to_str().ok());
    match (host_of(headers), origin) {
        (Some(host), Some(origin)) => {
            hosts.allows(host)
                && origin
                    .strip_prefix("http://")
                    .is_some_and(|o| o.eq_ignore_ascii_case(host))
        }
        _ => false,
    }
}

/// The WebSocket, when its Origin is this server.
async fn upgrade(
    State(app): State<Arc<App>>,
    headers: HeaderMap,
    ws: WebSocketUpgrade,
) -> Response {
    if !same_origin(&headers, &app.hosts) {
        return text(
            StatusCode::FORBIDDEN,
            "WebSocket refused: its Origin is not this server\n",
        );
    }
    ws.max_message_size(crate::protocol::MAX_SOCKET_MESSAGE)
        .max_frame_size(crate::protocol::MAX_SOCKET_MESSAGE)
        .on_upgrade(move |s| socket::serve(s, app))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(pairs: &[(header::HeaderName, &str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            if let Ok(v) = HeaderValue::from_str(v) {
                h.insert(k.clone(), v);
            }
        }
        h
    }

    #[test]
    fn only_this_servers_origin_opens_the_socket() {
        let hosts = Hosts::new("127.0.0.1");
        let host = (header::HOST, "127.0.0.1:8080");
        assert!(same_origin(
            &headers(&[host.clone(), (header::ORIGIN, "http://127.0.0.1:8080")]),
            &hosts
        ));
        for origin in [
            "http://127.0.0.1:8081",
            "http://evil.example",
            "https://127.0.0.1:8080",
            "null",
            "http://127.0.0.1:8080.evil.example",
        ] {
            let h = headers(&[host.clone(), (header::ORIGIN, origin)]);
            assert!(!same_origin(&h, &hosts), "{origin}");
        }
        assert!(!same_origin(&headers(&[host]), &hosts), "no Origin");
        // A page whose own name points here (DNS rebinding): Origin and Host agree, the name
        // is not this server's.
        let rebound = headers(&[
            (header::HOST, "evil.example:8080"),
            (header::ORIGIN, "http://evil.example:8080"),
        ]);
        assert!(!same_origin(&rebound, &hosts));
    }
}
