//! End-to-end tests of `oocfmt curve`: on a small generated scene the JSON has one row per
//! (cache, PoE), PoE 0 reproduces the reference exactly (PSNR infinite, written as null), the
//! plot and the contact sheet are valid files, bad flags exit 2.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use crate::common;

use common::*;

fn converted_mandelbulb(dir: &Path) {
    gen(dir, "mandelbulb", "3000", "mb.obj");
    run_ok(&["convert", "mb.obj", "-o", "mb.oocf", "--quiet"], dir);
}

fn read_png(path: &Path) -> (u32, u32) {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    (info.width, info.height)
}

#[test]
fn curve_writes_json_plot_and_sheet() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    converted_mandelbulb(d);
    let o = run_ok(
        &[
            "curve",
            "mb.oocf",
            "--size",
            "64x48",
            "--poe",
            "0,2,16",
            "--cache",
            "blocking,async",
            "--repeat",
            "2",
            "--json",
            "curve.json",
            "--plot",
            "curve.svg",
            "--sheet",
            "sheet.png",
        ],
        d,
    );
    let out = stdout(&o);
    assert!(out.contains("PSNR") && out.contains("inf"), "{out}");

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("curve.json")).unwrap()).unwrap();
    assert_eq!(json["schema"], "oocfmt-curve/1");
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    let poes: Vec<f64> = rows.iter().map(|r| r["poe"].as_f64().unwrap()).collect();
    assert_eq!(poes, [0.0, 2.0, 16.0, 0.0, 2.0, 16.0]);
    for r in rows {
        assert_eq!(r["lod"], "voxel");
        let p = &r["primary"];
        let total: u64 = ["triangle", "voxel", "proxy", "miss"]
            .iter()
            .map(|k| p[k].as_u64().unwrap())
            .sum();
        assert_eq!(total, 64 * 48);
        let e = &r["error"];
        let ssim = e["ssim"].as_f64().unwrap();
        assert!(ssim <= 1.0 && ssim > -1.0, "{ssim}");
        let within = e["within_tolerance"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&within));
        assert!(r["blocks_touched"].as_u64().unwrap() > 0);
        assert!(r["ms"].as_f64().unwrap() > 0.0);
        if r["poe"] == 0.0 {
            // Full detail with every block loaded is the reference, bit for bit, whatever the
            // cache once it is warm.
            assert_eq!(e["rmse"], 0.0, "{r}");
            assert!(e["psnr_db"].is_null(), "{r}");
            assert_eq!(e["ssim"], 1.0);
            assert_eq!(e["within_tolerance"], 1.0);
            assert_eq!(e["depth"]["hit_miss_differ"], 0);
            assert_eq!(e["depth"]["max_relative"], 0.0);
            assert_eq!(p["voxel"], 0);
            assert_eq!(p, &json["reference"]["primary"]);
        } else {
            // A finite PSNR goes with a positive RMSE; identical images only with none.
            let rmse = e["rmse"].as_f64().unwrap();
            assert_eq!(e["psnr_db"].is_null(), rmse == 0.0, "{r}");
        }
    }
    // At 16 pixels of error on a 48-pixel-high image the voxels show.
    assert!(rows[2]["primary"]["voxel"].as_u64().unwrap() > 0);

    let svg = std::fs::read_to_string(d.join("curve.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("poe 16"));
    // Reference and three PoEs per row, one row per cache, each with its labels.
    let (w, h) = read_png(&d.join("sheet.png"));
    assert!(w >= 4 * 64 && h >= 2 * 48, "{w}x{h}");
}

#[test]
fn curve_plots_png_and_walks_a_path() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    converted_mandelbulb(d);
    std::fs::write(
        d.join("path.json"),
        r#"{"keyframes": [{"eye": [0, 0.5, 3], "look_at": [0, 0, 0]},
                          {"eye": [2, 0.5, 2], "look_at": [0, 0, 0]}], "frames": 3}"#,
    )
    .unwrap();
    run_ok(
        &[
            "curve",
            "mb.oocf",
            "--size",
            "40x30",
            "--poe",
            "0,4",
            "--path",
            "path.json",
            "--repeat",
            "1",
            "--json",
            "c.json",
            "--plot",
            "c.png",
        ],
        d,
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("c.json")).unwrap()).unwrap();
    assert_eq!(json["frames"], 3);
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    let rays: u64 = ["triangle", "voxel", "proxy", "miss"]
        .iter()
        .map(|k| rows[0]["primary"][k].as_u64().unwrap())
        .sum();
    assert_eq!(rays, 3 * 40 * 30);
    assert_eq!(rows[0]["error"]["rmse"], 0.0);
    assert!(read_png(&d.join("c.png")).0 > 0);
}

#[test]
fn curve_rejects_bad_flags() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    converted_mandelbulb(d);
    for bad in [
        &["--poe", "-1"][..],
        &["--poe", ""],
        &["--poe", "0,nan"],
        &["--poe", "1,1"],
        &["--poe", "0,inf"],
        &["--cache", "lru"],
        &["--cache", "async,async"],
        &["--plot", "curve.jpg"],
        &["--repeat", "0"],
        &["--size", "0x10"],
    ] {
        let mut args = vec!["curve", "mb.oocf"];
        args.extend_from_slice(bad);
        let o = oocfmt(&args, d);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", stdout(&o));
        assert!(!o.stderr.is_empty(), "{bad:?}");
    }
    let o = oocfmt(&["curve", "missing.oocf"], d);
    assert_eq!(o.status.code(), Some(2));
    // mmap maps uncompressed containers only; the default codec compresses.
    let o = oocfmt(&["curve", "mb.oocf", "--cache", "mmap", "--size", "8x8"], d);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--codec none"));
}
