//! `oocfmt view` as a person runs it: the first line on standard output is the page's URL with
//! its token, on 127.0.0.1; the page answers with the token only; Ctrl-C (SIGINT) stops the
//! server with exit status 0; bad flags and a port in use exit 2.

use crate::common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::{gen, oocfmt, run_ok};

/// `oocfmt view ARGS` started with its standard output piped.
fn spawn(args: &[&str], cwd: &std::path::Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_oocfmt"))
        .arg("view")
        .args(args)
        .current_dir(cwd)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start oocfmt view: {e}"))
}

/// The status code of a GET of `target` at `host:port`.
fn status(addr: &str, target: &str) -> u16 {
    let mut s = TcpStream::connect(addr).unwrap_or_else(|e| panic!("{addr}: {e}"));
    let _ = s.set_read_timeout(Some(Duration::from_secs(10)));
    let _ = write!(
        s,
        "GET {target} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    );
    let mut out = String::new();
    let _ = s.read_to_string(&mut out);
    out.split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0)
}

/// Waits at most `limit` for `child` to exit; its exit code (None: still running, killed).
fn wait_for(child: &mut Child, limit: Duration) -> Option<i32> {
    let end = Instant::now() + limit;
    while Instant::now() < end {
        if let Ok(Some(s)) = child.try_wait() {
            return s.code();
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let _ = child.wait();
    None
}

#[test]
fn view_prints_its_url_first_serves_with_the_token_and_stops_on_ctrl_c() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    gen(dir.path(), "mandelbulb", "4000", "mb.obj");
    run_ok(
        &["convert", "mb.obj", "-o", "mb.oocf", "--quiet"],
        dir.path(),
    );
    let mut child = spawn(&["mb.oocf", "--port", "0"], dir.path());
    let mut line = String::new();
    if let Some(out) = child.stdout.take() {
        let _ = BufReader::new(out).read_line(&mut line);
    }
    let url = line.trim().to_string();
    let rest = url.strip_prefix("http://127.0.0.1:").unwrap_or_else(|| {
        let _ = child.kill();
        panic!("the first line is not a local URL: {url:?}")
    });
    let (port, token) = rest.split_once("/?token=").unwrap_or(("", ""));
    assert!(port.parse::<u16>().is_ok_and(|p| p > 0), "{url}");
    assert!(
        token.len() == 32 && token.bytes().all(|c| c.is_ascii_hexdigit()),
        "{url}"
    );
    let addr = format!("127.0.0.1:{port}");
    assert_eq!(status(&addr, &format!("/?token={token}")), 200);
    assert_eq!(status(&addr, "/"), 401);
    assert_eq!(status(&addr, "/?token=00"), 403);
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
    assert!(killed.is_ok_and(|s| s.success()), "cannot send SIGINT");
    assert_eq!(
        wait_for(&mut child, Duration::from_secs(20)),
        Some(0),
        "Ctrl-C did not stop the server cleanly"
    );
    assert!(TcpStream::connect(&addr).is_err(), "the port is still open");
}

#[test]
fn view_refuses_bad_flags_and_a_port_in_use() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let cwd = dir.path();
    for args in [
        vec!["view", "none.oocf"],
        vec!["view", "none.oocf", "--target-ms", "0"],
        vec!["view", "none.oocf", "--bind", "256.1.1.1"],
        vec!["view", "none.oocf", "--spp", "0"],
        vec!["view", "none.oocf", "--poe", "-1"],
    ] {
        let o = oocfmt(&args, cwd);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
    }
    gen(cwd, "mandelbulb", "2000", "mb.obj");
    run_ok(&["convert", "mb.obj", "-o", "mb.oocf", "--quiet"], cwd);
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap_or_else(|e| panic!("{e}"));
    let port = taken
        .local_addr()
        .map(|a| a.port().to_string())
        .unwrap_or_default();
    let mut child = spawn(&["mb.oocf", "--port", &port], cwd);
    assert_eq!(wait_for(&mut child, Duration::from_secs(20)), Some(2));
    let mut err = String::new();
    if let Some(mut e) = child.stderr.take() {
        let _ = e.read_to_string(&mut err);
    }
    assert!(err.contains("listening on 127.0.0.1"), "{err}");
}
