//! Interrupted conversions leave nothing behind, tried with real signals to a child `oocfmt
//! convert`: Ctrl-C (SIGINT) during an import from a pipe and SIGTERM during an out-of-core
//! build remove the spill folder and the temporary output, keep an existing output and say
//! so with exit codes 130 and 143; after a SIGKILL the next convert into that folder removes
//! the dead build's spill folder and says how much it freed, while one whose lock a live
//! process holds is kept.

use crate::common;

use common::*;

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use rustix::process::{kill_process, Pid, Signal};

/// Starts `oocfmt convert ARGS --quiet` in `dir`, its standard input `stdin`.
fn spawn_convert(dir: &Path, args: &[&str], stdin: Stdio) -> Child {
    Command::new(env!("CARGO_BIN_EXE_oocfmt"))
        .arg("convert")
        .args(args)
        .arg("--quiet")
        .current_dir(dir)
        .stdin(stdin)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start oocfmt: {e}"))
}

/// The spill folders in `dir`.
fn spill_folders(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|r| {
            r.flatten()
                .filter(|e| {
                    e.file_name()
                        .to_string_lossy()
                        .starts_with(".oocfmt-spill-")
                })
                .map(|e| e.path())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|r| {
            r.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// Polls `ready` every 2 ms until it holds; fails after 20 s, or if `child` ends first.
fn wait_for(what: &str, child: &mut Child, mut ready: impl FnMut() -> bool) {
    let start = Instant::now();
    while !ready() {
        if let Ok(Some(status)) = child.try_wait() {
            panic!("convert ended ({status}) before {what}");
        }
        assert!(start.elapsed() < Duration::from_secs(20), "no {what}");
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn send(child: &Child, signal: Signal) {
    kill_process(Pid::from_child(child), signal).unwrap_or_else(|e| panic!("kill: {e}"));
}

fn finish(child: Child) -> Output {
    child
        .wait_with_output()
        .unwrap_or_else(|e| panic!("wait: {e}"))
}

/// A folder with a Mandelbulb `m.obj` of about `tris` triangles and an old `out.oocf`.
fn folder(tris: &str) -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    gen(tmp.path(), "mandelbulb", tris, "m.obj");
    std::fs::write(tmp.path().join("out.oocf"), b"the old output").unwrap_or_default();
    tmp
}

/// What an interrupted convert must leave: its exit code and message, the folder as it was.
fn assert_clean(o: &Output, code: i32, dir: &Path) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(code), "{err}");
    assert!(err.contains("oocfmt: interrupted: removed "), "{err}");
    assert!(
        err.contains(" MiB of spill files; out.oocf was not written"),
        "{err}"
    );
    assert_eq!(names(dir), ["m.obj", "out.oocf"], "{err}");
    let old = std::fs::read(dir.join("out.oocf")).unwrap_or_default();
    assert_eq!(old, b"the old output");
}

#[test]
fn ctrl_c_during_an_import_from_a_pipe_leaves_nothing_behind() {
    let tmp = folder("100000");
    let dir = tmp.path();
    let obj = std::fs::read(dir.join("m.obj")).unwrap_or_default();
    let args = [
        "-",
        "--format",
        "obj",
        "-o",
        "out.oocf",
        "--mem-limit",
        "16M",
    ];
    let mut child = spawn_convert(dir, &args, Stdio::piped());
    let mut stdin = child.stdin.take().unwrap_or_else(|| panic!("no stdin"));
    let (first, rest) = obj.split_at(obj.len() / 2);
    assert!(stdin.write_all(first).is_ok());
    wait_for("a spill folder", &mut child, || {
        !spill_folders(dir).is_empty()
    });
    send(&child, Signal::INT);
    // The import notices at its next check, a few thousand triangles on; then the pipe closes.
    let _ = stdin.write_all(rest);
    drop(stdin);
    assert_clean(&finish(child), 130, dir);
}

#[test]
fn sigterm_during_an_out_of_core_build_leaves_nothing_behind() {
    let tmp = folder("200000");
    let dir = tmp.path();
    let args = ["m.obj", "-o", "out.oocf", "--mem-limit", "16M"];
    let mut child = spawn_convert(dir, &args, Stdio::null());
    // Past the import: the split's runs or the chunks' blocks are in the spill folder.
    let building = || {
        spill_folders(dir).iter().any(|f| {
            names(f)
                .iter()
                .any(|n| n != "lock" && !n.starts_with("import"))
        })
    };
    wait_for("the out-of-core build", &mut child, building);
    send(&child, Signal::TERM);
    assert_clean(&finish(child), 143, dir);
}

#[test]
fn a_killed_builds_spill_folder_is_removed_by_the_next_convert() {
    let tmp = folder("20000");
    let dir = tmp.path();
    // Held open, the pipe keeps the build waiting in its import.
    let args = ["-", "--format", "obj", "-o", "out.oocf"];
    let mut child = spawn_convert(dir, &args, Stdio::piped());
    let mut stdin = child.stdin.take().unwrap_or_else(|| panic!("no stdin"));
    let obj = std::fs::read(dir.join("m.obj")).unwrap_or_default();
    assert!(stdin.write_all(&obj[..obj.len() / 2]).is_ok());
    wait_for("a spill folder", &mut child, || {
        !spill_folders(dir).is_empty()
    });
    let dead = spill_folders(dir);
    send(&child, Signal::KILL);
    assert_eq!(finish(child).status.code(), None, "killed by a signal");
    drop(stdin);
    assert_eq!(spill_folders(dir), dead, "SIGKILL leaves its folder");
    // A live build's folder: this process holds its lock.
    let live = dir.join(".oocfmt-spill-live");
    std::fs::create_dir(&live).unwrap_or_default();
    let lock = File::create(live.join("lock")).unwrap_or_else(|e| panic!("{e}"));
    rustix::fs::flock(&lock, rustix::fs::FlockOperation::LockExclusive)
        .unwrap_or_else(|e| panic!("flock: {e}"));
    let o = oocfmt(&["convert", "m.obj", "-o", "new.oocf", "--quiet"], dir);
    ok(&o, "the next convert");
    let err = String::from_utf8_lossy(&o.stderr);
    let name = dead[0]
        .file_name()
        .map(|n| n.to_string_lossy().into_owned());
    let name = name.unwrap_or_default();
    assert!(
        err.contains(&format!("warning    removed stale spill folder ./{name} (")),
        "{err}"
    );
    assert!(
        err.contains(" MiB) left by a build that no longer runs"),
        "{err}"
    );
    assert!(!err.contains("oocfmt-spill-live"), "{err}");
    assert_eq!(spill_folders(dir), [live], "the live build's folder stays");
    drop(lock);
}
