//! `salvq compare A B` (spec Annex C.2, C.5): two scenes rendered from the same cameras.

#[path = "../../../tests/common/mod.rs"]
mod common;
use common::{repo_root, shared_data};

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use salvq_gen::{generate, GenParams};
use serde_json::Value;

fn salvq(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_salvq"))
        .args(args)
        .output()
        .unwrap()
}

/// The `--json` report of a compare that must succeed.
fn compare_json(args: &[&str]) -> Value {
    let out = salvq(&[&["compare", "--json"], args].concat());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A small generated scene as a stream.
fn stream_file(dir: &Path) -> PathBuf {
    let model = generate(&GenParams {
        feat_basis: false,
        ..GenParams::small(300, 4)
    });
    let file = dir.join("scene.salvq");
    std::fs::write(&file, salvq_encoder::encode(&model).unwrap()).unwrap();
    file
}

fn render_data(name: &str) -> PathBuf {
    repo_root()
        .join("crates/salvq-render/tests/data")
        .join(name)
}

#[test]
fn a_scene_compared_with_itself_is_identical_in_every_view() {
    let dir = tempfile::tempdir().unwrap();
    let s = stream_file(dir.path());
    let r = compare_json(&[
        path(&s),
        path(&s),
        "--views",
        "3",
        "--width",
        "64",
        "--height",
        "48",
    ]);
    let views = r["views"].as_array().unwrap();
    assert_eq!(views.len(), 3);
    for v in views.iter().chain([&r["overall"]]) {
        // MSE 0: PSNR +∞, which JSON writes as null.
        assert_eq!(v["mse"], 0.0, "{v}");
        assert!(v["psnr_db"].is_null(), "{v}");
        assert_eq!(v["ssim"], 1.0, "{v}");
    }
    assert_eq!(
        (&views[2]["width"], &views[2]["height"]),
        (&64.into(), &48.into())
    );
    // The table says so too.
    let out = salvq(&[
        "compare",
        path(&s),
        path(&s),
        "--views",
        "2",
        "--width",
        "32",
        "--height",
        "24",
    ]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(out.status.success());
    let all = text
        .lines()
        .find(|l| l.trim_start().starts_with("all"))
        .unwrap();
    assert!(all.contains(" inf ") && all.contains("1.00000"), "{text}");
}

#[test]
fn donut_against_a_lossy_version_has_a_finite_psnr() {
    let Some(bytes) = shared_data("donut.ply") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let original = dir.path().join("donut.ply");
    std::fs::write(&original, &bytes).unwrap();
    // Lossy: colours on a grid of 1/16 (about 4 bits of a colour's DC term).
    let mut g = salvq_render::ply::read_ply(&bytes).unwrap();
    for dc in g.f_dc.iter_mut().flatten() {
        *dc = (*dc * 16.0).round() / 16.0;
    }
    let lossy = dir.path().join("lossy.ply");
    std::fs::write(&lossy, salvq_render::ply::ply_bytes(&g).unwrap()).unwrap();
    let args = [
        path(&original),
        path(&lossy),
        "--width",
        "96",
        "--height",
        "72",
    ];
    let r = compare_json(&args);
    let views = r["views"].as_array().unwrap();
    assert_eq!(views.len(), 8);
    let psnr = r["overall"]["psnr_db"].as_f64().unwrap();
    let ssim = r["overall"]["ssim"].as_f64().unwrap();
    assert!(psnr > 20.0 && psnr < 80.0, "{psnr}");
    assert!(ssim > 0.5 && ssim < 1.0, "{ssim}");
    // Overall: the PSNR of the views' mean MSE (not the mean of their dB) and mean SSIM.
    let mean = |k: &str| views.iter().map(|v| v[k].as_f64().unwrap()).sum::<f64>() / 8.0;
    assert!((psnr + 10.0 * mean("mse").log10()).abs() < 1e-9);
    assert!((ssim - mean("ssim")).abs() < 1e-12);
    // The order matters only for the ring (around A): B against A is as far.
    let back = compare_json(&[
        path(&lossy),
        path(&original),
        "--width",
        "96",
        "--height",
        "72",
    ]);
    let back = back["overall"]["psnr_db"].as_f64().unwrap();
    assert!((back - psnr).abs() < 1.0, "{psnr} vs {back}");
}

#[test]
fn real_cameras_from_cameras_json_or_colmap_are_used_in_file_order_or_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let s = stream_file(dir.path());
    let json = render_data("cameras.json");
    let colmap = render_data("colmap");
    let r = compare_json(&[
        path(&s),
        path(&s),
        "--cameras",
        path(&json),
        "--width",
        "64",
    ]);
    let views = r["views"].as_array().unwrap();
    let names: Vec<&str> = views
        .iter()
        .map(|v| v["camera"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["a", "b"]);
    // Width given alone: the height keeps the camera's 4:3.
    assert_eq!(
        (&views[1]["width"], &views[1]["height"]),
        (&64.into(), &48.into())
    );
    let r = compare_json(&[
        path(&s),
        path(&s),
        "--colmap",
        path(&colmap),
        "--views",
        "1",
    ]);
    let views = r["views"].as_array().unwrap();
    assert_eq!(views.len(), 1);
    assert_eq!(views[0]["camera"], "a.png");
    assert_eq!(
        (&views[0]["width"], &views[0]["height"]),
        (&320.into(), &240.into())
    );
}

#[test]
fn a_bad_camera_file_fails_naming_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let s = stream_file(dir.path());
    let colmap = dir.path().join("sparse");
    std::fs::create_dir(&colmap).unwrap();
    std::fs::write(
        colmap.join("cameras.txt"),
        "# Camera list\n#\n#\n1 OPENCV 640 480 500 500 320 240 -0.1 0.01 0 0\n",
    )
    .unwrap();
    std::fs::write(colmap.join("images.txt"), "1 1 0 0 0 0 0 4 1 a.png\n\n").unwrap();
    let json = dir.path().join("cameras.json");
    std::fs::write(
        &json,
        "[{\"id\": 0,\n \"width\": 640,\n \"height\": 480, }]",
    )
    .unwrap();
    for (option, file, expected) in [
        (
            "--colmap",
            &colmap,
            "cameras.txt, line 4, field PARAMS: OPENCV with lens distortion",
        ),
        (
            "--cameras",
            &json,
            "cameras.json, line 3, field JSON: key must be a string",
        ),
    ] {
        let out = salvq(&["compare", path(&s), path(&s), option, path(file)]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains("error[CameraFileInvalid]"), "{stderr}");
        assert!(stderr.contains(expected), "{stderr}");
        assert!(out.stdout.is_empty());
    }
    // Both kinds of camera file at once is a usage error.
    let out = salvq(&[
        "compare",
        path(&s),
        path(&s),
        "--colmap",
        path(&colmap),
        "--cameras",
        path(&json),
    ]);
    assert_eq!(out.status.code(), Some(2));
}
