//! End-to-end tests of `oocfmt render`: generate, convert and render a scene; the PNG decodes
//! at the asked size, the depth PFM and the stats JSON are written, bad usage exits 2.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::process::Output;

use crate::common;

use common::*;

fn ok_(o: &Output) {
    ok(o, "oocfmt");
}

fn converted_mandelbulb(dir: &Path) {
    gen(dir, "mandelbulb", "3000", "mb.obj");
    run_ok(&["convert", "mb.obj", "-o", "mb.oocf", "--quiet"], dir);
}

#[test]
fn render_writes_a_png_a_depth_pfm_and_stats() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    converted_mandelbulb(d);
    let o = oocfmt(
        &[
            "render",
            "mb.oocf",
            "-o",
            "mb.png",
            "--size",
            "64x48",
            "--poe",
            "0",
            "--depth-out",
            "mb.pfm",
            "--stats-json",
            "stats.json",
        ],
        d,
    );
    ok_(&o);
    assert!(String::from_utf8_lossy(&o.stdout).contains("mb.png"));

    let decoder = png::Decoder::new(std::fs::File::open(d.join("mb.png")).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (64, 48));
    assert_eq!(info.color_type, png::ColorType::Rgb);
    // The default camera frames the model: the middle of the picture is not background.
    let mid = 3 * (24 * 64 + 32);
    let corner = &buf[0..3];
    assert_ne!(&buf[mid..mid + 3], corner);

    let pfm = std::fs::read(d.join("mb.pfm")).unwrap();
    let head = b"Pf\n64 48\n-1.0\n";
    assert_eq!(&pfm[..head.len()], head);
    assert_eq!(pfm.len(), head.len() + 4 * 64 * 48);
    let depths: Vec<f32> = pfm[head.len()..]
        .chunks(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert!(depths.iter().any(|d| d.is_infinite()));
    assert!(depths.iter().any(|d| d.is_finite() && *d > 0.0));

    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("stats.json")).unwrap()).unwrap();
    let p = &stats["primary"];
    let total: u64 = ["triangle", "voxel", "rlod", "proxy", "miss"]
        .iter()
        .map(|k| p[k].as_u64().unwrap())
        .sum();
    assert_eq!(total, 64 * 48);
    assert_eq!(p["voxel"].as_u64(), Some(0));
    assert!(stats["cache"]["blocks_loaded"].as_u64().unwrap() > 0);
}

/// A frame's or still image's `pinned_cores`.
fn pinned_of(stats: &serde_json::Value) -> Vec<u64> {
    stats["pinned_cores"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_u64().unwrap())
        .collect()
}

/// The stats' `pinned_cores` of `render mb.oocf ARGS`, and the PNG's bytes.
fn pinned_and_png(d: &Path, args: &[&str]) -> (Vec<u64>, Vec<u8>) {
    let mut all = vec![
        "render",
        "mb.oocf",
        "-o",
        "pin.png",
        "--size",
        "64x48",
        "--stats-json",
        "pin.json",
    ];
    all.extend_from_slice(args);
    ok_(&oocfmt(&all, d));
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("pin.json")).unwrap()).unwrap();
    (pinned_of(&stats), std::fs::read(d.join("pin.png")).unwrap())
}

#[test]
fn render_pin_binds_one_thread_per_core() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    converted_mandelbulb(d);
    let usable = oocfmt_trace::affinity::usable_cores();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let (pinned, png) = pinned_and_png(d, &["--pin"]);
    match usable {
        // As many render threads as cores: each has its own, in order.
        Some(cores) if cores.len() >= 2 && cores.len() == threads => {
            assert_eq!(pinned, cores.iter().map(|&c| c as u64).collect::<Vec<_>>());
        }
        _ => assert!(pinned.is_empty(), "{pinned:?}"),
    }
    // By default, or with one thread, nothing is bound; the picture is the same.
    for args in [&[][..], &["--pin", "--threads", "1"]] {
        let (none, same) = pinned_and_png(d, args);
        assert!(none.is_empty(), "{args:?}: {none:?}");
        assert!(same == png, "{args:?}: another picture");
    }
    // A walkthrough gives the same cores with every frame's figures.
    std::fs::write(
        d.join("path.json"),
        r#"[{"eye": [0, 0, 4], "look_at": [0, 0, 0]}, {"eye": [0, 1, 4], "look_at": [0, 0, 0]}]"#,
    )
    .unwrap();
    for f in walk_figures(d, "walk", &["--pin"]) {
        assert_eq!(pinned_of(&f), pinned);
    }
    // --pin that binds nothing says so.
    let o = oocfmt(
        &[
            "render",
            "mb.oocf",
            "-o",
            "one.png",
            "--size",
            "8x8",
            "--pin",
            "--threads",
            "1",
        ],
        d,
    );
    ok_(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--pin: the render threads are not bound"),
        "{err}"
    );
}

#[test]
fn render_usage_errors_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for args in [
        &["render", "missing.oocf", "-o", "x.png"][..],
        &["render", "m.oocf", "-o", "x.png", "--size", "0x10"][..],
        &["render", "m.oocf", "-o", "x.png", "--cache", "paged"][..],
        &["render", "m.oocf", "-o", "x.png", "--fetchers", "0"][..],
        &["render", "m.oocf", "-o", "x.png", "--eye", "1,2"][..],
        &["render", "m.oocf", "-o", "x.png", "--eviction", "fifo"][..],
        &["render", "m.oocf", "-o", "x.png", "--fetch-order", "size"][..],
        &["render", "m.oocf", "-o", "x.png", "--prefetch", "yes"][..],
        &["render", "m.oocf", "-o", "x.png", "--prefetch-mb", "0"][..],
        &["render", "m.oocf", "-o", "x.png", "--prefetch-frames", "0"][..],
        &["render", "m.oocf", "-o", "x.png", "--accuracy"][..],
        &["render", "m.oocf", "-o", "x.png", "--reference-spp", "4"][..],
    ] {
        let o = oocfmt(args, d);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
    }
    assert!(!d.join("x.png").exists());
}

#[test]
fn render_mmap_refuses_a_compressed_container() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    converted_mandelbulb(d);
    let o = oocfmt(
        &[
            "render", "mb.oocf", "-o", "x.png", "--size", "16x12", "--cache", "mmap",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--codec none"), "{err}");
    assert!(!d.join("x.png").exists());
}

#[test]
fn render_path_writes_numbered_pngs_and_per_frame_figures() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    converted_mandelbulb(d);
    std::fs::write(
        d.join("path.json"),
        r#"{"keyframes": [{"eye": [0, 0.5, 4], "look_at": [0, 0, 0]},
                          {"eye": [3, 0.5, 1.5], "look_at": [0, 0, 0], "fov_y": 35}],
            "frames": 3}"#,
    )
    .unwrap();
    let o = oocfmt(
        &[
            "render",
            "mb.oocf",
            "-o",
            "walk.png",
            "--size",
            "32x24",
            "--poe",
            "0",
            "--path",
            "path.json",
            "--stats-json",
            "walk.json",
        ],
        d,
    );
    ok_(&o);
    for i in 0..3 {
        assert!(d.join(format!("walk-000{i}.png")).exists(), "frame {i}");
    }
    assert!(!d.join("walk-0003.png").exists());
    assert!(!d.join("walk.png").exists());
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(stdout.lines().filter(|l| l.starts_with("frame")).count(), 3);
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("walk.json")).unwrap()).unwrap();
    let frames = stats.as_array().unwrap();
    assert_eq!(frames.len(), 3);
    for f in frames {
        let p = &f["primary"];
        let total: u64 = ["triangle", "voxel", "rlod", "proxy", "miss"]
            .iter()
            .map(|k| p[k].as_u64().unwrap())
            .sum();
        assert_eq!(total, 32 * 24);
        for k in ["ms", "rays_per_second", "working_set_mb", "hit_rate"] {
            assert!(f[k].as_f64().is_some(), "{k} in {f}");
        }
        for k in [
            "blocks_requested",
            "blocks_loaded",
            "blocks_evicted",
            "coarse_pixels",
        ] {
            assert!(f[k].as_u64().is_some(), "{k} in {f}");
        }
    }
    // A cold async cache: the first frame loads nothing in time and shows coarse levels.
    assert!(
        frames[0]["coarse_pixels"].as_u64().unwrap() > 0,
        "{}",
        frames[0]
    );

    let o = oocfmt(
        &[
            "render",
            "mb.oocf",
            "-o",
            "bad.png",
            "--path",
            "missing.json",
        ],
        d,
    );
    assert_eq!(o.status.code(), Some(2));
}

/// `render --path` with `extra` flags on a 3-frame path; the per-frame figures.
fn walk_figures(d: &Path, name: &str, extra: &[&str]) -> Vec<serde_json::Value> {
    let png = format!("{name}.png");
    let json = format!("{name}.json");
    let mut args = vec![
        "render",
        "mb.oocf",
        "-o",
        &png,
        "--size",
        "32x24",
        "--path",
        "path.json",
        "--stats-json",
        &json,
    ];
    args.extend_from_slice(extra);
    let o = oocfmt(&args, d);
    ok_(&o);
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join(&json)).unwrap()).unwrap();
    stats.as_array().unwrap().clone()
}

#[test]
fn render_path_accuracy_is_full_for_blocking_at_poe_0_and_partial_for_a_cold_async_start() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    converted_mandelbulb(d);
    std::fs::write(
        d.join("path.json"),
        r#"{"keyframes": [{"eye": [0, 0.5, 4], "look_at": [0, 0, 0]},
                          {"eye": [3, 0.5, 1.5], "look_at": [0, 0, 0]}], "frames": 3}"#,
    )
    .unwrap();
    let accuracy = |f: &serde_json::Value, k: &str| f["accuracy"][k].as_f64().unwrap();
    let blocking = walk_figures(
        d,
        "blocking",
        &[
            "--cache",
            "blocking",
            "--poe",
            "0",
            "--accuracy",
            "--reference-spp",
            "4",
        ],
    );
    for f in &blocking {
        // The frames are full detail: equal to it, and exactly as far from the supersampled
        // reference as the floor.
        assert_eq!(accuracy(f, "exact"), 1.0, "{f}");
        let a = &f["accuracy"];
        assert_eq!(a["error"], a["floor"], "{f}");
        assert_eq!(a["tolerance"].as_u64(), Some(8));
        assert_eq!(a["reference_spp"].as_u64(), Some(4));
        assert_eq!(a["error"]["whole"]["pixels"], 32 * 24);
        assert!(a["error"]["model"]["pixels"].as_u64().unwrap() > 0, "{f}");
        assert!(a["error"]["model"]["rmse"].as_f64().unwrap() > 0.0, "{f}");
    }
    // A one-ray reference is full detail itself.
    let one = walk_figures(
        d,
        "one",
        &[
            "--cache",
            "blocking",
            "--poe",
            "0",
            "--accuracy",
            "--reference-spp",
            "1",
        ],
    );
    for f in &one {
        let e = &f["accuracy"]["error"];
        assert_eq!(e["model"]["rmse"], 0.0, "{f}");
        assert_eq!(e["whole"]["within_tolerance"], 1.0, "{f}");
        assert_eq!(e["hit_miss_differ"], 0, "{f}");
    }
    let cold = walk_figures(
        d,
        "cold",
        &[
            "--poe",
            "0",
            "--accuracy",
            "--accuracy-tolerance",
            "3",
            "--reference-spp",
            "2",
            "--eviction",
            "second-chance",
            "--fetch-order",
            "wald",
            "--prefetch",
            "on",
        ],
    );
    let first = &cold[0];
    assert!(accuracy(first, "exact") < 1.0, "{first}");
    // A cold first frame is not full detail, so its error is not the floor's.
    let a = &first["accuracy"];
    assert_ne!(a["error"], a["floor"], "{first}");
    assert_eq!(a["tolerance"].as_u64(), Some(3));
    let cache = &cold[2]["stats"]["cache"];
    assert_eq!(cache["eviction"], "second-chance");
    assert_eq!(cache["fetch_order"], "wald");
    for k in ["blocks_missed", "blocks_prefetched", "blocks_prefetch_used"] {
        assert!(first[k].as_u64().is_some(), "{k} in {first}");
    }
    // Blocks the fetchers published cost them CPU time. Whether any arrive within three
    // frames of a tiny model depends on when the machine runs the fetchers (a loaded CI
    // machine may not before the walk ends), so the figure is checked against the blocks
    // loaded; `caches.rs` checks it where the fetchers are waited for.
    let fetch_ms: f64 = cold.iter().filter_map(|f| f["fetch_cpu_ms"].as_f64()).sum();
    let loaded: u64 = cold
        .iter()
        .filter_map(|f| f["blocks_loaded"].as_u64())
        .sum();
    assert!(
        loaded == 0 || fetch_ms > 0.0,
        "{loaded} blocks in {fetch_ms} ms"
    );
    // Without --accuracy there is no such figure.
    let plain = walk_figures(d, "plain", &[]);
    assert!(plain[0].get("accuracy").is_none());

    // Prefetching predicts a walkthrough's cameras with the async cache only.
    for extra in [
        &[
            "--prefetch",
            "on",
            "--cache",
            "blocking",
            "--path",
            "path.json",
        ][..],
        &["--prefetch", "on"][..],
    ] {
        let mut args = vec!["render", "mb.oocf", "-o", "p.png", "--size", "8x6"];
        args.extend_from_slice(extra);
        let o = oocfmt(&args, d);
        assert_eq!(o.status.code(), Some(2), "{extra:?}");
        assert!(String::from_utf8_lossy(&o.stderr).contains("--prefetch"));
    }
}
