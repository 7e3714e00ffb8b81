//! The CLI contract: gen / encode / decode / info work end to end; a failure prints one line
//! on stderr, exits non-zero, and leaves no output file (not even a temporary one) behind.

use std::path::Path;
use std::process::{Command, Output};

fn salvq(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_salvq"))
        .args(args)
        .output()
        .expect("binary runs")
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn gen_encode_decode_info() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_string_lossy().into_owned();
    let out = salvq(&[
        "gen",
        "--anchors",
        "300",
        "--seed",
        "3",
        "--small",
        "-o",
        &p("m.safetensors"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("sha256 "));
    assert!(out.stdout.is_empty(), "messages go to stderr");
    let out = salvq(&[
        "encode",
        &p("m.safetensors"),
        "-o",
        &p("s.salvq"),
        "--note",
        "cli test",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = salvq(&["decode", &p("s.salvq"), "-o", &p("d.safetensors")]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let input = salvq_render::interchange::read_model(Path::new(&p("m.safetensors"))).unwrap();
    let decoded = salvq_render::interchange::read_model(Path::new(&p("d.safetensors"))).unwrap();
    assert_eq!(decoded.anchors.voxel, input.anchors.voxel);
    assert_eq!(decoded.anchors.mask, input.anchors.mask);
    assert_ne!(
        decoded.anchors.feat, input.anchors.feat,
        "features are quantized"
    );
    let out = salvq(&["info", &p("s.salvq"), "--json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["head"]["anchors"], 300);
    assert_eq!(v["chunks"][1]["tag"], "encd");
    assert_eq!(
        files_in(dir.path()),
        ["d.safetensors", "m.safetensors", "s.salvq"]
    );
}

#[test]
fn failed_decode_prints_one_line_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_string_lossy().into_owned();
    assert!(salvq(&[
        "gen",
        "--anchors",
        "50",
        "--small",
        "-o",
        &p("m.safetensors")
    ])
    .status
    .success());
    assert!(salvq(&[
        "encode",
        &p("m.safetensors"),
        "-o",
        &p("s.salvq"),
        "--no-stats"
    ])
    .status
    .success());
    let mut s = std::fs::read(p("s.salvq")).unwrap();
    let n = s.len();
    s[n - 20] ^= 4; // inside the last anchor chunk: a CRC mismatch
    std::fs::write(p("bad.salvq"), &s).unwrap();
    let out = salvq(&["decode", &p("bad.salvq"), "-o", &p("out.safetensors")]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "one line: {stderr}");
    assert!(stderr.starts_with("salvq: error[ChunkCrcMismatch]: chunk AOFF: CRC-32C mismatch"));
    assert!(stderr.trim_end().ends_with("[§1.3]"));
    assert_eq!(
        files_in(dir.path()),
        ["bad.salvq", "m.safetensors", "s.salvq"]
    );
}

#[test]
fn failed_encode_of_a_bad_model_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_string_lossy().into_owned();
    std::fs::write(p("bad.safetensors"), b"\x08\0\0\0\0\0\0\0{}      ").unwrap();
    let out = salvq(&["encode", &p("bad.safetensors"), "-o", &p("s.salvq")]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1);
    assert!(
        stderr.contains("error[TensorMissing]: anchor.feat"),
        "{stderr}"
    );
    assert_eq!(files_in(dir.path()), ["bad.safetensors"]);
}

#[test]
fn missing_input_is_an_io_error() {
    let out = salvq(&["info", "/nonexistent/x.salvq"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).starts_with("salvq: error[Io]: cannot read"));
}

/// The explicit profile from the command line (spec §3, Annex A.8): a PLY with a NaN fails
/// naming the property and the Gaussian and leaves no file; `--drop-invalid` drops and
/// counts it; the stream decodes to a PLY; a SOG `meta.json` is named and refused.
#[test]
fn encode_a_ply_with_a_nan() {
    use salvq_gen::gaussians::{generate_gaussians, GaussianParams};
    let dir = tempfile::tempdir().unwrap();
    let mut g = generate_gaussians(&GaussianParams::new(300, 1, 4));
    g.f_dc[17][1] = f32::NAN;
    let ply = dir.path().join("scene.ply");
    std::fs::write(&ply, salvq_render::ply::ply_bytes(&g).unwrap()).unwrap();
    let out = dir.path().join("scene.salvq");
    let (ply_s, out_s) = (ply.to_str().unwrap(), out.to_str().unwrap());
    let o = salvq(&["encode", ply_s, "-o", out_s, "--psnr", "30"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("PlyValueNotFinite") && err.contains("vertex 17") && err.contains("f_dc_1"),
        "{err}"
    );
    assert_eq!(files_in(dir.path()), vec!["scene.ply"]);
    let o = salvq(&[
        "encode",
        ply_s,
        "-o",
        out_s,
        "--psnr",
        "30",
        "--drop-invalid",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("dropped 1 of 300"), "{err}");
    let back = dir.path().join("back.ply");
    let o = salvq(&["decode", out_s, "-o", back.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let decoded = salvq_render::ply::read_ply(&std::fs::read(&back).unwrap()).unwrap();
    assert_eq!(decoded.len(), 299);
    let meta = dir.path().join("meta.json");
    std::fs::write(&meta, b"{\"version\": 2, \"means\": {}}").unwrap();
    let o = salvq(&[
        "encode",
        meta.to_str().unwrap(),
        "-o",
        dir.path().join("x.salvq").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("UnsupportedInput") && err.contains("SOG"),
        "{err}"
    );
}

/// A vector to decode in the output tests.
fn vector() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../conformance/vectors/g-sh3-rates.salvq")
        .to_string_lossy()
        .into_owned()
}

#[cfg(unix)]
#[test]
fn outputs_get_the_permissions_of_any_new_file_and_symlinks_stay() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    // A file created the ordinary way gets the umask; salvq's output must get the same.
    let plain = dir.path().join("plain");
    std::fs::File::create(&plain).unwrap();
    let want = std::fs::metadata(&plain).unwrap().permissions().mode() & 0o777;
    let out = dir.path().join("g.ply");
    let o = salvq(&["decode", &vector(), "-o", &out.to_string_lossy()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let got = std::fs::metadata(&out).unwrap().permissions().mode() & 0o777;
    assert_eq!(got, want, "{got:o} vs {want:o}");
    // Replacing a file (--force) keeps its permissions; a symbolic link is followed and
    // stays a link.
    let real = dir.path().join("real.ply");
    std::fs::write(&real, b"old").unwrap();
    std::fs::set_permissions(&real, std::fs::Permissions::from_mode(0o640)).unwrap();
    let link = dir.path().join("link.ply");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let o = salvq(&[
        "decode",
        &vector(),
        "-o",
        &link.to_string_lossy(),
        "--force",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(std::fs::read(&real).unwrap().starts_with(b"ply"));
    assert_eq!(
        std::fs::metadata(&real).unwrap().permissions().mode() & 0o777,
        0o640
    );
    assert_eq!(
        files_in(dir.path()),
        ["g.ply", "link.ply", "plain", "real.ply"]
    );
}

#[cfg(unix)]
#[test]
fn dev_null_and_standard_output_are_written_directly() {
    let o = salvq(&["decode", &vector(), "-o", "/dev/null"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata("/dev/null")
        .unwrap()
        .file_type()
        .is_char_device());
    let o = salvq(&["decode", &vector(), "-o", "-"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(o.stdout.starts_with(b"ply\n"), "the PLY on standard output");
}

#[test]
fn an_output_that_is_a_folder_fails_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let o = salvq(&["decode", &vector(), "-o", &dir.path().to_string_lossy()]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("error[Io]") && err.contains("folder"), "{err}");
    // Nothing was decoded: the line is the only output, and no temporary file is left.
    assert!(o.stdout.is_empty());
    assert!(files_in(dir.path()).is_empty());
}

#[test]
fn a_reader_that_stops_early_is_not_a_failure() {
    use std::io::Read;
    use std::process::Stdio;
    // A report (`info --json`, many lines) and a binary output on standard output, each
    // read for a few bytes and then closed.
    for args in [
        vec!["info".to_string(), "--json".to_string(), vector()],
        vec![
            "gen".into(),
            "--anchors".into(),
            "20000".into(),
            "-o".into(),
            "-".into(),
        ],
    ] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_salvq"))
            .args(&args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut first = [0u8; 8];
        child.stdout.take().unwrap().read_exact(&mut first).unwrap();
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(out.status.success(), "{args:?}: {err}");
    }
}

#[test]
fn a_region_that_is_no_box_is_refused_before_the_stream_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.ply");
    let out = out.to_str().unwrap();
    // §10.3.1: min > max on y, and a NaN; the stream is not even opened (it does not exist).
    for (bad, axis) in [("0,2,0,1,1,1", "y axis"), ("0,0,NaN,1,1,1", "z axis")] {
        let o = salvq(&["decode", "/nonexistent.salvq", "-o", out, "--region", bad]);
        assert_eq!(o.status.code(), Some(2), "{bad}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(axis) && err.contains("§10.3.1"), "{err}");
    }
    // A valid box that meets no tile: nothing written, status 0.
    let o = salvq(&[
        "decode",
        &vector(),
        "-o",
        out,
        "--region",
        "1e6,1e6,1e6,1e6,1e6,1e6",
    ]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("intersects no tile"));
    assert!(!Path::new(out).exists());
}

#[test]
fn demo_checks_pass_with_the_default_encoder_choices() {
    // The demo's own check (geometry, masks and the MLPs as stored exact; every value within
    // half a step) fails it with status 1; CI's demo run once did after a default changed.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = salvq(&["demo", "--anchors", "3000", "--out", out]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(text.contains("quantizers exact; every coded value within half a step: yes"));
    // The files it kept are not replaced by a second run, unless --force.
    let stream = std::fs::read(dir.path().join("scene.salvq")).unwrap();
    let o = salvq(&["demo", "--anchors", "2000", "--out", out]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("OutputExists"), "{err}");
    assert_eq!(
        std::fs::read(dir.path().join("scene.salvq")).unwrap(),
        stream
    );
    let o = salvq(&["demo", "--anchors", "2000", "--out", out, "-f"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_ne!(
        std::fs::read(dir.path().join("scene.salvq")).unwrap(),
        stream
    );
}
