//! End-to-end tests of `oocfmt curve`: on a small generated scene the JSON has one row per
//! (cache, PoE), PoE 0 reproduces the aliasing floor exactly (full detail at one ray per pixel,
//! measured against the supersampled reference), the whole image's error is the model's
//! diluted by exactly the background's share, a one-ray reference is the floor itself (PSNR
//! infinite, written as null), the plot and the contact sheet are valid files, bad flags exit 2.
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
            "--reference-spp",
            "4",
        ],
        d,
    );
    let out = stdout(&o);
    assert!(
        out.contains("PSNR") && out.contains("all RMSE") && out.contains("aliasing floor"),
        "{out}"
    );

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("curve.json")).unwrap()).unwrap();
    assert_eq!(json["schema"], "oocfmt-curve/3");
    assert_eq!(json["ao"], 0);
    assert_eq!(json["tolerance"], 8);
    assert_eq!(json["reference"]["spp"], 4);
    assert_eq!(json["reference"]["poe"], 0.0);
    let floor = &json["floor"];
    assert_eq!(floor["spp"], 1);
    let fe = &floor["error"];
    // Full detail at one ray per pixel is not the supersampled picture: aliasing shows on the
    // model's edges and detail.
    assert!(fe["model"]["rmse"].as_f64().unwrap() > 0.0, "{fe}");
    assert!(fe["model"]["pixels"].as_u64().unwrap() > 0, "{fe}");
    assert_eq!(fe["whole"]["pixels"], 64 * 48);
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    let poes: Vec<f64> = rows.iter().map(|r| r["poe"].as_f64().unwrap()).collect();
    assert_eq!(poes, [0.0, 2.0, 16.0, 0.0, 2.0, 16.0]);
    for r in rows {
        assert_eq!(r["lod"], "rlod");
        let p = &r["primary"];
        let total: u64 = ["triangle", "voxel", "rlod", "proxy", "miss"]
            .iter()
            .map(|k| p[k].as_u64().unwrap())
            .sum();
        assert_eq!(total, 64 * 48);
        let e = &r["error"];
        for region in ["model", "whole"] {
            let g = &e[region];
            let ssim = g["ssim"].as_f64().unwrap();
            assert!(ssim <= 1.0 && ssim > -1.0, "{ssim}");
            let within = g["within_tolerance"].as_f64().unwrap();
            assert!((0.0..=1.0).contains(&within));
            assert!(g["bias"].as_f64().unwrap().abs() < 255.0);
            // A finite PSNR goes with a positive RMSE; identical regions only with none.
            let rmse = g["rmse"].as_f64().unwrap();
            assert_eq!(g["psnr_db"].is_null(), rmse == 0.0, "{r}");
        }
        assert_eq!(e["whole"]["pixels"], 64 * 48);
        // Outside the model's pixels both images show the background, identically: the
        // whole image's squared error is the model's, spread over more pixels.
        let sse = |g: &serde_json::Value| {
            g["rmse"].as_f64().unwrap().powi(2) * g["pixels"].as_f64().unwrap()
        };
        let (ms, ws) = (sse(&e["model"]), sse(&e["whole"]));
        assert!((ms - ws).abs() <= 1e-9 * ms.max(1.0), "{e}");
        assert!(r["blocks_touched"].as_u64().unwrap() > 0);
        assert!(r["ms"].as_f64().unwrap() > 0.0);
        if r["poe"] == 0.0 {
            // Full detail with every block loaded is the floor, bit for bit, whatever the
            // cache once it is warm.
            assert_eq!(e, fe, "{r}");
            assert_eq!(p["voxel"], 0);
            assert_eq!(p["rlod"], 0);
            assert_eq!(p, &floor["primary"]);
        }
    }
    // At 16 pixels of error on a 48-pixel-high image the R-LODs (the file's default) show.
    assert!(rows[2]["primary"]["rlod"].as_u64().unwrap() > 0);

    let svg = std::fs::read_to_string(d.join("curve.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("poe 16"));
    // Reference, floor and three PoEs per row, one row per cache, each with its labels over
    // a 4x crop (the whole 64x48 image here: 256x192).
    let (w, h) = read_png(&d.join("sheet.png"));
    assert!(w >= 5 * 256 && h >= 2 * (48 + 192), "{w}x{h}");
}

#[test]
fn a_one_ray_reference_is_the_floor_itself() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    converted_mandelbulb(d);
    run_ok(
        &[
            "curve",
            "mb.oocf",
            "--size",
            "48x36",
            "--poe",
            "0,4",
            "--cache",
            "blocking",
            "--repeat",
            "1",
            "--reference-spp",
            "1",
            "--json",
            "c.json",
        ],
        d,
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("c.json")).unwrap()).unwrap();
    let fe = &json["floor"]["error"];
    for region in ["model", "whole"] {
        assert_eq!(fe[region]["rmse"], 0.0, "{fe}");
        assert!(fe[region]["psnr_db"].is_null(), "{fe}");
        assert_eq!(fe[region]["ssim"], 1.0);
        assert_eq!(fe[region]["within_tolerance"], 1.0);
        assert_eq!(fe[region]["bias"], 0.0);
    }
    assert_eq!(fe["depth"]["hit_miss_differ"], 0);
    assert_eq!(json["reference"]["primary"], json["floor"]["primary"]);
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows[0]["error"]["model"]["rmse"], 0.0);
    // The model's pixels are those either image hits: PoE 4's voxels may cover more.
    let pixels = |r: &serde_json::Value| r["error"]["model"]["pixels"].as_u64().unwrap();
    assert!(pixels(&rows[1]) >= pixels(&rows[0]), "{rows:?}");
    assert!(pixels(&rows[0]) > 0);
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
            "--reference-spp",
            "2",
        ],
        d,
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("c.json")).unwrap()).unwrap();
    assert_eq!(json["frames"], 3);
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    let rays: u64 = ["triangle", "voxel", "rlod", "proxy", "miss"]
        .iter()
        .map(|k| rows[0]["primary"][k].as_u64().unwrap())
        .sum();
    assert_eq!(rays, 3 * 40 * 30);
    // Over every frame: PoE 0 is the floor, and the floor is measured on all three.
    assert_eq!(rows[0]["error"], json["floor"]["error"]);
    assert_eq!(json["floor"]["error"]["whole"]["pixels"], 3 * 40 * 30);
    assert!(read_png(&d.join("c.png")).0 > 0);
}

/// `--shadows` lights the reference, the floor and every PoE alike (PoE 0 is the floor, and the
/// floor stays near the reference), and a reference cache far too small for its view only
/// costs time: the figures are those of the default budget.
#[test]
fn curve_with_shadows_or_occlusion_lights_every_image_alike() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    converted_mandelbulb(d);
    let curve = |extra: &[&str], json: &str| {
        let mut args = vec![
            "curve",
            "mb.oocf",
            "--size",
            "48x36",
            "--poe",
            "0,4",
            "--repeat",
            "1",
            "--reference-spp",
            "4",
            "--json",
            json,
        ];
        args.extend_from_slice(extra);
        run_ok(&args, d);
        let text = std::fs::read_to_string(d.join(json)).unwrap();
        serde_json::from_str::<serde_json::Value>(&text).unwrap()
    };
    let lit = curve(&[], "lit.json");
    let shadowed = curve(&["--shadows"], "shadowed.json");
    let small = curve(&["--shadows", "--reference-mb", "1"], "small.json");
    assert_eq!(lit["shadows"], false);
    assert_eq!(shadowed["shadows"], true);
    let floor_rmse = |c: &serde_json::Value| c["floor"]["error"]["model"]["rmse"].as_f64().unwrap();
    let rows = shadowed["rows"].as_array().unwrap();
    assert_eq!(rows[0]["error"], shadowed["floor"]["error"]);
    assert_ne!(shadowed["floor"]["error"], lit["floor"]["error"]);
    // A reference lit otherwise than its floor would sit tens of levels away.
    assert!(
        floor_rmse(&shadowed) < 3.0 * floor_rmse(&lit) + 2.0,
        "{} against {}",
        floor_rmse(&shadowed),
        floor_rmse(&lit)
    );
    for (a, b) in rows.iter().zip(small["rows"].as_array().unwrap()) {
        assert_eq!(a["error"], b["error"]);
    }
    assert_eq!(shadowed["floor"]["error"], small["floor"]["error"]);
    // Ambient occlusion lights the reference and the images alike too.
    let occluded = curve(&["--ao", "2"], "occluded.json");
    assert_eq!(
        (occluded["ao"].clone(), lit["ao"].clone()),
        (2.into(), 0.into())
    );
    let rows = occluded["rows"].as_array().unwrap();
    assert_eq!(rows[0]["error"], occluded["floor"]["error"]);
    assert_ne!(occluded["floor"]["error"], lit["floor"]["error"]);
    assert!(floor_rmse(&occluded) < 3.0 * floor_rmse(&lit) + 2.0);
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
        &["--reference-spp", "0"],
        &["--reference-spp", "257"],
        &["--size", "0x10"],
        &["--reference-mb", "0"],
        &["--light", "1,2,3"],
        &["--ao", "0"],
        &["--ao-distance", "1"],
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
