//! The viewer's server for real, on a free port of 127.0.0.1: the token on every request, the
//! Origin on the socket, on every interface a URL naming this machine and only its own names
//! answered, only the page's own assets, cameras in and frames out over a
//! WebSocket with the last frame of a still view equal to the blocking cache's full-detail
//! render bit for bit, picks, refused messages answered and changing nothing, several tabs, and a
//! clean stop.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::io::{Read, Write};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::http::HeaderValue;
use tokio_tungstenite::tungstenite::{Error as WsError, Message};
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

use oocfmt_build::convert::{convert, ConvertOptions};
use oocfmt_build::progress::NoProgress;
use oocfmt_scenes::mandelbulb::{self, MandelbulbOptions};
use oocfmt_trace::cache::asynchronous::AsyncOptions;
use oocfmt_trace::live::{LiveOptions, Quality, Viewer};
use oocfmt_trace::session::{stored_point, Cache, CacheKind};
use oocfmt_trace::{render, BlockingCache, Camera, RenderOptions, Scene};
use oocfmt_view::{start, Running, ViewConfig};

type Ws = WebSocketStream<MaybeTlsStream<TcpStream>>;

fn mandelbulb(dir: &Path) -> PathBuf {
    let obj = dir.join("mb.obj");
    let opts = MandelbulbOptions {
        triangles: 6_000,
        ..MandelbulbOptions::default()
    };
    mandelbulb::write_obj(&obj, &opts, &mut |_, _| {}).unwrap();
    let out = dir.join("mb.oocf");
    let opts = ConvertOptions {
        mem_limit: 1 << 30,
        ..ConvertOptions::default()
    };
    convert(&[obj], &out, &opts, &mut NoProgress).unwrap();
    out
}

struct Fixture {
    _dir: tempfile::TempDir,
    scene: Arc<Scene>,
    running: Running,
}

async fn serve() -> Fixture {
    serve_on(IpAddr::V4(Ipv4Addr::LOCALHOST)).await
}

async fn serve_on(bind: IpAddr) -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let path = mandelbulb(dir.path());
    let (scene, cache) = Cache::open(
        &path,
        None,
        CacheKind::Async,
        64 << 20,
        &AsyncOptions::default(),
        None,
    )
    .unwrap();
    let opts = LiveOptions {
        target_ms: 10.0,
        still_ms: 30.0,
        ..LiveOptions::DEFAULT
    };
    let viewer = Viewer::start(Arc::clone(&scene), cache, RenderOptions::DEFAULT, opts).unwrap();
    let config = ViewConfig {
        bind,
        ..ViewConfig::local("mb.oocf", Quality { poe: 0.0, spp: 1 })
    };
    let running = start(Arc::new(viewer), &config).await.unwrap();
    Fixture {
        _dir: dir,
        scene,
        running,
    }
}

/// A raw HTTP/1.1 GET of `target`, exactly as written (no client normalises the path):
/// the status and the whole response.
fn get(addr: SocketAddr, target: &str) -> (u16, String) {
    get_as(addr, &addr.to_string(), target)
}

/// [`get`] with `host` as the Host header.
fn get_as(addr: SocketAddr, host: &str, target: &str) -> (u16, String) {
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(
        s,
        "GET {target} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out).unwrap();
    let text = String::from_utf8_lossy(&out).into_owned();
    let status = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (status, text)
}

async fn socket(addr: SocketAddr, query: &str, origin: Option<&str>) -> Result<Ws, WsError> {
    let mut req = format!("ws://{addr}/ws{query}")
        .into_client_request()
        .unwrap();
    if let Some(o) = origin {
        req.headers_mut()
            .insert("Origin", HeaderValue::from_str(o).unwrap());
    }
    tokio_tungstenite::connect_async(req)
        .await
        .map(|(ws, _)| ws)
}

/// A socket to `addr` as a browser that opened `host` (the Host header) from a page of
/// `origin`: the HTTP status of its refusal, or None when it opened.
async fn socket_as(addr: SocketAddr, host: &str, query: &str, origin: &str) -> Option<u16> {
    let mut req = format!("ws://{host}/ws{query}")
        .into_client_request()
        .unwrap();
    req.headers_mut()
        .insert("Origin", HeaderValue::from_str(origin).unwrap());
    let tcp = TcpStream::connect(addr).await.unwrap();
    match tokio_tungstenite::client_async(req, tcp).await {
        Ok(_) => None,
        Err(WsError::Http(resp)) => Some(resp.status().as_u16()),
        Err(e) => panic!("refused without an HTTP status: {e}"),
    }
}

fn refused_with(r: Result<Ws, WsError>) -> u16 {
    match r {
        Err(WsError::Http(resp)) => resp.status().as_u16(),
        Err(e) => panic!("refused without an HTTP status: {e}"),
        Ok(_) => panic!("the socket was accepted"),
    }
}

/// The next message within 20 s.
async fn next(ws: &mut Ws) -> Message {
    match tokio::time::timeout(Duration::from_secs(20), ws.next()).await {
        Ok(Some(Ok(m))) => m,
        other => panic!("no message: {other:?}"),
    }
}

async fn next_text(ws: &mut Ws) -> serde_json::Value {
    loop {
        if let Message::Text(t) = next(ws).await {
            return serde_json::from_str(t.as_str()).unwrap();
        }
    }
}

/// A frame message: its header and image file.
fn frame(bytes: &[u8]) -> (serde_json::Value, Vec<u8>) {
    assert_eq!(&bytes[..4], b"OVF1");
    let n = u32::from_le_bytes(bytes[4..8].try_into().unwrap()) as usize;
    let header = serde_json::from_slice(&bytes[8..8 + n]).unwrap();
    (header, bytes[8 + n..].to_vec())
}

/// Frames until the last one of camera `seq`; every header on the way.
async fn until_last(ws: &mut Ws, seq: u64) -> (Vec<serde_json::Value>, Vec<u8>) {
    let mut headers = Vec::new();
    loop {
        if let Message::Binary(b) = next(ws).await {
            let (h, image) = frame(&b);
            headers.push(h.clone());
            if h["seq"] == seq && h["figures"]["last"] == true {
                return (headers, image);
            }
        }
    }
}

fn png_rgb(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
        .read_info()
        .unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// The camera message of `c` (stored coordinates) in world coordinates.
fn camera_json(scene: &Scene, c: &Camera, seq: u64) -> String {
    let o = scene.metadata().scene.origin;
    let w = |p: [f64; 3]| [0, 1, 2].map(|k| p[k] + o[k]);
    serde_json::json!({
        "type": "camera", "seq": seq, "eye": w(c.eye), "look_at": w(c.look_at), "up": c.up,
        "fov_y": c.fov_y, "width": c.width, "height": c.height,
    })
    .to_string()
}

/// `c` as the server stores it: to world coordinates and back.
fn round_trip(scene: &Scene, c: &Camera) -> Camera {
    let o = scene.metadata().scene.origin;
    let w = |p: [f64; 3]| [0, 1, 2].map(|k| p[k] + o[k]);
    Camera {
        eye: stored_point(scene, w(c.eye)),
        look_at: stored_point(scene, w(c.look_at)),
        ..*c
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_request_needs_the_token_and_only_the_page_is_served() {
    let f = serve().await;
    let (addr, token) = (f.running.addr(), f.running.token().to_string());
    assert!(addr.ip().is_loopback());
    assert_eq!(
        f.running.url(),
        format!("http://{addr}/?token={token}"),
        "the URL carries the token"
    );
    let t = |path: &str| format!("{path}?token={token}");
    let (status, page) = get(addr, &t("/"));
    assert_eq!(status, 200, "{page}");
    assert!(page.contains(&format!("app.js?token={token}")));
    for header in [
        "content-security-policy:",
        "cache-control: no-store",
        "referrer-policy: no-referrer",
        "x-content-type-options: nosniff",
    ] {
        assert!(page.to_ascii_lowercase().contains(header), "{header}");
    }
    let (status, js) = get(addr, &t("/app.js"));
    assert_eq!(status, 200);
    assert!(js.contains("text/javascript"));
    assert_eq!(get(addr, &t("/style.css")).0, 200);
    // No token, a wrong one, one of the wrong length, one in another parameter.
    for target in ["/", "/app.js", "/ws", "/nothing", "/?tok=1"] {
        assert_eq!(get(addr, target).0, 401, "{target}");
    }
    let wrong = "0".repeat(token.len());
    for target in [
        format!("/?token={wrong}"),
        format!("/?token={}", &token[1..]),
        format!("/app.js?token={}", token.to_uppercase()),
        format!("/?token=%{}", &token[1..]),
    ] {
        assert_eq!(get(addr, &target).0, 403, "{target}");
    }
    // With the token, anything but the page and its assets is not found.
    for path in [
        "/../Cargo.toml",
        "/..%2fCargo.toml",
        "/%2e%2e/%2e%2e/Cargo.toml",
        "/app.js/",
        "/./app.js",
        "/assets/app.js",
        "//etc/passwd",
        "/etc/passwd",
        "/index.html",
        "/%61pp.js",
        "/app.js%00",
        "/ws/../app.js",
    ] {
        assert_eq!(get(addr, &t(path)).0, 404, "{path}");
    }
    f.running.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_socket_needs_the_token_and_this_servers_origin() {
    let f = serve().await;
    let (addr, token) = (f.running.addr(), f.running.token().to_string());
    let origin = format!("http://{addr}");
    let good = format!("?token={token}");
    assert_eq!(refused_with(socket(addr, "", Some(&origin)).await), 401);
    let wrong = format!("?token={}", "f".repeat(token.len()));
    assert_eq!(refused_with(socket(addr, &wrong, Some(&origin)).await), 403);
    for o in [
        None,
        Some("http://evil.example"),
        Some("http://127.0.0.1:1"),
        Some("null"),
    ] {
        assert_eq!(refused_with(socket(addr, &good, o).await), 403, "{o:?}");
    }
    let mut ws = socket(addr, &good, Some(&origin)).await.unwrap();
    let hello = next_text(&mut ws).await;
    assert_eq!(hello["type"], "hello");
    assert_eq!(hello["model"]["name"], "mb.oocf");
    assert!(
        hello["model"]["triangles"].as_u64().unwrap() > 1000,
        "{hello}"
    );
    assert_eq!(hello["quality"]["poe"], 0.0);
    f.running.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn on_every_interface_the_url_names_this_machine_and_only_its_names_are_answered() {
    let f = serve_on(IpAddr::V4(Ipv4Addr::UNSPECIFIED)).await;
    let (addr, token) = (f.running.addr(), f.running.token().to_string());
    assert!(addr.ip().is_unspecified());
    let host = f.running.host().to_string();
    assert_eq!(
        f.running.url(),
        format!("http://{host}:{}/?token={token}", addr.port())
    );
    assert!(!f.running.url().contains("0.0.0.0"), "{}", f.running.url());
    assert!(
        host.parse::<IpAddr>()
            .map_or(true, |ip| !ip.is_unspecified()),
        "{host}"
    );
    if let Some(name) = oocfmt_view::host::machine_name() {
        assert_eq!(host, name, "the URL names this machine");
    }
    // Reached over loopback, as a browser that opened the printed URL, or localhost.
    let local = SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), addr.port());
    let printed = format!("{host}:{}", addr.port());
    let page = format!("/?token={token}");
    for h in [
        printed.as_str(),
        &format!("localhost:{}", addr.port()),
        &local.to_string(),
    ] {
        assert_eq!(get_as(local, h, &page).0, 200, "{h}");
    }
    // A page whose own name was pointed at this machine is refused, token or not.
    for h in ["evil.example", "evil.example:80", "vm.evil.example"] {
        assert_eq!(get_as(local, h, &page).0, 403, "{h}");
    }
    let query = format!("?token={token}");
    let origin = format!("http://{printed}");
    assert_eq!(socket_as(local, &printed, &query, &origin).await, None);
    for (h, o) in [
        (printed.as_str(), "http://evil.example"),
        (printed.as_str(), "null"),
        ("evil.example:8800", "http://evil.example:8800"),
    ] {
        assert_eq!(
            socket_as(local, h, &query, o).await,
            Some(403),
            "Host {h}, Origin {o}"
        );
    }
    f.running.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cameras_in_frames_out_and_the_still_frame_is_full_detail_bit_for_bit() {
    let f = serve().await;
    let (addr, token) = (f.running.addr(), f.running.token().to_string());
    let origin = format!("http://{addr}");
    let mut ws = socket(addr, &format!("?token={token}"), Some(&origin))
        .await
        .unwrap();
    assert_eq!(next_text(&mut ws).await["type"], "hello");
    let m = f.scene.metadata();
    let base = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, 120, 90);
    // A drag: cameras faster than frames; the last one wins.
    for seq in 1..=6 {
        let mut c = base;
        c.eye[1] += seq as f64 * 0.02;
        ws.send(Message::Text(camera_json(&f.scene, &c, seq).into()))
            .await
            .unwrap();
    }
    let (headers, png) = until_last(&mut ws, 6).await;
    let first = &headers[0];
    assert_eq!(first["format"], "jpeg", "{first}");
    assert_eq!(headers.last().unwrap()["format"], "png");
    let seqs: Vec<u64> = headers.iter().map(|h| h["seq"].as_u64().unwrap()).collect();
    assert!(seqs.windows(2).all(|w| w[0] <= w[1]), "{seqs:?}");
    let mut c6 = base;
    c6.eye[1] += 6.0 * 0.02;
    let blocking = BlockingCache::new(Arc::clone(&f.scene), 64 << 20);
    let (want, _) = render(
        &f.scene,
        &blocking,
        &round_trip(&f.scene, &c6),
        &RenderOptions::DEFAULT,
    )
    .unwrap();
    let (w, h, rgb) = png_rgb(&png);
    assert_eq!((w, h), (120, 90));
    assert!(
        rgb == want.rgb,
        "the still frame differs from render --poe 0 --cache blocking"
    );

    // Picks: the centre is the model, at the still frame's depth; a corner is background;
    // a pixel outside the image is an error.
    for (seq, x, y) in [(1, 60, 45), (2, 0, 0), (3, 500, 5)] {
        let m = format!(r#"{{"type":"pick","seq":{seq},"x":{x},"y":{y}}}"#);
        ws.send(Message::Text(m.into())).await.unwrap();
    }
    let centre = next_text(&mut ws).await;
    assert_eq!(
        (centre["type"].as_str(), centre["seq"].as_u64()),
        (Some("pick"), Some(1))
    );
    let distance = centre["hit"]["distance"].as_f64().unwrap();
    let depth = f64::from(want.depth[45 * 120 + 60]);
    assert!(
        (distance - depth).abs() <= 1e-4 * depth,
        "{centre} against {depth}"
    );
    assert_eq!(centre["hit"]["point"].as_array().map(Vec::len), Some(3));
    let corner = next_text(&mut ws).await;
    assert_eq!(
        (corner["seq"].as_u64(), &corner["hit"]),
        (Some(2), &serde_json::Value::Null)
    );
    let outside = next_text(&mut ws).await;
    assert!(
        outside["message"].as_str().unwrap().contains("pick 3"),
        "{outside}"
    );

    // Refused messages are answered and change nothing: no frame follows them.
    let refusals = [
        ("not json", "message refused"),
        (
            r#"{"type":"quality","poe":1,"spp":2,"more":1}"#,
            "unknown field",
        ),
        (r#"{"type":"shell","cmd":"rm"}"#, "unknown variant"),
        (r#"{"type":"quality","poe":-1,"spp":2}"#, "quality refused"),
        (r#"{"type":"quality","poe":1,"spp":0}"#, "quality refused"),
    ];
    for (text, says) in refusals {
        ws.send(Message::Text(text.into())).await.unwrap();
        let e = next_text(&mut ws).await;
        assert_eq!(e["type"], "error");
        assert!(e["message"].as_str().unwrap().contains(says), "{text}: {e}");
    }
    let mut bad = c6;
    bad.fov_y = 0.0;
    ws.send(Message::Text(camera_json(&f.scene, &bad, 7).into()))
        .await
        .unwrap();
    let e = next_text(&mut ws).await;
    assert!(
        e["message"].as_str().unwrap().contains("camera 7 refused"),
        "{e}"
    );
    let big = Camera {
        width: 9000,
        height: 9000,
        ..c6
    };
    ws.send(Message::Text(camera_json(&f.scene, &big, 8).into()))
        .await
        .unwrap();
    assert!(next_text(&mut ws).await["message"]
        .as_str()
        .unwrap()
        .contains("camera 8 refused"));
    let oversize = format!(
        "{{\"type\":\"quality\",\"poe\":1,\"spp\":2,\"pad\":\"{}\"}}",
        "x".repeat(5000)
    );
    ws.send(Message::Text(oversize.into())).await.unwrap();
    assert!(next_text(&mut ws).await["message"]
        .as_str()
        .unwrap()
        .contains("the limit is 4096"));
    ws.send(Message::Binary(vec![1, 2, 3].into()))
        .await
        .unwrap();
    assert!(next_text(&mut ws).await["message"]
        .as_str()
        .unwrap()
        .contains("binary"));
    match tokio::time::timeout(Duration::from_millis(400), ws.next()).await {
        Err(_) => {}
        Ok(m) => panic!("a refused message changed something: {m:?}"),
    }
    // The connection still works: a new quality refines again, to 2 samples.
    ws.send(Message::Text(
        r#"{"type":"quality","poe":0,"spp":2}"#.into(),
    ))
    .await
    .unwrap();
    let (headers, _) = until_last(&mut ws, 6).await;
    assert_eq!(headers.last().unwrap()["figures"]["samples"], 2);
    // A message past the socket's own limit closes the connection.
    ws.send(Message::Text("x".repeat(100_000).into()))
        .await
        .unwrap();
    let closed = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            match ws.next().await {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return,
                Some(Ok(_)) => {}
            }
        }
    })
    .await;
    assert!(closed.is_ok(), "the connection stayed open");
    f.running.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn several_tabs_get_their_own_frames_and_stop_closes_them() {
    let f = serve().await;
    let (addr, token) = (f.running.addr(), f.running.token().to_string());
    let origin = format!("http://{addr}");
    let q = format!("?token={token}");
    let (mut a, mut b) = (
        socket(addr, &q, Some(&origin)).await.unwrap(),
        socket(addr, &q, Some(&origin)).await.unwrap(),
    );
    next_text(&mut a).await;
    next_text(&mut b).await;
    let m = f.scene.metadata();
    let ca = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, 64, 48);
    let cb = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, 80, 40);
    a.send(Message::Text(camera_json(&f.scene, &ca, 1).into()))
        .await
        .unwrap();
    b.send(Message::Text(camera_json(&f.scene, &cb, 1).into()))
        .await
        .unwrap();
    let (_, pa) = until_last(&mut a, 1).await;
    let (_, pb) = until_last(&mut b, 1).await;
    assert_eq!(png_rgb(&pa).0, 64);
    assert_eq!(png_rgb(&pb).0, 80);
    f.running.stop().await.unwrap();
    for ws in [&mut a, &mut b] {
        let closed = tokio::time::timeout(Duration::from_secs(10), async {
            loop {
                match ws.next().await {
                    None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return,
                    Some(Ok(_)) => {}
                }
            }
        })
        .await;
        assert!(closed.is_ok(), "a tab stayed connected after stop");
    }
    assert!(
        std::net::TcpStream::connect(addr).is_err(),
        "the port still accepts connections"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_section_message_cuts_the_still_frame_and_a_bad_plane_is_refused() {
    let f = serve().await;
    let (addr, token) = (f.running.addr(), f.running.token().to_string());
    let origin = format!("http://{addr}");
    let mut ws = socket(addr, &format!("?token={token}"), Some(&origin))
        .await
        .unwrap();
    assert_eq!(next_text(&mut ws).await["type"], "hello");
    let m = f.scene.metadata();
    let c = Camera::framing(m.scene.bounds_min, m.scene.bounds_max, 96, 72);
    ws.send(Message::Text(camera_json(&f.scene, &c, 1).into()))
        .await
        .unwrap();
    let (_, whole_png) = until_last(&mut ws, 1).await;
    // The plane x = the box's middle (world coordinates), keeping the far half.
    let mid = f64::from(m.scene.bounds_min[0] + m.scene.bounds_max[0]) / 2.0 + m.scene.origin[0];
    let plane = oocfmt_trace::Section::axis(0, mid).unwrap();
    let text = serde_json::json!({"type": "section", "plane": plane}).to_string();
    ws.send(Message::Text(text.into())).await.unwrap();
    let (_, cut_png) = until_last(&mut ws, 1).await;
    // The reference from a scene of its own: the server's views set their planes on theirs.
    let reference = Arc::new(Scene::open(&f._dir.path().join("mb.oocf")).unwrap());
    reference.set_section(Some(plane));
    let blocking = BlockingCache::new(Arc::clone(&reference), 64 << 20);
    let camera = round_trip(&f.scene, &c);
    let (want, _) = render(&reference, &blocking, &camera, &RenderOptions::DEFAULT).unwrap();
    let (_, _, rgb) = png_rgb(&cut_png);
    assert!(
        rgb == want.rgb,
        "the cut still frame differs from render --section"
    );
    assert_ne!(png_rgb(&whole_png).2, rgb, "the plane cut something away");
    // A plane that is not one is refused and changes nothing.
    for bad in [
        r#"{"type":"section","plane":{"normal":[0,0,0],"offset":1}}"#,
        r#"{"type":"section","plane":{"normal":[1,0,0],"offset":"x"}}"#,
    ] {
        ws.send(Message::Text(bad.into())).await.unwrap();
        let e = next_text(&mut ws).await;
        assert_eq!(e["type"], "error", "{bad}: {e}");
    }
    match tokio::time::timeout(Duration::from_millis(400), ws.next()).await {
        Err(_) => {}
        Ok(m) => panic!("a refused section changed something: {m:?}"),
    }
    // No plane: the whole model again.
    ws.send(Message::Text(r#"{"type":"section","plane":null}"#.into()))
        .await
        .unwrap();
    let (_, again) = until_last(&mut ws, 1).await;
    assert!(png_rgb(&again).2 == png_rgb(&whole_png).2);
    f.running.stop().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tree_messages_are_answered_and_ids_past_the_part_table_refused() {
    let f = serve().await;
    let (addr, token) = (f.running.addr(), f.running.token().to_string());
    let origin = format!("http://{addr}");
    let mut ws = socket(addr, &format!("?token={token}"), Some(&origin))
        .await
        .unwrap();
    assert_eq!(next_text(&mut ws).await["type"], "hello");
    // The Mandelbulb has no parts: an empty top level, and any id is past the table.
    ws.send(Message::Text(
        r#"{"type":"part_children","seq":4,"parent":null}"#.into(),
    ))
    .await
    .unwrap();
    let top = next_text(&mut ws).await;
    assert_eq!(
        (
            top["type"].as_str(),
            top["seq"].as_u64(),
            top["total"].as_u64()
        ),
        (Some("part_children"), Some(4), Some(0)),
        "{top}"
    );
    for (text, says) in [
        (
            r#"{"type":"part_children","seq":5,"parent":0}"#,
            "part_children 5 refused",
        ),
        (r#"{"type":"parts","hide":[0]}"#, "parts refused"),
        (r#"{"type":"parts","isolate":[3]}"#, "parts refused"),
    ] {
        ws.send(Message::Text(text.into())).await.unwrap();
        let e = next_text(&mut ws).await;
        assert_eq!(e["type"], "error", "{text}: {e}");
        assert!(e["message"].as_str().unwrap().contains(says), "{text}: {e}");
    }
    // Nothing hidden is a filter any file takes.
    ws.send(Message::Text(r#"{"type":"parts","hide":[]}"#.into()))
        .await
        .unwrap();
    match tokio::time::timeout(Duration::from_millis(300), ws.next()).await {
        Err(_) => {}
        Ok(m) => panic!("an empty parts message was answered: {m:?}"),
    }
    f.running.stop().await.unwrap();
}
