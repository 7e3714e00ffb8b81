//! The CLI as a Unix tool, so that it composes in pipes: data alone on standard output,
//! messages on standard error, `-` for standard input, no command writes over one of its
//! inputs or, without `--force`, over a file that exists; every value changed on input is
//! counted; targets are sorted so that rate 0 is the finest; progress off a terminal is a
//! line per step; the encoder's summary is what `compare` measures.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use salvq_gen::gaussians::{generate_gaussians, GaussianParams};

fn salvq(args: &[&str]) -> Output {
    salvq_with_input(args, None)
}

/// Runs `salvq args`, with `stdin` as its standard input when given.
fn salvq_with_input(args: &[&str], stdin: Option<&[u8]>) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_salvq"))
        .args(args)
        .stdin(if stdin.is_some() {
            Stdio::piped()
        } else {
            Stdio::null()
        })
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary runs");
    if let Some(bytes) = stdin {
        let mut pipe = child.stdin.take().unwrap();
        pipe.write_all(bytes).unwrap();
    }
    child.wait_with_output().unwrap()
}

fn ok(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    err
}

fn failed(o: &Output, class: &str) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "succeeded: {err}");
    assert!(err.starts_with(&format!("salvq: error[{class}]")), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(o.stdout.is_empty());
    err
}

/// A usage error: exit status 2, one `error:` line, nothing on stdout.
fn usage_error(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.starts_with("error: "), "{err}");
    assert!(o.stdout.is_empty());
    err
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A small SH 1 scene as a PLY file in `dir`.
fn scene(dir: &Path, name: &str) -> PathBuf {
    let g = generate_gaussians(&GaussianParams::new(300, 1, 4));
    let path = dir.join(name);
    std::fs::write(&path, salvq_render::ply::ply_bytes(&g).unwrap()).unwrap();
    path
}

/// `scene.ply` encoded at two rates into `scene.salvq` (the default name), and the `--json`
/// summary.
fn encoded(dir: &Path) -> (PathBuf, PathBuf, serde_json::Value) {
    let ply = scene(dir, "scene.ply");
    let o = salvq(&["encode", s(&ply), "--psnr", "40,30", "--json"]);
    let err = ok(&o);
    assert!(err.contains("encoded 300 Gaussians"), "{err}");
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON alone");
    let stream = dir.join("scene.salvq");
    assert!(stream.is_file(), "the default output name");
    (ply, stream, summary)
}

#[test]
fn every_command_writes_only_its_data_on_standard_output() {
    let dir = tempfile::tempdir().unwrap();
    let (_, stream, _) = encoded(dir.path());
    let p = |n: &str| dir.path().join(n);
    // Each command once into a file (nothing on stdout), once into `-` (the file's bytes).
    let runs: [(&[&str], &str); 5] = [
        (&["decode", s(&stream), "--rate", "1"], "d.ply"),
        (&["extract", s(&stream), "--rate", "1"], "x.salvq"),
        (
            &["render", s(&stream), "--width", "64", "--height", "48"],
            "r.png",
        ),
        (&["export-ply", s(&stream)], "e.ply"),
        (&["gen", "--anchors", "200", "--small"], "m.safetensors"),
    ];
    for (args, name) in runs {
        let file = p(name);
        let to_file = salvq(&[args, &["-o", s(&file)]].concat());
        let err = ok(&to_file);
        assert!(to_file.stdout.is_empty(), "{args:?} wrote to stdout");
        assert!(!err.is_empty(), "{args:?}: a message on stderr");
        let to_stdout = salvq(&[args, &["-o", "-"]].concat());
        ok(&to_stdout);
        assert_eq!(
            to_stdout.stdout,
            std::fs::read(&file).unwrap(),
            "{args:?}: stdout is the file's bytes, nothing else"
        );
    }
    // The encoder's stream on stdout, its summary on stderr; `info -` reads it back.
    let o = salvq(&["encode", s(&p("scene.ply")), "-o", "-", "--psnr", "30"]);
    let err = ok(&o);
    assert!(o.stdout.starts_with(b"\x89SALVQ"));
    assert!(
        err.contains(&format!("into standard output ({} bytes", o.stdout.len())),
        "{err}"
    );
    let info = salvq_with_input(&["info", "-", "--json"], Some(&o.stdout));
    assert_eq!(ok(&info), "", "info prints nothing on stderr");
    let v: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(v["gaussians"], 300, "{v}");
    // `--json` and `-o -` would share stdout: a usage error before any work.
    let err = usage_error(&salvq(&["decode", s(&stream), "-o", "-", "--json"]));
    assert!(err.contains("--json"), "{err}");
    // Standard input: the same decode as from the file; no name to derive an output from.
    let bytes = std::fs::read(&stream).unwrap();
    let o = salvq_with_input(&["decode", "-", "--rate", "1", "-o", "-"], Some(&bytes));
    ok(&o);
    assert_eq!(o.stdout, std::fs::read(p("d.ply")).unwrap());
    let err = usage_error(&salvq_with_input(&["decode", "-"], Some(&bytes)));
    assert!(err.contains("-o FILE"), "{err}");
}

#[test]
fn no_command_writes_over_an_input_or_an_existing_output() {
    let dir = tempfile::tempdir().unwrap();
    let (_, stream, _) = encoded(dir.path());
    let before = std::fs::read(&stream).unwrap();
    let p = |n: &str| dir.path().join(n);
    // The input, by its name or another, even with --force.
    for args in [
        vec!["decode", s(&stream), "-o", s(&stream)],
        vec!["extract", s(&stream), "--rate", "1", "-o", s(&stream), "-f"],
        vec!["decode", s(&stream), "-o", "./scene.salvq", "--force"],
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_salvq"))
            .args(&args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        failed(&o, "OutputIsInput");
    }
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&stream, p("link.ply")).unwrap();
        failed(
            &salvq(&["decode", s(&stream), "-o", s(&p("link.ply")), "-f"]),
            "OutputIsInput",
        );
    }
    assert_eq!(
        std::fs::read(&stream).unwrap(),
        before,
        "the input is intact"
    );
    // An output that exists: refused, and left as it was; replaced with --force.
    std::fs::write(p("out.ply"), b"keep me").unwrap();
    let err = failed(
        &salvq(&["decode", s(&stream), "-o", s(&p("out.ply"))]),
        "OutputExists",
    );
    assert!(err.contains("--force"), "{err}");
    assert_eq!(std::fs::read(p("out.ply")).unwrap(), b"keep me");
    ok(&salvq(&[
        "decode",
        s(&stream),
        "-o",
        s(&p("out.ply")),
        "-f",
    ]));
    assert!(std::fs::read(p("out.ply")).unwrap().starts_with(b"ply\n"));
    // Default names: scene.salvq -> scene.ply, which is the PLY it was encoded from: kept.
    failed(&salvq(&["decode", s(&stream)]), "OutputExists");
    std::fs::remove_file(p("scene.ply")).unwrap();
    ok(&salvq(&["decode", s(&stream)]));
    assert!(p("scene.ply").is_file());
    failed(&salvq(&["decode", s(&stream)]), "OutputExists");
    ok(&salvq(&["extract", s(&stream), "--rate", "1"]));
    assert!(p("scene.rate1.salvq").is_file());
    // A folder that takes no new file (/proc, even for root) fails before the work.
    #[cfg(target_os = "linux")]
    {
        let err = failed(
            &salvq(&["decode", s(&stream), "-o", "/proc/salvq-test.ply"]),
            "Io",
        );
        assert!(err.contains("temporary file"), "{err}");
    }
    // The extension names the format; a wrong one is refused before decoding.
    let err = failed(
        &salvq(&["decode", s(&stream), "-o", s(&p("x.safetensors"))]),
        "OutputExtension",
    );
    assert!(err.contains(".ply"), "{err}");
    // Every command's output names its format, and a wrong one fails before any work.
    for (args, wants) in [
        (vec!["encode", s(&p("out.ply"))], ".salvq"),
        (vec!["extract", s(&stream), "--rate", "1"], ".salvq"),
        (vec!["render", s(&stream)], ".png"),
        (vec!["export-ply", s(&stream)], ".ply"),
        (vec!["gen", "--anchors", "100", "--small"], ".safetensors"),
    ] {
        let wrong = p("wrong.jpg");
        let o = salvq(&[args.as_slice(), &["-o", s(&wrong)]].concat());
        let err = failed(&o, "OutputExtension");
        assert!(err.contains(wants), "{args:?}: {err}");
        assert!(!wrong.exists());
    }
}

#[test]
fn values_changed_on_input_are_counted_and_targets_sorted_finest_first() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = generate_gaussians(&GaussianParams::new(300, 1, 4));
    for i in 0..37 {
        g.opacity_logit[5 * i] = f32::INFINITY;
    }
    g.opacity_logit[1] = f32::NEG_INFINITY;
    g.opacity_logit[2] = 20.0;
    g.f_rest[4 * 9 + 2] = f32::NAN;
    let ply = dir.path().join("inf.ply");
    std::fs::write(&ply, salvq_render::ply::ply_bytes(&g).unwrap()).unwrap();
    // `info` says it before any encode.
    let o = salvq(&["info", s(&ply)]);
    ok(&o);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("a 3DGS PLY, not a stream: 300 Gaussians"),
        "{text}"
    );
    assert!(
        text.contains("37 opacity values of +inf become 16"),
        "{text}"
    );
    assert!(
        text.contains("1 Gaussians hold a value the format cannot hold (f_rest_2: 1)"),
        "{text}"
    );
    assert!(text.contains("encode it: salvq encode"), "{text}");
    let o = salvq(&[
        "encode",
        s(&ply),
        "--psnr",
        "30,40",
        "--drop-invalid",
        "--json",
    ]);
    let err = ok(&o);
    for said in [
        "--drop-invalid: dropped 1 of 300 Gaussians (by the first value each cannot hold: f_rest_2: 1)",
        "changed on input: 37 opacity values of +inf became 16",
        "changed on input: 1 opacity values of > 16 became 16",
        "changed on input: 1 opacity values of -inf became -16",
        "--psnr 30,40: sorted finest first, so rate 0 is the finest: 40,30",
    ] {
        assert!(err.contains(said), "missing {said:?} in\n{err}");
    }
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["input_changes"][0]["count"], 37);
    assert_eq!(v["dropped"]["dropped"], 1);
    assert_eq!(v["targets_given"], serde_json::json!([30.0, 40.0]));
    let layers = v["layers"].as_array().unwrap();
    assert_eq!(layers[0]["target_db"], 40.0);
    assert_eq!(layers[1]["target_db"], 30.0);
    assert!(layers[0]["psnr_db"].as_f64() > layers[1]["psnr_db"].as_f64());
    for l in layers {
        assert!(l["target_met"].is_boolean(), "{l}");
    }
    // Progress off a terminal: a line per step, with the time and the share done.
    let step = err
        .lines()
        .find(|l| l.contains("fitting rate 0 of 2 to 40 dB"))
        .unwrap_or_else(|| panic!("{err}"));
    assert!(
        step.starts_with('[') && step.contains(" s] ") && step.contains(" %  "),
        "{step}"
    );
    assert!(
        err.lines()
            .filter(|l| l.contains("measuring what precision costs"))
            .count()
            >= 10
    );
    // A target above what the scene can reach fails at once, and writes nothing.
    let out = dir.path().join("high.salvq");
    let err = failed(
        &salvq(&[
            "encode",
            s(&ply),
            "--drop-invalid",
            "--psnr",
            "200",
            "-o",
            s(&out),
            "-q",
        ]),
        "TargetUnreachable",
    );
    assert!(err.contains("rate 0: the target 200 dB is above"), "{err}");
    assert!(!out.exists());
}

#[test]
fn the_encoder_reports_what_compare_measures() {
    let dir = tempfile::tempdir().unwrap();
    let (ply, stream, summary) = encoded(dir.path());
    assert_eq!(summary["psnr_measured_at"]["width"], 512);
    assert_eq!(summary["psnr_measured_at"]["height"], 384);
    for layer in summary["layers"].as_array().unwrap() {
        let rate = layer["rate"].to_string();
        let o = salvq(&["compare", s(&ply), s(&stream), "--rate-b", &rate, "--json"]);
        ok(&o);
        let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let (encoder, compare) = (
            layer["psnr_db"].as_f64().unwrap(),
            c["overall"]["psnr_db"].as_f64().unwrap(),
        );
        assert!(
            (encoder - compare).abs() < 1e-9,
            "rate {rate}: {encoder} vs {compare}"
        );
        let (encoder, compare) = (
            layer["ssim"].as_f64().unwrap(),
            c["overall"]["ssim"].as_f64().unwrap(),
        );
        assert!(
            (encoder - compare).abs() < 1e-9,
            "rate {rate}: {encoder} vs {compare}"
        );
    }
    // --quiet: nothing on stderr.
    let o = salvq(&[
        "decode",
        s(&stream),
        "-o",
        s(&dir.path().join("q.ply")),
        "-q",
    ]);
    assert_eq!(ok(&o), "");
}

#[test]
fn inputs_it_does_not_read_are_named_by_what_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    std::fs::write(p("notes.txt"), b"just some notes\nabout a scene\n").unwrap();
    let err = failed(&salvq(&["encode", s(&p("notes.txt"))]), "UnsupportedInput");
    assert!(
        err.contains("a text file (its first line: \"just some notes\")"),
        "{err}"
    );
    std::fs::write(
        p("ascii.ply"),
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
    )
    .unwrap();
    let err = failed(&salvq(&["encode", s(&p("ascii.ply"))]), "UnsupportedInput");
    assert!(
        err.contains("ASCII PLY") && err.contains("plyfile"),
        "{err}"
    );
    let empty = salvq_render::ply::ply_header(0, 0);
    std::fs::write(p("empty.ply"), empty.as_bytes()).unwrap();
    let err = failed(&salvq(&["encode", s(&p("empty.ply"))]), "UnsupportedInput");
    assert!(err.contains("no Gaussian"), "{err}");
    assert!(!p("empty.salvq").exists() && !p("notes.salvq").exists());
    // A file that is no stream fails as what it is, whatever output it is given.
    let err = failed(
        &salvq(&["decode", s(&p("empty.ply")), "-o", s(&p("x.ply"))]),
        "UnsupportedInput",
    );
    assert!(err.contains("a 3DGS PLY, not a SALVQ stream"), "{err}");
    let err = failed(
        &salvq(&["decode", s(&p("notes.txt")), "-o", s(&p("x.ply"))]),
        "SignatureMismatch",
    );
    assert!(err.contains("§1.2"), "{err}");
    // Targets that are no PSNR, or two equal ones, are usage errors before the PLY is read.
    for bad in ["45,45", "0", "-5", "inf"] {
        let err = usage_error(&salvq(&["encode", s(&p("empty.ply")), "--psnr", bad]));
        assert!(
            err.contains("--psnr") || err.contains("above 0"),
            "{bad}: {err}"
        );
    }
    let o = salvq(&["info", s(&p("empty.ply"))]);
    ok(&o);
    assert!(String::from_utf8_lossy(&o.stdout).contains("nothing to encode"));
    let o = salvq(&["--version"]);
    let v = String::from_utf8_lossy(&o.stdout);
    let format = format!(
        "(format {}.{}, commit ",
        salvq_bitstream::container::FORMAT_MAJOR,
        salvq_bitstream::container::FORMAT_MINOR
    );
    assert!(v.starts_with("salvq 0.") && v.contains(&format), "{v}");
}
